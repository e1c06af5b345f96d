//! The recorder and replay. What is recorded reads back bit for bit; a file cut anywhere in its
//! last record, or with a changed byte in the middle, loses that record only and says which line; a
//! recording is never overwritten by accident and can be continued; and a recorder killed with SIGKILL
//! loses no record it had reported as written.

use std::io::BufRead;
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use eitskin_io::codec::{BadFrame, Event};
use eitskin_io::recorder::{Header, Mode, Recorder};
use eitskin_io::replay::{read_recording, replay_lines, Corrupt, Damage, Record, Skipped};
use serde_json::json;
use tempfile::TempDir;

/// A fresh, empty folder for one test, removed when dropped (when the test ends, passed or failed).
fn folder(name: &str) -> TempDir {
    tempfile::Builder::new().prefix(&format!("eitskin-recorder-{name}-")).tempdir().expect("a temporary folder")
}

/// A header with a fixed start, so that it can be compared.
fn header(measurements: usize) -> Header {
    Header { measurements, protocol: "two-terminal".to_string(), started_unix_s: 1_767_225_600.125 }
}

/// The values of frame `seq`: awkward floats whose every bit matters.
fn values(seq: u64, measurements: usize) -> Vec<f64> {
    (0..measurements)
        .map(|i| ((seq as f64 + 1.0) * (i as f64 + 0.1)).sin() / 3.0 * 10f64.powi(i as i32 % 7 - 3))
        .collect()
}

/// Frame `seq` as it should read back; every third frame has no result, the others a non-ASCII one.
fn record(seq: u64, measurements: usize) -> Record {
    let result = (!seq.is_multiple_of(3))
        .then(|| json!({ "touches": [{ "x_m": 0.05, "force_N": seq as f64 * 0.1, "unit": "Ω" }] }));
    Record { seq, t_s: seq as f64 * 0.0125, values: values(seq, measurements), result }
}

/// Writes `records` into a new recording.
fn write(path: &Path, measurements: usize, records: &[Record]) {
    let mut recorder = Recorder::create(path, &header(measurements)).expect("a new recording");
    for r in records {
        recorder.record(r.seq, r.t_s, &r.values, r.result.as_ref()).expect("recorded");
    }
}

fn bits(records: &[Record]) -> Vec<(u64, u64, Vec<u64>, Option<serde_json::Value>)> {
    records
        .iter()
        .map(|r| (r.seq, r.t_s.to_bits(), r.values.iter().map(|x| x.to_bits()).collect(), r.result.clone()))
        .collect()
}

#[test]
fn recorder_round_trip_is_bit_exact() {
    let dir = folder("round-trip");
    let path = dir.path().join("run.jsonl");
    let mut records: Vec<Record> = (0..20).map(|seq| record(seq, 16)).collect();
    records[4].values[..8].copy_from_slice(&[
        0.1,
        -0.0,
        5e-324,
        f64::MIN_POSITIVE,
        f64::MAX,
        std::f64::consts::PI,
        1.0 / 3.0,
        -123_456_789.012_345_68,
    ]);
    records[4].t_s = 1e-9 / 3.0;
    write(&path, 16, &records);
    let recording = read_recording(&path).expect("readable");
    assert_eq!(recording.header, header(16));
    assert_eq!(recording.skipped, Skipped::default());
    assert_eq!(bits(&recording.records), bits(&records));
    // The header line is as documented, fields in order.
    let text = std::fs::read_to_string(&path).expect("readable");
    assert!(
        text.starts_with(
            "{\"format\":\"eitskin-recording\",\"version\":2,\"measurements\":16,\"protocol\":\"two-terminal\",\
             \"started_unix_s\":1767225600.125}\n{\"seq\":0,\"t_s\":0.0,\"values\":["
        ),
        "{}",
        &text[..200]
    );
    assert_eq!(text.lines().count(), 21);
}

