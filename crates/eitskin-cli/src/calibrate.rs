//! `eitskin calibrate` and `eitskin evaluate`: fit a per-area calibration from recorded
//! samples, and measure a calibration's force error on other samples.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use eitskin::calibration::{force_errors, Calibration, ForceEstimate, Sample};
use eitskin::chain::LabelledFrame;
use eitskin::pseudo_array::PseudoArray;
use eitskin::spec::Quantity;
use eitskin::strength::Strength;
use eitskin::{ReconstructorParams, SensorSpec, TouchParams};
use eitskin_io::{CalibrationFile, Imaging, Location, Measured, SampleRow};

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
    #[arg(long)]
    out: PathBuf,
    /// Units per side of the pseudo-array, 1–100 (the paper's 5; 1: one curve for the sheet).
    #[arg(long, default_value_t = 5, value_parser = ranges::whole("a number of units per side", 1, 100))]
    grid: usize,
    /// Reference (no-touch) frame, needed when the samples hold raw frames.
    #[arg(long)]
    reference: Option<PathBuf>,
    /// What the curves take as the touch's strength: `peak` (the image's, the paper's),
    /// `fitted-drop` (of the press fitted to Δv), `peak-sensitivity` (peak ÷ the forward model's
    /// sensitivity there), or the forward model's contrast map read from the peak, the volume or
    /// both: `contrast-map-peak`, `contrast-map-volume`, `contrast-map-peak-and-volume`. All
    /// but `peak` need raw frames.
    #[arg(long, value_parser = parse_strength, default_value = "peak")]
    strength: Strength,
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
    /// Reference (no-touch) frame, needed when the samples hold raw frames.
    #[arg(long)]
    reference: Option<PathBuf>,
}

/// Runs `eitskin calibrate`.
pub fn calibrate(args: CalibrateArgs) -> Result<()> {
    let mut read = vec![("--samples", args.samples.as_path())];
    read.extend(args.reference.as_deref().map(|p| ("--reference", p)));
    read.extend(args.spec.as_deref().map(|p| ("the spec", p)));
    outputs::check(&[("--out", &args.out)], &read)?;
    let spec = load::spec(args.spec.as_deref())?;
    let array = PseudoArray::by_symmetry(&spec.outline, &spec.electrode_positions()?, [args.grid; 2])?;
    let strength = args.strength;
    let rows = eitskin_io::read_samples(&args.samples, spec.length_unit.metres())?;
    let samples = match Labelled::of(&spec, &array, &args.samples, rows)? {
        Labelled::Peaks(peaks) if strength == Strength::Peak => peaks,
        Labelled::Peaks(_) => {
            bail!(
                "{}: a \"{strength}\" calibration needs each sample's raw frame, not its peak",
                args.samples.display()
            )
        }
        Labelled::Frames(frames) => {
            let reference = reference(args.reference.as_deref(), &args.samples)?;
            let mut chain = load::chain(&spec, strength, false)?;
            let samples = chain.samples(&reference, &array, &frames)?;
            let missed = samples.iter().filter(|s| s.is_none()).count();
            if missed > 0 {
                eprintln!("{missed} of {} frames show no touch and are left out", samples.len());
            }
            samples.into_iter().flatten().collect()
        }
    };
    let calibration = Calibration::fit_strength(&samples, array.area_count(), strength)?;
    // The chain images as `load::chain` does: the file records it, and `run` then images so.
    let params = ReconstructorParams::default();
    let imaging = Imaging { hyperparameter: params.hyperparameter, normalized: params.normalized };
    std::fs::write(&args.out, eitskin_io::calibration_file_to_json(&spec, &array, &calibration, imaging)?)
        .with_context(|| format!("writing {}", args.out.display()))?;
    let unit = format!("[{}]", strength.unit());
    println!("{} samples, {} areas; {strength}(F) = a·e^(−F/b) + c:", samples.len(), array.area_count());
    println!(
        "{:>5} {:>12} {:>10} {:>12} {:>7} {:>10} {:>8}",
        "area",
        format!("a {unit}"),
        "b [N]",
        format!("c {unit}"),
        "R²",
        "F [N]",
        "samples"
    );
    for (k, c) in calibration.curves.iter().enumerate() {
        println!(
            "{:>5} {:>12.4e} {:>10.3} {:>12.4e} {:>7.3} {:>4.0}–{:<5.0} {:>8}",
            k + 1,
            c.a,
            c.b,
            c.c,
            c.r_squared,
            c.force_range[0],
            c.force_range[1],
            c.samples
        );
    }
    println!("wrote {}", args.out.display());
    Ok(())
}

