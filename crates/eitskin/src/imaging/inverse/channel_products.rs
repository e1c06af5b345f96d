//! What every derivation on one set of channels shares, whatever their noise: the products
//! J_S R⁻¹ J_Sᵀ and J_S R⁻¹ A² R⁻¹ J_Sᵀ of the channels' rows J_S of the Jacobian (divided by v₀
//! when normalised), the diagonal prior R they set and the triangles' areas A, measurement-sized.
//!
//! For noise Σ the whitened system is Σ^-½ (J_S R⁻¹ J_Sᵀ) Σ^-½ and the noise figure's Gram
//! matrix Σ^-½ (J_S R⁻¹ A² R⁻¹ J_Sᵀ) Σ^-½: channels² to form from these instead of channels² ×
//! triangles. A live sensor derives its λ and weights again each time its noise is measured
//! anew (four times in its first 150 frames), on the same channels: the linearisation keeps
//! the products of the last few channel sets ([`ProductsCache`]) for every reconstructor
//! derived from it.

use std::sync::{Arc, Mutex};

use faer::{Mat, MatRef};

use super::eigensystem::weighted_gram;
use super::linearisation::inverse_diagonal;
use super::product::BlockedMatrix;
use super::{InverseError, Linearisation, Prior};

/// The measurement-sized products of one set of channels (see the module doc).
#[derive(Debug)]
pub(crate) struct ChannelProducts {
    /// The channels (indices into the frame), their normalisation and the prior: the key.
    pub used: Vec<usize>,
    normalised: bool,
    prior: Prior,
    /// Per used channel, the factor of its row: 1/v₀ when normalised, else 1 (J_S = diag(scale) J[S, :]).
    pub scale: Vec<f64>,
    /// 1/R per triangle (R the prior's diagonal on J_S, floored where 0).
    pub r_inv: Vec<f64>,
    /// J_S R⁻¹ J_Sᵀ, used × used, both halves.
    pub gram: Mat<f64>,
    /// J_S R⁻¹ A² R⁻¹ J_Sᵀ, used × used, both halves.
    pub area_gram: Mat<f64>,
    /// R⁻¹ J_Sᵀ on the rasters asked for (the triangle under each pixel, and the basis), the
    /// newest last, at most [`KEPT_BASES`] (see [`super::shared_basis`]).
    bases: Mutex<Vec<RasterBasis>>,
}

/// A raster (the triangle under each pixel) and R⁻¹ J_Sᵀ on it.
type RasterBasis = (Vec<Option<usize>>, Arc<BlockedMatrix>);

/// Rasters whose basis a channel set keeps.
const KEPT_BASES: usize = 2;

impl ChannelProducts {
    /// The products of channels `used` of `lin` (J's rows divided by v₀ when `normalised`)
    /// under the diagonal `prior`: channels² × triangles of work, twice.
    fn new(lin: &Linearisation, used: &[usize], normalised: bool, prior: &Prior) -> Result<Self, InverseError> {
        let (jacobian, r) = lin.rows_with_diagonal(used, normalised, prior)?;
        let r_inv = inverse_diagonal(&r);
        let mesh = lin.mesh();
        // R⁻¹ as the whitened system has it, R⁻¹·R·R⁻¹ (0 where J's column is, as R is).
        let gram = weighted_gram(jacobian.as_ref(), |k| r_inv[k] * r_inv[k] * r[k]);
        let area_gram = weighted_gram(jacobian.as_ref(), |k| (r_inv[k] * mesh.area(k)).powi(2));
        let scale = lin.row_scale(used, normalised)?;
        let bases = Mutex::default();
        Ok(ChannelProducts { used: used.to_vec(), normalised, prior: *prior, scale, r_inv, gram, area_gram, bases })
    }

    /// R⁻¹ J_Sᵀ on the raster whose pixels lie on triangles `pixels`, made once for every
    /// reconstructor of this channel set ([`super::shared_basis::raster_basis`]).
    pub fn raster_basis(&self, lin: &Linearisation, pixels: &[Option<usize>]) -> Arc<BlockedMatrix> {
        // The newest last: a raster asked for again moves there, the oldest is dropped.
        let kept = |bases: &mut Vec<RasterBasis>| {
            let at = bases.iter().position(|(on, _)| on == pixels)?;
            let entry = bases.remove(at);
            let basis = Arc::clone(&entry.1);
            bases.push(entry);
            Some(basis)
        };
        if let Some(basis) = kept(&mut self.bases.lock().unwrap_or_else(|e| e.into_inner())) {
            return basis;
        }
        // Made without the lock held (a second thread asking meanwhile makes it too, and keeps
        // the first one's).
        let made = Arc::new(super::shared_basis::raster_basis(lin, self, pixels));
        let mut bases = self.bases.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(basis) = kept(&mut bases) {
            return basis;
        }
        if bases.len() == KEPT_BASES {
            bases.remove(0);
        }
        bases.push((pixels.to_vec(), Arc::clone(&made)));
        made
    }