#[test]
fn recorder_cut_anywhere_in_the_last_record_loses_only_it() {
    let dir = folder("cut");
    let path = dir.path().join("run.jsonl");
    let records: Vec<Record> = (0..5).map(|seq| record(seq, 8)).collect();
    write(&path, 8, &records);
    let bytes = std::fs::read(&path).expect("readable");
    assert_eq!(bytes.last(), Some(&b'\n'));
    let start = bytes[..bytes.len() - 1].iter().rposition(|&b| b == b'\n').expect("several lines") + 1;
    let cut_path = dir.path().join("cut.jsonl");
    for cut in start..=bytes.len() {
        std::fs::write(&cut_path, &bytes[..cut]).expect("writable");
        let recording = read_recording(&cut_path).unwrap_or_else(|e| panic!("cut at {cut}: {e}"));
        let (whole, torn) = match cut {
            c if c == start => (4, None),
            c if c == bytes.len() => (5, None),
            _ => (4, Some(6)), // the header is line 1, record 4 is line 6
        };
        assert_eq!(bits(&recording.records), bits(&records[..whole]), "cut at {cut}");
        assert_eq!(recording.skipped, Skipped { torn_tail: torn, corrupt: vec![] }, "cut at {cut}");
    }
}

#[test]
fn recorder_a_changed_digit_is_caught_by_the_crc_and_named_by_line() {
    let dir = folder("flip");
    let path = dir.path().join("run.jsonl");
    let records: Vec<Record> = (0..5).map(|seq| record(seq, 8)).collect();
    write(&path, 8, &records);
    let text = std::fs::read_to_string(&path).expect("readable");
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    // Line 4 is record 2; change the first digit after its `"values":[`, keeping valid JSON.
    let at = lines[3].find("\"values\":[").expect("values") + 10;
    let at = at + lines[3][at..].find(|c: char| c.is_ascii_digit() && c != '0').expect("a digit");
    let old = lines[3].as_bytes()[at];
    let new = if old == b'9' { '8' } else { (old + 1) as char };
    lines[3].replace_range(at..at + 1, &new.to_string());
    serde_json::from_str::<serde_json::Value>(&lines[3]).expect("still valid JSON: only the CRC can tell");
    std::fs::write(&path, lines.join("\n") + "\n").expect("writable");

    let recording = read_recording(&path).expect("readable");
    let seqs: Vec<u64> = recording.records.iter().map(|r| r.seq).collect();
    assert_eq!(seqs, [0, 1, 3, 4]);
    assert_eq!(bits(&recording.records[2..]), bits(&records[3..]));
    assert_eq!(recording.skipped.torn_tail, None);
    let [Corrupt { line, damage: Damage::Crc { stored, computed } }] = &recording.skipped.corrupt[..] else {
        panic!("one CRC mismatch expected: {:?}", recording.skipped);
    };
    assert_eq!((*line, stored == computed), (4, false));
}

#[test]
fn recorder_create_refuses_an_existing_file() {
    let dir = folder("refuse");
    let path = dir.path().join("run.jsonl");
    write(&path, 4, &[record(0, 4)]);
    let before = std::fs::read(&path).expect("readable");
    let err = Recorder::create(&path, &header(4)).expect_err("refused");
    let message = err.to_string();
    assert!(message.contains("run.jsonl") && message.contains("already exists"), "{message}");
    assert_eq!(std::fs::read(&path).expect("readable"), before, "the file is untouched");
    // Overwriting on purpose starts afresh.
    let recorder = Recorder::create_with(&path, &header(4), Mode::Overwrite).expect("overwritten");
    assert_eq!(recorder.last_seq(), None);
    assert!(read_recording(&path).expect("readable").records.is_empty());
}

#[test]
fn recorder_append_continues_the_recording() {
    let dir = folder("append");
    let path = dir.path().join("run.jsonl");
    let records: Vec<Record> = (0..6).map(|seq| record(seq, 4)).collect();
    write(&path, 4, &records[..3]);
    let later = Header { started_unix_s: 2e9, ..header(4) };
    let mut recorder = Recorder::create_with(&path, &later, Mode::Append).expect("appending");
    assert_eq!(recorder.last_seq(), Some(2));
    assert_eq!(recorder.header(), &header(4), "the file's start is kept");
    for r in &records[3..] {
        recorder.record(r.seq, r.t_s, &r.values, r.result.as_ref()).expect("recorded");
    }
    let recording = read_recording(&path).expect("readable");
    assert_eq!(recording.header, header(4));
    assert_eq!(bits(&recording.records), bits(&records));
    assert!(recording.skipped.is_empty());

    // Frames of another length are refused and the file is untouched.
    let before = std::fs::read(&path).expect("readable");
    let err = Recorder::create_with(&path, &header(5), Mode::Append).expect_err("refused");
    assert!(err.to_string().contains("`measurements` is 4 in the recording, but these frames have 5"), "{err}");
    assert_eq!(std::fs::read(&path).expect("readable"), before);
}

