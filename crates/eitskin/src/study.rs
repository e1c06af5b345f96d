//! The paper's study rerun on the virtual sensor (its sections 2.1 and 3.3), with every force
//! method side by side on the same validation presses.
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
//!    the same 475 presses: a finer n×n division; the continuous calibration, where the
//!    forward model supplies the sensitivity S(x) (the reconstructed peak of a reference
//!    inclusion, mapped over the sheet at setup) and one curve is fitted to peak ÷ S(centre);
//!    and the contrast map, its extension to the image's nonlinearity: at every map point the
//!    forward model gives the peak for a ladder of conductivity drops, a touch's peak is read
//!    back as the drop d̂ that explains it at its centre, and one curve d̂(F) is fitted; read
//!    from the touch's peak, from its volume (less noisy, smoother over the mesh), and from the
//!    mean of the two.

use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

use crate::calibration::{force_errors, Calibration, Curve, ForceErrors, Sample};
use crate::conductivity::Inclusion;
use crate::inverse::{Reconstructor, ReconstructorParams};
use crate::press_fit::{PressFit, PressModel, PressModelParams, PressScratch};
use crate::pseudo_array::PseudoArray;
use crate::sensitivity::{along_x, peaks, strongest_touches};
use crate::sim::{Press, SimParams, VirtualSensor};
use crate::spec::{SensorSpec, SpecError};
use crate::touch::{detect_into, Touch, TouchParams, TouchScratch};

/// How to run the study; `Default` is the paper's design.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StudyParams {
    /// The virtual sensor's settings (noise, press model, its finer mesh).
    pub sim: SimParams,
    /// Seed of the noise and of the validation positions and forces.
    pub seed: u64,
    /// Noisy frames per calibration press (15 in the paper).
    pub repeats: usize,
    /// Validation presses (475 in the paper).
    pub validation: usize,
    /// Units per side of the faithful pseudo-array (5 in the paper).
    pub grid: usize,
    /// Units per side of the finer division (10).
    pub fine_grid: usize,
    /// Positions per side of the continuous calibration's sensitivity map.
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
            sensitivity_map: 41,
            max_force: 16.0,
        }
    }
}

/// One force method's calibration and its validation.
#[derive(Debug, Clone, PartialEq)]
pub struct MethodResult {
    /// Its name, e.g. "pseudo-array 5×5".
    pub name: String,
    /// The fitted curves (one per area; one for the continuous method).
    pub curves: Vec<Curve>,
    /// Calibration samples used.
    pub calibration_samples: usize,
    /// Predicted force per validation press, in N (NaN where no touch was found).
    pub predicted: Vec<f64>,
    /// Errors against the true forces, over the presses that gave a touch.
    pub errors: ForceErrors,
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
    /// The calibration samples of the faithful pseudo-array (units of its grid).
    pub calibration: Vec<StudySample>,
}

/// Progress: a stage name, work done, work in all.
pub type Progress<'a> = &'a mut dyn FnMut(&str, usize, usize);

/// The paper's force ranges by area (its numbering from 1): 15, 15, 12, 15, 11, 9 N; areas
/// past the sixth (finer divisions) take the range of the 5×5 area their unit centre lies in.
const PAPER_RANGES: [f64; 6] = [15.0, 15.0, 12.0, 15.0, 11.0, 9.0];

