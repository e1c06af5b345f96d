//! Frame sources: where frames come from — the virtual sensor, a file, a board on a serial
//! port — behind one interface.
//!
//! A [`SourceSpec`] names the source (parsed from `sim`, `sim:SCRIPT`, `file:PATH` or
//! `serial:PATH[@BAUD]`); [`Source::open`] opens it, checking up front what it can (the script
//! parses, the file opens and its kind is known, the port opens), and yields [`Acquired`] items
//! until the source ends or the frame limit is reached. A file is a recording (it starts with
//! `{`), a table of frames (MAT or NPY, read whole: a published data set's recording), or else a
//! capture of a board's bytes:
//!
//! * [`Acquired::Frame`]: a frame, with its sequence number, its time in s and its values;
//! * [`Acquired::Bad`]: input the codec refused ([`BadFrame`], with its place);
//! * [`Acquired::Skipped`]: a damaged record of a recording, with its line;
//! * [`Acquired::Disconnected`], [`Acquired::Reconnected`]: a serial port went away, or came back;
//! * [`Acquired::Silent`], [`Acquired::Resumed`]: a network source's frames stopped, or came again.
//!
//! ```
//! use eitskin_io::replay::Speed;
//! use eitskin_io::source::{Acquired, Source, SourceSettings};
//! let sensor = eitskin::SensorSpec::square_hydrogel();
//! let settings = SourceSettings { frames: Some(3), speed: Speed::AsFastAsPossible, ..SourceSettings::default() };
//! let source = Source::open(&"sim".parse()?, &sensor, &settings)?;
//! let mut times = Vec::new();
//! for item in source {
//!     if let Acquired::Frame { seq, t, values } = item? {
//!         assert_eq!((seq, values.len()), (times.len() as u64, 120));
//!         times.push(t);
//!     }
//! }
//! assert_eq!(times, [0.0, 0.05, 0.1]); // the virtual clock, at 20 frames/s by default
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Each source owns its pacing ([`SourceSettings::speed`]): the virtual sensor and a capture
//! file deliver frame k at k / [`rate`](SourceSettings::rate) s after the first, a recording
//! each frame as long after the first as it was recorded, a serial port as the board sends; as
//! fast as possible, nothing waits. A file is read as it is delivered, through a buffer, so
//! memory does not grow with its length.
//!
//! | kind           | type                   | frames                                           |
//! |----------------|------------------------|--------------------------------------------------|
//! | virtual sensor | [`SimSource`]          | a [`VirtualSensor`] pressed by a [`Script`]       |
//! | recording      | [`RecordingSource`]    | a file the [`Recorder`](crate::recorder::Recorder) wrote; skipped records are items |
//! | capture        | [`CaptureSource`]      | a file of the bytes a board sends, decoded by the [`Codec`] |
//! | serial port    | [`SerialSource`]       | a board, decoded by the [`Codec`], reopened after an unplug |
//!
//! A file whose first character (after white space) is `{` is a recording: its JSON header
//! says so, and a header that is not a recording's is an error, not frames. Anything else is a
//! capture. Text captures never start with `{`; a binary capture that does (1 chance in 256 if
//! it was cut mid-frame) must be trimmed to its first sync byte.
//!
//! Why a trait ([`FrameSource`]) and not an enum of the four: the processing loop needs only
//! "the next item", every source is a different state machine with nothing shared, and a
//! program that has frames from elsewhere (a network stream, a test's script) can put its own
//! source behind [`Source::new`] and keep the rest. One virtual call per item costs nothing
//! next to a frame's reconstruction.
//!
//! A source blocks while it waits for its next item. Read it on a thread of its own and hand
//! the items over a channel: a channel without a bound for a [live](Source::is_live) source
//! (a port whose input is lost if it is not read in time), so that a slow consumer never stalls
//! acquisition; a bounded one for the others, which then wait and keep memory flat.
//!
//! Not for: decoding bytes (that is [`codec`](crate::codec)) or reconstructing images from the
//! frames (that is `eitskin`).

mod error;
mod file;
pub mod serial;
mod sim;
mod spec;

use std::fmt;
use std::path::Path;
use std::time::{Duration, Instant};

use eitskin::sim::{Script, SimParams, VirtualSensor};
use eitskin::SensorSpec;

use crate::codec::{BadFrame, BinaryDecoder, Decoder, LinesDecoder};
use crate::replay::{Corrupt, Speed};

pub use error::SourceError;
pub use file::{CaptureSource, RecordingSource};
pub use serial::SerialSource;
pub use sim::SimSource;
pub use spec::SourceSpec;

