//! # eitskin
//!
//! Electrical impedance tomography for tactile skins: from a sensor spec to the voltages its
//! electrodes measure. The chain is spec → mesh → forward model (P1 FEM with the complete
//! electrode model, one sparse Cholesky factorisation, L−1 solves) → measurements in protocol
//! order. Everything is in SI units (m, S/m, Ω·m², A, V); no I/O happens here (see `eitskin-io`).
//!
//! ```
//! use eitskin::{conductivity::{with_inclusions, Inclusion}, SensorSpec};
//! let spec = SensorSpec::square_hydrogel();          // 200 mm square, 16 electrodes, 120 pairs
//! let model = spec.forward_model()?;                  // mesh + FEM + complete electrode model
//! let v_ref = model.measure(&spec.homogeneous(model.mesh()))?;
//! let press = Inclusion { centre: [0.05, 0.0], radius: 0.01, conductivity: 0.5 };
//! let v = model.measure(&with_inclusions(model.mesh(), 1.0, &[press]))?;
//! assert_eq!(v.len(), 120);
//! // A less conductive spot raises every two-terminal transfer impedance (Ω at 1 A).
//! assert!(v.iter().zip(&v_ref).all(|(a, b)| a >= b));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Not for: reading files or ports (that is `eitskin-io`), or anything per frame that
//! allocates.

#![deny(missing_docs)]
#![warn(rustdoc::broken_intra_doc_links)]
#![cfg_attr(not(test), warn(clippy::unwrap_used, clippy::expect_used))]

/// The linear-algebra crate whose matrices appear in this API (Jacobians, reconstruction matrices).
pub use faer;

pub mod analytic;
pub mod conductivity;
pub mod convergence;
pub mod forward;
pub mod geometry;
pub mod image;
pub mod inverse;
pub mod mesh;
pub mod protocol;
pub mod sensitivity;
pub mod spec;
pub mod touch;

pub use forward::{ElectrodeModel, ForwardError, ForwardModel, ForwardSolution};
pub use geometry::{Electrode, Outline};
pub use image::Image;
pub use inverse::{InverseError, Prior, Reconstructor, ReconstructorParams};
pub use mesh::{Mesh, MeshError, MeshParams, PointLocator, RasterMap};
pub use protocol::{Measurement, Protocol, ProtocolError};
pub use spec::{ElectrodeSpec, LengthUnit, Placement, ProtocolSpec, SensorSpec, SpecError};
pub use touch::{Touch, TouchParams};
