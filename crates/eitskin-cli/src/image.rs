//! `eitskin image`: reconstruct one frame against a reference, print its touches, draw it.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use eitskin::image::Image;
use eitskin::inverse::{
    mean_frame, noise_variance, plausible_ratio, typical_ratio, Channels, Hyperparameter, DEFAULT_RELATIVE_NOISE,
};
use eitskin::memory::Stage;
use eitskin::noise::{NoiseModel, Significance};
use eitskin::segmentation;
use eitskin::touch::{detect_tested_into, labels, PeakOf, Polarity, Touch, TouchScratch};
use eitskin::values::{signed_from_magnitudes, Component, Gains};
use eitskin::{Reconstructor, ReconstructorParams, SensorSpec, TouchParams};
use eitskin_io::{FrameLayout, FrameSelect, FrameTable};
use serde::Serialize;

use crate::{load, outputs, plot, ranges};

/// What `image` and `segment` read, and how they reconstruct: the flags they share.
#[derive(Debug, clap::Args)]
pub struct Input {
    /// Sensor spec file (TOML); default: the paper's sensor.
    spec: Option<PathBuf>,
    /// The reference (no-touch) frames: a MAT (v5, v7.3) or NPY file, a text log (one frame per
    /// line, as boards print them), a JSON array, `forward` output or CSV; several frames are
    /// averaged, and their spread is the measured noise.
    #[arg(long)]
    reference: PathBuf,
    /// The frame to image, in the same formats.
    #[arg(long)]
    frame: PathBuf,
    /// Which frame of the frame file, from 1.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..))]
    frame_index: u64,
    /// The variable of the frame's MAT file (a struct's field as NAME.FIELD).
    #[arg(long)]
    select: Option<String>,
    /// The variable of the reference's MAT file; default: `--select`'s.
    #[arg(long)]
    reference_select: Option<String>,
    /// Frames as `rows` or `columns` of the array; `auto`: columns in MAT files, rows otherwise.
    #[arg(long, default_value = "auto", value_parser = ["auto", "rows", "columns"])]
    layout: String,
    /// What the numbers are: `signed` voltages, `magnitude`s signed by the model, or `complex`
    /// (re, im) pairs, two numbers per measurement (complex MAT and NPY arrays are read as such
    /// whatever this says), imaged through --component.
    #[arg(long, default_value = "signed", value_parser = ["signed", "magnitude", "complex"])]
    values: String,
    /// For complex data, the part imaged: real, imaginary, magnitude (signed by the model) or phase.
    #[arg(long, default_value = "real")]
    component: Component,
    /// Hyperparameter λ of the one-step Gauss–Newton reconstruction, in (0, 1000], or `auto`:
    /// the larger of the λ for a noise figure of 0.5 (EIDORS') and the MAP λ of the noise level,
    /// with the noise measured from the reference frames when the reference file holds
    /// several, else 0.3 % of each value.
    #[arg(long, default_value = "auto")]
    hyperparameter: Hyperparameter,
    /// Normalised differences Δv/v_ref (immune to per-channel gains) instead of absolute ones.
    #[arg(long)]
    normalised: bool,
    /// Estimate each channel's gain from the reference against the model, divide it out, and
    /// drop (and name) the channels whose gain disagrees with the rest.
    #[arg(long)]
    gains: bool,
    /// Estimate a uniform change of the background conductivity between reference and frame
    /// (warming water, a drying gel), print it, and leave it out of the image.
    #[arg(long)]
    background_change: bool,
    /// Which changes are touches: `decrease` (a press on a hydrogel), `increase`, or `both`.
    #[arg(long, default_value = "decrease")]
    polarity: Polarity,
    /// Whose peak the threshold is a fraction of: `sign` (each sign's own strongest change, so a
    /// weaker object of the other sign is kept; with `--polarity both` the weaker sign is kept
    /// only when it rises above the shadow the stronger one casts in the image), `frame` (the
    /// strongest change of either sign, the paper's rule) or `touch` (each touch's own).
    #[arg(long, default_value = "sign")]
    peak_of: PeakOf,
    /// With several reference frames, touches (and labelled regions) whose peak the noise they
    /// measure explains are dropped: the false touches allowed per frame, in (0, 0.5]. With one
    /// reference frame only the weaker sign of `--polarity both` is tested, against 0.3 % noise.
    #[arg(long, default_value = "0.001", value_parser = ranges::number("a false-alarm rate", "(0, 0.5]", "0.001", |r| r > 0.0 && r <= 0.5))]
    false_alarm_rate: f64,
    /// Keep pixels at or above this fraction of the peak, in (0, 1].
    #[arg(long, default_value_t = 0.6, value_parser = ranges::number("a fraction of the peak", "(0, 1]", "0.6", |f| f > 0.0 && f <= 1.0))]
    threshold: f64,
    /// Mesh with about this many triangles instead of the spec's count, 1–100,000,000 (refused
    /// when the mesh and what is built on it would not fit in the memory available).
    #[arg(long, value_parser = ranges::triangles())]
    triangles: Option<usize>,
    /// The raster's pixels across and down, `NX` (square) or `NXxNY`, each in [4, 1024], over
    /// the mesh's bounding box.
    #[arg(long, default_value = "64", value_parser = parse_raster)]
    raster: [usize; 2],
    /// Always rebuild the reconstructor instead of loading it from the cache
    /// ($XDG_CACHE_HOME/eitskin or ~/.cache/eitskin, or $EITSKIN_CACHE).
    #[arg(long)]
    no_cache: bool,
}

