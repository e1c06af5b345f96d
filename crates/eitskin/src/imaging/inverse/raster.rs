//! The raster reconstructor: the reconstruction matrix projected once onto a pixel grid, so a
//! frame is one pixels × measurements product into a caller-owned [`Image`].
//!
//! Pixel p takes the value of the triangle under its centre, so row p of the raster matrix is
//! that triangle's row of the element-level matrix; pixels outside the outline are masked.
//! The matrix is kept in f32: half the memory traffic of f64, and images agree with the f64
//! product to about 1e-7 of their peak (tested to 1e-5).
//!
//! A reconstructor keeps the [`Linearisation`] it came from, so another λ, other channels (a
//! channel gone bad, a mask), other noise weights or another raster follow from it in
//! milliseconds ([`Reconstructor::derive`]), without a forward solve.

use std::sync::Arc;

use faer::Mat;

use super::eigensystem::Eigensystem;
use super::product::BlockedMatrix;
use super::shared_basis::ChannelMix;
use super::{Channels, InverseError, Linearisation, Prior};
use crate::forward::ForwardModel;
use crate::image::Image;
use crate::mesh::RasterMap;

/// The largest magnitude a frame's value may have, in the frame's unit (V, Ω or S): the image is
/// single precision, and differences past this would overflow it.
pub const LARGEST_VALUE: f64 = 1e30;

/// How to build a [`Reconstructor`]; `Default` is the paper's: NOSER (p = 0.5), λ = 0.1,
/// absolute differences, 64 × 64 pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReconstructorParams {
    /// The prior R.
    pub prior: Prior,
    /// The hyperparameter λ (dimensionless; λ² multiplies R).
    pub hyperparameter: f64,
    /// Normalised differences Δv/v_ref instead of absolute ones.
    pub normalised: bool,
    /// Raster columns and rows `[nx, ny]` over the mesh's bounding box.
    pub raster: [usize; 2],
    /// Estimate a uniform change of the background conductivity (warming water, a drying gel)
    /// with each image and leave it out of the image ([`Reconstructor::background_change`]).
    pub background_change: bool,
}

impl Default for ReconstructorParams {
    fn default() -> Self {
        ReconstructorParams {
            prior: Prior::default(),
            hyperparameter: 0.1,
            normalised: false,
            raster: [64, 64],
            background_change: false,
        }
    }
}

/// The precomputed one-step Gauss–Newton reconstructor on a raster (EIDORS' `RM`, pyEIT's `H`).
/// Not for iterative (absolute) reconstruction: it is linearised once at the background.
#[derive(Debug, Clone, PartialEq)]
pub struct Reconstructor {
    params: ReconstructorParams,
    linearisation: Arc<Linearisation>,
    channels: Channels,
    template: Image,
    /// Triangle under each pixel centre (`None` outside).
    pixels: Vec<Option<usize>>,
    /// Pixels × measurements, column-major (one column per measurement), S/m per V (per unit
    /// ratio when normalised); zero columns for dropped channels.
    matrix: BlockedMatrix,
    /// Triangles × measurements, column-major, in the same units.
    elements: BlockedMatrix,
    /// The row that gives the background change from Δv (S/m per V); empty when not estimated.
    background: Vec<f64>,
    /// Number of measurements (columns of `matrix`).
    measurements: usize,
    /// Its own mix M for a basis its channel set shares (`matrix` = B·M on the used columns),
    /// where λ was chosen on the whole eigensystem; see [`super::shared_basis`].
    mix: Option<Arc<ChannelMix>>,
    /// The shared basis B, while frames are imaged through it ([`Reconstructor::set_shared_basis`]).
    shared_basis: Option<Arc<BlockedMatrix>>,
}

impl Reconstructor {
    /// Linearises `model` at the homogeneous `background` conductivity (S/m) and projects the
    /// reconstruction matrix onto the raster; every channel used, equally weighted.
    pub fn new(
        model: &ForwardModel,
        background: f64,
        params: &ReconstructorParams,
    ) -> Result<Reconstructor, InverseError> {
        let linearisation = Linearisation::new(model, background)?;
        let channels = Channels::all(linearisation.measurements());
        Reconstructor::from_linearisation(Arc::new(linearisation), params, channels)
    }

