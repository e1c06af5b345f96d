//! The forward model: P1 finite elements with the complete electrode model.
//!
//! −∇·(σ∇u) = 0 in the sheet; on electrode l, u + z_l σ ∂u/∂n = U_l and ∫ σ ∂u/∂n = I_l;
//! elsewhere on the boundary σ ∂u/∂n = 0 (the paper's Appendix A, eqs. 5–9). The sheet is 2-D
//! with thickness t, so voltages scale as 1/t.
//!
//! Setup ([`ForwardModel::new`]) fixes the sparsity pattern and the symbolic Cholesky
//! factorisation once per mesh. [`ForwardModel::solve`] assembles for a conductivity, factors
//! numerically once, and solves the L−1 independent current patterns e_l − e_L; every
//! stimulation of any protocol is a combination of those, so measurements cost no more solves.

mod assemble;
mod jacobian;
mod low_rank;
mod quadratic;

pub use jacobian::JacobianFactors;
pub use low_rank::{disk_reach, ChangeScratch, LowRankUpdate, DENSE_LIMIT, GATHERED_ROWS, UPDATE_AFTER, WHOLE_LIMIT};

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Mat, Side};
use thiserror::Error;

use crate::geometry::dist;
use crate::mesh::Mesh;
use crate::protocol::Protocol;
use assemble::{cem_edge, local_stiffness, Entry, Pattern, GROUNDED};

/// What is wrong with a forward model or its input; electrodes are numbered from 1.
#[derive(Debug, Error, PartialEq)]
pub enum ForwardError {
    /// The protocol and the mesh disagree on the number of electrodes.
    #[error("the protocol has {protocol} electrodes but the mesh has {mesh}")]
    ElectrodeCount {
        /// Electrodes in the protocol.
        protocol: usize,
        /// Electrodes in the mesh.
        mesh: usize,
    },
    /// One contact impedance per electrode is needed.
    #[error("{got} contact impedances given for {expected} electrodes")]
    ContactImpedanceCount {
        /// Electrodes.
        expected: usize,
        /// Values given.
        got: usize,
    },
    /// Contact impedance must be positive and finite (use the point model for none).
    #[error("electrode {electrode}: contact impedance must be positive, got {value} Ω·m²; for ideal contacts use point electrodes")]
    ContactImpedance {
        /// 1-based electrode.
        electrode: usize,
        /// The value found, in Ω·m².
        value: f64,
    },
    /// A point electrode is a single boundary node.
    #[error("electrode {electrode} has {nodes} nodes, but a point electrode is exactly one node")]
    PointElectrode {
        /// 1-based electrode.
        electrode: usize,
        /// Its node count.
        nodes: usize,
    },
    /// A complete electrode covers at least one boundary edge.
    #[error("electrode {electrode} is a single node, but the complete electrode model needs an electrode that covers a boundary edge; use point electrodes")]
    CompleteElectrode {
        /// 1-based electrode.
        electrode: usize,
    },
    /// Thickness must be positive.
    #[error("thickness must be positive, got {0} m")]
    Thickness(f64),
    /// One conductivity per triangle is needed.
    #[error("{got} conductivities given for {expected} triangles")]
    ConductivityCount {
        /// Triangles in the mesh.
        expected: usize,
        /// Values given.
        got: usize,
    },
    /// Conductivity must be positive and finite.
    #[error("triangle {triangle}: conductivity must be positive and finite, got {value} S/m")]
    Conductivity {
        /// 0-based triangle.
        triangle: usize,
        /// The value found, in S/m.
        value: f64,
    },
    /// The system matrix lost positive definiteness during factorisation.
    #[error("the system matrix is not positive definite (pivot {pivot}); is the mesh connected?")]
    NotPositiveDefinite {
        /// Pivot index where factorisation failed.
        pivot: usize,
    },
    /// The sparse solver failed for a reason other than the matrix (e.g. memory).
    #[error("sparse factorisation failed: {0}")]
    Solver(String),
    /// One value per measurement is needed.
    #[error("{got} values where the protocol has {expected} measurements")]
    MeasurementCount {
        /// Measurements of the protocol.
        expected: usize,
        /// Values given.
        got: usize,
    },
    /// Quadratic elements are for complete electrodes only (a point electrode's potential is
    /// singular, which no higher order helps).
    #[error("quadratic elements need complete electrodes, and this model's are points")]
    QuadraticNeedsCompleteElectrodes,
}

