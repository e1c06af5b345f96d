//! The exact Δv of flat presses anywhere on the sheet, at any depth and size: the background's
//! one factorisation updated on the triangles under them ([`LowRankUpdate`]), so that presses
//! are fitted to Δv with the physics' own response rather than its linearisation read off a grid.
//!
//! The linear table ([`super::PressModel`]) is what finds presses: a scan of the whole sheet is
//! one product. But next to the electrodes a press's response changes within a grid step, and a
//! strong press's response differs in shape from its linearisation, both by 10–50 % of its
//! norm with each channel weighed by its noise; what is left of a strong press then looks like
//! another, weak one, and biases every other press's drop. The exact response leaves nothing
//! of a flat press.

use super::detect::MAX_PRESSES;
use crate::conductivity::{box_distance_squared, circle_triangle_area_gradient, covered_whole};
use crate::forward::{ChangeScratch, ForwardError, ForwardModel, LowRankUpdate};
use crate::mesh::TriangleBuckets;
use crate::scratch::room;

/// A flat press: a disk where the conductivity is lowered by a share of the background.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Disk {
    /// Centre, in m.
    pub centre: [f64; 2],
    /// Radius, in m.
    pub radius: f64,
    /// Conductivity drop under it, as a fraction of the background (0 to 1).
    pub drop: f64,
}

impl Disk {
    /// The drop of a disk of radius `radius` (m) with this disk's polarisation, and its
    /// derivatives along this disk's drop and radius (per m).
    ///
    /// A disk of radius r whose conductivity is lowered by d adds to a uniform field the dipole
    /// of strength r²·d/(2−d) (the contrast factor of a disk, (σ₀−σ₁)/(σ₀+σ₁), times its area):
    /// the far field Δv fixes best, whatever trade of drop against radius a fit makes. So a
    /// press fitted wider than the indenter reads on the same scale as one fitted at the
    /// indenter's radius, continuously where the fit starts sizing it (drop × area, exact
    /// only for shallow presses, jumps there). Equal to the drop at `radius` itself; a drop
    /// past 1 (a conductivity below 0, which a fit on linear responses may extrapolate to) is
    /// read as 1.
    pub fn equivalent_drop(&self, radius: f64) -> (f64, [f64; 2]) {
        let d = self.drop.min(1.0);
        let area = (self.radius / radius).powi(2);
        let q = area * d / (2.0 - d);
        let dq = [
            if self.drop < 1.0 { area * 2.0 / (2.0 - d).powi(2) } else { 0.0 },
            2.0 * self.radius / (radius * radius) * d / (2.0 - d),
        ];
        let outer = 2.0 / (1.0 + q).powi(2);
        (2.0 * q / (1.0 + q), [outer * dq[0], outer * dq[1]])
    }
}

/// Exact responses of flat presses on one sensor at a homogeneous background.
#[derive(Debug, Clone)]
pub struct ExactPresses {
    update: LowRankUpdate,
    buckets: TriangleBuckets,
    /// Per triangle of the mesh, its corners (m) and area (m²), side by side: read for every
    /// triangle near a press at every solve.
    shapes: Vec<([[f64; 2]; 3], f64)>,
    background: f64,
    /// Per channel, the factor from this model's values to those Δv is given in (1 unless
    /// [`ExactPresses::scaled_to`] another mesh of the sensor).
    scale: Vec<f64>,
}

/// Buffers of [`ExactPresses::response_into`] and [`ExactPresses::derivative_into`].
#[derive(Debug, Clone, Default)]
pub struct ExactScratch {
    /// One solve per group of presses solved together (all of them, or each alone).
    groups: Vec<ChangeScratch>,
    changes: Vec<(usize, f64)>,
    near: Vec<usize>,
    part: Vec<f64>,
    /// The triangles each disk's edge crosses or covers, for its response and its derivatives.
    edges: DiskEdges,
    /// The disks the last response solved together (one solve, `groups[0]`); empty where it
    /// solved them apart or failed.
    together: Vec<Disk>,
}

