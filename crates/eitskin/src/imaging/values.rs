//! What a board's numbers are: signed voltages, magnitudes, or complex values, turned into the
//! signed values the forward model predicts.
//!
//! Most boards send |V| per channel; the reconstruction needs the signed voltage. The sign of
//! each channel is the sign the homogeneous model gives it (a press changes a value by a few
//! per cent, never through zero), so `v_m = |v_m| · sign(v₀,m)`. A channel the model cannot
//! sign (|v₀,m| under 1e-3 of the median) or whose magnitude disagrees with the model's pattern
//! by more than a factor 10 from the median ratio is reported: its sign, or its wiring, is not
//! what the protocol says.
//!
//! Cheap boards also scale each channel by its own gain. [`Gains::estimate`] measures them
//! against the model from a reference of the homogeneous sensor and names the channels that
//! disagree with the rest; [`Gains::apply`] divides them out.
//!
//! A stream sends one [`ValueKind`] per frame, turned into signed values without allocating.
//!
//! ```
//! use eitskin::values::{signed_from_magnitudes, Component};
//! let model = [2.0, -1.0, 0.5];
//! let (signed, report) = signed_from_magnitudes(&[2.1, 0.9, 0.5], &model);
//! assert_eq!(signed, [2.1, -0.9, 0.5]);
//! assert!(report.unexplained.is_empty());
//! assert_eq!(Component::Magnitude.of(3.0, 4.0), 5.0);
//! ```

/// Which part of a complex value is imaged.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Component {
    /// The real (in-phase) part, in the value's unit.
    Real,
    /// The imaginary (quadrature) part.
    Imaginary,
    /// The magnitude |z| (signed from the model, as for magnitude-only boards).
    Magnitude,
    /// The phase arg z, in rad.
    Phase,
}

impl Component {
    /// This component of `re + i·im`.
    pub fn of(self, re: f64, im: f64) -> f64 {
        match self {
            Component::Real => re,
            Component::Imaginary => im,
            Component::Magnitude => re.hypot(im),
            Component::Phase => im.atan2(re),
        }
    }

    /// This component of each channel of a complex frame given as real and imaginary parts.
    pub fn of_frame(self, re: &[f64], im: &[f64]) -> Vec<f64> {
        re.iter().zip(im).map(|(&r, &i)| self.of(r, i)).collect()
    }

    /// The name in flags: `real`, `imaginary`, `magnitude`, `phase`.
    pub fn name(self) -> &'static str {
        match self {
            Component::Real => "real",
            Component::Imaginary => "imaginary",
            Component::Magnitude => "magnitude",
            Component::Phase => "phase",
        }
    }
}

impl std::str::FromStr for Component {
    type Err = String;

    /// `real`, `imaginary`, `magnitude` or `phase`.
    fn from_str(text: &str) -> Result<Component, String> {
        [Component::Real, Component::Imaginary, Component::Magnitude, Component::Phase]
            .into_iter()
            .find(|c| c.name() == text)
            .ok_or_else(|| format!("\"{text}\" is not a component: use real, imaginary, magnitude or phase"))
    }
}

/// What a board sends per measurement, on a serial line or in a capture.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ValueKind {
    /// Signed values, as the forward model gives them.
    Signed,
    /// Magnitudes |v|, signed by the model.
    Magnitude,
    /// Complex values as interleaved pairs (re₀, im₀, re₁, im₁, …), imaged through a component
    /// (a magnitude signed by the model).
    Complex(Component),
}

impl ValueKind {
    /// Numbers per measurement in a frame: 2 for complex pairs, else 1.
    pub fn per_measurement(self) -> usize {
        if matches!(self, ValueKind::Complex(_)) {
            2
        } else {
            1
        }
    }

    /// The signed values of a frame `raw` of this kind into `out` (one per measurement), signs
    /// from the model's values `model`; NaN stays NaN. Allocates nothing.
    pub fn signed_into(self, raw: &[f64], model: &[f64], out: &mut [f64]) {
        assert_eq!(raw.len(), out.len() * self.per_measurement(), "numbers per frame");
        assert_eq!(model.len(), out.len(), "one model value per measurement");
        let signed = |v: f64, m: f64| v.abs() * m.signum();
        match self {
            ValueKind::Signed => out.copy_from_slice(raw),
            ValueKind::Magnitude => {
                for ((o, v), m) in out.iter_mut().zip(raw).zip(model) {
                    *o = signed(*v, *m);
                }
            }
            ValueKind::Complex(component) => {
                for ((o, pair), m) in out.iter_mut().zip(raw.chunks_exact(2)).zip(model) {
                    let value = component.of(pair[0], pair[1]);
                    *o = if component == Component::Magnitude { signed(value, *m) } else { value };
                }
            }
        }
    }
}

