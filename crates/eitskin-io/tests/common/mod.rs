//! Where the shared reference data live, for the tests that compare against them.
// Each test binary uses a subset of these helpers.
#![allow(dead_code)]

use std::path::PathBuf;

/// `../shared` beside the checkout (or `$EITSKIN_SHARED`). Its absence fails the test loudly:
/// a reference comparison that did not run must never look like one that passed.
pub fn shared() -> PathBuf {
    let dir = std::env::var_os("EITSKIN_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared"));
    assert!(
        dir.join("reference").is_dir(),
        "THIS TEST DID NOT RUN: the shared reference data are not at {} (put the shared/ folder beside \
         the checkout, or set EITSKIN_SHARED)",
        dir.display()
    );
    dir
}

/// Reads a JSON file under the shared folder.
pub fn json(relative: &str) -> serde_json::Value {
    let path = shared().join(relative);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// A JSON array of numbers as a vector.
pub fn floats(v: &serde_json::Value) -> Vec<f64> {
    v.as_array().expect("an array").iter().map(|x| x.as_f64().expect("a number")).collect()
}

/// The largest |a − b| over the largest |b|.
pub fn max_relative_error(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len(), "lengths differ");
    let scale = b.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    a.iter().zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs())) / scale
}
