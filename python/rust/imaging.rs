//! Images from frames: the one-step Gauss–Newton reconstructor, images and touches.

use eitskin::inverse::{normalize_jacobian, reconstruction_matrix};
use eitskin::touch::Polarity;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::model::{ForwardModel, Mesh};
use crate::{as_array, error, fail, floats};

/// The prior from its name.
fn prior(name: &str, exponent: f64) -> PyResult<eitskin::Prior> {
    match name {
        "noser" => Ok(eitskin::Prior::Noser { exponent }),
        "tikhonov" => Ok(eitskin::Prior::Tikhonov),
        "laplace" => Ok(eitskin::Prior::Laplace),
        other => Err(fail(format!("prior must be \"noser\", \"tikhonov\" or \"laplace\", got {other:?}"))),
    }
}

/// The element-level one-step Gauss–Newton matrix (triangles, measurements), S/m per V:
/// Δσ = (JᵀJ + λ²R)⁻¹JᵀΔv for `jacobian` (measurements, triangles) on `mesh`.
#[pyfunction]
#[pyo3(signature = (jacobian, mesh, hyperparameter, prior = "noser", exponent = 0.5, background = None))]
pub(crate) fn one_step_matrix<'py>(
    py: Python<'py>,
    jacobian: &Bound<'py, PyAny>,
    mesh: &Mesh,
    hyperparameter: f64,
    prior: &str,
    exponent: f64,
    background: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let array = as_array(jacobian, "float64")?;
    let array: PyReadonlyArray2<'_, f64> = array.extract().map_err(|_| fail("jacobian: expected a 2-D array"))?;
    let (rows, columns) = (array.shape()[0], array.shape()[1]);
    let values = array.as_slice()?;
    let mut j = eitskin::faer::Mat::from_fn(rows, columns, |m, t| values[m * columns + t]);
    if let Some(background) = background {
        normalize_jacobian(&mut j, &floats(background)?).map_err(error)?;
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
/// paper's 0.6), joined into connected regions; `per_touch` compares each touch with its own
/// peak (several presses) instead of the frame's.
#[pyfunction]
#[pyo3(signature = (image, threshold = 0.6, polarity = "decrease", per_touch = false))]
pub(crate) fn touches(image: &Image, threshold: f64, polarity: &str, per_touch: bool) -> PyResult<Vec<Touch>> {
    if !(threshold > 0.0 && threshold <= 1.0) {
        return Err(fail(format!("threshold must be in (0, 1], got {threshold}")));
    }
    let polarity: Polarity = polarity.parse().map_err(fail)?;
    let params = eitskin::TouchParams {
        threshold,
        polarity,
        peak_of: if per_touch { eitskin::touch::PeakOf::Touch } else { eitskin::touch::PeakOf::Frame },
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
/// Δσ = (JᵀJ + λ²R)⁻¹JᵀΔv.
///
/// Parameters
/// ----------
/// model : ForwardModel
///     The sensor's forward model (its mesh, electrodes and protocol).
/// background : float
///     The homogeneous conductivity it is linearised at, in S/m.
/// hyperparameter : float, default 0.1
///     λ, dimensionless; λ² multiplies the prior (pyEIT's ``lamb`` is λ²).
/// prior : {"noser", "tikhonov", "laplace"}, default "noser"
///     R: diag(JᵀJ)^exponent, the identity, or a Laplacian over neighbouring triangles.
/// exponent : float, default 0.5
///     The NOSER exponent p (pyEIT's "lm" is p = 1).
/// normalized : bool, default False
///     Image Δv/v_ref instead of Δv.
/// raster : (int, int), default (64, 64)
///     Pixels (nx, ny) over the mesh's bounding box, 1 to 4096 each.
///
/// Raises
/// ------
/// EitskinError
///     A hyperparameter that is not positive and finite, an unknown prior, a raster out of range.
///
/// Examples
/// --------
/// >>> spec = SensorSpec.square_hydrogel()
/// >>> recon = Reconstructor(spec.forward_model(), spec.conductivity)
/// >>> recon.measurements
/// 120
#[pyclass(module = "eitskin", frozen)]
pub(crate) struct Reconstructor(pub(crate) eitskin::Reconstructor);

#[pymethods]
impl Reconstructor {
    /// Linearises `model` at `background` (S/m): prior "noser" (exponent p), "tikhonov" or
    /// "laplace"; hyperparameter λ (λ² multiplies the prior); `normalized` uses Δv/v_ref;
    /// `raster` (nx, ny) pixels over the mesh's bounding box.
    #[new]
    #[allow(clippy::too_many_arguments, reason = "Python's keyword arguments, one per setting")]
    #[pyo3(
        signature = (model, background, hyperparameter = 0.1, prior = "noser", exponent = 0.5, normalized = false, raster = (64, 64)),
        text_signature = "(model, background, hyperparameter=0.1, prior='noser', exponent=0.5, normalized=False, raster=(64, 64))"
    )]
    fn new(
        py: Python<'_>,
        model: &ForwardModel,
        background: f64,
        hyperparameter: f64,
        prior: &str,
        exponent: f64,
        normalized: bool,
        raster: (usize, usize),
    ) -> PyResult<Reconstructor> {
        if !(1..=4096).contains(&raster.0) || !(1..=4096).contains(&raster.1) {
            return Err(fail(format!("raster must be 1 to 4096 pixels each way, got {raster:?}")));
        }
        let params = eitskin::ReconstructorParams {
            prior: self::prior(prior, exponent)?,
            hyperparameter,
            normalized,
            raster: [raster.0, raster.1],
            ..eitskin::ReconstructorParams::default()
        };
        let model = &model.0;
        let measurements = model.protocol().measurements().len();
        eitskin::memory::check_raster(params.raster, measurements, eitskin_io::available_memory()).map_err(error)?;
        py.detach(|| eitskin::Reconstructor::new(model, background, &params)).map(Reconstructor).map_err(error)
    }

    /// The image of frame `v` against the reference `v_ref` (V, protocol order).
    fn image(&self, py: Python<'_>, v_ref: &Bound<'_, PyAny>, v: &Bound<'_, PyAny>) -> PyResult<Image> {
        let (v_ref, v) = (crate::vector(v_ref, "v_ref")?, crate::vector(v, "v")?);
        let (v_ref, v) = (v_ref.as_slice()?, v.as_slice()?);
        let recon = &self.0;
        py.detach(|| recon.image(v_ref, v)).map(Image).map_err(error)
    }

    /// The conductivity change per triangle, (triangles,), S/m.
    fn element_values<'py>(
        &self,
        py: Python<'py>,
        v_ref: &Bound<'py, PyAny>,
        v: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f32>>> {
        let (v_ref, v) = (crate::vector(v_ref, "v_ref")?, crate::vector(v, "v")?);
        let (v_ref, v) = (v_ref.as_slice()?, v.as_slice()?);
        let recon = &self.0;
        Ok(py.detach(|| recon.element_values(v_ref, v)).map_err(error)?.into_pyarray(py))
    }

    /// Number of measurements a frame has.
    #[getter]
    fn measurements(&self) -> usize {
        self.0.measurements()
    }

    fn __repr__(&self) -> String {
        format!("Reconstructor({} measurements)", self.0.measurements())
    }
}
