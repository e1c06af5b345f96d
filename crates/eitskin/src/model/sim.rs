//! The virtual sensor: a hydrogel sheet that is pressed, simulated on its own finer mesh (never
//! the reconstruction mesh, so no inverse crime), with measurement noise and slow drift.
//!
//! **Press model.** An indenter of radius r (10 mm: the paper's 20 mm cylinder) pressing with
//! force F lowers the conductivity under it to σ·(1 − d(F)), with the saturating drop
//!
//!   d(F) = d_max·(1 − e^(−F/F₀)),  d_max = 0.9, F₀ = 5.54 N,
//!
//! so 16 N lowers it by 85 % (inside the paper's 0.1–0.9 C₀ range, section 2.1.2) and the
//! response flattens at large forces as the paper's hydrogel does (its Fig. 9, Table 2).
//! Triangles cut by the indenter's rim get the area-weighted value. Presses unlike that, to
//! test methods on what they do not assume: a smooth, Hertz-like [`Profile`] whose contact
//! radius grows with force, another [`ForceLaw`], another indenter radius.
//!
//! **Noise.** Each value gets independent Gaussian noise of standard deviation
//! `noise_relative`·|v_m|; the default 1e-4 (80 dB) is argued from the AD5940's datasheet
//! figures: its 16-bit ADC (98 dB ideal) and the processing gain of its on-chip DFT over
//! thousands of samples put the converter's own noise far below 1e-4, and its 12-bit
//! excitation DAC (74 dB ideal) is cancelled to first order by the ratiometric measurement
//! against the calibration resistor; what is left is the repeatability of the multiplexers,
//! wiring and gel contact, which we take as 0.01 % of each value. The study reports 60–90 dB. **Drift.** The background conductivity falls by `drift_per_hour`
//! (relative) per simulated hour of [`VirtualSensor::advance`], as a dehydrating gel does.
//!
//! Not for: reconstruction (use [`crate::Reconstructor`] on the spec's own mesh).

pub mod imperfect;

use crate::SeededRng;
use rand::Rng;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

use crate::calibration::MAX_FORCE;
use crate::conductivity::{box_distance, mixed, Inclusion};
use crate::forward::{ChangeScratch, ForwardError, ForwardModel, LowRankUpdate, UPDATE_AFTER};
use crate::mesh::TriangleBuckets;
use crate::spec::{SensorSpec, SpecError};

/// How the gel answers a press: the drop d(F) by its [`ForceLaw`], spread under the indenter
/// by its [`Profile`]; `Default` is the flat 10 mm indenter and the saturating law, what the
/// press model assumes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hydrogel {
    /// The largest relative conductivity drop, approached at large force (dimensionless).
    pub max_drop: f64,
    /// Force scale F₀ of the law, in N.
    pub force_scale: f64,
    /// Radius of the indenter, in m.
    pub indenter_radius: f64,
    /// How the drop follows the force.
    pub law: ForceLaw,
    /// How the drop is spread under the indenter.
    pub profile: Profile,
}

/// How a press's conductivity drop follows its force F.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ForceLaw {
    /// d = d_max·(1 − e^(−F/F₀)): saturating, as the paper's gel (its Fig. 9).
    #[default]
    Saturating,
    /// d = d_max·F/(F + F₀): slower to saturate (another gel).
    Hyperbolic,
}

/// How a press's drop is spread under the indenter.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Profile {
    /// Uniform over a disk of the indenter's radius (a flat punch).
    #[default]
    Disk,
    /// A sphere pressed into the gel (Hertz): d(r) = d·√(1 − r²/a²) inside the contact radius
    /// a = r_indenter·(F/`reference_force`)^(1/3), which grows with the force.
    Hertz {
        /// The force at which the contact radius is the indenter's radius, in N.
        reference_force: f64,
    },
}

impl Default for Hydrogel {
    fn default() -> Self {
        Hydrogel {
            max_drop: 0.9,
            force_scale: 5.54,
            indenter_radius: 0.010,
            law: ForceLaw::Saturating,
            profile: Profile::Disk,
        }
    }
}

