//! `eitskin calibrate` and `eitskin evaluate`: fit a per-area calibration from recorded
//! samples, and measure a calibration's force error on other samples.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use eitskin::calibration::{force_errors, Calibration, ForceEstimate, Sample};
use eitskin::chain::LabelledFrame;
use eitskin::labelled::{self, process_labelled, split_references, MATCH_DISTANCE};
use eitskin::pipeline::PipelineParams;
use eitskin::pseudo_array::PseudoArray;
use eitskin::spec::Quantity;
use eitskin::strength::Strength;
use eitskin::{ReconstructorParams, SensorSpec};
use eitskin_io::build::ChainSetup;
use eitskin_io::{CalibrationFile, FrameSelect, Imaging, Location, Measured, SampleRow};

use crate::{load, outputs, ranges};

/// Flags of `eitskin calibrate`.
#[derive(Debug, clap::Args)]
pub struct CalibrateArgs {
    /// Sensor spec file (TOML); default: the paper's sensor.
    spec: Option<PathBuf>,
    /// Samples (CSV): `unit` or `x,y`; `force`; `peak` or the raw frame's values.
    #[arg(long)]
    samples: PathBuf,
    /// Where to write the calibration (JSON).
    #[arg(long, value_parser = outputs::writes(&["json"]))]
    out: PathBuf,
    /// Units per side of the pseudo-array, 1–100 (the paper's 5; 1: one curve for the sheet).
    #[arg(long, default_value_t = 5, value_parser = ranges::whole("a number of units per side", 1, eitskin::pseudo_array::MAX_UNITS_PER_SIDE))]
    grid: usize,
    /// Frames without a press (a MAT, NPY or text file of one or many frames), for samples of
    /// raw frames: the reference is their mean (with the samples' rows of 0 N) and each
    /// channel's noise is measured on them.
    #[arg(long)]
    reference: Option<PathBuf>,
    /// What the curves take as the touch's strength: `auto` (raw frames: the press strength
    /// that reads the samples best at places its curve did not see, each printed; peaks: the
    /// peak), `peak` (the image's, the paper's), `fitted-drop` (of the press fitted to Δv),
    /// `sized-drop` (the same, every press's radius fitted), `peak-sensitivity` (peak ÷ the
    /// forward model's sensitivity there), or the forward model's contrast map read from the
    /// peak, the volume or both: `contrast-map-peak`, `contrast-map-volume`,
    /// `contrast-map-peak-and-volume`. All but `peak` need raw frames.
    #[arg(long, value_parser = parse_strength_choice, default_value = "auto")]
    strength: StrengthChoice,
}

/// `--strength`: one strength, or the best press strength for the samples.
#[derive(Debug, Clone, Copy, PartialEq)]
enum StrengthChoice {
    /// The press strength that reads the samples best ([`labelled::choose_strength`]); the
    /// peak for samples of peaks.
    Auto,
    /// This one.
    One(Strength),
}

/// Parses `--strength`: `auto` or a strength's flag.
fn parse_strength_choice(text: &str) -> Result<StrengthChoice, String> {
    if text == "auto" {
        return Ok(StrengthChoice::Auto);
    }
    parse_strength(text)
        .map(StrengthChoice::One)
        .map_err(|e| e.replace("expected one of ", "expected auto, or one of "))
}

/// A strength's name on the command line: its file name in kebab case (`fitted drop` →
/// `fitted-drop`, `contrast map (peak)` → `contrast-map-peak`).
fn strength_flag(strength: Strength) -> String {
    strength.name().replace(" / ", " ").replace(['(', ')'], "").replace(' ', "-")
}

/// Parses `--strength`, naming every accepted value when it cannot.
fn parse_strength(text: &str) -> Result<Strength, String> {
    Strength::ALL.into_iter().find(|s| strength_flag(*s) == text).ok_or_else(|| {
        let names: Vec<String> = Strength::ALL.into_iter().map(strength_flag).collect();
        format!("expected one of {}", names.join(", "))
    })
}

