//! The frame path allocates nothing once warm: reference taken, buffers grown. Counted with a
//! global allocator that tallies every allocation while a flag is up.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use eitskin::calibration::{Calibration, Strength};
use eitskin::chain::Chain;
use eitskin::pipeline::{Pipeline, PipelineParams, Status};
use eitskin::press_fit::{PressModel, PressModelParams, TableUse};
use eitskin::pseudo_array::PseudoArray;
use eitskin::sim::{Hydrogel, VirtualSensor};
use eitskin::{Reconstructor, ReconstructorParams, SensorSpec, TouchParams};

struct Counting;

static COUNTING: AtomicBool = AtomicBool::new(false);
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

#[allow(unsafe_code, reason = "a global allocator can only be written with unsafe code")]
// SAFETY: every call is passed on to the system allocator unchanged.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.load(Ordering::Relaxed) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: the caller's contract is the system allocator's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: as above.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if COUNTING.load(Ordering::Relaxed) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: as above.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

#[test]
fn a_frame_with_touches_fitted_presses_forces_and_learned_answers_allocates_nothing() {
    let mut spec = SensorSpec::square_hydrogel();
    spec.mesh.triangles = 1200;
    let model = spec.forward_model().unwrap();
    let recon = Reconstructor::new(&model, 1.0, &ReconstructorParams::default()).unwrap();
    let press_model = PressModel::new(&model, 1.0, &PressModelParams::default()).unwrap();
    let array = PseudoArray::of_sensor(&spec, [1, 1]).unwrap();
    let gel = Hydrogel::default().drop_curve(16.0);
    let calibration = Calibration { curves: vec![gel], strength: Strength::FittedDrop };
    let chain = Chain::new(recon, TouchParams::default())
        .with_press_model(press_model)
        .with_calibration(array, calibration)
        .unwrap();
    let mut pipeline = Pipeline::new(chain, PipelineParams::default());
    let mut skin = VirtualSensor::new(&spec, 2).unwrap();
    let mut frames = Vec::new();
    for _ in 0..10 {
        frames.push(skin.frame().unwrap());
    }
    skin.press([-0.05, -0.04], 8.0);
    skin.press([0.05, 0.05], 10.0);
    for _ in 0..5 {
        frames.push(skin.frame().unwrap());
    }
    // Then pressed elsewhere: found afresh.
    skin.release();
    skin.press([0.04, -0.06], 6.0);
    skin.press([-0.06, 0.05], 12.0);
    let moved = skin.frame().unwrap();
    // And elsewhere again, like them (a stronger press and a weaker, apart).
    skin.release();
    skin.press([0.06, -0.03], 7.0);
    skin.press([-0.04, 0.06], 11.0);
    let elsewhere = skin.frame().unwrap();
    // The counter counts: a reference frame is copied into the pipeline.
    COUNTING.store(true, Ordering::Relaxed);
    pipeline.process(&frames[0]).unwrap();
    COUNTING.store(false, Ordering::Relaxed);
    assert!(ALLOCATIONS.swap(0, Ordering::Relaxed) > 0);
    for frame in &frames[1..11] {
        pipeline.process(frame).unwrap(); // the rest of the reference, then one warm-up frame
    }
    COUNTING.store(true, Ordering::Relaxed);
    let mut tracked = [None; 4];
    for (frame, how) in frames[11..].iter().zip(&mut tracked) {
        pipeline.process(frame).unwrap();
        *how = pipeline.chain().tracked();
    }
    COUNTING.store(false, Ordering::Relaxed);
    // Held still, the presses are carried from frame to frame (no fit at all).
    assert!(tracked.contains(&Some(eitskin::press_fit::Tracked::Carried)), "{tracked:?}");
    let touches = pipeline.touches();
    assert_eq!(touches.len(), 2, "{touches:?}");
    // Each force with its standard deviation (its posterior's, from the fit's spread).
    assert!(touches.iter().all(|t| t.press.is_some() && t.force.is_some_and(|f| f.std.is_some())), "{touches:?}");
    assert_eq!(ALLOCATIONS.load(Ordering::Relaxed), 0, "allocations in 4 frames");
    // Presses found afresh, fitted together exactly: nothing either.
    COUNTING.store(true, Ordering::Relaxed);
    pipeline.process(&moved).unwrap();
    COUNTING.store(false, Ordering::Relaxed);
    assert_eq!(pipeline.chain().tracked(), Some(eitskin::press_fit::Tracked::Found));
    assert_eq!(pipeline.touches().len(), 2, "{:?}", pipeline.touches());
    assert_eq!(ALLOCATIONS.load(Ordering::Relaxed), 0, "allocations in a frame of presses found afresh");
    // The same with the press model's tabulated response, fitted on it, starting exact fits
    // from it, and the two by turns (the default): a stream that carries its presses (the
    // default: whether it finds these afresh or fits them again from its model is the fit's to
    // decide), and one that finds them afresh in every frame.
    let linear = PressModel::new(&model, 1.0, &PressModelParams::default()).unwrap();
    let auto = linear.with_table_use(Some(TableUse::Auto)).unwrap();
    let tabulated = [TableUse::Fit, TableUse::Start, TableUse::Auto]
        .map(|table_use| auto.clone().with_table_use(Some(table_use)).unwrap());
    for (press_model, carry_presses) in tabulated.iter().flat_map(|m| [(m, true), (m, false)]) {
        let recon = Reconstructor::new(&model, 1.0, &ReconstructorParams::default()).unwrap();
        let chain = Chain::new(recon, TouchParams::default()).with_press_model(press_model.clone());
        let mut on_table = Pipeline::new(chain, PipelineParams { carry_presses, ..PipelineParams::default() });
        for frame in &frames[..12] {
            on_table.process(frame).unwrap(); // the reference, and the presses found once
        }
        // Its buffers grown by presses moved as these are, elsewhere (off the table, a carried
        // press of a fitted size is fitted exactly, which fits on the table alone never ask
        // for), then back where they were.
        on_table.process(&elsewhere).unwrap();
        on_table.process(&frames[12]).unwrap();
        ALLOCATIONS.store(0, Ordering::Relaxed);
        COUNTING.store(true, Ordering::Relaxed);
        on_table.process(&moved).unwrap();
        COUNTING.store(false, Ordering::Relaxed);
        let tracked = on_table.chain().tracked();
        let fitted = [eitskin::press_fit::Tracked::Found, eitskin::press_fit::Tracked::Refitted].map(Some);
        assert!(fitted.contains(&tracked), "{carry_presses}: {tracked:?}");
        assert!(carry_presses || tracked == Some(eitskin::press_fit::Tracked::Found));
        let table_use = press_model.table_use();
        assert_eq!(ALLOCATIONS.load(Ordering::Relaxed), 0, "allocations in a frame fitted afresh, table {table_use:?}");
    }
    // A channel going bad is an event (the reconstructor is derived again); after it, the frames
    // that still miss the channel cost nothing again.
    let mut lost = frames[11].clone();
    lost[7] = f64::NAN;
    assert_eq!(pipeline.process(&lost).unwrap(), Status::ChannelsDropped { count: 1 });
    pipeline.process(&lost).unwrap(); // warm-up: the press fit's buffers
    COUNTING.store(true, Ordering::Relaxed);
    for _ in 0..3 {
        assert_eq!(pipeline.process(&lost).unwrap(), Status::Processed);
    }
    COUNTING.store(false, Ordering::Relaxed);
    assert_eq!(pipeline.touches().len(), 2, "{:?}", pipeline.touches());
    assert_eq!(ALLOCATIONS.load(Ordering::Relaxed), 0, "allocations in 3 frames after a channel was dropped");

    // A learned model's answer (`run --model`), with its uncertainty: nothing once warm. In this
    // one test, since the count is global to the process.
    use eitskin::learn::{train, Method, NominalSensor, PredictScratch};
    use eitskin::sim::imperfect::{ImperfectSkin, Imperfections};
    let mut spec = SensorSpec::square_hydrogel();
    spec.mesh.triangles = 1500;
    let mut skin = ImperfectSkin::new(&spec, &Imperfections::default(), 5).unwrap();
    let presses = skin.robot_presses(60, 0.08, 2.0..16.0).unwrap();
    let sensor = NominalSensor::of_spec(&spec, None).unwrap();
    for name in ["gp-shape", "knn-5", "gp-press", "curve-press", "gp-curve-press"] {
        let model = train(&presses, Method::from_name(name).unwrap(), Some(&sensor)).unwrap();
        let mut scratch = PredictScratch::default();
        assert!(model.predict(&presses[0].inputs, &mut scratch).is_some());
        COUNTING.store(true, Ordering::Relaxed);
        for p in &presses[1..10] {
            model.predict(&p.inputs, &mut scratch);
        }
        COUNTING.store(false, Ordering::Relaxed);
        assert_eq!(ALLOCATIONS.load(Ordering::Relaxed), 0, "allocations in 9 answers of {name}");
    }
}
