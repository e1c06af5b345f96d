//! What `image` and `segment` share: their input flags, one setup from the reference (the
//! reconstructor, λ, the channels in use, gains and the noise test), and each frame of the
//! selection imaged and segmented with it.

use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use anyhow::{Context, Result};
use eitskin::image::Image;
use eitskin::inverse::{
    mark_missing, mean_frame, noise_variance, plausible_ratio, typical_ratio, HyperparameterRule, Weighting,
    WeightingUsed, DEFAULT_RELATIVE_NOISE,
};
use eitskin::memory::Stage;
use eitskin::noise::{NoiseModel, Significance};
use eitskin::segmentation;
use eitskin::touch::{detect_tested_into, labels, PeakOf, Polarity, Touch, TouchScratch};
use eitskin::values::{signed_from_magnitudes, Component, Gains, ValueKind};
use eitskin::{Reconstructor, ReconstructorParams, SensorSpec, TouchParams};
use eitskin_io::build::ReferenceImaging;
use eitskin_io::{FrameLayout, FrameSelect, FrameTable};
use serde::Serialize;

use crate::{load, ranges};

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
    /// The frames to image, in the same formats.
    #[arg(long)]
    pub frame: PathBuf,
    /// Which frames of the frame file, from 1: `K` (one frame), `A-B` (frames A to B) or `all`,
    /// each imaged with one setup (one λ, one set of channels: a channel missing in any of them
    /// is dropped from all).
    #[arg(long, alias = "frame-index", default_value = "1")]
    pub frames: Frames,
    /// The variable of the frame's MAT file (a struct's field as NAME.FIELD).
    #[arg(long)]
    select: Option<String>,
    /// The variable of the reference's MAT file; default: `--select`'s.
    #[arg(long)]
    reference_select: Option<String>,
    /// Frames as `rows` or `columns` of the array; `auto`: columns in MAT files, rows otherwise.
    #[arg(long, value_enum, default_value_t = LayoutFlag::Auto)]
    layout: LayoutFlag,
    /// What the numbers are: `signed` voltages, `magnitude`s signed by the model, or `complex`
    /// (re, im) pairs, two numbers per measurement (complex MAT and NPY arrays are read as such
    /// whatever this says), imaged through --component.
    #[arg(long, value_enum, default_value_t = ValuesFlag::Signed)]
    values: ValuesFlag,
    /// For complex data, the part imaged: real, imaginary, magnitude (signed by the model) or phase.
    #[arg(long, default_value = "real")]
    component: Component,
    /// Hyperparameter λ of the one-step Gauss–Newton reconstruction, in [1e-6, 1000], or `auto`:
    /// the larger of the λ for a noise figure of 0.5 (EIDORS') and the MAP λ of the noise level,
    /// with the noise measured from the reference frames when the reference file holds
    /// several, else 0.3 % of each value; or chosen from the frames themselves: `gcv`
    /// (generalised cross-validation) or `discrepancy` (the fit no closer than that noise).
    #[arg(long, default_value = "auto")]
    hyperparameter: HyperparameterRule,
    /// How the channels are weighted: `noise` (each by its noise variance, measured from several
    /// reference frames, else 0.3 % of its value) or `none` (all alike, at their mean noise);
    /// default: `noise` with a chosen λ, `none` with a given one. The λ printed and this
    /// weighting given back reproduce the image.
    #[arg(long)]
    weighting: Option<WeightingFlag>,
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

impl Input {
    /// The files read: the spec (when given), the reference and the frame, each with its flag.
    pub fn files(&self) -> Vec<(&'static str, &Path)> {
        let mut files = vec![("--reference", self.reference.as_path()), ("--frame", self.frame.as_path())];
        files.extend(self.spec.as_deref().map(|s| ("the spec", s)));
        files
    }
}

/// `--values`, as clap reads it: what a board's or a file's numbers are.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ValuesFlag {
    /// Signed values, as the forward model gives them.
    Signed,
    /// Magnitudes |v|, signed by the model.
    Magnitude,
    /// (re, im) pairs, two numbers per measurement.
    Complex,
}

impl ValuesFlag {
    /// The library's value kind, complex pairs imaged through `component`.
    pub fn kind(self, component: Component) -> ValueKind {
        match self {
            ValuesFlag::Signed => ValueKind::Signed,
            ValuesFlag::Magnitude => ValueKind::Magnitude,
            ValuesFlag::Complex => ValueKind::Complex(component),
        }
    }
}