/// Flags of `eitskin evaluate`.
#[derive(Debug, clap::Args)]
pub struct EvaluateArgs {
    /// Sensor spec file (TOML); default: the paper's sensor.
    spec: Option<PathBuf>,
    /// The calibration (JSON, from `eitskin calibrate`).
    #[arg(long, required_unless_present = "model", conflicts_with = "model")]
    calibration: Option<PathBuf>,
    /// A learned model (JSON, from `eitskin learn`) instead: its position and force errors on
    /// the samples (`x`, `y`, optional `force`, then each press's channels).
    #[arg(long)]
    model: Option<PathBuf>,
    /// Samples (CSV), as for `calibrate`.
    #[arg(long)]
    samples: PathBuf,
    /// Frames without a press (a MAT, NPY or text file of one or many frames), for samples of
    /// raw frames: the reference is their mean (with the samples' rows of 0 N) and each
    /// channel's noise is measured on them.
    #[arg(long)]
    reference: Option<PathBuf>,
    /// Write each sample's result here (CSV: the label, whether its press was found, where, the
    /// force read and its standard deviation; with --model, the model's position, force and
    /// depth with their standard deviations).
    #[arg(long, value_parser = outputs::writes(&["csv"]))]
    out: Option<PathBuf>,
}

/// Runs `eitskin calibrate`.
pub fn calibrate(args: CalibrateArgs) -> Result<()> {
    let mut read = vec![("--samples", args.samples.as_path())];
    read.extend(args.reference.as_deref().map(|p| ("--reference", p)));
    read.extend(args.spec.as_deref().map(|p| ("the spec", p)));
    outputs::check(&[("--out", &args.out)], &read)?;
    let spec = load::spec(args.spec.as_deref())?;
    let array = PseudoArray::of_sensor(&spec, [args.grid; 2])?;
    let rows = eitskin_io::read_samples(&args.samples, spec.length_unit.metres())?;
    let labelled = Labelled::of(&spec, &array, &args.samples, rows)?;
    if let (Labelled::Peaks(_), Some(path)) = (&labelled, &args.reference) {
        bail!(
            "--reference {}: {} holds peaks, read as they are; frames at rest are for samples of raw frames",
            path.display(),
            args.samples.display()
        );
    }
    let (samples, strength) = match (labelled, args.strength) {
        (Labelled::Peaks(peaks), StrengthChoice::Auto | StrengthChoice::One(Strength::Peak)) => (peaks, Strength::Peak),
        (Labelled::Peaks(_), StrengthChoice::One(strength)) => {
            bail!(
                "{}: a \"{strength}\" calibration needs each sample's raw frame, not its peak",
                args.samples.display()
            )
        }
        (Labelled::Frames(frames), choice) => {
            let (references, pressed) = references(&spec, args.reference.as_deref(), &args.samples, frames)?;
            check_areas(&array, &pressed, &args.samples)?;
            let strengths = match choice {
                StrengthChoice::Auto => labelled::PRESS_STRENGTHS.to_vec(),
                StrengthChoice::One(strength) => vec![strength],
            };
            let setup = ChainSetup { strength: strengths[0], ..ChainSetup::new(ReconstructorParams::default()) };
            let chain = load::chain("calibrate", &spec, setup)?;
            let params = PipelineParams::default();
            let (trials, best) = labelled::choose_strength(&chain, &strengths, params, &references, &pressed, &array)?;
            if trials.len() > 1 {
                print_trials(&trials, best);
            }
            let trial = &trials[best];
            report_missed(&args.samples, &pressed, &trial.samples);
            (trial.samples.iter().flatten().copied().collect(), trial.strength)
        }
    };
    let calibration = Calibration::fit_strength(&samples, array.area_count(), strength)?;
    // The chain images as `eitskin_io::build::chain` does: the file records it, and `run` then images so.
    let params = ReconstructorParams::default();
    let imaging = Imaging { hyperparameter: params.hyperparameter, normalised: params.normalised };
    let mut staged = crate::outputs::Staged::default();
    std::fs::write(staged.path(&args.out), eitskin_io::calibration_file_to_json(&spec, &array, &calibration, imaging)?)
        .with_context(|| format!("writing {}", args.out.display()))?;
    staged.commit()?;
    print_curves(&calibration, &samples, strength);
    println!("wrote {}", args.out.display());
    Ok(())
}

