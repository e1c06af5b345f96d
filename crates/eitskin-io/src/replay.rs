//! Replay: recordings and frame captures read back, and the pace at which to deliver them again.
//!
//! * [`read_recording`]: a file written by the [`Recorder`](crate::recorder::Recorder). Every record whose
//!   CRC matches comes back as written, values bit for bit. A damaged record never stops the reading: a
//!   torn last line (a crash while writing it: no new line, bad JSON or bad CRC) is skipped and reported as
//!   [`Skipped::torn_tail`]; a damaged line before it is skipped and listed in [`Skipped::corrupt`], with its
//!   line number counted from 1 (the header is line 1).
//! * [`RecordReader`]: the same, one record at a time, for recordings too long to hold in memory.
//! * [`replay_lines`]: a capture of one frame per text line (OpenEIT, CSV), through the
//!   [`LinesDecoder`], events as a serial source would give them.
//! * [`Pace`]: how long to wait before each frame to replay at the recorded speed, or not at all.
//!
//! ```
//! use eitskin_io::replay::{Pace, Speed};
//! use std::time::Duration;
//! let mut pace = Pace::new(Speed::Recorded);
//! assert_eq!(pace.delay(10.0, Duration::ZERO), Duration::ZERO); // the first frame at once
//! assert_eq!(pace.delay(10.5, Duration::from_millis(100)), Duration::from_millis(400));
//! assert_eq!(Pace::new(Speed::AsFastAsPossible).delay(99.0, Duration::ZERO), Duration::ZERO);
//! ```
//!
//! Not for: repairing files (nothing is written), or checking that the values make physical sense.

use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::time::Duration;

use serde::Deserialize;

use crate::codec::{Decoder, Event, LinesDecoder};
use crate::record_format::{parse_header, record_crc, Header, CRC_FIELD, CRC_TAIL};
use crate::Error;

/// A recording read back.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    /// What the recording is of.
    pub header: Header,
    /// The records that read back whole, in file order.
    pub records: Vec<Record>,
    /// What was skipped, and where.
    pub skipped: Skipped,
}

/// One frame of a recording.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct Record {
    /// The frame's sequence number, as recorded.
    pub seq: u64,
    /// When the frame came, in seconds since the recording started.
    pub t_s: f64,
    /// The measurements, in protocol order (V or Ω, as the board sends); NaN where the board lost a
    /// channel (`null` in the file).
    #[serde(deserialize_with = "values_or_missing")]
    pub values: Vec<f64>,
    /// What the recorder attached (touches, forces), if anything.
    pub result: Option<serde_json::Value>,
}

/// A record's values, `null` read as NaN (a lost channel).
fn values_or_missing<'de, D: serde::Deserializer<'de>>(deserializer: D) -> Result<Vec<f64>, D::Error> {
    let values: Vec<Option<f64>> = Deserialize::deserialize(deserializer)?;
    Ok(values.into_iter().map(|v| v.unwrap_or(f64::NAN)).collect())
}

/// The lines of a recording that were skipped.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Skipped {
    /// The line number (from 1) of a torn last record, left by a crash while it was written.
    pub torn_tail: Option<usize>,
    /// The damaged records before the last, in file order.
    pub corrupt: Vec<Corrupt>,
}

impl Skipped {
    /// The number of records skipped.
    pub fn len(&self) -> usize {
        self.corrupt.len() + usize::from(self.torn_tail.is_some())
    }

    /// Whether every record read back.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// A damaged record before the last line.
#[derive(Debug, Clone, PartialEq)]
pub struct Corrupt {
    /// The line number, from 1 (the header is line 1).
    pub line: usize,
    /// What is wrong with it.
    pub damage: Damage,
}

/// What is wrong with a record.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Damage {
    /// The line has no new line at its end (only ever the last one).
    #[error("the record has no new line at its end; the recorder stopped while writing it")]
    NoLineEnd,
    /// The line does not end with a crc field.
    #[error("the record does not end with a crc field; it was cut short, or written by something else")]
    NoCrc,
    /// The CRC the record carries is not that of its text.
    #[error("the record carries CRC {stored:08x} but its text gives {computed:08x}; its bytes were changed")]
    Crc {
        /// The CRC the record carries.
        stored: u32,
        /// The CRC of the record's text.
        computed: u32,
    },
    /// The text matches its CRC but is not a record.
    #[error("the record is not valid: {message}")]
    Json {
        /// The JSON parser's message.
        message: String,
    },
    /// The record holds another number of values than the header says.
    #[error("the record has {got} values, but the header says {expected}")]
    WrongCount {
        /// The number of values in the header.
        expected: usize,
        /// The number of values in the record.
        got: usize,
    },
}

