//! The measurements after a change of conductivity on a few triangles, exactly, from the
//! background's one factorisation: a low-rank (Woodbury) update instead of a new solve.
//!
//! A press changes the conductivity of the few dozen triangles under the indenter, so the system
//! matrix changes only on the rows R of their nodes: K = K₀ + ΔK with ΔK = Σ_t δσ_t·K_t
//! supported on R × R (K_t the triangle's stiffness, thickness included). With G = K₀⁻¹, the new
//! field of a current pattern restricted to R solves (I + G_RR·ΔK_RR)·u_R = u₀_R, and
//! reciprocity gives every measurement from it: the voltage of electrode a less electrode L,
//! under basis pattern p, changes by −u₀_R,aᵀ·ΔK_RR·u_R,p. So with U the background's basis
//! fields on R,
//!
//!   ΔV = −U_Rᵀ·ΔK_RR·(I + G_RR·ΔK_RR)⁻¹·U_R,   Δv_m = w_mᵀ·ΔV·I_m,
//!
//! (w_m the measurement's weights and I_m its stimulation's currents on the basis e_p − e_L):
//! one system per change, exact up to rounding however strong the change. The rows of nodes
//! inside the change (every triangle of theirs changed, none on the boundary) are first
//! eliminated from K₀ and K₁ alike (`interior`), which leaves a change ΔS on the change's rim Γ
//! alone: the system solved is |Γ| × |Γ| and G is read on Γ × Γ only (97 of 231 rows for three
//! presses on the virtual sensor's truth mesh). That is done where the change has an interior
//! and its changed conductivity is positive there (else all rows are solved).
//!
//! G_RR is |R| columns of K₀⁻¹. A model of up to [`DENSE_LIMIT`] unknowns keeps K₀⁻¹ whole (its
//! columns solved at setup, its lower triangle stored in Z-order of the nodes so that a press's
//! rows are neighbours in memory; then a change costs no sparse solve), and one made
//! [`LowRankUpdate::whole_or_near`] up to [`WHOLE_LIMIT`] unknowns. A larger one made
//! [`LowRankUpdate::with_reach`] or [`LowRankUpdate::whole_or_near`] keeps the part of K₀⁻¹
//! between nodes within a reach of each other (a press's own block, for presses that fit in
//! it); G_RR is then gathered for changes of up to [`GATHERED_ROWS`] rows. Otherwise it solves
//! the |R| columns per change, unless they are more than [`SOLVED_ROWS`]: then a new
//! factorisation costs less than that many solves, and the change is solved in full (exact
//! either way).
//!
//! ```
//! use eitskin::conductivity::{with_inclusions, Inclusion};
//! use eitskin::forward::LowRankUpdate;
//! use eitskin::SensorSpec;
//! let mut spec = SensorSpec::square_hydrogel();
//! spec.mesh.triangles = 600;
//! let model = spec.forward_model()?;
//! let update = LowRankUpdate::new(&model, &vec![1.0; model.mesh().triangles().len()])?;
//! let press = Inclusion { centre: [0.03, -0.02], radius: 0.01, conductivity: 0.2 };
//! let sigma = with_inclusions(model.mesh(), 1.0, &[press]);
//! let changes: Vec<(usize, f64)> =
//!     sigma.iter().enumerate().filter(|(_, s)| **s != 1.0).map(|(t, s)| (t, s - 1.0)).collect();
//! let dv = update.measurement_change(&changes)?;
//! let solved = model.measure(&sigma)?;
//! let (m, v0) = (7, update.background_measurements()[7]);
//! assert!((dv[m] - (solved[m] - v0)).abs() < 1e-9 * solved[m].abs());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::ops::Range;

use faer::linalg::matmul::matmul;
use faer::linalg::solvers::Solve;
use faer::{Accum, Mat, MatMut, MatRef, Par};

use super::assemble::GROUNDED;
use super::{Factor, ForwardError, ForwardModel};
use crate::scratch::{grow, reserve, room, DenseLu};

mod interior;
mod stiffness;

use stiffness::{Adjacency, Nonzeros};

/// Frames of changes from one background past which a low-rank update repays its setup, by
/// rule of thumb: its setup costs about a hundred full solves on the paper's sensor, both on the
/// virtual sensor's truth mesh (0.75–0.86 s for K₀⁻¹ whole, its first frame with a press,
/// against 6 ms a solve on one core; a one-press frame then about 30 µs) and on the reconstruction
/// mesh (0.13 s for K₀⁻¹ whole against 1.2 ms; a frame then 25 µs).
pub const UPDATE_AFTER: usize = 100;

/// How far apart (m) the nodes a disk of `radius` (m) changes on `mesh` can lie, with room to
/// spare: its nodes lie within its radius and a triangle's longest edge of its centre, so within
/// twice that of each other (the reach [`LowRankUpdate::with_reach`] keeps K₀⁻¹ for).
pub fn disk_reach(mesh: &crate::mesh::Mesh, radius: f64) -> f64 {
    2.5 * (radius + mesh.longest_edge())
}

/// Unknowns up to which [`LowRankUpdate::new`] keeps the whole inverse of the background system
/// (its lower triangle, 8 bytes an entry: 36 MB at the limit).
pub const DENSE_LIMIT: usize = 3000;

/// Rows of a change beyond which, without the whole inverse, it is solved in full instead.
pub const SOLVED_ROWS: usize = 64;

/// Rows of a change beyond which, without the whole inverse, a gathered G_RR is not used: the
/// |R|² system then costs about what solving the changed system in full does (measured on the
/// virtual sensor's 12k-triangle truth mesh before a change's interior was eliminated: five
/// presses, 378 rows, 2.4 ms gathered; the full solve 5–11 ms on two cores or one).
pub const GATHERED_ROWS: usize = 500;

/// Unknowns up to which [`LowRankUpdate::whole_or_near`] keeps K₀⁻¹ whole (its lower
/// triangle, 8 bytes an entry: 268 MB at the limit), so that presses far apart are gathered too.
pub const WHOLE_LIMIT: usize = 8192;

/// Local corner pairs of a triangle's stiffness entries, in the order of the stored coefficients.
const LOCAL: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];

/// A corner's index in R where it is the grounded node: past every row's.
const GROUND: u32 = UNUSED - 1;

/// A row of the system outside the change's rows ([`ChangeScratch`]'s map).
const UNUSED: u32 = u32::MAX;

/// A forward model factored at a background conductivity, ready for exact local changes.
#[derive(Debug, Clone)]
pub struct LowRankUpdate {
    model: ForwardModel,
    factor: Factor,
    /// The background's basis fields, (L − 1) × unknowns (a row's fields a contiguous
    /// column, as a change reads them), in V.
    fields: Mat<f64>,
    /// K₀⁻¹ whole, for models of at most [`DENSE_LIMIT`] unknowns (or [`WHOLE_LIMIT`], made
    /// [`LowRankUpdate::whole_or_near`]).
    inverse: Option<WholeGreen>,
    /// K₀⁻¹ between nodes near each other, for larger models made [`LowRankUpdate::with_reach`]
    /// or [`LowRankUpdate::whole_or_near`].
    near: Option<NearGreen>,
    background: Vec<f64>,
    /// The background conductivity per triangle, S/m (for changes solved in full, and the
    /// changed stiffness of a change's interior).
    conductivity: Vec<f64>,
    /// Per row of the system, the triangles its node is in (a change's interior rows are those
    /// whose every triangle changes; see `interior`).
    incident: Vec<u32>,
    /// Each row's neighbours in the system's pattern, for ΔK's columns.
    adjacency: Adjacency,
    readout: Readout,
}

/// Each measurement as a sum of basis voltages: Δv_m = Σ w_a·I_p·ΔV[a, p] over its electrodes'
/// weights w and its stimulation's currents I on the basis (both sparse), flattened.
#[derive(Debug, Clone)]
struct Readout {
    /// Per measurement, its index and where its terms start and end, ordered by how many terms
    /// they are (a measurement against the grounded electrode has fewer): the sums' lengths
    /// change a few times a readout, not at every other measurement.
    sums: Vec<(usize, Range<usize>)>,
    /// (a + p·basis, w_a·I_p): ΔV[a, p]'s place in ΔV stored column after column, its weight.
    terms: Vec<(usize, f64)>,
}

