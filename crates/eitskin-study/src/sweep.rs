//! The study's noise sweep: presses the methods do not assume, one to three at once, from 50
//! to 90 dB of noise, through the frame path a user runs ([`Pipeline`]).
//!
//! Noise is the standard deviation of each value relative to it, in dB below the value:
//! 10^(−dB/20), so 50 dB is 0.32 %, 54 dB 0.2 %, 66 dB 0.05 %, 80 dB 0.01 %. The OpenEIT
//! captures vary 0.3–0.5 % from frame to frame (46–50 dB); the AD5940's converter alone is far
//! quieter (see [`eitskin::sim`]), so 80 dB is a best case of wiring and contact.
//!
//! Presses ([`PressKind`]): the flat 10 mm indenter and saturating law the press model assumes;
//! a smooth, Hertz-like profile whose contact radius grows with force; another force law; and a
//! 15 mm indenter (reported apart: its force is ambiguous for any method calibrated with 10 mm).
//! Each kind is pressed alone, in pairs and in threes, at random places at least 50 mm apart
//! with random forces from 2 to 16 N, simulated on the virtual sensor's own finer mesh.
//!
//! Methods: touches from the image (the paper's 60 % of the frame's peak, tested against the
//! noise) and presses found in Δv by the press model ([`eitskin::press_fit::PressDetection`]),
//! the latter with forces through one curve of the fitted drop, calibrated at each level on
//! single presses of the same kind (a user calibrates their own gel and indenter), except the
//! 15 mm indenter, read through the 10 mm one's calibration. A press is found when a touch lies within [`MATCH_DISTANCE`] of
//! it (each touch matched once, nearest first); touches left over are false, and so is any
//! touch on an untouched frame. Each share found comes with its 95 % interval
//! ([`wilson_interval`]), and each force RMS with its own ([`rms_interval`]) and with its
//! Cramér–Rao bound ([`drop_variance_bounds`] through the calibration's slope, at the noise of
//! Δv: the frame's and its reference's): how close a method comes to what Δv holds (a force read
//! as its posterior's mean over the calibrated range is not unbiased, and can fall below it).
//! Each force's standard deviation is checked too: how often the truth lies within twice it. Each pipeline takes its
//! reference and sees the sheet at rest until the reference has grown to its limit
//! ([`PipelineParams::reference_limit`]), as a user's sheet rests between presses.
//!
//! The levels run at once, one per thread; each draws its own noise, so the numbers do not
//! depend on the thread count.
//!
//! Not for: the paper's design (that is [`super::run`]).

use eitskin::SeededRng;
use rand::{RngExt, SeedableRng};
use rayon::prelude::*;

use super::{Progress, StudyError};
use eitskin::calibration::{Calibration, Curve};
use eitskin::chain::{Chain, LabelledFrame};
use eitskin::inverse::{Reconstructor, ReconstructorParams};
use eitskin::noise::NoiseModel;
use eitskin::pipeline::{Pipeline, PipelineParams};
use eitskin::press_fit::{refine, Disk, PressModel, PressModelParams, RefineParams, RefineScratch, TableUse};
use eitskin::pseudo_array::PseudoArray;
use eitskin::sim::{add_relative_noise, ForceLaw, Hydrogel, Press, Profile, SimParams, VirtualSensor};
use eitskin::spec::SensorSpec;
use eitskin::strength::Strength;
use eitskin::TouchParams;

/// A touch counts for a press within this distance of it, in m.
pub const MATCH_DISTANCE: f64 = 0.02;

/// Presses closer than this to each other are not placed together, in m.
pub const APART: f64 = 0.05;

/// A noise level of the sweep.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Level {
    /// Noise in dB below each value: relative standard deviation 10^(−dB/20).
    pub db: f64,
    /// Frames averaged into each frame imaged.
    pub average: usize,
}

impl Level {
    /// The relative standard deviation per value (dimensionless).
    pub fn relative(&self) -> f64 {
        10f64.powf(-self.db / 20.0)
    }
}

/// A kind of press, by the gel and indenter that make it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PressKind {
    /// Its name in the report.
    pub name: &'static str,
    /// The gel and indenter.
    pub hydrogel: Hydrogel,
}

