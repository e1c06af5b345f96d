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
    let mut model_sizes: Vec<f64> = model.iter().map(|m| m.abs()).collect();
    model_sizes.sort_by(f64::total_cmp);
    let tiny = 1e-3 * model_sizes.get(model_sizes.len() / 2).copied().unwrap_or(0.0);
    let ratio = |m: usize| magnitudes[m].abs() / model[m].abs();
    let mut ratios: Vec<f64> =
        (0..model.len()).filter(|&m| model[m].abs() > tiny && magnitudes[m].is_finite()).map(ratio).collect();
    ratios.sort_by(f64::total_cmp);
    let median = ratios.get(ratios.len() / 2).copied().unwrap_or(f64::NAN);
    let unexplained = (0..model.len())
        .filter(|&m| magnitudes[m].is_finite())
        .filter(|&m| {
            model[m].abs() <= tiny || !(ratio(m) / median).is_finite() || (ratio(m) / median).ln().abs() > 10f64.ln()
        })
        .collect();
    (signed, SignReport { unexplained })
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
    fn components_of_a_complex_value() {
        let (re, im) = (1.0, 1.0);
        assert_eq!(Component::Real.of(re, im), 1.0);
        assert_eq!(Component::Imaginary.of(re, im), 1.0);
        assert!((Component::Phase.of(re, im) - std::f64::consts::FRAC_PI_4).abs() < 1e-15);
        assert_eq!("phase".parse(), Ok(Component::Phase));
        assert!("angle".parse::<Component>().is_err());
    }
}
