//! Presses carried from frame to frame of a stream: see [`PressTrack`].

use faer::linalg::matmul::matmul;
use faer::{Accum, ColMut, ColRef, Mat, Par};

use super::detect::{Exact, PressDetection, Scan, MAX_PRESSES, MIN_DROP};
use super::exact::{Disk, DiskParameter, ExactScratch};
use super::joint::{disk_of, orthonormal_rows, unexplained_into};
use super::refine::DEEPEST;
use super::{PressFit, PressScratch};
use crate::inverse::InverseError;
use crate::scratch::{grow, room, DenseLu};

/// The largest shift of the fitted parameters the second-order term a carried step leaves out
/// may cause, in standard deviations of the fit (whitened: the term's part in the span of the
/// Jacobian): half of one.
pub const NONLINEAR: f64 = 0.5;

/// The parameters carried per press, in the order of the Jacobian's rows (the radius stays
/// as the last fit found it).
const CARRIED: [DiskParameter; 3] = [DiskParameter::X, DiskParameter::Y, DiskParameter::Drop];

/// Steps of the second differences, per parameter of [`CARRIED`]: 1 mm, 1 mm, 0.05.
const STEPS: [f64; 3] = [1e-3, 1e-3, 0.05];

/// How a frame's presses were found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Tracked {
    /// Carried from the last fit's linearisation by one step.
    Carried,
    /// Fitted again exactly from where the step put them (the step went past the linearisation).
    Refitted,
    /// Found afresh in Δv.
    Found,
}

/// The presses of one stream carried from frame to frame ([`PressDetection::track_into`]), and
/// the buffers of that; [`PressTrack::clear`] when the reference or the detection changes.
///
/// A press held on the sheet changes Δv by
/// little more than the noise between frames, so the joint exact fit of the last frame
/// ([`super::PressDetection::detect_into`]) is linearised once, and each new frame is one
/// Gauss–Newton step from it, read off that linearisation: a product with (JJᵀ)⁻¹J instead of a
/// Levenberg–Marquardt fit of rank-hundreds updates. The presses are fitted again, or found
/// afresh, as soon as the step cannot be trusted or the frame does not fit them:
/// - **the linearisation no longer holds** — each press's own response is known to second order
///   along each parameter (a difference of exact responses at linearisation), and the step's
///   second-order term e = ½·Σₚ ∂²F/∂θₚ²·δθₚ², whitened, may move the parameters (its part in
///   the span of the Jacobian) by at most [`NONLINEAR`] of their standard deviation; the rest of
///   it is taken off the misfit the tests below read; past it the presses are fitted again
///   exactly from where the step put them, and linearised there;
/// - **a press is gone** — its z against the misfit with its own response put back, or its
///   drop, fails as in the detection;
/// - **a new press is there** — the largest z of the misfit over the scan grid, against the part
///   of each point's response the presses cannot take up, passes the detection's threshold.
///
/// A frame carried so is what the exact fit would give to within a fraction of the spread the
/// noise gives the fit, 0.2–0.46 (`presses_held_are_carried_as_the_exact_fit_finds_them`), in
/// microseconds: what is left is the Jacobian held at the linearisation, not the second-order
/// term (bounding that tighter carries fewer frames no closer). Where the noise moves a weak
/// press's fit by millimetres from frame to frame, the step goes past the linearisation in
/// most frames, and those are fitted again (`eitskin bench`, `frame_three_presses_carried` at
/// 0.05 % noise against `frame_three_presses_carried_80db` at 0.01 %).
#[derive(Debug)]
pub struct PressTrack {
    /// Whether a linearisation is held.
    linearised: bool,
    /// The presses it was made at, and those of the last frame carried.
    at: Vec<PressFit>,
    current: Vec<PressFit>,
    /// The presses' joint exact response at `at`, whitened.
    response: Vec<f64>,
    /// Its whitened Jacobian, one row per press and parameter of [`CARRIED`].
    jacobian: Mat<f64>,
    /// (JJᵀ)⁻¹J: the step's map from the misfit.
    solver: Mat<f64>,
    normal: Mat<f64>,
    lu: DenseLu,
    /// Each press's own response (rows), its Jacobian and second derivatives (rows per press
    /// and parameter), whitened.
    own: Vec<f64>,
    own_jacobian: Mat<f64>,
    curvature: Mat<f64>,
    /// The rank of the Jacobian's orthonormal basis (its first rows in `basis`).
    rank: usize,
    /// The step's second-order term, whitened.
    second: Vec<f64>,
    /// Per scan point, the part of its gᵀg the presses cannot take up.
    unexplained: Vec<f64>,
    basis: Mat<f64>,
    projections: Mat<f64>,
    disks: Vec<Disk>,
    exact: ExactScratch,
    residual: Vec<f64>,
    step: Vec<f64>,
    row: Vec<f64>,
    centres: Vec<[f64; 2]>,
    correlations: Vec<f64>,
}

