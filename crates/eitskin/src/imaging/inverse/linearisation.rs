//! The forward model linearised once at the background: the Jacobian J, the model's own
//! measurements v₀ and the mesh. Everything a [`Reconstructor`](super::Reconstructor) needs
//! is derived from it in milliseconds — for another hyperparameter, another set of channels,
//! other noise weights, normalised differences or another raster — without a forward solve.
//!
//! For channels S, noise variances Σ (relative, see [`Channels`]) and a diagonal prior R:
//!
//!   H = R⁻¹J_Sᵀ(J_S R⁻¹J_Sᵀ + λ²Σ)⁻¹,
//!
//! the measurement-sized form of (J_SᵀΣ⁻¹J_S + λ²R)⁻¹J_SᵀΣ⁻¹. With normalised differences the
//! rows of J are divided by v₀ first (and R, which NOSER takes from J, follows).
//!
//! A uniform change δ of the background (S/m) moves every measurement along d = J·1. Fitted
//! jointly with the image and left unpenalised, it leaves the image problem with J and Δv
//! projected by P = I − d(dᵀWd)⁻¹dᵀW (W = Σ⁻¹); P is folded into H, so a frame costs the same.

use faer::linalg::matmul::triangular::{self, BlockStructure};
use faer::{Accum, Mat, MatRef, Side};

use super::channel_products::{ChannelProducts, ProductsCache};
use super::eigensystem::Range;
use super::{check_hyperparameter, Channels, InverseError, Prior, ReconstructorParams};
use crate::forward::{ForwardModel, JacobianFactors};
use crate::mesh::Mesh;

/// J, its factors, v₀ and the mesh of a forward model at a homogeneous background.
#[derive(Debug, Clone, PartialEq)]
pub struct Linearisation {
    jacobian: Mat<f64>,
    factors: JacobianFactors,
    background: Vec<f64>,
    mesh: Mesh,
    /// The measurement-sized products of the channel sets derived on last.
    products: ProductsCache,
}

impl Linearisation {
    /// `channels` weighted by their noise, as the automatic λ weighs them: `relative` is the
    /// noise measured per channel relative to its value (ratio², from
    /// [`super::noise_variance`]), or else [`super::DEFAULT_RELATIVE_NOISE`] of each value; in
    /// the model's units that is relative·v₀² for absolute differences (`normalised` false), so
    /// neither a board's unit nor its gains move λ.
    pub fn noise_weighted(&self, normalised: bool, channels: Channels, relative: Option<Vec<f64>>) -> Channels {
        let default = super::DEFAULT_RELATIVE_NOISE * super::DEFAULT_RELATIVE_NOISE;
        let relative = super::channels::floored(relative.unwrap_or_else(|| vec![default; self.measurements()]));
        let variance = if normalised {
            relative
        } else {
            relative.iter().zip(self.background()).map(|(r, v)| r * v * v).collect()
        };
        channels.with_variance(variance)
    }

    /// Solves `model` at the homogeneous `background` conductivity (S/m) and takes its Jacobian.
    pub fn new(model: &ForwardModel, background: f64) -> Result<Linearisation, InverseError> {
        let sigma = vec![background; model.mesh().triangles().len()];
        let solution = model.solve(&sigma)?;
        let jacobian = model.jacobian(&solution);
        let factors = model.jacobian_factors(&solution);
        let background = solution.measurements(model.protocol());
        Ok(Linearisation {
            jacobian,
            factors,
            background,
            mesh: model.mesh().clone(),
            products: ProductsCache::default(),
        })
    }

    /// A linearisation from its parts (as a cache file holds them), each column-major: the
    /// Jacobian (measurements × triangles), its factors' patterns (measurements × pairs) and
    /// basis products (pairs × triangles), v₀ and the mesh; `None` if the sizes disagree or a
    /// value is not finite.
    pub fn from_parts(
        jacobian: &[f64],
        [patterns, basis]: [&[f64]; 2],
        background: Vec<f64>,
        mesh: Mesh,
    ) -> Option<Linearisation> {
        let (m, k) = (background.len(), mesh.triangles().len());
        let pairs = JacobianFactors::pairs(mesh.electrodes().len());
        let consistent = m > 0
            && m.checked_mul(k) == Some(jacobian.len())
            && m.checked_mul(pairs) == Some(patterns.len())
            && pairs.checked_mul(k) == Some(basis.len())
            && background.iter().chain(jacobian).chain(patterns).chain(basis).all(|v| v.is_finite());
        if !consistent {
            return None;
        }
        let jacobian = Mat::from_fn(m, k, |i, t| jacobian[t * m + i]);
        let factors = JacobianFactors {
            patterns: Mat::from_fn(m, pairs, |i, p| patterns[p * m + i]),
            basis: Mat::from_fn(pairs, k, |p, t| basis[t * pairs + p]),
        };
        Some(Linearisation { jacobian, factors, background, mesh, products: ProductsCache::default() })
    }