/// `--layout`, as clap reads it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum LayoutFlag {
    /// Columns in MAT files, rows otherwise.
    Auto,
    /// One frame per row.
    Rows,
    /// One frame per column.
    Columns,
}

impl From<LayoutFlag> for FrameLayout {
    fn from(flag: LayoutFlag) -> FrameLayout {
        match flag {
            LayoutFlag::Auto => FrameLayout::Auto,
            LayoutFlag::Rows => FrameLayout::Rows,
            LayoutFlag::Columns => FrameLayout::Columns,
        }
    }
}

/// `--weighting`, as clap reads it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum WeightingFlag {
    /// Each channel by its noise variance (EIDORS' `meas_icov`).
    Noise,
    /// All channels alike.
    None,
}

impl From<WeightingFlag> for Weighting {
    fn from(flag: WeightingFlag) -> Weighting {
        match flag {
            WeightingFlag::Noise => Weighting::Noise,
            WeightingFlag::None => Weighting::None,
        }
    }
}

/// Serialises a weighting by its name.
fn weighting_name<S: serde::Serializer>(weighting: &WeightingUsed, serializer: S) -> Result<S::Ok, S::Error> {
    serializer.serialize_str(weighting.name())
}

/// Which frames of the frame file `--frames` names, from 1.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Frames {
    /// One frame: outputs hold one image, as for a file of one frame.
    One(usize),
    /// Frames `first..=last`: outputs hold a stack, one image per frame.
    Range(usize, usize),
    /// Every frame of the file: outputs hold a stack.
    All,
}

/// The largest frame number `--frames` takes.
const MAX_FRAME: usize = 1_000_000_000;

impl FromStr for Frames {
    type Err = String;

    fn from_str(text: &str) -> Result<Frames, String> {
        let refuse = || {
            format!(
                "\"{text}\" is not a selection of frames: write K, A-B (frames from 1 to {MAX_FRAME}, A ≤ B) or all"
            )
        };
        let number = |s: &str| s.trim().parse::<usize>().ok().filter(|k| (1..=MAX_FRAME).contains(k));
        let text_trimmed = text.trim();
        if text_trimmed.eq_ignore_ascii_case("all") {
            return Ok(Frames::All);
        }
        match text_trimmed.split_once('-') {
            Some((a, b)) => match (number(a), number(b)) {
                (Some(a), Some(b)) if a <= b => Ok(Frames::Range(a, b)),
                _ => Err(refuse()),
            },
            None => number(text_trimmed).map(Frames::One).ok_or_else(refuse),
        }
    }
}

impl Frames {
    /// Whether the outputs hold a stack of frames (a range or `all`, however many frames it holds).
    pub fn stacked(self) -> bool {
        !matches!(self, Frames::One(_))
    }

    /// The 0-based indices selected in a file of `count` frames; refused when the selection
    /// reaches past its end.
    fn indices(self, count: usize, file: &Path) -> Result<RangeInclusive<usize>> {
        let (first, last, said) = match self {
            Frames::All if count > 0 => return Ok(0..=count - 1),
            Frames::All => anyhow::bail!("{} holds no frame", file.display()),
            Frames::One(k) => (k, k, k.to_string()),
            Frames::Range(a, b) => (a, b, format!("{a}-{b}")),
        };
        if last > count {
            anyhow::bail!("--frames {said}: {} holds {count} frame(s)", file.display());
        }
        Ok(first - 1..=last - 1)
    }
}

/// The setup of a recording, made once from the reference: what every frame is imaged with.
pub struct Setup {
    /// The sensor.
    pub spec: SensorSpec,
    /// The reconstructor, derived for the data's channels and λ.
    pub recon: Reconstructor,
    /// The mean reference, signed, gains divided out.
    pub v_ref: Vec<f64>,
    /// The settings chosen and the quantities estimated, as printed.
    pub report: Report,
    /// The noise test, with the measured noise (several reference frames that vary).
    significance: Option<Significance>,
    /// The test of the weaker sign where the noise is not measured: against the assumed noise.
    assumed: Option<Significance>,
    touch: TouchParams,
}

