//! The Jacobian by the adjoint method, from the L−1 fields already solved (no extra solve).
//!
//! For measurement m (stimulation s, measurement weights w) and triangle k,
//!
//!   J[m,k] = ∂v_m/∂σ_k = −t·A_k·∇u_s·∇u_w,
//!
//! where u_s is the field of the stimulation's currents and u_w the field of 1 A driven by the
//! measurement's weights (reciprocity), both combinations of the basis fields; t is the
//! thickness and A_k the triangle's area. Units: V/A per S/m, i.e. Ω·m/S.

use faer::Mat;

use super::{ForwardModel, ForwardSolution, GROUNDED};

/// The Jacobian as a product J = P·B of the protocol's patterns and the basis fields' products:
/// every measurement is a bilinear form in the L−1 basis fields, so J has rank at most
/// L(L−1)/2 whatever the protocol (496 rows of B for 32 electrodes, against 2,356 channels of
/// a KTC-sized protocol), and what J's range costs can be paid at B's size.
#[derive(Debug, Clone, PartialEq)]
pub struct JacobianFactors {
    /// P, measurements × pairs (unitless): for the pair (p, a), p ≤ a, of basis patterns,
    /// s_p·w_a + s_a·w_p (s_p·w_p when p = a), s the stimulation's and w the measurement's
    /// coefficients on the basis e_p − e_L.
    pub patterns: Mat<f64>,
    /// B, pairs × triangles: −t·A_k·∇u_p·∇u_a, in Ω per S/m.
    pub basis: Mat<f64>,
}

impl JacobianFactors {
    /// The pairs of basis fields of `electrodes` electrodes, L(L−1)/2: the rows of B.
    pub fn pairs(electrodes: usize) -> usize {
        electrodes.saturating_sub(1) * electrodes / 2
    }
}

/// The pairs (p, a), p ≤ a, of `basis` basis patterns, in the order of [`JacobianFactors`]' rows.
fn pairs(basis: usize) -> impl Iterator<Item = (usize, usize)> {
    (0..basis).flat_map(move |a| (0..=a).map(move |p| (p, a)))
}

impl ForwardModel {
    /// The Jacobian of the protocol's measurements (rows) with respect to each triangle's
    /// conductivity (columns), at the conductivity `solution` was solved for, in Ω per S/m.
    pub fn jacobian(&self, solution: &ForwardSolution) -> Mat<f64> {
        let protocol = &self.protocol;
        let basis = self.mesh.electrodes().len() - 1;
        // Pattern coefficients on the basis e_p − e_L: the first L−1 entries (they sum to zero).
        let stimulations: Vec<&[f64]> = protocol.stimulations().iter().map(|s| &s[..basis]).collect();
        let weights: Vec<&[f64]> = protocol.measurements().iter().map(|m| &m.weights[..basis]).collect();
        let mut jacobian = Mat::<f64>::zeros(protocol.len(), self.mesh.triangles().len());
        let mut grad = vec![[0.0; 2]; basis];
        let mut grad_s = vec![[0.0; 2]; stimulations.len()];
        for k in 0..self.mesh.triangles().len() {
            let scale = self.basis_gradients(solution, k, &mut grad);
            let combine = |coefs: &[f64]| {
                coefs.iter().zip(&grad).fold([0.0; 2], |acc, (c, g)| [acc[0] + c * g[0], acc[1] + c * g[1]])
            };
            for (gs, s) in grad_s.iter_mut().zip(&stimulations) {
                *gs = combine(s);
            }
            let column = jacobian.col_mut(k);
            for ((j, w), m) in column.iter_mut().zip(&weights).zip(protocol.measurements()) {
                let gw = combine(w);
                let gs = grad_s[m.stimulation];
                *j = scale * (gs[0] * gw[0] + gs[1] * gw[1]);
            }
        }
        jacobian
    }

    /// [`ForwardModel::jacobian`] as its factors P·B (see [`JacobianFactors`]), at the
    /// conductivity `solution` was solved for.
    pub fn jacobian_factors(&self, solution: &ForwardSolution) -> JacobianFactors {
        let protocol = &self.protocol;
        let basis = self.mesh.electrodes().len() - 1;
        let index: Vec<(usize, usize)> = pairs(basis).collect();
        let count = index.len();
        let patterns = Mat::from_fn(protocol.len(), count, |m, pair| {
            let measurement = &protocol.measurements()[m];
            let (s, w) = (&protocol.stimulations()[measurement.stimulation], &measurement.weights);
            let (p, a) = index[pair];
            if p == a {
                s[p] * w[p]
            } else {
                s[p] * w[a] + s[a] * w[p]
            }
        });
        let mut products = Mat::<f64>::zeros(count, self.mesh.triangles().len());
        let mut grad = vec![[0.0; 2]; basis];
        for k in 0..self.mesh.triangles().len() {
            let scale = self.basis_gradients(solution, k, &mut grad);
            for (b, &(p, a)) in products.col_mut(k).iter_mut().zip(&index) {
                *b = scale * (grad[p][0] * grad[a][0] + grad[p][1] * grad[a][1]);
            }
        }
        JacobianFactors { patterns, basis: products }
    }

