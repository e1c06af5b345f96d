//! Numbers from Python, read once at the edge: every whole or real argument of the API is read
//! by one function here (`#[pyo3(from_py_with = arguments::seed)]`), which takes any Python
//! number, checks it against the range the library or the CLI states for it, and refuses
//! anything else as an `EitskinError` naming the argument and quoting the value as given (never
//! an OverflowError or a TypeError on the way to a Rust number).

use std::ops::RangeInclusive;

use eitskin::calibration::MAX_FORCE;
pub(crate) use eitskin::inverse::hyperparameter_in_range;
use eitskin::pipeline;
use pyo3::prelude::*;
use pyo3::types::PyString;

use crate::fail;

/// The NOSER exponent p the bindings take, dimensionless: 0 is Tikhonov's R = I, 1 pyEIT's
/// "lm" (the library refuses only a p that is not finite, and the CLI has no such flag).
pub(crate) const NOSER_EXPONENT: RangeInclusive<f64> = 0.0..=1.0;

/// `obj` as Python writes it, for a message: a string with its quotes, anything else as `str()`
/// does, cut to its first 80 characters.
pub(crate) fn given(obj: &Bound<'_, PyAny>) -> String {
    const LONGEST: usize = 80;
    let text = if obj.is_instance_of::<PyString>() { obj.repr() } else { obj.str() };
    let text = text.map_or_else(|_| "a value that cannot be written".into(), |t| t.to_string());
    match text.char_indices().nth(LONGEST) {
        Some((end, _)) => format!("{}…", &text[..end]),
        None => text,
    }
}

/// A whole number for `name` within `range` (any Python int or `__index__` object, however
/// large; a float, a string or anything else is refused).
pub(crate) fn whole<T: TryFrom<i128>>(obj: &Bound<'_, PyAny>, name: &str, range: RangeInclusive<i128>) -> PyResult<T> {
    obj.extract::<i128>()
        .ok()
        .filter(|v| range.contains(v))
        .and_then(|v| T::try_from(v).ok())
        .ok_or_else(|| fail(format!("{name} must be {} to {}, got {}", range.start(), range.end(), given(obj))))
}

/// A finite real number for `name` for which `within` holds, `what` saying which ("a number in
/// (0, 1]"); any Python int, float or `__float__` object, a string or complex refused.
pub(crate) fn real(obj: &Bound<'_, PyAny>, name: &str, what: &str, within: fn(f64) -> bool) -> PyResult<f64> {
    let value = if obj.is_instance_of::<PyString>() { None } else { obj.extract::<f64>().ok() };
    value
        .filter(|v| v.is_finite() && within(*v))
        .ok_or_else(|| fail(format!("{name} must be {what}, got {}", given(obj))))
}

/// A pair (nx, ny) for `name`, each a whole number within `range`: a tuple, list or array of two.
fn pair(obj: &Bound<'_, PyAny>, name: &str, range: RangeInclusive<i128>) -> PyResult<[usize; 2]> {
    let refuse =
        || fail(format!("{name} must be (nx, ny), each {} to {}, got {}", range.start(), range.end(), given(obj)));
    let items: Vec<Bound<'_, PyAny>> = obj.try_iter().map_err(|_| refuse())?.take(3).collect::<PyResult<_>>()?;
    match &items[..] {
        [x, y] => Ok([
            whole(x, name, range.clone()).map_err(|_| refuse())?,
            whole(y, name, range.clone()).map_err(|_| refuse())?,
        ]),
        _ => Err(refuse()),
    }
}

/// A range of counts as the range [`whole`] checks against.
fn counted(range: RangeInclusive<usize>) -> RangeInclusive<i128> {
    *range.start() as i128..=*range.end() as i128
}

/// `triangles`: about how many triangles to mesh with, 1 to 100,000,000 (the CLI's `--triangles`).
pub(crate) fn triangles(obj: &Bound<'_, PyAny>) -> PyResult<usize> {
    whole(obj, "triangles", counted(1..=eitskin::spec::MAX_TRIANGLES))
}

/// `electrodes` of a named protocol: 1 to 256 (the library refuses too few for the pattern).
pub(crate) fn electrodes(obj: &Bound<'_, PyAny>) -> PyResult<usize> {
    whole(obj, "electrodes", counted(1..=eitskin::protocol::MAX_ELECTRODES))
}

/// `seed`: 0 to 2⁶⁴ − 1, as the CLI's `--seed`.
pub(crate) fn seed(obj: &Bound<'_, PyAny>) -> PyResult<u64> {
    whole(obj, "seed", 0..=i128::from(u64::MAX))
}

/// `frames` a source delivers before it stops: None (every frame) or 1 to 10¹², as `run --frames`.
pub(crate) fn frames(obj: &Bound<'_, PyAny>) -> PyResult<Option<u64>> {
    (!obj.is_none()).then(|| whole(obj, "frames", 1..=1_000_000_000_000)).transpose()
}

/// `values_per_measurement`: 1 (real values) or 2 (complex (re, im) pairs).
pub(crate) fn values_per_measurement(obj: &Bound<'_, PyAny>) -> PyResult<usize> {
    whole(obj, "values_per_measurement", 1..=2)
}

/// `count` of robot presses: 1 to 1,000,000, as `robot-presses --count`.
pub(crate) fn count(obj: &Bound<'_, PyAny>) -> PyResult<usize> {
    whole(obj, "count", 1..=1_000_000)
}

