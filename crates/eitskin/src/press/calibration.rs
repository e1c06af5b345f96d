//! Force calibration: per area of the sensor, the touch peak follows the force as
//! σ(F) = a·e^(−F/b) + c, and a force is read off the inverse of that curve. Where the data
//! approach their asymptote more slowly than an exponential can, the curve takes the shape
//! a·(1 + F/(k·b))^(−k) + c instead, whose limit as k → ∞ is the paper's (module `shape`).
//!
//! The paper (its section 3.3, eq. 4 and Table 2) divides the sheet into areas, loads one unit of
//! each area at known forces and fits, per area, the reconstructed conductivity peak against the
//! force:
//!
//! 1. peak(F) = a·e^(−F/b) + c, with the peak a positive magnitude in S/m (a press lowers the
//!    conductivity; [`crate::touch::Touch`] reports the size of that dip), F in N, a and c in S/m
//!    and b in N. A peak that grows and saturates with force has a < 0, b > 0, c > 0 and
//!    peak(0) = a + c ≈ 0, but no sign is imposed: the least-squares fit decides;
//! 2. the fit minimises Σ (peakᵢ − peak(Fᵢ))² by Levenberg–Marquardt and reports
//!    R² = 1 − SS_res/SS_tot, SS_tot taken about the mean peak;
//! 3. a force is read off the inverse, F = −b·ln((peak − c)/a), defined where (peak − c)/a > 0.
//!
//! The inverse is clamped to the force range the fit saw, [F_min, F_max], and flagged
//! `saturated` when it had to be: a peak at or past the asymptote c (no finite force gives it)
//! reads as the end of the range where the curve approaches c (F_max for b > 0), and an inverse
//! that leaves the range by more than 10⁻⁹ of its span reads as the nearer end.
//!
//! A nearly linear data set drives b towards ∞; the fit holds |b| ≤ 10⁶ × the force span there,
//! where the curve is a straight line to within the noise and stays invertible.
//!
//! The solver is our own: three parameters need a 3 × 3 damped normal-equation solve on plain
//! arrays, and the `levenberg-marquardt` crate would bring nalgebra, which this crate keeps out
//! of its public API and its dependencies. It works on scaled data (force span and peak spread
//! of 1) in the form y = D + B·(1 − e^(−κx))/κ with κ = span/b, which tends to the straight line
//! D + B·x as b → ∞ instead of sending a and c to ∞. It starts from b₀·{1, 0.3, 3, −1, −3}, b₀
//! from the data (c₀ the mean peak at the largest force, a₀ that at the smallest less c₀, b₀ from
//! a straight-line fit of ln|peak − c₀| against F), and keeps the best fit that converges.
//! Where none converges, the fit falls back to the best curve of the family on a grid of decay
//! rates κ ∈ [−40, 40] (D and B in closed form at each, a straight line at κ = 0) and says so
//! ([`Curve::fallback`]): every curve of the family is monotone, so data that rise with force
//! always get one.
//!
//! ```
//! use eitskin::calibration::Curve;
//! let forces: Vec<f64> = (0..=15).map(f64::from).collect(); // N
//! let peaks: Vec<f64> = forces.iter().map(|f| -0.02 * (-f / 5.0).exp() + 0.021).collect(); // S/m
//! let curve = Curve::fit(0, &forces, &peaks)?;
//! assert!((curve.b - 5.0).abs() < 1e-6 && curve.r_squared > 0.999_999);
//! let estimate = curve.force(curve.peak(8.0));
//! assert!((estimate.newtons - 8.0).abs() < 1e-6 && !estimate.saturated);
//! let past = curve.force(0.03); // beyond the asymptote c = 0.021 S/m
//! assert!(past.saturated && past.newtons == 15.0);
//! # Ok::<(), eitskin::calibration::CalibrationError>(())
//! ```
//!
//! Not for: finding which area a touch lies in (that is `pseudo_array`), nor for making the
//! image the peak comes from (that is [`crate::inverse`]).

use thiserror::Error;

use crate::pseudo_array::PseudoArray;
use crate::strength::Reading;
pub use crate::strength::Strength;

mod shape;
mod spread;
pub use shape::SHAPES;
pub use spread::PLACE_FOLDS;

/// Largest |b| a fit may reach, as a multiple of the force span (b → ∞ for linear data).
pub const MAX_DECAY_PER_SPAN: f64 = 1e6;
/// The largest force a calibration sample or a calibrated range may hold, in N: a label past it
/// is a unit or a column gone wrong, not a press.
pub const MAX_FORCE: f64 = 1e5;
/// Most Levenberg–Marquardt iterations (Jacobian evaluations) per start.
const MAX_ITERATIONS: usize = 200;
/// Multiples of the estimated decay length b₀ to start from; negative ones let the data pick b < 0.
const START_MULTIPLES: [f64; 5] = [1.0, 0.3, 3.0, -1.0, -3.0];
/// A shape replaces the exponential only where it lowers the sum of squares by more than this
/// many times the residual variance it leaves (per degree of freedom, its shape counted as a
/// fourth parameter): χ²₁ passes 16 with a probability of 6e-5, so by chance one of the five
/// shapes does so for one data set of an exponential in about 3,000.
const SHAPE_TEST: f64 = 16.0;
/// Relative tolerance under which an inverse force still counts as inside the calibrated range.
const RANGE_TOLERANCE: f64 = 1e-9;
/// Points of the calibrated range a force's posterior is summed on ([`Curve::force_given`]).
const POSTERIOR_POINTS: usize = 512;
/// A posterior narrower than this many of its points (in standard deviations) is the inverse's.
const NARROW_POSTERIOR: f64 = 4.0;

/// What went wrong fitting or using a calibration; areas and samples are numbered from 1.
#[derive(Debug, Error, PartialEq)]
pub enum CalibrationError {
    /// The curve has 3 parameters, so an area needs samples at 3 or more distinct forces.
    #[error(
        "area {area} has samples at {distinct} distinct forces, but the curve a·e^(−F/b) + c needs at least 3: \
         load the area at more forces"
    )]
    TooFewForces {
        /// 1-based area.
        area: usize,
        /// Distinct forces found.
        distinct: usize,
    },
    /// Forces and peaks are pairs, and the two lists differ in length.
    #[error("area {area} has {forces} forces but {peaks} peaks: each force needs the peak measured at it")]
    LengthMismatch {
        /// 1-based area.
        area: usize,
        /// Forces given.
        forces: usize,
        /// Peaks given.
        peaks: usize,
    },
    /// A force or peak is NaN or infinite.
    #[error("the {quantity} of sample {sample} (area {area}) is not a finite number")]
    NotFinite {
        /// 1-based area.
        area: usize,
        /// 1-based position of the sample in the list given.
        sample: usize,
        /// "force" or "peak".
        quantity: &'static str,
    },
    /// Every peak of the area is the same, so no force can be read off a peak.
    #[error("every peak of area {area} is the same, so the peak does not respond to force there")]
    NoForceResponse {
        /// 1-based area.
        area: usize,
    },
    /// The fit converged to a parameter that is not finite.
    #[error(
        "the fit for area {area} gave a = {a}, b = {b}, c = {c}, which is not finite: \
         maybe the forces lie far from 0 compared with their span"
    )]
    NotFiniteFit {
        /// 1-based area.
        area: usize,
        /// Fitted a, in S/m.
        a: f64,
        /// Fitted b, in N.
        b: f64,
        /// Fitted c, in S/m.
        c: f64,
    },
    /// A calibration needs at least one area.
    #[error("a calibration needs at least 1 area, got 0")]
    NoAreas,
    /// An area has no calibration samples.
    #[error("area {area} has no calibration samples; every area needs samples at 3 or more distinct forces")]
    NoSamples {
        /// 1-based area.
        area: usize,
    },
    /// A sample names an area the calibration does not have.
    #[error("sample {sample} is for area {area}, but the calibration has {areas} areas (numbered from 1)")]
    SampleOutsideAreas {
        /// 1-based position of the sample in the list given.
        sample: usize,
        /// 1-based area the sample names.
        area: usize,
        /// Areas in the calibration.
        areas: usize,
    },
    /// A force was asked for in an area the calibration does not have.
    #[error("there is no area {area}: the calibration has {areas} areas (numbered from 1)")]
    NoSuchArea {
        /// 1-based area asked for.
        area: usize,
        /// Areas in the calibration.
        areas: usize,
    },
    /// A force was asked for with a peak that is NaN.
    #[error("the peak given for a touch in area {area} is NaN, so no force can be read off it")]
    PeakNotANumber {
        /// 1-based area.
        area: usize,
    },
}