/// Runs the whole study on `spec`'s sensor.
pub fn run(spec: &SensorSpec, params: &StudyParams, progress: Progress<'_>) -> Result<StudyReport, SpecError> {
    progress("setting up the sensor and the reconstructor", 0, 1);
    let model = spec.forward_model()?;
    let recon = Reconstructor::new(&model, spec.conductivity, &ReconstructorParams::default())?;
    let mut skin = VirtualSensor::with_params(spec, params.sim, params.seed)?;
    let electrodes = spec.electrode_positions()?;
    let array = PseudoArray::by_symmetry(&spec.outline, &electrodes, [params.grid; 2])?;
    let fine = PseudoArray::by_symmetry(&spec.outline, &electrodes, [params.fine_grid; 2])?;
    let [lo, hi] = spec.outline.bounds();
    let side = hi[0] - lo[0];
    let press_model = PressModel::new(
        &model,
        spec.conductivity,
        &PressModelParams { radius: params.sim.hydrogel.indenter_radius, ..PressModelParams::default() },
    )?;
    let mut chain = Chain::new(&recon, &press_model, &mut skin, params.repeats)?;

    progress("location dependence (Fig. 3c)", 0, 1);
    let (radius, half) = (0.05 * side, 0.5 * spec.conductivity);
    let line = along_x(side / 2.0, 0.05 * side, radius, half, 0.25 * radius);
    let line_peaks = peaks(chain.skin.model(), chain.skin.background(), &recon, &line)?;
    let profile = line.iter().zip(line_peaks).map(|(i, p)| (i.centre, p)).collect();

    progress("per-area curves in simulation (Fig. 4b)", 0, 1);
    let drops: Vec<f64> = (1..=9).map(|k| 0.1 * k as f64).collect();
    let mut simulated_curves = Vec::new();
    let mut simulated_fits = Vec::new();
    for unit in representatives(&array) {
        let centre = array.unit_centre(unit);
        let inclusions: Vec<Inclusion> = drops
            .iter()
            .map(|d| Inclusion { centre, radius: 0.05 * side, conductivity: spec.conductivity * (1.0 - d) })
            .collect();
        let p = peaks(chain.skin.model(), chain.skin.background(), &recon, &inclusions)?;
        simulated_fits.push(Curve::fit(array.area_of(unit), &drops, &p)?);
        simulated_curves.push((drops.clone(), p));
    }

    progress("calibration presses", 0, 1);
    let coarse_samples = chain.calibration(&array, &array, params.repeats, progress)?;
    let fine_samples = chain.calibration(&fine, &array, params.repeats, progress)?;

    progress("validation presses", 0, 1);
    let mut rng = StdRng::seed_from_u64(params.seed ^ 0x5eed);
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
    let (validation_touches, validation_fits) = chain.validation(&validation, progress)?;

    progress("continuous calibration: sensitivity and contrast maps", 0, 1);
    let map = ContrastMap::new(spec, &model, &recon, params.sensitivity_map)?;

    let truth: Vec<f64> = validation.iter().map(|p| p.force).collect();
    let mut methods = Vec::new();
    // Each validation press as (centre, strength) by the image's peak, or by the fitted press.
    let by_peak: Vec<Option<([f64; 2], f64)>> =
        validation_touches.iter().map(|t| t.map(|t| (t.centre, t.peak))).collect();
    let by_fit: Vec<Option<([f64; 2], f64)>> = validation_touches
        .iter()
        .zip(&validation_fits)
        .map(|(t, f)| t.map(|t| (f.map_or(t.centre, |f| f.centre), fitted_drop(*f))))
        .collect();
    for (name, division, samples, fitted) in [
        (format!("pseudo-array {0}×{0}", params.grid), &array, &coarse_samples, false),
        (format!("pseudo-array {0}×{0}", params.fine_grid), &fine, &fine_samples, false),
        (format!("pseudo-array {0}×{0} (fitted press)", params.grid), &array, &coarse_samples, true),
    ] {
        let per_area: Vec<Sample> = samples
            .iter()
            .map(|s| {
                let peak = if fitted { fitted_drop(s.fit) } else { s.peak };
                Sample { area: division.area_of(s.unit), force: s.force, peak }
            })
            .collect();
        let calibration = Calibration::fit(&per_area, division.area_count())?;
        let predicted: Vec<f64> = if fitted { &by_fit } else { &by_peak }
            .iter()
            .map(|r| match r.and_then(|(centre, strength)| division.unit_at(centre).map(|u| (u, strength))) {
                Some((unit, x)) => calibration.force(division.area_of(unit), x).map_or(f64::NAN, |f| f.newtons),
                None => f64::NAN,
            })
            .collect();
        methods.push(method(name, calibration.curves, per_area.len(), predicted, &truth));
    }
    // One curve of a per-position normalised peak against force, for the whole sheet.
    let continuous = |name: &str, normalise: &dyn Fn(f64, f64, [f64; 2]) -> f64| -> Result<MethodResult, SpecError> {
        let forces: Vec<f64> = coarse_samples.iter().map(|s| s.force).collect();
        let values: Vec<f64> = coarse_samples.iter().map(|s| normalise(s.peak, s.volume, s.centre)).collect();
        let curve = Curve::fit(0, &forces, &values)?;
        let predicted = validation_touches
            .iter()
            .map(|t| t.map_or(f64::NAN, |t| curve.force(normalise(t.peak, t.volume, t.centre)).newtons))
            .collect();
        Ok(method(name.into(), vec![curve], forces.len(), predicted, &truth))
    };
    methods.push(continuous("continuous", &|peak, _, at| peak / map.sensitivity(at))?);
    methods.push(continuous("contrast map", &|peak, _, at| map.drop(peak, at, false))?);
    methods.push(continuous("contrast map (volume)", &|_, volume, at| map.drop(volume, at, true))?);
    methods.push(continuous("contrast map (peak and volume)", &|peak, volume, at| {
        0.5 * (map.drop(peak, at, false) + map.drop(volume, at, true))
    })?);
    // The fitted press: its drop is an estimate of the gel's own, the same anywhere, so one curve.
    let forces: Vec<f64> = coarse_samples.iter().map(|s| s.force).collect();
    let drops: Vec<f64> = coarse_samples.iter().map(|s| fitted_drop(s.fit)).collect();
    let curve = Curve::fit(0, &forces, &drops)?;
    let predicted = validation_touches
        .iter()
        .zip(&validation_fits)
        .map(|(t, f)| t.map_or(f64::NAN, |_| curve.force(fitted_drop(*f)).newtons))
        .collect();
    methods.push(method("fitted press".into(), vec![curve], forces.len(), predicted, &truth));

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
        methods,
        calibration: coarse_samples,
    })
}