impl Hydrogel {
    /// The relative conductivity drop under the indenter (at its centre) at `force` (N); 0 for no force.
    pub fn drop(&self, force: f64) -> f64 {
        let f = force.max(0.0);
        match self.law {
            ForceLaw::Saturating => self.max_drop * (1.0 - (-f / self.force_scale).exp()),
            ForceLaw::Hyperbolic => self.max_drop * f / (f + self.force_scale),
        }
    }

    /// The radius over which a press of `force` (N) lowers the conductivity, in m.
    pub fn contact_radius(&self, force: f64) -> f64 {
        match self.profile {
            Profile::Disk => self.indenter_radius,
            Profile::Hertz { reference_force } => self.indenter_radius * (force.max(0.0) / reference_force).cbrt(),
        }
    }

    /// [`Hydrogel::drop`] as a calibration curve of the drop against force up to `max_force`
    /// (N): what a fitted-drop calibration of this gel should find.
    pub fn drop_curve(&self, max_force: f64) -> crate::calibration::Curve {
        let (a, b, c) = (-self.max_drop, self.force_scale, self.max_drop);
        crate::calibration::Curve {
            a,
            b,
            c,
            r_squared: 1.0,
            force_range: [0.0, max_force],
            samples: 0,
            spread: 0.0,
            fallback: false,
            shape: None,
        }
    }
}

/// Adds to each value of `frame` independent Gaussian noise of standard deviation `relative`
/// (dimensionless) times its magnitude: the virtual sensor's measurement noise.
pub fn add_relative_noise(frame: &mut [f64], relative: f64, rng: &mut impl Rng) {
    for v in frame.iter_mut() {
        let n: f64 = StandardNormal.sample(rng);
        *v += relative * v.abs() * n;
    }
}

/// The midpoint of `a` and `b`.
fn mid(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0]
}

/// The drop of press `p` at `q` (m) for the Hertz profile of gel `h`.
fn hertz(h: &Hydrogel, p: &Press, q: [f64; 2]) -> f64 {
    let a = h.contact_radius(p.force);
    let r2 = (q[0] - p.position[0]).powi(2) + (q[1] - p.position[1]).powi(2);
    if a <= 0.0 || r2 >= a * a {
        0.0
    } else {
        h.drop(p.force) * (1.0 - r2 / (a * a)).sqrt()
    }
}

/// One press: where, how hard.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Press {
    /// Centre of the indenter, in m from the outline's centre.
    pub position: [f64; 2],
    /// Force, in N.
    pub force: f64,
}

/// Settings of the virtual sensor; `Default` is what the study uses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimParams {
    /// Its mesh has this many times the spec's triangles.
    pub refine: usize,
    /// The gel's answer to a press.
    pub hydrogel: Hydrogel,
    /// Noise standard deviation relative to each value (dimensionless; 1e-4 is 80 dB).
    pub noise_relative: f64,
    /// Relative fall of the background conductivity per hour of simulated time.
    pub drift_per_hour: f64,
}

impl Default for SimParams {
    fn default() -> Self {
        SimParams { refine: 3, hydrogel: Hydrogel::default(), noise_relative: 1e-4, drift_per_hour: 0.0 }
    }
}

/// A simulated skin: press it, read frames in protocol order (V at 1 A).
#[derive(Debug)]
pub struct VirtualSensor {
    model: ForwardModel,
    /// The background's factorisation and its inverse (whole, or its near part on a large mesh), built
    /// at the first frame with a press: a frame is then a low-rank update of it (`None` if it failed to
    /// build: frames are then solved in full).
    update: std::sync::OnceLock<Option<(LowRankUpdate, TriangleBuckets)>>,
    /// The measurements of the sheet with no press at the spec's conductivity, solved once.
    unpressed: std::sync::OnceLock<Vec<f64>>,
    /// The update's buffers, kept from frame to frame.
    scratch: std::sync::Mutex<FrameScratch>,
    /// Frames [`VirtualSensor::clean_frames`] has been asked for, in all.
    asked: std::sync::atomic::AtomicUsize,
    background: f64,
    params: SimParams,
    presses: Vec<Press>,
    hours: f64,
    rng: SeededRng,
}

impl VirtualSensor {
    /// The sensor of `spec` with the default settings and noise seeded by `seed`.
    pub fn new(spec: &SensorSpec, seed: u64) -> Result<VirtualSensor, SpecError> {
        VirtualSensor::with_params(spec, SimParams::default(), seed)
    }