/// How electrodes meet the sheet.
#[derive(Debug, Clone, PartialEq)]
pub enum ElectrodeModel {
    /// The complete electrode model: each electrode covers boundary edges with a contact
    /// impedance, one value per electrode, in Ω·m².
    Complete {
        /// Contact impedance of each electrode, in Ω·m².
        contact_impedance: Vec<f64>,
    },
    /// Point electrodes: current enters at one node, and the node's potential is measured
    /// (no contact impedance; a driven electrode's voltage then depends on the mesh).
    Point,
}

/// A forward model ready to solve: mesh, electrodes, thickness, protocol, and the symbolic
/// factorisation of its system. Not for meshes that change: build a new model instead.
#[derive(Debug, Clone)]
pub struct ForwardModel {
    mesh: Mesh,
    electrodes: ElectrodeModel,
    thickness: f64,
    protocol: Protocol,
    ground: usize,
    row_of_node: Vec<usize>,
    row_of_electrode: Vec<usize>,
    pattern: Pattern,
    symbolic: SymbolicLlt<usize>,
}

/// The conductivity-dependent system matrix (lower triangle, CSC values).
#[derive(Debug, Clone)]
pub struct SystemMatrix {
    values: Vec<f64>,
}

/// The numeric Cholesky factor of a [`SystemMatrix`].
#[derive(Debug, Clone)]
pub struct Factor {
    llt: Llt<usize, f64>,
}

impl ForwardModel {
    /// Checks that mesh, electrodes and protocol agree and factors the sparsity pattern once.
    pub fn new(
        mesh: Mesh,
        electrodes: ElectrodeModel,
        thickness: f64,
        protocol: Protocol,
    ) -> Result<ForwardModel, ForwardError> {
        let l = mesh.electrodes().len();
        if protocol.electrode_count() != l {
            return Err(ForwardError::ElectrodeCount { protocol: protocol.electrode_count(), mesh: l });
        }
        if !(thickness > 0.0 && thickness.is_finite()) {
            return Err(ForwardError::Thickness(thickness));
        }
        let is_electrode_node = {
            let mut flag = vec![false; mesh.nodes().len()];
            mesh.electrodes().iter().flatten().for_each(|&n| flag[n] = true);
            flag
        };
        let ground = ground_node(&mesh, &is_electrode_node);
        let mut row_of_node = Vec::with_capacity(mesh.nodes().len());
        let mut next = 0;
        for n in 0..mesh.nodes().len() {
            row_of_node.push(if n == ground { GROUNDED } else { next });
            next += usize::from(n != ground);
        }

        let mut entries: Vec<Entry> = Vec::new();
        let row_of_electrode = match &electrodes {
            ElectrodeModel::Complete { contact_impedance } => {
                if contact_impedance.len() != l {
                    return Err(ForwardError::ContactImpedanceCount { expected: l, got: contact_impedance.len() });
                }
                let mut rows = Vec::with_capacity(l);
                for (e, &z) in contact_impedance.iter().enumerate() {
                    if !(z > 0.0 && z.is_finite()) {
                        return Err(ForwardError::ContactImpedance { electrode: e + 1, value: z });
                    }
                    let edges = mesh.electrode_edges(e);
                    if edges.is_empty() {
                        return Err(ForwardError::CompleteElectrode { electrode: e + 1 });
                    }
                    let u = next + e;
                    for [a, b] in edges {
                        let len = dist(mesh.nodes()[a], mesh.nodes()[b]);
                        let [ra, rb] = [row_of_node[a], row_of_node[b]];
                        entries.extend(cem_edge(ra, rb, u, len, thickness, z));
                    }
                    rows.push(u);
                }
                rows
            }
            ElectrodeModel::Point => {
                for (e, set) in mesh.electrodes().iter().enumerate() {
                    if set.len() != 1 {
                        return Err(ForwardError::PointElectrode { electrode: e + 1, nodes: set.len() });
                    }
                }
                Vec::new()
            }
        };
        let size = next + row_of_electrode.len();
        let coefs =
            (0..mesh.triangles().len()).map(|t| local_stiffness(mesh.corners(t)).map(|k| k * thickness)).collect();
        let pattern = Pattern::new(size, mesh.triangles(), coefs, &row_of_node, &entries);
        let structure = SymbolicSparseColMatRef::new_checked(size, size, &pattern.col_ptr, None, &pattern.row_idx);
        let symbolic =
            SymbolicLlt::try_new(structure, Side::Lower).map_err(|e| ForwardError::Solver(format!("{e:?}")))?;
        Ok(ForwardModel {
            mesh,
            electrodes,
            thickness,
            protocol,
            ground,
            row_of_node,
            row_of_electrode,
            pattern,
            symbolic,
        })
    }

