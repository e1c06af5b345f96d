//! `eitskin image`: reconstruct one frame against a reference, print its touches, draw it.

use std::path::PathBuf;

use anyhow::{Context, Result};
use eitskin::inverse::{Channels, Hyperparameter};
use eitskin::touch::{detect, Polarity};
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
    /// Hyperparameter λ of the one-step Gauss–Newton reconstruction, in (0, 1000], or `auto`:
    /// chosen for a noise figure of 0.5 (EIDORS'), with the noise measured from the reference
    /// frames when the reference file holds several, else taken relative to each value.
    #[arg(long, default_value = "auto")]
    hyperparameter: Hyperparameter,
    /// Normalised differences Δv/v_ref (immune to per-channel gains) instead of absolute ones.
    #[arg(long)]
    normalised: bool,
    /// Which changes are touches: `decrease` (a press on a hydrogel), `increase`, or `both`.
    #[arg(long, default_value = "decrease")]
    polarity: Polarity,
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
    sign: &'static str,
    x: f64,
    y: f64,
    peak: f64,
    area: f64,
    pixels: usize,
}

#[derive(Serialize)]
struct Output {
    hyperparameter: f64,
    normalised: bool,
    channels_dropped: Vec<usize>,
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
    let fixed = match args.hyperparameter {
        Hyperparameter::Fixed(value) => value,
        Hyperparameter::Auto => ReconstructorParams::default().hyperparameter,
    };
    let params =
        ReconstructorParams { hyperparameter: fixed, normalized: args.normalised, ..ReconstructorParams::default() };
    let recon = load::reconstructor(&spec, &params, !args.no_cache)?;
    // A channel missing (NaN) in the reference or the frame is dropped, not refused.
    let channels = Channels::finite_in(&v_ref).masked(Channels::finite_in(&v).used_mask());
    let recon = match args.hyperparameter {
        Hyperparameter::Auto => recon.with_auto_hyperparameter(channels, None)?.0,
        Hyperparameter::Fixed(value) => recon.derive(value, channels)?,
    };
    let image = recon.image(&v_ref, &v).with_context(|| format!("imaging {}", args.frame.display()))?;
    let touch = TouchParams { threshold: args.threshold, polarity: args.polarity, ..TouchParams::default() };
    let touches = detect(&image, &touch);
    let k = 1.0 / spec.length_unit.metres();
    let out = Output {
        hyperparameter: recon.params().hyperparameter,
        normalised: args.normalised,
        channels_dropped: recon.channels().dropped().iter().map(|m| m + 1).collect(),
        length_unit: spec.length_unit.symbol(),
        peak_unit: "S/m",
        touches: touches
            .iter()
            .map(|t| TouchOut {
                sign: t.polarity.name(),
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
        let dropped = &out.channels_dropped;
        let dropped = if dropped.is_empty() { String::new() } else { format!(", channels {dropped:?} dropped") };
        println!("λ = {:.4}{dropped}", out.hyperparameter);
        println!("{} touch(es)", out.touches.len());
        for (i, t) in out.touches.iter().enumerate() {
            let u = out.length_unit;
            let (n, x, y, peak, area, sign) = (i + 1, t.x, t.y, t.peak, t.area, t.sign);
            println!("  {n}: {sign} at ({x:.2}, {y:.2}) {u}, peak {peak:.4e} S/m, area {area:.1} {u}²");
        }
    }
    Ok(())
}
