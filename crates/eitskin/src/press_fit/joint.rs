//! The presses found, fitted together with their exact responses ([`super::refine()`]), and the set
//! itself corrected by what the exact fit shows: the linear search leaves presses at a blend of
//! two, splits a strong press into several weak ones (what the linearisation misses of it), and
//! misses a weak press next to a strong one. After each exact fit, in turn:
//! - two presses nearer than two indenter radii are one: the one with the smaller z goes;
//! - a press whose z (against Δv less the others' exact responses) fails the threshold, or
//!   whose drop is under [`MIN_DROP`], goes;
//! - each press is placed again where the largest z is left once the others are taken off, if
//!   that is elsewhere, and kept there if the misfit falls;
//! - a new press is placed where the largest z is left, if it passes (not where a press was
//!   taken off);
//!
//! until none of these changes anything.

use super::detect::{Exact, Scan, MAX_PRESSES, MIN_DROP};
use super::exact::Disk;
use super::refine::{refine, RefineParams, DEEPEST};
use super::{PressFit, PressModel, PressScratch};
use crate::inverse::InverseError;
use faer::linalg::matmul::matmul;
use faer::{Accum, Par};

/// Per scan point, the part of its response's gᵀg that the presses of the last exact fit cannot
/// take up by moving, into the scratch's `unexplained`: gᵀg − |Qᵀg|², Q an orthonormal basis of
/// the fit's Jacobian (its rows), but at least [`UNEXPLAINED_FLOOR`] of gᵀg. The misfit left is
/// orthogonal to that span, so gᵀr/√(gᵀg − |Qᵀg|²) is the z of a new press with the others
/// fitted again: a weak press whose signal a strong one has partly taken up (by moving towards
/// it and deepening) is still found.
fn unexplained_into(scan: &Scan, scratch: &mut PressScratch) {
    let PressScratch { refine: refining, basis, projections, unexplained, .. } = scratch;
    let jacobian = refining.jacobian();
    let (n, m) = (jacobian.nrows(), jacobian.ncols());
    basis.resize_with(n, m, |_, _| 0.0);
    // Modified Gram–Schmidt on the rows, twice for orthogonality; a row that adds nothing is 0.
    let mut rank = 0;
    for a in 0..n {
        for q in 0..m {
            basis[(rank, q)] = jacobian[(a, q)];
        }
        let original: f64 = (0..m).map(|q| basis[(rank, q)].powi(2)).sum::<f64>().sqrt();
        for _ in 0..2 {
            for b in 0..rank {
                let dot: f64 = (0..m).map(|q| basis[(rank, q)] * basis[(b, q)]).sum();
                for q in 0..m {
                    basis[(rank, q)] -= dot * basis[(b, q)];
                }
            }
        }
        let norm: f64 = (0..m).map(|q| basis[(rank, q)].powi(2)).sum::<f64>().sqrt();
        if norm > 1e-9 * original && norm > 0.0 {
            for q in 0..m {
                basis[(rank, q)] /= norm;
            }
            rank += 1;
        }
    }
    let points = scan.matrix.nrows();
    projections.resize_with(points, rank, |_, _| 0.0);
    let q = basis.as_ref().subrows(0, rank);
    matmul(projections.as_mut(), Accum::Replace, scan.matrix.as_ref(), q.transpose(), 1.0, Par::Seq);
    unexplained.clear();
    unexplained.extend((0..points).map(|p| {
        let taken: f64 = (0..rank).map(|k| projections[(p, k)].powi(2)).sum();
        (scan.norms[p] - taken).max(UNEXPLAINED_FLOOR * scan.norms[p])
    }));
}

/// The least share of a response's gᵀg counted as not taken up by the presses fitted (z grows
/// by at most 1/√ of it): right beside a press, what is left of g is mostly noise in the fit.
const UNEXPLAINED_FLOOR: f64 = 0.25;

/// Rounds of corrections at most.
const ROUNDS: usize = 2 * MAX_PRESSES;

