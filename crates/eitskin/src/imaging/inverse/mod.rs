//! The inverse model: one-step Gauss–Newton difference reconstruction (the paper's eq. 1),
//!
//!   Δσ = (JᵀWJ + λ²R)⁻¹JᵀW·Δv,  W = I,
//!
//! with J the Jacobian at the background, R a [`Prior`] and λ the hyperparameter (EIDORS
//! `inv_solve_diff_GN_one_step`; note λ is squared). With R diagonal the same matrix is
//!
//!   R⁻¹Jᵀ(JR⁻¹Jᵀ + λ²I)⁻¹,
//!
//! since (JᵀJ + λ²R)·R⁻¹Jᵀ = Jᵀ(JR⁻¹Jᵀ + λ²I): a system the size of the measurement count
//! (120) instead of the triangle count. Normalised differences (EIDORS
//! `normalize_measurements`) use Δv_m / v_ref,m and J's rows divided by the model's v_m.
//!
//! [`reconstruction_matrix`] gives the element-level matrix; [`Reconstructor`] projects it
//! once onto a raster so that a frame costs one pixels × measurements product.

mod channel_products;
mod channels;
mod criterion;
mod eigensystem;
mod hyperparameter;
mod linearisation;
mod noise_model;
mod prior;
mod product;
mod raster;
mod reference;
mod shared_basis;

pub(crate) use channels::floored;
pub use channels::{
    mean_frame, mean_of_finite, noise_variance, plausible_ratio, typical_ratio, typical_ratio_in,
    typical_ratio_of_frames, Channels, SCALE_LIMIT,
};
pub use criterion::{data_hyperparameter, DataCriterion};
pub use hyperparameter::{
    choose_hyperparameter, hyperparameter_in_range, map_hyperparameter, noise_figure, noise_figure_hyperparameter,
    Hyperparameter, DEFAULT_RELATIVE_NOISE, LARGEST_HYPERPARAMETER, NOISE_FIGURE_TARGET, SMALLEST_HYPERPARAMETER,
    TARGET_CONTRAST,
};
pub use linearisation::Linearisation;
pub use noise_model::NoiseModel;
pub use prior::Prior;
pub use product::BlockedMatrix;
pub use raster::LARGEST_VALUE;
pub use raster::{Reconstructor, ReconstructorParams};
pub use reference::{mark_missing, HyperparameterRule, Reference, Weighting, WeightingUsed};

use faer::{Mat, MatRef};
use thiserror::Error;

use crate::mesh::Mesh;

