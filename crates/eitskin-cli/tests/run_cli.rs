//! Through the real binary: `eitskin run` on the virtual sensor and on a file prints one
//! JSON line per frame, in order, with touches where the presses are, and every bad frame as an
//! event with its reason; the stream goes on after it.

mod binary;

use binary::{scratch, Scratch};
use eitskin_io::stream::{self, Event, FrameLine, Line, Recorded, Start, Status};
use std::process::Output;

/// The lines after the start line.
fn lines(out: Output) -> Vec<serde_json::Value> {
    assert!(out.status.success(), "failed: {}", String::from_utf8_lossy(&out.stderr));
    let mut lines: Vec<serde_json::Value> =
        String::from_utf8(out.stdout).unwrap().lines().map(|l| serde_json::from_str(l).expect("a JSON line")).collect();
    assert_eq!(lines[0]["event"], "start", "the stream starts with its start line: {:?}", lines[0]);
    lines.remove(0);
    lines
}

/// The frame lines after the start line (no events).
fn frames_only(out: Output) -> Vec<serde_json::Value> {
    lines(out).into_iter().filter(|l| l.get("event").is_none()).collect()
}

/// Every line of a run's standard output, read with the schema's types (which refuse unknown
/// fields): the start line, then the rest.
fn typed_lines(out: Output) -> (Start, Vec<Line>) {
    assert!(out.status.success(), "failed: {}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    let mut lines = text.lines().map(|l| Line::parse(l).unwrap_or_else(|e| panic!("{e}: {l}")));
    let Some(Line::Event(Event::Start(start))) = lines.next() else { panic!("no start line first: {text}") };
    (start, lines.collect())
}

fn frame_lines(lines: &[Line]) -> Vec<&FrameLine> {
    lines
        .iter()
        .filter_map(|l| match l {
            Line::Frame(f) => Some(f),
            Line::Event(_) => None,
        })
        .collect()
}

#[test]
fn the_stream_reads_back_with_its_schema_a_start_line_then_counted_frames_in_mm() {
    let dir = scratch("schema");
    let script = dir.join("script.txt");
    std::fs::write(&script, "# start end x y force\n1.0 1.5 -50 40 9\n").unwrap();
    let source = format!("sim:{}", script.display());
    let (start, lines) =
        typed_lines(dir.eitskin(&["run", "--source", &source, "--fast", "--frames", "40", "--triangles", "1500"]));
    assert_eq!((start.format.as_str(), start.version), (stream::FORMAT, stream::VERSION));
    assert_eq!((start.source.as_str(), start.length_unit.as_str()), (source.as_str(), "mm"));
    assert_eq!((start.measurements, start.reference_frames, start.reference_limit), (120, 10, Some(100)));
    let frames = frame_lines(&lines);
    // Two events from a scripted virtual sensor: the reference taken, then the noise measured
    // again once the frames without a touch after it doubled what it was measured on.
    assert_eq!(frames.len() + 2, lines.len(), "{lines:?}");
    let updated =
        lines.iter().position(|l| matches!(l, Line::Event(Event::NoiseUpdated { frames, .. }) if *frames >= 18.0));
    assert_eq!(updated, Some(19), "{lines:?}");
    assert_eq!(frames.len(), 40);
    // The reference taken by the 10th frame (the event comes before that frame's line), with λ
    // chosen from their noise.
    let Line::Event(Event::ReferenceTaken {
        hyperparameter, chosen: true, normalised: false, channels_dropped, ..
    }) = &lines[9]
    else {
        panic!("{:?}", lines[9])
    };
    assert!(*hyperparameter > 0.0 && channels_dropped.is_empty(), "{:?}", lines[9]);
    for (k, frame) in frames.iter().enumerate() {
        assert_eq!((frame.seq, frame.counters.frames, frame.counters.bad), (k as u64, k as u64 + 1, 0), "{frame:?}");
        assert_eq!(frame.status, if k < 10 { Status::Referencing } else { Status::Ok }, "frame {k}");
        assert!(!frame.recorded && frame.counters.viewer_dropped.is_none(), "{frame:?}");
        assert!((frame.t - k as f64 * 0.05).abs() < 1e-9, "the virtual clock at 20 frames/s: {frame:?}");
        let pressed = (1.0..1.5).contains(&frame.t);
        assert_eq!(frame.touches.len(), usize::from(pressed), "{frame:?}");
        for touch in &frame.touches {
            // In mm: 50 mm from the centre, never 0.05 (m).
            assert!((touch.x + 50.0).hypot(touch.y - 40.0) < 15.0, "{touch:?}");
            assert!(touch.peak > 0.0 && touch.force.is_none() && touch.unit.is_none() && touch.press.is_none());
        }
    }

    // A capture: frames and bad lines, each counted once.
    let good = vec!["100"; 120].join(",");
    let capture = dir.join("capture.csv");
    std::fs::write(&capture, format!("{good}\n{good}\n1,2\n{good}\nx\n{good}\n")).unwrap();
    let source = format!("file:{}", capture.display());
    let (_, lines) = typed_lines(dir.eitskin(&[
        "run",
        "--source",
        &source,
        "--fast",
        "--reference-frames",
        "2",
        "--triangles",
        "800",
    ]));
    let bad: Vec<Option<u64>> = lines
        .iter()
        .filter_map(|l| match l {
            Line::Event(Event::Bad { seq, .. }) => Some(*seq),
            _ => None,
        })
        .collect();
    assert_eq!(bad, [Some(2), Some(4)]);
    let counted: Vec<(u64, u64, u64)> =
        frame_lines(&lines).iter().map(|f| (f.seq, f.counters.frames, f.counters.bad)).collect();
    assert_eq!(counted, [(0, 1, 0), (1, 2, 0), (3, 3, 1), (5, 4, 2)]);
}

#[test]
fn a_damaged_record_is_skipped_as_an_event_and_the_recording_holds_the_touches() {
    let dir = scratch("skipped");
    let script = dir.join("script.txt");
    std::fs::write(&script, "0.3 0.6 30 -60 10\n").unwrap();
    let record = dir.join("run.jsonl");
    std::fs::remove_file(&record).ok();
    let source = format!("sim:{}", script.display());
    let (_, live) = typed_lines(dir.eitskin(&[
        "run",
        "--source",
        &source,
        "--frames",
        "16",
        "--fast",
        "--triangles",
        "1500",
        "--reference-frames",
        "4",
        "--record",
        record.to_str().unwrap(),
    ]));
    assert!(frame_lines(&live).iter().all(|f| f.recorded));
    let recording = eitskin_io::replay::read_recording(&record).unwrap();
    for (frame, r) in frame_lines(&live).iter().zip(&recording.records) {
        let attached: Recorded<'static> = serde_json::from_value(r.result.clone().expect("touches attached")).unwrap();
        assert_eq!((r.seq, attached.touches.as_ref()), (frame.seq, frame.touches.as_slice()));
    }
    // Frame 5 (line 7) loses a digit: its CRC no longer matches.
    let text = std::fs::read_to_string(&record).unwrap();
    let mut file: Vec<String> = text.lines().map(String::from).collect();
    file[6] = file[6].replacen("\"seq\":5,", "\"seq\":50,", 1);
    std::fs::write(&record, file.join("\n") + "\n").unwrap();
    let replay = format!("file:{}", record.display());
    let (_, replayed) = typed_lines(dir.eitskin(&[
        "run",
        "--source",
        &replay,
        "--fast",
        "--triangles",
        "1500",
        "--reference-frames",
        "4",
    ]));
    let skipped: Vec<(usize, bool)> = replayed
        .iter()
        .filter_map(|l| match l {
            Line::Event(Event::Skipped { line, torn, .. }) => Some((*line, *torn)),
            _ => None,
        })
        .collect();
    assert_eq!(skipped, [(7, false)]);
    let frames = frame_lines(&replayed);
    assert_eq!(frames.len(), 15);
    assert!(frames.iter().all(|f| f.seq != 5 && f.counters.bad == u64::from(f.seq > 5)), "{frames:?}");
}

#[test]
fn the_virtual_sensor_pressed_by_a_script_gives_a_touch_where_and_when_pressed() {
    let dir = scratch("sim");
    let script = dir.join("script.txt");
    std::fs::write(&script, "# start end x y force\n1.0 1.5 -50 40 9\n").unwrap();
    let source = format!("sim:{}", script.display());
    let out = frames_only(dir.eitskin(&[
        "run",
        "--source",
        &source,
        "--frames",
        "40",
        "--rate",
        "20",
        "--triangles",
        "1500",
    ]));
    assert_eq!(out.len(), 40);
    for (k, line) in out.iter().enumerate() {
        assert_eq!(line["seq"], k as u64, "frames in order");
        let t = line["t"].as_f64().unwrap();
        let touches = line["touches"].as_array().unwrap();
        match k {
            0..=9 => assert_eq!(line["status"], "referencing"),
            _ if (1.0..1.5).contains(&t) => {
                assert_eq!(touches.len(), 1, "t = {t}: {line}");
                let (x, y) = (touches[0]["x"].as_f64().unwrap(), touches[0]["y"].as_f64().unwrap());
                assert!((x + 50.0).hypot(y - 40.0) < 15.0, "touch at ({x}, {y}) mm");
            }
            _ => assert!(touches.is_empty(), "no press at t = {t}: {line}"),
        }
    }
}

/// `--noise`: the virtual sensor's frames vary as much as asked, and the reference measures it
/// (0.4 %, an open board's; 0.01 %, the default and a best case).
#[test]
fn the_virtual_sensor_is_as_noisy_as_asked() {
    let dir = scratch("noise");
    for (noise, asked) in [(Some("0.004"), 0.004), (None, 1e-4)] {
        let mut args = vec!["run", "--fast", "--frames", "12", "--triangles", "1500"];
        args.extend(noise.map(|n| ["--noise", n]).into_iter().flatten());
        let (_, lines) = typed_lines(dir.eitskin(&args));
        let measured = lines.iter().find_map(|l| match l {
            Line::Event(Event::ReferenceTaken { noise: Some(noise), .. }) => Some(*noise),
            _ => None,
        });
        assert!(measured.is_some_and(|m| (m / asked - 1.0).abs() < 0.15), "{noise:?}: {measured:?}");
    }
}

/// `--press-table`: presses found afresh in every frame (`--fresh-presses`), fitted on the press
/// model's tabulated response (`fit`) or on it while it holds (`auto`, the default), are found
/// where the exact fit (`start`) finds them: the same frames with a press, each within 3 mm and
/// 0.05 in drop of the exact fit's.
#[test]
fn presses_fitted_on_the_table_are_those_of_the_exact_fit() {
    let dir = scratch("press-table");
    let script = dir.join("script.txt");
    std::fs::write(&script, "0.6 1.6 30 -20 7\n0.8 1.6 -40 50 11\n").unwrap();
    let source = format!("sim:{}", script.display());
    let run = |table: &[&str]| {
        let args =
            ["run", "--source", &source, "--frames", "40", "--fast", "--fit", "--fresh-presses", "--triangles", "1500"];
        frames_only(dir.eitskin(&[&args[..], table].concat()))
    };
    let presses = |line: &serde_json::Value| -> Vec<(f64, f64, f64)> {
        let touches = line["touches"].as_array().unwrap();
        let press = |t: &serde_json::Value| {
            let p = &t["press"];
            (p["x"].as_f64().unwrap(), p["y"].as_f64().unwrap(), p["drop"].as_f64().unwrap())
        };
        touches.iter().filter(|t| t["press"].is_object()).map(press).collect()
    };
    let exact = run(&["--press-table", "start"]);
    let (table, auto) = (run(&["--press-table", "fit"]), run(&[]));
    for read in [&table, &auto] {
        assert_eq!(exact.len(), read.len());
        let mut pressed = 0;
        for (a, b) in exact.iter().zip(read) {
            let (a, b) = (presses(a), presses(b));
            assert_eq!(a.len(), b.len(), "{a:?} against {b:?}");
            for p in &a {
                let near = b.iter().any(|q| (p.0 - q.0).hypot(p.1 - q.1) < 3.0 && (p.2 - q.2).abs() < 0.05);
                assert!(near, "{p:?} has no match in {b:?}");
            }
            pressed += usize::from(!a.is_empty());
        }
        assert!(pressed >= 10, "{pressed} frames with a press");
    }
    // And the flag is read: the fits are the table's, not the exact fit's to the last digit,
    // and so are the default's (these presses, far apart, fitted on the table).
    let all = |lines: &[serde_json::Value]| lines.iter().flat_map(presses).collect::<Vec<_>>();
    assert_ne!(all(&exact), all(&table));
    assert_ne!(all(&exact), all(&auto));
}

/// One core or two (`--cores`): the same lines, rasters included, byte for byte, since the
/// split product computes each pixel as one core does.
#[test]
fn one_core_gives_the_lines_two_cores_give() {
    let dir = scratch("cores");
    let script = dir.join("script.txt");
    std::fs::write(&script, "0.6 1.2 30 -20 7\n1.0 1.6 -40 50 11\n").unwrap();
    let source = format!("sim:{}", script.display());
    let run = |cores: &str| {
        let args =
            ["--cores", cores, "run", "--source", &source, "--frames", "40", "--fast", "--fit", "--stream-image"];
        binary::ok(dir.eitskin(&[&args[..], &["--triangles", "1500"]].concat()))
    };
    let (one, two) = (run("1"), run("2"));
    assert!(one.contains("\"raster\"") && one.contains("\"press\":{"), "images and presses in the lines: {one}");
    assert_eq!(one, two);
}

/// A first run that ends in newtons: the virtual sensor calibrated first as a user calibrates a
/// board (the paper's six units, 0–15 N), then pressed by a script at places it was not
/// calibrated: each touch has a force within 1 N of the script's, with its standard deviation.
#[test]
fn the_virtual_sensor_calibrated_as_the_paper_does_gives_forces_in_newtons() {
    let dir = scratch("sim-calibrated");
    let script = dir.join("script.txt");
    std::fs::write(&script, "# start end x y force\n1.0 1.5 -50 40 9\n2.0 2.5 60 -20 4\n").unwrap();
    let source = format!("sim:{}", script.display());
    let out = dir.eitskin(&[
        "run",
        "--source",
        &source,
        "--frames",
        "60",
        "--rate",
        "20",
        "--triangles",
        "1500",
        "--virtual-calibration",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(stderr.contains("calibrating the virtual sensor as the paper does"), "{stderr}");
    let mut pressed = 0;
    for line in frames_only(out) {
        let t = line["t"].as_f64().unwrap();
        let scripted = match t {
            _ if (1.0..1.5).contains(&t) => 9.0,
            _ if (2.0..2.5).contains(&t) => 4.0,
            _ => continue,
        };
        let touch = &line["touches"][0];
        let force = touch["force"].as_f64().unwrap_or_else(|| panic!("no force at t = {t}: {line}"));
        assert!((force - scripted).abs() < 1.0 && touch["force_std"].as_f64().unwrap() > 0.0, "t = {t}: {line}");
        pressed += 1;
    }
    assert_eq!(pressed, 20);
    let refused = dir.eitskin(&["run", "--source", "file:x.csv", "--virtual-calibration"]);
    assert!(String::from_utf8_lossy(&refused.stderr).contains("it goes with --source sim"), "{refused:?}");
}

/// A published recording as a table of frames (NPY, one frame per row): replayed through the
/// same path as a capture, the press found where the virtual sensor was pressed.
#[test]
fn a_table_of_frames_replays_like_a_capture() {
    let dir = scratch("table");
    let spec = eitskin::SensorSpec::square_hydrogel();
    let mut skin = eitskin::sim::VirtualSensor::new(&spec, 7).unwrap();
    let mut frames: Vec<Vec<f64>> = (0..12).map(|_| skin.frame().unwrap()).collect();
    skin.press([0.04, -0.05], 10.0);
    frames.extend((0..3).map(|_| skin.frame().unwrap()));
    let values: Vec<u8> = frames.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
    let path = dir.join("frames.npy");
    std::fs::write(&path, eitskin_testdata::npy("<f8", [frames.len(), 120], &values)).unwrap();
    let source = format!("file:{}", path.display());
    let out = frames_only(dir.eitskin(&["run", "--source", &source, "--fast"]));
    assert_eq!(out.len(), 15);
    for line in &out[12..] {
        let touch = &line["touches"][0];
        let (x, y) = (touch["x"].as_f64().unwrap(), touch["y"].as_f64().unwrap());
        assert!((x - 40.0).hypot(y + 50.0) < 15.0, "{line}");
    }
}

/// A source that ends before anything was imaged says so: an empty file is an error (it used
/// to end with the start line alone and exit 0), as is a run that ends before its reference is
/// taken (it warned and exited 0) unless it recorded the frames; a `--frames` too few for the
/// reference is refused before any work.
#[test]
fn a_source_that_ends_before_an_image_says_so() {
    let dir = scratch("empty");
    let empty = dir.join("empty.txt");
    std::fs::write(&empty, "").unwrap();
    let source = format!("file:{}", empty.display());
    let out = dir.eitskin(&["run", "--source", &source, "--triangles", "800"]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.ends_with(&format!("error: {source}: the source ended without a frame (0 bad or skipped)\n")),
        "{stderr}"
    );
    let out = dir.eitskin(&["run", "--frames", "3", "--fast", "--triangles", "800"]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.starts_with("error: --frames 3: the run would end before its reference is taken"), "{stderr}");
    assert!(stderr.contains("--reference-frames 10 × --average 1"), "{stderr}");
    let three = dir.join("three.txt");
    std::fs::write(&three, format!("{}\n", vec!["100"; 120].join(",")).repeat(3)).unwrap();
    let source = format!("file:{}", three.display());
    let out = dir.eitskin(&["run", "--source", &source, "--triangles", "800"]);
    assert_eq!(out.status.code(), Some(1));
    let ended = format!(
        "{source}: the source ended after 3 frames, before the reference (10 frames) was taken: nothing was imaged"
    );
    assert!(String::from_utf8_lossy(&out.stderr).ends_with(&format!("error: {ended}\n")), "{out:?}");
    // Recording was the work: it is whole, and the run succeeds with a warning.
    let record = dir.join("three.jsonl");
    let out = dir.eitskin(&["run", "--source", &source, "--triangles", "800", "--record", record.to_str().unwrap()]);
    assert!(out.status.success(), "{out:?}");
    let warning = format!("warning: {ended} ({} holds the frames)\n", record.display());
    assert!(String::from_utf8_lossy(&out.stderr).ends_with(&warning), "{out:?}");
}

#[test]
fn a_file_with_bad_lines_reports_each_and_goes_on() {
    let dir = scratch("file");
    let good: Vec<String> = (0..3).map(|k| vec![format!("{}", 100.0 + k as f64); 120].join(",")).collect();
    let text = format!(
        "{}\n{}\nmagnitudes: {}\n1,2,3\n{},NaN\n{}\n",
        good[0],
        good[1],
        good[2],
        vec!["100"; 119].join(","),
        good[0]
    );
    let file = dir.join("frames.csv");
    std::fs::write(&file, text).unwrap();
    let source = format!("file:{}", file.display());
    let out = lines(dir.eitskin(&[
        "run",
        "--source",
        &source,
        "--rate",
        "0",
        "--reference-frames",
        "2",
        "--triangles",
        "800",
    ]));
    let events: Vec<&serde_json::Value> = out.iter().filter(|l| l["event"] == "bad").collect();
    let frames: Vec<&serde_json::Value> = out.iter().filter(|l| l.get("event").is_none()).collect();
    assert_eq!(frames.len(), 5, "{out:?}");
    assert_eq!(frames.iter().map(|f| f["seq"].as_u64().unwrap()).collect::<Vec<_>>(), vec![0, 1, 2, 4, 5]);
    assert_eq!(events.len(), 1);
    assert!(events[0]["reason"].as_str().unwrap().contains("has 3 values, expected 120"), "{:?}", events[0]);
    assert_eq!(events[0]["seq"], 3);
    // The NaN is a channel lost, not a bad frame: dropped, named, and the frame imaged.
    let dropped: Vec<&serde_json::Value> = out.iter().filter(|l| l["event"] == "channels_dropped").collect();
    assert_eq!(dropped.len(), 1, "{out:?}");
    assert_eq!(
        (&dropped[0]["seq"], &dropped[0]["channels"], &dropped[0]["dropped"]),
        (&4.into(), &vec![120].into(), &1.into())
    );
    assert_eq!((&frames[3]["status"], &frames[4]["counters"]["bad"]), (&"ok".into(), &1.into()));
}

#[test]
fn a_recording_replays_to_the_same_touches() {
    let dir = scratch("replay");
    let script = dir.join("script.txt");
    std::fs::write(&script, "0.6 1.2 30 -60 10\n").unwrap();
    let record = dir.join("run.jsonl");
    let source = format!("sim:{}", script.display());
    let live = frames_only(dir.eitskin(&[
        "run",
        "--source",
        &source,
        "--frames",
        "30",
        "--fast",
        "--triangles",
        "1500",
        "--record",
        record.to_str().unwrap(),
    ]));
    assert!(live.iter().all(|l| l["recorded"] == true));
    let replay_source = format!("file:{}", record.display());
    let replayed = frames_only(dir.eitskin(&["run", "--source", &replay_source, "--fast", "--triangles", "1500"]));
    assert_eq!(replayed.len(), live.len());
    for (a, b) in live.iter().zip(&replayed) {
        assert_eq!((&a["seq"], &a["touches"]), (&b["seq"], &b["touches"]), "replay differs");
    }
    assert!(live.iter().any(|l| !l["touches"].as_array().unwrap().is_empty()), "the press was seen");
}

#[cfg(unix)]
#[test]
fn every_frame_reported_recorded_before_a_sigkill_is_in_the_file() {
    use std::io::BufRead;
    let dir = scratch("kill");
    let record = dir.join("killed.jsonl");
    let mut child = dir
        .command()
        .args(["run", "--source", "sim", "--rate", "200", "--triangles", "800", "--record", record.to_str().unwrap()])
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let stdout = child.stdout.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in std::io::BufReader::new(stdout).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    let mut reported = Vec::new();
    while reported.len() < 40 && std::time::Instant::now() < deadline {
        if let Ok(line) = rx.recv_timeout(std::time::Duration::from_millis(100)) {
            let v: serde_json::Value = serde_json::from_str(&line).unwrap();
            if v["recorded"] == true {
                reported.push(v["seq"].as_u64().unwrap());
            }
        }
    }
    child.kill().unwrap(); // SIGKILL on Unix
    child.wait().unwrap();
    assert!(reported.len() >= 40, "only {} frames reported before the deadline", reported.len());
    let recording = eitskin_io::replay::read_recording(&record).unwrap();
    let seqs: Vec<u64> = recording.records.iter().map(|r| r.seq).collect();
    for seq in &reported {
        assert!(seqs.contains(seq), "frame {seq} was reported recorded but is not in the file");
    }
    assert!(recording.skipped.corrupt.is_empty(), "{:?}", recording.skipped);
}

#[cfg(unix)]
#[test]
fn frames_from_a_real_pseudo_terminal_come_out_in_order_with_bad_ones_named() {
    use serialport::SerialPort;
    use std::io::{BufRead, Write};
    let (mut master, slave) = serialport::TTYPort::pair().expect("a pseudo-terminal pair");
    let path = slave.name().expect("the slave has a name");
    let source = format!("serial:{path}");
    let dir = scratch("serial");
    let (mut child, _stderr) = run_on_port(&dir, &source, &["--frames", "8"]);
    let good = |k: usize| vec![format!("{}", 150.0 + k as f64 * 1e-3); 120].join(",") + "\r\n";
    let mut text = String::new();
    for k in 0..4 {
        text += &good(k);
    }
    text += "magnitudes: 1, 2, 3\r\n";
    for k in 4..8 {
        text += &good(k);
    }
    let bytes = text.into_bytes();
    for chunk in bytes.chunks(333) {
        master.write_all(chunk).unwrap();
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    let stdout = std::io::BufReader::new(child.stdout.take().unwrap());
    let out: Vec<serde_json::Value> =
        stdout.lines().map_while(Result::ok).map(|l| serde_json::from_str(&l).unwrap()).collect();
    assert!(child.wait().unwrap().success());
    let seqs: Vec<u64> = out.iter().filter(|l| l.get("event").is_none()).map(|l| l["seq"].as_u64().unwrap()).collect();
    assert_eq!(seqs, vec![0, 1, 2, 3, 5, 6, 7, 8], "{out:?}");
    let bad: Vec<&serde_json::Value> = out.iter().filter(|l| l["event"] == "bad").collect();
    assert_eq!(bad.len(), 1);
    assert_eq!(bad[0]["seq"], 4);
    assert!(bad[0]["reason"].as_str().unwrap().contains("has 3 values, expected 120"));
    drop(slave);
}

#[cfg(unix)]
#[test]
fn every_kind_of_bad_line_an_unplug_and_a_return_are_reported_and_the_stream_goes_on() {
    use serialport::SerialPort;
    use std::io::{BufRead, Write};
    use std::time::{Duration, Instant};
    let (master, slave) = serialport::TTYPort::pair().expect("a pseudo-terminal pair");
    // serialport opens the pair without close-on-exec: keep the child from inheriting them, or
    // it would hold the line up after the test pulls the board out.
    #[allow(unsafe_code, reason = "std has no safe way to set close-on-exec on a descriptor it did not open")]
    let close_on_exec = |port: &serialport::TTYPort| {
        // SAFETY: fcntl on a file descriptor this test owns.
        unsafe { libc::fcntl(std::os::fd::AsRawFd::as_raw_fd(port), libc::F_SETFD, libc::FD_CLOEXEC) };
    };
    close_on_exec(&master);
    close_on_exec(&slave);
    let (mut master, mut slave) = (Some(master), Some(slave));
    let path = slave.as_ref().and_then(|s| s.name()).expect("the slave has a name");
    // The port by a stable name, as udev's /dev/serial/by-id links: a new board comes back under it.
    let dir = scratch("pty");
    let link = dir.join("ttyEIT");
    std::fs::remove_file(&link).ok();
    std::os::unix::fs::symlink(&path, &link).unwrap();
    let source = format!("serial:{}", link.display());
    let (mut child, _stderr) = run_on_port(&dir, &source, &[]);
    let (tx, rx) = std::sync::mpsc::channel();
    let stdout = child.stdout.take().unwrap();
    std::thread::spawn(move || {
        for line in std::io::BufReader::new(stdout).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let good = |k: usize| vec![format!("{}", 150.0 + k as f64 * 1e-3); 120].join(",");
    let with = |k: usize, field: &str| {
        let mut v: Vec<String> = good(k).split(',').map(String::from).collect();
        v[7] = field.to_string();
        v.join(",")
    };
    let lines = [
        good(0),             // seq 0: reference
        good(1),             // 1: reference
        good(2),             // 2: imaged
        "1,2,3".to_string(), // 3: wrong count
        with(3, "x"),        // 4: not a number
        with(4, "NaN"),      // 5: channel 8 lost: dropped, and the frame imaged
        "1,".repeat(40_000), // 6: over-long (80 kB)
    ];
    let port = master.as_mut().unwrap();
    for line in &lines {
        port.write_all(line.as_bytes()).unwrap();
        port.write_all(b"\r\n").unwrap();
    }
    let torn = good(5); // 7: arrives in two writes, must come out whole
    port.write_all(&torn.as_bytes()[..100]).unwrap();
    std::thread::sleep(Duration::from_millis(100));
    port.write_all(&torn.as_bytes()[100..]).unwrap();
    port.write_all(b"\n").unwrap();

    let mut out: Vec<serde_json::Value> = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(30);
    let (mut unplugged, mut replugged) = (false, None);
    let done = |out: &[serde_json::Value]| out.iter().filter(|l| l.get("event").is_none()).count() >= 7;
    while Instant::now() < deadline && !done(&out) {
        if let Ok(line) = rx.recv_timeout(Duration::from_millis(100)) {
            out.push(serde_json::from_str(&line).unwrap());
        }
        if !unplugged && out.iter().any(|l| l["seq"] == 7 && l.get("event").is_none()) {
            std::thread::sleep(Duration::from_millis(100)); // let the last bytes be read
            unplugged = true;
            (master, slave) = (None, None); // the board is pulled out
            std::fs::remove_file(&link).unwrap();
        }
        if unplugged && replugged.is_none() && out.iter().any(|l| l["event"] == "disconnected") {
            // A board is plugged back in under the same name and sends two frames.
            let (mut board, port) = serialport::TTYPort::pair().unwrap();
            close_on_exec(&board);
            close_on_exec(&port);
            std::os::unix::fs::symlink(port.name().unwrap(), &link).unwrap();
            board.write_all(format!("{}\n{}\n", good(8), good(9)).as_bytes()).unwrap();
            replugged = Some((board, port));
        }
    }
    child.kill().ok();
    child.wait().ok();
    assert!(master.is_none() && slave.is_none(), "the unplug happened");
    let frames: Vec<u64> =
        out.iter().filter(|l| l.get("event").is_none()).map(|l| l["seq"].as_u64().unwrap()).collect();
    // A new connection starts a new line count: the board's frames after the return are 0 and 1.
    assert_eq!(frames, vec![0, 1, 2, 5, 7, 0, 1], "{out:?}");
    let dropped = out.iter().find(|l| l["event"] == "channels_dropped").expect("the lost channel is named");
    assert_eq!((&dropped["seq"], &dropped["channels"]), (&5.into(), &vec![8].into()), "{dropped}");
    let reconnected = out.iter().position(|l| l["event"] == "reconnected").expect("the return is reported");
    assert!(out.iter().position(|l| l["event"] == "disconnected").unwrap() < reconnected);
    drop(replugged);
    let reasons: Vec<(u64, String)> = out
        .iter()
        .filter(|l| l["event"] == "bad")
        .map(|l| (l["seq"].as_u64().unwrap(), l["reason"].as_str().unwrap().to_string()))
        .collect();
    let expect = [(3, "has 3 values, expected 120"), (4, "\"x\""), (6, "bytes long")];
    assert_eq!(reasons.len(), expect.len(), "{reasons:?}");
    for ((seq, reason), (want_seq, want)) in reasons.iter().zip(expect) {
        assert_eq!(*seq, want_seq);
        assert!(reason.contains(want), "seq {seq}: {reason:?} does not say {want:?}");
    }
    assert!(out.iter().any(|l| l["event"] == "disconnected"), "the unplug was not reported: {out:?}");
    assert_eq!(out.iter().rfind(|l| l.get("event").is_none()).unwrap()["counters"]["bad"], 3);
    std::fs::remove_file(&link).ok();
}

/// Starts `eitskin run --source SOURCE` (reference of 2 frames, 800 triangles) and returns once
/// it has opened the port, which it says on stderr; the stderr reader is kept open for it.
#[cfg(unix)]
fn run_on_port(
    dir: &Scratch,
    source: &str,
    extra: &[&str],
) -> (std::process::Child, std::io::BufReader<std::process::ChildStderr>) {
    use std::io::BufRead;
    let mut child = dir
        .command()
        .args(["run", "--source", source, "--reference-frames", "2", "--triangles", "800"])
        .args(extra)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr = std::io::BufReader::new(child.stderr.take().unwrap());
    let mut said = String::new();
    while !said.contains("reading serial:") {
        said.clear();
        assert!(stderr.read_line(&mut said).unwrap() > 0, "eitskin run ended before opening the port");
    }
    (child, stderr)
}
