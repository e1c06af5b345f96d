//! The presses found, fitted together with their exact responses ([`super::refine()`]; or, while
//! they are of the indenter's size and apart, on one press's tabulated response, `TableUse::Auto`),
//! and the set itself corrected by what the fit shows: the linear search leaves presses at a blend
//! of two, splits a strong press into several weak ones (what the linearisation misses of it), and
//! misses a weak press next to a strong one. After each fit, in turn:
//! - two presses nearer than two indenter radii are one: the one with the smaller z goes;
//! - a press whose z (against Δv less the others' exact responses) fails the threshold, or
//!   whose drop is under [`MIN_DROP`], goes;
//! - each press is placed again where the largest z is left once the others are taken off, if
//!   that is elsewhere, and kept there if the misfit falls;
//! - a weaker press within four indenter radii of another goes, if the other, its radius fitted,
//!   explains Δv without it nearly as well (χ² grows by less than threshold², the test a new
//!   press must pass): a press wider than the indenter is one press, not one and the misfit it
//!   leaves, however little the other's own score test then asks for its size;
//! - each press's radius is fitted too, if that lowers the misfit by more than chance would
//!   ([`SIZE_TEST`]; tried where the radius's score test asks, or where the press is held at
//!   the deepest drop): a wider or narrower indenter, or a profile whose contact grows with
//!   force, is then one press of its own size, not several of the indenter's; once one press is
//!   merged or sized, the others' sizes are tested again;
//! - a new press is placed where the largest z of the fit's misfit is left, if it passes (not
//!   where a press was taken off), and kept if the misfit falls by as much (χ² by threshold²,
//!   the likelihood-ratio test);
//!
//! until none of these changes anything.

use super::detect::{Exact, MAX_PRESSES, MIN_DROP};
use super::exact::{Disk, DiskParameter};
use super::refine::{refine, refine_from_table, refine_tabulated, solve_at, RefineParams, DEEPEST, TABLE_START_APART};
use super::scan::{Reach, Scan};
use super::{dot, PressFit, PressModel, PressScratch};
use crate::inverse::InverseError;
use crate::scratch::{grow, room};
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};

/// Per scan point, the part of its response's gᵀg that presses cannot take up by moving, into
/// `unexplained`: gᵀg − |Qᵀg|², Q the first `rank` vectors of `basis` (an orthonormal basis of the
/// presses' Jacobian, [`orthonormal_rows`]), but at least [`UNEXPLAINED_FLOOR`] of gᵀg. A misfit
/// orthogonal to that span gives gᵀr/√(gᵀg − |Qᵀg|²) as the z of a new press with the others
/// fitted again: a weak press whose signal a strong one has partly taken up (by moving towards
/// it and deepening) is still found. `projections` is a buffer.
pub(crate) fn unexplained_into(
    scan: &Scan,
    basis: &[f64],
    rank: usize,
    projections: &mut Mat<f64>,
    unexplained: &mut Vec<f64>,
) {
    let (points, m) = (scan.matrix.nrows(), scan.matrix.ncols());
    grow(projections, points, rank);
    let q = MatRef::from_column_major_slice(&basis[..rank * m], m, rank);
    matmul(projections.as_mut(), Accum::Replace, scan.matrix.as_ref(), q, 1.0, Par::Seq);
    // |Qᵀg|² summed a column of projections at a time (contiguous), in the order of k.
    unexplained.clear();
    unexplained.resize(points, 0.0);
    for k in 0..rank {
        unexplained.iter_mut().zip(projections.col_as_slice(k)).for_each(|(taken, along)| *taken += along.powi(2));
    }
    unexplained.iter_mut().zip(&scan.norms).for_each(|(u, norm)| *u = (norm - *u).max(UNEXPLAINED_FLOOR * norm));
}

/// [`unexplained_into`] at one scan point, whose response is `g` and gᵀg `norm`.
pub(crate) fn unexplained_at(g: &[f64], norm: f64, basis: &[f64], rank: usize) -> f64 {
    let m = g.len();
    let taken = basis.chunks_exact(m).take(rank).fold(0.0, |taken, q| taken + dot(g, q).powi(2));
    (norm - taken).max(UNEXPLAINED_FLOOR * norm)
}

