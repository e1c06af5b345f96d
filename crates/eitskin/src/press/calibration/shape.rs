//! The curve's shapes: how a strength falls from its value at F = 0 towards its asymptote.
//!
//! The paper's curve is s(F) = a·e^(−F/b) + c. A gel whose drop follows F/(F + F₀), or a press
//! whose polarisation saturates as a power of F, approaches its asymptote more slowly than any
//! exponential: fitted with one, the curve is too flat at large forces and reads them with
//! errors many times the noise's. So a curve may also take the shape
//!
//! s(F) = a·(1 + F/(k·b))^(−k) + c, k > 0,
//!
//! whose limit as k → ∞ is the exponential (a hyperbola at k = 1). [`Curve::fit`](super::Curve::fit)
//! fits the exponential and each of [`SHAPES`], and keeps the shape with the least sum of
//! squares where it lowers the exponential's by more than chance would (a likelihood-ratio
//! test, the shape counted as a fourth parameter); else the paper's curve. A
//! finite shape is fitted only for b > 0 (a strength that saturates) and forces ≥ 0, where
//! 1 + F/(k·b) > 0.
//!
//! Each finite shape is fitted by its profile over the force scale b: at each b on a grid, a
//! and c are linear least squares; then the best grid point is refined by golden-section search
//! in log b. Every curve of the family is monotone, so data that rise with force always get one.
//!
//! ```
//! use eitskin::calibration::Curve;
//! // A hyperbola: 0.7·F/(F + 4) = 0.7 − 0.7·(1 + F/4)^(−1).
//! let forces: Vec<f64> = (0..=15).map(f64::from).collect(); // N
//! let drops: Vec<f64> = forces.iter().map(|f| 0.7 * f / (f + 4.0)).collect();
//! let curve = Curve::fit(0, &forces, &drops)?;
//! assert_eq!(curve.shape, Some(1.0));
//! assert!((curve.b - 4.0).abs() < 1e-4 && (curve.force(curve.peak(12.0)).newtons - 12.0).abs() < 1e-4);
//! # Ok::<(), eitskin::calibration::CalibrationError>(())
//! ```

/// The shapes k tried besides the exponential.
pub const SHAPES: [f64; 5] = [0.5, 1.0, 2.0, 4.0, 8.0];

/// Decay rates κ = span/b of the profile's grid run from 1/[`RATES`] to [`RATES`], log-spaced.
const RATES: f64 = 1e3;
/// Points of the profile's grid.
const GRID: usize = 240;
/// Golden-section steps refining the grid's best point (each shrinks the bracket by 0.618).
const GOLDEN_STEPS: usize = 60;

/// The fall g(t) from g(0) = 1 towards 0 at t = F/b: e^(−t) for the exponential (`None`),
/// (1 + t/k)^(−k) for shape k.
pub(super) fn fall(shape: Option<f64>, t: f64) -> f64 {
    match shape {
        None => (-t).exp(),
        Some(k) => (1.0 + t / k).max(0.0).powf(-k),
    }
}

/// dg/dt: −e^(−t), or −(1 + t/k)^(−k−1).
pub(super) fn fall_slope(shape: Option<f64>, t: f64) -> f64 {
    match shape {
        None => -(-t).exp(),
        Some(k) => -(1.0 + t / k).max(0.0).powf(-k - 1.0),
    }
}

/// The t with g(t) = `ratio` (> 0): −ln ratio, or k·(ratio^(−1/k) − 1).
pub(super) fn fall_inverse(shape: Option<f64>, ratio: f64) -> f64 {
    match shape {
        None => -ratio.ln(),
        Some(k) => k * (ratio.powf(-1.0 / k) - 1.0),
    }
}

/// A finite shape's best curve: a, b, c and its sum of squares.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct ShapeFit {
    pub shape: f64,
    pub a: f64,
    pub b: f64,
    pub c: f64,
    pub sum_of_squares: f64,
}

