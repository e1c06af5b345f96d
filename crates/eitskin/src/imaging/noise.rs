//! The measured noise of a sensor, and what it makes of an image: how far each pixel's change
//! is from what noise alone gives, and how far that must be for a stated false-alarm rate.
//!
//! **Noise model.** [`NoiseModel`] holds each channel's noise variance relative to its value
//! (ratio², free of a board's unit and gains): first the sample variance of the reference frames,
//! then updated on every frame without a touch by its deviation from the reference (clipped at
//! 3σ, so that drift or a press under the threshold cannot inflate it; the clip lowers a
//! Gaussian variance by 0.5 %). Once it has seen [`NoiseModel::WINDOW`] frames it forgets at
//! that rate, so it follows a board that warms up.
//!
//! **Significance.** An image is linear in Δv, Δσ = H·Δv, so with independent channel noise
//! of variance Σ_m each pixel's noise variance is s_p² = Σ_m H_pm²·Σ_m·(1 + 1/N) (the reference,
//! a mean of N frames, carries noise too). [`Significance`] holds 1/s_p per pixel, so a frame's
//! z-map z_p = Δσ_p/s_p costs one pass over the pixels.
//!
//! **False-alarm rate.** A frame without a touch should show none with probability 1 − α. The
//! largest z of a noise image is the maximum of a smooth random field, not of independent
//! pixels, so the threshold comes from the image's own noise: [`Significance::new`] images
//! [`CALIBRATION_SAMPLES`] frames of pure noise drawn from Σ, takes the 90th percentile z₁ of
//! their largest z, and extends the tail by the Euler characteristic of a 2-D Gaussian field
//! (Worsley, Adler): P(max z ≥ z) ≈ c·z·e^(−z²/2), with c fitted at z₁. Solved for α, that gives
//! the threshold. Lower-dimensional terms of the expansion fall faster, so for small α the
//! threshold errs high (fewer false alarms than α, not more).
//!
//! ```
//! use eitskin::noise::{NoiseModel, Significance};
//! use eitskin::image::Polarity;
//! use eitskin::{Reconstructor, ReconstructorParams, SensorSpec};
//! let mut spec = SensorSpec::square_hydrogel();
//! spec.mesh.triangles = 600;
//! let model = spec.forward_model()?;
//! let params = ReconstructorParams { raster: [24, 24], ..ReconstructorParams::default() };
//! let recon = Reconstructor::new(&model, 1.0, &params)?;
//! let v_ref = model.measure(&vec![1.0; model.mesh().triangles().len()])?;
//! // Ten reference frames, each value 0.1 % off at random (a fixed pattern here).
//! let frames: Vec<Vec<f64>> = (0..10)
//!     .map(|k| v_ref.iter().enumerate().map(|(m, v)| v * (1.0 + 1e-3 * (((m * 7 + k * 13) % 11) as f64 - 5.0) / 3.2)).collect())
//!     .collect();
//! let noise = NoiseModel::from_frames(&frames).expect("frames that vary");
//! let significance = Significance::new(&recon, &v_ref, &noise, 1, Polarity::Decrease, 1e-3)?;
//! assert!(significance.threshold() > 3.0 && significance.threshold() < 6.0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Not for: noise that is correlated between channels (a common-mode swing of the excitation);
//! only the diagonal of the covariance is estimated, as EIDORS' `meas_icov` uses it.

use crate::SeededRng;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

use crate::image::Polarity;
pub use crate::inverse::NoiseModel;
use crate::inverse::{InverseError, Reconstructor};

/// Noise images drawn to find a false-alarm threshold.
pub const CALIBRATION_SAMPLES: usize = 400;

/// The exceedance probability at which the tail is fitted to the noise images.
const FIT_EXCEEDANCE: f64 = 0.1;

/// Per pixel, 1/(standard deviation of its noise), and the z a touch's peak must reach for a
/// stated false-alarm rate per frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Significance {
    /// Per pixel (row-major, as the image), 1/s_p in m/S; 0 outside the outline.
    inverse_std: Vec<f32>,
    threshold: f64,
    false_alarm_rate: f64,
    /// The noise images' largest z at exceedance [`FIT_EXCEEDANCE`] (z₁).
    fitted_at: f64,
}

