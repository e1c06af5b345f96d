//! eitskin's Python module `eitskin._eitskin`: the library's types over numpy arrays, the GIL
//! released around every solve. The Python package `eitskin` re-exports it with its docs.
//!
//! By concept: [`model`] (spec, mesh, protocol, forward model), [`imaging`] (reconstructor,
//! images, touches), [`stream`] (virtual sensor, sources, pipeline, calibration) and [`learn`]
//! (calibration learned from labelled presses).

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
/// copy where it already is one); complex values are refused (numpy would drop their imaginary
/// parts with a warning).
pub(crate) fn as_array<'py>(obj: &Bound<'py, PyAny>, dtype: &str) -> PyResult<Bound<'py, PyAny>> {
    let numpy = obj.py().import("numpy")?;
    let array = numpy.call_method1("asarray", (obj,))?;
    if array.getattr("dtype")?.getattr("kind")?.extract::<String>()? == "c" {
        return Err(fail("complex values: give real ones (their magnitudes or real parts)"));
    }
    numpy.call_method1("ascontiguousarray", (array, dtype))
}

/// `obj` as a 1-D float64 array named `name` in messages: any array-like numpy converts (lists,
/// integers, float32, views), without a copy where it already is one.
pub(crate) fn vector<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<PyReadonlyArray1<'py, f64>> {
    let array = as_array(obj, "float64").map_err(|e| fail(format!("{name}: {}", e.value(obj.py()))))?;
    one_dimensional(&array, &format!("{name}: "))
}

/// A 1-D float64 array-like as a Vec.
pub(crate) fn floats(obj: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
    Ok(one_dimensional(&as_array(obj, "float64")?, "")?.as_slice()?.to_vec())
}

/// `array` as 1-D float64, else an error starting with `named` ("frame: ", or nothing).
fn one_dimensional<'py>(array: &Bound<'py, PyAny>, named: &str) -> PyResult<PyReadonlyArray1<'py, f64>> {
    array.extract().map_err(|_| fail(format!("{named}expected a 1-D array, got {} dimensions", ndim(array))))
}

fn ndim(array: &Bound<'_, PyAny>) -> usize {
    array.getattr("ndim").and_then(|n| n.extract()).unwrap_or(0)
}

/// An (n, K) array-like of `dtype` as rows of K.
pub(crate) fn rows<const K: usize, T: numpy::Element + Copy>(
    obj: &Bound<'_, PyAny>,
    dtype: &str,
    what: &str,
) -> PyResult<Vec<[T; K]>> {
    let array = as_array(obj, dtype)?;
    let array: PyReadonlyArray2<'_, T> = array.extract().map_err(|_| fail(format!("{what}: expected a 2-D array")))?;
    if array.shape()[1] != K {
        return Err(fail(format!("{what}: expected {K} columns, got {}", array.shape()[1])));
    }
    let values = array.as_slice()?;
    Ok(values.chunks_exact(K).map(|c| std::array::from_fn(|k| c[k])).collect())
}

/// A count from Python for `name`: a negative one is refused with its value (PyO3 would raise
/// OverflowError on its way to an unsigned number).
pub(crate) fn count(value: i64, name: &str) -> PyResult<usize> {
    usize::try_from(value).map_err(|_| fail(format!("{name} must be a whole number 0 or more, got {value}")))
}

/// A seed from Python for `name`: 0 or more.
pub(crate) fn seed(value: i64, name: &str) -> PyResult<u64> {
    u64::try_from(value).map_err(|_| fail(format!("{name} must be a whole number 0 or more, got {value}")))
}

/// Indices as usize, refusing negative ones.
pub(crate) fn indices(values: &[i64], what: &str) -> PyResult<Vec<usize>> {
    values.iter().map(|&i| usize::try_from(i).map_err(|_| fail(format!("{what}: index {i} is negative")))).collect()
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
