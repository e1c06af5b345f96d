//! The sensor spec file (TOML): parsed into [`SensorSpec`], lengths converted to metres once.
//!
//! Every key is documented in the book (`docs/src/spec.md`). Unknown keys are errors, and so is a key that does
//! not belong to the chosen `kind` or `placement`; values are then checked by
//! [`SensorSpec::validate`], whose errors name the key at fault.

use std::path::Path;

use eitskin::mount::Mount;
use eitskin::spec::Numbering;
use eitskin::{ChannelMask, ElectrodeSpec, LengthUnit, MeshParams, Outline, Placement, ProtocolSpec, SensorSpec};
use serde::{Deserialize, Serialize};

use crate::{protocol_file, Error};

/// The file's shape, keys exactly as written; lengths in the file's `units`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SpecFile {
    #[serde(default = "default_units")]
    units: String,
    thickness: f64,
    conductivity: f64,
    outline: OutlineFile,
    electrodes: ElectrodesFile,
    #[serde(default)]
    protocol: ProtocolFile,
    #[serde(default)]
    mesh: MeshFile,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    mount: Option<MountFile>,
}

/// `[mount]`: the sensor's frame and its pose on a robot's link; the position in `units`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct MountFile {
    frame_id: String,
    parent: String,
    #[serde(default)]
    position: [f64; 3],
    #[serde(default = "identity")]
    orientation: [f64; 4],
}

