//! Frames that cannot be read against their reference as given are said to be so, not imaged
//! into touches of rounding: complex values against real ones, a complex part of real values, a
//! frame equal to its reference, a frame of another pattern, a λ below the range.

mod binary;

use binary::{ok, scratch};

#[test]
fn frames_that_cannot_go_with_their_reference_are_said_to() {
    let dir = scratch("unlike");
    let rest: Vec<f64> = ok(dir.eitskin(&["forward", "--format", "csv"]))
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(1).unwrap().parse().unwrap())
        .collect();
    let line = |f: &[f64]| f.iter().map(f64::to_string).collect::<Vec<_>>().join(",") + "\n";
    let reference = dir.join("rest.txt");
    std::fs::write(&reference, line(&rest)).unwrap();
    // The same frames as complex values, a phase of 0.01 rad and no change at all.
    let complex: Vec<u8> =
        (0..3).flat_map(|_| rest.iter().flat_map(|v| [v.to_le_bytes(), (0.01 * v).to_le_bytes()].concat())).collect();
    let npy = dir.join("rest_complex.npy");
    std::fs::write(&npy, eitskin_testdata::npy("<c16", [3, 120], &complex)).unwrap();
    let (r, c) = (reference.to_str().unwrap(), npy.to_str().unwrap());
    let said = |args: &[&str]| {
        let out = dir.eitskin(&[&["image"], args].concat());
        (
            out.status.success(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
        )
    };
    let (success, message, _) = said(&["--reference", c, "--frame", r]);
    assert!(!success && message.contains("holds complex values and") && message.contains("real ones"), "{message}");
    let (success, message, _) = said(&["--reference", r, "--frame", r, "--component", "phase"]);
    assert!(!success && message.contains("--component phase: ") && message.contains("holds real values"), "{message}");
    // A phase that does not change gave four touches of 1e-20 S/m.
    let (success, message, out) = said(&["--reference", c, "--frame", c, "--component", "phase"]);
    assert!(success && message.contains("equals its reference to rounding"), "{message}");
    assert!(out.contains("0 touch(es)"), "{out}");
    // A frame of one value on every channel follows no reference's pattern.
    let flat = dir.join("flat.txt");
    std::fs::write(&flat, line(&vec![rest.iter().sum::<f64>() / 120.0; 120])).unwrap();
    let (_, message, _) = said(&["--reference", r, "--frame", flat.to_str().unwrap()]);
    assert!(message.contains("follows the pattern of") && message.contains("R² = "), "{message}");
    // λ below the range the automatic choice searches is refused as the flag's value.
    let (success, message, _) = said(&["--reference", r, "--frame", r, "--hyperparameter", "1e-300"]);
    assert!(!success && message.contains("\"1e-300\" is neither") && message.contains("[1e-6, 1000]"), "{message}");
}