    /// The Jacobian ∂v/∂σ, measurements × triangles, in V per S/m (at 1 A).
    pub fn jacobian(&self) -> MatRef<'_, f64> {
        self.jacobian.as_ref()
    }

    /// Whether `used` channels are decomposed through J's factors: they are more than the pairs.
    pub(crate) fn factored_for(&self, used: usize) -> bool {
        self.factors.basis.nrows() < used
    }

    /// The Jacobian's factors P·B (see [`JacobianFactors`]).
    pub fn factors(&self) -> &JacobianFactors {
        &self.factors
    }

    /// The model's measurements at the background, in V (at 1 A).
    pub fn background(&self) -> &[f64] {
        &self.background
    }

    /// The mesh the Jacobian is on.
    pub fn mesh(&self) -> &Mesh {
        &self.mesh
    }

    /// Number of measurements in a frame.
    pub fn measurements(&self) -> usize {
        self.background.len()
    }

    /// The rows of J for the used channels, divided by v₀ when `normalised`.
    pub(crate) fn rows(&self, used: &[usize], normalised: bool) -> Result<Mat<f64>, InverseError> {
        let scale = self.row_scale(used, normalised)?;
        Ok(Mat::from_fn(used.len(), self.jacobian.ncols(), |i, k| self.jacobian[(used[i], k)] * scale[i]))
    }

    /// [`Linearisation::rows`] with the diagonal prior R they set; refused for a prior that is
    /// not diagonal (what the automatic λ needs).
    pub(crate) fn rows_with_diagonal(
        &self,
        used: &[usize],
        normalised: bool,
        prior: &Prior,
    ) -> Result<(Mat<f64>, Vec<f64>), InverseError> {
        let jacobian = self.rows(used, normalised)?;
        let r = prior.diagonal(jacobian.as_ref()).ok_or(InverseError::AutoNeedsDiagonalPrior)?;
        Ok((jacobian, r))
    }

    /// The rows of the factors' P for the used channels, divided by v₀ when `normalised` (so
    /// that they times B are [`Linearisation::rows`]).
    pub(crate) fn pattern_rows(&self, used: &[usize], normalised: bool) -> Result<Mat<f64>, InverseError> {
        let scale = self.row_scale(used, normalised)?;
        let patterns = &self.factors.patterns;
        Ok(Mat::from_fn(used.len(), patterns.ncols(), |i, p| patterns[(used[i], p)] * scale[i]))
    }

    /// The measurement-sized products of channels `used` (J's rows divided by v₀ when
    /// `normalised`) under the diagonal `prior`, kept from an earlier derivation on them or
    /// made now ([`ChannelProducts`]).
    pub(crate) fn channel_products(
        &self,
        used: &[usize],
        normalised: bool,
        prior: &Prior,
    ) -> Result<std::sync::Arc<ChannelProducts>, InverseError> {
        self.products.get(self, used, normalised, prior)
    }

    /// Per used channel, 1/v₀ when `normalised`, else 1; an error for a v₀ of 0.
    pub(crate) fn row_scale(&self, used: &[usize], normalised: bool) -> Result<Vec<f64>, InverseError> {
        let mut scale = vec![1.0; used.len()];
        if normalised {
            for (s, &m) in scale.iter_mut().zip(used) {
                let v = self.background[m];
                if v == 0.0 {
                    return Err(InverseError::ZeroReference { measurement: m + 1 });
                }
                *s = 1.0 / v;
            }
        }
        Ok(scale)
    }

    /// The element-level reconstruction matrix (triangles × all measurements, S/m per V, or per
    /// unit ratio when normalised) for these parameters and channels; dropped channels get zero
    /// columns. With `params.background_change`, a global conductivity change is estimated
    /// with the image and left out of it (see [`Linearisation::background_change_row`]).
    pub fn element_matrix(&self, params: &ReconstructorParams, channels: &Channels) -> Result<Mat<f64>, InverseError> {
        let compact = self.compact_matrix(params, channels)?;
        let mut full = Mat::zeros(compact.nrows(), self.measurements());
        for (i, m) in channels.used().into_iter().enumerate() {
            full.col_mut(m).copy_from(compact.col(i));
        }
        Ok(full)
    }

    /// [`Linearisation::element_matrix`] for the used channels only (triangles × used, in the
    /// order of [`Channels::used`]): what a reconstructor is assembled from.
    pub(crate) fn compact_matrix(
        &self,
        params: &ReconstructorParams,
        channels: &Channels,
    ) -> Result<Mat<f64>, InverseError> {
        self.compact_matrix_by(params, channels, true)
    }

    /// [`Linearisation::compact_matrix`], through J's factors only where `by_factors` allows it.
    fn compact_matrix_by(
        &self,
        params: &ReconstructorParams,
        channels: &Channels,
        by_factors: bool,
    ) -> Result<Mat<f64>, InverseError> {
        check_hyperparameter(params.hyperparameter)?;
        channels.check(self.measurements())?;
        let used = channels.used();
        let mut jacobian = self.rows(&used, params.normalised)?;
        let variance = channels.relative_variance();
        let global = params.background_change.then(|| Global::new(jacobian.as_ref(), &variance));
        if let Some(global) = &global {
            global.project_jacobian(&mut jacobian);
        }
        let basis = self.factors.basis.as_ref();
        let mut compact = match params.prior.diagonal(jacobian.as_ref()) {
            // Fewer pairs than channels: through the range's eigenpairs, at the pairs' count.
            Some(r) if by_factors && self.factored_for(used.len()) => {
                let mut patterns = self.pattern_rows(&used, params.normalised)?;
                if let Some(global) = &global {
                    global.project_patterns(&mut patterns);
                }
                factored(patterns.as_ref(), basis, &r, params.hyperparameter, &variance)?
            }
            Some(r) => measurement_sized(jacobian.as_ref(), &r, params.hyperparameter, &variance)?,
            None => {
                weighted_element_sized(jacobian.as_ref(), &params.prior, params.hyperparameter, &variance, &self.mesh)?
            }
        };
        if let Some(global) = &global {
            global.project_data(&mut compact);
        }
        Ok(compact)
    }

    /// The row r (one weight per measurement, zero on dropped channels) for which r·Δv is the
    /// global conductivity change δ (S/m) fitted jointly with the image of `element` (from
    /// [`Linearisation::element_matrix`] with `background_change`): δ = c·(Wd)ᵀ(Δv − J·HΔv),
    /// with d = J·1 the change of every measurement for 1 S/m everywhere, W = Σ⁻¹, c = 1/(dᵀWd).
    pub fn background_change_row(
        &self,
        element: MatRef<'_, f64>,
        normalised: bool,
        channels: &Channels,
    ) -> Result<Vec<f64>, InverseError> {
        let used = channels.used();
        let compact = Mat::from_fn(element.nrows(), used.len(), |k, i| element[(k, used[i])]);
        let compact_row = self.compact_background_change_row(compact.as_ref(), normalised, channels)?;
        let mut row = vec![0.0; self.measurements()];
        for (r, m) in compact_row.into_iter().zip(used) {
            row[m] = r;
        }
        Ok(row)
    }

    /// [`Linearisation::background_change_row`] from a [`Linearisation::compact_matrix`], for
    /// the used channels only.
    pub(crate) fn compact_background_change_row(
        &self,
        compact: MatRef<'_, f64>,
        normalised: bool,
        channels: &Channels,
    ) -> Result<Vec<f64>, InverseError> {
        let jacobian = self.rows(&channels.used(), normalised)?;
        let global = Global::new(jacobian.as_ref(), &channels.relative_variance());
        let uh = faer::Row::from_fn(compact.nrows(), |k| global.u[k]) * compact; // uᵀH
        Ok((0..compact.ncols()).map(|i| global.c * global.wd[i] - uh[i]).collect())
    }
}