/// Reads a recording; see the [module doc](self) for what is skipped. Fails only when the file cannot be
/// read or its header is not that of a recording.
///
/// It holds the whole recording in memory: to replay a long one, read it a record at a time with a
/// [`RecordReader`] (or [`Source`](crate::source::Source), which paces it too).
pub fn read_recording(path: &Path) -> Result<Recording, Error> {
    let read_error = |source| Error::Read { path: path.to_path_buf(), source };
    let file = File::open(path).map_err(read_error)?;
    let records = RecordReader::new(BufReader::new(file)).map_err(|e| e.in_file(path))?;
    collect(records).map_err(read_error)
}

/// Reads the bytes of a recording.
pub(crate) fn parse_recording(bytes: &[u8]) -> Result<Recording, Error> {
    let records = RecordReader::new(bytes)?;
    // Reading bytes in memory cannot fail; the error is mapped all the same rather than assumed away.
    collect(records).map_err(|e| Error::Key { path: None, key: "record", reason: format!("cannot be read: {e}") })
}

/// Gathers what a reader reads into a [`Recording`].
fn collect<R: BufRead>(mut records: RecordReader<R>) -> std::io::Result<Recording> {
    let header = records.header().clone();
    let mut recording = Recording { header, records: Vec::new(), skipped: Skipped::default() };
    for entry in &mut records {
        match entry? {
            Entry::Record(record) => recording.records.push(record),
            Entry::Corrupt(corrupt) => recording.skipped.corrupt.push(corrupt),
            Entry::TornTail(corrupt) => recording.skipped.torn_tail = Some(corrupt.line),
        }
    }
    Ok(recording)
}

/// One line of a recording after its header, as a [`RecordReader`] reads it.
#[derive(Debug, Clone, PartialEq)]
pub enum Entry {
    /// A record that read back whole.
    Record(Record),
    /// A damaged record before the last, skipped.
    Corrupt(Corrupt),
    /// The last record, damaged (torn by a crash while it was written), skipped.
    TornTail(Corrupt),
}

/// Reads a recording one record at a time from a buffered reader (a file, bytes), so that memory does
/// not grow with the recording's length; the same records and the same skips as [`read_recording`].
///
/// A damaged record is held back until the next non-blank line or the end of the input tells whether it
/// was the last (a torn tail) or not (corrupt); otherwise nothing is read ahead.
///
/// ```
/// use eitskin_io::replay::{Entry, RecordReader};
/// let text = "{\"format\":\"eitskin-recording\",\"version\":1,\"measurements\":1,\"protocol\":\"p\",\"started_unix_s\":0}\n\
///             {\"seq\":0,\"t_s\":0.0,\"values\":[1.5],\"result\":null,\"crc\":\"4acac573\"}\n\
///             {\"seq\":1,\"t_s\":0.1,\"val";
/// let mut records = RecordReader::new(text.as_bytes())?;
/// assert_eq!(records.header().measurements, 1);
/// assert!(matches!(records.next(), Some(Ok(Entry::Record(r))) if r.values == [1.5]));
/// assert!(matches!(records.next(), Some(Ok(Entry::TornTail(c))) if c.line == 3));
/// assert!(records.next().is_none());
/// # Ok::<(), eitskin_io::Error>(())
/// ```
#[derive(Debug)]
pub struct RecordReader<R> {
    /// What is read.
    input: R,
    /// The recording's header.
    header: Header,
    /// The line being read, reused.
    line: Vec<u8>,
    /// The number of the last line read, from 1 (the header).
    number: usize,
    /// A damaged record whose place (last or not) is not known yet.
    held: Option<Corrupt>,
    /// A record read after a held damaged one, delivered next.
    ready: Option<Record>,
    /// Whether the input has ended (or failed).
    ended: bool,
}

