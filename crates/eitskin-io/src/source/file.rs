//! Files as sources: a recording, replayed at its pace, or a capture of a board's bytes, decoded
//! and timed at a rate. Both read the file as they deliver it, through a buffer.

use std::collections::VecDeque;
use std::fs::File;
use std::io::{BufRead, BufReader, ErrorKind};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use super::{wait_for_frame, Acquired, Codec, FrameSource, SourceError, SourceSettings};
use crate::codec::{Decoder, Event};
use crate::replay::{Entry, Pace, RecordReader, Speed};

/// How much of a file is read at once, in bytes.
const READ_BUFFER: usize = 64 * 1024;

/// Opens `path` as a recording or as a capture, as its first character says (see the
/// [module doc](super)), for frames of `measurements` values.
pub(super) fn open(
    path: &Path,
    measurements: usize,
    settings: &SourceSettings,
) -> Result<Box<dyn FrameSource>, SourceError> {
    let read_error = |e: std::io::Error| SourceError::Read { path: path.to_path_buf(), reason: e.to_string() };
    let mut reader = BufReader::with_capacity(READ_BUFFER, File::open(path).map_err(read_error)?);
    let head = reader.fill_buf().map_err(read_error)?;
    if head.iter().find(|b| !b.is_ascii_whitespace()) == Some(&b'{') {
        Ok(Box::new(RecordingSource::new(path, reader, measurements, settings.speed)?))
    } else {
        Ok(Box::new(CaptureSource::new(path, reader, measurements, settings.codec, settings.rate, settings.speed)))
    }
}

/// A recording written by the [`Recorder`](crate::recorder::Recorder), replayed one record at a
/// time: each frame with its recorded sequence number and time, each damaged record as an
/// [`Acquired::Skipped`] item.
#[derive(Debug)]
pub struct RecordingSource {
    /// The file, for messages.
    path: PathBuf,
    /// Its records.
    records: RecordReader<BufReader<File>>,
    /// When to deliver each frame.
    pace: Pace,
    /// When the first frame was delivered.
    start: Option<Instant>,
}

impl RecordingSource {
    /// The recording in `path`, read from `reader` (at the file's start), of frames of
    /// `measurements` values, replayed at `speed`; an error if its header is not a recording's or
    /// its frames are of another length.
    pub fn new(
        path: &Path,
        reader: BufReader<File>,
        measurements: usize,
        speed: Speed,
    ) -> Result<RecordingSource, SourceError> {
        let refuse = |reason: String| SourceError::Recording { path: path.to_path_buf(), reason };
        let records = RecordReader::new(reader).map_err(|e| refuse(e.to_string()))?;
        let recorded = records.header().measurements;
        if recorded != measurements {
            return Err(SourceError::RecordingLength { path: path.to_path_buf(), recorded, measurements });
        }
        Ok(RecordingSource { path: path.to_path_buf(), records, pace: Pace::new(speed), start: None })
    }

    /// Opens the recording in `path`; see [`RecordingSource::new`].
    pub fn open(path: &Path, measurements: usize, speed: Speed) -> Result<RecordingSource, SourceError> {
        let file =
            File::open(path).map_err(|e| SourceError::Read { path: path.to_path_buf(), reason: e.to_string() })?;
        RecordingSource::new(path, BufReader::with_capacity(READ_BUFFER, file), measurements, speed)
    }
}

impl FrameSource for RecordingSource {
    fn acquire(&mut self) -> Option<Result<Acquired, SourceError>> {
        Some(Ok(match self.records.next()? {
            Err(e) => return Some(Err(SourceError::Read { path: self.path.clone(), reason: e.to_string() })),
            Ok(Entry::Record(record)) => {
                let start = *self.start.get_or_insert_with(Instant::now);
                std::thread::sleep(self.pace.delay(record.t_s, start.elapsed()));
                Acquired::Frame { seq: record.seq, t: record.t_s, values: record.values }
            }
            Ok(Entry::Corrupt(record)) => Acquired::Skipped { record, torn_tail: false },
            Ok(Entry::TornTail(record)) => Acquired::Skipped { record, torn_tail: true },
        }))
    }
}

/// A capture: the bytes a board sends (one frame per text line, or binary frames), saved to a
/// file, decoded with a [`Codec`]. A capture has no times: frame k is timed at k / rate s and, in
/// real time, delivered then; without a rate, frames are timed as they are read.
pub struct CaptureSource {
    /// The file, for messages.
    path: PathBuf,
    /// The file, read a buffer at a time.
    reader: BufReader<File>,
    /// Decodes the bytes.
    decoder: Box<dyn Decoder + Send>,
    /// What the decoder gave, reused.
    decoded: Vec<Event>,
    /// Decoded and not yet delivered.
    pending: VecDeque<Event>,
    /// Whether the file has been read to its end.
    read_all: bool,
    /// The period of the clock, one frame, if there is a rate.
    period: Option<Duration>,
    /// Frames a second of the clock (0: none).
    rate: f64,
    /// Whether to wait until each frame is due.
    wait: bool,
    /// The frames delivered so far.
    delivered: u64,
    /// When the first frame was delivered.
    start: Option<Instant>,
}