    /// Each basis field's gradient on triangle `k` into `grad` (V/m at 1 A); the factor
    /// −t·A_k of its conductivity's derivative.
    fn basis_gradients(&self, solution: &ForwardSolution, k: usize, grad: &mut [[f64; 2]]) -> f64 {
        let p = self.mesh.corners(k);
        let area = self.mesh.area(k);
        // ∇φ_i = (y_j − y_l, x_l − x_j)/(2A) over the cyclic corners (i, j, l).
        let dphi: [[f64; 2]; 3] = std::array::from_fn(|i| {
            let (j, l) = ((i + 1) % 3, (i + 2) % 3);
            [(p[j][1] - p[l][1]) / (2.0 * area), (p[l][0] - p[j][0]) / (2.0 * area)]
        });
        let fields = solution.fields();
        for (b, g) in grad.iter_mut().enumerate() {
            *g = [0.0; 2];
            for (i, &n) in self.mesh.triangles()[k].iter().enumerate() {
                let row = self.row_of_node[n];
                if row != GROUNDED {
                    let u = fields[(row, b)];
                    g[0] += u * dphi[i][0];
                    g[1] += u * dphi[i][1];
                }
            }
        }
        -self.thickness * area
    }
}

#[cfg(test)]
mod tests {
    use crate::{conductivity::with_inclusions, conductivity::Inclusion, SensorSpec};

    #[test]
    fn jacobian_matches_central_finite_differences() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 600;
        let model = spec.forward_model().unwrap();
        // An inhomogeneous background, so the test does not rest on symmetry.
        let press = Inclusion { centre: [0.03, -0.02], radius: 0.03, conductivity: 0.4 };
        let sigma = with_inclusions(model.mesh(), 1.0, &[press]);
        let jacobian = model.jacobian(&model.solve(&sigma).unwrap());
        let mut worst = 0.0f64;
        for k in [0, 17, 123, 301, 599.min(model.mesh().triangles().len() - 1)] {
            let h = 1e-4 * sigma[k];
            let mut up = sigma.clone();
            up[k] += h;
            let mut down = sigma.clone();
            down[k] -= h;
            let (vu, vd) = (model.measure(&up).unwrap(), model.measure(&down).unwrap());
            let scale = (0..jacobian.nrows()).map(|m| jacobian[(m, k)].abs()).fold(0.0, f64::max);
            for m in 0..jacobian.nrows() {
                let fd = (vu[m] - vd[m]) / (2.0 * h);
                worst = worst.max((fd - jacobian[(m, k)]).abs() / scale);
            }
        }
        assert!(worst < 1e-5, "adjoint Jacobian differs from finite differences by {worst:e}");
    }

    /// J = P·B to rounding, on an inhomogeneous background and a protocol whose stimulations
    /// and measurements both touch the ground electrode.
    #[test]
    fn the_factors_multiply_to_the_jacobian() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 600;
        spec.protocol = crate::ProtocolSpec::AdjacentAll;
        let model = spec.forward_model().unwrap();
        let press = Inclusion { centre: [0.03, -0.02], radius: 0.03, conductivity: 0.4 };
        let solution = model.solve(&with_inclusions(model.mesh(), 1.0, &[press])).unwrap();
        let jacobian = model.jacobian(&solution);
        let factors = model.jacobian_factors(&solution);
        assert_eq!(factors.patterns.ncols(), 15 * 16 / 2);
        let product = &factors.patterns * &factors.basis;
        let scale = jacobian.norm_max();
        let worst = (&product - &jacobian).norm_max();
        assert!(worst < 1e-12 * scale, "P·B differs from J by {worst:e} of {scale:e}");
    }

    #[test]
    fn two_terminal_jacobian_is_never_positive() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 300;
        let model = spec.forward_model().unwrap();
        let jacobian = model.jacobian(&model.solve(&spec.homogeneous(model.mesh())).unwrap());
        assert!((0..jacobian.nrows()).all(|m| (0..jacobian.ncols()).all(|k| jacobian[(m, k)] <= 1e-15)));
    }
}
