//! `eitskin run`: a live sensor. Frames come from the virtual sensor, a file or a serial port;
//! each goes through the pipeline (reference, image, touches, forces) and out as one JSON line.
//!
//! Acquisition runs on its own thread and hands frames over an unbounded channel, so a slow
//! consumer never stalls it; processing writes every frame to the recorder before it prints.
//! With `--viewer`, processing also offers each frame to the web viewer without waiting (see
//! [`crate::viewer`]) and takes its commands (re-take the reference) between frames.

use std::io::Write;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use eitskin::calibration::Strength;
use eitskin::pipeline::{Pipeline, PipelineParams, Status};
use eitskin::pseudo_array::PseudoArray;
use eitskin::sim::{Script, VirtualSensor};
use eitskin::SensorSpec;
use eitskin_io::codec::{BinaryDecoder, Decoder, Event, LinesDecoder};
use eitskin_io::recorder::{Header, Recorder};
use eitskin_io::replay::{read_recording, Pace, Speed};
use eitskin_io::source::serial::{parse_serial_spec, SerialSource, SourceEvent};
use serde_json::json;

use crate::load;
use crate::viewer::{self, Viewer};

/// Flags of `eitskin run`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Sensor spec file (TOML); default: the paper's sensor.
    spec: Option<PathBuf>,
    /// Where frames come from: `sim[:SCRIPT]`, `file:PATH` (a recording, or one frame per text
    /// line), `serial:PATH[@BAUD]` (115200 8N1 unless told).
    #[arg(long, default_value = "sim")]
    source: String,
    /// Frames per second of the virtual sensor, or of a file without timestamps (0: as fast as possible).
    #[arg(long, default_value_t = 20.0)]
    rate: f64,
    /// Do not wait between frames (the virtual sensor's clock still advances at --rate).
    #[arg(long)]
    fast: bool,
    /// Mesh with about this many triangles instead of the spec's count.
    #[arg(long)]
    triangles: Option<usize>,
    /// Stop after this many frames (default: at the end of the source, never for `sim`).
    #[arg(long)]
    frames: Option<u64>,
    /// Frames averaged into the reference.
    #[arg(long, default_value_t = 10)]
    reference_frames: usize,
    /// Baseline update weight per frame without a touch (0 = off).
    #[arg(long, default_value_t = 0.0)]
    baseline_rate: f64,
    /// A calibration (JSON, from `eitskin calibrate`): forces in N per touch.
    #[arg(long)]
    calibration: Option<PathBuf>,
    /// Fit a press to Δv from each touch: its centre and conductivity drop (on by itself with a
    /// fitted-drop calibration).
    #[arg(long)]
    fit: bool,
    /// Seed of the virtual sensor's noise and random presses.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// How a serial board sends frames: `lines` (text) or `binary` (framed, with counter and CRC).
    #[arg(long, value_enum, default_value_t = Codec::Lines)]
    codec: Codec,
    /// Record every frame and its touches to this file (append-only JSON lines, crash-safe).
    #[arg(long)]
    record: Option<PathBuf>,
    /// Serve a live web page (image, 3-D view, touches, forces, counters) at ADDR (`HOST:PORT` or
    /// `PORT`; port 0: any free one); 127.0.0.1:8765 without a value.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = viewer::DEFAULT_ADDR,
          value_parser = viewer::parse_addr)]
    viewer: Option<SocketAddr>,
}

/// The frame codec of a serial source.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum Codec {
    /// One frame per text line of numbers.
    Lines,
    /// Sync bytes, counter, count, f32 values, CRC-16 (see the README).
    Binary,
}

