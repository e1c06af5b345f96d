//! A calibration learned from robot presses on an imperfect virtual skin (10 % larger than its
//! spec, electrodes moved up to 3 mm, gains ±20 %, the first drive dead, drift, magnitudes
//! only, 0.3 % noise per frame, each state the mean of 32 frames): the dead channels are found
//! from the data, and the Gaussian process on the channels' shape places presses at least 25 %
//! closer than 5-nearest neighbours, from the same 200 presses; on the fitted press (the spec's
//! sensor as specified) 100 presses place presses within 5 mm and forces within 5 % of the
//! largest.

use eitskin::learn::{choose, evaluate, train, Method, NominalSensor, PredictScratch};
use eitskin::sim::imperfect::{ImperfectSkin, Imperfections};
use eitskin::SensorSpec;

/// The paper's sensor on a 2,000-triangle mesh, and its skin as built drawn from `seed`, each
/// state the mean of 32 frames.
fn skin(seed: u64) -> (SensorSpec, ImperfectSkin) {
    let mut spec = SensorSpec::square_hydrogel();
    spec.mesh.triangles = 2000;
    let imperfections = Imperfections { frames_per_press: 32, ..Imperfections::default() };
    let skin = ImperfectSkin::new(&spec, &imperfections, seed).unwrap();
    (spec, skin)
}

#[test]
fn a_learned_process_beats_nearest_neighbours_on_an_imperfect_skin() {
    let (spec, mut skin) = skin(11);
    let training = skin.robot_presses(200, 0.08, 2.0..16.0).unwrap();
    let held_out = skin.robot_presses(200, 0.08, 2.0..16.0).unwrap();

    let knn = evaluate(&train(&training, Method::knn(5), None).unwrap(), &held_out);
    let gp = train(&training, Method::from_name("gp-shape").unwrap(), None).unwrap();
    let learned = evaluate(&gp, &held_out);
    eprintln!(
        "200 presses: knn-5 {:.1} mm, gp-shape {:.1} mm, force RMS {:.2} N",
        knn.mean_position * 1e3,
        learned.mean_position * 1e3,
        learned.force_rms.unwrap()
    );
    assert!(learned.mean_position <= 0.75 * knn.mean_position, "{learned:?} vs {knn:?}");

    // The first drive's channels (the two-terminal pair 1–2 alone) read 0: found dead.
    let protocol = spec.protocol().unwrap();
    let first_drive: Vec<usize> =
        (0..protocol.len()).filter(|&m| protocol.measurements()[m].stimulation == 0).collect();
    assert_eq!(gp.dead_channels(), first_drive);
    // Each answer carries an uncertainty, and the frame of another length is the caller's to refuse.
    let answer = gp.predict(&held_out[0].inputs, &mut PredictScratch::default()).unwrap();
    assert!(answer.position_std.is_some_and(|s| s > 0.0) && answer.force.is_some());
    assert_eq!(gp.channels(), 120);

    // Cross-validation on the training presses alone picks a learned method over the floor.
    let (best, scores) = choose(&training, &Method::candidates(false), 5, None, &mut |_, _, _| {}).unwrap();
    assert_eq!(scores.len(), Method::candidates(false).len());
    assert!(
        !matches!(best.regressor, eitskin::learn::RegressorKind::Knn { k: 5 })
            || best.features != eitskin::learn::Features::Raw
    );
}

#[test]
fn press_features_learn_an_imperfect_skin_from_100_presses() {
    let (spec, mut skin) = skin(12);
    let training = skin.robot_presses(100, 0.08, 2.0..16.0).unwrap();
    let held_out = skin.robot_presses(200, 0.08, 2.0..16.0).unwrap();
    let sensor = NominalSensor::of_spec(&spec, None).unwrap();

    let knn = evaluate(&train(&training, Method::knn(5), None).unwrap(), &held_out);
    let model = train(&training, Method::from_name("gp-press").unwrap(), Some(&sensor)).unwrap();
    let learned = evaluate(&model, &held_out);
    eprintln!(
        "100 presses: knn-5 {:.1} mm, gp-press {:.1} mm, force RMS {:.2} N ({:.1} % of 16 N)",
        knn.mean_position * 1e3,
        learned.mean_position * 1e3,
        learned.force_rms.unwrap(),
        100.0 * learned.force_rms.unwrap() / 16.0
    );
    assert_eq!(learned.unanswered, 0);
    let protocol = spec.protocol().unwrap();
    let first_drive: Vec<usize> =
        (0..protocol.len()).filter(|&m| protocol.measurements()[m].stimulation == 0).collect();
    assert_eq!(model.dead_channels(), first_drive);
    assert!(learned.mean_position <= 0.005, "{learned:?}");
    assert!(learned.force_rms.unwrap() <= 0.05 * 16.0, "{learned:?}");
    assert!(learned.mean_position <= 0.75 * knn.mean_position, "{learned:?} vs {knn:?}");
    // Without the sensor, press features are refused.
    let refused = train(&training, Method::from_name("gp-press").unwrap(), None).unwrap_err();
    assert_eq!(refused, eitskin::learn::LearnError::NoSensor);

    // A press that failed (its Δv all zero) is left out of press features, named, and the rest
    // still teach as well; the channels' methods keep it.
    let mut weak = training.clone();
    weak[17].inputs.fill(0.0);
    let kept = train(&weak, Method::from_name("gp-press").unwrap(), Some(&sensor)).unwrap();
    assert_eq!(kept.left_out, vec![17]);
    assert!(evaluate(&kept, &held_out).mean_position <= 1.1 * learned.mean_position);
    assert!(train(&weak, Method::knn(5), None).unwrap().left_out.is_empty());
    let mut dead = training[..4].to_vec();
    dead.iter_mut().skip(1).for_each(|p| p.inputs.fill(0.0));
    let refused = train(&dead, Method::from_name("gp-press").unwrap(), Some(&sensor)).unwrap_err();
    assert_eq!(refused, eitskin::learn::LearnError::FewLikePresses { like: 1, given: 4 });
}

