//! The serial-port source: a board plugged in over USB CDC or a UART adapter.
//!
//! [`SerialSource`] opens the port (8 data bits, no parity, 1 stop bit, no flow control), reads
//! whatever bytes arrive, feeds them to a [`Decoder`] and hands out [`SourceEvent`]s. A port that
//! vanishes (the board unplugged, the cable pulled) is not an error but an event: the source
//! reports [`SourceEvent::Disconnected`], reopens the same path with exponential back-off
//! (50 ms doubling to 2 s by default), reports [`SourceEvent::Reconnected`] once it is back, and
//! decodes on. A frame half received before the outage is reported by the old decoder's
//! [`finish`](Decoder::finish), never glued to the bytes after it: decoding resumes with a fresh
//! decoder, so a sequence number counted by the decoder (the lines codec's) starts again from 0.
//!
//! ```no_run
//! use eitskin_io::codec::LinesDecoder;
//! use eitskin_io::source::serial::{parse_serial_spec, SerialSource, SourceEvent};
//! let (path, baud) = parse_serial_spec("serial:/dev/ttyACM0@921600")?;
//! let mut source = SerialSource::open(&path, baud, || Box::new(LinesDecoder::new(120)))?;
//! let mut events = Vec::new();
//! for _ in 0..1000 {
//!     source.poll(&mut events); // waits up to the read timeout, 50 ms by default
//!     for event in events.drain(..) {
//!         match event {
//!             SourceEvent::Frame { frame, received } => println!("{} values at {received:?}", frame.values.len()),
//!             other => eprintln!("{other:?}"),
//!         }
//!     }
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Not for: files or network streams, or telling a silent board from an absent one (a port that
//! stays open but sends nothing yields no events at all).

use std::collections::VecDeque;
use std::fmt;
use std::io::ErrorKind;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use serialport::{DataBits, FlowControl, Parity, SerialPort, StopBits};

pub use super::SourceError;
use super::{Acquired, FrameSource};
use crate::codec::{BadFrame, Decoder, Event, Frame};

/// The baud rate used when none is given, in bit/s.
pub const DEFAULT_BAUD: u32 = 115_200;

/// How long [`SerialSource::poll`] waits for bytes by default.
pub const DEFAULT_READ_TIMEOUT: Duration = Duration::from_millis(50);

/// The wait before the first attempt to reopen a vanished port, by default.
pub const DEFAULT_FIRST_RETRY: Duration = Duration::from_millis(50);

/// The longest wait between two attempts to reopen a vanished port, by default.
pub const DEFAULT_MAX_RETRY: Duration = Duration::from_secs(2);

/// The most bytes taken from the port in one read (64 KiB, several OpenEIT frames).
const READ_BUFFER: usize = 64 * 1024;

/// What a [`SerialSource`] yields.
#[derive(Debug, Clone, PartialEq)]
pub enum SourceEvent {
    /// A frame that decoded cleanly.
    Frame {
        /// The frame.
        frame: Frame,
        /// When the read that completed the frame returned.
        received: Instant,
    },
    /// A piece of input that was skipped, and why.
    Bad(BadFrame),
    /// The port vanished; the source now tries to reopen it.
    Disconnected {
        /// The port's path, as given to [`SerialSource::open`].
        path: PathBuf,
        /// Why the port was given up, as the operating system said it.
        error: String,
    },
    /// The port is open again after an outage, and decoding resumes with a fresh decoder.
    Reconnected {
        /// The port's path, as given to [`SerialSource::open`].
        path: PathBuf,
        /// How long the port was away, from the [`SourceEvent::Disconnected`] event to now.
        outage: Duration,
    },
}

/// Reads the command-line form `serial:PATH[@BAUD]` as (path, baud in bit/s), with
/// [`DEFAULT_BAUD`] when no baud rate is given.
///
/// An `@` followed by text with a `/` belongs to the path, so `serial:/dev/a@b/tty0` is a path.
///
/// ```
/// use eitskin_io::source::serial::parse_serial_spec;
/// assert_eq!(parse_serial_spec("serial:/dev/ttyUSB0@921600")?, ("/dev/ttyUSB0".into(), 921_600));
/// assert!(parse_serial_spec("serial:/dev/ttyUSB0@fast").is_err());
/// # Ok::<(), eitskin_io::source::serial::SourceError>(())
/// ```
pub fn parse_serial_spec(text: &str) -> Result<(PathBuf, u32), SourceError> {
    let rest = text.strip_prefix("serial:").ok_or_else(|| SourceError::NotSerial { spec: text.to_owned() })?;
    let (path, baud) = match rest.rsplit_once('@') {
        Some((path, baud)) if !baud.contains('/') => {
            let rate = baud.parse::<u32>().ok().filter(|&rate| rate > 0);
            let rate = rate.ok_or_else(|| SourceError::BadBaud { spec: text.to_owned(), baud: baud.to_owned() })?;
            (path, rate)
        }
        _ => (rest, DEFAULT_BAUD),
    };
    if path.is_empty() {
        return Err(SourceError::EmptyPath { spec: text.to_owned() });
    }
    Ok((PathBuf::from(path), baud))
}

/// Makes a fresh decoder: at the start, and after each outage.
type DecoderFactory = Box<dyn FnMut() -> Box<dyn Decoder + Send> + Send>;

/// Frames from a board on a serial port, surviving unplugs; see the [module doc](self).
///
/// Settings are given at [`open`](SerialSource::open), with `with_*` methods for the optional
/// ones:
///
/// ```no_run
/// # use eitskin_io::codec::BinaryDecoder;
/// # use eitskin_io::source::serial::SerialSource;
/// # use std::time::Duration;
/// let source = SerialSource::open("/dev/ttyUSB0", 921_600, || Box::new(BinaryDecoder::new(120)))?
///     .with_read_timeout(Duration::from_millis(10))
///     .with_retry(Duration::from_millis(100), Duration::from_secs(5));
/// # Ok::<(), eitskin_io::source::serial::SourceError>(())
/// ```
pub struct SerialSource {
    /// The port's path, as given.
    path: PathBuf,
    /// The baud rate, in bit/s.
    baud: u32,
    /// How long one read waits for bytes.
    read_timeout: Duration,
    /// The wait before the first attempt to reopen.
    first_retry: Duration,
    /// The longest wait between two attempts to reopen.
    max_retry: Duration,
    /// Makes the decoder for each connection.
    make_decoder: DecoderFactory,
    /// The decoder of the current connection.
    decoder: Box<dyn Decoder + Send>,
    /// The open port, or how the attempts to reopen it stand.
    link: Link,
    /// Bytes read from the port, reused by every read.
    buffer: Vec<u8>,
    /// Decoder events, reused by every read.
    decoded: Vec<Event>,
    /// The bytes read since the source was opened, over all connections.
    bytes_received: u64,
    /// When the port was first opened: frames' times count from it.
    opened: Instant,
    /// Events polled and not yet handed out as [`Acquired`] items.
    pending: VecDeque<SourceEvent>,
    /// Events of one poll, reused.
    polled: Vec<SourceEvent>,
}

/// The state of the connection.
enum Link {
    /// The port is open.
    Up(Box<dyn SerialPort>),
    /// The port vanished.
    Down {
        /// When it was given up.
        since: Instant,
        /// When to try to reopen it next.
        next_attempt: Instant,
        /// The wait after the next attempt, should it fail.
        delay: Duration,
    },
}

impl SerialSource {
    /// Opens the port at `path` at `baud` bit/s, 8N1, with `decoder` making the decoder for each
    /// connection; an error if the port cannot be opened now.
    pub fn open(
        path: impl AsRef<Path>,
        baud: u32,
        decoder: impl FnMut() -> Box<dyn Decoder + Send> + Send + 'static,
    ) -> Result<SerialSource, SourceError> {
        let path = path.as_ref().to_path_buf();
        let port = open_port(&path, baud, DEFAULT_READ_TIMEOUT)
            .map_err(|reason| SourceError::Open { path: path.clone(), reason })?;
        let mut make_decoder: DecoderFactory = Box::new(decoder);
        Ok(SerialSource {
            path,
            baud,
            read_timeout: DEFAULT_READ_TIMEOUT,
            first_retry: DEFAULT_FIRST_RETRY,
            max_retry: DEFAULT_MAX_RETRY,
            decoder: make_decoder(),
            make_decoder,
            link: Link::Up(port),
            buffer: vec![0; READ_BUFFER],
            decoded: Vec::new(),
            bytes_received: 0,
            opened: Instant::now(),
            pending: VecDeque::new(),
            polled: Vec::new(),
        })
    }

    /// The same source, waiting at most `timeout` for bytes in each [`poll`](Self::poll)
    /// (default [`DEFAULT_READ_TIMEOUT`]).
    pub fn with_read_timeout(mut self, timeout: Duration) -> SerialSource {
        self.read_timeout = timeout;
        if let Link::Up(port) = &mut self.link {
            // A port that refuses the new timeout keeps its old one until it is reopened with the new one.
            let _ = port.set_timeout(timeout);
        }
        self
    }

    /// The same source, waiting `first` before the first attempt to reopen a vanished port and
    /// doubling the wait after each failed attempt up to `max` (defaults [`DEFAULT_FIRST_RETRY`]
    /// and [`DEFAULT_MAX_RETRY`]); a `max` below `first` is taken as `first`.
    pub fn with_retry(mut self, first: Duration, max: Duration) -> SerialSource {
        self.first_retry = first;
        self.max_retry = max.max(first);
        self
    }

    /// The port's path, as given to [`open`](Self::open).
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The baud rate, in bit/s.
    pub fn baud(&self) -> u32 {
        self.baud
    }

    /// Whether the port is open now (false between a disconnect and the reconnect).
    pub fn is_connected(&self) -> bool {
        matches!(self.link, Link::Up(_))
    }

    /// The number of bytes read from the port since it was first opened, over all connections.
    pub fn bytes_received(&self) -> u64 {
        self.bytes_received
    }

    /// Appends the next events to `out`: waits up to the read timeout for bytes (or, while the
    /// port is away, for the next attempt to reopen it) and returns whatever is ready, possibly
    /// nothing. A vanished port is an event, never an error.
    pub fn poll(&mut self, out: &mut Vec<SourceEvent>) {
        match &mut self.link {
            Link::Up(port) => match port.read(&mut self.buffer) {
                Ok(0) => self.disconnect("the port reported end of file".to_owned(), out),
                Ok(count) => {
                    let received = Instant::now();
                    self.bytes_received += count as u64;
                    self.decoder.feed(&self.buffer[..count], &mut self.decoded);
                    hand_out(&mut self.decoded, received, out);
                }
                Err(error) if is_quiet(error.kind()) => {}
                Err(error) => self.disconnect(error.to_string(), out),
            },
            Link::Down { since, next_attempt, delay } => {
                let mut now = Instant::now();
                if now < *next_attempt {
                    std::thread::sleep((*next_attempt - now).min(self.read_timeout));
                    now = Instant::now();
                    if now < *next_attempt {
                        return;
                    }
                }
                match open_port(&self.path, self.baud, self.read_timeout) {
                    Ok(port) => {
                        let outage = now.saturating_duration_since(*since);
                        self.link = Link::Up(port);
                        out.push(SourceEvent::Reconnected { path: self.path.clone(), outage });
                    }
                    Err(_) => {
                        *next_attempt = now + *delay;
                        *delay = next_retry(*delay, self.max_retry);
                    }
                }
            }
        }
    }

    /// Gives the port up: ends the current decoder's stream, reports the outage, and schedules
    /// the first attempt to reopen.
    fn disconnect(&mut self, error: String, out: &mut Vec<SourceEvent>) {
        let now = Instant::now();
        self.decoder.abandon(&mut self.decoded);
        hand_out(&mut self.decoded, now, out);
        self.decoder = (self.make_decoder)();
        self.link = Link::Down {
            since: now,
            next_attempt: now + self.first_retry,
            delay: next_retry(self.first_retry, self.max_retry),
        };
        out.push(SourceEvent::Disconnected { path: self.path.clone(), error });
    }
}

/// As a [`Source`](super::Source): polls until there is an event; never ends by itself. A frame's
/// time is when the read that completed it returned, in s since the port was first opened.
impl FrameSource for SerialSource {
    fn acquire(&mut self) -> Option<Result<Acquired, SourceError>> {
        loop {
            if let Some(event) = self.pending.pop_front() {
                return Some(Ok(match event {
                    SourceEvent::Frame { frame, received } => {
                        let t = received.saturating_duration_since(self.opened).as_secs_f64();
                        Acquired::Frame { seq: frame.seq, t, values: frame.values }
                    }
                    SourceEvent::Bad(bad) => Acquired::Bad(bad),
                    SourceEvent::Disconnected { path, error } => Acquired::Disconnected { path, error },
                    SourceEvent::Reconnected { path, outage } => Acquired::Reconnected { path, outage },
                }));
            }
            let mut polled = std::mem::take(&mut self.polled);
            self.poll(&mut polled);
            self.pending.extend(polled.drain(..));
            self.polled = polled;
        }
    }

    /// A port's input is lost when it is not read in time.
    fn is_live(&self) -> bool {
        true
    }
}

impl fmt::Debug for SerialSource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SerialSource")
            .field("path", &self.path)
            .field("baud", &self.baud)
            .field("connected", &self.is_connected())
            .field("bytes_received", &self.bytes_received)
            .finish_non_exhaustive()
    }
}

