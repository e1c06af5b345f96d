//! What can go wrong naming, opening or reading a frame source.

use std::path::PathBuf;

use eitskin::sim::ScriptError;
use eitskin::{ForwardError, SpecError};

/// What can go wrong naming a source (`--source` text), opening it, or reading it.
///
/// Parse errors quote the text as written and list what is accepted; open errors name the file
/// or port and say what to check.
#[derive(Debug, PartialEq, thiserror::Error)]
pub enum SourceError {
    /// Text that names no kind of source.
    #[error(
        "{spec:?} is not a frame source{}; write `sim` (the virtual sensor), `sim:SCRIPT` (pressed by a script), \
         `file:PATH` (a recording or a capture), `serial:PATH[@BAUD]` (a board, e.g. `serial:/dev/ttyACM0@921600`) \
         or `zenoh:KEY` (frames published on Zenoh)",
        path_hint(spec)
    )]
    Unknown {
        /// The text as written.
        spec: String,
    },
    /// `sim:` without a script.
    #[error("{spec:?} names no script; write `sim` for random presses, or `sim:SCRIPT`, e.g. `sim:presses.txt`")]
    NoScript {
        /// The text as written.
        spec: String,
    },
    /// Numbers per measurement other than 1 (signed or magnitudes) or 2 (complex pairs), or
    /// complex pairs asked of the virtual sensor, which sends signed values.
    #[error("{per} numbers per measurement: a board sends 1 (signed values or magnitudes) or 2 (complex re, im pairs); the virtual sensor sends 1")]
    ValuesPerMeasurement {
        /// The number asked for.
        per: usize,
    },
    /// `file:` without a path.
    #[error("{spec:?} names no file; write `file:PATH`, e.g. `file:run.jsonl` or `file:frames.csv`")]
    NoFile {
        /// The text as written.
        spec: String,
    },
    /// `zenoh:` without a key expression.
    #[error("{spec:?} names no key expression; write `zenoh:KEY`, e.g. `zenoh:robot/skin/frames`")]
    NoKey {
        /// The text as written.
        spec: String,
    },
    /// [`Source::push`](super::Source::push) asked of a source that is read, not pushing.
    #[error("this source is read, it does not hand its frames over itself")]
    CannotPush,
    /// A Zenoh source asked of a build without Zenoh, or of [`Source::open`](super::Source::open),
    /// which has no session: open it with `middleware::ZenohSource` on the session.
    #[error("{spec}: {reason}")]
    Zenoh {
        /// The source as written.
        spec: String,
        /// Why it cannot be opened here.
        reason: String,
    },
    /// A source spec that does not start with `serial:`.
    #[error("{spec:?} is not a serial source; write `serial:PATH` or `serial:PATH@BAUD`, e.g. `serial:/dev/ttyACM0`")]
    NotSerial {
        /// The spec as given.
        spec: String,
    },
    /// A serial source spec without a path.
    #[error("{spec:?} names no port; write `serial:PATH` or `serial:PATH@BAUD`, e.g. `serial:/dev/ttyUSB0@921600`")]
    EmptyPath {
        /// The spec as given.
        spec: String,
    },
    /// A baud rate that is not a positive whole number.
    #[error("{spec:?}: baud rate {baud:?} is not a positive whole number of bit/s, e.g. 115200 or 921600")]
    BadBaud {
        /// The spec as given.
        spec: String,
        /// The text after `@`.
        baud: String,
    },
    /// The port could not be opened the first time.
    #[error(
        "cannot open serial port {}: {reason}; is the board plugged in, and may this user open the port \
         (on Linux, the `dialout` group)?",
        path.display()
    )]
    Open {
        /// The port's path.
        path: PathBuf,
        /// Why, as the operating system said it.
        reason: String,
    },
    /// A file (frames, recording, press script) that cannot be opened or read.
    #[error("cannot read {}: {reason}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why, as the operating system said it.
        reason: String,
    },
    /// A press script that does not parse.
    #[error("{}: {error}", path.display())]
    Script {
        /// The script file.
        path: PathBuf,
        /// The line at fault and why (in the message, so not also a `source()`).
        error: ScriptError,
    },
    /// A file that starts as a recording (a JSON header) but is not one this crate can replay.
    #[error("{}: {reason} (a file that starts with `{{` is read as an eitskin recording)", path.display())]
    Recording {
        /// The file.
        path: PathBuf,
        /// What is wrong with its header, naming the key.
        reason: String,
    },
    /// A recording of frames of another length than the sensor's protocol.
    #[error(
        "{}: the recording holds frames of {recorded} values, but the sensor's protocol has {measurements}; \
         is it a recording of another sensor?",
        path.display()
    )]
    RecordingLength {
        /// The file.
        path: PathBuf,
        /// The number of values in the recording's frames.
        recorded: usize,
        /// The number of values in the sensor's frames.
        measurements: usize,
    },
    /// A table of frames (MAT, NPY) that does not hold the sensor's frames.
    #[error("{}: {reason}", path.display())]
    Table {
        /// The file.
        path: PathBuf,
        /// What it holds instead, and what to do.
        reason: String,
    },
    /// A table of frames (MAT, NPY) that cannot be read, as the array reader says it (the file
    /// named in it).
    #[error("{message}")]
    TableRead {
        /// The reader's whole message.
        message: String,
    },
    /// A virtual sensor without a positive frame rate for its clock.
    #[error(
        "the virtual sensor needs a positive frame rate for its clock, not {rate} frames/s; to deliver frames \
         without waiting for the clock, replay as fast as possible instead (`--fast`)"
    )]
    Rate {
        /// The rate given, in frames/s.
        rate: f64,
    },
    /// The virtual sensor's noise outside its range.
    #[error(
        "the virtual sensor's noise is a relative standard deviation per value in [0, 0.1] \
         (open boards vary 0.003–0.005 from frame to frame), not {noise}"
    )]
    Noise {
        /// The noise given, relative to each value.
        noise: f64,
    },
    /// The sensor spec does not make a virtual sensor or a protocol.
    #[error("the sensor spec does not make a virtual sensor")]
    Sensor(#[from] SpecError),
    /// The virtual sensor's forward model could not be solved.
    #[error("the virtual sensor could not simulate a frame")]
    Simulate(#[from] ForwardError),
}

/// A hint to write `file:TEXT` when the text looks like a path.
fn path_hint(spec: &str) -> String {
    if spec.contains(['/', '\\', '.']) {
        format!(" (a file? write `file:{spec}`)")
    } else {
        String::new()
    }
}