    fn is_for(&self, used: &[usize], normalised: bool, prior: &Prior) -> bool {
        self.used == used && self.normalised == normalised && self.prior == *prior
    }

    /// J_Sᵀ `m` for `m` used × k, through J's own columns (no copy of J_S): triangles × k; in
    /// blocks of about [`ROW_BLOCK`] triangles with a [step aside](crate::parallel::set_step_aside)
    /// between where the thread asked for one.
    pub fn transposed_times(&self, lin: &Linearisation, m: MatRef<'_, f64>) -> Mat<f64> {
        // J_Sᵀ m = J[S, :]ᵀ diag(scale) m = Jᵀ m', m' with m's rows scaled and put at S's rows.
        let mut spread = Mat::zeros(lin.measurements(), m.ncols());
        for (i, (&row, s)) in self.used.iter().zip(&self.scale).enumerate() {
            for j in 0..m.ncols() {
                spread[(row, j)] = s * m[(i, j)];
            }
        }
        match crate::parallel::stepping_aside() {
            true => product_in_blocks(lin.jacobian().transpose(), spread.as_ref(), ROW_BLOCK),
            false => lin.jacobian().transpose() * spread,
        }
    }

    /// J_S·1 over `triangles`: each used channel's change for 1 S/m on each of them.
    pub fn response_to(&self, lin: &Linearisation, triangles: &[usize]) -> Vec<f64> {
        let jacobian = lin.jacobian();
        let sum = |row: usize| triangles.iter().map(|&t| jacobian[(row, t)]).sum::<f64>();
        self.used.iter().zip(&self.scale).map(|(&row, s)| sum(row) * s).collect()
    }
}

/// Triangles of J_Sᵀ·m made in one piece, at most: about half a millisecond for 120 channels.
const ROW_BLOCK: usize = 512;

/// `lhs`·`rhs` in row blocks of equal size, at most `block` rows each (none of a few rows, which
/// faer would take as dot products, rounded otherwise), stepping aside between them; each entry
/// as the one product gives it where faer's own kernels run (x86-64 with AVX2 or AVX-512).
fn product_in_blocks(lhs: MatRef<'_, f64>, rhs: MatRef<'_, f64>, block: usize) -> Mat<f64> {
    let rows = lhs.nrows();
    let size = rows.div_ceil(rows.div_ceil(block.max(1)).max(1)).max(1);
    let mut product = Mat::zeros(rows, rhs.ncols());
    for first in (0..rows).step_by(size) {
        if first > 0 {
            crate::parallel::step_aside();
        }
        let part = size.min(rows - first);
        faer::linalg::matmul::matmul(
            product.as_mut().subrows_mut(first, part),
            faer::Accum::Replace,
            lhs.subrows(first, part),
            rhs,
            1.0,
            faer::get_global_parallelism(),
        );
    }
    product
}

/// The products of the channel sets a linearisation was last derived on, at most [`KEPT`]
/// (each channels² × 16 bytes); equal to any other (it changes no result).
#[derive(Default)]
pub(crate) struct ProductsCache(Mutex<Vec<Arc<ChannelProducts>>>);

/// Channel sets a linearisation keeps the products of (the newest).
const KEPT: usize = 4;

impl ProductsCache {
    /// The products of `used` of `lin` under `prior`, kept from before or made now (see
    /// [`ChannelProducts::new`]) and kept.
    pub fn get(
        &self,
        lin: &Linearisation,
        used: &[usize],
        normalised: bool,
        prior: &Prior,
    ) -> Result<Arc<ChannelProducts>, InverseError> {
        // The newest last: a set used again moves there, the oldest is dropped.
        let kept = |entries: &mut Vec<Arc<ChannelProducts>>| {
            let at = entries.iter().position(|p| p.is_for(used, normalised, prior))?;
            let products = entries.remove(at);
            entries.push(Arc::clone(&products));
            Some(products)
        };
        if let Some(products) = kept(&mut self.0.lock().unwrap_or_else(|e| e.into_inner())) {
            return Ok(products);
        }
        // Made without the lock held (a second thread asking meanwhile makes them too, and
        // keeps the first one's).
        let made = Arc::new(ChannelProducts::new(lin, used, normalised, prior)?);
        let mut entries = self.0.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(products) = kept(&mut entries) {
            return Ok(products);
        }
        if entries.len() >= KEPT {
            entries.remove(0);
        }
        entries.push(Arc::clone(&made));
        Ok(made)
    }
}

/// A clone starts with none kept (reconstructors share one linearisation through an `Arc`).
impl Clone for ProductsCache {
    fn clone(&self) -> Self {
        ProductsCache::default()
    }
}

