//! Gaussian-process regression on z-scored channels (kernel ridge with an uncertainty).
//!
//! Squared-exponential kernel k(a, b) = exp(−|a − b|² / (2ℓ²D)) over D used channels (ℓ is
//! relative to the spread of a channel, so one grid serves any channel count), unit signal
//! variance on standardised targets, noise variance σ², and optionally a linear term λ·a·b/D
//! (a Bayesian linear mean, R&W §2.7). ℓ, σ² and λ are chosen on a grid by the log marginal
//! likelihood summed over the outputs (Rasmussen & Williams, eq. 2.30), which needs one
//! Cholesky factor per grid point and no held-out presses.

use crate::parallel::widest;
use std::sync::atomic::{AtomicU64, Ordering};

use faer::linalg::solvers::{DenseSolveCore, Solve};
use faer::{Mat, Side};

/// The length scales tried, relative to √D.
pub const LENGTH_SCALES: [f64; 9] = [0.1, 0.15, 0.2, 0.3, 0.45, 0.7, 1.0, 1.5, 2.5];
/// The noise variances tried, of the standardised targets.
pub const NOISE_VARIANCES: [f64; 5] = [1e-5, 1e-4, 1e-3, 1e-2, 1e-1];
/// The weights of the linear kernel term tried.
pub const LINEAR_WEIGHTS: [f64; 3] = [0.0, 3.0, 30.0];

/// Chunks of rows the predictive variance is split into (about equal work each).
const VARIANCE_CHUNKS: usize = 8;

/// A trained process: its training points, weights and what the uncertainty needs.
#[derive(Debug, Clone)]
pub struct GaussianProcess {
    /// ℓ relative to √D.
    pub length_scale: f64,
    /// σ², of the standardised targets.
    pub noise_variance: f64,
    /// λ of the linear term λ·a·b/D.
    pub linear: f64,
    dimensions: usize,
    /// Training points, N × D in f32 in the image product's blocked layout: a frame's distances
    /// are |p|² + |z|² − 2p·z, the p·z of every point in one pass at the memory limit (shared
    /// with a second core while it is free). In f32 at N = 1,000, D = 192 they fit a core's L2.
    points: crate::inverse::BlockedMatrix,
    /// |p|² per training point (of the f32 values).
    norms: Vec<f64>,
    /// (K + σ²I)⁻¹·Y, row-major T × N (standardised targets).
    alpha: Vec<f64>,
    /// What the predictive variance kᵀ(K + σ²I)⁻¹k is computed with.
    variance: Variance,
    /// Target means and spreads, to undo the standardisation.
    target_mean: Vec<f64>,
    target_std: Vec<f64>,
}

/// (K + σ²I)⁻¹ as the predictive variance reads it: a frame's largest read.
#[derive(Debug, Clone)]
enum Variance {
    /// Its upper triangle (it is symmetric), row by row (row i holds columns i..N), in f32: its
    /// rounding (~1e-7 relative) is far below the variance's scale.
    Packed {
        inverse: Vec<f32>,
        /// Where each row of `inverse` starts, and one more entry for its end.
        row_start: Vec<usize>,
        /// The rows of each chunk of the work (about equal entries each), as boundaries.
        chunk_rows: Vec<usize>,
    },
    /// B = diag(1/√(λᵢ + σ²))·Uᵀ over the r largest eigenpairs (λᵢ, uᵢ) of the noise-free K, so
    /// that kᵀ(K + σ²I)⁻¹k ≈ |Bk|²: a smooth kernel's spectrum falls fast, and r is the fewest
    /// pairs that leave every training point's variance within [`LOW_RANK_TOLERANCE`]·σ² (used
    /// only when r ≤ N/4, a smaller read than the triangle's). In f64, row-major r × N: |Bk|²
    /// is about the prior variance, and the variance its difference from it, down to σ².
    LowRank {
        basis: Vec<f64>,
        /// The rows of each chunk of the work, as boundaries.
        chunk_rows: Vec<usize>,
    },
}

/// The largest error, as a fraction of σ², that dropping eigenpairs may leave in a training
/// point's predictive variance (0.05 % of the smallest standard deviation the process gives).
pub const LOW_RANK_TOLERANCE: f64 = 0.001;