/// Each press strength tried on the samples, and which `--strength auto` keeps.
fn print_trials(trials: &[labelled::StrengthTrial], best: usize) {
    println!("strengths tried (one curve each, read at places it did not see, on the presses all of them found):");
    for (k, trial) in trials.iter().enumerate() {
        let read = trial.samples.iter().flatten().count();
        let error = trial.held_out_rms.map_or("– (fewer than 3 places)".into(), |e| format!("{e:.3} N"));
        let kept = if k == best { "  ← kept" } else { "" };
        println!("  {:<12} {read:>5} presses read, held-out force RMS {error}{kept}", trial.strength.name());
    }
}

/// The fitted curves, one line per area, with how far each reads from one curve for every sample.
fn print_curves(calibration: &Calibration, samples: &[Sample], strength: Strength) {
    let unit = format!("[{}]", strength.unit());
    // One curve for every sample, to say how far each area's curve reads from it.
    let pooled: Vec<Sample> = samples.iter().map(|s| Sample { area: 0, ..*s }).collect();
    let offsets = match Calibration::fit_strength(&pooled, 1, strength) {
        Ok(one) if calibration.curves.len() > 1 => calibration.offsets_from(&one.curves[0]),
        _ => vec![f64::NAN; calibration.curves.len()],
    };
    println!(
        "{} samples, {} areas; {strength}(F) = a·e^(−F/b) + c, or a·(1 + F/(k·b))^(−k) + c where a shape k fits better:",
        samples.len(),
        calibration.curves.len()
    );
    println!(
        "{:>5} {:>12} {:>10} {:>12} {:>5} {:>7} {:>12} {:>10} {:>8} {:>13}",
        "area",
        format!("a {unit}"),
        "b [N]",
        format!("c {unit}"),
        "k",
        "R²",
        format!("spread {unit}"),
        "F [N]",
        "samples",
        "vs one [N]"
    );
    for (k, (c, offset)) in calibration.curves.iter().zip(&offsets).enumerate() {
        let offset = if offset.is_finite() { format!("{offset:.2}") } else { "–".into() };
        println!(
            "{:>5} {:>12.4e} {:>10.3} {:>12.4e} {:>5} {:>7.3} {:>12.3e} {:>4.0}–{:<5.0} {:>8} {:>13}{}",
            k + 1,
            c.a,
            c.b,
            c.c,
            c.shape.map_or("exp".into(), |k| format!("{k}")),
            c.r_squared,
            c.spread,
            c.force_range[0],
            c.force_range[1],
            c.samples,
            offset,
            if c.fallback { "  (Levenberg–Marquardt did not converge: the best curve on a grid of b)" } else { "" }
        );
    }
    if offsets.iter().any(|o| o.is_finite()) {
        println!(
            "vs one: the RMS force (N) one curve for every sample reads for each area's curve, less the force; \
             areas within the noise of each other read better as one curve (--grid 1)"
        );
    }
}

