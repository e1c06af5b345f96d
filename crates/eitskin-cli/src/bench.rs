//! `eitskin bench`: times each stage of the setup chain over repeated runs, prints medians.
//!
//! Stages: `mesh` (triangulation and refinement), `model` (sparsity pattern and symbolic
//! Cholesky, once per mesh), `assembly`, `factorisation` (numeric Cholesky), `solves` (all
//! L−1 current patterns), `measurements` (the protocol's values from the fields); then the
//! imaging chain: `jacobian`, `reconstructor` (prior, the measurement-sized solve and the
//! raster projection), `press_model` (its response table and, by low-rank updates, the ladder
//! of strong presses) and `press_detection` (its noise threshold, from 400 noise frames) and,
//! per frame (median over many frames), `frame_image`, `frame_touches`, `frame_press_fit` (one
//! press fitted from the touch) and `frame_three_presses` (three presses found in Δv against
//! 0.05 % noise, median of 201 runs on the noiseless frame), `frame_three_presses_noisy` (the
//! same on 201 frames of the presses held, each with its own 0.05 % noise) and
//! `frame_three_presses_carried` (those frames as a stream, the presses carried from frame to
//! frame) and `frame_three_presses_carried_80db` (the same stream at 0.01 % noise, the reference
//! of 100 frames); `simulated_frame` and `simulated_three_presses` (the virtual
//! sensor's frame on its finer truth mesh, one press and three apart); `learn_1000_presses` and
//! `learned_frame` (a Gaussian process on 1,000 robot presses of 192 channels, and its answer
//! for one frame), and the same on the fitted press (`learn_1000_presses_press`,
//! `learned_press_frame`); and `replay`: a file of 5,000 text frames through the lines decoder, the
//! pipeline and the JSON line, as fast as possible (frames/s, median latency per frame).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Result;
use eitskin::chain::Chain;
use eitskin::conductivity::{with_inclusions, Inclusion};
use eitskin::inverse::Channels;
use eitskin::memory::Stage;
use eitskin::pipeline::{Pipeline, PipelineParams};
use eitskin::press_fit::{exact_model_for, PressDetection, PressModel, PressModelParams, PressScratch, PressTrack};
use eitskin::sim::VirtualSensor;
use eitskin::touch::{detect_into, TouchScratch};
use eitskin::{Reconstructor, ReconstructorParams, TouchParams};
use eitskin_io::codec::{Decoder, Event, LinesDecoder};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

use crate::{load, ranges};

/// Flags of `eitskin bench`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Sensor spec file (TOML); default: the paper's sensor.
    spec: Option<PathBuf>,
    /// Mesh with about this many triangles instead of the spec's count, 1–100,000,000 (refused
    /// when the mesh and what is built on it would not fit in the memory available).
    #[arg(long, value_parser = ranges::triangles())]
    triangles: Option<usize>,
    /// Runs per stage, 1–10,000; the median is reported.
    #[arg(long, default_value_t = 15, value_parser = ranges::whole("a number of runs", 1, 10_000))]
    repeat: usize,
    /// Print one JSON object with a field per stage, in seconds.
    #[arg(long)]
    json: bool,
}

/// The median and the fastest of several timings, in s.
#[derive(Debug, Clone, Copy)]
struct Timing {
    median: f64,
    min: f64,
}

impl Timing {
    /// Of `times`, sorted here.
    fn of(times: &mut [f64]) -> Timing {
        times.sort_by(f64::total_cmp);
        Timing {
            median: times.get(times.len() / 2).copied().unwrap_or(f64::NAN),
            min: times.first().copied().unwrap_or(f64::NAN),
        }
    }
}

/// The timings of `runs` runs of `f`, in s, and its last result.
fn time<T>(runs: usize, mut f: impl FnMut() -> Result<T>) -> Result<(Timing, T)> {
    let mut times = Vec::with_capacity(runs);
    let mut last = None;
    for _ in 0..runs.max(1) {
        let start = Instant::now();
        let out = std::hint::black_box(f()?);
        times.push(start.elapsed().as_secs_f64());
        last = Some(out);
    }
    // `runs.max(1)` iterations ran, so `last` is set.
    Ok((Timing::of(&mut times), last.ok_or_else(|| anyhow::anyhow!("no run"))?))
}