impl Default for PressTrack {
    fn default() -> Self {
        let empty = || Mat::zeros(0, 0);
        PressTrack {
            linearised: false,
            at: Vec::new(),
            current: Vec::new(),
            response: Vec::new(),
            jacobian: empty(),
            solver: empty(),
            normal: empty(),
            lu: DenseLu::default(),
            own: Vec::new(),
            own_jacobian: empty(),
            curvature: empty(),
            rank: 0,
            second: Vec::new(),
            unexplained: Vec::new(),
            basis: empty(),
            projections: empty(),
            disks: Vec::new(),
            exact: ExactScratch::default(),
            residual: Vec::new(),
            step: Vec::new(),
            row: Vec::new(),
            centres: Vec::new(),
            correlations: Vec::new(),
        }
    }
}

impl Clone for PressTrack {
    /// What is carried belongs to one stream: a clone starts afresh.
    fn clone(&self) -> Self {
        PressTrack::default()
    }
}

impl PressTrack {
    /// Forgets the presses carried: the next frame's are found afresh.
    pub fn clear(&mut self) {
        self.linearised = false;
    }

    /// Linearises the exact responses at `presses` (whitened by `weights`); false (and nothing
    /// held) where a press is solved in full, without the update's derivatives.
    fn linearise(&mut self, exact: Exact<'_>, scan: &Scan, presses: &[PressFit]) -> Result<bool, InverseError> {
        self.linearised = false;
        let (m, k) = (exact.dv.len(), presses.len());
        let n = CARRIED.len() * k;
        let model = exact.presses;
        model.reserve(&mut self.exact);
        for buffer in [&mut self.response, &mut self.residual, &mut self.row, &mut self.second] {
            room(buffer, m);
            buffer.resize(m, 0.0);
        }
        room(&mut self.own, MAX_PRESSES * m);
        self.own.resize(k * m, 0.0);
        room(&mut self.step, CARRIED.len() * MAX_PRESSES);
        self.step.resize(n, 0.0);
        for buffer in [&mut self.at, &mut self.current] {
            room(buffer, MAX_PRESSES);
        }
        room(&mut self.disks, MAX_PRESSES);
        room(&mut self.centres, MAX_PRESSES);
        room(&mut self.correlations, scan.points.len());
        room(&mut self.unexplained, scan.points.len());
        grow(&mut self.jacobian, n, m);
        grow(&mut self.own_jacobian, n, m);
        grow(&mut self.curvature, n, m);
        grow(&mut self.solver, n, m);
        grow(&mut self.normal, n, n);
        let weigh = |out: &mut [f64]| out.iter_mut().zip(exact.weights).for_each(|(o, w)| *o *= w);
        // The joint response and its Jacobian, from one solve.
        self.disks.clear();
        self.disks.extend(presses.iter().map(disk_of));
        model.response_into(&self.disks, &mut self.exact, &mut self.response)?;
        weigh(&mut self.response);
        for i in 0..k {
            for (p, &parameter) in CARRIED.iter().enumerate() {
                if !model.derivative_into(&self.disks, i, parameter, &mut self.exact, &mut self.row) {
                    return Ok(false);
                }
                weigh(&mut self.row);
                self.row.iter().enumerate().for_each(|(q, d)| self.jacobian[(3 * i + p, q)] = *d);
            }
        }
        // Each press alone: its response, Jacobian and second differences.
        for i in 0..k {
            let disk = [self.disks[i]];
            let own = &mut self.own[i * m..(i + 1) * m];
            model.response_into(&disk, &mut self.exact, own)?;
            weigh(own);
            for (p, &parameter) in CARRIED.iter().enumerate() {
                if !model.derivative_into(&disk, 0, parameter, &mut self.exact, &mut self.row) {
                    return Ok(false);
                }
                weigh(&mut self.row);
                self.row.iter().enumerate().for_each(|(q, d)| self.own_jacobian[(3 * i + p, q)] = *d);
            }
            for (p, &parameter) in CARRIED.iter().enumerate() {
                let mut moved = disk;
                let h = match parameter {
                    DiskParameter::X => STEPS[0],
                    DiskParameter::Y => -STEPS[1],
                    _ if disk[0].drop + STEPS[2] <= DEEPEST => STEPS[2],
                    _ => -STEPS[2],
                };
                match parameter {
                    DiskParameter::X => moved[0].centre[0] += h,
                    DiskParameter::Y => moved[0].centre[1] += h,
                    _ => moved[0].drop += h,
                }
                model.response_into(&moved, &mut self.exact, &mut self.row)?;
                weigh(&mut self.row);
                // F(θ + h) − F(θ) − h·∂F/∂θ ≈ ½h²·∂²F/∂θ².
                let own = &self.own[i * m..(i + 1) * m];
                for (q, (moved, own)) in self.row.iter().zip(own).enumerate() {
                    let left = moved - own - h * self.own_jacobian[(3 * i + p, q)];
                    self.curvature[(3 * i + p, q)] = 2.0 * left / (h * h);
                }
            }
        }
        // (JJᵀ)⁻¹J, once; and what of each scan point's response the presses can take up.
        let j = self.jacobian.as_ref();
        matmul(self.normal.as_mut(), Accum::Replace, j, j.transpose(), 1.0, Par::Seq);
        self.solver.copy_from(j);
        if n > 0 {
            self.lu.solve_in_place(self.normal.as_mut(), self.solver.as_mut());
        }
        if (0..n).any(|a| (0..m).any(|q| !self.solver[(a, q)].is_finite())) {
            return Ok(false);
        }
        self.rank = orthonormal_rows(self.jacobian.as_ref(), &mut self.basis);
        unexplained_into(scan, &self.basis, self.rank, &mut self.projections, &mut self.unexplained);
        self.at.clear();
        self.at.extend_from_slice(presses);
        self.linearised = true;
        Ok(true)
    }
}

