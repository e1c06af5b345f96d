//! eitskin's Python module `eitskin._eitskin`: the library's types over numpy arrays, the GIL
//! released around every solve. The Python package `eitskin` re-exports it with its docs.

use eitskin::inverse::{normalize_jacobian, reconstruction_matrix};
use eitskin::touch::Polarity;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

create_exception!(eitskin, EitskinError, PyValueError, "A value eitskin refuses, with the library's message.");

/// Any library error as an `EitskinError` carrying its message.
fn fail(error: impl std::fmt::Display) -> PyErr {
    EitskinError::new_err(error.to_string())
}

/// `obj` as a contiguous numpy array of `dtype` (any array-like numpy can convert).
fn as_array<'py>(obj: &Bound<'py, PyAny>, dtype: &str) -> PyResult<Bound<'py, PyAny>> {
    let numpy = obj.py().import("numpy")?;
    numpy.call_method1("ascontiguousarray", (obj, dtype))
}

/// A 1-D float64 array-like as a Vec.
fn floats(obj: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
    let array = as_array(obj, "float64")?;
    let array: PyReadonlyArray1<'_, f64> =
        array.extract().map_err(|_| fail(format!("expected a 1-D array, got {} dimensions", ndim(&array))))?;
    Ok(array.as_slice()?.to_vec())
}

fn ndim(array: &Bound<'_, PyAny>) -> usize {
    array.getattr("ndim").and_then(|n| n.extract()).unwrap_or(0)
}

/// An (n, K) array-like of `dtype` as rows of K.
fn rows<const K: usize, T: numpy::Element + Copy>(
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

/// Indices as usize, refusing negative ones.
fn indices(values: &[i64], what: &str) -> PyResult<Vec<usize>> {
    values.iter().map(|&i| usize::try_from(i).map_err(|_| fail(format!("{what}: index {i} is negative")))).collect()
}

/// The sensor's description: outline, electrodes, protocol, mesh settings, gel.
#[pyclass(module = "eitskin", frozen)]
#[derive(Clone)]
struct SensorSpec(eitskin::SensorSpec);

#[pymethods]
impl SensorSpec {
    /// The paper's sensor (200 × 200 mm square hydrogel, 16 electrodes, two-terminal protocol).
    #[staticmethod]
    fn square_hydrogel() -> SensorSpec {
        SensorSpec(eitskin::SensorSpec::square_hydrogel())
    }

    /// A spec from TOML text (the spec file's format); `base` is the folder a custom protocol
    /// file is relative to.
    #[staticmethod]
    #[pyo3(signature = (text, base = "."))]
    fn from_toml(text: &str, base: &str) -> PyResult<SensorSpec> {
        eitskin_io::parse_spec(text, std::path::Path::new(base)).map(SensorSpec).map_err(fail)
    }

    /// A spec from a TOML file.
    #[staticmethod]
    fn from_file(path: std::path::PathBuf) -> PyResult<SensorSpec> {
        eitskin_io::read_spec(&path).map(SensorSpec).map_err(fail)
    }

    /// The spec as TOML text.
    fn to_toml(&self) -> String {
        eitskin_io::spec_to_toml(&self.0)
    }

    /// Number of electrodes.
    #[getter]
    fn electrode_count(&self) -> usize {
        self.0.electrodes.count
    }

    /// Background conductivity of the gel, S/m.
    #[getter]
    fn conductivity(&self) -> f64 {
        self.0.conductivity
    }

    /// The same spec meshed with about `triangles` triangles.
    fn with_triangles(&self, triangles: usize) -> PyResult<SensorSpec> {
        if !(1..=100_000_000).contains(&triangles) {
            return Err(fail(format!("triangles must be 1 to 100000000, got {triangles}")));
        }
        let mut spec = self.0.clone();
        spec.mesh.triangles = triangles;
        Ok(SensorSpec(spec))
    }

    /// The spec's mesh (m).
    fn mesh(&self, py: Python<'_>) -> PyResult<Mesh> {
        let spec = self.0.clone();
        py.detach(move || spec.mesh()).map(Mesh).map_err(fail)
    }

    /// The spec's protocol.
    fn protocol(&self) -> PyResult<Protocol> {
        self.0.protocol().map(Protocol).map_err(fail)
    }

    /// The spec's forward model (its mesh, electrodes, thickness and protocol).
    fn forward_model(&self, py: Python<'_>) -> PyResult<ForwardModel> {
        let spec = self.0.clone();
        py.detach(move || spec.forward_model()).map(ForwardModel).map_err(fail)
    }

    fn __repr__(&self) -> String {
        format!("SensorSpec({} electrodes, about {} triangles)", self.0.electrodes.count, self.0.mesh.triangles)
    }
}

/// A triangle mesh: nodes (m), triangles (node indices, counter-clockwise), electrodes (the
/// nodes each covers).
#[pyclass(module = "eitskin", frozen)]
#[derive(Clone)]
struct Mesh(eitskin::Mesh);

#[pymethods]
impl Mesh {
    /// A mesh from arrays: nodes (n, 2) in m, triangles (t, 3) of 0-based node indices, and per
    /// electrode the node indices it covers (one node each for point electrodes).
    #[new]
    fn new(
        nodes: &Bound<'_, PyAny>,
        triangles: &Bound<'_, PyAny>,
        electrodes: Vec<Bound<'_, PyAny>>,
    ) -> PyResult<Mesh> {
        let nodes = rows::<2, f64>(nodes, "float64", "nodes")?;
        let triangles: Vec<[i64; 3]> = rows::<3, i64>(triangles, "int64", "triangles")?;
        let triangles = triangles
            .iter()
            .map(|t| indices(t, "triangles").map(|v| [v[0], v[1], v[2]]))
            .collect::<PyResult<Vec<_>>>()?;
        let electrodes = electrodes
            .iter()
            .map(|e| {
                let array = as_array(e, "int64")?.call_method1("reshape", (-1,))?;
                let array: PyReadonlyArray1<'_, i64> = array.extract()?;
                let values = array.as_slice()?;
                indices(values, "electrodes")
            })
            .collect::<PyResult<Vec<_>>>()?;
        eitskin::Mesh::new(nodes, triangles, electrodes).map(Mesh).map_err(fail)
    }

    /// Node coordinates, (n, 2), m.
    #[getter]
    fn nodes<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let nodes = self.0.nodes();
        Array2::from_shape_fn((nodes.len(), 2), |(i, k)| nodes[i][k]).into_pyarray(py)
    }

    /// Triangles, (t, 3) node indices.
    #[getter]
    fn triangles<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<i64>> {
        let triangles = self.0.triangles();
        Array2::from_shape_fn((triangles.len(), 3), |(t, k)| triangles[t][k] as i64).into_pyarray(py)
    }

    /// Per electrode, the node indices it covers.
    #[getter]
    fn electrodes<'py>(&self, py: Python<'py>) -> Vec<Bound<'py, PyArray1<i64>>> {
        self.0.electrodes().iter().map(|e| e.iter().map(|&n| n as i64).collect::<Vec<_>>().into_pyarray(py)).collect()
    }

    /// Triangle areas, (t,), m².
    fn areas<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        (0..self.0.triangles().len()).map(|t| self.0.area(t)).collect::<Vec<_>>().into_pyarray(py)
    }

    /// Triangle centroids, (t, 2), m.
    fn centroids<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let t = self.0.triangles().len();
        Array2::from_shape_fn((t, 2), |(t, k)| self.0.centroid(t)[k]).into_pyarray(py)
    }

    fn __repr__(&self) -> String {
        let m = &self.0;
        format!(
            "Mesh({} nodes, {} triangles, {} electrodes)",
            m.nodes().len(),
            m.triangles().len(),
            m.electrodes().len()
        )
    }
}

