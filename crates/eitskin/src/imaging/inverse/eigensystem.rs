//! The whitened system K = Σ^-½ J R⁻¹ Jᵀ Σ^-½ = U diag(e) Uᵀ of the used channels, in which the
//! noise figure ([`super::hyperparameter`]) and the data's criteria ([`super::criterion`]) cost
//! channels² or less per λ.
//!
//! **Its range only.** J's rank is far below its row count when the channels are many: every
//! measurement is a bilinear form in the L−1 basis fields, so J = P·B with P channels ×
//! L(L−1)/2 pairs ([`crate::forward::JacobianFactors`]: 496 pairs for a 32-electrode tank's 2,356
//! channels). Every eigenvector outside P's range has e = 0 and neither carries a target's
//! signal nor images to anything, so only that range is decomposed: with Σ^-½ P = Q R_p (thin
//! QR), Σ^-½ J R⁻¹ = Q S for S = R_p B R⁻¹, and K = Q (S R Sᵀ) Qᵀ is decomposed at the pairs'
//! count, exactly and with no product at the channels' count × triangles. Where the pairs are
//! not fewer than the channels, K is decomposed whole, formed from J R⁻¹ Jᵀ as the
//! linearisation keeps it for the channels ([`ChannelProducts`]): channels² for each new noise.

use std::sync::Arc;

use faer::{Mat, MatRef, Side};

use super::channel_products::ChannelProducts;
use super::linearisation::{inverse_diagonal, lower_product};
use super::shared_basis::ChannelMix;
use super::{Channels, InverseError, Linearisation, Prior};

/// The whitened system's eigenpairs on its range, with what the criteria need of it.
pub(super) struct Eigensystem {
    /// Each used channel's noise standard deviation relative to the mean variance's root.
    pub std: Vec<f64>,
    /// The eigenvalues e of K on its range, ascending; every other eigenvalue is 0.
    pub eigenvalues: Vec<f64>,
    /// The eigenvectors V of T (rows × eigenvalues); K's are Q V.
    v: Mat<f64>,
    form: Form,
}

/// How K was decomposed.
enum Form {
    /// Whole (Q = I, T = K = Σ^-½ J R⁻¹ Jᵀ Σ^-½), from the channels' products kept with the
    /// linearisation ([`ChannelProducts`]): channels² to form.
    Whole(Arc<ChannelProducts>),
    /// On J's range: Σ^-½ J R⁻¹ = Q S, T = S R Sᵀ, with J's rows of the used channels (divided
    /// by v₀ when normalised) and 1/R.
    Range { jacobian: Mat<f64>, r_inv: Vec<f64>, q: Mat<f64>, s: Mat<f64> },
}

impl Eigensystem {
    /// The eigensystem of `channels` (see the module doc).
    pub(super) fn new(
        lin: &Linearisation,
        prior: &Prior,
        normalised: bool,
        channels: &Channels,
    ) -> Result<Eigensystem, InverseError> {
        Eigensystem::build(lin, prior, normalised, channels, true)
    }

    /// [`Eigensystem::new`], on the range alone only where `on_range` allows it.
    fn build(
        lin: &Linearisation,
        prior: &Prior,
        normalised: bool,
        channels: &Channels,
        on_range: bool,
    ) -> Result<Eigensystem, InverseError> {
        channels.check(lin.measurements())?;
        let used = channels.used();
        let std: Vec<f64> = channels.relative_variance().iter().map(|v| v.sqrt()).collect();
        if on_range && lin.factored_for(used.len()) {
            let (jacobian, r) = lin.rows_with_diagonal(&used, normalised, prior)?;
            let basis = lin.factors().basis.as_ref();
            let range = Range::factored(lin.pattern_rows(&used, normalised)?.as_ref(), basis, &std, &r)?;
            let Range { q, s, eigenvalues, v } = range;
            let r_inv = inverse_diagonal(&r);
            return Ok(Eigensystem { std, eigenvalues, v, form: Form::Range { jacobian, r_inv, q, s } });
        }
        let products = lin.channel_products(&used, normalised, prior)?;
        let t = Mat::from_fn(used.len(), used.len(), |i, j| products.gram[(i, j)] / (std[i] * std[j]));
        let (eigenvalues, v) = eigen(t)?;
        Ok(Eigensystem { std, eigenvalues, v, form: Form::Whole(products) })
    }

