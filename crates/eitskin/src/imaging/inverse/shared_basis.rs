//! A reconstructor as a basis shared by every reconstructor of one linearisation and channel
//! set, times a small mix of its own: H = B·M on the raster, with B = R⁻¹ J_Sᵀ (the triangle
//! under each pixel; pixels × used channels, whatever the noise and λ) and
//! M = Σ^-½ V diag(1/(e + λ²)) Vᵀ Σ^-½ (used × used, the sensor's own). A frame costs
//! channels² multiply-adds for y = M·Δv, then B·y: sensors of one spec (a fleet of identical
//! patches) read one basis, which stays in the cache, where each would read its own matrix
//! from memory.
//!
//! Kept for reconstructors whose λ was chosen on the whole eigensystem of at most
//! [`SHARED_CHANNELS`] channels (without a background change), and read only where asked
//! ([`Reconstructor::set_shared_basis`](super::Reconstructor::set_shared_basis)). Each
//! pixel then differs from the matrix's image by the rounding of two single-precision products
//! instead of one.

use std::sync::Arc;

use faer::MatRef;

use super::channel_products::ChannelProducts;
use super::product::BlockedMatrix;
use super::Linearisation;

/// The most channels a reconstructor keeps its mix for (its buffers are on the stack).
pub(crate) const SHARED_CHANNELS: usize = 256;

/// A reconstructor's own mix M and the products its basis comes from.
#[derive(Debug)]
pub(crate) struct ChannelMix {
    products: Arc<ChannelProducts>,
    /// M, used × used, column-major (whitened channels' weights: H = B·M).
    mix: Vec<f32>,
}

impl PartialEq for ChannelMix {
    fn eq(&self, other: &Self) -> bool {
        self.mix == other.mix && Arc::ptr_eq(&self.products, &other.products)
    }
}

impl ChannelMix {
    /// M (used × used) for the channel set of `products`; `None` past [`SHARED_CHANNELS`].
    pub(crate) fn new(products: Arc<ChannelProducts>, mix: MatRef<'_, f64>) -> Option<ChannelMix> {
        let n = products.used.len();
        if n > SHARED_CHANNELS || mix.nrows() != n || mix.ncols() != n {
            return None;
        }
        let mix = (0..n).flat_map(|j| (0..n).map(move |i| mix[(i, j)] as f32)).collect();
        Some(ChannelMix { products, mix })
    }

    /// B on the raster whose pixels lie on triangles `pixels` (`None` outside), kept with the
    /// products for every reconstructor of the set.
    pub(crate) fn basis(&self, lin: &Linearisation, pixels: &[Option<usize>]) -> Arc<BlockedMatrix> {
        self.products.raster_basis(lin, pixels)
    }

    /// `out` = B·(M·d), d's entry for used channel i being `difference(m)` of its channel m;
    /// allocates nothing.
    pub(crate) fn mul_into(&self, basis: &BlockedMatrix, out: &mut [f32], difference: impl Fn(usize) -> f32) {
        let used = &self.products.used;
        let n = used.len();
        debug_assert_eq!(basis.columns(), n, "a basis of the mix's channels");
        let (mut d, mut y) = ([0.0_f32; SHARED_CHANNELS], [0.0_f32; SHARED_CHANNELS]);
        d.iter_mut().zip(used).for_each(|(d, &m)| *d = difference(m));
        mix_into(&mut y[..n], &self.mix, &d[..n]);
        basis.mul_into(out, |i| y[i]);
    }
}

crate::parallel::widest! {
    /// `y` = M·`d` for M column-major (`mix`, d's length squared).
    fn mix_into = mix_portable(y: &mut [f32], mix: &[f32], d: &[f32]) -> ()
}

/// [`mix_into`] in portable code: one column of M at a time, added to `y`.
#[inline(always)]
fn mix_portable(y: &mut [f32], mix: &[f32], d: &[f32]) {
    y.fill(0.0);
    for (column, dj) in mix.chunks_exact(d.len().max(1)).zip(d) {
        y.iter_mut().zip(column).for_each(|(y, m)| *y += m * dj);
    }
}