/// The kinds pressed: the model's first.
pub fn press_kinds() -> Vec<PressKind> {
    let model = Hydrogel::default();
    vec![
        PressKind { name: "flat 10 mm (the model's)", hydrogel: model },
        PressKind {
            name: "Hertz-like, contact 10 mm at 8 N",
            hydrogel: Hydrogel { profile: Profile::Hertz { reference_force: 8.0 }, ..model },
        },
        PressKind { name: "another force law", hydrogel: Hydrogel { law: ForceLaw::Hyperbolic, ..model } },
        PressKind { name: "flat 15 mm indenter", hydrogel: Hydrogel { indenter_radius: 0.015, ..model } },
    ]
}

/// Settings of the sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepParams {
    /// Noise levels.
    pub levels: Vec<Level>,
    /// Frames with one, two and three presses, per kind.
    pub scenes: [usize; 3],
    /// Untouched frames per level, for the false touches.
    pub untouched: usize,
    /// Calibration presses (of the model's kind) per level.
    pub calibration: usize,
    /// Frames in each reference, counted in frames imaged (×`average` frames taken).
    pub reference_frames: usize,
    /// False touches per frame without one that the noise tests allow.
    pub false_alarm_rate: f64,
    /// Seed of the places, forces and noise.
    pub seed: u64,
}

impl Default for SweepParams {
    fn default() -> Self {
        let level = |db, average| Level { db, average };
        SweepParams {
            levels: vec![
                level(50.0, 1),
                level(54.0, 1),
                level(54.0, 16),
                level(60.0, 1),
                level(66.0, 1),
                level(70.0, 1),
                level(80.0, 1),
                level(90.0, 1),
            ],
            scenes: [300; 3],
            untouched: 10_000,
            calibration: 60,
            reference_frames: 10,
            false_alarm_rate: 1e-3,
            seed: 7,
        }
    }
}

/// What one method did on one kind of scene at one level.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepRow {
    /// The level.
    pub level: Level,
    /// The kind of press (empty for untouched frames).
    pub kind: &'static str,
    /// Presses per frame (0: untouched frames).
    pub presses: usize,
    /// The method: `image` or `presses in Δv`.
    pub method: &'static str,
    /// Frames.
    pub frames: usize,
    /// Share of the presses found (NaN for untouched frames).
    pub detection: f64,
    /// The 95 % interval of that share (Wilson's score interval of a binomial; NaN for
    /// untouched frames): how well so many presses pin it down.
    pub detection_interval: [f64; 2],
    /// Touches that matched no press, per 1,000 frames.
    pub false_per_1000: f64,
    /// Mean distance of a found press's touch from it, in m (NaN if none found).
    pub position_error: f64,
    /// RMS force error of the found presses, in N (NaN without forces).
    pub force_rms: f64,
    /// The 95 % interval of that RMS ([`rms_interval`] over the frames; NaN without forces):
    /// how well so many presses pin it down.
    pub force_rms_interval: [f64; 2],
    /// Share of the forces with a standard deviation whose error is within twice it (about
    /// 95 % if the standard deviations are honest; NaN without any).
    pub force_within_two_std: f64,
    /// The Cramér–Rao bound on that RMS over the scenes' presses: what no unbiased estimate of
    /// the press model's drop from Δv, read through the same curve, can beat (from
    /// [`drop_variance_bounds`] and the curve's slope at each press's force), in N; NaN for the
    /// image, or without exact responses.
    pub force_rms_bound: f64,
}

/// Everything the sweep measured.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepReport {
    /// One row per level, kind, press count and method.
    pub rows: Vec<SweepRow>,
    /// The largest force the calibration and scenes use, in N.
    pub max_force: f64,
}

/// Forces of the scenes and the calibration, in N.
const FORCES: [f64; 2] = [2.0, 16.0];