impl Readout {
    fn new(protocol: &crate::Protocol, basis: usize) -> Readout {
        let mut readout = Readout { sums: Vec::new(), terms: Vec::new() };
        for (q, m) in protocol.measurements().iter().enumerate() {
            let (current, first) = (&protocol.stimulations()[m.stimulation][..basis], readout.terms.len());
            for (a, w) in m.weights[..basis].iter().enumerate().filter(|(_, w)| **w != 0.0) {
                for (p, i) in current.iter().enumerate().filter(|(_, i)| **i != 0.0) {
                    readout.terms.push((a + p * basis, w * i));
                }
            }
            readout.sums.push((q, first..readout.terms.len()));
        }
        readout.sums.sort_by_key(|(q, terms)| (terms.len(), *q));
        readout
    }
}

/// K₀⁻¹ between the rows of nodes at most a reach apart (for a model too large to keep it
/// whole); rows numbered by their nodes' place along a Z-order curve (electrode unknowns last),
/// so that the nodes of one press are neighbours in memory.
#[derive(Debug, Clone)]
struct NearGreen {
    /// Each row's place on the curve.
    place: Vec<usize>,
    /// Per place (CSR), where its near places start (one more entry than rows): those at or
    /// after it along the curve, the lower triangle (the matrix is symmetric).
    start: Vec<usize>,
    /// The places near each place and not before it, sorted.
    near: Vec<usize>,
    values: Vec<f64>,
}

/// K₀⁻¹ whole, its lower triangle packed column after column, rows and columns numbered by
/// their nodes' place along a Z-order curve (as [`NearGreen`]'s), so that the rows of one press
/// are neighbours in memory and its G_RR is read from a few cache lines a column rather than
/// from all over a matrix larger than the cache.
#[derive(Debug, Clone)]
struct WholeGreen {
    /// Each row's place on the curve.
    place: Vec<usize>,
    /// The lower triangle of K₀⁻¹ between places, column after column ([`packed_offset`]).
    packed: Vec<f64>,
}

impl WholeGreen {
    /// K₀⁻¹ of `model`'s factored system `factor`, in Z-order: columns solved for the unit
    /// vectors of the rows at their places, in batches (in parallel), each batch writing its own
    /// stretch of the packed triangle.
    fn of(model: &ForwardModel, factor: &Factor) -> WholeGreen {
        use rayon::prelude::*;
        let n = model.system_size();
        let place = z_order(&node_of_row(model), model.mesh().nodes(), model.mesh().bounds());
        let mut row_at = vec![0; n];
        place.iter().enumerate().for_each(|(row, &p)| row_at[p] = row);
        let mut packed = vec![0.0; packed_offset(n, n)];
        let mut stretches = Vec::new();
        let mut rest = packed.as_mut_slice();
        for first in (0..n).step_by(BATCH) {
            let len = packed_offset(n, (first + BATCH).min(n)) - packed_offset(n, first);
            let (stretch, after) = rest.split_at_mut(len);
            stretches.push((first, stretch));
            rest = after;
        }
        stretches.into_par_iter().for_each(|(first, stretch)| {
            let columns = first..(first + BATCH).min(n);
            let rhs = columns_at(factor, &row_at, columns.clone());
            let mut packed = stretch.iter_mut();
            for (k, p) in columns.enumerate() {
                let column = rhs.col(k);
                row_at[p..].iter().zip(packed.by_ref()).for_each(|(&row, g)| *g = column[row]);
            }
        });
        WholeGreen { place, packed }
    }

    /// K₀⁻¹ between rows `a` and `b` of the system.
    fn at(&self, a: usize, b: usize) -> f64 {
        let (p, q) = (self.place[a], self.place[b]);
        let (lo, hi) = (p.min(q), p.max(q));
        self.packed[packed_offset(self.place.len(), lo) + hi - lo]
    }

    /// G between the rows `rows` into `green` (|R| × |R|), as [`NearGreen::block_into`] reads
    /// it, every entry kept.
    fn block_into(&self, rows: &[usize], green: &mut Mat<f64>, sorted: &mut Vec<(usize, usize)>) {
        let n = self.place.len();
        sorted.clear();
        sorted.extend(rows.iter().enumerate().map(|(i, &row)| (self.place[row], i)));
        sorted.sort_unstable();
        for (b, &(pj, j)) in sorted.iter().enumerate() {
            let column = &self.packed[packed_offset(n, pj)..];
            for &(pi, i) in &sorted[b..] {
                let g = column[pi - pj];
                green[(i, j)] = g;
                green[(j, i)] = g;
            }
        }
    }
}

/// The node of each row of `model`'s system (`usize::MAX` for electrode unknowns, which have none).
fn node_of_row(model: &ForwardModel) -> Vec<usize> {
    let mut node_of_row = vec![usize::MAX; model.system_size()];
    for (node, &row) in model.row_of_node.iter().enumerate() {
        if row != GROUNDED {
            node_of_row[row] = node;
        }
    }
    node_of_row
}

/// Where column j's entries (places j..n) start in the packed lower triangle of an n × n matrix.
fn packed_offset(n: usize, j: usize) -> usize {
    j * n - j * j.saturating_sub(1) / 2
}

impl NearGreen {
    /// G between the rows `rows` into `green` (|R| × |R|), read place by place: each column from
    /// its diagonal down, and mirrored. `sorted` is a buffer. `false` if an entry is not kept.
    fn block_into(&self, rows: &[usize], green: &mut Mat<f64>, sorted: &mut Vec<(usize, usize)>) -> bool {
        sorted.clear();
        sorted.extend(rows.iter().enumerate().map(|(i, &row)| (self.place[row], i)));
        sorted.sort_unstable();
        for (b, &(pj, j)) in sorted.iter().enumerate() {
            let (near, values) = (&self.near[self.start[pj]..self.start[pj + 1]], &self.values[self.start[pj]..]);
            let mut k = 0;
            for &(pi, i) in &sorted[b..] {
                while k < near.len() && near[k] < pi {
                    k += 1;
                }
                if k == near.len() || near[k] != pi {
                    return false;
                }
                let g = values[k];
                green[(i, j)] = g;
                green[(j, i)] = g;
            }
        }
        true
    }
}

/// Each row's place along a Z-order (Morton) curve through its node's position, rows without a
/// node (electrode unknowns) last in row order.
fn z_order(node_of_row: &[usize], nodes: &[[f64; 2]], [lo, hi]: [[f64; 2]; 2]) -> Vec<usize> {
    // 16 bits per axis, interleaved.
    let spread = |x: f64| -> u64 {
        let mut v = (x.clamp(0.0, 1.0) * 65535.0) as u64;
        v = (v | (v << 8)) & 0x00ff_00ff;
        v = (v | (v << 4)) & 0x0f0f_0f0f;
        v = (v | (v << 2)) & 0x3333_3333;
        (v | (v << 1)) & 0x5555_5555
    };
    let code = |row: usize| match nodes.get(node_of_row[row]) {
        Some(p) => spread((p[0] - lo[0]) / (hi[0] - lo[0])) | spread((p[1] - lo[1]) / (hi[1] - lo[1])) << 1,
        None => u64::MAX,
    };
    let mut by_code: Vec<(u64, usize)> = (0..node_of_row.len()).map(|row| (code(row), row)).collect();
    by_code.sort_unstable();
    let mut place = vec![0; node_of_row.len()];
    by_code.iter().enumerate().for_each(|(k, &(_, row))| place[row] = k);
    place
}

/// Columns of K₀⁻¹ solved at once when it is kept, whole or its near part.
const BATCH: usize = 256;

