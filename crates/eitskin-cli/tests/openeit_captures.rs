//! The OpenEIT board's real captures (`../shared/data/openeit`), read as the board wrote them:
//! one frame per `magnitudes:` line. Their values sit on three levels in the ratio 1 : √2 : 2
//! whatever the tank holds, so they do not follow any model's pattern; `image` must say so
//! rather than print a confident image.

mod binary;

use binary::scratch;

#[test]
fn image_reads_a_board_log_and_warns_that_saturated_values_do_not_follow_the_model() {
    let Some(shared) = eitskin_testdata::shared() else { return };
    let data = shared.join("data/openeit");
    let spec = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/openeit-tank-32.toml");
    let dir = scratch("openeit");
    let (reference, frame) = (data.join("Baseline1.txt"), data.join("CupOnLeft.txt"));
    let args = ["image", spec, "--triangles", "1500", "--values", "magnitude", "--normalised", "--json"];
    let paths = ["--reference", reference.to_str().unwrap(), "--frame", frame.to_str().unwrap()];
    let out = dir.eitskin(&[&args[..], &paths].concat());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let fit = json["pattern_fit"].as_f64().unwrap();
    assert!(fit < 0.0, "R² = {fit}");
    assert!(stderr.contains("follows the model's pattern poorly"), "{stderr}");
}