    /// A reconstructor from a linearisation, for these parameters and channels.
    pub fn from_linearisation(
        linearisation: Arc<Linearisation>,
        params: &ReconstructorParams,
        channels: Channels,
    ) -> Result<Reconstructor, InverseError> {
        let map = RasterMap::new(linearisation.mesh(), params.raster);
        let inside: Vec<bool> = map.triangle.iter().map(Option::is_some).collect();
        let template = Image::new(map.size, map.bounds, inside);
        Reconstructor::assemble(linearisation, params, channels, template, map.triangle)
    }

    fn assemble(
        linearisation: Arc<Linearisation>,
        params: &ReconstructorParams,
        channels: Channels,
        template: Image,
        pixels: Vec<Option<usize>>,
    ) -> Result<Reconstructor, InverseError> {
        let compact = linearisation.compact_matrix(params, &channels)?;
        Reconstructor::assemble_compact(linearisation, params, channels, template, pixels, compact)
    }

    /// [`Reconstructor::assemble`] from its matrix on the triangles (triangles × used channels).
    fn assemble_compact(
        linearisation: Arc<Linearisation>,
        params: &ReconstructorParams,
        channels: Channels,
        template: Image,
        pixels: Vec<Option<usize>>,
        compact: Mat<f64>,
    ) -> Result<Reconstructor, InverseError> {
        let background = if params.background_change {
            let row = linearisation.compact_background_change_row(compact.as_ref(), params.normalised, &channels)?;
            let mut full = vec![0.0; channels.len()];
            for (r, m) in row.into_iter().zip(channels.used()) {
                full[m] = r;
            }
            full
        } else {
            Vec::new()
        };
        // Columns of H for the used channels, zero columns for the dropped, in f32: per pixel
        // the triangle under it, and per triangle as it is.
        let measurements = channels.len();
        let mut columns: Vec<&[f64]> = vec![&[]; measurements];
        for (i, m) in channels.used().into_iter().enumerate() {
            // Owned matrices are stored column by column, so a column is one slice.
            columns[m] = compact.col(i).try_as_col_major().map(|c| c.as_slice()).unwrap_or_default();
        }
        let mut elements = BlockedMatrix::zeros(compact.nrows(), measurements);
        for (first, m, lanes) in elements.blocks_mut() {
            lanes.iter_mut().zip(columns[m].get(first..).unwrap_or_default()).for_each(|(x, h)| *x = *h as f32);
        }
        crate::parallel::step_aside();
        let mut matrix = BlockedMatrix::zeros(pixels.len(), measurements);
        for (first, m, lanes) in matrix.blocks_mut().filter(|(_, m, _)| !columns[*m].is_empty()) {
            let column = columns[m];
            let under = pixels[first..].iter().map(|t| t.and_then(|t| column.get(t)).map_or(0.0, |h| *h as f32));
            lanes.iter_mut().zip(under).for_each(|(x, h)| *x = h);
        }
        Ok(Reconstructor {
            params: *params,
            linearisation,
            channels,
            template,
            pixels,
            matrix,
            elements,
            background,
            measurements,
            mix: None,
            shared_basis: None,
        })
    }

    /// The same reconstructor with another λ and other channels (milliseconds: one system the
    /// size of the measurement count, no forward solve).
    pub fn derive(&self, hyperparameter: f64, channels: Channels) -> Result<Reconstructor, InverseError> {
        let params = ReconstructorParams { hyperparameter, ..self.params };
        Reconstructor::assemble(
            Arc::clone(&self.linearisation),
            &params,
            channels,
            self.template.clone(),
            self.pixels.clone(),
        )
    }

    /// The same reconstructor with other parameters (prior, λ, normalisation, raster) and channels.
    pub fn rederive(&self, params: &ReconstructorParams, channels: Channels) -> Result<Reconstructor, InverseError> {
        if params.raster == self.params.raster {
            let (template, pixels) = (self.template.clone(), self.pixels.clone());
            return Reconstructor::assemble(Arc::clone(&self.linearisation), params, channels, template, pixels);
        }
        Reconstructor::from_linearisation(Arc::clone(&self.linearisation), params, channels)
    }

    /// The raster matrix: pixels × measurements, in S/m per V.
    pub fn matrix(&self) -> &BlockedMatrix {
        &self.matrix
    }

