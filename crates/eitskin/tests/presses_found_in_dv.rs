//! Presses found in Δv itself by the press model, tested against the measured noise: none on an
//! untouched sheet beyond the stated rate, a weak press beside a strong one, three at once.

use eitskin::chain::Chain;
use eitskin::forward::ForwardModel;
use eitskin::pipeline::{Pipeline, PipelineParams, Status};
use eitskin::press_fit::{
    exact_model_for, Disk, PressDetection, PressFit, PressModel, PressModelParams, PressScratch, TableUse,
};
use eitskin::sim::{Hydrogel, Profile, SimParams, VirtualSensor};
use eitskin::{Reconstructor, ReconstructorParams, SensorSpec, TouchParams};

/// The paper's sensor with a press model on a coarse mesh, its virtual skin at 0.05 % noise per
/// value, and a pipeline (1 false touch per 1,000 frames) after its 10 reference frames; the
/// skin's untouched clean frame.
fn setup() -> (Pipeline, VirtualSensor, Vec<f64>) {
    setup_in(|frame| frame.to_vec())
}

/// [`setup`], with every frame the pipeline sees passed through `board` (a board's unit, gains).
fn setup_in(board: impl Fn(&[f64]) -> Vec<f64>) -> (Pipeline, VirtualSensor, Vec<f64>) {
    setup_with(1500, board, |model| model)
}

/// [`setup_in`] on a mesh of about `triangles`, with the press model passed through
/// `press_model` first.
fn setup_with(
    triangles: usize,
    board: impl Fn(&[f64]) -> Vec<f64>,
    press_model: impl Fn(PressModel) -> PressModel,
) -> (Pipeline, VirtualSensor, Vec<f64>) {
    let mut spec = SensorSpec::square_hydrogel();
    spec.mesh.triangles = triangles;
    let model = spec.forward_model().unwrap();
    let recon = Reconstructor::new(&model, 1.0, &ReconstructorParams::default()).unwrap();
    let press_model = press_model(PressModel::new(&model, 1.0, &PressModelParams::default()).unwrap());
    let chain = Chain::new(recon, TouchParams::default()).with_press_model(press_model);
    let params = PipelineParams { auto_hyperparameter: true, ..PipelineParams::default() };
    let mut pipeline = Pipeline::new(chain, params);
    let sim = SimParams { noise_relative: 5e-4, ..SimParams::default() };
    let mut skin = VirtualSensor::with_params(&spec, sim, 17).unwrap();
    let clean = skin.clean_frame().unwrap();
    for _ in 0..10 {
        pipeline.process(&board(&skin.noisy(&clean))).unwrap();
    }
    assert!(pipeline.chain().press_detection().is_some());
    (pipeline, skin, clean)
}

fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// The presses of `presses` (position m, force N) each matched to the nearest touch found,
/// frame after frame: per press, the worst distance over `frames` frames, in m; and whether
/// every frame had exactly as many touches as presses.
fn worst_distances(
    pipeline: &mut Pipeline,
    skin: &mut VirtualSensor,
    presses: &[([f64; 2], f64)],
    frames: usize,
) -> (Vec<f64>, bool) {
    skin.release();
    presses.iter().for_each(|(at, force)| skin.press(*at, *force));
    let clean = skin.clean_frame().unwrap();
    let (mut worst, mut counted) = (vec![0.0_f64; presses.len()], true);
    for _ in 0..frames {
        assert!(pipeline.process(&skin.noisy(&clean)).unwrap().imaged());
        let touches = pipeline.touches();
        counted &= touches.len() == presses.len();
        for (w, (at, _)) in worst.iter_mut().zip(presses) {
            let nearest = touches.iter().map(|t| distance(t.touch.centre, *at)).fold(f64::INFINITY, f64::min);
            *w = w.max(nearest);
        }
    }
    (worst, counted)
}