/// The columns of K₀⁻¹ (`factor`'s) of the rows at `places` (`row_at` the row at each place),
/// one solve of their unit vectors: n × |places|.
fn columns_at(factor: &Factor, row_at: &[usize], places: std::ops::Range<usize>) -> Mat<f64> {
    let mut rhs = Mat::<f64>::zeros(row_at.len(), places.len());
    places.enumerate().for_each(|(k, p)| rhs[(row_at[p], k)] = 1.0);
    factor.llt.solve_in_place(rhs.as_mut());
    rhs
}

/// The rows a change touches, and what the update needs of them.
#[derive(Debug, Clone)]
struct LocalRows {
    /// The unknowns (rows of the system) of the changed triangles' nodes, ground left out.
    rows: Vec<usize>,
    /// G_RR, |R| × |R|; `None` where the change is cheaper solved in full.
    green: Option<Mat<f64>>,
    /// U_R, |R| × (L − 1).
    fields: Mat<f64>,
}

impl LowRankUpdate {
    /// Factors `model` at `conductivity` (one value per triangle, S/m) and solves its basis fields.
    pub fn new(model: &ForwardModel, conductivity: &[f64]) -> Result<LowRankUpdate, ForwardError> {
        let factor = model.factorize(&model.assemble(conductivity)?)?;
        let solution = model.solve_patterns(&factor);
        let background = solution.measurements(model.protocol());
        let n = model.system_size();
        let inverse = (n <= DENSE_LIMIT).then(|| WholeGreen::of(model, &factor));
        let conductivity = conductivity.to_vec();
        let fields = solution.fields.transpose().to_owned();
        let readout = Readout::new(model.protocol(), fields.nrows());
        Ok(LowRankUpdate {
            model: model.clone(),
            factor,
            fields,
            inverse,
            near: None,
            background,
            conductivity,
            incident: interior::incident_triangles(model),
            adjacency: Adjacency::of(&model.pattern),
            readout,
        })
    }

    /// [`LowRankUpdate::new`], keeping for a model of more than [`DENSE_LIMIT`] unknowns the
    /// part of K₀⁻¹ between nodes at most `reach` (m) apart: every column is solved once, in
    /// batches (in parallel), and a change whose nodes lie within `reach` of each other then
    /// needs no sparse solve.
    pub fn with_reach(model: &ForwardModel, conductivity: &[f64], reach: f64) -> Result<LowRankUpdate, ForwardError> {
        LowRankUpdate::keeping(model, conductivity, reach, DENSE_LIMIT)
    }

    /// [`LowRankUpdate::with_reach`], keeping K₀⁻¹ whole up to [`WHOLE_LIMIT`] unknowns
    /// instead, so that changes far apart need no sparse solve either.
    pub fn whole_or_near(
        model: &ForwardModel,
        conductivity: &[f64],
        reach: f64,
    ) -> Result<LowRankUpdate, ForwardError> {
        LowRankUpdate::keeping(model, conductivity, reach, WHOLE_LIMIT)
    }

    /// [`LowRankUpdate::new`], keeping K₀⁻¹ whole up to `whole` unknowns, else its near part.
    fn keeping(
        model: &ForwardModel,
        conductivity: &[f64],
        reach: f64,
        whole: usize,
    ) -> Result<LowRankUpdate, ForwardError> {
        let mut update = LowRankUpdate::new(model, conductivity)?;
        if update.inverse.is_none() {
            if model.system_size() <= whole {
                update.inverse = Some(WholeGreen::of(model, &update.factor));
            } else if reach > 0.0 && reach.is_finite() {
                update.near = Some(update.near_green(reach));
            }
        }
        Ok(update)
    }

    /// The part of K₀⁻¹ between node rows at most `reach` (m) apart.
    fn near_green(&self, reach: f64) -> NearGreen {
        use rayon::prelude::*;
        let model = &self.model;
        let mesh = model.mesh();
        let n = model.system_size();
        let node_of_row = node_of_row(model);
        // Rows near each row, by a grid of cells `reach` wide.
        let [lo, hi] = mesh.bounds();
        let cells = |k: usize| (((hi[k] - lo[k]) / reach).floor() as usize + 1).min(4096);
        let (nx, ny) = (cells(0), cells(1));
        let cell_of = |p: [f64; 2]| {
            let c = |k: usize, n: usize| (((p[k] - lo[k]) / reach).floor().max(0.0) as usize).min(n - 1);
            (c(0, nx), c(1, ny))
        };
        let mut bucket: Vec<Vec<usize>> = vec![Vec::new(); nx * ny];
        for (row, &node) in node_of_row.iter().enumerate().filter(|(_, n)| **n != usize::MAX) {
            let (cx, cy) = cell_of(mesh.nodes()[node]);
            bucket[cy * nx + cx].push(row);
        }
        let place = z_order(&node_of_row, mesh.nodes(), [lo, hi]);
        let mut row_at = vec![0; n];
        place.iter().enumerate().for_each(|(row, &p)| row_at[p] = row);
        // The places near a row's and not before it, sorted.
        let near_places = |row: usize| -> Vec<usize> {
            let node = node_of_row[row];
            if node == usize::MAX {
                return Vec::new();
            }
            let p = mesh.nodes()[node];
            let (cx, cy) = cell_of(p);
            let mut near: Vec<usize> = (cy.saturating_sub(1)..=(cy + 1).min(ny - 1))
                .flat_map(|y| (cx.saturating_sub(1)..=(cx + 1).min(nx - 1)).map(move |x| y * nx + x))
                .flat_map(|cell| bucket[cell].iter().copied())
                .filter(|&other| crate::geometry::dist(p, mesh.nodes()[node_of_row[other]]) <= reach)
                .map(|other| place[other])
                .filter(|&q| q >= place[row])
                .collect();
            near.sort_unstable();
            near
        };
        let factor = &self.factor;
        // Columns solved in batches of places (in parallel).
        let firsts: Vec<usize> = (0..n).step_by(BATCH).collect();
        let batches: Vec<(Vec<usize>, Vec<f64>, Vec<usize>)> = firsts
            .into_par_iter()
            .map(|first| {
                let columns = first..(first + BATCH).min(n);
                let rhs = columns_at(factor, &row_at, columns.clone());
                let (mut counts, mut near, mut values) = (Vec::new(), Vec::new(), Vec::new());
                for (k, p) in columns.enumerate() {
                    let column = rhs.col(k);
                    let places = near_places(row_at[p]);
                    counts.push(places.len());
                    values.extend(places.iter().map(|&q| column[row_at[q]]));
                    near.extend(places);
                }
                (near, values, counts)
            })
            .collect();
        let mut green = NearGreen { place, start: vec![0], near: Vec::new(), values: Vec::new() };
        for (near, values, counts) in batches {
            for count in counts {
                let last = *green.start.last().unwrap_or(&0);
                green.start.push(last + count);
            }
            green.near.extend(near);
            green.values.extend(values);
        }
        green
    }

    /// The forward model.
    pub fn model(&self) -> &ForwardModel {
        &self.model
    }

    /// The measurements at the background, in V (protocol order).
    pub fn background_measurements(&self) -> &[f64] {
        &self.background
    }

    /// What a change on `triangles` needs: their rows, G_RR and U_R (one sparse solve of |R|
    /// columns, or none when the inverse is kept).
    fn local_rows(&self, triangles: impl IntoIterator<Item = usize>) -> LocalRows {
        let mut rows: Vec<usize> = Vec::new();
        for t in triangles {
            for node in self.model.mesh.triangles()[t] {
                let row = self.model.row_of_node[node];
                if row != GROUNDED {
                    rows.push(row);
                }
            }
        }
        rows.sort_unstable();
        rows.dedup();
        let s = rows.len();
        let near = self.near.as_ref().filter(|_| s <= GATHERED_ROWS).and_then(|near| {
            let mut green = Mat::<f64>::zeros(s, s);
            near.block_into(&rows, &mut green, &mut Vec::new()).then_some(green)
        });
        let green = match (&self.inverse, near) {
            (Some(inverse), _) => Some(Mat::from_fn(s, s, |i, j| inverse.at(rows[i], rows[j]))),
            (None, Some(green)) => Some(green),
            (None, None) if s <= SOLVED_ROWS => {
                let mut columns = Mat::<f64>::zeros(self.model.system_size(), s);
                rows.iter().enumerate().for_each(|(j, &r)| columns[(r, j)] = 1.0);
                self.factor.llt.solve_in_place(columns.as_mut());
                Some(Mat::from_fn(s, s, |i, j| columns[(rows[i], j)]))
            }
            (None, None) => None,
        };
        let fields = Mat::from_fn(s, self.fields.nrows(), |i, p| self.fields[(p, rows[i])]);
        LocalRows { rows, green, fields }
    }