/// Flags of `eitskin image`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    input: Input,
    /// Write the raster as data: `.npy` (f32, ny × nx, row 0 at the top, NaN outside) or `.csv`
    /// (x, y in the spec's unit, Δσ in S/m per inside pixel).
    #[arg(long, value_parser = outputs::writes(&["npy", "csv"]))]
    out: Option<PathBuf>,
    /// Write the conductivity change of every triangle as CSV (triangle, centroid x, y, Δσ).
    #[arg(long, value_parser = outputs::writes(&["csv"]))]
    elements: Option<PathBuf>,
    /// Write the image as a PNG figure: Δσ in S/m on a colour bar, axes in the spec's unit, the
    /// electrodes numbered and each touch's centre ringed.
    #[arg(long, value_parser = outputs::writes(&["png"]))]
    png: Option<PathBuf>,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

impl Input {
    /// The files read: the spec (when given), the reference and the frame, each with its flag.
    pub fn files(&self) -> Vec<(&'static str, &Path)> {
        let mut files = vec![("--reference", self.reference.as_path()), ("--frame", self.frame.as_path())];
        files.extend(self.spec.as_deref().map(|s| ("the spec", s)));
        files
    }
}

/// One frame reconstructed against its reference, with what was found on the way.
pub struct Reconstruction {
    /// The sensor.
    pub spec: SensorSpec,
    /// The reconstructor, derived for the data's channels and λ.
    pub recon: Reconstructor,
    /// The mean reference and the frame, signed, gains divided out.
    pub v_ref: Vec<f64>,
    /// The frame imaged.
    pub v: Vec<f64>,
    /// The conductivity-change image (S/m).
    pub image: Image,
    /// A label per pixel ([`eitskin::segmentation`]'s rule): the touches' pixels.
    pub labels: Vec<u8>,
    /// The touches of the image (of the weaker sign only when it passes the shadow test).
    pub touches: Vec<Touch>,
    /// The settings chosen and the quantities estimated, as printed.
    pub report: Report,
}

