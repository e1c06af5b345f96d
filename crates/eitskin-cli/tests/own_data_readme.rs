//! The book's "Your own data" (docs/src/own-data.md): a tank's MAT file (homogeneous and object frames as two
//! variables, one frame per column) to touches and a label image, with the chapter's own spec
//! and commands, on frames simulated by `forward` (an object of known place and sign).

mod binary;

use binary::{ok, scratch};

/// The spec between `cat > tank.toml <<'TOML'` and `TOML` in the book's chapter.
fn readme_spec() -> String {
    let readme = include_str!("../../../docs/src/own-data.md");
    let start = readme.find("cat > tank.toml <<'TOML'\n").expect("the chapter writes tank.toml") + 25;
    let end = start + readme[start..].find("\nTOML\n").expect("the spec ends");
    readme[start..end].to_string()
}

#[test]
fn a_tank_mat_file_gives_touches_and_labels_with_the_readmes_commands() {
    let dir = scratch("own-data");
    let spec = dir.join("tank.toml");
    std::fs::write(&spec, readme_spec()).unwrap();
    let spec = spec.to_str().unwrap();
    let forward = |extra: &[&str]| -> Vec<f64> {
        let json: serde_json::Value =
            serde_json::from_str(&ok(dir.eitskin(&[&["forward", spec], extra].concat()))).unwrap();
        json["measurements"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect()
    };
    let homogeneous = forward(&[]);
    assert_eq!(homogeneous.len(), 208, "16 electrodes, adjacent: 16 × 13");
    let object = forward(&["--inclusion", "60,40,15,3.0"]);
    // Two homogeneous frames a little apart (the board's noise), three object frames.
    let vh: Vec<f64> = [0.998, 1.002].iter().flat_map(|k| homogeneous.iter().map(move |v| v * k)).collect();
    let vi: Vec<f64> = (0..3).flat_map(|_| object.iter().copied()).collect();
    let mat = dir.join("tank.mat");
    std::fs::write(&mat, eitskin_testdata::mat5(&[("vh", 208, 2, &vh), ("vi", 208, 3, &vi)])).unwrap();
    let mat = mat.to_str().unwrap();
    let input = ["--reference", mat, "--reference-select", "vh", "--frame", mat, "--select", "vi"];
    let input = [&input[..], &["--polarity", "both"]].concat();
    let image: serde_json::Value =
        serde_json::from_str(&ok(dir.eitskin(&[&["image", spec], &input[..], &["--frames", "3", "--json"]].concat())))
            .unwrap();
    assert!(image["pattern_fit"].as_f64().unwrap() > 0.99, "{image}");
    let touches = image["touches"].as_array().unwrap();
    assert_eq!(touches.len(), 1, "{image}");
    assert_eq!(touches[0]["sign"], "increase");
    let (x, y) = (touches[0]["x"].as_f64().unwrap(), touches[0]["y"].as_f64().unwrap());
    assert!((x - 60.0).hypot(y - 40.0) < 20.0, "touch at ({x}, {y}) mm, object at (60, 40)");
    let labels = dir.join("labels.npy");
    let out =
        [&["segment", spec], &input[..], &["--frames", "all", "--json", "--out", labels.to_str().unwrap()]].concat();
    let counts: serde_json::Value = serde_json::from_str(&ok(dir.eitskin(&out))).unwrap();
    let frames = counts["frames"].as_array().unwrap();
    assert_eq!(frames.len(), 3, "every frame of vi: {counts}");
    for f in frames {
        assert!(f["more_conductive"].as_u64().unwrap() > 0 && f["less_conductive"] == 0, "{counts}");
    }
    assert_eq!(&std::fs::read(labels).unwrap()[..6], b"\x93NUMPY");
}
