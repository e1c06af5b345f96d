//! `eitskin segment`: a label image of one frame (background, less or more conductive), by the
//! touches' own documented rule, so a data set's segmentation can be scored.

use std::path::PathBuf;

use anyhow::Result;
use eitskin::touch::{BACKGROUND, LESS_CONDUCTIVE, MORE_CONDUCTIVE};
use serde::Serialize;

use crate::image::{reconstruct, Input, Reconstruction};
use crate::outputs;

/// Flags of `eitskin segment`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    input: Input,
    /// Where to write the labels: `.npy` (u8, ny × nx, row 0 at the top) or `.csv` (x, y in the
    /// spec's unit, label per inside pixel); 0 background, 1 less, 2 more conductive.
    #[arg(long, value_parser = outputs::writes(&["npy", "csv"]))]
    out: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

#[derive(Serialize)]
struct Output<'a> {
    #[serde(flatten)]
    report: &'a crate::image::Report,
    size: [usize; 2],
    background: usize,
    less_conductive: usize,
    more_conductive: usize,
}

/// Runs `eitskin segment`.
pub fn run(args: Args) -> Result<()> {
    outputs::check(&[("--out", &args.out)], &args.input.files())?;
    let Reconstruction { spec, image, labels, report, .. } = reconstruct(&args.input)?;
    let mut staged = outputs::Staged::default();
    if outputs::has_extension(&args.out, "npy") {
        eitskin_io::write_labels_npy(&staged.path(&args.out), &labels, image.size)?;
    } else {
        eitskin_io::write_labels_csv(&staged.path(&args.out), &image, &labels, spec.length_unit)?;
    }
    staged.commit()?;
    let inside = |label: u8| labels.iter().zip(&image.inside).filter(|&(l, i)| *i && *l == label).count();
    let out = Output {
        report: &report,
        size: image.size,
        background: inside(BACKGROUND),
        less_conductive: inside(LESS_CONDUCTIVE),
        more_conductive: inside(MORE_CONDUCTIVE),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        println!("{}", report.text());
        let [nx, ny] = out.size;
        println!(
            "{nx} × {ny} pixels inside the outline: {} background, {} less, {} more conductive",
            out.background, out.less_conductive, out.more_conductive
        );
    }
    Ok(())
}