/// The least-squares curve a·(1 + F/(k·b))^(−k) + c with b > 0 through (`forces`, `peaks`):
/// forces ≥ 0 spanning `span` > 0, the peaks' mean `mean` and spread `spread` > 0 (as
/// [`Curve::fit`](super::Curve::fit) has them). `None` where no b gives finite numbers.
pub(super) fn fit_shape(
    shape: f64,
    forces: &[f64],
    peaks: &[f64],
    span: f64,
    mean: f64,
    spread: f64,
) -> Option<ShapeFit> {
    // Scaled as the exponential's fit: x = F/span, y = (s − mean)/spread, and the regressor
    // φ(κ, x) = (1 − g(κx))/κ, which tends to x as κ → 0 (a straight line stays regular).
    let xs: Vec<f64> = forces.iter().map(|f| f / span).collect();
    let ys: Vec<f64> = peaks.iter().map(|p| (p - mean) / spread).collect();
    let at = |log_rate: f64| line(&xs, &ys, shape, log_rate.exp());
    let (lo, hi) = (-RATES.ln(), RATES.ln());
    let step = (hi - lo) / (GRID - 1) as f64;
    let (best, _) = (0..GRID)
        .map(|i| (i, at(lo + step * i as f64).map_or(f64::INFINITY, |l| l.2)))
        .min_by(|x, y| x.1.total_cmp(&y.1))?;
    // Golden-section search in log κ between the best point's neighbours.
    let ratio = (5f64.sqrt() - 1.0) / 2.0;
    let (mut left, mut right) =
        (lo + step * best.saturating_sub(1) as f64, lo + step * (best + 1).min(GRID - 1) as f64);
    for _ in 0..GOLDEN_STEPS {
        let (p, q) = (right - ratio * (right - left), left + ratio * (right - left));
        let cost = |r: f64| at(r).map_or(f64::INFINITY, |l| l.2);
        if cost(p) <= cost(q) {
            right = q;
        } else {
            left = p;
        }
    }
    let rate = ((left + right) / 2.0).exp();
    let (value, slope, sum_of_squares) = at(rate.ln())?;
    // y = D + B·(1 − g)/κ = (D + B/κ) − (B/κ)·g: amplitude −B/κ, asymptote D + B/κ.
    let (amplitude, asymptote) = (-slope / rate, value + slope / rate);
    let fit = ShapeFit {
        shape,
        a: spread * amplitude,
        b: span / rate,
        c: spread * asymptote + mean,
        sum_of_squares: sum_of_squares * spread * spread,
    };
    (fit.a.is_finite() && fit.b.is_finite() && fit.c.is_finite() && fit.b > 0.0).then_some(fit)
}

/// D, B and the sum of squares of the least-squares line y = D + B·φ(κ, x) at `rate` κ.
fn line(xs: &[f64], ys: &[f64], shape: f64, rate: f64) -> Option<(f64, f64, f64)> {
    let phi = |x: f64| (1.0 - fall(Some(shape), rate * x)) / rate;
    let (value, slope) = super::line_through(xs.iter().zip(ys).map(|(&x, &y)| (phi(x), y)))?;
    let sum_of_squares: f64 = xs.iter().zip(ys).map(|(&x, y)| (y - value - slope * phi(x)).powi(2)).sum();
    sum_of_squares.is_finite().then_some((value, slope, sum_of_squares))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// g, its slope and its inverse agree, for the exponential and each shape; a large k is
    /// nearly the exponential.
    #[test]
    fn the_fall_its_slope_and_its_inverse_agree() {
        for shape in [None, Some(0.5), Some(1.0), Some(4.0)] {
            for t in [0.0, 0.3, 1.0, 4.0] {
                let h = 1e-6;
                let numeric = (fall(shape, t + h) - fall(shape, t - h)) / (2.0 * h);
                assert!((numeric - fall_slope(shape, t)).abs() < 1e-7, "{shape:?} {t}");
                assert!((fall_inverse(shape, fall(shape, t)) - t).abs() < 1e-10, "{shape:?} {t}");
            }
        }
        assert!((fall(Some(1e6), 2.0) - (-2.0f64).exp()).abs() < 1e-6);
    }

    /// Each shape's exact samples are fitted back to their parameters.
    #[test]
    fn each_shape_is_fitted_back() {
        for shape in SHAPES {
            let forces: Vec<f64> = (0..=16).map(f64::from).collect();
            let peaks: Vec<f64> = forces.iter().map(|f| -0.8 * fall(Some(shape), f / 3.0) + 0.9).collect();
            let mean = peaks.iter().sum::<f64>() / peaks.len() as f64;
            let spread = (peaks.iter().map(|p| (p - mean).powi(2)).sum::<f64>() / peaks.len() as f64).sqrt();
            let fit = fit_shape(shape, &forces, &peaks, 16.0, mean, spread).unwrap();
            assert!((fit.a + 0.8).abs() < 1e-6 && (fit.b - 3.0).abs() < 1e-5 && (fit.c - 0.9).abs() < 1e-6, "{fit:?}");
            assert!(fit.sum_of_squares < 1e-12, "{fit:?}");
        }
    }
}