    /// The sensor of `spec` with `params`, noise seeded by `seed`.
    pub fn with_params(spec: &SensorSpec, params: SimParams, seed: u64) -> Result<VirtualSensor, SpecError> {
        let mut fine = spec.clone();
        fine.mesh.triangles = spec.mesh.triangles * params.refine.max(1);
        fine.mesh.max_element_size = spec.mesh.max_element_size.map(|h| h / (params.refine.max(1) as f64).sqrt());
        let model = fine.forward_model()?;
        Ok(VirtualSensor {
            model,
            update: std::sync::OnceLock::new(),
            unpressed: std::sync::OnceLock::new(),
            scratch: std::sync::Mutex::new(FrameScratch::default()),
            asked: std::sync::atomic::AtomicUsize::new(0),
            background: spec.conductivity,
            params,
            presses: Vec::new(),
            hours: 0.0,
            rng: SeededRng::seed_from_u64(seed),
        })
    }

    /// Its own forward model (the finer mesh).
    pub fn model(&self) -> &ForwardModel {
        &self.model
    }

    /// Adds a press at `position` (m) with `force` (N).
    pub fn press(&mut self, position: [f64; 2], force: f64) {
        self.presses.push(Press { position, force });
    }

    /// Lifts every press.
    pub fn release(&mut self) {
        self.presses.clear();
    }

    /// The presses now on the sheet.
    pub fn presses(&self) -> &[Press] {
        &self.presses
    }

    /// Lets `seconds` of simulated time pass (the background drifts).
    pub fn advance(&mut self, seconds: f64) {
        self.hours += seconds / 3600.0;
    }

    /// The background conductivity now, in S/m.
    pub fn background(&self) -> f64 {
        self.background * (1.0 - self.params.drift_per_hour * self.hours).max(0.05)
    }

    /// The conductivity of each triangle of its mesh now, in S/m.
    pub fn conductivity(&self) -> Vec<f64> {
        self.conductivity_with(&self.presses)
    }

    /// The conductivity of each triangle (S/m) under `presses`, with the background of now.
    pub fn conductivity_with(&self, presses: &[Press]) -> Vec<f64> {
        let (background, inclusions) = (self.background(), self.inclusions(presses));
        (0..self.model.mesh().triangles().len()).map(|t| self.triangle(t, presses, background, &inclusions)).collect()
    }

    /// Flat presses as inclusions of the background's conductivity less their drop (none for
    /// the Hertz-like profile, which [`VirtualSensor::triangle`] evaluates itself).
    fn inclusions(&self, presses: &[Press]) -> Vec<Inclusion> {
        let (background, h) = (self.background(), self.params.hydrogel);
        match h.profile {
            Profile::Disk => presses
                .iter()
                .map(|p| Inclusion {
                    centre: p.position,
                    radius: h.indenter_radius,
                    conductivity: background * (1.0 - h.drop(p.force)),
                })
                .collect(),
            Profile::Hertz { .. } => Vec::new(),
        }
    }

    /// Triangle t's conductivity (S/m) under `presses` over `background`.
    fn triangle(&self, t: usize, presses: &[Press], background: f64, inclusions: &[Inclusion]) -> f64 {
        let (mesh, h) = (self.model.mesh(), self.params.hydrogel);
        let c = mesh.corners(t);
        match h.profile {
            Profile::Disk => mixed(c, mesh.area(t), background, inclusions),
            Profile::Hertz { .. } => {
                // Outside every contact radius the profile is exactly 0.
                if !presses.iter().any(|p| box_distance(p.position, c) < h.contact_radius(p.force)) {
                    return background;
                }
                // The mean of the profile at the centroid and at the midpoints between the
                // centroid and the corners (the triangles are small).
                let g = [(c[0][0] + c[1][0] + c[2][0]) / 3.0, (c[0][1] + c[1][1] + c[2][1]) / 3.0];
                let points = [g, mid(g, c[0]), mid(g, c[1]), mid(g, c[2])];
                let kept: f64 =
                    points.iter().map(|q| presses.iter().map(|p| 1.0 - hertz(&h, p, *q)).product::<f64>()).sum::<f64>()
                        / points.len() as f64;
                background * kept
            }
        }
    }

