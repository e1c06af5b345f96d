//! `eitskin run`: a live sensor. Frames come from a source of [`eitskin_io::source`] (the
//! virtual sensor, a file, a serial port); each goes through the pipeline (reference, image,
//! touches, forces) and out as one JSON line of the [`eitskin_io::stream`] schema, after a start
//! line that gives its version and length unit.
//!
//! Acquisition runs on its own thread, a plain loop over the source, and hands items over a
//! channel: without a bound for a live source (a serial port, whose input is lost if not read in
//! time), so that a slow consumer never stalls it; bounded for the others (files, the virtual
//! sensor), which then wait, so that memory stays flat however long the file. Processing writes
//! every frame to the recorder before it prints. With `--viewer`, processing also offers each
//! frame to the web viewer without waiting (see [`crate::viewer`]) and takes its commands
//! (re-take the reference) between frames.
//!
//! Imaging: λ is chosen from the reference frames' noise unless given (`--hyperparameter`), or
//! taken from the calibration, which fixes λ and the normalisation it was fitted with (see
//! [`imaging`]). A channel that goes bad (not finite) is dropped and named on stderr and in a
//! `channels_dropped` event, until the reference is re-taken; see [`eitskin::pipeline`].

mod imaging;
mod learned;

use std::borrow::Cow;
use std::io::Write;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::mpsc;

use anyhow::{bail, Result};
use eitskin::calibration::Strength;
use eitskin::inverse::Hyperparameter;
use eitskin::memory::Stage;
use eitskin::pipeline::{NoiseFloor, Pipeline, PipelineParams, Status};
use eitskin::pseudo_array::PseudoArray;
use eitskin::touch::{PeakOf, Polarity};
use eitskin::values::{Component, ValueKind};
use eitskin::{ReconstructorParams, SensorSpec, TouchParams};
use eitskin_io::recorder::{Header, Recorder};
use eitskin_io::replay::Speed;
use eitskin_io::source::{Acquired, Codec, Source, SourceError, SourceSettings, SourceSpec};
use eitskin_io::stream::{self, Counters, Event, FrameLine, Raster, Recorded, Start};

use crate::viewer::{self, Viewer};
use crate::{load, outputs, ranges};

/// Items a source that can wait may have ready before processing takes them.
const QUEUE_ITEMS: usize = 1024;

/// How long a source that can wait sleeps when the queue is full, before it tries again.
const QUEUE_WAIT: std::time::Duration = std::time::Duration::from_millis(1);