/// Runs `eitskin evaluate`: with raw frames, each through the same chain as `eitskin run`
/// (the strongest touch's force, its unit where the chain places it); with peaks, at the
/// sample's own unit.
pub fn evaluate(args: EvaluateArgs) -> Result<()> {
    let spec = load::spec(args.spec.as_deref())?;
    let Some(path) = &args.calibration else {
        let model = args.model.as_deref().context("give --calibration or --model")?;
        return crate::learn::evaluate_model(&spec, model, &args.samples, args.reference.as_deref());
    };
    let CalibrationFile { array, calibration, imaging } = eitskin_io::read_calibration_file(path, &spec)?;
    let rows = eitskin_io::read_samples(&args.samples, spec.length_unit.metres())?;
    let (mut truth, mut predicted, mut saturated, mut missed) = (Vec::new(), Vec::new(), 0, 0);
    let mut add = |force: f64, estimate: Option<ForceEstimate>| match estimate {
        Some(f) => {
            saturated += usize::from(f.saturated);
            truth.push(force);
            predicted.push(f.newtons);
        }
        None => missed += 1,
    };
    match Labelled::of(&spec, &array, &args.samples, rows)? {
        Labelled::Peaks(peaks) if calibration.strength == Strength::Peak => {
            for s in &peaks {
                add(s.force, Some(calibration.force(s.area, s.peak)?));
            }
        }
        Labelled::Peaks(_) => bail!(
            "{}: the calibration reads the \"{}\", which needs each sample's raw frame, not its peak",
            args.samples.display(),
            calibration.strength
        ),
        Labelled::Frames(frames) => {
            let reference = reference(args.reference.as_deref(), &args.samples)?;
            let params = ReconstructorParams {
                hyperparameter: imaging.hyperparameter,
                normalized: imaging.normalized,
                ..ReconstructorParams::default()
            };
            let strength = calibration.strength;
            let mut chain = load::chain_with(&spec, &params, TouchParams::default(), strength, false)?
                .with_calibration(array, calibration)?;
            for (k, f) in frames.iter().enumerate() {
                let touches = chain.process(&reference, &f.frame).with_context(|| format!("sample {}", k + 1))?;
                add(f.force, touches.first().and_then(|t| t.force));
            }
        }
    }
    let e = force_errors(&truth, &predicted);
    println!("{} samples ({saturated} saturated, {missed} without a touch on the pseudo-array, left out)", e.count);
    println!(
        "RMS error {:.3} N ({:.2} % of the largest force), correlation {:.3}, mean absolute error {:.3} N",
        e.rms, e.rms_percent_of_max, e.correlation, e.mean_absolute
    );
    Ok(())
}

/// The reference frame of a samples file of raw frames.
fn reference(path: Option<&Path>, samples: &Path) -> Result<Vec<f64>> {
    let Some(path) = path else { bail!("{} holds raw frames: give --reference FILE", samples.display()) };
    Ok(eitskin_io::read_frame(path)?)
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
                Measured::Peak(peak) => peaks.push(Sample { area: array.area_of(unit), force, peak }),
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
        assert!(parse_strength("volume").unwrap_err().contains("fitted-drop, peak-sensitivity"));
    }
}