    /// The noise-free frame now, in V at 1 A.
    ///
    /// Without drift, a frame is the background's measurements plus the exact change of the
    /// triangles the presses reach, by a low-rank update of the one factorisation
    /// ([`LowRankUpdate`]), K₀⁻¹ kept whole (up to [`crate::forward::WHOLE_LIMIT`] unknowns).
    /// Beyond, its near part covers each press of up to 16 N, and presses far apart take column
    /// solves, or a full solve past 64 rows; a change of more than
    /// [`crate::forward::GATHERED_ROWS`] rows is solved in full. With drift the background
    /// itself changes, and the frame is solved in full.
    pub fn clean_frame(&self) -> Result<Vec<f64>, ForwardError> {
        if self.background() != self.background {
            return self.model.measure(&self.conductivity());
        }
        if self.presses.is_empty() {
            if let Some(v) = self.unpressed.get() {
                return Ok(v.clone());
            }
            let v = self.model.measure(&self.conductivity())?;
            return Ok(self.unpressed.get_or_init(|| v).clone());
        }
        let Some((update, buckets)) = self.update.get_or_init(|| self.low_rank_update()) else {
            return self.model.measure(&self.conductivity());
        };
        // A scratch another thread left poisoned is only buffers: take it as it is.
        let mut scratch = self.scratch.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        self.updated(update, buckets, &self.presses, &mut scratch)
    }

    /// The noise-free frame (V at 1 A) under `presses` over the background of the spec, from
    /// the background's measurements by the low-rank update of the triangles they reach.
    fn updated(
        &self,
        update: &LowRankUpdate,
        buckets: &TriangleBuckets,
        presses: &[Press],
        scratch: &mut FrameScratch,
    ) -> Result<Vec<f64>, ForwardError> {
        // Only triangles whose box a press reaches can change: found by the buckets kept.
        let h = self.params.hydrogel;
        let FrameScratch { change, near, seen, generation, candidates, changes } = scratch;
        // A triangle two presses' boxes list (their boxes meet, or share a bucket) is taken
        // once: marked with this frame's generation as it comes.
        seen.resize(self.model.mesh().triangles().len(), 0);
        *generation = generation.wrapping_add(1);
        if *generation == 0 {
            seen.fill(0);
            *generation = 1;
        }
        candidates.clear();
        for p in presses {
            let ([x, y], r) = (p.position, h.contact_radius(p.force));
            buckets.near_once_into([x - r, y - r], [x + r, y + r], near);
            for &t in near.iter() {
                if seen[t] != *generation {
                    seen[t] = *generation;
                    candidates.push(t);
                }
            }
        }
        let inclusions = self.inclusions(presses);
        changes.clear();
        changes.extend(
            candidates
                .iter()
                .map(|&t| (t, self.triangle(t, presses, self.background, &inclusions) - self.background))
                .filter(|(_, d)| *d != 0.0),
        );
        update.measurements_with(changes, change)
    }

    /// The update of the background, keeping K₀⁻¹ whole (up to [`crate::forward::WHOLE_LIMIT`]
    /// unknowns), else between nodes as far apart as the widest press reaches (its contact
    /// radius at 16 N, twice, and the cut triangles' nodes beyond it).
    fn low_rank_update(&self) -> Option<(LowRankUpdate, TriangleBuckets)> {
        let mesh = self.model.mesh();
        let area: f64 = (0..mesh.triangles().len()).map(|t| mesh.area(t)).sum();
        let edge = (2.0 * area / mesh.triangles().len() as f64).sqrt();
        let reach = 2.0 * self.params.hydrogel.contact_radius(16.0) + 4.0 * edge;
        let background = vec![self.background; mesh.triangles().len()];
        Some((LowRankUpdate::whole_or_near(&self.model, &background, reach).ok()?, TriangleBuckets::new(mesh)))
    }

