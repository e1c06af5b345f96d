//! Calibration files (JSON, versioned): the pseudo-array's areas and one curve per area, tied
//! to the sensor they were made for.
//!
//! ```json
//! { "format": "eitskin-calibration", "version": 6, "spec_key": "…", "strength": "peak",
//!   "hyperparameter": 0.1, "normalised": false, "grid": [5, 5], "areas": [6, 5, 3, …], "curves": [{ "a": …, "b": …, "c": …,
//!   "r_squared": …, "force_range": [0, 15], "samples": 240, "spread": 0.004 }, …] }
//! ```
//! `areas` gives each unit's area, counting both from 1, units row-major from the bottom-left;
//! curve k is area k + 1, s(F) = a·e^(−F/b) + c with F in N and the strength s named as in
//! [`Strength::name`]: the image's `"peak"` in S/m, the `"fitted drop"` of the press fitted to
//! Δv (a fraction of the background), or one of the contrast map's readings. Version 1 files (no
//! `strength`) are read as peak. A strength depends on how the images were made, so version 4
//! records it ([`Imaging`]): the hyperparameter λ and whether differences were normalised
//! (Δv/v_ref); older files were all made with the paper's λ = 0.1 and absolute differences, and
//! are read so. Version 5 adds each curve's `spread`: the standard deviation of the strength
//! about the curve that its samples' own noise does not explain, added to each reading's when a
//! force's standard deviation is given (read as 0 from older files). Version 6 adds a curve's
//! `shape` k where it is a·(1 + F/(k·b))^(−k) + c (k > 0, b > 0) instead of the exponential;
//! a curve without it is the exponential. A file made for another sensor (another `spec_key`)
//! is refused.
//!
//! The key ([`spec_key`]) is a SHA-256 of the sensor's canonical values, serialised as JSON: a
//! key version; thickness and background conductivity; the outline's kind and lengths; the
//! electrode model, width, contact impedance and each electrode's centre (m); the protocol's
//! stimulation currents and measurement weights. The mesh density and the spec's length unit
//! are not part of it, nor how the electrodes were placed (only where they are, in electrode
//! order: numbering the same electrodes clockwise is another sensor, as its frames are). Files of
//! versions 1 and 2 carry an older key (the spec file's TOML and the protocol's debug text),
//! which is still accepted for them.

use std::path::Path;

use eitskin::calibration::{Calibration, Curve, Strength, MAX_DECAY_PER_SPAN, MAX_FORCE};
use eitskin::pseudo_array::PseudoArray;
use eitskin::{Outline, SensorSpec};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::{Error, Quoted};

const FORMAT: &str = "eitskin-calibration";
const VERSION: u32 = 6;
/// The version of the canonical sensor values hashed into the key.
const KEY_VERSION: u32 = 1;

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct CalibrationJson {
    format: String,
    version: u32,
    spec_key: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    strength: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    hyperparameter: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    normalised: Option<bool>,
    grid: [usize; 2],
    areas: Vec<usize>,
    curves: Vec<CurveJson>,
}

#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct CurveJson {
    a: f64,
    b: f64,
    c: f64,
    r_squared: f64,
    force_range: [f64; 2],
    samples: usize,
    /// The strength's spread about the curve its samples' noise does not explain (version 5;
    /// 0 before).
    #[serde(default)]
    spread: f64,
    /// Whether the curve is the fallback's, not a converged fit (version 5; false before).
    #[serde(default)]
    fallback: bool,
    /// The shape k of a·(1 + F/(k·b))^(−k) + c (version 6); absent for a·e^(−F/b) + c.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    shape: Option<f64>,
}

impl From<&Curve> for CurveJson {
    fn from(c: &Curve) -> CurveJson {
        let Curve { a, b, c, r_squared, force_range, samples, spread, fallback, shape } = *c;
        CurveJson { a, b, c, r_squared, force_range, samples, spread, fallback, shape }
    }
}

impl From<&CurveJson> for Curve {
    fn from(c: &CurveJson) -> Curve {
        let CurveJson { a, b, c, r_squared, force_range, samples, spread, fallback, shape } = *c;
        Curve { a, b, c, r_squared, force_range, samples, spread, fallback, shape }
    }
}

