//! Recordings: frames and what was made of them, written as they come, in a file that survives a crash.
//!
//! A recording is a JSON-lines file, only ever appended to. Line 1 is the header:
//!
//! ```text
//! {"format":"eitskin-recording","version":2,"measurements":16,"protocol":"two-terminal","started_unix_s":1767225600.5}
//! ```
//!
//! and every further line is one frame:
//!
//! ```text
//! {"seq":0,"t_s":0.0125,"values":[101.5,98.25,…],"result":{"touches":[…]},"crc":"1c291ca3"}
//! ```
//!
//! * `measurements`: the number of values in every frame; `protocol`: its name, as the caller gives it;
//!   `started_unix_s`: when the recording started, in seconds since 1970-01-01 UTC.
//! * `seq`: the frame's sequence number; `t_s`: when it came, in seconds since the recording started;
//!   `values`: its measurements in protocol order (V or Ω, as the board sends), printed so that they read back
//!   bit for bit, except that a value that is NaN or infinite (a channel the board lost) is `null` and reads
//!   back as NaN; `result`: any JSON the caller attaches (touches, forces), or `null`. Version 2 added those
//!   `null`s; version-1 files read as before.
//! * `crc`: the CRC-32 (ISO-HDLC, as zlib and PNG) of the record's JSON text without its crc field — the
//!   line up to `,"crc"`, closed by `}` — as 8 lower-case hex digits. It is always the last field, so a reader
//!   checks the bytes as written, without printing anything again.
//!
//! Each record is one `write` of the whole line, new line included, to the file, with no buffer in
//! between: once [`Recorder::record`] returns, the line is with the operating system and survives the process
//! being killed (SIGKILL). A power cut may still lose the last lines unless [`Recorder::sync`] was called. A
//! crash in the middle of a write leaves at most a torn last line, which
//! [`read_recording`](crate::replay::read_recording) detects and skips.
//!
//! ```
//! use eitskin_io::recorder::{Header, Recorder};
//! let path = std::env::temp_dir().join(format!("eitskin-doc-recorder-{}.jsonl", std::process::id()));
//! # let _ = std::fs::remove_file(&path);
//! let mut recorder = Recorder::create(&path, &Header::now(3, "two-terminal"))?;
//! recorder.record(0, 0.0, &[1.5, 2.0, 0.1], None)?;
//! recorder.record(1, 0.02, &[1.5, 2.5, 0.1], Some(&serde_json::json!({ "touches": 1 })))?;
//! assert!(Recorder::create(&path, recorder.header()).is_err()); // never overwrites by accident
//! let recording = eitskin_io::replay::read_recording(&path)?;
//! assert_eq!(recording.records[1].values, [1.5, 2.5, 0.1]);
//! assert_eq!(recording.records[1].result, Some(serde_json::json!({ "touches": 1 })));
//! # std::fs::remove_file(&path)?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Not for: raw captures of a serial line (keep the bytes and replay them with
//! [`replay_lines`](crate::replay::replay_lines)), or compact archives (the text is about 20 bytes a value).

use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::record_format::{record_crc, HeaderLine, CRC_FIELD};
pub use crate::record_format::{Header, FORMAT, VERSION};
use crate::Error;

/// What to do when the file already exists.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Mode {
    /// Create the file; refuse if it exists.
    #[default]
    New,
    /// Continue the recording in the file, once its header is checked against ours; create it if it does not exist.
    Append,
    /// Replace whatever the file holds.
    Overwrite,
}

/// Writes a recording, one record per frame; see the [module doc](self) for the format.
///
/// Not for: reading (that is [`read_recording`](crate::replay::read_recording)).
#[derive(Debug)]
pub struct Recorder {
    /// The file, as given.
    path: PathBuf,
    /// The file, open for writing at its end.
    file: File,
    /// The recording's header: ours, or the file's when appending.
    header: Header,
    /// The line being written, kept between records so that recording does not allocate.
    line: Vec<u8>,
    /// Whether the file may end inside a line (a torn record), so that the next record must start a new one.
    open_line: bool,
    /// The sequence number of the last record in the file.
    last_seq: Option<u64>,
}

