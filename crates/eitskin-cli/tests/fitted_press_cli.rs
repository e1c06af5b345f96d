//! Past the paper, through the real binary: a calibration on the drop of the press
//! fitted to Δv (`--strength fitted-drop`, one curve for the sheet) from raw frames of the
//! virtual sensor, against the paper's per-area peak calibration from the same frames; then
//! `eitskin run` on a file of the same frames gives the forces `evaluate` gave, frame for frame.

mod binary;

use binary::{ok, scratch};
use std::fmt::Write as _;
use std::path::Path;

use eitskin::sim::{Press, VirtualSensor};
use eitskin::SensorSpec;
use rand::{RngExt, SeedableRng};

fn rms_of(text: &str) -> f64 {
    let after = text.split("RMS error ").nth(1).unwrap_or_else(|| panic!("no RMS in {text}"));
    after.split(' ').next().unwrap().parse().unwrap()
}

/// Frames of presses as a samples CSV (x, y in the spec's unit; force; the frame's values).
fn write_samples(path: &Path, presses: &[Press], frames: &[Vec<f64>], per_metre: f64) {
    let mut csv = String::from("x,y,force");
    (1..=frames[0].len()).for_each(|m| write!(csv, ",v{m}").unwrap());
    for (p, v) in presses.iter().zip(frames) {
        write!(csv, "\n{},{},{}", p.position[0] * per_metre, p.position[1] * per_metre, p.force).unwrap();
        v.iter().for_each(|x| write!(csv, ",{x:e}").unwrap());
    }
    std::fs::write(path, csv).unwrap();
}

#[test]
fn fitted_drop_calibration_beats_the_peak_on_the_same_frames_and_runs_live() {
    let dir = scratch("fitted");
    let spec = SensorSpec::square_hydrogel();
    let per_metre = 1.0 / spec.length_unit.metres();
    let mut skin = VirtualSensor::new(&spec, 11).unwrap();
    let noisy = |skin: &mut VirtualSensor, clean: Vec<Vec<f64>>| -> Vec<Vec<f64>> {
        clean
            .into_iter()
            .map(|mut v| {
                skin.add_noise(&mut v);
                v
            })
            .collect()
    };
    // Frames at rest: 15 noisy frames of the untouched sheet, one per line.
    let blank = skin.clean_frame().unwrap();
    let rest = noisy(&mut skin, vec![blank; 15]);
    let line = |v: &Vec<f64>| v.iter().map(|x| format!("{x:e}")).collect::<Vec<_>>().join(",");
    std::fs::write(dir.join("reference.txt"), rest.iter().map(line).collect::<Vec<_>>().join("\n")).unwrap();

    // Calibration: the centres of the lower-left 3×3 units of the 5×5 grid, 0–12 N, twice each.
    let centres: Vec<[f64; 2]> =
        (0..3).flat_map(|r| (0..3).map(move |c| [-0.08 + 0.04 * c as f64, -0.08 + 0.04 * r as f64])).collect();
    let calibration: Vec<Press> = centres
        .iter()
        .flat_map(|&position| (0..=12).flat_map(move |f| [Press { position, force: f as f64 }; 2]))
        .collect();
    let frames = skin.clean_frames(&calibration.iter().map(|p| vec![*p]).collect::<Vec<_>>()).unwrap();
    write_samples(&dir.join("calibration.csv"), &calibration, &noisy(&mut skin, frames), per_metre);
    // Validation: random positions in the right half (units never calibrated), random 0–12 N.
    let mut rng = eitskin::SeededRng::seed_from_u64(5);
    let validation: Vec<Press> = (0..60)
        .map(|_| Press {
            position: [rng.random_range(0.0..0.1), rng.random_range(-0.1..0.1)],
            force: rng.random_range(0.0..12.0),
        })
        .collect();
    let frames = skin.clean_frames(&validation.iter().map(|p| vec![*p]).collect::<Vec<_>>()).unwrap();
    let validation_frames = noisy(&mut skin, frames);
    write_samples(&dir.join("validation.csv"), &validation, &validation_frames, per_metre);

    let path = |name: &str| -> String { dir.join(name).to_str().unwrap().to_string() };
    let mut rms = Vec::new();
    for (strength, grid) in [("peak", "5"), ("fitted-drop", "1"), ("auto", "1"), ("sized-drop", "1")] {
        let cal = path(&format!("{strength}.json"));
        let table = ok(dir.eitskin(&[
            "calibrate",
            "--samples",
            &path("calibration.csv"),
            "--reference",
            &path("reference.txt"),
            "--strength",
            strength,
            "--grid",
            grid,
            "--out",
            &cal,
        ]));
        assert!(table.contains(if strength == "peak" { "peak(F)" } else { "drop(F)" }), "{table}");
        // `auto` reads both press strengths, says how each reads the places left out, keeps one.
        if strength == "auto" {
            assert!(
                table.contains("strengths tried") && table.contains("sized drop") && table.contains("← kept"),
                "{table}"
            );
        }
        let text = ok(dir.eitskin(&[
            "evaluate",
            "--calibration",
            &cal,
            "--samples",
            &path("validation.csv"),
            "--reference",
            &path("reference.txt"),
        ]));
        rms.push(rms_of(&text));
    }
    assert!(rms[1] < 0.6 * rms[0], "fitted drop {} N against peak {} N", rms[1], rms[0]);
    assert!(rms[2] < 0.6 * rms[0], "auto {} N against peak {} N", rms[2], rms[0]);
    // A fitted-drop calibration cannot be made from peaks alone.
    std::fs::write(dir.join("peaks.csv"), "unit,force,peak\n1,0,0.01\n1,5,0.1\n1,10,0.2\n").unwrap();
    let out = dir.eitskin(&[
        "calibrate",
        "--samples",
        &path("peaks.csv"),
        "--strength",
        "fitted-drop",
        "--out",
        &path("x.json"),
    ]);
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("needs each sample's raw frame"));
    // By default, samples of peaks calibrate the peak.
    let table =
        ok(dir.eitskin(&["calibrate", "--samples", &path("peaks.csv"), "--grid", "1", "--out", &path("x.json")]));
    assert!(table.contains("peak(F)") && !table.contains("strengths tried"), "{table}");

    // Live: the same frames at rest, then the validation frames, through `eitskin run`, each
    // frame a scene of its own: the forces `evaluate` gave, frame for frame, with either press
    // strength (the sized drop fits every press's radius in `run` as in `evaluate`).
    let mut lines = String::new();
    for v in rest.iter().chain(&validation_frames) {
        lines += &line(v);
        lines.push('\n');
    }
    std::fs::write(dir.join("frames.txt"), lines).unwrap();
    for calibration in ["fitted-drop.json", "sized-drop.json"] {
        let (live, count) = live_against_evaluate(&dir, &path(calibration), &validation, per_metre);
        eprintln!("{calibration}: live RMS {live} N over {count} touches");
        assert!(count >= validation.len() * 3 / 4, "{count} of {} presses gave a touch", validation.len());
        assert!(live < rms[0], "live RMS {live} N over {count} touches, peak calibration {} N", rms[0]);
    }
    eprintln!(
        "RMS error: peak per area {} N, fitted drop {} N, auto {} N, sized drop {} N",
        rms[0], rms[1], rms[2], rms[3]
    );
}