impl Significance {
    /// The significance of `recon`'s images against the reference `v_ref` (protocol order) under
    /// the noise of `noise`, for frames that are the mean of `averaged` frames (1: single
    /// frames), for touches of `polarity`, at `false_alarm_rate` (false touches per no-touch
    /// frame, in (0, 0.5]). About [`CALIBRATION_SAMPLES`] images of setup work.
    pub fn new(
        recon: &Reconstructor,
        v_ref: &[f64],
        noise: &NoiseModel,
        averaged: usize,
        polarity: Polarity,
        false_alarm_rate: f64,
    ) -> Result<Significance, InverseError> {
        let m = recon.measurements();
        if v_ref.len() != m || noise.len() != m {
            let got = if v_ref.len() != m { v_ref.len() } else { noise.len() };
            return Err(InverseError::FrameLength { expected: m, got });
        }
        assert!(false_alarm_rate > 0.0 && false_alarm_rate <= 0.5, "a false-alarm rate in (0, 0.5]");
        let sd = difference_std(recon, v_ref, noise, averaged);
        let pixels = recon.blank_image().values.len();
        let mut variance = vec![0.0_f64; pixels];
        // Σ_m (H_pm·s_m)², each pixel's terms in the order of m, read in the matrix's own order.
        for (first, m, lanes) in recon.matrix().blocks() {
            let s = sd[m];
            if s > 0.0 {
                let part = &mut variance[first..first + lanes.len()];
                part.iter_mut().zip(lanes).for_each(|(v, h)| *v += (f64::from(*h) * s).powi(2));
            }
        }
        let inverse_std = variance.iter().map(|v| if *v > 0.0 { (1.0 / v.sqrt()) as f32 } else { 0.0 }).collect();
        let mut significance =
            Significance { inverse_std, threshold: f64::INFINITY, false_alarm_rate, fitted_at: f64::NAN };
        let maxima = significance.noise_maxima(recon, v_ref, &sd, polarity)?;
        (significance.fitted_at, significance.threshold) = threshold_of(&maxima, false_alarm_rate);
        Ok(significance)
    }

    /// The z a touch's peak must reach (dimensionless).
    pub fn threshold(&self) -> f64 {
        self.threshold
    }

    /// False touches per frame without a touch that the threshold allows (dimensionless).
    pub fn false_alarm_rate(&self) -> f64 {
        self.false_alarm_rate
    }

    /// Per pixel, 1/(its noise's standard deviation), in m/S (0 outside the outline).
    pub fn inverse_std(&self) -> &[f32] {
        &self.inverse_std
    }

    /// The z of `change` (S/m, in the press direction) at pixel `index`.
    pub fn z(&self, index: usize, change: f64) -> f64 {
        change * f64::from(self.inverse_std.get(index).copied().unwrap_or(0.0))
    }

    /// The largest z of an image's `values` (row-major, as the map) toward `polarity`: the
    /// strongest any touch of it can be.
    pub fn strongest(&self, values: &[f32], polarity: Polarity) -> f64 {
        let n = values.len().min(self.inverse_std.len());
        let (sign, both) = (polarity.intensity(1.0) as f32, matches!(polarity, Polarity::Both));
        f64::from(strongest_z(&values[..n], &self.inverse_std[..n], sign, both))
    }

    /// The noise's standard deviation, in S/m, at the median inside pixel: a scale for showing images.
    pub fn typical_std(&self) -> f64 {
        let mut std: Vec<f32> = self.inverse_std.iter().filter(|x| **x > 0.0).map(|x| 1.0 / x).collect();
        std.sort_by(f32::total_cmp);
        std.get(std.len() / 2).map_or(0.0, |s| f64::from(*s))
    }

    /// A map of `pixels` pixels all with noise `std` (S/m) and a threshold `threshold` (z), for tests.
    #[cfg(test)]
    pub(crate) fn uniform(pixels: usize, std: f64, threshold: f64) -> Significance {
        let inverse_std = vec![(1.0 / std) as f32; pixels];
        Significance { inverse_std, threshold, false_alarm_rate: 1e-3, fitted_at: f64::NAN }
    }