    /// Images frames ([`Reconstructor::image_into`]) from a half-precision copy of the matrix
    /// when `on`: half the memory a frame reads, each pixel within about 2⁻¹¹·Σ|H·Δv| of the
    /// single-precision image (see [`BlockedMatrix::keep_half`]), on the calling core. For many
    /// sensors on few cores, whose matrices do not share the cache. Allocates the copy.
    pub fn set_half_precision(&mut self, on: bool) {
        match on {
            true => self.matrix.keep_half(),
            false => self.matrix.drop_half(),
        }
    }

    /// Whether frames are imaged from a half-precision copy of the matrix.
    pub fn half_precision(&self) -> bool {
        self.matrix.is_half()
    }

    /// Images frames through the basis R⁻¹ J_Sᵀ that every reconstructor of its linearisation
    /// and channels shares, times its own channels² mix, when `on` and it has one (λ chosen
    /// from the noise, at most 256 channels, no background change: see
    /// [`Reconstructor::with_auto_hyperparameter`], on no more channels than the electrodes
    /// have pairs); whether frames now go through it. For many sensors of one spec in one
    /// process (one linearisation): they read one basis where each would read its own matrix.
    /// Each pixel within the rounding of B·(M·Δv) in single precision of the matrix's image.
    /// Allocates (the basis, once for the channel set and raster).
    pub fn set_shared_basis(&mut self, on: bool) -> bool {
        self.shared_basis = match (on, &self.mix) {
            (true, Some(mix)) => Some(mix.basis(&self.linearisation, &self.pixels)),
            _ => None,
        };
        self.shared_basis.is_some()
    }

    /// Whether frames are imaged through a shared basis ([`Reconstructor::set_shared_basis`]).
    pub fn shared_basis(&self) -> bool {
        self.shared_basis.is_some()
    }

    /// Whether it has a mix for a shared basis, so that [`Reconstructor::set_shared_basis`] can
    /// turn it on.
    pub fn can_share_basis(&self) -> bool {
        self.mix.is_some()
    }

    /// The shared basis frames are imaged through, if they are (for tests: who shares it).
    #[cfg(test)]
    pub(crate) fn basis(&self) -> Option<&Arc<BlockedMatrix>> {
        self.shared_basis.as_ref()
    }

    /// The same reconstructor with λ chosen from the noise (see [`choose_hyperparameter`](super::choose_hyperparameter))
    /// and the channels weighted by it ([`Linearisation::noise_weighted`]). Returns it with λ.
    pub fn with_auto_hyperparameter(
        &self,
        channels: Channels,
        relative: Option<Vec<f64>>,
    ) -> Result<(Reconstructor, f64), InverseError> {
        let lin = &self.linearisation;
        let normalised = self.params.normalised;
        let channels = lin.noise_weighted(normalised, channels, relative);
        let prior = &self.params.prior;
        let system = Eigensystem::new(lin, prior, normalised, &channels)?;
        crate::parallel::step_aside();
        let lambda = super::hyperparameter::choose_hyperparameter_on(lin, &channels, &system);
        crate::parallel::step_aside();
        // The matrix at λ from the eigenpairs λ was chosen on (with a global change fitted
        // beside the image, the Jacobian projected first: derived afresh).
        if self.params.background_change {
            return Ok((self.derive(lambda, channels)?, lambda));
        }
        let params = ReconstructorParams { hyperparameter: lambda, ..self.params };
        let (template, pixels) = (self.template.clone(), self.pixels.clone());
        let (compact, mix) = system.compact_matrix_and_mix(lin, lambda)?;
        crate::parallel::step_aside();
        let mut recon = Reconstructor::assemble_compact(Arc::clone(lin), &params, channels, template, pixels, compact)?;
        recon.mix = mix.map(Arc::new);
        Ok((recon, lambda))
    }

    /// The linearisation it was derived from.
    pub fn linearisation(&self) -> &Arc<Linearisation> {
        &self.linearisation
    }

