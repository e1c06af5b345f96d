//! Through the real binary: `eitskin run` images as `eitskin image` does — normalised
//! differences, touches of either sign, λ chosen from the reference frames or fixed by a
//! calibration — streams the raster on request, and names a channel that goes bad mid-stream.

mod binary;

use binary::scratch;
use eitskin::calibration::{Calibration, Strength};
use eitskin::pseudo_array::PseudoArray;
use eitskin::sim::{Hydrogel, VirtualSensor};
use eitskin::SensorSpec;
use eitskin_io::stream::{Event, FrameLine, Line, Sign, Start, Status};
use std::process::Output;

/// The start line, the events and the frames of a run that must have succeeded, read with the
/// schema's types (which refuse unknown fields); and its standard error.
fn run(out: Output) -> (Start, Vec<Event>, Vec<FrameLine>, String) {
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "failed: {stderr}");
    let text = String::from_utf8(out.stdout).unwrap();
    let mut lines = text.lines().map(|l| Line::parse(l).unwrap_or_else(|e| panic!("{e}: {l}")));
    let Some(Line::Event(Event::Start(start))) = lines.next() else { panic!("no start line first: {text}") };
    let (mut events, mut frames) = (Vec::new(), Vec::new());
    for line in lines {
        match line {
            Line::Event(e) => events.push(e),
            Line::Frame(f) => frames.push(f),
        }
    }
    (start, events, frames, stderr)
}

/// λ, whether chosen, and the channels left out, of the run's `reference_taken` event.
fn reference_taken(events: &[Event]) -> (f64, bool, Vec<usize>) {
    events
        .iter()
        .find_map(|e| match e {
            Event::ReferenceTaken { hyperparameter, chosen, channels_dropped, .. } => {
                Some((*hyperparameter, *chosen, channels_dropped.clone()))
            }
            _ => None,
        })
        .expect("a reference_taken event")
}

#[test]
fn normalised_both_polarities_report_the_sign_and_stream_the_raster() {
    let dir = scratch("run-normalised");
    let script = dir.join("script.txt");
    std::fs::write(&script, "0.8 1.2 -50 40 9\n").unwrap();
    let source = format!("sim:{}", script.display());
    let args = ["--frames", "30", "--fast", "--triangles", "1500", "--normalised", "--polarity", "both"];
    let (start, events, frames, stderr) =
        run(dir.eitskin(&[&["run", "--source", &source, "--stream-image"], &args[..]].concat()));
    assert!(start.normalised && start.polarity == "both", "{start:?}");
    let (lambda, chosen, dropped) = reference_taken(&events);
    assert!(chosen && lambda > 0.0 && dropped.is_empty(), "λ = {lambda}");
    assert!(stderr.contains(&format!("λ = {lambda:.4} (chosen from the noise of 10 reference frames)")), "{stderr}");
    let pressed: Vec<&FrameLine> = frames.iter().filter(|f| (0.8..1.2).contains(&f.t)).collect();
    assert!(!pressed.is_empty());
    for frame in pressed {
        let touch = frame.touches.first().expect("a touch while pressed");
        assert_eq!(touch.sign, Sign::Decrease, "{frame:?}");
        assert!((touch.x + 50.0).hypot(touch.y - 40.0) < 15.0, "{touch:?}");
    }
    for frame in &frames {
        match (frame.status, &frame.raster) {
            (Status::Referencing, raster) => assert!(raster.is_none()),
            (Status::Ok, None) => panic!("no raster on frame {}", frame.seq),
            (Status::Ok, Some(raster)) => {
                assert_eq!((raster.nx, raster.ny, raster.values.len()), (64, 64, 4096));
                assert_eq!(raster.bounds, [[-100.0, -100.0], [100.0, 100.0]], "in mm");
            }
        }
    }
    // Off by default.
    let (_, _, frames, _) = run(dir.eitskin(&[&["run", "--source", &source][..], &args[..]].concat()));
    assert!(frames.iter().all(|f| f.raster.is_none()));
}