#[test]
fn an_untouched_sheet_shows_no_press_beyond_the_rate() {
    let (mut pipeline, mut skin, clean) = setup();
    let (frames, mut false_frames) = (2000, 0);
    for _ in 0..frames {
        let status = pipeline.process(&skin.noisy(&clean)).unwrap();
        assert!(matches!(status, Status::Processed | Status::NoiseUpdated));
        false_frames += usize::from(!pipeline.touches().is_empty());
    }
    // 2 expected at 1e-3 per frame.
    assert!(false_frames <= 6, "{false_frames} of {frames} untouched frames showed a press");
}

#[test]
fn weak_strong_and_several_presses_are_each_found() {
    let (mut pipeline, mut skin, _) = setup();
    // One press of 2 N (a 27 % drop) anywhere: at the edge within a few mm, in the middle
    // (the least sensitive place) within 20 mm.
    for at in [[0.085, 0.0], [-0.03, -0.08], [0.05, 0.05], [0.0, 0.0]] {
        let (worst, counted) = worst_distances(&mut pipeline, &mut skin, &[(at, 2.0)], 4);
        let bound = if at[0].hypot(at[1]) < 0.04 { 0.02 } else { 0.006 };
        assert!(counted && worst[0] < bound, "2 N at {at:?}: {worst:?}, one touch each frame: {counted}");
    }
    // 15 N near a corner and 3 N near the middle, which the image's 60 % of the frame's peak
    // (and its side lobes of the strong press) hide.
    let (worst, counted) =
        worst_distances(&mut pipeline, &mut skin, &[([-0.075, -0.07], 15.0), ([0.01, 0.02], 3.0)], 4);
    assert!(counted && worst[0] < 0.003 && worst[1] < 0.02, "{worst:?}, {counted}");
    // Three at once, 10, 5 and 3 N: each found.
    let three = [([-0.03, 0.04], 10.0), ([0.04, -0.02], 5.0), ([0.06, 0.07], 3.0)];
    let (worst, counted) = worst_distances(&mut pipeline, &mut skin, &three, 4);
    assert!(counted && worst.iter().all(|w| *w < 0.025), "{worst:?}, {counted}");
}

/// A board in its own counts with gains of ±20 % per channel finds the same presses, with the
/// same drops: the press fit takes each channel's relative change, in the model's volts.
#[test]
fn a_boards_unit_and_gains_change_nothing() {
    let gains: Vec<f64> = (0..120).map(|m| 250.0 * (1.0 + 0.2 * ((m * 37 % 11) as f64 / 5.0 - 1.0))).collect();
    let in_counts = |frame: &[f64]| -> Vec<f64> { frame.iter().zip(&gains).map(|(v, g)| v * g).collect() };
    let (mut volts, mut skin, _) = setup();
    let (mut counts, _, _) = setup_in(in_counts);
    skin.press([-0.075, -0.07], 15.0);
    skin.press([0.01, 0.02], 3.0);
    let pressed = skin.clean_frame().unwrap();
    for _ in 0..3 {
        let frame = skin.noisy(&pressed);
        volts.process(&frame).unwrap();
        counts.process(&in_counts(&frame)).unwrap();
        let drops = |p: &Pipeline| p.touches().iter().filter_map(|t| t.press.map(|f| f.drop)).collect::<Vec<_>>();
        let (a, b) = (drops(&volts), drops(&counts));
        assert!(a.len() == 2 && b.len() == 2, "volts {a:?}, counts {b:?}");
        assert!(a.iter().zip(&b).all(|(a, b)| (a - b).abs() < 0.05), "volts {a:?}, counts {b:?}");
    }
}

