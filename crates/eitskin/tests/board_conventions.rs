//! What a real board does to its values, each with a known truth on the virtual sensor (its own
//! finer mesh, no inverse crime, 0.3 % frame-to-frame noise as on open boards): per-channel
//! gains, a uniform background change between reference and frame, and complex values.
//!
//! The press is held for ten frames and they are averaged, as a static measurement would be;
//! the reference is twenty frames. A single 0.3 % frame of the paper's 120 channels places a
//! 10 N press only to about 20 mm, with noise blobs beside it: that limit is the noise's, and
//! each property here is checked against the same data without the board's distortion.

use eitskin::inverse::{mean_frame, Channels};
use eitskin::sim::{SimParams, VirtualSensor};
use eitskin::touch::{detect, Touch};
use eitskin::values::{signed_from_magnitudes, Component, Gains};
use eitskin::{Reconstructor, ReconstructorParams, SensorSpec, TouchParams};

const PRESS: [f64; 2] = [0.04, -0.03];
const NOISE: f64 = 0.003;

fn spec() -> SensorSpec {
    let mut spec = SensorSpec::square_hydrogel();
    spec.mesh.triangles = 1500;
    spec
}

fn sensor(spec: &SensorSpec, drift_per_hour: f64) -> VirtualSensor {
    let params = SimParams { noise_relative: NOISE, drift_per_hour, ..SimParams::default() };
    VirtualSensor::with_params(spec, params, 7).unwrap()
}

/// Twenty reference frames, then the mean of ten frames of a 10 N press (after `hours` of drift).
fn frames(skin: &mut VirtualSensor, hours: f64) -> (Vec<Vec<f64>>, Vec<f64>) {
    let references = (0..20).map(|_| skin.frame().unwrap()).collect();
    skin.advance(hours * 3600.0);
    skin.press(PRESS, 10.0);
    let pressed: Vec<Vec<f64>> = (0..10).map(|_| skin.frame().unwrap()).collect();
    (references, mean_frame(&pressed))
}

/// The one touch of an image made with λ chosen from the references' noise.
fn touches(recon: &Reconstructor, references: &[Vec<f64>], v: &[f64]) -> Vec<Touch> {
    let v_ref = mean_frame(references);
    let variance = eitskin::inverse::noise_variance(references);
    let channels = Channels::finite_in(&v_ref).masked(Channels::finite_in(v).used_mask());
    let (recon, _) = recon.with_auto_hyperparameter(channels, variance).unwrap();
    detect(&recon.image(&v_ref, v).unwrap(), &TouchParams::default())
}

fn distance(touch: &Touch) -> f64 {
    (touch.centre[0] - PRESS[0]).hypot(touch.centre[1] - PRESS[1])
}

#[test]
fn per_channel_gains_of_30_percent_are_estimated_and_divided_out() {
    let spec = spec();
    let recon = Reconstructor::new(&spec.forward_model().unwrap(), 1.0, &ReconstructorParams::default()).unwrap();
    let (references, v) = frames(&mut sensor(&spec, 0.0), 0.0);
    // Gains spread evenly over ±30 % around a board scale of 250 counts per volt.
    let truth: Vec<f64> = (0..120).map(|m| 250.0 * (1.0 + 0.3 * (((m * 37) % 120) as f64 / 59.5 - 1.0))).collect();
    let scale = |frame: &Vec<f64>| frame.iter().zip(&truth).map(|(x, g)| x * g).collect::<Vec<f64>>();
    let (board_refs, board_v): (Vec<Vec<f64>>, Vec<f64>) = (references.iter().map(scale).collect(), scale(&v));
    let gains = Gains::estimate(&mean_frame(&board_refs), recon.linearisation().background());
    assert!(gains.outliers.is_empty(), "{:?}", gains.outliers);
    // Up to one common factor (the sim's finer mesh gives slightly different values), the gains.
    let common = gains.median / 250.0;
    let worst = gains.gains.iter().zip(&truth).map(|(g, t)| (g / (t * common) - 1.0).abs()).fold(0.0, f64::max);
    eprintln!("gains: common factor {common:.4}, worst channel off by {:.2} %", 100.0 * worst);
    assert!(worst < 0.05, "a gain is off by {:.1} %", 100.0 * worst);
    let corrected =
        touches(&recon, &board_refs.iter().map(|r| gains.apply(r)).collect::<Vec<_>>(), &gains.apply(&board_v));
    assert_eq!(corrected.len(), 1, "{corrected:?}");
    assert!(distance(&corrected[0]) < 0.015, "{:?}", corrected[0].centre);
    // And it is the image a board without gains gives, to within a millimetre.
    let [free] = touches(&recon, &references, &v)[..] else { panic!("the gain-free data give one touch") };
    let apart = (free.centre[0] - corrected[0].centre[0]).hypot(free.centre[1] - corrected[0].centre[1]);
    assert!(apart < 1e-3, "{apart} m from the gain-free touch");
    // Normalised differences are immune to the gains by construction: the same press.
    let normalised = recon.rederive(&ReconstructorParams { normalised: true, ..*recon.params() }, Channels::all(120));
    let normalised = touches(&normalised.unwrap(), &board_refs, &board_v);
    assert_eq!(normalised.len(), 1, "{normalised:?}");
    assert!(distance(&normalised[0]) < 0.015, "{:?}", normalised[0].centre);
    let raw = touches(&recon, &board_refs, &board_v);
    let raw_error = raw.first().map_or(f64::INFINITY, distance);
    eprintln!("uncorrected: {} touch(es), the strongest {:.1} mm from the press", raw.len(), 1e3 * raw_error);
}