#[test]
fn recorder_append_after_a_crash_keeps_the_torn_line_apart() {
    let dir = folder("append-torn");
    let path = dir.path().join("run.jsonl");
    let records: Vec<Record> = (0..5).map(|seq| record(seq, 4)).collect();
    write(&path, 4, &records[..3]);
    let bytes = std::fs::read(&path).expect("readable");
    std::fs::write(&path, &bytes[..bytes.len() - 20]).expect("writable"); // record 2 torn
    let mut recorder = Recorder::create_with(&path, &header(4), Mode::Append).expect("appending");
    assert_eq!(recorder.last_seq(), Some(1));
    for r in &records[3..] {
        recorder.record(r.seq, r.t_s, &r.values, r.result.as_ref()).expect("recorded");
    }
    let recording = read_recording(&path).expect("readable");
    let kept = [&records[..2], &records[3..]].concat();
    assert_eq!(bits(&recording.records), bits(&kept));
    assert_eq!(recording.skipped.torn_tail, None);
    assert_eq!(recording.skipped.corrupt.len(), 1);
    assert_eq!(recording.skipped.corrupt[0].line, 4, "record 2 on line 4 is now in the middle");
}

#[test]
fn recorder_refuses_frames_that_would_not_read_back() {
    let dir = folder("refuse-frames");
    let path = dir.path().join("run.jsonl");
    let mut recorder = Recorder::create(&path, &header(3)).expect("a new recording");
    let err = recorder.record(7, 0.0, &[1.0, 2.0], None).expect_err("too short");
    assert!(err.to_string().contains("frame seq 7 has 2 values, but the recording holds frames of 3"), "{err}");
    assert!(recorder.record(9, f64::INFINITY, &[1.0, 2.0, 3.0], None).is_err());
    recorder.record(10, 0.5, &[1.0, 2.0, 3.0], Some(&serde_json::Value::Null)).expect("recorded");
    recorder.sync().expect("synced");
    let recording = read_recording(&path).expect("readable");
    assert_eq!(recording.records, [Record { seq: 10, t_s: 0.5, values: vec![1.0, 2.0, 3.0], result: None }]);
}

/// A channel the board lost (NaN or ∞) is recorded as `null` and reads back as NaN, the rest bit for bit.
#[test]
fn a_lost_channel_is_recorded_as_null_and_reads_back_as_nan() {
    let dir = folder("lost-channel");
    let path = dir.path().join("run.jsonl");
    let mut recorder = Recorder::create(&path, &header(3)).expect("a new recording");
    recorder.record(3, 0.25, &[0.1, f64::NAN, f64::NEG_INFINITY], None).expect("recorded");
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("\"values\":[0.1,null,null]"), "{text}");
    let recording = read_recording(&path).expect("readable");
    let values = &recording.records[0].values;
    assert!(values[0] == 0.1 && values[1].is_nan() && values[2].is_nan(), "{values:?}");
    // A version-1 file (no nulls then) still reads.
    std::fs::write(&path, text.replace("\"version\":2", "\"version\":1")).unwrap();
    assert_eq!(read_recording(&path).expect("version 1 reads").records.len(), 1);
}

#[test]
fn replay_rejects_what_is_not_a_recording() {
    let dir = folder("not-a-recording");
    let path = dir.path().join("x.jsonl");
    let rest = "\"measurements\":1,\"protocol\":\"p\",\"started_unix_s\":0}\n";
    for (text, says) in [
        (String::new(), "`header` is missing"),
        (format!("{{\"format\":\"other\",\"version\":1,{rest}"), "`format`"),
        (format!("{{\"format\":\"eitskin-recording\",\"version\":3,{rest}"), "`version` is 3"),
        ("1 2 3\n".to_string(), "header"),
    ] {
        std::fs::write(&path, &text).expect("writable");
        let err = read_recording(&path).expect_err(&text).to_string();
        assert!(err.starts_with(&path.display().to_string()) && err.contains(says), "{err}");
    }
}

