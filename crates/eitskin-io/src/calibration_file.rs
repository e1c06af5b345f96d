//! Calibration files (JSON, versioned): the pseudo-array's areas and one curve per area, tied
//! to the sensor spec they were made for.
//!
//! ```json
//! { "format": "eitskin-calibration", "version": 2, "spec_key": "…", "strength": "peak",
//!   "grid": [5, 5], "areas": [6, 5, 3, …], "curves": [{ "a": …, "b": …, "c": …,
//!   "r_squared": …, "force_range": [0, 15], "samples": 240 }, …] }
//! ```
//! `areas` gives each unit's area, counting both from 1, units row-major from the bottom-left;
//! curve k is area k + 1, s(F) = a·e^(−F/b) + c with F in N and the strength s either the
//! image's `"peak"` in S/m or the `"fitted drop"` of the press fitted to Δv (a fraction of the
//! background). Version 1 files (no `strength`) are read as peak. A file made for another spec
//! (another `spec_key`) is refused.

use std::path::Path;

use eitskin::calibration::{Calibration, Curve, Strength};
use eitskin::pseudo_array::PseudoArray;
use eitskin::SensorSpec;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::Error;

const FORMAT: &str = "eitskin-calibration";
const VERSION: u32 = 2;

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct CalibrationJson {
    format: String,
    version: u32,
    spec_key: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    strength: Option<String>,
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
}

impl From<&Curve> for CurveJson {
    fn from(c: &Curve) -> CurveJson {
        let Curve { a, b, c, r_squared, force_range, samples } = *c;
        CurveJson { a, b, c, r_squared, force_range, samples }
    }
}

impl From<&CurveJson> for Curve {
    fn from(c: &CurveJson) -> Curve {
        let CurveJson { a, b, c, r_squared, force_range, samples } = *c;
        Curve { a, b, c, r_squared, force_range, samples }
    }
}

/// A hex SHA-256 of what a calibration depends on: the spec (outline, electrodes, protocol).
pub fn spec_key(spec: &SensorSpec) -> Result<String, Error> {
    let mut hash = Sha256::new();
    let mut geometry = spec.clone();
    geometry.mesh = eitskin::MeshParams::default(); // the mesh density does not change the sensor
    hash.update(crate::spec_to_toml(&geometry));
    hash.update(format!("{:?}", spec.protocol()?));
    Ok(hash.finalize().iter().map(|b| format!("{b:02x}")).collect())
}

/// The calibration as JSON, for `spec` with its pseudo-array.
pub fn calibration_to_json(spec: &SensorSpec, array: &PseudoArray, calibration: &Calibration) -> Result<String, Error> {
    let file = CalibrationJson {
        format: FORMAT.into(),
        version: VERSION,
        spec_key: spec_key(spec)?,
        strength: Some(strength_name(calibration.strength).into()),
        grid: array.grid(),
        areas: (0..array.unit_count()).map(|u| array.area_of(u) + 1).collect(),
        curves: calibration.curves.iter().map(CurveJson::from).collect(),
    };
    serde_json::to_string_pretty(&file).map_err(|e| Error::Json { path: None, message: e.to_string() })
}

/// Reads a calibration made for `spec`: its pseudo-array (over the spec's outline) and curves.
pub fn read_calibration(path: &Path, spec: &SensorSpec) -> Result<(PseudoArray, Calibration), Error> {
    parse_calibration(&crate::read_text(path)?, spec).map_err(|e| e.in_file(path))
}

/// Parses calibration JSON made for `spec`.
pub fn parse_calibration(text: &str, spec: &SensorSpec) -> Result<(PseudoArray, Calibration), Error> {
    let file: CalibrationJson =
        serde_json::from_str(text).map_err(|e| Error::Json { path: None, message: e.to_string() })?;
    let refuse = |key: &'static str, reason: String| Err(Error::Key { path: None, key, reason });
    if file.format != FORMAT {
        return refuse("format", format!("is \"{}\", not \"{FORMAT}\": this is not a calibration file", file.format));
    }
    if !(1..=VERSION).contains(&file.version) {
        return refuse("version", format!("is {}, but this eitskin reads versions 1 to {VERSION}", file.version));
    }
    let strength = match file.strength.as_deref() {
        None | Some("peak") => Strength::Peak,
        Some("fitted drop") => Strength::FittedDrop,
        Some(other) => return refuse("strength", format!("is \"{other}\"; use \"peak\" or \"fitted drop\"")),
    };
    let key = spec_key(spec)?;
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
    let curves = file.curves.iter().map(Curve::from).collect();
    Ok((array, Calibration { curves, strength }))
}

/// The file's name for a kind of strength.
pub fn strength_name(strength: Strength) -> &'static str {
    match strength {
        Strength::Peak => "peak",
        Strength::FittedDrop => "fitted drop",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use eitskin::calibration::Sample;

    fn fitted(spec: &SensorSpec) -> (PseudoArray, Calibration) {
        let array = PseudoArray::by_symmetry(&spec.outline, &spec.electrode_positions().unwrap(), [5, 5]).unwrap();
        let samples: Vec<Sample> = (0..array.area_count())
            .flat_map(|area| {
                (0..10).map(move |f| Sample {
                    area,
                    force: f as f64,
                    peak: 0.1 * (area + 1) as f64 * (1.0 - (-(f as f64) / 5.0).exp()),
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
        let err = parse_calibration(&text.replace("\"version\": 2", "\"version\": 7"), &spec).unwrap_err();
        assert!(err.to_string().contains("reads versions 1 to 2"), "{err}");
        // Version 1 had no strength: its curves are of the peak.
        let v1 = text.replace("\"version\": 2", "\"version\": 1").replace("\"strength\": \"peak\",", "");
        assert_eq!(parse_calibration(&v1, &spec).unwrap().1, calibration);
        // A fitted-drop calibration keeps its kind; an unknown kind is refused by name.
        let drop = Calibration { strength: Strength::FittedDrop, ..calibration.clone() };
        let text = calibration_to_json(&spec, &array, &drop).unwrap();
        assert_eq!(parse_calibration(&text, &spec).unwrap().1.strength, Strength::FittedDrop);
        let err = parse_calibration(&text.replace("fitted drop", "volume"), &spec).unwrap_err().to_string();
        assert!(err.contains("strength") && err.contains("\"volume\""), "{err}");
    }
}