#[test]
fn a_3_percent_background_change_is_estimated_and_left_out() {
    let spec = spec();
    let params = ReconstructorParams { background_change: true, ..ReconstructorParams::default() };
    let recon = Reconstructor::new(&spec.forward_model().unwrap(), 1.0, &params).unwrap();
    // The gel's conductivity falls by 3 % between the reference and the pressed frame.
    let mut skin = sensor(&spec, 0.03);
    let (references, v) = frames(&mut skin, 1.0);
    let truth = skin.background() - 1.0;
    assert!((truth + 0.03).abs() < 1e-12);
    let v_ref = mean_frame(&references);
    let estimated = recon.background_change(&v_ref, &v).unwrap().unwrap();
    eprintln!("background change: true {truth:+.4} S/m, estimated {estimated:+.4} S/m");
    assert!((estimated - truth).abs() < 0.15 * truth.abs(), "estimated {estimated}, true {truth}");
    let found = touches(&recon, &references, &v);
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(distance(&found[0]) < 0.015, "{:?}", found[0].centre);
    let plain = recon.rederive(&ReconstructorParams::default(), Channels::all(120)).unwrap();
    let unremoved = touches(&plain, &references, &v);
    eprintln!(
        "without it: {} touch(es), the strongest {:.1} mm from the press, {:.0} mm² (with it: {:.0} mm²)",
        unremoved.len(),
        1e3 * unremoved.first().map_or(f64::INFINITY, distance),
        1e6 * unremoved.first().map_or(0.0, |t| t.area),
        1e6 * found[0].area
    );
}

#[test]
fn complex_values_image_through_their_magnitude_and_real_part() {
    let spec = spec();
    let recon = Reconstructor::new(&spec.forward_model().unwrap(), 1.0, &ReconstructorParams::default()).unwrap();
    let (references, v) = frames(&mut sensor(&spec, 0.0), 0.0);
    // Each channel's demodulator adds its own phase (a cable, a filter): up to ±40°.
    let phase: Vec<f64> = (0..120).map(|m| 0.7 * (((m * 53) % 120) as f64 / 59.5 - 1.0)).collect();
    let complex = |frame: &Vec<f64>| -> (Vec<f64>, Vec<f64>) {
        (
            frame.iter().zip(&phase).map(|(x, p)| x * p.cos()).collect(),
            frame.iter().zip(&phase).map(|(x, p)| x * p.sin()).collect(),
        )
    };
    let model = recon.linearisation().background();
    let magnitude = |frame: &Vec<f64>| {
        let (re, im) = complex(frame);
        let (signed, report) = signed_from_magnitudes(&Component::Magnitude.of_frame(&re, &im), model);
        assert!(report.unexplained.is_empty(), "{report:?}");
        signed
    };
    let found = touches(&recon, &references.iter().map(magnitude).collect::<Vec<_>>(), &magnitude(&v));
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(distance(&found[0]) < 0.015, "{:?}", found[0].centre);
    // The real part alone carries cos(phase) per channel: a gain, which normalised differences remove.
    let real = |frame: &Vec<f64>| complex(frame).0;
    let normalised = recon.rederive(&ReconstructorParams { normalised: true, ..*recon.params() }, Channels::all(120));
    let found = touches(&normalised.unwrap(), &references.iter().map(real).collect::<Vec<_>>(), &real(&v));
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(distance(&found[0]) < 0.015, "{:?}", found[0].centre);
}