/// The triangles each disk (centre and radius) covers or crosses, with each crossed one's
/// covered area and its gradient: what a press's share of each triangle and every derivative of
/// it need, computed once at each [`ExactPresses::response_into`], which the derivatives follow.
#[derive(Debug, Clone, Default)]
struct DiskEdges {
    /// Per disk, the centre and radius its triangles are of (`None`: not computed).
    of: Vec<Option<([f64; 2], f64)>>,
    /// Per disk, where its triangles start (one more entry than disks).
    start: Vec<usize>,
    triangles: Vec<EdgeTriangle>,
}

/// (triangle, its area, covered whole, covered area and its gradient along x, y, radius), in
/// m² and m² per m.
type EdgeTriangle = (usize, f64, bool, f64, [f64; 3]);

impl DiskEdges {
    fn clear(&mut self) {
        self.of.clear();
        self.start.clear();
        self.start.push(0);
        self.triangles.clear();
    }

    /// The next disk's triangles, `disk`'s (`near` a buffer).
    fn push(&mut self, exact: &ExactPresses, disk: &Disk, near: &mut Vec<usize>) {
        exact.each_triangle(disk, near, |t, corners, area| match Overlap::of(corners, disk) {
            Overlap::Outside => {}
            Overlap::Inside => self.triangles.push((t, area, true, area, [0.0; 3])),
            Overlap::Crossing => {
                let (overlap, gradient) = circle_triangle_area_gradient(disk.centre, disk.radius, corners);
                self.triangles.push((t, area, false, overlap, gradient));
            }
        });
        self.of.push(Some((disk.centre, disk.radius)));
        self.start.push(self.triangles.len());
    }

    /// Disk `k`'s triangles that it changes, with the share of each it covers: rounding leaves
    /// a share of about 1e-16 on some triangles the disk misses, which are left out.
    fn shares(&self, k: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        self.triangles[self.start[k]..self.start[k + 1]].iter().filter_map(|&(t, area, inside, overlap, _)| {
            let share = if inside { 1.0 } else { (overlap / area).min(1.0) };
            (share > 1e-9).then_some((t, share))
        })
    }

    /// Disk `k`'s triangles, if they were computed for `disk`'s centre and radius.
    fn of_disk(&self, k: usize, disk: &Disk) -> Option<&[EdgeTriangle]> {
        let computed = self.of.get(k).copied().flatten() == Some((disk.centre, disk.radius));
        computed.then(|| &self.triangles[self.start[k]..self.start[k + 1]])
    }
}

/// A parameter of a [`Disk`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DiskParameter {
    /// Centre x, in m.
    X,
    /// Centre y, in m.
    Y,
    /// Drop (fraction of the background).
    Drop,
    /// Radius, in m.
    Radius,
}

/// Presses solved together at most; more are solved each alone and their responses added (two
/// presses 50 mm apart change each other's Δv by about 1 %).
pub const JOINT_PRESSES: usize = 4;

impl ExactPresses {
    /// The exact responses of `model`'s presses at the homogeneous `background` (S/m), from
    /// `update` (made at that background).
    pub fn new(update: LowRankUpdate, background: f64) -> ExactPresses {
        let mesh = update.model().mesh();
        let buckets = TriangleBuckets::new(mesh);
        let shapes = (0..mesh.triangles().len()).map(|t| (mesh.corners(t), mesh.area(t))).collect();
        let scale = vec![1.0; update.background_measurements().len()];
        ExactPresses { update, buckets, shapes, background, scale }
    }

    /// The same responses in the units of `values`, another model's measurements of the same
    /// sensor at the same background (V): each channel's response times its value there over v₀, so a
    /// coarser mesh's exact responses serve a finer model's Δv. A channel whose value here is 0
    /// or not finite keeps its scale of 1.
    pub fn scaled_to(mut self, values: &[f64]) -> ExactPresses {
        for ((s, v), own) in self.scale.iter_mut().zip(values).zip(self.update.background_measurements()) {
            let ratio = v / own;
            *s = if ratio.is_finite() && ratio != 0.0 { ratio } else { 1.0 };
        }
        self
    }

    /// The forward model.
    pub fn model(&self) -> &ForwardModel {
        self.update.model()
    }

    /// Values per response.
    pub fn measurements(&self) -> usize {
        self.scale.len()
    }

    /// The measurements at the background, in V (protocol order).
    pub fn background_measurements(&self) -> &[f64] {
        self.update.background_measurements()
    }

