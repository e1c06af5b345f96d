//! Touches told from noise by the measured noise: no more false touches than the stated rate
//! on an untouched sheet, and weak presses found, at a noise level a good board reaches.

use eitskin::chain::Chain;
use eitskin::pipeline::{NoiseFloor, Pipeline, PipelineParams, Status};
use eitskin::sim::{SimParams, VirtualSensor};
use eitskin::touch::PeakOf;
use eitskin::{Reconstructor, ReconstructorParams, SensorSpec, TouchParams};

/// The paper's sensor imaged on a coarse mesh, its virtual skin at `noise` (relative, per value),
/// and a pipeline testing touches at 1 false touch per 1,000 frames, averaging `average` frames.
fn setup(noise: f64, average: usize, peak_of: PeakOf) -> (Pipeline, VirtualSensor) {
    let mut spec = SensorSpec::square_hydrogel();
    spec.mesh.triangles = 1500;
    let recon = Reconstructor::new(&spec.forward_model().unwrap(), 1.0, &ReconstructorParams::default()).unwrap();
    let touch = TouchParams { peak_of, ..TouchParams::default() };
    let params = PipelineParams {
        noise_floor: NoiseFloor::FalseAlarm { rate: 1e-3 },
        auto_hyperparameter: true,
        average,
        ..PipelineParams::default()
    };
    let sim = SimParams { noise_relative: noise, ..SimParams::default() };
    (Pipeline::new(Chain::new(recon, touch), params), VirtualSensor::with_params(&spec, sim, 17).unwrap())
}

fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Takes the reference from 10 frames of the untouched skin; its clean frame.
fn reference(pipeline: &mut Pipeline, skin: &mut VirtualSensor) -> Vec<f64> {
    let clean = skin.clean_frame().unwrap();
    for _ in 0..10 {
        pipeline.process(&skin.noisy(&clean)).unwrap();
    }
    assert!(pipeline.noise_measured() && pipeline.significance().is_some());
    clean
}

#[test]
fn an_untouched_sheet_shows_false_touches_at_the_stated_rate_at_most() {
    let (mut pipeline, mut skin) = setup(5e-4, 1, PeakOf::Touch);
    let clean = reference(&mut pipeline, &mut skin);
    let (frames, mut false_frames, mut updates) = (3000, 0, 0);
    for _ in 0..frames {
        let status = pipeline.process(&skin.noisy(&clean)).unwrap();
        updates += usize::from(status == Status::NoiseUpdated);
        false_frames += usize::from(!pipeline.touches().is_empty());
    }
    // 3 expected at 1e-3; the first frames test against noise measured on 10 frames only.
    assert!(false_frames <= 9, "{false_frames} of {frames} untouched frames showed a touch");
    // The model grew on every frame (10 → 3,010 frames); of its 7 checks, λ and the threshold
    // were derived again only where the noise had changed: the 10 frames' estimate is coarse
    // (a channel's variance from 9 degrees of freedom is off by half), a steady board's later
    // ones are not.
    assert!((1..7).contains(&updates), "{updates} refreshes");
    assert!(pipeline.noise().unwrap().frames() > 900.0);
}

/// Presses of 2 N (a 27 % drop under the indenter), single frames at 0.05 % noise: each found
/// by the noise test, by either rule (the old floor, twice the reference frames' largest image
/// peak, found 28 of 30 here). Positions are the image's centre of gravity, which the edges pull
/// inward.
#[test]
fn weak_presses_pass_the_noise_test() {
    for peak_of in [PeakOf::Frame, PeakOf::Touch] {
        let (mut pipeline, mut skin) = setup(5e-4, 1, peak_of);
        reference(&mut pipeline, &mut skin);
        let spots = [[0.0, 0.0], [0.05, 0.05], [-0.06, 0.03], [0.07, -0.07], [-0.03, -0.08], [0.085, 0.0]];
        let (mut found, mut tried) = (0, 0);
        for at in spots {
            skin.release();
            skin.press(at, 2.0);
            let clean = skin.clean_frame().unwrap();
            for _ in 0..5 {
                pipeline.process(&skin.noisy(&clean)).unwrap();
                tried += 1;
                found += usize::from(pipeline.touches().iter().any(|t| distance(t.touch.centre, at) < 0.03));
            }
        }
        assert_eq!(found, tried, "{peak_of:?}: 2 N presses: {found} of {tried} found");
    }
}