/// An orthonormal basis of the rows of `jacobian` into `basis`, one vector after another (each
/// of the Jacobian's columns long); their number. Modified Gram–Schmidt, twice for
/// orthogonality; a row that adds nothing is left out.
pub(crate) fn orthonormal_rows(jacobian: MatRef<'_, f64>, basis: &mut Vec<f64>) -> usize {
    let (n, m) = (jacobian.nrows(), jacobian.ncols());
    basis.clear();
    basis.resize(n * m, 0.0);
    let mut rank = 0;
    for a in 0..n {
        let (done, rest) = basis.split_at_mut(rank * m);
        let new = &mut rest[..m];
        new.iter_mut().enumerate().for_each(|(q, b)| *b = jacobian[(a, q)]);
        let original = dot(new, new).sqrt();
        for _ in 0..2 {
            for b in done.chunks_exact(m) {
                let along = dot(new, b);
                new.iter_mut().zip(b).for_each(|(x, y)| *x -= along * y);
            }
        }
        let norm = dot(new, new).sqrt();
        if norm > 1e-9 * original && norm > 0.0 {
            new.iter_mut().for_each(|x| *x /= norm);
            rank += 1;
        }
    }
    rank
}

/// [`orthonormal_rows`] of the last exact fit's Jacobian, into the scratch's basis; its rank.
/// Made again only after another fit (the sizes' tests and the search for a new press read the
/// same one where no fit came between them).
fn fit_basis(scratch: &mut PressScratch) -> usize {
    let PressScratch { refine: refining, basis, basis_of, refits, .. } = scratch;
    match *basis_of {
        Some((fit, rank)) if fit == *refits => rank,
        _ => {
            let rank = orthonormal_rows(refining.jacobian(), basis);
            *basis_of = Some((*refits, rank));
            rank
        }
    }
}

/// The least share of a response's gᵀg counted as not taken up by the presses fitted (z grows
/// by at most 1/√ of it): right beside a press, what is left of g is mostly noise in the fit.
pub(crate) const UNEXPLAINED_FLOOR: f64 = 0.25;

/// Whether a press's radius is its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Size {
    /// Not tested yet: the indenter's.
    Untested,
    /// The indenter's: the data do not ask for another.
    Nominal,
    /// Fitted.
    Fitted,
}

/// The fall of the misfit (χ², whitened) for which a press's radius is fitted: χ²₁ at a
/// probability of 1e-3 is 10.8, doubled against the misfit the model's mesh leaves of a press
/// of the model's kind. Both it and the score test that screens for it are scaled by the
/// fit's misfit per degree of freedom where that is over 1 ([`misfit_scale`]: the sized fit's,
/// and the fit's before sizing).
const SIZE_TEST: f64 = 25.0;

/// The fit's misfit per degree of freedom, at least 1: `cost` (χ²) of `presses` fitted with
/// `free_radii` radii besides their centres and drops, over the channels `exact` uses. Where
/// the noise is so low that the model's own error (its mesh against the sheet's) is most of the
/// misfit, a press of the model's kind no longer fits to the noise, and the size's test asks
/// for as much more (an F-test in place of the χ² one): the mesh's error is not a wider press.
fn misfit_scale(cost: f64, exact: Exact<'_>, presses: usize, free_radii: u32) -> f64 {
    let used = exact.weights.iter().filter(|w| **w > 0.0).count() as f64;
    let parameters = (3 * presses) as f64 + f64::from(free_radii.count_ones());
    if used > parameters {
        (cost / (used - parameters)).max(1.0)
    } else {
        1.0
    }
}

/// An exact fit is done once its next Gauss–Newton step would lower χ² by less than this: move
/// the presses by under a tenth of their standard deviation, which no later frame's noise lets
/// one tell from the optimum (Δv is whitened here). Near the optimum the noise's residual
/// bends the steps, and fitting to the fixed tolerances took 4–11 iterations.
const CONVERGED: f64 = 0.01;

/// Radii a press's size is fitted from, as multiples of its radius.
const SIZE_STARTS: [f64; 2] = [1.0, 1.6];

/// Radii a fitted press may take, as multiples of the indenter's.
const RADII: [f64; 2] = [0.5, 2.5];

/// The disk a press found is, its drop within what the exact fit takes.
pub(super) fn disk_of(press: &PressFit) -> Disk {
    Disk { centre: press.centre, radius: press.radius, drop: press.drop.clamp(0.0, DEEPEST) }
}