    /// The exact change of every measurement (V, protocol order) when triangle t's
    /// conductivity changes by δσ (S/m), for each (t, δσ) of `changes`.
    pub fn measurement_change(&self, changes: &[(usize, f64)]) -> Result<Vec<f64>, ForwardError> {
        let mut out = vec![0.0; self.background.len()];
        self.measurement_change_into(changes, &mut ChangeScratch::default(), &mut out)?;
        Ok(out)
    }

    /// The measurements (V, protocol order) with `changes` made to the background: its own
    /// measurements plus [`LowRankUpdate::measurement_change_into`] (nothing to solve for no
    /// change).
    pub fn measurements_with(
        &self,
        changes: &[(usize, f64)],
        scratch: &mut ChangeScratch,
    ) -> Result<Vec<f64>, ForwardError> {
        let mut frame = vec![0.0; self.background.len()];
        if !changes.is_empty() {
            self.measurement_change_into(changes, scratch, &mut frame)?;
        }
        frame.iter_mut().zip(&self.background).for_each(|(d, v)| *d += v);
        Ok(frame)
    }

    /// [`LowRankUpdate::measurement_change`] into `out` (one value per measurement, else an
    /// error; a triangle may appear more than once, its changes add). Allocates nothing once `scratch`
    /// has grown, where G_RR needs no sparse solve (the inverse kept whole, or its near part
    /// covers the change's rows, at most [`GATHERED_ROWS`]);
    /// otherwise it solves the rows' columns of K₀⁻¹, or, past 64 of them (`SOLVED_ROWS`), the
    /// whole changed system.
    pub fn measurement_change_into(
        &self,
        changes: &[(usize, f64)],
        scratch: &mut ChangeScratch,
        out: &mut [f64],
    ) -> Result<(), ForwardError> {
        if out.len() != self.background.len() {
            return Err(ForwardError::MeasurementCount { expected: self.background.len(), got: out.len() });
        }
        let ChangeScratch {
            rows,
            local,
            places,
            bits,
            green,
            nonzeros,
            fields,
            system,
            x,
            xt,
            dkxt,
            change,
            lu,
            solved,
            interior,
            kept,
            z,
            extended,
            part_x,
        } = scratch;
        *solved = false;
        rows.iter().for_each(|&r| local[r] = UNUSED);
        local.resize(self.fields.ncols(), UNUSED);
        // The changed triangles' rows, each once, in increasing order.
        bits.clear(local.len());
        for &(t, _) in changes {
            for node in self.model.mesh.triangles()[t] {
                let row = self.model.row_of_node[node];
                if row != GROUNDED {
                    bits.insert(row);
                }
            }
        }
        bits.drain_into(rows, local);
        let s = rows.len();
        *kept = s;
        let basis = self.fields.nrows();
        // The rim's rows first where the change has an interior that can be eliminated, and
        // G_ΓΓ gathered for them; G_RR otherwise.
        let gathered = self.inverse.is_some() || (self.near.is_some() && s <= GATHERED_ROWS);
        let mut rim = s;
        if gathered && interior.analyse(self, changes, rows, local) > 0 {
            rim = interior.order_rows(self, rows, local);
            if !interior.condense(self, local, rim) {
                interior::sorted(rows, local, bits);
                rim = s;
            }
        }
        if !gathered || !self.gather(&rows[..rim], green, places) {
            return self.solved_apart(changes, out);
        }
        // U_Γᵀ, each row's fields a contiguous column.
        grow(fields, basis, rim);
        for (i, &row) in rows[..rim].iter().enumerate() {
            fields.col_as_slice_mut(i).copy_from_slice(self.fields.col_as_slice(row));
        }
        *kept = rim;
        grow(x, s, basis);
        // A part of the rim solved alone later ([`LowRankUpdate::part_change_into`]) fits.
        reserve(part_x, rim, basis);
        x.as_mut().subrows_mut(0, rim).copy_from(fields.transpose());
        if rim < s {
            // X_Γ = (I + G_ΓΓ·ΔS)⁻¹·U_Γ by an LU in place, then ΔV = −U_Γᵀ·ΔS·X_Γ; the
            // interior's rows of X only for a derivative that asks for them.
            interior.rim_system(green, system, rim);
            lu.solve_in_place(system.as_mut(), x.as_mut().subrows_mut(0, rim));
            grow(z, rim, basis);
            interior.schur_times(x.as_ref().subrows(0, rim), z.as_mut());
            self.measurements_of_product(fields.as_ref(), z.as_ref(), change, out);
            *extended = false;
        } else {
            // I + G·ΔK: ΔK has a few entries per column (a node's neighbours), so each of its
            // columns is a sum of a few of G's.
            nonzeros.stiffness_change(self, changes, rows, local);
            grow(system, s, s);
            for j in 0..s {
                let column = system.col_as_slice_mut(j);
                column.fill(0.0);
                column[j] = 1.0;
                add_columns(column, green, nonzeros.column(j));
            }
            lu.solve_in_place(system.as_mut(), x.as_mut());
            // Xᵀ, each row of X contiguous (for the derivatives that follow too), then (ΔK·X)ᵀ,
            // each entry of ΔK (symmetric: its columns are its rows) adding a row of X, and
            // ΔV = −U_Rᵀ·ΔK·X.
            transpose_padded(x.as_ref(), xt);
            grow(dkxt, xt.nrows(), s);
            for i in 0..s {
                let to = dkxt.col_as_slice_mut(i);
                to.fill(0.0);
                for &(j, value) in nonzeros.column(i) {
                    to.iter_mut().zip(xt.col_as_slice(j)).for_each(|(t, x)| *t += value * x);
                }
            }
            let dkx = dkxt.as_ref().subrows(0, basis).transpose();
            self.measurements_of_product(fields.as_ref(), dkx, change, out);
            *extended = true;
        }
        *solved = true;
        Ok(())
    }

    /// The part of the last change solved with `scratch` (a connected set of its triangles, which
    /// a press's are) that holds triangle `t`, if that solve eliminated the change's interior
    /// rows, `t` was one of its triangles and that part has interior rows: what
    /// [`LowRankUpdate::part_change_into`] reads.
    pub fn part_holding(&self, scratch: &ChangeScratch, t: usize) -> Option<usize> {
        let eliminated = scratch.solved && scratch.kept < scratch.rows.len();
        eliminated.then(|| scratch.interior.part_holding(self, &scratch.local, t)).flatten()
    }

    /// The change of every measurement (V, protocol order) had part `part` of the last change
    /// solved with `scratch` ([`LowRankUpdate::part_holding`]) changed alone, into `out`: its
    /// rim's system I + G_ΓΓ·ΔS solved again from that solve's G and ΔS on its rows, which
    /// are what a solve of its changes alone computes, the same to the bit, without reading the
    /// change or the inverse again. That solve's fields (which derivatives read) are kept.
    /// `false` (and `out` untouched) where there is no such part or `out` is not one value per
    /// measurement.
    pub fn part_change_into(&self, part: usize, scratch: &mut ChangeScratch, out: &mut [f64]) -> bool {
        let ChangeScratch { rows, green, fields, system, part_x, z, change, lu, solved, interior, kept, .. } = scratch;
        if !*solved || *kept >= rows.len() || out.len() != self.background.len() {
            return false;
        }
        let Some((rim, schur)) = interior.part_rim(part) else { return false };
        let (g, basis) = (rim.len(), self.fields.nrows());
        grow(system, g, g);
        let green = green.as_ref().submatrix(rim.start, rim.start, g, g);
        matmul(system.as_mut(), Accum::Replace, green, schur, 1.0, Par::Seq);
        (0..g).for_each(|i| system[(i, i)] += 1.0);
        let fields = fields.as_ref().subcols(rim.start, g);
        grow(part_x, g, basis);
        part_x.copy_from(fields.transpose());
        lu.solve_in_place(system.as_mut(), part_x.as_mut());
        grow(z, g, basis);
        matmul(z.as_mut(), Accum::Replace, schur, part_x.as_ref(), 1.0, Par::Seq);
        self.measurements_of_product(fields, z.as_ref(), change, out);
        true
    }

