//! A learned model's file (JSON): the method and the labelled presses it was trained on, tied
//! to the sensor (version 2: its `spec_key`, as a calibration's), the protocol and its channel
//! count. Loading trains the method again on those presses
//! (deterministic: the same grid, the same folds), so the file holds data, not a solver's state.
//!
//! ```json
//! {"format": "eitskin-learned-model", "version": 2, "spec_key": "…", "protocol": "two-terminal", "channels": 120,
//!  "method": "gp-shape", "presses": [{"x": 0.01, "y": -0.02, "force": 5.0, "inputs": [...]}, ...]}
//! ```
//! Positions in m, forces in N; a press may also have a `depth`, in m. The presses are held to
//! what a samples file may hold: on the sheet, forces and depths of 0 or more (forces at most
//! [`MAX_FORCE`]). Version 1 files (no key) still read.

use std::path::Path;

use eitskin::calibration::MAX_FORCE;
use eitskin::learn::{train, Features, LabelledPress, LearnedModel, Method, NominalSensor};
use eitskin::press_fit::PressModelParams;
use eitskin::SensorSpec;
use serde::{Deserialize, Serialize};

use crate::Error;

const FORMAT: &str = "eitskin-learned-model";
const VERSION: u32 = 2;

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ModelJson {
    format: String,
    version: u32,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    spec_key: Option<String>,
    protocol: String,
    channels: usize,
    method: String,
    presses: Vec<PressJson>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct PressJson {
    x: f64,
    y: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    force: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    depth: Option<f64>,
    inputs: Vec<f64>,
}

/// The model of `method` trained on `presses` for `spec`'s protocol, as JSON.
pub fn learned_model_to_json(spec: &SensorSpec, method: Method, presses: &[LabelledPress]) -> Result<String, Error> {
    let file = ModelJson {
        format: FORMAT.into(),
        version: VERSION,
        spec_key: Some(crate::spec_key(spec)?),
        protocol: crate::protocol_kind(&spec.protocol),
        channels: presses.first().map_or(0, |p| p.inputs.len()),
        method: method.name(),
        presses: presses
            .iter()
            .map(|p| PressJson {
                x: p.position[0],
                y: p.position[1],
                force: p.force,
                depth: p.depth,
                inputs: p.inputs.clone(),
            })
            .collect(),
    };
    serde_json::to_string(&file).map_err(|e| Error::Json { path: None, message: e.to_string() })
}

/// `spec` as specified, for press features: its press model (default indenter) from the cache
/// in `cache` when given (built and kept there if missing), and its measurements without a press.
pub fn nominal_sensor(spec: &SensorSpec, cache: Option<&Path>) -> Result<NominalSensor, Error> {
    let params = PressModelParams::default();
    let press = match cache {
        Some(dir) => crate::load_or_build_press_model(dir, spec, &params)?.0,
        None => crate::build_press_model(spec, &params)?,
    };
    NominalSensor::of_spec(spec, Some(press)).map_err(|e| Error::Key { path: None, key: "spec", reason: e.to_string() })
}

/// Reads a model for `spec` (`channels` values a frame: the protocol's length, or twice it for
/// complex pairs) and trains it again (press features on [`nominal_sensor`], with `cache`); a
/// model for another protocol or channel count is refused.
pub fn read_learned_model(
    path: &Path,
    spec: &SensorSpec,
    channels: usize,
    cache: Option<&Path>,
) -> Result<LearnedModel, Error> {
    parse_learned_model(&crate::read_text(path)?, spec, channels, cache).map_err(|e| e.in_file(path))
}

/// [`read_learned_model`] on text.
pub fn parse_learned_model(
    text: &str,
    spec: &SensorSpec,
    channels: usize,
    cache: Option<&Path>,
) -> Result<LearnedModel, Error> {
    let file: ModelJson = crate::parse_json_file(text, FORMAT)?;
    let key = |key: &'static str, reason: String| Error::Key { path: None, key, reason };
    if !(1..=VERSION).contains(&file.version) {
        return Err(key("version", format!("is {}; this eitskin reads versions 1 to {VERSION}", file.version)));
    }
    let protocol = crate::protocol_kind(&spec.protocol);
    if file.protocol != protocol {
        return Err(key("protocol", format!("is {:?}, but the sensor's protocol is {protocol:?}", file.protocol)));
    }
    if file.channels != channels {
        return Err(key("channels", format!("is {}, but the frames given have {channels} values", file.channels)));
    }
    if file.version >= 2 {
        let here = crate::spec_key(spec)?;
        match &file.spec_key {
            Some(k) if *k == here => {}
            Some(k) => {
                return Err(key(
                    "spec_key",
                    format!(
                        "says the model was learned on another sensor spec ({}… here {}…); learn this sensor",
                        k.get(..12).unwrap_or(k),
                        &here[..12]
                    ),
                ))
            }
            None => return Err(key("spec_key", "is missing: a file of version 2 or later records it".into())),
        }
    }
    let method =
        Method::from_name(&file.method).ok_or_else(|| key("method", format!("{:?} is not a method", file.method)))?;
    let presses: Vec<LabelledPress> = file
        .presses
        .into_iter()
        .map(|p| LabelledPress { inputs: p.inputs, position: [p.x, p.y], force: p.force, depth: p.depth })
        .collect();
    check_labels(&presses, spec)?;
    let sensor = (method.features == Features::Press).then(|| nominal_sensor(spec, cache)).transpose()?;
    train(&presses, method, sensor.as_ref()).map_err(|e| key("presses", e.to_string()))
}

/// The presses' labels as a samples file may hold them: forces in [0, [`MAX_FORCE`]] N,
/// depths of 0 or more, positions on the sheet ([`crate::check_labels_on_sheet`]).
fn check_labels(presses: &[LabelledPress], spec: &SensorSpec) -> Result<(), Error> {
    let refuse = |k: usize, reason: String| Error::Key {
        path: None,
        key: "presses",
        reason: format!("press {}: {reason}", k + 1),
    };
    for (k, p) in presses.iter().enumerate() {
        if let Some(f) = p.force.filter(|f| !(0.0..=MAX_FORCE).contains(f)) {
            return Err(refuse(k, format!("force {f:?} N is outside 0–{MAX_FORCE:e} N")));
        }
        if let Some(d) = p.depth.filter(|d| *d < 0.0) {
            return Err(refuse(k, format!("depth {d:?} m is negative")));
        }
    }
    crate::check_labels_on_sheet(presses, spec)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_model_round_trips_and_another_sensors_is_refused() {
        let spec = SensorSpec::square_hydrogel();
        let presses: Vec<LabelledPress> = (0..12)
            .map(|i| {
                let x = i as f64 * 0.01;
                LabelledPress {
                    inputs: vec![x, 2.0 * x + 0.1, (x * 7.0).sin()],
                    position: [x, -x],
                    force: Some(x * 100.0),
                    depth: Some(x * 0.01),
                }
            })
            .collect();
        let text = learned_model_to_json(&spec, Method::knn(1), &presses).unwrap();
        let model = parse_learned_model(&text, &spec, 3, None).unwrap();
        assert_eq!(model.method, Method::knn(1));
        assert!(model.forces && model.depths);
        let err = parse_learned_model(&text, &spec, 120, None).unwrap_err().to_string();
        assert_eq!(err, "`channels` is 3, but the frames given have 120 values");
        let mut other = spec.clone();
        other.protocol = eitskin::ProtocolSpec::Adjacent;
        let err = parse_learned_model(&text, &other, 3, None).unwrap_err().to_string();
        assert_eq!(err, "`protocol` is \"two-terminal\", but the sensor's protocol is \"adjacent\"");
        // Another sheet with the same protocol is another sensor; a file of version 1 has no key.
        let mut wider = spec.clone();
        wider.outline = eitskin::Outline::Rectangle { width: 0.3, height: 0.3 };
        let err = parse_learned_model(&text, &wider, 3, None).unwrap_err().to_string();
        assert!(err.starts_with("`spec_key` says the model was learned on another sensor spec"), "{err}");
        let key = format!("\"spec_key\":\"{}\",", crate::spec_key(&spec).unwrap());
        let v1 = text.replace(&key, "").replace("\"version\":2", "\"version\":1");
        assert!(parse_learned_model(&v1, &wider, 3, None).is_ok(), "{v1}");
        // Labels a samples file could not hold.
        for (spoiled, says) in [
            (text.replacen("\"force\":0.0", "\"force\":-10.0", 1), "press 1: force -10.0 N is outside 0–1e5 N"),
            (text.replacen("\"x\":0.0", "\"x\":1e300", 1), "of press 1 are (1e303"),
        ] {
            let err = parse_learned_model(&spoiled, &spec, 3, None).unwrap_err().to_string();
            assert!(err.contains(says), "{err}");
        }
        // A model given where a calibration is wanted, and the other way round, is named as what
        // it is, before any of its fields is read.
        let err = crate::parse_calibration(&text, &spec).unwrap_err().to_string();
        assert_eq!(
            err,
            "`format` is \"eitskin-learned-model\": this is a learned model (what `eitskin learn --out` writes), and a calibration (what `eitskin calibrate --out` writes) is needed here"
        );
        let calibration = r#"{"format": "eitskin-calibration", "version": 5, "curves": []}"#;
        let err = parse_learned_model(calibration, &spec, 3, None).unwrap_err().to_string();
        assert!(err.starts_with("`format` is \"eitskin-calibration\": this is a calibration"), "{err}");
        let err = parse_learned_model(r#"{"x": 1}"#, &spec, 3, None).unwrap_err().to_string();
        assert!(err.ends_with("this is not a learned model (what `eitskin learn --out` writes)"), "{err}");
    }
}