/// Buffers for [`GaussianProcess::predict_into`], grown once.
#[derive(Debug, Default)]
pub struct GpScratch {
    kernel: Vec<f64>,
    /// p·z for every training point.
    dots: Vec<f32>,
    /// The kernel row in f32, for the variance.
    product: Vec<f32>,
    /// The variance's partial sums, one per chunk of rows.
    partial: Vec<AtomicU64>,
}

/// Each output's mean and standard deviation over `targets` (N rows of T outputs; 1 for an
/// output that does not vary) and the targets standardised by them, N × T.
pub(super) fn standardised(targets: &[Vec<f64>]) -> (Vec<f64>, Vec<f64>, Mat<f64>) {
    let (n, outputs) = (targets.len(), targets.first().map_or(0, Vec::len));
    let mean: Vec<f64> = (0..outputs).map(|t| targets.iter().map(|r| r[t]).sum::<f64>() / n as f64).collect();
    let std: Vec<f64> = (0..outputs)
        .map(|t| {
            let v = targets.iter().map(|r| (r[t] - mean[t]).powi(2)).sum::<f64>() / n as f64;
            if v > 0.0 {
                v.sqrt()
            } else {
                1.0
            }
        })
        .collect();
    let y = Mat::from_fn(n, outputs, |i, t| (targets[i][t] - mean[t]) / std[t]);
    (mean, std, y)
}

/// Squared distances between the rows of `a` and `b` (|a|² + |b|² − 2a·b, floored at 0).
pub(super) fn squared_distances(a: &Mat<f64>, b: &Mat<f64>) -> Mat<f64> {
    let gram = a * b.transpose();
    let na: Vec<f64> = (0..a.nrows()).map(|i| (0..a.ncols()).map(|k| a[(i, k)] * a[(i, k)]).sum()).collect();
    let nb: Vec<f64> = (0..b.nrows()).map(|i| (0..b.ncols()).map(|k| b[(i, k)] * b[(i, k)]).sum()).collect();
    Mat::from_fn(a.nrows(), b.nrows(), |i, j| (na[i] + nb[j] - 2.0 * gram[(i, j)]).max(0.0))
}

impl GaussianProcess {
    /// Trains on `points` (z-scored rows, N × D) and `targets` (N rows of T outputs), with the
    /// grid point of the largest log marginal likelihood, the weights of the linear term tried
    /// being `linear` (`&[0.0]`: none); `None` with fewer than 2 points.
    pub fn fit(points: &[Vec<f64>], targets: &[Vec<f64>], linear: &[f64]) -> Option<GaussianProcess> {
        let n = points.len();
        let dimensions = points.first().map_or(0, Vec::len);
        let outputs = targets.first().map_or(0, Vec::len);
        if n < 2 || dimensions == 0 || outputs == 0 {
            return None;
        }
        let x = Mat::from_fn(n, dimensions, |i, k| points[i][k]);
        let (target_mean, target_std, y) = standardised(targets);
        let distances = squared_distances(&x, &x);
        let gram = &x * x.transpose();
        let dims = dimensions as f64;
        // K + σ²I of length scale ℓ (relative to √D) and linear weight λ.
        let kernel = |length: f64, linear: f64, noise: f64| {
            let scale = 1.0 / (2.0 * length * length * dims);
            Mat::from_fn(n, n, |i, j| {
                (-distances[(i, j)] * scale).exp() + linear * gram[(i, j)] / dims + if i == j { noise } else { 0.0 }
            })
        };
        let mut best: Option<(f64, f64, f64, f64)> = None;
        for &linear in linear {
            for &length in &LENGTH_SCALES {
                for &noise in &NOISE_VARIANCES {
                    let Ok(llt) = kernel(length, linear, noise).llt(Side::Lower) else { continue };
                    let alpha = llt.solve(&y);
                    let fit: f64 = (0..outputs).map(|t| (0..n).map(|i| y[(i, t)] * alpha[(i, t)]).sum::<f64>()).sum();
                    let log_det: f64 = (0..n).map(|i| llt.L()[(i, i)].ln()).sum::<f64>() * 2.0;
                    let lml = -0.5 * fit - 0.5 * outputs as f64 * log_det;
                    if best.is_none_or(|b| lml > b.0) {
                        best = Some((lml, length, noise, linear));
                    }
                }
            }
        }
        let (_, length_scale, noise_variance, linear) = best?;
        let llt = kernel(length_scale, linear, noise_variance).llt(Side::Lower).ok()?;
        let alpha = llt.solve(&y);
        let alpha = (0..outputs * n).map(|k| alpha[(k % n, k / n)]).collect();
        let variance = Variance::low_rank(&kernel(length_scale, linear, 0.0), noise_variance)
            .unwrap_or_else(|| Variance::packed(&llt.inverse()));
        let mut points = crate::inverse::BlockedMatrix::zeros(n, dimensions);
        let mut norms = vec![0.0; n];
        for i in 0..n {
            for k in 0..dimensions {
                let v = x[(i, k)] as f32;
                points.set(i, k, v);
                norms[i] += f64::from(v) * f64::from(v);
            }
        }
        Some(GaussianProcess {
            length_scale,
            noise_variance,
            linear,
            dimensions,
            points,
            norms,
            alpha,
            variance,
            target_mean,
            target_std,
        })
    }

