//! Which measurements (channels) an image uses, and how much each is trusted.
//!
//! Real boards lose channels (a dead electrode, a saturated amplifier, a value missing from a
//! data set) and their channels are not equally noisy. [`Channels`] says which are used and
//! each one's noise variance; the reconstruction drops the unused ones and weights the rest by
//! W = Σ⁻¹ (EIDORS' `meas_icov`), which for a diagonal prior costs one system the size of the
//! measurement count, not a rebuild of the Jacobian.

use super::InverseError;

/// The channels of a frame: which are used, and each one's noise variance.
#[derive(Debug, Clone, PartialEq)]
pub struct Channels {
    used: Vec<bool>,
    variance: Option<Vec<f64>>,
}

impl Channels {
    /// All `count` channels used, equally noisy (W = I).
    pub fn all(count: usize) -> Channels {
        Channels { used: vec![true; count], variance: None }
    }

    /// The channels that are finite in `frame` (NaN or ±∞ marks a missing channel), equally noisy.
    pub fn finite_in(frame: &[f64]) -> Channels {
        Channels { used: frame.iter().map(|v| v.is_finite()).collect(), variance: None }
    }

    /// These channels, with `mask[m] = false` dropping channel m as well.
    pub fn masked(mut self, mask: &[bool]) -> Channels {
        for (u, &keep) in self.used.iter_mut().zip(mask) {
            *u &= keep;
        }
        self
    }

    /// These channels with each one's noise variance (in the differences' units², V² or
    /// ratio²; only the ratios between channels matter). A channel whose variance is not
    /// positive and finite is dropped.
    pub fn with_variance(mut self, variance: Vec<f64>) -> Channels {
        assert_eq!(variance.len(), self.used.len(), "one variance per channel");
        for (u, v) in self.used.iter_mut().zip(&variance) {
            *u &= v.is_finite() && *v > 0.0;
        }
        self.variance = Some(variance);
        self
    }

    /// These channels equally weighted at their mean noise: each used channel's variance
    /// replaced by the mean over the used ones (the noise level kept, its shape across channels
    /// dropped); unchanged without variances.
    pub fn uniform_variance(mut self) -> Channels {
        if let Some(mean) = self.mean_variance() {
            self.variance = Some(vec![mean; self.used.len()]);
        }
        self
    }

    /// Number of channels, used or not.
    pub fn len(&self) -> usize {
        self.used.len()
    }

    /// Whether there are no channels at all.
    pub fn is_empty(&self) -> bool {
        self.used.is_empty()
    }

    /// Whether channel `m` (0-based) is used.
    pub fn is_used(&self, m: usize) -> bool {
        self.used.get(m).copied().unwrap_or(false)
    }

    /// Per channel, whether it is used (a mask to combine with [`Channels::masked`]).
    pub fn used_mask(&self) -> &[bool] {
        &self.used
    }

    /// The used channels, 0-based, in frame order.
    pub fn used(&self) -> Vec<usize> {
        (0..self.used.len()).filter(|&m| self.used[m]).collect()
    }

    /// The channels dropped, 0-based.
    pub fn dropped(&self) -> Vec<usize> {
        (0..self.used.len()).filter(|&m| !self.used[m]).collect()
    }

    /// Each used channel's variance divided by their mean (1 for all without a measured noise),
    /// in the order of [`Channels::used`]: the diagonal of Σ that λ² multiplies, so that λ keeps
    /// its meaning when weights are switched on.
    pub(crate) fn relative_variance(&self) -> Vec<f64> {
        let used = self.used();
        let Some(variance) = &self.variance else {
            return vec![1.0; used.len()];
        };
        let mean = used.iter().map(|&m| variance[m]).sum::<f64>() / used.len().max(1) as f64;
        used.iter().map(|&m| variance[m] / mean).collect()
    }

    /// The mean noise variance of the used channels (their unit²); `None` without variances.
    pub(crate) fn mean_variance(&self) -> Option<f64> {
        let variance = self.variance.as_ref()?;
        let used = self.used();
        (!used.is_empty()).then(|| used.iter().map(|&m| variance[m]).sum::<f64>() / used.len() as f64)
    }

    /// Refuses a channel set that leaves nothing to image with.
    pub(crate) fn check(&self, expected: usize) -> Result<(), InverseError> {
        if self.used.len() != expected {
            return Err(InverseError::FrameLength { expected, got: self.used.len() });
        }
        if !self.used.contains(&true) {
            return Err(InverseError::NoChannels);
        }
        Ok(())
    }
}

/// The mean of several frames per channel (the reference of a set of no-touch frames); NaN
/// where any frame misses the channel, so a channel missing once stays dropped.
pub fn mean_frame(frames: &[Vec<f64>]) -> Vec<f64> {
    let n = frames.len() as f64;
    let width = frames.first().map_or(0, Vec::len);
    (0..width).map(|m| frames.iter().map(|f| f.get(m).copied().unwrap_or(f64::NAN)).sum::<f64>() / n).collect()
}

/// How far a frame's values may typically lie from its reference's, as a factor either way,
/// before the two are taken as from another unit, gain or board: a press changes a channel by
/// percents, never by ten times.
pub const SCALE_LIMIT: f64 = 10.0;

/// A frame's values against its reference's, typically: the median over channels (both values
/// finite, the reference's not zero) of v/v_ref, signed (a frame of the other sign gives about
/// −1); `None` where no channel has both. About 1 for a frame of the same sensor.
pub fn typical_ratio(frame: &[f64], reference: &[f64]) -> Option<f64> {
    typical_ratio_in(frame, reference, &mut Vec::with_capacity(frame.len()))
}