/// Three presses at once of the gel the model assumes, on the study's mesh: fitted together
/// with their exact responses, each one's drop over 6 frames is the gel's own within 0.02 (0.2 N
/// at 2.5 N, 1.3 N at 12 N); with the linear responses alone (a model read from its table), the
/// strong presses' shapes, which the linearisation misses, bias the others by far more (here
/// 0.006 and 0.071).
#[test]
fn several_presses_keep_their_own_drops() {
    let presses = [([-0.06, -0.05], 12.0), ([0.05, -0.04], 6.0), ([0.0, 0.05], 2.5)];
    let frames = 6;
    // The largest error of a press's mean drop; every press found in every frame.
    let worst_error = |pipeline: &mut Pipeline, skin: &mut VirtualSensor| {
        skin.release();
        presses.iter().for_each(|(at, force)| skin.press(*at, *force));
        let clean = skin.clean_frame().unwrap();
        let mut sums = [0.0; 3];
        for _ in 0..frames {
            pipeline.process(&skin.noisy(&clean)).unwrap();
            for (sum, (at, _)) in sums.iter_mut().zip(presses) {
                let found = pipeline.touches().iter().filter_map(|t| t.press).find(|p| distance(p.centre, at) < 0.01);
                *sum += found.map_or(f64::NAN, |p| p.drop);
            }
        }
        let truth = presses.map(|(_, force)| Hydrogel::default().drop(force));
        sums.iter().zip(truth).map(|(sum, truth)| (sum / frames as f64 - truth).abs()).fold(0.0, f64::max)
    };
    let (mut exact, mut skin, _) = setup_with(4000, |frame| frame.to_vec(), |m| m);
    assert!(exact.chain().press_model().is_some_and(|m| m.exact().is_some()));
    let exact_error = worst_error(&mut exact, &mut skin);
    let (mut linear, mut skin, _) =
        setup_with(4000, |frame| frame.to_vec(), |m| PressModel::from_table(m.table()).unwrap());
    let linear_error = worst_error(&mut linear, &mut skin);
    assert!(
        exact_error < 0.02 && linear_error > 3.0 * exact_error,
        "mean drop off by: exact {exact_error}, linear {linear_error}"
    );
}

/// A 15 mm indenter on a model of 10 mm: a strong press is one press, wider than the indenter
/// (the linear search may split it in two; the exact fit merges and sizes it). At 0.05 % noise
/// its size is only roughly known: the misfit changes little along its polarisation
/// r²·d/(2−d), so the radius found is 12–21 mm; the drop of a 10 mm press of the same
/// polarisation is known better than its drop. A 10 mm press keeps
/// the indenter's radius (its misfit does not ask for another) and the gel's drop.
#[test]
fn a_wider_press_is_one_press_of_its_own_size() {
    let mut spec = SensorSpec::square_hydrogel();
    spec.mesh.triangles = 4000;
    let model = spec.forward_model().unwrap();
    let press_model = PressModel::new(&model, 1.0, &PressModelParams::default()).unwrap();
    for (radius, sized) in [(0.015, true), (0.010, false)] {
        let hydrogel = Hydrogel { indenter_radius: radius, ..Hydrogel::default() };
        let sim = SimParams { hydrogel, noise_relative: 5e-4, ..SimParams::default() };
        let mut skin = VirtualSensor::with_params(&spec, sim, 3).unwrap();
        for found in presses_found(&model, &press_model, &mut skin, &[([0.03, -0.02], 10.0)], 3) {
            assert_eq!(found.len(), 1, "{radius} m: {found:?}");
            let press = found[0];
            assert!(distance(press.centre, [0.03, -0.02]) < 0.002, "{radius} m: {press:?}");
            if sized {
                // The polarisation varies less along the misfit's valley than either: as a
                // 10 mm press of the same polarisation (the drop alone 26–35 % off).
                let truth = Disk { centre: [0.03, -0.02], radius, drop: hydrogel.drop(10.0) };
                let equivalent = truth.equivalent_drop(0.01).0;
                let off = press.equivalent_drop(0.01) / equivalent - 1.0;
                assert!(press.radius > 0.012 && off.abs() < 0.25, "{radius} m: {press:?}, {off}");
            } else {
                assert!(press.radius == radius && (press.drop - hydrogel.drop(10.0)).abs() < 0.03, "{press:?}");
            }
        }
    }
}

