//! The study's calibration as users make it: a few places by the paper's protocol, or random
//! robot presses, then presses anywhere else, of a kind the press model does not assume, read
//! through the path `eitskin calibrate` and `evaluate` take ([`eitskin::labelled`]).
//!
//! The sweep ([`super::sweep`]) calibrates on presses drawn from the very generator it then
//! validates on, over the whole sheet. Here, per kind of press and noise level:
//!
//! - **the paper's protocol**: the centres of the six units of the 5×5 pseudo-array that the
//!   study's calibration uses (one per area, in the lower-left 3×3 units), 0–15 N in 1 N
//!   steps, one frame each, a reference that is the mean of [`UsersParams::reference_frames`]
//!   frames at rest (the 0 N frames join it, as `calibrate` takes them);
//! - **robot presses**: [`UsersParams::robot`] presses at random places anywhere on the sheet,
//!   0.5–16 N, one frame each;
//! - **validation**: [`UsersParams::validation`] single presses of 0.5–16 N at random places
//!   outside the calibrated 3×3 units, and [`UsersParams::pairs`] frames of two presses of
//!   2–16 N at least [`PAIR_APART`] apart anywhere;
//! - **methods**: the image's peak on the 5×5 pseudo-array (the paper's), the fitted press's
//!   drop on the 5×5 pseudo-array, on one curve for the whole sheet the fitted drop, the sized
//!   drop (every press's radius fitted), and the one of those two that reads the calibration
//!   presses best at places its curve did not see (`calibrate --strength auto`).
//!
//! Presses are kept [`EDGE_MARGIN`] inside the outline's box. Kinds: a Hertz-like sphere whose
//! contact grows with force (10 mm at 8 N) on the saturating law, and a flat 15 mm indenter on
//! another force law ([`ForceLaw::Hyperbolic`]); neither is the press model's flat 10 mm disk,
//! and each is simulated on the virtual sensor's own finer mesh.
//!
//! Not for: the noise sweep over every press kind (that is [`super::sweep`]).

use eitskin::SeededRng;
use rand::{RngExt, SeedableRng};

use super::{Progress, StudyError};
use eitskin::calibration::{force_errors, Calibration};
use eitskin::chain::{Chain, LabelledFrame, TouchForce};
use eitskin::inverse::{Reconstructor, ReconstructorParams};
use eitskin::labelled::{
    choose_strength, process_labelled, process_scenes, samples, split_references, PRESS_STRENGTHS,
};
use eitskin::pipeline::PipelineParams;
use eitskin::press_fit::{PressModel, PressModelParams, TableUse};
use eitskin::pseudo_array::PseudoArray;
use eitskin::sim::{add_relative_noise, ForceLaw, Hydrogel, Press, Profile, SimParams, VirtualSensor};
use eitskin::spec::SensorSpec;
use eitskin::strength::Strength;
use eitskin::TouchParams;

/// Presses are kept this far inside the outline's box, in m.
pub const EDGE_MARGIN: f64 = 0.012;

/// The two presses of a pair are at least this far apart, in m.
pub const PAIR_APART: f64 = 0.06;

/// The largest force pressed, in N.
pub const MAX_FORCE: f64 = 16.0;

/// The least force a press must have to count towards the share found, in N.
pub const COUNTED_FROM: f64 = 2.0;

/// Settings of the section.
#[derive(Debug, Clone, PartialEq)]
pub struct UsersParams {
    /// Noise levels, relative standard deviation per value.
    pub levels: Vec<f64>,
    /// Single presses validated, per kind.
    pub validation: usize,
    /// Frames of two presses validated, per kind.
    pub pairs: usize,
    /// Random robot presses to calibrate from, per kind.
    pub robot: usize,
    /// Frames at rest the reference is the mean of.
    pub reference_frames: usize,
    /// Seed of places, forces and noise.
    pub seed: u64,
}

impl Default for UsersParams {
    fn default() -> Self {
        UsersParams {
            levels: vec![1e-4, 5e-4, 2e-3],
            validation: 150,
            pairs: 40,
            robot: 300,
            reference_frames: 20,
            seed: 1,
        }
    }
}

