//! The sensor's description and its forward model: spec, mesh, protocol, voltages, Jacobian.

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;

use crate::arguments;
use crate::{electrode_nodes, error, fail, floats, indices, matrix, rows};

/// The sensor's description: outline, electrodes, protocol, mesh settings, gel.
///
/// Made with `SensorSpec.square_hydrogel()` (the paper's sheet), `SensorSpec.from_toml(text)`
/// or `SensorSpec.from_file(path)` (the spec file `eitskin` reads); lengths in the file's unit,
/// everything here in m and S/m.
#[pyclass(module = "eitskin", frozen)]
#[derive(Clone)]
pub(crate) struct SensorSpec(pub(crate) eitskin::SensorSpec);

#[pymethods]
impl SensorSpec {
    /// A spec from keyword arguments, keys and tables as in the spec file: `units` ("mm"),
    /// `thickness`, `conductivity` (S/m), `outline` (dict with `kind`), `electrodes` (dict with
    /// `count`, `placement`, …), and optional `protocol` and `mesh` dicts.
    #[new]
    #[pyo3(signature = (**fields))]
    fn new(py: Python<'_>, fields: Option<&Bound<'_, pyo3::types::PyDict>>) -> PyResult<SensorSpec> {
        let Some(fields) = fields.filter(|f| !f.is_empty()) else {
            return Err(fail("give the spec's fields (units, thickness, conductivity, outline, electrodes, …), or use SensorSpec.square_hydrogel()"));
        };
        let json: String = py.import("json")?.call_method1("dumps", (fields,))?.extract()?;
        let table: toml::Table = serde_json::from_str(&json).map_err(|e| fail(format!("the spec's fields: {e}")))?;
        let text = toml::to_string(&table).map_err(|e| fail(format!("the spec's fields: {e}")))?;
        SensorSpec::from_toml(&text, ".")
    }

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
        eitskin_io::parse_spec(text, std::path::Path::new(base)).map(SensorSpec).map_err(error)
    }

    /// A spec from a TOML file.
    #[staticmethod]
    fn from_file(path: std::path::PathBuf) -> PyResult<SensorSpec> {
        eitskin_io::read_spec(&path).map(SensorSpec).map_err(error)
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

    /// The outline as a closed line to draw, (k, 2) in m (a circle as 256 segments).
    #[getter]
    fn outline<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray2<f64>> {
        let ring: Vec<Vec<f64>> = self.0.outline.ring(256).iter().map(|p| p.to_vec()).collect();
        numpy::PyArray2::from_vec2(py, &ring).unwrap_or_else(|_| numpy::PyArray2::zeros(py, [0, 2], false))
    }

    /// Each electrode's centre on the outline, (electrodes, 2) in m, electrode 1 first.
    #[getter]
    fn electrodes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
        let spec = &self.0;
        let positions = spec.electrode_positions().map_err(crate::error)?;
        let centres: Vec<Vec<f64>> = positions.iter().map(|e| spec.outline.point_at(e.centre).to_vec()).collect();
        numpy::PyArray2::from_vec2(py, &centres).map_err(|e| crate::fail(e.to_string()))
    }

    /// The same spec meshed with about `triangles` triangles.
    fn with_triangles(&self, #[pyo3(from_py_with = arguments::triangles)] triangles: usize) -> PyResult<SensorSpec> {
        let mut spec = self.0.clone();
        spec.mesh.triangles = triangles;
        Ok(SensorSpec(spec))
    }

    /// The spec's mesh (m).
    fn mesh(&self, py: Python<'_>) -> PyResult<Mesh> {
        let spec = self.0.clone();
        py.detach(move || spec.mesh()).map(Mesh).map_err(error)
    }

    /// The spec's protocol.
    fn protocol(&self) -> PyResult<Protocol> {
        self.0.protocol().map(Protocol).map_err(error)
    }

    /// The spec's forward model (its mesh, electrodes, thickness and protocol).
    fn forward_model(&self, py: Python<'_>) -> PyResult<ForwardModel> {
        let spec = self.0.clone();
        py.detach(move || spec.forward_model()).map(ForwardModel).map_err(error)
    }

    fn __repr__(&self) -> String {
        format!("SensorSpec({} electrodes, about {} triangles)", self.0.electrodes.count, self.0.mesh.triangles)
    }
}

/// A triangle mesh: nodes (m), triangles (node indices, counter-clockwise), electrodes (the
/// nodes each covers).
#[pyclass(module = "eitskin", frozen)]
#[derive(Clone)]
pub(crate) struct Mesh(pub(crate) eitskin::Mesh);

