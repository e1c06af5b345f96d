//! The raster reconstructor: the reconstruction matrix projected once onto a pixel grid, so a
//! frame is one pixels × measurements product into a caller-owned [`Image`].
//!
//! Pixel p takes the value of the triangle under its centre, so row p of the raster matrix is
//! that triangle's row of the element-level matrix; pixels outside the outline are masked.
//! The matrix is kept in f32: half the memory traffic of f64, and images agree with the f64
//! product to about 1e-7 of their peak (tested to 1e-5).

use super::{normalize_jacobian, reconstruction_matrix, InverseError, Prior};
use crate::forward::ForwardModel;
use crate::image::Image;
use crate::mesh::RasterMap;

/// How to build a [`Reconstructor`]; `Default` is the paper's: NOSER (p = 0.5), λ = 0.1,
/// absolute differences, 64 × 64 pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReconstructorParams {
    /// The prior R.
    pub prior: Prior,
    /// The hyperparameter λ (dimensionless; λ² multiplies R).
    pub hyperparameter: f64,
    /// Normalised differences Δv/v_ref instead of absolute ones.
    pub normalized: bool,
    /// Raster columns and rows `[nx, ny]` over the mesh's bounding box.
    pub raster: [usize; 2],
}

impl Default for ReconstructorParams {
    fn default() -> Self {
        ReconstructorParams { prior: Prior::default(), hyperparameter: 0.1, normalized: false, raster: [64, 64] }
    }
}

/// The precomputed one-step Gauss–Newton reconstructor on a raster (EIDORS' `RM`, pyEIT's `H`).
/// Not for iterative (absolute) reconstruction: it is linearised once at the background.
#[derive(Debug, Clone, PartialEq)]
pub struct Reconstructor {
    params: ReconstructorParams,
    template: Image,
    /// Pixels × measurements, column-major (one column per measurement), S/m per V (per unit
    /// ratio when normalised).
    matrix: Vec<f32>,
    /// Number of measurements (columns of `matrix`).
    measurements: usize,
}

impl Reconstructor {
    /// Linearises `model` at the homogeneous `background` conductivity (S/m) and projects the
    /// reconstruction matrix onto the raster.
    pub fn new(
        model: &ForwardModel,
        background: f64,
        params: &ReconstructorParams,
    ) -> Result<Reconstructor, InverseError> {
        let sigma = vec![background; model.mesh().triangles().len()];
        // The background is positive and the count right: the forward model accepts it.
        let solution = model.solve(&sigma)?;
        let mut jacobian = model.jacobian(&solution);
        if params.normalized {
            normalize_jacobian(&mut jacobian, &solution.measurements(model.protocol()))?;
        }
        let element = reconstruction_matrix(jacobian.as_ref(), &params.prior, params.hyperparameter, model.mesh())?;
        let map = RasterMap::new(model.mesh(), params.raster);
        let inside: Vec<bool> = map.triangle.iter().map(Option::is_some).collect();
        let template = Image::new(map.size, map.bounds, inside);
        let measurements = element.ncols();
        let element = &element;
        let matrix = (0..measurements)
            .flat_map(|m| map.triangle.iter().map(move |t| t.map_or(0.0, |t| element[(t, m)] as f32)))
            .collect();
        Ok(Reconstructor { params: *params, template, matrix, measurements })
    }

    /// A reconstructor from its parts, as saved by [`Reconstructor::matrix`] and
    /// [`Reconstructor::blank_image`]; `None` if the sizes disagree.
    pub fn from_parts(params: ReconstructorParams, template: Image, matrix: Vec<f32>) -> Option<Reconstructor> {
        let pixels = template.size[0] * template.size[1];
        let consistent = pixels > 0
            && template.values.len() == pixels
            && template.inside.len() == pixels
            && !matrix.is_empty()
            && matrix.len().is_multiple_of(pixels);
        consistent.then(|| Reconstructor { params, measurements: matrix.len() / pixels, template, matrix })
    }

    /// The raster matrix: pixels × measurements, column-major, in S/m per V.
    pub fn matrix(&self) -> &[f32] {
        &self.matrix
    }

    /// The parameters it was built with.
    pub fn params(&self) -> &ReconstructorParams {
        &self.params
    }

    /// Number of measurements a frame must have.
    pub fn measurements(&self) -> usize {
        self.measurements
    }

    /// An all-zero image of the right size and mask, to pass to [`Reconstructor::image_into`].
    pub fn blank_image(&self) -> Image {
        self.template.clone()
    }

    /// The conductivity-change image (S/m) of frame `v` against the reference frame `v_ref`.
    pub fn image(&self, v_ref: &[f64], v: &[f64]) -> Result<Image, InverseError> {
        let mut image = self.blank_image();
        self.image_into(v_ref, v, &mut image)?;
        Ok(image)
    }

    /// [`Reconstructor::image`] into a caller-owned image (from [`Reconstructor::blank_image`]);
    /// allocates nothing.
    pub fn image_into(&self, v_ref: &[f64], v: &[f64], image: &mut Image) -> Result<(), InverseError> {
        let expected = self.measurements();
        for frame in [v_ref, v] {
            if frame.len() != expected {
                return Err(InverseError::FrameLength { expected, got: frame.len() });
            }
            if let Some(m) = frame.iter().position(|x| !x.is_finite()) {
                return Err(InverseError::NotFinite { measurement: m + 1 });
            }
        }
        if self.params.normalized {
            if let Some(m) = v_ref.iter().position(|x| *x == 0.0) {
                return Err(InverseError::ZeroReference { measurement: m + 1 });
            }
        }
        let pixels = self.template.values.len();
        assert_eq!(image.values.len(), pixels, "the image must come from blank_image()");
        image.values.fill(0.0);
        let normalized = self.params.normalized;
        let difference = |m: usize| if normalized { v[m] / v_ref[m] - 1.0 } else { v[m] - v_ref[m] } as f32;
        accumulate(&mut image.values, &self.matrix, difference);
        Ok(())
    }
}

/// values += Σ_m matrix[:, m]·difference(m), the matrix column-major with `values.len()` rows;
/// with 8-lane AVX2 where the processor has it (checked at run time), else portable code.
#[allow(unsafe_code, reason = "calls the AVX2 kernel, only once the processor is known to have AVX2")]
fn accumulate(values: &mut [f32], matrix: &[f32], difference: impl Fn(usize) -> f32) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the features the function is compiled for were just detected.
        unsafe { accumulate_avx2(values, matrix, difference) };
        return;
    }
    accumulate_portable(values, matrix, difference);
}

#[inline(always)]
fn accumulate_portable(values: &mut [f32], matrix: &[f32], difference: impl Fn(usize) -> f32) {
    for (m, column) in matrix.chunks_exact(values.len()).enumerate() {
        let d = difference(m);
        for (pixel, h) in values.iter_mut().zip(column) {
            *pixel += h * d;
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn accumulate_avx2(values: &mut [f32], matrix: &[f32], difference: impl Fn(usize) -> f32) {
    // The same loop, compiled for 8-lane vectors.
    accumulate_portable(values, matrix, difference);
}