/// [`typical_ratio`] with the ratios in `scratch` (cleared first): allocates nothing where its
/// capacity holds a ratio per channel, as on the frame path.
pub fn typical_ratio_in(frame: &[f64], reference: &[f64], scratch: &mut Vec<f64>) -> Option<f64> {
    scratch.clear();
    scratch.extend(
        frame.iter().zip(reference).filter(|(v, r)| v.is_finite() && r.is_finite() && **r != 0.0).map(|(v, r)| v / r),
    );
    if scratch.is_empty() {
        return None;
    }
    let middle = scratch.len() / 2;
    Some(*scratch.select_nth_unstable_by(middle, f64::total_cmp).1)
}

/// Frames' values against a reference's, typically: the median over `frames` of each one's
/// [`typical_ratio`]; `None` where no frame has one.
pub fn typical_ratio_of_frames<'a>(frames: impl IntoIterator<Item = &'a [f64]>, reference: &[f64]) -> Option<f64> {
    let mut ratios: Vec<f64> = frames.into_iter().filter_map(|f| typical_ratio(f, reference)).collect();
    if ratios.is_empty() {
        return None;
    }
    let middle = ratios.len() / 2;
    Some(*ratios.select_nth_unstable_by(middle, f64::total_cmp).1)
}

/// Whether a [`typical_ratio`] is one a frame of the same sensor can have: within
/// [`SCALE_LIMIT`] either way of 1, and positive.
pub fn plausible_ratio(ratio: f64) -> bool {
    ratio > 1.0 / SCALE_LIMIT && ratio < SCALE_LIMIT
}

/// The mean of each channel's finite values over several frames (a stream's reference, whose
/// channels missing from some frames are dropped by other means); NaN where none is finite.
pub fn mean_of_finite(frames: &[Vec<f64>]) -> Vec<f64> {
    let width = frames.first().map_or(0, Vec::len);
    (0..width)
        .map(|m| {
            let finite = frames.iter().filter_map(|f| f.get(m).copied()).filter(|v| v.is_finite());
            let (sum, count) = finite.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
            if count > 0 {
                sum / count as f64
            } else {
                f64::NAN
            }
        })
        .collect()
}

/// Per-channel relative noise variance of several frames of an unchanging sensor (the
/// reference frames): the variance of v/v̄ about each channel's mean v̄ (ratio², free of the
/// board's unit and gains); `None` with fewer than two frames. NaN values are left out of
/// their channel.
///
/// Few frames estimate a variance badly, and a quantised board can repeat a value exactly:
/// each variance is floored at a tenth of the median channel's, so that no channel is
/// trusted without limit.
pub fn noise_variance(frames: &[Vec<f64>]) -> Option<Vec<f64>> {
    super::NoiseModel::from_frames(frames).map(|model| model.relative_variance())
}

/// Each finite variance raised to at least a tenth of the median finite one.
pub(crate) fn floored(variance: Vec<f64>) -> Vec<f64> {
    let mut finite: Vec<f64> = variance.iter().copied().filter(|v| v.is_finite()).collect();
    if finite.is_empty() {
        return variance;
    }
    finite.sort_by(f64::total_cmp);
    let floor = 0.1 * finite[finite.len() / 2];
    variance.into_iter().map(|v| if v.is_finite() { v.max(floor) } else { v }).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn masks_and_variances_drop_channels() {
        let c = Channels::finite_in(&[1.0, f64::NAN, 2.0, 3.0]).masked(&[true, true, true, false]);
        assert_eq!(c.used(), [0, 2]);
        assert_eq!(c.dropped(), [1, 3]);
        let c = Channels::all(3).with_variance(vec![1.0, 0.0, 3.0]);
        assert_eq!(c.used(), [0, 2]);
        assert_eq!(c.relative_variance(), [0.5, 1.5]);
        assert_eq!(Channels::all(2).masked(&[false, false]).check(2), Err(InverseError::NoChannels));
    }

    #[test]
    fn the_mean_of_finite_values_skips_missing_ones() {
        let frames = vec![vec![1.0, f64::NAN, 4.0], vec![3.0, f64::NAN, f64::INFINITY]];
        let mean = mean_of_finite(&frames);
        assert_eq!((mean[0], mean[2]), (2.0, 4.0));
        assert!(mean[1].is_nan() && !mean_frame(&frames)[2].is_finite(), "the plain mean keeps ∞");
    }

    #[test]
    fn noise_variance_is_the_relative_sample_variance_with_a_floor() {
        let frames = vec![vec![1.0, 10.0, 5.0, 7.0], vec![3.0, 12.0, 5.0, 7.0], vec![2.0, 11.0, f64::NAN, 7.0]];
        // Channel 1: variance 1 about a mean of 2; channel 2: 1 about 11; 3 has two equal values
        // and 4 never moved: both floored at a tenth of the median, channel 2's.
        let v = noise_variance(&frames).unwrap();
        let want = [0.25, 1.0 / 121.0, 0.1 / 121.0, 0.1 / 121.0];
        assert!(v.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-15), "{v:?}");
        assert!(noise_variance(&frames[..1]).is_none());
        // In a board's counts or in volts, the same relative noise.
        let counts: Vec<Vec<f64>> = frames.iter().map(|f| f.iter().map(|x| 250.0 * x).collect()).collect();
        let in_counts = noise_variance(&counts).unwrap();
        assert!(in_counts.iter().zip(&v).all(|(a, b)| (a / b - 1.0).abs() < 1e-12), "{in_counts:?}");
    }
}
