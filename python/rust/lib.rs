//! eitskin's Python module `eitskin._eitskin`: the library's types over numpy arrays, the GIL
//! released around every solve. The Python package `eitskin` re-exports it with its docs.
//!
//! By concept: [`arguments`] (every number from Python, read and range-checked once), [`model`] (spec, mesh, protocol, forward model), [`imaging`] (reconstructor,
//! images, touches), [`stream`] (virtual sensor, sources, pipeline, calibration) and [`learn`]
//! (calibration learned from labelled presses).

mod arguments;
mod imaging;
mod learn;
mod model;
mod stream;

use numpy::{PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

create_exception!(eitskin, EitskinError, PyValueError, "A value eitskin refuses, with the library's message.");

/// A message as an `EitskinError`.
pub(crate) fn fail(message: impl std::fmt::Display) -> PyErr {
    EitskinError::new_err(message.to_string())
}

/// A library error as an `EitskinError` carrying its message and each of its causes ([`message`]).
pub(crate) fn error(error: impl std::error::Error) -> PyErr {
    EitskinError::new_err(message(&error))
}

/// An error's message and each of its causes, joined by ": " as the CLI prints them ("the spec
/// does not make a sensor: `thickness` must be …"); a message that already ends in its cause's
/// text (thiserror's `{0}`) does not repeat it.
pub(crate) fn message(error: &dyn std::error::Error) -> String {
    let mut message = error.to_string();
    let mut cause = error.source();
    while let Some(c) = cause {
        let text = c.to_string();
        if !message.ends_with(&text) {
            message = format!("{message}: {text}");
        }
        cause = c.source();
    }
    message
}

/// `obj` as a contiguous numpy array of `dtype` (any array-like numpy can convert, without a
/// copy where it already is one), named `name` in messages: what numpy cannot convert (strings,
/// ragged lists, objects) and complex values (numpy would drop their imaginary parts with a
/// warning) are refused.
pub(crate) fn as_array<'py>(obj: &Bound<'py, PyAny>, dtype: &str, name: &str) -> PyResult<Bound<'py, PyAny>> {
    let numpy = obj.py().import("numpy")?;
    let refuse = |e: PyErr| fail(format!("{name}: {}", e.value(obj.py())));
    let array = numpy.call_method1("asarray", (obj,)).map_err(refuse)?;
    if array.getattr("dtype")?.getattr("kind")?.extract::<String>()? == "c" {
        return Err(fail(format!("{name}: complex values: give real ones (their magnitudes or real parts)")));
    }
    numpy.call_method1("ascontiguousarray", (array, dtype)).map_err(refuse)
}

/// `obj` as a 1-D float64 array named `name` in messages: any array-like numpy converts (lists,
/// integers, float32, views), without a copy where it already is one.
pub(crate) fn vector<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<PyReadonlyArray1<'py, f64>> {
    let array = as_array(obj, "float64", name)?;
    array.extract().map_err(|_| fail(format!("{name}: expected a 1-D array, got {} dimensions", ndim(&array))))
}

