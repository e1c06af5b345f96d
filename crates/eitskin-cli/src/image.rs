//! `eitskin image`: reconstruct one frame against a reference, print its touches, draw it.

use std::path::PathBuf;

use anyhow::{Context, Result};
use eitskin::touch::detect;
use eitskin::{ReconstructorParams, TouchParams};
use serde::Serialize;

use crate::{load, plot};

/// Flags of `eitskin image`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Sensor spec file (TOML); default: the paper's sensor.
    spec: Option<PathBuf>,
    /// The reference (no-touch) frame: JSON array, `forward` output, or CSV.
    #[arg(long)]
    reference: PathBuf,
    /// The frame to image, in the same formats.
    #[arg(long)]
    frame: PathBuf,
    /// Write the image as a PNG heat map (touches marked).
    #[arg(long)]
    png: Option<PathBuf>,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
    /// Hyperparameter λ of the one-step Gauss–Newton reconstruction.
    #[arg(long, default_value_t = 0.1)]
    hyperparameter: f64,
    /// Keep pixels at or above this fraction of the peak.
    #[arg(long, default_value_t = 0.6)]
    threshold: f64,
    /// Mesh with about this many triangles instead of the spec's count.
    #[arg(long)]
    triangles: Option<usize>,
    /// Always rebuild the reconstructor instead of loading it from the cache
    /// ($XDG_CACHE_HOME/eitskin or ~/.cache/eitskin, or $EITSKIN_CACHE).
    #[arg(long)]
    no_cache: bool,
}

#[derive(Serialize)]
struct TouchOut {
    x: f64,
    y: f64,
    peak: f64,
    area: f64,
    pixels: usize,
}

#[derive(Serialize)]
struct Output {
    length_unit: &'static str,
    peak_unit: &'static str,
    touches: Vec<TouchOut>,
}

/// Runs `eitskin image`.
pub fn run(args: Args) -> Result<()> {
    let mut spec = load::spec(args.spec.as_deref())?;
    if let Some(n) = args.triangles {
        spec.mesh.triangles = n;
    }
    let v_ref = eitskin_io::read_frame(&args.reference)?;
    let v = eitskin_io::read_frame(&args.frame)?;
    let params = ReconstructorParams { hyperparameter: args.hyperparameter, ..ReconstructorParams::default() };
    let recon = load::reconstructor(&spec, &params, !args.no_cache)?;
    let image = recon.image(&v_ref, &v).with_context(|| format!("imaging {}", args.frame.display()))?;
    let touches = detect(&image, &TouchParams { threshold: args.threshold, ..TouchParams::default() });
    let k = 1.0 / spec.length_unit.metres();
    let out = Output {
        length_unit: spec.length_unit.symbol(),
        peak_unit: "S/m",
        touches: touches
            .iter()
            .map(|t| TouchOut {
                x: t.centre[0] * k,
                y: t.centre[1] * k,
                peak: t.peak,
                area: t.area * k * k,
                pixels: t.pixels,
            })
            .collect(),
    };
    if let Some(png) = &args.png {
        plot::image_png(&image, &touches, png)?;
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        println!("{} touch(es)", out.touches.len());
        for (i, t) in out.touches.iter().enumerate() {
            let u = out.length_unit;
            println!("  {}: at ({:.2}, {:.2}) {u}, peak {:.4e} S/m, area {:.1} {u}²", i + 1, t.x, t.y, t.peak, t.area);
        }
    }
    Ok(())
}
