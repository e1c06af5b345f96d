//! The plain baseline a learned calibration must beat: kernel ridge regression on the z-scored
//! channels, its width and regularisation chosen by K-fold cross-validation — what a user
//! would write with scikit-learn's `KernelRidge(kernel="rbf")` and `GridSearchCV`.
//!
//! The kernel is the Gaussian process's squared exponential without its linear term,
//! exp(−|a − b|²/(2ℓ²D)), on the same grids of ℓ ([`LENGTH_SCALES`]) and λ
//! ([`NOISE_VARIANCES`], on standardised targets); the pair kept is the one of the smallest
//! cross-validated mean position error, so the figure it reports is, if anything, flattering
//! to it (the choice is made on the very folds it is scored on).

use faer::linalg::solvers::Solve;
use faer::{Mat, Side};

use super::gp::{squared_distances, standardised, LENGTH_SCALES, NOISE_VARIANCES};
use super::{check, Errors, LabelledPress, LearnError, Standardiser, Tally};

/// Kernel ridge fitted to labelled presses: the z-scoring, the training points and weights.
#[derive(Debug, Clone)]
pub struct KernelRidge {
    /// ℓ relative to √D.
    pub length_scale: f64,
    /// λ, on standardised targets.
    pub lambda: f64,
    standardiser: Standardiser,
    points: Mat<f64>,
    /// Weights, one column per output (x, y, then the force and the depth when labelled).
    alpha: Mat<f64>,
    target_mean: Vec<f64>,
    target_std: Vec<f64>,
}

/// The baseline's choice and how well it did.
#[derive(Debug, Clone)]
pub struct Baseline {
    /// The model with the chosen ℓ and λ, trained on every press.
    pub model: KernelRidge,
    /// Its cross-validated errors at that choice.
    pub errors: Errors,
}

impl KernelRidge {
    /// Trains on `presses` (channels as they are) with this `length_scale` and `lambda`; `None`
    /// where no channel varies or the kernel cannot be factored.
    pub fn fit(presses: &[&LabelledPress], length_scale: f64, lambda: f64) -> Option<KernelRidge> {
        let inputs: Vec<Vec<f64>> = presses.iter().map(|p| p.inputs.clone()).collect();
        let standardiser = Standardiser::fit(&inputs);
        let used = standardiser.used().len();
        if used == 0 || presses.is_empty() {
            return None;
        }
        let mut z = vec![0.0; used];
        let mut points = Mat::zeros(presses.len(), used);
        for (i, p) in presses.iter().enumerate() {
            standardiser.apply_into(&p.inputs, &mut z);
            z.iter().enumerate().for_each(|(k, v)| points[(i, k)] = *v);
        }
        let targets: Vec<Vec<f64>> = presses.iter().map(|p| targets(p)).collect();
        let (target_mean, target_std, y) = standardised(&targets);
        let scale = 1.0 / (2.0 * length_scale * length_scale * used as f64);
        let distances = squared_distances(&points, &points);
        let kernel = Mat::from_fn(presses.len(), presses.len(), |i, j| {
            (-distances[(i, j)] * scale).exp() + if i == j { lambda } else { 0.0 }
        });
        let alpha = kernel.llt(Side::Lower).ok()?.solve(&y);
        Some(KernelRidge { length_scale, lambda, standardiser, points, alpha, target_mean, target_std })
    }

    /// The answer for `frame`: x, y (m), then the force (N) and the depth (m) where trained
    /// with them; `None` for a frame of another length than the training presses'.
    pub fn predict(&self, frame: &[f64]) -> Option<Vec<f64>> {
        if frame.len() != self.standardiser.channels() {
            return None;
        }
        let used = self.standardiser.used().len();
        let mut z = vec![0.0; used];
        self.standardiser.apply_into(frame, &mut z);
        let scale = 1.0 / (2.0 * self.length_scale * self.length_scale * used as f64);
        let kernel: Vec<f64> = (0..self.points.nrows())
            .map(|i| (-(0..used).map(|k| (self.points[(i, k)] - z[k]).powi(2)).sum::<f64>() * scale).exp())
            .collect();
        let answer = (0..self.alpha.ncols()).map(|t| {
            let value: f64 = kernel.iter().enumerate().map(|(i, k)| k * self.alpha[(i, t)]).sum();
            value * self.target_std[t] + self.target_mean[t]
        });
        Some(answer.collect())
    }
}