/// Flags of `eitskin run`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Sensor spec file (TOML); default: the paper's sensor.
    spec: Option<PathBuf>,
    /// Where frames come from: `sim` (the virtual sensor, pressed at random), `sim:SCRIPT` (pressed
    /// as a script of `start end x y force` lines says), `file:PATH` (a recording made with
    /// --record, replayed at its pace, or a capture of a board's bytes, decoded with --codec, at
    /// --rate), or `serial:PATH[@BAUD]` (a board on a serial port, 8N1 at 115200 bit/s unless told,
    /// e.g. serial:/dev/ttyACM0@921600; frames decoded with --codec).
    #[arg(long, value_name = "SOURCE", default_value = "sim")]
    source: SourceSpec,
    /// Frames per second of the virtual sensor, or of a capture file, which has no times, in
    /// [0, 100000] (0: a capture as fast as possible).
    #[arg(long, default_value_t = 20.0, value_parser = ranges::number("a frame rate", "[0, 100000] frames/s", "20", |r| (0.0..=1e5).contains(&r)))]
    rate: f64,
    /// Do not wait between frames (the virtual sensor's clock still advances at --rate; a
    /// recording replays as fast as possible).
    #[arg(long)]
    fast: bool,
    /// Mesh with about this many triangles instead of the spec's count, 1–100,000,000 (refused
    /// when the mesh and what is built on it would not fit in the memory available).
    #[arg(long, value_parser = ranges::triangles())]
    triangles: Option<usize>,
    /// Stop after this many frames, 1 to 10¹² (default: at the end of the source, never for `sim`).
    #[arg(long, value_parser = ranges::whole("a number of frames", 1, 1_000_000_000_000))]
    frames: Option<usize>,
    /// Frames averaged into the reference, 1–10,000, counted in frames imaged (with
    /// `--average N`, N times as many are taken); with two or more, each channel's noise is
    /// measured from them (and then from every frame without a touch).
    #[arg(long, default_value_t = 10, value_parser = ranges::whole("a number of reference frames", 1, 10_000))]
    reference_frames: usize,
    /// Frames imaged the reference grows to, 1–1,000,000: each frame without a touch joins the
    /// reference's mean until it holds this many (its noise is in every Δv); at or below
    /// `--reference-frames` it stays as taken.
    #[arg(long, default_value_t = 100, value_parser = ranges::whole("a number of reference frames", 1, 1_000_000))]
    reference_limit: usize,
    /// False touches allowed per frame without a touch, in (0, 0.5]: a touch's peak must stand
    /// out from the measured noise by the z this rate calls for (about 4.6 at 0.001).
    #[arg(long, default_value = "0.001", value_parser = ranges::number("a false-alarm rate", "(0, 0.5]", "0.001", |r| r > 0.0 && r <= 0.5))]
    false_alarm_rate: f64,
    /// Image the mean of the last N frames, 1–1000: the noise falls by √N, and a change shows
    /// (N − 1)/2 frames late on average.
    #[arg(long, default_value_t = 1, value_parser = ranges::whole("a number of frames", 1, 1000))]
    average: usize,
    /// Whose peak a touch's 60 % threshold is a fraction of: `frame` (the strongest touch's, the
    /// paper's rule) or `touch` (each touch's own, from each local maximum that passes the noise
    /// test: a weak press beside a strong one is found, but so is a strong press's side lobe).
    #[arg(long, default_value = "frame", value_parser = clap::builder::TypedValueParser::map(clap::builder::PossibleValuesParser::new(["frame", "touch"]),
        |name: String| if name == "touch" { PeakOf::Touch } else { PeakOf::Frame }))]
    peak_of: PeakOf,
    /// Baseline update weight per frame without a touch, in [0, 1] (0 = off, 1 = the last
    /// untouched frame is the reference).
    #[arg(long, default_value_t = 0.0, value_parser = ranges::number("a baseline rate", "[0, 1]", "0.01", |r| (0.0..=1.0).contains(&r)))]
    baseline_rate: f64,
    /// A calibration (JSON, from `eitskin calibrate`): forces in N per touch.
    #[arg(long)]
    calibration: Option<PathBuf>,
    /// With the virtual sensor (`--source sim`): calibrate it first as a user calibrates a board
    /// (the paper's protocol, six unit centres at 0–15 N, one frame each, through `calibrate`'s
    /// path, the fitted press's drop on the 5×5 pseudo-array), then read forces with it.
    #[arg(long, conflicts_with = "calibration")]
    virtual_calibration: bool,
    /// A learned model (JSON, from `eitskin learn`): each frame with a touch also gets the model's
    /// position, force and uncertainty from its Δv (`learned` in the line).
    #[arg(long)]
    model: Option<PathBuf>,
    /// Fit a press to Δv from each touch: its centre and conductivity drop (on by itself with a
    /// fitted-drop calibration).
    #[arg(long)]
    fit: bool,
    /// Find the presses in Δv afresh in every frame, instead of carrying those of the last frame
    /// by one step while they explain it (a press held costs microseconds, not milliseconds).
    #[arg(long)]
    fresh_presses: bool,
    /// Seed of the virtual sensor's noise and random presses, 0 to 2⁶⁴ − 1.
    #[arg(long, default_value_t = 1, value_parser = ranges::seed)]
    seed: u64,
    /// How a serial board (or a capture file of its bytes) encodes frames: `lines` (text) or
    /// `binary` (framed, with counter and CRC).
    #[arg(long, default_value_t = Codec::Lines)]
    codec: Codec,
    /// Record every frame and its touches to this file (append-only JSON lines, crash-safe).
    #[arg(long, value_parser = outputs::writes(&["jsonl", "ndjson"]))]
    record: Option<PathBuf>,
    /// Serve a live web page (image, 3-D view, touches, forces, counters) at ADDR (`HOST:PORT` or
    /// `PORT`; port 0: any free one); 127.0.0.1:8765 without a value.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = viewer::DEFAULT_ADDR,
          value_parser = viewer::parse_addr)]
    viewer: Option<SocketAddr>,
    /// Hyperparameter λ of the one-step Gauss–Newton reconstruction, in (0, 1000], or `auto`:
    /// the larger of the λ for a noise figure of 0.5 (EIDORS') and the MAP λ of the noise level,
    /// with the noise measured from the reference frames (each time the reference is taken).
    /// Default: `auto`, or with --calibration the λ the calibration was fitted with (another is
    /// refused).
    #[arg(long, value_name = "auto|λ")]
    hyperparameter: Option<imaging::HyperparameterFlag>,
    /// Normalised differences Δv/v_ref (immune to per-channel gains) instead of absolute ones;
    /// a channel whose reference is zero (dead) is dropped. With --calibration, as it was fitted.
    #[arg(long)]
    normalised: bool,
    /// Which changes are touches: `decrease` (a press on a hydrogel), `increase`, or `both`
    /// (each touch then says its `sign`).
    #[arg(long, default_value = "decrease")]
    polarity: Polarity,
    /// Add each imaged frame's raster to its JSON line (`raster`: nx, ny, bounds in the spec's
    /// unit, Δσ in S/m row by row from the top, null outside the outline): about 4,000 numbers a
    /// frame at 64 × 64, some 60 kB a line.
    #[arg(long)]
    stream_image: bool,
    /// What a board's numbers are: `signed` values, `magnitude`s (signed by the model), or
    /// `complex` (re, im) pairs, two numbers per measurement, imaged through --component.
    #[arg(long, value_enum, default_value_t = crate::imaging::ValuesFlag::Signed)]
    values: crate::imaging::ValuesFlag,
    /// For complex values, the part imaged: real, imaginary, magnitude (signed by the model) or phase.
    #[arg(long, default_value = "real")]
    component: Component,
}

