//! Calibration learned from labelled presses: robot presses of the imperfect virtual skin, and
//! a model from Δv to where (and how hard, how deep) a press is, with its uncertainty.

use numpy::{IntoPyArray, PyArray1, PyArray2, PyArrayMethods};
use pyo3::prelude::*;

use crate::arguments;
use crate::model::SensorSpec;
use crate::{error, fail};

/// A model learned from labelled presses: Δv → position (m), and force (N) and depth (m) when
/// the presses had them, each with its uncertainty (Gaussian processes).
///
/// Train it with `LearnedModel.train`; read and write the JSON of `eitskin learn --out`.
///
/// Examples
/// --------
/// >>> import eitskin
/// >>> spec = eitskin.SensorSpec.square_hydrogel().with_triangles(1500)
/// >>> dv, positions, forces = eitskin.robot_presses(spec, 60, seed=2)
/// >>> model = eitskin.LearnedModel.train(dv, positions, forces=forces, method="gp-press", spec=spec)
/// >>> x, y = positions[0]
/// >>> answer = model.predict(dv[0])
/// >>> abs(answer["x"] - x) < 0.01 and answer["force"] > 0
/// True
#[pyclass(module = "eitskin")]
pub(crate) struct LearnedModel {
    model: eitskin::learn::LearnedModel,
    /// What `save` writes: the presses trained on, or the file it was loaded from.
    saved: Saved,
    scratch: eitskin::learn::PredictScratch,
}

enum Saved {
    Presses(Vec<eitskin::learn::LabelledPress>),
    File(String),
}

/// Each press's Δv from a (presses, channels) array-like, every value finite.
fn inputs(dv: &Bound<'_, PyAny>) -> PyResult<Vec<Vec<f64>>> {
    let inputs = crate::matrix(dv, "dv")?;
    for (press, values) in inputs.iter().enumerate() {
        if let Some(channel) = values.iter().position(|v| !v.is_finite()) {
            return Err(fail(format!(
                "dv: press {} channel {} is {}: every value must be a finite number",
                press + 1,
                channel + 1,
                crate::quoted(values[channel])
            )));
        }
    }
    Ok(inputs)
}

/// An optional label per press (None, or one finite value ≥ 0 per press).
fn labels(obj: Option<&Bound<'_, PyAny>>, what: &str, presses: usize) -> PyResult<Vec<Option<f64>>> {
    let Some(obj) = obj else { return Ok(vec![None; presses]) };
    let values = crate::floats(obj, what)?;
    if values.len() != presses {
        return Err(fail(format!("{what}: one per press needed, got {} for {presses} presses", values.len())));
    }
    if let Some(v) = values.iter().find(|v| !(v.is_finite() && **v >= 0.0)) {
        return Err(fail(format!("{what}: every value must be finite and ≥ 0, got {v}")));
    }
    Ok(values.into_iter().map(Some).collect())
}