/// The period of the virtual sensor's random presses, in s (each is held half of it).
pub const RANDOM_PRESS_PERIOD_S: f64 = 2.0;

/// The number of the virtual sensor's random presses (an hour's worth).
pub const RANDOM_PRESSES: usize = 1800;

/// One thing a source yields.
#[derive(Debug, Clone, PartialEq)]
pub enum Acquired {
    /// A frame.
    Frame {
        /// Its sequence number: the board's counter, the line count, or as recorded.
        seq: u64,
        /// When it came, in s: on the source's clock from its first frame (virtual sensor, capture at
        /// a rate), as recorded, or since the source was opened (serial port, capture without a rate).
        t: f64,
        /// The measurements, in protocol order (V or Ω, as the board sends).
        values: Vec<f64>,
    },
    /// Input the codec refused, and why; [`BadFrame::seq`] says where, if it belongs to a frame.
    Bad(BadFrame),
    /// A record of a recording that was damaged and skipped.
    Skipped {
        /// Its line (from 1, the header is line 1) and what is wrong with it.
        record: Corrupt,
        /// Whether it is the file's last record, torn by a crash while it was written.
        torn_tail: bool,
    },
    /// The serial port went away; the source tries to reopen it.
    Disconnected {
        /// The port, as named.
        path: std::path::PathBuf,
        /// Why it was given up, as the operating system said it.
        error: String,
    },
    /// The serial port is back; decoding starts again with a fresh decoder.
    Reconnected {
        /// The port, as named.
        path: std::path::PathBuf,
        /// How long it was away.
        outage: Duration,
    },
    /// A network source's frames stopped: none came for `after` (its bridge or board is gone,
    /// or the network between); it waits for them to come again.
    Silent {
        /// The source, as given (`zenoh:KEY`).
        source: String,
        /// How long since its last frame.
        after: Duration,
    },
    /// A network source's frames came again after it was [`Acquired::Silent`].
    Resumed {
        /// The source, as given.
        source: String,
        /// How long none came, from its last frame before to the first after.
        outage: Duration,
    },
}

/// How a board's bytes encode frames (a serial port, a capture file).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Codec {
    /// One frame per text line of numbers ([`LinesDecoder`]).
    #[default]
    Lines,
    /// Sync bytes, counter, count, f32 values and CRC ([`BinaryDecoder`]).
    Binary,
}

impl std::str::FromStr for Codec {
    type Err = String;

    /// `lines` or `binary`, as on the command line.
    fn from_str(text: &str) -> Result<Codec, String> {
        match text {
            "lines" => Ok(Codec::Lines),
            "binary" => Ok(Codec::Binary),
            _ => Err(format!("{text:?} is not a codec; use `lines` or `binary`")),
        }
    }
}

impl std::fmt::Display for Codec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Codec::Lines => "lines",
            Codec::Binary => "binary",
        })
    }
}

impl Codec {
    /// A fresh decoder for frames of `measurements` values.
    pub fn decoder(self, measurements: usize) -> Box<dyn Decoder + Send> {
        match self {
            Codec::Lines => Box::new(LinesDecoder::new(measurements)),
            Codec::Binary => Box::new(BinaryDecoder::new(measurements)),
        }
    }
}

/// How to run a source: pacing, frame limit, codec, the virtual sensor's seed.
#[derive(Debug, Clone, PartialEq)]
pub struct SourceSettings {
    /// Frames per second of the virtual sensor's clock (must be positive) and of a capture file,
    /// which has no times of its own (0: no clock; its frames are timed as they are read).
    pub rate: f64,
    /// In real time ([`Speed::Recorded`]: a recording at its recorded times, the virtual sensor and
    /// a capture at `rate`), or as fast as possible (the virtual clock still advances at `rate`).
    /// A serial port always goes at the board's pace.
    pub speed: Speed,
    /// Stop after this many frames (bad input and events not counted); `None`: at the end of the
    /// source, never for the virtual sensor or a port.
    pub frames: Option<u64>,
    /// How a serial port's or a capture file's bytes encode frames.
    pub codec: Codec,
    /// The seed of the virtual sensor's noise and random presses.
    pub seed: u64,
    /// Numbers a board sends per measurement: 1, or 2 for complex (re, im) pairs; a frame from
    /// a port or a capture holds this many times the protocol's length. The virtual sensor
    /// sends signed values and takes 1 only.
    pub values_per_measurement: usize,
    /// The virtual sensor's measurement noise: a relative standard deviation per value and
    /// frame, in [0, 0.1] (its default 1e-4 is a best case; open boards vary 0.003–0.005).
    pub noise: f64,
}