#[test]
fn a_given_lambda_is_used_and_a_calibration_fixes_it() {
    let dir = scratch("run-lambda");
    let base = ["run", "--frames", "12", "--fast", "--triangles", "800"];
    let (_, events, _, _) = run(dir.eitskin(&[&base[..], &["--hyperparameter", "0.05"]].concat()));
    assert_eq!(reference_taken(&events), (0.05, false, vec![]));

    // A calibration records λ and normalisation; a run takes them, and refuses others.
    let spec = SensorSpec::square_hydrogel();
    let array = PseudoArray::of_sensor(&spec, [5, 5]).unwrap();
    let curves = vec![Hydrogel::default().drop_curve(16.0); array.area_count()];
    let calibration = Calibration { curves, strength: Strength::Peak };
    let path = dir.join("calibration.json");
    let text = eitskin_io::calibration_to_json(&spec, &array, &calibration).unwrap();
    std::fs::write(&path, &text).unwrap();
    let with = |extra: &[&str]| dir.eitskin(&[&base[..], &["--calibration", path.to_str().unwrap()], extra].concat());
    let (_, events, _, stderr) = run(with(&[]));
    assert_eq!(reference_taken(&events), (0.1, false, vec![]));
    assert!(stderr.contains("λ = 0.1, absolute differences, as the calibration"), "{stderr}");
    let refused = with(&["--hyperparameter", "0.050"]);
    let message = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success() && message.contains("--hyperparameter 0.050: the calibration"), "{message}");
    assert!(message.contains("λ = 0.1"), "{message}");
    let refused = with(&["--normalised"]);
    let message = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success() && message.contains("absolute differences"), "{message}");
    // A file of version 3 (no λ recorded) was made with the paper's λ = 0.1.
    let v3: Vec<&str> = text
        .lines()
        .filter(|l| !l.contains("\"hyperparameter\"") && !l.contains("\"normalised\""))
        .map(|l| if l.contains("\"version\"") { "\"version\": 3," } else { l })
        .collect();
    std::fs::write(&path, v3.join("\n")).unwrap();
    let (_, events, _, _) = run(with(&["--hyperparameter", "0.1"]));
    assert_eq!(reference_taken(&events), (0.1, false, vec![]));
}

#[test]
fn a_channel_lost_mid_stream_is_named_and_the_press_still_found() {
    let dir = scratch("run-channel");
    let spec = SensorSpec::square_hydrogel();
    let mut skin = VirtualSensor::new(&spec, 4).unwrap();
    let line = |v: &[f64]| v.iter().map(|x| format!("{x:e}")).collect::<Vec<_>>().join(",");
    let mut text: Vec<String> = (0..10).map(|_| line(&skin.frame().unwrap())).collect();
    skin.press([0.05, -0.04], 10.0);
    for k in 0..6 {
        let mut frame = skin.frame().unwrap();
        if k >= 2 {
            frame[16] = f64::NAN; // channel 17 lost from frame 12 on
        }
        if k == 4 {
            frame[40..80].fill(f64::NAN); // 41 of 120 at once: refused
        }
        text.push(line(&frame));
    }
    let capture = dir.join("capture.csv");
    std::fs::write(&capture, text.join("\n") + "\n").unwrap();
    let source = format!("file:{}", capture.display());
    let (_, events, frames, stderr) =
        run(dir.eitskin(&["run", "--source", &source, "--rate", "0", "--triangles", "800"]));
    assert!(stderr.contains("warning: frame seq 12: channel(s) [17] went bad"), "{stderr}");
    let dropped: Vec<&Event> = events.iter().filter(|e| matches!(e, Event::ChannelsDropped { .. })).collect();
    assert_eq!(dropped.len(), 1, "{events:?}");
    let Event::ChannelsDropped { seq: 12, channels, dropped: 1, .. } = dropped[0] else { panic!("{:?}", dropped[0]) };
    assert_eq!(channels, &[17]);
    let Some(Event::Bad { seq: Some(14), reason }) = events.iter().find(|e| matches!(e, Event::Bad { .. })) else {
        panic!("{events:?}")
    };
    assert!(reason.starts_with("41 of 120 channels are missing or not finite (40 of them new"), "{reason}");
    assert!(stderr.contains("warning: frame seq 14: 41 of 120 channels"), "{stderr}");
    let imaged: Vec<&FrameLine> = frames.iter().filter(|f| f.status == Status::Ok).collect();
    assert_eq!(imaged.iter().map(|f| f.seq).collect::<Vec<_>>(), [10, 11, 12, 13, 15]);
    for frame in imaged {
        let touch = frame.touches.first().expect("the press");
        assert!((touch.x - 50.0).hypot(touch.y + 40.0) < 15.0, "frame {}: {touch:?}", frame.seq);
    }
}