#[pymethods]
impl LearnedModel {
    /// Trains a model on labelled presses.
    ///
    /// Parameters
    /// ----------
    /// dv : array_like, shape (presses, channels)
    ///     Each press's Δv (pressed less before, in the board's unit) in protocol order.
    /// positions : array_like, shape (presses, 2)
    ///     Where each press was, in m from the outline's centre.
    /// forces, depths : array_like, shape (presses,), optional
    ///     Each press's force (N) and indenter depth (m), when labelled.
    /// method : str, optional
    ///     "knn-K" (K ≥ 1) or "gp", either with "-shape" or "-press", or "curve-press" (the
    ///     physics alone) or "gp-curve-press" (with a learned residual); by default the one whose
    ///     `folds`-fold cross-validated errors are least, position and force (and depth) each
    ///     relative to the best candidate's, as `eitskin learn` chooses.
    /// spec : SensorSpec, optional
    ///     The sensor as specified: with it (and Δv of its protocol's length), the methods on the
    ///     press fitted to Δv are candidates too.
    /// folds : int, default 5
    ///     Folds of the cross-validation, 2 to 20.
    ///
    /// Raises
    /// ------
    /// EitskinError
    ///     For arrays that disagree, a label < 0, a position far off `spec`'s sheet, an unknown
    ///     method, a "-press" method without `spec`, or presses too few to train on.
    #[staticmethod]
    #[pyo3(signature = (dv, positions, forces = None, depths = None, method = None, spec = None, folds = 5))]
    #[allow(clippy::too_many_arguments, reason = "Python keyword arguments")]
    fn train(
        py: Python<'_>,
        dv: &Bound<'_, PyAny>,
        positions: &Bound<'_, PyAny>,
        forces: Option<&Bound<'_, PyAny>>,
        depths: Option<&Bound<'_, PyAny>>,
        method: Option<&str>,
        spec: Option<&SensorSpec>,
        #[pyo3(from_py_with = arguments::folds)] folds: usize,
    ) -> PyResult<LearnedModel> {
        use eitskin::learn::{choose, train, LabelledPress, Method};
        let inputs = inputs(dv)?;
        let positions = crate::rows::<2>(positions, "positions")?;
        if positions.len() != inputs.len() {
            return Err(fail(format!("{} positions for {} presses", positions.len(), inputs.len())));
        }
        let (forces, depths) = (labels(forces, "forces", inputs.len())?, labels(depths, "depths", inputs.len())?);
        let presses: Vec<LabelledPress> = inputs
            .into_iter()
            .zip(positions)
            .zip(forces.into_iter().zip(depths))
            .map(|((inputs, p), (force, depth))| LabelledPress { inputs, position: [p[0], p[1]], force, depth })
            .collect();
        let presses = without_copies(py, presses)?;
        let forced = method
            .map(|m| {
                Method::from_name(m).ok_or_else(|| {
                    fail(format!(
                        "{m:?} is not a method: give knn-K or gp, either with -shape or -press, or curve-press or gp-curve-press"
                    ))
                })
            })
            .transpose()?;
        let spec = spec.map(|s| s.0.clone());
        if let Some(spec) = &spec {
            eitskin_io::check_labels_on_sheet(&presses, spec).map_err(|e| fail(format!("positions: {e}")))?;
        }
        let channels = presses.first().map_or(0, |p| p.inputs.len());
        let (model, presses) = py
            .detach(|| -> Result<_, String> {
                let sensor = match &spec {
                    Some(spec) if spec.protocol().map_err(|e| crate::message(&e))?.len() == channels => {
                        // The press model from the cache, as `eitskin learn` builds it.
                        Some(eitskin_io::build::nominal_sensor(spec).map_err(|e| crate::message(&e))?)
                    }
                    _ => None,
                };
                let method = match forced {
                    Some(m) => m,
                    None => {
                        let quiet = &mut |_: &str, _: usize, _: usize| {};
                        choose(&presses, &Method::candidates(sensor.is_some()), folds, sensor.as_ref(), quiet)
                            .map_err(|e| crate::message(&e))?
                            .0
                    }
                };
                let model = train(&presses, method, sensor.as_ref()).map_err(|e| crate::message(&e))?;
                Ok((model, presses))
            })
            .map_err(fail)?;
        Ok(LearnedModel { model, saved: Saved::Presses(presses), scratch: eitskin::learn::PredictScratch::default() })
    }

    /// The method it was trained with ("gp-press", "knn-5", …).
    #[getter]
    fn method(&self) -> String {
        self.model.method.name()
    }

    /// Channels that carried nothing over the training presses (0-based), left out.
    #[getter]
    fn dead_channels(&self) -> Vec<usize> {
        self.model.dead_channels()
    }

    /// The answer for one Δv (channels in protocol order): a dict of "x", "y" (m), "force" (N)
    /// and "depth" (m) when trained with them, and the standard deviations "position_std",
    /// "force_std", "depth_std" (Gaussian processes only); None for press features of a Δv like
    /// no press.
    fn predict<'py>(
        &mut self,
        py: Python<'py>,
        dv: &Bound<'py, PyAny>,
    ) -> PyResult<Option<Bound<'py, pyo3::types::PyDict>>> {
        let dv = crate::vector(dv, "dv")?;
        let dv = dv.as_slice()?;
        if dv.len() != self.model.channels() {
            return Err(fail(format!("dv has {} values, the model {} channels", dv.len(), self.model.channels())));
        }
        if let Some(k) = dv.iter().position(|v| !v.is_finite()) {
            return Err(fail(format!("dv value {} is {}: every value must be a finite number", k + 1, dv[k])));
        }
        // A press changes a frame by percents: a Δv ten times the training presses' is a raw
        // frame, or another unit or gain (a weak press's Δv may be any smaller).
        let size = eitskin::learn::typical_size(std::iter::once(dv)).unwrap_or(0.0);
        if size >= eitskin::inverse::SCALE_LIMIT * self.model.input_size {
            return Err(fail(format!(
                "dv's root mean square is {size:.4e}, {:.3} times that of the presses the model learned from ({:.4e}): give Δv (a frame less its reference) in the unit and gain the model learned",
                size / self.model.input_size,
                self.model.input_size
            )));
        }
        let Some(answer) = self.model.predict(dv, &mut self.scratch) else { return Ok(None) };
        let dict = pyo3::types::PyDict::new(py);
        dict.set_item("x", answer.position[0])?;
        dict.set_item("y", answer.position[1])?;
        let optional = [
            ("force", answer.force),
            ("depth", answer.depth),
            ("position_std", answer.position_std),
            ("force_std", answer.force_std),
            ("depth_std", answer.depth_std),
        ];
        for (key, value) in optional {
            if let Some(v) = value {
                dict.set_item(key, v)?;
            }
        }
        Ok(Some(dict))
    }

    /// Writes it for `spec` as the JSON `eitskin run --model` reads (a model loaded from a file:
    /// that file's text), to a name ending in `.json` or in no format's extension.
    fn save(&self, path: std::path::PathBuf, spec: &SensorSpec) -> PyResult<()> {
        crate::check_output_name(&path, &["json"])?;
        let text = match &self.saved {
            Saved::Presses(presses) => {
                eitskin_io::learned_model_to_json(&spec.0, self.model.method, presses).map_err(error)?
            }
            Saved::File(text) => text.clone(),
        };
        std::fs::write(&path, text).map_err(|e| fail(format!("cannot write {}: {e}", path.display())))
    }

    /// Reads a model made for `spec` (by `eitskin learn --out` or `save`), trained again.
    #[staticmethod]
    fn load(py: Python<'_>, path: std::path::PathBuf, spec: &SensorSpec) -> PyResult<LearnedModel> {
        let spec = &spec.0;
        let text = std::fs::read_to_string(&path).map_err(|e| fail(format!("cannot read {}: {e}", path.display())))?;
        let channels = spec.protocol().map_err(error)?.len();
        let model = py
            .detach(|| eitskin_io::parse_learned_model(&text, spec, channels, None))
            .map_err(|e| fail(format!("{}: {e}", path.display())))?;
        Ok(LearnedModel { model, saved: Saved::File(text), scratch: eitskin::learn::PredictScratch::default() })
    }
}

