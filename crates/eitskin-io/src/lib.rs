//! # eitskin-io
//!
//! Everything that crosses the edge of [`eitskin`]: file formats (sensor specs in TOML, meshes
//! and custom protocols in JSON, single frames, calibration samples in CSV, calibration files
//! tied to their sensor), the on-disk caches of precomputed models (reconstructor, press model,
//! contrast map), frame codecs for acquisition boards ([`codec`]: text lines, binary with CRC),
//! frame sources ([`source`]: a serial port that survives unplugging), the crash-safe
//! [`recorder`] and its [`replay`]. Every reader checks what it reads and says which file, line
//! or key is at fault.
//!
//! ```
//! use std::path::Path;
//! let spec = eitskin_io::parse_spec(r#"
//!     units = "mm"
//!     thickness = 10.0
//!     conductivity = 1.0
//!     [outline]
//!     kind = "circle"
//!     radius = 100.0
//!     [electrodes]
//!     count = 16
//!     width = 10.0
//!     contact_impedance = 1e-4
//!     placement = "equal"
//! "#, Path::new("."))?;
//! assert_eq!(spec.protocol()?.len(), 120); // two-terminal unless told otherwise
//! assert!(eitskin_io::parse_spec("thickness = 1.0\nbogus = 2", Path::new(".")).is_err());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Not for: computation (that is `eitskin`), or printing results (the CLI does that).

#![deny(missing_docs)]
#![warn(rustdoc::broken_intra_doc_links)]
#![cfg_attr(not(test), warn(clippy::unwrap_used, clippy::expect_used))]

mod array_file;
pub mod build;
mod calibration_file;
pub mod codec;
mod contrast_map_file;
mod fleet_file;
mod frame_file;
mod learned_model_file;
mod memory;
mod mesh_file;
#[cfg(feature = "zenoh")]
pub mod middleware;
mod output_name;
mod press_model_file;
mod protocol_file;
mod raster_file;
mod reconstructor_file;
mod record_format;
pub mod recorder;
pub mod replay;
mod samples_file;
pub mod source;
mod spec_file;
pub mod stream;

use std::path::{Path, PathBuf};

pub use array_file::{read_frames, read_one_frame, ArrayProblem, ArrayVariable, FrameLayout, FrameSelect, FrameTable};
pub use calibration_file::{
    calibration_file_to_json, calibration_to_json, parse_calibration, parse_calibration_file, read_calibration,
    read_calibration_file, spec_key, CalibrationFile, Imaging,
};
pub use contrast_map_file::{contrast_map_path, decode_contrast_map, encode_contrast_map, load_or_build_contrast_map};
pub use fleet_file::{parse_fleet, read_fleet, Fleet, FleetSensor, MAX_SENSORS};
pub use frame_file::{parse_frame, read_frame};
pub use learned_model_file::{learned_model_to_json, nominal_sensor, parse_learned_model, read_learned_model};
pub use memory::{available_memory, last_level_cache, peak_memory};
pub use mesh_file::{mesh_to_json, parse_mesh, read_mesh};
pub use output_name::check_output_name;
pub use press_model_file::{
    build_press_model, decode_press_model, encode_press_model, load_or_build_press_model, press_model_path,
};
pub use protocol_file::{parse_protocol, read_protocol};
pub use raster_file::{
    write_elements_csv, write_elements_stack_csv, write_labels_csv, write_labels_npy, write_labels_stack_csv,
    write_labels_stack_npy, write_raster_csv, write_raster_npy, write_raster_stack_csv, write_raster_stack_npy,
};
pub use reconstructor_file::{
    cache_key, cache_path, cached_hyperparameter, decode_linearisation, encode_linearisation, load_linearisation,
    load_or_build, shared_linearisation,
};
pub use samples_file::{
    check_labels_on_sheet, labelled_presses_to_csv, off_sheet, parse_samples, read_labelled_presses, read_samples,
    Location, Measured, SampleRow, OFF_SHEET, SPECK,
};
pub use spec_file::{parse_spec, protocol_by_name, protocol_kind, read_spec, spec_to_toml};

