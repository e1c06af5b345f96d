//! On EIDORS' 40×40 mesh, our adjoint Jacobian, NOSER prior and one-step
//! Gauss–Newton images (λ = 0.1) match EIDORS' to 1e-6 relative, for both protocols.

mod common;

use common::{floats, json};
use eitskin::inverse::{reconstruction_matrix, Prior};
use eitskin::{ElectrodeModel, ForwardModel, Protocol};
use eitskin_testdata::{max_relative_error, reference};

fn check(name: &str, protocol: Protocol) {
    let mesh = eitskin_io::read_mesh(&reference("eidors/mesh.json")).unwrap();
    let electrodes = ElectrodeModel::Complete { contact_impedance: vec![0.01; 16] };
    let model = ForwardModel::new(mesh, electrodes, 1.0, protocol).unwrap();
    let jacobian = model.jacobian(&model.solve(&vec![1.0; 3200]).unwrap());
    let reference = json(&format!("eidors/protocol_{name}.json"));

    let rows = reference["jacobian_rows_index"].as_array().unwrap();
    for (row, values) in rows.iter().zip(reference["jacobian_rows"].as_array().unwrap()) {
        let m = row.as_u64().unwrap() as usize;
        let ours: Vec<f64> = (0..3200).map(|k| jacobian[(m, k)]).collect();
        let err = max_relative_error(&ours, &floats(values));
        assert!(err < 1e-6, "{name}: Jacobian row {m} differs by {err:e}");
    }
    let sumsq: Vec<f64> = (0..3200).map(|k| (0..jacobian.nrows()).map(|m| jacobian[(m, k)].powi(2)).sum()).collect();
    assert!(max_relative_error(&sumsq, &floats(&reference["jacobian_col_sumsq"])) < 1e-6);
    let noser = Prior::Noser { exponent: 0.5 }.diagonal(jacobian.as_ref()).unwrap();
    assert!(max_relative_error(&noser, &floats(&reference["noser_diag"])) < 1e-6);

    let rm = reconstruction_matrix(jacobian.as_ref(), &Prior::Noser { exponent: 0.5 }, 0.1, model.mesh()).unwrap();
    let mut worst = 0.0f64;
    let cases = json(&format!("eidors/cases_{name}.json"));
    for case in cases["cases"].as_array().unwrap() {
        let dv = floats(&case["dv"]);
        let image: Vec<f64> = (0..3200).map(|k| (0..dv.len()).map(|m| rm[(k, m)] * dv[m]).sum()).collect();
        worst = worst.max(max_relative_error(&image, &floats(&case["recon_delta_sigma"])));
    }
    eprintln!("{name}: 20 one-step NOSER images, worst error {worst:.2e} of the peak");
    assert!(worst < 1e-6, "{name}: images differ by {worst:e} of their peak");
}

#[test]
fn two_terminal_images_match_eidors() {
    check("two_terminal", Protocol::two_terminal(16).unwrap());
}

#[test]
fn adjacent_images_match_eidors() {
    check("adjacent", Protocol::adjacent(16, true).unwrap());
}