/// `evaluate` with `calibration` on the validation frames, then `run` on the frames at rest and
/// those frames: each press's force the same in both (or missed by both); the RMS error of the
/// live forces (N) and how many presses gave one.
fn live_against_evaluate(
    dir: &binary::Scratch,
    calibration: &str,
    validation: &[Press],
    per_metre: f64,
) -> (f64, usize) {
    let path = |name: &str| -> String { dir.join(name).to_str().unwrap().to_string() };
    let results = path("results.csv");
    ok(dir.eitskin(&[
        "evaluate",
        "--calibration",
        calibration,
        "--samples",
        &path("validation.csv"),
        "--reference",
        &path("reference.txt"),
        "--out",
        &results,
    ]));
    let evaluated: Vec<Option<f64>> = std::fs::read_to_string(&results)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(7).unwrap().parse::<f64>().ok())
        .collect();
    assert_eq!(evaluated.len(), validation.len());
    let out = ok(dir.eitskin(&[
        "run",
        "--source",
        &format!("file:{}", path("frames.txt")),
        "--rate",
        "0",
        "--reference-frames",
        "15",
        "--fresh-presses",
        "--calibration",
        calibration,
    ]));
    let processed: Vec<serde_json::Value> = out
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .filter(|j| j["status"] == "ok")
        .collect();
    assert_eq!(processed.len(), validation.len());
    let (mut sum, mut count) = (0.0, 0);
    for ((line, press), evaluated) in processed.iter().zip(validation).zip(&evaluated) {
        // The touch `evaluate` matched: the one nearest the press within 20 mm.
        let touches = line["touches"].as_array().unwrap();
        let nearest = touches
            .iter()
            .map(|t| {
                let (x, y) =
                    (t["press"]["x"].as_f64().unwrap() / per_metre, t["press"]["y"].as_f64().unwrap() / per_metre);
                ((x - press.position[0]).hypot(y - press.position[1]), t)
            })
            .filter(|(d, _)| *d <= 0.02)
            .min_by(|a, b| a.0.total_cmp(&b.0));
        let live = nearest.map(|(_, t)| t["force"].as_f64().unwrap());
        match (live, evaluated) {
            (Some(live), Some(evaluated)) => {
                assert!((live - evaluated).abs() <= 1e-9 * live.abs().max(1.0), "run {live} N, evaluate {evaluated} N");
                sum += (live - press.force).powi(2);
                count += 1;
            }
            (None, None) => {}
            other => panic!("run and evaluate disagree on whether {press:?} was found: {other:?}"),
        }
    }
    ((sum / count as f64).sqrt(), count)
}