use eitskin::{InverseError, MeshError, ProtocolError, ProtocolSpec, SpecError};
use thiserror::Error;

/// What went wrong reading a file; `path` names the file when there is one.
#[derive(Debug, Error)]
pub enum Error {
    /// The file could not be read.
    #[error("cannot read {}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A protocol named neither by a built-in protocol's name nor by a file that exists.
    #[error("\"{name}\" is neither a protocol ({}) nor a protocol file", ProtocolSpec::NAMES)]
    UnknownProtocol {
        /// The name as given.
        name: String,
    },
    /// TOML syntax, a missing or unknown key, or a value of the wrong type.
    #[error("{}{message}", at(path))]
    Toml {
        /// The file, if any.
        path: Option<PathBuf>,
        /// The parser's message, with line, column and key.
        message: String,
    },
    /// JSON syntax, a missing key, or a value of the wrong type.
    #[error("{}{message}", at(path))]
    Json {
        /// The file, if any.
        path: Option<PathBuf>,
        /// The parser's message, with line and column.
        message: String,
    },
    /// A key whose value is not allowed.
    #[error("{}`{key}` {reason}", at(path))]
    Key {
        /// The file, if any.
        path: Option<PathBuf>,
        /// The key, e.g. `electrodes.placement`.
        key: &'static str,
        /// Why it is refused.
        reason: String,
    },
    /// The spec's values do not make a sensor.
    #[error("{}the spec does not make a sensor", at(path))]
    Spec {
        /// The file, if any.
        path: Option<PathBuf>,
        /// What is wrong.
        source: SpecError,
    },
    /// The mesh is not a valid mesh.
    #[error("{}the mesh is not valid", at(path))]
    Mesh {
        /// The file, if any.
        path: Option<PathBuf>,
        /// What is wrong.
        source: MeshError,
    },
    /// The protocol is not a valid protocol.
    #[error("{}the protocol is not valid", at(path))]
    Protocol {
        /// The file, if any.
        path: Option<PathBuf>,
        /// What is wrong.
        source: ProtocolError,
    },
    /// An array file (MAT, NPY) or the array chosen in it does not give frames.
    #[error("{}{}: {problem}", path.display(), variable.as_ref().map(|v| format!(", variable `{v}`")).unwrap_or_default())]
    Array {
        /// The file.
        path: PathBuf,
        /// The variable read or asked for, if any.
        variable: Option<String>,
        /// What is wrong.
        problem: ArrayProblem,
    },
    /// A file could not be written.
    #[error("cannot write {}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A precomputed model (reconstructor, press model) could not be built.
    #[error("the inverse model could not be built")]
    Inverse(#[from] InverseError),
    /// A press model could not be built.
    #[error("the press model could not be built")]
    PressModel(#[from] eitskin::press_fit::PressModelError),
    /// The frame chain could not be assembled.
    #[error("the frame chain could not be assembled")]
    Chain(#[from] eitskin::chain::ChainError),
    /// A pipeline setting is out of its range.
    #[error(transparent)]
    Setting(#[from] eitskin::pipeline::RangeError),
}

fn at(path: &Option<PathBuf>) -> String {
    path.as_ref().map(|p| format!("{}: ", p.display())).unwrap_or_default()
}

impl Error {
    /// The same error, naming `file` if it names no file yet.
    fn in_file(mut self, file: &Path) -> Error {
        match &mut self {
            Error::Read { .. }
            | Error::Array { .. }
            | Error::Write { .. }
            | Error::Inverse(_)
            | Error::Chain(_)
            | Error::Setting(_)
            | Error::PressModel(_)
            | Error::UnknownProtocol { .. } => {}
            Error::Toml { path, .. }
            | Error::Json { path, .. }
            | Error::Key { path, .. }
            | Error::Spec { path, .. }
            | Error::Mesh { path, .. }
            | Error::Protocol { path, .. } => {
                if path.is_none() {
                    *path = Some(file.to_path_buf());
                }
            }
        }
        self
    }
}

impl From<SpecError> for Error {
    fn from(source: SpecError) -> Error {
        Error::Spec { path: None, source }
    }
}

impl From<MeshError> for Error {
    fn from(source: MeshError) -> Error {
        Error::Mesh { path: None, source }
    }
}

impl From<ProtocolError> for Error {
    fn from(source: ProtocolError) -> Error {
        Error::Protocol { path: None, source }
    }
}

/// An error and its causes joined by ": ", each once: the whole message, as the CLI prints it
/// (every error here keeps its cause as [`std::error::Error::source`] and does not repeat it).
pub fn full_message(error: &dyn std::error::Error) -> String {
    let mut text = error.to_string();
    let mut cause = error.source();
    while let Some(e) = cause {
        text += &format!(": {e}");
        cause = e.source();
    }
    text
}

/// eitskin's JSON files by their `format`, with what each is and which command writes it.
const JSON_FILES: [(&str, &str); 2] = [
    ("eitskin-calibration", "a calibration (what `eitskin calibrate --out` writes)"),
    ("eitskin-learned-model", "a learned model (what `eitskin learn --out` writes)"),
];

/// What eitskin JSON file `head` (a file's first bytes) starts, by its `format`, if it is one
/// of [`JSON_FILES`] (a calibration, a learned model), in words.
fn json_file_kind(head: &[u8]) -> Option<&'static str> {
    let text = String::from_utf8_lossy(head);
    let after = text[text.find("\"format\"")? + "\"format\"".len()..].trim_start().strip_prefix(':')?;
    let value = after.trim_start().strip_prefix('"')?;
    let format = &value[..value.find('"')?];
    JSON_FILES.iter().find(|(known, _)| *known == format).map(|(_, what)| *what)
}

/// `text` as the eitskin JSON file of `format`: a file of another kind is named as such (its
/// `format` read first) before any of its fields is checked.
fn parse_json_file<T: serde::de::DeserializeOwned>(text: &str, format: &str) -> Result<T, Error> {
    let json = |e: serde_json::Error| Error::Json { path: None, message: e.to_string() };
    let value: serde_json::Value = serde_json::from_str(text).map_err(json)?;
    let found = value.get("format").and_then(serde_json::Value::as_str).unwrap_or_default();
    let name = |f: &str| JSON_FILES.iter().find(|(known, _)| *known == f).map(|(_, what)| *what);
    if found != format {
        let want = name(format).unwrap_or(format);
        let reason = match name(found) {
            Some(what) => format!("is \"{found}\": this is {what}, and {want} is needed here"),
            None => match value.get("format") {
                Some(other) => format!("is {other}, not \"{format}\": this is not {want}"),
                None => format!("is missing: this is not {want}"),
            },
        };
        return Err(Error::Key { path: None, key: "format", reason });
    }
    // Again from the text, so that a message names its line and column, and the field.
    serde_path_to_error::deserialize(&mut serde_json::Deserializer::from_str(text)).map_err(|e| {
        let field = e.path().to_string();
        let message = e.into_inner().to_string();
        Error::Json { path: None, message: if field == "." { message } else { format!("`{field}`: {message}") } }
    })
}

/// The text of `path`, without the byte-order mark a spreadsheet's "CSV UTF-8" starts with.
fn read_text(path: &Path) -> Result<String, Error> {
    let text = std::fs::read_to_string(path).map_err(|source| Error::Read { path: path.to_path_buf(), source })?;
    Ok(match text.strip_prefix('\u{feff}') {
        Some(rest) => rest.to_string(),
        None => text,
    })
}

/// A number from a file as its shortest text (`1e300`, not 301 digits; `20`, not `20.0`).
pub(crate) struct Quoted(pub(crate) f64);

impl std::fmt::Display for Quoted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let text = format!("{:?}", self.0);
        f.write_str(text.strip_suffix(".0").unwrap_or(&text))
    }
}