/// At 90 dB (0.003 % per value) the model's mesh, against the sheet's finer one, leaves more
/// misfit than the noise: presses of the model's own 10 mm indenter at these places (where the
/// study found them sized) were fitted 8.8–9.7 mm wide, their forces 2–3 N off, when the
/// size's test read that misfit as noise. It now asks for a fall of the misfit in proportion
/// to the fit's misfit per degree of freedom.
#[test]
fn the_meshs_own_error_is_not_a_wider_or_narrower_press() {
    let spec = SensorSpec::square_hydrogel();
    let model = spec.forward_model().unwrap();
    let press_model = PressModel::new(&model, 1.0, &PressModelParams::default()).unwrap();
    let noise = 10f64.powf(-90.0 / 20.0);
    let sim = SimParams { noise_relative: noise, ..SimParams::default() };
    let mut skin = VirtualSensor::with_params(&spec, sim, 5).unwrap();
    let places = [
        ([0.017, 0.051], 11.75),
        ([0.041, -0.035], 14.25),
        ([0.007, 0.052], 12.9),
        ([-0.069, 0.012], 13.06),
        ([-0.075, -0.078], 12.86),
        ([-0.064, -0.016], 13.06),
        ([-0.021, 0.079], 11.04),
        ([-0.078, -0.014], 8.31),
    ];
    let mut sized = Vec::new();
    for press in places {
        for found in presses_found_at(noise, &model, &press_model, &mut skin, &[press], 2) {
            assert_eq!(found.len(), 1, "{press:?}: {found:?}");
            assert!(distance(found[0].centre, press.0) < 0.002, "{press:?}: {found:?}");
            if found[0].radius != 0.01 {
                sized.push((press.0, found[0].radius));
            }
        }
    }
    // 11 of these 16 fits were sized when the test read the mesh's error as noise; 4 still are.
    assert!(sized.len() <= 5, "{} of 16 sized: {sized:?}", sized.len());
}

/// Two presses of a 15 mm indenter, one at the deepest drop a 10 mm press can take: the linear
/// search splits them, and the weak part left of one beside it (35 mm off) took up what the
/// size's score test reads, so it was kept as a third press. A weaker press near a stronger
/// one is now tested for merging whatever that score says: each is one press again.
#[test]
fn wide_presses_leave_no_press_beside_them() {
    let spec = SensorSpec::square_hydrogel();
    let model = spec.forward_model().unwrap();
    let press_model = PressModel::new(&model, 1.0, &PressModelParams::default()).unwrap();
    let hydrogel = Hydrogel { indenter_radius: 0.015, ..Hydrogel::default() };
    let sim = SimParams { hydrogel, noise_relative: 5e-4, ..SimParams::default() };
    let mut skin = VirtualSensor::with_params(&spec, sim, 3).unwrap();
    let presses = [([0.041, -0.025], 12.3), ([-0.060, 0.014], 6.9)];
    for found in presses_found(&model, &press_model, &mut skin, &presses, 6) {
        assert_eq!(found.len(), 2, "{found:?}");
        assert!(presses.iter().all(|(at, _)| found.iter().any(|p| distance(p.centre, *at) < 0.005)), "{found:?}");
    }
}

/// Two 5 N presses of a smooth (Hertz-like) profile, one in the weakly sensitive middle: where
/// the linear search takes them for one press between them, the exact fit's test for a new
/// press (with that press free to move back) finds the second. It failed in 4 of 10 frames
/// when the new press's drop was read off the misfit alone (what the first press had not
/// taken of it).
#[test]
fn a_press_another_has_half_taken_is_found_again() {
    let spec = SensorSpec::square_hydrogel();
    let model = spec.forward_model().unwrap();
    let press_model = PressModel::new(&model, 1.0, &PressModelParams::default()).unwrap();
    let hydrogel = Hydrogel { profile: Profile::Hertz { reference_force: 8.0 }, ..Hydrogel::default() };
    let sim = SimParams { hydrogel, noise_relative: 5e-4, ..SimParams::default() };
    let mut skin = VirtualSensor::with_params(&spec, sim, 9).unwrap();
    let presses = [([0.012, 0.0], 5.0), ([0.031, 0.062], 5.0)];
    for found in presses_found(&model, &press_model, &mut skin, &presses, 10) {
        // The middle is the least sensitive place: there a weak press is placed within 30 mm.
        assert_eq!(found.len(), 2, "{found:?}");
        for ((at, _), within) in presses.iter().zip([0.03, 0.01]) {
            assert!(found.iter().any(|p| distance(p.centre, *at) < within), "{at:?}: {found:?}");
        }
    }
}