fn identity() -> [f64; 4] {
    [0.0, 0.0, 0.0, 1.0]
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
enum OutlineFile {
    Rectangle { width: f64, height: f64 },
    Circle { radius: f64 },
    Polygon { points: Vec<[f64; 2]> },
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ElectrodesFile {
    count: usize,
    #[serde(default = "default_model")]
    model: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    width: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    contact_impedance: Option<f64>,
    placement: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    numbering: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    start_angle_deg: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    positions: Option<Vec<[f64; 2]>>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ProtocolFile {
    kind: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    file: Option<String>,
    /// The MAT variable with the stimulations' currents, when `file` is a MAT file.
    #[serde(skip_serializing_if = "Option::is_none")]
    stimulation: Option<String>,
    /// The MAT variable with the measurement patterns' weights, when `file` is a MAT file.
    #[serde(skip_serializing_if = "Option::is_none")]
    measurement: Option<String>,
    /// Measurements left out of every image, 1-based.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    drop_channels: Vec<usize>,
    /// Broken electrodes, 1-based: every measurement that drives or reads one is left out.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    drop_electrodes: Vec<usize>,
}

impl Default for ProtocolFile {
    fn default() -> Self {
        ProtocolFile {
            kind: "two-terminal".into(),
            file: None,
            stimulation: None,
            measurement: None,
            drop_channels: Vec::new(),
            drop_electrodes: Vec::new(),
        }
    }
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct MeshFile {
    #[serde(default = "default_triangles")]
    triangles: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    max_element_size: Option<f64>,
    #[serde(default = "default_grading")]
    grading: f64,
    #[serde(default = "default_min_angle")]
    min_angle_deg: f64,
}

impl Default for MeshFile {
    fn default() -> Self {
        let d = MeshParams::default();
        MeshFile { triangles: d.triangles, max_element_size: None, grading: d.grading, min_angle_deg: d.min_angle_deg }
    }
}

fn default_units() -> String {
    "mm".into()
}
fn default_model() -> String {
    "complete".into()
}
fn default_triangles() -> usize {
    MeshParams::default().triangles
}
fn default_grading() -> f64 {
    MeshParams::default().grading
}
fn default_min_angle() -> f64 {
    MeshParams::default().min_angle_deg
}

/// Reads and checks a spec file; a custom protocol file is found relative to the spec's folder.
pub fn read_spec(path: &Path) -> Result<SensorSpec, Error> {
    let text = crate::read_text(path)?;
    let base = path.parent().unwrap_or(Path::new("."));
    parse_spec(&text, base).map_err(|e| e.in_file(path))
}

/// Parses and checks spec text; `base` is the folder a custom protocol `file` is relative to.
pub fn parse_spec(text: &str, base: &Path) -> Result<SensorSpec, Error> {
    let file: SpecFile = toml::from_str(text).map_err(|e| Error::Toml { path: None, message: e.to_string() })?;
    let spec = file.into_spec(base)?;
    spec.validate()?;
    Ok(spec)
}

/// The spec as TOML text, lengths in its own unit (a custom protocol is written as `custom`
/// with no file: save the protocol separately).
pub fn spec_to_toml(spec: &SensorSpec) -> String {
    let k = 1.0 / spec.length_unit.metres();
    let outline = match &spec.outline {
        Outline::Rectangle { width, height } => OutlineFile::Rectangle { width: width * k, height: height * k },
        Outline::Circle { radius } => OutlineFile::Circle { radius: radius * k },
        Outline::Polygon { points } => {
            OutlineFile::Polygon { points: points.iter().map(|p| p.map(|c| c * k)).collect() }
        }
    };
    let e = &spec.electrodes;
    let (placement, start_angle_deg, positions) = match &e.placement {
        Placement::PerSide => ("per-side", None, None),
        Placement::Equal { start_angle_deg } => ("equal", Some(*start_angle_deg), None),
        Placement::Explicit { positions } => {
            ("explicit", None, Some(positions.iter().map(|p| p.map(|c| c * k)).collect()))
        }
    };
    let (model, width, contact_impedance) =
        if e.point { ("point", None, None) } else { ("complete", Some(e.width * k), Some(e.contact_impedance)) };
    let file = SpecFile {
        units: spec.length_unit.symbol().into(),
        thickness: spec.thickness * k,
        conductivity: spec.conductivity,
        outline,
        electrodes: ElectrodesFile {
            count: e.count,
            model: model.into(),
            width,
            contact_impedance,
            placement: placement.into(),
            numbering: Some(e.numbering.name().into()),
            start_angle_deg,
            positions,
        },
        protocol: ProtocolFile {
            kind: protocol_kind(&spec.protocol),
            drop_channels: spec.mask.channels.iter().map(|c| c + 1).collect(),
            drop_electrodes: spec.mask.electrodes.iter().map(|e| e + 1).collect(),
            ..ProtocolFile::default()
        },
        mesh: MeshFile {
            triangles: spec.mesh.triangles,
            max_element_size: spec.mesh.max_element_size.map(|h| h * k),
            grading: spec.mesh.grading,
            min_angle_deg: spec.mesh.min_angle_deg,
        },
        mount: spec.mount.as_ref().map(|m| MountFile {
            frame_id: m.frame_id.clone(),
            parent: m.parent.clone(),
            position: m.position.map(|c| c * k),
            orientation: m.orientation,
        }),
    };
    // Serialising plain structs of numbers and strings cannot fail.
    toml::to_string(&file).unwrap_or_default()
}

/// The spec file's name of a protocol kind, e.g. "skip-2" ([`ProtocolSpec::name`]).
pub fn protocol_kind(protocol: &ProtocolSpec) -> String {
    protocol.name()
}

/// A protocol named as on the command line or in `protocol.kind` (one of
/// [`ProtocolSpec::NAMES`]); anything else is a protocol file, relative to `base`, for a
/// sensor of `electrodes` electrodes (a file of another count is refused, naming it).
pub fn protocol_by_name(name: &str, base: &Path, electrodes: usize) -> Result<ProtocolSpec, Error> {
    match ProtocolSpec::from_name(name) {
        Some(builtin) => Ok(builtin),
        None if !base.join(name).exists() => Err(Error::UnknownProtocol { name: name.into() }),
        None => Ok(ProtocolSpec::Custom(protocol_file::read_protocol_for(&base.join(name), electrodes)?)),
    }
}

impl SpecFile {
    fn into_spec(self, base: &Path) -> Result<SensorSpec, Error> {
        let length_unit = match self.units.as_str() {
            "mm" => LengthUnit::Millimetre,
            "m" => LengthUnit::Metre,
            other => return Err(key_error("units", format!("must be \"mm\" or \"m\", got \"{other}\""))),
        };
        let k = length_unit.metres();
        let outline = match self.outline {
            OutlineFile::Rectangle { width, height } => Outline::Rectangle { width: width * k, height: height * k },
            OutlineFile::Circle { radius } => Outline::Circle { radius: radius * k },
            OutlineFile::Polygon { points } => {
                Outline::Polygon { points: points.iter().map(|p| p.map(|c| c * k)).collect() }
            }
        };
        let e = self.electrodes;
        let point = match e.model.as_str() {
            "complete" => false,
            "point" => true,
            other => {
                return Err(key_error(
                    "electrodes.model",
                    format!("must be \"complete\" or \"point\", got \"{other}\""),
                ))
            }
        };
        if !point {
            for (key, value) in [("electrodes.width", e.width), ("electrodes.contact_impedance", e.contact_impedance)] {
                if value.is_none() {
                    return Err(key_error(key, "is required for complete electrodes".into()));
                }
            }
        }
        let only_for = |key: &'static str, given: bool, placement: &str| {
            if given && e.placement != placement {
                Err(key_error(key, format!("applies only to placement = \"{placement}\", not \"{}\"", e.placement)))
            } else {
                Ok(())
            }
        };
        only_for("electrodes.start_angle_deg", e.start_angle_deg.is_some(), "equal")?;
        only_for("electrodes.positions", e.positions.is_some(), "explicit")?;
        let numbering = match e.numbering.as_deref() {
            None => Numbering::default(),
            Some(name) => Numbering::from_name(name).ok_or_else(|| {
                key_error(
                    "electrodes.numbering",
                    format!("must be \"counter-clockwise\" or \"clockwise\", got \"{name}\""),
                )
            })?,
        };
        let placement = match e.placement.as_str() {
            "per-side" => Placement::PerSide,
            "equal" => Placement::Equal { start_angle_deg: e.start_angle_deg.unwrap_or(0.0) },
            "explicit" => match e.positions {
                Some(positions) => {
                    Placement::Explicit { positions: positions.iter().map(|p| p.map(|c| c * k)).collect() }
                }
                None => {
                    return Err(key_error("electrodes.positions", "is required for placement = \"explicit\"".into()))
                }
            },
            other => {
                return Err(key_error(
                    "electrodes.placement",
                    format!("must be \"per-side\", \"equal\" or \"explicit\", got \"{other}\""),
                ))
            }
        };
        let from_one = |key: &'static str, list: &[usize]| -> Result<Vec<usize>, Error> {
            list.iter()
                .map(|&n| n.checked_sub(1).ok_or_else(|| key_error(key, "counts from 1, got 0".into())))
                .collect()
        };
        let mask = ChannelMask {
            channels: from_one("protocol.drop_channels", &self.protocol.drop_channels)?,
            electrodes: from_one("protocol.drop_electrodes", &self.protocol.drop_electrodes)?,
        };
        let matrices = match (self.protocol.stimulation, self.protocol.measurement) {
            (Some(stimulation), Some(measurement)) => Some((stimulation, measurement)),
            (None, None) => None,
            (Some(_), None) => {
                return Err(key_error("protocol.measurement", "is required with protocol.stimulation".into()))
            }
            (None, Some(_)) => {
                return Err(key_error("protocol.stimulation", "is required with protocol.measurement".into()))
            }
        };
        let protocol = match (self.protocol.kind.as_str(), self.protocol.file) {
            ("custom", Some(file)) => match &matrices {
                Some((stimulation, measurement)) => ProtocolSpec::Custom(protocol_file::read_protocol_matrices(
                    &base.join(file),
                    stimulation,
                    measurement,
                    e.count,
                )?),
                None => ProtocolSpec::Custom(protocol_file::read_protocol_for(&base.join(file), e.count)?),
            },
            ("custom", None) => return Err(key_error("protocol.file", "is required for kind = \"custom\"".into())),
            (_, Some(_)) => return Err(key_error("protocol.file", "applies only to kind = \"custom\"".into())),
            (_, None) if matrices.is_some() => {
                return Err(key_error("protocol.stimulation", "applies only to kind = \"custom\" with a file".into()))
            }
            (name, None) => match ProtocolSpec::from_name(name) {
                Some(builtin) => builtin,
                None => {
                    return Err(key_error(
                        "protocol.kind",
                        format!("must be one of {}, or custom, got \"{name}\"", ProtocolSpec::NAMES),
                    ))
                }
            },
        };
        Ok(SensorSpec {
            length_unit,
            thickness: self.thickness * k,
            conductivity: self.conductivity,
            outline,
            electrodes: ElectrodeSpec {
                count: e.count,
                width: e.width.unwrap_or(0.0) * k,
                contact_impedance: e.contact_impedance.unwrap_or(0.0),
                placement,
                numbering,
                point,
            },
            protocol,
            mask,
            mesh: MeshParams {
                triangles: self.mesh.triangles,
                max_element_size: self.mesh.max_element_size.map(|h| h * k),
                grading: self.mesh.grading,
                min_angle_deg: self.mesh.min_angle_deg,
            },
            mount: self.mount.map(|m| Mount {
                frame_id: m.frame_id,
                parent: m.parent,
                position: m.position.map(|c| c * k),
                orientation: m.orientation,
            }),
        })
    }
}

fn key_error(key: &'static str, reason: String) -> Error {
    Error::Key { path: None, key, reason }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_spec_round_trips_through_toml() {
        let spec = SensorSpec::square_hydrogel();
        let text = spec_to_toml(&spec);
        let back = parse_spec(&text, Path::new(".")).unwrap();
        assert_eq!(back.electrodes, spec.electrodes);
        assert_eq!(back.outline, spec.outline);
        assert!((back.thickness - spec.thickness).abs() < 1e-15);
        assert_eq!(back.protocol, spec.protocol);
        assert!(text.contains("units = \"mm\"") && text.contains("width = 200.0"), "{text}");
        assert!(text.contains("numbering = \"counter-clockwise\""), "{text}");
    }

    #[test]
    fn numbering_angle_and_skip_protocols_round_trip() {
        let text = r#"
thickness = 5.0
conductivity = 1.0
[outline]
kind = "rectangle"
width = 300.0
height = 200.0
[electrodes]
count = 16
width = 10.0
contact_impedance = 1e-4
placement = "equal"
numbering = "clockwise"
start_angle_deg = 180.0
[protocol]
kind = "skip-2"
drop_channels = [5, 200]
drop_electrodes = [3]
"#;
        let spec = parse_spec(text, Path::new(".")).unwrap();
        assert_eq!(spec.mask, ChannelMask { channels: vec![4, 199], electrodes: vec![2] });
        assert_eq!(spec.electrodes.numbering, Numbering::Clockwise);
        assert_eq!(spec.electrodes.placement, Placement::Equal { start_angle_deg: 180.0 });
        assert_eq!(spec.protocol, ProtocolSpec::Skip { skip: 2, skip_driven: true });
        let printed = spec_to_toml(&spec);
        let lines =
            ["numbering = \"clockwise\"", "start_angle_deg = 180.0", "kind = \"skip-2\"", "drop_channels = [5, 200]"];
        for line in lines {
            assert!(printed.contains(line), "{line} not in {printed}");
        }
        let back = parse_spec(&printed, Path::new(".")).unwrap();
        assert_eq!(back.electrodes, spec.electrodes);
        assert_eq!((back.protocol, back.mask), (spec.protocol, spec.mask));
        let zero = text.replace("drop_electrodes = [3]", "drop_electrodes = [0]");
        let err = parse_spec(&zero, Path::new(".")).unwrap_err();
        assert_eq!(err.to_string(), "`protocol.drop_electrodes` counts from 1, got 0");
        let all = parse_spec(&text.replace("skip-2", "skip-2-all"), Path::new(".")).unwrap();
        assert_eq!(all.protocol().unwrap().len(), 256);
    }

    /// A custom protocol file of another electrode count than the spec's is refused when the
    /// spec is read, naming the protocol's file (the forward model said only "the protocol has
    /// 8 electrodes but the mesh has 16"); so is one named on the command line.
    #[test]
    fn a_protocol_of_another_electrode_count_names_its_file() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("pr_el8.json"), r#"{"electrodes": 8, "quads": [[1, 2, 3, 4]]}"#).unwrap();
        let spec = spec_to_toml(&SensorSpec::square_hydrogel())
            .replace("kind = \"two-terminal\"", "kind = \"custom\"\nfile = \"pr_el8.json\"");
        let err = crate::full_message(&parse_spec(&spec, dir.path()).unwrap_err());
        let file = dir.path().join("pr_el8.json");
        assert!(err.starts_with(&format!("{}: `electrodes` is 8", file.display())), "{err}");
        assert!(err.contains("the sensor has 16 electrodes"), "{err}");
        let err = crate::full_message(&protocol_by_name("pr_el8.json", dir.path(), 16).unwrap_err());
        assert!(err.starts_with(&format!("{}: `electrodes` is 8", file.display())), "{err}");
        assert!(protocol_by_name("pr_el8.json", dir.path(), 8).is_ok());
    }

    #[test]
    fn bad_numbering_angle_and_kind_name_the_key() {
        let spec = spec_to_toml(&SensorSpec::square_hydrogel());
        let message = |text: &str| crate::full_message(&parse_spec(text, Path::new(".")).unwrap_err());
        let err = message(&spec.replace("\"counter-clockwise\"", "\"anticlockwise\""));
        assert!(err.contains("`electrodes.numbering`") && err.contains("\"anticlockwise\""), "{err}");
        let err = message(&spec.replace("placement = \"per-side\"", "placement = \"equal\"\nstart_angle_deg = 720.0"));
        assert!(
            err.contains("`electrodes.start_angle_deg` must be a finite number within [-360, 360] degrees"),
            "{err}"
        );
        let err = message(
            &spec.replace("start_angle_deg = 720.0", "").replace("kind = \"two-terminal\"", "kind = \"skip-x\""),
        );
        assert!(err.contains("`protocol.kind`") && err.contains("skip-S"), "{err}");
        let err = message(&spec.replace("kind = \"two-terminal\"", "kind = \"skip-15\""));
        assert!(err.contains("skip-15 pairs electrode k with k + 16"), "{err}");
    }

    /// `[mount]` is read with its position in the spec's unit, written back the same, and a bad
    /// value is refused with its key and value as written.
    #[test]
    fn mount_reads_in_the_spec_unit_and_round_trips() {
        let spec = spec_to_toml(&SensorSpec::square_hydrogel())
            + "\n[mount]\nframe_id = \"skin_palm\"\nparent = \"hand_link\"\nposition = [10.0, 0.0, 250.0]\n";
        let read = parse_spec(&spec, Path::new(".")).unwrap();
        let mount = read.mount.clone().unwrap();
        assert_eq!((mount.frame_id.as_str(), mount.parent.as_str()), ("skin_palm", "hand_link"));
        assert_eq!((mount.position, mount.orientation), ([0.01, 0.0, 0.25], [0.0, 0.0, 0.0, 1.0]));
        assert_eq!(parse_spec(&spec_to_toml(&read), Path::new(".")).unwrap(), read);
        let message = |text: &str| crate::full_message(&parse_spec(text, Path::new(".")).unwrap_err());
        let err = message(&(spec.clone() + "orientation = [0.0, 0.0, 0.7, 0.0]\n"));
        assert!(err.contains("`mount.orientation` = [0, 0, 0.7, 0]: it must be a unit quaternion"), "{err}");
        let err = message(&spec.replace("parent = \"hand_link\"\n", ""));
        assert!(err.contains("parent"), "{err}");
        let err = message(&spec.replace("\"skin_palm\"", "\"/skin\""));
        assert!(err.contains("`mount.frame_id` = \"/skin\""), "{err}");
    }
}
