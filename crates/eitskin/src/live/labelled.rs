//! Labelled frames (a press of known place and force, and the frame measured under it) through
//! the frame path a user runs: the [`Pipeline`], frame after frame, as `eitskin run` feeds it.
//!
//! This is how `eitskin calibrate` and `evaluate` read their samples, so that what `evaluate`
//! reports is what `run` gives on the same frames: the reference is the mean of the frames
//! without a press, each channel's noise is measured on them, touches are tested against that
//! noise, presses are found in Δv and fitted together (with a press model), and each force is
//! its posterior's mean with its standard deviation. Frames without a touch join the reference
//! as they do in `run` ([`PipelineParams::reference_limit`]).
//!
//! [`choose_strength`] reads the same presses with several strengths and keeps the one whose
//! curve reads forces best at the places it did not see (`calibrate --strength auto`).
//!
//! Each labelled press is matched to the touch nearest its label within [`MATCH_DISTANCE`]
//! (several presses in one frame each to a touch of its own, [`process_scenes`]); a press with
//! none is *missed* (`None`), to be counted, never dropped unseen.
//!
//! ```
//! use eitskin::chain::{Chain, LabelledFrame};
//! use eitskin::labelled::process_labelled;
//! use eitskin::pipeline::PipelineParams;
//! use eitskin::sim::VirtualSensor;
//! use eitskin::{Reconstructor, ReconstructorParams, SensorSpec, TouchParams};
//! let mut spec = SensorSpec::square_hydrogel();
//! spec.mesh.triangles = 800;
//! let recon = Reconstructor::new(&spec.forward_model()?, 1.0, &ReconstructorParams::default())?;
//! let mut skin = VirtualSensor::new(&spec, 3)?;            // 0.01 % noise on its own mesh
//! let references: Vec<Vec<f64>> = (0..10).map(|_| skin.frame()).collect::<Result<_, _>>()?;
//! skin.press([0.04, -0.03], 10.0);
//! let pressed = LabelledFrame { position: [0.04, -0.03], force: 10.0, frame: skin.frame()? };
//! let chain = Chain::new(recon, TouchParams::default());
//! let found = process_labelled(chain, PipelineParams::default(), &references, &[pressed])?;
//! let [x, y] = found[0].expect("found").touch.centre;     // metres from the centre
//! assert!((x - 0.04).hypot(y + 0.03) < 0.015);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Not for: pressing the sheet (that is [`crate::sim`]) or fitting curves ([`crate::calibration`]).

use thiserror::Error;

use crate::calibration::{Calibration, Sample};
use crate::chain::{Chain, ChainError, LabelledFrame, TouchForce};
use crate::inverse::InverseError;
use crate::pipeline::{Pipeline, PipelineParams};
use crate::pseudo_array::PseudoArray;
use crate::strength::Strength;

/// A touch counts for a labelled press within this distance of the label, in m.
pub const MATCH_DISTANCE: f64 = 0.02;

