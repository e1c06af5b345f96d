//! A learned model's file (JSON): the method and the labelled presses it was trained on, tied
//! to the protocol and its channel count. Loading trains the method again on those presses
//! (deterministic: the same grid, the same folds), so the file holds data, not a solver's state.
//!
//! ```json
//! {"format": "eitskin-learned-model", "version": 1, "protocol": "two-terminal", "channels": 120,
//!  "method": "gp-shape", "presses": [{"x": 0.01, "y": -0.02, "force": 5.0, "inputs": [...]}, ...]}
//! ```
//! Positions in m, forces in N; a press may also have a `depth`, in m.

use std::path::Path;

use eitskin::learn::{train, Features, LabelledPress, LearnedModel, Method, NominalSensor};
use eitskin::press_fit::PressModelParams;
use eitskin::SensorSpec;
use serde::{Deserialize, Serialize};

use crate::Error;

const FORMAT: &str = "eitskin-learned-model";
const VERSION: u32 = 1;

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ModelJson {
    format: String,
    version: u32,
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
    if file.version != VERSION {
        return Err(key("version", format!("is {}; this eitskin reads version {VERSION}", file.version)));
    }
    let protocol = crate::protocol_kind(&spec.protocol);
    if file.protocol != protocol {
        return Err(key("protocol", format!("is {:?}, but the sensor's protocol is {protocol:?}", file.protocol)));
    }
    if file.channels != channels {
        return Err(key("channels", format!("is {}, but the frames given have {channels} values", file.channels)));
    }
    let method =
        Method::from_name(&file.method).ok_or_else(|| key("method", format!("{:?} is not a method", file.method)))?;
    let presses: Vec<LabelledPress> = file
        .presses
        .into_iter()
        .map(|p| LabelledPress { inputs: p.inputs, position: [p.x, p.y], force: p.force, depth: p.depth })
        .collect();
    let sensor = (method.features == Features::Press).then(|| nominal_sensor(spec, cache)).transpose()?;
    train(&presses, method, sensor.as_ref()).map_err(|e| key("presses", e.to_string()))
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
