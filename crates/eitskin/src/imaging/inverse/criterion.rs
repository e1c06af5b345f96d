//! λ chosen from the data themselves: generalised cross-validation and the discrepancy
//! principle (Hansen, *Rank-deficient and discrete ill-posed problems*, 1998).
//!
//! In the eigenbasis of the whitened system S = Σ^-½ J R⁻¹ Jᵀ Σ^-½ = U diag(e) Uᵀ (Σ the
//! channels' noise variances relative to their mean, as λ² multiplies them), a frame's
//! whitened difference d has coefficients b = Uᵀ d, and for each λ
//!
//! - the residual ‖d − J x_λ‖² = Σ (λ²/(e + λ²))² b²,
//! - the residual's degrees of freedom tr(I − A_λ) = Σ λ²/(e + λ²),
//!
//! each a sum over channels, so a criterion costs one channels² product per frame and then
//! channels per λ. Over several frames the residuals add.
//!
//! - **GCV** minimises n·‖residual‖²/tr(I − A_λ)²: the λ that best predicts each channel left out.
//! - **Discrepancy** takes the λ whose mean residual per channel equals the noise's mean
//!   variance (Morozov): no closer fit than the noise allows. It needs the noise's level.
//!
//! The L-curve (the corner of log residual against log ‖x‖_R) was tried and left out: on the
//! paper's sensor at 2 % noise the curve has no corner (the log residual moves by 2.8 while the
//! log norm falls by 21 over the range), and its largest curvature sat at λ = 6e-5.
//!
//! They see the model's error (the one-step linearisation, electrodes and outline not as built)
//! as noise, which the noise figure, a function of the model alone, does not.

use std::str::FromStr;

use super::eigensystem::Eigensystem;
use super::hyperparameter::SEARCH;
use super::{Channels, InverseError, Linearisation, Prior};

/// A criterion that chooses λ from frames with their reference.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DataCriterion {
    /// Generalised cross-validation.
    Gcv,
    /// The discrepancy principle on the noise's level.
    Discrepancy,
}

impl DataCriterion {
    /// The criterion's name, as [`FromStr`] reads it.
    pub fn name(self) -> &'static str {
        match self {
            DataCriterion::Gcv => "gcv",
            DataCriterion::Discrepancy => "discrepancy",
        }
    }
}

impl FromStr for DataCriterion {
    type Err = String;

    /// `gcv` or `discrepancy`.
    fn from_str(text: &str) -> Result<DataCriterion, String> {
        match text.trim() {
            "gcv" => Ok(DataCriterion::Gcv),
            "discrepancy" => Ok(DataCriterion::Discrepancy),
            _ => Err(format!("\"{text}\" is not a criterion: gcv or discrepancy")),
        }
    }
}

/// Steps per decade of λ on which the criteria are evaluated.
const STEPS_PER_DECADE: f64 = 100.0;

/// The λ that `criterion` chooses for `frames` (each a frame `v` with its reference `v_ref`,
/// full-length, of which the used `channels` count), with the reconstruction's prior and
/// differences (`normalised`: v/v_ref − 1, else v − v_ref) and `channels`' noise variances
/// (their shape weighs the channels; their level is the discrepancy's target, which refuses
/// channels without variances). Searched on 100 steps a decade over [1e-6, 1e3].
pub fn data_hyperparameter(
    lin: &Linearisation,
    prior: &Prior,
    normalised: bool,
    channels: &Channels,
    frames: &[(&[f64], &[f64])],
    criterion: DataCriterion,
) -> Result<f64, InverseError> {
    let system = Eigensystem::new(lin, prior, normalised, channels)?;
    let used = channels.used();
    let expected = lin.measurements();
    let mut coefficients = Vec::with_capacity(frames.len());
    for (v_ref, v) in frames {
        if v_ref.len() != expected || v.len() != expected {
            let got = if v.len() != expected { v.len() } else { v_ref.len() };
            return Err(InverseError::FrameLength { expected, got });
        }
        let d: Vec<f64> = used
            .iter()
            .zip(&system.std)
            .map(|(&m, s)| if normalised { v[m] / v_ref[m] - 1.0 } else { v[m] - v_ref[m] } / s)
            .collect();
        if let Some(i) = d.iter().position(|x| !x.is_finite()) {
            return Err(InverseError::NotFinite { measurement: used[i] + 1 });
        }
        let b = system.coefficients(&d);
        // What lies outside the eigenvectors' span (eigenvalue 0: never fitted).
        let outside = (d.iter().map(|d| d * d).sum::<f64>() - b.iter().map(|b| b * b).sum::<f64>()).max(0.0);
        coefficients.push((b, outside));
    }
    let e: Vec<f64> = system.eigenvalues.iter().map(|e| e.max(0.0)).collect();
    let n = used.len() as f64;
    let residual = |lambda2: f64| -> f64 {
        let each = |(b, outside): &(Vec<f64>, f64)| {
            e.iter().zip(b).map(|(e, b)| (lambda2 / (e + lambda2) * b).powi(2)).sum::<f64>() + outside
        };
        coefficients.iter().map(each).sum()
    };
    let (lo, hi) = (SEARCH.0.log10(), SEARCH.1.log10());
    let steps = ((hi - lo) * STEPS_PER_DECADE).round() as usize;
    let grid: Vec<f64> = (0..=steps).map(|i| 10f64.powf(lo + (hi - lo) * i as f64 / steps as f64)).collect();
    let chosen = match criterion {
        DataCriterion::Gcv => {
            let gcv = |lambda: f64| {
                let lambda2 = lambda * lambda;
                let freedom: f64 = e.iter().map(|e| lambda2 / (e + lambda2)).sum::<f64>() + (n - e.len() as f64);
                n * residual(lambda2) / (freedom * freedom)
            };
            argmin(&grid, gcv)
        }
        DataCriterion::Discrepancy => {
            let variance = channels.mean_variance().ok_or(InverseError::DiscrepancyNeedsNoise)?;
            // The residual grows with λ; the target is n channels' noise in each frame.
            let target = n * variance * coefficients.len() as f64;
            grid.iter().copied().find(|l| residual(l * l) >= target).unwrap_or(SEARCH.1)
        }
    };
    Ok(chosen)
}