    /// The channels it uses and their weights.
    pub fn channels(&self) -> &Channels {
        &self.channels
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

    /// The conductivity change (S/m) at one pixel of the image of `v` against `v_ref`, without
    /// the rest of the image: a row of the image matrix. Panics if `pixel` is not one of the
    /// raster's (a caller contract).
    #[track_caller]
    pub fn pixel_value(&self, v_ref: &[f64], v: &[f64], pixel: usize) -> Result<f32, InverseError> {
        assert!(pixel < self.template.values.len(), "pixel {pixel} is beyond the raster");
        self.check(v_ref, v)?;
        Ok((0..self.measurements).map(|m| self.matrix.get(pixel, m) * self.difference(v_ref, v, m)).sum())
    }

    /// The conductivity change on each triangle of the mesh (S/m), in mesh order.
    pub fn element_values(&self, v_ref: &[f64], v: &[f64]) -> Result<Vec<f32>, InverseError> {
        self.check(v_ref, v)?;
        let mut values = vec![0.0; self.linearisation.mesh().triangles().len()];
        self.elements.mul_into(&mut values, |m| self.difference(v_ref, v, m));
        Ok(values)
    }

    /// The uniform change of the background conductivity (S/m) between `v_ref` and `v`,
    /// estimated with the image and left out of it; `None` unless built with
    /// [`ReconstructorParams::background_change`]. Allocates nothing.
    pub fn background_change(&self, v_ref: &[f64], v: &[f64]) -> Result<Option<f64>, InverseError> {
        if self.background.is_empty() {
            return Ok(None);
        }
        self.check(v_ref, v)?;
        let delta = self.background.iter().enumerate().map(|(m, r)| r * f64::from(self.difference(v_ref, v, m))).sum();
        Ok(Some(delta))
    }

    /// [`Reconstructor::image`] into a caller-owned image (from [`Reconstructor::blank_image`]);
    /// allocates nothing.
    pub fn image_into(&self, v_ref: &[f64], v: &[f64], image: &mut Image) -> Result<(), InverseError> {
        self.check(v_ref, v)?;
        let pixels = self.template.values.len();
        assert_eq!(image.values.len(), pixels, "the image must come from blank_image()");
        let difference = |m| self.difference(v_ref, v, m);
        match (&self.shared_basis, &self.mix) {
            (Some(basis), Some(mix)) => mix.mul_into(basis, &mut image.values, difference),
            _ => self.matrix.mul_into(&mut image.values, difference),
        }
        Ok(())
    }

    /// The pixel values of the images of several `frames` against one reference `v_ref`, in
    /// S/m (pixels × frames; 0 outside the outline): one matrix product, the matrix read once
    /// for all of them. Refuses what [`Reconstructor::image`] refuses, the reference first, then
    /// the first frame refused (the error names its channel, not the frame).
    pub fn image_values_of(&self, v_ref: &[f64], frames: &[&[f64]]) -> Result<Mat<f32>, InverseError> {
        self.check(v_ref, v_ref)?;
        for v in frames {
            self.check(v_ref, v)?;
        }
        let d = Mat::from_fn(self.measurements(), frames.len(), |m, f| self.difference(v_ref, frames[f], m));
        let mut values = Mat::zeros(self.template.values.len(), frames.len());
        self.matrix.mul_frames_into(d.as_ref(), values.as_mut());
        Ok(values)
    }

    /// The difference of channel m that the matrix multiplies: 0 for a dropped channel.
    #[inline(always)]
    fn difference(&self, v_ref: &[f64], v: &[f64], m: usize) -> f32 {
        if !self.channels.is_used(m) {
            0.0
        } else if self.params.normalised {
            (v[m] / v_ref[m] - 1.0) as f32
        } else {
            (v[m] - v_ref[m]) as f32
        }
    }

    /// Refuses frames of the wrong length, and non-finite or (normalised) zero values on a used channel.
    fn check(&self, v_ref: &[f64], v: &[f64]) -> Result<(), InverseError> {
        let expected = self.measurements();
        for frame in [v_ref, v] {
            if frame.len() != expected {
                return Err(InverseError::FrameLength { expected, got: frame.len() });
            }
            let bad = |(m, x): (usize, &f64)| self.channels.is_used(m) && !x.is_finite();
            if let Some((m, _)) = frame.iter().enumerate().find(|&p| bad(p)) {
                return Err(InverseError::NotFinite { measurement: m + 1 });
            }
            let huge = |(m, x): (usize, &f64)| self.channels.is_used(m) && x.abs() > LARGEST_VALUE;
            if let Some((m, x)) = frame.iter().enumerate().find(|&p| huge(p)) {
                return Err(InverseError::TooLarge { measurement: m + 1, value: *x });
            }
        }
        if self.params.normalised {
            let zero = |(m, x): (usize, &f64)| self.channels.is_used(m) && *x == 0.0;
            if let Some((m, _)) = v_ref.iter().enumerate().find(|&p| zero(p)) {
                return Err(InverseError::ZeroReference { measurement: m + 1 });
            }
        }
        Ok(())
    }
}
