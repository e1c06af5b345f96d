//! A curve's spread: how far the strength of presses at places the curve did not see lies from
//! it, beyond what their own noise explains.
//!
//! Each sample's residual is taken on a curve fitted without its place (up to [`PLACE_FOLDS`]
//! folds of places). The variance the residuals share beyond their noise is Paule and Mandel's
//! estimator of the variance between studies in a meta-analysis: the τ² ≥ 0 at which
//! Σ rᵢ²/(τ² + vᵢ) equals its expectation, the number of residuals. Each residual counts by its
//! own noise, so a few precise samples that miss (near the electrodes, where a press is read
//! sharply and the model errs most) are not averaged away by many noisy ones that do not.
//!
//! A spread that depends on place (the same estimator with kernel weights, its width chosen by
//! how well it predicts the residuals of each place left out) was tried on the study's robot
//! presses: the left-out places chose it for one data set in twelve, where it did not change the
//! coverage; it is not kept.

use super::{Curve, Sample};

/// The most folds a curve's spread is cross-validated over, places taken in turn.
pub const PLACE_FOLDS: usize = 10;
/// Bisection steps of the spread's equation (relative precision 2⁻⁶⁰).
const BISECTIONS: usize = 60;

/// Each sample with the curve fitted without its fold of places (up to [`PLACE_FOLDS`] folds,
/// places taken in turn), given to `visit`; the number of places: every sample's place known
/// and three places or more, else `None` (a fold that leaves no curve that fits is skipped).
fn held_out(samples: &[&Sample], mut visit: impl FnMut(&Curve, &Sample)) -> Option<usize> {
    let places: Vec<[f64; 2]> = samples.iter().map(|s| s.place).collect::<Option<_>>()?;
    let mut distinct: Vec<[f64; 2]> = Vec::new();
    let place_of: Vec<usize> = places
        .iter()
        .map(|p| {
            distinct.iter().position(|d| d == p).unwrap_or_else(|| {
                distinct.push(*p);
                distinct.len() - 1
            })
        })
        .collect();
    if distinct.len() < 3 {
        return None;
    }
    let folds = distinct.len().min(PLACE_FOLDS);
    for fold in 0..folds {
        let held = |k: &usize| place_of[*k] % folds == fold;
        let kept: Vec<&Sample> = (0..samples.len()).filter(|k| !held(k)).map(|k| samples[k]).collect();
        let forces: Vec<f64> = kept.iter().map(|s| s.force).collect();
        let peaks: Vec<f64> = kept.iter().map(|s| s.peak).collect();
        let Ok(curve) = Curve::fit(0, &forces, &peaks) else { continue };
        (0..samples.len()).filter(held).for_each(|k| visit(&curve, samples[k]));
    }
    Some(distinct.len())
}

/// The residuals (in the strength's unit) of curves fitted without each fold of places on the
/// samples of that fold, each with its sample's noise variance ([`noise_variance`]), and the
/// number of places ([`held_out`]; `None` also when no fold leaves a curve that fits).
fn held_out_residuals(samples: &[&Sample]) -> Option<(Vec<(f64, f64)>, usize)> {
    let mut residuals = Vec::with_capacity(samples.len());
    let places = held_out(samples, |curve, s| residuals.push((s.peak - curve.peak(s.force), noise_variance(s))))?;
    (!residuals.is_empty()).then_some((residuals, places))
}

/// The RMS force error (N) of one curve read at places it did not see: each sample's force
/// read off the curve fitted without its fold of places ([`held_out`]), less its own; `None`
/// where its places are unknown or fewer than three.
pub(super) fn held_out_force_rms(samples: &[&Sample]) -> Option<f64> {
    let mut squares = Vec::with_capacity(samples.len());
    held_out(samples, |curve, s| squares.push((curve.force(s.peak).newtons - s.force).powi(2)))?;
    (!squares.is_empty()).then(|| (squares.iter().sum::<f64>() / squares.len() as f64).sqrt())
}

