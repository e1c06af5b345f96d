//! `image` and `segment` take a whole recording with one setup (`--frames all`, or a range): each
//! frame's answer is the one its own run gives, the outputs stack the frames, and a frame unlike
//! its reference is refused alone while the others are imaged.

mod binary;

use binary::{ok, scratch, Scratch};
use serde_json::Value;

/// The paper sensor's frame for `inclusions` (`x,y,r,sigma`), from `forward`.
fn forward(dir: &Scratch, inclusions: &[&str]) -> Vec<f64> {
    let inclusions: Vec<String> = inclusions.iter().map(|o| format!("--inclusion={o}")).collect();
    let inclusions: Vec<&str> = inclusions.iter().map(String::as_str).collect();
    let csv = ok(dir.eitskin(&[&["forward", "--format", "csv"], &inclusions[..]].concat()));
    csv.lines().skip(1).map(|l| l.split(',').nth(1).unwrap().parse().unwrap()).collect()
}

/// A text log, one frame per line, as boards print them.
fn log(frames: &[Vec<f64>]) -> String {
    let line = |f: &Vec<f64>| f.iter().map(f64::to_string).collect::<Vec<_>>().join(",");
    frames.iter().map(line).collect::<Vec<_>>().join("\n")
}

/// A recording of four frames: a press on the left, one up right, a frame in millivolts (the
/// reference is in volts) and the sheet at rest.
fn recording(dir: &Scratch) -> (String, String) {
    let rest = forward(dir, &[]);
    let left = forward(dir, &["-50,0,20,0.1"]);
    let right = forward(dir, &["40,40,20,0.1"]);
    let millivolts: Vec<f64> = rest.iter().map(|v| v * 1000.0).collect();
    let (reference, frames) = (dir.join("reference.txt"), dir.join("recording.txt"));
    std::fs::write(&reference, log(std::slice::from_ref(&rest))).unwrap();
    std::fs::write(&frames, log(&[left, right, millivolts, rest])).unwrap();
    (reference.to_str().unwrap().to_owned(), frames.to_str().unwrap().to_owned())
}

#[test]
fn a_recording_is_imaged_frame_by_frame_with_one_setup() {
    let dir = scratch("recording-image");
    let (reference, frames) = recording(&dir);
    let image = |extra: &[&str]| {
        let out =
            ok(dir.eitskin(&[&["image", "--reference", &reference, "--frame", &frames, "--json"], extra].concat()));
        serde_json::from_str::<Value>(&out).unwrap()
    };
    let all = image(&["--frames", "all"]);
    let stack = all["frames"].as_array().unwrap();
    let numbers: Vec<u64> = stack.iter().map(|f| f["frame"].as_u64().unwrap()).collect();
    assert_eq!(numbers, [1, 2, 4], "{all}");
    let refused = all["refused"].as_array().unwrap();
    assert_eq!(refused.len(), 1, "{all}");
    assert_eq!(refused[0]["frame"], 3);
    assert!(refused[0]["reason"].as_str().unwrap().contains("1000.000 times"), "{all}");

    let centres = |frame: &Value| -> Vec<(f64, f64)> {
        let touches = frame["touches"].as_array().unwrap();
        touches.iter().map(|t| (t["x"].as_f64().unwrap(), t["y"].as_f64().unwrap())).collect()
    };
    let near = |c: &[(f64, f64)], x: f64, y: f64| c.len() == 1 && (c[0].0 - x).hypot(c[0].1 - y) < 15.0;
    assert!(near(&centres(&stack[0]), -50.0, 0.0), "{}", stack[0]);
    assert!(near(&centres(&stack[1]), 40.0, 40.0), "{}", stack[1]);
    assert!(centres(&stack[2]).is_empty(), "the sheet at rest has no touch: {}", stack[2]);
    // Each frame's own run (the old flag's name too) gives the same answer.
    for (k, frame) in [(1, &stack[0]), (2, &stack[1]), (4, &stack[2])] {
        let one = image(&["--frame-index", &k.to_string()]);
        assert_eq!(one["frame"], k, "{one}");
        assert_eq!(one["touches"], frame["touches"], "frame {k}");
        assert_eq!(one["hyperparameter"], all["hyperparameter"], "one setup: one λ");
    }
}