/// What is wrong with an inverse model or a frame; measurements are counted from 1.
#[derive(Debug, Error, PartialEq)]
pub enum InverseError {
    /// The hyperparameter must be positive and finite.
    #[error("the hyperparameter λ must be positive and finite, got {0}")]
    Hyperparameter(f64),
    /// The forward model could not be solved (at the background, or with an inclusion).
    #[error("the forward model could not be solved")]
    Forward(#[from] crate::forward::ForwardError),
    /// The system (JR⁻¹Jᵀ + λ²I or JᵀJ + λ²R) could not be factored.
    #[error("the regularised system is not positive definite; raise the hyperparameter or check the prior")]
    NotPositiveDefinite,
    /// A frame has the wrong number of values.
    #[error("a frame has {got} values but the protocol has {expected} measurements")]
    FrameLength {
        /// Measurements in the protocol.
        expected: usize,
        /// Values in the frame.
        got: usize,
    },
    /// A frame value is NaN or infinite.
    #[error("measurement {measurement} of the frame is not a finite number")]
    NotFinite {
        /// 1-based measurement.
        measurement: usize,
    },
    /// A frame value is larger than any measurement ([`LARGEST_VALUE`]).
    #[error(
        "measurement {measurement} of the frame is {value:e}, past {LARGEST_VALUE:e} in size: not a measurement \
         (the image would overflow)"
    )]
    TooLarge {
        /// 1-based measurement.
        measurement: usize,
        /// The value, in the frame's unit.
        value: f64,
    },
    /// Every channel is dropped (masked, missing or without a usable noise estimate).
    #[error("no channel is left to image with: every measurement is masked, missing or not finite")]
    NoChannels,
    /// The automatic hyperparameter needs a diagonal prior (NOSER or Tikhonov).
    #[error("the hyperparameter can be chosen from the noise only with a diagonal prior (NOSER or Tikhonov); give λ")]
    AutoNeedsDiagonalPrior,
    /// The discrepancy principle needs the noise's level.
    #[error("the discrepancy principle needs the noise's level: measured from reference frames, or assumed")]
    DiscrepancyNeedsNoise,
    /// More than a quarter of a frame's channels are missing or not finite, counting those
    /// dropped before: the frame is refused.
    #[error(
        "{bad} of {channels} channels are missing or not finite ({new} of them new in this frame; \
         first: {first:?}), more than a quarter: the frame is refused; check the board and its \
         wiring, then re-take the reference"
    )]
    TooManyBadChannels {
        /// Channels bad in this frame or dropped before.
        bad: usize,
        /// Of those, the ones bad for the first time in this frame.
        new: usize,
        /// Channels in a frame.
        channels: usize,
        /// The first bad channels (at most 8), 1-based.
        first: Vec<usize>,
    },
    /// Normalised differences divide by the reference, which must not be zero.
    #[error("measurement {measurement} of the reference frame is zero, so it cannot be normalised")]
    ZeroReference {
        /// 1-based measurement.
        measurement: usize,
    },
    /// A frame whose values are typically far from, or of the other sign than, its reference's
    /// ([`typical_ratio`]): another unit, gain or board, not a press.
    #[error(
        "the frame's values are typically {ratio:.3e} times the reference's (the median over channels); a press changes them by percents: is the board sending what it sent for the reference?{}",
        if *restarted { " The reference starts again from the next frame." } else { "" }
    )]
    FrameScale {
        /// The typical ratio.
        ratio: f64,
        /// Whether the frame came while the reference was taken, which then starts again.
        restarted: bool,
    },
    /// A Jacobian (or the background it is normalised by) whose shape does not fit.
    #[error("the Jacobian is {rows} × {columns}, but {expected}")]
    JacobianShape {
        /// Its rows (measurements).
        rows: usize,
        /// Its columns (triangles).
        columns: usize,
        /// What it must match, in words.
        expected: String,
    },
    /// A Jacobian entry, background value or prior exponent that is NaN or infinite.
    #[error("{what} is not a finite number")]
    NotFiniteInput {
        /// Which value, in words ("Jacobian entry (3, 7)").
        what: String,
    },
}

/// The element-level reconstruction matrix (triangles × measurements, S/m per V) of
/// Δσ = (JᵀJ + λ²R)⁻¹JᵀΔv; diagonal priors go through the measurement-sized system.
pub fn reconstruction_matrix(
    jacobian: MatRef<'_, f64>,
    prior: &Prior,
    hyperparameter: f64,
    mesh: &Mesh,
) -> Result<Mat<f64>, InverseError> {
    check_hyperparameter(hyperparameter)?;
    check_jacobian(jacobian, prior, mesh)?;
    linearisation::weighted(jacobian, prior, hyperparameter, &vec![1.0; jacobian.nrows()], mesh)
}

/// (JᵀJ + λ²R)⁻¹Jᵀ through the triangles × triangles system: for non-diagonal priors, and to
/// check the measurement-sized form.
pub fn element_sized(
    jacobian: MatRef<'_, f64>,
    prior: &Prior,
    hyperparameter: f64,
    mesh: &Mesh,
) -> Result<Mat<f64>, InverseError> {
    check_hyperparameter(hyperparameter)?;
    check_jacobian(jacobian, prior, mesh)?;
    linearisation::weighted_element_sized(jacobian, prior, hyperparameter, &vec![1.0; jacobian.nrows()], mesh)
}