/// Three strong presses (11–15 N) fitted together: no fourth press between them. Strong presses
/// change each other's field, which looks like a press between them in Δv less the sum of
/// their own responses; a new press is looked for in the joint fit's misfit instead, and kept
/// only if the presses with it explain Δv better by the likelihood ratio.
#[test]
fn strong_presses_show_no_press_between_them() {
    let spec = SensorSpec::square_hydrogel();
    let model = spec.forward_model().unwrap();
    let press_model = PressModel::new(&model, 1.0, &PressModelParams::default()).unwrap();
    let sim = SimParams { noise_relative: 5e-4, ..SimParams::default() };
    let mut skin = VirtualSensor::with_params(&spec, sim, 9).unwrap();
    let presses = [([-0.075, 0.032], 13.7), ([-0.040, -0.014], 11.6), ([-0.044, -0.071], 15.0)];
    for found in presses_found(&model, &press_model, &mut skin, &presses, 6) {
        assert_eq!(found.len(), 3, "{found:?}");
        assert!(presses.iter().all(|(at, _)| found.iter().any(|p| distance(p.centre, *at) < 0.01)), "{found:?}");
    }
}

/// The presses `press_model` (made on `model`) finds in each of `frames` noisy frames of `skin`
/// pressed by `presses` (position m, force N), against its untouched clean frame, with the
/// noise of 0.05 % per value known exactly; Δv in the model's volts, as the chain gives it.
fn presses_found(
    model: &ForwardModel,
    press_model: &PressModel,
    skin: &mut VirtualSensor,
    presses: &[([f64; 2], f64)],
    frames: usize,
) -> Vec<Vec<PressFit>> {
    presses_found_at(5e-4, model, press_model, skin, presses, frames)
}

/// [`presses_found`] with the skin's noise, relative per value, known to be `noise`.
fn presses_found_at(
    noise: f64,
    model: &ForwardModel,
    press_model: &PressModel,
    skin: &mut VirtualSensor,
    presses: &[([f64; 2], f64)],
    frames: usize,
) -> Vec<Vec<PressFit>> {
    let v0 = model.measure(&vec![1.0; model.mesh().triangles().len()]).unwrap();
    let std: Vec<f64> = v0.iter().map(|v| noise * v.abs()).collect();
    let detection = PressDetection::new(press_model, &std, f64::INFINITY, 1e-3).unwrap();
    skin.release();
    let reference = skin.clean_frame().unwrap();
    presses.iter().for_each(|(at, force)| skin.press(*at, *force));
    let pressed = skin.clean_frame().unwrap();
    let (mut whitened, mut scratch, mut found) = (Vec::new(), PressScratch::default(), Vec::new());
    (0..frames)
        .map(|_| {
            let frame = skin.noisy(&pressed);
            let dv: Vec<f64> = frame.iter().zip(&reference).zip(&v0).map(|((v, r), v0)| (v - r) * v0 / r).collect();
            detection.detect_into(&dv, &mut whitened, &mut scratch, &mut found).unwrap();
            found.clone()
        })
        .collect()
}