/// One frame imaged with the setup.
pub struct Imaged {
    /// The frame's number in its file, from 1.
    pub frame: usize,
    /// The frame, signed, gains divided out.
    pub v: Vec<f64>,
    /// The conductivity-change image (S/m).
    pub image: Image,
    /// A label per pixel ([`eitskin::segmentation`]'s rule): the touches' pixels.
    pub labels: Vec<u8>,
    /// The touches of the image (of the weaker sign only when it passes the shadow test).
    pub touches: Vec<Touch>,
    /// The uniform background change estimated with the image, with `--background-change`.
    pub background_change: Option<BackgroundOut>,
}

/// A frame of the selection the setup could not image, and why.
#[derive(Serialize)]
pub struct Refused {
    /// The frame's number in its file, from 1.
    pub frame: usize,
    /// Why, in words.
    pub reason: String,
}

/// The frames of the selection, each imaged or refused, with their one setup.
pub struct Recording {
    /// What every frame was imaged with.
    pub setup: Setup,
    /// The frames imaged, in file order.
    pub imaged: Vec<Imaged>,
    /// The frames refused (only with a stacked selection: one frame refused is an error).
    pub refused: Vec<Refused>,
}

/// What a reconstruction chose and estimated, for text and JSON output.
#[derive(Serialize)]
pub struct Report {
    /// R² of the reference's ln|v| against the model's ([`Gains::pattern_fit`]).
    pattern_fit: f64,
    hyperparameter: f64,
    /// What chose λ: `given`, `noise-figure-and-map` (`auto`), `gcv` or `discrepancy`.
    chosen_by: &'static str,
    /// How the channels were weighted.
    #[serde(serialize_with = "weighting_name")]
    weighting: WeightingUsed,
    normalised: bool,
    channels_dropped: Vec<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    gains: Option<GainsOut>,
}

#[derive(Serialize)]
struct GainsOut {
    /// Median gain, the board's unit per model volt.
    median: f64,
    /// 1-based channels whose gain is an outlier (dropped).
    outliers: Vec<usize>,
}

/// A uniform background conductivity change, as printed.
#[derive(Serialize)]
pub struct BackgroundOut {
    /// The background conductivity change, S/m.
    delta_s_per_m: f64,
    /// The same relative to the spec's conductivity.
    relative: f64,
}

impl BackgroundOut {
    /// The change as a line of text.
    pub fn text(&self) -> String {
        format!("background change: {:+.4e} S/m ({:+.2} %)", self.delta_s_per_m, 100.0 * self.relative)
    }
}

/// Each frame's item in file order for a stack: the imaged frames' (frame number, item) and
/// `blank` for every refused frame, so that a stack's index is still the frame's place.
pub fn in_frame_order<'a, T: ?Sized>(imaged: &[(usize, &'a T)], refused: &[Refused], blank: &'a T) -> Vec<&'a T> {
    let mut all: Vec<(usize, &T)> = imaged.to_vec();
    all.extend(refused.iter().map(|r| (r.frame, blank)));
    all.sort_by_key(|(frame, _)| *frame);
    all.into_iter().map(|(_, item)| item).collect()
}

/// Reads the reference and the selected frames, makes one setup, and images and segments each
/// frame: the chain `image` and `segment` share.
pub fn reconstruct(input: &Input) -> Result<Recording> {
    if !(input.threshold > 0.0 && input.threshold <= 1.0) {
        anyhow::bail!("--threshold {}: must be in (0, 1], a fraction of the peak", input.threshold);
    }
    let spec = load::sized(load::spec(input.spec.as_deref())?, input.triangles, Stage::Reconstructor)?;
    let measurements = spec.protocol()?.measurements().len();
    eitskin::memory::check_raster(input.raster, measurements, eitskin_io::available_memory())?;
    let Read { mut references, selected, first } = read_input(input, &spec)?;
    let Kept { numbers, frames: mut selected, refused } = without_empty(input, selected, first)?;
    let lin = eitskin_io::build::linearisation(&spec, !input.no_cache)?;
    crate::ranges::warn_raised_triangles(input.triangles, lin.mesh(), &spec)?;
    let (pattern_fit, gains) = signed_and_gained(input, lin.background(), &mut references, &mut selected);
    let setup = setup(input, spec, &lin, (&references, &selected), pattern_fit, gains)?;
    let recording = Recording { setup, imaged: Vec::new(), refused };
    image_all(input, recording, selected, &numbers)
}