/// Runs `eitskin evaluate`: with raw frames, each through the same chain as `eitskin run`
/// (the strongest touch's force, its unit where the chain places it); with peaks, at the
/// sample's own unit.
pub fn evaluate(args: EvaluateArgs) -> Result<()> {
    let spec = load::spec(args.spec.as_deref())?;
    if let Some(out) = &args.out {
        let mut read = vec![("--samples", args.samples.as_path())];
        read.extend(args.calibration.as_deref().map(|p| ("--calibration", p)));
        read.extend(args.model.as_deref().map(|p| ("--model", p)));
        read.extend(args.reference.as_deref().map(|p| ("--reference", p)));
        read.extend(args.spec.as_deref().map(|p| ("the spec", p)));
        outputs::check(&[("--out", out)], &read)?;
    }
    let Some(path) = &args.calibration else {
        let model = args.model.as_deref().context("give --calibration or --model")?;
        let (samples, reference, out) = (&args.samples, args.reference.as_deref(), args.out.as_deref());
        return crate::learn::evaluate_model(&spec, model, samples, reference, out);
    };
    let file = eitskin_io::read_calibration_file(path, &spec)?;
    let results = evaluated(&spec, file, &args.samples, args.reference.as_deref())?;
    print_force_errors(&results);
    if let Some(out) = &args.out {
        write_evaluated(out, &spec, &results)?;
    }
    Ok(())
}

/// A labelled sample and what the chain read of it.
struct Evaluated {
    /// Where it was pressed, m (NaN for a peak's sample).
    at: [f64; 2],
    /// Its force, N.
    force: f64,
    /// What the chain found, if anything.
    found: Option<Found>,
}

/// Each sample of `samples` read with the calibration `file`: raw frames through the same
/// pipeline as `run`, peaks at the sample's own unit.
fn evaluated(
    spec: &SensorSpec,
    file: CalibrationFile,
    samples: &Path,
    reference: Option<&Path>,
) -> Result<Vec<Evaluated>> {
    let CalibrationFile { array, calibration, imaging } = file;
    let rows = eitskin_io::read_samples(samples, spec.length_unit.metres())?;
    let mut results = Vec::new();
    match Labelled::of(spec, &array, samples, rows)? {
        Labelled::Peaks(peaks) if calibration.strength == Strength::Peak => {
            for s in &peaks {
                let force = calibration.force(s.area, s.peak)?;
                let found = Some(Found { centre: [f64::NAN; 2], force: Some(force) });
                results.push(Evaluated { at: [f64::NAN; 2], force: s.force, found });
            }
        }
        Labelled::Peaks(_) if reference.is_some() => bail!(
            "--reference {}: {} holds peaks, read as they are; frames at rest are for samples of raw frames",
            reference.map_or_else(String::new, |p| p.display().to_string()),
            samples.display()
        ),
        Labelled::Peaks(_) => bail!(
            "{}: the calibration reads the \"{}\", which needs each sample's raw frame, not its peak",
            samples.display(),
            calibration.strength
        ),
        Labelled::Frames(frames) => {
            let (references, pressed) = references(spec, reference, samples, frames)?;
            let params = ReconstructorParams {
                hyperparameter: imaging.hyperparameter,
                normalised: imaging.normalised,
                ..ReconstructorParams::default()
            };
            let setup = ChainSetup { calibration: Some((array, calibration)), ..ChainSetup::new(params) };
            let chain = load::chain("evaluate", spec, setup)?;
            let found = process_labelled(chain, PipelineParams::default(), &references, &pressed)?;
            report_missed(samples, &pressed, &found);
            for (labelled, touch) in pressed.iter().zip(&found) {
                let found =
                    touch.map(|t| Found { centre: t.press.map_or(t.touch.centre, |p| p.centre), force: t.force });
                results.push(Evaluated { at: labelled.position, force: labelled.force, found });
            }
        }
    }
    Ok(results)
}