impl PartialEq for ProductsCache {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl std::fmt::Debug for ProductsCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let kept = self.0.lock().map_or(0, |entries| entries.len());
        write!(f, "ProductsCache {{ kept: {kept} }}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A channel set's products are made once and kept, each set (channels, normalisation,
    /// prior) its own, equal to the sums they stand for; a clone makes its own; the oldest of
    /// more than [`KEPT`] sets is dropped.
    #[test]
    fn each_channel_sets_products_are_made_once_and_kept() {
        let mut spec = crate::SensorSpec::square_hydrogel();
        spec.mesh.triangles = 400;
        let lin = Linearisation::new(&spec.forward_model().unwrap(), 1.0).unwrap();
        let all: Vec<usize> = (0..lin.measurements()).collect();
        let noser = Prior::default();
        let first = lin.channel_products(&all, false, &noser).unwrap();
        assert!(Arc::ptr_eq(&first, &lin.channel_products(&all, false, &noser).unwrap()));
        assert!(!Arc::ptr_eq(&first, &lin.clone().channel_products(&all, false, &noser).unwrap()));
        let mesh = lin.mesh();
        let others = [
            (&all[..], true, noser),
            (&all[..], false, Prior::Tikhonov),
            (&all[..], true, Prior::Tikhonov),
            (&all[3..], false, noser),
        ];
        for (used, normalised, prior) in others {
            let products = lin.channel_products(used, normalised, &prior).unwrap();
            assert!(!Arc::ptr_eq(&products, &first));
            let j = lin.rows(used, normalised).unwrap();
            let r_inv = inverse_diagonal(&prior.diagonal(j.as_ref()).unwrap());
            for (a, b) in [(0, 0), (1, 7), (used.len() - 1, 2)] {
                let sum = |w: &dyn Fn(usize) -> f64| (0..j.ncols()).map(|k| j[(a, k)] * j[(b, k)] * w(k)).sum::<f64>();
                let (gram, area_gram) = (sum(&|k| r_inv[k]), sum(&|k| (r_inv[k] * mesh.area(k)).powi(2)));
                // (to the size of the diagonal: an entry may be small by cancellation)
                let close = |got: &Mat<f64>, want: f64| {
                    (got[(a, b)] - want).abs() <= 1e-12 * (got[(a, a)] * got[(b, b)]).sqrt()
                        && got[(a, b)] == got[(b, a)]
                };
                assert!(close(&products.gram, gram), "({a}, {b}): {} vs {gram}", products.gram[(a, b)]);
                assert!(close(&products.area_gram, area_gram), "({a}, {b}): {area_gram}");
            }
        }
        // Four sets were asked for after the first: it was dropped, and is made again; a set
        // asked for again is kept as the newest.
        assert!(!Arc::ptr_eq(&first, &lin.channel_products(&all, false, &noser).unwrap()));
        let tikhonov = lin.channel_products(&all, false, &Prior::Tikhonov).unwrap();
        for fewer in [&all[1..], &all[2..], &all[4..]] {
            lin.channel_products(fewer, false, &noser).unwrap();
            assert!(Arc::ptr_eq(&tikhonov, &lin.channel_products(&all, false, &Prior::Tikhonov).unwrap()));
        }
        assert_eq!(
            lin.channel_products(&all, false, &Prior::Laplace).unwrap_err(),
            InverseError::AutoNeedsDiagonalPrior
        );
    }

    /// J_Sᵀ·m made in row blocks, stepping aside between, is the one product Jᵀ·m' (m's rows
    /// scaled and put at the channels' rows) entry for entry, and J_Sᵀ·m to rounding (normalised
    /// rows, channels missing, more triangles than a block); so is a product of 1 to 2,000 rows
    /// in blocks (counts one past a multiple of the block among them), on this machine's kernels.
    #[test]
    fn the_product_made_in_blocks_is_the_whole_one() {
        let mut spec = crate::SensorSpec::square_hydrogel();
        spec.mesh.triangles = 2 * ROW_BLOCK + 300;
        let lin = Linearisation::new(&spec.forward_model().unwrap(), 1.0).unwrap();
        assert!(lin.jacobian().ncols() > 2 * ROW_BLOCK);
        let used: Vec<usize> = (0..lin.measurements()).filter(|m| m % 7 != 3).collect();
        let products = lin.channel_products(&used, true, &Prior::default()).unwrap();
        let m = Mat::<f64>::from_fn(used.len(), 5, |i, j| ((i * 13 + j * 5) % 17) as f64 - 8.0);
        let whole = products.transposed_times(&lin, m.as_ref());
        crate::parallel::set_step_aside(std::time::Duration::from_micros(1));
        let blocks = products.transposed_times(&lin, m.as_ref());
        crate::parallel::set_step_aside(std::time::Duration::ZERO);
        assert_eq!(blocks, whole);
        let direct = lin.rows(&used, true).unwrap().transpose() * &m;
        assert!((&blocks - &direct).norm_max() <= 1e-12 * direct.norm_max());
        for rows in [1, 511, 513, 1025, 1537, 2000] {
            let lhs = Mat::<f64>::from_fn(rows, 120, |i, k| ((i * 120 + k) as f64 * 0.7).sin());
            let rhs = Mat::<f64>::from_fn(120, 120, |k, j| ((k * 120 + j) as f64 * 1.3).cos() / (1.0 + k as f64));
            assert_eq!(product_in_blocks(lhs.as_ref(), rhs.as_ref(), ROW_BLOCK), &lhs * &rhs, "{rows} rows");
        }
    }
}