/// One thing the acquisition thread saw.
enum Acquired {
    Frame { seq: u64, t: f64, values: Vec<f64> },
    Bad { seq: Option<u64>, reason: String },
    Port { event: &'static str, detail: String },
}

/// Runs `eitskin run`.
pub fn run(args: Args) -> Result<()> {
    let mut spec = load::spec(args.spec.as_deref())?;
    if let Some(n) = args.triangles {
        spec.mesh.triangles = n;
    }
    let chain = match &args.calibration {
        Some(path) => {
            let (array, calibration) = eitskin_io::read_calibration(path, &spec)?;
            load::chain(&spec, calibration.strength, args.fit)?.with_calibration(array, calibration)?
        }
        None => load::chain(&spec, Strength::Peak, args.fit)?,
    };
    let params = PipelineParams {
        reference_frames: args.reference_frames,
        baseline_rate: args.baseline_rate,
        ..PipelineParams::default()
    };
    let mut pipeline = Pipeline::new(chain, params);
    let protocol = spec.protocol()?;
    let mut recorder = match &args.record {
        Some(path) => Some(Recorder::create(path, &Header::now(protocol.len(), protocol.description()))?),
        None => None,
    };
    let k = 1.0 / spec.length_unit.metres();
    let viewer = match args.viewer {
        Some(addr) => {
            let viewer = Viewer::start(addr, &viewer_setup(&spec, &pipeline, k)?)?;
            eprintln!("eitskin run: viewer at http://{}/", viewer.addr());
            Some(viewer)
        }
        None => None,
    };
    let (tx, rx) = mpsc::channel();
    let acquisition = start_source(&args, &spec, tx)?;
    eprintln!("eitskin run: reading {}", args.source);
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    let (mut frames, mut bad) = (0u64, 0u64);
    for item in rx {
        for command in viewer.iter().flat_map(Viewer::commands) {
            let line = match command {
                viewer::Command::RetakeReference => {
                    pipeline.retake_reference();
                    json!({"event": "reference", "detail": "re-taking the reference, as the viewer asked"})
                }
            };
            // A closed stdout is noticed, and ends the run, when the frame's line is printed.
            let _ = writeln!(out, "{line}");
            viewer.iter().for_each(|v| v.offer_event(&line));
        }
        let line = match item {
            Acquired::Bad { seq, reason } => {
                bad += 1;
                json!({"event": "bad", "seq": seq, "reason": reason})
            }
            Acquired::Port { event, detail } => json!({"event": event, "detail": detail}),
            Acquired::Frame { seq, t, values } => match pipeline.process(&values) {
                Err(e) => {
                    bad += 1;
                    json!({"event": "bad", "seq": seq, "reason": e.to_string()})
                }
                Ok(status) => {
                    frames += 1;
                    let mut line = frame_json(seq, t, status, &pipeline, k, [frames, bad]);
                    if let Some(viewer) = &viewer {
                        let counters = viewer::Counters { frames, bad, viewer_dropped: viewer.dropped() };
                        line["counters"]["viewer_dropped"] = counters.viewer_dropped.into();
                        let referencing = match status {
                            Status::Referencing { collected, needed } => Some([collected, needed]),
                            Status::Processed => None,
                        };
                        viewer.offer_frame(&viewer::Frame {
                            seq,
                            t,
                            status: line["status"].as_str().unwrap_or_default(),
                            referencing,
                            touches: &line["touches"],
                            counters,
                            image: &pipeline.image().values,
                        });
                    }
                    if let Some(recorder) = recorder.as_mut() {
                        // Written and flushed before the line is printed: what is printed as
                        // recorded survives a crash of this process.
                        recorder.record(seq, t, &values, Some(&line["touches"]))?;
                        line["recorded"] = true.into();
                    }
                    line
                }
            },
        };
        if let (Some(viewer), Some(_)) = (&viewer, line.get("event")) {
            viewer.offer_event(&line);
        }
        // A closed stdout (the reader went away) ends the run.
        if writeln!(out, "{line}").and_then(|()| out.flush()).is_err() {
            break;
        }
    }
    drop(out);
    match acquisition.join() {
        Ok(result) => result,
        Err(_) => bail!("the acquisition thread panicked"),
    }
}

/// The JSON line of a processed frame: touches (positions times `k`, i.e. in the spec's units;
/// unit and area counted from 1; force in N; the fitted press's centre and drop, or null) and
/// the counters `[frames, bad]`.
pub fn frame_json(
    seq: u64,
    t: f64,
    status: Status,
    pipeline: &Pipeline,
    k: f64,
    counters: [u64; 2],
) -> serde_json::Value {
    let touches: Vec<_> = pipeline
        .touches()
        .iter()
        .map(|t| {
            json!({
                "x": t.touch.centre[0] * k,
                "y": t.touch.centre[1] * k,
                "peak": t.touch.peak,
                "unit": t.unit.map(|u| u + 1),
                "area": t.area.map(|a| a + 1),
                "force": t.force.map(|f| f.newtons),
                "saturated": t.force.map(|f| f.saturated),
                "press": t.press.map(|p| json!({"x": p.centre[0] * k, "y": p.centre[1] * k, "drop": p.drop})),
            })
        })
        .collect();
    let status = match status {
        Status::Referencing { .. } => "referencing",
        Status::Processed => "ok",
    };
    json!({"seq": seq, "t": t, "status": status, "touches": touches,
           "counters": {"frames": counters[0], "bad": counters[1]}})
}

/// What the viewer's page needs to draw frames, in the spec's units: the calibration's
/// pseudo-array, or 5 × 5 units over the outline's box without one.
fn viewer_setup(spec: &SensorSpec, pipeline: &Pipeline, k: f64) -> Result<viewer::Setup> {
    let scale = |p: [f64; 2]| [p[0] * k, p[1] * k];
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
    })
}