    /// The same update keeping only the near part of K₀⁻¹ (`reach` in m), as a model too large
    /// for the whole inverse would: for tests of that path on a small model.
    #[cfg(test)]
    pub(crate) fn near_only(mut self, reach: f64) -> LowRankUpdate {
        self.near = Some(self.near_green(reach));
        self.inverse = None;
        self
    }

    /// Whether it keeps K₀⁻¹ whole, so that changes far apart are solved together exactly.
    pub fn keeps_inverse(&self) -> bool {
        self.inverse.is_some()
    }

    /// G between the rows `rows` into `green`, from the inverse kept or its near part; `false`
    /// where it lacks an entry.
    fn gather(&self, rows: &[usize], green: &mut Mat<f64>, places: &mut Vec<(usize, usize)>) -> bool {
        let s = rows.len();
        grow(green, s, s);
        match (&self.inverse, &self.near) {
            (Some(inverse), _) => {
                inverse.block_into(rows, green, places);
                true
            }
            (None, Some(near)) => near.block_into(rows, green, places),
            (None, None) => false,
        }
    }

    /// The change solved without G_RR gathered: its rows' columns of K₀⁻¹ solved, or the whole
    /// changed system (allocates).
    fn solved_apart(&self, changes: &[(usize, f64)], out: &mut [f64]) -> Result<(), ForwardError> {
        let local = self.local_rows(changes.iter().map(|(t, _)| *t));
        let dv = self.measurement_change_on(&local, changes)?;
        out.copy_from_slice(&dv);
        Ok(())
    }

    /// The derivative of every measurement (V per unit, protocol order) along `direction`
    /// ((t, ∂σ_t) in S/m per unit), at the conductivity the last
    /// [`LowRankUpdate::measurement_change_into`] with `scratch` solved: −Xᵀ·∂K·X, X the fields
    /// there (the adjoint Jacobian, exact, from the same solve). A triangle whose nodes are not
    /// all among that change's rows is left out: the direction must change no triangle outside
    /// it, as a press's edge moving does not to first order. `false` (and `out` untouched) if
    /// the last change was solved in full, not by the update, or `out` is not one value per
    /// measurement.
    pub fn derivative_into(&self, direction: &[(usize, f64)], scratch: &mut ChangeScratch, out: &mut [f64]) -> bool {
        let ChangeScratch { rows, local: local_of, dkxt, x, xt, change, solved, interior, kept, extended, .. } =
            scratch;
        if !*solved || out.len() != self.background.len() {
            return false;
        }
        let (s, basis) = (rows.len(), x.ncols());
        if !*extended {
            interior.extend(x.as_mut(), *kept);
            transpose_padded(x.as_ref(), xt);
            *extended = true;
        }
        // (∂K·X)ᵀ, a row of ∂K·X a contiguous column, each entry of ∂K adding a row of X.
        grow(dkxt, xt.nrows(), s);
        dkxt.fill(0.0);
        add_direction(self, direction, local_of, xt, dkxt);
        let (xt_basis, dkx) = (xt.as_ref().subrows(0, basis), dkxt.as_ref().subrows(0, basis).transpose());
        self.measurements_of_product(xt_basis, dkx, change, out);
        true
    }

    /// Triangle `t`'s stiffness entries (i, j, per unit conductivity and thickness) between its
    /// rows' indices in R (`local`: a row of the system's index, [`UNUSED`] outside R), the
    /// grounded node left out; `None` if a row of it is outside R: [`LowRankUpdate::triangle_rows`]
    /// as pairs, for the update and the solve of a whole place (the derivative's kernel reads the
    /// rows themselves, in the same order).
    fn triangle_entries(&self, t: usize, local: &[u32]) -> Option<impl Iterator<Item = (usize, usize, f64)>> {
        let (index, coefs) = self.triangle_rows(t, local)?;
        Some(LOCAL.iter().zip(coefs).filter_map(move |(&(a, b), coef)| {
            let (i, j) = (index[a], index[b]);
            (i != GROUND && j != GROUND).then_some((i as usize, j as usize, coef))
        }))
    }

    /// Triangle `t`'s corners' indices in R ([`GROUND`] for the grounded node) and its
    /// stiffness entries in [`LOCAL`]'s order; `None` if a row of it is outside R. The one place
    /// ΔK's entries are read from the mesh.
    fn triangle_rows(&self, t: usize, local: &[u32]) -> Option<([u32; 3], [f64; 6])> {
        let mut index = [GROUND; 3];
        for (k, &n) in self.model.mesh.triangles()[t].iter().enumerate() {
            let row = self.model.row_of_node[n];
            if row != GROUNDED {
                index[k] = *local.get(row).filter(|&&i| i != UNUSED)?;
            }
        }
        Some((index, self.model.pattern.triangle_coefs[t]))
    }

    /// Every measurement (V, protocol order) of the change ΔV = −`a`·`b` (basis × basis), made in
    /// `change` (a buffer, ΔV column after column) and read with [`LowRankUpdate::measurements_of`].
    fn measurements_of_product(&self, a: MatRef<'_, f64>, b: MatRef<'_, f64>, change: &mut Vec<f64>, out: &mut [f64]) {
        let basis = self.fields.nrows();
        change.resize(basis * basis, 0.0);
        let change_mat = MatMut::from_column_major_slice_mut(change, basis, basis);
        matmul(change_mat, Accum::Replace, a, b, -1.0, Par::Seq);
        self.measurements_of(change, out);
    }

    /// Every measurement (V, protocol order) of a change `change` of the basis voltages
    /// ((L − 1) × (L − 1), column after column: electrode a's voltage under basis pattern p at
    /// a + p·(L − 1)), into `out`.
    fn measurements_of(&self, change: &[f64], out: &mut [f64]) {
        // Each sum's terms in order, as `Iterator::sum` adds them ([`LANES`] sums at a time).
        let Readout { sums, terms } = &self.readout;
        let term = |i: usize| {
            let (at, c) = terms[i];
            c * change[at]
        };
        let mut k = 0;
        while k < sums.len() {
            let len = sums[k].1.len();
            if len > 0 && k + LANES <= sums.len() && sums[k + LANES - 1].1.len() == len {
                let first: [usize; LANES] = std::array::from_fn(|j| sums[k + j].1.start);
                // A loop, not `first.map(term)`: the map was left a call (1 % of a three-press frame).
                let mut acc = [0.0; LANES];
                for j in 0..LANES {
                    acc[j] = term(first[j]);
                }
                for t in 1..len {
                    for j in 0..LANES {
                        acc[j] += term(first[j] + t);
                    }
                }
                for j in 0..LANES {
                    out[sums[k + j].0] = acc[j];
                }
                k += LANES;
            } else {
                out[sums[k].0] = terms[sums[k].1.clone()].iter().map(|&(at, c)| c * change[at]).sum();
                k += 1;
            }
        }
    }