    /// The predictive mean of each output for `z` into `out`, and its standard deviation into
    /// `std` (in the targets' units; `std` may be empty to skip it). Allocates nothing once
    /// `scratch` has grown.
    pub fn predict_into(&self, z: &[f64], scratch: &mut GpScratch, out: &mut [f64], std: &mut [f64]) {
        let n = self.alpha.len() / self.target_mean.len().max(1);
        let scale = 1.0 / (2.0 * self.length_scale * self.length_scale * self.dimensions as f64);
        let zz: f64 = z.iter().map(|&v| f64::from(v as f32).powi(2)).sum();
        scratch.dots.resize(n, 0.0);
        self.points.mul_into(&mut scratch.dots, |k| z[k] as f32);
        scratch.kernel.clear();
        scratch.kernel.extend(scratch.dots.iter().zip(&self.norms).map(|(&dot, norm)| {
            (-(norm + zz - 2.0 * f64::from(dot)).max(0.0) * scale).exp()
                + self.linear * f64::from(dot) / self.dimensions as f64
        }));
        for ((o, weights), (mean, spread)) in
            out.iter_mut().zip(self.alpha.chunks_exact(n)).zip(self.target_mean.iter().zip(&self.target_std))
        {
            *o = mean + spread * dot_portable::<f64, 16>(weights, &scratch.kernel);
        }
        if std.is_empty() {
            return;
        }
        // kᵀ(K + σ²I)⁻¹k, the part of the prior variance the training points explain.
        let explained = self.variance.explained(scratch);
        let variance = (1.0 + self.linear * zz / self.dimensions as f64 + self.noise_variance - explained)
            .max(self.noise_variance);
        for (s, spread) in std.iter_mut().zip(&self.target_std) {
            *s = spread * variance.sqrt();
        }
    }
}

impl Variance {
    /// The packed upper triangle of `inverse`, (K + σ²I)⁻¹.
    fn packed(inverse: &Mat<f64>) -> Variance {
        let n = inverse.nrows();
        let packed = (0..n).flat_map(|i| (i..n).map(move |j| (i, j))).map(|(i, j)| inverse[(i, j)] as f32).collect();
        // Row i of the packed upper triangle holds columns i..n.
        let row_start: Vec<usize> = std::iter::once(0)
            .chain((0..n).scan(0, |at, i| {
                *at += n - i;
                Some(*at)
            }))
            .collect();
        let per_chunk = (row_start[n] / VARIANCE_CHUNKS).max(1);
        let mut chunk_rows = vec![0];
        for (i, &start) in row_start.iter().enumerate().take(n).skip(1) {
            if start >= per_chunk * chunk_rows.len() {
                chunk_rows.push(i);
            }
        }
        chunk_rows.push(n);
        Variance::Packed { inverse: packed, row_start, chunk_rows }
    }

