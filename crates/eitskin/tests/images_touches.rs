//! Images and touches on eitskin's own meshes, with data simulated on a finer mesh
//! than the one reconstructed on (no inverse crime).

use eitskin::conductivity::{with_inclusions, Inclusion};
use eitskin::inverse::reconstruction_matrix;
use eitskin::touch::detect;
use eitskin::{ForwardModel, Prior, Reconstructor, ReconstructorParams, SensorSpec, TouchParams};

fn paper(triangles: usize) -> SensorSpec {
    let mut spec = SensorSpec::square_hydrogel();
    spec.mesh.triangles = triangles;
    spec
}

/// Frames of the paper sensor simulated on its own 8,000-triangle mesh.
struct Truth {
    model: ForwardModel,
    reference: Vec<f64>,
}

impl Truth {
    fn new() -> Truth {
        let spec = paper(8000);
        let model = spec.forward_model().unwrap();
        let reference = model.measure(&spec.homogeneous(model.mesh())).unwrap();
        Truth { model, reference }
    }

    fn frame(&self, presses: &[Inclusion]) -> Vec<f64> {
        self.model.measure(&with_inclusions(self.model.mesh(), 1.0, presses)).unwrap()
    }
}

fn press(x: f64, y: f64) -> Inclusion {
    Inclusion { centre: [x, y], radius: 0.01, conductivity: 0.5 }
}

#[test]
fn a_single_inclusion_anywhere_is_found_within_a_tenth_of_the_side() {
    let truth = Truth::new();
    let model = paper(3000).forward_model().unwrap();
    let recon = Reconstructor::new(&model, 1.0, &ReconstructorParams::default()).unwrap();
    let mut worst = 0.0f64;
    for i in 0..7 {
        for j in 0..7 {
            let (x, y) = (-0.075 + 0.025 * i as f64, -0.075 + 0.025 * j as f64);
            let image = recon.image(&truth.reference, &truth.frame(&[press(x, y)])).unwrap();
            let touches = detect(&image, &TouchParams::default());
            assert_eq!(touches.len(), 1, "press at ({x}, {y}): {touches:?}");
            let c = touches[0].centre;
            worst = worst.max((c[0] - x).hypot(c[1] - y));
        }
    }
    eprintln!("49 presses over the sheet: worst centre-of-gravity error {:.1} mm", worst * 1e3);
    assert!(worst < 0.02, "worst position error {worst} m on a 0.2 m sheet");
}

#[test]
fn two_inclusions_far_apart_give_two_touches() {
    let truth = Truth::new();
    let model = paper(3000).forward_model().unwrap();
    let recon = Reconstructor::new(&model, 1.0, &ReconstructorParams::default()).unwrap();
    let (a, b) = ([-0.05, -0.05], [0.05, 0.05]);
    let image = recon.image(&truth.reference, &truth.frame(&[press(a[0], a[1]), press(b[0], b[1])])).unwrap();
    let touches = detect(&image, &TouchParams::default());
    assert_eq!(touches.len(), 2, "{touches:?}");
    for target in [a, b] {
        let nearest = touches
            .iter()
            .map(|t| (t.centre[0] - target[0]).hypot(t.centre[1] - target[1]))
            .fold(f64::INFINITY, f64::min);
        assert!(nearest < 0.02, "no touch within 20 mm of {target:?}: {touches:?}");
    }
}

#[test]
fn f32_raster_images_agree_with_the_f64_element_matrix() {
    let model = paper(2000).forward_model().unwrap();
    let params = ReconstructorParams::default();
    let recon = Reconstructor::new(&model, 1.0, &params).unwrap();
    let jacobian = model.jacobian(&model.solve(&vec![1.0; model.mesh().triangles().len()]).unwrap());
    let rm = reconstruction_matrix(jacobian.as_ref(), &Prior::default(), 0.1, model.mesh()).unwrap();
    let map = eitskin::RasterMap::new(model.mesh(), params.raster);
    let truth = Truth::new();
    let v = truth.frame(&[press(0.03, -0.04)]);
    let image = recon.image(&truth.reference, &v).unwrap();
    let dv: Vec<f64> = v.iter().zip(&truth.reference).map(|(a, b)| a - b).collect();
    let exact: Vec<f64> =
        map.triangle.iter().map(|t| t.map_or(0.0, |t| (0..dv.len()).map(|m| rm[(t, m)] * dv[m]).sum())).collect();
    let peak = exact.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let worst = image.values.iter().zip(&exact).map(|(a, b)| (*a as f64 - b).abs()).fold(0.0, f64::max) / peak;
    assert!(worst < 1e-5, "f32 image differs from f64 by {worst:e} of the peak");
}

#[test]
fn bad_frames_are_refused_with_the_measurement_named() {
    let model = paper(500).forward_model().unwrap();
    let recon = Reconstructor::new(&model, 1.0, &ReconstructorParams::default()).unwrap();
    let reference = vec![1.0; 120];
    let err = recon.image(&reference, &[1.0; 119]).unwrap_err();
    assert_eq!(err.to_string(), "a frame has 119 values but the protocol has 120 measurements");
    let mut bad = reference.clone();
    bad[41] = f64::NAN;
    assert_eq!(
        recon.image(&reference, &bad).unwrap_err().to_string(),
        "measurement 42 of the frame is not a finite number"
    );
}