/// What makes a curve s(F) = a·e^(−F/b) + c unusable, if anything: a value that is not a
/// number, an e-folding force b of 0 (it divides by zero; a negative b, a curve that
/// steepens, is a fit like any other), a flat curve (a = 0
/// gives every strength the same force), a force range that is not 0 ≤ F₀ < F₁.
fn curve_problem(c: &CurveJson, version: u32) -> Option<String> {
    let [lo, hi] = c.force_range;
    if let Some(problem) = curve_fields_problem(c, version) {
        Some(problem)
    } else if !(c.a.is_finite() && c.c.is_finite()) {
        Some(format!("`a` = {} and `c` = {} must be finite numbers", c.a, c.c))
    } else if !(c.b.is_finite() && c.b != 0.0) {
        Some(format!("`b` = {} N must be a force other than 0 (the e-folding force of a·e^(−F/b) + c)", c.b))
    } else if c.a == 0.0 {
        Some("`a` = 0: the curve is flat, so no strength tells one force from another".into())
    } else if !(lo.is_finite() && hi.is_finite() && 0.0 <= lo && lo < hi && hi <= MAX_FORCE) {
        Some(format!(
            "`force_range` = [{lo}, {hi}] N must run from a force ≥ 0 to a larger one, at most {MAX_FORCE:e} N",
            lo = Quoted(lo),
            hi = Quoted(hi)
        ))
    } else if c.b.abs() > MAX_DECAY_PER_SPAN * (hi - lo) {
        Some(format!(
            "`b` = {:?} N is past {MAX_DECAY_PER_SPAN:e} times the force range, the most a fit gives (the curve is flat there)",
            c.b
        ))
    } else if let Some(k) = c.shape.filter(|k| !(k.is_finite() && *k > 0.0 && c.b > 0.0)) {
        Some(format!(
            "`shape` = {k} with `b` = {} N: a curve a·(1 + F/(k·b))^(−k) + c needs k > 0 and b > 0 (omit `shape` for a·e^(−F/b) + c)",
            c.b
        ))
    } else if !(c.spread.is_finite() && c.spread >= 0.0) {
        Some(format!("`spread` = {} must be a finite number ≥ 0 (the strength's spread about the curve)", c.spread))
    } else {
        strength_problem(c)
    }
}

/// What a curve's bookkeeping fields hold that no fit gives: a `shape` before version 6, an
/// R² over 1. (A curve written by hand, from a law, has no samples: `samples` may be 0.)
fn curve_fields_problem(c: &CurveJson, version: u32) -> Option<String> {
    if c.shape.is_some() && version < 6 {
        Some(format!("has a `shape`, which a file of version {version} cannot hold (version 6 or later)"))
    } else if c.r_squared > 1.0 {
        Some(format!("`r_squared` = {:?} is over 1", c.r_squared))
    } else {
        None
    }
}

/// Whether the curve's strength changes over its force range as numbers can hold it, and by
/// more than its spread: else no strength tells one force from another.
fn strength_problem(c: &CurveJson) -> Option<String> {
    let curve = Curve::from(c);
    let [lo, hi] = c.force_range;
    let rise = (curve.peak(hi) - curve.peak(lo)).abs();
    if !(rise.is_finite() && rise > 0.0) {
        Some(format!(
            "the strength does not change between {lo} and {hi} N in floating point (`a` = {:?}, `b` = {:?} N, `c` = {:?}): no strength tells one force from another",
            c.a, c.b, c.c
        ))
    } else if c.spread > rise {
        Some(format!(
            "`spread` = {:?} is more than the curve's whole rise over its range ({rise:e}): it reads no force",
            c.spread
        ))
    } else {
        None
    }
}

/// How the images a calibration was fitted on were made; `Default` is the paper's (and that of
/// every file before version 4): λ = 0.1, absolute differences.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Imaging {
    /// The hyperparameter λ (dimensionless).
    pub hyperparameter: f64,
    /// Whether differences were normalised (Δv/v_ref).
    pub normalised: bool,
}

impl Default for Imaging {
    fn default() -> Self {
        Imaging { hyperparameter: 0.1, normalised: false }
    }
}

/// A calibration file's contents: the pseudo-array, the curves and how the images were made.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationFile {
    /// The pseudo-array, over the spec's outline.
    pub array: PseudoArray,
    /// The curves, one per area, and the strength they read.
    pub calibration: Calibration,
    /// The λ and normalisation the curves were fitted with.
    pub imaging: Imaging,
}

