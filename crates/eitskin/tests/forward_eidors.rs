//! On EIDORS' own 40×40 mesh of the 2×2 square, eitskin's complete electrode model
//! gives EIDORS' voltages (both protocols, homogeneous and all 20 inclusions) to 1e-6 relative.
//! Conventions are in `testdata/reference/eidors/README.md`.

mod common;

use common::{floats, json};
use eitskin::{ElectrodeModel, ForwardModel, Protocol};
use eitskin_testdata::{max_relative_error, reference};

fn model(protocol: Protocol) -> ForwardModel {
    let mesh = eitskin_io::read_mesh(&reference("eidors/mesh.json")).unwrap();
    assert_eq!((mesh.nodes().len(), mesh.triangles().len()), (1681, 3200));
    let electrodes = ElectrodeModel::Complete { contact_impedance: vec![0.01; 16] };
    ForwardModel::new(mesh, electrodes, 1.0, protocol).unwrap()
}

/// EIDORS' quads (0-based in its file) as a protocol.
fn protocol(name: &str) -> Protocol {
    let file = json(&format!("eidors/protocol_{name}.json"));
    let quads: Vec<[usize; 4]> = file["quads"]
        .as_array()
        .unwrap()
        .iter()
        .map(|q| std::array::from_fn(|k| q[k].as_u64().unwrap() as usize + 1))
        .collect();
    Protocol::from_quads(name, 16, &quads).unwrap()
}

fn elementwise_relative(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| ((x - y) / y).abs()).fold(0.0, f64::max)
}

fn check(name: &str, builtin: Protocol) {
    let file = protocol(name);
    assert_eq!(file.measurements(), builtin.measurements(), "our {name} protocol is EIDORS' order");
    let model = model(builtin);
    let reference = json(&format!("eidors/protocol_{name}.json"));
    let homogeneous = vec![1.0; 3200];
    let v = model.measure(&homogeneous).unwrap();
    let v_ref = floats(&reference["v_homog"]);
    let err = elementwise_relative(&v, &v_ref);
    eprintln!("{name}: homogeneous, worst relative error {err:.2e}");
    assert!(err < 1e-6, "{name}: homogeneous voltages differ by {err:e}");

    let cases = json(&format!("eidors/cases_{name}.json"));
    let mut worst = (0.0f64, 0.0f64);
    for case in cases["cases"].as_array().unwrap() {
        let mut sigma = homogeneous.clone();
        let elems = case["perturbed_elems"].as_array().unwrap();
        for (e, s) in elems.iter().zip(floats(&case["perturbed_sigma"])) {
            sigma[e.as_u64().unwrap() as usize] = s;
        }
        let v_inhom = model.measure(&sigma).unwrap();
        let dv: Vec<f64> = v_inhom.iter().zip(&v).map(|(a, b)| a - b).collect();
        worst.0 = worst.0.max(elementwise_relative(&v_inhom, &floats(&case["v_inhom"])));
        worst.1 = worst.1.max(max_relative_error(&dv, &floats(&case["dv"])));
    }
    eprintln!("{name}: 20 inclusions, voltages {:.2e}, differences {:.2e} of their peak", worst.0, worst.1);
    assert!(worst.0 < 1e-6 && worst.1 < 1e-6, "{name}: inclusion voltages differ: {worst:?}");

    // Node potentials of the example stimulation, with the same ground node at (0, 0).
    let stim = reference["example_stim_index"].as_u64().unwrap() as usize;
    let solution = model.solve(&homogeneous).unwrap();
    let current = &model.protocol().stimulations()[model.protocol().measurements()[stim].stimulation];
    assert_eq!(model.mesh().nodes()[model.ground_node()], [0.0, 0.0]);
    let nodes = model.node_potentials(&solution, current);
    let err = max_relative_error(&nodes, &floats(&reference["example_node_voltages"]));
    assert!(err < 1e-6, "{name}: node potentials differ by {err:e}");
}

#[test]
fn two_terminal_matches_eidors() {
    check("two_terminal", Protocol::two_terminal(16).unwrap());
}

#[test]
fn adjacent_matches_eidors() {
    check("adjacent", Protocol::adjacent(16, true).unwrap());
}