impl CaptureSource {
    /// The capture in `path`, read from `reader`, of frames of `measurements` values encoded as
    /// `codec`; at `rate` frames/s (0: no clock), delivered at `speed`.
    pub fn new(
        path: &Path,
        reader: BufReader<File>,
        measurements: usize,
        codec: Codec,
        rate: f64,
        speed: Speed,
    ) -> CaptureSource {
        let period = (rate > 0.0).then(|| Duration::try_from_secs_f64(1.0 / rate).ok()).flatten();
        CaptureSource {
            path: path.to_path_buf(),
            reader,
            decoder: codec.decoder(measurements),
            decoded: Vec::new(),
            pending: VecDeque::new(),
            read_all: false,
            period,
            rate,
            wait: speed == Speed::Recorded,
            delivered: 0,
            start: None,
        }
    }

    /// Opens the capture in `path`; see [`CaptureSource::new`].
    pub fn open(
        path: &Path,
        measurements: usize,
        codec: Codec,
        rate: f64,
        speed: Speed,
    ) -> Result<CaptureSource, SourceError> {
        let file =
            File::open(path).map_err(|e| SourceError::Read { path: path.to_path_buf(), reason: e.to_string() })?;
        Ok(CaptureSource::new(path, BufReader::with_capacity(READ_BUFFER, file), measurements, codec, rate, speed))
    }

    /// Decodes the next buffer of the file (or ends the stream at its end) into `pending`.
    fn read_more(&mut self) -> Result<(), SourceError> {
        let bytes = loop {
            match self.reader.fill_buf() {
                Ok(bytes) => break bytes,
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                Err(e) => {
                    self.read_all = true;
                    return Err(SourceError::Read { path: self.path.clone(), reason: e.to_string() });
                }
            }
        };
        if bytes.is_empty() {
            self.decoder.finish(&mut self.decoded);
            self.read_all = true;
        } else {
            self.decoder.feed(bytes, &mut self.decoded);
            let count = bytes.len();
            self.reader.consume(count);
        }
        self.pending.extend(self.decoded.drain(..));
        Ok(())
    }

    /// The time of the next frame, in s, waiting until it is due in real time.
    fn clock(&mut self) -> f64 {
        let k = self.delivered;
        self.delivered += 1;
        let start = *self.start.get_or_insert_with(Instant::now);
        match self.period {
            Some(period) => {
                if self.wait {
                    wait_for_frame(start, period, k);
                }
                // k / rate, rounded once.
                k as f64 / self.rate
            }
            None => start.elapsed().as_secs_f64(),
        }
    }
}

impl FrameSource for CaptureSource {
    fn acquire(&mut self) -> Option<Result<Acquired, SourceError>> {
        loop {
            match self.pending.pop_front() {
                Some(Event::Frame(frame)) => {
                    let t = self.clock();
                    return Some(Ok(Acquired::Frame { seq: frame.seq, t, values: frame.values }));
                }
                Some(Event::Bad(bad)) => return Some(Ok(Acquired::Bad(bad))),
                None if self.read_all => return None,
                None => {
                    if let Err(e) = self.read_more() {
                        return Some(Err(e));
                    }
                }
            }
        }
    }
}