    /// Grows `scratch` at once to what any presses can need (every triangle changed), so that the
    /// frame path does not allocate when a press first grows wider.
    pub fn reserve(&self, scratch: &mut ExactScratch) {
        let triangles = self.update.model().mesh().triangles().len();
        room(&mut scratch.changes, triangles);
        room(&mut scratch.near, triangles);
        room(&mut scratch.part, self.update.background_measurements().len());
        room(&mut scratch.edges.triangles, triangles);
        room(&mut scratch.edges.of, MAX_PRESSES);
        room(&mut scratch.edges.start, MAX_PRESSES + 1);
        room(&mut scratch.together, MAX_PRESSES);
        for group in &mut scratch.groups {
            group.reserve(self.update.model().system_size());
        }
    }

    /// Whether presses are solved together, each one's field on the others included (the
    /// inverse is kept whole); else each alone and their responses added.
    pub fn joint(&self) -> bool {
        self.update.keeps_inverse()
    }

    /// Whether `count` presses are solved together: on a model that keeps the inverse, up to
    /// [`JOINT_PRESSES`] (the solve grows as the cube of their rows).
    fn together(&self, count: usize) -> bool {
        self.joint() && count <= JOINT_PRESSES
    }

    /// Calls `push` with each triangle (index, corners, area) whose bounding box may meet `disk`,
    /// each once; `near` is a buffer.
    fn each_triangle(&self, disk: &Disk, near: &mut Vec<usize>, mut push: impl FnMut(usize, [[f64; 2]; 3], f64)) {
        let [x, y] = disk.centre;
        let r = disk.radius;
        self.buckets.near_once_into([x - r, y - r], [x + r, y + r], near);
        for &t in near.iter() {
            let (corners, area) = self.shapes[t];
            push(t, corners, area);
        }
    }

    /// Δv (V, protocol order) of `disks` pressed together, into `out`. Allocates nothing once
    /// `scratch` has grown (on a model whose inverse is kept, see [`LowRankUpdate`]).
    pub fn response_into(
        &self,
        disks: &[Disk],
        scratch: &mut ExactScratch,
        out: &mut [f64],
    ) -> Result<(), ForwardError> {
        let ExactScratch { groups, changes, near, part, edges, together: solved_together } = scratch;
        solved_together.clear();
        // Each disk's triangles, for its shares and for the derivatives that follow.
        edges.clear();
        for disk in disks {
            edges.push(self, disk, near);
        }
        let together = self.together(disks.len());
        let groups_needed = if together { 1 } else { disks.len() };
        while groups.len() < groups_needed {
            let mut group = ChangeScratch::default();
            group.reserve(self.update.model().system_size());
            groups.push(group);
        }
        out.fill(0.0);
        part.resize(out.len(), 0.0);
        for (g, group) in groups.iter_mut().enumerate().take(groups_needed) {
            let members = if together { 0..disks.len() } else { g..g + 1 };
            changes.clear();
            for k in members {
                let drop = disks[k].drop;
                changes.extend(edges.shares(k).map(|(t, share)| (t, -self.background * drop * share)));
            }
            if changes.is_empty() {
                // Nothing to solve: no solve left here for the derivatives to read.
                group.forget();
                continue;
            }
            self.update.measurement_change_into(changes, group, part)?;
            out.iter_mut().zip(part.iter()).for_each(|(o, p)| *o += p);
            if together {
                solved_together.extend_from_slice(disks);
            }
        }
        out.iter_mut().zip(&self.scale).for_each(|(o, s)| *o *= s);
        Ok(())
    }