/// Refuses a recording path before any work: one that exists (a recording is never written
/// over), whose folder does not exist, or that is one of the files read.
fn check_record(path: &Path, args: &Args) -> Result<()> {
    if path.exists() {
        bail!(
            "--record {}: the file exists; record into another file (a recording is never written over)",
            path.display()
        );
    }
    let mut read = Vec::new();
    read.extend(args.spec.as_deref().map(|p| ("the spec", p)));
    read.extend(args.calibration.as_deref().map(|p| ("--calibration", p)));
    read.extend(args.model.as_deref().map(|p| ("--model", p)));
    match &args.source {
        SourceSpec::File(p) => read.push(("--source", p.as_path())),
        SourceSpec::Sim { script: Some(p) } => read.push(("--source", p.as_path())),
        _ => {}
    }
    outputs::check(&[("--record", path)], &read)
}

/// The virtual sensor's calibration, made now as `calibrate` makes one from a board's presses
/// (frames drawn with another seed than the run's), and what to call it in messages.
fn virtual_calibration(spec: &SensorSpec, args: &Args) -> Result<(PathBuf, eitskin_io::CalibrationFile)> {
    if !matches!(args.source, SourceSpec::Sim { .. }) {
        bail!("--virtual-calibration calibrates the virtual sensor: it goes with --source sim");
    }
    eprintln!(
        "eitskin run: calibrating the virtual sensor as the paper does (six unit centres, 0–15 N, one frame each)…"
    );
    let started = std::time::Instant::now();
    let strength = Strength::FittedDrop;
    let chain = load::chain("run", spec, &ReconstructorParams::default(), TouchParams::default(), strength, false)?;
    let array = PseudoArray::by_symmetry(&spec.outline, &spec.electrode_positions()?, [5, 5])?;
    let sim = eitskin::sim::SimParams::default();
    let seed = args.seed ^ 0x00ca_11b0;
    let (calibration, found) = eitskin::study::users::calibrate_virtual(spec, sim, seed, chain, &array, 20)?;
    eprintln!(
        "eitskin run: {:.0} % of the calibration presses found, {} curves of the fitted drop ({:.1} s)",
        100.0 * found,
        calibration.curves.len(),
        started.elapsed().as_secs_f64()
    );
    let imaging = eitskin_io::Imaging::default();
    Ok((PathBuf::from("of the virtual sensor"), eitskin_io::CalibrationFile { array, calibration, imaging }))
}