#[test]
fn replay_lines_decodes_an_openeit_capture() {
    // 51 lines, of which line 21 (seq 20) was torn in the capture: 24 values instead of 28.
    let Some(shared) = eitskin_testdata::shared() else { return };
    let path = shared.join("data/openeit/anticlockwise_motion.txt");
    let events = replay_lines(&path, 28).expect("readable");
    assert_eq!(events.len(), 51);
    assert_eq!(events[20], Event::Bad(BadFrame::WrongCount { seq: 20, expected: 28, got: 24 }));
    assert!(events.iter().enumerate().all(|(i, e)| i == 20 || matches!(e, Event::Frame(f) if f.seq == i as u64)));
    assert!(replay_lines(&path.with_file_name("missing.txt"), 28).is_err());
}

/// The environment variable that makes [`recorder_crash_child`] record; it holds the file's path.
const CHILD: &str = "EITSKIN_RECORDER_CHILD";

/// Not a test on its own: run by [`recorder_survives_sigkill`] as a child process that records
/// until it is killed. Without the variable it returns at once.
#[test]
fn recorder_crash_child() {
    let Some(path) = std::env::var_os(CHILD) else { return };
    let mut recorder = Recorder::create(Path::new(&path), &header(32)).expect("a new recording");
    // Bounded, in case the parent dies before killing this process.
    let deadline = Instant::now() + Duration::from_secs(30);
    for seq in 0.. {
        let r = record(seq, 32);
        recorder.record(r.seq, r.t_s, &r.values, r.result.as_ref()).expect("recorded");
        println!("recorded {seq}");
        if Instant::now() > deadline {
            break;
        }
    }
}

#[cfg(unix)]
#[test]
fn recorder_survives_sigkill() {
    use std::os::unix::process::ExitStatusExt;

    let dir = folder("sigkill");
    let path = dir.path().join("run.jsonl");
    let mut child = Command::new(std::env::current_exe().expect("the test binary"))
        .args(["--exact", "recorder_crash_child", "--nocapture", "--test-threads=1"])
        .env(CHILD, &path)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("the child starts");
    let stdout = child.stdout.take().expect("piped");
    let (send, receive) = mpsc::channel();
    let reader = std::thread::spawn(move || {
        let mut stdout = std::io::BufReader::new(stdout);
        let mut line = String::new();
        // Only whole lines count: each is printed after its record() returned. The first follows the
        // harness's "test … " on the same line.
        while stdout.read_line(&mut line).is_ok_and(|n| n > 0) && line.ends_with('\n') {
            if let Some(seq) = line.trim_end().rsplit_once("recorded ").and_then(|(_, s)| s.parse::<u64>().ok()) {
                if send.send(seq).is_err() {
                    break;
                }
            }
            line.clear();
        }
    });
    let deadline = Instant::now() + Duration::from_secs(3);
    let mut reported = Vec::new();
    while reported.len() < 200 {
        match receive.recv_timeout(deadline.saturating_duration_since(Instant::now())) {
            Ok(seq) => reported.push(seq),
            Err(_) => break,
        }
    }
    child.kill().expect("killed"); // SIGKILL on Unix
    let status = child.wait().expect("reaped");
    assert_eq!(status.signal(), Some(9), "the child must die by SIGKILL, not finish: {status:?}");
    reader.join().expect("the reader ends at the end of the pipe");
    reported.extend(receive.try_iter());
    assert!(!reported.is_empty(), "the child reported no record within 3 s");

    let recording = read_recording(&path).expect("readable after a kill");
    println!(
        "{} records reported, {} read back, torn tail {:?}",
        reported.len(),
        recording.records.len(),
        recording.skipped.torn_tail
    );
    assert!(recording.skipped.corrupt.is_empty(), "{:?}", recording.skipped);
    let last = *reported.last().expect("not empty");
    assert_eq!(reported, (0..=last).collect::<Vec<_>>(), "reported in order");
    assert!(recording.records.len() as u64 > last, "{} records, {} reported", recording.records.len(), last + 1);
    let want: Vec<Record> = (0..recording.records.len() as u64).map(|seq| record(seq, 32)).collect();
    assert_eq!(bits(&recording.records), bits(&want), "every record unchanged, the reported ones included");
}