/// Stimulation and measurement patterns.
#[pyclass(module = "eitskin", frozen)]
#[derive(Clone)]
struct Protocol(eitskin::Protocol);

#[pymethods]
impl Protocol {
    /// Every pair of electrodes driven and measured across itself (the paper's board: 120 values
    /// for 16 electrodes).
    #[staticmethod]
    fn two_terminal(electrodes: usize) -> PyResult<Protocol> {
        eitskin::Protocol::two_terminal(electrodes).map(Protocol).map_err(fail)
    }

    /// Adjacent drive, adjacent measurement (pyEIT's `dist_exc=1, step_meas=1`); `skip_driven`
    /// leaves out pairs that touch a driven electrode.
    #[staticmethod]
    #[pyo3(signature = (electrodes, skip_driven = true))]
    fn adjacent(electrodes: usize, skip_driven: bool) -> PyResult<Protocol> {
        eitskin::Protocol::adjacent(electrodes, skip_driven).map(Protocol).map_err(fail)
    }

    /// Opposite drive, adjacent measurement.
    #[staticmethod]
    fn opposite(electrodes: usize) -> PyResult<Protocol> {
        eitskin::Protocol::opposite(electrodes).map(Protocol).map_err(fail)
    }

    /// Number of electrodes.
    #[getter]
    fn electrode_count(&self) -> usize {
        self.0.electrode_count()
    }