/// Opens the port 8N1 without flow control; the error is the operating system's reason.
fn open_port(path: &Path, baud: u32, read_timeout: Duration) -> Result<Box<dyn SerialPort>, String> {
    let name = path.to_str().ok_or_else(|| "the path is not valid UTF-8".to_owned())?;
    serialport::new(name, baud)
        .data_bits(DataBits::Eight)
        .parity(Parity::None)
        .stop_bits(StopBits::One)
        .flow_control(FlowControl::None)
        .timeout(read_timeout)
        .open()
        .map_err(|error| error.to_string())
}

/// Whether a read error means only that no bytes came, not that the port is gone.
fn is_quiet(kind: ErrorKind) -> bool {
    matches!(kind, ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted)
}

/// The wait after `delay`: twice as long, at most `max`.
fn next_retry(delay: Duration, max: Duration) -> Duration {
    delay.saturating_mul(2).min(max)
}

/// Moves the decoder's events to `out`, stamping frames with `received`.
fn hand_out(decoded: &mut Vec<Event>, received: Instant, out: &mut Vec<SourceEvent>) {
    out.extend(decoded.drain(..).map(|event| match event {
        Event::Frame(frame) => SourceEvent::Frame { frame, received },
        Event::Bad(bad) => SourceEvent::Bad(bad),
    }));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::LinesDecoder;

    #[test]
    fn spec_with_and_without_baud() {
        assert_eq!(parse_serial_spec("serial:/dev/ttyACM0"), Ok((PathBuf::from("/dev/ttyACM0"), DEFAULT_BAUD)));
        assert_eq!(parse_serial_spec("serial:/dev/ttyUSB0@921600"), Ok((PathBuf::from("/dev/ttyUSB0"), 921_600)));
        assert_eq!(parse_serial_spec("serial:COM3@9600"), Ok((PathBuf::from("COM3"), 9600)));
        assert_eq!(
            parse_serial_spec("serial:/dev/by-id/usb@1/tty"),
            Ok((PathBuf::from("/dev/by-id/usb@1/tty"), DEFAULT_BAUD))
        );
    }

    #[test]
    fn bad_specs_say_which_part_is_wrong() {
        let bad_baud = |spec: &str, baud: &str| SourceError::BadBaud { spec: spec.into(), baud: baud.into() };
        assert_eq!(parse_serial_spec("serial:/dev/ttyUSB0@fast"), Err(bad_baud("serial:/dev/ttyUSB0@fast", "fast")));
        assert_eq!(parse_serial_spec("serial:/dev/ttyUSB0@0"), Err(bad_baud("serial:/dev/ttyUSB0@0", "0")));
        assert_eq!(parse_serial_spec("serial:/dev/ttyUSB0@"), Err(bad_baud("serial:/dev/ttyUSB0@", "")));
        assert_eq!(parse_serial_spec("serial:/dev/ttyUSB0@-1"), Err(bad_baud("serial:/dev/ttyUSB0@-1", "-1")));
        assert_eq!(parse_serial_spec("serial:@9600"), Err(SourceError::EmptyPath { spec: "serial:@9600".into() }));
        assert_eq!(parse_serial_spec("serial:"), Err(SourceError::EmptyPath { spec: "serial:".into() }));
        assert_eq!(parse_serial_spec("/dev/ttyACM0"), Err(SourceError::NotSerial { spec: "/dev/ttyACM0".into() }));
        let message = parse_serial_spec("serial:/dev/ttyUSB0@fast").unwrap_err().to_string();
        assert!(message.contains("\"fast\"") && message.contains("serial:/dev/ttyUSB0@fast"), "{message}");
    }

    #[test]
    fn retry_doubles_up_to_the_cap() {
        let max = Duration::from_secs(2);
        let mut delay = DEFAULT_FIRST_RETRY;
        let mut waits = vec![delay];
        for _ in 0..7 {
            delay = next_retry(delay, max);
            waits.push(delay);
        }
        let ms: Vec<u128> = waits.iter().map(Duration::as_millis).collect();
        assert_eq!(ms, [50, 100, 200, 400, 800, 1600, 2000, 2000]);
    }

    #[test]
    fn first_open_failure_names_the_path() {
        let path = Path::new("/nonexistent/eitskin/ttyACM9");
        let error = SerialSource::open(path, DEFAULT_BAUD, || Box::new(LinesDecoder::new(4))).unwrap_err();
        assert!(matches!(&error, SourceError::Open { path: p, .. } if p == path), "{error:?}");
        assert!(error.to_string().contains("/nonexistent/eitskin/ttyACM9"), "{error}");
    }

    #[test]
    fn source_can_move_to_a_reader_thread() {
        fn is_send<T: Send>() {}
        is_send::<SerialSource>();
    }
}
