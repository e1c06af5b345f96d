//! With point electrodes on pyEIT's own distmesh of the 2×2 square, eitskin gives
//! pyEIT's adjacent (and pair) voltages to 1e-8 relative, homogeneous and with an inclusion.
//! Conventions are in `testdata/reference/pyeit/README.md`.

mod common;

use common::{floats, json};
use eitskin::{ElectrodeModel, ForwardModel, Mesh, Protocol};
use eitskin_testdata::max_relative_error;

fn pyeit_model(protocol: Protocol) -> (ForwardModel, serde_json::Value) {
    let data = json("pyeit/square16_4k.json");
    let m = &data["mesh"];
    let nodes: Vec<[f64; 2]> =
        m["nodes"].as_array().unwrap().iter().map(|p| [p[0].as_f64().unwrap(), p[1].as_f64().unwrap()]).collect();
    let triangles: Vec<[usize; 3]> = m["triangles"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| std::array::from_fn(|k| t[k].as_u64().unwrap() as usize))
        .collect();
    let electrodes =
        m["electrode_nodes"].as_array().unwrap().iter().map(|n| vec![n.as_u64().unwrap() as usize]).collect();
    let mesh = Mesh::new(nodes, triangles, electrodes).unwrap();
    assert_eq!(mesh.triangles().len(), 3949);
    (ForwardModel::new(mesh, ElectrodeModel::Point, 1.0, protocol).unwrap(), data)
}

fn inclusion_conductivity(data: &serde_json::Value, triangles: usize) -> Vec<f64> {
    let inclusion = &data["conductivity"]["inclusion"];
    let mut sigma = vec![1.0; triangles];
    for t in inclusion["triangles"].as_array().unwrap() {
        sigma[t.as_u64().unwrap() as usize] = inclusion["value"].as_f64().unwrap();
    }
    sigma
}

fn check(protocol: Protocol, key: &str) {
    let (model, data) = pyeit_model(protocol);
    let n = model.mesh().triangles().len();
    for (case, sigma) in [("v_homogeneous", vec![1.0; n]), ("v_inclusion", inclusion_conductivity(&data, n))] {
        let v = model.measure(&sigma).unwrap();
        let err = max_relative_error(&v, &floats(&data[key][case]));
        eprintln!("pyEIT {key} {case}: worst error {err:.2e} of the largest value");
        assert!(err < 1e-8, "{key} {case}: {err:e}");
    }
}

#[test]
fn adjacent_point_electrodes_match_pyeit() {
    check(Protocol::adjacent(16, true).unwrap(), "adjacent");
}

#[test]
fn pair_point_electrodes_match_pyeit() {
    check(Protocol::two_terminal(16).unwrap(), "pairs");
}

#[test]
fn adjacent_difference_signal_matches_pyeit() {
    let (model, data) = pyeit_model(Protocol::adjacent(16, true).unwrap());
    let n = model.mesh().triangles().len();
    let v0 = model.measure(&vec![1.0; n]).unwrap();
    let v1 = model.measure(&inclusion_conductivity(&data, n)).unwrap();
    let dv: Vec<f64> = v1.iter().zip(&v0).map(|(a, b)| a - b).collect();
    let (r1, r0) = (floats(&data["adjacent"]["v_inclusion"]), floats(&data["adjacent"]["v_homogeneous"]));
    let dv_ref: Vec<f64> = r1.iter().zip(&r0).map(|(a, b)| a - b).collect();
    let err = max_relative_error(&dv, &dv_ref);
    assert!(err < 1e-8, "difference signal differs by {err:e} of its peak");
}
