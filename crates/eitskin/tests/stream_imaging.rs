//! The frame path images as `eitskin image` does: normalised differences, touches of either
//! sign, and λ chosen from the reference frames' own noise.

use eitskin::chain::Chain;
use eitskin::inverse::{choose_hyperparameter, noise_variance, Channels};
use eitskin::pipeline::{Pipeline, PipelineParams, Status};
use eitskin::sim::VirtualSensor;
use eitskin::touch::Polarity;
use eitskin::{Reconstructor, ReconstructorParams, SensorSpec, TouchParams};

const PRESS: [f64; 2] = [-0.05, 0.03];

/// A pipeline on the paper's sensor (coarse mesh) with these settings, and its virtual skin.
fn setup(params: ReconstructorParams, touch: TouchParams, auto: bool) -> (Pipeline, VirtualSensor) {
    let mut spec = SensorSpec::square_hydrogel();
    spec.mesh.triangles = 800;
    let recon = Reconstructor::new(&spec.forward_model().unwrap(), 1.0, &params).unwrap();
    let pipeline_params = PipelineParams { auto_hyperparameter: auto, ..PipelineParams::default() };
    (Pipeline::new(Chain::new(recon, touch), pipeline_params), VirtualSensor::new(&spec, 5).unwrap())
}

/// Takes the reference, presses 10 N at [`PRESS`] and returns the distance of the strongest
/// touch from it, in m.
fn found_at(pipeline: &mut Pipeline, skin: &mut VirtualSensor) -> f64 {
    for _ in 0..10 {
        pipeline.process(&skin.frame().unwrap()).unwrap();
    }
    skin.press(PRESS, 10.0);
    assert_eq!(pipeline.process(&skin.frame().unwrap()).unwrap(), Status::Processed);
    let c = pipeline.touches().first().expect("a touch").touch.centre;
    (c[0] - PRESS[0]).hypot(c[1] - PRESS[1])
}

#[test]
fn normalised_differences_find_the_press() {
    let params = ReconstructorParams { normalised: true, ..ReconstructorParams::default() };
    let (mut pipeline, mut skin) = setup(params, TouchParams::default(), false);
    assert!(found_at(&mut pipeline, &mut skin) < 0.015);
    assert!(pipeline.chain().reconstructor().params().normalised);
    assert!(pipeline.image().values.iter().all(|v| v.is_finite()));
}

#[test]
fn with_both_polarities_the_press_is_a_decrease() {
    let touch = TouchParams { polarity: Polarity::Both, ..TouchParams::default() };
    let (mut pipeline, mut skin) = setup(ReconstructorParams::default(), touch, false);
    assert!(found_at(&mut pipeline, &mut skin) < 0.015);
    assert_eq!(pipeline.touches()[0].touch.polarity, Polarity::Decrease);
    // The sheet made more conductive is an increase; with `decrease` alone it is no touch.
    let touch = TouchParams { polarity: Polarity::Both, ..TouchParams::default() };
    let (mut pipeline, mut skin) = setup(ReconstructorParams::default(), touch, false);
    let mut frames: Vec<Vec<f64>> = (0..10).map(|_| skin.frame().unwrap()).collect();
    skin.press(PRESS, 10.0);
    // Swap the roles: frames of the pressed sheet as the reference (each with its noise, as a
    // board sends them: one frame repeated measures no noise), the rest as the frame.
    let rest = frames.pop().unwrap();
    for _ in 0..10 {
        pipeline.process(&skin.frame().unwrap()).unwrap();
    }
    pipeline.process(&rest).unwrap();
    let strongest = pipeline.touches().first().expect("a touch");
    assert_eq!(strongest.touch.polarity, Polarity::Increase, "{strongest:?}");
}

#[test]
fn auto_lambda_is_chosen_from_the_reference_noise() {
    let (mut pipeline, mut skin) = setup(ReconstructorParams::default(), TouchParams::default(), true);
    let mut reference = Vec::new();
    for k in 0..10 {
        let frame = skin.frame().unwrap();
        reference.push(frame.clone());
        let status = pipeline.process(&frame).unwrap();
        assert_eq!(status, Status::Referencing { collected: k + 1, needed: 10 });
        if k < 9 {
            assert_eq!(pipeline.hyperparameter(), 0.1, "λ is the given one until the reference is in");
        }
    }
    // The λ of the noise figure for the noise these very frames show.
    let recon = pipeline.chain().reconstructor();
    // Relative noise, in the model's units (V² at 1 A) as the pipeline weighs it.
    let relative = noise_variance(&reference).unwrap();
    let model = recon.linearisation().background();
    let channels = Channels::all(120).with_variance(relative.iter().zip(model).map(|(r, v)| r * v * v).collect());
    let expected = choose_hyperparameter(recon.linearisation(), &recon.params().prior, false, &channels).unwrap();
    let lambda = pipeline.hyperparameter();
    assert!((lambda / expected - 1.0).abs() < 1e-9 && (lambda / 0.1 - 1.0).abs() > 0.05, "λ = {lambda}, {expected}");
    skin.press(PRESS, 10.0);
    pipeline.process(&skin.frame().unwrap()).unwrap();
    let c = pipeline.touches().first().expect("a touch").touch.centre;
    assert!((c[0] - PRESS[0]).hypot(c[1] - PRESS[1]) < 0.015, "{c:?}");
}
