//! Priors (regularisation matrices R) for one-step Gauss–Newton.
//!
//! * NOSER (Cheney et al. 1990; EIDORS `prior_noser`): R = diag(JᵀJ)^p, p = 0.5 by default.
//! * Tikhonov: R = I.
//! * Laplace: R = DᵀD, D the difference operator over each pair of triangles that share an
//!   edge (σ_i − σ_j): a smoothing prior that leaves constant images free.

use faer::{Mat, MatRef};

use crate::mesh::Mesh;

/// The regularisation matrix R of Δσ = (JᵀJ + λ²R)⁻¹JᵀΔv.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Prior {
    /// R = diag(JᵀJ)^exponent (EIDORS' default exponent is 0.5).
    Noser {
        /// The exponent p, dimensionless.
        exponent: f64,
    },
    /// R = I.
    Tikhonov,
    /// R = DᵀD over edge-sharing triangles (not diagonal: costs an element-sized solve).
    Laplace,
}

impl Default for Prior {
    fn default() -> Self {
        Prior::Noser { exponent: 0.5 }
    }
}

impl Prior {
    /// The diagonal of R for a Jacobian (measurements × triangles), or `None` if R is not diagonal.
    pub fn diagonal(&self, jacobian: MatRef<'_, f64>) -> Option<Vec<f64>> {
        match *self {
            Prior::Noser { exponent } => Some(
                (0..jacobian.ncols())
                    .map(|k| jacobian.col(k).iter().map(|j| j * j).sum::<f64>().powf(exponent))
                    .collect(),
            ),
            Prior::Tikhonov => Some(vec![1.0; jacobian.ncols()]),
            Prior::Laplace => None,
        }
    }

    /// R as a dense triangles × triangles matrix.
    pub fn matrix(&self, jacobian: MatRef<'_, f64>, mesh: &Mesh) -> Mat<f64> {
        match self.diagonal(jacobian) {
            Some(d) => Mat::from_fn(d.len(), d.len(), |i, j| if i == j { d[i] } else { 0.0 }),
            None => laplace(mesh),
        }
    }
}

/// DᵀD over the triangles of `mesh` that share an edge: the graph Laplacian of the dual mesh.
fn laplace(mesh: &Mesh) -> Mat<f64> {
    let n = mesh.triangles().len();
    let mut r = Mat::<f64>::zeros(n, n);
    let mut edges: Vec<([usize; 2], usize)> = mesh
        .triangles()
        .iter()
        .enumerate()
        .flat_map(|(t, tri)| (0..3).map(move |i| ([tri[i].min(tri[(i + 1) % 3]), tri[i].max(tri[(i + 1) % 3])], t)))
        .collect();
    edges.sort_unstable();
    for pair in edges.windows(2) {
        if pair[0].0 == pair[1].0 {
            let (a, b) = (pair[0].1, pair[1].1);
            r[(a, a)] += 1.0;
            r[(b, b)] += 1.0;
            r[(a, b)] -= 1.0;
            r[(b, a)] -= 1.0;
        }
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn laplace_rows_sum_to_zero_and_count_neighbours() {
        let nodes = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.5]];
        let tris = vec![[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]];
        let mesh = Mesh::new(nodes, tris, vec![]).unwrap();
        let r = Prior::Laplace.matrix(Mat::<f64>::zeros(1, 4).as_ref(), &mesh);
        for i in 0..4 {
            assert_eq!(r[(i, i)], 2.0, "each triangle of the fan has two neighbours");
            assert_eq!((0..4).map(|j| r[(i, j)]).sum::<f64>(), 0.0);
        }
    }

    #[test]
    fn noser_is_the_column_norm_to_the_exponent() {
        let j = Mat::from_fn(2, 2, |i, k| [[3.0, 0.0], [4.0, 2.0]][i][k]);
        assert_eq!(Prior::Noser { exponent: 0.5 }.diagonal(j.as_ref()).unwrap(), vec![5.0, 2.0]);
        assert_eq!(Prior::Noser { exponent: 1.0 }.diagonal(j.as_ref()).unwrap(), vec![25.0, 4.0]);
    }
}