    /// [`LowRankUpdate::measurement_change`] for changes on the triangles of `local` (from
    /// `local_rows`), so that several changes of one place share its solve.
    /// Panics if a changed triangle's rows are not in `local` (a caller contract).
    /// A change of many rows is solved in full (an error only if that solve fails).
    #[track_caller]
    fn measurement_change_on(&self, local: &LocalRows, changes: &[(usize, f64)]) -> Result<Vec<f64>, ForwardError> {
        let Some(green) = &local.green else {
            let mut sigma = self.conductivity.clone();
            changes.iter().for_each(|&(t, delta)| sigma[t] += delta);
            let solved = self.model.measure(&sigma)?;
            return Ok(solved.iter().zip(&self.background).map(|(v, v0)| v - v0).collect());
        };
        let mut index = vec![UNUSED; self.fields.ncols()];
        local.rows.iter().enumerate().for_each(|(i, &r)| index[r] = i as u32);
        let s = local.rows.len();
        let mut dk = Mat::<f64>::zeros(s, s);
        for &(t, delta) in changes {
            let Some(entries) = self.triangle_entries(t, &index) else {
                panic!("triangle {t}'s rows are not among the local rows")
            };
            for (i, j, coef) in entries {
                dk[(i, j)] += delta * coef;
                if i != j {
                    dk[(j, i)] += delta * coef;
                }
            }
        }
        let system = Mat::<f64>::identity(local.rows.len(), local.rows.len()) + green * &dk;
        let x = system.partial_piv_lu().solve(&local.fields);
        let change = -(local.fields.transpose() * (&dk * &x));
        let (rows, columns) = (change.nrows(), change.ncols());
        let flat: Vec<f64> = (0..columns).flat_map(|p| (0..rows).map(move |a| (a, p))).map(|at| change[at]).collect();
        let mut out = vec![0.0; self.background.len()];
        self.measurements_of(&flat, &mut out);
        Ok(out)
    }
}

crate::parallel::widest! {
    /// `column` += Σ value·G[:, i] over (i, value) of `entries`: a column of G·ΔK.
    fn add_columns = add_columns_portable(column: &mut [f64], green: &Mat<f64>, entries: &[(usize, f64)]) -> ()
}

#[inline(always)]
fn add_columns_portable(column: &mut [f64], green: &Mat<f64>, entries: &[(usize, f64)]) {
    for &(i, value) in entries {
        column.iter_mut().zip(green.col_as_slice(i)).for_each(|(c, g)| *c += value * g);
    }
}

/// Buffers of [`LowRankUpdate::measurement_change_into`].
#[derive(Debug)]
pub struct ChangeScratch {
    rows: Vec<usize>,
    /// Each row of the system's index in `rows`, [`UNUSED`] for the others.
    local: Vec<u32>,
    /// Each row's place and its index in the change's rows, for the gather of G.
    places: Vec<(usize, usize)>,
    /// The change's rows as bits, to order them.
    bits: interior::RowBits,
    /// G between the rows kept in the dense solve: G_ΓΓ, or G_RR where nothing is eliminated.
    green: Mat<f64>,
    nonzeros: Nonzeros,
    /// U_Γᵀ, (L − 1) × |Γ| (U_Rᵀ where nothing is eliminated).
    fields: Mat<f64>,
    system: Mat<f64>,
    /// X, |R| × (L − 1): the rows kept in the dense solve, and the interior's once `extended`.
    x: Mat<f64>,
    /// Xᵀ of the last solve, once `extended`: (L − 1) × |R|, padded with rows of zeros to a
    /// multiple of [`PASS_ROWS`].
    xt: Mat<f64>,
    /// (ΔK·X)ᵀ where nothing is eliminated, and a derivative's (∂K·X)ᵀ, padded as `xt` (its rows
    /// past the basis never read).
    dkxt: Mat<f64>,
    /// ΔV, (L − 1) × (L − 1) column after column.
    change: Vec<f64>,
    /// X_Γ of one part solved alone ([`LowRankUpdate::part_change_into`]), `x` kept.
    part_x: Mat<f64>,
    lu: DenseLu,
    /// Whether `rows`, `local` and `x` hold the last change's solve (and `xt`, once `extended`).
    solved: bool,
    /// The change's interior eliminated from K₀ and K₁ alike.
    interior: interior::Interior,
    /// The rows the last change kept in its dense solve (the rim's, or all).
    kept: usize,
    /// ΔS·X_Γ, |Γ| × (L − 1).
    z: Mat<f64>,
    /// Whether `x` and `xt` hold every row's fields of the last solve (not yet where the
    /// interior was eliminated and no derivative has asked for them).
    extended: bool,
}

impl ChangeScratch {
    /// Whether the last change was found by the update, not solved in full.
    #[cfg(test)]
    pub(crate) fn updated(&self) -> bool {
        self.solved
    }

    /// The last change's rows, and how many of them its solve kept (its rim's).
    #[cfg(test)]
    fn rows_and_rim(&self) -> (usize, usize) {
        (self.rows.len(), self.kept)
    }

    /// Holds no solve from now on: derivatives and parts are refused until the next change is
    /// solved with it.
    pub fn forget(&mut self) {
        self.solved = false;
    }

    /// Room for changes touching up to `rows` rows of the system (ΔK's sums, one per entry of
    /// the system's pattern, grow at the first change).
    pub fn reserve(&mut self, rows: usize) {
        room(&mut self.rows, rows);
        room(&mut self.local, rows);
        room(&mut self.places, rows);
        self.bits.reserve(rows);
        self.nonzeros.reserve(rows);
        self.lu.reserve(rows);
        self.interior.reserve(rows);
    }
}

impl Default for ChangeScratch {
    fn default() -> Self {
        let empty = || Mat::zeros(0, 0);
        let (green, fields, system, x, xt, dkxt, z) = (empty(), empty(), empty(), empty(), empty(), empty(), empty());
        let part_x = empty();
        ChangeScratch {
            rows: Vec::new(),
            local: Vec::new(),
            places: Vec::new(),
            bits: interior::RowBits::default(),
            green,
            nonzeros: Nonzeros::default(),
            fields,
            system,
            x,
            xt,
            dkxt,
            change: Vec::new(),
            part_x,
            lu: DenseLu::default(),
            solved: false,
            interior: interior::Interior::default(),
            kept: 0,
            z,
            extended: false,
        }
    }
}

impl Clone for ChangeScratch {
    /// Buffers are not worth copying: a clone starts empty.
    fn clone(&self) -> Self {
        ChangeScratch::default()
    }
}

crate::parallel::widest! {
    /// (∂K·X)ᵀ along `direction` ((t, ∂σ_t)) added into `dkxt` (padded basis × rows), from Xᵀ `xt`:
    /// each entry of ∂K adding a row of X (a few hundred additions of a row of L − 1 values a
    /// derivative, in the widest vectors the processor has).
    fn add_direction = add_direction_portable(update: &LowRankUpdate, direction: &[(usize, f64)], local: &[u32], xt: &Mat<f64>, dkxt: &mut Mat<f64>) -> ()
}

/// Measurements of as many terms a readout sums side by side: each sum is a chain of
/// dependent additions, and eight chains in step keep the adder busy (one at a time waited on
/// each addition: 5.8 → 3.1 % of a noisy three-press frame).
const LANES: usize = 8;

/// Rows of the basis a pass of [`add_direction`] keeps in registers per column; Xᵀ and
/// (∂K·X)ᵀ have a multiple of it (Xᵀ's rows past the basis 0).
const PASS_ROWS: usize = 16;

/// Xᵀ of `x` (rows × basis) into `xt`, its rows padded with zeros to a multiple of [`PASS_ROWS`].
fn transpose_padded(x: MatRef<'_, f64>, xt: &mut Mat<f64>) {
    let (s, basis) = (x.nrows(), x.ncols());
    let padded = basis.next_multiple_of(PASS_ROWS);
    grow(xt, padded, s);
    xt.as_mut().subrows_mut(0, basis).copy_from(x.transpose());
    xt.as_mut().subrows_mut(basis, padded - basis).fill(0.0);
}

