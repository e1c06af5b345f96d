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
//! one |R| × |R| system per change, exact up to rounding however strong the change.
//!
//! G_RR is |R| columns of K₀⁻¹. A model of up to [`DENSE_LIMIT`] unknowns keeps K₀⁻¹ whole (one
//! solve of the identity at setup, then a change costs no sparse solve); a larger one solves
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

use faer::linalg::solvers::Solve;
use faer::Mat;

use super::assemble::GROUNDED;
use super::{Factor, ForwardError, ForwardModel};

/// Unknowns up to which the whole inverse of the background system is kept (8 bytes each squared:
/// 72 MB at the limit).
pub const DENSE_LIMIT: usize = 3000;

/// Rows of a change beyond which, without the whole inverse, it is solved in full instead.
pub const SOLVED_ROWS: usize = 64;

/// Local corner pairs of a triangle's stiffness entries, in the order of the stored coefficients.
const LOCAL: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];

/// A forward model factored at a background conductivity, ready for exact local changes.
#[derive(Debug, Clone)]
pub struct LowRankUpdate {
    model: ForwardModel,
    factor: Factor,
    /// The background's basis fields, unknowns × (L − 1), in V.
    fields: Mat<f64>,
    /// K₀⁻¹ whole, for models of at most [`DENSE_LIMIT`] unknowns.
    inverse: Option<Mat<f64>>,
    /// K₀⁻¹ between nodes near each other, for larger models made [`LowRankUpdate::with_reach`].
    near: Option<NearGreen>,
    background: Vec<f64>,
    /// The background conductivity per triangle, S/m (for changes solved in full).
    conductivity: Vec<f64>,
}

/// K₀⁻¹ between the rows of nodes at most a reach apart: per row (CSR), the rows near it,
/// sorted, and the values.
#[derive(Debug, Clone)]
struct NearGreen {
    start: Vec<usize>,
    rows: Vec<usize>,
    values: Vec<f64>,
}

impl NearGreen {
    /// G[i, j], if rows i and j are near each other.
    fn get(&self, i: usize, j: usize) -> Option<f64> {
        let (from, to) = (*self.start.get(j)?, *self.start.get(j + 1)?);
        let k = self.rows[from..to].binary_search(&i).ok()?;
        Some(self.values[from + k])
    }
}

/// Columns of K₀⁻¹ solved at once when the near part of it is built.
const BATCH: usize = 256;

