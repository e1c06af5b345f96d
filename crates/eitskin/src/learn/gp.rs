//! Gaussian-process regression on z-scored channels (kernel ridge with an uncertainty).
//!
//! Squared-exponential kernel k(a, b) = exp(−|a − b|² / (2ℓ²D)) over D used channels (ℓ is
//! relative to the spread of a channel, so one grid serves any channel count), unit signal
//! variance on standardised targets, noise variance σ². ℓ and σ² are chosen on a grid by the
//! log marginal likelihood summed over the outputs (Rasmussen & Williams, eq. 2.30), which
//! needs one Cholesky factor per grid point and no held-out presses.

use faer::linalg::solvers::{DenseSolveCore, Solve};
use faer::{Mat, Side};

/// The length scales tried, relative to √D.
pub const LENGTH_SCALES: [f64; 9] = [0.1, 0.15, 0.2, 0.3, 0.45, 0.7, 1.0, 1.5, 2.5];
/// The noise variances tried, of the standardised targets.
pub const NOISE_VARIANCES: [f64; 5] = [1e-5, 1e-4, 1e-3, 1e-2, 1e-1];

/// A trained process: its training points, weights and what the uncertainty needs.
#[derive(Debug, Clone)]
pub struct GaussianProcess {
    /// ℓ relative to √D.
    pub length_scale: f64,
    /// σ², of the standardised targets.
    pub noise_variance: f64,
    dimensions: usize,
    /// Training points, N × D.
    points: Mat<f64>,
    /// |point|² per training point.
    norms: Vec<f64>,
    /// (K + σ²I)⁻¹·Y, N × T (standardised targets).
    alpha: Mat<f64>,
    /// (K + σ²I)⁻¹, N × N, for the predictive variance.
    inverse: Mat<f64>,
    /// Target means and spreads, to undo the standardisation.
    target_mean: Vec<f64>,
    target_std: Vec<f64>,
}

/// Buffers for [`GaussianProcess::predict_into`], grown once.
#[derive(Debug, Clone, Default)]
pub struct GpScratch {
    kernel: Vec<f64>,
    product: Vec<f64>,
}

/// Squared distances between the rows of `a` and `b` (|a|² + |b|² − 2a·b, floored at 0).
fn squared_distances(a: &Mat<f64>, b: &Mat<f64>) -> Mat<f64> {
    let gram = a * b.transpose();
    let na: Vec<f64> = (0..a.nrows()).map(|i| (0..a.ncols()).map(|k| a[(i, k)] * a[(i, k)]).sum()).collect();
    let nb: Vec<f64> = (0..b.nrows()).map(|i| (0..b.ncols()).map(|k| b[(i, k)] * b[(i, k)]).sum()).collect();
    Mat::from_fn(a.nrows(), b.nrows(), |i, j| (na[i] + nb[j] - 2.0 * gram[(i, j)]).max(0.0))
}

impl GaussianProcess {
    /// Trains on `points` (z-scored rows, N × D) and `targets` (N rows of T outputs), with the
    /// grid point of the largest log marginal likelihood; `None` with fewer than 2 points.
    pub fn fit(points: &[Vec<f64>], targets: &[Vec<f64>]) -> Option<GaussianProcess> {
        let n = points.len();
        let dimensions = points.first().map_or(0, Vec::len);
        let outputs = targets.first().map_or(0, Vec::len);
        if n < 2 || dimensions == 0 || outputs == 0 {
            return None;
        }
        let x = Mat::from_fn(n, dimensions, |i, k| points[i][k]);
        let target_mean: Vec<f64> =
            (0..outputs).map(|t| targets.iter().map(|r| r[t]).sum::<f64>() / n as f64).collect();
        let target_std: Vec<f64> = (0..outputs)
            .map(|t| {
                let v = targets.iter().map(|r| (r[t] - target_mean[t]).powi(2)).sum::<f64>() / n as f64;
                if v > 0.0 {
                    v.sqrt()
                } else {
                    1.0
                }
            })
            .collect();
        let y = Mat::from_fn(n, outputs, |i, t| (targets[i][t] - target_mean[t]) / target_std[t]);
        let distances = squared_distances(&x, &x);
        let mut best: Option<(f64, f64, f64)> = None;
        for &length in &LENGTH_SCALES {
            let scale = 1.0 / (2.0 * length * length * dimensions as f64);
            for &noise in &NOISE_VARIANCES {
                let k =
                    Mat::from_fn(n, n, |i, j| (-distances[(i, j)] * scale).exp() + if i == j { noise } else { 0.0 });
                let Ok(llt) = k.llt(Side::Lower) else { continue };
                let alpha = llt.solve(&y);
                let fit: f64 = (0..outputs).map(|t| (0..n).map(|i| y[(i, t)] * alpha[(i, t)]).sum::<f64>()).sum();
                let log_det: f64 = (0..n).map(|i| llt.L()[(i, i)].ln()).sum::<f64>() * 2.0;
                let lml = -0.5 * fit - 0.5 * outputs as f64 * log_det;
                if best.is_none_or(|b| lml > b.0) {
                    best = Some((lml, length, noise));
                }
            }
        }
        let (_, length_scale, noise_variance) = best?;
        let scale = 1.0 / (2.0 * length_scale * length_scale * dimensions as f64);
        let k =
            Mat::from_fn(n, n, |i, j| (-distances[(i, j)] * scale).exp() + if i == j { noise_variance } else { 0.0 });
        let llt = k.llt(Side::Lower).ok()?;
        let alpha = llt.solve(&y);
        let inverse = llt.inverse();
        let norms = (0..n).map(|i| (0..dimensions).map(|k| x[(i, k)] * x[(i, k)]).sum()).collect();
        Some(GaussianProcess {
            length_scale,
            noise_variance,
            dimensions,
            points: x,
            norms,
            alpha,
            inverse,
            target_mean,
            target_std,
        })
    }