/// The kernel of [`add_direction`]: a triangle's three columns of (∂K·X)ᵀ held in registers
/// while its entries add into them, [`PASS_ROWS`] of the basis at a time (through memory, each
/// addition into a column waited on the last one's store). Every element receives the same
/// additions in the same order either way: [`LowRankUpdate::triangle_entries`]'s.
#[inline(always)]
fn add_direction_portable(
    update: &LowRankUpdate,
    direction: &[(usize, f64)],
    local: &[u32],
    xt: &Mat<f64>,
    dkxt: &mut Mat<f64>,
) {
    debug_assert!(
        xt.nrows().is_multiple_of(PASS_ROWS) && dkxt.nrows() == xt.nrows(),
        "padded as transpose_padded pads"
    );
    let padded = xt.nrows().min(dkxt.nrows());
    for first in (0..padded).step_by(PASS_ROWS) {
        let rows = first..first + PASS_ROWS;
        // A pass's rows of a column, as a whole register block.
        let block = |column: &[f64]| -> [f64; PASS_ROWS] {
            column.get(rows.clone()).and_then(|rows| rows.try_into().ok()).unwrap_or([0.0; PASS_ROWS])
        };
        for &(t, delta) in direction {
            let Some((index, coefs)) = update.triangle_rows(t, local) else { continue };
            let present = index.map(|i| i != GROUND);
            // A mesh's triangle has three corners of three nodes, each its own row.
            debug_assert!((0..3).all(|a| (0..a).all(|b| !present[a] || index[a] != index[b])), "distinct rows");
            // A grounded corner reads as zeros, which add nothing (x + c·0 is x), and is not
            // stored: every index below is a constant, so the blocks stay in registers.
            let (mut sums, mut x) = ([[0.0; PASS_ROWS]; 3], [[0.0; PASS_ROWS]; 3]);
            for corner in 0..3 {
                if present[corner] {
                    let column = index[corner] as usize;
                    sums[corner] = block(dkxt.col_as_slice(column));
                    x[corner] = block(xt.col_as_slice(column));
                }
            }
            for (&(a, b), coef) in LOCAL.iter().zip(coefs) {
                let c = delta * coef;
                for k in 0..PASS_ROWS {
                    sums[a][k] += c * x[b][k];
                }
                if a != b {
                    for k in 0..PASS_ROWS {
                        sums[b][k] += c * x[a][k];
                    }
                }
            }
            for corner in 0..3 {
                if present[corner] {
                    if let Some(to) = dkxt.col_as_slice_mut(index[corner] as usize).get_mut(rows.clone()) {
                        to.copy_from_slice(&sums[corner]);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::conductivity::{with_inclusions, Inclusion};
    use crate::SensorSpec;

    /// The derivative's kernel adds each entry of ∂K's rows of X into (∂K·X)ᵀ exactly as entry
    /// after entry through memory would, to the bit, over a basis of several passes (32
    /// electrodes: 31 rows, padded to 32), with Xᵀ's padding zero.
    #[test]
    fn the_derivatives_kernel_adds_entry_after_entry() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.electrodes.count = 32;
        spec.mesh.triangles = 1200;
        let model = spec.forward_model().unwrap();
        let update = LowRankUpdate::new(&model, &vec![1.0; model.mesh().triangles().len()]).unwrap();
        let presses = [
            Inclusion { centre: [-0.04, 0.03], radius: 0.02, conductivity: 0.4 },
            Inclusion { centre: [0.05, -0.05], radius: 0.012, conductivity: 0.7 },
        ];
        let sigma = with_inclusions(model.mesh(), 1.0, &presses);
        let changes: Vec<(usize, f64)> =
            sigma.iter().enumerate().filter(|(_, s)| **s != 1.0).map(|(t, s)| (t, s - 1.0)).collect();
        let (mut scratch, mut dv) = (ChangeScratch::default(), vec![0.0; update.background_measurements().len()]);
        update.measurement_change_into(&changes, &mut scratch, &mut dv).unwrap();
        let direction: Vec<(usize, f64)> = changes.iter().map(|&(t, d)| (t, 0.7 * d + 0.01 * t as f64)).collect();
        assert!(update.derivative_into(&direction, &mut scratch, &mut dv));
        let basis = scratch.x.ncols();
        assert_eq!((basis, scratch.xt.nrows()), (31, 32));
        assert!(scratch.xt.row(31).iter().all(|x| *x == 0.0));
        let mut reference = Mat::<f64>::zeros(basis, scratch.rows.len());
        for &(t, delta) in &direction {
            let Some(entries) = update.triangle_entries(t, &scratch.local) else { continue };
            for (i, j, coef) in entries {
                let c = delta * coef;
                for k in 0..basis {
                    reference[(k, i)] += c * scratch.xt[(k, j)];
                    if i != j {
                        reference[(k, j)] += c * scratch.xt[(k, i)];
                    }
                }
            }
        }
        let touched = (0..scratch.rows.len()).filter(|&i| reference.col(i).iter().any(|x| *x != 0.0)).count();
        assert!(touched > 20, "{touched} columns touched");
        for i in 0..scratch.rows.len() {
            for k in 0..basis {
                assert_eq!(scratch.dkxt[(k, i)].to_bits(), reference[(k, i)].to_bits(), "row {k}, column {i}");
            }
        }
    }

    /// Against full solves: strong and weak presses, one over the ground node, two at once, and
    /// both ways of getting G_RR.
    #[test]
    fn a_local_change_is_exactly_a_new_solve() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 700;
        let model = spec.forward_model().unwrap();
        let background = vec![1.0; model.mesh().triangles().len()];
        let mut update = LowRankUpdate::new(&model, &background).unwrap();
        assert!(update.inverse.is_some());
        let cases = [
            vec![Inclusion { centre: [0.0, 0.0], radius: 0.01, conductivity: 0.1 }],
            vec![Inclusion { centre: [0.07, -0.08], radius: 0.012, conductivity: 0.9 }],
            vec![
                Inclusion { centre: [-0.05, 0.04], radius: 0.01, conductivity: 0.3 },
                Inclusion { centre: [0.04, 0.05], radius: 0.015, conductivity: 2.0 },
            ],
            // The most rows of the four: without the whole inverse, column solves.
            vec![Inclusion { centre: [0.0, 0.02], radius: 0.05, conductivity: 0.5 }],
        ];
        assert!(model.mesh().triangles().iter().any(|t| t.contains(&model.ground_node())));
        let mut near = LowRankUpdate::new(&model, &background).unwrap();
        near.inverse = None;
        near.near = Some(near.near_green(0.08));
        // A 10 mm press's nodes are near each other: no sparse solve.
        let press = with_inclusions(model.mesh(), 1.0, &cases[0]);
        let local = near.local_rows((0..press.len()).filter(|&t| press[t] < 0.999));
        assert!(local.green.is_some() && local.rows.len() > 3);
        // Two presses 91 mm apart: their coupling lies outside a near part of 30 mm, inside one
        // of 300 mm.
        let two = with_inclusions(model.mesh(), 1.0, &cases[2]);
        let rows = near.local_rows((0..two.len()).filter(|&t| two[t] != 1.0)).rows;
        let gathered =
            |green: &NearGreen| green.block_into(&rows, &mut Mat::zeros(rows.len(), rows.len()), &mut Vec::new());
        assert!(gathered(&near.near_green(0.3)) && !gathered(&near.near_green(0.03)));
        for (path, dense) in [("dense", true), ("column solves", false), ("near", false)] {
            if path == "near" {
                update = near.clone();
            } else if !dense {
                update.inverse = None;
            }
            let tolerance = 1e-9;
            for inclusions in &cases {
                let sigma = with_inclusions(model.mesh(), 1.0, inclusions);
                let changes: Vec<(usize, f64)> =
                    sigma.iter().enumerate().filter(|(_, s)| **s != 1.0).map(|(t, s)| (t, s - 1.0)).collect();
                let mut scratch = ChangeScratch::default();
                let mut dv = vec![0.0; update.background_measurements().len()];
                update.measurement_change_into(&changes, &mut scratch, &mut dv).unwrap();
                // A press or two within the near part's reach are gathered from it.
                if path == "near" && inclusions.len() == 1 && inclusions[0].radius < 0.02 {
                    assert!(scratch.updated(), "{inclusions:?}");
                }
                let solved = model.measure(&sigma).unwrap();
                let scale = dv.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
                for (m, (d, (v, v0))) in dv.iter().zip(solved.iter().zip(update.background_measurements())).enumerate()
                {
                    assert!(
                        (d - (v - v0)).abs() < tolerance * scale,
                        "{path}, {inclusions:?}, m {m}: {d} vs {}",
                        v - v0
                    );
                }
            }
        }
    }

    /// The paper's sensor meshed at about `triangles`, and its update at 1 S/m everywhere.
    fn paper_update(triangles: usize) -> (ForwardModel, LowRankUpdate) {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = triangles;
        let model = spec.forward_model().unwrap();
        let update = LowRankUpdate::new(&model, &vec![1.0; model.mesh().triangles().len()]).unwrap();
        (model, update)
    }

    /// An output of another length than the protocol's measurements is refused, saying both,
    /// and leaves no solve behind for derivatives or parts; one forgotten holds none either.
    #[test]
    fn an_output_of_the_wrong_length_is_refused() {
        let (_, update) = paper_update(700);
        let m = update.background_measurements().len();
        let changes: Vec<(usize, f64)> = (0..12).map(|t| (t, -0.3)).collect();
        let mut scratch = ChangeScratch::default();
        let mut short = vec![0.0; m - 1];
        let err = update.measurement_change_into(&changes, &mut scratch, &mut short).unwrap_err();
        assert_eq!(err, ForwardError::MeasurementCount { expected: m, got: m - 1 });
        assert_eq!(err.to_string(), format!("{} values where the protocol has {m} measurements", m - 1));
        let mut out = vec![0.0; m];
        update.measurement_change_into(&changes, &mut scratch, &mut out).unwrap();
        assert!(!update.derivative_into(&changes, &mut scratch, &mut short));
        assert!(update.derivative_into(&changes, &mut scratch, &mut out));
        scratch.forget();
        assert!(!update.derivative_into(&changes, &mut scratch, &mut out));
    }

    /// Presses' interior rows are eliminated, the dense solve kept to their rims: the change is
    /// a full solve's (for three presses, for one, and for a change of a thousandth), a triangle
    /// listed twice adds, and the derivative is the central difference's (after a solve of
    /// several presses or of one, and on a scratch whose last solve kept every row); a
    /// conductivity below nothing (K₁_II not positive definite) is solved on all its rows, as
    /// the update without elimination solves it.
    #[test]
    fn a_change_is_solved_on_its_rim() {
        let (model, update) = paper_update(2400);
        assert!(update.inverse.is_some());
        let change_of = |inclusions: &[Inclusion]| -> Vec<(usize, f64)> {
            let sigma = with_inclusions(model.mesh(), 1.0, inclusions);
            sigma.iter().enumerate().filter(|(_, s)| **s != 1.0).map(|(t, s)| (t, s - 1.0)).collect()
        };
        // Two wide presses and a narrow one, a part with no interior row.
        let two = [
            Inclusion { centre: [-0.04, 0.03], radius: 0.025, conductivity: 0.3 },
            Inclusion { centre: [0.05, -0.04], radius: 0.02, conductivity: 1.8 },
            Inclusion { centre: [0.06, 0.07], radius: 0.002, conductivity: 0.5 },
        ];
        let mut changes = change_of(&two);
        // A triangle covered whole (its nodes interior) listed twice: its changes add.
        let whole = changes.iter().position(|c| c.1 == 0.3 - 1.0).unwrap();
        let (t, d) = changes[whole];
        changes[whole].1 = 0.25 * d;
        changes.push((t, 0.75 * d));
        let (mut scratch, mut dv) = (ChangeScratch::default(), vec![0.0; update.background_measurements().len()]);
        update.measurement_change_into(&changes, &mut scratch, &mut dv).unwrap();
        let (rows, rim) = scratch.rows_and_rim();
        assert!(scratch.updated() && rim < rows / 2, "{rim} of {rows} rows kept");
        let solved = model.measure(&with_inclusions(model.mesh(), 1.0, &two)).unwrap();
        let scale = dv.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
        for (m, (d, (v, v0))) in dv.iter().zip(solved.iter().zip(update.background_measurements())).enumerate() {
            assert!((d - (v - v0)).abs() < 1e-9 * scale, "m {m}: {d} vs {}", v - v0);
        }
        // The same through a near part that holds the whole sheet (G_ΓΓ gathered place by place
        // along its near lists).
        let mut near = update.clone();
        near.inverse = None;
        near.near = Some(near.near_green(0.3));
        let (mut apart, mut through_near) = (ChangeScratch::default(), dv.clone());
        near.measurement_change_into(&changes, &mut apart, &mut through_near).unwrap();
        let (rows, rim) = apart.rows_and_rim();
        assert!(apart.updated() && rim < rows / 2, "{rim} of {rows} rows kept");
        assert!(through_near.iter().zip(&dv).all(|(f, d)| (f - d).abs() < 1e-12 * scale));
        // Along the change itself (every changed triangle's δσ scaled): central differences,
        // twice from the same solve (the interior's fields found once).
        let along_itself = |changes: &[(usize, f64)], scratch: &mut ChangeScratch| {
            let scaled = |by: f64| changes.iter().map(|&(t, d)| (t, by * d)).collect::<Vec<_>>();
            let n = update.background_measurements().len();
            let (h, mut up, mut down) = (1e-4, vec![0.0; n], vec![0.0; n]);
            let mut other = ChangeScratch::default();
            update.measurement_change_into(&scaled(1.0 + h), &mut other, &mut up).unwrap();
            update.measurement_change_into(&scaled(1.0 - h), &mut other, &mut down).unwrap();
            for _ in 0..2 {
                let mut derivative = vec![0.0; n];
                assert!(update.derivative_into(changes, scratch, &mut derivative));
                let scale = derivative.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
                for (m, (d, (u, w))) in derivative.iter().zip(up.iter().zip(&down)).enumerate() {
                    let difference = (u - w) / (2.0 * h);
                    assert!((d - difference).abs() < 1e-6 * scale, "m {m}: {d} vs {difference}");
                }
            }
        };
        along_itself(&changes, &mut scratch);
        // One press, and one changed by a thousandth: solved on the rim too, as a full solve.
        let one = &two[..1];
        let faint = [Inclusion { conductivity: 0.999, ..two[0] }];
        for presses in [one, &faint[..]] {
            let changes = change_of(presses);
            update.measurement_change_into(&changes, &mut scratch, &mut dv).unwrap();
            let (rows, rim) = scratch.rows_and_rim();
            assert!(rim < rows, "{rim} of {rows} rows kept");
            let solved = model.measure(&with_inclusions(model.mesh(), 1.0, presses)).unwrap();
            let scale = dv.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
            for (m, (d, (v, v0))) in dv.iter().zip(solved.iter().zip(update.background_measurements())).enumerate() {
                assert!((d - (v - v0)).abs() < 1e-9 * scale, "m {m}: {d} vs {}", v - v0);
            }
        }
        update.measurement_change_into(&change_of(one), &mut scratch, &mut dv).unwrap();
        along_itself(&change_of(one), &mut scratch);
        // σ = −0.5 under a press: every row kept, the same as the update on all rows.
        let mut under = two;
        under[0].conductivity = -0.5;
        let below = change_of(&under);
        update.measurement_change_into(&below, &mut scratch, &mut dv).unwrap();
        let (rows, rim) = scratch.rows_and_rim();
        assert_eq!(rim, rows);
        let whole = update.measurement_change_on(&update.local_rows(below.iter().map(|c| c.0)), &below).unwrap();
        let scale = whole.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
        assert!(scale.is_finite() && scale > 0.0);
        assert!(dv.iter().zip(&whole).all(|(d, w)| (d - w).abs() < 1e-8 * scale), "{dv:?} vs {whole:?}");
        // The derivative from a solve that kept every row (a narrow press, with no interior row),
        // on the scratch of eliminated ones.
        let narrow = change_of(&two[2..]);
        update.measurement_change_into(&narrow, &mut scratch, &mut dv).unwrap();
        let (rows, rim) = scratch.rows_and_rim();
        assert_eq!(rim, rows);
        along_itself(&narrow, &mut scratch);
    }
}