/// A robot that sets depth, not force: presses labelled with the indenter's depth only (here a
/// Hertz-like 0.4 mm·(F/16 N)^(2/3)) teach depth, with an uncertainty, and no force.
#[test]
fn depths_are_learned_when_the_presses_have_them() {
    let (spec, mut skin) = skin(13);
    let by_depth = |presses: Vec<eitskin::learn::LabelledPress>| -> Vec<eitskin::learn::LabelledPress> {
        presses
            .into_iter()
            .map(|p| {
                let depth = p.force.map(|f| 4e-4 * (f / 16.0).powf(2.0 / 3.0));
                eitskin::learn::LabelledPress { force: None, depth, ..p }
            })
            .collect()
    };
    let training = by_depth(skin.robot_presses(100, 0.08, 2.0..16.0).unwrap());
    let held_out = by_depth(skin.robot_presses(100, 0.08, 2.0..16.0).unwrap());
    let sensor = NominalSensor::of_spec(&spec, None).unwrap();
    let model = train(&training, Method::from_name("gp-press").unwrap(), Some(&sensor)).unwrap();
    let errors = evaluate(&model, &held_out);
    eprintln!("depth RMS {:.1} µm of 400 µm", errors.depth_rms.unwrap() * 1e6);
    assert!(errors.force_rms.is_none() && errors.depth_rms.unwrap() < 0.1 * 4e-4, "{errors:?}");
    let answer = model.predict(&held_out[0].inputs, &mut PredictScratch::default()).unwrap();
    assert!(answer.force.is_none() && answer.depth_std.is_some_and(|s| s > 0.0), "{answer:?}");
    let mut mixed = training.clone();
    mixed[3].depth = None;
    let refused = train(&mixed, Method::knn(5), None).unwrap_err();
    assert_eq!(refused, eitskin::learn::LearnError::MixedDepths { press: 4 });
}

/// The physics alone (the fitted centre, and the force its drop gives on one curve) cannot
/// learn that the skin is larger than its spec; with a Gaussian process on what it gets wrong
/// it places presses as well as the process on the fitted press, and keeps the physics' forces
/// where presses are few.
#[test]
fn the_physics_and_its_learned_residual_each_mend_the_other() {
    let (spec, mut skin) = skin(14);
    let sensor = NominalSensor::of_spec(&spec, None).unwrap();
    let held_out = skin.robot_presses(200, 0.08, 2.0..16.0).unwrap();
    let training = skin.robot_presses(100, 0.08, 2.0..16.0).unwrap();
    let names = ["gp-press", "curve-press", "gp-curve-press"];
    let errors = |n: usize| {
        let errors = names.map(|name| {
            let model = train(&training[..n], Method::from_name(name).unwrap(), Some(&sensor)).unwrap();
            let errors = evaluate(&model, &held_out);
            (errors.mean_position, errors.force_rms.unwrap())
        });
        let line: Vec<String> =
            names.iter().zip(&errors).map(|(name, (p, f))| format!("{name} {:.1} mm {f:.2} N", p * 1e3)).collect();
        eprintln!("{n} presses: {}", line.join(", "));
        errors
    };
    // Few presses: the physics reads forces better than a process on the fitted press, and the
    // residual keeps most of that.
    let [gp, physics, both] = errors(25);
    assert!(physics.1 <= gp.1 && both.1 <= gp.1, "25 presses: {physics:?} {both:?} {gp:?}");
    // More: the residual has learned the outline's size the physics cannot know.
    let [gp, physics, both] = errors(100);
    assert!(both.0 <= 0.7 * physics.0 && both.0 <= 1.1 * gp.0, "100 presses: {both:?} {physics:?} {gp:?}");
    assert!(both.1 <= gp.1, "100 presses: {both:?} {gp:?}");
    // The physics' force comes with its curve's spread, the residual's with the process's.
    let model = train(&training, Method::from_name("curve-press").unwrap(), Some(&sensor)).unwrap();
    let answer = model.predict(&held_out[0].inputs, &mut PredictScratch::default()).unwrap();
    assert!(answer.position_std.is_none() && answer.force_std.is_some_and(|s| s > 0.0), "{answer:?}");
}