/// A press's targets: x, y, then its force and depth where labelled.
fn targets(p: &LabelledPress) -> Vec<f64> {
    let mut t = p.position.to_vec();
    t.extend(p.force);
    t.extend(p.depth);
    t
}

/// The baseline on `presses` (at least 2 a fold): every (ℓ, λ) of the grids scored by
/// `folds`-fold cross-validation (press i in fold i mod folds, as [`super::cross_validate`]),
/// the one of the smallest mean position error trained on every press.
pub fn baseline(presses: &[LabelledPress], folds: usize) -> Result<Baseline, LearnError> {
    let folds = folds.max(2);
    check(presses, 2 * folds)?;
    let mut best: Option<(f64, f64, Errors)> = None;
    for &length in &LENGTH_SCALES {
        for &lambda in &NOISE_VARIANCES {
            let mut tally = Tally::default();
            for fold in 0..folds {
                let kept: Vec<&LabelledPress> =
                    presses.iter().enumerate().filter(|(i, _)| i % folds != fold).map(|(_, p)| p).collect();
                let Some(model) = KernelRidge::fit(&kept, length, lambda) else { continue };
                for p in presses.iter().enumerate().filter(|(i, _)| i % folds == fold).map(|(_, p)| p) {
                    tally.answer(p, model.predict(&p.inputs).as_deref());
                }
            }
            let errors = tally.errors();
            if errors.presses > 0 && best.as_ref().is_none_or(|b| errors.mean_position < b.2.mean_position) {
                best = Some((length, lambda, errors));
            }
        }
    }
    let (length, lambda, errors) = best.ok_or(LearnError::NotFitted)?;
    let all: Vec<&LabelledPress> = presses.iter().collect();
    let model = KernelRidge::fit(&all, length, lambda).ok_or(LearnError::NotFitted)?;
    Ok(Baseline { model, errors })
}

/// The errors of the baseline's `model` on `presses`.
pub fn evaluate_baseline(model: &KernelRidge, presses: &[LabelledPress]) -> Errors {
    let mut tally = Tally::default();
    presses.iter().for_each(|p| tally.answer(p, model.predict(&p.inputs).as_deref()));
    tally.errors()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a smooth toy sensor: the baseline learns the position (to a few per cent of the
    /// range) and its cross-validated error is a real one (held-out presses agree within 2×).
    #[test]
    fn the_baseline_learns_a_smooth_sensor_by_cross_validation() {
        let frame = |x: f64, y: f64| vec![x + 0.2 * y * y, y - 0.1 * x, x * y, (x + y).sin()];
        let press = |x: f64, y: f64| LabelledPress { inputs: frame(x, y), position: [x, y], force: None, depth: None };
        let grid = |n: usize, offset: f64| -> Vec<LabelledPress> {
            (0..n * n)
                .map(|i| ((i % n) as f64 / n as f64 - 0.5 + offset, (i / n) as f64 / n as f64 - 0.5 + offset))
                .map(|(x, y)| press(x, y))
                .collect()
        };
        let training = grid(10, 0.0);
        let held_out = grid(6, 0.03);
        let Baseline { model, errors } = baseline(&training, 5).unwrap();
        let held = evaluate_baseline(&model, &held_out);
        assert!(errors.mean_position < 0.03 && held.mean_position < 0.03, "{errors:?} {held:?}");
        assert!(held.mean_position < 2.0 * errors.mean_position + 0.005, "{errors:?} {held:?}");
        assert!(LENGTH_SCALES.contains(&model.length_scale) && NOISE_VARIANCES.contains(&model.lambda));
        // A frame of another length has no answer, and counts as unanswered.
        assert_eq!(model.predict(&[0.1, 0.2]), None);
        let short = [LabelledPress { inputs: vec![0.1], ..held_out[0].clone() }];
        assert_eq!(evaluate_baseline(&model, &short).unanswered, 1);
        assert_eq!(baseline(&training[..5], 5).unwrap_err(), LearnError::TooFewPresses { got: 5, needed: 10 });
    }
}