/// The frames kept for imaging, with the numbers in their file, and those refused before.
struct Kept {
    /// Each kept frame's number in its file, from 1.
    numbers: Vec<usize>,
    /// The kept frames.
    frames: Vec<Vec<f64>>,
    /// The frames refused.
    refused: Vec<Refused>,
}

/// The selected frames (numbered from `first` + 1) less those with no finite value, which
/// would leave no channel to image any frame with: each refused and named in a stack, else the
/// error.
fn without_empty(input: &Input, selected: Vec<Vec<f64>>, first: usize) -> Result<Kept> {
    let (mut numbers, mut kept, mut refused) = (Vec::new(), Vec::new(), Vec::new());
    for (k, v) in selected.into_iter().enumerate() {
        let frame = first + k + 1;
        if v.iter().any(|x| x.is_finite()) {
            numbers.push(frame);
            kept.push(v);
            continue;
        }
        let reason = "holds no finite value (every channel missing)".to_owned();
        if !input.frames.stacked() {
            anyhow::bail!("{}: frame {frame} {reason}", input.frame.display());
        }
        eprintln!("warning: frame {frame} of {} not imaged: {reason}", input.frame.display());
        refused.push(Refused { frame, reason });
    }
    if kept.is_empty() {
        anyhow::bail!("no frame of {} holds a finite value", input.frame.display());
    }
    Ok(Kept { numbers, frames: kept, refused })
}

/// The reference frames and the selected frames of `input`, each as long as the protocol, the
/// channels the spec drops (and dead ones) missing (NaN); and the index of the first frame
/// selected.
fn read_input(input: &Input, spec: &SensorSpec) -> Result<Read> {
    let layout = FrameLayout::from(input.layout);
    let select = FrameSelect { variable: input.select.clone(), layout };
    let reference_select = FrameSelect { variable: input.reference_select.clone().or(input.select.clone()), layout };
    let pairs = input.values == ValuesFlag::Complex;
    let (reference_table, frame_table) = (
        eitskin_io::read_frames(&input.reference, &reference_select)?,
        eitskin_io::read_frames(&input.frame, &select)?,
    );
    check_kinds(input, &reference_table, &frame_table)?;
    let mut references = frames(&reference_table, input.component, pairs)
        .with_context(|| format!("reading {}", input.reference.display()))?;
    let mut table =
        frames(&frame_table, input.component, pairs).with_context(|| format!("reading {}", input.frame.display()))?;
    let indices = input.frames.indices(table.len(), &input.frame)?;
    let first = *indices.start();
    table.truncate(indices.end() + 1);
    let mut selected: Vec<Vec<f64>> = table.drain(first..).collect();
    let protocol = spec.protocol()?;
    let count = |path: &Path, k: usize, frame: &[f64]| {
        match frame.len() == protocol.len() {
        true => Ok(()),
        false => Err(anyhow::anyhow!(
            "{}: frame {} holds {} values, but the protocol ({}) has {}: is it another protocol, or another board's order?",
            path.display(),
            k + 1,
            frame.len(),
            protocol.description(),
            protocol.len()
        )),
    }
    };
    references.iter().enumerate().try_for_each(|(k, r)| count(&input.reference, k, r))?;
    selected.iter().enumerate().try_for_each(|(k, v)| count(&input.frame, first + k, v))?;
    // A channel the spec drops, or a dead one, is missing (NaN) from here on: dropped from the
    // image and named by no check of the values.
    mark_missing(&spec.used_channels()?, &mut references, &mut selected);
    Ok(Read { references, selected, first })
}

/// Refuses a reference and frames of which one holds complex values and the other real ones
/// (a part of the complex values would be compared with the real values), and a complex
/// component asked of real frames (it would image the real values without a word).
fn check_kinds(input: &Input, reference: &FrameTable, frames: &FrameTable) -> Result<()> {
    let kind = |t: &FrameTable| if t.imaginary.is_some() { "complex" } else { "real" };
    if reference.imaginary.is_some() != frames.imaginary.is_some() {
        anyhow::bail!(
            "{} holds {} values and {} {} ones: give the frames at rest and the frames as the same board sent them",
            input.reference.display(),
            kind(reference),
            input.frame.display(),
            kind(frames)
        );
    }
    let complex = frames.imaginary.is_some() || input.values == ValuesFlag::Complex;
    if !complex && matches!(input.component, Component::Imaginary | Component::Phase) {
        anyhow::bail!(
            "--component {}: {} holds real values, which have no such part (complex frames have one; (re, im) pairs need --values complex)",
            if input.component == Component::Phase { "phase" } else { "imaginary" },
            input.frame.display()
        );
    }
    Ok(())
}