    /// The largest z in each of [`CALIBRATION_SAMPLES`] images of pure noise (a fixed seed, so
    /// the threshold is the same every time).
    fn noise_maxima(
        &self,
        recon: &Reconstructor,
        v_ref: &[f64],
        sd: &[f64],
        polarity: Polarity,
    ) -> Result<Vec<f64>, InverseError> {
        let normalised = recon.params().normalised;
        let mut rng = SeededRng::seed_from_u64(0x05ee_d0f2_015e);
        // Half as many at a time where the thread steps aside between them.
        let batch = if crate::parallel::stepping_aside() { BATCH / 2 } else { BATCH };
        let mut frames = vec![v_ref.to_vec(); batch];
        let mut maxima = Vec::with_capacity(CALIBRATION_SAMPLES);
        while maxima.len() < CALIBRATION_SAMPLES {
            if !maxima.is_empty() {
                crate::parallel::step_aside();
            }
            let count = batch.min(CALIBRATION_SAMPLES - maxima.len());
            for frame in &mut frames[..count] {
                for (m, v) in frame.iter_mut().enumerate() {
                    let n: f64 = StandardNormal.sample(&mut rng);
                    let d = if sd[m] > 0.0 { sd[m] * n } else { 0.0 };
                    *v = if normalised { v_ref[m] * (1.0 + d) } else { v_ref[m] + d };
                }
            }
            let batch: Vec<&[f64]> = frames[..count].iter().map(Vec::as_slice).collect();
            let images = recon.image_values_of(v_ref, &batch)?;
            // (An owned matrix's column is one slice.)
            let column = |f: usize| images.col(f).try_as_col_major().map(|c| c.as_slice()).unwrap_or_default();
            maxima.extend((0..count).map(|f| self.strongest(column(f), polarity)));
        }
        Ok(maxima)
    }
}

crate::parallel::widest! {
    /// The largest of `values` (times `sign`, or their magnitudes when `both`) times `weights`,
    /// and 0: [`Significance::strongest`]'s pass.
    fn strongest_z = strongest_z_portable(values: &[f32], weights: &[f32], sign: f32, both: bool) -> f32
}

/// [`strongest_z`] in portable code: sixteen running maxima over whole chunks and the rest
/// apart, so that the pass vectorises (outside the outline the weight 1/s is 0). A NaN is never
/// the larger (as `f32::max` has it), written as one comparison so that it is one vector max.
#[inline(always)]
fn strongest_z_portable(values: &[f32], weights: &[f32], sign: f32, both: bool) -> f32 {
    let mut lanes = [0.0_f32; 16];
    let step = |lanes: &mut [f32; 16], v: &[f32], w: &[f32]| {
        for ((lane, v), w) in lanes.iter_mut().zip(v).zip(w) {
            let z = if both { v.abs() } else { sign * v } * w;
            *lane = if z > *lane { z } else { *lane };
        }
    };
    let (values, weights) = (values.chunks_exact(16), weights.chunks_exact(16));
    let rest = (values.remainder(), weights.remainder());
    values.zip(weights).for_each(|(v, w)| step(&mut lanes, v, w));
    step(&mut lanes, rest.0, rest.1);
    lanes.iter().fold(0.0_f32, |a, b| a.max(*b))
}

/// Noise frames imaged at once in the calibration (one matrix product each batch).
const BATCH: usize = 100;

/// Each used channel's noise standard deviation in the differences' units (V, or a ratio when
/// normalised) for frames that are the mean of `averaged`, with the reference's share; 0 for a
/// channel not used.
fn difference_std(recon: &Reconstructor, v_ref: &[f64], noise: &NoiseModel, averaged: usize) -> Vec<f64> {
    let std = noise.difference_std(v_ref, recon.params().normalised, averaged);
    std.iter().enumerate().map(|(m, s)| if recon.channels().is_used(m) && s.is_finite() { *s } else { 0.0 }).collect()
}

/// The z for `rate` false alarms per frame from the largest z of each of many noise frames
/// `maxima`: their value z₁ at exceedance [`FIT_EXCEEDANCE`], and the tail extended from it
/// ([`tail_threshold`]). Returns (z₁, threshold).
pub(crate) fn threshold_of(maxima: &[f64], rate: f64) -> (f64, f64) {
    let fitted_at = quantile(maxima, 1.0 - FIT_EXCEEDANCE);
    (fitted_at, tail_threshold(fitted_at, FIT_EXCEEDANCE, rate))
}