impl Default for SourceSettings {
    /// 20 frames/s in real time, no limit, the lines codec, seed 1.
    fn default() -> SourceSettings {
        SourceSettings {
            rate: 20.0,
            speed: Speed::Recorded,
            frames: None,
            codec: Codec::Lines,
            seed: 1,
            values_per_measurement: 1,
            noise: SimParams::default().noise_relative,
        }
    }
}

/// One source of frames: what every kind of source implements for [`Source`].
pub trait FrameSource: Send {
    /// The next item, once it is due (the source paces itself); `None` once the source has ended.
    /// An error ends the source.
    fn acquire(&mut self) -> Option<Result<Acquired, SourceError>>;

    /// Whether input is lost when the source is not read in time (a serial port's buffer
    /// overflows): read it on a thread that never waits for the consumer. False by default.
    fn is_live(&self) -> bool {
        false
    }

    /// Whether it can hand its items over from threads of its own ([`FrameSource::push`]): a
    /// network library's callbacks. False by default.
    fn pushes(&self) -> bool {
        false
    }

    /// Hands the items to `deliver` from threads of its own, in order, as they come, until
    /// `deliver` answers false or the source ends (an error, the last item, is delivered), and
    /// then drops `deliver`: no thread of the caller's waits on the source. It stops when the
    /// [`Pushed`] it returns is dropped. Only where [`FrameSource::pushes`]; the default refuses.
    fn push(self: Box<Self>, deliver: Deliver) -> Result<Pushed, SourceError> {
        drop(deliver);
        Err(SourceError::CannotPush)
    }
}

/// Where a pushing source hands its items ([`FrameSource::push`]): `false` stops it.
pub type Deliver = Box<dyn FnMut(Result<Acquired, SourceError>) -> bool + Send>;

/// A source handing its items over from threads of its own ([`Source::push`]); dropping it
/// stops them.
pub struct Pushed(Option<Box<dyn Send>>);

impl Pushed {
    /// What keeps a source's threads or callbacks going, for as long as it lives.
    pub fn new(running: Box<dyn Send>) -> Pushed {
        Pushed(Some(running))
    }
}

impl fmt::Debug for Pushed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Pushed").field("running", &self.0.is_some()).finish()
    }
}

/// An open source with its frame limit: an iterator over what it yields. See the
/// [module doc](self).
pub struct Source {
    /// The source.
    inner: Box<dyn FrameSource>,
    /// The most frames to deliver.
    limit: Option<u64>,
    /// The frames delivered so far.
    frames: u64,
    /// Whether the source ended or failed.
    ended: bool,
}

impl Source {
    /// Opens the source `spec` names, for `sensor`'s frames (its protocol's length, its length unit
    /// for a press script), as `settings` say; an error if it cannot be opened now.
    pub fn open(spec: &SourceSpec, sensor: &SensorSpec, settings: &SourceSettings) -> Result<Source, SourceError> {
        let per = settings.values_per_measurement;
        if !(1..=2).contains(&per) {
            return Err(SourceError::ValuesPerMeasurement { per });
        }
        let measurements = sensor.protocol()?.len() * per;
        let inner: Box<dyn FrameSource> = match spec {
            SourceSpec::Sim { script } => {
                if !(settings.rate > 0.0 && settings.rate.is_finite()) {
                    return Err(SourceError::Rate { rate: settings.rate });
                }
                if per != 1 {
                    return Err(SourceError::ValuesPerMeasurement { per });
                }
                if !(0.0..=0.1).contains(&settings.noise) {
                    return Err(SourceError::Noise { noise: settings.noise });
                }
                let script = match script {
                    Some(path) => read_script(path, sensor)?,
                    None => Script::random(&sensor.outline, RANDOM_PRESS_PERIOD_S, RANDOM_PRESSES, settings.seed),
                };
                let params = SimParams { noise_relative: settings.noise, ..SimParams::default() };
                let skin = VirtualSensor::with_params(sensor, params, settings.seed)?;
                Box::new(SimSource::new(skin, script, settings.rate, settings.speed)?)
            }
            SourceSpec::File(path) => file::open(path, measurements, settings)?,
            SourceSpec::Serial { path, baud } => {
                let codec = settings.codec;
                Box::new(SerialSource::open(path, *baud, move || codec.decoder(measurements))?)
            }
            SourceSpec::Zenoh { .. } => {
                let reason = if cfg!(feature = "zenoh") {
                    "a Zenoh source is opened on its session (middleware::ZenohSource::open)"
                } else {
                    "this build of eitskin-io has no Zenoh (its `zenoh` feature is off); the eitskin program has it"
                };
                return Err(SourceError::Zenoh { spec: spec.to_string(), reason: reason.to_owned() });
            }
        };
        Ok(Source::new(inner, settings.frames))
    }