/// What one step from the linearisation found.
enum Step {
    /// The presses, carried: in the track's `current`.
    Held,
    /// The step went past what the linearisation holds for; the presses passed.
    TooFar,
    /// A press is gone or a new one is there.
    Changed,
}

impl PressTrack {
    /// One Gauss–Newton step from the linearisation to whitened Δv `whitened`, tested as
    /// [`PressTrack`] says; the presses into `current`.
    fn step(&mut self, detection: &PressDetection, whitened: &[f64]) -> Step {
        let (m, k) = (whitened.len(), self.at.len());
        let n = CARRIED.len() * k;
        self.residual.iter_mut().zip(whitened).zip(&self.response).for_each(|((r, v), f)| *r = v - f);
        // δθ = (JJᵀ)⁻¹J·r; the misfit left, r − Jᵀδθ.
        let step = ColMut::from_slice_mut(&mut self.step[..n]);
        let residual = ColRef::from_slice(&self.residual);
        matmul(step.as_mat_mut(), Accum::Replace, self.solver.as_ref(), residual.as_mat(), 1.0, Par::Seq);
        let left = ColMut::from_slice_mut(&mut self.residual);
        let step = ColRef::from_slice(&self.step[..n]);
        matmul(left.as_mat_mut(), Accum::Add, self.jacobian.transpose(), step.as_mat(), -1.0, Par::Seq);
        // The second-order term the step leaves out, e = ½·Σₚ ∂²F/∂θₚ²·δθₚ²: its part in the span
        // of the Jacobian is what it would move the parameters by (in standard deviations of the
        // fit); the rest stays in the misfit.
        self.second.fill(0.0);
        for (a, d) in self.step[..n].iter().enumerate() {
            self.second.iter_mut().enumerate().for_each(|(q, e)| *e += 0.5 * d * d * self.curvature[(a, q)]);
        }
        let second_order = (0..self.rank)
            .map(|k| (0..m).map(|q| self.basis[(k, q)] * self.second[q]).sum::<f64>().powi(2))
            .sum::<f64>()
            .sqrt();
        // Within the linearisation's reach the misfit the tests read is the better for it; past
        // it the term is no estimate of anything, and the step is refitted anyway.
        if second_order <= NONLINEAR {
            self.residual.iter_mut().zip(&self.second).for_each(|(r, e)| *r -= e);
        }
        let [lo, hi] = detection.model.grid.bounds();
        let mut changed = false;
        self.current.clear();
        self.centres.clear();
        for (i, press) in self.at.iter().enumerate() {
            let d = &self.step[3 * i..3 * i + 3];
            let mut carried = *press;
            carried.centre =
                [(press.centre[0] + d[0]).clamp(lo[0], hi[0]), (press.centre[1] + d[1]).clamp(lo[1], hi[1])];
            carried.drop = press.drop + d[2];
            // Its z against the misfit with its own response (to first order) put back.
            self.row.copy_from_slice(&self.own[i * m..(i + 1) * m]);
            for (p, dp) in d.iter().enumerate() {
                self.row.iter_mut().enumerate().for_each(|(q, g)| *g += dp * self.own_jacobian[(3 * i + p, q)]);
            }
            let gg: f64 = self.row.iter().map(|g| g * g).sum();
            let gr: f64 = self.row.iter().zip(&self.residual).map(|(g, r)| g * (r + g)).sum();
            carried.z = if gg > 0.0 { gr / gg.sqrt() } else { 0.0 };
            changed |= carried.z < detection.threshold || carried.drop < MIN_DROP || carried.drop > DEEPEST;
            self.centres.push(carried.centre);
            self.current.push(carried);
        }
        if changed {
            return Step::Changed;
        }
        // A new press, where the presses cannot take its response up.
        let best = detection.model.best_point_in(
            &detection.scan,
            &self.residual,
            &self.centres,
            &self.unexplained,
            &mut self.correlations,
        );
        if best.is_some_and(|(_, z)| z >= detection.threshold) {
            return Step::Changed;
        }
        if second_order > NONLINEAR {
            return Step::TooFar;
        }
        Step::Held
    }
}