/// The default use of the table ([`TableUse::Auto`]) on the same noisy frames as the other two:
/// three presses of the indenter's kind far apart are fitted on the table, to the bit as
/// [`TableUse::Fit`] fits them; two presses closer than five radii are fitted exactly from the
/// first fit, to the bit as [`TableUse::Start`] fits them; a press wider than the indenter is
/// decided by the exact fit, one press of its own size as [`TableUse::Start`] finds it.
#[test]
fn the_default_fits_on_the_table_only_while_it_holds() {
    let mut spec = SensorSpec::square_hydrogel();
    spec.mesh.triangles = 1500;
    let model = spec.forward_model().unwrap();
    let linear = PressModel::new(&model, 1.0, &PressModelParams::default()).unwrap();
    let auto = linear.with_table_use(TableUse::DEFAULT).unwrap();
    assert_eq!(auto.table_use(), Some(TableUse::Auto));
    let [fit, start] = [TableUse::Fit, TableUse::Start].map(|u| auto.clone().with_table_use(Some(u)).unwrap());
    let found = |press_model: &PressModel, hydrogel: Hydrogel, presses: &[([f64; 2], f64)]| {
        let sim = SimParams { hydrogel, noise_relative: 5e-4, ..SimParams::default() };
        let mut skin = VirtualSensor::with_params(&spec, sim, 5).unwrap();
        presses_found(&model, press_model, &mut skin, presses, 4)
    };
    let far = [([-0.03, 0.04], 10.0), ([0.04, -0.02], 5.0), ([0.06, 0.07], 3.0)];
    let on_table = found(&auto, Hydrogel::default(), &far);
    assert!(on_table.iter().all(|f| f.len() == 3), "{on_table:?}");
    assert_eq!(on_table, found(&fit, Hydrogel::default(), &far));
    // Found nearer than five radii by the linear search: exact from the first fit.
    let near = [([-0.065, 0.045], 12.0), ([-0.065, 0.01], 12.0)];
    let exact = found(&auto, Hydrogel::default(), &near);
    assert!(exact.iter().all(|f| f.len() == 2), "{exact:?}");
    assert_eq!(exact, found(&start, Hydrogel::default(), &near));
    // Two presses 40 mm apart, wherever the linear search places them (farther, the fit on the
    // table that brings them nearer hands them to the exact fit). Presses this near have more
    // than one exact optimum within the noise, so it may end at another than the exact fit from
    // the linear search's places: on average as near where they are and the gel's drop, within
    // a fifth (measured: 1.9 mm and 0.054 of a drop, exact 1.9 mm, 0.047).
    let nearer = [([-0.06, 0.05], 10.0), ([-0.06, 0.01], 10.0)];
    let errors = |found: Vec<Vec<PressFit>>| {
        let (mut off, mut drop_off) = (0.0, 0.0);
        for found in &found {
            assert_eq!(found.len(), 2, "{found:?}");
            for (at, force) in nearer {
                let nearest = found.iter().min_by(|a, b| distance(a.centre, at).total_cmp(&distance(b.centre, at)));
                let press = nearest.unwrap_or_else(|| panic!("{at:?}: none in {found:?}"));
                off += distance(press.centre, at);
                drop_off += (press.drop - Hydrogel::default().drop(force)).abs();
            }
        }
        let count = (found.len() * nearer.len()) as f64;
        (off / count, drop_off / count)
    };
    let read = errors(found(&auto, Hydrogel::default(), &nearer));
    let solved = errors(found(&start, Hydrogel::default(), &nearer));
    assert!(read.0 < 1.2 * solved.0 + 5e-4 && read.1 < 1.2 * solved.1 + 0.01, "auto {read:?}, start {solved:?}");
    let wide = Hydrogel { indenter_radius: 0.015, ..Hydrogel::default() };
    let one = [([0.03, -0.02], 10.0)];
    for (auto, start) in found(&auto, wide, &one).iter().zip(found(&start, wide, &one)) {
        assert!(auto.len() == 1 && start.len() == 1, "{auto:?} {start:?}");
        let (a, s) = (auto[0], start[0]);
        assert!(a.radius > 0.012 && (a.radius - s.radius).abs() < 5e-4, "{a:?} {s:?}");
        assert!(distance(a.centre, s.centre) < 5e-4 && (a.drop - s.drop).abs() < 0.02, "{a:?} {s:?}");
    }
}