/// The frames of an `image` or `segment` call, as long as the protocol.
struct Read {
    /// The frames at rest.
    references: Vec<Vec<f64>>,
    /// The frames selected, to be imaged.
    selected: Vec<Vec<f64>>,
    /// The index of the first frame selected in its file.
    first: usize,
}

/// Magnitudes signed by the model, and the gains applied with `--gains`; the reference's fit
/// to the model's pattern (R²) and the gains estimated, each warned of when off.
fn signed_and_gained(
    input: &Input,
    model: &[f64],
    references: &mut Vec<Vec<f64>>,
    selected: &mut Vec<Vec<f64>>,
) -> (f64, Option<Gains>) {
    let magnitudes = input.values == ValuesFlag::Magnitude || input.component == Component::Magnitude;
    if magnitudes {
        let mut unexplained = std::collections::BTreeSet::new();
        for v in selected.iter_mut() {
            let (signed, report) = signed_from_magnitudes(v, model);
            unexplained.extend(report.unexplained.iter().map(|m| m + 1));
            *v = signed;
        }
        if !unexplained.is_empty() {
            let channels: Vec<usize> = unexplained.into_iter().collect();
            eprintln!("warning: the model does not explain the magnitudes of channels {channels:?}");
        }
        *references = references.iter().map(|r| signed_from_magnitudes(r, model).0).collect();
    }
    let estimate = Gains::estimate(&mean_frame(references), model);
    if estimate.pattern_fit < PATTERN_FIT_WARNING {
        eprintln!(
            "warning: the reference follows the model's pattern poorly (R² = {} of ln|v| against the model's): \
             the values may not be this protocol's voltages (a saturated or clipped front end, another measurement \
             order, another electrode layout)",
            r_squared(estimate.pattern_fit)
        );
    }
    let pattern_fit = estimate.pattern_fit;
    let gains = input.gains.then_some(estimate);
    if let Some(gains) = &gains {
        *references = references.iter().map(|r| gains.apply(r)).collect();
        *selected = selected.iter().map(|v| gains.apply(v)).collect();
    }
    if references.len() > 1 && noise_variance(references).is_none() {
        eprintln!(
            "warning: the {} reference frames of {} are all equal: no noise can be measured from them, so {} % per value is assumed (several frames of a board at rest differ)",
            references.len(),
            input.reference.display(),
            100.0 * eitskin::inverse::DEFAULT_RELATIVE_NOISE
        );
    }
    (pattern_fit, gains)
}

/// The one setup of every frame: λ and the weighting from the reference, the noise test, the
/// touch settings and the report.
fn setup(
    input: &Input,
    spec: SensorSpec,
    lin: &std::sync::Arc<eitskin::inverse::Linearisation>,
    (references, selected): (&[Vec<f64>], &[Vec<f64>]),
    pattern_fit: f64,
    gains: Option<Gains>,
) -> Result<Setup> {
    let params = ReconstructorParams {
        normalised: input.normalised,
        background_change: input.background_change,
        raster: input.raster,
        ..ReconstructorParams::default()
    };
    let rule = (input.hyperparameter, input.weighting.map(Weighting::from));
    let imaging = ReferenceImaging::new(&spec, lin, &params, (references, selected), rule, !input.no_cache)?;
    let (recon, v_ref) = (imaging.recon, imaging.reference.v_ref);
    // Touches are tested against the noise only when it is measured: an assumed level could
    // hide a real touch. The weaker sign must stand above the noise, measured or assumed.
    let measured = NoiseModel::from_frames(references);
    let test = |noise: &NoiseModel| Significance::new(&recon, &v_ref, noise, 1, input.polarity, input.false_alarm_rate);
    let significance = measured.as_ref().map(test).transpose()?;
    let both_signs = input.peak_of != PeakOf::Frame && input.polarity == Polarity::Both;
    let assumed = match (&significance, both_signs) {
        (None, true) => Some(test(&NoiseModel::assumed(DEFAULT_RELATIVE_NOISE, v_ref.len(), references.len()))?),
        _ => None,
    };
    let touch = TouchParams {
        threshold: input.threshold,
        polarity: input.polarity,
        peak_of: input.peak_of,
        ..TouchParams::default()
    };
    let report = Report {
        pattern_fit,
        hyperparameter: recon.params().hyperparameter,
        chosen_by: imaging.chosen_by,
        weighting: imaging.weighting,
        normalised: input.normalised,
        channels_dropped: recon.channels().dropped().iter().map(|m| m + 1).collect(),
        gains: gains
            .as_ref()
            .map(|g| GainsOut { median: g.median, outliers: g.outliers.iter().map(|m| m + 1).collect() }),
    };
    Ok(Setup { spec, recon, v_ref, report, significance, assumed, touch })
}