impl PressDetection {
    /// [`PressDetection::detect_into`] for the frames of one stream: the presses of the last
    /// frame carried by one step while they explain Δv (see [`PressTrack`]), else
    /// fitted again or found afresh; how. `track` holds what is carried, `whitened` and
    /// `scratch` are buffers. Allocates nothing once they have grown. Without exact responses,
    /// each frame's presses are found afresh.
    pub fn track_into(
        &self,
        dv: &[f64],
        whitened: &mut Vec<f64>,
        scratch: &mut PressScratch,
        track: &mut PressTrack,
        out: &mut Vec<PressFit>,
    ) -> Result<Tracked, InverseError> {
        out.clear();
        self.whiten_into(dv, whitened)?;
        let Some(exact) = self.exact(dv).filter(|_| whitened.iter().all(|v| v.is_finite())) else {
            track.clear();
            self.detect_into(dv, whitened, scratch, out)?;
            return Ok(Tracked::Found);
        };
        if track.linearised {
            let step = track.step(self, whitened);
            if let Step::TooFar = step {
                // Fitted again from where the step put them, linearised there, and tested by a
                // step from there.
                out.extend_from_slice(&track.current);
                self.model.refit_with(exact, out, 0, scratch)?;
                if track.linearise(exact, &self.scan, out)? {
                    if let Step::Held = track.step(self, whitened) {
                        Self::carried_into(track, out);
                        return Ok(Tracked::Refitted);
                    }
                }
            } else if let Step::Held = step {
                Self::carried_into(track, out);
                return Ok(Tracked::Carried);
            }
        }
        self.detect_into(dv, whitened, scratch, out)?;
        track.linearise(exact, &self.scan, out)?;
        Ok(Tracked::Found)
    }

