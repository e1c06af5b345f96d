//! A channel going bad mid-stream (its values NaN, as a board marks a lost one): the pipeline
//! drops it, names it, keeps imaging and fitting presses without it, and refuses frames that
//! would leave more than a quarter of the channels dropped.

use eitskin::chain::Chain;
use eitskin::pipeline::{Pipeline, PipelineParams, Status};
use eitskin::press_fit::{PressModel, PressModelParams};
use eitskin::sim::VirtualSensor;
use eitskin::{InverseError, Reconstructor, ReconstructorParams, SensorSpec, TouchParams};

const PRESS: [f64; 2] = [0.04, -0.03];

fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// A pipeline with a press model on the paper's sensor (coarse mesh), its reference taken.
fn referenced(with_press_model: bool) -> (Pipeline, VirtualSensor) {
    let mut spec = SensorSpec::square_hydrogel();
    spec.mesh.triangles = 800;
    let model = spec.forward_model().unwrap();
    let recon = Reconstructor::new(&model, 1.0, &ReconstructorParams::default()).unwrap();
    let mut chain = Chain::new(recon, TouchParams::default());
    if with_press_model {
        chain = chain.with_press_model(PressModel::new(&model, 1.0, &PressModelParams::default()).unwrap());
    }
    let mut pipeline = Pipeline::new(chain, PipelineParams::default());
    let mut skin = VirtualSensor::new(&spec, 11).unwrap();
    for _ in 0..10 {
        pipeline.process(&skin.frame().unwrap()).unwrap();
    }
    assert!(pipeline.dropped_channels().is_empty());
    (pipeline, skin)
}

/// The channel that carries the most of the press's signal: losing it hurts most.
fn strongest_channel(skin: &mut VirtualSensor) -> usize {
    let rest = skin.clean_frame().unwrap();
    skin.press(PRESS, 10.0);
    let touch = skin.clean_frame().unwrap();
    skin.release();
    (0..rest.len()).max_by(|&a, &b| (touch[a] - rest[a]).abs().total_cmp(&(touch[b] - rest[b]).abs())).unwrap()
}

#[test]
fn a_channel_lost_mid_stream_is_dropped_named_and_the_press_still_found() {
    let (mut pipeline, mut skin) = referenced(true);
    let lost = strongest_channel(&mut skin);
    skin.press(PRESS, 10.0);
    let mut frame = skin.frame().unwrap();
    frame[lost] = f64::NAN;
    assert_eq!(pipeline.process(&frame).unwrap(), Status::ChannelsDropped { count: 1 });
    assert_eq!((pipeline.newly_dropped(), pipeline.dropped_channels()), (&[lost][..], vec![lost]));
    let check = |pipeline: &Pipeline| {
        assert!(pipeline.image().values.iter().all(|v| v.is_finite()), "NaN reached the image");
        let touches = pipeline.touches();
        assert_eq!(touches.len(), 1, "{touches:?}");
        let found = touches[0];
        assert!(distance(found.touch.centre, PRESS) < 0.015, "{found:?}");
        let press = found.press.expect("a press fitted without the channel");
        assert!(distance(press.centre, PRESS) < 0.015 && press.drop.is_finite() && press.drop > 0.0, "{press:?}");
    };
    check(&pipeline);
    // Dropped it stays: even a wild finite value on it next changes nothing.
    let mut frame = skin.frame().unwrap();
    frame[lost] = 1e6;
    assert_eq!(pipeline.process(&frame).unwrap(), Status::Processed);
    assert!(pipeline.newly_dropped().is_empty() && pipeline.dropped_channels() == [lost]);
    check(&pipeline);
    // Until the reference is taken again.
    skin.release();
    pipeline.retake_reference();
    for _ in 0..10 {
        pipeline.process(&skin.frame().unwrap()).unwrap();
    }
    assert!(pipeline.dropped_channels().is_empty());
}

#[test]
fn more_than_a_quarter_bad_is_refused_and_changes_nothing() {
    let (mut pipeline, mut skin) = referenced(false);
    // 30 of 120 is a quarter, not more: dropped, and imaging goes on.
    let mut frame = skin.frame().unwrap();
    frame[..30].fill(f64::NAN);
    assert_eq!(pipeline.process(&frame).unwrap(), Status::ChannelsDropped { count: 30 });
    // One more, in another frame, is too many in all.
    let mut frame = skin.frame().unwrap();
    frame[100] = f64::INFINITY;
    let err = pipeline.process(&frame).unwrap_err();
    assert_eq!(err, InverseError::TooManyBadChannels { bad: 31, new: 1, channels: 120, first: (1..=8).collect() });
    let text = err.to_string();
    assert!(text.starts_with("31 of 120 channels are missing or not finite (1 of them new"), "{text}");
    assert!(text.contains("first: [1, 2, 3, 4, 5, 6, 7, 8]"), "{text}");
    assert!(pipeline.newly_dropped().is_empty());
    assert_eq!(pipeline.dropped_channels(), (0..30).collect::<Vec<_>>(), "the refused frame changed nothing");
    skin.press(PRESS, 10.0);
    assert_eq!(pipeline.process(&skin.frame().unwrap()).unwrap(), Status::Processed);
    assert!(distance(pipeline.touches()[0].touch.centre, PRESS) < 0.015, "{:?}", pipeline.touches());

    // Many at once in one frame: refused, naming them.
    let (mut pipeline, mut skin) = referenced(false);
    let mut frame = skin.frame().unwrap();
    frame.iter_mut().skip(40).take(40).for_each(|v| *v = f64::NAN);
    let err = pipeline.process(&frame).unwrap_err();
    assert_eq!(err, InverseError::TooManyBadChannels { bad: 40, new: 40, channels: 120, first: (41..=48).collect() });
    assert!(pipeline.dropped_channels().is_empty());
}