/// Runs the sweep on `spec`'s sensor.
pub fn run(spec: &SensorSpec, params: &SweepParams, progress: Progress<'_>) -> Result<SweepReport, StudyError> {
    progress("sweep: setting up", 0, 1);
    let model = spec.forward_model()?;
    let recon = Reconstructor::new(&model, spec.conductivity, &ReconstructorParams::default())?;
    // As `eitskin run` fits presses (its table's default use).
    let press_model =
        PressModel::new(&model, spec.conductivity, &PressModelParams::default())?.with_table_use(TableUse::DEFAULT)?;
    let array = PseudoArray::of_sensor(spec, [1, 1])?;
    let mut rng = SeededRng::seed_from_u64(params.seed);

    // Clean frames, once: the untouched sheet, calibration presses of the model's kind, scenes.
    let kinds = press_kinds();
    let mut skins = Vec::new();
    for kind in &kinds {
        let sim = SimParams { hydrogel: kind.hydrogel, ..SimParams::default() };
        skins.push(VirtualSensor::with_params(spec, sim, params.seed)?);
    }
    let untouched = skins[0].clean_frame()?;
    let calibration_presses: Vec<Vec<Press>> =
        (0..params.calibration).filter_map(|_| scene(spec, &mut rng, 1)).collect();
    let mut calibration_clean = Vec::new();
    for (kind, skin) in kinds.iter().zip(&skins) {
        let own = kind.hydrogel.indenter_radius == Hydrogel::default().indenter_radius;
        calibration_clean.push(if own { Some(skin.clean_frames(&calibration_presses)?) } else { None });
    }
    let mut scenes = Vec::new();
    let bounds = spec.outline.bounds();
    // Each kind's skin goes once its scenes are made, and with it the update its frames came
    // through (its K₀⁻¹ alone 161 MB on the paper's sensor): one is held at a time.
    for (k, skin) in skins.into_iter().enumerate() {
        for (n, &count) in params.scenes.iter().enumerate() {
            progress("sweep: simulating presses", k * 3 + n, kinds.len() * 3);
            let cases: Vec<Vec<Press>> = (0..count).filter_map(|_| scene(spec, &mut rng, n + 1)).collect();
            let frames = skin.clean_frames(&cases)?;
            let variances: Vec<Vec<f64>> = cases
                .par_iter()
                .zip(&frames)
                .map(|(presses, clean)| {
                    // Noise relative to each value, at 1: the levels scale it.
                    let std: Vec<f64> = clean.iter().map(|v| v.abs()).collect();
                    drop_variance_bounds(&press_model, bounds, &untouched, clean, &std, presses)
                })
                .collect();
            let made = cases.into_iter().zip(frames).zip(variances);
            scenes.extend(made.map(|((presses, clean), drop_variance)| Scene {
                kind: k,
                presses,
                clean,
                drop_variance,
            }));
        }
    }

    // The levels at once, each on its own thread (their noise is drawn per level, so the rows
    // are the same however many threads there are); progress as each level ends.
    let setup = Setup { params, recon: &recon, press_model: &press_model, array: &array, kinds: &kinds };
    let (untouched, calibration_presses) = (&untouched, &calibration_presses);
    let (calibration_clean, scenes) = (&calibration_clean, &scenes[..]);
    let levels = params.levels.len();
    progress("sweep: noise levels", 0, levels);
    let (done, finished) = std::sync::mpsc::channel();
    let per_level = std::thread::scope(|threads| {
        let work = threads.spawn(move || {
            params
                .levels
                .par_iter()
                .enumerate()
                .map_with(done, |done, (l, level)| {
                    let rows = level_rows(&setup, l, level, untouched, calibration_presses, calibration_clean, scenes);
                    let _ = done.send(());
                    rows
                })
                .collect::<Vec<_>>()
        });
        for k in 0..levels {
            if finished.recv().is_err() {
                break;
            }
            progress("sweep: noise levels", k + 1, levels);
        }
        work.join()
    });
    // A level that panicked panics here, as it would have without the threads.
    let per_level = per_level.unwrap_or_else(|panic| std::panic::resume_unwind(panic));
    let mut rows = Vec::new();
    for level in per_level {
        rows.extend(level?);
    }
    Ok(SweepReport { rows, max_force: FORCES[1] })
}

/// A frame of presses: the kind (index into [`press_kinds`]), the presses, the clean frame (V),
/// and per press the Cramér–Rao bound on its fitted drop's variance at a relative noise of 1
/// ([`drop_variance_bounds`]).
struct Scene {
    kind: usize,
    presses: Vec<Press>,
    clean: Vec<f64>,
    drop_variance: Vec<f64>,
}

