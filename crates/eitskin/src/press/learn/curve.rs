//! The physical answer for a fitted press: its centre, and the force (and depth) its drop gives
//! on one curve strength(F) = a·e^(−F/b) + c fitted to the labelled presses: the calibration's
//! curve ([`crate::calibration`]), the whole sheet one area, its spread cross-validated place
//! by place. What a Gaussian process then learns on top of it ([`super::RegressorKind::CurveResidual`])
//! is only what the physics gets wrong.

use super::{LabelledPress, LearnError};
use crate::calibration::{Calibration, Curve, Sample};
use crate::press_fit::PressFit;
use crate::strength::Strength;

/// The curves of the labelled quantities on the fitted press's drop.
#[derive(Debug, Clone, PartialEq)]
pub struct PressCurves {
    /// Drop (fraction of the background) against force (N); `None` without force labels.
    pub force: Option<Curve>,
    /// Drop against depth (m); `None` without depth labels.
    pub depth: Option<Curve>,
}

impl PressCurves {
    /// The curves of `presses`' labels on the drops of `fits` (one fit per press, in order).
    pub fn fit(fits: &[PressFit], presses: &[&LabelledPress]) -> Result<PressCurves, LearnError> {
        let curve = |label: fn(&LabelledPress) -> Option<f64>| -> Result<Option<Curve>, LearnError> {
            if presses.first().and_then(|p| label(p)).is_none() {
                return Ok(None);
            }
            let samples: Vec<Sample> = fits
                .iter()
                .zip(presses)
                .map(|(fit, p)| Sample {
                    area: 0,
                    force: label(p).unwrap_or(f64::NAN),
                    peak: fit.drop,
                    std: fit.equivalent_drop_std,
                    place: Some(p.position),
                })
                .collect();
            let calibration = Calibration::fit_strength(&samples, 1, Strength::FittedDrop)?;
            Ok(calibration.curves.into_iter().next())
        };
        Ok(PressCurves { force: curve(|p| p.force)?, depth: curve(|p| p.depth)? })
    }

    /// The answer for `fit` into `out`: x, y (m), then the force (N) and the depth (m) where
    /// there are curves for them; each one's standard deviation into `std` (NaN for the
    /// position, which the physics gives without one). Both at least as long as the outputs.
    pub fn answer_into(&self, fit: &PressFit, out: &mut [f64], std: &mut [f64]) {
        out[..2].copy_from_slice(&fit.centre);
        std[..2].fill(f64::NAN);
        let read =
            self.force.iter().chain(&self.depth).map(|curve| curve.force_given(fit.drop, fit.equivalent_drop_std));
        for ((o, s), estimate) in out[2..].iter_mut().zip(&mut std[2..]).zip(read) {
            *o = estimate.newtons;
            *s = estimate.std.unwrap_or(f64::NAN);
        }
    }

    /// Outputs of an answer: 2, and one per curve.
    pub fn outputs(&self) -> usize {
        2 + usize::from(self.force.is_some()) + usize::from(self.depth.is_some())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fit_at(centre: [f64; 2], drop: f64) -> PressFit {
        PressFit { centre, radius: 0.01, contrast: drop, drop, z: 10.0, equivalent_drop_std: None }
    }

    /// On drops that follow a curve of the family exactly, the physics reads back each force
    /// and places each press at its fitted centre; without depth labels there is no depth.
    #[test]
    fn the_physics_reads_back_forces_on_its_own_curve() {
        let drop = |force: f64| 0.7 - 0.6 * (-force / 5.0).exp();
        let presses: Vec<LabelledPress> = (0..40)
            .map(|i| {
                let force = 0.5 + 0.4 * f64::from(i);
                let position = [f64::from(i % 7) * 0.01, f64::from(i % 5) * -0.01];
                LabelledPress { inputs: vec![], position, force: Some(force), depth: None }
            })
            .collect();
        let fits: Vec<PressFit> = presses.iter().map(|p| fit_at(p.position, drop(p.force.unwrap()))).collect();
        let curves = PressCurves::fit(&fits, &presses.iter().collect::<Vec<_>>()).unwrap();
        assert!(curves.depth.is_none() && curves.outputs() == 3);
        let (mut out, mut std) = ([0.0; 4], [0.0; 4]);
        curves.answer_into(&fit_at([0.03, -0.02], drop(7.3)), &mut out, &mut std);
        assert_eq!(out[..2], [0.03, -0.02]);
        assert!((out[2] - 7.3).abs() < 1e-3, "{out:?}");
        assert!(std[0].is_nan() && std[2] >= 0.0 && std[2] < 1e-2, "{std:?}");
        // Labels that do not rise with the drop at all: no curve, an error that says so.
        let flat: Vec<PressFit> = presses.iter().map(|p| fit_at(p.position, 0.3)).collect();
        let refused = PressCurves::fit(&flat, &presses.iter().collect::<Vec<_>>()).unwrap_err();
        assert!(matches!(refused, LearnError::Curve(_)), "{refused:?}");
    }
}