/// The fitted drop; 0 where a touch was found but nothing in Δv looks like a press.
fn fitted_drop(fit: Option<PressFit>) -> f64 {
    fit.map_or(0.0, |f| f.drop)
}

fn method(name: String, curves: Vec<Curve>, samples: usize, predicted: Vec<f64>, truth: &[f64]) -> MethodResult {
    let (t, p): (Vec<f64>, Vec<f64>) =
        truth.iter().zip(&predicted).filter(|(_, p)| p.is_finite()).map(|(t, p)| (*t, *p)).unzip();
    MethodResult { name, curves, calibration_samples: samples, errors: force_errors(&t, &p), predicted }
}

/// The first unit of each area met when scanning the lower-left block of [`units_block`]
/// (then the rest of the grid, for areas the block misses).
fn representatives(array: &PseudoArray) -> Vec<usize> {
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
fn units_block(array: &PseudoArray, col: usize, row: usize) -> Vec<usize> {
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

/// A calibration sample before it is assigned to an area.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StudySample {
    /// The pressed unit of the division it was taken for (0-based).
    pub unit: usize,
    /// Applied force, in N.
    pub force: f64,
    /// Peak of the strongest touch, in S/m.
    pub peak: f64,
    /// Volume of the strongest touch (change summed over its pixels × pixel area), in S/m·m².
    pub volume: f64,
    /// Centre of gravity of that touch, in m.
    pub centre: [f64; 2],
    /// The press fitted to the frame from that touch, if any.
    pub fit: Option<PressFit>,
}

/// Per validation press: the strongest touch, and the press fitted from it.
type Readings = (Vec<Option<Touch>>, Vec<Option<PressFit>>);

/// The measuring chain: virtual sensor → reference → image → strongest touch.
struct Chain<'a> {
    recon: &'a Reconstructor,
    press_model: &'a PressModel,
    press_scratch: PressScratch,
    fits: Vec<Option<PressFit>>,
    difference: Vec<f64>,
    skin: &'a mut VirtualSensor,
    reference: Vec<f64>,
    image: crate::image::Image,
    scratch: TouchScratch,
    touches: Vec<Touch>,
}