    /// A source of one's own, delivering at most `limit` frames.
    pub fn new(inner: Box<dyn FrameSource>, limit: Option<u64>) -> Source {
        Source { inner, limit, frames: 0, ended: false }
    }

    /// Whether input is lost when the source is not read in time; see [`FrameSource::is_live`].
    pub fn is_live(&self) -> bool {
        self.inner.is_live()
    }

    /// The frames delivered so far.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Whether it can hand its items over itself ([`Source::push`]) rather than be read.
    pub fn pushes(&self) -> bool {
        self.inner.pushes()
    }

    /// Hands the items to `deliver` from the source's own threads ([`FrameSource::push`]), up
    /// to its frame limit; only where [`Source::pushes`] (else [`SourceError::CannotPush`]).
    pub fn push(
        self,
        mut deliver: impl FnMut(Result<Acquired, SourceError>) -> bool + Send + 'static,
    ) -> Result<Pushed, SourceError> {
        let Source { inner, limit, mut frames, ended } = self;
        if ended || limit.is_some_and(|limit| frames >= limit) {
            return Ok(Pushed(None));
        }
        inner.push(Box::new(move |item| {
            let (frame, last) = (matches!(item, Ok(Acquired::Frame { .. })), item.is_err());
            frames += u64::from(frame);
            deliver(item) && !last && limit.is_none_or(|limit| frames < limit)
        }))
    }
}

impl Iterator for Source {
    type Item = Result<Acquired, SourceError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.ended || self.limit.is_some_and(|limit| self.frames >= limit) {
            return None;
        }
        let item = self.inner.acquire();
        match &item {
            Some(Ok(Acquired::Frame { .. })) => self.frames += 1,
            Some(Ok(_)) => {}
            Some(Err(_)) | None => self.ended = true,
        }
        item
    }
}

impl fmt::Debug for Source {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Source")
            .field("live", &self.is_live())
            .field("limit", &self.limit)
            .field("frames", &self.frames)
            .field("ended", &self.ended)
            .finish_non_exhaustive()
    }
}

/// Reads and parses a press script for `sensor`, positions in its length unit; a press centred
/// off the sheet is refused by line ([`press_on_sheet`]).
fn read_script(path: &Path, sensor: &SensorSpec) -> Result<Script, SourceError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| SourceError::Read { path: path.to_path_buf(), reason: e.to_string() })?;
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    Script::parse_where(text, sensor.length_unit.metres(), |centre| press_on_sheet(centre, sensor))
        .map_err(|error| SourceError::Script { path: path.to_path_buf(), error })
}

/// Refuses a press centre (m) more than [`OFF_SHEET`](crate::OFF_SHEET) of the outline's size
/// outside its box, as presses' labels are: a unit or an origin gone wrong, not a press.
fn press_on_sheet([x, y]: [f64; 2], sensor: &SensorSpec) -> Result<(), String> {
    if !crate::off_sheet([x, y], sensor) {
        return Ok(());
    }
    let [[x0, y0], [x1, y1]] = sensor.outline.bounds();
    let (per_metre, unit) = (1.0 / sensor.length_unit.metres(), sensor.length_unit.symbol());
    let [x, y] = [x, y].map(|v| crate::Quoted(v * per_metre));
    let [x0, x1, y0, y1] = [x0, x1, y0, y1].map(|v| crate::Quoted(v * per_metre));
    Err(format!(
        "the press at ({x}, {y}) {unit} is far off the sheet (its outline spans {x0} to {x1} by {y0} to {y1} {unit}): give it in the spec's unit ({unit}), from the outline's origin"
    ))
}