impl Recorder {
    /// Starts a recording in a new file; refuses a file that exists.
    pub fn create(path: &Path, header: &Header) -> Result<Recorder, Error> {
        Recorder::create_with(path, header, Mode::New)
    }

    /// Starts or continues a recording, doing `mode` when the file exists.
    ///
    /// When appending, the file's header must have our number of measurements and our protocol; the file's
    /// start time is kept (see [`header`](Recorder::header)) and records go on after the last line, a torn
    /// one included, which stays behind as one corrupt line.
    pub fn create_with(path: &Path, header: &Header, mode: Mode) -> Result<Recorder, Error> {
        let mut options = OpenOptions::new();
        match mode {
            Mode::New => options.append(true).create_new(true),
            Mode::Append => options.append(true).create(true),
            Mode::Overwrite => options.write(true).create(true).truncate(true),
        };
        let file = options.open(path).map_err(|e| {
            if e.kind() == std::io::ErrorKind::AlreadyExists {
                Error::Key {
                    path: Some(path.to_path_buf()),
                    key: "recording",
                    reason: "already exists; choose another file".to_string(),
                }
            } else {
                write_error(path, &e)
            }
        })?;
        let mut recorder = Recorder {
            path: path.to_path_buf(),
            file,
            header: header.clone(),
            line: Vec::new(),
            open_line: false,
            last_seq: None,
        };
        let existing = match mode {
            Mode::Append => std::fs::read(path).map_err(|source| Error::Read { path: path.to_path_buf(), source })?,
            Mode::New | Mode::Overwrite => Vec::new(),
        };
        if existing.is_empty() {
            let mut line = serde_json::to_vec(&HeaderLine::of(header)).map_err(|e| json_error(path, &e))?;
            line.push(b'\n');
            recorder.file.write_all(&line).map_err(|e| write_error(path, &e))?;
        } else {
            let recording = crate::replay::parse_recording(&existing).map_err(|e| e.in_file(path))?;
            check_same(&recording.header, header).map_err(|e| e.in_file(path))?;
            recorder.header = recording.header;
            recorder.last_seq = recording.records.last().map(|r| r.seq);
            recorder.open_line = existing.last() != Some(&b'\n');
        }
        Ok(recorder)
    }

    /// Appends one frame: its sequence number, its time in seconds since the start, its values and what was
    /// made of it. Once this returns, the record survives the process being killed.
    ///
    /// `result` `None` and `Some(&Value::Null)` both read back as `None`. Refuses, writing nothing, a frame
    /// whose length is not the header's or whose time or values are not finite.
    pub fn record(
        &mut self,
        seq: u64,
        t_s: f64,
        values: &[f64],
        result: Option<&serde_json::Value>,
    ) -> Result<(), Error> {
        self.write(seq, t_s, values, result)
    }

    /// Appends one frame as [`record`](Recorder::record) does, with a typed `result` (for
    /// `eitskin run`, its [`Recorded`](crate::stream::Recorded) touches) printed straight into the
    /// line, without a [`serde_json::Value`] in between.
    pub fn record_with(&mut self, seq: u64, t_s: f64, values: &[f64], result: &impl Serialize) -> Result<(), Error> {
        self.write(seq, t_s, values, Some(result))
    }

    /// Appends one frame; see [`record`](Recorder::record).
    fn write<R: Serialize + ?Sized>(
        &mut self,
        seq: u64,
        t_s: f64,
        values: &[f64],
        result: Option<&R>,
    ) -> Result<(), Error> {
        self.check(seq, t_s, values)?;
        self.line.clear();
        if self.open_line {
            self.line.push(b'\n');
        }
        let start = self.line.len();
        encode_record(&mut self.line, seq, t_s, values, result).map_err(|e| json_error(&self.path, &e))?;
        let crc = record_crc(&self.line[start..]);
        self.line.extend_from_slice(CRC_FIELD);
        push_hex(&mut self.line, crc);
        self.line.extend_from_slice(b"\"}\n");
        // One write of the whole line: a kill leaves the line whole or torn, never interleaved.
        match self.file.write_all(&self.line) {
            Ok(()) => {
                self.open_line = false;
                self.last_seq = Some(seq);
                Ok(())
            }
            Err(e) => {
                self.open_line = true;
                Err(write_error(&self.path, &e))
            }
        }
    }