impl<R: BufRead> RecordReader<R> {
    /// Reads and checks the header; an error if the input is empty or its first line is not the header
    /// of a recording of this version.
    pub fn new(mut input: R) -> Result<RecordReader<R>, Error> {
        let mut line = Vec::new();
        let read = input.read_until(b'\n', &mut line).map_err(|e| Error::Key {
            path: None,
            key: "header",
            reason: format!("cannot be read: {e}"),
        })?;
        if read == 0 {
            return Err(Error::Key { path: None, key: "header", reason: "is missing: the file is empty".to_string() });
        }
        let header = parse_header(trim_line_end(&line))?;
        line.clear();
        Ok(RecordReader { input, header, line, number: 1, held: None, ready: None, ended: false })
    }

    /// The recording's header.
    pub fn header(&self) -> &Header {
        &self.header
    }
}

impl<R: BufRead> Iterator for RecordReader<R> {
    type Item = std::io::Result<Entry>;

    fn next(&mut self) -> Option<Self::Item> {
        if let Some(record) = self.ready.take() {
            return Some(Ok(Entry::Record(record)));
        }
        loop {
            if self.ended {
                return self.held.take().map(|corrupt| Ok(Entry::TornTail(corrupt)));
            }
            self.line.clear();
            match self.input.read_until(b'\n', &mut self.line) {
                Ok(0) => {
                    self.ended = true;
                    continue;
                }
                Ok(_) => {}
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(e) => {
                    self.ended = true;
                    self.held = None;
                    return Some(Err(e));
                }
            }
            self.number += 1;
            if is_blank(&self.line) {
                continue;
            }
            // A line follows the held record: it was not the last.
            let earlier = self.held.take().map(Entry::Corrupt);
            match parse_record(&self.line, self.header.measurements) {
                Ok(record) => match earlier {
                    Some(corrupt) => {
                        self.ready = Some(record);
                        return Some(Ok(corrupt));
                    }
                    None => return Some(Ok(Entry::Record(record))),
                },
                Err(damage) => {
                    self.held = Some(Corrupt { line: self.number, damage });
                    if let Some(corrupt) = earlier {
                        return Some(Ok(corrupt));
                    }
                }
            }
        }
    }
}

/// Reads one record line, new line included, checking its CRC before anything else.
fn parse_record(line: &[u8], measurements: usize) -> Result<Record, Damage> {
    if line.last() != Some(&b'\n') {
        return Err(Damage::NoLineEnd);
    }
    let line = trim_line_end(line);
    let open = line.len().checked_sub(CRC_TAIL).ok_or(Damage::NoCrc)?;
    let (body, tail) = line.split_at(open);
    let stored = tail
        .strip_prefix(CRC_FIELD)
        .and_then(|rest| rest.strip_suffix(b"\"}"))
        .and_then(parse_hex)
        .ok_or(Damage::NoCrc)?;
    let computed = record_crc(body);
    if stored != computed {
        return Err(Damage::Crc { stored, computed });
    }
    let record: Record = serde_json::from_slice(line).map_err(|e| Damage::Json { message: e.to_string() })?;
    if record.values.len() != measurements {
        return Err(Damage::WrongCount { expected: measurements, got: record.values.len() });
    }
    Ok(record)
}

/// Eight hex digits as a number.
fn parse_hex(digits: &[u8]) -> Option<u32> {
    if digits.len() != 8 || !digits.iter().all(u8::is_ascii_hexdigit) {
        return None;
    }
    u32::from_str_radix(std::str::from_utf8(digits).ok()?, 16).ok()
}

/// The line without its `\n` or `\r\n`.
fn trim_line_end(line: &[u8]) -> &[u8] {
    let line = line.strip_suffix(b"\n").unwrap_or(line);
    line.strip_suffix(b"\r").unwrap_or(line)
}

/// Whether a line holds nothing but white space.
fn is_blank(line: &[u8]) -> bool {
    line.iter().all(u8::is_ascii_whitespace)
}