/// Channels whose magnitude the homogeneous model does not explain (0-based).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SignReport {
    /// Channels the model cannot sign, or whose magnitude is off the model's pattern by more
    /// than a factor 10 (from the median ratio of measured to model magnitudes).
    pub unexplained: Vec<usize>,
}

/// Signed values from magnitudes `magnitudes` (any unit) by the signs of the model's `model`
/// values (V), with the channels the model does not explain; NaN stays NaN.
pub fn signed_from_magnitudes(magnitudes: &[f64], model: &[f64]) -> (Vec<f64>, SignReport) {
    assert_eq!(magnitudes.len(), model.len(), "one model value per channel");
    let signed = magnitudes.iter().zip(model).map(|(v, m)| v.abs() * m.signum()).collect();
    let tiny = 1e-3 * median(model.iter().map(|m| m.abs()).collect());
    let ratio = |m: usize| magnitudes[m].abs() / model[m].abs();
    let centre =
        median((0..model.len()).filter(|&m| model[m].abs() > tiny && magnitudes[m].is_finite()).map(ratio).collect());
    let unexplained = (0..model.len())
        .filter(|&m| magnitudes[m].is_finite())
        .filter(|&m| {
            model[m].abs() <= tiny || !(ratio(m) / centre).is_finite() || (ratio(m) / centre).ln().abs() > 10f64.ln()
        })
        .collect();
    (signed, SignReport { unexplained })
}

/// Per-channel gains of a board against the model: what each channel's reference value is in
/// units of the model's, with the channels that disagree with the rest.
#[derive(Debug, Clone, PartialEq)]
pub struct Gains {
    /// g_m = v_ref,m / v₀,m per channel (NaN where the model gives no value or the reference is
    /// missing); the board's unit per V.
    pub gains: Vec<f64>,
    /// The median gain (the board's unit per V): the common scale, which also absorbs a
    /// background conductivity other than the model's.
    pub median: f64,
    /// Channels (0-based) whose gain is not positive (the sign is not the model's) or lies more
    /// than 5 robust standard deviations (1.4826 × the median absolute deviation of ln g), and
    /// at least a factor 1.5, from the median.
    pub outliers: Vec<usize>,
    /// How much of the spread of ln|v_ref| over the channels the model's pattern ln|v₀| explains
    /// (R², 1 = all; NaN when the pattern is flat): near 1 on a board whose values are the
    /// protocol's voltages, low or negative when they are not (a saturated front end, another
    /// measurement order, another electrode layout).
    pub pattern_fit: f64,
}

impl Gains {
    /// Least-squares gains g_m = argmin Σ_t (v_t,m − g·v₀,m)² = mean_t(v_t,m) / v₀,m, from the
    /// mean reference `reference` and the model's values `model` (V).
    pub fn estimate(reference: &[f64], model: &[f64]) -> Gains {
        assert_eq!(reference.len(), model.len(), "one model value per channel");
        let gains: Vec<f64> =
            reference.iter().zip(model).map(|(r, m)| if *m != 0.0 { r / m } else { f64::NAN }).collect();
        let positive: Vec<f64> = gains.iter().copied().filter(|g| *g > 0.0 && g.is_finite()).collect();
        let centre = median(positive.clone());
        let logs: Vec<f64> = positive.iter().map(|g| (g / centre).ln().abs()).collect();
        let spread: f64 = 1.4826 * median(logs);
        let limit = (5.0 * spread).max(1.5f64.ln());
        let outliers = (0..gains.len())
            .filter(|&m| gains[m].is_finite() && (gains[m] <= 0.0 || (gains[m] / centre).ln().abs() > limit))
            .collect();
        let pattern_fit = pattern_fit(reference, model);
        Gains { gains, median: centre, outliers, pattern_fit }
    }

    /// A frame in the model's units: each value divided by its channel's gain (NaN where the
    /// gain is unknown or an outlier, so the channel is dropped).
    pub fn apply(&self, frame: &[f64]) -> Vec<f64> {
        assert_eq!(frame.len(), self.gains.len(), "one gain per channel");
        let usable = |m: usize| self.gains[m].is_finite() && self.outliers.binary_search(&m).is_err();
        frame.iter().enumerate().map(|(m, v)| if usable(m) { v / self.gains[m] } else { f64::NAN }).collect()
    }
}

