//! Channels z-scored over the training presses, and the channels that carry nothing found there.

/// Per channel: the training mean and standard deviation, and whether it is used.
#[derive(Debug, Clone, PartialEq)]
pub struct Standardiser {
    mean: Vec<f64>,
    /// 1 / standard deviation for a used channel, 0 for a dropped one.
    inverse_std: Vec<f64>,
    /// The used channels, in order.
    used: Vec<usize>,
}

/// A channel is dead when its spread over the presses is below this fraction of the median
/// channel's (or is not finite): it is constant, saturated or disconnected.
pub const DEAD_SPREAD: f64 = 1e-6;

/// A channel whose spread is below this fraction of its mean is constant to rounding.
const ROUNDING: f64 = 1e-12;

impl Standardiser {
    /// Mean and spread of each channel over `inputs` (rows of equal length); channels whose
    /// spread is below [`DEAD_SPREAD`] of the median or within rounding of their mean, or with a
    /// non-finite value, are dropped.
    pub fn fit(inputs: &[Vec<f64>]) -> Standardiser {
        let channels = inputs.first().map_or(0, Vec::len);
        let n = inputs.len().max(1) as f64;
        let mut mean = vec![0.0; channels];
        let mut finite = vec![true; channels];
        for row in inputs {
            for (c, v) in row.iter().enumerate() {
                mean[c] += v / n;
                finite[c] &= v.is_finite();
            }
        }
        let mut std = vec![0.0; channels];
        for row in inputs {
            for (c, v) in row.iter().enumerate() {
                std[c] += (v - mean[c]).powi(2) / n;
            }
        }
        std.iter_mut().for_each(|s| *s = s.sqrt());
        let mut sorted: Vec<f64> = std.iter().copied().filter(|s| s.is_finite()).collect();
        sorted.sort_by(f64::total_cmp);
        let median = sorted.get(sorted.len() / 2).copied().unwrap_or(0.0);
        // A spread within rounding of the channel's value is none (a constant channel's spread
        // is rounding, and where every channel is constant the median is rounding too).
        let carries = |c: usize| std[c] > DEAD_SPREAD * median && std[c] > ROUNDING * mean[c].abs();
        let used: Vec<usize> = (0..channels).filter(|&c| finite[c] && std[c].is_finite() && carries(c)).collect();
        let mut inverse_std = vec![0.0; channels];
        used.iter().for_each(|&c| inverse_std[c] = 1.0 / std[c]);
        Standardiser { mean, inverse_std, used }
    }

    /// Channels in a frame.
    pub fn channels(&self) -> usize {
        self.mean.len()
    }

    /// The used channels, 0-based.
    pub fn used(&self) -> &[usize] {
        &self.used
    }

    /// The dropped (dead) channels, 0-based.
    pub fn dead(&self) -> Vec<usize> {
        (0..self.channels()).filter(|c| self.inverse_std[*c] == 0.0).collect()
    }

    /// `frame`'s used channels z-scored into `out` (one entry per used channel).
    pub fn apply_into(&self, frame: &[f64], out: &mut [f64]) {
        for (o, &c) in out.iter_mut().zip(&self.used) {
            *o = (frame[c] - self.mean[c]) * self.inverse_std[c];
        }
    }

    /// The parts, for saving: mean and 1/std per channel (0 for a dropped one).
    pub fn parts(&self) -> (&[f64], &[f64]) {
        (&self.mean, &self.inverse_std)
    }

    /// A standardiser from saved parts (equal lengths; a 1/std of 0 drops the channel).
    pub fn from_parts(mean: Vec<f64>, inverse_std: Vec<f64>) -> Option<Standardiser> {
        if mean.len() != inverse_std.len() || mean.iter().chain(&inverse_std).any(|v| !v.is_finite()) {
            return None;
        }
        let used = (0..mean.len()).filter(|&c| inverse_std[c] != 0.0).collect();
        Some(Standardiser { mean, inverse_std, used })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_and_broken_channels_are_found_dead() {
        let inputs: Vec<Vec<f64>> = (0..20)
            .map(|i| {
                let i = i as f64;
                vec![i, 5.0, 2.0 * i + 1.0, if i == 3.0 { f64::NAN } else { i }]
            })
            .collect();
        let s = Standardiser::fit(&inputs);
        assert_eq!(s.used(), &[0, 2]);
        assert_eq!(s.dead(), vec![1, 3]);
        let mut z = [0.0; 2];
        s.apply_into(&inputs[10], &mut z);
        assert!(z[0].abs() < 0.1 && (z[0] - z[1]).abs() < 1e-12, "{z:?}");
    }
}