/// One area's curve peak(F) = a·e^(−F/b) + c (the paper's), or a·(1 + F/(k·b))^(−k) + c of a
/// shape k (module `shape`), peak in S/m and F in N.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Curve {
    /// Amplitude a, in S/m (negative for a peak that grows with force).
    pub a: f64,
    /// Decay force b, in N (non-zero; |b| ≤ 10⁶ × the force span).
    pub b: f64,
    /// Asymptote c, the peak as F → ∞ for b > 0, in S/m.
    pub c: f64,
    /// Coefficient of determination R² = 1 − SS_res/SS_tot of the fit, dimensionless.
    pub r_squared: f64,
    /// Smallest and largest force the fit saw, in N.
    pub force_range: [f64; 2],
    /// Number of samples fitted.
    pub samples: usize,
    /// Standard deviation of the strength about the curve that the samples' own noise does not
    /// explain (where the press was, its shape, the model's error), in the strength's unit: the
    /// calibration's own residual spread, added to each reading's noise
    /// ([`Curve::force_given`]); 0 where unknown.
    pub spread: f64,
    /// Whether Levenberg–Marquardt converged from no start and the curve is the best of a grid
    /// of decay forces b instead (monotone like every curve of the family, but not a minimum).
    pub fallback: bool,
    /// The shape k > 0 of a·(1 + F/(k·b))^(−k) + c, whose fall to c is slower than the
    /// exponential's; `None` for the paper's a·e^(−F/b) + c (the limit k → ∞).
    pub shape: Option<f64>,
}

/// A force read off a curve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceEstimate {
    /// Force, in N (clamped to the calibrated range; NaN only for a NaN peak).
    pub newtons: f64,
    /// The peak was outside what the curve can invert, or the force outside the calibrated range.
    pub saturated: bool,
    /// Its standard deviation from the measurement noise, in N; `None` where the peak's noise
    /// is not known ([`Curve::force_given`]).
    pub std: Option<f64>,
}

impl Curve {
    /// Fits the curve to samples (force in N, peak in S/m): the paper's exponential, or the
    /// shape of [`SHAPES`] with the least sum of squares where one fits better (forces ≥ 0 and a
    /// strength that saturates); `area` (0-based) is only for messages.
    pub fn fit(area: usize, forces: &[f64], peaks: &[f64]) -> Result<Curve, CalibrationError> {
        Curve::fit_among(area, forces, peaks, &SHAPES)
    }

    /// [`Curve::fit`] with the exponential and `shapes` only.
    fn fit_among(area: usize, forces: &[f64], peaks: &[f64], shapes: &[f64]) -> Result<Curve, CalibrationError> {
        let area_number = area + 1;
        if forces.len() != peaks.len() {
            return Err(CalibrationError::LengthMismatch {
                area: area_number,
                forces: forces.len(),
                peaks: peaks.len(),
            });
        }
        for (index, (force, peak)) in forces.iter().zip(peaks).enumerate() {
            for (quantity, value) in [("force", force), ("peak", peak)] {
                if !value.is_finite() {
                    return Err(CalibrationError::NotFinite { area: area_number, sample: index + 1, quantity });
                }
            }
        }
        let distinct = distinct_count(forces);
        if distinct < 3 {
            return Err(CalibrationError::TooFewForces { area: area_number, distinct });
        }
        let low = forces.iter().copied().fold(f64::INFINITY, f64::min);
        let high = forces.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let span = high - low;
        if peaks.iter().all(|&p| p == peaks[0]) {
            return Err(CalibrationError::NoForceResponse { area: area_number });
        }
        let mean = peaks.iter().sum::<f64>() / peaks.len() as f64;
        let total = peaks.iter().map(|p| (p - mean).powi(2)).sum::<f64>();
        let spread = (total / peaks.len() as f64).sqrt();
        // Scaled problem y = D + B·φ(κ, x), φ(κ, x) = (1 − e^(−κx))/κ, with x = (F − F_min)/span
        // ∈ [0, 1] and y = (peak − mean)/spread: every parameter is of order 1, and the form stays
        // regular as κ → 0 (φ → x, a straight line), where A = −B/κ and C = D − A run off to ∞.
        let xs: Vec<f64> = forces.iter().map(|f| (f - low) / span).collect();
        let ys: Vec<f64> = peaks.iter().map(|p| (p - mean) / spread).collect();
        let best = starting_decays(&xs, &ys)
            .into_iter()
            .map(|decay| levenberg_marquardt(&xs, &ys, start_at(&xs, &ys, decay)))
            .filter(|fit| fit.converged)
            .min_by(|left, right| left.sum_of_squares.total_cmp(&right.sum_of_squares));
        // Where no start converges, the best curve of the family on a grid of decay rates,
        // each with its closed-form D and B: it cannot fail, and every such curve is monotone.
        let fallback = best.is_none();
        let best = best.unwrap_or_else(|| profile(&xs, &ys));
        // Back to y = A·e^(−κx) + C, holding |b| ≤ MAX_DECAY_PER_SPAN·span, then to physical units:
        // peak = spread·A·e^(−(F − F_min)/b) + spread·C + mean.
        let [value, slope, decay] = best.theta;
        let decay =
            if decay.abs() >= 1.0 / MAX_DECAY_PER_SPAN { decay } else { (1.0 / MAX_DECAY_PER_SPAN).copysign(decay) };
        let amplitude = -slope / decay;
        let b = span / decay;
        let a = spread * amplitude * (low / b).exp();
        let c = spread * (value - amplitude) + mean;
        if !(a.is_finite() && b.is_finite() && c.is_finite() && b != 0.0) {
            return Err(CalibrationError::NotFiniteFit { area: area_number, a, b, c });
        }
        let force_range = [low, high];
        let mut curve = Curve {
            a,
            b,
            c,
            r_squared: f64::NAN,
            force_range,
            samples: forces.len(),
            spread: 0.0,
            fallback,
            shape: None,
        };
        let sum_of_squares = |curve: &Curve| forces.iter().zip(peaks).map(|(&f, p)| (p - curve.peak(f)).powi(2)).sum();
        let mut residual: f64 = sum_of_squares(&curve);
        // A shape that falls to c more slowly, where it fits better than chance would let it
        // (module `shape`).
        if low >= 0.0 && forces.len() > 4 {
            let best = shapes
                .iter()
                .filter_map(|&k| shape::fit_shape(k, forces, peaks, high, mean, spread))
                .map(|fit| {
                    let shaped =
                        Curve { a: fit.a, b: fit.b, c: fit.c, fallback: false, shape: Some(fit.shape), ..curve };
                    (sum_of_squares(&shaped), shaped)
                })
                .min_by(|x, y| x.0.total_cmp(&y.0));
            if let Some((shaped_residual, shaped)) = best {
                let noise = shaped_residual / (forces.len() - 4) as f64;
                if residual - shaped_residual > SHAPE_TEST * noise {
                    (curve, residual) = (shaped, shaped_residual);
                }
            }
        }
        curve.r_squared = 1.0 - residual / total;
        // The residual's standard deviation, per degree of freedom (3 parameters fitted).
        if forces.len() > 3 {
            curve.spread = (residual / (forces.len() - 3) as f64).sqrt();
        }
        Ok(curve)
    }

    /// The peak (S/m) the curve predicts at `force` (N).
    pub fn peak(&self, force: f64) -> f64 {
        self.a * shape::fall(self.shape, force / self.b) + self.c
    }

    /// The curve's slope dpeak/dF at `force` (N), in S/m per N: −(a/b)·e^(−F/b) for the
    /// exponential.
    pub fn slope(&self, force: f64) -> f64 {
        self.a / self.b * shape::fall_slope(self.shape, force / self.b)
    }