/// What a reconstruction chose and estimated, for text and JSON output.
#[derive(Serialize)]
pub struct Report {
    /// R² of the reference's ln|v| against the model's ([`Gains::pattern_fit`]).
    pattern_fit: f64,
    hyperparameter: f64,
    normalised: bool,
    channels_dropped: Vec<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    gains: Option<GainsOut>,
    #[serde(skip_serializing_if = "Option::is_none")]
    background_change: Option<BackgroundOut>,
}

#[derive(Serialize)]
struct GainsOut {
    /// Median gain, the board's unit per model volt.
    median: f64,
    /// 1-based channels whose gain is an outlier (dropped).
    outliers: Vec<usize>,
}

#[derive(Serialize)]
struct BackgroundOut {
    /// The background conductivity change, S/m.
    delta_s_per_m: f64,
    /// The same relative to the spec's conductivity.
    relative: f64,
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
struct Output<'a> {
    #[serde(flatten)]
    report: &'a Report,
    length_unit: &'static str,
    peak_unit: &'static str,
    touches: Vec<TouchOut>,
}

/// Reads the reference and the frame, reconstructs, and finds the touches: the chain `image`
/// and `segment` share.
pub fn reconstruct(input: &Input) -> Result<Reconstruction> {
    if !(input.threshold > 0.0 && input.threshold <= 1.0) {
        anyhow::bail!("--threshold {}: must be in (0, 1], a fraction of the peak", input.threshold);
    }
    let spec = load::sized(load::spec(input.spec.as_deref())?, input.triangles, Stage::Reconstructor)?;
    let measurements = spec.protocol()?.measurements().len();
    eitskin::memory::check_raster(input.raster, measurements, eitskin_io::available_memory())?;
    let layout = match input.layout.as_str() {
        "rows" => FrameLayout::Rows,
        "columns" => FrameLayout::Columns,
        _ => FrameLayout::Auto,
    };
    let select = FrameSelect { variable: input.select.clone(), layout };
    let reference_select = FrameSelect { variable: input.reference_select.clone().or(input.select.clone()), layout };
    let pairs = input.values == "complex";
    let mut references = frames(&eitskin_io::read_frames(&input.reference, &reference_select)?, input.component, pairs)
        .with_context(|| format!("reading {}", input.reference.display()))?;
    let table = frames(&eitskin_io::read_frames(&input.frame, &select)?, input.component, pairs)
        .with_context(|| format!("reading {}", input.frame.display()))?;
    let index = usize::try_from(input.frame_index - 1).unwrap_or(usize::MAX);
    let Some(mut v) = table.get(index).cloned() else {
        anyhow::bail!("--frame-index {}: {} holds {} frame(s)", input.frame_index, input.frame.display(), table.len());
    };
    let fixed = match input.hyperparameter {
        Hyperparameter::Fixed(value) => value,
        Hyperparameter::Auto => ReconstructorParams::default().hyperparameter,
    };
    let params = ReconstructorParams {
        hyperparameter: fixed,
        normalized: input.normalised,
        background_change: input.background_change,
        raster: input.raster,
        ..ReconstructorParams::default()
    };
    let recon = load::reconstructor(&spec, &params, !input.no_cache)?;
    let model = recon.linearisation().background();
    let count = |path: &Path, k: usize, frame: &[f64]| {
        match frame.len() == model.len() {
        true => Ok(()),
        false => Err(anyhow::anyhow!(
            "{}: frame {} holds {} values, but the protocol ({}) has {}: is it another protocol, or another board's order?",
            path.display(),
            k + 1,
            frame.len(),
            spec.protocol()?.description(),
            model.len()
        )),
    }
    };
    references.iter().enumerate().try_for_each(|(k, r)| count(&input.reference, k, r))?;
    count(&input.frame, index, &v)?;
    // A channel the spec drops, or a dead one (0 in every reference frame: a board prints 0 for
    // a broken contact, which would tell the image that nothing changed there), is missing from
    // here on: NaN, so it is dropped from the image and named by no check of the values.
    let in_use = spec.used_channels()?;
    let dead: Vec<bool> = mean_frame(&references).iter().map(|r| *r == 0.0).collect();
    for frame in references.iter_mut().chain(std::iter::once(&mut v)) {
        frame.iter_mut().enumerate().filter(|(m, _)| !in_use[*m] || dead[*m]).for_each(|(_, x)| *x = f64::NAN);
    }
    let magnitudes = input.values == "magnitude" || input.component == Component::Magnitude;
    let (mut references, mut v) = if magnitudes {
        let (v, report) = signed_from_magnitudes(&v, model);
        if !report.unexplained.is_empty() {
            let channels: Vec<usize> = report.unexplained.iter().map(|m| m + 1).collect();
            eprintln!("warning: the model does not explain the magnitudes of channels {channels:?}");
        }
        (references.iter().map(|r| signed_from_magnitudes(r, model).0).collect(), v)
    } else {
        (references, v)
    };
    let estimate = Gains::estimate(&mean_frame(&references), model);
    if estimate.pattern_fit < PATTERN_FIT_WARNING {
        eprintln!(
            "warning: the reference follows the model's pattern poorly (R² = {:.2} of ln|v| against the model's): \
             the values may not be this protocol's voltages (a saturated or clipped front end, another measurement \
             order, another electrode layout)",
            estimate.pattern_fit
        );
    }
    let pattern_fit = estimate.pattern_fit;
    let gains = input.gains.then_some(estimate);
    if let Some(gains) = &gains {
        references = references.iter().map(|r| gains.apply(r)).collect();
        v = gains.apply(&v);
    }
    let v_ref = mean_frame(&references);
    // Phases and quadrature parts may sit near 0, where a ratio means nothing.
    if matches!(input.component, Component::Real | Component::Magnitude) {
        check_scale(&v, &v_ref, input)?;
    }
    let variance = noise_variance(&references);
    if references.len() > 1 && variance.is_none() {
        eprintln!(
            "warning: the {} reference frames of {} are all equal: no noise can be measured from them, so {} % per value is assumed (several frames of a board at rest differ)",
            references.len(),
            input.reference.display(),
            100.0 * eitskin::inverse::DEFAULT_RELATIVE_NOISE
        );
    }
    // A channel missing (NaN) in the reference or the frame is dropped, not refused.
    let channels = Channels::finite_in(&v_ref).masked(Channels::finite_in(&v).used_mask());
    let recon = match input.hyperparameter {
        Hyperparameter::Auto => recon.with_auto_hyperparameter(channels, variance)?.0,
        Hyperparameter::Fixed(value) => recon.derive(value, channels)?,
    };
    let image = recon.image(&v_ref, &v).with_context(|| format!("imaging {}", input.frame.display()))?;
    // Touches are tested against the noise only when it is measured: an assumed level could
    // hide a real touch. The weaker sign must stand above the noise, measured or assumed.
    let measured = NoiseModel::from_frames(&references);
    let test = |noise: &NoiseModel| Significance::new(&recon, &v_ref, noise, 1, input.polarity, input.false_alarm_rate);
    let significance = measured.as_ref().map(test).transpose()?;
    let significance = significance.as_ref();
    let touch = TouchParams {
        threshold: input.threshold,
        polarity: input.polarity,
        peak_of: input.peak_of,
        ..TouchParams::default()
    };
    // Each sign at its own peak: the weaker sign only where it stands above the other's shadow.
    let polarity = if input.peak_of == PeakOf::Frame || input.polarity != Polarity::Both {
        input.polarity
    } else {
        let assumed = match significance {
            Some(_) => None,
            None => Some(test(&NoiseModel::assumed(DEFAULT_RELATIVE_NOISE, v_ref.len(), references.len()))?),
        };
        segmentation::signs(&recon, &image, &touch, significance.or(assumed.as_ref()))?
    };
    let touch = TouchParams { polarity, ..touch };
    let mut touches = Vec::new();
    detect_tested_into(&image, &touch, significance, &mut TouchScratch::new(image.size), &mut touches);
    let labels = labels(&image, &touch, significance);
    let background_change = recon
        .background_change(&v_ref, &v)?
        .map(|delta| BackgroundOut { delta_s_per_m: delta, relative: delta / spec.conductivity });
    let report = Report {
        pattern_fit,
        hyperparameter: recon.params().hyperparameter,
        normalised: input.normalised,
        channels_dropped: recon.channels().dropped().iter().map(|m| m + 1).collect(),
        gains: gains.map(|g| GainsOut { median: g.median, outliers: g.outliers.iter().map(|m| m + 1).collect() }),
        background_change,
    };
    Ok(Reconstruction { spec, recon, v_ref, v, image, labels, touches, report })
}