    /// The mesh.
    pub fn mesh(&self) -> &Mesh {
        &self.mesh
    }

    /// The protocol.
    pub fn protocol(&self) -> &Protocol {
        &self.protocol
    }

    /// How the electrodes are modelled.
    pub fn electrode_model(&self) -> &ElectrodeModel {
        &self.electrodes
    }

    /// Sheet thickness, in m.
    pub fn thickness(&self) -> f64 {
        self.thickness
    }

    /// The node held at 0 V (0-based): the non-electrode node nearest the mesh's centre.
    pub fn ground_node(&self) -> usize {
        self.ground
    }

    /// Number of unknowns of the linear system (nodes − 1 + complete electrodes).
    pub fn system_size(&self) -> usize {
        self.pattern.size
    }

    /// Assembles the system matrix for one conductivity per triangle, in S/m.
    pub fn assemble(&self, conductivity: &[f64]) -> Result<SystemMatrix, ForwardError> {
        self.check_conductivity(conductivity)?;
        let mut values = vec![0.0; self.pattern.row_idx.len()];
        self.pattern.assemble_into(conductivity, &mut values);
        Ok(SystemMatrix { values })
    }

    /// Refuses a conductivity that is not one positive, finite value (S/m) per triangle.
    fn check_conductivity(&self, conductivity: &[f64]) -> Result<(), ForwardError> {
        let expected = self.mesh.triangles().len();
        if conductivity.len() != expected {
            return Err(ForwardError::ConductivityCount { expected, got: conductivity.len() });
        }
        if let Some(t) = conductivity.iter().position(|s| !(*s > 0.0 && s.is_finite())) {
            return Err(ForwardError::Conductivity { triangle: t, value: conductivity[t] });
        }
        Ok(())
    }

    /// Numeric Cholesky factorisation of an assembled matrix, reusing the symbolic one.
    pub fn factorize(&self, matrix: &SystemMatrix) -> Result<Factor, ForwardError> {
        let n = self.pattern.size;
        let structure = SymbolicSparseColMatRef::new_checked(n, n, &self.pattern.col_ptr, None, &self.pattern.row_idx);
        let a = SparseColMatRef::new(structure, &matrix.values);
        let llt = Llt::try_new_with_symbolic(self.symbolic.clone(), a, Side::Lower).map_err(|e| match e {
            faer::sparse::linalg::LltError::Numeric(
                faer::linalg::cholesky::llt::factor::LltError::NonPositivePivot { index },
            ) => ForwardError::NotPositiveDefinite { pivot: index },
            other => ForwardError::Solver(format!("{other:?}")),
        })?;
        Ok(Factor { llt })
    }

    /// Solves the L−1 current patterns e_l − e_L (1 A in at electrode l, out at the last).
    pub fn solve_patterns(&self, factor: &Factor) -> ForwardSolution {
        let rows: Vec<Option<usize>> = (0..self.mesh.electrodes().len()).map(|e| self.electrode_row(e)).collect();
        basis_solution(self.pattern.size, &rows, |rhs| factor.llt.solve_in_place(rhs))
    }

    /// Assembles, factors and solves for one conductivity per triangle (S/m).
    pub fn solve(&self, conductivity: &[f64]) -> Result<ForwardSolution, ForwardError> {
        let matrix = self.assemble(conductivity)?;
        let factor = self.factorize(&matrix)?;
        Ok(self.solve_patterns(&factor))
    }

    /// The protocol's measurements for one conductivity per triangle, in V at 1 A
    /// (= transfer impedances in Ω), in protocol order.
    pub fn measure(&self, conductivity: &[f64]) -> Result<Vec<f64>, ForwardError> {
        Ok(self.solve(conductivity)?.measurements(&self.protocol))
    }