/// B = R⁻¹ J_Sᵀ (J_S's rows divided by v₀ when normalised) on the raster: per pixel the row of
/// the triangle under it (0 outside), per used channel a column; single precision.
pub(crate) fn raster_basis(lin: &Linearisation, products: &ChannelProducts, pixels: &[Option<usize>]) -> BlockedMatrix {
    let jacobian = lin.jacobian();
    let mut basis = BlockedMatrix::zeros(pixels.len(), products.used.len());
    for (first, i, lanes) in basis.blocks_mut() {
        let (row, scale) = (products.used[i], products.scale[i]);
        let under =
            pixels[first..].iter().map(|t| t.map_or(0.0, |t| (products.r_inv[t] * jacobian[(row, t)] * scale) as f32));
        lanes.iter_mut().zip(under).for_each(|(b, v)| *b = v);
    }
    basis
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::inverse::{Channels, Prior, Reconstructor, ReconstructorParams};

    /// Three sensors' reconstructors of one spec, λ chosen from different noise (absolute and
    /// normalised differences; a channel dropped; 100 times less noise): through the shared
    /// basis each frame's image is the matrix's within 1e-5 of its peak; sensors of the same
    /// channels share one basis; a reconstructor with λ given has none and images as before.
    #[test]
    fn images_through_the_shared_basis_are_the_matrix_images() {
        let mut spec = crate::SensorSpec::square_hydrogel();
        spec.mesh.triangles = 800;
        let model = spec.forward_model().unwrap();
        for normalised in [false, true] {
            let params = ReconstructorParams { normalised, raster: [40, 40], ..ReconstructorParams::default() };
            let recon = Reconstructor::new(&model, 1.0, &params).unwrap();
            let m = recon.measurements();
            assert!(!recon.clone().set_shared_basis(true), "λ given: no mix");
            let v_ref = model.measure(&vec![1.0; model.mesh().triangles().len()]).unwrap();
            let mut pressed = vec![1.0; model.mesh().triangles().len()];
            pressed.iter_mut().step_by(9).for_each(|s| *s = 0.7);
            let v = model.measure(&pressed).unwrap();
            let mut used = vec![true; m];
            used[17] = false;
            let mut first_basis = None;
            // 0.1–0.2 % noise; a channel dropped; and 0.001–0.002 % (λ much smaller).
            let sensors = [(Channels::all(m), 1e-6), (Channels::all(m).masked(&used), 1e-6), (Channels::all(m), 1e-10)];
            for (sensor, (channels, level)) in sensors.into_iter().enumerate() {
                let noise: Vec<f64> = (0..m).map(|k| level * (1.0 + ((k * 7 + sensor) % 5) as f64)).collect();
                let (alone, _) = recon.with_auto_hyperparameter(channels, Some(noise)).unwrap();
                let mut shared = alone.clone();
                assert!(shared.set_shared_basis(true) && shared.shared_basis());
                let (want, got) = (alone.image(&v_ref, &v).unwrap(), shared.image(&v_ref, &v).unwrap());
                let peak = want.values.iter().fold(0.0_f32, |a, b| a.max(b.abs()));
                assert!(peak > 0.0);
                for (w, g) in want.values.iter().zip(&got.values) {
                    assert!((w - g).abs() <= 1e-5 * peak, "normalised {normalised}: {g} against {w} (peak {peak})");
                }
                // Sensors of the same channels share one basis, whatever their noise.
                let basis = Arc::clone(shared.basis().unwrap());
                match (sensor, &first_basis) {
                    (0, _) => first_basis = Some(basis),
                    (1, Some(first)) => assert!(!Arc::ptr_eq(first, &basis)),
                    (_, Some(first)) => assert!(Arc::ptr_eq(first, &basis)),
                    _ => unreachable!(),
                }
                assert!(!shared.set_shared_basis(false) && shared.image(&v_ref, &v).unwrap() == want);
            }
            let lin = recon.linearisation();
            let products = lin.channel_products(&(0..m).collect::<Vec<_>>(), normalised, &Prior::default()).unwrap();
            let pixels = vec![Some(3), None, Some(5)];
            assert!(Arc::ptr_eq(&products.raster_basis(lin, &pixels), &products.raster_basis(lin, &pixels)));
        }
    }
}
