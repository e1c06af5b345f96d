//! `eitskin run`: a live sensor, as a loop of a source, the pipeline and sinks. Frames come
//! from a source of [`eitskin_io::source`] (the virtual sensor, a file, a serial port); each goes
//! through the pipeline (reference, image, touches, forces) and out to every sink of [`sink`]:
//! the recording, the web viewer, and stdout's JSON lines of the [`eitskin_io::stream`] schema,
//! after a start line that gives its version and length unit.
//!
//! - [`setup`] builds the pipeline from the flags (calibration, learned model, imaging, chain).
//! - [`acquire`] reads the source on its own thread, a plain loop, and hands items over a
//!   channel: without a bound for a live source (a serial port, whose input is lost if not read
//!   in time), so that a slow consumer never stalls it; bounded for the others (files, the
//!   virtual sensor), which then wait, so that memory stays flat however long the file.
//! - [`process`] takes each item through the pipeline to the sinks, in their order: the
//!   recording first (a frame is on disk before anything shows it), then the viewer (offered
//!   without waiting, see [`crate::viewer`]; its requests, re-take the reference, are taken
//!   between items), then stdout.
//!
//! Imaging: λ is chosen from the reference frames' noise unless given (`--hyperparameter`), or
//! taken from the calibration, which fixes λ and the normalisation it was fitted with (see
//! [`imaging`]). A channel that goes bad (not finite) is dropped and named on stderr and in a
//! `channels_dropped` event, until the reference is re-taken; see [`eitskin::pipeline`].

pub(crate) mod acquire;
mod events;
mod imaging;
mod learned;
mod process;
pub(crate) mod publish;
mod setup;
pub(crate) mod sink;

use std::net::SocketAddr;
use std::path::{Path, PathBuf};

use anyhow::{bail, Result};
use eitskin::memory::Stage;
use eitskin::pipeline::{self, Pipeline, PipelineParams};
use eitskin::touch::{PeakOf, Polarity};
use eitskin::values::{Component, ValueKind};
use eitskin::SensorSpec;
use eitskin_io::replay::Speed;
use eitskin_io::source::{Codec, Source, SourceSettings, SourceSpec};
use eitskin_io::stream::Start;

pub(crate) use process::fill_frame_line;
pub(crate) use process::{Drained, Processing, Tally};
pub(crate) use setup::{choose_precision, Precision, PressTable};
use sink::{to_all, Flow, Lines, Recording, Sink, Viewing};

use crate::{load, outputs, ranges, viewer};

/// Flags of `eitskin run`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Sensor spec file (TOML); default: the paper's sensor.
    spec: Option<PathBuf>,
    /// Where frames come from: `sim` (the virtual sensor, pressed at random), `sim:SCRIPT` (pressed
    /// as a script of `start end x y force` lines says), `file:PATH` (a recording made with
    /// --record, replayed at its pace, or a capture of a board's bytes, decoded with --codec, at
    /// --rate), or `serial:PATH[@BAUD]` (a board on a serial port, 8N1 at 115200 bit/s unless told,
    /// e.g. serial:/dev/ttyACM0@921600; frames decoded with --codec), or `zenoh:KEY` (frames a
    /// board's bridge publishes on Zenoh: {"seq", "t_s", "values"} in JSON or CBOR; see --connect).
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
    #[arg(long, default_value_t = 10, value_parser = ranges::within("a number of reference frames", pipeline::REFERENCE_FRAMES))]
    reference_frames: usize,
    /// Frames imaged the reference grows to, 1–1,000,000: each frame without a touch joins the
    /// reference's mean until it holds this many (its noise is in every Δv); at or below
    /// `--reference-frames` it stays as taken.
    #[arg(long, default_value_t = 100, value_parser = ranges::within("a number of reference frames", pipeline::REFERENCE_LIMIT))]
    reference_limit: usize,
    /// False touches allowed per frame without a touch, in (0, 0.5]: a touch's peak must stand
    /// out from the measured noise by the z this rate calls for (about 4.6 at 0.001).
    #[arg(long, default_value = "0.001", value_parser = ranges::number("a false-alarm rate", "(0, 0.5]", "0.001", pipeline::false_alarm_rate_ok))]
    false_alarm_rate: f64,
    /// Image the mean of the last N frames, 1–1000: the noise falls by √N, and a change shows
    /// (N − 1)/2 frames late on average.
    #[arg(long, default_value_t = 1, value_parser = ranges::within("a number of frames", pipeline::AVERAGE))]
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
    /// on a model of them while they explain it (a press held costs microseconds, not milliseconds).
    #[arg(long)]
    fresh_presses: bool,
    /// What one press's exact response, tabulated over the sheet at setup (about 0.36 s on two
    /// cores and 41 MiB on the paper's sheet), is used for in fitting presses (with --fit or a
    /// fitted-drop calibration): `auto` fits on it while the presses are of the indenter's size
    /// and at least five indenter radii apart (no exact solve), and exactly from there
    /// once a press's size is in question or two come closer; `fit` fits on it throughout; `start`
    /// starts each exact fit of presses five radii apart from it; `off` tabulates nothing.
    #[arg(long, value_enum, value_name = "USE", default_value_t = PressTable::Auto)]
    press_table: PressTable,
    /// The precision each frame's image is computed from: `half` reads a binary16 copy of the
    /// reconstruction matrix (half the memory a frame reads, each pixel within 2⁻¹¹ times the sum
    /// of its terms' magnitudes), `single` the matrix itself; `auto` takes half where the
    /// matrices the process reads every frame (all of `serve`'s sensors') overflow the
    /// processor's last-level cache, and there `serve`'s sensors of one spec image through the
    /// basis they share once each one's λ is chosen from its noise.
    #[arg(long, value_enum, default_value_t = Precision::Auto)]
    precision: Precision,
    /// Seed of the virtual sensor's noise and random presses, 0 to 2⁶⁴ − 1.
    #[arg(long, default_value_t = 1, value_parser = ranges::seed)]
    seed: u64,
    /// The virtual sensor's measurement noise, a relative standard deviation per value and
    /// frame in [0, 0.1]: 1e-4 (0.01 %) is a best case; open boards vary 0.003–0.005.
    #[arg(long, default_value_t = 1e-4, value_parser = ranges::number("a relative noise", "[0, 0.1]", "0.004", |n| (0.0..=0.1).contains(&n)))]
    noise: f64,
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
    /// Hyperparameter λ of the one-step Gauss–Newton reconstruction, in [1e-6, 1000], or `auto`:
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
    #[command(flatten)]
    pub(crate) zenoh: publish::ZenohArgs,
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

