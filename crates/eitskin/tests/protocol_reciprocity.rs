//! Reciprocity of the built-in protocols on the complete electrode model: driving pair P and
//! measuring pair Q gives the value of driving Q and measuring P. In the all-pairs adjacent
//! and skip protocols row L·k + m is (drive k, measure m) with both pairs of the same shape,
//! so v[L·k + m] = v[L·m + k]; the two-terminal protocol drives and measures the same pair.

use eitskin::{Outline, Placement, ProtocolSpec, SensorSpec};

fn pentagon(protocol: ProtocolSpec) -> SensorSpec {
    let mut spec = SensorSpec::square_hydrogel();
    spec.outline =
        Outline::Polygon { points: vec![[-0.1, -0.08], [0.12, -0.1], [0.1, 0.05], [0.0, 0.12], [-0.11, 0.06]] };
    spec.electrodes.placement = Placement::Equal { start_angle_deg: 75.0 };
    spec.protocol = protocol;
    spec.mesh.triangles = 1500;
    spec
}

#[test]
fn all_pairs_protocols_are_reciprocal() {
    for protocol in [ProtocolSpec::AdjacentAll, ProtocolSpec::Skip { skip: 2, skip_driven: false }] {
        let spec = pentagon(protocol);
        let model = spec.forward_model().unwrap();
        let l = spec.electrodes.count;
        // An uneven sheet: conductivity rising to the right, so no symmetry makes this trivial.
        let sigma: Vec<f64> =
            (0..model.mesh().triangles().len()).map(|t| 1.0 + 5.0 * (model.mesh().centroid(t)[0] + 0.11)).collect();
        let v = model.measure(&sigma).unwrap();
        assert_eq!(v.len(), l * l);
        let scale = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for k in 0..l {
            for m in 0..l {
                let (a, b) = (v[l * k + m], v[l * m + k]);
                assert!(
                    (a - b).abs() <= 1e-9 * scale,
                    "{}: drive {k} measure {m}: {a} vs {b}",
                    model.protocol().description()
                );
            }
        }
    }
}