    /// The force (N) for a measured `peak` (S/m), clamped to the calibrated range.
    pub fn force(&self, peak: f64) -> ForceEstimate {
        let [low, high] = self.force_range;
        if peak.is_nan() {
            return ForceEstimate { newtons: f64::NAN, saturated: true, std: None };
        }
        let inverse = self.inverse(peak);
        let tolerance = RANGE_TOLERANCE * (high - low);
        let saturated = !inverse.is_finite() || inverse < low - tolerance || inverse > high + tolerance;
        ForceEstimate { newtons: inverse.clamp(low, high), saturated, std: None }
    }

    /// The force (N) whose peak is `peak` on the curve extended past the calibrated range;
    /// ±∞ at or past the asymptote c (+∞ for b > 0, which reaches c as F → +∞).
    fn inverse(&self, peak: f64) -> f64 {
        let ratio = (peak - self.c) / self.a;
        if ratio > 0.0 {
            self.b * shape::fall_inverse(self.shape, ratio)
        } else if self.b > 0.0 {
            f64::INFINITY
        } else {
            f64::NEG_INFINITY
        }
    }

    /// The force (N) for a `peak` measured with standard deviation `std` (both in the curve's
    /// unit), the curve's own [`spread`](Curve::spread) added to it: the mean of its posterior
    /// over the calibrated range, with that posterior's standard deviation. The prior is uniform over the range (the sheet is pressed as it was
    /// calibrated, which the inverse's clamp assumes too), the peak normal about the curve.
    /// Where the peak pins the force (std/|slope| under 4 of the range's 512 points it sums
    /// on) this is the inverse, [`Curve::force`], with std/|slope|; where
    /// the curve flattens, a noisy peak no longer reads as the range's end but as what forces
    /// could have given it. A reading outside the range (`saturated`) adds to its standard
    /// deviation how far the curve, extended past the range, puts the force from the one given.
    /// `std` `None`, not finite or not positive: the inverse alone.
    pub fn force_given(&self, peak: f64, std: Option<f64>) -> ForceEstimate {
        let inverse = self.force(peak);
        let [low, high] = self.force_range;
        let measured = std.filter(|s| s.is_finite() && *s > 0.0).unwrap_or(0.0);
        let std = measured.hypot(if self.spread.is_finite() { self.spread } else { 0.0 });
        if !(std > 0.0 && peak.is_finite() && high > low) {
            return inverse;
        }
        // A reading the curve puts outside the calibrated range is given at the range's end;
        // how far the curve, extended, puts it beyond is part of its uncertainty.
        let beyond = |newtons: f64| {
            let extended = self.inverse(peak);
            if inverse.saturated && extended.is_finite() {
                extended - newtons
            } else {
                0.0
            }
        };
        let step = (high - low) / POSTERIOR_POINTS as f64;
        let linear = std / self.slope(inverse.newtons).abs();
        if linear < NARROW_POSTERIOR * step {
            return ForceEstimate { std: Some(linear.hypot(beyond(inverse.newtons))), ..inverse };
        }
        // On the midpoints of the range: the log-likelihood's largest value first, so that
        // the weights neither overflow nor all vanish.
        let force = |k: usize| low + (k as f64 + 0.5) * step;
        let mut log_likelihood = [0.0; POSTERIOR_POINTS];
        for (k, l) in log_likelihood.iter_mut().enumerate() {
            *l = -0.5 * ((peak - self.peak(force(k))) / std).powi(2);
        }
        let largest = log_likelihood.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let (mut weight, mut first, mut second) = (0.0, 0.0, 0.0);
        for (k, l) in log_likelihood.iter().enumerate() {
            let (f, w) = (force(k), (l - largest).exp());
            (weight, first, second) = (weight + w, first + w * f, second + w * f * f);
        }
        let mean = first / weight;
        let variance = (second / weight - mean * mean).max(0.0);
        ForceEstimate { newtons: mean, saturated: inverse.saturated, std: Some(variance.sqrt().hypot(beyond(mean))) }
    }
}

/// One calibration sample: the area (0-based) of the touch, the applied force (N) and its strength.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Area of the touch, 0-based.
    pub area: usize,
    /// Applied force, in N.
    pub force: f64,
    /// Strength of the touch, in the unit of the calibration's [`Strength`] (the image's peak
    /// in S/m, the fitted press's drop as a fraction of the background, …).
    pub peak: f64,
    /// The strength's standard deviation from the measurement noise, in its unit, where known.
    pub std: Option<f64>,
    /// Where the press was, in m, where known: a curve whose samples come from three places or
    /// more has its spread cross-validated place by place ([`Calibration::fit_strength`]).
    pub place: Option<[f64; 2]>,
}

impl Sample {
    /// The sample of a press of `force` (N) labelled at `place` (m) in `area` (0-based), whose
    /// touch gave `reading`.
    pub fn read(area: usize, force: f64, place: [f64; 2], reading: Reading) -> Sample {
        Sample { area, force, peak: reading.value, std: reading.std, place: Some(place) }
    }
}

/// A per-area calibration: one curve per area, indexed by the 0-based area.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    /// The curve of each area, in area order.
    pub curves: Vec<Curve>,
    /// What the curves take as the strength (the samples' `peak`).
    pub strength: Strength,
}

impl Calibration {
    /// Fits one curve per area 0..areas from the samples (every area needs ≥ 3 distinct forces),
    /// taking their `peak` as the image peak.
    pub fn fit(samples: &[Sample], areas: usize) -> Result<Calibration, CalibrationError> {
        Calibration::fit_strength(samples, areas, Strength::Peak)
    }

    /// [`Calibration::fit`] with the samples' `peak` holding the given kind of strength. Each
    /// curve's [`spread`](Curve::spread) is its error less what the samples' own noise (their
    /// `std`, where known) explains, each sample counted by its own noise (Paule and Mandel's
    /// estimator; module `spread`): the error on places it did not see where its samples name
    /// three places or more (up to [`PLACE_FOLDS`]-fold cross-validation, each place's samples
    /// held out together), else its residual. A spread measured on n places is known to n − 1
    /// degrees of freedom ν: the error at a new place is Student's t, whose standard deviation
    /// is the spread's times √(ν/(ν − 2)) (×1.29 for the paper's six places; ν held at 3 or
    /// more).
    pub fn fit_strength(samples: &[Sample], areas: usize, strength: Strength) -> Result<Calibration, CalibrationError> {
        if areas == 0 {
            return Err(CalibrationError::NoAreas);
        }
        let mut forces = vec![Vec::new(); areas];
        let mut peaks = vec![Vec::new(); areas];
        for (index, sample) in samples.iter().enumerate() {
            if sample.area >= areas {
                return Err(CalibrationError::SampleOutsideAreas { sample: index + 1, area: sample.area + 1, areas });
            }
            for (quantity, value) in [("force", sample.force), ("peak", sample.peak)] {
                if !value.is_finite() {
                    return Err(CalibrationError::NotFinite { area: sample.area + 1, sample: index + 1, quantity });
                }
            }
            forces[sample.area].push(sample.force);
            peaks[sample.area].push(sample.peak);
        }
        let curves = (0..areas)
            .map(|area| {
                if forces[area].is_empty() {
                    return Err(CalibrationError::NoSamples { area: area + 1 });
                }
                let mut curve = Curve::fit(area, &forces[area], &peaks[area])?;
                let own: Vec<&Sample> = samples.iter().filter(|s| s.area == area).collect();
                curve.spread = spread::spread(&curve, &own);
                Ok(curve)
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Calibration { curves, strength })
    }

    /// How well one curve of `samples`' strength reads forces at places it did not see: the
    /// RMS force error (N) of each sample read off the curve fitted without its place (up to
    /// [`PLACE_FOLDS`] folds), every area pooled; `None` where the samples name fewer than three
    /// places. Strengths read off the same presses compare by it.
    pub fn held_out_force_rms(samples: &[Sample]) -> Option<f64> {
        spread::held_out_force_rms(&samples.iter().collect::<Vec<_>>())
    }

    /// How far each area's curve reads from `pooled` (one curve fitted to every sample), in N:
    /// the RMS, over 32 forces F spread across the area's range, of the force `pooled` gives
    /// for the strength the area's curve predicts at F, less F. Areas whose curves are within
    /// the noise of each other are one curve: fewer samples per curve, read anywhere.
    pub fn offsets_from(&self, pooled: &Curve) -> Vec<f64> {
        const POINTS: usize = 32;
        self.curves
            .iter()
            .map(|curve| {
                let [low, high] = curve.force_range;
                let squares: f64 = (0..POINTS)
                    .map(|k| low + (high - low) * (k as f64 + 0.5) / POINTS as f64)
                    .map(|f| (pooled.force(curve.peak(f)).newtons - f).powi(2))
                    .sum();
                (squares / POINTS as f64).sqrt()
            })
            .collect()
    }

    /// The unit and area of `reading` on `array`, and the force its area's curve gives (`None`
    /// for a NaN strength); `None` off the array.
    pub fn locate(&self, array: &PseudoArray, reading: Reading) -> Option<Located> {
        let unit = array.unit_at(reading.centre)?;
        let area = array.area_of(unit);
        Some(Located { unit, area, force: self.force_given(area, reading.value, reading.std).ok() })
    }

    /// The force (N) for a touch in `area` (0-based) with strength `peak` (in the unit of
    /// [`Calibration::strength`]).
    pub fn force(&self, area: usize, peak: f64) -> Result<ForceEstimate, CalibrationError> {
        self.force_given(area, peak, None)
    }

    /// [`Calibration::force`] for a strength measured with standard deviation `std` (its
    /// unit): the posterior's mean and standard deviation ([`Curve::force_given`]).
    pub fn force_given(&self, area: usize, peak: f64, std: Option<f64>) -> Result<ForceEstimate, CalibrationError> {
        let curve =
            self.curves.get(area).ok_or(CalibrationError::NoSuchArea { area: area + 1, areas: self.curves.len() })?;
        if peak.is_nan() {
            return Err(CalibrationError::PeakNotANumber { area: area + 1 });
        }
        Ok(curve.force_given(peak, std))
    }
}

/// A reading placed on a pseudo-array, with its force.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Located {
    /// The unit holding the reading's centre, 0-based.
    pub unit: usize,
    /// That unit's area, 0-based.
    pub area: usize,
    /// The force, `None` for a strength that is not a number.
    pub force: Option<ForceEstimate>,
}