/// The canonical values of a sensor, hashed into [`spec_key`].
#[derive(Serialize)]
struct SensorValues<'a> {
    key_version: u32,
    thickness_m: f64,
    conductivity_s_per_m: f64,
    outline: &'static str,
    outline_values_m: Vec<f64>,
    point_electrodes: bool,
    electrode_width_m: f64,
    contact_impedance_ohm_m2: f64,
    electrode_centres_m: Vec<[f64; 2]>,
    stimulations: &'a [Vec<f64>],
    measurements: Vec<(usize, &'a [f64])>,
}

/// A hex SHA-256 of the sensor a calibration depends on: its canonical values (see the module doc).
pub fn spec_key(spec: &SensorSpec) -> Result<String, Error> {
    let protocol = spec.protocol()?;
    let (outline, outline_values_m) = match &spec.outline {
        Outline::Rectangle { width, height } => ("rectangle", vec![*width, *height]),
        Outline::Circle { radius } => ("circle", vec![*radius]),
        Outline::Polygon { points } => ("polygon", points.iter().flatten().copied().collect()),
    };
    let values = SensorValues {
        key_version: KEY_VERSION,
        thickness_m: spec.thickness,
        conductivity_s_per_m: spec.conductivity,
        outline,
        outline_values_m,
        point_electrodes: spec.electrodes.point,
        electrode_width_m: if spec.electrodes.point { 0.0 } else { spec.electrodes.width },
        contact_impedance_ohm_m2: if spec.electrodes.point { 0.0 } else { spec.electrodes.contact_impedance },
        // Derived by arithmetic, so rounded to a nanometre: the same electrodes placed another way match.
        electrode_centres_m: spec
            .electrode_positions()?
            .iter()
            .map(|e| spec.outline.point_at(e.centre).map(|c| (c * 1e9).round() / 1e9))
            .collect(),
        stimulations: protocol.stimulations(),
        measurements: protocol.measurements().iter().map(|m| (m.stimulation, m.weights.as_slice())).collect(),
    };
    let json = serde_json::to_string(&values).map_err(|e| Error::Json { path: None, message: e.to_string() })?;
    Ok(hex(&Sha256::digest(json)))
}