/// Runs `eitskin run`.
pub fn run(args: Args) -> Result<()> {
    if let Some(path) = &args.record {
        check_record(path, &args)?;
    }
    let spec = load::sized(load::spec(args.spec.as_deref())?, args.triangles, Stage::Reconstructor)?;
    let calibration = match &args.calibration {
        Some(path) => Some((path.clone(), eitskin_io::read_calibration_file(path, &spec)?)),
        None if args.virtual_calibration => Some(virtual_calibration(&spec, &args)?),
        None => None,
    };
    // A learned model of this sensor's frames, trained again from its presses: another
    // protocol's or channel count's is refused before any work.
    let mut learned = match &args.model {
        Some(path) => {
            let cache = eitskin_io::build::cache_dir();
            let model = eitskin_io::read_learned_model(path, &spec, spec.protocol()?.len(), cache.as_deref())?;
            eprintln!("eitskin run: learned model {} ({})", path.display(), model.method.name());
            Some(learned::LearnedAnswers::new(model))
        }
        None => None,
    };
    let imaging = imaging::resolve(
        args.hyperparameter.as_ref(),
        args.normalised,
        calibration.as_ref().map(|(path, file)| (path.as_path(), file.imaging)),
    )?;
    let recon_params = ReconstructorParams {
        hyperparameter: match imaging.hyperparameter {
            Hyperparameter::Fixed(value) => value,
            // Chosen once the reference frames are in; until then, the paper's.
            Hyperparameter::Auto => ReconstructorParams::default().hyperparameter,
        },
        normalised: imaging.normalised,
        ..ReconstructorParams::default()
    };
    let touch = TouchParams { polarity: args.polarity, peak_of: args.peak_of, ..TouchParams::default() };
    let chain = match calibration {
        Some((path, file)) => {
            let strength = file.calibration.strength;
            eprintln!(
                "eitskin run: λ = {}, {} differences, as the calibration {} was fitted",
                file.imaging.hyperparameter,
                if file.imaging.normalised { "normalised" } else { "absolute" },
                path.display()
            );
            load::chain("run", &spec, &recon_params, touch, strength, args.fit)?
                .with_calibration(file.array, file.calibration)?
        }
        None => load::chain("run", &spec, &recon_params, touch, Strength::Peak, args.fit)?,
    };
    let params = PipelineParams {
        reference_frames: args.reference_frames,
        reference_limit: args.reference_limit,
        baseline_rate: args.baseline_rate,
        auto_hyperparameter: imaging.hyperparameter == Hyperparameter::Auto,
        noise_floor: NoiseFloor::FalseAlarm { rate: args.false_alarm_rate },
        average: args.average,
        carry_presses: !args.fresh_presses,
    };
    let mut pipeline = Pipeline::new(chain, params);
    if args.average > 1 {
        let frames = pipeline.latency_frames();
        let at = if args.rate > 0.0 {
            format!(" ({:.0} ms at {} frames/s)", 1e3 * frames / args.rate, args.rate)
        } else {
            String::new()
        };
        eprintln!(
            "eitskin run: averaging {} frames delays a change by {frames} frames on average{at}; the reference takes {} frames",
            args.average,
            params.frames_in_reference()
        );
    }
    let kind = args.values.kind(args.component);
    // The signed frame the pipeline takes, from what the board sends (allocated once).
    let model = pipeline.chain().reconstructor().linearisation().background().to_vec();
    let mut signed = vec![0.0; model.len()];
    let protocol = spec.protocol()?;
    let mut recorder = match &args.record {
        // As the board sent them: complex pairs are two numbers per measurement.
        Some(path) => {
            let numbers = protocol.len() * kind.per_measurement();
            Some(Recorder::create(path, &Header::now(numbers, protocol.description()))?)
        }
        None => None,
    };
    let metres = spec.length_unit.metres();
    let viewer = match args.viewer {
        Some(addr) => {
            let viewer = Viewer::start(addr, &viewer_setup(&spec, &pipeline, metres)?)?;
            eprintln!("eitskin run: viewer at http://{}/", viewer.addr());
            Some(viewer)
        }
        None => None,
    };
    let settings = SourceSettings {
        rate: args.rate,
        speed: if args.fast || args.rate <= 0.0 { Speed::AsFastAsPossible } else { Speed::Recorded },
        frames: args.frames.map(|n| n as u64),
        codec: args.codec,
        seed: args.seed,
        values_per_measurement: kind.per_measurement(),
    };
    let (items, acquisition) = start(Source::open(&args.source, &spec, &settings)?);
    eprintln!("eitskin run: reading {}", args.source);
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    let mut start =
        Start::new(args.source.to_string(), spec.length_unit.symbol(), protocol.len(), params.frames_in_reference());
    start.reference_limit = Some(params.reference_limit_frames());
    start.normalised = imaging.normalised;
    start.polarity = args.polarity.name().to_owned();
    start.average = args.average;
    start.peak_of = args.peak_of.name().to_owned();
    start.false_alarm_rate = Some(args.false_alarm_rate);
    // A closed stdout (the reader went away) ends the run, here and at every line below.
    if print(&mut out, &Event::Start(start)).is_err() {
        return Ok(());
    }
    let mut line = FrameLine::default();
    let (mut frames, mut bad) = (0u64, 0u64);
    loop {
        let item = match items.try_recv() {
            Ok(item) => item,
            // Nothing waiting: the lines written go out now, so that a reader sees each frame
            // as it comes; while frames queue up (a replay), they go out in larger writes.
            Err(mpsc::TryRecvError::Empty) => match out.flush().map(|()| items.recv()) {
                Ok(Ok(item)) => item,
                Ok(Err(_)) => break,
                Err(_) => return Ok(()),
            },
            Err(mpsc::TryRecvError::Disconnected) => break,
        };
        for command in viewer.iter().flat_map(Viewer::commands) {
            let event = match command {
                viewer::Command::RetakeReference => {
                    pipeline.retake_reference();
                    Event::Reference { detail: "re-taking the reference, as the viewer asked".into() }
                }
            };
            viewer.iter().for_each(|v| v.offer_event(&event));
            if print(&mut out, &event).is_err() {
                return Ok(());
            }
        }
        let printed = match item? {
            Acquired::Frame { seq, t, values } => match signed_frame(kind, &values, &model, &mut signed)
                .and_then(|frame| pipeline.process(frame).map(|status| (status, frame)))
            {
                Err(e) => {
                    if let eitskin::InverseError::TooManyBadChannels { .. } = e {
                        eprintln!("warning: frame {seq}: {e}");
                    }
                    bad += 1;
                    let event = Event::Bad { seq: Some(seq), reason: e.to_string() };
                    viewer.iter().for_each(|v| v.offer_event(&event));
                    print(&mut out, &event)
                }
                Ok((status, frame)) => {
                    if let Some(event) = channel_event(seq, status, &pipeline, imaging.hyperparameter) {
                        viewer.iter().for_each(|v| v.offer_event(&event));
                        if print(&mut out, &event).is_err() {
                            return Ok(());
                        }
                    }
                    frames += 1;
                    let counters = Counters { frames, bad, viewer_dropped: viewer.as_ref().map(Viewer::dropped) };
                    fill_frame_line(&mut line, seq, t, status, &pipeline, metres, counters);
                    set_raster(&mut line, args.stream_image && status.imaged(), &pipeline, metres);
                    line.learned = learned.as_mut().and_then(|l| l.answer(frame, &pipeline, metres));
                    if let Some(viewer) = &viewer {
                        let referencing = match status {
                            Status::Referencing { collected, needed } => Some([collected, needed]),
                            Status::Processed | Status::ChannelsDropped { .. } | Status::NoiseUpdated => None,
                        };
                        let image = &pipeline.image().values;
                        viewer.offer_frame(&viewer::Frame { line: &line, referencing, image });
                    }
                    if let Some(recorder) = recorder.as_mut() {
                        // Written and flushed before the line is printed: what is printed as
                        // recorded survives a crash of this process.
                        recorder.record_with(seq, t, &values, &Recorded { touches: Cow::Borrowed(&line.touches) })?;
                        line.recorded = true;
                    }
                    print(&mut out, &line)
                }
            },
            other => {
                if matches!(other, Acquired::Bad(_) | Acquired::Skipped { .. }) {
                    bad += 1;
                }
                // Only frames have no event line, and this is not one.
                let Some(event) = Event::of(&other) else { continue };
                viewer.iter().for_each(|v| v.offer_event(&event));
                print(&mut out, &event)
            }
        };
        if printed.is_err() {
            return Ok(());
        }
    }
    if out.flush().is_err() {
        return Ok(());
    }
    // The source ended: its thread has returned, or panicked.
    if acquisition.join().is_err() {
        bail!("the acquisition thread panicked");
    }
    // An end before anything was imaged is said, not left to an empty stream.
    if frames == 0 {
        bail!("{}: the source ended without a frame ({bad} bad or skipped)", args.source);
    }
    if pipeline.reference().is_none() {
        eprintln!(
            "warning: {}: the source ended after {frames} frames, before the reference ({} frames) was taken: nothing was imaged",
            args.source,
            params.frames_in_reference()
        );
    }
    Ok(())
}