/// A model too fine to keep its inverse whole takes its exact responses from the sensor meshed
/// at `EXACT_TRIANGLES`, scaled to its own values: two presses (12 and 4 N, 0.05 % noise) are
/// found within 5 mm of where they are (the weaker, nearer the middle, 3.6 mm off in one frame)
/// with the gel's drops.
#[test]
fn a_fine_model_fits_presses_with_a_coarser_meshs_exact_responses() {
    let mut spec = SensorSpec::square_hydrogel();
    spec.mesh.triangles = 12_000;
    let model = spec.forward_model().unwrap();
    let exact = exact_model_for(&spec, &model).unwrap().expect("12,000 triangles are too many to keep the inverse");
    assert!(exact.mesh().triangles().len() < 6000);
    let press_model = PressModel::with_exact_model(&model, &exact, 1.0, &PressModelParams::default()).unwrap();
    let sim = SimParams { noise_relative: 5e-4, refine: 1, ..SimParams::default() };
    let mut skin = VirtualSensor::with_params(&spec, sim, 5).unwrap();
    let presses = [([0.04, -0.05], 12.0), ([-0.03, 0.04], 4.0)];
    for found in presses_found(&model, &press_model, &mut skin, &presses, 3) {
        assert_eq!(found.len(), 2, "{found:?}");
        for (at, force) in presses {
            let press =
                found.iter().find(|p| distance(p.centre, at) < 0.005).unwrap_or_else(|| panic!("{at:?}: {found:?}"));
            assert!((press.drop - Hydrogel::default().drop(force)).abs() < 0.03, "{at:?}: {press:?}");
        }
    }
}

/// Three presses found afresh with each one's response read from the table of its exact
/// response ([`PressModel::with_tabulated`]: no exact solve for presses apart, instead of
/// several per iteration) are found as well as with the exact fits, frame by frame on the same noisy frames
/// of a skin simulated on a finer mesh: every press in every frame, on average as near where it
/// is and as near the gel's drop, within a fifth (measured: 2.23 mm and 0.028 in drop on the
/// table, 2.25 mm and 0.027 exact). Frame by frame the two differ: the table leaves out the
/// presses' fields on each other, its derivatives are the smooth interpolant's, the exact
/// ones turn as the disk's edge crosses the coarse mesh's nodes, and with the misfit a finer
/// mesh leaves the two optima apart.
#[test]
fn presses_fitted_on_the_table_are_found_as_well_as_with_the_exact_fit() {
    let mut spec = SensorSpec::square_hydrogel();
    spec.mesh.triangles = 1500;
    let model = spec.forward_model().unwrap();
    let exact = PressModel::new(&model, 1.0, &PressModelParams::default()).unwrap();
    let tabulated = exact.clone().with_tabulated().unwrap();
    assert!(exact.tabulated().is_none() && tabulated.tabulated().is_some());
    let presses = [([-0.03, 0.04], 10.0), ([0.04, -0.02], 5.0), ([0.06, 0.07], 3.0)];
    let sim = SimParams { noise_relative: 5e-4, ..SimParams::default() };
    // Mean distance from where the presses are (m) and mean error of the drop.
    let errors = |press_model: &PressModel| {
        let mut skin = VirtualSensor::with_params(&spec, sim, 11).unwrap();
        let (mut off, mut drop_off, mut count) = (0.0, 0.0, 0.0);
        for found in presses_found(&model, press_model, &mut skin, &presses, 12) {
            assert_eq!(found.len(), presses.len(), "{found:?}");
            for (at, force) in presses {
                let nearest = found.iter().min_by(|a, b| distance(a.centre, at).total_cmp(&distance(b.centre, at)));
                let press = nearest.unwrap_or_else(|| panic!("{at:?}: none in {found:?}"));
                off += distance(press.centre, at);
                drop_off += (press.drop - Hydrogel::default().drop(force)).abs();
                count += 1.0;
            }
        }
        (off / count, drop_off / count)
    };
    let (solved, read) = (errors(&exact), errors(&tabulated));
    assert!(read.0 < 1.2 * solved.0 + 2e-4 && read.1 < 1.2 * solved.1 + 0.005, "exact {solved:?}, tabulated {read:?}");
}