/// Frame k of a clock of `period` per frame started at `start`: sleeps until it is due.
fn wait_for_frame(start: Instant, period: Duration, k: u64) {
    let due = start + period.mul_f64(k as f64);
    if let Some(wait) = due.checked_duration_since(Instant::now()) {
        std::thread::sleep(wait);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A source that yields what it is given.
    struct Given(std::vec::IntoIter<Result<Acquired, SourceError>>);

    impl FrameSource for Given {
        fn acquire(&mut self) -> Option<Result<Acquired, SourceError>> {
            self.0.next()
        }
    }

    fn frame(seq: u64) -> Result<Acquired, SourceError> {
        Ok(Acquired::Frame { seq, t: 0.0, values: vec![1.0] })
    }

    /// A press script saved with a byte-order mark reads as without it.
    #[test]
    fn a_script_with_a_byte_order_mark_reads() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("script.txt");
        std::fs::write(&path, "\u{feff}0 1 50 -20 8\n").unwrap();
        let sensor = SensorSpec::square_hydrogel();
        let script = read_script(&path, &sensor).unwrap();
        std::fs::write(&path, "0 1 50 -20 8\n").unwrap();
        assert_eq!(script, read_script(&path, &sensor).unwrap());
    }

    /// A press far off the sheet is refused naming the file and line, quoting it in the spec's
    /// unit; one a little outside the outline (a frame's offset) stands, as labels do.
    #[test]
    fn a_press_off_the_sheet_is_refused_by_line() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("script.txt");
        let sensor = SensorSpec::square_hydrogel(); // 200 mm, from -100 to 100 mm
        std::fs::write(&path, "# t0 t1 x y F\n0 1 0 0 8\n1 2 5000 0 8\n").unwrap();
        let err = read_script(&path, &sensor).unwrap_err().to_string();
        assert_eq!(
            err,
            format!(
                "{}: script line 3: the press at (5000, 0) mm is far off the sheet (its outline spans -100 to 100 by -100 to 100 mm): give it in the spec's unit (mm), from the outline's origin",
                path.display()
            )
        );
        std::fs::write(&path, "0 1 190 -190 8\n").unwrap();
        assert!(read_script(&path, &sensor).is_ok());
        std::fs::write(&path, "0 1 0 nan 8\n").unwrap();
        assert!(read_script(&path, &sensor)
            .unwrap_err()
            .to_string()
            .ends_with("script line 1: nan is not a finite number"));
    }

    /// The virtual sensor's noise is checked before it is built, the value quoted as given;
    /// within its range its frames vary by about as much.
    #[test]
    fn the_virtual_sensors_noise_is_checked_and_given() {
        let mut sensor = SensorSpec::square_hydrogel();
        sensor.mesh.triangles = 300;
        let spec = SourceSpec::Sim { script: None };
        for noise in [-0.001, 0.5, f64::NAN] {
            let settings = SourceSettings { noise, speed: Speed::AsFastAsPossible, ..SourceSettings::default() };
            let err = Source::open(&spec, &sensor, &settings).err().map(|e| e.to_string()).unwrap_or_default();
            assert!(err.starts_with("the virtual sensor's noise is a relative standard deviation"), "{noise}: {err}");
            assert!(err.ends_with(&format!("not {noise}")), "{err}");
        }
        let settings = SourceSettings {
            noise: 0.004,
            speed: Speed::AsFastAsPossible,
            frames: Some(40),
            ..SourceSettings::default()
        };
        let frames: Vec<Vec<f64>> = Source::open(&spec, &sensor, &settings)
            .unwrap()
            .filter_map(|item| match item {
                Ok(Acquired::Frame { values, .. }) => Some(values),
                _ => None,
            })
            .collect();
        // The first frames are at rest (the random presses start half a period in): their
        // relative spread per value.
        let rest = &frames[..10];
        let spread: f64 = (0..rest[0].len())
            .map(|m| {
                let mean = rest.iter().map(|f| f[m]).sum::<f64>() / 10.0;
                (rest.iter().map(|f| (f[m] - mean).powi(2)).sum::<f64>() / 9.0).sqrt() / mean.abs()
            })
            .sum::<f64>()
            / rest[0].len() as f64;
        assert!((0.0034..0.0046).contains(&spread), "{spread}");
    }

    fn bad(seq: u64) -> Result<Acquired, SourceError> {
        Ok(Acquired::Bad(BadFrame::WrongCount { seq, expected: 1, got: 2 }))
    }

    fn seqs(source: Source) -> Vec<Option<u64>> {
        source
            .map(|item| match item {
                Ok(Acquired::Frame { seq, .. }) => Some(seq),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn the_limit_counts_frames_only() {
        let items = vec![frame(0), bad(1), frame(2), bad(3), frame(4), frame(5)];
        let source = Source::new(Box::new(Given(items.into_iter())), Some(2));
        assert_eq!(seqs(source), [Some(0), None, Some(2)]);
    }

    #[test]
    fn an_error_ends_the_source() {
        let items = vec![frame(0), Err(SourceError::Rate { rate: 0.0 }), frame(1)];
        let mut source = Source::new(Box::new(Given(items.into_iter())), None);
        assert!(source.next().is_some_and(|i| i.is_ok()));
        assert!(source.next().is_some_and(|i| i.is_err()));
        assert!(source.next().is_none(), "nothing after the error");
        assert_eq!(source.frames(), 1);
    }
}