/// Runs `eitskin run`: the source opened, the pipeline built, the sinks (recording, viewer,
/// stdout's lines) started, then every item through them until the source ends.
pub fn run(args: Args) -> Result<()> {
    let zenoh = check(&args)?;
    let Sensor { spec, mut processing, start, params } = prepare(&args)?;
    choose_precision("run", &mut [(args.precision, &mut processing.pipeline)]);
    let session = if zenoh { Some(args.zenoh.open()?) } else { None };
    let source = open_source(&args, &spec, processing.kind(), session.as_ref())?;
    let mut sinks = sinks(&args, &spec, &processing.pipeline, processing.kind(), session.as_ref())?;
    sinks.push(Box::new(Lines::new(std::io::stdout())));
    let (items, acquisition) = acquire::start(source);
    eprintln!("eitskin run: reading {}", args.source);
    if to_all(&mut sinks, |s| s.start(&start))? == Flow::Stop {
        return Ok(());
    }
    let tally = processing.drive(&items, &mut sinks)?;
    if tally.stopped {
        return Ok(());
    }
    // The source ended: its thread has returned, or panicked.
    acquisition.finish()?;
    ended(&args, tally, &processing, &params)
}

impl Args {
    /// Whether the run's results go anywhere but stdout: published, or recorded.
    pub(crate) fn publishes(&self) -> bool {
        self.zenoh.publishes() || self.record.is_some()
    }

    /// The precision its frames are imaged in, as asked.
    pub(crate) fn precision(&self) -> Precision {
        self.precision
    }

    /// The recording's path, if recording.
    pub(crate) fn record(&self) -> Option<&Path> {
        self.record.as_deref()
    }

    /// The viewer's address, if serving one.
    pub(crate) fn viewer(&self) -> Option<SocketAddr> {
        self.viewer
    }
}

/// Checks the flags before any work; whether a Zenoh session is needed.
pub(crate) fn check(args: &Args) -> Result<bool> {
    if let Some(path) = &args.record {
        check_record(path, args)?;
    }
    let zenoh = args.zenoh.check(&args.source)?;
    let reference_frames = args.reference_frames.saturating_mul(args.average);
    if let (Some(frames), None) = (args.frames, &args.record) {
        if frames <= reference_frames {
            bail!(
                "--frames {frames}: the run would end before its reference is taken (the first {reference_frames}: \
                 --reference-frames {} × --average {}), and image nothing; give more frames, or --record to record them",
                args.reference_frames,
                args.average
            );
        }
    }
    Ok(zenoh)
}

/// A sensor ready to run but for its source: its spec, its processing (the pipeline and a
/// frame's buffers) and the start line of its stream.
pub(crate) struct Sensor {
    /// The spec, sized as asked.
    pub spec: SensorSpec,
    /// Frames through the pipeline to the sinks.
    pub processing: Processing,
    /// The stream's first line.
    pub start: Start,
    /// The pipeline's settings.
    pub params: PipelineParams,
}