/// Error metrics of predicted against true forces; not finite where undefined (no pairs, no variance).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceErrors {
    /// Root-mean-square error, in N.
    pub rms: f64,
    /// RMS error as a percentage of the largest true force (by magnitude), in %.
    pub rms_percent_of_max: f64,
    /// Pearson correlation coefficient r of predicted with true forces, dimensionless.
    pub correlation: f64,
    /// Mean absolute error, in N.
    pub mean_absolute: f64,
    /// Number of force pairs.
    pub count: usize,
}

/// RMS error (N), RMS as % of the largest true force, Pearson correlation, mean absolute error (N).
///
/// # Panics
///
/// If `truth` and `predicted` differ in length.
#[track_caller]
pub fn force_errors(truth: &[f64], predicted: &[f64]) -> ForceErrors {
    assert_eq!(
        truth.len(),
        predicted.len(),
        "force_errors: {} true forces but {} predicted",
        truth.len(),
        predicted.len()
    );
    let count = truth.len();
    let n = count as f64;
    let squared = truth.iter().zip(predicted).map(|(t, p)| (p - t).powi(2)).sum::<f64>();
    let absolute = truth.iter().zip(predicted).map(|(t, p)| (p - t).abs()).sum::<f64>();
    let rms = (squared / n).sqrt();
    let largest = truth.iter().fold(0.0_f64, |max, t| max.max(t.abs()));
    let (truth_mean, predicted_mean) = (truth.iter().sum::<f64>() / n, predicted.iter().sum::<f64>() / n);
    let (mut covariance, mut truth_variance, mut predicted_variance) = (0.0, 0.0, 0.0);
    for (t, p) in truth.iter().zip(predicted) {
        covariance += (t - truth_mean) * (p - predicted_mean);
        truth_variance += (t - truth_mean).powi(2);
        predicted_variance += (p - predicted_mean).powi(2);
    }
    ForceErrors {
        rms,
        rms_percent_of_max: 100.0 * rms / largest,
        correlation: covariance / (truth_variance * predicted_variance).sqrt(),
        mean_absolute: absolute / n,
        count,
    }
}

/// How many different values `values` holds.
fn distinct_count(values: &[f64]) -> usize {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    sorted.dedup();
    sorted.len()
}

/// φ(κ, x) = (1 − e^(−κx))/κ, which is x at κ = 0, and its derivative ∂φ/∂κ.
fn rise(decay: f64, x: f64) -> (f64, f64) {
    let t = decay * x;
    if t.abs() < 1e-3 {
        // Series in t = κx, exact to ~1e-14 here where the closed form would cancel.
        let value = x * (1.0 - t / 2.0 + t * t / 6.0 - t * t * t / 24.0);
        let slope = -x * x * (0.5 - t / 3.0 + t * t / 8.0 - t * t * t / 30.0);
        (value, slope)
    } else {
        let value = -(-t).exp_m1() / decay;
        (value, (x * (-t).exp() - value) / decay)
    }
}

/// The scaled model y = D + B·φ(κ, x) at `x`, for θ = [D, B, κ].
fn model(theta: &[f64; 3], x: f64) -> f64 {
    theta[0] + theta[1] * rise(theta[2], x).0
}

/// Σ (yᵢ − model(xᵢ))² of the scaled problem.
fn sum_of_squares(theta: &[f64; 3], xs: &[f64], ys: &[f64]) -> f64 {
    xs.iter().zip(ys).map(|(&x, y)| (y - model(theta, x)).powi(2)).sum()
}

/// Mean of the `ys` whose `xs` equal `at`.
fn mean_at(xs: &[f64], ys: &[f64], at: f64) -> f64 {
    let (sum, count) = xs.iter().zip(ys).filter(|(&x, _)| x == at).fold((0.0, 0.0), |(s, n), (_, y)| (s + y, n + 1.0));
    sum / count
}

/// Starting decay rates κ₀ = span/b₀ for the scaled problem (x ∈ [0, 1]).
///
/// c₀ is the mean peak at the largest force and a₀ the mean peak at the smallest force less c₀;
/// b₀ comes from a straight-line fit of ln|y − c₀| against x over the points well away from c₀
/// on the side of a₀, falling back to a third of the force span; then b₀ times each multiple.
fn starting_decays(xs: &[f64], ys: &[f64]) -> [f64; START_MULTIPLES.len()] {
    let offset = mean_at(xs, ys, 1.0);
    let amplitude = mean_at(xs, ys, 0.0) - offset;
    let points: Vec<(f64, f64)> = xs
        .iter()
        .zip(ys)
        .filter(|(_, &y)| (y - offset) * amplitude.signum() > 0.1 * amplitude.abs())
        .map(|(&x, &y)| (x, (y - offset).abs().ln()))
        .collect();
    let n = points.len() as f64;
    let (x_mean, z_mean) = (points.iter().map(|p| p.0).sum::<f64>() / n, points.iter().map(|p| p.1).sum::<f64>() / n);
    let sxz = points.iter().map(|(x, z)| (x - x_mean) * (z - z_mean)).sum::<f64>();
    let sxx = points.iter().map(|(x, _)| (x - x_mean).powi(2)).sum::<f64>();
    let slope_decay = -sxz / sxx; // ln|y − c₀| = ln|a₀| − κx
    let usable = amplitude != 0.0 && slope_decay.is_finite() && slope_decay.abs() > 1e-3;
    let decay = if usable { slope_decay } else { 3.0 }; // else b₀ = span/3
    START_MULTIPLES.map(|multiple| decay / multiple)
}

/// The start [D, B, κ] at decay rate `decay`: D and B from the linear least-squares fit at that κ.
fn start_at(xs: &[f64], ys: &[f64], decay: f64) -> [f64; 3] {
    match line_through(xs.iter().zip(ys).map(|(&x, &y)| (rise(decay, x).0, y))) {
        Some((value, slope)) => [value, slope, decay],
        None => {
            let (low, high) = (mean_at(xs, ys, 0.0), mean_at(xs, ys, 1.0));
            [low, (high - low) / rise(decay, 1.0).0, decay]
        }
    }
}

