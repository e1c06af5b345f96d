//! Physics features: the press fitted to a frame's Δv on the sensor as specified: where (x, y,
//! in m) and how strong (the log of its contrast). On a skin built roughly as specified, these are
//! nearly the label already, so a regressor on them needs few presses to learn what is left: the
//! outline's real size, the electrodes' real places, the gel's law.

use super::{LabelledPress, LearnError, Standardiser};
use crate::press_fit::{Locator, PressFit, PressModel, PressModelParams, PressScratch};
use crate::SensorSpec;

/// The sensor as specified: its press model and its measurements without a press (V).
#[derive(Debug, Clone)]
pub struct NominalSensor {
    press: PressModel,
    background: Vec<f64>,
}

impl NominalSensor {
    /// The sensor of press model `press` whose measurements without a press are `background`
    /// (V, one per measurement of its protocol); `None` if their counts differ.
    pub fn new(press: PressModel, background: Vec<f64>) -> Option<NominalSensor> {
        (press.measurements() == background.len()).then_some(NominalSensor { press, background })
    }

    /// The sensor of `spec` on its own mesh, with `press` as its press model (built with the
    /// default indenter when `None`: a fraction of a second at 4,000 triangles, its exact
    /// responses on [`crate::press_fit::EXACT_TRIANGLES`] for a finer mesh).
    pub fn of_spec(spec: &SensorSpec, press: Option<PressModel>) -> Result<NominalSensor, LearnError> {
        let model = spec.forward_model()?;
        let background = model.measure(&spec.homogeneous(model.mesh()))?;
        let press = match press {
            Some(press) => press,
            None => {
                // Its exact responses on a coarser mesh when this one is too fine to keep K⁻¹ whole.
                let exact = crate::press_fit::exact_model_for(spec, &model)?;
                let params = PressModelParams::default();
                PressModel::with_exact_model(&model, exact.as_ref().unwrap_or(&model), spec.conductivity, &params)?
            }
        };
        let (expected, got) = (background.len(), press.measurements());
        NominalSensor::new(press, background).ok_or(crate::InverseError::FrameLength { expected, got }.into())
    }

    /// Measurements per frame.
    pub fn measurements(&self) -> usize {
        self.background.len()
    }
}

/// The press features of Δv: each channel weighted (its sign for magnitudes, its noise, 0 for a
/// dead one), then one press placed anywhere on the sheet.
#[derive(Debug, Clone)]
pub struct PressFeatures {
    locator: Locator,
    /// Per channel: sign / noise, 0 for a dead channel. A board's noise is relative to each value
    /// ([`NOISE_FLOOR`] of the largest at least, so that a value near 0 is not taken as exact).
    weights: Vec<f64>,
    /// Whether Δv is read as a change of magnitudes, Δ|v|.
    pub magnitudes: bool,
    /// The channels constant over the training presses (0-based), left out.
    dead: Vec<usize>,
}

/// The smallest noise a channel is given, as a fraction of the largest background value's: a
/// measurement near 0 (by symmetry, say) still has its converter's noise.
pub const NOISE_FLOOR: f64 = 1e-3;

/// Buffers for [`PressFeatures::features_into`].
#[derive(Debug, Default)]
pub struct FeatureScratch {
    weighted: Vec<f64>,
    press: PressScratch,
}

impl PressFeatures {
    /// The features for presses like `presses`: the channels constant over them are left out,
    /// and Δv is read as a change of magnitudes or of signed values, whichever the presses match
    /// better (the larger sum of the fitted presses' z²). An error if a press's Δv has another
    /// length than the sensor's measurements; a press whose Δv looks like no press is one of
    /// [`PressFeatures::unlike`].
    pub fn fit(sensor: &NominalSensor, presses: &[LabelledPress]) -> Result<PressFeatures, LearnError> {
        let m = sensor.measurements();
        if let Some((i, p)) = presses.iter().enumerate().find(|(_, p)| p.inputs.len() != m) {
            return Err(LearnError::Channels { press: i + 1, expected: m, got: p.inputs.len() });
        }
        let inputs: Vec<Vec<f64>> = presses.iter().map(|p| p.inputs.clone()).collect();
        let standardiser = Standardiser::fit(&inputs);
        let mut used = vec![false; m];
        standardiser.used().iter().for_each(|&c| used[c] = true);
        let largest = sensor.background.iter().fold(0.0, |a: f64, v| a.max(v.abs()));
        let noise: Vec<f64> = sensor.background.iter().map(|v| v.abs().max(NOISE_FLOOR * largest)).collect();
        let locator = Locator::new(sensor.press.masked(&used).whitened(&noise));
        let dead = standardiser.dead();
        let weights = |magnitudes: bool| -> Vec<f64> {
            let channels = sensor.background.iter().zip(&noise).zip(&used);
            channels
                .map(|((v, n), &u)| match (u, magnitudes) {
                    (false, _) => 0.0,
                    (true, true) => v.signum() / n,
                    (true, false) => 1.0 / n,
                })
                .collect()
        };
        let conventions = if sensor.background.iter().any(|v| *v < 0.0) { vec![false, true] } else { vec![false] };
        let mut best: Option<(f64, PressFeatures)> = None;
        for magnitudes in conventions {
            let features = PressFeatures {
                locator: locator.clone(),
                weights: weights(magnitudes),
                magnitudes,
                dead: dead.clone(),
            };
            let mut scratch = FeatureScratch::default();
            let mut evidence = 0.0;
            for p in presses {
                evidence += features.fit_into(&p.inputs, &mut scratch).map_or(0.0, |f| f.z * f.z);
            }
            if best.as_ref().is_none_or(|(b, _)| evidence > *b) {
                best = Some((evidence, features));
            }
        }
        best.map(|(_, features)| features).ok_or(LearnError::NoChannels)
    }

