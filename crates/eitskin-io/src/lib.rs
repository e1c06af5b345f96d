//! # eitskin-io
//!
//! File formats for [`eitskin`]: sensor specs (TOML), meshes and custom protocols (JSON),
//! single frames (JSON or CSV).
//! Every reader checks what it reads and says which file and which key is at fault.
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

mod calibration_file;
pub mod codec;
mod frame_file;
mod mesh_file;
mod press_model_file;
mod protocol_file;
mod reconstructor_file;
pub mod recorder;
pub mod replay;
mod samples_file;
pub mod source;
mod spec_file;
pub mod stream;

use std::path::{Path, PathBuf};

pub use calibration_file::{calibration_to_json, parse_calibration, read_calibration, spec_key, strength_name};
pub use frame_file::{parse_frame, read_frame};
pub use mesh_file::{mesh_to_json, parse_mesh, read_mesh};
pub use press_model_file::{decode_press_model, encode_press_model, load_or_build_press_model, press_model_path};
pub use protocol_file::{parse_protocol, read_protocol};
pub use reconstructor_file::{cache_key, cache_path, decode, encode, load_or_build};
pub use samples_file::{parse_samples, read_samples, Location, Measured, SampleRow};
pub use spec_file::{parse_spec, protocol_by_name, protocol_kind, read_spec, spec_to_toml};

use eitskin::{MeshError, ProtocolError, SpecError};
use thiserror::Error;

/// What went wrong reading a file; `path` names the file when there is one.
#[derive(Debug, Error)]
pub enum Error {
    /// The file could not be read.
    #[error("cannot read {}: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
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
    #[error("{}{source}", at(path))]
    Spec {
        /// The file, if any.
        path: Option<PathBuf>,
        /// What is wrong.
        source: SpecError,
    },
    /// The mesh is not a valid mesh.
    #[error("{}{source}", at(path))]
    Mesh {
        /// The file, if any.
        path: Option<PathBuf>,
        /// What is wrong.
        source: MeshError,
    },
    /// The protocol is not a valid protocol.
    #[error("{}{source}", at(path))]
    Protocol {
        /// The file, if any.
        path: Option<PathBuf>,
        /// What is wrong.
        source: ProtocolError,
    },
}

fn at(path: &Option<PathBuf>) -> String {
    path.as_ref().map(|p| format!("{}: ", p.display())).unwrap_or_default()
}

impl Error {
    /// The same error, naming `file` if it names no file yet.
    fn in_file(mut self, file: &Path) -> Error {
        match &mut self {
            Error::Read { .. } => {}
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

fn read_text(path: &Path) -> Result<String, Error> {
    std::fs::read_to_string(path).map_err(|source| Error::Read { path: path.to_path_buf(), source })
}