    /// The low-rank form of (`noise_free` + σ²I)⁻¹, if at most N/4 eigenpairs meet the tolerance.
    fn low_rank(noise_free: &Mat<f64>, noise_variance: f64) -> Option<Variance> {
        let n = noise_free.nrows();
        let eigen = noise_free.self_adjoint_eigen(Side::Lower).ok()?;
        let (u, values) = (eigen.U(), eigen.S().column_vector());
        // At training point j, k = K·e_j and pair i explains λᵢ²·u_ij²/(λᵢ + σ²); the pairs are
        // taken from the largest λ until what is left at every point is within tolerance.
        let term = |i: usize, j: usize| {
            let l = values[i].max(0.0);
            l * l * u[(j, i)] * u[(j, i)] / (l + noise_variance)
        };
        let mut left: Vec<f64> = (0..n).map(|j| (0..n).map(|i| term(i, j)).sum()).collect();
        let tolerance = LOW_RANK_TOLERANCE * noise_variance;
        let mut rank = 0;
        while left.iter().any(|&l| l > tolerance) {
            if rank >= n / 4 {
                return None;
            }
            let i = n - 1 - rank;
            left.iter_mut().enumerate().for_each(|(j, l)| *l -= term(i, j));
            rank += 1;
        }
        let basis = (0..rank)
            .flat_map(|r| {
                let i = n - 1 - r;
                let weight = 1.0 / (values[i].max(0.0) + noise_variance).sqrt();
                (0..n).map(move |j| weight * u[(j, i)])
            })
            .collect();
        let chunks = VARIANCE_CHUNKS.min(rank).max(1);
        let chunk_rows = (0..=chunks).map(|c| c * rank / chunks).collect();
        Some(Variance::LowRank { basis, chunk_rows })
    }

    /// kᵀ(K + σ²I)⁻¹k for the kernel row in `scratch`, in chunks of rows shared with a second
    /// core while it is free.
    fn explained(&self, scratch: &mut GpScratch) -> f64 {
        let chunk_rows = match self {
            Variance::Packed { chunk_rows, .. } | Variance::LowRank { chunk_rows, .. } => chunk_rows,
        };
        let chunks = chunk_rows.len() - 1;
        scratch.partial.resize_with(chunks, || AtomicU64::new(0));
        // The packed f32 triangle reads the kernel row in f32; the low-rank basis in f64.
        scratch.product.clear();
        if let Variance::Packed { .. } = self {
            scratch.product.extend(scratch.kernel.iter().map(|&k| k as f32));
        }
        let (kernel, product, partial) = (&scratch.kernel, &scratch.product, &scratch.partial);
        crate::parallel::run_split(chunks, &|c| {
            let rows = chunk_rows[c]..chunk_rows[c + 1];
            let sum = match self {
                Variance::Packed { inverse, row_start, .. } => quadratic_rows(inverse, row_start, product, rows),
                Variance::LowRank { basis, .. } => squared_rows(basis, kernel, rows),
            };
            partial[c].store(sum.to_bits(), Ordering::Relaxed);
        });
        partial.iter().map(|p| f64::from_bits(p.load(Ordering::Relaxed))).sum()
    }
}

widest! {
    /// Σᵢ kᵢ·(2·Σ_{j≥i} A_ij k_j − A_ii k_i) over `rows` of the packed upper triangle `inverse`.
    fn quadratic_rows = quadratic_rows_portable(inverse: &[f32], row_start: &[usize], kernel: &[f32], rows: std::ops::Range<usize>) -> f64
}

widest! {
    /// Σᵢ (Bᵢ·k)² over `rows` of the row-major `basis` (rows of k's length).
    fn squared_rows = squared_rows_portable(basis: &[f64], kernel: &[f64], rows: std::ops::Range<usize>) -> f64
}

#[inline(always)]
fn squared_rows_portable(basis: &[f64], kernel: &[f64], rows: std::ops::Range<usize>) -> f64 {
    let n = kernel.len();
    rows.map(|r| dot_portable::<f64, 16>(&basis[r * n..(r + 1) * n], kernel).powi(2)).sum()
}

#[inline(always)]
fn quadratic_rows_portable(inverse: &[f32], row_start: &[usize], kernel: &[f32], rows: std::ops::Range<usize>) -> f64 {
    let mut sum = 0.0;
    for i in rows {
        let row = &inverse[row_start[i]..row_start[i + 1]];
        let ki = kernel[i];
        sum += f64::from(ki) * f64::from(2.0 * dot_portable::<f32, 32>(row, &kernel[i..]) - row[0] * ki);
    }
    sum
}