/// `frames_per_press`: frames averaged per state, 1 to 10,000, as `robot-presses --frames-per-press`.
pub(crate) fn frames_per_press(obj: &Bound<'_, PyAny>) -> PyResult<usize> {
    whole(obj, "frames_per_press", 1..=10_000)
}

/// `folds` of the cross-validation: 2 to 20, as `learn --folds`.
pub(crate) fn folds(obj: &Bound<'_, PyAny>) -> PyResult<usize> {
    whole(obj, "folds", 2..=20)
}

/// `reference_frames` of a pipeline: the library's [`pipeline::REFERENCE_FRAMES`].
pub(crate) fn reference_frames(obj: &Bound<'_, PyAny>) -> PyResult<usize> {
    whole(obj, "reference_frames", counted(pipeline::REFERENCE_FRAMES))
}

/// `reference_limit` of a pipeline: the library's [`pipeline::REFERENCE_LIMIT`].
pub(crate) fn reference_limit(obj: &Bound<'_, PyAny>) -> PyResult<usize> {
    whole(obj, "reference_limit", counted(pipeline::REFERENCE_LIMIT))
}

/// `average`: frames per image of a pipeline, the library's [`pipeline::AVERAGE`].
pub(crate) fn average(obj: &Bound<'_, PyAny>) -> PyResult<usize> {
    whole(obj, "average", counted(pipeline::AVERAGE))
}

/// `raster`: pixels (nx, ny) over the mesh's bounding box, each 1 to 4096.
pub(crate) fn raster(obj: &Bound<'_, PyAny>) -> PyResult<[usize; 2]> {
    pair(obj, "raster", 1..=4096)
}

/// `grid`: units (nx, ny) of the pseudo-array, each 1 to 100 (the library's most).
pub(crate) fn grid(obj: &Bound<'_, PyAny>) -> PyResult<[usize; 2]> {
    pair(obj, "grid", counted(1..=eitskin::pseudo_array::MAX_UNITS_PER_SIDE))
}

/// `exponent`: the NOSER exponent p, in [`NOSER_EXPONENT`].
pub(crate) fn exponent(obj: &Bound<'_, PyAny>) -> PyResult<f64> {
    let what = format!("a number in [{}, {}]", NOSER_EXPONENT.start(), NOSER_EXPONENT.end());
    real(obj, "exponent", &what, |p| NOSER_EXPONENT.contains(&p))
}

/// `hyperparameter` λ given as a number, dimensionless: in [1e-6, 1000], as the CLI's.
pub(crate) fn hyperparameter(obj: &Bound<'_, PyAny>) -> PyResult<f64> {
    real(obj, "hyperparameter", "a number in [1e-6, 1000]", hyperparameter_in_range)
}

/// `threshold`: a fraction of the peak, in (0, 1], as the CLI's `--threshold`.
pub(crate) fn threshold(obj: &Bound<'_, PyAny>) -> PyResult<f64> {
    real(obj, "threshold", "a number in (0, 1]", |t| t > 0.0 && t <= 1.0)
}

/// `false_alarm_rate`: false touches per no-touch frame, the library's (0, 0.5].
pub(crate) fn false_alarm_rate(obj: &Bound<'_, PyAny>) -> PyResult<f64> {
    real(obj, "false_alarm_rate", "a number in (0, 0.5]", pipeline::false_alarm_rate_ok)
}

/// `noise`: relative noise per value and frame, in [0, 0.1], as `robot-presses --noise`.
pub(crate) fn noise(obj: &Bound<'_, PyAny>) -> PyResult<f64> {
    real(obj, "noise", "a number in [0, 0.1] (relative)", |n| (0.0..=0.1).contains(&n))
}

/// `rate`: frames/s, in [0, 100000], as `run --rate`.
pub(crate) fn rate(obj: &Bound<'_, PyAny>) -> PyResult<f64> {
    real(obj, "rate", "a number in [0, 100000] frames/s", |r| (0.0..=1e5).contains(&r))
}

/// `force` of a press, in [0, [`MAX_FORCE`]] N (the most a label may hold).
pub(crate) fn force(obj: &Bound<'_, PyAny>) -> PyResult<f64> {
    real(obj, "force", &format!("a number in [0, {MAX_FORCE:e}] N"), force_ok)
}

/// Whether `force` (N) is one a press may have: 0 to [`MAX_FORCE`], as a samples file's forces.
pub(crate) fn force_ok(force: f64) -> bool {
    (0.0..=MAX_FORCE).contains(&force)
}

/// A finite number for `name`; its range is the library's to check.
fn finite(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<f64> {
    real(obj, name, "a finite number", |_| true)
}

/// `x`: a coordinate in m, finite.
pub(crate) fn x(obj: &Bound<'_, PyAny>) -> PyResult<f64> {
    finite(obj, "x")
}

/// `y`: a coordinate in m, finite.
pub(crate) fn y(obj: &Bound<'_, PyAny>) -> PyResult<f64> {
    finite(obj, "y")
}

/// `strength` of a touch (its peak, S/m), finite.
pub(crate) fn strength(obj: &Bound<'_, PyAny>) -> PyResult<f64> {
    finite(obj, "strength")
}

/// `thickness` of the sheet in m, finite (the library refuses one not above 0).
pub(crate) fn thickness(obj: &Bound<'_, PyAny>) -> PyResult<f64> {
    finite(obj, "thickness")
}

/// `background` conductivity in S/m, finite (the library refuses one not above 0).
pub(crate) fn background(obj: &Bound<'_, PyAny>) -> PyResult<f64> {
    finite(obj, "background")
}
