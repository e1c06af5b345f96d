//! `eitskin calibrate` and `eitskin evaluate`: fit a per-area calibration from recorded
//! samples, and measure a calibration's force error on other samples.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use eitskin::calibration::{force_errors, Calibration, Sample, Strength};
use eitskin::pseudo_array::PseudoArray;
use eitskin::touch::detect;
use eitskin::{ReconstructorParams, SensorSpec, TouchParams};
use eitskin_io::{Location, Measured, SampleRow};

use crate::load;

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
    /// Units per side of the pseudo-array.
    #[arg(long, default_value_t = 5)]
    grid: usize,
    /// Reference (no-touch) frame, needed when the samples hold raw frames.
    #[arg(long)]
    reference: Option<PathBuf>,
    /// What the curves take as the touch's strength: the image's `peak`, or the `fitted-drop`
    /// of the press fitted to Δv (needs raw frames).
    #[arg(long, value_enum, default_value_t = StrengthArg::Peak)]
    strength: StrengthArg,
}

/// `--strength` of `eitskin calibrate`.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum StrengthArg {
    /// The peak of the touch's image (S/m), as the paper.
    Peak,
    /// The conductivity drop of the press fitted to Δv (fraction of the background).
    FittedDrop,
}

/// Flags of `eitskin evaluate`.
#[derive(Debug, clap::Args)]
pub struct EvaluateArgs {
    /// Sensor spec file (TOML); default: the paper's sensor.
    spec: Option<PathBuf>,
    /// The calibration (JSON, from `eitskin calibrate`).
    #[arg(long)]
    calibration: PathBuf,
    /// Samples (CSV), as for `calibrate`.
    #[arg(long)]
    samples: PathBuf,
    /// Reference (no-touch) frame, needed when the samples hold raw frames.
    #[arg(long)]
    reference: Option<PathBuf>,
}

/// Runs `eitskin calibrate`.
pub fn calibrate(args: CalibrateArgs) -> Result<()> {
    let spec = load::spec(args.spec.as_deref())?;
    let array = PseudoArray::by_symmetry(&spec.outline, &spec.electrode_positions()?, [args.grid; 2])?;
    let strength = match args.strength {
        StrengthArg::Peak => Strength::Peak,
        StrengthArg::FittedDrop => Strength::FittedDrop,
    };
    let samples = samples(&spec, &array, &args.samples, args.reference.as_deref(), strength)?;
    let calibration = Calibration::fit_strength(&samples, array.area_count(), strength)?;
    std::fs::write(&args.out, eitskin_io::calibration_to_json(&spec, &array, &calibration)?)
        .with_context(|| format!("writing {}", args.out.display()))?;
    let (name, unit) = match strength {
        Strength::Peak => ("peak", "[S/m]"),
        Strength::FittedDrop => ("drop", "[1]"),
    };
    println!("{} samples, {} areas; {name}(F) = a·e^(−F/b) + c:", samples.len(), array.area_count());
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

/// Runs `eitskin evaluate`.
pub fn evaluate(args: EvaluateArgs) -> Result<()> {
    let spec = load::spec(args.spec.as_deref())?;
    let (array, calibration) = eitskin_io::read_calibration(&args.calibration, &spec)?;
    let samples = samples(&spec, &array, &args.samples, args.reference.as_deref(), calibration.strength)?;
    let mut saturated = 0;
    let mut predicted = Vec::with_capacity(samples.len());
    for s in &samples {
        let f = calibration.force(s.area, s.peak)?;
        saturated += usize::from(f.saturated);
        predicted.push(f.newtons);
    }
    let truth: Vec<f64> = samples.iter().map(|s| s.force).collect();
    let e = force_errors(&truth, &predicted);
    println!("{} samples ({saturated} saturated)", e.count);
    println!(
        "RMS error {:.3} N ({:.2} % of the largest force), correlation {:.3}, mean absolute error {:.3} N",
        e.rms, e.rms_percent_of_max, e.correlation, e.mean_absolute
    );
    Ok(())
}

/// Each row as an area, force and strength: frames are imaged against the reference first (and
/// for the fitted drop, a press is fitted from the strongest touch; none found is a drop of 0).
fn samples(
    spec: &SensorSpec,
    array: &PseudoArray,
    path: &Path,
    reference: Option<&Path>,
    strength: Strength,
) -> Result<Vec<Sample>> {
    let rows = eitskin_io::read_samples(path, spec.length_unit.metres())?;
    let needs_frames = rows.iter().any(|r| matches!(r.measured, Measured::Frame(_)));
    if strength == Strength::FittedDrop && rows.iter().any(|r| matches!(r.measured, Measured::Peak(_))) {
        bail!("{}: a fitted-drop calibration needs each sample's raw frame, not its peak", path.display());
    }
    let press_model = match strength {
        Strength::FittedDrop => Some(load::press_model(spec)?),
        Strength::Peak => None,
    };
    let imaging = if needs_frames {
        let Some(reference) = reference else { bail!("{} holds raw frames: give --reference FILE", path.display()) };
        let v_ref = eitskin_io::read_frame(reference)?;
        let recon = load::reconstructor(spec, &ReconstructorParams::default(), true)?;
        Some((v_ref, recon))
    } else {
        None
    };
    rows.iter()
        .enumerate()
        .map(|(k, row)| {
            let SampleRow { location, force, measured } = row;
            let unit = match *location {
                Location::Unit(u) if u < array.unit_count() => u,
                Location::Unit(u) => {
                    bail!("sample {}: unit {} does not exist ({} units)", k + 1, u + 1, array.unit_count())
                }
                Location::Point(p) => {
                    array.unit_at(p).with_context(|| format!("sample {}: {p:?} m is off the sheet", k + 1))?
                }
            };
            let peak = match (measured, &imaging) {
                (Measured::Peak(p), _) => *p,
                (Measured::Frame(v), Some((v_ref, recon))) => {
                    let image = recon.image(v_ref, v).with_context(|| format!("sample {}", k + 1))?;
                    let touch = detect(&image, &TouchParams::default()).first().copied();
                    match (&press_model, touch) {
                        (None, touch) => touch.map_or(0.0, |t| t.peak),
                        (Some(_), None) => 0.0,
                        (Some(model), Some(t)) => {
                            let dv: Vec<f64> = v.iter().zip(v_ref).map(|(v, r)| v - r).collect();
                            model
                                .fit(&dv, t.centre)
                                .with_context(|| format!("sample {}", k + 1))?
                                .map_or(0.0, |p| p.drop)
                        }
                    }
                }
                (Measured::Frame(_), None) => bail!("sample {} holds a raw frame: give --reference FILE", k + 1),
            };
            Ok(Sample { area: array.area_of(unit), force: *force, peak })
        })
        .collect()
}