    /// The predictive mean of each output for `z` into `out`, and its standard deviation into
    /// `std` (in the targets' units; `std` may be empty to skip it). Allocates nothing once
    /// `scratch` has grown.
    pub fn predict_into(&self, z: &[f64], scratch: &mut GpScratch, out: &mut [f64], std: &mut [f64]) {
        let n = self.points.nrows();
        let scale = 1.0 / (2.0 * self.length_scale * self.length_scale * self.dimensions as f64);
        let zz: f64 = z.iter().map(|v| v * v).sum();
        scratch.kernel.resize(n, 0.0);
        for (i, k) in scratch.kernel.iter_mut().enumerate() {
            let row = self.points.row(i);
            let dot: f64 = (0..self.dimensions).map(|d| row[d] * z[d]).sum();
            *k = (-(self.norms[i] + zz - 2.0 * dot).max(0.0) * scale).exp();
        }
        for (t, o) in out.iter_mut().enumerate() {
            let mean: f64 = (0..n).map(|i| self.alpha[(i, t)] * scratch.kernel[i]).sum();
            *o = self.target_mean[t] + self.target_std[t] * mean;
        }
        if std.is_empty() {
            return;
        }
        // kᵀ(K + σ²I)⁻¹k, the part of the prior variance the training points explain.
        scratch.product.resize(n, 0.0);
        for (j, p) in scratch.product.iter_mut().enumerate() {
            let column = self.inverse.col(j);
            *p = (0..n).map(|i| column[i] * scratch.kernel[i]).sum();
        }
        let explained: f64 = scratch.product.iter().zip(&scratch.kernel).map(|(p, k)| p * k).sum();
        let variance = (1.0 + self.noise_variance - explained).max(self.noise_variance);
        for (t, s) in std.iter_mut().enumerate() {
            *s = self.target_std[t] * variance.sqrt();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth function of two inputs is learned from 60 points to well within its range, and
    /// the uncertainty is small at a training point and large far from every point.
    #[test]
    fn a_smooth_function_is_learned_with_its_uncertainty() {
        let f = |a: f64, b: f64| (1.5 * a).sin() + 0.5 * b * b;
        let points: Vec<Vec<f64>> =
            (0..60).map(|i| vec![-2.0 + 4.0 * ((i * 7) % 60) as f64 / 59.0, -2.0 + 4.0 * i as f64 / 59.0]).collect();
        let targets: Vec<Vec<f64>> = points.iter().map(|p| vec![f(p[0], p[1])]).collect();
        let gp = GaussianProcess::fit(&points, &targets).unwrap();
        let (mut scratch, mut out, mut std) = (GpScratch::default(), [0.0], [0.0]);
        let mut worst: f64 = 0.0;
        for i in 0..20 {
            let q = [-1.5 + 3.0 * i as f64 / 19.0, 1.0 - 0.1 * i as f64];
            gp.predict_into(&q, &mut scratch, &mut out, &mut std);
            worst = worst.max((out[0] - f(q[0], q[1])).abs());
        }
        assert!(worst < 0.1, "largest error {worst} (ℓ = {}, σ² = {})", gp.length_scale, gp.noise_variance);
        gp.predict_into(&points[5], &mut scratch, &mut out, &mut std);
        let near = std[0];
        gp.predict_into(&[30.0, -30.0], &mut scratch, &mut out, &mut std);
        assert!(near < 0.1 * std[0], "std at a training point {near}, far away {}", std[0]);
    }
}
