//! On a disk, the finite-element forward model converges under mesh refinement to
//! independent analytic answers (a Fourier-series solution of the complete electrode model,
//! and the point-electrode dipole), and it is reciprocal; quadratic elements converge to the
//! same answer, faster.

use std::f64::consts::PI;

use eitskin::analytic::disk_point_dipole;
use eitskin::{ElectrodeModel, ForwardModel, Outline, Placement, Protocol, SensorSpec};
use eitskin_study::convergence::{disk_values, relative_error};

/// The unit disk, σ = 1 S/m, t = 1 m, 16 electrodes 0.1 m wide from angle 0, z = 0.01 Ω·m².
fn disk(triangles: usize) -> SensorSpec {
    let mut spec = SensorSpec::square_hydrogel();
    spec.length_unit = eitskin::LengthUnit::Metre;
    spec.thickness = 1.0;
    spec.outline = Outline::Circle { radius: 1.0 };
    spec.electrodes.width = 0.1;
    spec.electrodes.contact_impedance = 0.01;
    spec.electrodes.placement = Placement::Equal { start_angle_deg: 0.0 };
    spec.mesh.triangles = triangles;
    spec
}

/// Errors at 1k, 4k and 16k triangles, and the observed orders in h ∝ N^(−1/2) (h halves per step).
fn convergence(protocol: Protocol) -> (Vec<f64>, Vec<f64>) {
    let mut truth_spec = disk(1000);
    truth_spec.protocol = eitskin::ProtocolSpec::Custom(protocol.clone());
    let truth = disk_values(&truth_spec).unwrap().expect("a disk with complete electrodes has an analytic answer");
    let levels = [1000, 4000, 16000];
    let mut errors = Vec::new();
    for n in levels {
        let mut spec = disk(n);
        spec.protocol = eitskin::ProtocolSpec::Custom(protocol.clone());
        let model = spec.forward_model().unwrap();
        let v = model.measure(&spec.homogeneous(model.mesh())).unwrap();
        errors.push(relative_error(&v, &truth));
    }
    let orders = errors.windows(2).map(|e| (e[0] / e[1]).log2()).collect();
    (errors, orders)
}

#[test]
fn two_terminal_converges_to_the_fourier_solution() {
    let (errors, orders) = convergence(Protocol::two_terminal(16).unwrap());
    eprintln!("disk two-terminal: errors {errors:?}, orders in h {orders:?}");
    assert!(errors.windows(2).all(|e| e[1] < 0.5 * e[0]), "errors must fall: {errors:?}");
    assert!(orders.iter().all(|&p| p > 1.0), "order in h below 1: {orders:?}");
    assert!(errors[2] < 1e-2, "16k triangles: {:.2e}", errors[2]);
}

#[test]
fn adjacent_converges_to_the_fourier_solution() {
    let (errors, orders) = convergence(Protocol::adjacent(16, true).unwrap());
    eprintln!("disk adjacent: errors {errors:?}, orders in h {orders:?}");
    assert!(errors.windows(2).all(|e| e[1] < 0.5 * e[0]), "errors must fall: {errors:?}");
    assert!(errors[2] < 2e-3, "16k triangles: {:.2e}", errors[2]);
}

#[test]
fn quadratic_elements_converge_to_the_fourier_solution_faster() {
    let protocol = Protocol::adjacent(16, true).unwrap();
    let mut truth_spec = disk(1000);
    truth_spec.protocol = eitskin::ProtocolSpec::Custom(protocol.clone());
    let truth = disk_values(&truth_spec).unwrap().expect("a disk with complete electrodes has an analytic answer");
    let (mut linear, mut quadratic) = (Vec::new(), Vec::new());
    for n in [1000, 4000, 16000] {
        let mut spec = disk(n);
        spec.protocol = eitskin::ProtocolSpec::Custom(protocol.clone());
        let model = spec.forward_model().unwrap();
        let sigma = spec.homogeneous(model.mesh());
        linear.push(relative_error(&model.measure(&sigma).unwrap(), &truth));
        quadratic.push(relative_error(&model.measure_quadratic(&sigma).unwrap(), &truth));
    }
    eprintln!("disk adjacent, P1 {linear:?}, P2 {quadratic:?}");
    assert!(quadratic.windows(2).all(|e| e[1] < 0.5 * e[0]), "P2 errors must fall: {quadratic:?}");
    assert!(quadratic.iter().zip(&linear).all(|(q, l)| q < l), "P2 {quadratic:?} against P1 {linear:?}");
}