/// A sample's noise variance, in the strength's unit squared: its `std` squared, 0 where not known.
fn noise_variance(sample: &Sample) -> f64 {
    sample.std.filter(|s| s.is_finite()).map_or(0.0, |s| s * s)
}

/// The variance τ², in the strength's unit squared, that residuals rᵢ with noise variances vᵢ
/// (`(r, v)`) share beyond their noise: the τ² ≥ 0 at which Σ rᵢ²/(τ² + vᵢ) = `freedom` (Paule
/// and Mandel), 0 where the noise alone explains them.
fn excess_variance(residuals: &[(f64, f64)], freedom: f64) -> f64 {
    let statistic =
        |tau2: f64| residuals.iter().filter(|(r, _)| *r != 0.0).map(|(r, v)| r * r / (tau2 + v)).sum::<f64>();
    // The statistic falls as τ² grows, from its value at 0 to at most `freedom` at Σ rᵢ²/freedom.
    let mut high = residuals.iter().map(|(r, _)| r * r).sum::<f64>() / freedom;
    if !(high > 0.0 && high.is_finite()) || statistic(0.0) <= freedom {
        return 0.0;
    }
    let mut low = 0.0;
    for _ in 0..BISECTIONS {
        let middle = 0.5 * (low + high);
        if statistic(middle) > freedom {
            low = middle;
        } else {
            high = middle;
        }
    }
    0.5 * (low + high)
}

/// Student's factor for a variance measured on `places` places (ν = places − 1, held at 3 or
/// more): the error at a new place has the variance's times ν/(ν − 2).
fn student(places: f64) -> f64 {
    let freedom = (places - 1.0).max(3.0);
    freedom / (freedom - 2.0)
}

/// The spread of `curve`, fitted to `samples`, in the strength's unit: [`excess_variance`] of
/// the residuals on places it did not see ([`held_out_residuals`]) times [`student`], else of its
/// own residuals (3 parameters fitted).
pub(super) fn spread(curve: &Curve, samples: &[&Sample]) -> f64 {
    match held_out_residuals(samples) {
        Some((residuals, places)) => {
            (excess_variance(&residuals, residuals.len() as f64) * student(places as f64)).sqrt()
        }
        None => {
            let residuals: Vec<(f64, f64)> =
                samples.iter().map(|s| (s.peak - curve.peak(s.force), noise_variance(s))).collect();
            excess_variance(&residuals, (residuals.len() as f64 - 3.0).max(1.0)).sqrt()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_excess_is_what_the_noise_does_not_explain() {
        // Residuals of variance 4 with noise variance 1 known: τ² near 3.
        let residuals: Vec<(f64, f64)> = (0..4000).map(|k| (if k % 2 == 0 { 2.0 } else { -2.0 }, 1.0)).collect();
        assert!((excess_variance(&residuals, 4000.0) - 3.0).abs() < 1e-9);
        // Noise explains them all: none.
        let quiet: Vec<(f64, f64)> = residuals.iter().map(|(r, _)| (*r, 5.0)).collect();
        assert_eq!(excess_variance(&quiet, 4000.0), 0.0);
        // No noise known: the mean square.
        let bare: Vec<(f64, f64)> = residuals.iter().map(|(r, _)| (*r, 0.0)).collect();
        assert!((excess_variance(&bare, 4000.0) - 4.0).abs() < 1e-9);
    }

    #[test]
    fn precise_samples_that_miss_are_not_averaged_away() {
        // Ten noisy samples fully explained by their noise (r² = v = 100) and ten precise ones
        // (v = 0.01) that miss by 1: the pooled mean square less the mean noise variance gives
        // 50.5 − 50.005 ≈ 0.5, half what the precise ones miss by; the estimator about 1.
        let mut residuals = vec![(10.0, 100.0); 10];
        residuals.extend(vec![(1.0, 0.01); 10]);
        let tau2 = excess_variance(&residuals, 20.0);
        assert!(tau2 > 0.5 && tau2 < 1.5, "{tau2}");
    }
}
