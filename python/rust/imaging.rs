//! Images from frames: the one-step Gauss–Newton reconstructor, images and touches.

use eitskin::inverse::{normalize_jacobian, plausible_ratio, reconstruction_matrix, typical_ratio};
use eitskin::touch::Polarity;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::arguments;
use crate::model::{ForwardModel, Mesh};
use crate::{as_array, error, fail, floats, matrix};

/// The prior from its name, with the NOSER exponent p (read by [`arguments::exponent`]).
fn prior(name: &str, exponent: f64) -> PyResult<eitskin::Prior> {
    match name {
        "noser" => Ok(eitskin::Prior::Noser { exponent }),
        "tikhonov" => Ok(eitskin::Prior::Tikhonov),
        "laplace" => Ok(eitskin::Prior::Laplace),
        other => Err(fail(format!("prior must be \"noser\", \"tikhonov\" or \"laplace\", got {other:?}"))),
    }
}

/// The element-level one-step Gauss–Newton matrix (triangles, measurements), S/m per V:
/// Δσ = (JᵀJ + λ²R)⁻¹JᵀΔv for `jacobian` (measurements, triangles) on `mesh`, λ in [1e-6, 1000],
/// the NOSER exponent in [0, 1].
#[pyfunction]
#[pyo3(signature = (jacobian, mesh, hyperparameter, prior = "noser", exponent = 0.5, background = None))]
pub(crate) fn one_step_matrix<'py>(
    py: Python<'py>,
    jacobian: &Bound<'py, PyAny>,
    mesh: &Mesh,
    #[pyo3(from_py_with = arguments::hyperparameter)] hyperparameter: f64,
    prior: &str,
    #[pyo3(from_py_with = arguments::exponent)] exponent: f64,
    background: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let rows = matrix(jacobian, "jacobian")?;
    let columns = rows.first().map_or(0, Vec::len);
    let mut j = eitskin::faer::Mat::from_fn(rows.len(), columns, |m, t| rows[m][t]);
    if let Some(background) = background {
        normalize_jacobian(&mut j, &floats(background, "background")?).map_err(error)?;
    }
    let prior = self::prior(prior, exponent)?;
    let mesh = &mesh.0;
    let rm = py.detach(|| reconstruction_matrix(j.as_ref(), &prior, hyperparameter, mesh)).map_err(error)?;
    Ok(Array2::from_shape_fn((rm.nrows(), rm.ncols()), |(t, m)| rm[(t, m)]).into_pyarray(py))
}

/// An image on a raster: values (ny, nx) in S/m, row 0 at the top; `inside` marks the pixels
/// within the outline.
#[pyclass(module = "eitskin", frozen)]
pub(crate) struct Image(pub(crate) eitskin::Image);

#[pymethods]
impl Image {
    /// Conductivity change per pixel, (ny, nx), S/m, row 0 at the top (NaN outside the outline).
    #[getter]
    fn values<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f32>> {
        let [nx, ny] = self.0.size;
        let values: Vec<f32> =
            self.0.values.iter().zip(&self.0.inside).map(|(v, inside)| if *inside { *v } else { f32::NAN }).collect();
        let shaped = Array2::from_shape_vec((ny, nx), values);
        // The image's size is its values' count by construction; a mismatch would be a bug.
        shaped.unwrap_or_else(|_| Array2::from_elem((ny, nx), f32::NAN)).into_pyarray(py)
    }

    /// Whether each pixel lies inside the outline, (ny, nx).
    #[getter]
    fn inside<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<bool>> {
        let [nx, ny] = self.0.size;
        Array2::from_shape_fn((ny, nx), |(r, c)| self.0.inside[r * nx + c]).into_pyarray(py)
    }

    /// (left, right, bottom, top) in m, for matplotlib's `imshow(extent=...)`.
    #[getter]
    fn extent(&self) -> (f64, f64, f64, f64) {
        let [[x0, y0], [x1, y1]] = self.0.bounds;
        (x0, x1, y0, y1)
    }

    /// The pixel with the largest |change| and that change, ((row, column), S/m), or None.
    fn peak(&self) -> Option<((usize, usize), f32)> {
        let nx = self.0.size[0];
        self.0.peak().map(|(i, v)| ((i / nx, i % nx), v))
    }

    fn __repr__(&self) -> String {
        format!("Image({} × {} pixels)", self.0.size[0], self.0.size[1])
    }
}

