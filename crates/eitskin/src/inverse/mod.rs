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

mod prior;
mod raster;

pub use prior::Prior;
pub use raster::{Reconstructor, ReconstructorParams};

use faer::{Mat, MatRef, Side};
use thiserror::Error;

use crate::mesh::Mesh;

/// What is wrong with an inverse model or a frame; measurements are counted from 1.
#[derive(Debug, Error, PartialEq)]
pub enum InverseError {
    /// The hyperparameter must be positive and finite.
    #[error("the hyperparameter λ must be positive and finite, got {0}")]
    Hyperparameter(f64),
    /// The indenter radius of a press model must be positive and finite.
    #[error("the indenter radius must be positive and finite, got {0} m")]
    IndenterRadius(f64),
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
    /// Normalised differences divide by the reference, which must not be zero.
    #[error("measurement {measurement} of the reference frame is zero, so it cannot be normalised")]
    ZeroReference {
        /// 1-based measurement.
        measurement: usize,
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
    let Some(r) = prior.diagonal(jacobian) else {
        return element_sized(jacobian, prior, hyperparameter, mesh);
    };
    // A triangle no measurement sees has R = 0 under NOSER: give it the smallest positive weight.
    let floor = r.iter().copied().filter(|x| *x > 0.0).fold(f64::INFINITY, f64::min).min(f64::MAX);
    let r_inv: Vec<f64> = r.iter().map(|&x| 1.0 / if x > 0.0 { x } else { floor }).collect();
    let (m, k) = (jacobian.nrows(), jacobian.ncols());
    let scaled = Mat::from_fn(m, k, |i, j| jacobian[(i, j)] * r_inv[j]); // J R⁻¹
    let mut system = &scaled * jacobian.transpose(); // J R⁻¹ Jᵀ
    let lambda2 = hyperparameter * hyperparameter;
    for i in 0..m {
        system[(i, i)] += lambda2;
    }
    let llt = system.llt(Side::Lower).map_err(|_| InverseError::NotPositiveDefinite)?;
    // (JR⁻¹Jᵀ + λ²I)⁻¹ J R⁻¹ = RMᵀ, since both factors are symmetric.
    let transposed = faer::linalg::solvers::Solve::solve(&llt, &scaled);
    Ok(transposed.transpose().to_owned())
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
    let mut system = jacobian.transpose() * jacobian;
    let r = prior.matrix(jacobian, mesh);
    system += (hyperparameter * hyperparameter) * r;
    let llt = system.llt(Side::Lower).map_err(|_| InverseError::NotPositiveDefinite)?;
    Ok(faer::linalg::solvers::Solve::solve(&llt, jacobian.transpose()))
}

/// Divides row m of the Jacobian by the background measurement v_m (V), for normalised
/// differences Δv_m / v_m (EIDORS `normalize_measurements`, pyEIT `jac_normalized`).
pub fn normalize_jacobian(jacobian: &mut Mat<f64>, background: &[f64]) -> Result<(), InverseError> {
    assert_eq!(jacobian.nrows(), background.len(), "one background value per measurement");
    for (m, &v) in background.iter().enumerate() {
        if v == 0.0 {
            return Err(InverseError::ZeroReference { measurement: m + 1 });
        }
        for k in 0..jacobian.ncols() {
            jacobian[(m, k)] /= v;
        }
    }
    Ok(())
}

fn check_hyperparameter(hyperparameter: f64) -> Result<(), InverseError> {
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
