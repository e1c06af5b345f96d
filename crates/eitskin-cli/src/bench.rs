//! `eitskin bench`: times each stage of the setup chain over repeated runs, prints medians.
//!
//! Stages: `mesh` (triangulation and refinement), `model` (sparsity pattern and symbolic
//! Cholesky, once per mesh), `assembly`, `factorisation` (numeric Cholesky), `solves` (all
//! L−1 current patterns), `measurements` (the protocol's values from the fields); then the
//! imaging chain: `jacobian`, `forward_p2_graded` (the whole forward chain within 0.1 % of the
//! converged values: quadratic elements on the sheet graded to 0.02, 5,600 triangles; complete
//! electrodes only), `reconstructor` (prior, the measurement-sized solve and the
//! raster projection), `auto_hyperparameter` (λ chosen from the noise, on the sensor's
//! reconstructor, its channels' products kept), `auto_hyperparameter_first` (λ alone, first on a
//! linearisation: the products made), `derive_reference`, `derive_refresh_noise` and `derive_refresh_grown` (what a
//! live pipeline derives off its frame path, λ from the noise: when its reference is taken, when
//! its noise has changed, and when only its reference has grown) and `auto_hyperparameter_2356` and `reconstructor_2356` (λ, then the reconstructor at it, on a
//! KTC-sized 32-electrode tank, 2,356 channels), `press_model` (its response table and, by low-rank updates, the ladder
//! of strong presses), `press_table` (one press's exact response tabulated over the sheet and
//! its drop, put to its default use, [`TableUse::DEFAULT`]), `contrast_map`
//! (the contrast calibrations' map: 41 × 41 places × 11 presses simulated on the model and
//! imaged) and `press_detection` (its noise threshold, from 400 noise frames) and,
//! per frame (median over many frames), `frame_image`, `frame_touches`, `frame_press_fit` (one
//! press fitted from the touch), `fleet_frame_half` and `fleet_frame_shared` (one image on one
//! core from each of 100 sensors of one spec in turn, λ from each one's noise: from their own
//! half-precision matrices, and through their shared basis; left out where there is none) and `frame_three_presses` (three presses found in Δv against
//! 0.05 % noise, median of 201 runs on the noiseless frame, with `run`'s press model, fitted on
//! the table while it holds), `frame_three_presses_noisy` (the same on 201 frames of the
//! presses held, each with its own 0.05 % noise; `frame_three_presses_noisy_tabulated` fitted on
//! the table throughout, `run --press-table fit`; `_noisy_table_start` exact fits started from
//! it, `run --press-table start`; `_noisy_no_table` without it, `run --press-table off`) and
//! `frame_three_presses_carried` (those frames as a stream, the presses carried from frame to
//! frame) and `frame_three_presses_carried_80db` (the same stream at 0.01 % noise, the reference
//! of 100 frames); `simulated_frame` and `simulated_three_presses` (the virtual
//! sensor's frame on its finer truth mesh, one press and three apart, median of 201 frames)
//! and `simulated_frames_bulk` (one frame of 200 single presses asked for at once, as the study
//! asks, in parallel on every core: `--cores` sets the frame path's products only);
//! `learn_1000_presses` and `learned_frame` (a Gaussian process on 1,000 robot presses of 192
//! channels, and its answer for one frame), and the same on the fitted press
//! (`learn_1000_presses_press`, `learned_press_frame`); and `replay`: a file of 5,000 text
//! frames through the lines decoder, the pipeline and the JSON line, as fast as possible
//! (frames/s, median latency per frame).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Result;
use eitskin::chain::Chain;
use eitskin::conductivity::{with_inclusions, Inclusion};
use eitskin::contrast_map::{ContrastMap, ContrastMapParams};
use eitskin::inverse::Channels;
use eitskin::memory::Stage;
use eitskin::pipeline::{Deferred, Pipeline, PipelineParams};
use eitskin::press_fit::{
    exact_model_for, PressDetection, PressModel, PressModelParams, PressScratch, PressTrack, TableUse,
};
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