/// The `q` quantile of `values` (the nearest rank).
fn quantile(values: &[f64], q: f64) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let rank = ((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len().max(1)) - 1;
    sorted.get(rank).copied().unwrap_or(f64::NAN)
}

/// The z where c·z·e^(−z²/2) = `rate`, with c fitted so that it is `fitted` at z = `at`; never
/// below `at` for a rate under `fitted`.
pub(crate) fn tail_threshold(at: f64, fitted: f64, rate: f64) -> f64 {
    let tail = |z: f64| z * (-z * z / 2.0).exp();
    if at.is_nan() || at <= 1.0 || rate >= fitted {
        return at;
    }
    let c = fitted / tail(at);
    // The tail falls monotonically past z = 1: bisect.
    let (mut lo, mut hi) = (at, at + 10.0);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if c * tail(mid) > rate {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::{ReconstructorParams, SensorSpec};
    use rand_distr::Normal;

    /// The strongest z of an image is the largest of its pixels' z toward the polarity (0 for
    /// none toward it), whatever its length; pixels past the map's count nothing.
    #[test]
    fn the_strongest_z_is_the_largest_pixels() {
        for pixels in [0, 5, 16, 33, 4096] {
            let significance = Significance {
                inverse_std: (0..pixels).map(|p| (p % 7) as f32 * 0.5).collect(),
                ..Significance::uniform(0, 1.0, 4.0)
            };
            let values: Vec<f32> = (0..pixels + 3).map(|p| ((p * 37 % 101) as f32 - 50.0) * 1e-2).collect();
            // An infinite value where the weight is 0 (outside the outline) is no z (its NaN never the larger).
            let mut values = values;
            if pixels > 7 {
                values[7] = f32::INFINITY * if pixels % 2 == 0 { 1.0 } else { -1.0 };
            }
            for polarity in [Polarity::Decrease, Polarity::Increase, Polarity::Both] {
                let z = |p: usize| polarity.intensity(values[p] * significance.inverse_std[p]);
                let want = (0..pixels).map(z).fold(0.0, f64::max);
                assert!(want.is_finite());
                assert_eq!(significance.strongest(&values, polarity), want, "{pixels} pixels, {polarity:?}");
            }
        }
    }

    fn setup(raster: usize) -> (Reconstructor, Vec<f64>) {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 800;
        let model = spec.forward_model().unwrap();
        let params = ReconstructorParams { raster: [raster, raster], ..ReconstructorParams::default() };
        let recon = Reconstructor::new(&model, 1.0, &params).unwrap();
        let v_ref = model.measure(&vec![1.0; model.mesh().triangles().len()]).unwrap();
        (recon, v_ref)
    }

    /// Frames of `v` with independent relative noise `relative[m]` per channel.
    fn noisy(v: &[f64], relative: &[f64], rng: &mut SeededRng) -> Vec<f64> {
        v.iter().zip(relative).map(|(v, r)| v * (1.0 + r * Normal::new(0.0, 1.0).unwrap().sample(rng))).collect()
    }

    #[test]
    fn the_model_measures_each_channels_noise_and_follows_it() {
        let mut rng = SeededRng::seed_from_u64(3);
        let v = vec![2.0, -1.0, 0.5, 4.0];
        let relative = [1e-3, 2e-3, 5e-4, 1e-3];
        let frames: Vec<Vec<f64>> = (0..400).map(|_| noisy(&v, &relative, &mut rng)).collect();
        let model = NoiseModel::from_frames(&frames).unwrap();
        for (var, r) in model.relative_variance().iter().zip(relative) {
            assert!((var.sqrt() / r - 1.0).abs() < 0.1, "{} for {r}", var.sqrt());
        }
        // Ten reference frames, then updated on 2,000 frames: within 5 %.
        let mut model = NoiseModel::from_frames(&frames[..10]).unwrap();
        let reference = crate::inverse::mean_frame(&frames[..10]);
        for _ in 0..2000 {
            model.update(&reference, &noisy(&v, &relative, &mut rng));
        }
        assert!(model.frames() > 900.0, "{}", model.frames());
        // The spread about the running mean, not about the reference (whose own error is fixed).
        for (var, r) in model.relative_variance().iter().zip(relative) {
            assert!((var.sqrt() / r - 1.0).abs() < 0.05, "{} for {r}", var.sqrt());
        }
        // A frame far off (a press, a glitch) moves it by a clipped amount only.
        let before = model.relative_variance();
        let mut off = v.clone();
        off[0] *= 1.5;
        model.update(&reference, &off);
        assert!(model.relative_variance()[0] < 1.01 * before[0]);
        // Nothing varies: no model; one frame: no model.
        assert_eq!(NoiseModel::from_frames(&[v.clone(), v.clone()]), None);
        assert_eq!(NoiseModel::from_frames(&frames[..1]), None);
    }

    /// The pixel noise the map predicts is the pixel noise of images of noisy frames.
    #[test]
    fn pixel_noise_is_what_noisy_frames_give() {
        let (recon, v_ref) = setup(24);
        let relative: Vec<f64> = (0..v_ref.len()).map(|m| 1e-3 * (1.0 + (m % 5) as f64 / 2.0)).collect();
        let variance: Vec<f64> = relative.iter().map(|r| r * r).collect();
        let noise = NoiseModel::with_variance(&variance, 10.0, 1_000_000);
        let significance = Significance::new(&recon, &v_ref, &noise, 1, Polarity::Decrease, 1e-3).unwrap();
        let mut rng = SeededRng::seed_from_u64(11);
        let samples = 2000;
        let mut sum_sq = vec![0.0_f64; 24 * 24];
        for _ in 0..samples {
            let image = recon.image(&v_ref, &noisy(&v_ref, &relative, &mut rng)).unwrap();
            sum_sq.iter_mut().zip(&image.values).for_each(|(s, v)| *s += f64::from(*v).powi(2));
        }
        let inside: Vec<usize> = (0..sum_sq.len()).filter(|&p| significance.inverse_std[p] > 0.0).collect();
        assert!(inside.len() > 300);
        for &p in &inside {
            let measured = (sum_sq[p] / samples as f64).sqrt();
            let predicted = 1.0 / f64::from(significance.inverse_std[p]);
            // 2,000 samples estimate a standard deviation to about 1.6 %.
            assert!((measured / predicted - 1.0).abs() < 0.07, "pixel {p}: {measured} vs {predicted}");
        }
    }

    /// Images of noise alone exceed the threshold about as often as the rate says, not more.
    #[test]
    fn noise_alone_exceeds_the_threshold_at_the_stated_rate() {
        let (recon, v_ref) = setup(24);
        let relative = vec![1e-3; v_ref.len()];
        let noise = NoiseModel::assumed(1e-3, v_ref.len(), 1_000_000);
        let rate = 0.01;
        let significance = Significance::new(&recon, &v_ref, &noise, 1, Polarity::Decrease, rate).unwrap();
        assert!(significance.threshold() > significance.fitted_at);
        let mut rng = SeededRng::seed_from_u64(5);
        let trials = 6000;
        let alarms = (0..trials)
            .filter(|_| {
                let image = recon.image(&v_ref, &noisy(&v_ref, &relative, &mut rng)).unwrap();
                (0..image.values.len()).any(|p| {
                    significance.z(p, Polarity::Decrease.intensity(image.values[p])) >= significance.threshold()
                })
            })
            .count();
        let measured = alarms as f64 / trials as f64;
        // 60 expected: more than 1.5× is a threshold too low; under a fifth, far too high.
        assert!(measured <= 1.5 * rate && measured >= rate / 5.0, "{alarms} alarms in {trials} frames");
    }

    #[test]
    fn the_tail_threshold_solves_the_fitted_law() {
        let z = tail_threshold(2.5, 0.1, 1e-3);
        let law = |z: f64| z * (-z * z / 2.0).exp();
        assert!((0.1 * law(z) / law(2.5) - 1e-3).abs() < 1e-9);
        assert_eq!(tail_threshold(2.5, 0.1, 0.2), 2.5, "a rate above the fitted one keeps z₁");
    }
}