    /// 1/R per triangle (R the prior's diagonal on the channels, floored where 0).
    pub(super) fn r_inv(&self) -> &[f64] {
        match &self.form {
            Form::Whole(products) => &products.r_inv,
            Form::Range { r_inv, .. } => r_inv,
        }
    }

    /// Uᵀ d = Vᵀ (Qᵀ d) for a whitened `d` of the used channels: its coefficients on the
    /// eigenvectors.
    pub(super) fn coefficients(&self, d: &[f64]) -> Vec<f64> {
        let d = faer::ColRef::from_slice(d);
        let b = match &self.form {
            Form::Whole(_) => self.v.transpose() * d,
            Form::Range { q, .. } => self.v.transpose() * (q.transpose() * d),
        };
        b.iter().copied().collect()
    }

    /// CᵀC for C = A (Σ^-½ J R⁻¹)ᵀ U, the eigenvectors' images weighted by the triangles'
    /// areas A: eigenvalues × eigenvalues, symmetric.
    pub(super) fn area_gram(&self, lin: &Linearisation) -> Mat<f64> {
        let gram = match &self.form {
            Form::Whole(products) => {
                let std = &self.std;
                Mat::from_fn(std.len(), std.len(), |i, j| products.area_gram[(i, j)] / (std[i] * std[j]))
            }
            // Vᵀ (S A² Sᵀ) V, at the range's size.
            Form::Range { s, .. } => weighted_gram(s.as_ref(), |t| lin.mesh().area(t).powi(2)),
        };
        self.v.transpose() * gram * &self.v
    }

    /// J·1 over `triangles` for each used channel (divided by v₀ when normalised).
    pub(super) fn response_to(&self, lin: &Linearisation, triangles: &[usize]) -> Vec<f64> {
        match &self.form {
            Form::Whole(products) => products.response_to(lin, triangles),
            Form::Range { jacobian, .. } => {
                (0..jacobian.nrows()).map(|i| triangles.iter().map(|&t| jacobian[(i, t)]).sum()).collect()
            }
        }
    }

    /// M = Σ^-½ V diag(1/(e + λ²)) Vᵀ Σ^-½ (used × used) at λ `hyperparameter`: the whole
    /// form's reconstructor is R⁻¹ J_Sᵀ M.
    fn mix(&self, hyperparameter: f64) -> Result<Mat<f64>, InverseError> {
        let v = self.v.as_ref();
        let lambda2 = regularised(&self.eigenvalues, hyperparameter)?;
        let std = &self.std;
        let filtered =
            Mat::from_fn(v.nrows(), v.ncols(), |i, k| v[(i, k)] / (self.eigenvalues[k].max(0.0) + lambda2) / std[i]);
        let whitened = Mat::from_fn(v.ncols(), v.nrows(), |k, j| v[(j, k)] / std[j]);
        Ok(filtered * whitened)
    }