    /// Noise-free frames (V at 1 A) for several sets of presses, in parallel; the presses on the
    /// sheet are left as they are. Each by the update of [`VirtualSensor::clean_frame`] once the
    /// sensor has it, or once it has been asked for [`UPDATE_AFTER`] frames in all, this call's
    /// included (the update's setup costs about as many full solves): the study's thousands of
    /// frames in a fraction of the time, the same to rounding. Before that, and with drift,
    /// each is solved in full.
    pub fn clean_frames(&self, cases: &[Vec<Press>]) -> Result<Vec<Vec<f64>>, ForwardError> {
        use rayon::prelude::*;
        let asked = self.asked.fetch_add(cases.len(), std::sync::atomic::Ordering::Relaxed) + cases.len();
        let worth = self.update.get().is_some() || asked >= UPDATE_AFTER;
        let drifted = self.background() != self.background;
        let update = (worth && !drifted).then(|| self.update.get_or_init(|| self.low_rank_update()).as_ref()).flatten();
        match update {
            Some((update, buckets)) => cases
                .par_iter()
                .map_init(FrameScratch::default, |scratch, presses| self.updated(update, buckets, presses, scratch))
                .collect(),
            _ => cases.par_iter().map(|presses| self.model.measure(&self.conductivity_with(presses))).collect(),
        }
    }

    /// A frame now, with noise, in V at 1 A.
    pub fn frame(&mut self) -> Result<Vec<f64>, ForwardError> {
        let mut v = self.clean_frame()?;
        self.add_noise(&mut v);
        Ok(v)
    }

    /// A copy of the clean frame `clean` with the sensor's measurement noise (for repeated
    /// frames of one press).
    pub fn noisy(&mut self, clean: &[f64]) -> Vec<f64> {
        let mut frame = clean.to_vec();
        self.add_noise(&mut frame);
        frame
    }

    /// Adds the sensor's measurement noise to a clean frame (for repeated frames of one press).
    pub fn add_noise(&mut self, frame: &mut [f64]) {
        add_relative_noise(frame, self.params.noise_relative, &mut self.rng);
    }
}

/// Buffers of a frame by the update, kept from frame to frame.
#[derive(Debug, Default)]
struct FrameScratch {
    change: ChangeScratch,
    /// The triangles one press's box meets.
    near: Vec<usize>,
    /// Per triangle, the generation of the last frame that listed it.
    seen: Vec<u32>,
    generation: u32,
    /// Those of every press, each once.
    candidates: Vec<usize>,
    /// (triangle, change of its conductivity, S/m).
    changes: Vec<(usize, f64)>,
}

/// Presses over time: each held from a start to an end time (s) at a position (m) with a force (N).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Script {
    /// (start s, end s, press), in any order; overlapping presses are all on the sheet.
    pub presses: Vec<(f64, f64, Press)>,
}

/// A line of a press script that is not `start end x y force`.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("script line {line}: {reason}")]
pub struct ScriptError {
    /// 1-based line.
    pub line: usize,
    /// What is wrong.
    pub reason: String,
}

/// The latest time a press script may name, in s (about 31 years): no run reaches it, so a
/// later one is a slip, not a press.
pub const MAX_SCRIPT_TIME: f64 = 1e9;

impl Script {
    /// Parses lines `start end x y force` (seconds, positions in units of `metres` m, N),
    /// separated by spaces, tabs or commas; `#` starts a comment. Every number is finite; times
    /// run from 0 to [`MAX_SCRIPT_TIME`] s with the end after the start, and forces from 0 to
    /// [`MAX_FORCE`] N; an error names the line and quotes the value as written.
    pub fn parse(text: &str, metres: f64) -> Result<Script, ScriptError> {
        Script::parse_where(text, metres, |_| Ok(()))
    }