/// Each selected frame (numbered in `numbers`) imaged and segmented into `recording`; with a
/// stacked selection a frame refused is named and skipped, else it is the error.
fn image_all(input: &Input, mut recording: Recording, selected: Vec<Vec<f64>>, numbers: &[usize]) -> Result<Recording> {
    let mut scratch = TouchScratch::new(input.raster);
    for (v, &frame) in selected.into_iter().zip(numbers) {
        match recording.setup.image(frame, v, input, &mut scratch) {
            Ok(imaged) => recording.imaged.push(imaged),
            Err(e) if input.frames.stacked() => {
                let reason = format!("{e:#}");
                eprintln!("warning: frame {frame} of {} not imaged: {reason}", input.frame.display());
                recording.refused.push(Refused { frame, reason });
            }
            Err(e) => return Err(e),
        }
    }
    if recording.imaged.is_empty() {
        anyhow::bail!("no frame of {} could be imaged (see the warnings above)", input.frame.display());
    }
    recording.refused.sort_by_key(|r| r.frame);
    Ok(recording)
}

impl Setup {
    /// Images and segments frame number `frame` (its values `v`, signed, gains not yet divided
    /// out): refused when its scale is unlike the reference's.
    fn image(&self, frame: usize, v: Vec<f64>, input: &Input, scratch: &mut TouchScratch) -> Result<Imaged> {
        // Phases and quadrature parts may sit near 0, where a ratio means nothing.
        if matches!(input.component, Component::Real | Component::Magnitude) {
            check_scale(&v, &self.v_ref, frame, input)?;
        }
        let recon = &self.recon;
        let image = recon.image(&self.v_ref, &v).with_context(|| format!("imaging {}", input.frame.display()))?;
        if let Some((change, largest)) = unchanged(&v, &self.v_ref) {
            eprintln!(
                "warning: frame {frame} of {} equals its reference to rounding (largest change {change:.1e} against values up to {largest:.1e}): no touch",
                input.frame.display()
            );
            let labels = vec![eitskin::touch::BACKGROUND; image.values.len()];
            return Ok(Imaged { frame, v, image, labels, touches: Vec::new(), background_change: None });
        }
        let significance = self.significance.as_ref();
        // Each sign at its own peak: the weaker sign only where it stands above the other's shadow.
        let polarity = match (input.peak_of, input.polarity) {
            (PeakOf::Frame, p) | (_, p @ (Polarity::Decrease | Polarity::Increase)) => p,
            (_, Polarity::Both) => {
                segmentation::signs(recon, &image, &self.touch, significance.or(self.assumed.as_ref()))?
            }
        };
        let touch = TouchParams { polarity, ..self.touch };
        let mut touches = Vec::new();
        detect_tested_into(&image, &touch, significance, scratch, &mut touches);
        let labels = labels(&image, &touch, significance);
        let background_change = recon
            .background_change(&self.v_ref, &v)?
            .map(|delta| BackgroundOut { delta_s_per_m: delta, relative: delta / self.spec.conductivity });
        Ok(Imaged { frame, v, image, labels, touches, background_change })
    }
}