/// The kinds pressed: neither is the press model's flat 10 mm disk on the saturating law.
pub fn press_kinds() -> Vec<(&'static str, Hydrogel)> {
    let model = Hydrogel::default();
    vec![
        ("Hertz-like, contact 10 mm at 8 N", Hydrogel { profile: Profile::Hertz { reference_force: 8.0 }, ..model }),
        ("flat 15 mm, another force law", Hydrogel { indenter_radius: 0.015, law: ForceLaw::Hyperbolic, ..model }),
    ]
}

/// The paper's calibration presses on `array`: the centre of one unit per area (the first met in
/// its lower-left 3×3 units), 0–15 N in 1 N steps.
pub fn paper_protocol(array: &PseudoArray) -> Vec<Press> {
    super::representatives(array)
        .into_iter()
        .flat_map(|unit| (0..=15).map(move |f| (unit, f64::from(f))))
        .map(|(unit, force)| Press { position: array.unit_centre(unit), force })
        .collect()
}

/// A calibration of the virtual sensor of `spec` and `sim` (its gel, indenter and noise; frames
/// drawn with `seed`) made as a user makes one with `calibrate`: the paper's protocol on
/// `array` ([`paper_protocol`], one frame a press), `reference_frames` frames at rest, read by
/// `chain` through the pipeline ([`process_labelled`]); the calibration and the share of its
/// presses found.
pub fn calibrate_virtual(
    spec: &SensorSpec,
    sim: SimParams,
    seed: u64,
    chain: Chain,
    array: &PseudoArray,
    reference_frames: usize,
) -> Result<(Calibration, f64), StudyError> {
    let mut skin = VirtualSensor::with_params(spec, sim, seed)?;
    let rest = skin.clean_frame()?;
    let mut references: Vec<Vec<f64>> = (0..reference_frames.max(1)).map(|_| skin.noisy(&rest)).collect();
    let presses = paper_protocol(array);
    let clean = skin.clean_frames(&presses.iter().map(|p| vec![*p]).collect::<Vec<_>>())?;
    let frames: Vec<LabelledFrame> = presses
        .iter()
        .zip(&clean)
        .map(|(p, c)| LabelledFrame { position: p.position, force: p.force, frame: skin.noisy(c) })
        .collect();
    let (rest, pressed) = split_references(frames);
    references.extend(rest);
    let strength = chain.strength();
    let found = process_labelled(chain, PipelineParams::default(), &references, &pressed)?;
    let share = found.iter().filter(|f| f.is_some()).count() as f64 / found.len().max(1) as f64;
    let calibration = Calibration::fit_strength(&samples(array, &pressed, &found), array.area_count(), strength)?;
    Ok((calibration, share))
}

/// One method, calibrated one way, on one kind at one noise level.
#[derive(Debug, Clone, PartialEq)]
pub struct UsersRow {
    /// The kind of press ([`press_kinds`]).
    pub kind: &'static str,
    /// Noise, relative standard deviation per value.
    pub noise: f64,
    /// How it was calibrated: `"paper's six units"` or `"robot presses"`.
    pub calibrated: &'static str,
    /// The strength its curves take.
    pub strength: Strength,
    /// Whether that strength was chosen among [`PRESS_STRENGTHS`] by how well each reads the
    /// calibration presses at places its curve did not see (`calibrate --strength auto`).
    pub chosen: bool,
    /// Units per side of its pseudo-array.
    pub grid: usize,
    /// Why `calibrate` refused, if it did (then the numbers below are NaN).
    pub refused: Option<String>,
    /// Share of the calibration presses whose press was found.
    pub calibration_found: f64,
    /// Share of single presses of [`COUNTED_FROM`] N and more found.
    pub single_found: f64,
    /// RMS force error of the single presses found, in N.
    pub single_rms: f64,
    /// Share of the found single presses whose truth lies within twice the force's standard
    /// deviation (NaN without standard deviations).
    pub single_within: f64,
    /// Share of the pairs' presses found.
    pub pair_found: f64,
    /// RMS force error of the pairs' presses found, in N.
    pub pair_rms: f64,
    /// Share of the found pairs' presses within twice their standard deviation.
    pub pair_within: f64,
}

/// What the section found, and the frames of each kind and level (for `calibrate` and
/// `evaluate` to reproduce it).
#[derive(Debug, Clone)]
pub struct UsersReport {
    /// One row per kind, level, calibration and method.
    pub rows: Vec<UsersRow>,
    /// Per kind and level, in row order: its frames.
    pub frames: Vec<UsersFrames>,
}