    /// Stimulation currents, (stimulations, electrodes), A per unit.
    #[getter]
    fn stimulations<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let s = self.0.stimulations();
        Array2::from_shape_fn((s.len(), self.0.electrode_count()), |(i, l)| s[i][l]).into_pyarray(py)
    }

    /// Measurement weights, (measurements, electrodes): v_m = Σ w_l·u_l.
    #[getter]
    fn measurement_weights<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let m = self.0.measurements();
        Array2::from_shape_fn((m.len(), self.0.electrode_count()), |(i, l)| m[i].weights[l]).into_pyarray(py)
    }

    /// The stimulation each measurement is taken under, (measurements,).
    #[getter]
    fn measurement_stimulation<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i64>> {
        self.0.measurements().iter().map(|m| m.stimulation as i64).collect::<Vec<_>>().into_pyarray(py)
    }

    fn __len__(&self) -> usize {
        self.0.len()
    }

    fn __repr__(&self) -> String {
        format!("Protocol({}, {} measurements)", self.0.description(), self.0.len())
    }
}

/// The forward model: voltages from conductivity (finite elements, complete or point electrodes).
#[pyclass(module = "eitskin", frozen)]
#[derive(Clone)]
struct ForwardModel(eitskin::ForwardModel);

impl ForwardModel {
    /// One conductivity per triangle from a scalar or an array-like.
    fn conductivity(&self, conductivity: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
        let n = self.0.mesh().triangles().len();
        if let Ok(value) = conductivity.extract::<f64>() {
            return Ok(vec![value; n]);
        }
        let values = floats(conductivity)?;
        if values.len() != n {
            return Err(fail(format!("conductivity has {} values, the mesh {n} triangles", values.len())));
        }
        Ok(values)
    }
}

#[pymethods]
impl ForwardModel {
    /// A model on `mesh` with `protocol`: `electrodes` "point", or "complete" with one contact
    /// impedance (Ω·m²) or one per electrode; `thickness` in m.
    #[new]
    #[pyo3(signature = (mesh, protocol, electrodes = "point", contact_impedance = None, thickness = 1.0))]
    fn new(
        mesh: &Mesh,
        protocol: &Protocol,
        electrodes: &str,
        contact_impedance: Option<&Bound<'_, PyAny>>,
        thickness: f64,
    ) -> PyResult<ForwardModel> {
        let model = match electrodes {
            "point" => eitskin::ElectrodeModel::Point,
            "complete" => {
                let count = mesh.0.electrodes().len();
                let z = match contact_impedance {
                    None => return Err(fail("the complete electrode model needs contact_impedance (Ω·m²)")),
                    Some(z) => match z.extract::<f64>() {
                        Ok(z) => vec![z; count],
                        Err(_) => floats(z)?,
                    },
                };
                eitskin::ElectrodeModel::Complete { contact_impedance: z }
            }
            other => return Err(fail(format!("electrodes must be \"point\" or \"complete\", got {other:?}"))),
        };
        eitskin::ForwardModel::new(mesh.0.clone(), model, thickness, protocol.0.clone()).map(ForwardModel).map_err(fail)
    }

    /// The model's mesh.
    #[getter]
    fn mesh(&self) -> Mesh {
        Mesh(self.0.mesh().clone())
    }

    /// The model's protocol.
    #[getter]
    fn protocol(&self) -> Protocol {
        Protocol(self.0.protocol().clone())
    }

    /// The measurements (V at 1 A, protocol order) at `conductivity` (S/m: a scalar or one
    /// per triangle).
    fn measure<'py>(&self, py: Python<'py>, conductivity: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let sigma = self.conductivity(conductivity)?;
        let model = &self.0;
        let v = py.detach(|| model.measure(&sigma)).map_err(fail)?;
        Ok(v.into_pyarray(py))
    }

    /// The Jacobian ∂v_m/∂σ_t at `conductivity`, (measurements, triangles), V per S/m
    /// (pyEIT's J is its negative).
    fn jacobian<'py>(&self, py: Python<'py>, conductivity: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let sigma = self.conductivity(conductivity)?;
        let model = &self.0;
        let j = py.detach(|| model.solve(&sigma).map(|s| model.jacobian(&s))).map_err(fail)?;
        Ok(Array2::from_shape_fn((j.nrows(), j.ncols()), |(m, t)| j[(m, t)]).into_pyarray(py))
    }

    fn __repr__(&self) -> String {
        format!("ForwardModel({} triangles, {} measurements)", self.0.mesh().triangles().len(), self.0.protocol().len())
    }
}

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
fn one_step_matrix<'py>(
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
        normalize_jacobian(&mut j, &floats(background)?).map_err(fail)?;
    }
    let prior = self::prior(prior, exponent)?;
    let mesh = &mesh.0;
    let rm = py.detach(|| reconstruction_matrix(j.as_ref(), &prior, hyperparameter, mesh)).map_err(fail)?;
    Ok(Array2::from_shape_fn((rm.nrows(), rm.ncols()), |(t, m)| rm[(t, m)]).into_pyarray(py))
}

