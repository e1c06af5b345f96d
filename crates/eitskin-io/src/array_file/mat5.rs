//! MAT v5 files (MATLAB's `-v6` and `-v7`, `scipy.io.savemat`), through the `matfile` crate.
//!
//! `matfile` reads numeric arrays (every class, real or complex, compressed or not) and skips
//! structs, cells, strings and sparse arrays: those are neither listed nor read. On some damaged
//! files it panics (an integer overflow on the dimensions in debug builds): the panic is caught and
//! reported as a damaged file, though Rust's panic hook still prints its message on stderr.

use matfile::NumericData;

use super::{Array, ArrayProblem, ArrayVariable};

const FORMAT: &str = "MAT v5";

/// The named (or the only) numeric array of a MAT v5 file, and the variable's name.
pub(super) fn read(
    bytes: Vec<u8>,
    wanted: Option<&str>,
) -> Result<(Array, Option<String>), (Option<String>, ArrayProblem)> {
    let named = wanted.map(str::to_string);
    let malformed = |message: String| (named.clone(), ArrayProblem::Malformed { format: FORMAT, message });
    // The bytes are owned here and dropped with the parser's state: nothing half-built outlives a panic.
    let parsed = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| matfile::MatFile::parse(&bytes[..])));
    let file = match parsed {
        Ok(Ok(file)) => file,
        Ok(Err(matfile::Error::ParseError(_))) => {
            return Err(malformed("the data end early or do not follow the format".into()));
        }
        Ok(Err(other)) => return Err(malformed(other.to_string())),
        Err(_) => return Err(malformed("the parser failed on damaged data".into())),
    };
    let arrays = file.arrays();
    let chosen = match wanted {
        Some(name) if name.contains('.') => return Err((named, ArrayProblem::StructField)),
        Some(name) => file.find_by_name(name),
        None if arrays.len() == 1 => arrays.first(),
        None => None,
    };
    let Some(array) = chosen else {
        let found = arrays
            .iter()
            .map(|a| ArrayVariable { name: a.name().to_string(), shape: a.size().clone(), class: class(a.data()) })
            .collect();
        return Err((named.clone(), ArrayProblem::Variable { wanted: named, found }));
    };
    let (real, imaginary) = values(array.data());
    let read = Array { shape: array.size().clone(), column_major: true, real, imaginary };
    Ok((read, Some(array.name().to_string())))
}

/// MATLAB's class name of the data, with `complex` before it for complex data.
fn class(data: &NumericData) -> String {
    macro_rules! name {
        ($($variant:ident => $name:literal),*) => {
            match data {
                $(NumericData::$variant { imag, .. } => {
                    if imag.is_some() { concat!("complex ", $name) } else { $name }
                })*
            }
        };
    }
    name!(Int8 => "int8", UInt8 => "uint8", Int16 => "int16", UInt16 => "uint16", Int32 => "int32",
          UInt32 => "uint32", Int64 => "int64", UInt64 => "uint64", Single => "single", Double => "double")
    .to_string()
}

/// Real and imaginary parts as `f64` (64-bit integers beyond 2⁵³ round to the nearest double).
fn values(data: &NumericData) -> (Vec<f64>, Option<Vec<f64>>) {
    macro_rules! convert {
        ($($variant:ident),*) => {
            match data {
                $(NumericData::$variant { real, imag } => (
                    real.iter().map(|&x| x as f64).collect(),
                    imag.as_ref().map(|im| im.iter().map(|&x| x as f64).collect()),
                ),)*
            }
        };
    }
    convert!(Int8, UInt8, Int16, UInt16, Int32, UInt32, Int64, UInt64, Single, Double)
}
