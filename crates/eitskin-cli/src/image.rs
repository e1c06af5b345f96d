//! `eitskin image`: reconstruct frames against a reference, print their touches, draw one.

use std::path::PathBuf;

use anyhow::Result;
use serde::Serialize;

use crate::imaging::{in_frame_order, reconstruct, BackgroundOut, Imaged, Input, Recording, Refused, Report};
use crate::{outputs, plot};

/// Flags of `eitskin image`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    input: Input,
    /// Write the raster as data: `.npy` (f32, ny × nx, row 0 at the top, NaN outside) or `.csv`
    /// (x, y in the spec's unit, Δσ in S/m per inside pixel); for a range of frames or `all`, a
    /// stack: frames × ny × nx (a frame refused all NaN, in its place), or a first CSV column
    /// `frame`.
    #[arg(long, value_parser = outputs::writes(&["npy", "csv"]))]
    out: Option<PathBuf>,
    /// Write the conductivity change of every triangle as CSV (triangle, centroid x, y, Δσ; a
    /// first column `frame` for a range of frames or `all`).
    #[arg(long, value_parser = outputs::writes(&["csv"]))]
    elements: Option<PathBuf>,
    /// Write the image as a PNG figure: Δσ in S/m on a colour bar, axes in the spec's unit, the
    /// electrodes numbered and each touch's centre ringed (one frame: `--frames K`).
    #[arg(long, value_parser = outputs::writes(&["png"]))]
    png: Option<PathBuf>,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

#[derive(Serialize)]
struct TouchOut {
    sign: &'static str,
    x: f64,
    y: f64,
    #[serde(serialize_with = "eitskin_io::stream::single_precision")]
    peak: f64,
    area: f64,
    pixels: usize,
}

/// One frame's answer: its touches, in the spec's unit.
#[derive(Serialize)]
struct FrameOut<'a> {
    frame: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    background_change: Option<&'a BackgroundOut>,
    touches: Vec<TouchOut>,
}

/// One frame's answer at the top level, or a stack's answers in `frames`.
#[derive(Serialize)]
#[serde(untagged)]
enum FramesOut<'a> {
    One(FrameOut<'a>),
    Stack { frames: Vec<FrameOut<'a>>, refused: &'a [Refused] },
}

impl FrameOut<'_> {
    /// The answer for frame `i`, lengths times `k` (the spec's unit per metre).
    fn of(i: &Imaged, k: f64) -> FrameOut<'_> {
        let touches = i.touches.iter().map(|t| TouchOut {
            sign: t.polarity.name(),
            x: t.centre[0] * k,
            y: t.centre[1] * k,
            peak: t.peak,
            area: t.area * k * k,
            pixels: t.pixels,
        });
        FrameOut { frame: i.frame, background_change: i.background_change.as_ref(), touches: touches.collect() }
    }
}

#[derive(Serialize)]
struct Output<'a> {
    #[serde(flatten)]
    report: &'a Report,
    length_unit: &'static str,
    peak_unit: &'static str,
    #[serde(flatten)]
    frames: FramesOut<'a>,
}

/// Runs `eitskin image`.
pub fn run(args: Args) -> Result<()> {
    let written = [("--out", &args.out), ("--elements", &args.elements), ("--png", &args.png)];
    let written: Vec<_> = written.iter().filter_map(|(flag, p)| p.as_deref().map(|p| (*flag, p))).collect();
    outputs::check(&written, &args.input.files())?;
    let stacked = args.input.frames.stacked();
    if stacked && args.png.is_some() {
        anyhow::bail!("--png draws one frame: choose it with --frames K (a range or `all` images several)");
    }
    let Recording { setup, imaged, refused } = reconstruct(&args.input)?;
    let (spec, recon) = (&setup.spec, &setup.recon);
    let k = 1.0 / spec.length_unit.metres();
    let mut answers: Vec<FrameOut> = imaged.iter().map(|i| FrameOut::of(i, k)).collect();
    let mut staged = outputs::Staged::default();
    let images: Vec<(usize, &eitskin::Image)> = imaged.iter().map(|i| (i.frame, &i.image)).collect();
    match &args.out {
        Some(path) if outputs::has_extension(path, "npy") => match stacked {
            true => {
                // A refused frame keeps its place in the stack, all NaN.
                let first = images[0].1;
                let blank = eitskin::Image { values: vec![f32::NAN; first.values.len()], ..first.clone() };
                eitskin_io::write_raster_stack_npy(&staged.path(path), &in_frame_order(&images, &refused, &blank))?
            }
            false => eitskin_io::write_raster_npy(&staged.path(path), images[0].1)?,
        },
        Some(path) => match stacked {
            true => eitskin_io::write_raster_stack_csv(&staged.path(path), &images, spec.length_unit)?,
            false => eitskin_io::write_raster_csv(&staged.path(path), images[0].1, spec.length_unit)?,
        },
        None => {}
    }
    if let Some(path) = &args.elements {
        let mut values = Vec::with_capacity(imaged.len());
        for i in &imaged {
            values.push((
                i.frame,
                recon.element_values(&setup.v_ref, &i.v)?.into_iter().map(f64::from).collect::<Vec<f64>>(),
            ));
        }
        let (mesh, unit, column) = (recon.linearisation().mesh(), spec.length_unit, "delta_sigma_s_per_m");
        match stacked {
            true => {
                let frames: Vec<(usize, &[f64])> = values.iter().map(|(k, v)| (*k, v.as_slice())).collect();
                eitskin_io::write_elements_stack_csv(&staged.path(path), mesh, &frames, unit, column)?
            }
            false => eitskin_io::write_elements_csv(&staged.path(path), mesh, &values[0].1, unit, column)?,
        }
    }
    if let (Some(png), Some(one)) = (&args.png, imaged.first()) {
        let frame = &args.input.frame;
        let name = frame.file_name().unwrap_or(frame.as_os_str()).to_string_lossy();
        let title = format!("Conductivity change: {name}, frame {}", one.frame);
        plot::image_png(&one.image, &one.touches, spec, &title, &staged.path(png))?;
    }
    staged.commit()?;
    if !args.json {
        println!("{}", setup.report.text());
    }
    let u = spec.length_unit.symbol();
    for answer in answers.iter().filter(|_| !args.json) {
        let frame = if stacked { format!("frame {}: ", answer.frame) } else { String::new() };
        if let Some(b) = answer.background_change {
            println!("{frame}{}", b.text());
        }
        println!("{frame}{} touch(es)", answer.touches.len());
        for (i, t) in answer.touches.iter().enumerate() {
            let (n, x, y, peak, area, sign) = (i + 1, t.x, t.y, t.peak, t.area, t.sign);
            println!("  {n}: {sign} at ({x:.2}, {y:.2}) {u}, peak {peak:.4e} S/m, area {area:.1} {u}²");
        }
    }
    if stacked && !args.json {
        println!("{} frame(s) imaged, {} refused", imaged.len(), refused.len());
    }
    if args.json {
        let frames = match stacked {
            true => FramesOut::Stack { frames: answers, refused: &refused },
            false => FramesOut::One(answers.remove(0)),
        };
        let out = Output { report: &setup.report, length_unit: u, peak_unit: "S/m", frames };
        println!("{}", serde_json::to_string_pretty(&out)?);
    }
    Ok(())
}