impl std::fmt::Debug for CaptureSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CaptureSource")
            .field("path", &self.path)
            .field("period", &self.period)
            .field("wait", &self.wait)
            .field("delivered", &self.delivered)
            .finish_non_exhaustive()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::{encode, BadFrame};
    use crate::recorder::{Header, Recorder};
    use crate::replay::Damage;

    /// A path named `name` in a folder of its own, removed with the folder when the test ends.
    fn scratch(name: &str) -> (tempfile::TempDir, PathBuf) {
        let dir = tempfile::Builder::new().prefix("eitskin-source-file-").tempdir().unwrap();
        let path = dir.path().join(name);
        (dir, path)
    }

    fn settings(codec: Codec, rate: f64) -> SourceSettings {
        SourceSettings { codec, rate, speed: Speed::AsFastAsPossible, ..SourceSettings::default() }
    }

    fn all(mut source: Box<dyn FrameSource>) -> Vec<Acquired> {
        std::iter::from_fn(|| source.acquire()).map(|item| item.unwrap()).collect()
    }

    #[test]
    fn a_recording_streams_its_frames_and_names_each_skipped_record() {
        let (_dir, path) = scratch("damaged.jsonl");
        let mut recorder = Recorder::create(&path, &Header::now(2, "p")).unwrap();
        for seq in 0..4 {
            recorder.record(seq, 0.5 * seq as f64, &[seq as f64, 1.0], None).unwrap();
        }
        drop(recorder);
        let mut text = std::fs::read_to_string(&path).unwrap();
        text = text.replacen("\"seq\":1,", "\"seq\":7,", 1); // line 3: the CRC no longer matches
        text.push_str("{\"seq\":4,\"t_s\":2"); // line 6: torn by a crash
        std::fs::write(&path, text).unwrap();
        let items = all(open(&path, 2, &settings(Codec::Lines, 0.0)).unwrap());
        let seqs: Vec<_> = items
            .iter()
            .map(|item| match item {
                Acquired::Frame { seq, t, .. } => format!("{seq}@{t}"),
                Acquired::Skipped { record, torn_tail } => format!("line {} torn {torn_tail}", record.line),
                other => panic!("{other:?}"),
            })
            .collect();
        assert_eq!(seqs, ["0@0", "line 3 torn false", "2@1", "3@1.5", "line 6 torn true"]);
        assert!(matches!(&items[1], Acquired::Skipped { record, .. } if matches!(record.damage, Damage::Crc { .. })));
    }

    #[test]
    fn a_recording_of_another_length_or_a_json_file_that_is_not_one_is_refused() {
        let (_dir, path) = scratch("other.jsonl");
        Recorder::create(&path, &Header::now(16, "p")).unwrap();
        let error = open(&path, 120, &settings(Codec::Lines, 0.0)).err().unwrap().to_string();
        assert!(error.contains("frames of 16 values") && error.contains("has 120"), "{error}");
        let (_dir, path) = scratch("stdout.jsonl");
        std::fs::write(&path, "\n {\"event\":\"start\",\"format\":\"eitskin-run\"}\n").unwrap();
        let error = open(&path, 120, &settings(Codec::Lines, 0.0)).err().unwrap();
        assert!(matches!(&error, SourceError::Recording { path: p, .. } if p == &path), "{error:?}");
        let (_dir, missing) = scratch("missing.csv");
        let error = open(&missing, 120, &settings(Codec::Lines, 0.0)).err().unwrap();
        assert!(error.to_string().starts_with("cannot read ") && error.to_string().contains("missing.csv"), "{error}");
    }

    #[test]
    fn a_text_capture_is_decoded_and_timed_at_the_rate() {
        let (_dir, path) = scratch("frames.csv");
        // Longer than one read buffer, so that lines are cut between reads.
        let line = |k: usize| format!("{k}, {}\r\n", "1.25 ".repeat(9_999));
        let text = format!("{}1 2\n{}", (0..7).map(line).collect::<String>(), line(7).trim_end());
        std::fs::write(&path, text).unwrap();
        let items = all(open(&path, 10_000, &settings(Codec::Lines, 4.0)).unwrap());
        assert_eq!(items.len(), 9);
        assert_eq!(items[7], Acquired::Bad(BadFrame::WrongCount { seq: 7, expected: 10_000, got: 2 }));
        let frames: Vec<(u64, f64, f64)> = items
            .iter()
            .filter_map(|item| match item {
                Acquired::Frame { seq, t, values } => Some((*seq, *t, values[0])),
                _ => None,
            })
            .collect();
        let want: Vec<(u64, f64, f64)> =
            (0..8u64).map(|k| (k + u64::from(k == 7), k as f64 * 0.25, k as f64)).collect();
        assert_eq!(frames, want, "the last line, without its line ending, is a frame too");
    }

    #[test]
    fn a_binary_capture_is_decoded_with_the_binary_codec() {
        let (_dir, path) = scratch("frames.bin");
        let mut bytes = Vec::new();
        for counter in [5, 6, 8] {
            bytes.extend_from_slice(&encode(counter, &[1.0, 2.0, counter as f32]));
        }
        std::fs::write(&path, bytes).unwrap();
        let items = all(open(&path, 3, &settings(Codec::Binary, 0.0)).unwrap());
        assert!(matches!(&items[0], Acquired::Frame { seq: 5, values, .. } if values == &[1.0, 2.0, 5.0]));
        assert!(matches!(&items[1], Acquired::Frame { seq: 6, .. }));
        assert_eq!(items[2], Acquired::Bad(BadFrame::Gap { seq: 8, missing: 1 }));
        assert!(matches!(&items[3], Acquired::Frame { seq: 8, .. }));
        assert_eq!(items.len(), 4);
    }
}