/// The rows a change touches, and what the update needs of them.
#[derive(Debug, Clone)]
pub struct LocalRows {
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
        let inverse = (n <= DENSE_LIMIT).then(|| {
            let mut identity = Mat::<f64>::identity(n, n);
            factor.llt.solve_in_place(identity.as_mut());
            identity
        });
        let conductivity = conductivity.to_vec();
        let fields = solution.fields;
        Ok(LowRankUpdate { model: model.clone(), factor, fields, inverse, near: None, background, conductivity })
    }

    /// [`LowRankUpdate::new`], keeping for a model of more than [`DENSE_LIMIT`] unknowns the
    /// part of K₀⁻¹ between nodes at most `reach` (m) apart: every column is solved once, in
    /// batches (in parallel), and a change whose nodes lie within `reach` of each other then
    /// needs no sparse solve.
    pub fn with_reach(model: &ForwardModel, conductivity: &[f64], reach: f64) -> Result<LowRankUpdate, ForwardError> {
        let mut update = LowRankUpdate::new(model, conductivity)?;
        if update.inverse.is_none() && reach > 0.0 && reach.is_finite() {
            update.near = Some(update.near_green(reach));
        }
        Ok(update)
    }

    /// The part of K₀⁻¹ between node rows at most `reach` (m) apart.
    fn near_green(&self, reach: f64) -> NearGreen {
        use rayon::prelude::*;
        let model = &self.model;
        let mesh = model.mesh();
        let n = model.system_size();
        // The node of each row (electrode unknowns have none).
        let mut node_of_row = vec![usize::MAX; n];
        for (node, &row) in model.row_of_node.iter().enumerate() {
            if row != GROUNDED {
                node_of_row[row] = node;
            }
        }
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
        let near_rows = |row: usize| -> Vec<usize> {
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
                .collect();
            near.sort_unstable();
            near
        };
        let factor = &self.factor;
        let batches: Vec<(Vec<usize>, Vec<f64>, Vec<usize>)> = (0..n)
            .step_by(BATCH)
            .collect::<Vec<_>>()
            .into_par_iter()
            .map(|first| {
                let columns = first..(first + BATCH).min(n);
                let mut rhs = Mat::<f64>::zeros(n, columns.len());
                columns.clone().enumerate().for_each(|(k, j)| rhs[(j, k)] = 1.0);
                factor.llt.solve_in_place(rhs.as_mut());
                let (mut counts, mut rows, mut values) = (Vec::new(), Vec::new(), Vec::new());
                for (k, j) in columns.enumerate() {
                    let near = near_rows(j);
                    counts.push(near.len());
                    values.extend(near.iter().map(|&i| rhs[(i, k)]));
                    rows.extend(near);
                }
                (rows, values, counts)
            })
            .collect();
        let mut near = NearGreen { start: vec![0], rows: Vec::new(), values: Vec::new() };
        for (rows, values, counts) in batches {
            for count in counts {
                let last = *near.start.last().unwrap_or(&0);
                near.start.push(last + count);
            }
            near.rows.extend(rows);
            near.values.extend(values);
        }
        near
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
    pub fn local_rows(&self, triangles: impl IntoIterator<Item = usize>) -> LocalRows {
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
        let near = self.near.as_ref().and_then(|near| {
            let mut green = Mat::<f64>::zeros(s, s);
            for j in 0..s {
                for i in 0..s {
                    green[(i, j)] = near.get(rows[i], rows[j])?;
                }
            }
            Some(green)
        });
        let green = match (&self.inverse, near) {
            (Some(inverse), _) => Some(Mat::from_fn(s, s, |i, j| inverse[(rows[i], rows[j])])),
            (None, Some(green)) => Some(green),
            (None, None) if s <= SOLVED_ROWS => {
                let mut columns = Mat::<f64>::zeros(self.model.system_size(), s);
                rows.iter().enumerate().for_each(|(j, &r)| columns[(r, j)] = 1.0);
                self.factor.llt.solve_in_place(columns.as_mut());
                Some(Mat::from_fn(s, s, |i, j| columns[(rows[i], j)]))
            }
            (None, None) => None,
        };
        let fields = Mat::from_fn(s, self.fields.ncols(), |i, p| self.fields[(rows[i], p)]);
        LocalRows { rows, green, fields }
    }

    /// The exact change of every measurement (V, protocol order) when triangle t's
    /// conductivity changes by δσ (S/m), for each (t, δσ) of `changes`.
    pub fn measurement_change(&self, changes: &[(usize, f64)]) -> Result<Vec<f64>, ForwardError> {
        let local = self.local_rows(changes.iter().map(|(t, _)| *t));
        self.measurement_change_on(&local, changes)
    }

    /// [`LowRankUpdate::measurement_change`] for changes on the triangles of `local` (from
    /// [`LowRankUpdate::local_rows`]), so that several changes of one place share its solve.
    /// Panics if a changed triangle's rows are not in `local` (a caller contract).
    /// A change of many rows is solved in full (an error only if that solve fails).
    #[track_caller]
    pub fn measurement_change_on(&self, local: &LocalRows, changes: &[(usize, f64)]) -> Result<Vec<f64>, ForwardError> {
        let Some(green) = &local.green else {
            let mut sigma = self.conductivity.clone();
            changes.iter().for_each(|&(t, delta)| sigma[t] += delta);
            let solved = self.model.measure(&sigma)?;
            return Ok(solved.iter().zip(&self.background).map(|(v, v0)| v - v0).collect());
        };
        let s = local.rows.len();
        let index = |row: usize| {
            local.rows.binary_search(&row).unwrap_or_else(|_| panic!("row {row} is not among the local rows"))
        };
        // ΔK_RR, assembled from the changed triangles' stiffness.
        let mut dk = Mat::<f64>::zeros(s, s);
        for &(t, delta) in changes {
            let nodes = self.model.mesh.triangles()[t];
            let coefs = self.model.pattern.triangle_coefs[t];
            for (&(a, b), coef) in LOCAL.iter().zip(coefs) {
                let (ra, rb) = (self.model.row_of_node[nodes[a]], self.model.row_of_node[nodes[b]]);
                if ra == GROUNDED || rb == GROUNDED {
                    continue;
                }
                let (i, j) = (index(ra), index(rb));
                dk[(i, j)] += delta * coef;
                if i != j {
                    dk[(j, i)] += delta * coef;
                }
            }
        }
        // X = (I + G·ΔK)⁻¹·U_R, then ΔV = −U_Rᵀ·ΔK·X.
        let system = Mat::<f64>::identity(s, s) + green * &dk;
        let x = system.partial_piv_lu().solve(&local.fields);
        let change = -(local.fields.transpose() * (&dk * &x));
        let protocol = self.model.protocol();
        let basis = change.nrows();
        Ok(protocol
            .measurements()
            .iter()
            .map(|m| {
                let current = &protocol.stimulations()[m.stimulation][..basis];
                let mut value = 0.0;
                for (a, w) in m.weights[..basis].iter().enumerate().filter(|(_, w)| **w != 0.0) {
                    value += w * (0..basis).map(|p| change[(a, p)] * current[p]).sum::<f64>();
                }
                value
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::conductivity::{with_inclusions, Inclusion};
    use crate::SensorSpec;

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
            // More rows than SOLVED_ROWS: without the whole inverse, solved in full.
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
        for (path, dense) in [("dense", true), ("column solves", false), ("near", false)] {
            if path == "near" {
                update = near.clone();
            } else if !dense {
                update.inverse = None;
            }
            for inclusions in &cases {
                let sigma = with_inclusions(model.mesh(), 1.0, inclusions);
                let changes: Vec<(usize, f64)> =
                    sigma.iter().enumerate().filter(|(_, s)| **s != 1.0).map(|(t, s)| (t, s - 1.0)).collect();
                let dv = update.measurement_change(&changes).unwrap();
                let solved = model.measure(&sigma).unwrap();
                let scale = dv.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
                for (m, (d, (v, v0))) in dv.iter().zip(solved.iter().zip(update.background_measurements())).enumerate()
                {
                    assert!(
                        (d - (v - v0)).abs() < 1e-9 * scale,
                        "dense {dense}, {inclusions:?}, m {m}: {d} vs {}",
                        v - v0
                    );
                }
            }
        }
    }
}