    /// The track's presses carried into `out`, strongest (deepest) first.
    fn carried_into(track: &PressTrack, out: &mut Vec<PressFit>) {
        out.clear();
        out.extend_from_slice(&track.current);
        out.sort_unstable_by(|a, b| b.drop.total_cmp(&a.drop));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::press_fit::{PressModel, PressModelParams};
    use crate::SeededRng;
    use crate::SensorSpec;
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};

    /// Three presses held still for 40 frames of fresh 0.01 % noise, then a fourth pressed, then
    /// two lifted: half the held frames are carried without a fit at all, each what the exact fit
    /// finds afresh to within half the spread the noise gives the fit (0.46 in centre, 0.34 in
    /// drop here; 0.31 and 0.38 when only the frames whose second-order term was under half a
    /// standard deviation in full were carried, 10 of 40); a press pressed or lifted is found
    /// afresh.
    #[test]
    fn presses_held_are_carried_as_the_exact_fit_finds_them() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 1500;
        let model = spec.forward_model().unwrap();
        let values = model.measure(&spec.homogeneous(model.mesh())).unwrap();
        let press_model = PressModel::new(&model, 1.0, &PressModelParams::default()).unwrap();
        let std: Vec<f64> = values.iter().map(|v| 1e-4 * v.abs()).collect();
        let detection = PressDetection::new(&press_model, &std, f64::INFINITY, 1e-3).unwrap();
        let exact = press_model.exact().unwrap();
        let disk = |centre, drop| Disk { centre, radius: 0.01, drop };
        let held = [disk([-0.03, 0.04], 0.25), disk([0.04, -0.02], 0.5), disk([0.06, 0.07], 0.6)];
        let mut rng = SeededRng::seed_from_u64(3);
        let mut frame = |disks: &[Disk]| {
            let mut dv = vec![0.0; values.len()];
            exact.response_into(disks, &mut ExactScratch::default(), &mut dv).unwrap();
            for (d, s) in dv.iter_mut().zip(&std) {
                let normal: f64 = StandardNormal.sample(&mut rng);
                *d += s * normal;
            }
            dv
        };
        let (mut whitened, mut scratch, mut track) = (Vec::new(), PressScratch::default(), PressTrack::default());
        let (mut carried, mut full) = (Vec::new(), Vec::new());
        let (mut how, mut off, mut spread) = (Vec::new(), [0.0; 2], [0.0; 2]);
        for _ in 0..40 {
            let dv = frame(&held);
            how.push(detection.track_into(&dv, &mut whitened, &mut scratch, &mut track, &mut carried).unwrap());
            detection.detect_into(&dv, &mut whitened, &mut PressScratch::default(), &mut full).unwrap();
            assert_eq!((carried.len(), full.len()), (3, 3), "{how:?}");
            if how.last() != Some(&Tracked::Carried) {
                continue;
            }
            for ((c, f), truth) in carried.iter().zip(&full).zip(held.iter().rev()) {
                off[0] += (c.centre[0] - f.centre[0]).powi(2) + (c.centre[1] - f.centre[1]).powi(2);
                off[1] += (c.drop - f.drop).powi(2);
                spread[0] += (f.centre[0] - truth.centre[0]).powi(2) + (f.centre[1] - truth.centre[1]).powi(2);
                spread[1] += (f.drop - truth.drop).powi(2);
            }
        }
        for k in 0..2 {
            let ratio = (off[k] / spread[k]).sqrt();
            assert!(ratio < 0.5, "{k}: carried frames off the exact fit by {ratio} of its spread");
        }
        assert_eq!(how[0], Tracked::Found);
        // Half the frames: the second-order term's part in the span of the Jacobian, not its
        // whole norm, is what is bounded (its whole norm carried 10 of these 40).
        assert!(how.iter().filter(|h| **h == Tracked::Carried).count() >= 20, "{how:?}");
        let four = [held[0], held[1], held[2], disk([-0.06, -0.05], 0.4)];
        assert_eq!(
            detection.track_into(&frame(&four), &mut whitened, &mut scratch, &mut track, &mut carried),
            Ok(Tracked::Found)
        );
        assert_eq!(carried.len(), 4);
        assert_eq!(
            detection.track_into(&frame(&four[2..]), &mut whitened, &mut scratch, &mut track, &mut carried),
            Ok(Tracked::Found)
        );
        assert_eq!(carried.len(), 2);
    }
}