#[pymethods]
impl Mesh {
    /// A mesh from arrays: nodes (n, 2) in m, triangles (t, 3) of 0-based node indices, and per
    /// electrode the node indices it covers (one node each for point electrodes).
    #[new]
    fn new(nodes: &Bound<'_, PyAny>, triangles: &Bound<'_, PyAny>, electrodes: &Bound<'_, PyAny>) -> PyResult<Mesh> {
        Mesh::from_indices(nodes, triangles, electrodes, 0)
    }

    /// A mesh from EIDORS-shaped arrays: `nodes` (n, 2), `elems` (t, 3) and per electrode its
    /// nodes, all 1-based as MATLAB numbers them (`fwd_model.nodes`, `.elems`, `.electrode(i).nodes`).
    #[staticmethod]
    fn from_eidors(
        nodes: &Bound<'_, PyAny>,
        elems: &Bound<'_, PyAny>,
        electrodes: &Bound<'_, PyAny>,
    ) -> PyResult<Mesh> {
        Mesh::from_indices(nodes, elems, electrodes, 1)
    }

    /// The mesh as EIDORS numbers it: {"nodes": (n, 2), "elems": (t, 3) 1-based,
    /// "electrode_nodes": [1-based arrays]}.
    fn to_eidors<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
        let out = pyo3::types::PyDict::new(py);
        out.set_item("nodes", self.nodes(py))?;
        let triangles = self.0.triangles();
        out.set_item(
            "elems",
            Array2::from_shape_fn((triangles.len(), 3), |(t, k)| triangles[t][k] as i64 + 1).into_pyarray(py),
        )?;
        let electrodes: Vec<_> = self
            .0
            .electrodes()
            .iter()
            .map(|e| e.iter().map(|&n| n as i64 + 1).collect::<Vec<_>>().into_pyarray(py))
            .collect();
        out.set_item("electrode_nodes", electrodes)?;
        Ok(out)
    }

    /// The mesh as pyEIT holds it: {"node": (n, 2), "element": (t, 3), "el_pos": one node per
    /// electrode (the first node of each)}.
    fn to_pyeit<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
        let out = pyo3::types::PyDict::new(py);
        out.set_item("node", self.nodes(py))?;
        out.set_item("element", self.triangles(py))?;
        let el_pos: Vec<i64> = self.0.electrodes().iter().map(|e| e.first().map_or(-1, |&n| n as i64)).collect();
        out.set_item("el_pos", el_pos.into_pyarray(py))?;
        Ok(out)
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

impl Mesh {
    /// A mesh from nodes (n, 2) in m, triangles (t, 3) and per electrode its nodes, the indices
    /// numbered from `first` (0, or 1 as EIDORS numbers them).
    fn from_indices(
        nodes: &Bound<'_, PyAny>,
        triangles: &Bound<'_, PyAny>,
        electrodes: &Bound<'_, PyAny>,
        first: usize,
    ) -> PyResult<Mesh> {
        let triangles_name = if first == 0 { "triangles" } else { "elems" };
        let nodes = rows::<2>(nodes, "nodes")?;
        let triangles = rows::<3>(triangles, triangles_name)?
            .iter()
            .map(|t| indices(t, triangles_name, first).map(|v| [v[0], v[1], v[2]]))
            .collect::<PyResult<Vec<_>>>()?;
        let electrodes = electrode_nodes(electrodes, "electrodes", first)?;
        eitskin::Mesh::new(nodes, triangles, electrodes).map(Mesh).map_err(error)
    }
}

/// Stimulation and measurement patterns.
#[pyclass(module = "eitskin", frozen)]
#[derive(Clone)]
pub(crate) struct Protocol(pub(crate) eitskin::Protocol);

#[pymethods]
impl Protocol {
    /// Every pair of electrodes driven and measured across itself (the paper's board: 120 values
    /// for 16 electrodes).
    #[staticmethod]
    fn two_terminal(#[pyo3(from_py_with = arguments::electrodes)] electrodes: usize) -> PyResult<Protocol> {
        eitskin::Protocol::two_terminal(electrodes).map(Protocol).map_err(error)
    }

    /// Adjacent drive, adjacent measurement (pyEIT's `dist_exc=1, step_meas=1`); `skip_driven`
    /// leaves out pairs that touch a driven electrode.
    #[staticmethod]
    #[pyo3(signature = (electrodes, skip_driven = true))]
    fn adjacent(
        #[pyo3(from_py_with = arguments::electrodes)] electrodes: usize,
        skip_driven: bool,
    ) -> PyResult<Protocol> {
        eitskin::Protocol::adjacent(electrodes, skip_driven).map(Protocol).map_err(error)
    }

    /// Opposite drive, adjacent measurement.
    #[staticmethod]
    fn opposite(#[pyo3(from_py_with = arguments::electrodes)] electrodes: usize) -> PyResult<Protocol> {
        eitskin::Protocol::opposite(electrodes).map(Protocol).map_err(error)
    }

