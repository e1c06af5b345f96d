//! Every kind of invalid spec is refused with a message naming the key and the reason.

use std::path::Path;

use eitskin_io::{full_message, parse_spec};

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
        Err(e) => full_message(&e),
    }
}

/// The spec is refused with exactly `expected`: every part of the message once.
#[track_caller]
fn assert_refused(text: &str, expected: &str) {
    assert_eq!(message(text), expected);
}

const SPEC: &str = "the spec does not make a sensor: ";

#[test]
fn the_paper_spec_is_accepted() {
    let spec = parse_spec(PAPER, Path::new(".")).unwrap();
    assert_eq!(spec, eitskin::SensorSpec::square_hydrogel());
}

#[test]
fn unknown_key_is_named() {
    assert_refused(
        &PAPER.replace("count = 16", "count = 16\ncolour = \"red\""),
        "TOML parse error at line 13, column 1\n   |\n13 | colour = \"red\"\n   | ^^^^^^\nunknown field `colour`, \
         expected one of `count`, `model`, `width`, `contact_impedance`, `placement`, `numbering`, `start_angle_deg`, \
         `positions`\n",
    );
    assert_refused(
        &format!("{PAPER}\nfoo = 1"),
        "TOML parse error at line 23, column 1\n   |\n23 | foo = 1\n   | ^^^\nunknown field `foo`, \
         expected one of `triangles`, `max_element_size`, `grading`, `min_angle_deg`\n",
    );
    assert_refused(
        &PAPER.replace("height = 200.0", "height = 200.0\nradius = 3.0"),
        "TOML parse error at line 6, column 1\n  |\n6 | [outline]\n  | ^^^^^^^^^\nunknown field `radius`, \
         expected `width` or `height`\n",
    );
}

#[test]
fn self_crossing_polygon_is_refused() {
    let bow = PAPER.replace(
        "kind = \"rectangle\"\nwidth = 200.0\nheight = 200.0",
        "kind = \"polygon\"\npoints = [[0, 0], [100, 100], [100, 0], [0, 100]]",
    );
    let bow = bow.replace("placement = \"per-side\"", "placement = \"explicit\"\npositions = []");
    assert_refused(
        &bow,
        &format!(
            "{SPEC}`outline.points`: edge 1 crosses edge 3 (edge k joins point k to point k+1, counting from 1); \
             the outline must be a simple polygon"
        ),
    );
}

#[test]
fn clockwise_polygon_is_refused() {
    let cw = PAPER.replace(
        "kind = \"rectangle\"\nwidth = 200.0\nheight = 200.0",
        "kind = \"polygon\"\npoints = [[0, 0], [0, 100], [100, 100], [100, 0]]",
    );
    assert_refused(&cw, &format!("{SPEC}`outline.points` run clockwise; list them counter-clockwise"));
}

#[test]
fn overlapping_electrodes_are_refused() {
    let circle = PAPER
        .replace("kind = \"rectangle\"\nwidth = 200.0\nheight = 200.0", "kind = \"circle\"\nradius = 20.0")
        .replace("placement = \"per-side\"", "placement = \"equal\"");
    // 16 electrodes 10 mm wide on a 125.7 mm circumference: centres 7.85 mm apart.
    assert_refused(
        &circle,
        &format!(
            "{SPEC}electrodes 1 and 2 overlap: their centres are 7.854 mm apart along the boundary \
             but `electrodes.width` is 10 mm"
        ),
    );
}

#[test]
fn electrode_wider_than_its_side_is_refused() {
    let wide = PAPER.replace("height = 200.0", "height = 8.0");
    assert_refused(&wide, &format!("{SPEC}`electrodes.width` = 10 mm is wider than side 2 (8 mm) of the rectangle"));
}

#[test]
fn non_positive_values_are_refused() {
    assert_refused(
        &PAPER.replace("conductivity = 1.0", "conductivity = 0.0"),
        &format!("{SPEC}`conductivity` must be a positive number, got 0 S/m"),
    );
    assert_refused(
        &PAPER.replace("contact_impedance = 1e-4", "contact_impedance = -1e-4"),
        &format!("{SPEC}`electrodes.contact_impedance` must be a positive number, got -0.0001 Ω·m²"),
    );
    assert_refused(
        &PAPER.replace("thickness = 10.0", "thickness = -0.2"),
        &format!("{SPEC}`thickness` must be a finite number within [0.001 mm, 1000000 mm], got -0.2 mm"),
    );
    assert_refused(
        &PAPER.replace("width = 200.0", "width = 0.0"),
        &format!("{SPEC}`outline.width` must be a finite number within [0.001 mm, 1000000 mm], got 0 mm"),
    );
    assert_refused(
        &PAPER.replace("units = \"mm\"", "units = \"m\"").replace("width = 200.0", "width = 0.0"),
        &format!("{SPEC}`outline.width` must be a finite number within [0.000001 m, 1000 m], got 0 m"),
    );
}