/// An image on a raster: values (ny, nx) in S/m, row 0 at the top; `inside` marks the pixels
/// within the outline.
#[pyclass(module = "eitskin", frozen)]
struct Image(eitskin::Image);

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
struct Touch {
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
fn touches(image: &Image, threshold: f64, polarity: &str, per_touch: bool) -> PyResult<Vec<Touch>> {
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

/// The one-step Gauss–Newton reconstructor on a raster (EIDORS' RM, pyEIT's H), linearised once
/// at a homogeneous background.
#[pyclass(module = "eitskin", frozen)]
struct Reconstructor(eitskin::Reconstructor);

#[pymethods]
impl Reconstructor {
    /// Linearises `model` at `background` (S/m): prior "noser" (exponent p), "tikhonov" or
    /// "laplace"; hyperparameter λ (λ² multiplies the prior); `normalized` uses Δv/v_ref;
    /// `raster` (nx, ny) pixels over the mesh's bounding box.
    #[new]
    #[allow(clippy::too_many_arguments, reason = "Python's keyword arguments, one per setting")]
    #[pyo3(signature = (model, background, hyperparameter = 0.1, prior = "noser", exponent = 0.5, normalized = false, raster = (64, 64)))]
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
        py.detach(|| eitskin::Reconstructor::new(model, background, &params)).map(Reconstructor).map_err(fail)
    }

    /// The image of frame `v` against the reference `v_ref` (V, protocol order).
    fn image(&self, py: Python<'_>, v_ref: PyReadonlyArray1<'_, f64>, v: PyReadonlyArray1<'_, f64>) -> PyResult<Image> {
        let (v_ref, v) = (v_ref.as_slice()?, v.as_slice()?);
        let recon = &self.0;
        py.detach(|| recon.image(v_ref, v)).map(Image).map_err(fail)
    }

    /// The conductivity change per triangle, (triangles,), S/m.
    fn element_values<'py>(
        &self,
        py: Python<'py>,
        v_ref: PyReadonlyArray1<'py, f64>,
        v: PyReadonlyArray1<'py, f64>,
    ) -> PyResult<Bound<'py, PyArray1<f32>>> {
        let (v_ref, v) = (v_ref.as_slice()?, v.as_slice()?);
        let recon = &self.0;
        Ok(py.detach(|| recon.element_values(v_ref, v)).map_err(fail)?.into_pyarray(py))
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

/// The virtual sensor: the spec's sheet on a finer mesh, pressed, with the spec's noise.
#[pyclass(module = "eitskin")]
struct VirtualSensor(eitskin::sim::VirtualSensor);

#[pymethods]
impl VirtualSensor {
    /// The sensor of `spec`, its noise seeded by `seed`.
    #[new]
    #[pyo3(signature = (spec, seed = 0))]
    fn new(py: Python<'_>, spec: &SensorSpec, seed: u64) -> PyResult<VirtualSensor> {
        let spec = &spec.0;
        py.detach(|| eitskin::sim::VirtualSensor::new(spec, seed)).map(VirtualSensor).map_err(fail)
    }

    /// Adds a press at (x, y) m from the outline's centre with `force` N.
    fn press(&mut self, x: f64, y: f64, force: f64) -> PyResult<()> {
        if !(x.is_finite() && y.is_finite() && force.is_finite() && force >= 0.0) {
            return Err(fail(format!(
                "a press needs a finite position and a force ≥ 0 N, got ({x}, {y}) m, {force} N"
            )));
        }
        self.0.press([x, y], force);
        Ok(())
    }

    /// Lifts every press.
    fn release(&mut self) {
        self.0.release();
    }

    /// A frame now, with noise (V at 1 A, protocol order).
    fn frame<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let sensor = &mut self.0;
        Ok(py.detach(|| sensor.frame()).map_err(fail)?.into_pyarray(py))
    }

    /// The noise-free frame now (V at 1 A, protocol order).
    fn clean_frame<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let sensor = &self.0;
        Ok(py.detach(|| sensor.clean_frame()).map_err(fail)?.into_pyarray(py))
    }
}

/// eitskin's native module.
#[pymodule]
fn _eitskin(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("EitskinError", m.py().get_type::<EitskinError>())?;
    m.add_class::<SensorSpec>()?;
    m.add_class::<Mesh>()?;
    m.add_class::<Protocol>()?;
    m.add_class::<ForwardModel>()?;
    m.add_class::<Reconstructor>()?;
    m.add_class::<Image>()?;
    m.add_class::<Touch>()?;
    m.add_class::<VirtualSensor>()?;
    m.add_function(wrap_pyfunction!(one_step_matrix, m)?)?;
    m.add_function(wrap_pyfunction!(touches, m)?)?;
    Ok(())
}