/// R² of ln|reference| against ln|model| + a constant, over the channels the model gives a
/// value (|v₀| above 1e-3 of the median) and the reference a finite non-zero one: 1 for the
/// same pattern up to a gain, 0 for none; NaN where the reference has no spread. Any two
/// frames compare so (a frame as `model` against its reference).
pub fn pattern_fit(reference: &[f64], model: &[f64]) -> f64 {
    let tiny = 1e-3 * median(model.iter().map(|m| m.abs()).collect());
    let pairs: Vec<(f64, f64)> = reference
        .iter()
        .zip(model)
        .filter(|(r, m)| m.abs() > tiny && r.is_finite() && **r != 0.0)
        .map(|(r, m)| (r.abs().ln(), m.abs().ln()))
        .collect();
    let n = pairs.len() as f64;
    let mean_of = |f: &dyn Fn(&(f64, f64)) -> f64| pairs.iter().map(f).sum::<f64>() / n;
    let (mean_r, mean_gain) = (mean_of(&|p| p.0), mean_of(&|p| p.0 - p.1));
    let total: f64 = pairs.iter().map(|p| (p.0 - mean_r).powi(2)).sum();
    let residual: f64 = pairs.iter().map(|p| (p.0 - p.1 - mean_gain).powi(2)).sum();
    if total > 0.0 {
        1.0 - residual / total
    } else {
        f64::NAN
    }
}

/// The median of `values` (NaN when empty).
fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    values.get(values.len() / 2).copied().unwrap_or(f64::NAN)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn magnitudes_take_the_models_signs_and_odd_channels_are_reported() {
        let model = [1.0, -2.0, 3.0, -4.0, 1e-9];
        let (signed, report) = signed_from_magnitudes(&[10.0, 20.0, 600.0, f64::NAN, 1.0], &model);
        assert_eq!(signed[..3], [10.0, -20.0, 600.0]);
        assert!(signed[3].is_nan());
        // Channel 3 is 20× the pattern; channel 5 has no sign in the model.
        assert_eq!(report.unexplained, [2, 4]);
    }

    #[test]
    fn gains_are_recovered_and_a_wrong_channel_is_named() {
        let model: Vec<f64> = (0..40).map(|m| if m % 3 == 0 { -1.0 - m as f64 } else { 2.0 + m as f64 }).collect();
        // ±30 % gains on a common scale of 50, one channel 4× off and one with the wrong sign.
        let truth: Vec<f64> = (0..40).map(|m| 50.0 * (1.0 + 0.3 * ((m * 7 % 13) as f64 / 6.0 - 1.0))).collect();
        let mut reference: Vec<f64> = model.iter().zip(&truth).map(|(v, g)| v * g).collect();
        reference[5] *= 4.0;
        reference[9] = -reference[9];
        let gains = Gains::estimate(&reference, &model);
        assert_eq!(gains.outliers, [5, 9]);
        assert!((gains.median / 50.0 - 1.0).abs() < 0.1, "{}", gains.median);
        for m in (0..40).filter(|m| ![5, 9].contains(m)) {
            assert!((gains.gains[m] / truth[m] - 1.0).abs() < 1e-12);
        }
        assert!(gains.pattern_fit > 0.8, "{}", gains.pattern_fit);
        // Values that ignore the model's pattern (a saturated front end: two levels) fit badly.
        let saturated: Vec<f64> = (0..40).map(|m| if m % 2 == 0 { 178.0 } else { 252.0 }).collect();
        assert!(Gains::estimate(&saturated, &model).pattern_fit < 0.0);
        let corrected = gains.apply(&reference);
        assert!(corrected[5].is_nan() && corrected[9].is_nan());
        assert!((corrected[0] - model[0]).abs() < 1e-12);
    }

    #[test]
    fn each_value_kind_gives_the_signed_values() {
        let model = [2.0, -1.0];
        let mut out = [0.0; 2];
        ValueKind::Signed.signed_into(&[2.1, -0.9], &model, &mut out);
        assert_eq!(out, [2.1, -0.9]);
        ValueKind::Magnitude.signed_into(&[2.1, 0.9], &model, &mut out);
        assert_eq!(out, [2.1, -0.9]);
        ValueKind::Complex(Component::Magnitude).signed_into(&[3.0, 4.0, 0.6, 0.8], &model, &mut out);
        assert_eq!(out, [5.0, -1.0]);
        ValueKind::Complex(Component::Imaginary).signed_into(&[3.0, 4.0, 0.6, -0.8], &model, &mut out);
        assert_eq!(out, [4.0, -0.8]);
        assert_eq!(ValueKind::Complex(Component::Real).per_measurement(), 2);
    }

    #[test]
    fn components_of_a_complex_value() {
        let (re, im) = (1.0, 1.0);
        assert_eq!(Component::Real.of(re, im), 1.0);
        assert_eq!(Component::Imaginary.of(re, im), 1.0);
        assert!((Component::Phase.of(re, im) - std::f64::consts::FRAC_PI_4).abs() < 1e-15);
        assert_eq!("phase".parse(), Ok(Component::Phase));
        assert!("angle".parse::<Component>().is_err());
    }
}