    /// [`Script::parse`], also refusing a press whose centre (m) `place` refuses: its `Err`
    /// is the reason, quoted after the line (e.g. "the centre (5000, 0) mm is off the sheet").
    pub fn parse_where(
        text: &str,
        metres: f64,
        place: impl Fn([f64; 2]) -> Result<(), String>,
    ) -> Result<Script, ScriptError> {
        let mut presses = Vec::new();
        for (n, line) in text.lines().enumerate() {
            let line = line.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let fail = |reason: String| ScriptError { line: n + 1, reason };
            let fields: Vec<&str> = line.split([',', ' ', '\t']).filter(|f| !f.is_empty()).collect();
            let v: Vec<f64> = fields
                .iter()
                .map(|f| match f.parse::<f64>() {
                    Ok(v) if v.is_finite() => Ok(v),
                    Ok(_) => Err(fail(format!("{f} is not a finite number"))),
                    Err(_) => Err(fail(format!("{f:?} is not a number"))),
                })
                .collect::<Result<_, _>>()?;
            let (&[start, end, x, y, force], &[t0, t1, _, _, f]) = (&v[..], &fields[..]) else {
                return Err(fail(format!("expected 5 numbers `start end x y force`, got {}", v.len())));
            };
            for (what, time, text) in [("start", start, t0), ("end", end, t1)] {
                if !(0.0..=MAX_SCRIPT_TIME).contains(&time) {
                    return Err(fail(format!(
                        "{what} {text} s is outside 0–{MAX_SCRIPT_TIME:e} s: times count from the run's start, and no run lasts {MAX_SCRIPT_TIME:e} s"
                    )));
                }
            }
            if end <= start {
                return Err(fail(format!("end {t1} s is not after start {t0} s")));
            }
            if !(0.0..=MAX_FORCE).contains(&force) {
                return Err(fail(format!("force {f} N is outside 0–{MAX_FORCE:e} N")));
            }
            let position = [x * metres, y * metres];
            place(position).map_err(fail)?;
            presses.push((start, end, Press { position, force }));
        }
        Ok(Script { presses })
    }

    /// One press every `period` s, held half of it, at a random place inside `outline` (kept
    /// 10 % of the width from the box's edges) with a random force from 2 to 12 N, for `count` presses.
    pub fn random(outline: &crate::Outline, period: f64, count: usize, seed: u64) -> Script {
        use rand::RngExt;
        let [lo, hi] = outline.bounds();
        let margin = 0.1 * (hi[0] - lo[0]);
        let mut rng = SeededRng::seed_from_u64(seed);
        let presses = (0..count)
            .map(|k| {
                let position = [
                    rng.random_range(lo[0] + margin..hi[0] - margin),
                    rng.random_range(lo[1] + margin..hi[1] - margin),
                ];
                let start = period * (k as f64 + 0.5);
                (start, start + 0.5 * period, Press { position, force: rng.random_range(2.0..12.0) })
            })
            .filter(|p| outline.contains(p.2.position))
            .collect();
        Script { presses }
    }