/// Starts the acquisition thread for `args.source`.
fn start_source(
    args: &Args,
    spec: &SensorSpec,
    tx: mpsc::Sender<Acquired>,
) -> Result<std::thread::JoinHandle<Result<()>>> {
    let limit = args.frames.unwrap_or(u64::MAX);
    let clock = (args.rate > 0.0).then(|| Duration::from_secs_f64(1.0 / args.rate));
    let period = clock.filter(|_| !args.fast);
    let measurements = spec.protocol()?.len();
    if args.source == "sim" || args.source.starts_with("sim:") {
        let script = match args.source.strip_prefix("sim:") {
            Some(path) => {
                let text = std::fs::read_to_string(path).with_context(|| format!("reading {path}"))?;
                Script::parse(&text, spec.length_unit.metres()).with_context(|| path.to_string())?
            }
            None => Script::random(&spec.outline, 2.0, 1800, args.seed),
        };
        let Some(clock) = clock else {
            bail!("--rate must be positive for the virtual sensor (use --fast not to wait)")
        };
        let mut skin = VirtualSensor::new(spec, args.seed)?;
        return Ok(std::thread::spawn(move || {
            let start = Instant::now();
            for seq in 0..limit {
                let t = seq as f64 * clock.as_secs_f64();
                skin.release();
                for press in script.at(t) {
                    skin.press(press.position, press.force);
                }
                let values = skin.frame()?;
                if tx.send(Acquired::Frame { seq, t, values }).is_err() {
                    break;
                }
                pace(start, period, seq + 1);
            }
            Ok(())
        }));
    }
    if let Some(path) = args.source.strip_prefix("file:") {
        let path = PathBuf::from(path);
        let text = std::fs::read(&path).with_context(|| format!("reading {}", path.display()))?;
        if text.starts_with(br#"{"format":"eitskin-recording""#) {
            let recording = read_recording(&path)?;
            if let Some(line) = recording.skipped.torn_tail {
                eprintln!("{}: the last record (line {line}) is torn and skipped", path.display());
            }
            for c in &recording.skipped.corrupt {
                eprintln!("{}: line {} is damaged and skipped: {:?}", path.display(), c.line, c.damage);
            }
            let speed = if args.fast || args.rate <= 0.0 { Speed::AsFastAsPossible } else { Speed::Recorded };
            return Ok(std::thread::spawn(move || {
                let mut pace = Pace::new(speed);
                let start = Instant::now();
                for record in recording.records.into_iter().take(limit.min(usize::MAX as u64) as usize) {
                    std::thread::sleep(pace.delay(record.t_s, start.elapsed()));
                    let item = Acquired::Frame { seq: record.seq, t: record.t_s, values: record.values };
                    if tx.send(item).is_err() {
                        break;
                    }
                }
                Ok(())
            }));
        }
        return Ok(std::thread::spawn(move || {
            let mut decoder = LinesDecoder::new(measurements);
            let mut events = Vec::new();
            decoder.feed(&text, &mut events);
            decoder.finish(&mut events);
            let start = Instant::now();
            let mut sent = 0u64;
            for event in events {
                if sent >= limit {
                    break;
                }
                let item = match event {
                    Event::Frame(f) => {
                        let t = clock.map_or(start.elapsed().as_secs_f64(), |p| sent as f64 * p.as_secs_f64());
                        sent += 1;
                        pace(start, period, sent);
                        Acquired::Frame { seq: f.seq, t, values: f.values }
                    }
                    Event::Bad(b) => Acquired::Bad { seq: b.seq(), reason: b.to_string() },
                };
                if tx.send(item).is_err() {
                    break;
                }
            }
            Ok(())
        }));
    }
    if args.source.starts_with("serial:") {
        let (path, baud) = parse_serial_spec(&args.source)?;
        let codec = args.codec;
        let decoder = move || -> Box<dyn Decoder + Send> {
            match codec {
                Codec::Lines => Box::new(LinesDecoder::new(measurements)),
                Codec::Binary => Box::new(BinaryDecoder::new(measurements)),
            }
        };
        let mut port = SerialSource::open(&path, baud, decoder)?;
        return Ok(std::thread::spawn(move || {
            let start = Instant::now();
            let mut events = Vec::new();
            let mut sent = 0u64;
            while sent < limit {
                events.clear();
                port.poll(&mut events);
                for event in events.drain(..) {
                    let item = match event {
                        SourceEvent::Frame { frame, received } => {
                            sent += 1;
                            let t = received.saturating_duration_since(start).as_secs_f64();
                            Acquired::Frame { seq: frame.seq, t, values: frame.values }
                        }
                        SourceEvent::Bad(b) => Acquired::Bad { seq: b.seq(), reason: b.to_string() },
                        SourceEvent::Disconnected { path, error } => Acquired::Port {
                            event: "disconnected",
                            detail: format!("{} disconnected ({error}); reopening", path.display()),
                        },
                        SourceEvent::Reconnected { path, outage } => Acquired::Port {
                            event: "reconnected",
                            detail: format!("{} is back after {:.2} s", path.display(), outage.as_secs_f64()),
                        },
                    };
                    if tx.send(item).is_err() {
                        return Ok(());
                    }
                }
            }
            Ok(())
        }));
    }
    bail!("--source {:?}: expected sim, sim:SCRIPT, file:PATH or serial:PATH[@BAUD]", args.source)
}

/// Sleeps until frame `next` is due at `period` per frame since `start` (no wait without a period).
fn pace(start: Instant, period: Option<Duration>, next: u64) {
    if let Some(p) = period {
        let due = start + p.mul_f64(next as f64);
        if let Some(wait) = due.checked_duration_since(Instant::now()) {
            std::thread::sleep(wait);
        }
    }
}