/// The noisy frames of one kind at one level.
#[derive(Debug, Clone)]
pub struct UsersFrames {
    /// The kind of press.
    pub kind: &'static str,
    /// Noise, relative standard deviation per value.
    pub noise: f64,
    /// Frames at rest.
    pub rest: Vec<Vec<f64>>,
    /// The paper's protocol (0 N frames included).
    pub paper: Vec<LabelledFrame>,
    /// Random robot presses.
    pub robot: Vec<LabelledFrame>,
    /// Single presses validated.
    pub validation: Vec<LabelledFrame>,
    /// Frames of two presses: the presses and the frame.
    pub pairs: Vec<(Vec<Press>, Vec<f64>)>,
}

/// Runs the section on `spec`'s sensor.
pub fn run(spec: &SensorSpec, params: &UsersParams, progress: Progress<'_>) -> Result<UsersReport, StudyError> {
    progress("as users calibrate: setting up", 0, 1);
    let model = spec.forward_model()?;
    let recon = Reconstructor::new(&model, spec.conductivity, &ReconstructorParams::default())?;
    // As `eitskin run` fits presses (its table's default use).
    let press_model =
        PressModel::new(&model, spec.conductivity, &PressModelParams::default())?.with_table_use(TableUse::DEFAULT)?;
    let electrodes = spec.electrode_positions()?;
    let paper_array = PseudoArray::by_symmetry(&spec.outline, &electrodes, [5, 5])?;
    let one = PseudoArray::by_symmetry(&spec.outline, &electrodes, [1, 1])?;
    let mut rng = SeededRng::seed_from_u64(params.seed ^ 0x05e7_5ca1);
    let places = Places::new(spec, &paper_array);
    let paper = paper_protocol(&paper_array);
    let robot: Vec<Press> =
        (0..params.robot).map(|_| Press { position: places.anywhere(&mut rng), force: force(&mut rng, 0.5) }).collect();
    let validation: Vec<Press> = (0..params.validation)
        .map(|_| Press { position: places.elsewhere(&mut rng), force: force(&mut rng, 0.5) })
        .collect();
    let pairs: Vec<Vec<Press>> = (0..params.pairs).map(|_| places.pair(&mut rng)).collect();

    let kinds = press_kinds();
    let methods: [(&[Strength], &PseudoArray); 5] = [
        (&[Strength::Peak], &paper_array),
        (&[Strength::FittedDrop], &paper_array),
        (&[Strength::FittedDrop], &one),
        (&[Strength::SizedDrop], &one),
        (&PRESS_STRENGTHS, &one),
    ];
    let mut report = UsersReport { rows: Vec::new(), frames: Vec::new() };
    let steps = kinds.len() * (1 + params.levels.len());
    for (k, (name, hydrogel)) in kinds.iter().enumerate() {
        progress("as users calibrate", k * (1 + params.levels.len()), steps);
        let skin =
            VirtualSensor::with_params(spec, SimParams { hydrogel: *hydrogel, ..SimParams::default() }, params.seed)?;
        let single = |presses: &[Press]| presses.iter().map(|p| vec![*p]).collect::<Vec<_>>();
        let rest = skin.clean_frame()?;
        let clean_paper = skin.clean_frames(&single(&paper))?;
        let clean_robot = skin.clean_frames(&single(&robot))?;
        let clean_validation = skin.clean_frames(&single(&validation))?;
        let clean_pairs = skin.clean_frames(&pairs)?;
        for (l, &noise) in params.levels.iter().enumerate() {
            let mut noise_rng =
                SeededRng::seed_from_u64(params.seed ^ ((k * 16 + l) as u64 + 1).wrapping_mul(0x9e37_79b9));
            let mut noisy = |clean: &[f64]| {
                let mut frame = clean.to_vec();
                add_relative_noise(&mut frame, noise, &mut noise_rng);
                frame
            };
            let labelled = |noisy: &mut dyn FnMut(&[f64]) -> Vec<f64>, presses: &[Press], clean: &[Vec<f64>]| {
                let frames = presses.iter().zip(clean);
                frames.map(|(p, c)| LabelledFrame { position: p.position, force: p.force, frame: noisy(c) }).collect()
            };
            let frames = UsersFrames {
                kind: name,
                noise,
                rest: (0..params.reference_frames).map(|_| noisy(&rest)).collect(),
                paper: labelled(&mut noisy, &paper, &clean_paper),
                robot: labelled(&mut noisy, &robot, &clean_robot),
                validation: labelled(&mut noisy, &validation, &clean_validation),
                pairs: pairs.iter().zip(&clean_pairs).map(|(p, c)| (p.clone(), noisy(c))).collect(),
            };
            for (calibrated, presses) in [("paper's six units", &frames.paper), ("robot presses", &frames.robot)] {
                for (strengths, array) in methods {
                    let mut chain = Chain::new(recon.clone(), TouchParams::default());
                    if strengths.iter().any(|s| s.needs_press_model()) {
                        chain = chain.with_press_model(press_model.clone());
                    }
                    let row = UsersRow {
                        kind: name,
                        noise,
                        calibrated,
                        strength: strengths[0],
                        chosen: strengths.len() > 1,
                        grid: array.grid()[0],
                        ..UsersRow::refused(String::new())
                    };
                    report.rows.push(method_row(row, &chain, strengths, array, &frames, presses)?);
                }
            }
            report.frames.push(frames);
            progress("as users calibrate", k * (1 + params.levels.len()) + l + 2, steps);
        }
    }
    Ok(report)
}