/// Refuses a Jacobian that is not measurements × `mesh`'s triangles (at least one of each) or
/// holds a value that is not finite, and a NOSER exponent that is not finite.
fn check_jacobian(jacobian: MatRef<'_, f64>, prior: &Prior, mesh: &Mesh) -> Result<(), InverseError> {
    let (rows, columns) = (jacobian.nrows(), jacobian.ncols());
    if rows == 0 || columns != mesh.triangles().len() {
        let expected =
            format!("it must have a row per measurement and a column per triangle ({})", mesh.triangles().len());
        return Err(InverseError::JacobianShape { rows, columns, expected });
    }
    if let Prior::Noser { exponent } = prior {
        if !exponent.is_finite() {
            return Err(InverseError::NotFiniteInput { what: format!("the NOSER exponent {exponent}") });
        }
    }
    for t in 0..columns {
        for m in 0..rows {
            if !jacobian[(m, t)].is_finite() {
                return Err(InverseError::NotFiniteInput { what: format!("Jacobian entry ({}, {})", m + 1, t + 1) });
            }
        }
    }
    Ok(())
}

/// Divides row m of the Jacobian by the background measurement v_m (V), for normalised
/// differences Δv_m / v_m (EIDORS `normalize_measurements`, pyEIT `jac_normalized`).
pub fn normalize_jacobian(jacobian: &mut Mat<f64>, background: &[f64]) -> Result<(), InverseError> {
    if jacobian.nrows() != background.len() {
        let (rows, columns) = (jacobian.nrows(), jacobian.ncols());
        let expected = format!("the background has {} values: one per measurement is needed", background.len());
        return Err(InverseError::JacobianShape { rows, columns, expected });
    }
    for (m, &v) in background.iter().enumerate() {
        if v == 0.0 {
            return Err(InverseError::ZeroReference { measurement: m + 1 });
        }
        if !v.is_finite() {
            return Err(InverseError::NotFiniteInput { what: format!("background measurement {} ({v})", m + 1) });
        }
        for k in 0..jacobian.ncols() {
            jacobian[(m, k)] /= v;
        }
    }
    Ok(())
}