/// The force errors over the samples read with a force, and how often the truth lies within
/// twice the force's standard deviation.
fn print_force_errors(results: &[Evaluated]) {
    let estimates: Vec<(f64, ForceEstimate)> =
        results.iter().filter_map(|r| Some((r.force, r.found.as_ref()?.force?))).collect();
    let (truth, predicted): (Vec<f64>, Vec<f64>) = estimates.iter().map(|(t, f)| (*t, f.newtons)).unzip();
    let saturated = estimates.iter().filter(|(_, f)| f.saturated).count();
    let found = results.iter().filter(|r| r.found.is_some()).count();
    let e = force_errors(&truth, &predicted);
    println!(
        "{} samples: {found} found, {} missed, {} with a force ({saturated} saturated); errors over those with a force",
        results.len(),
        results.len() - found,
        e.count
    );
    // Forces all 0 N (or all alike) have no percentage (no largest force) or no correlation.
    let percent = if e.rms_percent_of_max.is_finite() {
        format!("{:.2} % of the largest force", e.rms_percent_of_max)
    } else {
        "no percentage: every labelled force is 0 N".into()
    };
    let correlation = if e.correlation.is_finite() {
        format!("correlation {:.3}", e.correlation)
    } else {
        "no correlation: the forces do not vary".into()
    };
    println!("RMS error {:.3} N ({percent}), {correlation}, mean absolute error {:.3} N", e.rms, e.mean_absolute);
    let with_std: Vec<(f64, f64)> =
        estimates.iter().filter_map(|(t, f)| f.std.map(|s| ((f.newtons - t).abs(), s))).collect();
    if !with_std.is_empty() {
        let within = with_std.iter().filter(|(error, std)| *error <= 2.0 * std).count();
        println!(
            "the true force lies within twice the force's standard deviation for {:.1} % of the {} forces",
            100.0 * within as f64 / with_std.len() as f64,
            with_std.len()
        );
    }
}

/// Each sample's row (where, force, what was found) as CSV at `out`, in the spec's unit.
fn write_evaluated(out: &Path, spec: &SensorSpec, results: &[Evaluated]) -> Result<()> {
    let per_unit = 1.0 / spec.length_unit.metres();
    let u = spec.length_unit.symbol();
    let mut csv = format!("sample,x_{u},y_{u},force_n,found,found_x_{u},found_y_{u},predicted_n,std_n,saturated\n");
    for (k, Evaluated { at, force: truth, found }) in results.iter().enumerate() {
        let blank = |v: f64| if v.is_finite() { format!("{v}") } else { String::new() };
        let centre = found.as_ref().map_or([f64::NAN; 2], |f| f.centre);
        let force = found.as_ref().and_then(|f| f.force);
        csv += &format!(
            "{},{},{},{truth},{},{},{},{},{},{}\n",
            k + 1,
            blank(at[0] * per_unit),
            blank(at[1] * per_unit),
            u8::from(found.is_some()),
            blank(centre[0] * per_unit),
            blank(centre[1] * per_unit),
            force.map_or(String::new(), |f| blank(f.newtons)),
            force.and_then(|f| f.std).map_or(String::new(), blank),
            force.map_or(String::new(), |f| u8::from(f.saturated).to_string()),
        );
    }
    let mut staged = crate::outputs::Staged::default();
    std::fs::write(staged.path(out), csv).with_context(|| format!("writing {}", out.display()))?;
    staged.commit()?;
    println!("wrote {}", out.display());
    Ok(())
}

/// What the chain found for a labelled sample: its centre (the fitted press's, m) and force.
struct Found {
    centre: [f64; 2],
    force: Option<ForceEstimate>,
}

/// The frames without a press (those of `--reference`, then the samples' rows of 0 N, in
/// order) and the pressed ones, of a samples file of raw frames; each of `spec`'s protocol's
/// length, else refused naming its file.
fn references(
    spec: &SensorSpec,
    path: Option<&Path>,
    samples: &Path,
    frames: Vec<LabelledFrame>,
) -> Result<(Vec<Vec<f64>>, Vec<LabelledFrame>)> {
    let measurements = spec.protocol()?.measurements().len();
    if let Some(frame) = frames.first().filter(|f| f.frame.len() != measurements) {
        bail!(
            "{}: each sample holds {} values, and the sensor's protocol has {measurements} measurements",
            samples.display(),
            frame.frame.len()
        );
    }
    let mut references = match path {
        Some(path) => {
            let table = eitskin_io::read_frames(path, &FrameSelect::default())?;
            // The samples' frames are real: which part of a complex value they are is not ours
            // to guess.
            if table.imaginary.is_some() {
                bail!(
                    "--reference {}: holds complex values, and the samples' frames are real: give the frames at rest as the same real values the samples hold (magnitudes, or real parts)",
                    path.display()
                );
            }
            if let Some(k) = table.frames.iter().position(|f| f.len() != measurements) {
                bail!(
                    "--reference {}: frame {} holds {} values, and the sensor's protocol has {measurements} measurements",
                    path.display(),
                    k + 1,
                    table.frames[k].len()
                );
            }
            table.frames
        }
        None => Vec::new(),
    };
    let (rest, pressed) = split_references(frames);
    if pressed.is_empty() {
        bail!("{}: every sample is at 0 N (the sheet at rest): there is no press to read", samples.display());
    }
    check_scale(&references, &rest, &pressed, path, samples)?;
    references.extend(rest);
    if references.is_empty() {
        bail!(
            "{} holds raw frames but none without a press (force 0): give the frames at rest with --reference FILE",
            samples.display()
        );
    }
    Ok((references, pressed))
}

