//! Through the real binary: model inputs that gave an answer without a word (a frame at rest, a
//! table of NaN, values of 1e300 Ω) are refused before any work, naming the flag or the file
//! (and its line or key) and quoting the value as written: inclusions that cover no triangle,
//! convergence levels that are not coarse to fine, protocol patterns of nothing or of too much,
//! press scripts off the sheet or out of range, and a spec's conductivity out of its range; a
//! `--triangles` under what the mesher makes is raised with a warning; quadratic elements
//! refused for point electrodes.

mod binary;

use std::path::{Path, PathBuf};
use std::process::Output;

use binary::{ok, scratch};

/// The standard error of a run that must have failed with nothing on standard output.
fn refused(out: Output) -> String {
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(!out.status.success(), "accepted: {stdout}");
    assert!(stdout.is_empty(), "printed: {stdout}");
    String::from_utf8(out.stderr).expect("UTF-8")
}

/// `text` written to `name` in `dir`.
fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

fn text(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// An inclusion off the sheet, or too small to cover a triangle, printed the frame at rest.
#[test]
fn forward_refuses_an_inclusion_that_covers_no_triangle() {
    let dir = scratch("inclusion");
    let forward = |inclusion: &str| dir.eitskin(&["forward", "--triangles", "1000", "--inclusion", inclusion]);
    let err = refused(forward("5000,0,10,0.5"));
    assert!(
        err.starts_with(
            "error: --inclusion \"5000,0,10,0.5\": its centre (5000, 0) mm is off the sheet (x from -100 to 100 mm, y from -100 to 100 mm)"
        ),
        "{err}"
    );
    let err = refused(forward("0,0,1e-9,0.5"));
    assert!(
        err.starts_with("error: --inclusion \"0,0,1e-9,0.5\": its radius 1e-9 mm covers no triangle's centroid"),
        "{err}"
    );
    assert!(err.contains("give a radius of at least"), "{err}");
    let err = refused(forward("0,0,10,1e-300"));
    assert_eq!(err, "error: --inclusion \"0,0,10,1e-300\": its conductivity 1e-300 S/m is outside [1e-6, 1e6] S/m\n");
    // One that covers triangles still changes the frame.
    let rest = ok(dir.eitskin(&["forward", "--triangles", "1000", "--format", "csv"]));
    assert_ne!(ok(forward("0,0,30,0.5")), rest);
}

/// Levels that are not coarse to fine printed a table of NaN, or were accepted; an inclusion off
/// the sheet gave "difference error NaN".
#[test]
fn convergence_refuses_levels_not_coarse_to_fine_and_inclusions_that_change_nothing() {
    let dir = scratch("convergence");
    let convergence = |args: &[&str]| dir.eitskin(&[&["convergence"], args].concat());
    let err = refused(convergence(&["--triangles", "1000,1000,1000"]));
    assert!(
        err.starts_with("error: --triangles 1000,1000,1000: level 2 (1000) is not more than level 1 (1000)"),
        "{err}"
    );
    let err = refused(convergence(&["--triangles", "4000,2000,1000"]));
    assert!(
        err.starts_with("error: --triangles 4000,2000,1000: level 2 (2000) is not more than level 1 (4000)"),
        "{err}"
    );
    let err = refused(convergence(&["--triangles", "1,2,3"]));
    assert!(
        err.starts_with("error: --triangles 1,2,3: levels 1 and 2 (1 and 2) are both below the fewest the mesher makes on this sheet, about"),
        "{err}"
    );
    let err = refused(convergence(&["--triangles", "500,1000,2000", "--inclusion", "5000,0,10,0.5"]));
    assert!(err.starts_with("error: --inclusion \"5000,0,10,0.5\": on the finest level's mesh, its centre (5000, 0) mm is off the sheet"), "{err}");
    let err = refused(convergence(&["--triangles", "500,1000,2000", "--inclusion", "0,0,1e-9,0.5"]));
    assert!(err.contains("its radius 1e-9 mm covers no triangle's centroid"), "{err}");
    let err = refused(convergence(&["--triangles", "500,1000,2000", "--inclusion", "0,0,20,1"]));
    assert!(err.contains("its conductivity is the background's (1 S/m)"), "{err}");
    // A level under the fewest is raised with a warning, and the table holds numbers.
    let out = convergence(&["--triangles", "1,1000,2000", "--json"]);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    let json: serde_json::Value = serde_json::from_str(&ok(out)).unwrap();
    assert!(stderr.starts_with("warning: --triangles 1,1000,2000: level 1 (1) is below the fewest"), "{stderr}");
    for level in json["levels"].as_array().unwrap() {
        for key in ["value_error", "difference_error"] {
            assert!(level[key].as_f64().is_some_and(f64::is_finite), "{json}");
        }
    }
}

/// `--elements p2` studies quadratic elements, and refuses point electrodes before any work.
#[test]
fn convergence_studies_quadratic_elements_of_complete_electrodes_only() {
    let dir = scratch("quadratic");
    let out = ok(dir.eitskin(&["convergence", "--elements", "p2", "--triangles", "500,1000,2000", "--json"]));
    let json: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(json["elements"], "p2", "{json}");
    let errors: Vec<f64> =
        json["levels"].as_array().unwrap().iter().map(|l| l["value_error"].as_f64().unwrap()).collect();
    assert!(errors.iter().all(|e| e.is_finite()) && errors[2] < errors[0], "{json}");
    let spec = write(
        &dir,
        "points.toml",
        "units = \"m\"\nthickness = 1.0\nconductivity = 1.0\n[outline]\nkind = \"circle\"\nradius = 1.0\n[electrodes]\ncount = 16\nmodel = \"point\"\nplacement = \"equal\"\n",
    );
    let err = refused(dir.eitskin(&["convergence", text(&spec), "--elements", "p2", "--triangles", "500,1000,2000"]));
    assert!(err.starts_with("error: --elements p2: the sensor has point electrodes"), "{err}");
}

/// `mesh --triangles 1` made 200 triangles without a word.
#[test]
fn a_triangle_count_under_the_fewest_is_raised_with_a_warning() {
    let dir = scratch("fewest");
    let out = dir.eitskin(&["mesh", "--triangles", "1", "--out", text(&dir.join("m.json"))]);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    let stdout = ok(out);
    let made = stdout.split(" triangles").next().and_then(|s| s.rsplit(' ').next()).unwrap();
    assert!(
        stderr.starts_with("warning: --triangles 1 is below the fewest the mesher makes on this sheet, about ")
            && stderr.ends_with(&format!(": the mesh has {made}\n")),
        "{stderr}"
    );
    let out = dir.eitskin(&["forward", "--triangles", "50", "--format", "csv"]);
    assert!(String::from_utf8_lossy(&out.stderr).starts_with("warning: --triangles 50 is below the fewest"));
    let out = dir.eitskin(&["mesh", "--triangles", "2000", "--out", text(&dir.join("m.json"))]);
    assert!(out.stderr.is_empty(), "{}", String::from_utf8_lossy(&out.stderr));
}

/// A stimulation of no current or a measurement of no weight printed 0 values, currents of
/// 1e300 A printed 1e300 Ω, and a protocol of 8 electrodes on a 16-electrode sensor was refused
/// without naming its file.
#[test]
fn protocol_files_of_nothing_too_much_or_another_sensor_are_refused_naming_the_file() {
    let dir = scratch("protocol");
    let measure = r#"{"stimulation": 1, "weights": [0, 0, 1, -1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]}"#;
    let drive = "[1, -1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]";
    let zero = "[0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]";
    let cases = [
        (
            "no_current.json",
            format!(r#"{{"stimulations": [{drive}, {zero}], "measurements": [{measure}]}}"#),
            "the protocol is not valid: stimulation 2 drives no current: every electrode's current is 0 A",
        ),
        (
            "no_weight.json",
            format!(
                r#"{{"stimulations": [{drive}], "measurements": [{measure}, {{"stimulation": 1, "weights": {zero}}}]}}"#
            ),
            "the protocol is not valid: measurement 2 weighs no electrode: every weight is 0",
        ),
        (
            "huge.json",
            format!(
                r#"{{"stimulations": [[1e300, -1e300, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]], "measurements": [{measure}]}}"#
            ),
            "the protocol is not valid: stimulation 1 puts a current of 1e300 A on electrode 1: past ±1e3 A, more than any board uses",
        ),
        (
            "pr_el8.json",
            r#"{"electrodes": 8, "quads": [[1, 2, 3, 4], [1, 2, 5, 6]]}"#.to_string(),
            "`electrodes` is 8 (as given, or the most its patterns name), but the sensor has 16 electrodes (the spec's `electrodes.count`): is it another sensor's protocol?",
        ),
    ];
    for (name, json, says) in cases {
        let path = write(&dir, name, &json);
        let err = refused(dir.eitskin(&["forward", "--triangles", "500", "--protocol", text(&path)]));
        assert_eq!(err, format!("error: {}: {says}\n", path.display()), "{name}");
    }
}

/// Press scripts far off the sheet, with NaN, 1e9 N, negative times or times of 1e300 ran
/// without a word.
#[test]
fn press_scripts_out_of_range_are_refused_naming_the_file_and_line() {
    let dir = scratch("script");
    let cases = [
        (
            "1 2 5000 0 8",
            "the press at (5000, 0) mm is far off the sheet (its outline spans -100 to 100 by -100 to 100 mm)",
        ),
        ("1 2 nan 0 8", "nan is not a finite number"),
        ("1 2 0 0 1e9", "force 1e9 N is outside 0–1e5 N"),
        ("-1 2 0 0 8", "start -1 s is outside 0–1e9 s"),
        ("1 1e300 0 0 8", "end 1e300 s is outside 0–1e9 s"),
        ("2 1 0 0 8", "end 1 s is not after start 2 s"),
    ];
    for (line, says) in cases {
        let script = write(&dir, "script.txt", &format!("# start end x y force\n0.5 1 10 10 5\n{line}\n"));
        let source = format!("sim:{}", script.display());
        let err = refused(dir.eitskin(&["run", "--source", &source, "--fast", "--frames", "30", "--triangles", "500"]));
        let line_3 = format!("{}: script line 3: {says}", script.display());
        assert!(err.contains(&line_3), "{line}: {err}");
        assert!(!err.contains("\n\n"), "{err}");
    }
}

/// A conductivity of 1e-300 S/m reached the solver, which said the mesh might not be connected.
#[test]
fn a_spec_conductivity_out_of_range_is_refused_naming_the_key() {
    let dir = scratch("spec-range");
    let spec = ok(dir.eitskin(&["spec"]));
    for (from, to, says) in [
        (
            "conductivity = 1.0",
            "conductivity = 1e-300",
            "`conductivity` must be a finite number within [1e-6, 1e6] S/m, got 1e-300 S/m",
        ),
        (
            "contact_impedance = 0.0001",
            "contact_impedance = 1e300",
            "`electrodes.contact_impedance` must be a finite number within [1e-9, 1e3] Ω·m², got 1e300 Ω·m²",
        ),
        (
            "thickness = 10.0",
            "thickness = 1e-300",
            "`thickness` must be a finite number within [0.001 mm, 1000000 mm], got 1e-300 mm",
        ),
    ] {
        assert!(spec.contains(from), "{spec}");
        let path = write(&dir, "spec.toml", &spec.replace(from, to));
        let err = refused(dir.eitskin(&["forward", text(&path), "--triangles", "500"]));
        assert_eq!(err, format!("error: {}: the spec does not make a sensor: {says}\n", path.display()));
    }
}
