//! The low-rank update of a local change is a new solve, whatever the change: one to three
//! disks anywhere on the sheet (across its edge, over the ground node, overlapping or apart), from
//! a triangle's size to a fifth of the sheet, lowering or raising the conductivity, so that their
//! interiors are eliminated or not; against the forward model solved in full.

use std::sync::OnceLock;

use eitskin::conductivity::{with_inclusions, Inclusion};
use eitskin::forward::LowRankUpdate;
use eitskin::{ForwardModel, SensorSpec};
use proptest::prelude::*;

/// The paper's sensor on an 800-triangle mesh, and its update at 1 S/m (made once).
fn setup() -> &'static (ForwardModel, LowRankUpdate) {
    static SETUP: OnceLock<(ForwardModel, LowRankUpdate)> = OnceLock::new();
    SETUP.get_or_init(|| {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 800;
        let model = spec.forward_model().unwrap();
        let update = LowRankUpdate::new(&model, &vec![1.0; model.mesh().triangles().len()]).unwrap();
        (model, update)
    })
}

/// A disk centred on or just past the 200 mm sheet, 2–40 mm across its radius, its conductivity
/// lowered or raised.
fn inclusion() -> impl Strategy<Value = Inclusion> {
    ([-0.11..0.11f64, -0.11..0.11f64], 0.002..0.04f64, prop_oneof![0.02..0.98f64, 1.02..4.0f64])
        .prop_map(|(centre, radius, conductivity)| Inclusion { centre, radius, conductivity })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, max_shrink_iters: 0, ..ProptestConfig::default() })]

    #[test]
    fn a_local_change_is_a_new_solve(inclusions in prop::collection::vec(inclusion(), 1..4)) {
        let (model, update) = setup();
        let sigma = with_inclusions(model.mesh(), 1.0, &inclusions);
        let changes: Vec<(usize, f64)> =
            sigma.iter().enumerate().filter(|(_, s)| **s != 1.0).map(|(t, s)| (t, s - 1.0)).collect();
        prop_assume!(!changes.is_empty());
        let dv = update.measurement_change(&changes).unwrap();
        let solved = model.measure(&sigma).unwrap();
        let full: Vec<f64> = solved.iter().zip(update.background_measurements()).map(|(v, v0)| v - v0).collect();
        let scale = full.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
        for (m, (d, f)) in dv.iter().zip(&full).enumerate() {
            prop_assert!((d - f).abs() <= 1e-8 * scale, "m {m}: {d} against {f} (largest {scale}), {inclusions:?}");
        }
    }
}