    /// A protocol from arrays: `stimulations` (s, L) currents per electrode (A per unit, each row
    /// summing to 0), `measurement_weights` (m, L) (v = Σ w_l·u_l, each row summing to 0) and
    /// `measurement_stimulation` (m,) the 0-based stimulation each is taken under.
    #[staticmethod]
    #[pyo3(signature = (stimulations, measurement_weights, measurement_stimulation, description = "custom"))]
    fn from_arrays(
        stimulations: &Bound<'_, PyAny>,
        measurement_weights: &Bound<'_, PyAny>,
        measurement_stimulation: &Bound<'_, PyAny>,
        description: &str,
    ) -> PyResult<Protocol> {
        let stimulations = matrix(stimulations, "stimulations")?;
        let weights = matrix(measurement_weights, "measurement_weights")?;
        let index = crate::vector(measurement_stimulation, "measurement_stimulation")?;
        let index = indices(index.as_slice()?, "measurement_stimulation", 0)?;
        if index.len() != weights.len() {
            return Err(fail(format!(
                "measurement_stimulation has {} entries, measurement_weights {} rows",
                index.len(),
                weights.len()
            )));
        }
        let electrodes = stimulations.first().map_or(0, Vec::len);
        let measurements = weights
            .into_iter()
            .zip(index)
            .map(|(weights, stimulation)| eitskin::Measurement { stimulation, weights })
            .collect();
        eitskin::Protocol::new(description, electrodes, stimulations, measurements).map(Protocol).map_err(error)
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

/// The forward model: voltages from conductivity (linear finite elements).
///
/// Parameters
/// ----------
/// mesh : Mesh
///     Nodes in m, triangles, and the nodes each electrode covers.
/// protocol : Protocol
///     Stimulation and measurement patterns; its electrode count must be the mesh's.
/// electrodes : {"point", "complete"}, default "point"
///     Point electrodes (pyEIT's model) or the complete electrode model (EIDORS').
/// contact_impedance : float or array_like, optional
///     For "complete": one value, or one per electrode, in Ω·m².
/// thickness : float, default 1.0
///     Sheet thickness in m (voltages scale as 1/thickness).
///
/// Examples
/// --------
/// >>> spec = SensorSpec.square_hydrogel()
/// >>> model = spec.forward_model()
/// >>> model.measure(spec.conductivity).shape
/// (120,)
#[pyclass(module = "eitskin", frozen)]
#[derive(Clone)]
pub(crate) struct ForwardModel(pub(crate) eitskin::ForwardModel);

impl ForwardModel {
    /// One conductivity per triangle from a scalar or an array-like.
    fn conductivity(&self, conductivity: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
        let n = self.0.mesh().triangles().len();
        if let Ok(value) = conductivity.extract::<f64>() {
            return Ok(vec![value; n]);
        }
        let values = floats(conductivity, "conductivity")?;
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
        #[pyo3(from_py_with = arguments::thickness)] thickness: f64,
    ) -> PyResult<ForwardModel> {
        let model = match electrodes {
            "point" => eitskin::ElectrodeModel::Point,
            "complete" => {
                let count = mesh.0.electrodes().len();
                let z = match contact_impedance {
                    None => return Err(fail("the complete electrode model needs contact_impedance (Ω·m²)")),
                    Some(z) => match z.extract::<f64>() {
                        Ok(z) => vec![z; count],
                        Err(_) => floats(z, "contact_impedance")?,
                    },
                };
                eitskin::ElectrodeModel::Complete { contact_impedance: z }
            }
            other => return Err(fail(format!("electrodes must be \"point\" or \"complete\", got {other:?}"))),
        };
        eitskin::ForwardModel::new(mesh.0.clone(), model, thickness, protocol.0.clone())
            .map(ForwardModel)
            .map_err(error)
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
        let v = py.detach(|| model.measure(&sigma)).map_err(error)?;
        Ok(v.into_pyarray(py))
    }

    /// The Jacobian ∂v_m/∂σ_t at `conductivity`, (measurements, triangles), V per S/m
    /// (pyEIT's J is its negative).
    fn jacobian<'py>(&self, py: Python<'py>, conductivity: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let sigma = self.conductivity(conductivity)?;
        let model = &self.0;
        let j = py.detach(|| model.solve(&sigma).map(|s| model.jacobian(&s))).map_err(error)?;
        Ok(Array2::from_shape_fn((j.nrows(), j.ncols()), |(m, t)| j[(m, t)]).into_pyarray(py))
    }

    fn __repr__(&self) -> String {
        format!("ForwardModel({} triangles, {} measurements)", self.0.mesh().triangles().len(), self.0.protocol().len())
    }
}
