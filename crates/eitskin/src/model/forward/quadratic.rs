//! The same forward model with quadratic (P2) elements on the same mesh, for the measurements:
//! a second unknown on every edge's midpoint, so that the potential is quadratic on each
//! triangle, and the complete electrode model's edge terms integrated with the quadratic trace.
//!
//! Per triangle of constant σ, with barycentric coordinates λ_i (∇λ_i constant), the vertex basis
//! is λ_i(2λ_i − 1) and the edge basis 4λ_iλ_j; their gradients are linear, so the stiffness
//! σt∫∇φ_a·∇φ_b is exact with the three-point edge-midpoint rule. On an electrode edge of length
//! ℓ (ends a, b, midpoint m) the quadratic trace's mass is ℓ/30·[[4, −1, 2], [−1, 4, 2], [2, 2,
//! 16]] and its integral ℓ/6·[1, 1, 4], in the terms (t/z)∫(u − U)(v − V) of the P1 model
//! ([`super`]). The edges are straight (subparametric): a curved outline is the same polygon as
//! for P1. The ground is the P1 model's node.
//!
//! For a convergence study ([`ForwardModel::measure_quadratic`]): the Jacobian, images and
//! low-rank updates stay on P1.

use std::collections::HashMap;

use faer::linalg::solvers::Solve;
use faer::sparse::{SparseColMat, Triplet};
use faer::Side;

use super::{basis_solution, ElectrodeModel, ForwardError, ForwardModel, ForwardSolution, GROUNDED};
use crate::geometry::dist;

/// The midpoint of the edge opposite each corner: local unknowns 3, 4, 5.
const OPPOSITE: [(usize, usize); 3] = [(1, 2), (2, 0), (0, 1)];

/// The quadratic stiffness of one triangle per unit conductivity and thickness, 6 × 6 over its
/// corners then the midpoints of the edges opposite them (dimensionless).
pub(crate) fn quadratic_stiffness(p: [[f64; 2]; 3]) -> [[f64; 6]; 6] {
    let b = [p[1][1] - p[2][1], p[2][1] - p[0][1], p[0][1] - p[1][1]];
    let c = [p[2][0] - p[1][0], p[0][0] - p[2][0], p[1][0] - p[0][0]];
    let twice = b[0] * c[1] - b[1] * c[0];
    let grad: [[f64; 2]; 3] = std::array::from_fn(|i| [b[i] / twice, c[i] / twice]);
    let mut k = [[0.0; 6]; 6];
    // The edge-midpoint rule: λ = ½ on the edge's two corners, 0 on the third; weight |A|/3.
    for q in 0..3 {
        let mut lambda = [0.5; 3];
        lambda[q] = 0.0;
        let basis: [[f64; 2]; 6] = std::array::from_fn(|a| {
            if a < 3 {
                let s = 4.0 * lambda[a] - 1.0;
                [s * grad[a][0], s * grad[a][1]]
            } else {
                let (i, j) = OPPOSITE[a - 3];
                let g = |d: usize| 4.0 * (lambda[i] * grad[j][d] + lambda[j] * grad[i][d]);
                [g(0), g(1)]
            }
        });
        let weight = twice.abs() / 6.0;
        for a in 0..6 {
            for b in 0..6 {
                k[a][b] += weight * (basis[a][0] * basis[b][0] + basis[a][1] * basis[b][1]);
            }
        }
    }
    k
}

impl ForwardModel {
    /// The protocol's measurements with quadratic (P2) elements on this model's mesh, for one
    /// conductivity per triangle (S/m), in V at 1 A; complete electrodes only. A second unknown
    /// on every edge's midpoint, the stiffness exact by the edge-midpoint rule, the electrode
    /// terms with the quadratic trace; straight edges (a curved outline is the same polygon as
    /// for P1). For convergence studies: the Jacobian, images and low-rank updates stay on P1.
    pub fn measure_quadratic(&self, conductivity: &[f64]) -> Result<Vec<f64>, ForwardError> {
        Ok(self.solve_quadratic(conductivity)?.measurements(&self.protocol))
    }