impl PressModel {
    /// Fits `presses` (found on the linear responses) together to whitened Δv `dv` with their
    /// exact responses, correcting the set as the [module doc](self) says. Allocates nothing
    /// once `scratch` has grown.
    pub(crate) fn fit_jointly(
        &self,
        scan: &Scan,
        dv: &[f64],
        threshold: f64,
        exact: Exact<'_>,
        presses: &mut Vec<PressFit>,
        scratch: &mut PressScratch,
    ) -> Result<(), InverseError> {
        let m = self.measurements;
        let window = 2.0 * self.grid.spacing;
        let mut cost = self.refit(exact, dv, presses, scratch)?;
        scratch.rejected.clear();
        for _ in 0..ROUNDS {
            if let Some(weaker) = self.overlapping(presses) {
                scratch.rejected.push(presses.remove(weaker).centre);
                cost = self.refit(exact, dv, presses, scratch)?;
                continue;
            }
            let failing = presses
                .iter()
                .enumerate()
                .filter(|(_, p)| p.z < threshold || p.drop < MIN_DROP)
                .min_by(|a, b| a.1.z.total_cmp(&b.1.z));
            if let Some((i, _)) = failing {
                scratch.rejected.push(presses.remove(i).centre);
                cost = self.refit(exact, dv, presses, scratch)?;
                continue;
            }
            let mut changed = false;
            for i in 0..presses.len() {
                self.others_into(dv, presses, i, scratch);
                let PressScratch { residual, response, centres, correlations, .. } = &mut *scratch;
                let Some((j, _)) = self.best_point(scan, residual, centres, correlations) else { continue };
                let (p, at) = (self.grid.point(j), presses[i].centre);
                if (p[0] - at[0]).hypot(p[1] - at[1]) <= self.radius {
                    continue;
                }
                let Some(candidate) = self.fit_one(residual, p, window, response) else { continue };
                scratch.saved.clear();
                scratch.saved.extend_from_slice(presses);
                scratch.saved_responses.clear();
                scratch.saved_responses.extend_from_slice(&scratch.responses[..presses.len() * m]);
                presses[i] = candidate;
                let moved = self.refit(exact, dv, presses, scratch)?;
                if moved < cost {
                    (cost, changed) = (moved, true);
                } else {
                    presses.clear();
                    presses.extend_from_slice(&scratch.saved);
                    let k = presses.len() * m;
                    scratch.responses[..k].copy_from_slice(&scratch.saved_responses);
                }
            }
            if changed {
                continue;
            }
            if presses.len() < MAX_PRESSES {
                // Not where a press was taken off: it would only come back.
                self.others_into(dv, presses, usize::MAX, scratch);
                unexplained_into(scan, scratch);
                let PressScratch { residual, response, centres, correlations, unexplained, rejected, .. } =
                    &mut *scratch;
                centres.extend_from_slice(rejected);
                let best = self.best_point_in(scan, residual, centres, unexplained, correlations);
                let new = best.filter(|(_, z)| *z >= threshold).and_then(|(j, _)| {
                    self.fit_one(residual, self.grid.point(j), window, response).filter(|f| f.drop >= MIN_DROP)
                });
                if let Some(new) = new {
                    presses.push(new);
                    cost = self.refit(exact, dv, presses, scratch)?;
                    continue;
                }
            }
            break;
        }
        // Should the rounds run out, what is returned still passes.
        presses.retain(|p| p.z >= threshold && p.drop >= MIN_DROP);
        Ok(())
    }

    /// The index of the weaker (smaller z) of the first two presses nearer than two indenter
    /// radii to each other, if any.
    fn overlapping(&self, presses: &[PressFit]) -> Option<usize> {
        let apart = 2.0 * self.radius;
        for (i, a) in presses.iter().enumerate() {
            for (j, b) in presses.iter().enumerate().skip(i + 1) {
                if (a.centre[0] - b.centre[0]).hypot(a.centre[1] - b.centre[1]) < apart {
                    return Some(if a.z < b.z { i } else { j });
                }
            }
        }
        None
    }

    /// Whitened Δv less every press's exact response but the `skip`th's, into the scratch's
    /// residual; the others' centres into its centres.
    fn others_into(&self, dv: &[f64], presses: &[PressFit], skip: usize, scratch: &mut PressScratch) {
        let m = self.measurements;
        let PressScratch { residual, responses, centres, .. } = scratch;
        residual.clear();
        residual.extend_from_slice(dv);
        centres.clear();
        for (k, press) in presses.iter().enumerate().filter(|(k, _)| *k != skip) {
            residual.iter_mut().zip(&responses[k * m..(k + 1) * m]).for_each(|(r, g)| *r -= g);
            centres.push(press.centre);
        }
    }

    /// Fits `presses` together with their exact responses, in place: each one's whitened exact
    /// response into its row of the scratch's responses, and its z against Δv less the
    /// others'. The misfit left (χ²).
    fn refit(
        &self,
        exact: Exact<'_>,
        dv: &[f64],
        presses: &mut [PressFit],
        scratch: &mut PressScratch,
    ) -> Result<f64, InverseError> {
        let m = self.measurements;
        let PressScratch { disks, refine: refining, responses, .. } = &mut *scratch;
        disks.clear();
        disks.extend(presses.iter().map(|f| Disk {
            centre: f.centre,
            radius: f.radius,
            drop: f.drop.clamp(0.0, DEEPEST),
        }));
        let params = RefineParams {
            fit_radius: false,
            radius_range: [self.radius, self.radius],
            bounds: [self.grid.lo, self.grid.point(self.grid.len() - 1)],
        };
        let cost = refine(exact.presses, exact.dv, exact.weights, disks, &params, refining)?;
        let own = refining.own_responses();
        responses.resize(responses.len().max(presses.len() * m), 0.0);
        responses[..presses.len() * m].copy_from_slice(&own[..presses.len() * m]);
        for (press, disk) in presses.iter_mut().zip(disks.iter()) {
            (press.centre, press.radius, press.drop) = (disk.centre, disk.radius, disk.drop);
        }
        for i in 0..presses.len() {
            self.others_into(dv, presses, i, scratch);
            let g = &scratch.responses[i * m..(i + 1) * m];
            let gg: f64 = g.iter().map(|g| g * g).sum();
            let gr: f64 = g.iter().zip(&scratch.residual).map(|(g, r)| g * r).sum();
            presses[i].z = if gg > 0.0 { gr / gg.sqrt() } else { 0.0 };
        }
        Ok(cost)
    }
}
