//! The reference an image is taken against, made once from frames at rest: their mean, the
//! channels in use (those the spec keeps, alive, and present in every frame), each weighted by
//! its noise, and the rule that chooses λ. The CLI's `image` and `segment` and Python's
//! `Reconstructor.from_reference` take this one path, so the same frames give the same image.

use std::str::FromStr;

use super::criterion::{data_hyperparameter, DataCriterion};
use super::hyperparameter::Hyperparameter;
use super::{mean_frame, noise_variance, plausible_ratio, typical_ratio, Channels, InverseError, Linearisation, Prior};

/// How the channels are weighted in the reconstruction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Weighting {
    /// Each channel by its noise variance (EIDORS' `meas_icov`): measured from several
    /// reference frames, else [`super::DEFAULT_RELATIVE_NOISE`] of its value.
    Noise,
    /// All channels alike, at their mean noise.
    None,
}

impl FromStr for Weighting {
    type Err = String;

    /// `noise` or `none`.
    fn from_str(text: &str) -> Result<Weighting, String> {
        match text.trim() {
            "noise" => Ok(Weighting::Noise),
            "none" => Ok(Weighting::None),
            _ => Err(format!("\"{text}\" is not a weighting: noise or none")),
        }
    }
}

/// How the channels were weighted, as reported.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WeightingUsed {
    /// By the noise measured from the reference frames.
    NoiseMeasured,
    /// By the default relative noise of each value (one reference frame, or frames that do not vary).
    NoiseAssumed,
    /// All alike.
    None,
}

impl WeightingUsed {
    /// `noise-measured`, `noise-assumed` or `none`.
    pub fn name(self) -> &'static str {
        match self {
            WeightingUsed::NoiseMeasured => "noise-measured",
            WeightingUsed::NoiseAssumed => "noise-assumed",
            WeightingUsed::None => "none",
        }
    }
}

/// How λ is set: by the model and the noise ([`Hyperparameter`]: given, or `auto`), or by a
/// criterion on the frames imaged ([`DataCriterion`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HyperparameterRule {
    /// A given λ, or the noise figure's and the noise level's (`auto`).
    Model(Hyperparameter),
    /// Chosen from the frames imaged.
    Data(DataCriterion),
}

impl HyperparameterRule {
    /// What chose λ, as reported: `given`, `noise-figure-and-map` (`auto`), `gcv` or `discrepancy`.
    pub fn chosen_by(self) -> &'static str {
        match self {
            HyperparameterRule::Model(Hyperparameter::Auto) => "noise-figure-and-map",
            HyperparameterRule::Model(Hyperparameter::Fixed(_)) => "given",
            HyperparameterRule::Data(criterion) => criterion.name(),
        }
    }

    /// The weighting that goes with it unless one is asked for: none with a given λ (the image
    /// of that λ as the paper takes it), the noise's with a chosen one.
    pub fn default_weighting(self) -> Weighting {
        match self {
            HyperparameterRule::Model(Hyperparameter::Fixed(_)) => Weighting::None,
            _ => Weighting::Noise,
        }
    }
}

impl FromStr for HyperparameterRule {
    type Err = String;

    /// `auto`, `gcv`, `discrepancy`, or a λ in [1e-6, 1000].
    fn from_str(text: &str) -> Result<HyperparameterRule, String> {
        match (text.parse::<DataCriterion>(), text.parse::<Hyperparameter>()) {
            (Ok(criterion), _) => Ok(HyperparameterRule::Data(criterion)),
            (_, Ok(given)) => Ok(HyperparameterRule::Model(given)),
            _ => Err(format!("\"{text}\" is neither `auto`, `gcv`, `discrepancy` nor a number in [1e-6, 1000]")),
        }
    }
}

/// Marks as missing (NaN) in every frame, reference and imaged alike, the channels that the
/// spec does not use (`in_use` false) and the dead ones: 0 in the mean of the references (a
/// board prints 0 for a broken contact, which would tell the image that nothing changed there).
pub fn mark_missing(in_use: &[bool], references: &mut [Vec<f64>], frames: &mut [Vec<f64>]) {
    let dead: Vec<bool> = mean_frame(references).iter().map(|r| *r == 0.0).collect();
    let missing = |m: usize| !in_use.get(m).copied().unwrap_or(true) || dead.get(m).copied().unwrap_or(false);
    for frame in references.iter_mut().chain(frames.iter_mut()) {
        frame.iter_mut().enumerate().filter(|(m, _)| missing(*m)).for_each(|(_, x)| *x = f64::NAN);
    }
}