impl Report {
    /// The report as text lines: λ, the channels dropped and the gains.
    pub fn text(&self) -> String {
        let dropped = &self.channels_dropped;
        let weighting = match self.weighting {
            WeightingUsed::NoiseMeasured => "channels weighted by their measured noise".to_string(),
            WeightingUsed::NoiseAssumed => {
                format!("channels weighted by an assumed noise of {} % of each value", 100.0 * DEFAULT_RELATIVE_NOISE)
            }
            WeightingUsed::None => "channels weighted alike".to_string(),
        };
        let mut text = format!(
            "λ = {} ({}; {weighting}), reference against the model R² = {}",
            significant(self.hyperparameter),
            self.chosen_by.replace('-', " "),
            r_squared(self.pattern_fit)
        );
        if !dropped.is_empty() {
            text += &format!(", channels {dropped:?} dropped");
        }
        if let Some(g) = &self.gains {
            text += &format!("\ngains: median {:.4e}, outliers {:?}", g.median, g.outliers);
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
fn check_scale(v: &[f64], v_ref: &[f64], frame: usize, input: &Input) -> Result<()> {
    let Some(median) = typical_ratio(v, v_ref) else { return Ok(()) };
    let said = format!(
        "frame {frame} of {} has values typically {median:.3} times those of {} (the median over channels)",
        input.frame.display(),
        input.reference.display()
    );
    if !plausible_ratio(median) {
        anyhow::bail!("{said}: a press changes them by percents; are the two in the same unit and gain?");
    }
    if !(median > 1.0 / SCALE_WARNED && median < SCALE_WARNED) {
        eprintln!("warning: {said}; a press changes them by percents: are the two in the same unit and gain?");
    }
    // The frame's pattern against its reference's (the reference's spread the whole).
    let fit = eitskin::values::pattern_fit(v_ref, v);
    if fit < PATTERN_FIT_WARNING {
        eprintln!(
            "warning: frame {frame} of {} follows the pattern of {} poorly (R² = {} of ln|v| against the reference's, channel by channel): a press changes a few channels by percents; is it the same sensor, protocol and order?",
            input.frame.display(),
            input.reference.display(),
            r_squared(fit)
        );
    }
    Ok(())
}

/// A frame no different from its reference but for rounding: the largest change over the
/// channels and the largest value, where the change is under [`ROUNDING`] of the value.
fn unchanged(v: &[f64], v_ref: &[f64]) -> Option<(f64, f64)> {
    let finite = v.iter().zip(v_ref).filter(|(a, b)| a.is_finite() && b.is_finite());
    let (change, largest) = finite.fold((0.0f64, 0.0f64), |(c, l), (a, b)| (c.max((a - b).abs()), l.max(b.abs())));
    (largest > 0.0 && change <= ROUNDING * largest).then_some((change, largest))
}

/// A λ as text: four decimals, or four significant digits where it is below 1 (1e-6 read 0.0000).
fn significant(value: f64) -> String {
    if value >= 1.0 {
        format!("{value:.4}")
    } else {
        format!("{value:.4e}")
    }
}

/// A change under this fraction of the largest value is rounding, not a press.
const ROUNDING: f64 = 1e-9;

/// An R² as text: three decimals, or "below −1" where it means no likeness at all.
fn r_squared(value: f64) -> String {
    if value < -1.0 {
        "below −1".into()
    } else {
        format!("{value:.3}")
    }
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
    fn frame_selections_are_read_checked_and_held_to_the_file() {
        assert_eq!("3".parse(), Ok(Frames::One(3)));
        assert_eq!("2-40".parse(), Ok(Frames::Range(2, 40)));
        assert_eq!(" ALL ".parse(), Ok(Frames::All));
        for bad in ["0", "5-2", "-3", "1-", "x", "1-2-3", "", "2000000000"] {
            let err = bad.parse::<Frames>().unwrap_err();
            assert!(err.starts_with(&format!("\"{bad}\" is not a selection of frames")), "{err}");
        }
        let file = Path::new("rec.txt");
        assert_eq!(Frames::All.indices(51, file).unwrap(), 0..=50);
        assert_eq!(Frames::Range(2, 51).indices(51, file).unwrap(), 1..=50);
        assert_eq!(Frames::One(51).indices(51, file).unwrap(), 50..=50);
        let err = Frames::Range(5, 60).indices(51, file).unwrap_err();
        assert_eq!(err.to_string(), "--frames 5-60: rec.txt holds 51 frame(s)");
        assert_eq!(Frames::All.indices(0, file).unwrap_err().to_string(), "rec.txt holds no frame");
        assert!(!Frames::One(4).stacked() && Frames::Range(4, 4).stacked() && Frames::All.stacked());
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
