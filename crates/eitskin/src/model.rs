//! The sensor and its physics: the spec, its outline and electrodes, the mesh, the protocol,
//! conductivities, the forward model (with analytic checks) and the virtual sensor that simulates
//! its frames.

pub mod analytic;
pub mod conductivity;
pub mod forward;
pub mod geometry;
pub mod mesh;
pub mod mount;
pub mod protocol;
pub mod sim;
pub mod spec;
