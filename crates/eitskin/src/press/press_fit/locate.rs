//! One press anywhere on the sheet, whatever Δv's unit: the fitted press as a feature of a
//! frame (where, and how strong), for data whose scale nobody states (a board's counts, a data
//! set's arbitrary units).

use super::scan::Scan;
use super::{PressFit, PressModel, PressScratch};

/// Response-grid points between scan points: a quarter of the indenter's radius each, so the
/// scan's step is its radius.
pub const STRIDE: usize = 4;

/// A press model ready to place one press anywhere on the sheet: the best point of a scan grid
/// of every [`STRIDE`]-th response-grid point each way (one matrix product small enough for a
/// core's cache: a press's correlation with Δv varies over its own size, so the best scan point is
/// next to the best point), then the fit on the full grid within one scan step of it.
#[derive(Debug, Clone)]
pub struct Locator {
    model: PressModel,
    scan: Scan,
    /// |Δv| the search runs at: small enough that no grid point's drop passes its bound.
    search_norm: f64,
}

impl Locator {
    /// The locator of `model` (mask or whiten it first: [`PressModel::masked`],
    /// [`PressModel::whitened`]).
    pub fn new(model: PressModel) -> Locator {
        let scan = Scan::with_stride(&model, STRIDE);
        let smallest = model.norms.iter().filter(|&&n| n > 0.0).fold(f64::INFINITY, |a, &n| a.min(n.sqrt()));
        // gᵀΔv/gᵀg ≤ |Δv|/|g|: at a thousandth of the smallest |g| every contrast is ≤ 1e-3.
        Locator { search_norm: 1e-3 * smallest, model, scan }
    }

    /// The single press that matches `dv` best anywhere on the sheet (largest gᵀΔv/|g| with
    /// gᵀΔv > 0), with its contrast and z in Δv's own unit (per unit of the model's); `None` for
    /// a Δv of the wrong length, zero, not finite, or like no press. Where it is does not depend on
    /// Δv's scale, so no bound on the drop applies (the drop is read from the contrast as if Δv
    /// were in the model's unit). Allocates nothing once `scratch` has grown.
    pub fn locate_into(&self, dv: &[f64], scratch: &mut PressScratch) -> Option<PressFit> {
        let m = self.model.measurements;
        let norm = dv.iter().map(|v| v * v).sum::<f64>().sqrt();
        if dv.len() != m || !(norm > 0.0 && norm.is_finite()) || self.scan.points.is_empty() {
            return None;
        }
        // The search on Δv scaled to `search_norm`: the same place, every drop within bounds.
        let scale = self.search_norm / norm;
        scratch.residual.clear();
        scratch.residual.extend(dv.iter().map(|v| v * scale));
        scratch.response.resize(m, 0.0);
        let (j, _) = self.model.best_point(&self.scan, &scratch.residual, &[], &mut scratch.correlations)?;
        let window = STRIDE as f64 * self.model.grid.spacing;
        let fit = self.model.fit_one(&scratch.residual, self.model.grid.point(j), window, &mut scratch.response)?;
        let contrast = fit.contrast / scale;
        Some(PressFit { contrast, z: fit.z / scale, drop: self.model.drop(contrast, fit.centre), ..fit })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::press_fit::PressModelParams;
    use crate::SensorSpec;

    /// A press is placed where it is, at any scale of Δv, within a grid spacing.
    #[test]
    fn a_press_is_placed_at_any_scale() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 1500;
        let model = spec.forward_model().unwrap();
        let press = PressModel::new(&model, 1.0, &PressModelParams::default()).unwrap();
        let locator = Locator::new(press.clone());
        let mut scratch = PressScratch::default();
        let mut dv = vec![0.0; press.measurements()];
        for (p, scale) in [([0.03, -0.05], 1.0), ([-0.06, 0.02], 1e6), ([0.0, 0.07], 1e-6)] {
            assert!(press.response_into(p, &mut dv));
            dv.iter_mut().for_each(|v| *v *= 0.2 * scale);
            let fit = locator.locate_into(&dv, &mut scratch).unwrap();
            let off = (fit.centre[0] - p[0]).hypot(fit.centre[1] - p[1]);
            assert!(off < 2.5e-3, "{p:?} at scale {scale}: placed {off} m off");
            assert!((fit.contrast / (0.2 * scale) - 1.0).abs() < 0.05, "contrast {} at scale {scale}", fit.contrast);
        }
        assert!(locator.locate_into(&vec![0.0; press.measurements()], &mut scratch).is_none());
        assert!(locator.locate_into(&[1.0], &mut scratch).is_none());
    }
}