impl<'a> Chain<'a> {
    /// The chain with its reference: the mean of `frames` noisy frames of the untouched sheet.
    fn new(
        recon: &'a Reconstructor,
        press_model: &'a PressModel,
        skin: &'a mut VirtualSensor,
        frames: usize,
    ) -> Result<Chain<'a>, SpecError> {
        skin.release();
        let clean = skin.clean_frame()?;
        let mut reference = vec![0.0; clean.len()];
        for _ in 0..frames.max(1) {
            let mut v = clean.clone();
            skin.add_noise(&mut v);
            reference.iter_mut().zip(&v).for_each(|(r, x)| *r += x / frames.max(1) as f64);
        }
        let image = recon.blank_image();
        let scratch = TouchScratch::new(image.size);
        Ok(Chain {
            recon,
            press_model,
            press_scratch: PressScratch::default(),
            fits: Vec::with_capacity(1),
            difference: vec![0.0; reference.len()],
            skin,
            reference,
            image,
            scratch,
            touches: Vec::with_capacity(16),
        })
    }

    /// The strongest touch in a frame, and the press fitted from it.
    fn strongest(&mut self, frame: &[f64]) -> Result<Option<(Touch, Option<PressFit>)>, SpecError> {
        self.recon.image_into(&self.reference, frame, &mut self.image)?;
        detect_into(&self.image, &TouchParams::default(), &mut self.scratch, &mut self.touches);
        let Some(touch) = self.touches.first().copied() else { return Ok(None) };
        self.difference.iter_mut().zip(frame.iter().zip(&self.reference)).for_each(|(d, (v, r))| *d = v - r);
        self.press_model.fit_into(&self.difference, &[touch.centre], &mut self.press_scratch, &mut self.fits)?;
        Ok(Some((touch, self.fits.first().copied().flatten())))
    }

    /// Presses one unit per area of `division` (the first met in its lower-left 3×3 block) at
    /// 1 N steps up to the paper's range for the area of `paper` holding it, `repeats` frames each.
    fn calibration(
        &mut self,
        division: &PseudoArray,
        paper: &PseudoArray,
        repeats: usize,
        progress: Progress<'_>,
    ) -> Result<Vec<StudySample>, SpecError> {
        let mut cases = Vec::new();
        for unit in representatives(division) {
            let centre = division.unit_centre(unit);
            let range =
                paper.unit_at(centre).map_or(15.0, |u| PAPER_RANGES.get(paper.area_of(u)).copied().unwrap_or(15.0));
            for f in 0..=(range as usize) {
                cases.push((unit, f as f64, centre));
            }
        }
        let presses: Vec<Vec<Press>> =
            cases.iter().map(|&(_, force, position)| vec![Press { position, force }]).collect();
        let frames = self.skin.clean_frames(&presses)?;
        let mut samples = Vec::with_capacity(cases.len() * repeats);
        for (k, (&(unit, force, _), clean)) in cases.iter().zip(&frames).enumerate() {
            progress("calibration presses", k + 1, cases.len());
            for _ in 0..repeats.max(1) {
                let mut v = clean.clone();
                self.skin.add_noise(&mut v);
                if let Some((t, fit)) = self.strongest(&v)? {
                    samples.push(StudySample { unit, force, peak: t.peak, volume: t.volume, centre: t.centre, fit });
                }
            }
        }
        Ok(samples)
    }

    /// One noisy frame per validation press; the strongest touch of each and its fitted press.
    fn validation(&mut self, presses: &[Press], progress: Progress<'_>) -> Result<Readings, SpecError> {
        let cases: Vec<Vec<Press>> = presses.iter().map(|p| vec![*p]).collect();
        let (mut touches, mut fits) = (Vec::with_capacity(presses.len()), Vec::with_capacity(presses.len()));
        for (chunk, batch) in cases.chunks(50).enumerate() {
            let frames = self.skin.clean_frames(batch)?;
            for mut v in frames {
                self.skin.add_noise(&mut v);
                let found = self.strongest(&v)?;
                touches.push(found.map(|(t, _)| t));
                fits.push(found.and_then(|(_, f)| f));
            }
            progress("validation presses", (chunk * 50 + batch.len()).min(presses.len()), presses.len());
        }
        Ok((touches, fits))
    }
}

/// The forward model's view of the sheet for the continuous calibrations: at each point of an
/// n×n grid of touch centres (inset by the indenter's radius), the reconstructed peak of an
/// inclusion of the indenter's size for conductivity drops 0.1, 0.2 … 0.9, simulated on the
/// reconstruction model itself (no knowledge of the virtual sensor); read bilinearly.
struct ContrastMap {
    lo: [f64; 2],
    step: [f64; 2],
    n: usize,
    drops: Vec<f64>,
    /// `peaks[k][j]`: peak (S/m) at grid point j for drop k.
    peaks: Vec<Vec<f64>>,
    /// `volumes[k][j]`: volume (S/m·m²) at grid point j for drop k.
    volumes: Vec<Vec<f64>>,
}

/// The drop whose peak is the sensitivity S(x) of the plain continuous calibration.
const REFERENCE_DROP: usize = 4; // 0.5

/// Fixed-point steps that move map inclusions so their images' centres land on the grid.
const MAP_ITERATIONS: usize = 2;