    /// The reconstruction matrix of `lin` at λ `hyperparameter`, triangles × used channels,
    /// from the eigenpairs already made (no system formed or factored again), and the mix M it
    /// was made from for a basis its channel set shares ([`ChannelMix`]: the whole form's, of at
    /// most [`super::shared_basis::SHARED_CHANNELS`] channels; else `None`).
    pub(super) fn compact_matrix_and_mix(
        &self,
        lin: &Linearisation,
        hyperparameter: f64,
    ) -> Result<(Mat<f64>, Option<ChannelMix>), InverseError> {
        let v = self.v.as_ref();
        match &self.form {
            Form::Range { q, s, .. } => {
                Ok((Range::matrix(q.as_ref(), s.as_ref(), &self.eigenvalues, v, &self.std, hyperparameter)?, None))
            }
            // H = R⁻¹ Jᵀ Σ^-½ V diag(1/(e + λ²)) Vᵀ Σ^-½: the filter at the channels' size, then
            // one product with J.
            Form::Whole(products) => {
                let mix = self.mix(hyperparameter)?;
                let mut h = products.transposed_times(lin, mix.as_ref());
                for j in 0..h.ncols() {
                    h.col_mut(j).iter_mut().zip(&products.r_inv).for_each(|(h, r)| *h *= r);
                }
                Ok((h, ChannelMix::new(Arc::clone(products), mix.as_ref())))
            }
        }
    }
}

/// λ², refused where it leaves the range's null directions unregularised (its square underflows).
fn regularised(eigenvalues: &[f64], hyperparameter: f64) -> Result<f64, InverseError> {
    let lambda2 = hyperparameter * hyperparameter;
    if eigenvalues.first().is_some_and(|e| e.max(0.0) + lambda2 <= 0.0) {
        return Err(InverseError::NotPositiveDefinite);
    }
    Ok(lambda2)
}

/// Σ^-½ J R⁻¹ = Q S (Q orthonormal columns), with the eigenpairs of T = S R Sᵀ = V diag(e) Vᵀ:
/// the whitened system is K = (Q V) diag(e) (Q V)ᵀ.
pub(super) struct Range {
    pub q: Mat<f64>,
    pub s: Mat<f64>,
    /// Ascending.
    pub eigenvalues: Vec<f64>,
    pub v: Mat<f64>,
}

impl Range {
    /// From J's factors (see the module doc): `patterns` P's rows as J's (used channels × pairs),
    /// `basis` B, each channel's noise `std` and the diagonal prior `r`.
    pub(super) fn factored(
        patterns: MatRef<'_, f64>,
        basis: MatRef<'_, f64>,
        std: &[f64],
        r: &[f64],
    ) -> Result<Range, InverseError> {
        // Σ^-½ P = Q R_p, so Σ^-½ J R⁻¹ = Q (R_p B R⁻¹).
        let whitened = Mat::from_fn(patterns.nrows(), patterns.ncols(), |i, p| patterns[(i, p)] / std[i]);
        let qr = whitened.qr();
        let r_inv = inverse_diagonal(r);
        let scaled = Mat::from_fn(basis.nrows(), basis.ncols(), |p, j| basis[(p, j)] * r_inv[j]);
        Range::of(qr.compute_thin_Q(), qr.thin_R() * scaled, r)
    }

    /// The reconstruction matrix at λ `hyperparameter` from Σ^-½ J R⁻¹ = Q S and T's eigenpairs
    /// (`eigenvalues`, `v`), for channels of noise `std`: triangles × used channels,
    /// H = R⁻¹Jᵀ(JR⁻¹Jᵀ + λ²Σ)⁻¹ = Sᵀ V diag(1/(e + λ²)) Vᵀ Qᵀ Σ^-½, the part of the data
    /// outside Q imaging to nothing. Triangles × channels × rows of work.
    pub(super) fn matrix(
        q: MatRef<'_, f64>,
        s: MatRef<'_, f64>,
        eigenvalues: &[f64],
        v: MatRef<'_, f64>,
        std: &[f64],
        hyperparameter: f64,
    ) -> Result<Mat<f64>, InverseError> {
        let lambda2 = regularised(eigenvalues, hyperparameter)?;
        let filtered = Mat::from_fn(v.nrows(), v.ncols(), |i, k| v[(i, k)] / (eigenvalues[k].max(0.0) + lambda2));
        let data = Mat::from_fn(q.ncols(), q.nrows(), |p, i| q[(i, p)] / std[i]);
        Ok(s.transpose() * (filtered * (v.transpose() * data)))
    }

