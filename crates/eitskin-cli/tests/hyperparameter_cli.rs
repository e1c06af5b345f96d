//! `image`'s automatic λ says how it weighted the channels, and that λ given back with that
//! weighting gives the same image; the λ is kept in the cache for the same channels and noise;
//! λ chosen from the frame by a named criterion.

mod binary;

use binary::{ok, scratch};
use serde_json::Value;

#[test]
fn the_printed_lambda_and_weighting_given_back_reproduce_the_image() {
    let dir = scratch("auto-lambda");
    let write = |name: &str, args: &[&str]| {
        let path = dir.join(name);
        std::fs::write(&path, ok(dir.eitskin(&[&["forward", "--format", "csv"], args].concat()))).unwrap();
        path.to_str().unwrap().to_owned()
    };
    let (reference, frame) = (write("reference.csv", &[]), write("frame.csv", &["--inclusion=30,-20,20,0.2"]));
    let image = |extra: &[&str]| -> Value {
        let args = [&["image", "--reference", &reference, "--frame", &frame, "--json"], extra].concat();
        serde_json::from_str(&ok(dir.eitskin(&args))).unwrap()
    };
    let auto = image(&[]);
    assert_eq!(auto["weighting"], "noise-assumed", "one reference frame measures no noise: {auto}");
    let lambda = auto["hyperparameter"].as_f64().unwrap();
    let peak = |out: &Value| out["touches"][0]["peak"].as_f64().unwrap();

    let given = image(&["--hyperparameter", &lambda.to_string(), "--weighting", "noise"]);
    assert_eq!(given["weighting"], "noise-assumed");
    assert_eq!(given["touches"], auto["touches"], "the same λ and weighting, the same image");
    let unweighted = image(&["--hyperparameter", &lambda.to_string()]);
    assert_eq!(unweighted["weighting"], "none", "a given λ weighs the channels alike by default");
    let (a, b) = (peak(&auto), peak(&unweighted));
    assert!((a - b).abs() > 0.01 * a.abs(), "the weighting changes the image: peaks {a} and {b}");

    // The λ chosen is kept in the cache, and found again for the same channels and noise.
    let kept = std::fs::read_dir(dir.cache()).unwrap().filter_map(Result::ok);
    let kept: Vec<String> = kept.map(|e| e.file_name().to_string_lossy().into_owned()).collect();
    assert_eq!(kept.iter().filter(|n| n.starts_with("hyperparameter-")).count(), 1, "{kept:?}");
    assert_eq!(image(&[])["hyperparameter"], auto["hyperparameter"]);
    assert_eq!(auto["chosen_by"], "noise-figure-and-map");
    assert_eq!(given["chosen_by"], "given");

    // λ from the frame itself: named, inside the searched range, and a misspelt rule refused.
    for criterion in ["gcv", "discrepancy"] {
        let chosen = image(&["--hyperparameter", criterion]);
        assert_eq!(chosen["chosen_by"], criterion);
        let lambda = chosen["hyperparameter"].as_f64().unwrap();
        assert!((1e-6..=1e3).contains(&lambda), "{criterion}: {chosen}");
    }
    let out = dir.eitskin(&["image", "--reference", &reference, "--frame", &frame, "--hyperparameter", "gvc"]);
    let message = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && message.contains("\"gvc\" is neither `auto`, `gcv`, `discrepancy`"), "{message}");

    let alike = image(&["--weighting", "none"]);
    assert_eq!(alike["weighting"], "none");
    assert!(alike["hyperparameter"].as_f64().unwrap() > 0.0, "{alike}");
}