/// The signed frame of what a board sent (`kind`), in `signed` unless it already is one; a
/// frame of the wrong length is refused.
fn signed_frame<'a>(
    kind: ValueKind,
    values: &'a [f64],
    model: &[f64],
    signed: &'a mut [f64],
) -> Result<&'a [f64], eitskin::InverseError> {
    if kind == ValueKind::Signed {
        return Ok(values);
    }
    let expected = signed.len() * kind.per_measurement();
    if values.len() != expected {
        return Err(eitskin::InverseError::FrameLength { expected, got: values.len() });
    }
    kind.signed_into(values, model, signed);
    Ok(signed)
}

/// The event a frame's status calls for, also said on stderr: the reference taken (with λ and
/// the channels left out), or channels dropped; `None` for any other frame.
fn channel_event(seq: u64, status: Status, pipeline: &Pipeline, hyperparameter: Hyperparameter) -> Option<Event> {
    let one_based = |channels: &[usize]| channels.iter().map(|m| m + 1).collect::<Vec<usize>>();
    match status {
        Status::Referencing { collected, needed } if collected == needed => {
            let lambda = pipeline.hyperparameter();
            let chosen = hyperparameter == Hyperparameter::Auto;
            let normalised = pipeline.chain().reconstructor().params().normalised;
            let dropped = one_based(&pipeline.dropped_channels());
            let how =
                if chosen { format!(" (chosen from the noise of {needed} reference frames)") } else { String::new() };
            let left_out = if dropped.is_empty() {
                String::new()
            } else {
                format!("; channels {dropped:?} left out (missing from a reference frame, or a zero reference)")
            };
            let (threshold, noise) = noise_figures(pipeline);
            let measured = pipeline.noise_measured();
            let test = match threshold {
                Some(z) => format!(
                    "; noise {:.3} % per value ({}), a touch needs z ≥ {z:.2}",
                    100.0 * noise,
                    if measured { "measured" } else { "assumed: one reference frame" }
                ),
                None => String::new(),
            };
            let detail = format!("reference taken; λ = {lambda:.4}{how}{left_out}{test}");
            eprintln!("eitskin run: {detail}");
            Some(Event::ReferenceTaken {
                hyperparameter: lambda,
                chosen,
                normalised,
                channels_dropped: dropped,
                threshold,
                noise: Some(noise),
                noise_measured: measured,
                image_noise: pipeline.significance().map(|s| s.typical_std()),
                detail,
            })
        }
        Status::NoiseUpdated => {
            let (threshold, noise) = noise_figures(pipeline);
            let frames = pipeline.noise().map_or(0.0, |n| n.frames());
            let reference = pipeline.noise().map_or(0, |n| n.reference_frames());
            let lambda = pipeline.hyperparameter();
            let z = threshold.map_or(String::new(), |z| format!(", a touch needs z ≥ {z:.2}"));
            let detail = format!(
                "noise measured on {frames:.0} frames, reference the mean of {reference}: {:.3} % per value; λ = {lambda:.4}{z}",
                100.0 * noise
            );
            eprintln!("eitskin run: {detail}");
            let image_noise = pipeline.significance().map(|s| s.typical_std());
            Some(Event::NoiseUpdated { seq, frames, hyperparameter: lambda, threshold, noise, image_noise, detail })
        }
        Status::ChannelsDropped { .. } => {
            let channels = one_based(pipeline.newly_dropped());
            let dropped = pipeline.dropped_channels().len();
            let detail = format!(
                "channel(s) {channels:?} went bad (not finite) and are dropped until the reference is \
                 re-taken ({dropped} dropped in all); imaging goes on without them"
            );
            eprintln!("warning: frame {seq}: {detail}");
            Some(Event::ChannelsDropped { seq, channels, dropped, detail })
        }
        _ => None,
    }
}

