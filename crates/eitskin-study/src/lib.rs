//! # eitskin-study
//!
//! The research around eitskin, built on the runtime library (`eitskin`), never the other way
//! round: the paper's study rerun on the virtual sensor (its sections 2.1 and 3.3), with every
//! force method side by side on the same validation presses; the noise sweep through the frame
//! path ([`sweep`]); calibration as users calibrate ([`users`]); learning curves of the learned
//! calibration ([`learning`]); and the forward model's convergence under refinement
//! ([`convergence`]).
//!
//! ```
//! use eitskin_study::convergence::{observed_order, relative_error};
//! // Differences between levels that halve with each doubling of the triangles (h shrinks by
//! // √2 each time): second order in h.
//! let levels: [&[f64]; 3] = [&[1.4, 2.4], &[1.2, 2.2], &[1.1, 2.1]];
//! let order = observed_order(levels, [1000, 2000, 4000]).unwrap_or(f64::NAN);
//! assert!((order - 2.0).abs() < 1e-9);
//! assert!(relative_error(levels[2], &[1.0, 2.0]) < relative_error(levels[0], &[1.0, 2.0]));
//! ```
//!
//! The study itself:
//!
//! 1. Location dependence (Fig. 3c): an inclusion of radius 5 % of the side at half the
//!    background conductivity, every 5 % of the side along x.
//! 2. Per-area curves in simulation (Fig. 4b): on one unit of each area, the inclusion's
//!    conductivity from 0.9 to 0.1 of the background; the reconstructed peak against the drop,
//!    fitted with the same exponential, with R².
//! 3. The in-silico experiment (section 3.3): calibration presses on one unit per area in the
//!    lower-left 3×3 units, 0–15 N (central areas 1, 2, 4), 0–12 N (area 3), 0–11 N (area 5),
//!    0–9 N (area 6), 1 N steps, 15 noisy frames each (1,245 samples); validation at random
//!    positions anywhere in the lower-right and upper-right 3×3 units with random forces
//!    0–16 N (475 samples).
//! 4. Beyond the pseudo-array, calibrated from presses laid out the same way and validated on
//!    the same 475 presses: a finer n×n division; the pseudo-array on the fitted press's drop;
//!    and one curve for the whole sheet on each strength that is meant to be the same anywhere
//!    (peak ÷ sensitivity, the contrast map's drop from the peak, the volume and both, the
//!    fitted drop; see [`eitskin::strength`] and [`eitskin::contrast_map`]).
//!
//! Every method is a [`ForceMethod`] — a division and a [`Strength`] — and runs through the one
//! [`Chain`]: its samples are the chain's readings of the calibration frames, and its forces
//! the chain's, with the fitted calibration, on the validation frames. `eitskin calibrate` and
//! `evaluate` on the frames the study writes give the same numbers.

#![deny(missing_docs)]
#![warn(rustdoc::broken_intra_doc_links)]
#![cfg_attr(not(test), warn(clippy::unwrap_used, clippy::expect_used))]

pub mod convergence;
pub mod learning;
pub mod sweep;
pub mod users;

use eitskin::SeededRng;
use rand::{RngExt, SeedableRng};
use thiserror::Error;

use eitskin::calibration::{force_errors, Calibration, CalibrationError, Curve, ForceErrors};
use eitskin::chain::{Chain, ChainError, LabelledFrame};
use eitskin::conductivity::Inclusion;
use eitskin::contrast_map::{ContrastMap, ContrastMapParams};
use eitskin::forward::ForwardError;
use eitskin::inverse::mean_of_finite;
use eitskin::inverse::{InverseError, Reconstructor, ReconstructorParams};
use eitskin::labelled::{self, process_labelled, split_references};
use eitskin::pipeline::PipelineParams;
use eitskin::press_fit::{PressFit, PressModel, PressModelParams, TableUse};
use eitskin::pseudo_array::{PseudoArray, PseudoArrayError};
use eitskin::sensitivity::{along_x, peaks};
use eitskin::sim::{Press, SimParams, VirtualSensor};
use eitskin::spec::{SensorSpec, SpecError};
use eitskin::strength::Strength;
use eitskin::touch::{Touch, TouchParams};