    /// The presses on the sheet at time `t` (s).
    pub fn at(&self, t: f64) -> impl Iterator<Item = Press> + '_ {
        self.presses.iter().filter(move |p| p.0 <= t && t < p.1).map(|p| p.2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scripts_parse_and_say_where_they_are_wrong() {
        let script = Script::parse("# t0 t1 x y F\n0 1 50 -20 8\n0.5, 2, 0, 0, 3 # two at once\n", 1e-3).unwrap();
        assert_eq!(script.at(0.7).count(), 2);
        assert_eq!(script.at(1.5).next(), Some(Press { position: [0.0, 0.0], force: 3.0 }));
        assert_eq!(
            Script::parse("0 1 2 3\n", 1.0).unwrap_err().to_string(),
            "script line 1: expected 5 numbers `start end x y force`, got 4"
        );
        assert!(Script::parse("\n1 0 0 0 1\n", 1.0).unwrap_err().to_string().starts_with("script line 2"));
        // Numbers that no press has are refused by line, quoted as written (they ran unrefused).
        for (line, reason) in [
            ("0 1 nan 0 8", "nan is not a finite number"),
            ("0 1 0 inf 8", "inf is not a finite number"),
            ("0 1 0 0 1e9", "force 1e9 N is outside 0–1e5 N"),
            ("0 1 0 0 -2", "force -2 N is outside 0–1e5 N"),
            ("-1 1 0 0 8", "start -1 s is outside 0–1e9 s"),
            ("0 1e300 0 0 8", "end 1e300 s is outside 0–1e9 s"),
            ("2 1 0 0 8", "end 1 s is not after start 2 s"),
        ] {
            let err = Script::parse(&format!("0 1 0 0 8\n{line}\n"), 1e-3).unwrap_err().to_string();
            assert!(err.starts_with(&format!("script line 2: {reason}")), "{line}: {err}");
        }
        let edge = Script::parse(&format!("0 {MAX_SCRIPT_TIME} 0 0 {MAX_FORCE}\n0 1 0 0 0"), 1e-3).unwrap();
        assert_eq!(edge.presses.len(), 2);
        // A place the caller refuses is refused with its reason, on its line.
        let err = Script::parse_where("0 1 0 0 8\n\n0 1 5000 0 8", 1e-3, |[x, _]| {
            if x > 1.0 {
                Err(format!("the centre x = {} m is off the sheet", x))
            } else {
                Ok(())
            }
        })
        .unwrap_err();
        assert_eq!(err.to_string(), "script line 3: the centre x = 5 m is off the sheet");
        let random = Script::random(&crate::Outline::Circle { radius: 0.1 }, 2.0, 50, 4);
        assert!(
            !random.presses.is_empty() && random.presses.iter().all(|p| p.2.position[0].hypot(p.2.position[1]) <= 0.1)
        );
    }

    /// A Hertz press lowers the middle most, over a contact that grows with the force, and
    /// another law saturates more slowly.
    #[test]
    fn presses_unlike_the_flat_indenter() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 3000;
        let hydrogel = Hydrogel { profile: Profile::Hertz { reference_force: 8.0 }, ..Hydrogel::default() };
        assert!((hydrogel.contact_radius(1.0) - 0.005).abs() < 1e-12);
        let params = SimParams { hydrogel, ..SimParams::default() };
        let skin = VirtualSensor::with_params(&spec, params, 1).unwrap();
        let sigma = skin.conductivity_with(&[Press { position: [0.0, 0.0], force: 8.0 }]);
        let mesh = skin.model().mesh();
        let at = |r: f64| {
            let locator = crate::PointLocator::new(mesh);
            sigma[locator.locate([r, 0.0]).unwrap()]
        };
        assert!(
            at(0.0) < at(0.006) && at(0.006) < at(0.012) && at(0.012) == 1.0,
            "{} {} {}",
            at(0.0),
            at(0.006),
            at(0.012)
        );
        assert!((1.0 - at(0.0) - hydrogel.drop(8.0)).abs() < 0.1);
        let hyperbolic = Hydrogel { law: ForceLaw::Hyperbolic, ..Hydrogel::default() };
        assert!(hyperbolic.drop(16.0) < Hydrogel::default().drop(16.0) && hyperbolic.drop(1e6) > 0.89);
    }

    #[test]
    fn sixteen_newtons_lower_the_gel_by_85_percent() {
        let d = Hydrogel::default().drop(16.0);
        assert!((d - 0.85).abs() < 0.005, "{d}");
        assert_eq!(Hydrogel::default().drop(0.0), 0.0);
        assert!(Hydrogel::default().drop(8.0) < d);
    }

