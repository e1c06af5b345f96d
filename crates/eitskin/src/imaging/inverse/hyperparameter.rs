//! The hyperparameter λ, given or chosen from the noise: by the noise figure, and at least the
//! λ the noise level calls for.
//!
//! **Noise figure.** The noise figure (Adler & Guardo 1996; EIDORS' `calc_noise_figure`) compares the
//! signal-to-noise ratio of the measurements with that of the image, for a small target at
//! the centre and the measurement noise Σ:
//!
//!   SNR_z = Σ z₀² / tr Σ,   SNR_x = Σ (A x₀)² / tr(A H Σ Hᵀ A),   NF = SNR_z / SNR_x,
//!
//! with z₀ = J δσ the target's signal, x₀ = H z₀ its image and A the triangle areas. A small
//! λ passes noise into the image (NF large); a large λ smooths it away (NF small). The rule:
//! λ is where NF = 0.5, the value EIDORS' GREIT examples recommend. It uses only the model
//! and the measured noise (its shape across channels; its scale cancels), never a frame with
//! a touch, so it is fixed for a stream and a calibration made with it stays valid. The
//! target is the triangles within 10 % of the sensor's equivalent radius √(area/π) of the
//! mesh's area centroid (at least the triangle nearest to it), at unit contrast.
//!
//! In the eigenbasis of the whitened system Σ^-½ J R⁻¹Jᵀ Σ^-½ = U diag(e) Uᵀ on its range
//! ([`super::eigensystem`]), every NF(λ) costs rank² (through the Gram matrix of the
//! eigenvectors' images), so λ is found on a fine grid in milliseconds.
//!
//! **Noise level.** NF is a ratio of two SNRs, so the noise's level cancels from it, and λ_NF
//! would stay the same however noisy the board. The one-step reconstruction is also the
//! maximum a posteriori estimate for Gaussian noise Σ and a Gaussian prior q·R⁻¹ on Δσ, for
//! which λ² = mean(Σ)/q (λ² multiplies Σ/mean(Σ) here): λ grows in proportion to the noise.
//! The prior's scale q is set, without reference to any data set, by the same standard target
//! the noise figure uses: a change of [`TARGET_CONTRAST`] × σ₀ over the target's share a of the
//! sensor's area has the area-mean square c²σ₀²a, and q is such that the prior's area-mean
//! variance q·⟨R⁻¹⟩ equals it. σ₀ follows from the model (v₀ = −σ₀·J·1 for a homogeneous
//! body, fitted by least squares). The chosen λ is max(λ_NF, λ_MAP): the noise figure's at low
//! noise, growing with the noise above it.

use std::str::FromStr;

use faer::Mat;

use super::eigensystem::Eigensystem;
use super::linearisation::{inverse_diagonal, uniform_response};
use super::{Channels, InverseError, Linearisation, Prior};

/// The noise figure λ is chosen for (EIDORS' GREIT examples use 0.5).
pub const NOISE_FIGURE_TARGET: f64 = 0.5;

/// The standard target's conductivity loss as a fraction of the background (dimensionless),
/// which sets the prior's scale: half the background, a light press on a hydrogel (the virtual
/// sensor's gel loses half at about 4.5 N) or an insulating object over half the target.
pub const TARGET_CONTRAST: f64 = 0.5;

/// The noise assumed without a measured one: 0.3 % of each value (dimensionless), the
/// frame-to-frame noise of open boards.
pub const DEFAULT_RELATIVE_NOISE: f64 = 0.003;

/// The largest λ a user may give (dimensionless): the top of the range `auto` searches.
pub const LARGEST_HYPERPARAMETER: f64 = 1e3;

/// The smallest λ a user may give (dimensionless): the bottom of the range `auto` searches
/// (below it the system is all but unregularised, and the image is rounding: λ = 1e-300 gave
/// ±9,000 S/m).
pub const SMALLEST_HYPERPARAMETER: f64 = 1e-6;

/// The range λ is searched in (dimensionless).
pub(super) const SEARCH: (f64, f64) = (SMALLEST_HYPERPARAMETER, LARGEST_HYPERPARAMETER);

/// Whether a given λ is in the range a user may give, [1e-6, 1000].
pub fn hyperparameter_in_range(lambda: f64) -> bool {
    (SEARCH.0..=SEARCH.1).contains(&lambda)
}