/// What stopped the study; each stage keeps its own error as the cause.
#[derive(Debug, Error, PartialEq)]
pub enum StudyError {
    /// The spec does not make a sensor.
    #[error("the sensor spec does not make a sensor")]
    Spec(#[from] SpecError),
    /// The virtual sensor's forward model could not be solved.
    #[error("the virtual sensor could not simulate a frame")]
    Forward(#[from] ForwardError),
    /// A reconstructor, press model or contrast map could not be built, or a frame was refused.
    #[error("the inverse model failed")]
    Inverse(#[from] InverseError),
    /// A press model could not be built.
    #[error("the press model could not be built")]
    PressModel(#[from] eitskin::press_fit::PressModelError),
    /// A pseudo-array could not be made.
    #[error("the pseudo-array could not be made")]
    PseudoArray(#[from] PseudoArrayError),
    /// A calibration could not be fitted.
    #[error("a calibration could not be fitted")]
    Calibration(#[from] CalibrationError),
    /// A chain lacked what a method needs.
    #[error("the frame chain could not be set up")]
    Chain(#[from] ChainError),
    /// Labelled frames could not go through the pipeline.
    #[error("labelled frames could not go through the pipeline")]
    Labelled(#[from] eitskin::labelled::LabelledError),
    /// A calibration could not be learned.
    #[error("a calibration could not be learned")]
    Learn(#[from] eitskin::learn::LearnError),
}

/// How to run the study; `Default` is the paper's design.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StudyParams {
    /// The virtual sensor's settings (noise, press model, its finer mesh).
    pub sim: SimParams,
    /// Seed of the noise and of the validation positions and forces.
    pub seed: u64,
    /// Noisy frames per calibration press (15 in the paper), ≥ 1.
    pub repeats: usize,
    /// Validation presses (475 in the paper).
    pub validation: usize,
    /// Units per side of the faithful pseudo-array (5 in the paper).
    pub grid: usize,
    /// Units per side of the finer division (10).
    pub fine_grid: usize,
    /// Positions per side of the contrast map (the continuous strengths).
    pub sensitivity_map: usize,
    /// Largest validation force, in N (16 in the paper).
    pub max_force: f64,
}

impl Default for StudyParams {
    fn default() -> Self {
        StudyParams {
            sim: SimParams::default(),
            seed: 1,
            repeats: 15,
            validation: 475,
            grid: 5,
            fine_grid: 10,
            sensitivity_map: ContrastMapParams::default().points,
            max_force: 16.0,
        }
    }
}

/// A force method: a division of the sheet into units and areas, and the strength its curves take.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ForceMethod {
    /// Units per side of its pseudo-array (1: one curve for the whole sheet).
    pub grid: usize,
    /// What its curves take as the touch's strength.
    pub strength: Strength,
}

impl ForceMethod {
    /// Its name, e.g. "pseudo-array 5×5, peak" or "one curve, fitted drop".
    pub fn name(&self) -> String {
        match self.grid {
            1 => format!("one curve, {}", self.strength),
            n => format!("pseudo-array {n}×{n}, {}", self.strength),
        }
    }
}

/// One force method's calibration and its validation.
#[derive(Debug, Clone, PartialEq)]
pub struct MethodResult {
    /// The method.
    pub method: ForceMethod,
    /// The fitted curves (one per area).
    pub curves: Vec<Curve>,
    /// Calibration samples used.
    pub calibration_samples: usize,
    /// Predicted force per validation press, in N (NaN where no touch was found).
    pub predicted: Vec<f64>,
    /// Errors against the true forces, over the presses that gave a touch (NaN when refused).
    pub errors: ForceErrors,
    /// Why its calibration was refused, as `calibrate` would say it (then no curves and every
    /// prediction NaN).
    pub refused: Option<String>,
}

/// Everything the study measured.
#[derive(Debug, Clone, PartialEq)]
pub struct StudyReport {
    /// Fig. 3c: inclusion centres along x (m) and the reconstructed peak at each (S/m).
    pub profile: Vec<([f64; 2], f64)>,
    /// Fig. 4b: per area, the conductivity drops (fraction of the background) and the peaks (S/m).
    pub simulated_curves: Vec<(Vec<f64>, Vec<f64>)>,
    /// Fig. 4b: the exponential fitted to each area's simulated curve (x = drop).
    pub simulated_fits: Vec<Curve>,
    /// Validation presses: position (m) and force (N).
    pub validation: Vec<Press>,
    /// The strongest touch of each validation frame, if any.
    pub validation_touches: Vec<Option<Touch>>,
    /// The press fitted to each validation frame from its strongest touch, if any.
    pub validation_fits: Vec<Option<PressFit>>,
    /// Mean distance from touch centre to press centre, in m.
    pub mean_position_error: f64,
    /// Mean distance from fitted press centre to press centre, in m.
    pub mean_fit_position_error: f64,
    /// Share of validation touches placed in the unit of the press (0–1).
    pub right_unit: f64,
    /// The force methods, the faithful pseudo-array first.
    pub methods: Vec<MethodResult>,
    /// The reference frame the paper's touch positions are imaged against (mean of
    /// `reference_frames`), V at 1 A.
    pub reference: Vec<f64>,
    /// The frames at rest (`repeats` noisy frames) each method's pipeline takes its reference
    /// from, with the 0 N calibration frames, V at 1 A.
    pub reference_frames: Vec<Vec<f64>>,
    /// The calibration presses of the faithful pseudo-array, with their noisy frames.
    pub calibration: Vec<LabelledFrame>,
    /// The validation presses with their noisy frames.
    pub validation_frames: Vec<LabelledFrame>,
}

pub use eitskin::Progress;

/// The paper's force ranges by area (its numbering from 1): 15, 15, 12, 15, 11, 9 N; areas
/// past the sixth (finer divisions) take the range of the 5×5 area their unit centre lies in.
const PAPER_RANGES: [f64; 6] = [15.0, 15.0, 12.0, 15.0, 11.0, 9.0];

/// The study's force methods for grids `grid` and `fine`, in report order.
pub fn methods(grid: usize, fine: usize) -> Vec<ForceMethod> {
    let m = |grid, strength| ForceMethod { grid, strength };
    vec![
        m(grid, Strength::Peak),
        m(fine, Strength::Peak),
        m(grid, Strength::FittedDrop),
        m(1, Strength::Sensitivity),
        m(1, Strength::ContrastPeak),
        m(1, Strength::ContrastVolume),
        m(1, Strength::ContrastPeakAndVolume),
        m(1, Strength::FittedDrop),
    ]
}

/// Runs the whole study on `spec`'s sensor.
pub fn run(spec: &SensorSpec, params: &StudyParams, progress: Progress<'_>) -> Result<StudyReport, StudyError> {
    progress("setting up the sensor and the reconstructor", 0, 1);
    let model = spec.forward_model()?;
    let recon = Reconstructor::new(&model, spec.conductivity, &ReconstructorParams::default())?;
    let mut skin = VirtualSensor::with_params(spec, params.sim, params.seed)?;
    let electrodes = spec.electrode_positions()?;
    let division = |n: usize| PseudoArray::by_symmetry(&spec.outline, &electrodes, [n; 2]);
    let array = division(params.grid)?;
    let fine = division(params.fine_grid)?;
    let [lo, hi] = spec.outline.bounds();
    let side = hi[0] - lo[0];
    let radius = params.sim.hydrogel.indenter_radius;
    // As `eitskin run` fits presses (its table's default use).
    let press_model = PressModel::new(&model, spec.conductivity, &PressModelParams { radius, ..Default::default() })?
        .with_table_use(TableUse::DEFAULT)?;
    let reference_frames = rest_frames(&mut skin, params.repeats)?;
    let reference = mean_of_finite(&reference_frames);

    progress("location dependence (Fig. 3c)", 0, 1);
    let (inclusion_radius, half) = (0.05 * side, 0.5 * spec.conductivity);
    let line = along_x(side / 2.0, 0.05 * side, inclusion_radius, half, 0.25 * inclusion_radius);
    let line_peaks = peaks(skin.model(), skin.background(), &recon, &line)?;
    let profile = line.iter().zip(line_peaks).map(|(i, p)| (i.centre, p)).collect();

    progress("per-area curves in simulation (Fig. 4b)", 0, 1);
    let drops: Vec<f64> = (1..=9).map(|k| 0.1 * k as f64).collect();
    let mut simulated_curves = Vec::new();
    let mut simulated_fits = Vec::new();
    for unit in representatives(&array) {
        let centre = array.unit_centre(unit);
        let inclusions: Vec<Inclusion> = drops
            .iter()
            .map(|d| Inclusion { centre, radius: inclusion_radius, conductivity: spec.conductivity * (1.0 - d) })
            .collect();
        let p = peaks(skin.model(), skin.background(), &recon, &inclusions)?;
        simulated_fits.push(Curve::fit(array.area_of(unit), &drops, &p)?);
        simulated_curves.push((drops.clone(), p));
    }

    progress("calibration presses", 0, 1);
    let coarse_frames = calibration_frames(&mut skin, &array, &array, params.repeats, progress)?;
    let fine_frames = calibration_frames(&mut skin, &fine, &array, params.repeats, progress)?;

    progress("validation presses", 0, 1);
    let mut rng = SeededRng::seed_from_u64(params.seed ^ 0x5eed);
    let blocks = [units_block(&array, 2, 0), units_block(&array, 2, params.grid.saturating_sub(3))];
    let validation: Vec<Press> = (0..params.validation)
        .map(|_| {
            let block = &blocks[rng.random_range(0..blocks.len())];
            let unit = block[rng.random_range(0..block.len())];
            let [u_lo, u_hi] = array.unit_bounds(unit);
            let position = [rng.random_range(u_lo[0]..u_hi[0]), rng.random_range(u_lo[1]..u_hi[1])];
            Press { position, force: rng.random_range(0.0..params.max_force) }
        })
        .collect();
    let validation_frames = validation_frames(&mut skin, &validation, progress)?;

    progress("continuous calibration: contrast map", 0, 1);
    let map_params = ContrastMapParams { points: params.sensitivity_map, ..ContrastMapParams::default() };
    let map = ContrastMap::new(&model, spec.conductivity, &recon, spec.outline.bounds(), &map_params)?;
    let base = Chain::new(recon, TouchParams::default()).with_contrast_map(map);
    let mut chain = base.clone().with_press_model(press_model.clone());

    // Where the strongest touch and its fitted press put each validation press.
    let (mut validation_touches, mut validation_fits) = (Vec::new(), Vec::new());
    for frame in &validation_frames {
        let strongest = chain.process(&reference, &frame.frame)?.first();
        validation_touches.push(strongest.map(|t| t.touch));
        validation_fits.push(strongest.and_then(|t| t.press));
    }

    let truth: Vec<f64> = validation.iter().map(|p| p.force).collect();
    let mut results = Vec::new();
    let methods = methods(params.grid, params.fine_grid);
    for (k, &method) in methods.iter().enumerate() {
        progress("force methods", k, methods.len());
        let division = if method.grid == params.grid { array.clone() } else { division(method.grid)? };
        let frames = if method.grid == params.fine_grid { &fine_frames } else { &coarse_frames };
        // As `calibrate` and `evaluate` read them: through the pipeline, the reference the mean
        // of the frames at rest and the 0 N presses, a press model only where the strength reads it.
        let mut chain = base.clone();
        if method.strength.needs_press_model() {
            chain = chain.with_press_model(press_model.clone());
        }
        let chain = chain.with_strength(method.strength)?;
        let (mut references, pressed) = split_references(frames.clone());
        references.splice(0..0, reference_frames.iter().cloned());
        let found = process_labelled(chain.clone(), PipelineParams::default(), &references, &pressed)?;
        let samples = labelled::samples(&division, &pressed, &found);
        let calibration = match Calibration::fit_strength(&samples, division.area_count(), method.strength) {
            Ok(c) => c,
            // A method the frames cannot calibrate is reported so; the others go on.
            Err(e) => {
                let (predicted, errors) = (vec![f64::NAN; truth.len()], force_errors(&[], &[]));
                let (calibration_samples, refused) = (samples.len(), Some(e.to_string()));
                results.push(MethodResult {
                    method,
                    curves: Vec::new(),
                    calibration_samples,
                    predicted,
                    errors,
                    refused,
                });
                continue;
            }
        };
        let curves = calibration.curves.clone();
        let chain = chain.with_calibration(division, calibration)?;
        let found = process_labelled(chain, PipelineParams::default(), &reference_frames, &validation_frames)?;
        let predicted: Vec<f64> =
            found.iter().map(|t| t.and_then(|t| t.force).map_or(f64::NAN, |f| f.newtons)).collect();
        let (t, p): (Vec<f64>, Vec<f64>) =
            truth.iter().zip(&predicted).filter(|(_, p)| p.is_finite()).map(|(t, p)| (*t, *p)).unzip();
        let errors = force_errors(&t, &p);
        let calibration_samples = samples.len();
        results.push(MethodResult { method, curves, calibration_samples, predicted, errors, refused: None });
    }

    let found: Vec<(&Press, &Touch)> =
        validation.iter().zip(&validation_touches).filter_map(|(p, t)| t.as_ref().map(|t| (p, t))).collect();
    let distance = |p: &Press, t: &Touch| (t.centre[0] - p.position[0]).hypot(t.centre[1] - p.position[1]);
    let mean_position_error = found.iter().map(|(p, t)| distance(p, t)).sum::<f64>() / found.len().max(1) as f64;
    let right = found.iter().filter(|(p, t)| array.unit_at(p.position) == array.unit_at(t.centre)).count();
    let right_unit = right as f64 / found.len().max(1) as f64;
    let fitted: Vec<f64> = validation
        .iter()
        .zip(&validation_fits)
        .filter_map(|(p, f)| f.map(|f| (f.centre[0] - p.position[0]).hypot(f.centre[1] - p.position[1])))
        .collect();
    let mean_fit_position_error = fitted.iter().sum::<f64>() / fitted.len().max(1) as f64;
    Ok(StudyReport {
        profile,
        simulated_curves,
        simulated_fits,
        validation,
        validation_touches,
        validation_fits,
        mean_position_error,
        mean_fit_position_error,
        right_unit,
        methods: results,
        reference,
        reference_frames,
        calibration: coarse_frames,
        validation_frames,
    })
}

/// `frames` noisy frames of the untouched sheet.
fn rest_frames(skin: &mut VirtualSensor, frames: usize) -> Result<Vec<Vec<f64>>, ForwardError> {
    skin.release();
    let clean = skin.clean_frame()?;
    Ok((0..frames.max(1)).map(|_| skin.noisy(&clean)).collect())
}

/// Presses one unit per area of `division` (the first met in its lower-left 3×3 block) at its
/// centre, at 1 N steps up to the paper's range for the area of `paper` holding it, `repeats`
/// noisy frames each.
fn calibration_frames(
    skin: &mut VirtualSensor,
    division: &PseudoArray,
    paper: &PseudoArray,
    repeats: usize,
    progress: Progress<'_>,
) -> Result<Vec<LabelledFrame>, ForwardError> {
    let mut cases = Vec::new();
    for unit in representatives(division) {
        let centre = division.unit_centre(unit);
        let range = paper.unit_at(centre).map_or(15.0, |u| PAPER_RANGES.get(paper.area_of(u)).copied().unwrap_or(15.0));
        for f in 0..=(range as usize) {
            cases.push(Press { position: centre, force: f as f64 });
        }
    }
    let presses: Vec<Vec<Press>> = cases.iter().map(|p| vec![*p]).collect();
    let clean = skin.clean_frames(&presses)?;
    let mut frames = Vec::with_capacity(cases.len() * repeats);
    for (k, (press, clean)) in cases.iter().zip(&clean).enumerate() {
        progress("calibration presses", k + 1, cases.len());
        for _ in 0..repeats.max(1) {
            let mut frame = clean.clone();
            skin.add_noise(&mut frame);
            frames.push(LabelledFrame { position: press.position, force: press.force, frame });
        }
    }
    Ok(frames)
}

/// One noisy frame per validation press.
fn validation_frames(
    skin: &mut VirtualSensor,
    presses: &[Press],
    progress: Progress<'_>,
) -> Result<Vec<LabelledFrame>, ForwardError> {
    let mut frames = Vec::with_capacity(presses.len());
    for (chunk, batch) in presses.chunks(50).enumerate() {
        let cases: Vec<Vec<Press>> = batch.iter().map(|p| vec![*p]).collect();
        for (press, mut frame) in batch.iter().zip(skin.clean_frames(&cases)?) {
            skin.add_noise(&mut frame);
            frames.push(LabelledFrame { position: press.position, force: press.force, frame });
        }
        progress("validation presses", (chunk * 50 + batch.len()).min(presses.len()), presses.len());
    }
    Ok(frames)
}

/// The first unit of each area met when scanning the lower-left block of [`units_block`]
/// (then the rest of the grid, for areas the block misses).
pub(crate) fn representatives(array: &PseudoArray) -> Vec<usize> {
    let mut found: Vec<Option<usize>> = vec![None; array.area_count()];
    for unit in units_block(array, 0, 0).into_iter().chain(0..array.unit_count()) {
        let area = array.area_of(unit);
        if found[area].is_none() {
            found[area] = Some(unit);
        }
    }
    found.into_iter().flatten().collect()
}

/// The units of the 3×3 block (of a 5×5 grid; scaled for others) whose bottom-left unit is at
/// column `col`·n/5 … and row `row`·n/5 ….
pub(crate) fn units_block(array: &PseudoArray, col: usize, row: usize) -> Vec<usize> {
    let [nx, ny] = array.grid();
    let span = |n: usize| (3 * n).div_ceil(5);
    let (c0, r0) = (col * nx / 5, row * ny / 5);
    let mut units = Vec::new();
    for r in r0..(r0 + span(ny)).min(ny) {
        for c in c0..(c0 + span(nx)).min(nx) {
            units.push(r * nx + c);
        }
    }
    units
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The whole study on a coarse sensor with few presses: every method runs through the one
    /// chain, and the fitted press's single curve beats the paper's per-area peak. The paper's
    /// 15 frames a press: the pipeline measures the noise on the frames at rest, and with a few
    /// of them its thresholds leave the image's peak without samples in the finer grid's areas.
    #[test]
    fn the_study_runs_every_method_on_a_coarse_sensor() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 2500;
        let params = StudyParams { repeats: 15, validation: 60, sensitivity_map: 11, ..StudyParams::default() };
        let report = run(&spec, &params, &mut |_, _, _| {}).unwrap();
        let expected = methods(5, 10);
        assert_eq!(report.methods.iter().map(|m| m.method).collect::<Vec<_>>(), expected);
        // 6 areas: forces 0–15, 0–15, 0–12, 0–15, 0–11, 0–9 N, 15 frames each.
        assert_eq!(report.calibration.len(), 15 * (16 + 16 + 13 + 16 + 12 + 10));
        assert_eq!(report.validation_frames.len(), 60);
        for m in &report.methods {
            let areas = if m.method.grid == 1 { 1 } else { m.curves.len() };
            assert!(m.curves.len() == areas && m.errors.rms.is_finite(), "{}: {:?}", m.method.name(), m.errors);
            assert!(m.calibration_samples <= report.calibration.len() || m.method.grid == 10);
        }
        let rms = |grid, strength| {
            report.methods.iter().find(|m| m.method == ForceMethod { grid, strength }).unwrap().errors.rms
        };
        let (paper, fitted) = (rms(5, Strength::Peak), rms(1, Strength::FittedDrop));
        assert!(fitted < paper, "fitted drop {fitted} N against the paper's peak {paper} N");
        assert!(report.mean_fit_position_error < report.mean_position_error);
    }
}
