//! Every kind of invalid spec is refused with a message naming the key and the reason.

use std::path::Path;

use eitskin_io::parse_spec;

const PAPER: &str = r#"
units = "mm"
thickness = 10.0
conductivity = 1.0

[outline]
kind = "rectangle"
width = 200.0
height = 200.0

[electrodes]
count = 16
width = 10.0
contact_impedance = 1e-4
placement = "per-side"

[protocol]
kind = "two-terminal"

[mesh]
triangles = 4000
"#;

fn message(text: &str) -> String {
    match parse_spec(text, Path::new(".")) {
        Ok(_) => panic!("the spec was accepted:\n{text}"),
        Err(e) => e.to_string(),
    }
}

fn assert_says(text: &str, parts: &[&str]) {
    let msg = message(text);
    for p in parts {
        assert!(msg.contains(p), "message {msg:?} does not say {p:?}");
    }
}

#[test]
fn the_paper_spec_is_accepted() {
    let spec = parse_spec(PAPER, Path::new(".")).unwrap();
    assert_eq!(spec, eitskin::SensorSpec::square_hydrogel());
}

#[test]
fn unknown_key_is_named() {
    assert_says(&PAPER.replace("count = 16", "count = 16\ncolour = \"red\""), &["unknown field `colour`", "line 13"]);
    assert_says(&format!("{PAPER}\nfoo = 1"), &["unknown field `foo`"]);
    assert_says(&PAPER.replace("height = 200.0", "height = 200.0\nradius = 3.0"), &["unknown field `radius`"]);
}

#[test]
fn self_crossing_polygon_is_refused() {
    let bow = PAPER.replace(
        "kind = \"rectangle\"\nwidth = 200.0\nheight = 200.0",
        "kind = \"polygon\"\npoints = [[0, 0], [100, 100], [100, 0], [0, 100]]",
    );
    let bow = bow.replace("placement = \"per-side\"", "placement = \"explicit\"\npositions = []");
    assert_says(&bow, &["`outline.points`", "edge 1 crosses edge 3", "simple polygon"]);
}

#[test]
fn clockwise_polygon_is_refused() {
    let cw = PAPER.replace(
        "kind = \"rectangle\"\nwidth = 200.0\nheight = 200.0",
        "kind = \"polygon\"\npoints = [[0, 0], [0, 100], [100, 100], [100, 0]]",
    );
    assert_says(&cw, &["`outline.points`", "clockwise"]);
}

#[test]
fn overlapping_electrodes_are_refused() {
    let circle = PAPER
        .replace("kind = \"rectangle\"\nwidth = 200.0\nheight = 200.0", "kind = \"circle\"\nradius = 20.0")
        .replace("placement = \"per-side\"", "placement = \"equal\"");
    // 16 electrodes 10 mm wide on a 125.7 mm circumference: centres 7.85 mm apart.
    assert_says(&circle, &["electrodes 1 and 2 overlap", "`electrodes.width` is 0.01 m"]);
}

#[test]
fn electrode_wider_than_its_side_is_refused() {
    let wide = PAPER.replace("height = 200.0", "height = 8.0");
    assert_says(&wide, &["`electrodes.width` = 0.01 m is wider than side 2"]);
}

#[test]
fn non_positive_values_are_refused() {
    assert_says(
        &PAPER.replace("conductivity = 1.0", "conductivity = 0.0"),
        &["`conductivity` must be a positive number"],
    );
    assert_says(
        &PAPER.replace("contact_impedance = 1e-4", "contact_impedance = -1e-4"),
        &["`electrodes.contact_impedance` must be a positive number", "-0.0001"],
    );
    assert_says(&PAPER.replace("thickness = 10.0", "thickness = -1.0"), &["`thickness` must be a positive number"]);
    assert_says(&PAPER.replace("width = 200.0", "width = 0.0"), &["`outline.width` must be a positive number"]);
}

#[test]
fn misplaced_and_missing_keys_are_named() {
    assert_says(
        &PAPER.replace("placement = \"per-side\"", "placement = \"equal\""),
        &["`electrodes.placement` = \"equal\" does not fit a rectangle outline"],
    );
    assert_says(
        &PAPER.replace("placement = \"per-side\"", "placement = \"per-side\"\nstart_angle_deg = 3.0"),
        &["`electrodes.start_angle_deg` applies only to placement = \"equal\""],
    );
    assert_says(&PAPER.replace("contact_impedance = 1e-4\n", ""), &["`electrodes.contact_impedance` is required"]);
    assert_says(&PAPER.replace("count = 16", "count = 14"), &["`electrodes.count` = 14", "multiple of 4"]);
    assert_says(&PAPER.replace("kind = \"two-terminal\"", "kind = \"four-terminal\""), &["`protocol.kind` must be"]);
    assert_says(&PAPER.replace("units = \"mm\"", "units = \"inch\""), &["`units` must be \"mm\" or \"m\""]);
    assert_says(&PAPER.replace("thickness = 10.0\n", ""), &["missing field `thickness`"]);
}

#[test]
fn a_custom_protocol_file_is_read_relative_to_the_spec() {
    let folder = tempfile::Builder::new().prefix("eitskin-spec-").tempdir().unwrap();
    let dir = folder.path();
    std::fs::write(dir.join("p.json"), r#"{"electrodes": 16, "quads": [[1, 9, 1, 9], [2, 10, 3, 4]]}"#).unwrap();
    let text = PAPER.replace("kind = \"two-terminal\"", "kind = \"custom\"\nfile = \"p.json\"");
    std::fs::write(dir.join("s.toml"), &text).unwrap();
    let spec = eitskin_io::read_spec(&dir.join("s.toml")).unwrap();
    assert_eq!(spec.protocol().unwrap().len(), 2);
    std::fs::write(dir.join("p.json"), r#"{"electrodes": 16, "quads": [[1, 9, 1, 99]]}"#).unwrap();
    let err = eitskin_io::read_spec(&dir.join("s.toml")).unwrap_err().to_string();
    assert!(err.contains("p.json") && err.contains("electrode 99"), "{err}");
}