    /// Δv (V, protocol order) of `disks[k]` pressed alone, into `out`, from the last
    /// [`ExactPresses::response_into`] with `scratch`, which must have been of `disks`: where
    /// they were solved together, their interiors eliminated, and press `k`'s triangles are a
    /// part of that change of their own (touching no other press's), its rim's system solved
    /// again from that solve's pieces ([`LowRankUpdate::part_change_into`]): what a response of
    /// it alone gives, to the bit, in a fraction of its time. `false` (and `out` untouched)
    /// where not; the solve's derivatives are kept either way.
    pub fn alone_into(&self, disks: &[Disk], k: usize, scratch: &mut ExactScratch, out: &mut [f64]) -> bool {
        let ExactScratch { groups, part, edges, together, .. } = scratch;
        let solved_here = together.as_slice() == disks
            && k < disks.len()
            && edges.start.len() == disks.len() + 1
            && disks.iter().enumerate().all(|(i, disk)| edges.of_disk(i, disk).is_some());
        let Some(group) = groups.first_mut().filter(|_| solved_here) else { return false };
        let update = &self.update;
        let part_of = |t: usize| update.part_holding(group, t);
        // Press k's part: the one all its triangles are in, and none of any other press's.
        let Some(own) = edges.shares(k).next().and_then(|(t, _)| part_of(t)) else { return false };
        let alone = edges.shares(k).all(|(t, _)| part_of(t) == Some(own))
            && (0..disks.len()).filter(|&i| i != k).all(|i| edges.shares(i).all(|(t, _)| part_of(t) != Some(own)));
        part.resize(out.len(), 0.0);
        if !alone || !update.part_change_into(own, group, part) {
            return false;
        }
        // As a response of it alone adds it: onto 0, then scaled.
        out.iter_mut().zip(part.iter()).zip(&self.scale).for_each(|((o, p), s)| *o = (0.0 + p) * s);
        true
    }

    /// The derivative of Δv (V per unit of the parameter, protocol order) along `parameter`
    /// of `disks[i]`, into `out`, at the `disks` the last [`ExactPresses::response_into`] with
    /// `scratch` was given (exact: the adjoint Jacobian from that solve, and the covered shares'
    /// own derivatives, [`circle_triangle_area_gradient`]). `false` if that solve was done in
    /// full, not by the update.
    pub fn derivative_into(
        &self,
        disks: &[Disk],
        i: usize,
        parameter: DiskParameter,
        scratch: &mut ExactScratch,
        out: &mut [f64],
    ) -> bool {
        let ExactScratch { groups, changes, near, edges, .. } = scratch;
        let disk = disks[i];
        let Some(group) = groups.get_mut(if self.together(disks.len()) { 0 } else { i }) else { return false };
        let scale = -self.background;
        // Computed by the response these derivatives follow; else (a disk it was not given)
        // computed here, as disk i alone.
        if edges.of_disk(i, &disk).is_none() {
            edges.clear();
            for _ in 0..i {
                edges.of.push(None);
                edges.start.push(0);
            }
            edges.push(self, &disk, near);
        }
        let Some(triangles) = edges.of_disk(i, &disk) else { return false };
        changes.clear();
        for &(t, area, inside, overlap, gradient) in triangles {
            let rate = match (inside, parameter) {
                (true, DiskParameter::Drop) => 1.0,
                // A triangle the disk's edge does not cross keeps its share.
                (true, _) => 0.0,
                (false, DiskParameter::Drop) => (overlap / area).min(1.0),
                (false, DiskParameter::X) => disk.drop * gradient[0] / area,
                (false, DiskParameter::Y) => disk.drop * gradient[1] / area,
                (false, DiskParameter::Radius) => disk.drop * gradient[2] / area,
            };
            if rate.abs() > 0.0 && rate.is_finite() {
                changes.push((t, scale * rate));
            }
        }
        let done = self.update.derivative_into(changes, group, out);
        out.iter_mut().zip(&self.scale).for_each(|(o, s)| *o *= s);
        done
    }
}

/// Where a triangle lies against a disk's edge.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Overlap {
    /// Every corner inside the disk: the whole triangle is covered.
    Inside,
    /// Nothing of the triangle is within the disk.
    Outside,
    /// The disk's edge crosses the triangle (or touches it).
    Crossing,
}

impl Overlap {
    fn of(corners: [[f64; 2]; 3], disk: &Disk) -> Overlap {
        let (centre, squared) = (disk.centre, disk.radius * disk.radius);
        // Its box farther from the centre than the radius, by more than rounding: outside, as the
        // edges' distances would find (a third of a disk's triangles, in its box's corners).
        if box_distance_squared(centre, corners) > squared * (1.0 + 1e-9) {
            return Overlap::Outside;
        }
        Overlap::by_edges(corners, disk)
    }

