//! Sparse assembly of the P1 stiffness matrix and the complete electrode model.
//!
//! Unknowns are the node potentials (the ground node removed) followed by one voltage U_l per
//! complete electrode. For a sheet of thickness t:
//!
//! * triangle e adds t·σ_e·(b_i b_j + c_i c_j)/(4 A_e) between its nodes i, j, where
//!   (b_i, c_i) = (y_j − y_k, x_k − x_j) over the cyclic corners: K = Σ_e σ_e A_e ∇φ_i·∇φ_j;
//! * each electrode edge of length ℓ with contact impedance z adds t·ℓ/(6z)·[[2,1],[1,2]] between
//!   its nodes, −t·ℓ/(2z) between each node and U_l, and t·ℓ/z to U_l (Somersalo, Cheney and
//!   Isaacson 1992; the same terms as EIDORS).
//!
//! Only the lower triangle is stored. The pattern and each entry's slot are found once, so a
//! new conductivity costs one pass over the triangles.

/// Marks an entry that falls on the removed ground row or column.
pub(crate) const GROUNDED: usize = usize::MAX;

/// Lower-triangular CSC pattern of the system with the slot of every local contribution.
#[derive(Debug, Clone)]
pub(crate) struct Pattern {
    /// Matrix dimension.
    pub size: usize,
    /// Column pointers (CSC).
    pub col_ptr: Vec<usize>,
    /// Row index of each stored entry (CSC, sorted within a column).
    pub row_idx: Vec<usize>,
    /// Slot in the value array of the 6 local entries (00, 11, 22, 01, 02, 12) of each triangle.
    pub triangle_slots: Vec<[usize; 6]>,
    /// Local entries per unit conductivity, times thickness (S⁻¹·S = dimensionless · m).
    pub triangle_coefs: Vec<[f64; 6]>,
    /// Values that do not depend on conductivity: the complete electrode model.
    pub fixed: Vec<f64>,
}

/// Pairs of local corners in the order of `triangle_slots`.
const LOCAL: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];

/// The P1 stiffness of one triangle per unit conductivity and thickness, entries in `LOCAL`
/// order (dimensionless).
pub(crate) fn local_stiffness(p: [[f64; 2]; 3]) -> [f64; 6] {
    let b = [p[1][1] - p[2][1], p[2][1] - p[0][1], p[0][1] - p[1][1]];
    let c = [p[2][0] - p[1][0], p[0][0] - p[2][0], p[1][0] - p[0][0]];
    let area = 0.5 * (b[0] * c[1] - b[1] * c[0]);
    LOCAL.map(|(i, j)| (b[i] * b[j] + c[i] * c[j]) / (4.0 * area))
}

/// One entry of the complete electrode model: row, column (full-system unknowns), value.
pub(crate) type Entry = (usize, usize, f64);

impl Pattern {
    /// Builds the pattern for triangles `triangles` over unknown rows `row_of` (GROUNDED for the
    /// ground), with per-triangle `coefs` and the conductivity-free `entries`.
    pub fn new(
        size: usize,
        triangles: &[[usize; 3]],
        coefs: Vec<[f64; 6]>,
        row_of: &[usize],
        entries: &[Entry],
    ) -> Pattern {
        let lower = |a: usize, b: usize| (a.max(b), a.min(b));
        let mut pairs: Vec<(usize, usize)> = Vec::with_capacity(6 * triangles.len() + entries.len());
        for tri in triangles {
            for (i, j) in LOCAL {
                let (r, c) = (row_of[tri[i]], row_of[tri[j]]);
                if r != GROUNDED && c != GROUNDED {
                    pairs.push(lower(r, c));
                }
            }
        }
        for &(r, c, _) in entries {
            if r != GROUNDED && c != GROUNDED {
                pairs.push(lower(r, c));
            }
        }
        pairs.sort_unstable_by_key(|&(r, c)| (c, r));
        pairs.dedup();
        let mut col_ptr = vec![0; size + 1];
        for &(_, c) in &pairs {
            col_ptr[c + 1] += 1;
        }
        for c in 0..size {
            col_ptr[c + 1] += col_ptr[c];
        }
        let row_idx: Vec<usize> = pairs.iter().map(|&(r, _)| r).collect();
        let slot = |r: usize, c: usize| -> usize {
            if r == GROUNDED || c == GROUNDED {
                return GROUNDED;
            }
            let (r, c) = lower(r, c);
            let rows = &row_idx[col_ptr[c]..col_ptr[c + 1]];
            // The pair was inserted above, so the search always finds it.
            col_ptr[c] + rows.binary_search(&r).unwrap_or_else(|i| i)
        };
        let triangle_slots =
            triangles.iter().map(|tri| LOCAL.map(|(i, j)| slot(row_of[tri[i]], row_of[tri[j]]))).collect();
        let mut fixed = vec![0.0; row_idx.len()];
        for &(r, c, v) in entries {
            let s = slot(r, c);
            if s != GROUNDED {
                fixed[s] += v;
            }
        }
        Pattern { size, col_ptr, row_idx, triangle_slots, triangle_coefs: coefs, fixed }
    }