/// The key of files of versions 1 and 2: a SHA-256 of the spec file's TOML (mesh settings left
/// at their defaults) and the protocol's text as `{:?}` printed it then, written out here so
/// that a change to the protocol type cannot move it.
fn legacy_spec_key(spec: &SensorSpec) -> Result<String, Error> {
    let protocol = spec.protocol()?;
    let mut geometry = spec.clone();
    geometry.mesh = eitskin::MeshParams::default();
    // Where the sensor is mounted changes nothing it measures (and postdates these versions).
    geometry.mount = None;
    let measurements: Vec<String> = protocol
        .measurements()
        .iter()
        .map(|m| format!("Measurement {{ stimulation: {}, weights: {:?} }}", m.stimulation, m.weights))
        .collect();
    let text = format!(
        "Protocol {{ description: {:?}, electrode_count: {}, stimulations: {:?}, measurements: [{}] }}",
        protocol.description(),
        protocol.electrode_count(),
        protocol.stimulations(),
        measurements.join(", ")
    );
    // Versions 1 and 2 predate `electrodes.numbering`: the default's line was not printed then.
    let toml = crate::spec_to_toml(&geometry).replace("numbering = \"counter-clockwise\"\n", "");
    let mut hash = Sha256::new();
    hash.update(toml);
    hash.update(text);
    Ok(hex(&hash.finalize()))
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// The calibration as JSON, for `spec` with its pseudo-array, fitted on images of the paper's
/// λ = 0.1 and absolute differences (else see [`calibration_file_to_json`]).
pub fn calibration_to_json(spec: &SensorSpec, array: &PseudoArray, calibration: &Calibration) -> Result<String, Error> {
    calibration_file_to_json(spec, array, calibration, Imaging::default())
}

/// The calibration as JSON, for `spec` with its pseudo-array, fitted on images made as `imaging` says.
pub fn calibration_file_to_json(
    spec: &SensorSpec,
    array: &PseudoArray,
    calibration: &Calibration,
    imaging: Imaging,
) -> Result<String, Error> {
    let file = CalibrationJson {
        format: FORMAT.into(),
        version: VERSION,
        spec_key: spec_key(spec)?,
        strength: Some(calibration.strength.name().into()),
        hyperparameter: Some(imaging.hyperparameter),
        normalised: Some(imaging.normalised),
        grid: array.grid(),
        areas: (0..array.unit_count()).map(|u| array.area_of(u) + 1).collect(),
        curves: calibration.curves.iter().map(CurveJson::from).collect(),
    };
    serde_json::to_string_pretty(&file).map_err(|e| Error::Json { path: None, message: e.to_string() })
}

/// Reads a calibration made for `spec`: its pseudo-array (over the spec's outline) and curves.
pub fn read_calibration(path: &Path, spec: &SensorSpec) -> Result<(PseudoArray, Calibration), Error> {
    read_calibration_file(path, spec).map(|f| (f.array, f.calibration))
}

/// Parses calibration JSON made for `spec`.
pub fn parse_calibration(text: &str, spec: &SensorSpec) -> Result<(PseudoArray, Calibration), Error> {
    parse_calibration_file(text, spec).map(|f| (f.array, f.calibration))
}

/// Reads a calibration made for `spec`, with how its images were made.
pub fn read_calibration_file(path: &Path, spec: &SensorSpec) -> Result<CalibrationFile, Error> {
    parse_calibration_file(&crate::read_text(path)?, spec).map_err(|e| e.in_file(path))
}

/// Parses calibration JSON made for `spec`, with how its images were made.
pub fn parse_calibration_file(text: &str, spec: &SensorSpec) -> Result<CalibrationFile, Error> {
    let file: CalibrationJson = crate::parse_json_file(text, FORMAT)?;
    let refuse = |key: &'static str, reason: String| Err(Error::Key { path: None, key, reason });
    if !(1..=VERSION).contains(&file.version) {
        return refuse("version", format!("is {}, but this eitskin reads versions 1 to {VERSION}", file.version));
    }
    let strength = match file.strength.as_deref() {
        None => Strength::Peak,
        Some(name) => match Strength::from_name(name) {
            Some(strength) => strength,
            None => {
                let names: Vec<String> = Strength::ALL.iter().map(|s| format!("\"{s}\"")).collect();
                return refuse("strength", format!("is \"{name}\"; use one of {}", names.join(", ")));
            }
        },
    };
    let imaging = match (file.version, file.hyperparameter, file.normalised) {
        (..=3, _, _) => Imaging::default(),
        (_, Some(hyperparameter), Some(normalised)) if eitskin::inverse::hyperparameter_in_range(hyperparameter) => {
            Imaging { hyperparameter, normalised }
        }
        (_, Some(hyperparameter), Some(_)) => {
            return refuse(
                "hyperparameter",
                format!("is {}; λ must be in [1e-6, 1000]", crate::Quoted(hyperparameter)),
            );
        }
        (_, None, _) => return refuse("hyperparameter", "is missing: a file of version 4 or later records λ".into()),
        (_, _, None) => return refuse("normalised", "is missing: a file of version 4 or later records it".into()),
    };
    let key = if file.version >= 3 { spec_key(spec)? } else { legacy_spec_key(spec)? };
    if file.spec_key != key {
        return refuse(
            "spec_key",
            format!(
                "says the calibration was made for another sensor spec ({}… here {}…); calibrate this sensor",
                &file.spec_key.get(..12).unwrap_or(&file.spec_key),
                &key[..12]
            ),
        );
    }
    let Some(areas) = file.areas.iter().map(|a| a.checked_sub(1)).collect::<Option<Vec<usize>>>() else {
        return refuse("areas", "counts areas from 1; found a 0".into());
    };
    let array = PseudoArray::with_areas(spec.outline.bounds(), file.grid, areas).map_err(|e| Error::Key {
        path: None,
        key: "areas",
        reason: e.to_string(),
    })?;
    if file.curves.len() != array.area_count() {
        return refuse("curves", format!("has {} curves for {} areas", file.curves.len(), array.area_count()));
    }
    for (k, curve) in file.curves.iter().enumerate() {
        if let Some(problem) = curve_problem(curve, file.version) {
            return refuse("curves", format!("curve {} (area {}): {problem}; fit the calibration again", k + 1, k + 1));
        }
    }
    let curves = file.curves.iter().map(Curve::from).collect();
    Ok(CalibrationFile { array, calibration: Calibration { curves, strength }, imaging })
}

#[cfg(test)]
mod tests {
    use super::*;
    use eitskin::calibration::Sample;

    fn fitted(spec: &SensorSpec) -> (PseudoArray, Calibration) {
        let array = PseudoArray::of_sensor(spec, [5, 5]).unwrap();
        let samples: Vec<Sample> = (0..array.area_count())
            .flat_map(|area| {
                (0..10).map(move |f| Sample {
                    area,
                    force: f as f64,
                    peak: 0.1 * (area + 1) as f64 * (1.0 - (-(f as f64) / 5.0).exp()),
                    std: None,
                    place: None,
                })
            })
            .collect();
        (array.clone(), Calibration::fit(&samples, array.area_count()).unwrap())
    }

    #[test]
    fn a_calibration_reads_back_and_is_refused_for_another_spec() {
        let spec = SensorSpec::square_hydrogel();
        let (array, calibration) = fitted(&spec);
        let text = calibration_to_json(&spec, &array, &calibration).unwrap();
        let (back_array, back) = parse_calibration(&text, &spec).unwrap();
        assert_eq!(back, calibration);
        assert_eq!(back_array, array);
        let mut other = spec.clone();
        other.electrodes.contact_impedance *= 2.0;
        let err = parse_calibration(&text, &other).unwrap_err().to_string();
        assert!(err.contains("made for another sensor spec"), "{err}");
        let mut denser = spec.clone();
        denser.mesh.triangles = 9000;
        assert!(parse_calibration(&text, &denser).is_ok(), "the mesh density is not part of the sensor");
        let err = parse_calibration(&text.replace("\"version\": 6", "\"version\": 7"), &spec).unwrap_err();
        assert!(err.to_string().contains("reads versions 1 to 6"), "{err}");
        // A fitted-drop calibration keeps its kind; an unknown kind is refused by name.
        let drop = Calibration { strength: Strength::FittedDrop, ..calibration.clone() };
        let text = calibration_to_json(&spec, &array, &drop).unwrap();
        assert_eq!(parse_calibration(&text, &spec).unwrap().1.strength, Strength::FittedDrop);
        let err = parse_calibration(&text.replace("fitted drop", "volume"), &spec).unwrap_err().to_string();
        assert!(err.contains("strength") && err.contains("\"volume\""), "{err}");
        for strength in Strength::ALL {
            let file = calibration_to_json(&spec, &array, &Calibration { strength, ..calibration.clone() }).unwrap();
            assert_eq!(parse_calibration(&file, &spec).unwrap().1.strength, strength);
        }
        // A field of the wrong type is named, with its place in the file.
        let err =
            parse_calibration(&text.replace("\"version\": 6", "\"version\": \"6\""), &spec).unwrap_err().to_string();
        assert!(err.starts_with("`version`: invalid type: string \"6\", expected u32 at line"), "{err}");
        let err = parse_calibration(&text.replace("\"grid\": [\n    5,", "\"grid\": [\n    -5,"), &spec)
            .unwrap_err()
            .to_string();
        assert!(err.starts_with("`grid[0]`: invalid value: integer `-5`"), "{err}");
        // A curve of a shape keeps it; an exponential's file has no `shape`.
        assert!(!text.contains("shape"), "{text}");
        let mut shaped = drop.clone();
        shaped.curves[3].shape = Some(1.0);
        let text = calibration_to_json(&spec, &array, &shaped).unwrap();
        assert_eq!(parse_calibration(&text, &spec).unwrap().1, shaped);
    }

    /// A curve that cannot turn a strength into a force is refused, naming the curve and the
    /// key: b = 0 was read and gave forces 63 % off with no word, a = 0 gave every touch the
    /// same force.
    #[test]
    fn curves_that_give_no_force_are_refused() {
        let spec = SensorSpec::square_hydrogel();
        let (array, calibration) = fitted(&spec);
        let mut broken = calibration.clone();
        let reason = |broken: &Calibration| {
            let text = calibration_to_json(&spec, &array, broken).unwrap();
            parse_calibration(&text, &spec).unwrap_err().to_string()
        };
        broken.curves[2].b = 0.0;
        assert_eq!(
            reason(&broken),
            "`curves` curve 3 (area 3): `b` = 0 N must be a force other than 0 (the e-folding force of a·e^(−F/b) + c); fit the calibration again"
        );
        broken.curves[2] = calibration.curves[2];
        broken.curves[0].a = 0.0;
        assert_eq!(
            reason(&broken),
            "`curves` curve 1 (area 1): `a` = 0: the curve is flat, so no strength tells one force from another; fit the calibration again"
        );
        broken.curves[0] = calibration.curves[0];
        broken.curves[1].shape = Some(-1.0);
        assert_eq!(
            reason(&broken),
            format!(
                "`curves` curve 2 (area 2): `shape` = -1 with `b` = {} N: a curve a·(1 + F/(k·b))^(−k) + c needs k > 0 and b > 0 (omit `shape` for a·e^(−F/b) + c); fit the calibration again",
                calibration.curves[1].b
            )
        );
        broken.curves[1] = calibration.curves[1];
        // Fields no fit gives: each refused, naming what.
        type Spoil = fn(&mut Curve);
        let fields: [(Spoil, &str); 6] = [
            (|c| c.b = 1e300, "`b` = 1e300 N is past 1e6 times the force range"),
            (|c| c.c = 1e300, "the strength does not change between 0 and 9 N in floating point"),
            (|c| c.spread = 1e300, "`spread` = 1e300 is more than the curve's whole rise"),
            (|c| c.force_range[1] = 1e300, "must run from a force ≥ 0 to a larger one, at most 1e5 N"),
            (|c| c.r_squared = 5.0, "`r_squared` = 5.0 is over 1"),
            (|c| c.a = 1e-300, "the strength does not change between 0 and 9 N"),
        ];
        for (spoil, says) in fields {
            spoil(&mut broken.curves[4]);
            assert!(
                reason(&broken).starts_with("`curves` curve 5 (area 5): ") && reason(&broken).contains(says),
                "{}",
                reason(&broken)
            );
            broken.curves[4] = calibration.curves[4];
        }
        broken.curves[4].shape = Some(1.0);
        let text = calibration_to_json(&spec, &array, &broken).unwrap().replace("\"version\": 6", "\"version\": 5");
        let err = parse_calibration(&text, &spec).unwrap_err().to_string();
        assert!(err.contains("has a `shape`, which a file of version 5 cannot hold"), "{err}");
        broken.curves[4] = calibration.curves[4];
        broken.curves[5].force_range = [20.0, 15.0];
        assert_eq!(
            reason(&broken),
            "`curves` curve 6 (area 6): `force_range` = [20, 15] N must run from a force ≥ 0 to a larger one, at most 1e5 N; fit the calibration again"
        );
    }

    /// The keys of the paper's sensor as files of each version carry them: version 2's was
    /// written by eitskin before the canonical key (so old files still read), version 3's pins
    /// the canonical values.
    #[test]
    fn keys_of_the_paper_sensor_are_stable() {
        let spec = SensorSpec::square_hydrogel();
        assert_eq!(legacy_spec_key(&spec).unwrap(), LEGACY_KEY);
        assert_eq!(spec_key(&spec).unwrap(), CANONICAL_KEY);
        // A mount on a robot is no other sensor.
        let mount = eitskin::mount::Mount {
            frame_id: "skin".into(),
            parent: "link".into(),
            position: [0.1, 0.0, 0.0],
            orientation: [0.0, 0.0, 0.0, 1.0],
        };
        let mounted = SensorSpec { mount: Some(mount), ..spec.clone() };
        assert_eq!(
            (legacy_spec_key(&mounted).unwrap(), spec_key(&mounted).unwrap()),
            (LEGACY_KEY.into(), CANONICAL_KEY.into())
        );
        let (array, calibration) = fitted(&spec);
        let v3 = version_3(&calibration_to_json(&spec, &array, &calibration).unwrap());
        let v2 = v3.replace("\"version\": 3", "\"version\": 2").replace(CANONICAL_KEY, LEGACY_KEY);
        let old = before_version_5(&calibration);
        assert_eq!(parse_calibration(&v2, &spec).unwrap().1, old);
        // Version 1 had no strength: its curves are of the peak.
        let v1 = v2.replace("\"version\": 2", "\"version\": 1").replace("\"strength\": \"peak\",", "");
        assert_eq!(parse_calibration(&v1, &spec).unwrap().1, old);
        // A version-2 file with the new key, or the other way round, is another sensor's.
        assert!(parse_calibration(&v3.replace("\"version\": 3", "\"version\": 2"), &spec).is_err());
        // Placing the same electrodes another way is the same sensor.
        let mut explicit = spec.clone();
        let centres = spec.electrode_positions().unwrap().iter().map(|e| spec.outline.point_at(e.centre)).collect();
        explicit.electrodes.placement = eitskin::Placement::Explicit { positions: centres };
        assert_eq!(spec_key(&explicit).unwrap(), CANONICAL_KEY);
    }

    /// A version-5 file as version 3 wrote it: without `hyperparameter`, `normalised`, and each
    /// curve's `spread` and `fallback`.
    fn version_3(v5: &str) -> String {
        let new = ["\"hyperparameter\"", "\"normalised\"", "\"spread\"", "\"fallback\""];
        let lines: Vec<&str> = v5.lines().filter(|l| !new.iter().any(|k| l.contains(k))).collect();
        // A key left last in its object loses its comma: JSON allows none after the last.
        let kept: Vec<&str> = (0..lines.len())
            .map(|k| match lines.get(k + 1) {
                Some(next) if next.trim_start().starts_with('}') => lines[k].trim_end_matches(','),
                _ => lines[k],
            })
            .collect();
        kept.join("\n").replace("\"version\": 6", "\"version\": 3")
    }

    /// `calibration` as a file older than version 5 holds it: no spread, no fallback.
    fn before_version_5(calibration: &Calibration) -> Calibration {
        let curves = calibration.curves.iter().map(|c| Curve { spread: 0.0, fallback: false, ..*c }).collect();
        Calibration { curves, ..calibration.clone() }
    }

    /// Version 4 records λ and the normalisation, and reads them back; a file of version 3 or
    /// older was made with the paper's λ = 0.1 and absolute differences.
    #[test]
    fn the_imaging_is_recorded_and_old_files_read_as_the_papers() {
        let spec = SensorSpec::square_hydrogel();
        let (array, calibration) = fitted(&spec);
        let imaging = Imaging { hyperparameter: 0.0316, normalised: true };
        let v4 = calibration_file_to_json(&spec, &array, &calibration, imaging).unwrap();
        assert!(v4.contains("\"hyperparameter\": 0.0316") && v4.contains("\"normalised\": true"), "{v4}");
        let back = parse_calibration_file(&v4, &spec).unwrap();
        assert_eq!((back.imaging, &back.calibration, &back.array), (imaging, &calibration, &array));
        let v3 = version_3(&v4);
        assert!(!v3.contains("hyperparameter") && v3.contains("\"version\": 3"), "{v3}");
        let old = parse_calibration_file(&v3, &spec).unwrap();
        assert_eq!(old.imaging, Imaging { hyperparameter: 0.1, normalised: false });
        assert_eq!(old.calibration, before_version_5(&calibration));
        let err = parse_calibration_file(&v4.replace("0.0316", "-1.0"), &spec).unwrap_err().to_string();
        assert!(err.contains("`hyperparameter` is -1"), "{err}");
        // Beyond the flag's own range, as `--hyperparameter` refuses it.
        let err = parse_calibration_file(&v4.replace("0.0316", "1e300"), &spec).unwrap_err().to_string();
        assert!(err.contains("`hyperparameter` is 1e300; λ must be in [1e-6, 1000]"), "{err}");
        let missing = v3.replace("\"version\": 3", "\"version\": 4");
        let err = parse_calibration_file(&missing, &spec).unwrap_err().to_string();
        assert!(err.contains("`hyperparameter` is missing"), "{err}");
    }

    const LEGACY_KEY: &str = "1c07185805c58b979be4cbecb34bb4bf0addff2e8f475fa606149629e0cb9614";
    const CANONICAL_KEY: &str = "a9e8171de3d65eb23cba5eda2c7f07d9f615f9d878d95e856d19e18cf0ea301b";
}