/// Refuses frames at rest from two places (`--reference`'s `given`, the samples' rows at 0 N
/// `rest`) whose values are typically
/// ([`typical_ratio_of_frames`](eitskin::inverse::typical_ratio_of_frames)) beyond
/// [`SCALE_LIMIT`](eitskin::inverse::SCALE_LIMIT) times apart either way, and pressed frames so
/// far from all of them: another sensor, unit or gain, which no curve can read (and which made
/// calibration search every frame for touches that are not there).
fn check_scale(
    given: &[Vec<f64>],
    rest: &[Vec<f64>],
    pressed: &[LabelledFrame],
    path: Option<&Path>,
    samples: &Path,
) -> Result<()> {
    use eitskin::inverse::{mean_frame, plausible_ratio, typical_ratio_of_frames};
    let refuse = |what: &str, ratio: f64, against: String| {
        anyhow::anyhow!(
            "{}: {what} values are typically {ratio:.3} times those of {against} (the median over frames and channels): a press changes them by percents; are the two from the same sensor, unit and gain?",
            samples.display()
        )
    };
    let given_name = || path.map_or_else(String::new, |p| format!("--reference {}", p.display()));
    if !given.is_empty() && !rest.is_empty() {
        let ratio = typical_ratio_of_frames(rest.iter().map(Vec::as_slice), &mean_frame(given));
        if let Some(ratio) = ratio.filter(|r| !plausible_ratio(*r)) {
            return Err(refuse("the 0 N frames'", ratio, given_name()));
        }
    }
    let (reference, against) = match given.is_empty() {
        true => (mean_frame(rest), "its 0 N frames".to_owned()),
        false => (mean_frame(given), given_name()),
    };
    let ratio = typical_ratio_of_frames(pressed.iter().map(|p| p.frame.as_slice()), &reference);
    if let Some(ratio) = ratio.filter(|r| !plausible_ratio(*r)) {
        return Err(refuse("the pressed frames'", ratio, against));
    }
    Ok(())
}

/// Refuses pressed samples whose labels leave an area of `array` with presses at fewer than 3
/// distinct forces, before any frame is imaged: its curve could not be fitted, whatever the
/// frames hold (calibration spent a minute reading every frame first).
fn check_areas(array: &PseudoArray, pressed: &[LabelledFrame], samples: &Path) -> Result<()> {
    for area in 0..array.area_count() {
        let mut forces: Vec<f64> = pressed
            .iter()
            .filter(|p| array.unit_at(p.position).is_some_and(|u| array.area_of(u) == area))
            .map(|p| p.force)
            .collect();
        forces.sort_by(f64::total_cmp);
        forces.dedup();
        if forces.len() < 3 {
            let units: Vec<String> = array.units_in_area(area).iter().map(|u| (u + 1).to_string()).collect();
            bail!(
                "{}: area {} (units {}) has presses at {} distinct force(s) by the labels; its curve needs 3 or more: press there too, or fit one curve for the sheet (--grid 1)",
                samples.display(),
                area + 1,
                units.join(", "),
                forces.len()
            );
        }
    }
    Ok(())
}

