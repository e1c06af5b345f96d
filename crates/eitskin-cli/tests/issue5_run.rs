//! Issue 5, through the real binary: `eitskin run` on the virtual sensor and on a file prints one
//! JSON line per frame, in order, with touches where the presses are, and every bad frame as an
//! event with its reason; the stream goes on after it.

use std::process::{Command, Output};

fn eitskin(args: &[&str]) -> Output {
    let cache = std::env::temp_dir().join(format!("eitskin-run-{}-cache", std::process::id()));
    Command::new(env!("CARGO_BIN_EXE_eitskin"))
        .args(args)
        .env("EITSKIN_CACHE", cache)
        .output()
        .expect("the binary runs")
}

fn lines(out: Output) -> Vec<serde_json::Value> {
    assert!(out.status.success(), "failed: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).unwrap().lines().map(|l| serde_json::from_str(l).expect("a JSON line")).collect()
}

fn scratch(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("eitskin-run-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn the_virtual_sensor_pressed_by_a_script_gives_a_touch_where_and_when_pressed() {
    let dir = scratch("sim");
    let script = dir.join("script.txt");
    std::fs::write(&script, "# start end x y force\n1.0 1.5 -50 40 9\n").unwrap();
    let source = format!("sim:{}", script.display());
    let out = lines(eitskin(&["run", "--source", &source, "--frames", "40", "--rate", "20", "--triangles", "1500"]));
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
    let out =
        lines(eitskin(&["run", "--source", &source, "--rate", "0", "--reference-frames", "2", "--triangles", "800"]));
    let events: Vec<&serde_json::Value> = out.iter().filter(|l| l["event"] == "bad").collect();
    let frames: Vec<&serde_json::Value> = out.iter().filter(|l| l.get("event").is_none()).collect();
    assert_eq!(frames.len(), 4, "{out:?}");
    assert_eq!(frames.iter().map(|f| f["seq"].as_u64().unwrap()).collect::<Vec<_>>(), vec![0, 1, 2, 5]);
    assert_eq!(events.len(), 2);
    assert!(events[0]["reason"].as_str().unwrap().contains("has 3 values, expected 120"), "{:?}", events[0]);
    assert_eq!(events[0]["seq"], 3);
    assert!(events[1]["reason"].as_str().unwrap().contains("not a finite number"), "{:?}", events[1]);
    assert_eq!(frames[3]["counters"]["bad"], 2);
}