    /// The quadratic model's solution: `fields` holds its unknowns (corners without the ground,
    /// then edge midpoints, then electrodes) per basis pattern.
    fn solve_quadratic(&self, conductivity: &[f64]) -> Result<ForwardSolution, ForwardError> {
        self.check_conductivity(conductivity)?;
        let ElectrodeModel::Complete { contact_impedance } = &self.electrodes else {
            return Err(ForwardError::QuadraticNeedsCompleteElectrodes);
        };
        let corners = self.mesh.nodes().len() - 1;
        // The edges' midpoints, numbered after the corners' rows.
        let mut edges: HashMap<(usize, usize), usize> = HashMap::new();
        let mut midpoint = |a: usize, b: usize| {
            let next = corners + edges.len();
            *edges.entry((a.min(b), a.max(b))).or_insert(next)
        };
        let rows: Vec<[usize; 6]> = self
            .mesh
            .triangles()
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|n| self.row_of_node[n]);
                [a, b, c, midpoint(t[1], t[2]), midpoint(t[2], t[0]), midpoint(t[0], t[1])]
            })
            .collect();
        let electrode_edges: Vec<Vec<[usize; 3]>> = (0..self.mesh.electrodes().len())
            .map(|e| self.mesh.electrode_edges(e).into_iter().map(|[a, b]| [a, b, midpoint(a, b)]).collect())
            .collect();
        let electrodes = contact_impedance.len();
        let first_electrode = corners + edges.len();
        let size = first_electrode + electrodes;
        let t = self.thickness;
        let mut triplets = Vec::with_capacity(21 * rows.len());
        // The lower half only: the factorisation reads no other.
        let mut add = |r: usize, c: usize, v: f64| {
            if r != GROUNDED && c != GROUNDED && r >= c {
                triplets.push(Triplet::new(r, c, v));
            }
        };
        for (k, (local, sigma)) in rows.iter().zip(conductivity).enumerate() {
            let stiffness = quadratic_stiffness(self.mesh.corners(k));
            for a in 0..6 {
                for b in 0..6 {
                    add(local[a], local[b], t * sigma * stiffness[a][b]);
                }
            }
        }
        const MASS: [[f64; 3]; 3] = [[4.0, -1.0, 2.0], [-1.0, 4.0, 2.0], [2.0, 2.0, 16.0]];
        const TRACE: [f64; 3] = [1.0, 1.0, 4.0];
        for (e, (edges, z)) in electrode_edges.iter().zip(contact_impedance).enumerate() {
            let u = first_electrode + e;
            for &[a, b, m] in edges {
                let g = t * dist(self.mesh.nodes()[a], self.mesh.nodes()[b]) / z;
                let local = [self.row_of_node[a], self.row_of_node[b], m];
                for i in 0..3 {
                    for j in 0..3 {
                        add(local[i], local[j], g * MASS[i][j] / 30.0);
                    }
                    add(u, local[i], -g * TRACE[i] / 6.0);
                }
                add(u, u, g);
            }
        }
        let matrix = SparseColMat::<usize, f64>::try_new_from_triplets(size, size, &triplets)
            .map_err(|e| ForwardError::Solver(format!("{e:?}")))?;
        let llt = matrix.sp_cholesky(Side::Lower).map_err(|e| ForwardError::Solver(format!("{e:?}")))?;
        let rows: Vec<Option<usize>> = (0..electrodes).map(|e| Some(first_electrode + e)).collect();
        Ok(basis_solution(size, &rows, |rhs| llt.solve_in_place(rhs)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// K·1 = 0 (a constant has no energy), and a linear potential's energy is exact:
    /// u = x on a triangle of area A has ∫|∇u|² = A.
    #[test]
    fn the_quadratic_stiffness_is_exact_on_linear_potentials() {
        let p = [[0.1, 0.2], [1.3, 0.4], [0.5, 1.7]];
        let k = quadratic_stiffness(p);
        for row in &k {
            assert!(row.iter().sum::<f64>().abs() < 1e-12, "{row:?}");
        }
        let mid = |i: usize, j: usize| [(p[i][0] + p[j][0]) / 2.0, (p[i][1] + p[j][1]) / 2.0];
        let points = [p[0], p[1], p[2], mid(1, 2), mid(2, 0), mid(0, 1)];
        let u: Vec<f64> = points.iter().map(|q| q[0]).collect();
        let energy: f64 = (0..6).map(|a| (0..6).map(|b| u[a] * k[a][b] * u[b]).sum::<f64>()).sum();
        let area = 0.5 * ((p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[2][0] - p[0][0]) * (p[1][1] - p[0][1]));
        assert!((energy - area.abs()).abs() < 1e-12, "{energy} vs {area}");
    }
}
