//! Files as sources: a recording, replayed at its pace; a table of frames (MAT, NPY), read whole
//! and timed at a rate; or a capture of a board's bytes, decoded and timed at a rate. Recordings
//! and captures are read as they are delivered, through a buffer.

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

/// Opens `path` as a table of frames (MAT, NPY), a recording or a capture, as its first bytes
/// say (see the [module doc](super)), for frames of `measurements` values.
pub(super) fn open(
    path: &Path,
    measurements: usize,
    settings: &SourceSettings,
) -> Result<Box<dyn FrameSource>, SourceError> {
    let read_error = |e: std::io::Error| SourceError::Read { path: path.to_path_buf(), reason: e.to_string() };
    let mut reader = BufReader::with_capacity(READ_BUFFER, File::open(path).map_err(read_error)?);
    // A byte-order mark (an editor's "UTF-8 with BOM") is not part of the first record or line.
    if reader.fill_buf().map_err(read_error)?.starts_with(b"\xef\xbb\xbf") {
        reader.consume(3);
    }
    let head = reader.fill_buf().map_err(read_error)?;
    if head.starts_with(b"\x93NUMPY") || head.starts_with(b"MATLAB") {
        return Ok(Box::new(TableSource::open(path, measurements, settings)?));
    }
    if head.iter().find(|b| !b.is_ascii_whitespace()) == Some(&b'{') {
        // Another of eitskin's JSON files is named as what it is.
        if let Some(what) = crate::json_file_kind(head) {
            let reason = format!("this is {what}, not a recording (what `eitskin run --record` writes)");
            return Err(SourceError::Recording { path: path.to_path_buf(), reason });
        }
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

/// A table of frames from a MAT (v5, v7.3) or NPY file, as published data sets and numpy save
/// them (MATLAB's frames in columns, numpy's in rows; the file's only numeric array), read whole
/// and timed as a capture. Complex values come as (re, im) pairs, two numbers per measurement.
#[derive(Debug)]
pub struct TableSource {
    /// Its frames, in order.
    frames: std::vec::IntoIter<Vec<f64>>,
    /// The number of the next frame.
    seq: u64,
    /// When each frame is timed and delivered.
    clock: Clock,
}

impl TableSource {
    /// The frames of the table in `path`, each of `measurements` values (per measurement, one
    /// real number, or two for a complex table read with two values a measurement), timed as
    /// `settings` say.
    pub fn open(path: &Path, measurements: usize, settings: &SourceSettings) -> Result<TableSource, SourceError> {
        let table = crate::read_frames(path, &crate::FrameSelect::default())
            .map_err(|e| SourceError::TableRead { message: crate::full_message(&e) })?;
        let per = settings.values_per_measurement;
        let frames: Vec<Vec<f64>> = match (table.imaginary, per) {
            (Some(imaginary), 2) => table
                .frames
                .iter()
                .zip(&imaginary)
                .map(|(re, im)| re.iter().zip(im).flat_map(|(r, i)| [*r, *i]).collect())
                .collect(),
            (Some(_), _) => {
                let reason = "holds complex values: read them as (re, im) pairs (`--values complex`)".to_string();
                return Err(SourceError::Table { path: path.to_path_buf(), reason });
            }
            (None, _) => table.frames,
        };
        if let Some(first) = frames.first().filter(|f| f.len() != measurements) {
            let reason = format!(
                "its frames hold {} values, but the sensor's frames have {measurements}; is it another protocol, or its frames the other way (rows for columns)?",
                first.len()
            );
            return Err(SourceError::Table { path: path.to_path_buf(), reason });
        }
        Ok(TableSource { frames: frames.into_iter(), seq: 0, clock: Clock::new(settings.rate, settings.speed) })
    }
}

impl FrameSource for TableSource {
    fn acquire(&mut self) -> Option<Result<Acquired, SourceError>> {
        let values = self.frames.next()?;
        let (seq, t) = (self.seq, self.clock.tick());
        self.seq += 1;
        Some(Ok(Acquired::Frame { seq, t, values }))
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
    /// When each frame is timed and delivered.
    clock: Clock,
}

/// The clock of a file without times: frame k at k / rate s, delivered then in real time;
/// without a rate, each frame timed as it is read.
#[derive(Debug)]
struct Clock {
    /// One frame, if there is a rate.
    period: Option<Duration>,
    /// Frames a second (0: none).
    rate: f64,
    /// Whether to wait until each frame is due.
    wait: bool,
    /// The frames delivered so far.
    delivered: u64,
    /// When the first frame was delivered.
    start: Option<Instant>,
}

impl Clock {
    /// At `rate` frames/s (0: none), delivered at `speed`.
    fn new(rate: f64, speed: Speed) -> Clock {
        let period = (rate > 0.0).then(|| Duration::try_from_secs_f64(1.0 / rate).ok()).flatten();
        Clock { period, rate, wait: speed == Speed::Recorded, delivered: 0, start: None }
    }

    /// The time of the next frame, in s, waiting until it is due in real time.
    fn tick(&mut self) -> f64 {
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
        CaptureSource {
            path: path.to_path_buf(),
            reader,
            decoder: codec.decoder(measurements),
            decoded: Vec::new(),
            pending: VecDeque::new(),
            read_all: false,
            clock: Clock::new(rate, speed),
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
}

impl FrameSource for CaptureSource {
    fn acquire(&mut self) -> Option<Result<Acquired, SourceError>> {
        loop {
            match self.pending.pop_front() {
                Some(Event::Frame(frame)) => {
                    let t = self.clock.tick();
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
        f.debug_struct("CaptureSource").field("path", &self.path).field("clock", &self.clock).finish_non_exhaustive()
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

    /// An NPY file of `rows` × `columns` numbers of dtype `descr` from `bytes`.
    fn npy(path: &Path, descr: &str, shape: [usize; 2], bytes: &[u8]) {
        std::fs::write(path, eitskin_testdata::npy(descr, shape, bytes)).unwrap();
    }

    /// A numpy table of frames (one per row) is a source of its frames, timed at k / rate; a
    /// complex one gives (re, im) pairs with two values a measurement and is refused with one;
    /// frames of another length are refused, saying so.
    #[test]
    fn a_table_of_frames_streams_each_row() {
        let (_dir, path) = scratch("frames.npy");
        let values: Vec<f64> = (0..12).map(f64::from).collect();
        npy(&path, "<f8", [3, 4], &values.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>());
        let frames = all(open(&path, 4, &settings(Codec::Lines, 20.0)).unwrap());
        let expected: Vec<Acquired> = (0..3)
            .map(|k| Acquired::Frame { seq: k, t: k as f64 / 20.0, values: values[4 * k as usize..][..4].to_vec() })
            .collect();
        assert_eq!(frames, expected);
        let refused = open(&path, 5, &settings(Codec::Lines, 20.0)).err().unwrap().to_string();
        assert!(refused.contains("its frames hold 4 values, but the sensor's frames have 5"), "{refused}");

        let complex: Vec<u8> = values.iter().flat_map(|v| [v.to_le_bytes(), (-v).to_le_bytes()].concat()).collect();
        npy(&path, "<c16", [3, 4], &complex);
        let pairs = SourceSettings { values_per_measurement: 2, ..settings(Codec::Lines, 20.0) };
        let Acquired::Frame { values: first, .. } = &all(open(&path, 8, &pairs).unwrap())[0] else { panic!() };
        assert_eq!(first, &[0.0, -0.0, 1.0, -1.0, 2.0, -2.0, 3.0, -3.0]);
        let refused = open(&path, 4, &settings(Codec::Lines, 20.0)).err().unwrap().to_string();
        assert!(refused.contains("holds complex values: read them as (re, im) pairs"), "{refused}");
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
        // A calibration given as a source is named as one; a recording saved with a byte-order
        // mark is still a recording.
        let (_dir, path) = scratch("cal.json");
        std::fs::write(&path, "{\n  \"format\": \"eitskin-calibration\",\n  \"version\": 6\n}").unwrap();
        let error = open(&path, 120, &settings(Codec::Lines, 0.0)).err().unwrap().to_string();
        assert!(
            error.contains("this is a calibration (what `eitskin calibrate --out` writes), not a recording"),
            "{error}"
        );
        let (_dir, path) = scratch("bom.jsonl");
        Recorder::create(&path, &Header::now(16, "p")).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        std::fs::write(&path, format!("\u{feff}{text}")).unwrap();
        let error = open(&path, 120, &settings(Codec::Lines, 0.0)).err().unwrap().to_string();
        assert!(error.contains("frames of 16 values"), "read as a recording: {error}");
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