    fn of(q: Mat<f64>, s: Mat<f64>, r: &[f64]) -> Result<Range, InverseError> {
        // T is symmetric and the eigensolver reads its lower half: only that is formed.
        let weighted = Mat::from_fn(s.nrows(), s.ncols(), |i, j| s[(i, j)] * r[j]);
        let (eigenvalues, v) = eigen(lower_product(s.as_ref(), weighted.transpose()))?;
        Ok(Range { q, s, eigenvalues, v })
    }
}

/// A diag(w) Aᵀ, both halves.
pub(super) fn weighted_gram(a: MatRef<'_, f64>, w: impl Fn(usize) -> f64) -> Mat<f64> {
    let weighted = Mat::from_fn(a.nrows(), a.ncols(), |i, k| a[(i, k)] * w(k));
    symmetric(lower_product(a, weighted.transpose()))
}

/// `lower` with its upper half copied from its lower half.
fn symmetric(mut lower: Mat<f64>) -> Mat<f64> {
    for j in 0..lower.ncols() {
        for i in 0..j {
            lower[(i, j)] = lower[(j, i)];
        }
    }
    lower
}

/// The eigenvalues (ascending) and eigenvectors of the symmetric `lower` (its lower half read).
fn eigen(lower: Mat<f64>) -> Result<(Vec<f64>, Mat<f64>), InverseError> {
    let eigen = lower.self_adjoint_eigen(Side::Lower).map_err(|_| InverseError::NotPositiveDefinite)?;
    Ok(((0..lower.nrows()).map(|i| eigen.S()[i]).collect(), eigen.U().to_owned()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The whitened Gram matrix's quadratic form and the filtered energy of a vector, as the
    /// noise figure and the data's criteria read them, at λ².
    fn readings(system: &Eigensystem, lin: &Linearisation, d: &[f64], lambda2: f64) -> (f64, f64) {
        let gram = system.area_gram(lin);
        let b = system.coefficients(d);
        let y: Vec<f64> = system.eigenvalues.iter().zip(&b).map(|(e, b)| b / (e.max(0.0) + lambda2)).collect();
        let signal: f64 = (0..y.len()).map(|i| y[i] * (0..y.len()).map(|j| gram[(i, j)] * y[j]).sum::<f64>()).sum();
        // The residual of the fit, with every direction outside the eigenvectors' span at e = 0.
        let kept: f64 = b.iter().map(|b| b * b).sum();
        let outside = (d.iter().map(|d| d * d).sum::<f64>() - kept).max(0.0);
        let residual: f64 =
            system.eigenvalues.iter().zip(&b).map(|(e, b)| (lambda2 / (e.max(0.0) + lambda2) * b).powi(2)).sum();
        (signal, residual + outside)
    }

    /// The matrix from the eigenpairs is the one a Cholesky factorisation of JR⁻¹Jᵀ + λ²Σ gives,
    /// decomposed whole or on the range alone, at every λ the search covers.
    #[test]
    fn the_matrix_from_the_eigenpairs_is_the_factorised_one() {
        let mut spec = crate::SensorSpec::square_hydrogel();
        spec.mesh.triangles = 400;
        let lin = Linearisation::new(&spec.forward_model().unwrap(), 1.0).unwrap();
        let m = lin.measurements();
        let variance: Vec<f64> = (0..m).map(|i| 1.0 + (i % 7) as f64).collect();
        let channels = Channels::all(m).with_variance(variance).masked(&(0..m).map(|i| i != 5).collect::<Vec<_>>());
        let prior = Prior::default();
        for (normalised, on_range) in [(false, true), (false, false), (true, false)] {
            let jacobian = lin.rows(&channels.used(), normalised).unwrap();
            let r = prior.diagonal(jacobian.as_ref()).unwrap();
            let system = Eigensystem::build(&lin, &prior, normalised, &channels, on_range).unwrap();
            // The target's signal, as J's rows give it.
            let target = [0, 17, 203];
            let response = system.response_to(&lin, &target);
            for (i, z) in response.iter().enumerate() {
                let want: f64 = target.iter().map(|&t| jacobian[(i, t)]).sum();
                assert!((z - want).abs() <= 1e-14 * want.abs().max(1e-300), "channel {i}: {z} vs {want}");
            }
            for lambda in [1e-3, 0.1, 3.0, 300.0] {
                let variance = channels.relative_variance();
                let factorised =
                    super::super::linearisation::measurement_sized(jacobian.as_ref(), &r, lambda, &variance).unwrap();
                let got = system.compact_matrix_and_mix(&lin, lambda).unwrap().0;
                let largest =
                    factorised.col_iter().flat_map(|c| c.iter().copied()).fold(0.0_f64, |a, h| a.max(h.abs()));
                // Both round to the system's condition, about e_max/λ², times the precision.
                let condition = 1.0 + system.eigenvalues.last().unwrap() / (lambda * lambda);
                let tolerance = 1e-14 * condition.max(1e4) * largest;
                for j in 0..got.ncols() {
                    for i in 0..got.nrows() {
                        let (a, b) = (got[(i, j)], factorised[(i, j)]);
                        assert!((a - b).abs() <= tolerance, "λ {lambda} ({normalised}): {a} vs {b} at ({i}, {j})");
                    }
                }
            }
        }
    }

    /// On a 32-electrode disc measuring every adjacent pair (1,024 channels, rank at most 496),
    /// the decomposition of the range alone has the whole one's nonzero eigenvalues, and gives
    /// the same image of a target and the same residual of a frame at every λ.
    #[test]
    fn the_range_alone_holds_every_nonzero_eigenpair() {
        let lin = super::super::linearisation::thirty_two_electrode_disc();
        let m = lin.measurements();
        let variance: Vec<f64> = (0..m).map(|i| 1.0 + (i % 5) as f64).collect();
        let channels = Channels::all(m).with_variance(variance);
        let reduced = Eigensystem::new(&lin, &Prior::default(), false, &channels).unwrap();
        let whole = Eigensystem::build(&lin, &Prior::default(), false, &channels, false).unwrap();
        let r = reduced.eigenvalues.len();
        assert!(r <= 496 && whole.eigenvalues.len() == m, "the range has {r} of {m} dimensions");
        let largest = whole.eigenvalues[m - 1];
        for (got, want) in reduced.eigenvalues.iter().rev().zip(whole.eigenvalues.iter().rev()) {
            assert!((got - want).abs() <= 1e-9 * largest, "{got} vs {want}");
        }
        // Past the range, the whole system's eigenvalues are rounding.
        assert!(whole.eigenvalues[..m - r].iter().all(|e| e.abs() < 1e-12 * largest));
        // A target's signal (in the range) and an arbitrary vector (mostly outside it).
        let response = reduced.response_to(&lin, &(0..40).collect::<Vec<_>>());
        let target: Vec<f64> = response.iter().zip(&reduced.std).map(|(z, s)| z / s).collect();
        let d: Vec<f64> = (0..m).map(|i| ((i * 37) % 11) as f64 - 5.0).collect();
        for lambda in [1e-4, 1e-2, 1.0, 100.0] {
            let lambda2 = lambda * lambda * largest;
            for v in [&target, &d] {
                let (a, b) = (readings(&reduced, &lin, v, lambda2), readings(&whole, &lin, v, lambda2));
                assert!((a.0 / b.0 - 1.0).abs() < 1e-7, "λ {lambda}: image {} vs {}", a.0, b.0);
                // (to the size of the vector: at small λ the residual is rounding in either)
                let size: f64 = v.iter().map(|x| x * x).sum();
                assert!((a.1 - b.1).abs() < 1e-9 * size, "λ {lambda}: residual {} vs {} of {size}", a.1, b.1);
            }
        }
    }
}