/// Why labelled frames could not go through the pipeline; frames are numbered from 1.
#[derive(Debug, Error, PartialEq)]
pub enum LabelledError {
    /// No frame without a press to take the reference from.
    #[error("no frame without a press to take the reference from: give reference frames")]
    NoReference,
    /// A reference frame was refused (wrong length, too many channels missing).
    #[error("reference frame {frame}: {reason}")]
    Reference {
        /// 1-based reference frame.
        frame: usize,
        /// Why (said in the message, so not also its source).
        reason: InverseError,
    },
    /// The chain cannot read a strength tried ([`choose_strength`]).
    #[error(transparent)]
    Chain(#[from] ChainError),
    /// A labelled frame was refused.
    #[error("sample {sample}: {reason}")]
    Sample {
        /// 1-based labelled frame.
        sample: usize,
        /// Why (said in the message, so not also its source).
        reason: InverseError,
    },
}

/// Runs `references` (frames without a press, the reference is their mean) and then each of
/// `frames` in order through a [`Pipeline`] of `chain` with `params` (its `reference_frames`
/// set to the references given, `average` to 1 and `carry_presses` off: each frame is a scene of
/// its own, as `run --fresh-presses` reads a stream); per labelled frame, the touch nearest its press within [`MATCH_DISTANCE`], or
/// `None` (missed).
pub fn process_labelled(
    chain: Chain,
    params: PipelineParams,
    references: &[Vec<f64>],
    frames: &[LabelledFrame],
) -> Result<Vec<Option<TouchForce>>, LabelledError> {
    let scenes: Vec<(&[f64], Vec<[f64; 2]>)> = frames.iter().map(|f| (f.frame.as_slice(), vec![f.position])).collect();
    Ok(process_scenes(chain, params, references, &scenes)?.into_iter().map(|mut found| found.remove(0)).collect())
}

/// [`process_labelled`] for frames of one or more presses each: per frame (its values and where
/// its presses were, m), each press's touch, matched nearest first within [`MATCH_DISTANCE`]
/// and each touch once ([`match_presses`]), or `None` (missed).
pub fn process_scenes(
    chain: Chain,
    params: PipelineParams,
    references: &[Vec<f64>],
    scenes: &[(&[f64], Vec<[f64; 2]>)],
) -> Result<Vec<Vec<Option<TouchForce>>>, LabelledError> {
    if references.is_empty() {
        return Err(LabelledError::NoReference);
    }
    let params = PipelineParams { reference_frames: references.len(), average: 1, carry_presses: false, ..params };
    let mut pipeline = Pipeline::new(chain, params);
    for (k, frame) in references.iter().enumerate() {
        pipeline.process(frame).map_err(|reason| LabelledError::Reference { frame: k + 1, reason })?;
    }
    scenes
        .iter()
        .enumerate()
        .map(|(k, (frame, presses))| {
            pipeline.process(frame).map_err(|reason| LabelledError::Sample { sample: k + 1, reason })?;
            Ok(match_presses(pipeline.touches(), presses))
        })
        .collect()
}

/// The calibration samples of labelled frames and what [`process_labelled`] found for them:
/// per press found with a strength, the area of `array` its label lies in, its force and that
/// strength (a press off the array or without a reading gives none).
pub fn samples(array: &PseudoArray, frames: &[LabelledFrame], found: &[Option<TouchForce>]) -> Vec<Sample> {
    frames.iter().zip(found).filter_map(|(labelled, touch)| sample(array, labelled, touch.as_ref())).collect()
}

/// The strengths [`choose_strength`] compares: the press fitted to Δv, read at the indenter's
/// radius where the misfit does not ask for another, or with every radius fitted.
pub const PRESS_STRENGTHS: [Strength; 2] = [Strength::FittedDrop, Strength::SizedDrop];

/// One strength read on labelled presses ([`choose_strength`]).
#[derive(Debug, Clone, PartialEq)]
pub struct StrengthTrial {
    /// The strength.
    pub strength: Strength,
    /// Per pressed frame, its calibration sample (`None`: its press was not found, or read no
    /// strength).
    pub samples: Vec<Option<Sample>>,
    /// The RMS force error (N) of one curve of this strength read at places it did not see
    /// ([`Calibration::held_out_force_rms`]), on the presses every strength tried read; `None`
    /// with fewer than three places.
    pub held_out_rms: Option<f64>,
}

/// Each of `strengths` read by `chain` (it must hold a press model where a strength needs one)
/// on the same labelled presses as [`process_labelled`] reads them, their places on `array`;
/// then each one's force error at places its curve did not see, on the presses all of them
/// read (a strength that misses presses another finds is not scored on fewer, easier ones).
/// Returns the trials and the index of the best (least held-out error; the first where none
/// has one).
pub fn choose_strength(
    chain: &Chain,
    strengths: &[Strength],
    params: PipelineParams,
    references: &[Vec<f64>],
    pressed: &[LabelledFrame],
    array: &PseudoArray,
) -> Result<(Vec<StrengthTrial>, usize), LabelledError> {
    let mut trials = Vec::with_capacity(strengths.len());
    for &strength in strengths {
        let chain = chain.clone().with_strength(strength)?;
        let found = process_labelled(chain, params, references, pressed)?;
        let samples = pressed.iter().zip(&found).map(|(f, t)| sample(array, f, t.as_ref())).collect();
        trials.push(StrengthTrial { strength, samples, held_out_rms: None });
    }
    let common = |trial: &StrengthTrial| -> Vec<Sample> {
        (0..pressed.len())
            .filter(|&k| trials.iter().all(|t| t.samples[k].is_some()))
            .filter_map(|k| trial.samples[k])
            .collect()
    };
    let scores: Vec<Option<f64>> = trials.iter().map(|t| Calibration::held_out_force_rms(&common(t))).collect();
    for (trial, score) in trials.iter_mut().zip(scores) {
        trial.held_out_rms = score;
    }
    let best = (0..trials.len())
        .filter_map(|k| Some((k, trials[k].held_out_rms?)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map_or(0, |(k, _)| k);
    Ok((trials, best))
}

/// The calibration sample of a labelled frame and what was found for it: its label's area on
/// `array`, its force and the touch's strength; `None` without a reading or off the array.
fn sample(array: &PseudoArray, labelled: &LabelledFrame, touch: Option<&TouchForce>) -> Option<Sample> {
    let reading = touch?.reading?;
    let unit = array.unit_at(labelled.position)?;
    Some(Sample::read(array.area_of(unit), labelled.force, labelled.position, reading))
}

/// Splits labelled frames into those without a press (force 0: the sheet at rest, frames for
/// the reference) and the pressed ones, each in its order.
pub fn split_references(frames: Vec<LabelledFrame>) -> (Vec<Vec<f64>>, Vec<LabelledFrame>) {
    let (rest, pressed): (Vec<_>, Vec<_>) = frames.into_iter().partition(|f| f.force == 0.0);
    (rest.into_iter().map(|f| f.frame).collect(), pressed)
}

/// Each press of `presses` (m) with its touch of `touches`: pairs within [`MATCH_DISTANCE`]
/// (a touch's place is its fitted press's centre where it has one), nearest first, each touch
/// and press matched once; `None` for a press no touch is left for.
pub fn match_presses(touches: &[TouchForce], presses: &[[f64; 2]]) -> Vec<Option<TouchForce>> {
    let place = |t: &TouchForce| t.press.map_or(t.touch.centre, |p| p.centre);
    let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
    for (p, at) in presses.iter().enumerate() {
        for (t, touch) in touches.iter().enumerate() {
            let [x, y] = place(touch);
            let distance = (x - at[0]).hypot(y - at[1]);
            if distance <= MATCH_DISTANCE {
                pairs.push((distance, p, t));
            }
        }
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut found = vec![None; presses.len()];
    let mut taken = vec![false; touches.len()];
    for (_, p, t) in pairs {
        if found[p].is_none() && !taken[t] {
            found[p] = Some(touches[t]);
            taken[t] = true;
        }
    }
    found
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::VirtualSensor;
    use crate::{Reconstructor, ReconstructorParams, SensorSpec, TouchParams};

    /// Both press strengths read the same presses; each is scored at places its curve did not
    /// see, the best is the smaller score, and with fewer than three places there is no score
    /// and the first strength is kept.
    #[test]
    fn the_strength_kept_reads_the_places_left_out_best() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 800;
        let model = spec.forward_model().unwrap();
        let recon = Reconstructor::new(&model, 1.0, &ReconstructorParams::default()).unwrap();
        let press = crate::press_fit::PressModel::new(&model, 1.0, &Default::default()).unwrap();
        let chain = Chain::new(recon, TouchParams::default()).with_press_model(press);
        let array = PseudoArray::of_sensor(&spec, [1, 1]).unwrap();
        let mut skin = VirtualSensor::new(&spec, 5).unwrap();
        let references: Vec<Vec<f64>> = (0..10).map(|_| skin.frame().unwrap()).collect();
        let mut pressed = Vec::new();
        for place in [[0.05, 0.05], [-0.04, 0.03], [0.02, -0.06], [-0.05, -0.05]] {
            for force in [3.0, 6.0, 9.0, 12.0] {
                skin.release();
                skin.press(place, force);
                pressed.push(LabelledFrame { position: place, force, frame: skin.frame().unwrap() });
            }
        }
        let params = PipelineParams::default();
        let (trials, best) = choose_strength(&chain, &PRESS_STRENGTHS, params, &references, &pressed, &array).unwrap();
        assert_eq!(trials.iter().map(|t| t.strength).collect::<Vec<_>>(), PRESS_STRENGTHS);
        assert!(trials.iter().all(|t| t.samples.len() == pressed.len() && t.samples.iter().flatten().count() >= 12));
        let scores: Vec<f64> = trials.iter().map(|t| t.held_out_rms.unwrap()).collect();
        assert!(scores.iter().all(|s| s.is_finite() && *s < 3.0), "{scores:?}");
        assert_eq!(best, if scores[1] < scores[0] { 1 } else { 0 }, "{scores:?}");
        let (trials, best) =
            choose_strength(&chain, &PRESS_STRENGTHS, params, &references, &pressed[..8], &array).unwrap();
        assert!(trials.iter().all(|t| t.held_out_rms.is_none()) && best == 0, "two places: {trials:?}");
    }

    /// A press far from its label is missed, not matched; a frame of the wrong length names its sample.
    #[test]
    fn a_press_away_from_its_label_is_missed_and_a_bad_frame_is_named() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 800;
        let recon = Reconstructor::new(&spec.forward_model().unwrap(), 1.0, &ReconstructorParams::default()).unwrap();
        let chain = Chain::new(recon, TouchParams::default());
        let mut skin = VirtualSensor::new(&spec, 4).unwrap();
        let references: Vec<Vec<f64>> = (0..10).map(|_| skin.frame().unwrap()).collect();
        skin.press([0.05, 0.05], 12.0);
        let frame = skin.frame().unwrap();
        let here = LabelledFrame { position: [0.05, 0.05], force: 12.0, frame: frame.clone() };
        let away = LabelledFrame { position: [-0.05, -0.05], force: 12.0, frame };
        let found = process_labelled(chain.clone(), PipelineParams::default(), &references, &[here, away]).unwrap();
        assert!(found[0].is_some() && found[1].is_none(), "{found:?}");
        let short = LabelledFrame { position: [0.0, 0.0], force: 1.0, frame: vec![1.0; 119] };
        let err = process_labelled(chain.clone(), PipelineParams::default(), &references, &[short]).unwrap_err();
        assert_eq!(err.to_string(), "sample 1: a frame has 119 values but the protocol has 120 measurements");
        let err = process_labelled(chain, PipelineParams::default(), &[], &[]).unwrap_err();
        assert_eq!(err, LabelledError::NoReference);
    }
}