    /// The row of the unknown whose value is electrode `e`'s voltage, `None` if it is ground.
    fn electrode_row(&self, e: usize) -> Option<usize> {
        let r = match self.electrodes {
            ElectrodeModel::Complete { .. } => self.row_of_electrode[e],
            ElectrodeModel::Point => self.row_of_node[self.mesh.electrodes()[e][0]],
        };
        (r != GROUNDED).then_some(r)
    }

    /// Node potentials (V, ground 0) of `solution` for a stimulation `current` (A per electrode,
    /// summing to zero).
    pub fn node_potentials(&self, solution: &ForwardSolution, current: &[f64]) -> Vec<f64> {
        let l = self.mesh.electrodes().len();
        assert_eq!(current.len(), l, "one current per electrode");
        self.row_of_node
            .iter()
            .map(|&r| if r == GROUNDED { 0.0 } else { (0..l - 1).map(|p| current[p] * solution.fields[(r, p)]).sum() })
            .collect()
    }
}

/// The L−1 basis patterns e_p − e_L (1 A in at electrode p, out at the last) of a system of
/// `size` unknowns where electrode e's voltage is unknown `rows[e]` (`None`: ground), solved in
/// place by `solve`.
fn basis_solution(size: usize, rows: &[Option<usize>], solve: impl FnOnce(faer::MatMut<'_, f64>)) -> ForwardSolution {
    let l = rows.len();
    let mut rhs = Mat::<f64>::zeros(size, l - 1);
    for p in 0..l - 1 {
        for (e, sign) in [(p, 1.0), (l - 1, -1.0)] {
            if let Some(r) = rows[e] {
                rhs[(r, p)] += sign;
            }
        }
    }
    solve(rhs.as_mut());
    let electrode_voltages =
        rows.iter().map(|r| (0..l - 1).map(|p| r.map_or(0.0, |r| rhs[(r, p)])).collect()).collect();
    ForwardSolution { fields: rhs, electrode_voltages }
}

/// The ground: the node nearest the centre of the bounding box that is not on an electrode.
fn ground_node(mesh: &Mesh, is_electrode_node: &[bool]) -> usize {
    let [lo, hi] = mesh.bounds();
    let centre = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
    (0..mesh.nodes().len())
        .filter(|&n| !is_electrode_node[n])
        .min_by(|&a, &b| dist(mesh.nodes()[a], centre).total_cmp(&dist(mesh.nodes()[b], centre)))
        .unwrap_or(0)
}

/// The fields of the L−1 basis current patterns, from which any stimulation follows.
#[derive(Debug, Clone)]
pub struct ForwardSolution {
    /// System unknowns (node potentials without ground, then electrode voltages) per pattern, in V.
    fields: Mat<f64>,
    /// `electrode_voltages[k][p]`: voltage of electrode k under pattern p, in V.
    electrode_voltages: Vec<Vec<f64>>,
}

impl ForwardSolution {
    /// Electrode voltages (V, relative to ground) for a stimulation `current` (A per electrode).
    pub fn electrode_voltages(&self, current: &[f64]) -> Vec<f64> {
        self.electrode_voltages.iter().map(|row| row.iter().zip(current).map(|(v, i)| v * i).sum()).collect()
    }

    /// The measurements of `protocol`, in V, in protocol order.
    pub fn measurements(&self, protocol: &Protocol) -> Vec<f64> {
        let mut out = vec![0.0; protocol.len()];
        self.measurements_into(protocol, &mut out);
        out
    }

    /// Writes the measurements of `protocol` into `out` (one per measurement), in V.
    pub fn measurements_into(&self, protocol: &Protocol, out: &mut [f64]) {
        assert_eq!(out.len(), protocol.len(), "one output per measurement");
        for (value, m) in out.iter_mut().zip(protocol.measurements()) {
            let current = &protocol.stimulations()[m.stimulation];
            // U = Σ_p I_p·U(e_p − e_L) because the currents sum to zero.
            *value = m
                .weights
                .iter()
                .zip(&self.electrode_voltages)
                .filter(|(w, _)| **w != 0.0)
                .map(|(w, row)| w * row.iter().zip(current).map(|(v, i)| v * i).sum::<f64>())
                .sum();
        }
    }

    /// The raw solved fields: one column per basis pattern, rows are system unknowns, in V.
    pub fn fields(&self) -> &Mat<f64> {
        &self.fields
    }
}
