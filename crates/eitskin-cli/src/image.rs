//! `eitskin image`: reconstruct one frame against a reference, print its touches, draw it.

use std::path::PathBuf;

use anyhow::{Context, Result};
use eitskin::inverse::{mean_frame, noise_variance, Channels, Hyperparameter};
use eitskin::touch::{detect, Polarity};
use eitskin::values::{signed_from_magnitudes, Component};
use eitskin::{ReconstructorParams, TouchParams};
use eitskin_io::{FrameLayout, FrameSelect, FrameTable};
use serde::Serialize;

use crate::{load, plot};

/// Flags of `eitskin image`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Sensor spec file (TOML); default: the paper's sensor.
    spec: Option<PathBuf>,
    /// The reference (no-touch) frames: a MAT (v5, v7.3) or NPY file, a JSON array, `forward`
    /// output or CSV; several frames are averaged, and their spread is the measured noise.
    #[arg(long)]
    reference: PathBuf,
    /// The frame to image, in the same formats.
    #[arg(long)]
    frame: PathBuf,
    /// Which frame of the frame file, from 1.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..))]
    frame_index: u64,
    /// The variable of a MAT file (a struct's field as NAME.FIELD).
    #[arg(long)]
    select: Option<String>,
    /// Frames as `rows` or `columns` of the array; `auto`: columns in MAT files, rows otherwise.
    #[arg(long, default_value = "auto", value_parser = ["auto", "rows", "columns"])]
    layout: String,
    /// What the numbers are: `signed` voltages, or `magnitude`s signed by the model.
    #[arg(long, default_value = "signed", value_parser = ["signed", "magnitude"])]
    values: String,
    /// For complex data, the part imaged: real, imaginary, magnitude (signed by the model) or phase.
    #[arg(long, default_value = "real")]
    component: Component,
    /// Write the raster as data: `.npy` (f32, ny × nx, row 0 at the top, NaN outside) or `.csv`
    /// (x, y in the spec's unit, Δσ in S/m per inside pixel).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Write a label image as NPY (u8, ny × nx, row 0 at the top): 0 background, 1 less and 2
    /// more conductive, by the touches' own rule (`--threshold` of the peak, `--polarity`).
    #[arg(long)]
    labels: Option<PathBuf>,
    /// Write the conductivity change of every triangle as CSV (triangle, centroid x, y, Δσ).
    #[arg(long)]
    elements: Option<PathBuf>,
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
    let layout = match args.layout.as_str() {
        "rows" => FrameLayout::Rows,
        "columns" => FrameLayout::Columns,
        _ => FrameLayout::Auto,
    };
    let select = FrameSelect { variable: args.select.clone(), layout };
    let references = frames(&eitskin_io::read_frames(&args.reference, &select)?, args.component);
    let table = frames(&eitskin_io::read_frames(&args.frame, &select)?, args.component);
    let index = usize::try_from(args.frame_index - 1).unwrap_or(usize::MAX);
    let Some(v) = table.get(index).cloned() else {
        anyhow::bail!("--frame-index {}: {} holds {} frame(s)", args.frame_index, args.frame.display(), table.len());
    };
    let fixed = match args.hyperparameter {
        Hyperparameter::Fixed(value) => value,
        Hyperparameter::Auto => ReconstructorParams::default().hyperparameter,
    };
    let params =
        ReconstructorParams { hyperparameter: fixed, normalized: args.normalised, ..ReconstructorParams::default() };
    let recon = load::reconstructor(&spec, &params, !args.no_cache)?;
    let magnitudes = args.values == "magnitude" || args.component == Component::Magnitude;
    let (references, v) = if magnitudes {
        let model = recon.linearisation().background();
        let (v, report) = signed_from_magnitudes(&v, model);
        if !report.unexplained.is_empty() {
            let channels: Vec<usize> = report.unexplained.iter().map(|m| m + 1).collect();
            eprintln!("warning: the model does not explain the magnitudes of channels {channels:?}");
        }
        (references.iter().map(|r| signed_from_magnitudes(r, model).0).collect(), v)
    } else {
        (references, v)
    };
    let v_ref = mean_frame(&references);
    let variance = noise_variance(&references, args.normalised);
    // A channel missing (NaN) in the reference or the frame is dropped, not refused; so is one
    // whose reference is zero (a dead channel) when differences are normalised by it.
    let alive: Vec<bool> = v_ref.iter().map(|r| !args.normalised || *r != 0.0).collect();
    let channels = Channels::finite_in(&v_ref).masked(Channels::finite_in(&v).used_mask()).masked(&alive);
    let recon = match args.hyperparameter {
        Hyperparameter::Auto => recon.with_auto_hyperparameter(channels, variance)?.0,
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
    match &args.out {
        Some(path) if path.extension().is_some_and(|e| e == "npy") => eitskin_io::write_raster_npy(path, &image)?,
        Some(path) => eitskin_io::write_raster_csv(path, &image, spec.length_unit)?,
        None => {}
    }
    if let Some(path) = &args.labels {
        eitskin_io::write_labels_npy(path, &eitskin::touch::labels(&image, &touch), image.size)?;
    }
    if let Some(path) = &args.elements {
        let values: Vec<f64> = recon.element_values(&v_ref, &v)?.into_iter().map(f64::from).collect();
        eitskin_io::write_elements_csv(
            path,
            recon.linearisation().mesh(),
            &values,
            spec.length_unit,
            "delta_sigma_s_per_m",
        )?;
    }
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

/// The frames of a table as signed values: real data as they are, complex data's `component`.
fn frames(table: &FrameTable, component: Component) -> Vec<Vec<f64>> {
    match &table.imaginary {
        None => table.frames.clone(),
        Some(imaginary) => table.frames.iter().zip(imaginary).map(|(re, im)| component.of_frame(re, im)).collect(),
    }
}