    /// [`Overlap::of`] from the corners' and the edges' distances to the centre alone.
    fn by_edges(corners: [[f64; 2]; 3], disk: &Disk) -> Overlap {
        let (centre, squared) = (disk.centre, disk.radius * disk.radius);
        let distance2 = |p: [f64; 2]| (p[0] - centre[0]).powi(2) + (p[1] - centre[1]).powi(2);
        if covered_whole(centre, disk.radius, corners) {
            return Overlap::Inside;
        }
        // Outside: the centre is farther than the radius from each edge and not in the triangle.
        let edge_distance2 = |a: [f64; 2], b: [f64; 2]| {
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let t = (((centre[0] - a[0]) * dx + (centre[1] - a[1]) * dy) / (dx * dx + dy * dy)).clamp(0.0, 1.0);
            distance2([a[0] + t * dx, a[1] + t * dy])
        };
        let near_edge = (0..3).any(|k| edge_distance2(corners[k], corners[(k + 1) % 3]) <= squared);
        if near_edge || crate::mesh::barycentric(corners, centre).iter().all(|&w| w >= 0.0) {
            Overlap::Crossing
        } else {
            Overlap::Outside
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::conductivity::{with_inclusions, Inclusion};
    use crate::SensorSpec;

    /// The paper's sensor meshed at about `triangles`, and its exact presses at a background of
    /// 1 S/m.
    fn paper_sensor(triangles: usize) -> (ForwardModel, ExactPresses) {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = triangles;
        let model = spec.forward_model().unwrap();
        let update = LowRankUpdate::new(&model, &vec![1.0; model.mesh().triangles().len()]).unwrap();
        (model, ExactPresses::new(update, 1.0))
    }

    /// A 15 mm press read as a 10 mm one: the 10 mm drop whose exact response is closest to
    /// the wide press's is the one of the same polarisation, within 0.03, and not the one of
    /// the same drop × area, for a shallow and a deep press; the derivatives are central
    /// differences of the value; at its own radius the value is the drop.
    #[test]
    fn the_equivalent_drop_keeps_the_polarisation_the_response_reads() {
        let (model, exact) = paper_sensor(3000);
        let mut scratch = ExactScratch::default();
        let m = model.measure(&vec![1.0; model.mesh().triangles().len()]).unwrap().len();
        let (mut wide_dv, mut narrow_dv) = (vec![0.0; m], vec![0.0; m]);
        // Drop × area off by 0.05 and 0.22 for these.
        for (drop, apart) in [(0.2, 0.03), (0.45, 0.1)] {
            let wide = Disk { centre: [0.03, -0.02], radius: 0.015, drop };
            exact.response_into(&[wide], &mut scratch, &mut wide_dv).unwrap();
            let misfit = |d: f64, scratch: &mut ExactScratch, narrow_dv: &mut Vec<f64>| {
                exact.response_into(&[Disk { radius: 0.01, drop: d, ..wide }], scratch, narrow_dv).unwrap();
                narrow_dv.iter().zip(&wide_dv).map(|(a, b)| (a - b).powi(2)).sum::<f64>()
            };
            let best = (0..=980)
                .map(|k| f64::from(k) / 1000.0)
                .min_by(|a, b| {
                    misfit(*a, &mut scratch, &mut narrow_dv).total_cmp(&misfit(*b, &mut scratch, &mut narrow_dv))
                })
                .unwrap();
            let (equivalent, _) = wide.equivalent_drop(0.01);
            let by_area = drop * 2.25;
            assert!((best - equivalent).abs() < 0.03, "drop {drop}: best {best}, equivalent {equivalent}");
            assert!((best - by_area).abs() > apart, "drop {drop}: best {best}, drop × area {by_area}");
        }
        let disk = Disk { centre: [0.0; 2], radius: 0.013, drop: 0.6 };
        assert!((Disk { radius: 0.01, ..disk }.equivalent_drop(0.01).0 - 0.6).abs() < 1e-15);
        let (_, gradient) = disk.equivalent_drop(0.01);
        let h = 1e-6;
        let value = |d: Disk| d.equivalent_drop(0.01).0;
        let by_drop = (value(Disk { drop: 0.6 + h, ..disk }) - value(Disk { drop: 0.6 - h, ..disk })) / (2.0 * h);
        let by_radius =
            (value(Disk { radius: 0.013 + h, ..disk }) - value(Disk { radius: 0.013 - h, ..disk })) / (2.0 * h);
        assert!((gradient[0] - by_drop).abs() < 1e-6 * by_drop.abs(), "{gradient:?} {by_drop}");
        assert!((gradient[1] - by_radius).abs() < 1e-6 * by_radius.abs(), "{gradient:?} {by_radius}");
    }

    /// Against full solves of the same presses: one, two at once, at an edge, a wide one.
    #[test]
    fn responses_are_full_solves() {
        let (model, exact) = paper_sensor(800);
        let v0 = model.measure(&vec![1.0; model.mesh().triangles().len()]).unwrap();
        let disk = |centre, radius, drop| Disk { centre, radius, drop };
        let cases = [
            vec![disk([0.01, -0.02], 0.01, 0.8)],
            vec![disk([-0.05, 0.04], 0.01, 0.3), disk([0.04, 0.05], 0.015, 0.6)],
            vec![disk([0.095, -0.06], 0.008, 0.5)],
        ];
        let mut scratch = ExactScratch::default();
        let mut dv = vec![0.0; v0.len()];
        for disks in &cases {
            exact.response_into(disks, &mut scratch, &mut dv).unwrap();
            let inclusions: Vec<Inclusion> = disks
                .iter()
                .map(|d| Inclusion { centre: d.centre, radius: d.radius, conductivity: 1.0 - d.drop })
                .collect();
            let solved = model.measure(&with_inclusions(model.mesh(), 1.0, &inclusions)).unwrap();
            let scale = dv.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
            assert!(scale > 0.0);
            for (m, (d, (v, v0))) in dv.iter().zip(solved.iter().zip(&v0)).enumerate() {
                assert!((d - (v - v0)).abs() < 1e-9 * scale, "{disks:?}, m {m}: {d} vs {}", v - v0);
            }
        }
        // Derivatives against central differences of the responses themselves.
        let disks = [disk([0.02, -0.01], 0.01, 0.7), disk([-0.05, 0.03], 0.012, 0.4)];
        let (mut up, mut down, mut derivative) = (dv.clone(), dv.clone(), dv.clone());
        for i in 0..2 {
            for (parameter, h) in [
                (DiskParameter::X, 1e-5),
                (DiskParameter::Y, 1e-5),
                (DiskParameter::Drop, 1e-5),
                (DiskParameter::Radius, 1e-5),
            ] {
                let nudged = |sign: f64| {
                    let mut d = disks;
                    match parameter {
                        DiskParameter::X => d[i].centre[0] += sign * h,
                        DiskParameter::Y => d[i].centre[1] += sign * h,
                        DiskParameter::Drop => d[i].drop += sign * h,
                        DiskParameter::Radius => d[i].radius += sign * h,
                    }
                    d
                };
                exact.response_into(&nudged(1.0), &mut scratch, &mut up).unwrap();
                exact.response_into(&nudged(-1.0), &mut scratch, &mut down).unwrap();
                exact.response_into(&disks, &mut scratch, &mut dv).unwrap();
                assert!(exact.derivative_into(&disks, i, parameter, &mut scratch, &mut derivative));
                let scale = derivative.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
                for (m, (d, (u, w))) in derivative.iter().zip(up.iter().zip(&down)).enumerate() {
                    let difference = (u - w) / (2.0 * h);
                    assert!((d - difference).abs() < 1e-4 * scale, "{i} {parameter:?} m {m}: {d} vs {difference}");
                }
            }
        }
        // Without the whole inverse (a large model): each press alone, exact, their responses
        // added; two presses 100 mm apart barely interact.
        let near = ExactPresses::new(
            LowRankUpdate::new(&model, &vec![1.0; model.mesh().triangles().len()]).unwrap().near_only(0.06),
            1.0,
        );
        assert!(!near.joint());
        let mut alone = dv.clone();
        near.response_into(&cases[1], &mut scratch, &mut alone).unwrap();
        exact.response_into(&cases[1], &mut scratch, &mut dv).unwrap();
        let scale = dv.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
        assert!(alone.iter().zip(&dv).all(|(a, d)| (a - d).abs() < 2e-2 * scale));
        assert!(near.derivative_into(&cases[1], 1, DiskParameter::Drop, &mut scratch, &mut derivative));
        assert!(derivative.iter().any(|d| *d != 0.0));
        // Nothing pressed: no change.
        exact.response_into(&[], &mut scratch, &mut dv).unwrap();
        assert!(dv.iter().all(|d| *d == 0.0));
    }

    /// Each press's response alone read from a joint solve of several is a response of it alone,
    /// to the bit (its channels scaled as another mesh's); the solve's derivatives are unchanged
    /// by the read; where two presses touch (one part of the change), for other disks than the
    /// solve's, or after a solve of one press, there is none.
    #[test]
    fn a_press_alone_from_the_joint_solve_is_its_own_solve() {
        let (model, exact) = paper_sensor(3000);
        let exact = exact.scaled_to(&vec![2.0; model.protocol().measurements().len()]);
        let m = exact.measurements();
        let disk = |centre: [f64; 2], radius: f64, drop: f64| Disk { centre, radius, drop };
        let apart = [disk([-0.05, 0.04], 0.01, 0.3), disk([0.04, 0.05], 0.015, 0.6), disk([0.03, -0.06], 0.01, 0.9)];
        let (mut joint, mut alone) = (ExactScratch::default(), ExactScratch::default());
        let (mut dv, mut read, mut solved) = (vec![0.0; m], vec![0.0; m], vec![0.0; m]);
        exact.response_into(&apart, &mut joint, &mut dv).unwrap();
        let (mut before, mut after) = (vec![0.0; m], vec![0.0; m]);
        assert!(exact.derivative_into(&apart, 1, DiskParameter::X, &mut joint, &mut before));
        for k in 0..apart.len() {
            assert!(exact.alone_into(&apart, k, &mut joint, &mut read), "press {k}");
            exact.response_into(&apart[k..=k], &mut alone, &mut solved).unwrap();
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&read), bits(&solved), "press {k}");
            assert!(read.iter().any(|v| *v != 0.0));
        }
        assert!(exact.derivative_into(&apart, 1, DiskParameter::X, &mut joint, &mut after));
        assert_eq!(before, after);
        // Other disks than the solve's (moved, or only deeper): no read.
        let moved = [apart[0], disk([0.041, 0.05], 0.015, 0.6), apart[2]];
        let deeper = [apart[0], disk([0.04, 0.05], 0.015, 0.7), apart[2]];
        read.fill(7.0);
        assert!(!exact.alone_into(&moved, 1, &mut joint, &mut read));
        assert!(!exact.alone_into(&deeper, 1, &mut joint, &mut read));
        assert!(read.iter().all(|v| *v == 7.0));
        // After a derivative of a disk the solve was not of: none either.
        assert!(exact.derivative_into(&apart[1..2], 0, DiskParameter::X, &mut joint, &mut after));
        assert!(!exact.alone_into(&apart[1..2], 0, &mut joint, &mut read));
        // Two presses whose triangles touch are one part: neither is read, the third is.
        let touching = [apart[0], disk([-0.05 + 0.019, 0.04], 0.01, 0.5), apart[2]];
        exact.response_into(&touching, &mut joint, &mut dv).unwrap();
        assert!(!exact.alone_into(&touching, 0, &mut joint, &mut read));
        assert!(!exact.alone_into(&touching, 1, &mut joint, &mut read));
        assert!(exact.alone_into(&touching, 2, &mut joint, &mut read));
        // A single press's solve is not of several.
        exact.response_into(&apart[..1], &mut joint, &mut dv).unwrap();
        assert!(!exact.alone_into(&apart, 0, &mut joint, &mut read));
    }