    /// The presses (0-based) whose Δv looks like no press on the sensor as specified: no
    /// features to give them (a real skin's weak or failed presses).
    pub fn unlike(&self, presses: &[LabelledPress]) -> Vec<usize> {
        let (mut scratch, mut out) = (FeatureScratch::default(), Vec::new());
        (0..presses.len()).filter(|&i| !self.features_into(&presses[i].inputs, &mut scratch, &mut out)).collect()
    }

    /// The channels left out as constant over the training presses (0-based).
    pub fn dead(&self) -> &[usize] {
        &self.dead
    }

    /// Channels a Δv must have.
    pub fn channels(&self) -> usize {
        self.weights.len()
    }

    /// The fitted press of `dv`.
    fn fit_into(&self, dv: &[f64], scratch: &mut FeatureScratch) -> Option<PressFit> {
        if dv.len() != self.weights.len() {
            return None;
        }
        scratch.weighted.clear();
        scratch.weighted.extend(dv.iter().zip(&self.weights).map(|(v, w)| if *w == 0.0 { 0.0 } else { v * w }));
        self.locator.locate_into(&scratch.weighted, &mut scratch.press)
    }

    /// The press fitted to `dv`; `None` where `dv` looks like no press (no fit, or a contrast
    /// that is not a drop).
    pub fn press_into(&self, dv: &[f64], scratch: &mut FeatureScratch) -> Option<PressFit> {
        self.fit_into(dv, scratch).filter(|fit| fit.contrast > 0.0)
    }

    /// The features of a fitted press into `out` (cleared): its x and y (m) and the log of its
    /// contrast.
    pub fn of_press_into(fit: &PressFit, out: &mut Vec<f64>) {
        out.clear();
        out.extend([fit.centre[0], fit.centre[1], fit.contrast.ln()]);
    }

    /// The features of `dv` into `out` (cleared): [`PressFeatures::of_press_into`] of
    /// [`PressFeatures::press_into`]; false (and `out` empty) where `dv` looks like no press.
    /// Allocates nothing once `scratch` and `out` have grown.
    pub fn features_into(&self, dv: &[f64], scratch: &mut FeatureScratch, out: &mut Vec<f64>) -> bool {
        out.clear();
        match self.press_into(dv, scratch) {
            Some(fit) => {
                PressFeatures::of_press_into(&fit, out);
                true
            }
            None => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::imperfect::{ImperfectSkin, Imperfections};

    /// Whether a board sends magnitudes or signed values is read from its presses (on a protocol
    /// whose background has both signs), and a Δv like no press is named.
    #[test]
    fn magnitudes_are_told_from_signed_values_by_the_presses() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 1500;
        spec.protocol = crate::ProtocolSpec::Opposite;
        let sensor = NominalSensor::of_spec(&spec, None).unwrap();
        assert!(sensor.background.iter().any(|v| *v < 0.0) && sensor.background.iter().any(|v| *v > 0.0));
        for magnitudes in [false, true] {
            let imperfections = Imperfections { magnitudes, frames_per_press: 8, ..Imperfections::default() };
            let mut skin = ImperfectSkin::new(&spec, &imperfections, 3).unwrap();
            let mut presses = skin.robot_presses(20, 0.07, 4.0..16.0).unwrap();
            assert_eq!(PressFeatures::fit(&sensor, &presses).unwrap().magnitudes, magnitudes);
            // A measurement that is 0 without a press still has its noise: finite features.
            let mut background = sensor.background.clone();
            background[5] = 0.0;
            let zero = NominalSensor::new(sensor.press.clone(), background).unwrap();
            let features = PressFeatures::fit(&zero, &presses).unwrap();
            let mut out = Vec::new();
            assert!(features.features_into(&presses[1].inputs, &mut FeatureScratch::default(), &mut out));
            assert!(out.iter().all(|v| v.is_finite()), "{out:?}");
            presses[7].inputs.fill(0.0);
            assert_eq!(PressFeatures::fit(&sensor, &presses).unwrap().unlike(&presses), vec![7]);
        }
    }
}