/// The threshold z of the pipeline's noise test (if any) and the median channel's relative noise.
fn noise_figures(pipeline: &Pipeline) -> (Option<f64>, f64) {
    let threshold = pipeline.significance().map(|s| s.threshold());
    let mut relative: Vec<f64> = pipeline.noise().map_or(Vec::new(), |n| n.relative_variance());
    relative.retain(|v| v.is_finite());
    relative.sort_by(f64::total_cmp);
    (threshold, relative.get(relative.len() / 2).map_or(0.0, |v| v.sqrt()))
}

/// Puts the pipeline's image into `line` (in units of `metres` m) when `on`, reusing its memory;
/// takes it out otherwise.
fn set_raster(line: &mut FrameLine, on: bool, pipeline: &Pipeline, metres: f64) {
    match (on, &mut line.raster) {
        (false, raster) => *raster = None,
        (true, Some(raster)) => raster.set(pipeline.image(), metres),
        (true, raster) => {
            let mut new = Raster::default();
            new.set(pipeline.image(), metres);
            *raster = Some(new);
        }
    }
}

/// Writes one line of the stream; the loop flushes whenever no frame is waiting.
fn print(out: &mut impl Write, line: &impl serde::Serialize) -> std::io::Result<()> {
    stream::write_line(out, line)
}