    #[test]
    fn a_press_raises_two_terminal_values_and_noise_is_seeded() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 400;
        let mut a = VirtualSensor::new(&spec, 7).unwrap();
        let mut b = VirtualSensor::new(&spec, 7).unwrap();
        assert!(a.model().mesh().triangles().len() > 2 * 400, "its own, finer mesh");
        let rest = a.clean_frame().unwrap();
        a.press([0.03, 0.02], 10.0);
        b.press([0.03, 0.02], 10.0);
        let pressed = a.clean_frame().unwrap();
        assert!(pressed.iter().zip(&rest).all(|(p, r)| p >= r));
        assert_eq!(a.frame().unwrap(), b.frame().unwrap(), "same seed, same noise");
        let noisy = a.frame().unwrap();
        let worst = noisy.iter().zip(&pressed).map(|(n, c)| ((n - c) / c).abs()).fold(0.0, f64::max);
        assert!(worst > 0.0 && worst < 6.0 * 1e-4, "noise {worst}");
    }

    /// Frames by the low-rank update are the full solve's, for one press and for three far
    /// apart, two whose boxes nearly meet, flat and Hertz-like, and for a press wider than the
    /// near part would hold: on truth meshes that keep K₀⁻¹ whole.
    #[test]
    fn updated_frames_are_full_solves() {
        let mut spec = SensorSpec::square_hydrogel();
        for (triangles, profile) in [
            (1500, Profile::Disk),
            (1500, Profile::Hertz { reference_force: 5.0 }),
            (2200, Profile::Hertz { reference_force: 5.0 }),
        ] {
            spec.mesh.triangles = triangles;
            let hydrogel = Hydrogel { profile, ..Hydrogel::default() };
            let params = SimParams { hydrogel, ..SimParams::default() };
            let mut skin = VirtualSensor::with_params(&spec, params, 3).unwrap();
            let unknowns = skin.model().system_size();
            assert_eq!(unknowns <= crate::forward::DENSE_LIMIT, triangles == 1500, "{unknowns} unknowns");
            assert!(unknowns <= crate::forward::WHOLE_LIMIT);
            for presses in [
                vec![([0.02, -0.03], 6.0)],
                vec![([0.05, 0.05], 3.0), ([-0.06, 0.0], 12.0), ([0.0, -0.07], 8.0)],
                // Boxes half a millimetre apart (flat), or meeting (Hertz): the triangles of the
                // buckets both list are changed once.
                vec![([0.0, 0.0], 6.0), ([0.0205, 0.0], 6.0)],
                vec![([-0.0205, 0.0], 6.0), ([0.0, 0.0], 6.0), ([0.0205, 0.0], 6.0)],
                vec![([0.0, 0.0], 2000.0)],
            ] {
                skin.release();
                for (at, force) in presses {
                    skin.press(at, force);
                }
                let updated = skin.clean_frame().unwrap();
                let solved = skin.model().measure(&skin.conductivity()).unwrap();
                let worst = updated.iter().zip(&solved).map(|(a, b)| ((a - b) / b).abs()).fold(0.0, f64::max);
                assert!(worst < 1e-9, "{triangles}, {profile:?}, {} presses: {worst:e}", skin.presses().len());
                assert!(skin.scratch.lock().unwrap().change.updated(), "{triangles}, {profile:?}");
            }
        }
    }

    /// Frames asked for in bulk are solved in full until the sensor has been asked for
    /// [`UPDATE_AFTER`] of them, then by the update: the same frames to rounding, an empty case
    /// included; with drift, in full again.
    #[test]
    fn frames_in_bulk_are_full_solves_through_the_update() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 400;
        let params = SimParams { drift_per_hour: 0.02, ..SimParams::default() };
        let mut skin = VirtualSensor::with_params(&spec, params, 1).unwrap();
        let press = |position: [f64; 2], force: f64| Press { position, force };
        let cases = vec![
            vec![press([0.02, -0.03], 6.0)],
            vec![],
            vec![press([0.05, 0.05], 3.0), press([-0.06, 0.0], 12.0), press([0.0, -0.07], 8.0)],
        ];
        let solved: Vec<Vec<f64>> =
            cases.iter().map(|c| skin.model().measure(&skin.conductivity_with(c)).unwrap()).collect();
        let few = skin.clean_frames(&cases).unwrap();
        assert!(skin.update.get().is_none(), "three frames are solved in full");
        assert_eq!(few, solved);
        let many: Vec<Vec<Press>> = cases.iter().cycle().take(UPDATE_AFTER).cloned().collect();
        let updated = skin.clean_frames(&many).unwrap();
        assert!(skin.update.get().is_some_and(Option::is_some), "the update is made");
        for (u, s) in updated.iter().zip(solved.iter().cycle()) {
            let worst = u.iter().zip(s).map(|(a, b)| ((a - b) / b).abs()).fold(0.0, f64::max);
            assert!(worst < 1e-9, "{worst:e}");
        }
        skin.advance(3600.0);
        let drifted = skin.clean_frames(&cases[..1]).unwrap();
        assert_eq!(drifted[0], skin.model().measure(&skin.conductivity_with(&cases[0])).unwrap());
    }

    #[test]
    fn drift_lowers_the_background() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 300;
        let params = SimParams { drift_per_hour: 0.02, ..SimParams::default() };
        let mut skin = VirtualSensor::with_params(&spec, params, 1).unwrap();
        let before = skin.clean_frame().unwrap();
        skin.advance(1800.0);
        assert!((skin.background() - 0.99).abs() < 1e-12);
        let after = skin.clean_frame().unwrap();
        // The sheet's share of each value scales as 1/σ; the contact impedance's does not.
        let ratio = after[0] / before[0];
        assert!(ratio > 1.0 && ratio <= 1.0 / 0.99 + 1e-12, "{ratio}");
    }
}