impl ContrastMap {
    fn new(
        spec: &SensorSpec,
        model: &crate::forward::ForwardModel,
        recon: &Reconstructor,
        n: usize,
    ) -> Result<ContrastMap, SpecError> {
        let n = n.max(2);
        let radius = SimParams::default().hydrogel.indenter_radius;
        let [lo, hi] = spec.outline.bounds();
        let lo = [lo[0] + radius, lo[1] + radius];
        let step = [(hi[0] - radius - lo[0]) / (n - 1) as f64, (hi[1] - radius - lo[1]) / (n - 1) as f64];
        let drops: Vec<f64> = (1..=9).map(|k| 0.1 * k as f64).collect();
        let grid: Vec<[f64; 2]> =
            (0..n * n).map(|k| [lo[0] + (k % n) as f64 * step[0], lo[1] + (k / n) as f64 * step[1]]).collect();
        let at = |centres: &[[f64; 2]], drop: f64| -> Result<Vec<Option<Touch>>, SpecError> {
            let inclusions: Vec<Inclusion> = centres
                .iter()
                .map(|&centre| Inclusion { centre, radius, conductivity: (1.0 - drop) * spec.conductivity })
                .collect();
            strongest_touches(model, spec.conductivity, recon, &inclusions)
        };
        // Touches are looked up by their centre of gravity, which is pulled away from the
        // press near the edges: move each map inclusion until its image's centre of gravity
        // sits on the grid point, so the map is indexed the way it is read.
        let mut centres = grid.clone();
        for _ in 0..MAP_ITERATIONS {
            let touches = at(&centres, drops[REFERENCE_DROP])?;
            for ((c, g), t) in centres.iter_mut().zip(&grid).zip(touches) {
                if let Some(t) = t {
                    for k in 0..2 {
                        c[k] = (c[k] + g[k] - t.centre[k]).clamp(lo[k], hi[k] - radius);
                    }
                }
            }
        }
        let ladder: Vec<Vec<Option<Touch>>> = drops.iter().map(|&d| at(&centres, d)).collect::<Result<_, _>>()?;
        let of = |f: fn(&Touch) -> f64| -> Vec<Vec<f64>> {
            ladder.iter().map(|row| row.iter().map(|t| t.as_ref().map_or(0.0, f)).collect()).collect()
        };
        Ok(ContrastMap { lo, step, n, peaks: of(|t| t.peak), volumes: of(|t| t.volume), drops })
    }

    /// Bilinear weights and grid indices at `p` (m), clamped to the grid.
    fn corners(&self, p: [f64; 2]) -> [(usize, f64); 4] {
        let coord = |k: usize| ((p[k] - self.lo[k]) / self.step[k]).clamp(0.0, (self.n - 1) as f64);
        let (x, y) = (coord(0), coord(1));
        let (i, j) = ((x as usize).min(self.n - 2), (y as usize).min(self.n - 2));
        let (fx, fy) = (x - i as f64, y - j as f64);
        let at = |a: usize, b: usize| b * self.n + a;
        [
            (at(i, j), (1.0 - fx) * (1.0 - fy)),
            (at(i + 1, j), fx * (1.0 - fy)),
            (at(i, j + 1), (1.0 - fx) * fy),
            (at(i + 1, j + 1), fx * fy),
        ]
    }

    /// The peak (S/m), or with `volume` the volume (S/m·m²), of drop number `k` at `p` (m).
    fn strength(&self, k: usize, p: [f64; 2], volume: bool) -> f64 {
        let table = if volume { &self.volumes } else { &self.peaks };
        self.corners(p).iter().map(|&(j, w)| w * table[k][j]).sum()
    }

    /// S(x): the peak of the reference drop at `p`, in S/m.
    fn sensitivity(&self, p: [f64; 2]) -> f64 {
        self.strength(REFERENCE_DROP, p, false)
    }

    /// The drop (fraction of the background) whose peak at `p` is `peak`: piecewise linear
    /// through (0, 0) and the ladder, extended past its ends along the nearest segment.
    fn drop(&self, peak: f64, p: [f64; 2], volume: bool) -> f64 {
        let ladder: Vec<(f64, f64)> = std::iter::once((0.0, 0.0))
            .chain(self.drops.iter().enumerate().map(|(k, &d)| (self.strength(k, p, volume), d)))
            .collect();
        let segment = ladder.windows(2).position(|w| peak <= w[1].0).unwrap_or(ladder.len() - 2);
        let ((p0, d0), (p1, d1)) = (ladder[segment], ladder[segment + 1]);
        if p1 > p0 {
            d0 + (peak - p0) * (d1 - d0) / (p1 - p0)
        } else {
            d0
        }
    }
}