/// The global-change direction d = J·1 of the used rows, with W·d, c = 1/(dᵀWd) and
/// u = c·JᵀWd: P = I − d·c·(Wd)ᵀ removes from data what a uniform change explains.
struct Global {
    d: Vec<f64>,
    wd: Vec<f64>,
    c: f64,
    u: Vec<f64>,
}

impl Global {
    fn new(jacobian: MatRef<'_, f64>, variance: &[f64]) -> Global {
        let d = uniform_response(jacobian);
        let wd: Vec<f64> = d.iter().zip(variance).map(|(d, s)| d / s).collect();
        let c = 1.0 / d.iter().zip(&wd).map(|(d, w)| d * w).sum::<f64>();
        let u = (0..jacobian.ncols())
            .map(|k| c * (0..jacobian.nrows()).map(|i| wd[i] * jacobian[(i, k)]).sum::<f64>())
            .collect();
        Global { d, wd, c, u }
    }

    /// J ← P·J = J − d·uᵀ.
    fn project_jacobian(&self, jacobian: &mut Mat<f64>) {
        for k in 0..jacobian.ncols() {
            for i in 0..jacobian.nrows() {
                jacobian[(i, k)] -= self.d[i] * self.u[k];
            }
        }
    }

    /// J's patterns P ← Π·P = P − d·(c·PᵀWd)ᵀ, so that they times B are
    /// [`Global::project_jacobian`]'s J.
    fn project_patterns(&self, patterns: &mut Mat<f64>) {
        for p in 0..patterns.ncols() {
            let along = self.c * patterns.col(p).iter().zip(&self.wd).map(|(x, w)| x * w).sum::<f64>();
            patterns.col_mut(p).iter_mut().zip(&self.d).for_each(|(x, d)| *x -= d * along);
        }
    }