#[test]
fn a_recordings_labels_are_stacked_and_its_selection_checked() {
    let dir = scratch("recording-segment");
    let (reference, frames) = recording(&dir);
    let segment =
        |extra: &[&str]| dir.eitskin(&[&["segment", "--reference", &reference, "--frame", &frames], extra].concat());
    let npy = dir.join("labels.npy");
    let out = ok(segment(&["--frames", "1-2", "--out", npy.to_str().unwrap(), "--raster", "40x30"]));
    assert!(out.contains("frame 2: ") && out.contains("2 frame(s) segmented, 0 refused"), "{out}");
    let bytes = std::fs::read(&npy).unwrap();
    let header_end = 10 + u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let header = String::from_utf8_lossy(&bytes[10..header_end]);
    assert!(header.contains("'shape': (2, 30, 40") && header.contains("|u1"), "{header}");
    assert_eq!(bytes.len() - header_end, 2 * 30 * 40, "one byte per label");

    // The stack's CSV is each frame's own CSV, numbered.
    let csv = |name: &str, frames: &str| {
        let path = dir.join(name);
        ok(segment(&["--frames", frames, "--out", path.to_str().unwrap()]));
        std::fs::read_to_string(path).unwrap()
    };
    let stack = csv("stack.csv", "all");
    let second = csv("second.csv", "2");
    let numbered: Vec<String> = second.lines().skip(1).map(|l| format!("2,{l}")).collect();
    let stacked: Vec<&str> = stack.lines().filter(|l| l.starts_with("2,")).collect();
    assert_eq!(stacked, numbered);
    assert!(stack.starts_with("frame,x_mm,y_mm,label\n") && !stack.contains("\n3,"), "frame 3 is refused");

    let refused = |args: &[&str], said: &str| {
        let out = segment(args);
        let message = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && message.contains(said), "{args:?}: {message}");
    };
    let out = npy.to_str().unwrap();
    refused(&["--frames", "3-5", "--out", out], "--frames 3-5: ");
    refused(&["--frames", "3-5", "--out", out], "holds 4 frame(s)");
    refused(&["--frames", "0", "--out", out], "\"0\" is not a selection of frames");
    refused(&["--frames", "3", "--out", out], "1000.000 times");
    // A frame refused keeps its place in an NPY stack (every label 255), so index k is still
    // frame k + 1; a frame with no finite value is refused alone, as a frame in millivolts is.
    let all = dir.join("all.npy");
    let said = ok(segment(&["--frames", "all", "--out", all.to_str().unwrap(), "--raster", "40x30"]));
    assert!(said.contains("3 frame(s) segmented, 1 refused"), "{said}");
    let bytes = std::fs::read(&all).unwrap();
    let header_end = 10 + u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    assert!(String::from_utf8_lossy(&bytes[10..header_end]).contains("'shape': (4, 30, 40"));
    let third = &bytes[header_end + 2 * 1200..][..1200];
    assert!(third.iter().all(|l| *l == 255) && bytes[header_end..][..1200].iter().any(|l| *l != 255));
    let text = std::fs::read_to_string(&frames).unwrap();
    let with_empty = dir.join("with_empty.txt");
    let empty = vec!["NaN"; 120].join(",");
    std::fs::write(&with_empty, text.replacen('\n', &format!("\n{empty}\n"), 1)).unwrap();
    let labels = dir.join("labels_empty.csv");
    let out = dir.eitskin(&[
        "segment",
        "--reference",
        &reference,
        "--frame",
        with_empty.to_str().unwrap(),
        "--frames",
        "all",
        "--out",
        labels.to_str().unwrap(),
    ]);
    let message = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{message}");
    assert!(message.contains("frame 2 of") && message.contains("holds no finite value"), "{message}");
    let png = dir.join("image.png");
    let png = png.to_str().unwrap();
    let out = dir.eitskin(&["image", "--reference", &reference, "--frame", &frames, "--frames", "all", "--png", png]);
    let message = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && message.contains("--png draws one frame"), "{message}");
}