impl Report {
    /// The report as text lines: λ, the channels dropped, gains and background change.
    pub fn text(&self) -> String {
        let dropped = &self.channels_dropped;
        let mut text =
            format!("λ = {:.4}, reference against the model R² = {:.3}", self.hyperparameter, self.pattern_fit);
        if !dropped.is_empty() {
            text += &format!(", channels {dropped:?} dropped");
        }
        if let Some(g) = &self.gains {
            text += &format!("\ngains: median {:.4e}, outliers {:?}", g.median, g.outliers);
        }
        if let Some(b) = &self.background_change {
            text += &format!("\nbackground change: {:+.4e} S/m ({:+.2} %)", b.delta_s_per_m, 100.0 * b.relative);
        }
        text
    }
}

/// Below this R² of the reference against the model, the values are suspect and a warning says so.
const PATTERN_FIT_WARNING: f64 = 0.5;

/// Beyond this factor (either way) between a frame's and its reference's values, a warning says so.
const SCALE_WARNED: f64 = 2.0;

/// Refuses a frame whose typical value against the reference's ([`typical_ratio`]: the median
/// over channels of v / v_ref) is beyond [`eitskin::inverse::SCALE_LIMIT`] either way or of the other sign, and
/// warns past [`SCALE_WARNED`]: a frame in other units than its reference, or from another gain
/// setting.
fn check_scale(v: &[f64], v_ref: &[f64], input: &Input) -> Result<()> {
    let Some(median) = typical_ratio(v, v_ref) else { return Ok(()) };
    let said = format!(
        "{}'s values are typically {median:.3} times those of {} (the median over channels)",
        input.frame.display(),
        input.reference.display()
    );
    if !plausible_ratio(median) {
        anyhow::bail!("{said}: a press changes them by percents; are the two in the same unit and gain?");
    }
    if !(median > 1.0 / SCALE_WARNED && median < SCALE_WARNED) {
        eprintln!("warning: {said}; a press changes them by percents: are the two in the same unit and gain?");
    }
    Ok(())
}

