//! The reference results (EIDORS, pyEIT) as JSON, for the tests that compare against them.
// Each test binary uses a subset of these helpers.
#![allow(dead_code)]

/// Reads a JSON file under the repository's reference folder (see [`eitskin_testdata::reference`]).
pub fn json(relative: &str) -> serde_json::Value {
    serde_json::from_str(&eitskin_testdata::read_reference(relative)).unwrap_or_else(|e| panic!("{relative}: {e}"))
}

/// A JSON array of numbers as a vector.
pub fn floats(v: &serde_json::Value) -> Vec<f64> {
    v.as_array().expect("an array").iter().map(|x| x.as_f64().expect("a number")).collect()
}