/// Replays text lines as fast as possible through the lines decoder, the pipeline (reference of
/// 10 frames, image, touches) and the JSON line `eitskin run` prints: frames per second over the
/// whole replay, and the latency from a line's last byte to its JSON line, in s.
fn replay(recon: &Reconstructor, rest: &[f64], pressed: &[f64]) -> Result<(f64, Timing)> {
    let count = 5000;
    let line = |v: &[f64]| v.iter().map(|x| format!("{x:.6e}")).collect::<Vec<_>>().join(",") + "\n";
    let lines: Vec<String> = (0..count).map(|k| line(if k % 2 == 0 || k < 10 { rest } else { pressed })).collect();
    let mut pipeline = Pipeline::new(Chain::new(recon.clone(), TouchParams::default()), PipelineParams::default());
    let mut decoder = LinesDecoder::new(rest.len());
    let (mut events, mut sink) = (Vec::with_capacity(4), Vec::with_capacity(4096));
    let mut out = eitskin_io::stream::FrameLine::default();
    let mut latencies = Vec::with_capacity(count);
    let start = Instant::now();
    for text in &lines {
        let t0 = Instant::now();
        events.clear();
        decoder.feed(text.as_bytes(), &mut events);
        for event in events.drain(..) {
            if let Event::Frame(f) = event {
                let status = pipeline.process(&f.values)?;
                sink.clear();
                let counters = eitskin_io::stream::Counters { frames: f.seq, bad: 0, viewer_dropped: None };
                crate::run::fill_frame_line(&mut out, f.seq, 0.0, status, &pipeline, 1e-3, counters);
                eitskin_io::stream::write_line(&mut sink, &out)?;
            }
        }
        latencies.push(t0.elapsed().as_secs_f64());
    }
    let fps = count as f64 / start.elapsed().as_secs_f64();
    Ok((fps, Timing::of(&mut latencies)))
}

/// A learned model's training on 1,000 robot presses of 192 channels (the sheet with the
/// `opposite` protocol, OpenEIT's count) and one frame's answer (position, force, uncertainty).
fn learned(spec: &eitskin::SensorSpec) -> Result<(Timing, Timing, Timing, Timing)> {
    use eitskin::learn::{train, Method, NominalSensor, PredictScratch};
    use eitskin::sim::imperfect::{disc_radius, ImperfectSkin, Imperfections};
    let mut opposite = spec.clone();
    opposite.protocol = eitskin::ProtocolSpec::Opposite;
    let imperfections = Imperfections { frames_per_press: 32, ..Imperfections::default() };
    let mut skin = ImperfectSkin::new(&opposite, &imperfections, 1)?;
    let presses = skin.robot_presses(1000, disc_radius(&spec.outline, 0.8), 2.0..16.0)?;
    let method = Method::from_name("gp-shape").unwrap_or(Method::knn(5));
    let (t_train, model) = time(3, || Ok(train(&presses, method, None)?))?;
    let mut scratch = PredictScratch::default();
    let (t_frame, _) = time(2001, || Ok(model.predict(&presses[0].inputs, &mut scratch)))?;
    // On the fitted press: the press model is built once per sensor, outside the timing.
    let sensor = NominalSensor::of_spec(&opposite, None)?;
    let method = Method::from_name("gp-press").unwrap_or(Method::knn(5));
    let (t_train_press, model) = time(3, || Ok(train(&presses, method, Some(&sensor))?))?;
    let (t_frame_press, _) = time(2001, || Ok(model.predict(&presses[0].inputs, &mut scratch)))?;
    Ok((t_train, t_frame, t_train_press, t_frame_press))
}