/// How λ is set: a given value, or chosen from the noise (see the module doc).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Hyperparameter {
    /// This λ (dimensionless, > 0).
    Fixed(f64),
    /// λ from the measured noise: see [`choose_hyperparameter`].
    Auto,
}

impl std::fmt::Display for Hyperparameter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Hyperparameter::Fixed(value) => write!(f, "{value}"),
            Hyperparameter::Auto => f.write_str("auto"),
        }
    }
}

impl FromStr for Hyperparameter {
    type Err = String;

    /// `auto`, or a number in [1e-6, 1000].
    fn from_str(text: &str) -> Result<Hyperparameter, String> {
        if text.trim() == "auto" {
            return Ok(Hyperparameter::Auto);
        }
        match text.trim().parse::<f64>() {
            Ok(value) if hyperparameter_in_range(value) => Ok(Hyperparameter::Fixed(value)),
            _ => Err(format!("\"{text}\" is neither `auto` nor a number in [1e-6, 1000]")),
        }
    }
}

/// What the noise figure needs, precomputed for one set of channels.
struct NoiseFigure {
    /// Eigenvalues e of the whitened system.
    eigenvalues: Vec<f64>,
    /// CᵀC, eigenvalues × eigenvalues, for C = A R⁻¹ J_wᵀ U (triangles × eigenvalues): the image of each
    /// eigenvector, area-weighted.
    gram: Mat<f64>,
    /// Uᵀ Σ^-½ z₀.
    target: Vec<f64>,
    /// SNR_z.
    snr_z: f64,
}

impl NoiseFigure {
    fn new(
        lin: &Linearisation,
        prior: &Prior,
        normalised: bool,
        channels: &Channels,
    ) -> Result<NoiseFigure, InverseError> {
        Ok(NoiseFigure::of(&Eigensystem::new(lin, prior, normalised, channels)?, lin, channels))
    }

    /// From the channels' eigensystem, already made.
    fn of(system: &Eigensystem, lin: &Linearisation, channels: &Channels) -> NoiseFigure {
        let variance = channels.relative_variance();
        // CᵀC: channels² work per λ instead of triangles × channels.
        let gram = system.area_gram(lin);
        let z0 = system.response_to(lin, &target(lin.mesh()));
        let zw: Vec<f64> = z0.iter().zip(&system.std).map(|(z, s)| z / s).collect();
        let target = system.coefficients(&zw);
        let snr_z = z0.iter().map(|z| z * z).sum::<f64>() / variance.iter().sum::<f64>();
        NoiseFigure { eigenvalues: system.eigenvalues.clone(), gram, target, snr_z }
    }

    fn at(&self, hyperparameter: f64) -> f64 {
        let lambda2 = hyperparameter * hyperparameter;
        let filter: Vec<f64> = self.eigenvalues.iter().map(|e| 1.0 / (e.max(0.0) + lambda2)).collect();
        let y = faer::Col::from_fn(filter.len(), |i| filter[i] * self.target[i]);
        // The image's signal ‖C y‖² = yᵀ (CᵀC y).
        let signal = y.transpose() * (&self.gram * &y);
        let noise: f64 = filter.iter().enumerate().map(|(i, f)| f * f * self.gram[(i, i)]).sum();
        self.snr_z / (signal / noise)
    }
}

/// The triangles of the noise figure's target (see the module doc).
fn target(mesh: &crate::mesh::Mesh) -> Vec<usize> {
    let n = mesh.triangles().len();
    let total: f64 = (0..n).map(|t| mesh.area(t)).sum();
    let mut centre = [0.0; 2];
    for t in 0..n {
        let [x, y] = mesh.centroid(t);
        centre[0] += x * mesh.area(t) / total;
        centre[1] += y * mesh.area(t) / total;
    }
    mesh.triangles_near(centre, 0.1 * (total / std::f64::consts::PI).sqrt())
}

/// The noise figure of the reconstruction with this λ and these channels (see the module doc).
pub fn noise_figure(
    lin: &Linearisation,
    prior: &Prior,
    normalised: bool,
    channels: &Channels,
    hyperparameter: f64,
) -> Result<f64, InverseError> {
    super::check_hyperparameter(hyperparameter)?;
    Ok(NoiseFigure::new(lin, prior, normalised, channels)?.at(hyperparameter))
}