    /// Derivatives read one after another from one solve (a fit's Jacobian, the size tests of
    /// each press in turn) are each what a new solve of the same presses gives, to the bit.
    #[test]
    fn derivatives_read_in_turn_are_those_of_a_new_solve() {
        let (_, exact) = paper_sensor(3000);
        let m = exact.measurements();
        let disk = |centre: [f64; 2], drop: f64| Disk { centre, radius: 0.01, drop };
        let presses = [disk([-0.05, 0.04], 0.3), disk([0.04, 0.05], 0.6), disk([0.03, -0.06], 0.9)];
        let parameters = [DiskParameter::Radius, DiskParameter::X, DiskParameter::Y, DiskParameter::Drop];
        let (mut kept, mut dv) = (ExactScratch::default(), vec![0.0; m]);
        let (mut in_turn, mut fresh) = (vec![0.0; m], vec![0.0; m]);
        exact.response_into(&presses, &mut kept, &mut dv).unwrap();
        for i in (0..presses.len()).rev() {
            for parameter in parameters {
                assert!(exact.derivative_into(&presses, i, parameter, &mut kept, &mut in_turn));
                let mut new = ExactScratch::default();
                exact.response_into(&presses, &mut new, &mut dv).unwrap();
                assert!(exact.derivative_into(&presses, i, parameter, &mut new, &mut fresh));
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&in_turn), bits(&fresh), "press {i}, {parameter:?}");
                assert!(in_turn.iter().any(|v| *v != 0.0));
            }
        }
    }

    /// A triangle found outside a disk has none of it (to rounding: under the least share a
    /// press changes, 1e-9) and is outside by the edges' distances too, one inside is covered
    /// whole: over triangles of every size and place around a disk, a quarter of them moved
    /// until their box's nearest point is on its circle.
    #[test]
    fn a_triangle_outside_has_none_of_the_disk() {
        use crate::conductivity::{circle_triangle_area, triangle_box};
        use rand::{RngExt, SeedableRng};
        let mut rng = crate::SeededRng::seed_from_u64(11);
        let disk = Disk { centre: [0.01, -0.02], radius: 0.01, drop: 0.5 };
        let mut counts = [0; 3];
        for k in 0..20_000 {
            let at = [rng.random_range(-0.01..0.03), rng.random_range(-0.04..0.0)];
            let size = rng.random_range(1e-4..0.02);
            let mut corners: [[f64; 2]; 3] =
                std::array::from_fn(|_| [at[0] + size * rng.random::<f64>(), at[1] + size * rng.random::<f64>()]);
            // Counter-clockwise, as the mesh's.
            let signed = (corners[1][0] - corners[0][0]) * (corners[2][1] - corners[0][1])
                - (corners[2][0] - corners[0][0]) * (corners[1][1] - corners[0][1]);
            if signed < 0.0 {
                corners.swap(1, 2);
            }
            // Every fourth moved so that its box's nearest point lies on the circle.
            if k % 4 == 0 {
                let [x_lo, y_lo, x_hi, y_hi] = triangle_box(corners);
                let nearest = [disk.centre[0].clamp(x_lo, x_hi), disk.centre[1].clamp(y_lo, y_hi)];
                let (dx, dy) = (nearest[0] - disk.centre[0], nearest[1] - disk.centre[1]);
                let distance = dx.hypot(dy);
                if distance > 0.0 {
                    let shift = disk.radius / distance - 1.0;
                    corners.iter_mut().for_each(|c| *c = [c[0] + shift * dx, c[1] + shift * dy]);
                }
            }
            let area = circle_triangle_area(disk.centre, disk.radius, corners);
            let whole = circle_triangle_area(disk.centre, 1.0, corners);
            // Where the box's test says outside, the edges' says so too: the same triangles kept.
            if matches!(Overlap::of(corners, &disk), Overlap::Outside) {
                assert!(matches!(Overlap::by_edges(corners, &disk), Overlap::Outside), "{corners:?}");
            }
            match Overlap::of(corners, &disk) {
                Overlap::Outside => assert!(area.abs() <= 1e-9 * whole, "{corners:?}: {area} of {whole}"),
                Overlap::Inside => assert!((area - whole).abs() <= 1e-9 * whole, "{corners:?}: {area} of {whole}"),
                Overlap::Crossing => {}
            }
            counts[match Overlap::of(corners, &disk) {
                Overlap::Outside => 0,
                Overlap::Inside => 1,
                Overlap::Crossing => 2,
            }] += 1;
        }
        assert!(counts.iter().all(|&c| c > 1000), "{counts:?}");
    }
}