/// The least-squares line y = D + B·u through `points` (u, y): (D, B), or `None` where the u
/// barely vary (the system is singular to working precision) or the line is not finite.
fn line_through(points: impl Iterator<Item = (f64, f64)>) -> Option<(f64, f64)> {
    let (mut n, mut su, mut suu, mut sy, mut suy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (u, y) in points {
        (n, su, suu, sy, suy) = (n + 1.0, su + u, suu + u * u, sy + y, suy + u * y);
    }
    let determinant = n * suu - su * su;
    let slope = (n * suy - su * sy) / determinant;
    let value = (suu * sy - su * suy) / determinant;
    (determinant > 1e-12 * n * suu && slope.is_finite() && value.is_finite()).then_some((value, slope))
}

/// Decay rates κ of the fallback's grid: ±[`PROFILE_DECAYS`] in [`PROFILE_STEPS`] steps each way.
const PROFILE_DECAYS: f64 = 40.0;
/// Steps of the fallback's grid each way from κ = 0.
const PROFILE_STEPS: usize = 400;

/// The best [D, B, κ] over a grid of κ in [−40, 40] (a straight line at κ = 0), D and B by
/// linear least squares at each: the fit where Levenberg–Marquardt converged from no start.
fn profile(xs: &[f64], ys: &[f64]) -> LmFit {
    let steps = PROFILE_STEPS as f64;
    (0..=2 * PROFILE_STEPS)
        .map(|k| PROFILE_DECAYS * (k as f64 - steps) / steps)
        .map(|decay| {
            let theta = start_at(xs, ys, decay);
            LmFit { theta, sum_of_squares: sum_of_squares(&theta, xs, ys), converged: false }
        })
        .filter(|fit| fit.sum_of_squares.is_finite())
        .min_by(|left, right| left.sum_of_squares.total_cmp(&right.sum_of_squares))
        .unwrap_or(LmFit { theta: [0.0, 1.0, 0.0], sum_of_squares: f64::INFINITY, converged: false })
}

/// The outcome of one Levenberg–Marquardt run on the scaled problem.
struct LmFit {
    theta: [f64; 3],
    sum_of_squares: f64,
    converged: bool,
}

/// Levenberg–Marquardt for y = D + B·φ(κ, x): (JᵀJ + λ·diag JᵀJ)·δ = Jᵀr, λ ÷ 10 on a step that
/// lowers Σr², × 10 on one that does not; converged on a small relative step or change of Σr².
fn levenberg_marquardt(xs: &[f64], ys: &[f64], start: [f64; 3]) -> LmFit {
    let mut theta = start;
    let mut current = sum_of_squares(&theta, xs, ys);
    let mut lambda = 1e-3;
    for _ in 0..MAX_ITERATIONS {
        if !current.is_finite() {
            break;
        }
        let mut normal = [[0.0; 3]; 3];
        let mut gradient = [0.0; 3];
        for (&x, &y) in xs.iter().zip(ys) {
            let (value, slope) = rise(theta[2], x);
            let row = [1.0, value, theta[1] * slope];
            let residual = y - (theta[0] + theta[1] * value);
            for (i, normal_row) in normal.iter_mut().enumerate() {
                gradient[i] += row[i] * residual;
                for (j, entry) in normal_row.iter_mut().enumerate() {
                    *entry += row[i] * row[j];
                }
            }
        }
        let floor = 1e-12 * normal[0][0].max(normal[1][1]).max(normal[2][2]);
        loop {
            let mut damped = normal;
            for (i, damped_row) in damped.iter_mut().enumerate() {
                damped_row[i] += lambda * normal[i][i].max(floor);
            }
            if let Some(step) = solve_symmetric(&damped, &gradient) {
                let trial = [theta[0] + step[0], theta[1] + step[1], theta[2] + step[2]];
                let next = sum_of_squares(&trial, xs, ys);
                if next < current {
                    let moved = step.iter().map(|d| d * d).sum::<f64>().sqrt();
                    let size = trial.iter().map(|t| t * t).sum::<f64>().sqrt();
                    let done = moved <= 1e-10 * (size + 1e-10)
                        || current - next <= 1e-12 * current
                        || next <= 1e-28 * xs.len() as f64;
                    (theta, current, lambda) = (trial, next, (lambda / 10.0).max(1e-15));
                    if done {
                        return LmFit { theta, sum_of_squares: current, converged: true };
                    }
                    break;
                }
            }
            lambda *= 10.0;
            if lambda > 1e16 {
                // No step, however short, lowers Σr²: θ is a minimum to working precision.
                return LmFit { theta, sum_of_squares: current, converged: true };
            }
        }
    }
    LmFit { theta, sum_of_squares: current, converged: false }
}

/// Solves the symmetric positive-definite 3 × 3 system `matrix`·x = `rhs` by Cholesky; None if not
/// positive definite.
fn solve_symmetric(matrix: &[[f64; 3]; 3], rhs: &[f64; 3]) -> Option<[f64; 3]> {
    let mut lower = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..=i {
            let sum = matrix[i][j] - (0..j).map(|k| lower[i][k] * lower[j][k]).sum::<f64>();
            if i == j {
                if sum.is_nan() || sum <= 0.0 {
                    return None;
                }
                lower[i][i] = sum.sqrt();
            } else {
                lower[i][j] = sum / lower[j][j];
            }
        }
    }
    let mut z = [0.0; 3];
    for i in 0..3 {
        z[i] = (rhs[i] - (0..i).map(|k| lower[i][k] * z[k]).sum::<f64>()) / lower[i][i];
    }
    let mut x = [0.0; 3];
    for i in (0..3).rev() {
        x[i] = (z[i] - (i + 1..3).map(|k| lower[k][i] * x[k]).sum::<f64>()) / lower[i][i];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// xorshift64* with Box–Muller normals: a tiny seeded noise source for the tests.
    struct Noise(u64);

    impl Noise {
        fn uniform(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            let bits = self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11;
            (bits as f64 + 0.5) / (1u64 << 53) as f64 // in (0, 1)
        }

        fn normal(&mut self) -> f64 {
            let (u, v) = (self.uniform(), self.uniform());
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        }
    }

    /// Samples of a·e^(−F/b) + c at forces 0..=top N in steps of 1 N, `repeats` each, with
    /// Gaussian noise of standard deviation `noise` × the span of the noise-free peaks.
    fn synthetic(a: f64, b: f64, c: f64, top: u32, repeats: usize, noise: f64, seed: u64) -> (Vec<f64>, Vec<f64>) {
        let curve = |f: f64| a * (-f / b).exp() + c;
        let sigma = noise * (curve(f64::from(top)) - curve(0.0)).abs();
        let mut rng = Noise(seed);
        let forces: Vec<f64> = (0..=top).flat_map(|f| std::iter::repeat_n(f64::from(f), repeats)).collect();
        let peaks = forces.iter().map(|&f| curve(f) + sigma * rng.normal()).collect();
        (forces, peaks)
    }

    fn relative_error(got: f64, want: f64) -> f64 {
        ((got - want) / want).abs()
    }

    fn exact_curve() -> Curve {
        let (forces, peaks) = synthetic(-0.02, 5.0, 0.021, 15, 1, 0.0, 1);
        Curve::fit(0, &forces, &peaks).unwrap()
    }

    /// The slope against a central difference of the peak, across the calibrated range.
    #[test]
    fn slope_is_the_peaks_derivative() {
        let curve = exact_curve();
        for force in [0.5, 4.0, 9.0, 14.5] {
            let h = 1e-4;
            let difference = (curve.peak(force + h) - curve.peak(force - h)) / (2.0 * h);
            assert!(relative_error(curve.slope(force), difference) < 1e-6, "{force} N: {}", curve.slope(force));
        }
    }

    /// Fits noisy samples of a·e^(−F/b) + c (forces 0..=15 N, 15 repeats, `seed`) and checks that
    /// a, b and c come back within `tolerance` (relative) and R² > 0.99.
    fn assert_recovers(a: f64, b: f64, c: f64, noise: f64, tolerance: f64, seed: u64) {
        let (forces, peaks) = synthetic(a, b, c, 15, 15, noise, seed);
        let curve = Curve::fit(0, &forces, &peaks).unwrap();
        for (got, want) in [(curve.a, a), (curve.b, b), (curve.c, c)] {
            assert!(relative_error(got, want) < tolerance, "noise {noise}: {got} for {want} in {curve:?}");
        }
        assert!(curve.r_squared > 0.99, "{curve:?}");
        assert_eq!((curve.force_range, curve.samples), ([0.0, 15.0], 16 * 15));
    }

    // Tolerances. With noise of 1 % of the peak span the standard error of b is about 0.7 % here
    // (1.0 % for area 6), so a 1 % bound would fail for one seed in nine; over 1000 seeds the worst
    // errors of a, b, c were 0.6 %, 2.1 %, 0.7 % (area 6: 1.7 %, 3.3 %, 2.0 %). At 0.2 % noise they
    // were 0.13 %, 0.43 %, 0.14 % (area 6: 0.33 %, 0.68 %, 0.40 %): 1 % holds with margin there,
    // and 1 % noise is checked against 5 %.

    #[test]
    fn fit_recovers_known_curve_from_noisy_samples() {
        assert_recovers(-0.02, 5.0, 0.021, 0.002, 0.01, 42);
        assert_recovers(-0.02, 5.0, 0.021, 0.01, 0.05, 42);
    }

    /// A gel whose drop follows F/(F + F₀) (here 0.9·F/(F + 5.5)), sampled with noise of 0.5 %
    /// of its span at 0–16 N: the exponential leaves a curve too flat at large forces, the
    /// hyperbola (k = 1) is kept, and it reads the noiseless drops back where the exponential
    /// misses by several times as much.
    #[test]
    fn a_hyperbolic_gel_gets_the_shape_that_reads_it() {
        let law = |f: f64| 0.9 * f / (f + 5.5);
        let mut noise = Noise(11);
        let forces: Vec<f64> = (0..=16).flat_map(|f| [f64::from(f); 6]).collect();
        let drops: Vec<f64> = forces.iter().map(|&f| law(f) + 0.005 * 0.67 * noise.normal()).collect();
        let curve = Curve::fit(0, &forces, &drops).unwrap();
        assert_eq!(curve.shape, Some(1.0), "{curve:?}");
        let exponential = Curve::fit_among(0, &forces, &drops, &[]).unwrap();
        assert_eq!(exponential.shape, None);
        let worst =
            |c: &Curve| (1..16).map(|f| (c.force(law(f64::from(f))).newtons - f64::from(f)).abs()).fold(0.0, f64::max);
        assert!(worst(&curve) < 0.2, "{}", worst(&curve));
        assert!(worst(&exponential) > 3.0 * worst(&curve), "{} against {}", worst(&exponential), worst(&curve));
    }

    #[test]
    fn fit_recovers_paper_table_2_area_6() {
        // Table 2 lists area 6 as a = −0.0178, b = −9.7668, c = 0.0165. With that negative b,
        // a·e^(−F/b) + c = c − 0.0178·e^(+F/9.77) falls without bound, which is not the rising,
        // saturating peak of the paper's Fig. 11: the table's b carries the opposite sign
        // convention. In ours the peak magnitude rises from a + c ≈ −0.0013 towards c, so b > 0.
        // Forces 0..=15 N rather than the paper's 0..=9 N: over 9 N (less than one b) b is only
        // known to about 2 % at 1 % noise.
        assert_recovers(-0.0178, 9.7668, 0.0165, 0.002, 0.01, 7);
        assert_recovers(-0.0178, 9.7668, 0.0165, 0.01, 0.05, 7);
    }

    #[test]
    fn fit_is_exact_on_noise_free_samples() {
        let curve = exact_curve();
        assert!(relative_error(curve.a, -0.02) < 1e-9 && relative_error(curve.b, 5.0) < 1e-9, "{curve:?}");
        assert!(relative_error(curve.c, 0.021) < 1e-9 && curve.r_squared > 1.0 - 1e-12, "{curve:?}");
    }

    #[test]
    fn fit_lets_the_data_choose_a_negative_b() {
        // A peak that grows faster and faster: a > 0, b < 0.
        let (forces, peaks) = synthetic(0.002, -6.0, -0.001, 12, 1, 0.0, 1);
        let curve = Curve::fit(0, &forces, &peaks).unwrap();
        assert!(relative_error(curve.a, 0.002) < 1e-6 && relative_error(curve.b, -6.0) < 1e-6, "{curve:?}");
        assert!(relative_error(curve.c, -0.001) < 1e-6, "{curve:?}");
        let estimate = curve.force(curve.peak(7.5));
        assert!((estimate.newtons - 7.5).abs() < 1e-6 && !estimate.saturated);
    }

    #[test]
    fn fit_holds_b_finite_on_linear_samples() {
        let forces: Vec<f64> = (0..=10).map(f64::from).collect();
        let peaks: Vec<f64> = forces.iter().map(|f| 0.001 + 0.002 * f).collect();
        let curve = Curve::fit(0, &forces, &peaks).unwrap();
        assert!(curve.a.is_finite() && curve.c.is_finite(), "{curve:?}");
        assert!(curve.b.abs() <= MAX_DECAY_PER_SPAN * 10.0 * (1.0 + 1e-12), "{curve:?}");
        assert!(curve.r_squared > 1.0 - 1e-6, "{curve:?}");
        for force in [0.5, 4.0, 9.5] {
            let estimate = curve.force(0.001 + 0.002 * force);
            assert!((estimate.newtons - force).abs() < 1e-3 && !estimate.saturated, "{force}: {estimate:?}");
        }
    }

    #[test]
    fn fit_refuses_a_curve_eq_4_cannot_hold() {
        // Forces near 1000 N and b = 0.5 N: a = a'·e^(1000/0.5) overflows.
        let forces = [1000.0_f64, 1000.5, 1001.0, 1002.0, 1003.0];
        let peaks = forces.map(|f| -0.02 * (-(f - 1000.0) / 0.5).exp() + 0.021);
        let error = Curve::fit(4, &forces, &peaks).unwrap_err();
        assert!(
            matches!(error, CalibrationError::NotFiniteFit { area: 5, a, .. } if a == f64::NEG_INFINITY),
            "{error}"
        );
    }

    #[test]
    fn fit_refuses_fewer_than_three_distinct_forces() {
        let error = Curve::fit(3, &[1.0, 1.0, 2.0, 2.0], &[0.1, 0.1, 0.2, 0.2]).unwrap_err();
        assert_eq!(error, CalibrationError::TooFewForces { area: 4, distinct: 2 });
        let message = error.to_string();
        assert!(message.contains("area 4") && message.contains("2 distinct forces"), "{message}");
    }

    #[test]
    fn fit_refuses_not_a_number() {
        let forces = [0.0, 1.0, 2.0, 3.0];
        let error = Curve::fit(0, &forces, &[0.0, 0.1, f64::NAN, 0.3]).unwrap_err();
        assert_eq!(error, CalibrationError::NotFinite { area: 1, sample: 3, quantity: "peak" });
        let error = Curve::fit(1, &[0.0, f64::INFINITY, 2.0], &[0.0, 0.1, 0.2]).unwrap_err();
        assert_eq!(error, CalibrationError::NotFinite { area: 2, sample: 2, quantity: "force" });
    }

    #[test]
    fn fit_refuses_mismatched_lengths_and_flat_peaks() {
        let error = Curve::fit(0, &[0.0, 1.0, 2.0], &[0.0, 0.1]).unwrap_err();
        assert_eq!(error, CalibrationError::LengthMismatch { area: 1, forces: 3, peaks: 2 });
        let error = Curve::fit(2, &[0.0, 1.0, 2.0], &[0.1; 3]).unwrap_err();
        assert_eq!(error, CalibrationError::NoForceResponse { area: 3 });
    }

    #[test]
    fn force_inverts_peak_inside_range() {
        let curve = exact_curve();
        for force in [0.0, 0.25, 3.0, 7.7, 14.0, 15.0] {
            let estimate = curve.force(curve.peak(force));
            assert!((estimate.newtons - force).abs() < 1e-9 && !estimate.saturated, "{force}: {estimate:?}");
        }
    }

    #[test]
    fn peak_beyond_asymptote_saturates_at_top() {
        let curve = exact_curve();
        for peak in [curve.c, curve.c + 0.005, f64::INFINITY] {
            assert_eq!(curve.force(peak), ForceEstimate { newtons: 15.0, saturated: true, std: None }, "{peak}");
        }
        // Between peak(15 N) and c the inverse exists but lies past 15 N.
        assert_eq!(curve.force(curve.peak(20.0)), ForceEstimate { newtons: 15.0, saturated: true, std: None });
    }

    /// A peak that pins the force (std/|slope| a hundredth of a newton) reads as the inverse,
    /// with that standard deviation; no noise given, no standard deviation.
    #[test]
    fn a_force_pinned_by_its_peak_is_the_inverse_with_its_spread() {
        // No spread of its own: the reading's noise alone.
        let curve = Curve { spread: 0.0, ..exact_curve() };
        let peak = curve.peak(7.7);
        let estimate = curve.force_given(peak, Some(1e-6));
        let spread = 1e-6 / curve.slope(7.7).abs();
        assert!((estimate.newtons - 7.7).abs() < 1e-9 && !estimate.saturated, "{estimate:?}");
        assert!((estimate.std.unwrap() / spread - 1.0).abs() < 1e-6, "{estimate:?} against {spread}");
        for std in [None, Some(0.0), Some(f64::NAN), Some(-1.0)] {
            assert_eq!(curve.force_given(peak, std), curve.force(peak), "{std:?}");
        }
    }

    /// Where the curve flattens, the posterior's mean and spread against the same integrals
    /// summed on 200 times as many points (trapezoids): the grid's sum is the posterior's.
    #[test]
    fn a_force_the_curve_cannot_pin_is_its_posteriors_mean() {
        let curve = exact_curve();
        let std = 0.0005; // S/m: at 15 N the slope is 0.0002 S/m per N
        for peak in [curve.peak(9.0), curve.peak(14.0), curve.c + 0.001] {
            let estimate = curve.force_given(peak, Some(std));
            let n = 100_000;
            let (mut w0, mut w1, mut w2) = (0.0, 0.0, 0.0);
            for k in 0..=n {
                let f = 15.0 * k as f64 / n as f64;
                let w =
                    (-0.5 * ((peak - curve.peak(f)) / std).powi(2)).exp() * if k == 0 || k == n { 0.5 } else { 1.0 };
                (w0, w1, w2) = (w0 + w, w1 + w * f, w2 + w * f * f);
            }
            let mean = w1 / w0;
            let spread = (w2 / w0 - mean * mean).sqrt();
            assert!((estimate.newtons - mean).abs() < 1e-3, "{peak}: {estimate:?} against {mean}");
            assert!((estimate.std.unwrap() - spread).abs() < 1e-3, "{peak}: {estimate:?} against {spread}");
        }
        // Past the range's top the inverse reads 15 N; the posterior, what forces could give it.
        let past = curve.force_given(curve.peak(20.0), Some(std));
        assert!(past.saturated && past.newtons < 14.5, "{past:?}");
    }

    /// A peak the curve puts 2 N below or 1 N above the calibrated range (0–15 N here from 2 N)
    /// is given at the range's end, flagged, its standard deviation the reading's and that
    /// distance added as variances; inside the range, the reading's alone.
    #[test]
    fn a_force_outside_the_range_says_how_far_the_curve_puts_it() {
        let curve = Curve { force_range: [2.0, 15.0], ..exact_curve() };
        let std = 1e-7; // S/m: pins the force to a few mN
        for (truth, given) in [(0.5, 2.0), (16.0, 15.0)] {
            let estimate = curve.force_given(curve.peak(truth), Some(std));
            let reading = std / curve.slope(given).abs();
            let expected = reading.hypot(truth - given);
            assert!(estimate.saturated && (estimate.newtons - given).abs() < 1e-6, "{truth}: {estimate:?}");
            assert!((estimate.std.unwrap() - expected).abs() < 1e-3 * expected, "{truth}: {estimate:?} {expected}");
        }
        let inside = curve.force_given(curve.peak(9.0), Some(std));
        assert!(!inside.saturated && inside.std.unwrap() < 0.01, "{inside:?}");
    }

    /// Forces drawn evenly over the range, their peaks read with noise that leaves the top of the
    /// range unpinned (0.0005 S/m, 2.5 N of force at 15 N): the posterior's mean misses by less
    /// than the clamped inverse (0.74 N against 0.83 N RMS), and its standard deviation is
    /// honest (a miss within twice it 96 % of the time).
    #[test]
    fn posterior_means_miss_by_less_than_the_inverse_and_know_by_how_much() {
        let curve = exact_curve();
        let std = 0.0005;
        let mut noise = Noise(17);
        let (mut inverse, mut posterior, mut within) = (0.0, 0.0, 0);
        let draws = 4000;
        for _ in 0..draws {
            let force = 15.0 * noise.uniform();
            let peak = curve.peak(force) + std * noise.normal();
            inverse += (curve.force(peak).newtons - force).powi(2);
            let estimate = curve.force_given(peak, Some(std));
            posterior += (estimate.newtons - force).powi(2);
            within += usize::from((estimate.newtons - force).abs() <= 2.0 * estimate.std.unwrap());
        }
        let (inverse, posterior) = ((inverse / draws as f64).sqrt(), (posterior / draws as f64).sqrt());
        let share = within as f64 / draws as f64;
        assert!(posterior < 0.95 * inverse, "posterior mean's RMS {posterior} N, the inverse's {inverse} N");
        assert!((0.93..0.98).contains(&share), "within twice the standard deviation: {share}");
    }

    #[test]
    fn peak_below_smallest_force_gives_bottom() {
        // peak(0) = a + c = 0.001 S/m; smaller peaks invert to F < 0, outside the range.
        let curve = exact_curve();
        for peak in [0.0005, -1.0, f64::NEG_INFINITY] {
            assert_eq!(curve.force(peak), ForceEstimate { newtons: 0.0, saturated: true, std: None }, "{peak}");
        }
        // A curve with b < 0 reaches its asymptote c as F → −∞: a peak past c reads as F_min.
        let (forces, peaks) = synthetic(0.002, -6.0, -0.001, 12, 1, 0.0, 1);
        let rising = Curve::fit(0, &forces, &peaks).unwrap();
        assert_eq!(rising.force(-0.002), ForceEstimate { newtons: 0.0, saturated: true, std: None });
        assert!(curve.force(f64::NAN).newtons.is_nan() && curve.force(f64::NAN).saturated);
    }

    #[test]
    fn calibration_splits_samples_by_area() {
        let (forces_0, peaks_0) = synthetic(-0.02, 5.0, 0.021, 15, 1, 0.0, 1);
        let (forces_1, peaks_1) = synthetic(-0.0178, 9.7668, 0.0165, 9, 1, 0.0, 1);
        // Interleaved, the second area first, as a recording would give them.
        let mut samples = Vec::new();
        for i in 0..forces_0.len() {
            if let (Some(&force), Some(&peak)) = (forces_1.get(i), peaks_1.get(i)) {
                samples.push(Sample { area: 1, force, peak, std: None, place: None });
            }
            samples.push(Sample { area: 0, force: forces_0[i], peak: peaks_0[i], std: None, place: None });
        }
        let calibration = Calibration::fit(&samples, 2).unwrap();
        let [first, second] = [calibration.curves[0], calibration.curves[1]];
        assert!(relative_error(first.b, 5.0) < 1e-9 && first.samples == 16, "{first:?}");
        assert!(relative_error(second.b, 9.7668) < 1e-9 && second.force_range == [0.0, 9.0], "{second:?}");
        let estimate = calibration.force(1, second.peak(4.0)).unwrap();
        assert!((estimate.newtons - 4.0).abs() < 1e-9 && !estimate.saturated);
    }

    #[test]
    fn calibration_refuses_area_without_samples() {
        let (forces, peaks) = synthetic(-0.02, 5.0, 0.021, 15, 1, 0.0, 1);
        let samples: Vec<Sample> = forces
            .iter()
            .zip(&peaks)
            .flat_map(|(&force, &peak)| {
                [
                    Sample { area: 0, force, peak, std: None, place: None },
                    Sample { area: 2, force, peak, std: None, place: None },
                ]
            })
            .collect();
        let error = Calibration::fit(&samples, 3).unwrap_err();
        assert_eq!(error, CalibrationError::NoSamples { area: 2 });
        assert!(error.to_string().contains("area 2 has no calibration samples"), "{error}");
        let error = Calibration::fit(&samples, 2).unwrap_err();
        assert_eq!(error, CalibrationError::SampleOutsideAreas { sample: 2, area: 3, areas: 2 });
        assert_eq!(Calibration::fit(&samples, 0).unwrap_err(), CalibrationError::NoAreas);
    }

    #[test]
    fn calibration_refuses_bad_samples_and_unknown_areas() {
        let mut samples: Vec<Sample> = (0..5)
            .map(|f| Sample { area: 0, force: f64::from(f), peak: 0.01 * f64::from(f), std: None, place: None })
            .collect();
        samples[3].force = f64::NAN;
        let error = Calibration::fit(&samples, 1).unwrap_err();
        assert_eq!(error, CalibrationError::NotFinite { area: 1, sample: 4, quantity: "force" });
        samples.truncate(3);
        samples[2].force = 1.0; // forces 0, 1 and 1 N: 2 distinct
        let error = Calibration::fit(&samples, 1).unwrap_err();
        assert_eq!(error, CalibrationError::TooFewForces { area: 1, distinct: 2 });
        let calibration = Calibration { curves: vec![exact_curve(); 6], strength: Strength::Peak };
        assert_eq!(calibration.force(6, 0.01).unwrap_err(), CalibrationError::NoSuchArea { area: 7, areas: 6 });
        assert_eq!(calibration.force(2, f64::NAN).unwrap_err(), CalibrationError::PeakNotANumber { area: 3 });
    }

    #[test]
    fn force_errors_match_hand_computed_example() {
        // Errors 1, 0, −1, 1 N: Σe² = 3, Σ|e| = 3. Deviations from the means (3 and 3.25 N):
        // truth −3, −1, 1, 3 (Σ = 20); predicted −2.25, −1.25, −0.25, 3.75 (Σ² = 20.75);
        // Σ products = 6.75 + 1.25 − 0.25 + 11.25 = 19.
        let errors = force_errors(&[0.0, 2.0, 4.0, 6.0], &[1.0, 2.0, 3.0, 7.0]);
        assert_eq!(errors.count, 4);
        assert!((errors.rms - 0.75_f64.sqrt()).abs() < 1e-15, "{errors:?}");
        assert!((errors.rms_percent_of_max - 100.0 * 0.75_f64.sqrt() / 6.0).abs() < 1e-12, "{errors:?}");
        assert!((errors.mean_absolute - 0.75).abs() < 1e-15, "{errors:?}");
        assert!((errors.correlation - 19.0 / (20.0_f64 * 20.75).sqrt()).abs() < 1e-15, "{errors:?}");
    }

    /// The calibration's own spread widens a force's standard deviation as the sum of the two
    /// variances, and the fit's spread is its residual's less what the samples' noise explains.
    #[test]
    fn the_curves_spread_adds_to_the_readings_noise() {
        let curve = Curve { spread: 2e-6, ..exact_curve() };
        let peak = curve.peak(7.7);
        let std = curve.force_given(peak, Some(1e-6)).std.unwrap();
        let expected = 1e-6_f64.hypot(2e-6) / curve.slope(7.7).abs();
        assert!((std / expected - 1.0).abs() < 1e-6, "{std} against {expected}");
        // With no noise of its own, the spread alone.
        let alone = curve.force_given(peak, None).std.unwrap();
        assert!((alone / (2e-6 / curve.slope(7.7).abs()) - 1.0).abs() < 1e-6, "{alone}");
        // Residuals of ±0.01 about an exact curve, half of them explained by the samples' noise.
        let samples: Vec<Sample> = (0..=15)
            .map(|f| {
                let force = f64::from(f);
                let sign = if f % 2 == 0 { 1.0 } else { -1.0 };
                Sample {
                    area: 0,
                    force,
                    peak: 0.5 * (1.0 - (-force / 5.0).exp()) + sign * 0.01,
                    std: Some(0.005),
                    place: None,
                }
            })
            .collect();
        let fitted = Calibration::fit_strength(&samples, 1, Strength::FittedDrop).unwrap().curves[0];
        let residual = Curve::fit(
            0,
            &samples.iter().map(|s| s.force).collect::<Vec<_>>(),
            &samples.iter().map(|s| s.peak).collect::<Vec<_>>(),
        )
        .unwrap()
        .spread;
        assert!((fitted.spread - (residual.powi(2) - 0.005_f64.powi(2)).sqrt()).abs() < 1e-12, "{fitted:?}");
        assert!(residual > 0.009 && residual < 0.012 && !fitted.fallback, "{residual}");
    }

    /// Six places whose curves differ by a gain each: one curve through them all has a residual
    /// about as large as the places' own differences, but a curve read at a seventh place errs
    /// by more; the spread cross-validated place by place says so, and is the residual's where
    /// the places are not known or fewer than three.
    #[test]
    fn the_spread_is_the_error_at_places_the_curve_did_not_see() {
        let gains = [0.85, 0.95, 1.0, 1.05, 1.1, 1.2];
        let samples: Vec<Sample> = gains
            .iter()
            .enumerate()
            .flat_map(|(k, gain)| {
                (0..=15).map(move |f| {
                    let force = f64::from(f);
                    let peak = gain * 0.5 * (1.0 - (-force / 5.0).exp());
                    Sample { area: 0, force, peak, std: None, place: Some([0.01 * k as f64, 0.0]) }
                })
            })
            .collect();
        let crossed = Calibration::fit_strength(&samples, 1, Strength::FittedDrop).unwrap().curves[0];
        let unplaced: Vec<Sample> = samples.iter().map(|s| Sample { place: None, ..*s }).collect();
        let residual = Calibration::fit_strength(&unplaced, 1, Strength::FittedDrop).unwrap().curves[0];
        // By hand: each place left out, the curve of the other five.
        let (mut squared, mut count) = (0.0, 0);
        for k in 0..gains.len() {
            let kept: Vec<&Sample> = samples.iter().filter(|s| s.place != Some([0.01 * k as f64, 0.0])).collect();
            let curve = Curve::fit(
                0,
                &kept.iter().map(|s| s.force).collect::<Vec<_>>(),
                &kept.iter().map(|s| s.peak).collect::<Vec<_>>(),
            )
            .unwrap();
            for s in samples.iter().filter(|s| s.place == Some([0.01 * k as f64, 0.0])) {
                squared += (s.peak - curve.peak(s.force)).powi(2);
                count += 1;
            }
        }
        // Known to 5 degrees of freedom: Student's t's standard deviation, √(5/3) times.
        let expected = (squared / f64::from(count) * 5.0 / 3.0).sqrt();
        assert!((crossed.spread - expected).abs() < 1e-12 * expected, "{} against {expected}", crossed.spread);
        assert!(crossed.spread > 1.1 * residual.spread, "{} {}", crossed.spread, residual.spread);
        // Two places: the residual's.
        let two: Vec<Sample> = samples.iter().filter(|s| s.place.is_some_and(|p| p[0] < 0.015)).copied().collect();
        let two_unplaced: Vec<Sample> = two.iter().map(|s| Sample { place: None, ..*s }).collect();
        let [a, b] =
            [&two, &two_unplaced].map(|s| Calibration::fit_strength(s, 1, Strength::FittedDrop).unwrap().curves[0]);
        assert_eq!(a.spread, b.spread);
    }

    /// Data no start converges on still get a monotone curve, flagged as the fallback's.
    #[test]
    fn the_fallback_fits_every_monotone_data_set() {
        // A step: flat, then a jump, then flat again; each start's fit chases the step.
        let forces: Vec<f64> = (0..=15).map(f64::from).collect();
        let peaks: Vec<f64> = forces.iter().map(|&f| if f < 7.5 { 0.1 } else { 0.9 }).collect();
        let xs: Vec<f64> = forces.iter().map(|f| f / 15.0).collect();
        let ys: Vec<f64> = peaks.iter().map(|p| (p - 0.5) / 0.4).collect();
        let fit = profile(&xs, &ys);
        assert!(fit.sum_of_squares.is_finite() && fit.theta[2].abs() <= PROFILE_DECAYS, "{:?}", fit.theta);
        let curve = Curve::fit(0, &forces, &peaks).unwrap();
        let rising = forces.windows(2).all(|w| curve.peak(w[1]) >= curve.peak(w[0]));
        assert!(rising && curve.r_squared > 0.5, "{curve:?}");
    }
}