/// Each mesh value has a range: a grading above 1 was clamped to 1 without a word, and an angle
/// the refinement cannot reach ran it to its vertex limit.
#[test]
fn mesh_values_and_electrode_counts_out_of_range_are_refused() {
    let mesh = |line: &str| PAPER.replace("triangles = 4000", line);
    assert_refused(
        &mesh("triangles = 0"),
        &format!("{SPEC}`mesh.triangles` must be a finite number within [1, 100000000], got 0"),
    );
    assert_refused(
        &mesh("grading = 2.0"),
        &format!("{SPEC}`mesh.grading` must be a finite number within [0.001, 1], got 2"),
    );
    assert_refused(
        &mesh("min_angle_deg = 40.0"),
        &format!("{SPEC}`mesh.min_angle_deg` must be a finite number within (0, 33] degrees, got 40 degrees"),
    );
    assert_refused(
        &mesh("max_element_size = -0.5"),
        &format!("{SPEC}`mesh.max_element_size` must be a finite number within [0.001 mm, 1000000 mm], got -0.5 mm"),
    );
    assert_refused(
        &PAPER.replace("count = 16", "count = 1024"),
        &format!("{SPEC}`electrodes.count` = 1024: at most 256 electrodes are taken"),
    );
}

#[test]
fn misplaced_and_missing_keys_are_named() {
    assert_refused(
        &PAPER.replace("kind = \"rectangle\"\nwidth = 200.0\nheight = 200.0", "kind = \"circle\"\nradius = 100.0"),
        &format!(
            "{SPEC}`electrodes.placement` = \"per-side\" does not fit a circle outline; per-side is for \
             rectangles; use \"equal\" spacing or \"explicit\" positions"
        ),
    );
    assert_refused(
        &PAPER.replace("placement = \"per-side\"", "placement = \"per-side\"\nnumbering = \"ccw\""),
        "`electrodes.numbering` must be \"counter-clockwise\" or \"clockwise\", got \"ccw\"",
    );
    assert_refused(
        &PAPER.replace("placement = \"per-side\"", "placement = \"equal\"\nstart_angle_deg = nan"),
        &format!("{SPEC}`electrodes.start_angle_deg` must be a finite number within [-360, 360] degrees, got NaN"),
    );
    assert_refused(
        &PAPER.replace("placement = \"per-side\"", "placement = \"per-side\"\nstart_angle_deg = 3.0"),
        "`electrodes.start_angle_deg` applies only to placement = \"equal\", not \"per-side\"",
    );
    assert_refused(
        &PAPER.replace("contact_impedance = 1e-4\n", ""),
        "`electrodes.contact_impedance` is required for complete electrodes",
    );
    assert_refused(
        &PAPER.replace("count = 16", "count = 14"),
        &format!("{SPEC}`electrodes.count` = 14: per-side placement needs a multiple of 4"),
    );
    assert_refused(
        &PAPER.replace("kind = \"two-terminal\"", "kind = \"four-terminal\""),
        "`protocol.kind` must be one of two-terminal, adjacent, adjacent-all, opposite, skip-S, skip-S-all (S = 0, 1, 2, …), or custom, got \"four-terminal\"",
    );
    assert_refused(
        &PAPER.replace("units = \"mm\"", "units = \"inch\""),
        "`units` must be \"mm\" or \"m\", got \"inch\"",
    );
    assert_refused(
        &PAPER.replace("thickness = 10.0\n", ""),
        "TOML parse error at line 1, column 1\n  |\n1 | \n  | ^\nmissing field `thickness`\n",
    );
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
    let err = full_message(&eitskin_io::read_spec(&dir.join("s.toml")).unwrap_err());
    let file = dir.join("p.json");
    let expected = format!(
        "{}: the protocol is not valid: row 1 names electrode 99, but electrodes are numbered 1 to 16",
        file.display()
    );
    assert_eq!(err, expected);
}