/// Runs `eitskin image`.
pub fn run(args: Args) -> Result<()> {
    let written = [("--out", &args.out), ("--elements", &args.elements), ("--png", &args.png)];
    let written: Vec<_> = written.iter().filter_map(|(flag, p)| p.as_deref().map(|p| (*flag, p))).collect();
    outputs::check(&written, &args.input.files())?;
    let Reconstruction { spec, recon, v_ref, v, image, touches, report, .. } = reconstruct(&args.input)?;
    let k = 1.0 / spec.length_unit.metres();
    let out = Output {
        report: &report,
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
    let mut staged = outputs::Staged::default();
    match &args.out {
        Some(path) if outputs::has_extension(path, "npy") => eitskin_io::write_raster_npy(&staged.path(path), &image)?,
        Some(path) => eitskin_io::write_raster_csv(&staged.path(path), &image, spec.length_unit)?,
        None => {}
    }
    if let Some(path) = &args.elements {
        let values: Vec<f64> = recon.element_values(&v_ref, &v)?.into_iter().map(f64::from).collect();
        eitskin_io::write_elements_csv(
            &staged.path(path),
            recon.linearisation().mesh(),
            &values,
            spec.length_unit,
            "delta_sigma_s_per_m",
        )?;
    }
    if let Some(png) = &args.png {
        let frame = &args.input.frame;
        let name = frame.file_name().unwrap_or(frame.as_os_str()).to_string_lossy();
        let title = format!("Conductivity change: {name}, frame {}", args.input.frame_index);
        plot::image_png(&image, &touches, &spec, &title, &staged.path(png))?;
    }
    staged.commit()?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        println!("{}", report.text());
        println!("{} touch(es)", out.touches.len());
        for (i, t) in out.touches.iter().enumerate() {
            let u = out.length_unit;
            let (n, x, y, peak, area, sign) = (i + 1, t.x, t.y, t.peak, t.area, t.sign);
            println!("  {n}: {sign} at ({x:.2}, {y:.2}) {u}, peak {peak:.4e} S/m, area {area:.1} {u}²");
        }
    }
    Ok(())
}

