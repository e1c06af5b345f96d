//! Where the test data live, for the tests of every eitskin crate that compare against them.
//!
//! - [`reference()`]: the EIDORS and pyEIT results on the paper's square, with the READMEs that
//!   state their conventions and provenance. They are in the repository
//!   (`testdata/reference/`), so a fresh clone tests alone.
//! - [`shared()`]: other groups' recorded captures (OpenEIT boards, tanks, skins), whose licences
//!   keep them out of the repository. They sit in a `shared/` folder beside the checkout, or
//!   wherever `$EITSKIN_SHARED` points; when they are missing, the test that asked for them
//!   says on the terminal that it did not run (a fresh clone tests alone), and fails instead
//!   where `EITSKIN_REQUIRE_SHARED=1` asks for them.
//!
//! It also writes test input in the field's file formats ([`npy`], [`mat5`]), so tests need
//! no numpy or MATLAB.
//!
//! A dev-dependency only (`publish = false`), with nothing beyond `std`; parsing what it reads is
//! the caller's business. Not for library or binary code.
#![deny(missing_docs)]

use std::path::{Path, PathBuf};

/// The repository's `testdata/reference` folder (EIDORS and pyEIT results), or the file at
/// `relative` under it.
pub fn reference(relative: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata/reference").join(relative)
}

/// The text of the file at `relative` under [`reference()`]; a failure naming the path if unreadable.
#[track_caller]
pub fn read_reference(relative: &str) -> String {
    let path = reference(relative);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// `../shared` beside the checkout (or `$EITSKIN_SHARED`) when it holds the third-party
/// captures under `data/`; else `None`, after saying on the terminal (past the test harness's
/// capture, so that it shows even when the test passes) that the calling test did not run.
/// With `EITSKIN_REQUIRE_SHARED=1` (`.ci/run` sets it where the captures are) their absence
/// fails the test instead.
#[track_caller]
pub fn shared() -> Option<PathBuf> {
    let dir = std::env::var_os("EITSKIN_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared"));
    let required = std::env::var_os("EITSKIN_REQUIRE_SHARED").is_some_and(|v| v == "1");
    checked(dir, required)
}

/// `dir` itself when it holds the captures; else a failure when they are `required`, or `None`
/// and a line on stderr that names the test that did not run.
#[track_caller]
fn checked(dir: PathBuf, required: bool) -> Option<PathBuf> {
    if dir.join("data").is_dir() {
        return Some(dir);
    }
    let said = format!(
        "THIS TEST DID NOT RUN ({}): the third-party captures are not at {} (their licences keep them \
         out of the repository: put the shared/ folder beside the checkout, or set EITSKIN_SHARED)",
        std::panic::Location::caller(),
        dir.join("data").display()
    );
    assert!(!required, "{said}, and EITSKIN_REQUIRE_SHARED=1 asks for them");
    // Straight to the stream: the harness captures `eprintln!` of a passing test.
    use std::io::Write;
    let _ = writeln!(std::io::stderr(), "{said}");
    None
}

/// The largest |a − b| over the largest |b| (dimensionless).
#[track_caller]
pub fn max_relative_error(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len(), "lengths differ");
    let scale = b.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    a.iter().zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs())) / scale
}

/// The bytes of an NPY file (version 1.0, C order) of `rows` × `columns` values of numpy dtype
/// `descr` (`"<f8"`, `"<c16"`, …), `data` their little-endian bytes: numpy's format, without numpy.
pub fn npy(descr: &str, [rows, columns]: [usize; 2], data: &[u8]) -> Vec<u8> {
    let mut header = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': ({rows}, {columns}), }}");
    // Magic, version and length take 10 bytes; the header ends in a newline at a multiple of 64.
    header += &(" ".repeat(63 - (10 + header.len()) % 64) + "\n");
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend(u16::try_from(header.len()).expect("a short header").to_le_bytes());
    bytes.extend(header.as_bytes());
    bytes.extend(data);
    bytes
}

/// The bytes of a MAT v5 file (uncompressed, little-endian, as MATLAB's `-v6` writes) holding
/// real double matrices, each `(name, rows, columns, values in column-major order)`: test
/// input in the format published EIT data come in, without MATLAB.
pub fn mat5(variables: &[(&str, usize, usize, &[f64])]) -> Vec<u8> {
    let mut bytes = format!("{:<116}", "MATLAB 5.0 MAT-file, written by eitskin's tests").into_bytes();
    bytes.extend([0; 8]);
    bytes.extend(0x0100u16.to_le_bytes());
    bytes.extend(b"IM");
    // A data element: type, byte count, the bytes, padded to 8 bytes.
    let element = |out: &mut Vec<u8>, kind: u32, data: &[u8]| {
        let count = u32::try_from(data.len()).expect("a test matrix under 4 GiB");
        out.extend(kind.to_le_bytes());
        out.extend(count.to_le_bytes());
        out.extend(data);
        out.resize(out.len().div_ceil(8) * 8, 0);
    };
    let int32 = |n: usize| i32::try_from(n).expect("a test dimension under 2³¹").to_le_bytes();
    for (name, rows, columns, values) in variables {
        assert_eq!(rows * columns, values.len(), "{name}: rows × columns values");
        let mut matrix = Vec::new();
        element(&mut matrix, 6, &[6u32.to_le_bytes(), 0u32.to_le_bytes()].concat()); // miUINT32 flags: mxDOUBLE_CLASS
        element(&mut matrix, 5, &[int32(*rows), int32(*columns)].concat()); // miINT32 dimensions
        element(&mut matrix, 1, name.as_bytes()); // miINT8 name
        element(&mut matrix, 9, &values.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>()); // miDOUBLE
        element(&mut bytes, 14, &matrix); // miMATRIX
    }
    bytes
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_folder_says_the_test_did_not_run() {
        assert_eq!(checked(PathBuf::from("/nonexistent/eitskin-shared"), false), None);
    }

    #[test]
    #[should_panic(expected = "THIS TEST DID NOT RUN")]
    fn a_missing_folder_fails_where_the_captures_are_required() {
        checked(PathBuf::from("/nonexistent/eitskin-shared"), true);
    }

    #[test]
    fn the_reference_results_are_in_the_repository() {
        for file in ["eidors/README.md", "eidors/mesh.json", "pyeit/README.md", "pyeit/square16_4k.json"] {
            assert!(reference(file).is_file(), "{} is missing", reference(file).display());
        }
    }

    #[test]
    fn relative_error_is_over_the_largest_reference_value() {
        assert_eq!(max_relative_error(&[1.0, -1.5], &[1.0, -2.0]), 0.25);
    }
}