/// Every press found to keep the indenter's radius is tested again: what that test read of the
/// misfit, another press (since merged or widened) may have taken up.
fn retest_sizes(sizes: &mut [Size]) {
    sizes.iter_mut().filter(|s| **s == Size::Nominal).for_each(|s| *s = Size::Untested);
}

/// The presses whose radius is fitted, bit i for press i.
fn fitted(sizes: &[Size]) -> u32 {
    sizes.iter().take(32).enumerate().filter(|(_, s)| **s == Size::Fitted).fold(0, |bits, (i, _)| bits | 1 << i)
}

/// Keeps `presses` and their responses aside.
fn save(presses: &[PressFit], scratch: &mut PressScratch, m: usize) {
    scratch.saved.clear();
    scratch.saved.extend_from_slice(presses);
    scratch.saved_responses.clear();
    scratch.saved_responses.extend_from_slice(&scratch.responses[..presses.len() * m]);
}

/// The presses and responses [`save`] kept.
fn restore(presses: &mut Vec<PressFit>, scratch: &mut PressScratch, m: usize) {
    presses.clear();
    presses.extend_from_slice(&scratch.saved);
    let k = presses.len() * m;
    scratch.responses[..k].copy_from_slice(&scratch.saved_responses);
}

/// Fits per frame at most (exact ones a few solves per iteration; on the table none): past them
/// the presses stay as the last fit left them. A frame of three presses of the study's kinds
/// takes 1–6.
const REFITS: usize = 16;

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
        scratch.refine.reserve(exact.presses, MAX_PRESSES, m);
        exact.presses.reserve(&mut scratch.exact);
        room(&mut scratch.saved, MAX_PRESSES);
        room(&mut scratch.saved_responses, MAX_PRESSES * m);
        room(&mut scratch.rejected, ROUNDS);
        room(&mut scratch.sizes, MAX_PRESSES);
        room(&mut scratch.disks, MAX_PRESSES);
        room(&mut scratch.exact_at, MAX_PRESSES);
        // The fit's Jacobian's rows: four parameters a press at most (its radius fitted).
        room(&mut scratch.basis, 4 * MAX_PRESSES * m);
        scratch.sizes.clear();
        scratch.sizes.resize(presses.len(), Size::Untested);
        // Its solve is of another frame's presses, maybe on another model.
        scratch.exact_at.clear();
        self.start_on_table(exact, presses, scratch);
        let mut cost = self.refit(exact, presses, scratch)?;
        scratch.rejected.clear();
        // Counted from here: the basis's fit is one of this frame's.
        (scratch.refits, scratch.basis_of) = (0, None);
        // Whether the last exact fit (its misfit, Jacobian and solve, which the sizes' tests and
        // the search for a new press read) is of other presses than these: a candidate's,
        // refused after its fit. Kept across rounds until these presses are fitted again.
        let mut stale = false;
        for _ in 0..ROUNDS {
            // Each fit costs a few solves per iteration; a frame's work is bounded.
            if scratch.refits >= REFITS {
                break;
            }
            if let Some(weaker) = self.overlapping(presses) {
                scratch.sizes.remove(weaker);
                scratch.rejected.push(presses.remove(weaker).centre);
                (cost, stale) = (self.refit(exact, presses, scratch)?, false);
                continue;
            }
            let failing = presses
                .iter()
                .enumerate()
                .filter(|(_, p)| p.z < threshold || p.drop < MIN_DROP)
                .min_by(|a, b| a.1.z.total_cmp(&b.1.z));
            if let Some((i, _)) = failing {
                scratch.sizes.remove(i);
                scratch.rejected.push(presses.remove(i).centre);
                (cost, stale) = (self.refit(exact, presses, scratch)?, false);
                continue;
            }
            let mut changed = false;
            for i in 0..presses.len() {
                if scratch.refits >= REFITS {
                    break;
                }
                self.others_into(dv, presses, i, scratch);
                let PressScratch { residual, response, centres, correlations, .. } = &mut *scratch;
                let Some((j, _)) = self.best_point(scan, residual, centres, correlations) else { continue };
                let (p, at) = (self.grid.point(j), presses[i].centre);
                if (p[0] - at[0]).hypot(p[1] - at[1]) <= self.radius {
                    continue;
                }
                let Some(candidate) = self.fit_one(residual, p, window, response) else { continue };
                save(presses, scratch, m);
                presses[i] = candidate;
                let size = std::mem::replace(&mut scratch.sizes[i], Size::Untested);
                let on_table = scratch.on_table;
                let moved = self.fit_candidate(exact, presses, &mut cost, scratch)?;
                // Clearly better, not the same place to rounding.
                if moved < cost - 1.0 {
                    (cost, changed, stale) = (moved, true, false);
                } else {
                    // Its size as tested, if on the same fit as now.
                    scratch.sizes[i] = if scratch.on_table == on_table { size } else { Size::Untested };
                    restore(presses, scratch, m);
                    stale = true;
                }
            }
            if changed {
                continue;
            }
            // Each press's size: a wider press that the linear search split is one press again
            // if each weaker neighbour within four radii goes and the misfit grows by less than
            // that press's own test; else fitted where the misfit falls by more than a wider or
            // narrower press could by chance.
            // The sizes' test reads the last fit's misfit and Jacobian: of these presses.
            if stale {
                (cost, stale) = (self.refit(exact, presses, scratch)?, false);
            }
            let rank = fit_basis(scratch);
            // Every radius fitted: any fall of the misfit sizes a press.
            let size_test = if self.every_radius { 0.0 } else { SIZE_TEST };
            for i in 0..presses.len() {
                if scratch.sizes[i] != Size::Untested || scratch.refits >= REFITS {
                    continue;
                }
                // The score test (one derivative): only a press whose misfit leans on its size
                // is fitted for it. A weaker press near it is tested whatever the score says:
                // it may be what takes up the misfit of a press wider than the indenter.
                let zz = self.size_z(exact, presses, i, rank, scratch)?;
                let neighbour = self.weaker_neighbour(presses, i);
                let scale = misfit_scale(cost, exact, presses.len(), fitted(&scratch.sizes));
                // A press held at the deepest drop is wider than the indenter or stronger than any
                // press of its size: its size is fitted whatever the score, which reads only what
                // a radius adds to the drop the fit could not give it.
                let held = presses[i].drop >= DEEPEST;
                let questioned = zz.powi(2) >= size_test * scale || neighbour.is_some() || held;
                if questioned && scratch.on_table && exact.start.is_some() {
                    // Its size in question: the frame fitted exactly from here, every test
                    // made again on the exact fit.
                    (cost, stale) = (self.leave_table(exact, presses, scratch)?, false);
                    changed = true;
                    break;
                }
                if zz.powi(2) < size_test * scale && neighbour.is_none() && !held {
                    scratch.sizes[i] = Size::Nominal;
                    continue;
                }
                // Each weaker neighbour in turn (a wide press may have been split in three).
                let (mut at, mut merged_any, mut neighbour) = (i, false, neighbour);
                while let Some(j) = neighbour {
                    save(presses, scratch, m);
                    let size_j = scratch.sizes.remove(j);
                    presses.remove(j);
                    let i = if j < at { at - 1 } else { at };
                    let (merged, press) = self.sized(exact, presses, i, scratch)?;
                    if merged >= cost + threshold * threshold {
                        restore(presses, scratch, m);
                        scratch.sizes.insert(j, size_j);
                        stale = true;
                        break;
                    }
                    presses[i] = press;
                    scratch.sizes[i] = Size::Fitted;
                    (cost, stale) = (self.refit(exact, presses, scratch)?, false);
                    (at, merged_any) = (i, true);
                    neighbour = self.weaker_neighbour(presses, at);
                }
                if merged_any {
                    retest_sizes(&mut scratch.sizes);
                    changed = true;
                    break;
                }
                if zz.powi(2) < size_test * scale && !held {
                    scratch.sizes[i] = Size::Nominal;
                    (cost, stale) = (self.refit(exact, presses, scratch)?, false);
                    continue;
                }
                save(presses, scratch, m);
                let (sized, press) = self.sized(exact, presses, i, scratch)?;
                let sized_scale = misfit_scale(sized, exact, presses.len(), fitted(&scratch.sizes) | 1 << i);
                if cost - sized > size_test * sized_scale {
                    presses[i] = press;
                    retest_sizes(&mut scratch.sizes);
                    scratch.sizes[i] = Size::Fitted;
                    changed = true;
                } else {
                    scratch.sizes[i] = Size::Nominal;
                }
                // Back to these presses' own fit (and misfit and Jacobian).
                (cost, stale) = (self.refit(exact, presses, scratch)?, false);
            }
            if changed {
                continue;
            }
            if stale {
                (cost, stale) = (self.refit(exact, presses, scratch)?, false);
            }
            if presses.len() < MAX_PRESSES {
                // Not where a press was taken off: it would only come back.
                // The fit's own misfit: Δv less the presses' joint response (less the sum of
                // their own responses would leave how strong presses change each other's
                // field, which looks like a press between them).
                let PressScratch { residual, refine: refining, centres, .. } = &mut *scratch;
                residual.clear();
                residual.extend_from_slice(refining.residual());
                centres.clear();
                centres.extend(presses.iter().map(|p| p.centre));
                let rank = fit_basis(scratch);
                let PressScratch { residual, response, centres, correlations, unexplained, rejected, basis, .. } =
                    &mut *scratch;
                centres.extend_from_slice(rejected);
                // Each point's unexplained share only where a new press's z could pass there.
                let share = |i: usize| unexplained_at(self.grid_response(scan.points[i]), scan.norms[i], basis, rank);
                let reach = Reach { threshold, least: UNEXPLAINED_FLOOR, share };
                let best = self.best_point_reaching(scan, residual, centres, reach, unexplained, correlations);
                let new = best.filter(|(_, z)| *z >= threshold).and_then(|(j, _)| {
                    let mut press = self.fit_one(residual, self.grid.point(j), window, response)?;
                    // Its contrast in the presses' joint fit, linearised: the others give back
                    // what they took of it, so it grows by gᵀg over the part they cannot take.
                    let row = scan.row(j)?;
                    press.contrast *= scan.norms[row] / unexplained[row];
                    press.drop = self.drop(press.contrast, press.centre);
                    (press.drop >= MIN_DROP).then_some(press)
                });
                if let Some(new) = new {
                    // Kept if the presses fitted with it explain Δv better by as much as the
                    // z test asks (the likelihood ratio: χ² falls by at least threshold²).
                    save(presses, scratch, m);
                    presses.push(new);
                    scratch.sizes.push(Size::Untested);
                    let with = self.fit_candidate(exact, presses, &mut cost, scratch)?;
                    if with <= cost - threshold * threshold {
                        cost = with;
                    } else {
                        scratch.sizes.pop();
                        restore(presses, scratch, m);
                        scratch.rejected.push(new.centre);
                        // The sizes' test and the next scan read the fit of these presses.
                        cost = self.refit(exact, presses, scratch)?;
                    }
                    continue;
                }
            }
            break;
        }
        // Should the rounds run out, what is returned still passes.
        presses.retain(|p| p.z >= threshold && p.drop >= MIN_DROP);
        Ok(())
    }

    /// The score test of press `i`'s radius at the last fit: ∂χ²/∂r over its standard
    /// deviation (∂F/∂r of the presses together; where the fit read each from the table, at its
    /// one exact solve, a short step from where its last fit on the table left them, or where it
    /// made none, the table's own radius derivative of each press alone),
    /// gᵀr / |g|, g = ∂F/∂r less its part in the span of the fit's Jacobian (the first `rank`
    /// vectors of the scratch's basis), r the whitened misfit; N(0, 1) if the indenter's radius
    /// is the press's. (With ∂F/∂r itself in place of g in gᵀr, what the fit had not converged,
    /// up to a hundredth of χ² along directions tens of times g, made presses of the indenter's
    /// size fit for their size in 13 % of frames of three.)
    fn size_z(
        &self,
        exact: Exact<'_>,
        presses: &[PressFit],
        i: usize,
        rank: usize,
        scratch: &mut PressScratch,
    ) -> Result<f64, InverseError> {
        // Where the fit read each press from the table (no radius fitted), from its one exact
        // solve, where the presses were before the table's fit with that solve's correction
        // (within a short step of where they are).
        let on_table = scratch.on_table && fitted(&scratch.sizes) == 0;
        let PressScratch { disks, exact: ex, exact_at, response, refine: refining, basis, .. } = scratch;
        disks.clear();
        disks.extend(presses.iter().map(disk_of));
        // Of all of them, from the fit's own last solve where that was at these presses.
        let kept = if on_table {
            // Where the fit made no solve (presses apart), the table's: one press's alone.
            refining.derivative_near_last_solve(exact.presses, disks, i, DiskParameter::Radius, response).or_else(
                || {
                    let table = exact.table?;
                    refining.table_radius_derivative_into(table, &disks[i], response).then_some(true)
                },
            )
        } else {
            refining.derivative_at_last_solve(exact.presses, disks, i, DiskParameter::Radius, response)
        };
        // Else (a solve elsewhere: another set of presses, or moved far since) solved here, once
        // for every press's test at these presses.
        let derived = match kept {
            Some(derived) => derived,
            None => {
                if exact_at != disks {
                    solve_at(exact.presses, disks, ex, exact_at, response)?;
                }
                exact.presses.derivative_into(disks, i, DiskParameter::Radius, ex, response)
            }
        };
        if !derived {
            return Ok(0.0);
        }
        let residual = refining.residual();
        response.iter_mut().zip(exact.weights).for_each(|(d, w)| *d *= w);
        // Both along the part of ∂F/∂r the fit's own parameters cannot take up: r's part along
        // them is what the fit has not yet converged (up to a hundredth of χ²), and ∂F/∂r's part
        // along them tens of times its own (a wider press is nearly a deeper one).
        let mut along = dot(response, residual);
        let mut left = dot(response, response);
        for k in 0..rank {
            let q = &basis[k * response.len()..(k + 1) * response.len()];
            let (on, share) = (dot(response, q), dot(residual, q));
            left -= on * on;
            along -= on * share;
        }
        Ok(if left > 0.0 { along / left.sqrt() } else { 0.0 })
    }

    /// The least misfit with press `i`'s radius fitted too (and the other presses' as they are
    /// fitted), and press `i` there; `presses` are left as they were. From its radius and from
    /// a wider one of the same d·r²: a strong press fitted too narrow sits at the deepest drop,
    /// where the fit cannot widen it.
    fn sized(
        &self,
        exact: Exact<'_>,
        presses: &mut [PressFit],
        i: usize,
        scratch: &mut PressScratch,
    ) -> Result<(f64, PressFit), InverseError> {
        let k = presses.len().min(MAX_PRESSES);
        let mut base = [presses[i]; MAX_PRESSES];
        base[..k].copy_from_slice(&presses[..k]);
        let mut best = (f64::INFINITY, presses[i]);
        for widen in SIZE_STARTS {
            presses[..k].copy_from_slice(&base[..k]);
            presses[i].radius *= widen;
            presses[i].drop /= widen * widen;
            let cost = self.refit_with(exact, presses, fitted(&scratch.sizes) | 1 << i, scratch)?;
            if cost < best.0 {
                best = (cost, presses[i]);
            }
        }
        presses[..k].copy_from_slice(&base[..k]);
        Ok(best)
    }

    /// The press with a smaller z than press `i` nearest to it within four indenter radii, if any.
    fn weaker_neighbour(&self, presses: &[PressFit], i: usize) -> Option<usize> {
        let at = presses[i].centre;
        let distance = |p: &PressFit| (p.centre[0] - at[0]).hypot(p.centre[1] - at[1]);
        presses
            .iter()
            .enumerate()
            .filter(|(j, p)| *j != i && p.z < presses[i].z && distance(p) < 4.0 * self.radius)
            .min_by(|a, b| distance(a.1).total_cmp(&distance(b.1)))
            .map(|(j, _)| j)
    }

    /// Whether `presses` may be fitted on the table in `TableUse::Auto`: every one of the
    /// indenter's radius, none sized (`sizes`), each pair at least [`TABLE_START_APART`] radii
    /// apart.
    fn table_holds(&self, presses: &[PressFit], sizes: &[Size]) -> bool {
        let apart = TABLE_START_APART * self.radius;
        fitted(sizes) == 0
            && presses.iter().all(|p| p.radius == self.radius)
            && presses.iter().enumerate().all(|(i, a)| {
                presses[..i].iter().all(|b| (a.centre[0] - b.centre[0]).hypot(a.centre[1] - b.centre[1]) >= apart)
            })
    }

    /// Whether a frame's fits of `presses` (none sized yet) begin on the table: always for
    /// `TableUse::Fit`, where the table holds for them for `TableUse::Auto`, never without
    /// a table to fit on.
    pub(super) fn start_on_table(&self, exact: Exact<'_>, presses: &[PressFit], scratch: &mut PressScratch) {
        scratch.on_table = exact.table.is_some() && (exact.start.is_none() || self.table_holds(presses, &[]));
    }

    /// The frame off the table (`TableUse::Auto`): `presses` fitted exactly and every size
    /// to be tested again; their misfit.
    fn leave_table(
        &self,
        exact: Exact<'_>,
        presses: &mut [PressFit],
        scratch: &mut PressScratch,
    ) -> Result<f64, InverseError> {
        scratch.on_table = false;
        scratch.sizes.iter_mut().for_each(|s| *s = Size::Untested);
        self.refit(exact, presses, scratch)
    }

    /// The candidate `presses` fitted (those before it saved, their misfit `cost`); its misfit.
    /// Where the frame is on the table (`TableUse::Auto`) and the table does not hold for the
    /// candidate, before its fit or after it: the frame off the table, those before it fitted
    /// exactly (`cost` now theirs, and saved again), then the candidate exactly, its presses
    /// where that fit left those before it but where it put them otherwise (where its own fit
    /// left them, if it was fitted).
    fn fit_candidate(
        &self,
        exact: Exact<'_>,
        presses: &mut Vec<PressFit>,
        cost: &mut f64,
        scratch: &mut PressScratch,
    ) -> Result<f64, InverseError> {
        let on_table = scratch.on_table && exact.start.is_some();
        if on_table && !self.table_holds(presses, &scratch.sizes) {
            scratch.on_table = false;
        } else {
            let fitted = self.refit(exact, presses, scratch)?;
            if !on_table || scratch.on_table {
                return Ok(fitted);
            }
        }
        let (m, k, before) = (self.measurements, presses.len(), scratch.saved.len());
        let mut candidate = [presses[0]; MAX_PRESSES];
        candidate[..k].copy_from_slice(presses);
        // The presses the candidate moved or added (a re-placed one, a new one).
        let mut its_own = [false; MAX_PRESSES];
        for (j, own) in its_own.iter_mut().enumerate().take(k) {
            *own = scratch.saved.get(j) != Some(&candidate[j]);
        }
        scratch.sizes.truncate(before);
        restore(presses, scratch, m);
        *cost = self.leave_table(exact, presses, scratch)?;
        save(presses, scratch, m);
        presses.resize(k, candidate[0]);
        for j in (0..k).filter(|&j| j >= before || its_own[j]) {
            presses[j] = candidate[j];
        }
        scratch.sizes.resize(k, Size::Untested);
        self.refit(exact, presses, scratch)
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
    /// response (alone) into its row of the scratch's responses, and its z against Δv less the
    /// others as fitted together (the misfit with its own response put back). The misfit left
    /// (χ²).
    fn refit(
        &self,
        exact: Exact<'_>,
        presses: &mut [PressFit],
        scratch: &mut PressScratch,
    ) -> Result<f64, InverseError> {
        self.refit_with(exact, presses, fitted(&scratch.sizes), scratch)
    }

    /// [`PressModel::refit`] with the radii of `free_radii` (bit i: press i) fitted.
    pub(super) fn refit_with(
        &self,
        exact: Exact<'_>,
        presses: &mut [PressFit],
        free_radii: u32,
        scratch: &mut PressScratch,
    ) -> Result<f64, InverseError> {
        let m = self.measurements;
        scratch.refits += 1;
        let table = exact.table.filter(|_| scratch.on_table);
        let PressScratch { disks, refine: refining, responses, .. } = &mut *scratch;
        disks.clear();
        disks.extend(presses.iter().map(disk_of));
        let params = RefineParams {
            free_radii,
            radius_range: [RADII[0] * self.radius, RADII[1] * self.radius],
            bounds: self.grid.bounds(),
            converged_below: CONVERGED,
        };
        let cost = match (table, exact.start) {
            (Some(table), _) => {
                refine_tabulated(exact.presses, table, exact.dv, exact.weights, disks, &params, refining)?
            }
            (None, Some(table)) => {
                refine_from_table(exact.presses, table, exact.dv, exact.weights, disks, &params, refining)?
            }
            (None, None) => refine(exact.presses, exact.dv, exact.weights, disks, &params, refining)?,
        };
        let own = refining.own_responses();
        responses.resize(responses.len().max(presses.len() * m), 0.0);
        responses[..presses.len() * m].copy_from_slice(&own[..presses.len() * m]);
        for (press, disk) in presses.iter_mut().zip(disks.iter()) {
            (press.centre, press.radius, press.drop) = (disk.centre, disk.radius, disk.drop);
        }
        if table.is_some() && exact.start.is_some() && !self.table_holds(presses, &[]) {
            // Fitted on the table nearer each other than it holds for: the frame exact from here.
            scratch.on_table = false;
            scratch.sizes.iter_mut().for_each(|s| *s = Size::Untested);
            return self.refit_with(exact, presses, free_radii, scratch);
        }
        // Each drop's standard deviation: the fit's covariance, scaled by its misfit per degree
        // of freedom where the model's own error makes that over 1.
        room(&mut scratch.variances, MAX_PRESSES);
        let PressScratch { disks, refine: refining, variances, .. } = &mut *scratch;
        let known = refining.equivalent_drop_variances_into(disks, self.radius, variances);
        let scale = misfit_scale(cost, exact, presses.len(), free_radii);
        for (i, press) in presses.iter_mut().enumerate() {
            press.equivalent_drop_std = if known { Some((scale * variances[i]).sqrt()) } else { None };
        }
        // Each press's z against the fit's misfit with its own response put back: Δv less the
        // others as they are together.
        let misfit = scratch.refine.residual();
        for (i, press) in presses.iter_mut().enumerate() {
            let g = &scratch.responses[i * m..(i + 1) * m];
            let gg = dot(g, g);
            let gr = dot(g, misfit) + gg;
            press.z = if gg > 0.0 { gr / gg.sqrt() } else { 0.0 };
        }
        Ok(cost)
    }
}