#[test]
fn point_electrodes_converge_to_the_dipole_potential() {
    let truth_for = |protocol: &Protocol| -> Vec<f64> {
        let angle = |l: usize| 2.0 * PI * l as f64 / 16.0;
        let at = |l: usize| [angle(l).cos(), angle(l).sin()];
        protocol
            .measurements()
            .iter()
            .map(|m| {
                let s = &protocol.stimulations()[m.stimulation];
                let (plus, minus) =
                    (s.iter().position(|&i| i > 0.0).unwrap(), s.iter().position(|&i| i < 0.0).unwrap());
                let u = |l| disk_point_dipole(1.0, 1.0, 1.0, angle(plus), angle(minus), at(l));
                m.weights.iter().enumerate().filter(|(_, w)| **w != 0.0).map(|(l, w)| w * u(l)).sum()
            })
            .collect()
    };
    let protocol = Protocol::adjacent(16, true).unwrap();
    let truth = truth_for(&protocol);
    let mut errors = Vec::new();
    for n in [1000, 4000, 16000] {
        let mut spec = disk(n);
        spec.electrodes.point = true;
        spec.protocol = eitskin::ProtocolSpec::Adjacent;
        let model = spec.forward_model().unwrap();
        errors.push(relative_error(&model.measure(&spec.homogeneous(model.mesh())).unwrap(), &truth));
    }
    eprintln!("disk point electrodes, adjacent: errors {errors:?}");
    assert!(errors.windows(2).all(|e| e[1] < 0.6 * e[0]), "errors must fall: {errors:?}");
    assert!(errors[2] < 1e-2, "{errors:?}");
}

#[test]
fn swapping_drive_and_measurement_pairs_gives_the_same_value() {
    let spec = disk(3000);
    let mesh = spec.mesh().unwrap();
    let electrodes = ElectrodeModel::Complete { contact_impedance: vec![0.01; 16] };
    let model = ForwardModel::new(mesh, electrodes, 1.0, Protocol::adjacent(16, false).unwrap()).unwrap();
    // An inhomogeneous, asymmetric conductivity: reciprocity must not rest on symmetry.
    let sigma: Vec<f64> = (0..model.mesh().triangles().len()).map(|t| 1.0 + 0.5 * (t as f64 * 0.37).sin()).collect();
    let solution = model.solve(&sigma).unwrap();
    let pattern = |a: usize, b: usize| {
        let mut p = vec![0.0; 16];
        p[a] = 1.0;
        p[b] = -1.0;
        p
    };
    let transfer = |drive: &[f64], measure: &[f64]| -> f64 {
        solution.electrode_voltages(drive).iter().zip(measure).map(|(u, w)| u * w).sum()
    };
    let mut worst = 0.0f64;
    for (a, b, c, d) in [(0, 1, 5, 9), (2, 3, 2, 3), (4, 12, 7, 8), (0, 8, 1, 15), (3, 10, 11, 2)] {
        let (forward, backward) = (transfer(&pattern(a, b), &pattern(c, d)), transfer(&pattern(c, d), &pattern(a, b)));
        worst = worst.max((forward - backward).abs() / forward.abs().max(1e-300));
    }
    assert!(worst < 1e-9, "reciprocity broken by {worst:e}");
}
