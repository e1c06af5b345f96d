//! Each channel's noise, measured on frames of an unchanging sensor and kept up to date: the
//! variance that weights the channels of an image and that the touch tests stand on
//! ([`crate::noise`]).

/// Residuals beyond this many standard deviations are clipped when the model is updated.
const CLIP: f64 = 3.0;

/// Each channel's noise variance relative to its value, measured and kept up to date.
#[derive(Debug, Clone, PartialEq)]
pub struct NoiseModel {
    /// Per channel, the weighted sum of squared deviations from `mean` (ratio²).
    sum: Vec<f64>,
    /// Per channel, the frames behind it (their weights, after forgetting).
    weight: Vec<f64>,
    /// Per channel, the running mean of v/v_ref − 1 (0 over the reference frames themselves).
    mean: Vec<f64>,
    /// Frames in the reference the deviations are measured from.
    reference_frames: usize,
}

/// The relative change of a value that is rounding, not noise: a few units in the last place.
const ROUNDING: f64 = 8.0 * f64::EPSILON;

impl NoiseModel {
    /// A model measured on `frames` frames per channel whose relative variances are `variance`
    /// (ratio²), against a reference of `reference_frames` frames: for tests that need a known noise.
    #[cfg(test)]
    pub(crate) fn with_variance(variance: &[f64], frames: f64, reference_frames: usize) -> NoiseModel {
        let sum = variance.iter().map(|v| v * (frames - 1.0)).collect();
        NoiseModel { sum, weight: vec![frames; variance.len()], mean: vec![0.0; variance.len()], reference_frames }
    }

    /// Frames after which the model forgets at the rate of one in this many.
    pub const WINDOW: f64 = 1000.0;

    /// The noise of the reference frames (a sensor left alone): per channel, the sample variance
    /// of v/v̄ (v̄ the channel's mean); NaN values are left out of their channel. `None` with
    /// fewer than two frames, or when no channel varied at all. A channel whose values differ by
    /// no more than rounding (v/v̄ − 1 within a few units in the last place: the mean of equal
    /// values need not be exactly their value) did not vary.
    pub fn from_frames(frames: &[Vec<f64>]) -> Option<NoiseModel> {
        let count = frames.first()?.len();
        let (mut sum, mut weight) = (vec![0.0; count], vec![0.0; count]);
        for m in 0..count {
            let values = || frames.iter().filter_map(|f| f.get(m).copied()).filter(|v| v.is_finite());
            let n = values().count();
            let mean = values().sum::<f64>() / n as f64;
            if n < 2 || mean == 0.0 {
                continue;
            }
            let deviations = values().map(|v| (v / mean - 1.0).powi(2)).sum::<f64>();
            sum[m] = if deviations > n as f64 * ROUNDING * ROUNDING { deviations } else { 0.0 };
            weight[m] = n as f64;
        }
        let mean = vec![0.0; count];
        sum.iter().any(|s| *s > 0.0).then_some(NoiseModel { sum, weight, mean, reference_frames: frames.len() })
    }

    /// A model that assumes `relative` (standard deviation per value, dimensionless) on every
    /// one of `count` channels, as if measured on `reference_frames` frames (at least 2).
    pub fn assumed(relative: f64, count: usize, reference_frames: usize) -> NoiseModel {
        let n = reference_frames.max(2) as f64;
        NoiseModel {
            sum: vec![relative * relative * (n - 1.0); count],
            weight: vec![n; count],
            mean: vec![0.0; count],
            reference_frames,
        }
    }

    /// Number of channels.
    pub fn len(&self) -> usize {
        self.sum.len()
    }

    /// Whether the model has no channels.
    pub fn is_empty(&self) -> bool {
        self.sum.is_empty()
    }

    /// Frames in the reference (its own noise adds 1/N of a frame's).
    pub fn reference_frames(&self) -> usize {
        self.reference_frames
    }

    /// Sets the frames in the reference, as it grows.
    pub fn set_reference_frames(&mut self, frames: usize) {
        self.reference_frames = frames;
    }

    /// The degrees of freedom behind the estimate, the median over channels (frames seen, less one).
    pub fn frames(&self) -> f64 {
        let mut dof: Vec<f64> = self.weight.iter().filter(|w| **w > 1.0).map(|w| w - 1.0).collect();
        dof.sort_by(f64::total_cmp);
        dof.get(dof.len() / 2).copied().unwrap_or(0.0)
    }

    /// Adds a frame without a touch, measured against `reference` (both in protocol order): each
    /// channel's v/v_ref − 1 joins its running mean and variance (West's weighted update), its
    /// deviation clipped at 3σ. Channels not finite in either are skipped. Allocates nothing.
    pub fn update(&mut self, reference: &[f64], frame: &[f64]) {
        let channels = self.sum.iter_mut().zip(self.weight.iter_mut()).zip(self.mean.iter_mut());
        for (((sum, weight), mean), (r, v)) in channels.zip(reference.iter().zip(frame)) {
            if !(r.is_finite() && v.is_finite()) || *r == 0.0 {
                continue;
            }
            if *weight >= Self::WINDOW {
                let keep = 1.0 - 1.0 / Self::WINDOW;
                *sum *= keep;
                *weight *= keep;
            }
            let limit = if *weight > 1.0 { CLIP * (*sum / (*weight - 1.0)).sqrt() } else { f64::INFINITY };
            let delta = (v / r - 1.0 - *mean).clamp(-limit, limit);
            *weight += 1.0;
            *mean += delta / *weight;
            *sum += delta * delta * (1.0 - 1.0 / *weight);
        }
    }

    /// Each channel's noise standard deviation in a difference v − v_ref (V, the unit of
    /// `reference`) or, `normalised`, in v/v_ref − 1, when v is the mean of `averaged` frames:
    /// the reference's own noise included; NaN for a channel never measured.
    pub fn difference_std(&self, reference: &[f64], normalised: bool, averaged: usize) -> Vec<f64> {
        let share = 1.0 / averaged.max(1) as f64 + 1.0 / self.reference_frames.max(1) as f64;
        let relative = self.relative_variance();
        relative.iter().zip(reference).map(|(r, v)| (r * share * if normalised { 1.0 } else { v * v }).sqrt()).collect()
    }

    /// Each channel's relative noise variance (ratio²; NaN for a channel never measured), each
    /// raised to at least a tenth of the median channel's, so that no channel is trusted
    /// without limit (few frames estimate a variance badly, and a quantised board can repeat a
    /// value exactly).
    pub fn relative_variance(&self) -> Vec<f64> {
        let raw =
            self.sum.iter().zip(&self.weight).map(|(s, w)| if *w > 1.0 { s / (w - 1.0) } else { f64::NAN }).collect();
        super::floored(raw)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Equal frames (a reference copied, a board that repeats itself) measure no noise, however
    /// their mean rounds: no channel is taken as measured with a variance of 1e-32.
    #[test]
    fn equal_frames_measure_no_noise() {
        let frame: Vec<f64> = (0..120).map(|m| 0.1 + 0.37 * f64::from(m).sin().abs()).collect();
        assert!(NoiseModel::from_frames(&[frame.clone(), frame.clone(), frame.clone()]).is_none());
        let mut varied = vec![frame.clone(), frame.clone(), frame];
        varied[1][3] *= 1.0 + 1e-6;
        let model = NoiseModel::from_frames(&varied).unwrap();
        let variance = model.relative_variance();
        assert!(variance[3] > 0.0 && variance.iter().enumerate().all(|(m, v)| m == 3 || *v == 0.0), "{variance:?}");
    }
}