/// Builds everything `args` asks for but the source and the sinks: the spec, the pipeline, the
/// start line.
pub(crate) fn prepare(args: &Args) -> Result<Sensor> {
    let spec = load::sized(load::spec(args.spec.as_deref())?, args.triangles, Stage::Reconstructor)?;
    let setup::Built { pipeline, params, imaging, learned } = setup::build(args, &spec)?;
    crate::ranges::warn_raised_triangles(
        args.triangles,
        pipeline.chain().reconstructor().linearisation().mesh(),
        &spec,
    )?;
    let kind = args.values.kind(args.component);
    let start = start_line(args, &spec, spec.protocol()?.len(), &params, imaging.normalised);
    let settings = process::Settings {
        kind,
        metres: spec.length_unit.metres(),
        stream_image: args.stream_image,
        hyperparameter: imaging.hyperparameter,
        recorded: args.record.is_some(),
        masked: spec.used_channels()?.iter().enumerate().filter(|(_, used)| !**used).map(|(m, _)| m).collect(),
        say: true,
    };
    let processing = Processing::new(pipeline, learned, settings);
    Ok(Sensor { spec, processing, start, params })
}

/// How fast `args`'s source is read (a board or a bridge: as its frames come).
pub(crate) fn speed(args: &Args) -> Speed {
    if args.fast || args.rate <= 0.0 {
        Speed::AsFastAsPossible
    } else {
        Speed::Recorded
    }
}

/// Opens the source `args` names for frames of `spec` whose numbers are `kind` (frames from Zenoh
/// on `session`), not yet read.
pub(crate) fn open_source(
    args: &Args,
    spec: &SensorSpec,
    kind: ValueKind,
    session: Option<&eitskin_io::middleware::Session>,
) -> Result<Source> {
    let settings = SourceSettings {
        rate: args.rate,
        speed: speed(args),
        frames: args.frames.map(|n| n as u64),
        codec: args.codec,
        seed: args.seed,
        values_per_measurement: kind.per_measurement(),
        noise: args.noise,
    };
    Ok(match (&args.source, session) {
        (SourceSpec::Zenoh { key }, Some(session)) => {
            let measurements = spec.protocol()?.len() * kind.per_measurement();
            publish::source(session, key, measurements, settings.frames)?
        }
        _ => Source::open(&args.source, spec, &settings)?,
    })
}

/// What a source that ended without being stopped answered: an error when it gave no frame, or
/// ended before the reference was taken (unless it was recorded: the recording is the work).
pub(crate) fn ended(args: &Args, tally: Tally, processing: &Processing, params: &PipelineParams) -> Result<()> {
    let Tally { frames, bad, .. } = tally;
    // An end before anything was imaged is said, not left to an empty stream.
    if frames == 0 {
        bail!("{}: the source ended without a frame ({bad} bad or skipped)", args.source);
    }
    if !processing.pipeline.imaging() {
        let said = format!(
            "{}: the source ended after {frames} frames, before the reference ({} frames) was taken: nothing was imaged",
            args.source,
            params.frames_in_reference()
        );
        // A recording was the run's work, and is whole; without one, the run answered nothing.
        match &args.record {
            Some(path) => eprintln!("warning: {said} ({} holds the frames)", path.display()),
            None => bail!("{said}"),
        }
    }
    Ok(())
}

/// The run's sinks, in the order they take each frame: the recording (on disk before anything
/// shows it), the viewer, the Zenoh and ROS 2 publishers (stdout's lines go last, `run`'s own).
pub(crate) fn sinks(
    args: &Args,
    spec: &SensorSpec,
    pipeline: &Pipeline,
    kind: ValueKind,
    session: Option<&eitskin_io::middleware::Session>,
) -> Result<Vec<Box<dyn Sink>>> {
    let mut sinks: Vec<Box<dyn Sink>> = Vec::new();
    if let Some(path) = &args.record {
        // As the board sent them: complex pairs are two numbers per measurement.
        let protocol = spec.protocol()?;
        let numbers = protocol.len() * kind.per_measurement();
        sinks.push(Box::new(Recording::create(path, numbers, protocol.description())?));
    }
    if let Some(addr) = args.viewer {
        sinks.push(Box::new(Viewing::start(addr, spec, pipeline)?));
    }
    if let Some(publishing) = args.zenoh.sink(session, spec)? {
        sinks.push(Box::new(publishing));
    }
    Ok(sinks)
}

/// The stream's first line: the source, the unit, and the settings a reader needs.
fn start_line(args: &Args, spec: &SensorSpec, channels: usize, params: &PipelineParams, normalised: bool) -> Start {
    let mut start =
        Start::new(args.source.to_string(), spec.length_unit.symbol(), channels, params.frames_in_reference());
    start.reference_limit = Some(params.reference_limit_frames());
    start.normalised = normalised;
    start.polarity = args.polarity.name().to_owned();
    start.average = args.average;
    start.peak_of = args.peak_of.name().to_owned();
    start.false_alarm_rate = Some(args.false_alarm_rate);
    start
}