/// A touch found in an image: centre (m), peak (S/m), area (m²).
#[pyclass(module = "eitskin", frozen, get_all)]
pub(crate) struct Touch {
    /// Centre of gravity, (x, y) in m.
    centre: (f64, f64),
    /// Largest change inside the touch, S/m (positive toward its polarity).
    peak: f64,
    /// Where the peak is, (x, y) in m.
    peak_at: (f64, f64),
    /// Area above the threshold, m².
    area: f64,
    /// Pixels above the threshold.
    pixels: usize,
    /// "decrease" (less conductive, a press on the gel) or "increase".
    polarity: String,
}

#[pymethods]
impl Touch {
    fn __repr__(&self) -> String {
        format!(
            "Touch(centre=({:.4}, {:.4}) m, peak={:.4} S/m, area={:.3e} m², {})",
            self.centre.0, self.centre.1, self.peak, self.area, self.polarity
        )
    }
}

/// The touches of `image`, strongest first: pixels at least `threshold` of the peak (the
/// paper's 0.6), joined into connected regions. `peak_of` says whose peak, as ``eitskin image
/// --peak-of`` does: "sign" (each sign's own strongest change; the CLI's default), "frame" (the
/// strongest change of either sign, the paper's rule) or "touch" (each touch's own; several
/// presses); `per_touch` is the older spelling of "touch".
#[pyfunction]
#[pyo3(signature = (image, threshold = 0.6, polarity = "decrease", per_touch = false, peak_of = "sign"))]
pub(crate) fn touches(
    image: &Image,
    #[pyo3(from_py_with = arguments::threshold)] threshold: f64,
    polarity: &str,
    per_touch: bool,
    peak_of: &str,
) -> PyResult<Vec<Touch>> {
    let polarity: Polarity = polarity.parse().map_err(fail)?;
    let peak_of: eitskin::touch::PeakOf = peak_of.parse().map_err(|e: String| fail(format!("peak_of: {e}")))?;
    let params = eitskin::TouchParams {
        threshold,
        polarity,
        peak_of: if per_touch { eitskin::touch::PeakOf::Touch } else { peak_of },
        ..eitskin::TouchParams::default()
    };
    Ok(eitskin::touch::detect(&image.0, &params)
        .into_iter()
        .map(|t| Touch {
            centre: (t.centre[0], t.centre[1]),
            peak: t.peak,
            peak_at: (t.peak_at[0], t.peak_at[1]),
            area: t.area,
            pixels: t.pixels,
            polarity: match t.polarity {
                Polarity::Increase => "increase".into(),
                _ => "decrease".into(),
            },
        })
        .collect())
}

/// The one-step Gauss–Newton reconstructor on a raster (EIDORS' RM, pyEIT's H).
///
/// Linearised once at a homogeneous background: an image is one product of the reconstruction
/// matrix (pixels × measurements) with the frame's differences,
/// Δσ = (JᵀWJ + λ²R)⁻¹JᵀWΔv.
///
/// λ is chosen as the CLI chooses it: ``"auto"`` takes the larger of the λ for a noise figure of
/// 0.5 and the MAP λ of the noise level, with the channels weighted (W) by their noise. Built
/// from a forward model, the noise is assumed (0.3 % of each value); built from frames at rest
/// (:meth:`Reconstructor.from_reference`), it is measured from them, exactly as ``eitskin
/// image --reference`` does, so the two give the same image of the same frames.
///
/// Parameters
/// ----------
/// model : ForwardModel
///     The sensor's forward model (its mesh, electrodes and protocol).
/// background : float
///     The homogeneous conductivity it is linearised at, in S/m.
/// hyperparameter : float or str, default "auto"
///     λ, dimensionless, in [1e-6, 1000] (λ² multiplies the prior; pyEIT's ``lamb`` is λ²), or
///     ``"auto"``.
/// prior : {"noser", "tikhonov", "laplace"}, default "noser"
///     R: diag(JᵀJ)^exponent, the identity, or a Laplacian over neighbouring triangles.
/// exponent : float, default 0.5
///     The NOSER exponent p, in [0, 1] (0 is Tikhonov's R; pyEIT's "lm" is p = 1).
/// normalised : bool, default False
///     Image Δv/v_ref instead of Δv (the CLI's ``--normalised``).
/// raster : (int, int), default (64, 64)
///     Pixels (nx, ny) over the mesh's bounding box, 1 to 4096 each.
/// weighting : {"noise", "none"}, optional
///     How channels are weighted: by their noise, or alike; default ``"noise"`` with ``"auto"``,
///     ``"none"`` with a given λ (the CLI's ``--weighting``).
///
/// Raises
/// ------
/// EitskinError
///     A hyperparameter, exponent or raster out of range, an unknown prior or weighting; in
///     `image`, a frame whose values are typically not within 10 times its reference's (another
///     unit or gain), as the CLI refuses it.
///
/// Examples
/// --------
/// >>> spec = SensorSpec.square_hydrogel()
/// >>> recon = Reconstructor(spec.forward_model(), spec.conductivity)
/// >>> recon.measurements, recon.chosen_by, recon.weighting
/// (120, 'noise-figure-and-map', 'noise-assumed')
#[pyclass(module = "eitskin", frozen)]
pub(crate) struct Reconstructor {
    pub(crate) recon: eitskin::Reconstructor,
    chosen_by: &'static str,
    weighting: eitskin::inverse::WeightingUsed,
    reference: Option<Vec<f64>>,
}

