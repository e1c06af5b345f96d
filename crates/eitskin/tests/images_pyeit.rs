//! On pyEIT's mesh with point electrodes, our Jacobian and one-step images (plain and
//! normalised differences) match pyEIT's to 1e-8 relative. pyEIT's J carries the opposite sign
//! and its "lm" prior is λ·diag(JᵀJ): our NOSER with exponent 1 and hyperparameter √λ.

mod common;

use common::{floats, json};
use eitskin::inverse::{normalize_jacobian, reconstruction_matrix};
use eitskin::{ElectrodeModel, ForwardModel, Mesh, Prior, Protocol};
use eitskin_testdata::max_relative_error;

fn model() -> (ForwardModel, serde_json::Value) {
    let data = json("pyeit/square16_4k.json");
    let m = &data["mesh"];
    let point = |p: &serde_json::Value| [p[0].as_f64().unwrap(), p[1].as_f64().unwrap()];
    let nodes: Vec<[f64; 2]> = m["nodes"].as_array().unwrap().iter().map(point).collect();
    let index = |v: &serde_json::Value| v.as_u64().unwrap() as usize;
    let triangles =
        m["triangles"].as_array().unwrap().iter().map(|t| [index(&t[0]), index(&t[1]), index(&t[2])]).collect();
    let electrodes = m["electrode_nodes"].as_array().unwrap().iter().map(|n| vec![index(n)]).collect();
    let mesh = Mesh::new(nodes, triangles, electrodes).unwrap();
    (ForwardModel::new(mesh, ElectrodeModel::Point, 1.0, Protocol::adjacent(16, true).unwrap()).unwrap(), data)
}

#[test]
fn jacobian_and_images_match_pyeit() {
    let (model, data) = model();
    let recon = json("pyeit/square16_4k_jacobian_recon.json");
    let n = model.mesh().triangles().len();
    let solution = model.solve(&vec![1.0; n]).unwrap();
    let jacobian = model.jacobian(&solution);

    // pyEIT's J = −∂v/∂σ.
    for (m, row) in recon["jacobian"]["rows_excitation0"].as_array().unwrap().iter().enumerate() {
        let ours: Vec<f64> = (0..n).map(|k| -jacobian[(m, k)]).collect();
        let err = max_relative_error(&ours, &floats(row));
        assert!(err < 1e-8, "Jacobian row {m} differs by {err:e}");
    }
    let sums: Vec<f64> = (0..n).map(|k| -(0..jacobian.nrows()).map(|m| jacobian[(m, k)]).sum::<f64>()).collect();
    assert!(max_relative_error(&sums, &floats(&recon["jacobian"]["column_sums"])) < 1e-8);

    let v0 = floats(&data["adjacent"]["v_homogeneous"]);
    let v1 = floats(&data["adjacent"]["v_inclusion"]);
    let prior = Prior::Noser { exponent: 1.0 };
    let lambda = 0.1f64.sqrt();
    let image = |rm: &eitskin::faer::Mat<f64>, dv: &[f64]| -> Vec<f64> {
        (0..n).map(|k| (0..dv.len()).map(|m| rm[(k, m)] * dv[m]).sum()).collect()
    };

    let rm = reconstruction_matrix(jacobian.as_ref(), &prior, lambda, model.mesh()).unwrap();
    let dv: Vec<f64> = v1.iter().zip(&v0).map(|(a, b)| a - b).collect();
    let err = max_relative_error(&image(&rm, &dv), &floats(&recon["noser_lambda0.1_plain"]["ds"]));
    eprintln!("pyEIT plain image: {err:.2e} of the peak");
    assert!(err < 1e-8, "plain image differs by {err:e}");

    let mut normalised = jacobian.clone();
    normalize_jacobian(&mut normalised, &solution.measurements(model.protocol())).unwrap();
    let rm = reconstruction_matrix(normalised.as_ref(), &prior, lambda, model.mesh()).unwrap();
    let dv: Vec<f64> = v1.iter().zip(&v0).map(|(a, b)| a / b - 1.0).collect();
    let err = max_relative_error(&image(&rm, &dv), &floats(&recon["noser_lambda0.1_normalized"]["ds"]));
    eprintln!("pyEIT normalised image: {err:.2e} of the peak");
    assert!(err < 1e-8, "normalised image differs by {err:e}");
}