/// A board on the OpenEIT firmware's 192-value opposite order sending complex (re, im) pairs,
/// each channel with its own demodulator phase, and a channel the spec masks: imaged through
/// the signed magnitude, the masked channel never used, the press found.
#[test]
fn complex_pairs_and_magnitudes_from_a_board_find_the_press() {
    let dir = scratch("run-complex");
    let mut spec = SensorSpec::square_hydrogel();
    spec.protocol = eitskin::ProtocolSpec::Opposite;
    spec.mesh.triangles = 800;
    let spec_path = dir.join("opposite.toml");
    let toml =
        eitskin_io::spec_to_toml(&spec).replace("kind = \"opposite\"", "kind = \"opposite\"\ndrop_channels = [3]");
    std::fs::write(&spec_path, toml).unwrap();
    let mut skin = VirtualSensor::new(&spec, 5).unwrap();
    let mut frames: Vec<Vec<f64>> = (0..10).map(|_| skin.frame().unwrap()).collect();
    skin.press([-0.05, 0.04], 10.0);
    frames.extend((0..3).map(|_| skin.frame().unwrap()));
    let phase = |m: usize| 0.6 * ((m * 37 % 192) as f64 / 96.0 - 1.0);
    let pairs = |v: &Vec<f64>| -> String {
        let numbers = v.iter().enumerate().flat_map(|(m, x)| {
            // Channel 3 is broken on this board: garbage the mask keeps out.
            let x = if m == 2 { 1e9 } else { x.abs() };
            [x * phase(m).cos(), x * phase(m).sin()]
        });
        numbers.map(|x| format!("{x:e}")).collect::<Vec<_>>().join(",")
    };
    let capture = dir.join("complex.csv");
    std::fs::write(&capture, frames.iter().map(pairs).collect::<Vec<_>>().join("\n") + "\n").unwrap();
    let source = format!("file:{}", capture.display());
    let spec_arg = spec_path.to_str().unwrap();
    let args = ["run", spec_arg, "--source", &source, "--rate", "0", "--values", "complex", "--component", "magnitude"];
    let (_, events, lines, stderr) = run(dir.eitskin(&args));
    let (_, _, dropped) = reference_taken(&events);
    assert_eq!(dropped, [3], "{stderr}");
    let imaged: Vec<&FrameLine> = lines.iter().filter(|f| f.status == Status::Ok).collect();
    assert_eq!(imaged.len(), 3, "{events:?}");
    for frame in imaged {
        let touch = frame.touches.first().expect("the press");
        assert!((touch.x + 50.0).hypot(touch.y - 40.0) < 15.0, "frame {}: {touch:?}", frame.seq);
    }
    // Complex pairs cannot come from the virtual sensor, which sends signed values.
    let out = dir.eitskin(&["run", "--frames", "12", "--values", "complex"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("2 numbers per measurement"));
}

/// `--precision half` images from the binary16 copy of the matrix: on the virtual sensor at its
/// own noise (0.01 %), pressed twice, every frame has the same status and touches as in single
/// precision, at the same places within 0.5 mm. Where the processor's last-level cache holds
/// the sensor's 2 MB matrix, `auto` (the default) keeps single precision: the same lines as
/// `single`, and nothing said of half precision.
#[test]
fn half_precision_finds_the_same_touches() {
    let dir = scratch("run-half");
    let script = dir.join("script.txt");
    std::fs::write(&script, "0.6 1.2 -50 40 9\n1.5 2.1 30 -20 4\n").unwrap();
    let source = format!("sim:{}", script.display());
    let args = ["run", "--source", &source, "--frames", "50", "--fast", "--triangles", "1500"];
    let (_, _, single, _) = run(dir.eitskin(&[&args[..], &["--precision", "single"]].concat()));
    let (_, _, halved, _) = run(dir.eitskin(&[&args[..], &["--precision", "half"]].concat()));
    assert_eq!(single.len(), halved.len());
    let (_, _, auto, said) = run(dir.eitskin(&args));
    if eitskin_io::last_level_cache().is_some_and(|bytes| bytes >= 4.0 * 1024.0 * 1024.0) {
        assert!(!said.contains("half precision"), "{said}");
        assert_eq!(auto.len(), single.len());
        for (a, s) in auto.iter().zip(&single) {
            assert_eq!((a.status, a.touches.len()), (s.status, s.touches.len()), "frame {}", a.seq);
            assert!(a.touches.iter().zip(&s.touches).all(|(a, s)| (a.x, a.y) == (s.x, s.y)), "frame {}", a.seq);
        }
    }
    let mut touched = 0;
    for (a, b) in single.iter().zip(&halved) {
        assert_eq!((a.status, a.touches.len()), (b.status, b.touches.len()), "frame {}", a.seq);
        for (s, h) in a.touches.iter().zip(&b.touches) {
            assert!((s.x - h.x).hypot(s.y - h.y) < 0.5, "frame {}: {s:?} against {h:?}", a.seq);
        }
        touched += usize::from(!a.touches.is_empty());
    }
    assert!(touched >= 20, "{touched} frames with a touch");
}