/// The automatic λ: the larger of the noise figure's ([`noise_figure_hyperparameter`]) and,
/// when the channels carry their noise variances in the model's units (V² at 1 A, or ratio²
/// when normalised), the noise level's ([`map_hyperparameter`]); see the module doc.
pub fn choose_hyperparameter(
    lin: &Linearisation,
    prior: &Prior,
    normalised: bool,
    channels: &Channels,
) -> Result<f64, InverseError> {
    let system = Eigensystem::new(lin, prior, normalised, channels)?;
    Ok(choose_hyperparameter_on(lin, channels, &system))
}

/// [`choose_hyperparameter`] on the channels' eigensystem, already made (the reconstructor at
/// the λ chosen is then derived from it: [`Eigensystem::compact_matrix_and_mix`]).
pub(super) fn choose_hyperparameter_on(lin: &Linearisation, channels: &Channels, system: &Eigensystem) -> f64 {
    let figure = NoiseFigure::of(system, lin, channels);
    crate::parallel::step_aside();
    let from_figure = noise_figure_search(&figure);
    crate::parallel::step_aside();
    let from_level = map_hyperparameter_of(lin, system.r_inv(), channels);
    from_level.map_or(from_figure, |l| from_figure.max(l.min(SEARCH.1)))
}

/// The MAP λ = √(mean(Σ)/q) for the channels' noise variances Σ (the model's units) and the
/// prior scale q of the standard target (see the module doc); `None` without variances.
pub fn map_hyperparameter(
    lin: &Linearisation,
    prior: &Prior,
    normalised: bool,
    channels: &Channels,
) -> Result<Option<f64>, InverseError> {
    if channels.mean_variance().is_none() {
        return Ok(None);
    }
    let (_, r) = lin.rows_with_diagonal(&channels.used(), normalised, prior)?;
    Ok(map_hyperparameter_of(lin, &inverse_diagonal(&r), channels))
}

/// [`map_hyperparameter`] for the prior's inverse diagonal `r_inv` on the channels, already made.
fn map_hyperparameter_of(lin: &Linearisation, r_inv: &[f64], channels: &Channels) -> Option<f64> {
    let mean_variance = channels.mean_variance()?;
    let mesh = lin.mesh();
    let area: Vec<f64> = (0..mesh.triangles().len()).map(|t| mesh.area(t)).collect();
    let total: f64 = area.iter().sum();
    let mean_r_inv = r_inv.iter().zip(&area).map(|(r, a)| r * a).sum::<f64>() / total;
    let share = target(mesh).iter().map(|&t| area[t]).sum::<f64>() / total;
    // σ₀ from v₀ = −σ₀·J·1, by least squares over every channel of the model.
    let d = uniform_response(lin.jacobian());
    let sigma0 =
        -lin.background().iter().zip(&d).map(|(v, d)| v * d).sum::<f64>() / d.iter().map(|d| d * d).sum::<f64>();
    let q = (TARGET_CONTRAST * sigma0).powi(2) * share / mean_r_inv;
    Some((mean_variance / q).sqrt()).filter(|l| l.is_finite() && *l > 0.0)
}

/// The λ whose noise figure is [`NOISE_FIGURE_TARGET`], searched on a grid of 20 steps a
/// decade over [1e-6, 1e3] and refined by bisection in log λ; the nearest end of the range if
/// the noise figure does not cross the target inside it.
pub fn noise_figure_hyperparameter(
    lin: &Linearisation,
    prior: &Prior,
    normalised: bool,
    channels: &Channels,
) -> Result<f64, InverseError> {
    Ok(noise_figure_search(&NoiseFigure::new(lin, prior, normalised, channels)?))
}