/// `hyperparameter` from Python: a λ in [1e-6, 1000], or a rule's name.
pub(crate) fn rule(hyperparameter: &Bound<'_, PyAny>) -> PyResult<eitskin::inverse::HyperparameterRule> {
    use eitskin::inverse::{Hyperparameter, HyperparameterRule};
    if let Ok(text) = hyperparameter.extract::<String>() {
        return text.parse().map_err(|e: String| fail(format!("hyperparameter: {e}")));
    }
    let what = "a number in [1e-6, 1000] or \"auto\"";
    let value = arguments::real(hyperparameter, "hyperparameter", what, arguments::hyperparameter_in_range)?;
    Ok(HyperparameterRule::Model(Hyperparameter::Fixed(value)))
}

/// `weighting` from Python: "noise", "none", or None for the rule's default.
fn weighting(weighting: Option<&str>) -> PyResult<Option<eitskin::inverse::Weighting>> {
    weighting.map(|w| w.parse().map_err(|e: String| fail(format!("weighting: {e}")))).transpose()
}

/// Reconstructor parameters from Python's keywords (the exponent and raster read by
/// [`arguments`]), λ left to the rule.
fn params(prior: &str, exponent: f64, normalised: bool, raster: [usize; 2]) -> PyResult<eitskin::ReconstructorParams> {
    Ok(eitskin::ReconstructorParams {
        prior: self::prior(prior, exponent)?,
        normalised,
        raster,
        ..eitskin::ReconstructorParams::default()
    })
}

/// Frames at rest from Python: one frame (1-D) or one per row (2-D).
fn frame_rows(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<Vec<f64>>> {
    let array = as_array(obj, "float64", name)?;
    if let Ok(rows) = array.extract::<PyReadonlyArray2<'_, f64>>() {
        let width = rows.shape()[1];
        let values = rows.as_slice()?;
        if values.is_empty() {
            return Err(fail(format!("{name}: no frame")));
        }
        return Ok(values.chunks_exact(width).map(<[f64]>::to_vec).collect());
    }
    Ok(vec![crate::vector(obj, name)?.as_slice()?.to_vec()])
}

/// A reference `v_ref` and a frame `v` (V, protocol order) from Python, the frame refused where
/// its values are typically ([`typical_ratio`]) not those of a frame of the same sensor, unit
/// and gain ([`plausible_ratio`]), as the CLI and the pipeline refuse it.
fn frame_pair<'py>(
    v_ref: &Bound<'py, PyAny>,
    v: &Bound<'py, PyAny>,
) -> PyResult<(PyReadonlyArray1<'py, f64>, PyReadonlyArray1<'py, f64>)> {
    let (v_ref, v) = (crate::vector(v_ref, "v_ref")?, crate::vector(v, "v")?);
    if let Some(ratio) = typical_ratio(v.as_slice()?, v_ref.as_slice()?).filter(|r| !plausible_ratio(*r)) {
        return Err(error(eitskin::InverseError::FrameScale { ratio, restarted: false }));
    }
    Ok((v_ref, v))
}