impl UsersRow {
    /// A row whose calibration was refused for `reason`: every number NaN.
    fn refused(reason: String) -> UsersRow {
        UsersRow {
            kind: "",
            noise: f64::NAN,
            calibrated: "",
            strength: Strength::Peak,
            chosen: false,
            grid: 0,
            refused: Some(reason),
            calibration_found: f64::NAN,
            single_found: f64::NAN,
            single_rms: f64::NAN,
            single_within: f64::NAN,
            pair_found: f64::NAN,
            pair_rms: f64::NAN,
            pair_within: f64::NAN,
        }
    }
}

/// `row` filled in: `chain` calibrated on `calibration` (its 0 N frames join the reference) as
/// `calibrate` does, with the best of `strengths` ([`choose_strength`]), then read on the
/// validation frames and pairs as `evaluate` and `run` do.
fn method_row(
    mut row: UsersRow,
    chain: &Chain,
    strengths: &[Strength],
    array: &PseudoArray,
    frames: &UsersFrames,
    calibration: &[LabelledFrame],
) -> Result<UsersRow, StudyError> {
    let (mut references, pressed) = split_references(calibration.to_vec());
    references.splice(0..0, frames.rest.iter().cloned());
    let params = PipelineParams::default();
    let (trials, best) = choose_strength(chain, strengths, params, &references, &pressed, array)?;
    let trial = &trials[best];
    row.strength = trial.strength;
    let samples: Vec<_> = trial.samples.iter().flatten().copied().collect();
    row.calibration_found = samples.len() as f64 / pressed.len().max(1) as f64;
    let calibration = match Calibration::fit_strength(&samples, array.area_count(), row.strength) {
        Ok(c) => c,
        Err(e) => {
            row.refused = Some(e.to_string());
            return Ok(row);
        }
    };
    row.refused = None;
    let chain = chain.clone().with_calibration(array.clone(), calibration)?;
    let found = process_labelled(chain.clone(), params, &frames.rest, &frames.validation)?;
    let forces: Vec<f64> = frames.validation.iter().map(|f| f.force).collect();
    let counted = forces.iter().zip(&found).filter(|(f, _)| **f >= COUNTED_FROM);
    let (counted, counted_found) = counted.fold((0, 0), |(n, k), (_, t)| (n + 1, k + usize::from(t.is_some())));
    row.single_found = counted_found as f64 / counted.max(1) as f64;
    (row.single_rms, row.single_within) = force_figures(&forces, &found);
    let scenes: Vec<(&[f64], Vec<[f64; 2]>)> =
        frames.pairs.iter().map(|(p, frame)| (frame.as_slice(), p.iter().map(|p| p.position).collect())).collect();
    let found: Vec<Option<TouchForce>> =
        process_scenes(chain, params, &frames.rest, &scenes)?.into_iter().flatten().collect();
    let forces: Vec<f64> = frames.pairs.iter().flat_map(|(p, _)| p.iter().map(|p| p.force)).collect();
    row.pair_found = found.iter().filter(|f| f.is_some()).count() as f64 / found.len().max(1) as f64;
    (row.pair_rms, row.pair_within) = force_figures(&forces, &found);
    Ok(row)
}