/// Robot presses of the imperfect virtual skin: `spec`'s sheet as built (10 % larger, or a
/// circle of that area, electrodes up to 3 mm off, gains ±20 %, the first drive dead, drift,
/// magnitudes only), pressed at random in a disc over 80 % of the half-width with 2–16 N.
///
/// Parameters
/// ----------
/// spec : SensorSpec
///     The sensor as specified.
/// count : int
///     Presses, 1 to 1,000,000.
/// seed : int, default 1
///     Seed of the skin's errors, the presses and the noise, 0 to 2⁶⁴ − 1.
/// frames_per_press : int, default 32
///     Frames averaged for each state (before, pressed), 1 to 10,000.
/// noise : float, default 0.003
///     Relative noise per value and frame, 0 to 0.1.
/// circle : bool, default False
///     Build the skin as a circle.
///
/// Returns
/// -------
/// dv : ndarray, shape (count, channels)
///     Each press's Δv (pressed less the frame before).
/// positions : ndarray, shape (count, 2)
///     Where, in m.
/// forces : ndarray, shape (count,)
///     How hard, in N.
#[pyfunction]
#[pyo3(signature = (spec, count, seed = 1, frames_per_press = 32, noise = 0.003, circle = false))]
#[allow(clippy::type_complexity, reason = "the three arrays Python receives as a tuple")]
pub(crate) fn robot_presses<'py>(
    py: Python<'py>,
    spec: &SensorSpec,
    #[pyo3(from_py_with = arguments::count)] count: usize,
    #[pyo3(from_py_with = arguments::seed)] seed: u64,
    #[pyo3(from_py_with = arguments::frames_per_press)] frames_per_press: usize,
    #[pyo3(from_py_with = arguments::noise)] noise: f64,
    circle: bool,
) -> PyResult<(Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<f64>>, Bound<'py, PyArray1<f64>>)> {
    use eitskin::sim::imperfect::{disc_radius, ImperfectSkin, Imperfections};
    let spec = &spec.0;
    let imperfections = Imperfections { frames_per_press, noise_relative: noise, circle, ..Imperfections::default() };
    let presses = py
        .detach(|| -> Result<_, String> {
            let mut skin = ImperfectSkin::new(spec, &imperfections, seed).map_err(|e| crate::message(&e))?;
            skin.robot_presses(count, disc_radius(&spec.outline, 0.8), 2.0..16.0).map_err(|e| crate::message(&e))
        })
        .map_err(fail)?;
    let channels = presses.first().map_or(0, |p| p.inputs.len());
    let dv: Vec<f64> = presses.iter().flat_map(|p| p.inputs.iter().copied()).collect();
    let positions: Vec<f64> = presses.iter().flat_map(|p| p.position).collect();
    let forces: Vec<f64> = presses.iter().map(|p| p.force.unwrap_or(f64::NAN)).collect();
    let dv = dv.into_pyarray(py).reshape([count, channels])?;
    let positions = positions.into_pyarray(py).reshape([count, 2])?;
    Ok((dv, positions, forces.into_pyarray(py)))
}

/// `presses` less their exact copies, named in a `UserWarning` as `eitskin learn` names them.
fn without_copies(
    py: Python<'_>,
    presses: Vec<eitskin::learn::LabelledPress>,
) -> PyResult<Vec<eitskin::learn::LabelledPress>> {
    let (kept, left_out) = eitskin::learn::without_copies(presses);
    if let Some(left_out) = left_out {
        let category = py.get_type::<pyo3::exceptions::PyUserWarning>();
        let message = std::ffi::CString::new(left_out.to_string()).map_err(|e| fail(e.to_string()))?;
        PyErr::warn(py, &category, &message, 1)?;
    }
    Ok(kept)
}