/// Decodes a capture of one frame of `expected` values per text line (OpenEIT, CSV without a header) into
/// the events a serial source would give: frames, and bad lines with their place.
pub fn replay_lines(path: &Path, expected: usize) -> Result<Vec<Event>, Error> {
    let bytes = std::fs::read(path).map_err(|source| Error::Read { path: path.to_path_buf(), source })?;
    let mut decoder = LinesDecoder::new(expected);
    let mut events = Vec::new();
    decoder.feed(&bytes, &mut events);
    decoder.finish(&mut events);
    Ok(events)
}

/// How fast to replay.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Speed {
    /// As the frames came: each one as long after the first as it was recorded.
    #[default]
    Recorded,
    /// Every frame at once.
    AsFastAsPossible,
}

/// When to deliver the frames of a replay; it only computes, the caller sleeps.
///
/// Delays are counted from the first frame, not from the one before, so that time lost in sleeping and
/// processing is made up and a long replay does not drift:
///
/// ```no_run
/// # use eitskin_io::replay::{Pace, Speed};
/// # let recording = eitskin_io::replay::read_recording("run.jsonl".as_ref())?;
/// let mut pace = Pace::new(Speed::Recorded);
/// let start = std::time::Instant::now();
/// for record in &recording.records {
///     std::thread::sleep(pace.delay(record.t_s, start.elapsed()));
///     // deliver record.values
/// }
/// # Ok::<(), eitskin_io::Error>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Pace {
    /// How fast.
    speed: Speed,
    /// The time of the first frame, in seconds, once it is seen.
    first_t_s: Option<f64>,
}

impl Pace {
    /// A pace for a replay that has delivered nothing yet.
    pub fn new(speed: Speed) -> Pace {
        Pace { speed, first_t_s: None }
    }

    /// How long to wait before delivering the frame recorded at `t_s` (seconds), when `elapsed` has passed
    /// since the first frame was delivered. Zero for the first frame, when behind, for times that go
    /// backwards or are not finite, and always when as fast as possible.
    pub fn delay(&mut self, t_s: f64, elapsed: Duration) -> Duration {
        match self.speed {
            Speed::AsFastAsPossible => Duration::ZERO,
            Speed::Recorded => {
                let first = *self.first_t_s.get_or_insert(t_s);
                let due = Duration::try_from_secs_f64(t_s - first).unwrap_or(Duration::ZERO);
                due.saturating_sub(elapsed)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pace_counts_from_the_first_frame_and_never_goes_negative() {
        let ms = Duration::from_millis;
        let mut pace = Pace::new(Speed::Recorded);
        assert_eq!(pace.delay(2.0, ms(0)), ms(0));
        assert_eq!(pace.delay(2.25, ms(50)), ms(200));
        assert_eq!(pace.delay(2.5, ms(600)), ms(0), "behind: no wait");
        assert_eq!(pace.delay(2.1, ms(600)), ms(0), "time going backwards: no wait");
        assert_eq!(pace.delay(f64::NAN, ms(0)), ms(0));
        assert_eq!(pace.delay(3.0, ms(0)), ms(1000), "the first frame stays the origin");
        let mut fast = Pace::new(Speed::AsFastAsPossible);
        assert_eq!(fast.delay(0.0, ms(0)), ms(0));
        assert_eq!(fast.delay(100.0, ms(0)), ms(0));
    }

    #[test]
    fn a_record_is_checked_before_it_is_parsed() {
        let good = b"{\"seq\":1,\"t_s\":0.5,\"values\":[1.0],\"result\":null";
        let mut line = good.to_vec();
        line.extend_from_slice(format!(",\"crc\":\"{:08x}\"}}\n", record_crc(good)).as_bytes());
        let record = parse_record(&line, 1).expect("a good record");
        assert_eq!((record.seq, record.t_s, record.values, record.result), (1, 0.5, vec![1.0], None));
        assert_eq!(parse_record(&line[..line.len() - 1], 1), Err(Damage::NoLineEnd));
        assert_eq!(parse_record(b"{\"seq\":1}\n", 1), Err(Damage::NoCrc));
        assert_eq!(parse_record(&line, 2), Err(Damage::WrongCount { expected: 2, got: 1 }));
        line[10] = b'7'; // seq 1 becomes 7
        assert!(matches!(parse_record(&line, 1), Err(Damage::Crc { .. })));
    }
}