/// The λ where `nf` crosses [`NOISE_FIGURE_TARGET`] (see [`noise_figure_hyperparameter`]).
fn noise_figure_search(nf: &NoiseFigure) -> f64 {
    let (lo, hi) = (SEARCH.0.log10(), SEARCH.1.log10());
    let steps = ((hi - lo) * 20.0).round() as usize;
    let at = |x: f64| nf.at(10f64.powf(x)) - NOISE_FIGURE_TARGET;
    let mut previous = (lo, at(lo));
    if previous.1 <= 0.0 {
        return SEARCH.0;
    }
    for i in 1..=steps {
        let x = lo + (hi - lo) * i as f64 / steps as f64;
        let value = at(x);
        if value <= 0.0 {
            let (mut a, mut b) = (previous.0, x);
            for _ in 0..40 {
                let mid = 0.5 * (a + b);
                if at(mid) > 0.0 {
                    a = mid;
                } else {
                    b = mid;
                }
            }
            return 10f64.powf(0.5 * (a + b));
        }
        previous = (x, value);
    }
    SEARCH.1
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{ReconstructorParams, SensorSpec};

    fn linearisation() -> Linearisation {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 400;
        Linearisation::new(&spec.forward_model().unwrap(), 1.0).unwrap()
    }

    /// The eigenbasis shortcut agrees with the noise figure computed from H itself.
    #[test]
    fn noise_figure_matches_its_definition_and_falls_with_lambda() {
        let lin = linearisation();
        let prior = Prior::default();
        let mut variance: Vec<f64> = (0..lin.measurements()).map(|m| 1.0 + (m % 7) as f64).collect();
        variance[3] = 4.0;
        let channels = Channels::all(lin.measurements()).with_variance(variance.clone());
        let lambda = 0.07;
        let params = ReconstructorParams { hyperparameter: lambda, ..ReconstructorParams::default() };
        let h = lin.element_matrix(&params, &channels).unwrap();
        let mean = variance.iter().sum::<f64>() / variance.len() as f64;
        let sigma: Vec<f64> = variance.iter().map(|v| v / mean).collect();
        let mesh = lin.mesh();
        let contrast = target(mesh);
        let z0: Vec<f64> =
            (0..lin.measurements()).map(|i| contrast.iter().map(|&t| lin.jacobian()[(i, t)]).sum()).collect();
        let snr_z = z0.iter().map(|z| z * z).sum::<f64>() / sigma.iter().sum::<f64>();
        let (mut signal, mut noise) = (0.0, 0.0);
        for t in 0..h.nrows() {
            let a = mesh.area(t);
            let x: f64 = (0..h.ncols()).map(|m| h[(t, m)] * z0[m]).sum();
            signal += (a * x).powi(2);
            noise += a * a * (0..h.ncols()).map(|m| h[(t, m)].powi(2) * sigma[m]).sum::<f64>();
        }
        let expected = snr_z / (signal / noise);
        let got = noise_figure(&lin, &prior, false, &channels, lambda).unwrap();
        assert!((got / expected - 1.0).abs() < 1e-8, "{got} vs {expected}");
        let low = noise_figure(&lin, &prior, false, &channels, 0.01).unwrap();
        let high = noise_figure(&lin, &prior, false, &channels, 1.0).unwrap();
        assert!(low > got && got > high, "NF falls as λ grows: {low}, {got}, {high}");
    }

    /// With noise variances, λ is the larger of the noise figure's, which ignores the noise
    /// level, and the MAP λ, which grows in proportion to it.
    #[test]
    fn the_chosen_lambda_grows_with_the_noise_level() {
        let lin = linearisation();
        let prior = Prior::default();
        let at = |level: f64| {
            let variance = lin.background().iter().map(|v| (level * v).powi(2)).collect();
            let channels = Channels::all(lin.measurements()).with_variance(variance);
            let figure = noise_figure_hyperparameter(&lin, &prior, false, &channels).unwrap();
            let map = map_hyperparameter(&lin, &prior, false, &channels).unwrap().unwrap();
            assert_eq!(choose_hyperparameter(&lin, &prior, false, &channels).unwrap(), figure.max(map));
            (figure, map)
        };
        let (figure_low, map_low) = at(0.0001);
        let (figure_high, map_high) = at(0.01);
        assert!((figure_low / figure_high - 1.0).abs() < 1e-6, "NF: {figure_low} vs {figure_high}");
        assert!((map_high / map_low - 100.0).abs() < 1e-6, "MAP: {map_low} vs {map_high}");
        // Quiet data keep the noise figure's λ; noisy data get a larger one.
        assert!(map_low < figure_low && map_high > figure_high, "{map_low} {figure_low} {map_high}");
    }

    #[test]
    fn the_chosen_lambda_meets_the_target() {
        let lin = linearisation();
        let channels = Channels::all(lin.measurements());
        let lambda = choose_hyperparameter(&lin, &Prior::default(), false, &channels).unwrap();
        let nf = noise_figure(&lin, &Prior::default(), false, &channels, lambda).unwrap();
        assert!((nf - NOISE_FIGURE_TARGET).abs() < 1e-6, "λ = {lambda}: NF = {nf}");
        assert_eq!("auto".parse(), Ok(Hyperparameter::Auto));
        assert_eq!("0.3".parse(), Ok(Hyperparameter::Fixed(0.3)));
        assert!("0".parse::<Hyperparameter>().is_err() && "nan".parse::<Hyperparameter>().is_err());
    }
}