/// The point of `grid` where `f` is least (NaN counting as largest).
fn argmin(grid: &[f64], f: impl Fn(f64) -> f64) -> f64 {
    let value = |l: f64| {
        let v = f(l);
        if v.is_nan() {
            f64::INFINITY
        } else {
            v
        }
    };
    grid.iter().copied().min_by(|&a, &b| value(a).total_cmp(&value(b))).unwrap_or(SEARCH.1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::conductivity::{with_inclusions, Inclusion};
    use crate::SensorSpec;

    /// The paper sensor's linearisation, its reference, `count` frames with one resistive
    /// inclusion (simulated on a finer mesh) with noise of `level` (relative), and the channels
    /// with that noise.
    struct Case {
        lin: Linearisation,
        reference: Vec<f64>,
        frames: Vec<Vec<f64>>,
        channels: Channels,
    }

    impl Case {
        fn pairs(&self) -> Vec<(&[f64], &[f64])> {
            self.frames.iter().map(|v| (self.reference.as_slice(), v.as_slice())).collect()
        }
    }

    fn frames(level: f64, count: usize) -> Case {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 600;
        let lin = Linearisation::new(&spec.forward_model().unwrap(), spec.conductivity).unwrap();
        let mut fine = spec.clone();
        fine.mesh.triangles = 2400;
        let model = fine.forward_model().unwrap();
        let sigma = fine.conductivity;
        let v0 = model.measure(&with_inclusions(model.mesh(), sigma, &[])).unwrap();
        let press = Inclusion { centre: [0.03, -0.02], radius: 0.02, conductivity: 0.5 * sigma };
        let v1 = model.measure(&with_inclusions(model.mesh(), sigma, &[press])).unwrap();
        // A deterministic spread of ±√3 · level (uniform, unit variance per level²).
        let noisy = |v: &[f64], k: usize| -> Vec<f64> {
            v.iter()
                .enumerate()
                .map(|(m, x)| {
                    let u = ((m * 7919 + k * 104_729) % 1000) as f64 / 1000.0 - 0.5;
                    x * (1.0 + level * 12f64.sqrt() * u)
                })
                .collect()
        };
        let frames = (0..count).map(|k| noisy(&v1, k + 1)).collect();
        let variance: Vec<f64> = v0.iter().map(|v| (level * v).powi(2)).collect();
        let channels = Channels::all(v0.len()).with_variance(variance);
        Case { lin, reference: v0, frames, channels }
    }

    #[test]
    fn each_criterion_smooths_noisier_data_more() {
        for criterion in [DataCriterion::Gcv, DataCriterion::Discrepancy] {
            let at = |level: f64| {
                let case = frames(level, 1);
                data_hyperparameter(&case.lin, &Prior::default(), false, &case.channels, &case.pairs(), criterion)
                    .unwrap()
            };
            let (quiet, noisy) = (at(0.0005), at(0.02));
            assert!(quiet > SEARCH.0 && noisy < SEARCH.1, "{}: an inner λ: {quiet}, {noisy}", criterion.name());
            assert!(noisy > quiet, "{}: λ {quiet} at 0.05 % noise, {noisy} at 2 %", criterion.name());
        }
    }

    #[test]
    fn the_discrepancy_fits_to_the_noise_and_names_are_read_back() {
        let case = frames(0.01, 2);
        let (lin, channels, pairs) = (&case.lin, &case.channels, case.pairs());
        let prior = Prior::default();
        let lambda = data_hyperparameter(lin, &prior, false, channels, &pairs, DataCriterion::Discrepancy).unwrap();
        // Just below the chosen λ the fit is closer than the noise; at it, not.
        let system = Eigensystem::new(lin, &prior, false, channels).unwrap();
        let n = system.eigenvalues.len() as f64;
        let residual = |l: f64| -> f64 {
            pairs
                .iter()
                .map(|(r, v)| {
                    let d: Vec<f64> = (0..r.len()).map(|m| (v[m] - r[m]) / system.std[m]).collect();
                    let b = system.coefficients(&d);
                    (b.iter().zip(&system.eigenvalues))
                        .map(|(b, e)| (l * l / (e.max(0.0) + l * l) * b).powi(2))
                        .sum::<f64>()
                })
                .sum()
        };
        let target = 2.0 * n * channels.mean_variance().unwrap();
        assert!(residual(lambda) >= target && residual(lambda / 1.03) < target, "λ = {lambda}");
        let unmeasured = Channels::all(120);
        assert!(data_hyperparameter(lin, &prior, false, &unmeasured, &pairs, DataCriterion::Discrepancy).is_err());
        for criterion in [DataCriterion::Gcv, DataCriterion::Discrepancy] {
            assert_eq!(criterion.name().parse(), Ok(criterion));
        }
        assert!("gvc".parse::<DataCriterion>().is_err());
    }
}