    /// Waits until the records so far are on the disk (fsync), so that they survive a power cut too.
    /// Slow (milliseconds): call it now and then, not for every frame.
    pub fn sync(&mut self) -> Result<(), Error> {
        self.file.sync_data().map_err(|e| write_error(&self.path, &e))
    }

    /// The recording's header: the file's when appending, else the one given.
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// The file written to.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The sequence number of the last record in the file, if any (the file's last one when appending).
    pub fn last_seq(&self) -> Option<u64> {
        self.last_seq
    }

    /// Refuses a frame that would not read back as written.
    fn check(&self, seq: u64, t_s: f64, values: &[f64]) -> Result<(), Error> {
        let refuse = |reason: String| Error::Key { path: Some(self.path.clone()), key: "record", reason };
        if values.len() != self.header.measurements {
            return Err(refuse(format!(
                "frame seq {seq} has {} values, but the recording holds frames of {}; is it the same protocol?",
                values.len(),
                self.header.measurements
            )));
        }
        if !t_s.is_finite() {
            return Err(refuse(format!("frame seq {seq} has time {t_s} s, which is not a finite number")));
        }
        Ok(())
    }
}

/// Appends a record without its crc field and closing brace to `line`.
fn encode_record<R: Serialize + ?Sized>(
    line: &mut Vec<u8>,
    seq: u64,
    t_s: f64,
    values: &[f64],
    result: Option<&R>,
) -> serde_json::Result<()> {
    line.extend_from_slice(b"{\"seq\":");
    serde_json::to_writer(&mut *line, &seq)?;
    line.extend_from_slice(b",\"t_s\":");
    serde_json::to_writer(&mut *line, &t_s)?;
    line.extend_from_slice(b",\"values\":");
    serde_json::to_writer(&mut *line, values)?;
    line.extend_from_slice(b",\"result\":");
    match result {
        Some(value) => serde_json::to_writer(&mut *line, value),
        None => {
            line.extend_from_slice(b"null");
            Ok(())
        }
    }
}

/// Appends `x` as 8 lower-case hex digits.
fn push_hex(line: &mut Vec<u8>, x: u32) {
    const DIGITS: &[u8; 16] = b"0123456789abcdef";
    line.extend((0..8).rev().map(|i| DIGITS[(x >> (4 * i)) as usize & 0xf]));
}

/// Refuses to append to a recording of other frames.
fn check_same(file: &Header, ours: &Header) -> Result<(), Error> {
    if file.measurements != ours.measurements {
        return Err(Error::Key {
            path: None,
            key: "measurements",
            reason: format!(
                "is {} in the recording, but these frames have {}; record them into another file",
                file.measurements, ours.measurements
            ),
        });
    }
    if file.protocol != ours.protocol {
        return Err(Error::Key {
            path: None,
            key: "protocol",
            reason: format!(
                "is {:?} in the recording, but these frames follow {:?}; record them into another file",
                file.protocol, ours.protocol
            ),
        });
    }
    Ok(())
}

/// An input/output error while writing `path`.
fn write_error(path: &Path, e: &std::io::Error) -> Error {
    Error::Key {
        path: Some(path.to_path_buf()),
        key: "recording",
        reason: format!("cannot be written: {e}; is the disk full, or the folder missing or read-only?"),
    }
}

/// A JSON error while printing a record (which cannot happen for numbers and `Value`s, but is not assumed).
fn json_error(path: &Path, e: &serde_json::Error) -> Error {
    Error::Json { path: Some(path.to_path_buf()), message: e.to_string() }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record_format::CRC_TAIL;

    #[test]
    fn hex_has_eight_lower_case_digits() {
        let mut line = Vec::new();
        push_hex(&mut line, 0x00ab_09ef);
        assert_eq!(line, b"00ab09ef");
        assert_eq!(CRC_TAIL, ",\"crc\":\"00ab09ef\"}".len());
    }
}
