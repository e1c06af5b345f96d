//! Through the real binary: `eitskin mesh`, `forward` (with EIDORS' mesh loaded),
//! `bench --json`, `spec`, and clear failures for bad input.

mod binary;

use binary::scratch;
use eitskin_testdata::max_relative_error;
use std::process::Output;

fn stdout_json(out: &Output) -> serde_json::Value {
    assert!(out.status.success(), "failed: {}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).expect("JSON on stdout")
}

/// A JSON array of numbers as a vector.
fn floats(v: &serde_json::Value) -> Vec<f64> {
    v.as_array().expect("an array").iter().map(|x| x.as_f64().expect("a number")).collect()
}

/// EIDORS' 2×2 square as a spec: metres, unit depth, 0.2 m electrodes, z = 0.01 Ω·m².
const EIDORS_SQUARE: &str = r#"
units = "m"
thickness = 1.0
conductivity = 1.0
[outline]
kind = "rectangle"
width = 2.0
height = 2.0
[electrodes]
count = 16
width = 0.2
contact_impedance = 0.01
placement = "per-side"
"#;

#[test]
fn forward_on_eidors_mesh_matches_eidors() {
    let dir = scratch("eidors");
    let spec = dir.join("square.toml");
    std::fs::write(&spec, EIDORS_SQUARE).unwrap();
    let mesh = eitskin_testdata::reference("eidors/mesh.json");
    for (protocol, file) in [("two-terminal", "two_terminal"), ("adjacent", "adjacent")] {
        let out =
            // EIDORS's elements are linear.
            dir.eitskin(&[
                "forward",
                spec.to_str().unwrap(),
                "--mesh",
                mesh.to_str().unwrap(),
                "--protocol",
                protocol,
                "--elements",
                "p1",
            ]);
        let json = stdout_json(&out);
        let ours = floats(&json["measurements"]);
        let reference: serde_json::Value =
            serde_json::from_str(&eitskin_testdata::read_reference(&format!("eidors/protocol_{file}.json"))).unwrap();
        let err = max_relative_error(&ours, &floats(&reference["v_homog"]));
        assert!(err < 1e-6, "{protocol}: {err:e}");
        assert_eq!(json["triangles"], 3200);
    }
}

#[test]
fn forward_default_sensor_prints_120_values_in_json_and_csv() {
    let dir = scratch("forward");
    let json = stdout_json(&dir.eitskin(&["forward", "--triangles", "800"]));
    assert_eq!(json["measurements"].as_array().unwrap().len(), 120);
    assert!(json["protocol"].as_str().unwrap().contains("two-terminal"));
    let values = floats(&json["measurements"]);
    // A press (lower conductivity) raises every two-terminal transfer impedance.
    let pressed = stdout_json(&dir.eitskin(&["forward", "--triangles", "800", "--inclusion", "-50,20,10,0.2"]));
    assert!(floats(&pressed["measurements"]).iter().zip(&values).all(|(p, v)| p >= v));
    let csv = dir.eitskin(&["forward", "--triangles", "800", "--format", "csv", "--protocol", "adjacent"]);
    let text = String::from_utf8(csv.stdout).unwrap();
    assert_eq!(text.lines().count(), 1 + 208);
    assert!(text.starts_with("measurement,value_ohm\n1,"));
}

/// forward's default elements (quadratic) are several times closer to the converged values than
/// linear ones on the same mesh (against quadratic elements on 8× the triangles: 2.8 % against
/// 12.8 % at 1,000); point electrodes take linear ones, and are refused quadratic ones.
#[test]
fn forward_defaults_to_quadratic_elements_nearer_the_converged_values() {
    let dir = scratch("elements");
    let forward = |args: &[&str]| stdout_json(&dir.eitskin(&[&["forward", "--triangles"], args].concat()));
    let reference = floats(&forward(&["8000", "--elements", "p2"])["measurements"]);
    let (default, linear) = (forward(&["1000"]), forward(&["1000", "--elements", "p1"]));
    assert_eq!((default["elements"].as_str(), linear["elements"].as_str()), (Some("p2"), Some("p1")));
    let error = |json: &serde_json::Value| max_relative_error(&floats(&json["measurements"]), &reference);
    let (quadratic, linear) = (error(&default), error(&linear));
    assert!(quadratic < linear / 3.0, "p2 {quadratic:e}, p1 {linear:e}");
    let spec_text = String::from_utf8(dir.eitskin(&["spec"]).stdout).unwrap();
    let spec = dir.join("point.toml");
    std::fs::write(&spec, spec_text.replace("model = \"complete\"", "model = \"point\"")).unwrap();
    let point = stdout_json(&dir.eitskin(&["forward", spec.to_str().unwrap(), "--triangles", "1000"]));
    assert_eq!(point["elements"], "p1");
    let refused = dir.eitskin(&["forward", spec.to_str().unwrap(), "--elements", "p2"]);
    assert!(!refused.status.success());
    assert!(String::from_utf8_lossy(&refused.stderr).contains("point electrodes"));
}

#[test]
fn mesh_writes_json_that_forward_reads_back_and_a_png() {
    let dir = scratch("mesh");
    let out_json = dir.join("paper.json");
    let out = dir.eitskin(&["mesh", "--triangles", "1500", "--out", out_json.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let png = std::fs::read(dir.join("paper.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    let fresh = stdout_json(&dir.eitskin(&["forward", "--triangles", "1500"]));
    let loaded = stdout_json(&dir.eitskin(&["forward", "--mesh", out_json.to_str().unwrap()]));
    assert_eq!(fresh["measurements"], loaded["measurements"], "the same mesh gives the same values");
}

#[test]
fn bench_json_has_every_stage() {
    let dir = scratch("bench");
    let json = stdout_json(&dir.eitskin(&["bench", "--triangles", "500", "--repeat", "3", "--json"]));
    for stage in [
        "mesh",
        "model",
        "assembly",
        "factorisation",
        "solves",
        "measurements",
        "total",
        "jacobian",
        "forward_p2_graded",
        "reconstructor",
        "drop_channel",
        "auto_hyperparameter",
        "auto_hyperparameter_2356",
        "reconstructor_2356",
        "frame_image",
        "frame_touches",
        "fleet_frame_half",
        "fleet_frame_shared",
    ] {
        assert!(json[stage].as_f64().is_some_and(|t| t > 0.0), "stage {stage} missing: {json}");
    }
}

#[test]
fn spec_prints_toml_that_reads_back() {
    let dir = scratch("spec");
    let out = dir.eitskin(&["spec"]);
    assert!(out.status.success());
    std::fs::write(dir.join("paper.toml"), &out.stdout).unwrap();
    let again = dir.eitskin(&["spec", dir.join("paper.toml").to_str().unwrap()]);
    assert_eq!(out.stdout, again.stdout);
}

#[test]
fn bad_input_fails_with_a_message_that_says_where() {
    let dir = scratch("bad");
    let spec = dir.join("bad.toml");
    std::fs::write(&spec, EIDORS_SQUARE.replace("contact_impedance = 0.01", "contact_impedance = 0")).unwrap();
    let out = dir.eitskin(&["forward", spec.to_str().unwrap()]);
    assert!(!out.status.success());
    // Each part of a message once: the file, what failed, and the cause.
    assert_eq!(
        String::from_utf8_lossy(&out.stderr),
        format!(
            "error: {}: the spec does not make a sensor: `electrodes.contact_impedance` must be a positive number, got 0 Ω·m²\n",
            spec.display()
        )
    );
    let out = dir.eitskin(&["forward", "--inclusion", "1,2,3"]);
    assert_eq!(
        String::from_utf8_lossy(&out.stderr),
        "error: --inclusion \"1,2,3\": expected four numbers x,y,r,sigma, got 3\n"
    );
    let out = dir.eitskin(&["forward", "--mesh", "/nonexistent/mesh.json"]);
    assert_eq!(
        String::from_utf8_lossy(&out.stderr),
        "error: cannot read /nonexistent/mesh.json: No such file or directory (os error 2)\n"
    );
}

/// A flag out of its range is refused before anything runs, with the range it takes: no
/// reference at all imaged every frame against nothing (touches on an untouched sheet), a
/// baseline weight above 1 or a threshold of NaN was taken as it was, and a study without
/// validation presses wrote a report of NaN.
#[test]
fn flags_out_of_range_are_refused_with_their_range() {
    let dir = scratch("flags");
    let frames = "is not a number of reference frames: give a whole number from 1 to 10000";
    let baseline = "is not a baseline rate: give a number in [0, 1], e.g. 0.01";
    let threshold = "is not a fraction of the peak: give a number in (0, 1], e.g. 0.6";
    for (command, flag, value, says) in [
        ("run", "--reference-frames", "0", frames),
        ("run", "--rate", "1e300", "is not a frame rate: give a number in [0, 100000] frames/s, e.g. 20"),
        ("run", "--baseline-rate", "2", baseline),
        ("run", "--baseline-rate", "nan", baseline),
        ("image", "--threshold", "nan", threshold),
        ("image", "--threshold", "1.5", threshold),
        ("study", "--validation", "0", "is not a number of validation presses: give a whole number from 1 to 100000"),
        ("study", "--noise", "-1", "is not a relative noise: give a number in [0, 0.1], e.g. 1e-4"),
    ] {
        let out = dir.eitskin(&[command, &format!("{flag}={value}")]);
        let upper = flag.trim_start_matches('-').replace('-', "_").to_uppercase();
        assert_eq!(
            String::from_utf8_lossy(&out.stderr),
            format!("error: invalid value '{value}' for '{flag} <{upper}>': \"{value}\" {says}\n\nFor more information, try '--help'.\n")
        );
        assert_eq!(out.status.code(), Some(2), "{command} {flag}={value}");
    }
}

/// Outputs are checked before any work: a study whose folder cannot be made ran for half a
/// minute first; a picture over the frame it images, a recording over an existing one and an
/// unknown protocol name are refused in the user's words.
#[test]
fn outputs_and_names_are_refused_before_any_work() {
    let dir = scratch("outputs");
    let frame = dir.join("frame.json");
    std::fs::write(&frame, dir.eitskin(&["forward"]).stdout).unwrap();
    let recording = dir.join("run.jsonl");
    std::fs::write(&recording, "{}\n").unwrap();
    let f = frame.to_str().unwrap();
    let r = recording.to_str().unwrap();
    // Outputs are checked before any input is read: the content does not matter.
    let table = dir.join("frame.csv");
    std::fs::copy(&frame, &table).unwrap();
    let c = table.to_str().unwrap();
    for (args, says) in [
        (vec!["study", "--out", "/dev/null/study"], "creating /dev/null/study: Not a directory (os error 20)".to_string()),
        (
            vec!["image", "--reference", c, "--frame", c, "--out", c],
            format!("--out {c}: would overwrite the input {c} (--reference); give another path"),
        ),
        (
            vec!["image", "--reference", f, "--frame", f, "--png", "/nonexistent/image.png"],
            "--png /nonexistent/image.png: the folder /nonexistent does not exist".to_string(),
        ),
        (
            vec!["run", "--record", r],
            format!("--record {r}: the file exists; record into another file (a recording is never written over)"),
        ),
        (
            vec!["forward", "--protocol", "-1"],
            "\"-1\" is neither a protocol (two-terminal, adjacent, adjacent-all, opposite, skip-S, skip-S-all (S = 0, 1, 2, …)) nor a protocol file".to_string(),
        ),
    ] {
        let out = dir.eitskin(&args);
        assert_eq!(String::from_utf8_lossy(&out.stderr), format!("error: {says}\n"), "{args:?}");
        assert_eq!(out.status.code(), Some(1), "{args:?}");
    }
    assert_eq!(std::fs::read_to_string(&recording).unwrap(), "{}\n");
    // A picture named as another format: refused by the flag itself, the frame untouched.
    let out = dir.eitskin(&["image", "--reference", f, "--frame", f, "--png", f]);
    let says = format!(
        "error: invalid value '{f}' for '--png <PNG>': this flag writes .png, not .json: name the file so\n\nFor more information, try '--help'.\n"
    );
    assert_eq!(String::from_utf8_lossy(&out.stderr), says);
    assert_eq!(out.status.code(), Some(2));
    assert!(std::fs::read_to_string(&frame).unwrap().contains("measurements"));
    // The table's use not named, or named as no use there is: refused by the flag, its uses
    // listed.
    for press_table in [&["--press-table"][..], &["--press-table", "exact"]] {
        let out = dir.eitskin(&[&["run", "--fit"][..], press_table].concat());
        let stderr = String::from_utf8_lossy(&out.stderr);
        let said = [
            "error: a value is required for '--press-table <USE>'",
            "error: invalid value 'exact' for '--press-table <USE>'",
        ];
        assert!(said.iter().any(|s| stderr.starts_with(s)), "{stderr}");
        assert!(stderr.contains("[possible values: auto, fit, start, off]"), "{stderr}");
        assert_eq!(out.status.code(), Some(2));
    }
}

/// `mesh --out m.png` wrote the mesh's JSON to m.png and then the picture over it ("wrote m.png
/// and m.png"): a name of another format is refused before any work, as is an output over the spec.
#[test]
fn mesh_outputs_never_overwrite_each_other_or_the_spec() {
    let dir = scratch("mesh-out");
    let png = dir.join("m.png");
    let out = dir.eitskin(&["mesh", "--out", png.to_str().unwrap()]);
    let says = format!(
        "error: invalid value '{}' for '--out <OUT>': this flag writes .json, not .png: name the file so\n\nFor more information, try '--help'.\n",
        png.display()
    );
    assert_eq!(String::from_utf8_lossy(&out.stderr), says);
    assert!(!png.exists());
    // The spec under a name the mesh could take: never written over, nor its picture made.
    let spec = dir.join("paper.json");
    std::fs::write(&spec, dir.eitskin(&["spec"]).stdout).unwrap();
    let out = dir.eitskin(&["mesh", spec.to_str().unwrap(), "--out", spec.to_str().unwrap()]);
    let says =
        format!("error: --out {0}: would overwrite the input {0} (the spec); give another path\n", spec.display());
    assert_eq!(String::from_utf8_lossy(&out.stderr), says);
    assert!(!dir.join("paper.png").exists() && std::fs::read_to_string(&spec).unwrap().contains("[outline]"));
}

#[test]
fn image_finds_a_simulated_press_from_forward_output() {
    let dir = scratch("image");
    let (reference, frame, png) = (dir.join("ref.json"), dir.join("frame.csv"), dir.join("image.png"));
    // Both frames from the same finer "truth" mesh; the image is reconstructed on a coarser one.
    std::fs::write(&reference, dir.eitskin(&["forward", "--triangles", "3000"]).stdout).unwrap();
    let pressed = dir.eitskin(&["forward", "--triangles", "3000", "--format", "csv", "--inclusion", "40,-30,10,0.5"]);
    std::fs::write(&frame, pressed.stdout).unwrap();
    let out = dir.eitskin(&[
        "image",
        "--triangles",
        "1500",
        "--reference",
        reference.to_str().unwrap(),
        "--frame",
        frame.to_str().unwrap(),
        "--png",
        png.to_str().unwrap(),
        "--json",
    ]);
    let json = stdout_json(&out);
    let touches = json["touches"].as_array().unwrap();
    assert_eq!(touches.len(), 1, "{json}");
    let (x, y) = (touches[0]["x"].as_f64().unwrap(), touches[0]["y"].as_f64().unwrap());
    assert!((x - 40.0).hypot(y + 30.0) < 20.0, "touch at ({x}, {y}) mm, press at (40, -30)");
    assert_eq!(&std::fs::read(png).unwrap()[1..4], b"PNG");
}

/// A more conductive object is a touch of the other sign: found with `--polarity both` and
/// named `increase`, not found with the default `decrease`; λ is chosen and printed.
#[test]
fn image_finds_a_more_conductive_object_with_either_polarity() {
    let dir = scratch("image-polarity");
    let (reference, frame) = (dir.join("ref.json"), dir.join("frame.json"));
    std::fs::write(&reference, dir.eitskin(&["forward", "--triangles", "3000"]).stdout).unwrap();
    let pressed = dir.eitskin(&["forward", "--triangles", "3000", "--inclusion", "-50,20,12,2.0"]);
    std::fs::write(&frame, pressed.stdout).unwrap();
    let image = |polarity: &str| {
        let args = ["image", "--triangles", "1500", "--reference", reference.to_str().unwrap()];
        let args = [&args[..], &["--frame", frame.to_str().unwrap(), "--json", "--polarity", polarity]].concat();
        stdout_json(&dir.eitskin(&args))
    };
    let both = image("both");
    let touches = both["touches"].as_array().unwrap();
    assert_eq!(touches.len(), 1, "{both}");
    assert_eq!(touches[0]["sign"], "increase");
    let (x, y) = (touches[0]["x"].as_f64().unwrap(), touches[0]["y"].as_f64().unwrap());
    assert!((x + 50.0).hypot(y - 20.0) < 20.0, "touch at ({x}, {y}) mm, object at (-50, 20)");
    let lambda = both["hyperparameter"].as_f64().unwrap();
    // One reference frame: no measured noise, so the default 0.3 % of each value sets λ.
    assert!(lambda > 1.0 && lambda < 100.0, "λ = {lambda}");
    let labels = dir.join("labels.npy");
    let args = ["segment", "--triangles", "1500", "--reference", reference.to_str().unwrap(), "--frame"];
    let args =
        [&args[..], &[frame.to_str().unwrap(), "--polarity", "both", "--json", "--out", labels.to_str().unwrap()]];
    let counts = stdout_json(&dir.eitskin(&args.concat()));
    assert!(counts["more_conductive"].as_u64().unwrap() > 0 && counts["less_conductive"] == 0, "{counts}");
    let bytes = std::fs::read(labels).unwrap();
    assert!(bytes.ends_with(&[0]) && bytes.contains(&2) && !bytes[128..].contains(&1), "labels: more conductive only");
    let decrease = image("decrease");
    assert!(decrease["touches"].as_array().unwrap().iter().all(|t| t["sign"] == "decrease"), "{decrease}");
}

/// A board that sends magnitudes in the OpenEIT firmware's 192-value opposite order, with a
/// channel missing, one dead and one masked in the spec: the signs come from the model, the
/// three channels are dropped and named, and the raster and element values are written as data.
#[test]
fn image_signs_magnitudes_drops_a_missing_channel_and_writes_data() {
    let dir = scratch("image-magnitudes");
    let spec = dir.join("opposite.toml");
    let text = String::from_utf8(dir.eitskin(&["spec"]).stdout).unwrap();
    // Channel 7 is a known fault of the board, dropped in the spec.
    let text = text.replace("kind = \"two-terminal\"", "kind = \"opposite\"\ndrop_channels = [7]");
    std::fs::write(&spec, text).unwrap();
    let spec = spec.to_str().unwrap();
    let values = |extra: &[&str]| {
        let out = dir.eitskin(&[&["forward", spec, "--triangles", "3000"], extra].concat());
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        json["measurements"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect::<Vec<f64>>()
    };
    let reference = values(&[]);
    assert!(reference.iter().any(|v| *v < 0.0), "opposite-drive measurements have both signs");
    // Channel 11 is dead (the board prints 0 in every frame); channel 5 is missing in the frame.
    let magnitudes = |v: &[f64], missing: Option<usize>| {
        let text: Vec<String> = v
            .iter()
            .enumerate()
            .map(|(m, x)| match m {
                10 => "0".into(),
                _ if Some(m) == missing => "NaN".into(),
                _ => x.abs().to_string(),
            })
            .collect();
        text.join(" ")
    };
    let (ref_file, frame_file) = (dir.join("ref.txt"), dir.join("frame.txt"));
    std::fs::write(&ref_file, magnitudes(&reference, None)).unwrap();
    std::fs::write(&frame_file, magnitudes(&values(&["--inclusion", "40,-30,12,0.5"]), Some(4))).unwrap();
    let (npy, elements) = (dir.join("image.npy"), dir.join("elements.csv"));
    let out = dir.eitskin(&[
        "image",
        spec,
        "--triangles",
        "1500",
        "--values",
        "magnitude",
        "--reference",
        ref_file.to_str().unwrap(),
        "--frame",
        frame_file.to_str().unwrap(),
        "--out",
        npy.to_str().unwrap(),
        "--elements",
        elements.to_str().unwrap(),
        "--gains",
        "--background-change",
        "--raster",
        "80x40",
        "--json",
    ]);
    let json = stdout_json(&out);
    assert_eq!(json["channels_dropped"], serde_json::json!([5, 7, 11]), "{json}");
    // The simulated board follows the model (a finer mesh, gain 1, no background change).
    assert!(json["pattern_fit"].as_f64().unwrap() > 0.99, "{json}");
    // The dead and the masked channel are dropped once, and named by no check of the values.
    assert_eq!(json["gains"]["outliers"], serde_json::json!([]), "{json}");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("does not explain"), "{stderr}");
    assert!((json["gains"]["median"].as_f64().unwrap() - 1.0).abs() < 0.02, "{json}");
    assert!(json["background_change"]["relative"].as_f64().unwrap().abs() < 0.01, "{json}");
    let touches = json["touches"].as_array().unwrap();
    assert!(!touches.is_empty(), "{json}");
    let (x, y) = (touches[0]["x"].as_f64().unwrap(), touches[0]["y"].as_f64().unwrap());
    assert!((x - 40.0).hypot(y + 30.0) < 20.0, "touch at ({x}, {y}) mm, press at (40, -30)");
    let npy = std::fs::read(npy).unwrap();
    assert_eq!(&npy[..6], b"\x93NUMPY");
    let header = String::from_utf8_lossy(&npy[..128]);
    assert!(header.contains("'shape': (40, 80,"), "the raster asked for: {header}");
    let rows = std::fs::read_to_string(elements).unwrap().lines().count();
    assert!(rows > 1000, "{rows} element rows");
}

#[test]
fn sensitivity_writes_the_profile_and_map() {
    let dir = scratch("sensitivity");
    let out = dir.eitskin(&["sensitivity", "--out", dir.to_str().unwrap(), "--refine", "2", "--map", "3"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let csv = std::fs::read_to_string(dir.join("profile.csv")).unwrap();
    let peaks: Vec<f64> = csv.lines().skip(1).map(|l| l.split(',').nth(1).unwrap().parse().unwrap()).collect();
    assert_eq!(peaks.len(), 17);
    assert!(peaks[0] > 2.0 * peaks[8] && peaks[16] > 2.0 * peaks[8], "edges must image stronger: {peaks:?}");
    for png in ["profile.png", "map.png"] {
        assert_eq!(&std::fs::read(dir.join(png)).unwrap()[1..4], b"PNG");
    }
}

/// A frame of another length than the protocol's stopped `image` with a panic (an assertion in
/// the gains' estimate); it is refused, naming the file, the frame and both counts.
#[test]
fn a_frame_of_another_length_is_refused_not_a_panic() {
    let dir = scratch("short-frame");
    let frame = dir.join("short.csv");
    std::fs::write(&frame, "1,2,3\n").unwrap();
    let f = frame.to_str().unwrap();
    let out = dir.eitskin(&["image", "--reference", f, "--frame", f]);
    assert_eq!(
        String::from_utf8_lossy(&out.stderr),
        format!(
            "error: {f}: frame 1 holds 3 values, but the protocol (two-terminal, all 120 pairs of 16 electrodes) has 120: is it another protocol, or another board's order?\n"
        )
    );
    assert_eq!(out.status.code(), Some(1));
}

/// A frame in other units than its reference (millivolts against volts) is refused with the
/// ratio, not imaged as a whole-sheet change; one twice as large is imaged with a warning; a
/// reference of equal frames is said to measure no noise.
#[test]
fn a_frame_in_another_unit_than_its_reference_is_refused() {
    let dir = scratch("frame-scale");
    let reference = String::from_utf8(dir.eitskin(&["forward", "--format", "csv"]).stdout).unwrap();
    let values: Vec<f64> = reference.lines().skip(1).map(|l| l.split(',').nth(1).unwrap().parse().unwrap()).collect();
    let write = |name: &str, scale: f64| {
        let path = dir.join(name);
        std::fs::write(&path, values.iter().map(|v| (v * scale).to_string()).collect::<Vec<_>>().join(",")).unwrap();
        path
    };
    let (r, millivolts, doubled) = (write("ref.csv", 1.0), write("mv.csv", 1000.0), write("double.csv", 2.5));
    let image = |frame: &std::path::Path| {
        dir.eitskin(&["image", "--reference", r.to_str().unwrap(), "--frame", frame.to_str().unwrap(), "--no-cache"])
    };
    let out = image(&millivolts);
    let message = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && message.contains("mv.csv has values typically 1000.000 times those of"),
        "{message}"
    );
    assert!(message.contains("are the two in the same unit and gain?"), "{message}");
    let out = image(&doubled);
    let message = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success() && message.contains("warning: ") && message.contains("2.500 times"), "{message}");

    // Reference frames that are all equal measure no noise (they dropped 101 channels whose
    // mean rounded, silently): said, and the default noise assumed.
    let row = values.iter().map(f64::to_string).collect::<Vec<_>>().join(",");
    let equal = dir.join("equal.csv");
    std::fs::write(&equal, format!("{row}\n{row}\n{row}\n")).unwrap();
    let e = equal.to_str().unwrap();
    let out = dir.eitskin(&["image", "--reference", e, "--frame", doubled.to_str().unwrap(), "--no-cache"]);
    let message = String::from_utf8_lossy(&out.stderr);
    assert!(
        message.contains("reference frames of") && message.contains("are all equal: no noise can be measured"),
        "{message}"
    );
    let report = String::from_utf8_lossy(&out.stdout);
    assert!(!report.contains("dropped"), "{report}");
}

/// Labelled samples of real values against frames at rest that are complex: which part the
/// samples hold is not the command's to guess, so it refuses and says what to give; a samples
/// file of a header and no rows, made by a spreadsheet (byte-order mark first), is named so.
#[test]
fn samples_and_references_that_cannot_go_together_are_refused() {
    let dir = scratch("complex-reference");
    let samples = dir.join("samples.csv");
    let channels: Vec<String> = (1..=120).map(|m| format!("v{m}")).collect();
    let values = vec!["1.0"; 120].join(",");
    std::fs::write(&samples, format!("x,y,force,{}\n10,20,5,{values}\n", channels.join(","))).unwrap();
    // Three frames of 120 complex values, 1 + 0.1i each.
    let values: Vec<u8> = (0..360).flat_map(|_| [1.0f64.to_le_bytes(), 0.1f64.to_le_bytes()].concat()).collect();
    let reference = dir.join("rest.npy");
    std::fs::write(&reference, eitskin_testdata::npy("<c16", [3, 120], &values)).unwrap();
    let (s, r) = (samples.to_str().unwrap(), reference.to_str().unwrap());
    let out_path = dir.join("c.json");
    let o = out_path.to_str().unwrap();
    let out = dir.eitskin(&["calibrate", "--samples", s, "--reference", r, "--strength", "fitted-drop", "--out", o]);
    assert_eq!(
        String::from_utf8_lossy(&out.stderr),
        format!("error: --reference {r}: holds complex values, and the samples' frames are real: give the frames at rest as the same real values the samples hold (magnitudes, or real parts)\n")
    );
    std::fs::write(&samples, "\u{feff}x,y,force,v1\n").unwrap();
    let out = dir.eitskin(&["calibrate", "--samples", s, "--out", o]);
    assert_eq!(
        String::from_utf8_lossy(&out.stderr),
        format!("error: {s}: `samples` line 1: a header and no samples under it\n")
    );
    // Frames at rest of another length are named by their file and frame, once; samples of
    // another length by theirs; samples all at 0 N have nothing to read.
    let ones = vec!["1.0"; 120].join(",");
    std::fs::write(&samples, format!("x,y,force,{}\n10,20,5,{ones}\n", channels.join(","))).unwrap();
    let rest = dir.join("rest.txt");
    std::fs::write(&rest, format!("{}\n", vec!["1.0"; 119].join(","))).unwrap();
    let rest = rest.to_str().unwrap();
    // (`evaluate` reads its samples through the same function.)
    let out = dir.eitskin(&["calibrate", "--samples", s, "--reference", rest, "--out", o]);
    assert_eq!(
        String::from_utf8_lossy(&out.stderr),
        format!(
            "error: --reference {rest}: frame 1 holds 119 values, and the sensor's protocol has 120 measurements\n"
        )
    );
    std::fs::write(&samples, "x,y,force,v1,v2\n10,20,5,1,1\n").unwrap();
    let out = dir.eitskin(&["calibrate", "--samples", s, "--reference", rest, "--out", o]);
    assert_eq!(
        String::from_utf8_lossy(&out.stderr),
        format!("error: {s}: each sample holds 2 values, and the sensor's protocol has 120 measurements\n")
    );
    std::fs::write(&samples, format!("x,y,force,{}\n10,20,0,{ones}\n", channels.join(","))).unwrap();
    let out = dir.eitskin(&["calibrate", "--samples", s, "--out", o]);
    assert_eq!(
        String::from_utf8_lossy(&out.stderr),
        format!("error: {s}: every sample is at 0 N (the sheet at rest): there is no press to read\n")
    );
    // Frames at rest in another unit (mV where the samples hold V) are refused with the ratio,
    // where calibration searched every frame for touches and said only that an area had none.
    std::fs::write(&samples, format!("x,y,force,{}\n10,20,5,{ones}\n", channels.join(","))).unwrap();
    let millivolts = dir.join("rest_mv.txt");
    std::fs::write(&millivolts, format!("{}\n", vec!["1000.0"; 120].join(","))).unwrap();
    let out = dir.eitskin(&["calibrate", "--samples", s, "--reference", millivolts.to_str().unwrap(), "--out", o]);
    assert_eq!(
        String::from_utf8_lossy(&out.stderr),
        format!(
            "error: {s}: the pressed frames' values are typically 0.001 times those of --reference {} (the median over frames and channels): a press changes them by percents; are the two from the same sensor, unit and gain?\n",
            millivolts.display()
        )
    );
    // Frames at rest from two places that disagree: the samples' 0 N rows in Ω, --reference in kΩ.
    let kilo = dir.join("rest_k.txt");
    std::fs::write(&kilo, format!("{}\n", vec!["0.001"; 120].join(","))).unwrap();
    std::fs::write(&samples, format!("x,y,force,{}\n10,20,0,{ones}\n10,20,5,{ones}\n", channels.join(","))).unwrap();
    let out = dir.eitskin(&["calibrate", "--samples", s, "--reference", kilo.to_str().unwrap(), "--out", o]);
    let message = String::from_utf8_lossy(&out.stderr);
    assert!(message.contains("the 0 N frames' values are typically 1000.000 times those of --reference"), "{message}");
    // Labels that leave an area without three forces are refused before any frame is imaged
    // (it took a minute to say so).
    let out = dir.eitskin(&["calibrate", "--samples", s, "--out", o]);
    let message = String::from_utf8_lossy(&out.stderr);
    assert!(
        message.contains("has presses at 0 distinct force(s) by the labels; its curve needs 3 or more"),
        "{message}"
    );
    // Peaks are read as they are: frames at rest given with them are refused, as are a negative
    // peak, a value past any measurement and a JSON file given as samples.
    let peaks = dir.join("peaks.csv");
    let p = peaks.to_str().unwrap();
    std::fs::write(&peaks, "unit,force,peak\n1,5,0.2\n").unwrap();
    let out = dir.eitskin(&["calibrate", "--samples", p, "--reference", rest, "--out", o]);
    assert!(String::from_utf8_lossy(&out.stderr).contains(&format!("{p} holds peaks, read as they are")), "{out:?}");
    for (row, said) in [("1,5,-0.2", "peak -0.2 S/m is negative"), ("1,5,1e300", "column 3 (1e300) is past ±1e30")] {
        std::fs::write(&peaks, format!("unit,force,peak\n{row}\n")).unwrap();
        let out = dir.eitskin(&["calibrate", "--samples", p, "--out", o]);
        assert!(String::from_utf8_lossy(&out.stderr).contains(said), "{out:?}");
    }
    std::fs::write(&peaks, r#"{"format": "eitskin-learned-model", "version": 2}"#).unwrap();
    let out = dir.eitskin(&["calibrate", "--samples", p, "--out", o]);
    let message = String::from_utf8_lossy(&out.stderr);
    assert!(
        message.contains("line 1: this is a learned model (what `eitskin learn --out` writes), not samples"),
        "{message}"
    );
    // An output that is a folder is refused before any work.
    let folder = dir.join("folder.json");
    std::fs::create_dir(&folder).unwrap();
    let out = dir.eitskin(&["calibrate", "--samples", s, "--out", folder.to_str().unwrap()]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("is a folder; give the path of a file to write"), "{out:?}");
}