/// Per press of `presses`, the Cramér–Rao bound on the variance of its drop fitted to Δv (`clean`
/// less the `untouched` frame, V) under independent channel noise of standard deviation `std`
/// (one per value, V; not positive or not finite: the channel is not used): the drop's diagonal
/// entry of (JJᵀ)⁻¹, J the whitened Jacobian of the exact fit (centre and drop of each press,
/// the indenter's radius) at the fit of the noiseless Δv, started at the presses. What no
/// unbiased estimate of the press model's drop can beat, with the other presses' parameters
/// unknown too; NaN without exact responses or where the fit fails. `bounds` is the box the
/// centres stay in (m). For a board, `std` is its measured noise; the sweep passes |clean|
/// (noise relative to each value, at 1) and scales by its levels' variance.
pub fn drop_variance_bounds(
    press_model: &PressModel,
    bounds: [[f64; 2]; 2],
    untouched: &[f64],
    clean: &[f64],
    std: &[f64],
    presses: &[Press],
) -> Vec<f64> {
    let unknown = vec![f64::NAN; presses.len()];
    let Some(exact) = press_model.exact() else { return unknown };
    let dv: Vec<f64> = clean.iter().zip(untouched).map(|(v, u)| v - u).collect();
    let weights: Vec<f64> = std.iter().map(|s| if *s > 0.0 && s.is_finite() { 1.0 / s } else { 0.0 }).collect();
    let radius = press_model.radius();
    let mut disks: Vec<Disk> = presses.iter().map(|p| Disk { centre: p.position, radius, drop: 0.5 }).collect();
    let params = RefineParams { free_radii: 0, radius_range: [radius, radius], bounds, converged_below: 0.0 };
    let mut scratch = RefineScratch::default();
    if refine(exact, &dv, &weights, &mut disks, &params, &mut scratch).is_err() {
        return unknown;
    }
    let mut variances = Vec::new();
    if !scratch.equivalent_drop_variances_into(&disks, radius, &mut variances) {
        return unknown;
    }
    variances
}

/// What every level's rows are made from: the sweep's settings, the chains' parts and the
/// kinds of press.
struct Setup<'a> {
    params: &'a SweepParams,
    recon: &'a Reconstructor,
    press_model: &'a PressModel,
    array: &'a PseudoArray,
    kinds: &'a [PressKind],
}