/// The frames at rest an image is taken against, and what they measure.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    /// Their mean per channel (the reference v_ref); NaN where a frame misses the channel.
    pub v_ref: Vec<f64>,
    /// Each channel's noise variance relative to its value (ratio²), when several frames vary
    /// ([`noise_variance`]).
    pub variance: Option<Vec<f64>>,
}

impl Reference {
    /// The reference of `frames` at rest (one or more, each as long as the protocol).
    pub fn new(frames: &[Vec<f64>]) -> Reference {
        Reference { v_ref: mean_frame(frames), variance: noise_variance(frames) }
    }

    /// The channels to image `frames` with: finite in the reference and in every frame, weighted
    /// by `weighting` (the measured noise, else the assumed one) for differences `normalised`
    /// or not; with how they were weighted.
    pub fn channels(
        &self,
        lin: &Linearisation,
        normalised: bool,
        frames: &[Vec<f64>],
        weighting: Weighting,
    ) -> (Channels, WeightingUsed) {
        let mut channels = Channels::finite_in(&self.v_ref);
        for v in frames {
            channels = channels.masked(Channels::finite_in(v).used_mask());
        }
        let channels = lin.noise_weighted(normalised, channels, self.variance.clone());
        match (weighting, &self.variance) {
            (Weighting::None, _) => (channels.uniform_variance(), WeightingUsed::None),
            (Weighting::Noise, Some(_)) => (channels, WeightingUsed::NoiseMeasured),
            (Weighting::Noise, None) => (channels, WeightingUsed::NoiseAssumed),
        }
    }

    /// λ by `rule` for `channels` (from [`Reference::channels`]), the `prior` and differences
    /// `normalised` or not: given, `auto` (computed by `auto`, which a caller may take from a
    /// cache; [`super::choose_hyperparameter`] otherwise), or a criterion on `frames`, of which
    /// those whose scale is unlike the reference's are no evidence.
    pub fn hyperparameter<E: From<InverseError>>(
        &self,
        rule: HyperparameterRule,
        lin: &Linearisation,
        (prior, normalised): (&Prior, bool),
        channels: &Channels,
        frames: &[Vec<f64>],
        auto: impl FnOnce() -> Result<f64, E>,
    ) -> Result<f64, E> {
        match rule {
            HyperparameterRule::Model(Hyperparameter::Auto) => auto(),
            HyperparameterRule::Model(Hyperparameter::Fixed(value)) => Ok(value),
            HyperparameterRule::Data(criterion) => {
                let plausible = |v: &&Vec<f64>| typical_ratio(v, &self.v_ref).is_none_or(plausible_ratio);
                let pairs: Vec<(&[f64], &[f64])> =
                    frames.iter().filter(plausible).map(|v| (self.v_ref.as_slice(), v.as_slice())).collect();
                Ok(data_hyperparameter(lin, prior, normalised, channels, &pairs, criterion)?)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rules_read_as_written_and_report_what_chose() {
        let rule = |t: &str| t.parse::<HyperparameterRule>();
        assert_eq!(rule("auto"), Ok(HyperparameterRule::Model(Hyperparameter::Auto)));
        assert_eq!(rule(" gcv"), Ok(HyperparameterRule::Data(DataCriterion::Gcv)));
        assert_eq!(rule("0.5").map(HyperparameterRule::chosen_by), Ok("given"));
        assert_eq!(rule("0.5").map(HyperparameterRule::default_weighting), Ok(Weighting::None));
        assert_eq!(rule("auto").map(HyperparameterRule::default_weighting), Ok(Weighting::Noise));
        assert!(rule("1e9").is_err_and(|e| e.contains("\"1e9\"")));
        assert!("loud".parse::<Weighting>().is_err_and(|e| e.contains("noise or none")));
    }

    #[test]
    fn dropped_and_dead_channels_are_missing_everywhere() {
        let mut references = vec![vec![1.0, 0.0, 2.0, 3.0], vec![1.2, 0.0, 2.2, 3.1]];
        let mut frames = vec![vec![1.1, 0.5, 2.1, 3.0]];
        mark_missing(&[true, true, true, false], &mut references, &mut frames);
        for frame in references.iter().chain(&frames) {
            assert!(frame[0].is_finite() && frame[2].is_finite());
            assert!(frame[1].is_nan() && frame[3].is_nan(), "{frame:?}");
        }
        let reference = Reference::new(&references);
        assert!((reference.v_ref[0] - 1.1).abs() < 1e-12 && reference.v_ref[1].is_nan());
    }
}