/// Runs `eitskin bench`.
pub fn run(args: Args) -> Result<()> {
    let spec = load::sized(load::spec(args.spec.as_deref())?, args.triangles, Stage::Reconstructor)?;
    let n = args.repeat;
    let (t_mesh, mesh) = time(n, || Ok(spec.mesh()?))?;
    let (t_model, model) = time(n, || Ok(spec.forward_model_on(mesh.clone())?))?;
    let sigma = spec.homogeneous(model.mesh());
    let (t_assembly, matrix) = time(n, || Ok(model.assemble(&sigma)?))?;
    let (t_factor, factor) = time(n, || Ok(model.factorize(&matrix)?))?;
    let (t_solves, solution) = time(n, || Ok(model.solve_patterns(&factor)))?;
    let mut values = vec![0.0; model.protocol().len()];
    let (t_measure, ()) = time(n.max(101), || {
        solution.measurements_into(model.protocol(), &mut values);
        Ok(())
    })?;
    let (t_jacobian, _) = time(n, || Ok(model.jacobian(&solution)))?;
    let params = ReconstructorParams::default();
    let background = spec.conductivity;
    let (t_recon, recon) = time(n, || Ok(Reconstructor::new(&model, background, &params)?))?;
    // A channel gone bad: the reconstructor derived again without it, from the linearisation.
    let mut mask = vec![true; recon.measurements()];
    mask[0] = false;
    let channels = Channels::all(mask.len()).masked(&mask);
    let (t_drop, _) = time(n, || Ok(recon.derive(params.hyperparameter, channels.clone())?))?;
    let (t_auto, _) = time(n.min(3), || Ok(recon.with_auto_hyperparameter(Channels::all(mask.len()), None)?))?;
    // A frame with a press at (30 %, −20 %) of the half-width, so the touch stage finds one.
    let [lo, hi] = model.mesh().bounds();
    let half = (hi[0] - lo[0]) / 2.0;
    let press = Inclusion { centre: [0.3 * half, -0.2 * half], radius: 0.1 * half, conductivity: 0.5 * background };
    let frame = model.measure(&with_inclusions(model.mesh(), background, &[press]))?;
    let mut image = recon.blank_image();
    let frames = 2001;
    let (t_image, ()) = time(frames, || Ok(recon.image_into(&values, &frame, &mut image)?))?;
    let (mut scratch, mut touches) = (TouchScratch::new(image.size), Vec::with_capacity(16));
    let touch_params = TouchParams::default();
    let (t_touches, ()) = time(frames, || {
        detect_into(&image, &touch_params, &mut scratch, &mut touches);
        Ok(())
    })?;
    let press_params = PressModelParams::default();
    // The press model with its exact responses, on a coarser mesh of the sensor when this one is
    // too fine to keep its inverse whole (that mesh's build is counted).
    let (t_press_model, press_model) = time(n.min(3), || {
        let exact = exact_model_for(&spec, &model)?;
        Ok(PressModel::with_exact_model(&model, exact.as_ref().unwrap_or(&model), background, &press_params)?)
    })?;
    let dv: Vec<f64> = frame.iter().zip(&values).map(|(v, r)| v - r).collect();
    let starts: Vec<[f64; 2]> = touches.iter().map(|t| t.centre).collect();
    let (mut press_scratch, mut fits) = (PressScratch::default(), Vec::with_capacity(16));
    let (t_fit, ()) = time(frames, || Ok(press_model.fit_into(&dv, &starts, &mut press_scratch, &mut fits)?))?;
    // Three presses at once, found in Δv against 0.05 % noise per value (the reference of 10 frames).
    let std: Vec<f64> = values.iter().map(|v| 5e-4 * v.abs() * 1.1_f64.sqrt()).collect();
    let (t_detection, detection) = time(n.min(3), || Ok(PressDetection::new(&press_model, &std, 9.0, 1e-3)?))?;
    let three = [([-0.3, 0.4], 0.25), ([0.4, -0.2], 0.5), ([0.6, 0.7], 0.6)].map(|(at, drop)| Inclusion {
        centre: [at[0] * half, at[1] * half],
        radius: press_params.radius,
        conductivity: (1.0 - drop) * background,
    });
    let pressed = model.measure(&with_inclusions(model.mesh(), background, &three))?;
    let dv3: Vec<f64> = pressed.iter().zip(&values).map(|(v, r)| v - r).collect();
    let (mut whitened, mut found) = (Vec::new(), Vec::with_capacity(16));
    let (t_detect, ()) =
        time(201, || Ok(detection.detect_into(&dv3, &mut whitened, &mut press_scratch, &mut found)?))?;
    // The same presses held over a stream of 201 frames, each with its own draw of the noise:
    // found afresh in each, and carried from frame to frame.
    let mut rng = eitskin::SeededRng::seed_from_u64(7);
    let mut held_under = |std: &[f64]| -> Vec<Vec<f64>> {
        let mut draw = || Distribution::<f64>::sample(&StandardNormal, &mut rng);
        (0..201).map(|_| dv3.iter().zip(std).map(|(d, s)| d + s * draw()).collect()).collect()
    };
    let held = held_under(&std);
    let mut next = 0;
    let (t_noisy, ()) = time(held.len(), || {
        next += 1;
        Ok(detection.detect_into(&held[next - 1], &mut whitened, &mut press_scratch, &mut found)?)
    })?;
    let (mut track, mut next) = (PressTrack::default(), 0);
    let (t_carried, _) = time(held.len(), || {
        next += 1;
        Ok(detection.track_into(&held[next - 1], &mut whitened, &mut press_scratch, &mut track, &mut found)?)
    })?;
    // The same stream at 80 dB (0.01 %, the virtual sensor's noise), against a detection for it.
    let std80: Vec<f64> = values.iter().map(|v| 1e-4 * v.abs() * 1.01_f64.sqrt()).collect();
    let detection80 = PressDetection::new(&press_model, &std80, 99.0, 1e-3)?;
    let held80 = held_under(&std80);
    let (mut track, mut next) = (PressTrack::default(), 0);
    let (t_carried80, _) = time(held80.len(), || {
        next += 1;
        Ok(detection80.track_into(&held80[next - 1], &mut whitened, &mut press_scratch, &mut track, &mut found)?)
    })?;
    let (replay_fps, replay_latency) = replay(&recon, &values, &frame)?;
    // The virtual sensor's frame on its finer truth mesh: one press, then three presses apart
    // (corners of a triangle half the sheet wide, unequal forces).
    let mut sensor = VirtualSensor::new(&spec, 1)?;
    sensor.press([0.3 * half, -0.2 * half], 5.0);
    let (t_simulated, _) = time(n.min(15), || Ok(sensor.frame()?))?;
    sensor.press([-0.5 * half, 0.5 * half], 9.0);
    sensor.press([0.5 * half, 0.5 * half], 3.0);
    let (t_simulated_three, _) = time(n.min(15), || Ok(sensor.frame()?))?;
    let (t_learn, t_learned_frame, t_learn_press, t_learned_press_frame) = learned(&spec)?;
    let stages = [
        ("mesh", t_mesh),
        ("model", t_model),
        ("assembly", t_assembly),
        ("factorisation", t_factor),
        ("solves", t_solves),
        ("measurements", t_measure),
        ("jacobian", t_jacobian),
        ("reconstructor", t_recon),
        ("drop_channel", t_drop),
        ("auto_hyperparameter", t_auto),
        ("press_model", t_press_model),
        ("press_detection", t_detection),
        ("learn_1000_presses", t_learn),
        ("learn_1000_presses_press", t_learn_press),
        ("frame_image", t_image),
        ("frame_touches", t_touches),
        ("frame_press_fit", t_fit),
        ("frame_three_presses", t_detect),
        ("frame_three_presses_noisy", t_noisy),
        ("frame_three_presses_carried", t_carried),
        ("frame_three_presses_carried_80db", t_carried80),
        ("replay_latency", replay_latency),
        ("simulated_frame", t_simulated),
        ("simulated_three_presses", t_simulated_three),
        ("learned_frame", t_learned_frame),
        ("learned_press_frame", t_learned_press_frame),
    ];
    let total: f64 = stages[..6].iter().map(|s| s.1.median).sum();
    let peak_memory = eitskin_io::peak_memory();
    if args.json {
        let mut out = serde_json::Map::new();
        out.insert("triangles".into(), model.mesh().triangles().len().into());
        out.insert("nodes".into(), model.mesh().nodes().len().into());
        out.insert("repeat".into(), n.into());
        let mut fastest = serde_json::Map::new();
        for (name, t) in stages {
            out.insert(name.into(), t.median.into());
            fastest.insert(name.into(), t.min.into());
        }
        out.insert("min".into(), fastest.into());
        out.insert("total".into(), total.into());
        out.insert("frame".into(), (t_image.median + t_touches.median).into());
        out.insert("replay_frames_per_second".into(), replay_fps.into());
        out.insert("peak_memory_bytes".into(), peak_memory.into());
        println!("{}", serde_json::Value::Object(out));
    } else {
        println!(
            "{} triangles, {} nodes, {} measurements; median (fastest) of {n} runs:",
            model.mesh().triangles().len(),
            model.mesh().nodes().len(),
            values.len()
        );
        for (name, t) in &stages[..6] {
            println!("  {name:<24} {:>10.3} ms  ({:.3})", t.median * 1e3, t.min * 1e3);
        }
        println!("  {:<24} {:>10.3} ms  (forward setup chain)", "total", total * 1e3);
        // The inverse setup: Jacobian, reconstructor, its re-derivations, the press model.
        let per_frame = stages.iter().position(|s| s.0 == "frame_image").unwrap_or(stages.len());
        for (name, t) in &stages[6..per_frame] {
            println!("  {name:<24} {:>10.3} ms  ({:.3})", t.median * 1e3, t.min * 1e3);
        }
        println!("per frame, median (fastest) of {frames} ({} pixels, {} touch):", image.values.len(), touches.len());
        for (name, t) in &stages[per_frame..] {
            println!("  {name:<24} {:>10.3} µs  ({:.3})", t.median * 1e6, t.min * 1e6);
        }
        println!("file replay through decoder, pipeline and JSON line: {replay_fps:.0} frames/s on one thread");
        match peak_memory {
            Some(bytes) => println!("peak memory (resident): {:.1} MB", bytes / 1e6),
            None => println!("peak memory: not known on this system"),
        }
    }
    Ok(())
}