    /// H ← H·P = H − (H·d)·c·(Wd)ᵀ, so the data need no projection per frame.
    fn project_data(&self, h: &mut Mat<f64>) {
        let hd: Vec<f64> = (0..h.nrows()).map(|k| (0..h.ncols()).map(|i| h[(k, i)] * self.d[i]).sum()).collect();
        for i in 0..h.ncols() {
            let w = self.c * self.wd[i];
            for (k, hd) in hd.iter().enumerate() {
                h[(k, i)] -= hd * w;
            }
        }
    }
}

/// J·1: each measurement's change for a change of 1 S/m on every triangle.
pub(crate) fn uniform_response(jacobian: MatRef<'_, f64>) -> Vec<f64> {
    // Column by column (J is column-major), each row summed in the order of its triangles.
    let mut d = vec![0.0; jacobian.nrows()];
    for k in 0..jacobian.ncols() {
        d.iter_mut().zip(jacobian.col(k).iter()).for_each(|(d, j)| *d += j);
    }
    d
}

/// (JᵀΣ⁻¹J + λ²R)⁻¹JᵀΣ⁻¹ (triangles × measurements): through the measurement-sized system for
/// a diagonal prior, else the triangles × triangles one.
pub(crate) fn weighted(
    jacobian: MatRef<'_, f64>,
    prior: &Prior,
    hyperparameter: f64,
    variance: &[f64],
    mesh: &Mesh,
) -> Result<Mat<f64>, InverseError> {
    match prior.diagonal(jacobian) {
        Some(r) => measurement_sized(jacobian, &r, hyperparameter, variance),
        None => weighted_element_sized(jacobian, prior, hyperparameter, variance, mesh),
    }
}

/// R⁻¹ for a diagonal prior; a triangle no measurement sees (R = 0 under NOSER) gets the
/// smallest positive weight.
pub(crate) fn inverse_diagonal(r: &[f64]) -> Vec<f64> {
    let floor = r.iter().copied().filter(|x| *x > 0.0).fold(f64::INFINITY, f64::min).min(f64::MAX);
    r.iter().map(|&x| 1.0 / if x > 0.0 { x } else { floor }).collect()
}

/// R⁻¹Jᵀ(JR⁻¹Jᵀ + λ²Σ)⁻¹, triangles × measurements, for a diagonal prior `r` and noise variances `variance`.
pub(crate) fn measurement_sized(
    jacobian: MatRef<'_, f64>,
    r: &[f64],
    hyperparameter: f64,
    variance: &[f64],
) -> Result<Mat<f64>, InverseError> {
    let r_inv = inverse_diagonal(r);
    let (m, k) = (jacobian.nrows(), jacobian.ncols());
    // J R⁻¹
    let scaled = Mat::from_fn(m, k, |i, j| jacobian[(i, j)] * r_inv[j]);
    // J R⁻¹ Jᵀ is symmetric and the Cholesky factorisation reads its lower half: only that is formed.
    let mut system = lower_product(scaled.as_ref(), jacobian.transpose());
    let lambda2 = hyperparameter * hyperparameter;
    for i in 0..m {
        system[(i, i)] += lambda2 * variance[i];
    }
    let llt = system.llt(Side::Lower).map_err(|_| InverseError::NotPositiveDefinite)?;
    // (JR⁻¹Jᵀ + λ²Σ)⁻¹ J R⁻¹ = Hᵀ, since both factors are symmetric.
    let transposed = faer::linalg::solvers::Solve::solve(&llt, &scaled);
    Ok(transposed.transpose().to_owned())
}

