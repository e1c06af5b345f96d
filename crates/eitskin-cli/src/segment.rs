//! `eitskin segment`: a label image of each frame (background, less or more conductive), by the
//! touches' own documented rule, so a data set's segmentation can be scored.

use std::path::PathBuf;

use anyhow::Result;
use eitskin::touch::{BACKGROUND, LESS_CONDUCTIVE, MORE_CONDUCTIVE};

/// The label of every pixel of a frame refused, in a stack.
const NOT_IMAGED: u8 = 255;
use serde::Serialize;

use crate::imaging::{in_frame_order, reconstruct, Input, Recording, Refused, Report};
use crate::outputs;

/// Flags of `eitskin segment`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    input: Input,
    /// Where to write the labels: `.npy` (u8, ny × nx, row 0 at the top) or `.csv` (x, y in the
    /// spec's unit, label per inside pixel); 0 background, 1 less, 2 more conductive. For a range
    /// of frames or `all`, a stack: frames × ny × nx (a frame refused all 255, in its place), or
    /// a first CSV column `frame`.
    #[arg(long, value_parser = outputs::writes(&["npy", "csv"]))]
    out: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

/// One frame's pixel counts inside the outline.
#[derive(Serialize)]
struct FrameOut {
    frame: usize,
    background: usize,
    less_conductive: usize,
    more_conductive: usize,
}

/// One frame's counts at the top level, or a stack's in `frames`.
#[derive(Serialize)]
#[serde(untagged)]
enum FramesOut<'a> {
    One(FrameOut),
    Stack { frames: Vec<FrameOut>, refused: &'a [Refused] },
}

#[derive(Serialize)]
struct Output<'a> {
    #[serde(flatten)]
    report: &'a Report,
    size: [usize; 2],
    #[serde(flatten)]
    frames: FramesOut<'a>,
}

/// Runs `eitskin segment`.
pub fn run(args: Args) -> Result<()> {
    outputs::check(&[("--out", &args.out)], &args.input.files())?;
    let stacked = args.input.frames.stacked();
    let Recording { setup, imaged, refused } = reconstruct(&args.input)?;
    let mut staged = outputs::Staged::default();
    let unit = setup.spec.length_unit;
    let grid = &imaged[0].image;
    let labels: Vec<(usize, &[u8])> = imaged.iter().map(|i| (i.frame, i.labels.as_slice())).collect();
    match (outputs::has_extension(&args.out, "npy"), stacked) {
        (true, true) => {
            // A refused frame keeps its place in the stack, every pixel NOT_IMAGED.
            let blank = vec![NOT_IMAGED; grid.values.len()];
            let stack = in_frame_order(&labels, &refused, blank.as_slice());
            eitskin_io::write_labels_stack_npy(&staged.path(&args.out), &stack, grid.size)?
        }
        (true, false) => eitskin_io::write_labels_npy(&staged.path(&args.out), labels[0].1, grid.size)?,
        (false, true) => eitskin_io::write_labels_stack_csv(&staged.path(&args.out), grid, &labels, unit)?,
        (false, false) => eitskin_io::write_labels_csv(&staged.path(&args.out), grid, labels[0].1, unit)?,
    }
    staged.commit()?;
    let mut counts: Vec<FrameOut> = imaged
        .iter()
        .map(|i| {
            let inside = |label: u8| i.labels.iter().zip(&i.image.inside).filter(|&(l, i)| *i && *l == label).count();
            FrameOut {
                frame: i.frame,
                background: inside(BACKGROUND),
                less_conductive: inside(LESS_CONDUCTIVE),
                more_conductive: inside(MORE_CONDUCTIVE),
            }
        })
        .collect();
    let [nx, ny] = grid.size;
    if args.json {
        let frames = match stacked {
            true => FramesOut::Stack { frames: counts, refused: &refused },
            false => FramesOut::One(counts.remove(0)),
        };
        let out = Output { report: &setup.report, size: grid.size, frames };
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    println!("{}", setup.report.text());
    for c in &counts {
        let frame = if stacked { format!("frame {}: ", c.frame) } else { String::new() };
        println!(
            "{frame}{nx} × {ny} pixels inside the outline: {} background, {} less, {} more conductive",
            c.background, c.less_conductive, c.more_conductive
        );
    }
    if stacked {
        println!("{} frame(s) segmented, {} refused", imaged.len(), refused.len());
    }
    Ok(())
}
