//! The study's learned calibration: every [`eitskin::learn`] method's learning curve on robot
//! presses of the imperfect virtual skin ([`eitskin::sim::imperfect`]).

use super::Progress;
use super::StudyError;
use eitskin::learn::{learning_curves, LearningCurve, NominalSensor};
use eitskin::sim::imperfect::{disc_radius, ImperfectSkin, Imperfections};
use eitskin::SensorSpec;

/// Robot presses held out of training.
pub const HELD_OUT: usize = 300;

/// The largest force pressed, in N (forces are uniform from 2 N to it).
pub const MAX_FORCE: f64 = 16.0;

/// The learning curves and how the presses were made.
#[derive(Debug, Clone, PartialEq)]
pub struct LearningReport {
    /// Presses trained on at most.
    pub training: usize,
    /// Presses held out.
    pub held_out: usize,
    /// How the skin differs from its spec, the noise and the frames averaged per state.
    pub imperfections: Imperfections,
    /// Every method's curve.
    pub curves: Vec<LearningCurve>,
    /// The largest force pressed, in N.
    pub max_force: f64,
}

/// `training` robot presses (and [`HELD_OUT`] more) of `spec`'s imperfect skin, in a disc over
/// 80 % of the half-width, each state the mean of 32 frames at the default 0.3 % noise, and
/// every method's learning curve on them, press features on the spec's own sensor included;
/// `progress` hears of each stage.
pub fn run(
    spec: &SensorSpec,
    training: usize,
    seed: u64,
    progress: Progress<'_>,
) -> Result<LearningReport, StudyError> {
    progress("learned calibration: the press model", 0, 1);
    let sensor = NominalSensor::of_spec(spec, None)?;
    let imperfections = Imperfections { frames_per_press: 32, ..Imperfections::default() };
    let mut skin = ImperfectSkin::new(spec, &imperfections, seed)?;
    let radius = disc_radius(&spec.outline, 0.8);
    let all = training + HELD_OUT;
    let mut presses = Vec::with_capacity(all);
    for k in 0..all {
        // One at a time: the same presses as all at once (each draws from the skin's stream in turn).
        progress("learned calibration: robot presses", k, all);
        presses.extend(skin.robot_presses(1, radius, 2.0..MAX_FORCE)?);
    }
    let held = presses.split_off(training);
    let curves = learning_curves(&presses, &held, Some(&sensor), progress);
    Ok(LearningReport { training, held_out: HELD_OUT, imperfections, curves, max_force: MAX_FORCE })
}