/// The rows of level `l`: every method on untouched frames and on each kind's scenes,
/// calibrated on `calibration_presses` (their clean frames per kind, or
/// `None` for a kind read through the model's calibration).
fn level_rows(
    setup: &Setup<'_>,
    l: usize,
    level: &Level,
    untouched: &[f64],
    calibration_presses: &[Vec<Press>],
    calibration_clean: &[Option<Vec<Vec<f64>>>],
    scenes: &[Scene],
) -> Result<Vec<SweepRow>, StudyError> {
    let Setup { params, recon, press_model, array, kinds } = *setup;
    let mut rows = Vec::new();
    // The virtual sensor's noise: independent, Gaussian, relative to each value.
    let mut noise_rng = SeededRng::seed_from_u64(params.seed ^ (l as u64 + 1).wrapping_mul(0x9e37_79b9));
    let relative = level.relative();
    let mut noisy = |clean: &[f64]| -> Vec<f64> {
        let mut frame = clean.to_vec();
        add_relative_noise(&mut frame, relative, &mut noise_rng);
        frame
    };
    let pipeline_params = PipelineParams {
        reference_frames: params.reference_frames,
        noise_floor: eitskin::pipeline::NoiseFloor::FalseAlarm { rate: params.false_alarm_rate },
        auto_hyperparameter: true,
        average: level.average,
        // Each frame is a scene of its own: nothing to carry from the last.
        carry_presses: false,
        ..PipelineParams::default()
    };
    // The frames a pipeline starts on: its reference, then the sheet at rest until the reference
    // has grown to its limit (a user's sheet rests between presses).
    // Twice the frames it grows to: averaging, a frame joins only once it has left the average,
    // and a false touch keeps the frames beside it out.
    let resting = 2 * pipeline_params.reference_limit_frames();
    let reference: Vec<Vec<f64>> = (0..resting).map(|_| noisy(untouched)).collect();
    // The press method's calibration: one curve of the fitted drop per kind, from presses of
    // that kind (a user calibrates their own gel and indenter); the 15 mm indenter is read
    // through the 10 mm one's, as a user pressing with another indenter would.
    let mut fitting = Pipeline::new(
        Chain::new(recon.clone(), TouchParams::default()).with_press_model(press_model.clone()),
        pipeline_params,
    );
    for frame in &reference {
        fitting.process(frame)?;
    }
    let mean_reference = fitting.reference().map(<[f64]>::to_vec).unwrap_or_default();
    let mut calibrations: Vec<Calibration> = Vec::new();
    for clean in calibration_clean {
        let Some(clean) = clean else {
            calibrations.push(calibrations[0].clone());
            continue;
        };
        let labelled: Vec<LabelledFrame> = calibration_presses
            .iter()
            .zip(clean)
            .map(|(p, clean)| LabelledFrame {
                position: p[0].position,
                force: p[0].force,
                frame: averaged(&mut noisy, clean, level.average),
            })
            .collect();
        let mut chain = fitting.chain().clone().with_strength(Strength::FittedDrop)?;
        let samples: Vec<_> = chain.samples(&mean_reference, array, &labelled)?.into_iter().flatten().collect();
        calibrations.push(Calibration::fit_strength(&samples, 1, Strength::FittedDrop)?);
    }
    let presses_in_dv = |calibration: Calibration| -> Result<Chain, StudyError> {
        Ok(Chain::new(recon.clone(), TouchParams::default())
            .with_press_model(press_model.clone())
            .with_calibration(array.clone(), calibration)?)
    };
    // Each kind's curve, for the bound on the force RMS: a drop's variance over the curve's
    // slope squared.
    let curves: Vec<Option<Curve>> = calibrations.iter().map(|c| c.curves.first().copied()).collect();
    let image = || Chain::new(recon.clone(), TouchParams::default());
    let mut methods: Vec<(&'static str, Vec<Chain>, bool)> = vec![("image", vec![image(); kinds.len()], false)];
    methods.push(("presses in Δv", calibrations.into_iter().map(presses_in_dv).collect::<Result<_, _>>()?, true));
    for (method, chains, forces) in methods {
        // One pipeline per kind (its own calibration), each from the same resting frames.
        let mut pipelines: Vec<Pipeline> = chains.into_iter().map(|c| Pipeline::new(c, pipeline_params)).collect();
        for pipeline in &mut pipelines {
            for frame in &reference {
                pipeline.process(frame)?;
            }
        }
        // Untouched frames.
        let mut tally = Tally::default();
        for _ in 0..params.untouched {
            let frame = noisy(untouched);
            pipelines[0].process(&frame)?;
            tally.frame(&[], pipelines[0].touches());
        }
        rows.push(tally.row(*level, "", 0, method));
        // Pressed frames, each after `average` frames of its press so the mean holds it alone.
        for (k, (kind, pipeline)) in kinds.iter().zip(&mut pipelines).enumerate() {
            // The noise's variance per value of Δv, relative to it: a frame imaged's (the mean of
            // `average`) and the reference's (the mean of as many frames as it grew to).
            let in_reference = pipeline.noise().map_or(1, NoiseModel::reference_frames);
            let variance = relative * relative * (1.0 / level.average.max(1) as f64 + 1.0 / in_reference as f64);
            for count in 1..=3 {
                let mut tally = Tally::default();
                for scene in scenes.iter().filter(|s| s.kind == k && s.presses.len() == count) {
                    for _ in 0..level.average.max(1) {
                        pipeline.process(&noisy(&scene.clean))?;
                    }
                    tally.frame(&scene.presses, pipeline.touches());
                    if let (true, Some(curve)) = (forces, curves[k]) {
                        tally.bound(&scene.presses, &scene.drop_variance, variance, &curve);
                    }
                }
                rows.push(tally.row(*level, kind.name, count, method));
            }
        }
    }
    Ok(rows)
}

/// The mean of `average` noisy frames of `clean`.
fn averaged(noisy: &mut impl FnMut(&[f64]) -> Vec<f64>, clean: &[f64], average: usize) -> Vec<f64> {
    let n = average.max(1);
    let mut sum = vec![0.0; clean.len()];
    for _ in 0..n {
        sum.iter_mut().zip(noisy(clean)).for_each(|(s, v)| *s += v / n as f64);
    }
    sum
}

/// Draws of a place tried for one scene before it is given up (a sheet too small for it).
const DRAWS: usize = 10_000;

/// `count` presses at random places inside `spec`'s outline, kept 20 mm from its edges and
/// [`APART`] from each other, with random forces from 2 to 16 N; `None` if [`DRAWS`] places
/// were not enough (the sheet is too small for them).
fn scene(spec: &SensorSpec, rng: &mut SeededRng, count: usize) -> Option<Vec<Press>> {
    let [lo, hi] = spec.outline.bounds();
    let margin = 0.02;
    let inside = |p: [f64; 2]| {
        [[margin, 0.0], [-margin, 0.0], [0.0, margin], [0.0, -margin]]
            .iter()
            .all(|d| spec.outline.contains([p[0] + d[0], p[1] + d[1]]))
    };
    let mut presses: Vec<Press> = Vec::with_capacity(count);
    for _ in 0..DRAWS {
        if presses.len() == count {
            break;
        }
        let position = [rng.random_range(lo[0]..hi[0]), rng.random_range(lo[1]..hi[1])];
        let apart = presses.iter().all(|p| (p.position[0] - position[0]).hypot(p.position[1] - position[1]) >= APART);
        if inside(position) && apart {
            presses.push(Press { position, force: rng.random_range(FORCES[0]..FORCES[1]) });
        }
    }
    (presses.len() == count).then_some(presses)
}

/// Running counts of one method on one kind of frame.
#[derive(Debug, Default)]
struct Tally {
    frames: usize,
    presses: usize,
    found: usize,
    false_touches: usize,
    distance: f64,
    /// Per frame with forces, their squared errors' sum (N²) and count: the RMS and its interval.
    force_frames: Vec<(f64, usize)>,
    /// Forces with a standard deviation, and those within twice it of the truth.
    with_std: usize,
    within_two_std: usize,
    /// Per press, the Cramér–Rao bound on its force's variance (N²).
    force_variance_bound: Vec<f64>,
}

impl Tally {
    /// Matches the touches of a frame to its presses, nearest pairs first.
    fn frame(&mut self, presses: &[Press], touches: &[eitskin::chain::TouchForce]) {
        self.frames += 1;
        self.presses += presses.len();
        let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
        for (i, p) in presses.iter().enumerate() {
            for (j, t) in touches.iter().enumerate() {
                let d = (t.touch.centre[0] - p.position[0]).hypot(t.touch.centre[1] - p.position[1]);
                if d <= MATCH_DISTANCE {
                    pairs.push((d, i, j));
                }
            }
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (mut press_used, mut touch_used) = (vec![false; presses.len()], vec![false; touches.len()]);
        let (mut squares, mut forces) = (0.0, 0);
        for (d, i, j) in pairs {
            if press_used[i] || touch_used[j] {
                continue;
            }
            (press_used[i], touch_used[j]) = (true, true);
            self.found += 1;
            self.distance += d;
            if let Some(force) = touches[j].force {
                let error = force.newtons - presses[i].force;
                (squares, forces) = (squares + error * error, forces + 1);
                if let Some(std) = force.std {
                    self.with_std += 1;
                    self.within_two_std += usize::from(error.abs() <= 2.0 * std);
                }
            }
        }
        self.false_touches += touch_used.iter().filter(|u| !**u).count();
        if forces > 0 {
            self.force_frames.push((squares, forces));
        }
    }

    /// Adds the bound on each press's force variance: its drop's at noise `variance` (relative,
    /// per value) over the slope of `curve` at its force, squared.
    fn bound(&mut self, presses: &[Press], drop_variance: &[f64], variance: f64, curve: &Curve) {
        for (press, v) in presses.iter().zip(drop_variance) {
            self.force_variance_bound.push(v * variance / curve.slope(press.force).powi(2));
        }
    }

    fn row(&self, level: Level, kind: &'static str, presses: usize, method: &'static str) -> SweepRow {
        let squares: f64 = self.force_frames.iter().map(|(s, _)| s).sum();
        let forces: usize = self.force_frames.iter().map(|(_, n)| n).sum();
        SweepRow {
            level,
            kind,
            presses,
            method,
            frames: self.frames,
            detection: if self.presses > 0 { self.found as f64 / self.presses as f64 } else { f64::NAN },
            detection_interval: wilson_interval(self.found, self.presses),
            false_per_1000: 1000.0 * self.false_touches as f64 / self.frames.max(1) as f64,
            position_error: if self.found > 0 { self.distance / self.found as f64 } else { f64::NAN },
            force_rms: if forces == 0 { f64::NAN } else { (squares / forces as f64).sqrt() },
            force_rms_interval: rms_interval(&self.force_frames),
            force_within_two_std: if self.with_std > 0 {
                self.within_two_std as f64 / self.with_std as f64
            } else {
                f64::NAN
            },
            force_rms_bound: if self.force_variance_bound.is_empty() {
                f64::NAN
            } else {
                (self.force_variance_bound.iter().sum::<f64>() / self.force_variance_bound.len() as f64).sqrt()
            },
        }
    }
}

/// The normal distribution's 97.5th percentile: a 95 % interval's half-width in its standard
/// deviations.
const Z: f64 = 1.959_963_984_540_054;

/// The 95 % score interval (Wilson's) of a binomial share, `found` of `trials`; NaN for none.
/// Unlike p ± 1.96·√(p(1−p)/n) it stays within [0, 1] and does not shrink to nothing at 0 or 1.
pub fn wilson_interval(found: usize, trials: usize) -> [f64; 2] {
    if trials == 0 {
        return [f64::NAN; 2];
    }
    let (n, p) = (trials as f64, found as f64 / trials as f64);
    let z2 = Z * Z / n;
    let centre = (p + z2 / 2.0) / (1.0 + z2);
    let half = Z / (1.0 + z2) * (p * (1.0 - p) / n + z2 / (4.0 * n)).sqrt();
    [(centre - half).max(0.0), (centre + half).min(1.0)]
}

/// The 95 % interval of an RMS from groups of errors, each given as its squared errors' sum and
/// count (errors within a group may be correlated, as two presses' forces in one frame are); NaN
/// for fewer than two groups, 0 where every error is 0. The mean square R = Σe²/Σn is a ratio of sums over the groups: its
/// standard error by the delta method, s = √(Σ(sᵢ − R·nᵢ)² / (G(G−1))) / n̄ over G groups, and
/// the interval R·e^(±1.96·s/R) (normal in log R, which a few large errors skew less than R),
/// square-rooted. Approximate: where a few presses dominate, it holds the truth less often
/// than 95 % (the test's heavier case).
pub fn rms_interval(groups: &[(f64, usize)]) -> [f64; 2] {
    if groups.len() < 2 {
        return [f64::NAN; 2];
    }
    let g = groups.len() as f64;
    let squares: f64 = groups.iter().map(|(s, _)| s).sum();
    let count = groups.iter().map(|(_, n)| *n as f64).sum::<f64>();
    let ratio = squares / count;
    if ratio == 0.0 {
        return [0.0; 2]; // no error at all
    }
    let mean_count = count / g;
    let spread: f64 = groups.iter().map(|(s, n)| (s - ratio * *n as f64).powi(2)).sum();
    let relative = Z * (spread / (g * (g - 1.0))).sqrt() / mean_count / ratio;
    [(ratio * (-relative).exp()).sqrt(), (ratio * relative.exp()).sqrt()]
}

#[cfg(test)]
mod tests {
    use super::*;
    use eitskin::Outline;

    /// Wilson's interval against values worked by hand: 57 of 60 (0.95) is [0.863, 0.983]; 0 of
    /// 10 is [0, 0.278]; all of 300 is [0.987, 1].
    #[test]
    fn detection_intervals_match_the_score_interval() {
        let close = |got: [f64; 2], want: [f64; 2]| (got[0] - want[0]).abs() < 1e-3 && (got[1] - want[1]).abs() < 1e-3;
        assert!(close(wilson_interval(57, 60), [0.8630, 0.9829]), "{:?}", wilson_interval(57, 60));
        assert!(close(wilson_interval(0, 10), [0.0, 0.2775]), "{:?}", wilson_interval(0, 10));
        assert!(close(wilson_interval(300, 300), [0.9874, 1.0]), "{:?}", wilson_interval(300, 300));
        assert!(wilson_interval(0, 0)[0].is_nan());
    }

    /// The force RMS's interval holds the true RMS about 95 % of the time, errors as the sweep's
    /// pairs have them: 150 frames of two presses whose errors pull against each other
    /// (correlation −0.5), each press with its own spread, log-normal (standard deviation 0.5 in
    /// log, so that a tenth of the presses' spreads are 1.9 times the median or more). Over
    /// 1,000 draws it holds the truth in 93 %; where a few presses dominate (0.8 in log),
    /// in 86 %.
    #[test]
    fn force_rms_intervals_hold_the_true_rms_about_95_percent_of_the_time() {
        use rand_distr::{Distribution, StandardNormal};
        let mut rng = SeededRng::seed_from_u64(5);
        let mut normal = || -> f64 { StandardNormal.sample(&mut rng) };
        let mut held = |spread: f64| {
            let truth = (2.0 * spread * spread).exp().sqrt();
            let draws = 1000;
            let mut held = 0;
            for _ in 0..draws {
                let frames: Vec<(f64, usize)> = (0..150)
                    .map(|_| {
                        let (a, b) = (normal(), normal());
                        let (z1, z2) = (a, -0.5 * a + 0.75f64.sqrt() * b);
                        let (e1, e2) = ((spread * normal()).exp() * z1, (spread * normal()).exp() * z2);
                        (e1 * e1 + e2 * e2, 2)
                    })
                    .collect();
                let [lo, hi] = rms_interval(&frames);
                held += usize::from(lo <= truth && truth <= hi);
            }
            held as f64 / draws as f64
        };
        let (moderate, heavy) = (held(0.5), held(0.8));
        assert!((0.915..0.97).contains(&moderate), "the interval held the true RMS in {moderate}");
        assert!((0.82..0.93).contains(&heavy), "with a few presses dominating, in {heavy}");
        assert!(rms_interval(&[(1.0, 1)])[0].is_nan());
    }

    /// The bound on a press's drop against the spread of its exact fits over 300 noise draws
    /// (0.01 % per value, where the fit is near linear; at 0.1 % the spread is 1.2 × the bound) on
    /// the model's own mesh, where the fit is the model: the two agree within what 300 draws can
    /// tell (±8 % in variance); and a second press, its parameters unknown too, raises the first's
    /// bound (here four times).
    #[test]
    fn drop_bounds_match_the_spread_of_fits_and_grow_with_a_second_press() {
        use eitskin::conductivity::{with_inclusions, Inclusion};
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 1500;
        let model = spec.forward_model().unwrap();
        let press_model = PressModel::new(&model, 1.0, &PressModelParams::default()).unwrap();
        let bounds = spec.outline.bounds();
        let untouched = model.measure(&vec![1.0; model.mesh().triangles().len()]).unwrap();
        let clean = |presses: &[Press]| {
            let disks: Vec<Inclusion> =
                presses.iter().map(|p| Inclusion { centre: p.position, radius: 0.01, conductivity: 0.4 }).collect();
            model.measure(&with_inclusions(model.mesh(), 1.0, &disks)).unwrap()
        };
        let a = Press { position: [0.03, -0.04], force: 8.0 };
        let b = Press { position: [-0.04, 0.03], force: 8.0 };
        let bound = |presses: &[Press]| {
            let frame = clean(presses);
            let std: Vec<f64> = frame.iter().map(|v| v.abs()).collect();
            drop_variance_bounds(&press_model, bounds, &untouched, &frame, &std, presses)[0]
        };
        let (alone, paired) = (bound(&[a]), bound(&[a, b]));
        assert!(paired > alone, "{paired} against {alone} alone");

        let (relative, frame) = (1e-4, clean(&[a]));
        let weights: Vec<f64> = frame.iter().map(|v| 1.0 / (relative * v.abs())).collect();
        let params = RefineParams { free_radii: 0, radius_range: [0.01, 0.01], bounds, converged_below: 0.0 };
        let exact = press_model.exact().unwrap();
        let (mut rng, mut scratch) = (SeededRng::seed_from_u64(4), RefineScratch::default());
        let drops: Vec<f64> = (0..300)
            .map(|_| {
                let mut noisy = frame.clone();
                add_relative_noise(&mut noisy, relative, &mut rng);
                let dv: Vec<f64> = noisy.iter().zip(&untouched).map(|(v, u)| v - u).collect();
                let mut disks = [Disk { centre: a.position, radius: 0.01, drop: 0.6 }];
                refine(exact, &dv, &weights, &mut disks, &params, &mut scratch).unwrap();
                disks[0].drop
            })
            .collect();
        let mean = drops.iter().sum::<f64>() / drops.len() as f64;
        let spread = drops.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / (drops.len() - 1) as f64;
        let ratio = spread / (alone * relative * relative);
        assert!((0.8..1.25).contains(&ratio), "fitted drops' variance {spread} is {ratio} of the bound");
    }

    /// Presses are placed apart and inside; a sheet too small for them gives up, never hangs.
    #[test]
    fn scenes_fit_the_sheet_or_are_given_up() {
        let mut rng = SeededRng::seed_from_u64(1);
        let square = SensorSpec::square_hydrogel();
        let three = scene(&square, &mut rng, 3).unwrap();
        for (i, a) in three.iter().enumerate() {
            assert!(square.outline.contains(a.position) && (FORCES[0]..FORCES[1]).contains(&a.force));
            for b in &three[i + 1..] {
                assert!((a.position[0] - b.position[0]).hypot(a.position[1] - b.position[1]) >= APART);
            }
        }
        let small = SensorSpec { outline: Outline::Circle { radius: 0.04 }, ..square };
        assert!(scene(&small, &mut rng, 1).is_some());
        assert_eq!(scene(&small, &mut rng, 3), None, "three presses 50 mm apart do not fit a 40 mm disk kept 20 mm in");
    }
}