/// Σ aᵢbᵢ in `LANES` independent sums, so that it vectorises (16 for f64, 32 for f32: two of
/// the widest registers).
#[inline(always)]
fn dot_portable<T, const LANES: usize>(a: &[T], b: &[T]) -> T
where
    T: Copy + Default + std::ops::Mul<Output = T> + std::ops::Add<Output = T> + std::ops::AddAssign + std::iter::Sum,
{
    let mut sums = [T::default(); LANES];
    let (ca, cb) = (a.chunks_exact(LANES), b.chunks_exact(LANES));
    let tail: T = ca.remainder().iter().zip(cb.remainder()).map(|(x, y)| *x * *y).sum();
    for (x, y) in ca.zip(cb) {
        for k in 0..LANES {
            sums[k] += x[k] * y[k];
        }
    }
    sums.into_iter().sum::<T>() + tail
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
        let gp = GaussianProcess::fit(&points, &targets, &[0.0]).unwrap();
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

    /// The low-rank variance of a smooth process (with a linear term, so a prior variance far
    /// above σ²) agrees with kᵀ(K + σ²I)⁻¹k solved in f64 between the training points to 2 %
    /// in the standard deviation; beyond them, where the pairs left out matter more, it errs on
    /// the side of more uncertainty (each would have explained a part of the variance), by < 5 %.
    #[test]
    fn the_low_rank_variance_is_the_exact_one() {
        let f = |a: f64, b: f64| a + 0.3 * (2.0 * b).sin();
        let points: Vec<Vec<f64>> = (0..400)
            .map(|i| vec![-1.7 + 3.4 * ((i * 37) % 400) as f64 / 399.0, -1.7 + 3.4 * i as f64 / 399.0])
            .collect();
        let targets: Vec<Vec<f64>> = points.iter().map(|p| vec![f(p[0], p[1])]).collect();
        let gp = GaussianProcess::fit(&points, &targets, &LINEAR_WEIGHTS).unwrap();
        assert!(matches!(gp.variance, Variance::LowRank { .. }), "ℓ = {}, σ² = {}", gp.length_scale, gp.noise_variance);
        assert!(gp.linear > 0.0);
        let n = points.len();
        let spread = (targets.iter().map(|t| t[0] * t[0]).sum::<f64>() / n as f64
            - (targets.iter().map(|t| t[0]).sum::<f64>() / n as f64).powi(2))
        .sqrt();
        let scale = 1.0 / (4.0 * gp.length_scale * gp.length_scale);
        // On the inputs as the process holds them, in f32.
        let kernel = |a: &[f64], b: &[f64]| {
            let round = |v: &[f64]| [f64::from(v[0] as f32), f64::from(v[1] as f32)];
            let (a, b) = (round(a), round(b));
            let d2 = (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2);
            (-d2 * scale).exp() + gp.linear * (a[0] * b[0] + a[1] * b[1]) / 2.0
        };
        let k =
            Mat::from_fn(n, n, |i, j| kernel(&points[i], &points[j]) + if i == j { gp.noise_variance } else { 0.0 });
        let llt = k.llt(Side::Lower).unwrap();
        let (mut scratch, mut out, mut std) = (GpScratch::default(), [0.0], [0.0]);
        for (q, within) in
            [([0.1, 0.2], 0.02), ([1.3, -0.9], 0.02), ([-1.6, 1.6], 0.02), ([2.5, 0.0], 0.05), ([6.0, -6.0], 0.05)]
        {
            let row = Mat::from_fn(n, 1, |i, _| kernel(&points[i], &q));
            let solved = llt.solve(&row);
            let explained: f64 = (0..n).map(|i| row[(i, 0)] * solved[(i, 0)]).sum();
            let exact = spread * (kernel(&q, &q) + gp.noise_variance - explained).sqrt();
            gp.predict_into(&q, &mut scratch, &mut out, &mut std);
            let ratio = std[0] / exact;
            assert!(ratio > 0.98 && ratio < 1.0 + within, "at {q:?}: {} vs {exact}", std[0]);
        }
    }
}