/// [`measurement_sized`] for J = P·B (`patterns` P as J's rows, `basis` B) with fewer pairs
/// than channels, through the eigenpairs of its range ([`Range::factored`]: Σ^-½ J R⁻¹ = Q S,
/// S R Sᵀ = V diag(e) Vᵀ): H = Sᵀ V diag(1/(e + λ²)) Vᵀ Qᵀ Σ^-½, the part of the data outside Q
/// imaging to nothing. Triangles × channels × pairs of work instead of triangles × channels².
pub(crate) fn factored(
    patterns: MatRef<'_, f64>,
    basis: MatRef<'_, f64>,
    r: &[f64],
    hyperparameter: f64,
    variance: &[f64],
) -> Result<Mat<f64>, InverseError> {
    let std: Vec<f64> = variance.iter().map(|v| v.sqrt()).collect();
    let Range { q, s, eigenvalues, v } = Range::factored(patterns, basis, &std, r)?;
    Range::matrix(q.as_ref(), s.as_ref(), &eigenvalues, v.as_ref(), &std, hyperparameter)
}

/// (JᵀΣ⁻¹J + λ²R)⁻¹JᵀΣ⁻¹ through the triangles × triangles system, for non-diagonal priors.
pub(crate) fn weighted_element_sized(
    jacobian: MatRef<'_, f64>,
    prior: &Prior,
    hyperparameter: f64,
    variance: &[f64],
    mesh: &Mesh,
) -> Result<Mat<f64>, InverseError> {
    let weighted = Mat::from_fn(jacobian.nrows(), jacobian.ncols(), |i, k| jacobian[(i, k)] / variance[i]);
    let mut system = jacobian.transpose() * &weighted;
    system += (hyperparameter * hyperparameter) * prior.matrix(jacobian, mesh);
    let llt = system.llt(Side::Lower).map_err(|_| InverseError::NotPositiveDefinite)?;
    Ok(faer::linalg::solvers::Solve::solve(&llt, weighted.transpose()))
}

/// The lower half (diagonal included) of a × b, a product known to be symmetric; the upper half 0.
pub(super) fn lower_product(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    let mut product = Mat::zeros(a.nrows(), b.ncols());
    triangular::matmul(
        product.as_mut(),
        BlockStructure::TriangularLower,
        Accum::Replace,
        a,
        BlockStructure::Rectangular,
        b,
        BlockStructure::Rectangular,
        1.0,
        faer::get_global_parallelism(),
    );
    product
}

/// A 32-electrode disc of 100 mm measuring every adjacent pair (1,024 channels; 496 pairs of
/// basis fields), on 1,500 triangles: more channels than J's rank, for tests.
#[cfg(test)]
pub(super) fn thirty_two_electrode_disc() -> Linearisation {
    let mut spec = crate::SensorSpec::square_hydrogel();
    spec.outline = crate::Outline::Circle { radius: 0.1 };
    spec.electrodes.count = 32;
    spec.electrodes.width = 0.008;
    spec.electrodes.placement = crate::Placement::Equal { start_angle_deg: 0.0 };
    spec.protocol = crate::ProtocolSpec::AdjacentAll;
    spec.mesh.triangles = 1500;
    Linearisation::new(&spec.forward_model().expect("a disc's model"), 1.0).expect("its linearisation")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Through J's factors (496 pairs of a 32-electrode disc's 1,024 channels) the element
    /// matrix is the measurement-sized solve's, with and without normalisation and the global
    /// change, at λ from where the data dominate to where the prior does: to rounding, which
    /// grows as λ falls (1.3e-7 of the largest entry at λ = 0.01, under 1e-11 at λ ≥ 1).
    #[test]
    fn the_factored_reconstruction_is_the_measurement_sized_one() {
        let lin = thirty_two_electrode_disc();
        let m = lin.measurements();
        let mut mask = vec![true; m];
        mask[5] = false;
        let variance: Vec<f64> = (0..m).map(|i| 1.0 + (i % 7) as f64).collect();
        for (normalised, background_change) in [(false, false), (true, false), (false, true)] {
            let channels = lin.noise_weighted(normalised, Channels::all(m).masked(&mask), Some(variance.clone()));
            for hyperparameter in [0.01, 1.0, 100.0] {
                let params =
                    ReconstructorParams { normalised, background_change, hyperparameter, ..Default::default() };
                let by_factors = lin.compact_matrix_by(&params, &channels, true).unwrap();
                let solved = lin.compact_matrix_by(&params, &channels, false).unwrap();
                let (worst, scale) = ((&by_factors - &solved).norm_max(), solved.norm_max());
                assert!(
                    worst < 1e-6 * scale,
                    "normalised {normalised}, global {background_change}, λ {hyperparameter}: {worst:e} of {scale:e}"
                );
            }
        }
    }
}
