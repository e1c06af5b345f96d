//! Where the shared reference data live, for the tests of every eitskin crate that compare
//! against them (EIDORS and pyEIT results, recorded OpenEIT captures).
//!
//! The data are not in the repository: they sit in a `shared/` folder beside the checkout, or
//! wherever `$EITSKIN_SHARED` points. When they are missing, [`shared`] fails the test that asked
//! for them, saying that it did not run: a reference comparison that did not run must never look
//! like one that passed.
//!
//! A dev-dependency only (`publish = false`), with nothing beyond `std`; parsing what it reads is
//! the caller's business. Not for library or binary code.
#![deny(missing_docs)]

use std::path::{Path, PathBuf};

/// `../shared` beside the checkout (or `$EITSKIN_SHARED`). Its absence fails the test loudly.
#[track_caller]
pub fn shared() -> PathBuf {
    let dir = std::env::var_os("EITSKIN_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared"));
    checked(dir)
}

/// `dir` itself when it holds the reference data, else a failure that says the test did not run.
#[track_caller]
fn checked(dir: PathBuf) -> PathBuf {
    assert!(
        dir.join("reference").is_dir(),
        "THIS TEST DID NOT RUN: the shared reference data are not at {} (put the shared/ folder beside \
         the checkout, or set EITSKIN_SHARED)",
        dir.display()
    );
    dir
}

/// The text of the file at `relative` under the shared folder; a failure naming the path if unreadable.
#[track_caller]
pub fn read(relative: &str) -> String {
    let path = shared().join(relative);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The largest |a − b| over the largest |b| (dimensionless).
#[track_caller]
pub fn max_relative_error(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len(), "lengths differ");
    let scale = b.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    a.iter().zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs())) / scale
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    #[should_panic(expected = "THIS TEST DID NOT RUN")]
    fn a_missing_folder_fails_and_says_the_test_did_not_run() {
        checked(PathBuf::from("/nonexistent/eitskin-shared"));
    }

    #[test]
    fn relative_error_is_over_the_largest_reference_value() {
        assert_eq!(max_relative_error(&[1.0, -1.5], &[1.0, -2.0]), 0.25);
    }
}