/// `NX` or `NXxNY` as pixels across and down, each in [4, 1024].
fn parse_raster(text: &str) -> Result<[usize; 2], String> {
    let refuse = || {
        format!("\"{text}\" is not a raster size: write NX or NXxNY, each from 4 to 1024 pixels, e.g. 128 or 160x120")
    };
    let (nx, ny) = text.split_once(['x', 'X', '×']).unwrap_or((text, text));
    let side = |s: &str| s.trim().parse::<usize>().ok().filter(|n| (4..=1024).contains(n));
    Ok([side(nx).ok_or_else(refuse)?, side(ny).ok_or_else(refuse)?])
}

/// The frames of a table as values to image: real data as they are, complex data's
/// `component`, and with `pairs` real frames of interleaved (re, im) pairs through `component`.
fn frames(table: &FrameTable, component: Component, pairs: bool) -> Result<Vec<Vec<f64>>> {
    match &table.imaginary {
        Some(imaginary) => Ok(table.frames.iter().zip(imaginary).map(|(re, im)| component.of_frame(re, im)).collect()),
        None if pairs => table
            .frames
            .iter()
            .enumerate()
            .map(|(k, frame)| {
                if frame.len() % 2 != 0 {
                    anyhow::bail!("frame {} holds {} numbers: (re, im) pairs need an even count", k + 1, frame.len());
                }
                Ok(frame.chunks_exact(2).map(|p| component.of(p[0], p[1])).collect())
            })
            .collect(),
        None => Ok(table.frames.clone()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn raster_sizes_are_read_and_checked() {
        assert_eq!(parse_raster("128"), Ok([128, 128]));
        assert_eq!(parse_raster("160x120"), Ok([160, 120]));
        for bad in ["3", "2000", "0x64", "64x", "big", "-64"] {
            let err = parse_raster(bad).unwrap_err();
            assert!(err.starts_with(&format!("\"{bad}\" is not a raster size")), "{err}");
        }
    }

    #[test]
    fn interleaved_pairs_give_the_component_and_an_odd_count_is_refused() {
        let table = FrameTable { frames: vec![vec![3.0, 4.0, 0.0, -2.0]], imaginary: None };
        assert_eq!(frames(&table, Component::Magnitude, true).unwrap(), [vec![5.0, 2.0]]);
        assert_eq!(frames(&table, Component::Imaginary, true).unwrap(), [vec![4.0, -2.0]]);
        assert_eq!(frames(&table, Component::Real, false).unwrap(), table.frames);
        let odd = FrameTable { frames: vec![vec![1.0, 2.0, 3.0]], imaginary: None };
        let err = frames(&odd, Component::Real, true).unwrap_err();
        assert_eq!(err.to_string(), "frame 1 holds 3 numbers: (re, im) pairs need an even count");
    }
}