/// The RMS force error (N) of the presses found with a force, and the share of those with a
/// standard deviation whose truth lies within twice it.
fn force_figures(truth: &[f64], found: &[Option<TouchForce>]) -> (f64, f64) {
    let estimates: Vec<(f64, eitskin::calibration::ForceEstimate)> =
        truth.iter().zip(found).filter_map(|(t, f)| Some((*t, f.as_ref()?.force?))).collect();
    let (t, p): (Vec<f64>, Vec<f64>) = estimates.iter().map(|(t, f)| (*t, f.newtons)).unzip();
    let with_std: Vec<bool> =
        estimates.iter().filter_map(|(t, f)| f.std.map(|s| (f.newtons - t).abs() <= 2.0 * s)).collect();
    let within = with_std.iter().filter(|w| **w).count() as f64 / with_std.len() as f64;
    (force_errors(&t, &p).rms, within)
}

/// A force drawn uniformly from `low` to [`MAX_FORCE`], N.
fn force(rng: &mut SeededRng, low: f64) -> f64 {
    rng.random_range(low..MAX_FORCE)
}

/// Where presses are placed: inside the outline's box by [`EDGE_MARGIN`], and for validation
/// outside the units the paper's protocol calibrates.
struct Places<'a> {
    spec: &'a SensorSpec,
    box_: [[f64; 2]; 2],
    calibrated: Vec<usize>,
    array: &'a PseudoArray,
}

impl<'a> Places<'a> {
    fn new(spec: &'a SensorSpec, array: &'a PseudoArray) -> Places<'a> {
        let [lo, hi] = spec.outline.bounds();
        let box_ = [[lo[0] + EDGE_MARGIN, lo[1] + EDGE_MARGIN], [hi[0] - EDGE_MARGIN, hi[1] - EDGE_MARGIN]];
        Places { spec, box_, calibrated: super::units_block(array, 0, 0), array }
    }

    /// A point on the sheet, at least [`EDGE_MARGIN`] inside its box.
    fn anywhere(&self, rng: &mut SeededRng) -> [f64; 2] {
        let [lo, hi] = self.box_;
        loop {
            let p = [rng.random_range(lo[0]..hi[0]), rng.random_range(lo[1]..hi[1])];
            if self.spec.outline.contains(p) {
                return p;
            }
        }
    }

    /// A point outside the calibrated units.
    fn elsewhere(&self, rng: &mut SeededRng) -> [f64; 2] {
        loop {
            let p = self.anywhere(rng);
            if self.array.unit_at(p).is_some_and(|u| !self.calibrated.contains(&u)) {
                return p;
            }
        }
    }

    /// Two presses of 2–16 N at least [`PAIR_APART`] apart.
    fn pair(&self, rng: &mut SeededRng) -> Vec<Press> {
        let first = self.anywhere(rng);
        loop {
            let second = self.anywhere(rng);
            if (second[0] - first[0]).hypot(second[1] - first[1]) >= PAIR_APART {
                let f = [force(rng, COUNTED_FROM), force(rng, COUNTED_FROM)];
                return vec![Press { position: first, force: f[0] }, Press { position: second, force: f[1] }];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a coarse sensor with few presses: every kind, calibration and method has its row, the
    /// fitted drop is calibrated from the paper's six units and reads presses elsewhere.
    #[test]
    fn every_row_is_made_and_the_fitted_drop_reads_presses_elsewhere() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 1000;
        let params =
            UsersParams { levels: vec![1e-4], validation: 12, pairs: 4, robot: 40, reference_frames: 10, seed: 3 };
        let report = run(&spec, &params, &mut |_, _, _| {}).unwrap();
        assert_eq!(report.rows.len(), 2 * 2 * 5, "kinds × calibrations × methods");
        assert_eq!(report.frames.len(), 2);
        let frames = &report.frames[0];
        assert_eq!(frames.paper.len(), 6 * 16, "six units, 0–15 N");
        assert!(frames.validation.iter().all(|f| f.force >= 0.5 && f.force < MAX_FORCE));
        let one = report
            .rows
            .iter()
            .find(|r| r.calibrated == "paper's six units" && r.strength == Strength::FittedDrop && r.grid == 1)
            .unwrap();
        assert!(one.refused.is_none() && one.single_found > 0.8, "{one:?}");
        assert!(one.single_rms < 0.2 * MAX_FORCE, "{one:?}");
    }
}