/// Reads `source` on a thread of its own, handing what it yields over a channel: one without a
/// bound for a live source, so that it never waits for processing; a bounded one otherwise,
/// which the reader refills after a short sleep when it is full rather than blocking on it: a
/// blocked sender is woken by every item taken, two context switches a frame (8 µs of a
/// replay's 48 µs here).
fn start(source: Source) -> (mpsc::Receiver<Result<Acquired, SourceError>>, std::thread::JoinHandle<()>) {
    fn pump(source: Source, mut send: impl FnMut(Result<Acquired, SourceError>) -> bool) {
        for item in source {
            if !send(item) {
                break;
            }
        }
    }
    if source.is_live() {
        let (tx, rx) = mpsc::channel();
        (rx, std::thread::spawn(move || pump(source, |item| tx.send(item).is_ok())))
    } else {
        let (tx, rx) = mpsc::sync_channel(QUEUE_ITEMS);
        let send = move |mut item| loop {
            match tx.try_send(item) {
                Ok(()) => return true,
                Err(mpsc::TrySendError::Full(back)) => {
                    item = back;
                    std::thread::sleep(QUEUE_WAIT);
                }
                Err(mpsc::TrySendError::Disconnected(_)) => return false,
            }
        };
        (rx, std::thread::spawn(move || pump(source, send)))
    }
}

/// Fills `line` with a processed frame: its status, the pipeline's touches (positions in units of
/// `metres` m; unit and area from 1; force in N; the fitted press or null) and `counters`; not
/// recorded (yet).
pub(crate) fn fill_frame_line(
    line: &mut FrameLine,
    seq: u64,
    t: f64,
    status: Status,
    pipeline: &Pipeline,
    metres: f64,
    counters: Counters,
) {
    line.seq = seq;
    line.t = t;
    line.status = status.into();
    line.set_touches(pipeline.touches(), metres);
    line.counters = counters;
    line.recorded = false;
}

/// What the viewer's page needs to draw frames, in the spec's units (`metres` m each): the calibration's
/// pseudo-array, or 5 × 5 units over the outline's box without one.
fn viewer_setup(spec: &SensorSpec, pipeline: &Pipeline, metres: f64) -> Result<viewer::Setup> {
    let scale = |p: [f64; 2]| [p[0] / metres, p[1] / metres];
    let default_array;
    let array = match pipeline.pseudo_array() {
        Some(array) => array,
        None => {
            default_array = PseudoArray::one_area_per_unit(spec.outline.bounds(), [5, 5])?;
            &default_array
        }
    };
    let image = pipeline.image();
    let [lo, hi] = image.bounds;
    let [glo, ghi] = array.bounds();
    Ok(viewer::Setup {
        unit: spec.length_unit.symbol(),
        image_size: image.size,
        image_bounds: [scale(lo), scale(hi)],
        inside: image.inside.clone(),
        outline: spec.outline.corners().into_iter().map(scale).collect(),
        electrodes: spec.electrode_positions()?.iter().map(|e| scale(spec.outline.point_at(e.centre))).collect(),
        grid: array.grid(),
        grid_bounds: [scale(glo), scale(ghi)],
        areas: (0..array.unit_count()).map(|u| array.area_of(u) + 1).collect(),
        calibrated: pipeline.pseudo_array().is_some(),
        colours: &eitskin::colour::COLOUR_STOPS,
    })
}