#[pymethods]
impl Reconstructor {
    /// Linearises `model` at `background` (S/m): prior "noser" (exponent p), "tikhonov" or
    /// "laplace"; hyperparameter λ (λ² multiplies the prior) or "auto" (the noise assumed);
    /// `normalised` uses Δv/v_ref; `raster` (nx, ny) pixels over the mesh's bounding box.
    #[new]
    #[allow(clippy::too_many_arguments, reason = "Python's keyword arguments, one per setting")]
    #[pyo3(
        signature = (model, background, hyperparameter = None, prior = "noser", exponent = 0.5, normalised = false, raster = [64, 64], weighting = None),
        text_signature = "(model, background, hyperparameter='auto', prior='noser', exponent=0.5, normalised=False, raster=(64, 64), weighting=None)"
    )]
    fn new(
        py: Python<'_>,
        model: &ForwardModel,
        #[pyo3(from_py_with = arguments::background)] background: f64,
        hyperparameter: Option<&Bound<'_, PyAny>>,
        prior: &str,
        #[pyo3(from_py_with = arguments::exponent)] exponent: f64,
        normalised: bool,
        #[pyo3(from_py_with = arguments::raster)] raster: [usize; 2],
        weighting: Option<&str>,
    ) -> PyResult<Reconstructor> {
        use eitskin::inverse::{Hyperparameter, HyperparameterRule, Linearisation, Reference};
        let rule =
            hyperparameter.map(self::rule).transpose()?.unwrap_or(HyperparameterRule::Model(Hyperparameter::Auto));
        if let HyperparameterRule::Data(c) = rule {
            return Err(fail(format!(
                "hyperparameter: {} chooses λ from the frames imaged; give them with Reconstructor.from_reference(…, frames=…)",
                c.name()
            )));
        }
        let weighting = self::weighting(weighting)?.unwrap_or(rule.default_weighting());
        let params = self::params(prior, exponent, normalised, raster)?;
        let model = &model.0;
        let measurements = model.protocol().measurements().len();
        eitskin::memory::check_raster(params.raster, measurements, eitskin_io::available_memory()).map_err(error)?;
        py.detach(|| -> Result<Reconstructor, eitskin::InverseError> {
            let lin = std::sync::Arc::new(Linearisation::new(model, background)?);
            // The model's own frame as the one reference: the noise assumed, every channel in use.
            let reference = Reference { v_ref: lin.background().to_vec(), variance: None };
            let (channels, used) = reference.channels(&lin, normalised, &[], weighting);
            let auto = || eitskin::inverse::choose_hyperparameter(&lin, &params.prior, normalised, &channels);
            let hyperparameter =
                reference.hyperparameter(rule, &lin, (&params.prior, normalised), &channels, &[], auto)?;
            let params = eitskin::ReconstructorParams { hyperparameter, ..params };
            let recon = eitskin::Reconstructor::from_linearisation(lin, &params, channels)?;
            Ok(Reconstructor { recon, chosen_by: rule.chosen_by(), weighting: used, reference: None })
        })
        .map_err(error)
    }

    /// The reconstructor that ``eitskin image`` makes of `spec` and the frames at rest
    /// `reference` (one frame, or one per row): their mean is the reference, their spread the
    /// measured noise; channels the spec drops, dead (0 at rest) or missing (NaN) are dropped;
    /// λ by `hyperparameter` ("auto", "gcv" or "discrepancy" on `frames`, or a number).
    #[classmethod]
    #[allow(clippy::too_many_arguments, reason = "Python's keyword arguments, one per setting")]
    #[pyo3(signature = (spec, reference, hyperparameter = None, frames = None, prior = "noser", exponent = 0.5, normalised = false, raster = [64, 64], weighting = None, cache = true))]
    fn from_reference(
        _class: &Bound<'_, pyo3::types::PyType>,
        py: Python<'_>,
        spec: &crate::model::SensorSpec,
        reference: &Bound<'_, PyAny>,
        hyperparameter: Option<&Bound<'_, PyAny>>,
        frames: Option<&Bound<'_, PyAny>>,
        prior: &str,
        #[pyo3(from_py_with = arguments::exponent)] exponent: f64,
        normalised: bool,
        #[pyo3(from_py_with = arguments::raster)] raster: [usize; 2],
        weighting: Option<&str>,
        cache: bool,
    ) -> PyResult<Reconstructor> {
        use eitskin::inverse::{mark_missing, Hyperparameter, HyperparameterRule};
        let rule =
            hyperparameter.map(self::rule).transpose()?.unwrap_or(HyperparameterRule::Model(Hyperparameter::Auto));
        let weighting = self::weighting(weighting)?;
        let params = self::params(prior, exponent, normalised, raster)?;
        let spec = &spec.0;
        let mut references = frame_rows(reference, "reference")?;
        let mut frames = frames.map(|f| frame_rows(f, "frames")).transpose()?.unwrap_or_default();
        if matches!(rule, HyperparameterRule::Data(_)) && frames.is_empty() {
            return Err(fail(
                "hyperparameter: gcv and discrepancy choose λ from the frames imaged: give them as frames=…",
            ));
        }
        let measurements = spec.protocol().map_err(error)?.measurements().len();
        for (name, rows) in [("reference", &references), ("frames", &frames)] {
            if let Some((k, row)) = rows.iter().enumerate().find(|(_, r)| r.len() != measurements) {
                return Err(fail(format!(
                    "{name}: frame {} holds {} values, but the protocol has {measurements}",
                    k + 1,
                    row.len()
                )));
            }
        }
        eitskin::memory::check_raster(params.raster, measurements, eitskin_io::available_memory()).map_err(error)?;
        py.detach(|| -> Result<Reconstructor, eitskin_io::Error> {
            mark_missing(&spec.used_channels()?, &mut references, &mut frames);
            let lin = eitskin_io::build::linearisation(spec, cache)?;
            let made = eitskin_io::build::ReferenceImaging::new(
                spec,
                &lin,
                &params,
                (&references, &frames),
                (rule, weighting),
                cache,
            )?;
            Ok(Reconstructor {
                recon: made.recon,
                chosen_by: made.chosen_by,
                weighting: made.weighting,
                reference: Some(made.reference.v_ref),
            })
        })
        .map_err(error)
    }

    /// λ, dimensionless: given, or as chosen.
    #[getter]
    fn hyperparameter(&self) -> f64 {
        self.recon.params().hyperparameter
    }

    /// What chose λ: "given", "noise-figure-and-map" ("auto"), "gcv" or "discrepancy".
    #[getter]
    fn chosen_by(&self) -> &'static str {
        self.chosen_by
    }

    /// How the channels are weighted: "noise-measured", "noise-assumed" or "none".
    #[getter]
    fn weighting(&self) -> &'static str {
        self.weighting.name()
    }

    /// The mean of the frames at rest (V, protocol order; NaN where a channel is dropped), when
    /// made by :meth:`from_reference`, else None.
    #[getter]
    fn reference<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        self.reference.clone().map(|v| v.into_pyarray(py))
    }

    /// The channels dropped (1-based, as the CLI names them).
    #[getter]
    fn channels_dropped(&self) -> Vec<usize> {
        self.recon.channels().dropped().iter().map(|m| m + 1).collect()
    }

    /// The image of frame `v` against the reference `v_ref` (V, protocol order); a frame in
    /// another unit or gain than its reference is refused ([`frame_pair`]).
    fn image(&self, py: Python<'_>, v_ref: &Bound<'_, PyAny>, v: &Bound<'_, PyAny>) -> PyResult<Image> {
        let (v_ref, v) = frame_pair(v_ref, v)?;
        let (v_ref, v) = (v_ref.as_slice()?, v.as_slice()?);
        let recon = &self.recon;
        py.detach(|| recon.image(v_ref, v)).map(Image).map_err(error)
    }

    /// The conductivity change per triangle, (triangles,), S/m.
    fn element_values<'py>(
        &self,
        py: Python<'py>,
        v_ref: &Bound<'py, PyAny>,
        v: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f32>>> {
        let (v_ref, v) = frame_pair(v_ref, v)?;
        let (v_ref, v) = (v_ref.as_slice()?, v.as_slice()?);
        let recon = &self.recon;
        Ok(py.detach(|| recon.element_values(v_ref, v)).map_err(error)?.into_pyarray(py))
    }

    /// Number of measurements a frame has.
    #[getter]
    fn measurements(&self) -> usize {
        self.recon.measurements()
    }

    fn __repr__(&self) -> String {
        format!(
            "Reconstructor({} measurements, λ = {:.4} ({}), weighting {})",
            self.recon.measurements(),
            self.recon.params().hyperparameter,
            self.chosen_by,
            self.weighting.name()
        )
    }
}