/// A 1-D float64 array-like named `name` in messages, as a Vec.
pub(crate) fn floats(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<f64>> {
    Ok(vector(obj, name)?.as_slice()?.to_vec())
}

fn ndim(array: &Bound<'_, PyAny>) -> usize {
    array.getattr("ndim").and_then(|n| n.extract()).unwrap_or(0)
}

/// Rows of a 2-D float64 array-like of any width named `name` (of a fixed width: [`rows`]).
pub(crate) fn matrix(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<Vec<f64>>> {
    let array = as_array(obj, "float64", name)?;
    let array: PyReadonlyArray2<'_, f64> =
        array.extract().map_err(|_| fail(format!("{name}: expected a 2-D array, got {} dimensions", ndim(&array))))?;
    let width = array.shape()[1].max(1);
    Ok(array.as_slice()?.chunks_exact(width).map(<[f64]>::to_vec).collect())
}

/// An (n, K) float64 array-like named `name` as rows of K.
pub(crate) fn rows<const K: usize>(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<[f64; K]>> {
    let array = as_array(obj, "float64", name)?;
    let array: PyReadonlyArray2<'_, f64> =
        array.extract().map_err(|_| fail(format!("{name}: expected a 2-D array, got {} dimensions", ndim(&array))))?;
    if array.shape()[1] != K {
        return Err(fail(format!("{name}: expected {K} columns, got {}", array.shape()[1])));
    }
    Ok(array.as_slice()?.chunks_exact(K).map(|c| std::array::from_fn(|k| c[k])).collect())
}

/// 2⁵³: up to it a float64 holds every whole number exactly.
const EXACT_WHOLE: f64 = 9_007_199_254_740_992.0;

/// A number from an array as a message quotes it: a whole one up to 2⁵³ as an integer (as Python
/// writes an int), any other in its shortest round-trip form (2.5, 1.2e21, 1e300, NaN, inf).
pub(crate) fn quoted(value: f64) -> String {
    if value.fract() == 0.0 && value.abs() <= EXACT_WHOLE {
        format!("{value}")
    } else {
        format!("{value:?}")
    }
}

/// Node (or other) indices named `name`, numbered from `first` (0, or 1 as EIDORS numbers
/// them), as 0-based ones: each must be a whole number, `first` or more (any numeric array
/// gives them: integers, or floats that are whole).
pub(crate) fn indices(values: &[f64], name: &str, first: usize) -> PyResult<Vec<usize>> {
    let base = first as f64;
    let index = |&v: &f64| match v {
        v if !(v.is_finite() && v.fract() == 0.0) => Err(format!("{name}: index {} is not a whole number", quoted(v))),
        v if v < base && first == 0 => Err(format!("{name}: index {} is negative", quoted(v))),
        v if v < base => Err(format!("{name}: index {} is below {first}: these count from {first}", quoted(v))),
        v if v > EXACT_WHOLE => Err(format!("{name}: index {} is larger than any mesh has", quoted(v))),
        v => Ok((v - base) as usize),
    };
    values.iter().map(index).collect::<Result<_, String>>().map_err(fail)
}

/// The nodes each electrode covers, from a list of array-likes of indices from `first` (one
/// array per electrode, any shape), as 0-based indices.
pub(crate) fn electrode_nodes(obj: &Bound<'_, PyAny>, name: &str, first: usize) -> PyResult<Vec<Vec<usize>>> {
    let refuse =
        || fail(format!("{name}: expected one array of node indices per electrode, got {}", arguments::given(obj)));
    let items = obj.try_iter().map_err(|_| refuse())?;
    items
        .map(|item| {
            let nodes = as_array(&item?, "float64", name)?.call_method1("reshape", (-1,))?;
            indices(vector(&nodes, name)?.as_slice()?, name, first)
        })
        .collect()
}

/// Refuses to write `path` unless its extension is one of `formats` (eitskin-io's rule for the
/// CLI's output flags too), naming the file.
pub(crate) fn check_output_name(path: &std::path::Path, formats: &[&str]) -> PyResult<()> {
    eitskin_io::check_output_name(path, formats).map_err(|e| fail(format!("cannot write {}: {e}", path.display())))
}

/// eitskin's native module.
#[pymodule]
fn _eitskin(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("EitskinError", m.py().get_type::<EitskinError>())?;
    // The one colour map's stops, sRGB from −1 (a decrease) to +1 (`eitskin::colour`).
    let stops: Vec<(u8, u8, u8)> = eitskin::colour::COLOUR_STOPS.iter().map(|&[r, g, b]| (r, g, b)).collect();
    m.add("COLOUR_STOPS", stops)?;
    m.add_class::<model::SensorSpec>()?;
    m.add_class::<model::Mesh>()?;
    m.add_class::<model::Protocol>()?;
    m.add_class::<model::ForwardModel>()?;
    m.add_class::<imaging::Reconstructor>()?;
    m.add_class::<imaging::Image>()?;
    m.add_class::<imaging::Touch>()?;
    m.add_class::<stream::VirtualSensor>()?;
    m.add_class::<stream::Source>()?;
    m.add_class::<stream::Frame>()?;
    m.add_class::<stream::Event>()?;
    m.add_class::<stream::Calibration>()?;
    m.add_class::<stream::Pipeline>()?;
    m.add_class::<stream::TouchForce>()?;
    m.add_class::<learn::LearnedModel>()?;
    m.add_function(wrap_pyfunction!(learn::robot_presses, m)?)?;
    m.add_function(wrap_pyfunction!(imaging::one_step_matrix, m)?)?;
    m.add_function(wrap_pyfunction!(imaging::touches, m)?)?;
    Ok(())
}