pub(crate) fn check_hyperparameter(hyperparameter: f64) -> Result<(), InverseError> {
    if hyperparameter > 0.0 && hyperparameter.is_finite() {
        Ok(())
    } else {
        Err(InverseError::Hyperparameter(hyperparameter))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::SensorSpec;
    use std::sync::Arc;

    #[test]
    fn a_jacobian_that_does_not_fit_the_mesh_or_holds_no_number_is_refused() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 300;
        let model = spec.forward_model().unwrap();
        let mesh = model.mesh();
        let j = model.jacobian(&model.solve(&spec.homogeneous(mesh)).unwrap());
        let (rows, columns) = (j.nrows(), j.ncols());
        let short = j.subcols(0, columns - 1).to_owned();
        for prior in [Prior::Laplace, Prior::Tikhonov, Prior::default()] {
            for matrix in [short.as_ref(), j.transpose(), j.subrows(0, 0)] {
                let err = reconstruction_matrix(matrix, &prior, 0.1, mesh).unwrap_err();
                assert!(matches!(err, InverseError::JacobianShape { .. }), "{err}");
                assert!(element_sized(matrix, &prior, 0.1, mesh).is_err());
            }
        }
        let mut spiked = j.clone();
        spiked[(2, 6)] = f64::NAN;
        let err = reconstruction_matrix(spiked.as_ref(), &Prior::default(), 0.1, mesh).unwrap_err();
        assert_eq!(err.to_string(), "Jacobian entry (3, 7) is not a finite number");
        let err = reconstruction_matrix(j.as_ref(), &Prior::Noser { exponent: f64::INFINITY }, 0.1, mesh).unwrap_err();
        assert_eq!(err.to_string(), "the NOSER exponent inf is not a finite number");
        let mut normalised = j.clone();
        let err = normalize_jacobian(&mut normalised, &[1.0; 3]).unwrap_err();
        let says = format!(
            "the Jacobian is {rows} × {columns}, but the background has 3 values: one per measurement is needed"
        );
        assert_eq!(err.to_string(), says);
        let mut background = vec![1.0; rows];
        background[4] = f64::INFINITY;
        assert_eq!(
            normalize_jacobian(&mut normalised, &background).unwrap_err().to_string(),
            "background measurement 5 (inf) is not a finite number"
        );
    }

    #[test]
    fn measurement_sized_form_equals_element_sized_form() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 300;
        let model = spec.forward_model().unwrap();
        let jacobian = model.jacobian(&model.solve(&spec.homogeneous(model.mesh())).unwrap());
        for prior in [Prior::Noser { exponent: 0.5 }, Prior::Noser { exponent: 1.0 }, Prior::Tikhonov] {
            for lambda in [0.1, 0.03] {
                let fast = reconstruction_matrix(jacobian.as_ref(), &prior, lambda, model.mesh()).unwrap();
                let slow = element_sized(jacobian.as_ref(), &prior, lambda, model.mesh()).unwrap();
                let scale = slow.norm_max();
                let diff = (&fast - &slow).norm_max() / scale;
                // The element-sized system is the worse conditioned (Tikhonov at λ = 0.03: ~1e9).
                assert!(diff < 1e-7, "{prior:?}, λ = {lambda}: forms differ by {diff:e}");
            }
        }
        let err = reconstruction_matrix(jacobian.as_ref(), &Prior::Tikhonov, 0.0, model.mesh()).unwrap_err();
        assert_eq!(err, InverseError::Hyperparameter(0.0));
    }

    /// Dropping a channel from the linearisation gives what a protocol without it gives.
    #[test]
    fn a_dropped_channel_equals_a_protocol_without_it() {
        use crate::spec::ProtocolSpec;
        use crate::Protocol;
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 300;
        let params = ReconstructorParams { raster: [24, 24], ..ReconstructorParams::default() };
        let full = Reconstructor::new(&spec.forward_model().unwrap(), 1.0, &params).unwrap();
        let protocol = spec.protocol().unwrap();
        let drop = 17;
        let mut kept = protocol.measurements().to_vec();
        kept.remove(drop);
        let smaller = Protocol::new("all but one", 16, protocol.stimulations().to_vec(), kept).unwrap();
        spec.protocol = ProtocolSpec::Custom(smaller);
        let direct = Reconstructor::new(&spec.forward_model().unwrap(), 1.0, &params).unwrap();
        let mut mask = vec![true; 120];
        mask[drop] = false;
        for normalised in [false, true] {
            let params = ReconstructorParams { normalised, ..params };
            let derived = full.rederive(&params, Channels::all(120).masked(&mask)).unwrap();
            let direct = direct.rederive(&params, Channels::all(119)).unwrap();
            let column = |r: &Reconstructor, m: usize| r.matrix().column(m).collect::<Vec<_>>();
            assert!(column(&derived, drop).iter().all(|x| *x == 0.0));
            let scale = (0..119).flat_map(|m| column(&direct, m)).fold(0.0f32, |a, x| a.max(x.abs()));
            for m in 0..119 {
                let d = column(&derived, if m < drop { m } else { m + 1 });
                let worst = d.iter().zip(column(&direct, m)).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
                assert!(worst < 1e-5 * scale, "normalised {normalised}, channel {m}: {worst}");
            }
            // A frame with the dropped channel missing images as the smaller protocol's.
            let mut frame = vec![1.0; 120];
            frame[3] = 1.01;
            frame[drop] = f64::NAN;
            let image = derived.image(&vec![1.0; 120], &frame).unwrap();
            assert!(image.values.iter().all(|v| v.is_finite()));
        }
    }

    /// Data that a uniform change explains exactly (Δv = δ·J·1) give δ back and an empty
    /// image; a local change still images where it is, with and without weights.
    #[test]
    fn one_pixels_value_is_the_images_value_there() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 300;
        let params = ReconstructorParams { raster: [24, 24], normalised: true, ..ReconstructorParams::default() };
        let recon = Reconstructor::new(&spec.forward_model().unwrap(), 1.0, &params).unwrap();
        let v_ref = recon.linearisation().background().to_vec();
        let v: Vec<f64> = v_ref.iter().enumerate().map(|(m, x)| x * (1.0 + 0.01 * (m as f64).sin())).collect();
        let image = recon.image(&v_ref, &v).unwrap();
        for pixel in [0, 100, 300, 24 * 24 - 1] {
            let value = recon.pixel_value(&v_ref, &v, pixel).unwrap();
            assert!((value - image.values[pixel]).abs() <= 1e-5 * image.values[pixel].abs().max(1e-9), "{pixel}");
        }
        assert!(recon.pixel_value(&v_ref, &v[1..], 0).is_err(), "a frame of the wrong length");
        // A value past any measurement would overflow the single-precision image: refused, in
        // either frame, naming it.
        let mut huge = v.clone();
        huge[6] = 1e300;
        let err = recon.image(&v_ref, &huge).unwrap_err();
        assert_eq!(err, InverseError::TooLarge { measurement: 7, value: 1e300 });
        assert!(err.to_string().starts_with("measurement 7 of the frame is 1e300, past 1e30"), "{err}");
        assert!(recon.image(&huge, &v).is_err());
    }

    #[test]
    fn a_uniform_change_is_estimated_and_left_out_of_the_image() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 300;
        let params =
            ReconstructorParams { raster: [24, 24], background_change: true, ..ReconstructorParams::default() };
        let recon = Reconstructor::new(&spec.forward_model().unwrap(), 1.0, &params).unwrap();
        let lin = Arc::clone(recon.linearisation());
        let j = lin.jacobian();
        let v0 = lin.background().to_vec();
        let d: Vec<f64> = (0..j.nrows()).map(|m| (0..j.ncols()).map(|k| j[(m, k)]).sum()).collect();
        let variance: Vec<f64> = (0..120).map(|m| 1.0 + (m % 5) as f64).collect();
        for normalised in [false, true] {
            for channels in [Channels::all(120), Channels::all(120).with_variance(variance.clone())] {
                let recon = recon.rederive(&ReconstructorParams { normalised, ..params }, channels).unwrap();
                let delta = -0.03;
                let v: Vec<f64> = v0.iter().zip(&d).map(|(v, d)| v + delta * d).collect();
                let estimated = recon.background_change(&v0, &v).unwrap().unwrap();
                // Normalised data are Δv/v_ref, so a uniform change is linear in them only to first order.
                let tolerance = if normalised { 1e-3 } else { 1e-6 };
                assert!((estimated - delta).abs() < tolerance * delta.abs(), "{normalised}: {estimated}");
                let image = recon.image(&v0, &v).unwrap();
                let peak = image.values.iter().fold(0.0f32, |a, x| a.max(x.abs()));
                // One triangle's change, for scale: what the image of a local change looks like.
                let local: Vec<f64> = v0.iter().enumerate().map(|(m, v)| v - 0.05 * j[(m, 150)]).collect();
                let local_image = recon.image(&v0, &local).unwrap();
                let local_peak = local_image.values.iter().fold(0.0f32, |a, x| a.max(x.abs()));
                assert!(peak < 1e-3 * local_peak, "{normalised}: {peak} vs {local_peak}");
            }
        }
        let plain = recon.rederive(&ReconstructorParams { background_change: false, ..params }, Channels::all(120));
        assert_eq!(plain.unwrap().background_change(&v0, &v0).unwrap(), None);
    }

    /// A background the forward model refuses is named as such, not blamed on the prior.
    #[test]
    fn a_bad_background_keeps_the_forward_models_reason() {
        use crate::forward::ForwardError;
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 300;
        let model = spec.forward_model().unwrap();
        for background in [-1.0, f64::NAN] {
            let err = Reconstructor::new(&model, background, &ReconstructorParams::default()).unwrap_err();
            let InverseError::Forward(ForwardError::Conductivity { triangle: 0, value }) = err else {
                panic!("{err:?}");
            };
            assert!(value.is_nan() || value == background);
            let cause = std::error::Error::source(&err).map(ToString::to_string);
            assert_eq!(err.to_string(), "the forward model could not be solved");
            assert!(cause.is_some_and(|c| c.starts_with("triangle 0: conductivity must be positive and finite")));
        }
    }
}