#[cfg(test)]
mod tests {
    use super::super::refine::tests::setup;
    use super::super::{PressDetection, PressModelParams, TableUse};
    use super::*;

    /// Two presses 40 mm apart, begun on the table 55 mm apart (the second 15 mm off): the fit on
    /// the table brings them nearer than it holds for, and the frame leaves it, both presses
    /// found and fitted exactly (an exact fit from there stays where it is, to the bit).
    #[test]
    fn presses_fitted_nearer_on_the_table_take_the_frame_off_it() {
        let params = PressModelParams::default();
        let truth = [[-0.06, 0.05], [-0.06, 0.01]];
        let (model, _, v0, dv) = setup(1500, &truth.map(|centre| Disk { centre, radius: params.radius, drop: 0.7 }));
        let auto = PressModel::new(&model, 1.0, &params).unwrap().with_table_use(Some(TableUse::Auto)).unwrap();
        let std: Vec<f64> = v0.iter().map(|v| 5e-4 * v.abs()).collect();
        let detection = PressDetection::new(&auto, &std, f64::INFINITY, 1e-3).unwrap();
        let mut whitened = Vec::new();
        detection.whiten_into(&dv, &mut whitened).unwrap();
        let exact = detection.exact(&dv).unwrap();
        let start = |centre| PressFit {
            centre,
            radius: params.radius,
            contrast: 1.0,
            drop: 0.7,
            z: 100.0,
            equivalent_drop_std: None,
        };
        let (mut presses, mut scratch) = (vec![start(truth[0]), start([-0.06, -0.005])], PressScratch::default());
        let threshold = detection.threshold;
        auto.fit_jointly(&detection.scan, &whitened, threshold, exact, &mut presses, &mut scratch).unwrap();
        assert!(!scratch.on_table);
        assert_eq!(presses.len(), 2, "{presses:?}");
        for at in truth {
            let near = presses.iter().any(|p| (p.centre[0] - at[0]).hypot(p.centre[1] - at[1]) < 0.003);
            assert!(near, "{at:?}: {presses:?}");
        }
        // The last fit exact: fitted exactly again from there, the same presses to the bit.
        let places = |p: &[PressFit]| p.iter().map(|p| (p.centre, p.drop, p.radius)).collect::<Vec<_>>();
        let before = places(&presses);
        auto.refit(exact, &mut presses, &mut scratch).unwrap();
        assert!(!scratch.on_table);
        assert_eq!(before, places(&presses));
    }
}