/// Says on stderr which samples' presses were not found (no touch within
/// [`MATCH_DISTANCE`] of the label), rows counted among the pressed ones from 1.
fn report_missed<T>(samples: &Path, pressed: &[LabelledFrame], found: &[Option<T>]) {
    let missed: Vec<String> =
        found.iter().enumerate().filter(|(_, t)| t.is_none()).map(|(k, _)| (k + 1).to_string()).collect();
    if missed.is_empty() {
        return;
    }
    let forces = pressed.iter().zip(found).filter(|(_, t)| t.is_none()).map(|(p, _)| p.force);
    let weakest = forces.clone().fold(f64::INFINITY, f64::min);
    let strongest = forces.fold(0.0, f64::max);
    let shown = missed.iter().take(20).cloned().collect::<Vec<_>>().join(", ");
    let more = if missed.len() > 20 { ", …" } else { "" };
    let [weakest, strongest] = [weakest, strongest].map(crate::plot::number);
    eprintln!(
        "{}: {} of {} presses not found within {:.0} mm of their label ({weakest}–{strongest} N; pressed samples {shown}{more})",
        samples.display(),
        missed.len(),
        pressed.len(),
        MATCH_DISTANCE * 1e3,
    );
}

/// A samples file's rows, all peaks or all raw frames.
enum Labelled {
    /// Each row's area, force and peak (S/m).
    Peaks(Vec<Sample>),
    /// Each row's press (its unit's centre for a `unit` column) and frame.
    Frames(Vec<LabelledFrame>),
}

impl Labelled {
    /// The rows of `path` placed on `array`; a unit or point off the array is an error naming the row.
    fn of(spec: &SensorSpec, array: &PseudoArray, path: &Path, rows: Vec<SampleRow>) -> Result<Labelled> {
        let per_unit = 1.0 / spec.length_unit.metres();
        let u = spec.length_unit.symbol();
        let mut peaks = Vec::new();
        let mut frames = Vec::new();
        for (k, SampleRow { location, force, measured, .. }) in rows.into_iter().enumerate() {
            let position = match location {
                Location::Unit(unit) if unit < array.unit_count() => array.unit_centre(unit),
                Location::Unit(unit) => {
                    bail!(
                        "{}: sample {}: unit {} does not exist ({} units)",
                        path.display(),
                        k + 1,
                        unit + 1,
                        array.unit_count()
                    )
                }
                Location::Point(p) => p,
            };
            let Some(force) = force else {
                bail!("{}: the samples have no `force` column: a calibration needs each press's force", path.display())
            };
            let Some(unit) = array.unit_at(position) else {
                let [x, y] = position.map(|c| Quantity::written(c * per_unit, u));
                bail!("{}: sample {}: ({x}, {y}) is off the sheet", path.display(), k + 1);
            };
            match measured {
                Measured::Peak(peak) => {
                    peaks.push(Sample { area: array.area_of(unit), force, peak, std: None, place: Some(position) })
                }
                Measured::Frame(frame) => frames.push(LabelledFrame { position, force, frame }),
            }
        }
        match (peaks.is_empty(), frames.is_empty()) {
            (false, false) => {
                bail!("{}: some samples hold a peak and others a raw frame; give one kind", path.display())
            }
            (true, false) => Ok(Labelled::Frames(frames)),
            _ => Ok(Labelled::Peaks(peaks)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_strength_has_a_flag_that_parses_back() {
        for strength in Strength::ALL {
            assert_eq!(parse_strength(&strength_flag(strength)), Ok(strength));
        }
        assert_eq!(strength_flag(Strength::ContrastPeakAndVolume), "contrast-map-peak-and-volume");
        assert!(parse_strength("volume").unwrap_err().contains("fitted-drop, sized-drop, peak-sensitivity"));
        assert_eq!(parse_strength_choice("auto"), Ok(StrengthChoice::Auto));
        assert!(parse_strength_choice("volume").unwrap_err().starts_with("expected auto, or one of peak"));
    }
}