/// Replays text lines as fast as possible through the lines decoder, the pipeline `run` builds
/// for `spec` (reference of 10 frames, image, touches) and the JSON line `eitskin run` prints:
/// frames per second over the whole replay, and the latency from a line's last byte to its JSON
/// line, in s.
fn replay(spec: &eitskin::SensorSpec, rest: &[f64], pressed: &[f64]) -> Result<(f64, Timing)> {
    let count = 5000;
    let line = |v: &[f64]| v.iter().map(|x| format!("{x:.6e}")).collect::<Vec<_>>().join(",") + "\n";
    let lines: Vec<String> = (0..count).map(|k| line(if k % 2 == 0 || k < 10 { rest } else { pressed })).collect();
    let setup = eitskin_io::build::ChainSetup::new(ReconstructorParams::default());
    let mut pipeline = eitskin_io::build::pipeline(spec, setup, PipelineParams::default())?;
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

/// The timings of the named stages: the setup's (the forward chain's first, [`FORWARD`] of
/// them), and each frame's.
#[derive(Default)]
struct Stages {
    setup: Vec<(&'static str, Timing)>,
    per_frame: Vec<(&'static str, Timing)>,
}

/// The stages of the forward setup chain, the first of [`Stages::setup`].
const FORWARD: usize = 6;

/// Frames each per-frame stage is timed over.
const FRAMES: usize = 2001;

/// Runs `eitskin bench`.
pub fn run(args: Args) -> Result<()> {
    let spec = load::sized(load::spec(args.spec.as_deref())?, args.triangles, Stage::Reconstructor)?;
    let n = args.repeat;
    let mut stages = Stages::default();
    let (model, values) = forward(&spec, n, &mut stages)?;
    let recon = inverse(&spec, &model, n, &mut stages)?;
    let (frame, pixels, touches) = frames(&spec, &model, &recon, &values, n, &mut stages)?;
    let (replay_fps, replay_latency) = replay(&spec, &values, &frame)?;
    stages.per_frame.push(("replay_latency", replay_latency));
    simulated(&spec, n, &mut stages)?;
    let (t_learn, t_learned_frame, t_learn_press, t_learned_press_frame) = learned(&spec)?;
    stages.setup.extend([("learn_1000_presses", t_learn), ("learn_1000_presses_press", t_learn_press)]);
    stages.per_frame.extend([("learned_frame", t_learned_frame), ("learned_press_frame", t_learned_press_frame)]);
    let sizes = [model.mesh().triangles().len(), model.mesh().nodes().len(), values.len(), pixels, touches];
    match args.json {
        true => print_json(&stages, sizes, n, replay_fps),
        false => print_text(&stages, sizes, n, replay_fps),
    }
    Ok(())
}

/// The forward setup chain, stage by stage: the model and its frame at the background.
fn forward(spec: &eitskin::SensorSpec, n: usize, stages: &mut Stages) -> Result<(eitskin::ForwardModel, Vec<f64>)> {
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
    // The forward model within 0.1 % of its converged values (eitskin convergence): quadratic
    // elements on the sheet graded to 0.02 at the electrodes' edges, 5,600 triangles.
    let mut graded = spec.clone();
    (graded.mesh.triangles, graded.mesh.max_element_size, graded.mesh.grading) = (5600, None, 0.02);
    let within = || {
        let model = graded.forward_model()?;
        Ok(model.measure_quadratic(&graded.homogeneous(model.mesh()))?)
    };
    let t_p2 = if spec.electrodes.point { None } else { Some(time(n.min(5), within)?.0) };
    stages.setup.extend([
        ("mesh", t_mesh),
        ("model", t_model),
        ("assembly", t_assembly),
        ("factorisation", t_factor),
        ("solves", t_solves),
        ("measurements", t_measure),
        ("jacobian", t_jacobian),
    ]);
    stages.setup.extend(t_p2.map(|t| ("forward_p2_graded", t)));
    Ok((model, values))
}

/// The reconstructor, derived again without a channel gone bad, and its automatic λ.
fn inverse(
    spec: &eitskin::SensorSpec,
    model: &eitskin::ForwardModel,
    n: usize,
    stages: &mut Stages,
) -> Result<Reconstructor> {
    let params = ReconstructorParams::default();
    let (t_recon, recon) = time(n, || Ok(Reconstructor::new(model, spec.conductivity, &params)?))?;
    let mut mask = vec![true; recon.measurements()];
    mask[0] = false;
    let channels = Channels::all(mask.len()).masked(&mask);
    let (t_drop, _) = time(n, || Ok(recon.derive(params.hyperparameter, channels.clone())?))?;
    // λ again on channels chosen before (a live sensor's refreshes: the channels' products
    // kept), and first on a linearisation (each a fresh copy, made outside the timing).
    let (t_auto, _) = time(n.min(3), || Ok(recon.with_auto_hyperparameter(Channels::all(mask.len()), None)?))?;
    let mut fresh: Vec<_> = (0..n.min(3)).map(|_| (**recon.linearisation()).clone()).collect();
    let first_lambda = || {
        let lin = fresh.pop().ok_or_else(|| anyhow::anyhow!("a fresh linearisation per run"))?;
        Ok(eitskin::inverse::choose_hyperparameter(&lin, &params.prior, false, &Channels::all(mask.len()))?)
    };
    let (t_first, _) = time(n.min(3), first_lambda)?;
    stages.setup.extend([
        ("reconstructor", t_recon),
        ("drop_channel", t_drop),
        ("auto_hyperparameter", t_auto),
        ("auto_hyperparameter_first", t_first),
    ]);
    derivations(spec, &recon, n, stages)?;
    let (lin, channels) = tank()?;
    let prior = eitskin::Prior::default();
    let choose = || Ok(eitskin::inverse::choose_hyperparameter(&lin, &prior, false, &channels)?);
    let (t_tank, hyperparameter) = time(n.min(3), choose)?;
    let params = ReconstructorParams { hyperparameter, ..ReconstructorParams::default() };
    let build = || Ok(Reconstructor::from_linearisation(lin.clone(), &params, channels.clone())?);
    let t_tank_recon = time(n.min(3), build)?.0;
    stages.setup.extend([("auto_hyperparameter_2356", t_tank), ("reconstructor_2356", t_tank_recon)]);
    Ok(recon)
}

/// The derivations a pipeline hands out ([`Deferred::All`]) on 400 frames of the virtual sensor
/// at rest, λ chosen from the noise: the reference's, and the first refresh of each kind.
fn derivations(spec: &eitskin::SensorSpec, recon: &Reconstructor, n: usize, stages: &mut Stages) -> Result<()> {
    let params = PipelineParams { auto_hyperparameter: true, ..PipelineParams::default() };
    let mut pipeline = Pipeline::new(Chain::new(recon.clone(), TouchParams::default()), params);
    pipeline.defer_derivations(Deferred::All);
    let mut skin = VirtualSensor::new(spec, 3)?;
    let mut timed: Vec<(&'static str, Timing)> = Vec::new();
    for _ in 0..400 {
        pipeline.process(&skin.frame()?)?;
        let Some(job) = pipeline.take_derivation() else { continue };
        let name = match (job.is_reference(), job.rederives()) {
            (true, _) => "derive_reference",
            (false, true) => "derive_refresh_noise",
            (false, false) => "derive_refresh_grown",
        };
        let (timing, derived) = time(n.min(5), || Ok(job.clone().run()))?;
        pipeline.deliver(derived);
        if timed.iter().all(|(seen, _)| *seen != name) {
            timed.push((name, timing));
        }
    }
    timed.sort_by_key(|(name, _)| *name);
    stages.setup.extend(timed);
    Ok(())
}

/// Sensors in [`fleet_frames`].
const FLEET: usize = 100;

/// Bytes the fleet of [`fleet_frames`] may hold, at most.
const FLEET_BYTES: usize = 1 << 30;

/// One image a frame, on one core, from each of [`FLEET`] sensors of one spec in turn, λ chosen
/// from each one's noise (as `serve` images a fleet whose matrices overflow the cache): from
/// their own half-precision matrices (read from memory), and through their shared basis with
/// their own mixes. `None` where the sensor's reconstructors have no shared basis (more channels
/// than the electrodes have pairs, or than 256) or a fleet of them would hold more than
/// [`FLEET_BYTES`].
fn fleet_frames(recon: &Reconstructor, values: &[f64], frame: &[f64]) -> Result<Option<(Timing, Timing)>> {
    let m = recon.measurements();
    let derive = |k: usize| {
        let noise = (0..m).map(|c| 1e-6 * (1.0 + ((c * 7 + k) % 5) as f64)).collect();
        Ok(recon.with_auto_hyperparameter(Channels::all(m), Some(noise))?.0)
    };
    let first: Reconstructor = derive(0)?;
    // Its single-precision raster and triangle matrices, and the half copy.
    let each = first.matrix().bytes_read() * 5 / 2 + first.blank_image().values.len() * 4;
    if !first.can_share_basis() || each.saturating_mul(FLEET) > FLEET_BYTES {
        return Ok(None);
    }
    let mut fleet = std::iter::once(Ok(first)).chain((1..FLEET).map(derive)).collect::<Result<Vec<_>>>()?;
    let par = eitskin::parallel::par();
    eitskin::parallel::set_par(eitskin::parallel::Par::Seq);
    let mut image = recon.blank_image();
    let mut timed = |fleet: &[Reconstructor]| {
        let mut k = 0;
        time(FRAMES, || {
            k = (k + 1) % FLEET;
            Ok(fleet[k].image_into(values, frame, &mut image)?)
        })
    };
    fleet.iter_mut().for_each(|r| r.set_half_precision(true));
    let own = timed(&fleet);
    fleet.iter_mut().for_each(|r| {
        r.set_half_precision(false);
        r.set_shared_basis(true);
    });
    let shared = timed(&fleet);
    eitskin::parallel::set_par(par);
    Ok(Some((own?.0, shared?.0)))
}

/// A 32-electrode tank with a KTC-sized protocol: 76 drives (32 adjacent, 32 skipping two, 12
/// opposite) × 31 adjacent differences = 2,356 channels, a disc of 115 mm radius with 4,000
/// triangles; its linearisation, and its channels with each one's noise 0.3 % of its value.
fn tank() -> Result<(std::sync::Arc<eitskin::inverse::Linearisation>, Channels)> {
    let l = 32;
    let pair = |a: usize, b: usize| (0..l).map(|e| f64::from(u8::from(e == a)) - f64::from(u8::from(e == b))).collect();
    let drives: Vec<Vec<f64>> = (0..l)
        .map(|k| pair(k, (k + 1) % l))
        .chain((0..l).map(|k| pair(k, (k + 3) % l)))
        .chain((0..12).map(|k| pair(k, k + l / 2)))
        .collect();
    let measurements = (0..drives.len())
        .flat_map(|stimulation| (0..l - 1).map(move |m| eitskin::Measurement { stimulation, weights: pair(m, m + 1) }))
        .collect();
    let mut spec = eitskin::SensorSpec::square_hydrogel();
    spec.outline = eitskin::Outline::Circle { radius: 0.115 };
    spec.electrodes.count = l;
    spec.electrodes.width = 0.008;
    spec.electrodes.placement = eitskin::Placement::Equal { start_angle_deg: 0.0 };
    spec.protocol = eitskin::ProtocolSpec::Custom(eitskin::Protocol::new("KTC-sized", l, drives, measurements)?);
    let lin = eitskin::inverse::Linearisation::new(&spec.forward_model()?, spec.conductivity)?;
    let channels = lin.noise_weighted(false, Channels::all(lin.measurements()), None);
    Ok((std::sync::Arc::new(lin), channels))
}

/// Each frame's stages on a press at (30 %, −20 %) of the half-width: image, touches, the press
/// fitted; then three presses found against 0.05 % noise, afresh and carried, and at 0.01 %.
/// The pressed frame, the image's pixels and the touches found.
fn frames(
    spec: &eitskin::SensorSpec,
    model: &eitskin::ForwardModel,
    recon: &Reconstructor,
    values: &[f64],
    n: usize,
    stages: &mut Stages,
) -> Result<(Vec<f64>, usize, usize)> {
    let background = spec.conductivity;
    let [lo, hi] = model.mesh().bounds();
    let half = (hi[0] - lo[0]) / 2.0;
    let press = Inclusion { centre: [0.3 * half, -0.2 * half], radius: 0.1 * half, conductivity: 0.5 * background };
    let frame = model.measure(&with_inclusions(model.mesh(), background, &[press]))?;
    let mut image = recon.blank_image();
    let (t_image, ()) = time(FRAMES, || Ok(recon.image_into(values, &frame, &mut image)?))?;
    let (mut scratch, mut touches) = (TouchScratch::new(image.size), Vec::with_capacity(16));
    let touch_params = TouchParams::default();
    let (t_touches, ()) = time(FRAMES, || {
        detect_into(&image, &touch_params, &mut scratch, &mut touches);
        Ok(())
    })?;
    let press_params = PressModelParams::default();
    // The press model with its exact responses, on a coarser mesh of the sensor when this one is
    // too fine to keep its inverse whole (that mesh's build is counted).
    let (t_press_model, press_model) = time(n.min(3), || {
        let exact = exact_model_for(spec, model)?;
        Ok(PressModel::with_exact_model(model, exact.as_ref().unwrap_or(model), background, &press_params)?)
    })?;
    let dv: Vec<f64> = frame.iter().zip(values).map(|(v, r)| v - r).collect();
    let starts: Vec<[f64; 2]> = touches.iter().map(|t| t.centre).collect();
    let (mut press_scratch, mut fits) = (PressScratch::default(), Vec::with_capacity(16));
    let (t_fit, ()) = time(FRAMES, || Ok(press_model.fit_into(&dv, &starts, &mut press_scratch, &mut fits)?))?;
    stages.setup.push(("press_model", t_press_model));
    let bounds = spec.outline.bounds();
    let map_params = ContrastMapParams::default();
    let (t_contrast_map, _) = time(n.min(3), || Ok(ContrastMap::new(model, background, recon, bounds, &map_params)?))?;
    stages.setup.push(("contrast_map", t_contrast_map));
    stages.per_frame.extend([("frame_image", t_image), ("frame_touches", t_touches), ("frame_press_fit", t_fit)]);
    if let Some((t_own, t_shared)) = fleet_frames(recon, values, &frame)? {
        stages.per_frame.extend([("fleet_frame_half", t_own), ("fleet_frame_shared", t_shared)]);
    }
    let three = [([-0.3, 0.4], 0.25), ([0.4, -0.2], 0.5), ([0.6, 0.7], 0.6)].map(|(at, drop)| Inclusion {
        centre: [at[0] * half, at[1] * half],
        radius: press_params.radius,
        conductivity: (1.0 - drop) * background,
    });
    let pressed = model.measure(&with_inclusions(model.mesh(), background, &three))?;
    let dv3: Vec<f64> = pressed.iter().zip(values).map(|(v, r)| v - r).collect();
    three_presses(&press_model, values, &dv3, n, stages)?;
    Ok((frame, image.values.len(), touches.len()))
}

/// Three presses (Δv `dv3`) found against 0.05 % noise per value (the reference of 10 frames),
/// with `run`'s press model (its table's default use): on the noiseless frame, on 201 frames
/// each with its own noise, found afresh and carried from frame to frame; and carried at 0.01 %
/// (the virtual sensor's noise, a reference of 100 frames). The noisy frames found afresh also
/// with the table's other uses, and without it.
fn three_presses(linear: &PressModel, values: &[f64], dv3: &[f64], n: usize, stages: &mut Stages) -> Result<()> {
    let std: Vec<f64> = values.iter().map(|v| 5e-4 * v.abs() * 1.1_f64.sqrt()).collect();
    let (t_table, press_model) = time(n.min(3), || Ok(linear.clone().with_table_use(TableUse::DEFAULT)?))?;
    let press_model = &press_model;
    let (t_detection, detection) = time(n.min(3), || Ok(PressDetection::new(press_model, &std, 9.0, 1e-3)?))?;
    let (mut whitened, mut found, mut scratch) = (Vec::new(), Vec::with_capacity(16), PressScratch::default());
    let (t_detect, ()) = time(201, || Ok(detection.detect_into(dv3, &mut whitened, &mut scratch, &mut found)?))?;
    let mut rng = eitskin::SeededRng::seed_from_u64(7);
    let mut held_under = |std: &[f64]| -> Vec<Vec<f64>> {
        let mut draw = || Distribution::<f64>::sample(&StandardNormal, &mut rng);
        (0..201).map(|_| dv3.iter().zip(std).map(|(d, s)| d + s * draw()).collect()).collect()
    };
    let held = held_under(&std);
    // The noisy frames found afresh, one after another, by `detection`.
    let mut afresh = |detection: &PressDetection| {
        let mut next = 0;
        time(held.len(), || {
            next += 1;
            Ok(detection.detect_into(&held[next - 1], &mut whitened, &mut scratch, &mut found)?)
        })
    };
    let (t_noisy, ()) = afresh(&detection)?;
    let used_for = |table_use| -> Result<PressDetection> {
        Ok(PressDetection::new(&press_model.clone().with_table_use(Some(table_use))?, &std, 9.0, 1e-3)?)
    };
    let (t_noisy_table, ()) = afresh(&used_for(TableUse::Fit)?)?;
    let (t_noisy_start, ()) = afresh(&used_for(TableUse::Start)?)?;
    let (t_noisy_without, ()) = afresh(&PressDetection::new(linear, &std, 9.0, 1e-3)?)?;
    let (mut track, mut next) = (PressTrack::default(), 0);
    let (t_carried, _) = time(held.len(), || {
        next += 1;
        Ok(detection.track_into(&held[next - 1], &mut whitened, &mut scratch, &mut track, &mut found)?)
    })?;
    let std80: Vec<f64> = values.iter().map(|v| 1e-4 * v.abs() * 1.01_f64.sqrt()).collect();
    let detection80 = PressDetection::new(press_model, &std80, 99.0, 1e-3)?;
    let held80 = held_under(&std80);
    let (mut track, mut next) = (PressTrack::default(), 0);
    let (t_carried80, _) = time(held80.len(), || {
        next += 1;
        Ok(detection80.track_into(&held80[next - 1], &mut whitened, &mut scratch, &mut track, &mut found)?)
    })?;
    stages.setup.extend([("press_detection", t_detection), ("press_table", t_table)]);
    stages.per_frame.extend([
        ("frame_three_presses", t_detect),
        ("frame_three_presses_noisy", t_noisy),
        ("frame_three_presses_noisy_tabulated", t_noisy_table),
        ("frame_three_presses_noisy_table_start", t_noisy_start),
        ("frame_three_presses_noisy_no_table", t_noisy_without),
        ("frame_three_presses_carried", t_carried),
        ("frame_three_presses_carried_80db", t_carried80),
    ]);
    Ok(())
}

/// Frames a virtual sensor's frame is timed over (a few hundred µs each; the first, with the
/// update's setup, about a second, which the median leaves out). The median of `--repeat`
/// frames (5) moved from 263 to 715 µs between runs of one binary on a busy machine.
const SIMULATED_FRAMES: usize = 201;

/// The virtual sensor's frame on its finer truth mesh: one press, then three presses apart
/// (corners of a triangle half the sheet wide, unequal forces), each over [`SIMULATED_FRAMES`].
fn simulated(spec: &eitskin::SensorSpec, n: usize, stages: &mut Stages) -> Result<()> {
    let [lo, hi] = spec.outline.bounds();
    let half = (hi[0] - lo[0]) / 2.0;
    let mut sensor = VirtualSensor::new(spec, 1)?;
    sensor.press([0.3 * half, -0.2 * half], 5.0);
    let (t_simulated, _) = time(SIMULATED_FRAMES, || Ok(sensor.frame()?))?;
    sensor.press([-0.5 * half, 0.5 * half], 9.0);
    sensor.press([0.5 * half, 0.5 * half], 3.0);
    let (t_simulated_three, _) = time(SIMULATED_FRAMES, || Ok(sensor.frame()?))?;
    // Frames in bulk, as the study asks for them: 200 single presses across the sheet, in
    // parallel through the update the sensor has made; per frame.
    let cases: Vec<Vec<eitskin::sim::Press>> = (0..200)
        .map(|k| {
            let (x, y) = ((k % 20) as f64 / 19.0 - 0.5, (k / 20) as f64 / 9.0 - 0.5);
            vec![eitskin::sim::Press { position: [1.4 * half * x, 1.4 * half * y], force: 1.0 + (k % 7) as f64 }]
        })
        .collect();
    let (bulk, _) = time(n.min(5), || Ok(sensor.clean_frames(&cases)?))?;
    let per_frame = |t: f64| t / cases.len() as f64;
    let t_bulk = Timing { median: per_frame(bulk.median), min: per_frame(bulk.min) };
    stages.per_frame.extend([
        ("simulated_frame", t_simulated),
        ("simulated_three_presses", t_simulated_three),
        ("simulated_frames_bulk", t_bulk),
    ]);
    Ok(())
}

/// One JSON object: each stage's median (and under `min` its fastest), in s, and the sizes.
fn print_json(stages: &Stages, [triangles, nodes, ..]: [usize; 5], n: usize, replay_fps: f64) {
    let total: f64 = stages.setup[..FORWARD].iter().map(|s| s.1.median).sum();
    let mut out = serde_json::Map::new();
    out.insert("triangles".into(), triangles.into());
    out.insert("nodes".into(), nodes.into());
    out.insert("repeat".into(), n.into());
    let mut fastest = serde_json::Map::new();
    let mut frame = 0.0;
    for &(name, t) in stages.setup.iter().chain(&stages.per_frame) {
        out.insert(name.into(), t.median.into());
        fastest.insert(name.into(), t.min.into());
        if name == "frame_image" || name == "frame_touches" {
            frame += t.median;
        }
    }
    out.insert("min".into(), fastest.into());
    out.insert("total".into(), total.into());
    out.insert("frame".into(), frame.into());
    out.insert("replay_frames_per_second".into(), replay_fps.into());
    out.insert("peak_memory_bytes".into(), eitskin_io::peak_memory().into());
    println!("{}", serde_json::Value::Object(out));
}

/// The stages as a table: the forward chain and its total, the inverse setup, each frame's.
fn print_text(stages: &Stages, [triangles, nodes, measurements, pixels, touches]: [usize; 5], n: usize, fps: f64) {
    println!("{triangles} triangles, {nodes} nodes, {measurements} measurements; median (fastest) of {n} runs:");
    let (forward, inverse) = stages.setup.split_at(FORWARD);
    for (name, t) in forward {
        println!("  {name:<24} {:>10.3} ms  ({:.3})", t.median * 1e3, t.min * 1e3);
    }
    let total: f64 = forward.iter().map(|s| s.1.median).sum();
    println!("  {:<24} {:>10.3} ms  (forward setup chain)", "total", total * 1e3);
    // The inverse setup: Jacobian, reconstructor, its re-derivations, the press model.
    for (name, t) in inverse {
        println!("  {name:<24} {:>10.3} ms  ({:.3})", t.median * 1e3, t.min * 1e3);
    }
    println!("per frame, median (fastest) of {FRAMES} ({pixels} pixels, {touches} touch):");
    for (name, t) in &stages.per_frame {
        println!("  {name:<24} {:>10.3} µs  ({:.3})", t.median * 1e6, t.min * 1e6);
    }
    println!("file replay through decoder, pipeline and JSON line: {fps:.0} frames/s on one thread");
    match eitskin_io::peak_memory() {
        Some(bytes) => println!("peak memory (resident): {:.1} MB", bytes / 1e6),
        None => println!("peak memory: not known on this system"),
    }
}
