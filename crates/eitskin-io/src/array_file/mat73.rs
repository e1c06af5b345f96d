//! MAT v7.3 files (MATLAB's `-v7.3`): HDF5 behind a 512-byte header, read with the pure-Rust
//! `hdf5-pure` crate.
//!
//! MATLAB stores each variable as a dataset whose dimensions are MATLAB's reversed (so the data
//! lie in MATLAB's column-major order), tags it with a `MATLAB_class` attribute, stores complex
//! numbers as a `{real, imag}` compound, and a struct as a group of its fields: `data.Uel` is the
//! dataset `data/Uel`. Names starting with `#` are MATLAB's internal references and are skipped.

use hdf5_pure::{AttrValue, DType, Dataset, File, Group};

use super::{Array, ArrayProblem, ArrayVariable};

const FORMAT: &str = "MAT v7.3";

/// MATLAB classes read as numbers.
const NUMERIC: [&str; 10] =
    ["double", "single", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64"];

/// How deep struct fields are listed (`a.b.c.d`).
const STRUCT_DEPTH: usize = 4;

fn malformed(e: hdf5_pure::Error) -> ArrayProblem {
    ArrayProblem::Malformed { format: FORMAT, message: e.to_string() }
}

type Failure = (Option<String>, ArrayProblem);

/// The named (or the only) numeric array of a MAT v7.3 file, and the variable's name.
pub(super) fn read(bytes: Vec<u8>, wanted: Option<&str>) -> Result<(Array, Option<String>), Failure> {
    let named = wanted.map(str::to_string);
    let file = File::from_bytes(bytes).map_err(|e| (named.clone(), malformed(e)))?;
    let mut found = Vec::new();
    list(&file.root(), "", STRUCT_DEPTH, &mut found).map_err(|e| (named.clone(), malformed(e)))?;
    let name = match wanted {
        Some(name) => name.to_string(),
        None if found.len() == 1 => found[0].name.clone(),
        None => return Err((None, ArrayProblem::Variable { wanted: None, found })),
    };
    let Ok(dataset) = file.dataset(&name.replace('.', "/")) else {
        return Err((named.clone(), ArrayProblem::Variable { wanted: named, found }));
    };
    let array = numeric(&dataset).map_err(|p| (Some(name.clone()), p))?;
    Ok((array, Some(name)))
}

/// Adds the numeric variables of `group` (and of its structs, `depth` levels down) to `found`.
fn list(group: &Group, prefix: &str, depth: usize, found: &mut Vec<ArrayVariable>) -> Result<(), hdf5_pure::Error> {
    for name in group.datasets()? {
        if name.starts_with('#') {
            continue;
        }
        let dataset = group.dataset(&name)?;
        let Some(class) = matlab_class(&dataset.attrs()?) else { continue };
        if !NUMERIC.contains(&class.as_str()) || dataset.attrs()?.contains_key("MATLAB_empty") {
            continue;
        }
        let complex = matches!(dataset.dtype()?, DType::Compound(_));
        found.push(ArrayVariable {
            name: format!("{prefix}{name}"),
            shape: matlab_shape(&dataset)?,
            class: if complex { format!("complex {class}") } else { class },
        });
    }
    if depth > 0 {
        for name in group.groups()? {
            let sub = group.group(&name)?;
            if !name.starts_with('#') && matlab_class(&sub.attrs()?).as_deref() == Some("struct") {
                list(&sub, &format!("{prefix}{name}."), depth - 1, found)?;
            }
        }
    }
    Ok(())
}

/// The `MATLAB_class` attribute, if there is one.
fn matlab_class(attrs: &std::collections::HashMap<String, AttrValue>) -> Option<String> {
    match attrs.get("MATLAB_class")? {
        AttrValue::AsciiString(s) | AttrValue::String(s) => Some(s.trim_end_matches('\0').to_string()),
        AttrValue::AsciiStringSized { value, .. } | AttrValue::StringSized { value, .. } => {
            Some(value.trim_end_matches('\0').to_string())
        }
        _ => None,
    }
}

/// MATLAB's size of the variable: the dataset's dimensions reversed.
fn matlab_shape(dataset: &Dataset) -> Result<Vec<usize>, hdf5_pure::Error> {
    Ok(dataset.shape()?.iter().rev().map(|&n| usize::try_from(n).unwrap_or(usize::MAX)).collect())
}

/// The values of one numeric variable, real or complex.
fn numeric(dataset: &Dataset) -> Result<Array, ArrayProblem> {
    let attrs = dataset.attrs().map_err(malformed)?;
    let class = matlab_class(&attrs).unwrap_or_else(|| "unknown (no MATLAB_class)".into());
    if !NUMERIC.contains(&class.as_str()) {
        return Err(ArrayProblem::ElementType { class });
    }
    let shape = matlab_shape(dataset).map_err(malformed)?;
    if attrs.contains_key("MATLAB_empty") {
        return Err(ArrayProblem::Empty { shape: vec![0, 0] });
    }
    let (real, imaginary) = match dataset.dtype().map_err(malformed)? {
        DType::Compound(fields) => complex(dataset, &fields)?,
        DType::F32 | DType::F64 | DType::I8 | DType::I16 | DType::I32 | DType::I64 => {
            (dataset.read_f64().map_err(malformed)?, None)
        }
        DType::U8 | DType::U16 | DType::U32 | DType::U64 => (dataset.read_f64().map_err(malformed)?, None),
        other => return Err(ArrayProblem::ElementType { class: format!("{class} stored as {other}") }),
    };
    Ok(Array { shape, column_major: true, real, imaginary })
}

/// Real and imaginary parts of a `{real, imag}` compound of two `f64` or two `f32` (MATLAB writes
/// them little-endian, real first).
#[allow(clippy::type_complexity)]
fn complex(dataset: &Dataset, fields: &[(String, DType)]) -> Result<(Vec<f64>, Option<Vec<f64>>), ArrayProblem> {
    let width = match fields {
        [(re, DType::F64), (im, DType::F64)] if re == "real" && im == "imag" => 8,
        [(re, DType::F32), (im, DType::F32)] if re == "real" && im == "imag" => 4,
        _ => {
            let names: Vec<String> = fields.iter().map(|(n, t)| format!("{n}: {t}")).collect();
            return Err(ArrayProblem::ElementType { class: format!("compound {{{}}}", names.join(", ")) });
        }
    };
    let raw = dataset.read_raw().map_err(malformed)?;
    let number = |bytes: &[u8]| match *bytes {
        [a, b, c, d] => f32::from_le_bytes([a, b, c, d]) as f64,
        [a, b, c, d, e, f, g, h] => f64::from_le_bytes([a, b, c, d, e, f, g, h]),
        _ => f64::NAN, // unreachable: chunks are `width` bytes long
    };
    let (mut real, mut imaginary) = (Vec::new(), Vec::new());
    for pair in raw.chunks_exact(2 * width) {
        let (re, im) = pair.split_at(width);
        real.push(number(re));
        imaginary.push(number(im));
    }
    Ok((real, Some(imaginary)))
}
