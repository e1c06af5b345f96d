//! What the setup chain needs in memory, estimated from the mesh's size before anything is
//! built, so that a job too large for the machine is refused with the size it would need
//! instead of growing until the system kills it.
//!
//! The figures are peak resident sizes measured with `/usr/bin/time -f %M` on the paper's
//! sensor (16 electrodes, 120 measurements) at 20k, 80k and 400k triangles, per triangle, with
//! about a third added for the allocator and other outlines: meshing (spade's refinement
//! included) took 430–500 B a triangle, a forward model (assembly and sparse Cholesky factor)
//! 610–630 B, a reconstructor 5.7 kB at 120 measurements (its dense matrices: about six
//! numbers per triangle and measurement).
//!
//! ```
//! use eitskin::memory::{needed_bytes, Stage};
//! let gb = needed_bytes(Stage::Mesh, 50e6, 120) / 1e9;
//! assert!(gb > 30.0 && gb < 35.0);
//! ```

/// Bytes a triangle takes while the mesh is generated.
const MESH_PER_TRIANGLE: f64 = 650.0;
/// Bytes a triangle takes at the forward model's peak (its mesh included).
const MODEL_PER_TRIANGLE: f64 = 820.0;
/// Bytes per triangle and measurement of the reconstructor's dense matrices, on top of the
/// forward model.
const RECONSTRUCTOR_PER_ENTRY: f64 = 56.0;
/// Bytes any job takes whatever its mesh: the program, rasters, buffers.
const BASE: f64 = 64e6;
/// Bytes per pixel and measurement of a reconstructor's image matrix (f32).
const RASTER_PER_ENTRY: f64 = 4.0;

/// An image raster too large for the memory available.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "a raster of {nx} × {ny} pixels at {measurements} measurements needs about {needed:.1} GB of memory, and {available:.1} GB is available: ask for fewer pixels"
)]
pub struct RasterTooLarge {
    /// Pixels along x.
    pub nx: usize,
    /// Pixels along y.
    pub ny: usize,
    /// Measurements of a frame.
    pub measurements: usize,
    /// Memory the image matrix needs, in GB.
    pub needed: f64,
    /// Memory available, in GB.
    pub available: f64,
}

/// Refuses a `raster` (nx, ny) whose image matrix at `measurements` measurements would not fit
/// in `available` bytes (where known), before it is allocated.
pub fn check_raster(raster: [usize; 2], measurements: usize, available: Option<f64>) -> Result<(), RasterTooLarge> {
    let [nx, ny] = raster;
    let needed = RASTER_PER_ENTRY * nx as f64 * ny as f64 * measurements as f64;
    match available {
        Some(available) if needed > available => {
            Err(RasterTooLarge { nx, ny, measurements, needed: needed / 1e9, available: available / 1e9 })
        }
        _ => Ok(()),
    }
}

/// A stage of the setup chain; each includes the ones before it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// The mesh alone.
    Mesh,
    /// The mesh and the forward model on it.
    ForwardModel,
    /// The mesh, the forward model and the one-step reconstructor.
    Reconstructor,
}

impl Stage {
    /// What the stage builds, in words: "a mesh", "a forward model", "a reconstructor".
    pub fn name(self) -> &'static str {
        match self {
            Stage::Mesh => "a mesh",
            Stage::ForwardModel => "a forward model",
            Stage::Reconstructor => "a reconstructor",
        }
    }

    fn per_triangle(self, measurements: usize) -> f64 {
        match self {
            Stage::Mesh => MESH_PER_TRIANGLE,
            Stage::ForwardModel => MODEL_PER_TRIANGLE,
            Stage::Reconstructor => MODEL_PER_TRIANGLE + RECONSTRUCTOR_PER_ENTRY * measurements as f64,
        }
    }
}

/// Estimated peak memory, in bytes, of building `stage` on a mesh of `triangles` triangles
/// for a protocol of `measurements` measurements.
pub fn needed_bytes(stage: Stage, triangles: f64, measurements: usize) -> f64 {
    BASE + stage.per_triangle(measurements) * triangles
}

/// The most triangles `stage` can be built on in `bytes` of memory (0 when not even the base
/// fits).
pub fn most_triangles(stage: Stage, bytes: f64, measurements: usize) -> f64 {
    ((bytes - BASE) / stage.per_triangle(measurements)).max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_raster_is_refused_where_its_image_matrix_would_not_fit() {
        // 4096 × 4096 pixels at 120 measurements: 8.05 GB of f32.
        let err = check_raster([4096, 4096], 120, Some(6e9)).unwrap_err();
        assert!((err.needed - 8.053).abs() < 1e-3, "{err}");
        assert!(err.to_string().starts_with("a raster of 4096 × 4096 pixels at 120 measurements needs about 8.1 GB"));
        assert!(check_raster([4096, 4096], 120, Some(9e9)).is_ok() && check_raster([4096, 4096], 120, None).is_ok());
    }

    #[test]
    fn most_triangles_inverts_the_estimate() {
        for stage in [Stage::Mesh, Stage::ForwardModel, Stage::Reconstructor] {
            let bytes = needed_bytes(stage, 1e6, 120);
            assert!((most_triangles(stage, bytes, 120) - 1e6).abs() < 1e-3);
        }
        assert_eq!(most_triangles(Stage::Mesh, 1e6, 120), 0.0);
        assert!(needed_bytes(Stage::Reconstructor, 1e5, 120) > needed_bytes(Stage::ForwardModel, 1e5, 120));
    }
}