    /// Writes the matrix values for per-triangle `conductivity` (S/m) into `values`.
    pub fn assemble_into(&self, conductivity: &[f64], values: &mut [f64]) {
        values.copy_from_slice(&self.fixed);
        for ((slots, coefs), &sigma) in self.triangle_slots.iter().zip(&self.triangle_coefs).zip(conductivity) {
            for k in 0..6 {
                if slots[k] != GROUNDED {
                    values[slots[k]] += sigma * coefs[k];
                }
            }
        }
    }
}

/// Complete-electrode-model entries of one electrode edge of length `len` (m), thickness `t`
/// (m) and contact impedance `z` (Ω·m²), between node rows `a`, `b` and electrode row `u`.
pub(crate) fn cem_edge(a: usize, b: usize, u: usize, len: f64, t: f64, z: f64) -> [Entry; 6] {
    let g = t * len / z;
    [(a, a, g / 3.0), (b, b, g / 3.0), (a, b, g / 6.0), (u, a, -g / 2.0), (u, b, -g / 2.0), (u, u, g)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_right_triangle_stiffness() {
        // φ0 = 1 − x − y, φ1 = x, φ2 = y on area 1/2: K = ½[[2,−1,−1],[−1,1,0],[−1,0,1]].
        let k = local_stiffness([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]);
        let expect = [1.0, 0.5, 0.5, -0.5, -0.5, 0.0];
        for (a, b) in k.iter().zip(expect) {
            assert!((a - b).abs() < 1e-15, "{k:?}");
        }
    }

    #[test]
    fn sparse_assembly_matches_a_dense_loop() {
        let nodes = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.4, 0.6]];
        let tris = [[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]];
        let sigma = [1.0, 2.0, 0.5, 3.0];
        let row_of = [0, 1, 2, 3, GROUNDED];
        let coefs: Vec<[f64; 6]> = tris.iter().map(|t| local_stiffness(t.map(|n| nodes[n]))).collect();
        let cem = cem_edge(0, 1, 4, 1.0, 1.0, 0.1);
        let pattern = Pattern::new(5, &tris, coefs.clone(), &row_of, &cem);
        let mut values = vec![0.0; pattern.row_idx.len()];
        pattern.assemble_into(&sigma, &mut values);

        let mut dense = [[0.0; 5]; 5];
        for (t, tri) in tris.iter().enumerate() {
            for (k, (i, j)) in LOCAL.iter().enumerate() {
                let (r, c) = (row_of[tri[*i]], row_of[tri[*j]]);
                if r == GROUNDED || c == GROUNDED {
                    continue;
                }
                dense[r][c] += sigma[t] * coefs[t][k];
                if r != c {
                    dense[c][r] += sigma[t] * coefs[t][k];
                }
            }
        }
        for (r, c, v) in cem {
            dense[r][c] += v;
            if r != c {
                dense[c][r] += v;
            }
        }
        let mut sparse = [[0.0; 5]; 5];
        for (c, bounds) in pattern.col_ptr.windows(2).enumerate() {
            for s in bounds[0]..bounds[1] {
                sparse[pattern.row_idx[s]][c] = values[s];
            }
        }
        for r in 0..5 {
            for c in 0..=r {
                assert!((sparse[r][c] - dense[r][c]).abs() < 1e-14, "entry ({r},{c})");
            }
        }
    }
}
