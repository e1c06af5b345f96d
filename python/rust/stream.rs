//! Frames over time: the virtual sensor, a board's or a file's frames, the pipeline and the
//! force calibration.

use numpy::{IntoPyArray, PyArray1};
use pyo3::prelude::*;

use crate::arguments;
use crate::model::SensorSpec;
use crate::{error, fail};

/// The virtual sensor: the spec's sheet simulated on a finer mesh, pressed, with noise.
///
/// Parameters
/// ----------
/// spec : SensorSpec
///     The sensor to simulate (its outline, electrodes, protocol and gel).
/// seed : int, default 0
///     Seed of the measurement noise (0.01 % of each value, relative), 0 to 2⁶⁴ − 1.
#[pyclass(module = "eitskin")]
pub(crate) struct VirtualSensor(pub(crate) eitskin::sim::VirtualSensor, eitskin::Outline);

#[pymethods]
impl VirtualSensor {
    /// The sensor of `spec`, its noise seeded by `seed`.
    #[new]
    #[pyo3(signature = (spec, seed = 0))]
    fn new(
        py: Python<'_>,
        spec: &SensorSpec,
        #[pyo3(from_py_with = arguments::seed)] seed: u64,
    ) -> PyResult<VirtualSensor> {
        let spec = &spec.0;
        let sensor = py.detach(|| eitskin::sim::VirtualSensor::new(spec, seed)).map_err(error)?;
        Ok(VirtualSensor(sensor, spec.outline.clone()))
    }

    /// Adds a press at (x, y) m from the outline's centre with `force` N; a press off the sheet is refused.
    fn press(
        &mut self,
        #[pyo3(from_py_with = arguments::x)] x: f64,
        #[pyo3(from_py_with = arguments::y)] y: f64,
        #[pyo3(from_py_with = arguments::force)] force: f64,
    ) -> PyResult<()> {
        if !self.1.contains([x, y]) {
            let [[x0, y0], [x1, y1]] = self.1.bounds();
            return Err(fail(format!(
                "a press at ({x}, {y}) m is off the sheet (its outline spans {x0}–{x1} m by {y0}–{y1} m, from its centre): it would change nothing"
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
        Ok(py.detach(|| sensor.frame()).map_err(error)?.into_pyarray(py))
    }

    /// The noise-free frame now (V at 1 A, protocol order).
    fn clean_frame<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let sensor = &self.0;
        Ok(py.detach(|| sensor.clean_frame()).map_err(error)?.into_pyarray(py))
    }
}

/// One frame from a source: its sequence number, its time (s) and its values (protocol order).
#[pyclass(module = "eitskin", frozen, get_all)]
pub(crate) struct Frame {
    /// The board's counter, the line count, or as recorded.
    seq: u64,
    /// When it came, in s (the source's clock).
    t: f64,
    /// The measurements, (measurements,), in protocol order (V or Ω, as the board sends).
    values: Py<PyArray1<f64>>,
}

#[pymethods]
impl Frame {
    fn __repr__(&self, py: Python<'_>) -> String {
        format!(
            "Frame(seq={}, t={:.4} s, {} values)",
            self.seq,
            self.t,
            numpy::PyUntypedArrayMethods::len(self.values.bind(py))
        )
    }
}

/// Anything else a source yields: "bad" input the codec refused, a "skipped" damaged record,
/// the port "disconnected" or "reconnected"; `message` says what and where.
#[pyclass(module = "eitskin", frozen, get_all)]
pub(crate) struct Event {
    /// "bad", "skipped", "disconnected" or "reconnected".
    kind: String,
    /// What happened, in words.
    message: String,
}

#[pymethods]
impl Event {
    fn __repr__(&self) -> String {
        format!("Event({:?}, {:?})", self.kind, self.message)
    }
}

/// Frames from a board, a file or the virtual sensor, as an iterator of `Frame` and `Event`.
///
/// Parameters
/// ----------
/// source : str
///     "serial:/dev/ttyACM0[@BAUD]", "file:PATH" (a recording, or one frame per text line),
///     "sim" (random presses) or "sim:SCRIPT".
/// spec : SensorSpec
///     The sensor whose frames these are (their length is its protocol's).
/// rate : float, default 20.0
///     Frames/s of the virtual sensor's clock and of a capture file's pace, 0 to 100,000.
/// fast : bool, default False
///     As fast as possible instead of in real time (a serial port keeps the board's pace).
/// frames : int, optional
///     Stop after this many frames, 1 to 10¹².
/// codec : {"lines", "binary"}, default "lines"
///     How a port's or a capture's bytes encode frames.
/// seed : int, default 1
///     The virtual sensor's seed, 0 to 2⁶⁴ − 1.
/// values_per_measurement : {1, 2}, default 1
///     2 for boards sending complex (re, im) pairs.
/// noise : float, default 1e-4
///     The virtual sensor's noise, a relative standard deviation per value in [0, 0.1] (1e-4 is
///     a best case; open boards vary 0.003–0.005).
///
/// Bad input never ends the stream: it comes as an `Event` ("bad", "skipped", "disconnected",
/// "reconnected") between frames, and the source goes on.
#[pyclass(module = "eitskin")]
pub(crate) struct Source(std::sync::Mutex<eitskin_io::source::Source>);

#[pymethods]
impl Source {
    /// Opens `source`: "serial:/dev/ttyACM0[@BAUD]", "file:PATH" (a recording or a capture of
    /// one frame per text line), "sim" or "sim:SCRIPT", for `spec`'s frames. `rate` is frames/s
    /// (the virtual sensor's clock, a capture's pace), `fast` skips the pacing, `frames` stops
    /// after that many, `codec` is "lines" or "binary", `values_per_measurement` 1 or 2 (complex).
    #[new]
    #[allow(clippy::too_many_arguments, reason = "Python's keyword arguments, one per setting")]
    #[pyo3(signature = (source, spec, rate = 20.0, fast = false, frames = None, codec = "lines", seed = 1, values_per_measurement = 1, noise = 1e-4))]
    fn new(
        py: Python<'_>,
        source: &str,
        spec: &SensorSpec,
        #[pyo3(from_py_with = arguments::rate)] rate: f64,
        fast: bool,
        #[pyo3(from_py_with = arguments::frames)] frames: Option<u64>,
        codec: &str,
        #[pyo3(from_py_with = arguments::seed)] seed: u64,
        #[pyo3(from_py_with = arguments::values_per_measurement)] values_per_measurement: usize,
        #[pyo3(from_py_with = arguments::noise)] noise: f64,
    ) -> PyResult<Source> {
        use eitskin_io::replay::Speed;
        use eitskin_io::source::{Codec, SourceSettings, SourceSpec};
        let which: SourceSpec = source.parse().map_err(error)?;
        let settings = SourceSettings {
            rate,
            speed: if fast { Speed::AsFastAsPossible } else { Speed::Recorded },
            frames,
            codec: codec.parse::<Codec>().map_err(fail)?,
            seed,
            values_per_measurement,
            noise,
        };
        let spec = &spec.0;
        py.detach(|| eitskin_io::source::Source::open(&which, spec, &settings))
            .map(|s| Source(std::sync::Mutex::new(s)))
            .map_err(error)
    }

    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    /// The next `Frame` or `Event`; waits (without the GIL) until it is due.
    fn __next__(&mut self, py: Python<'_>) -> PyResult<Option<Py<PyAny>>> {
        use eitskin_io::source::Acquired;
        let source = self.0.get_mut().unwrap_or_else(std::sync::PoisonError::into_inner);
        let item = match py.detach(|| source.next()) {
            None => return Ok(None),
            Some(item) => item.map_err(error)?,
        };
        let event = |kind: &str, message: String| Event { kind: kind.into(), message };
        Ok(Some(match item {
            Acquired::Frame { seq, t, values } => {
                Py::new(py, Frame { seq, t, values: values.into_pyarray(py).unbind() })?.into_any()
            }
            Acquired::Bad(bad) => Py::new(py, event("bad", bad.to_string()))?.into_any(),
            Acquired::Skipped { record, torn_tail } => {
                let tail = if torn_tail { " (the file's torn last record)" } else { "" };
                Py::new(py, event("skipped", format!("line {}: {}{tail}", record.line, record.damage)))?.into_any()
            }
            Acquired::Disconnected { path, error } => {
                Py::new(py, event("disconnected", format!("{}: {error}", path.display())))?.into_any()
            }
            Acquired::Reconnected { path, outage } => Py::new(
                py,
                event("reconnected", format!("{} is back after {:.1} s", path.display(), outage.as_secs_f64())),
            )?
            .into_any(),
            Acquired::Silent { source, after } => {
                Py::new(py, event("silent", format!("{source}: no frame for {:.1} s", after.as_secs_f64())))?.into_any()
            }
            Acquired::Resumed { source, outage } => {
                Py::new(py, event("resumed", format!("{source}: frames again after {:.1} s", outage.as_secs_f64())))?
                    .into_any()
            }
        }))
    }

    /// Frames delivered so far.
    #[getter]
    fn frames(&self) -> u64 {
        self.0.lock().unwrap_or_else(std::sync::PoisonError::into_inner).frames()
    }
}

/// Areas counted from 1, one per sample (any whole numbers: a list, an array, floats that are
/// whole), as 0-based indices, each in 1..=`count`.
fn areas(obj: &Bound<'_, PyAny>, count: usize) -> PyResult<Vec<usize>> {
    let values = crate::floats(obj, "area")?;
    let area = |(k, &v): (usize, &f64)| match v {
        v if v.fract() == 0.0 && v >= 1.0 && v <= count as f64 => Ok(v as usize - 1),
        v => Err(fail(format!(
            "area of sample {} must be 1 to {count} (areas are counted from 1), got {}",
            k + 1,
            crate::quoted(v)
        ))),
    };
    values.iter().enumerate().map(area).collect()
}

/// Samples of forces (N) and strengths, each force in [0, `MAX_FORCE`] as a samples file's,
/// each strength finite.
fn samples(force: &Bound<'_, PyAny>, strength: &Bound<'_, PyAny>) -> PyResult<(Vec<f64>, Vec<f64>)> {
    let (force, strength) = (crate::floats(force, "force")?, crate::floats(strength, "strength")?);
    if let Some(k) = force.iter().position(|f| !arguments::force_ok(*f)) {
        let max = eitskin::calibration::MAX_FORCE;
        let given = crate::quoted(force[k]);
        return Err(fail(format!("force of sample {} is {given} N: a press's force is 0 to {max:e} N", k + 1)));
    }
    if let Some(k) = strength.iter().position(|s| !s.is_finite()) {
        let given = crate::quoted(strength[k]);
        return Err(fail(format!("strength of sample {} is {given}: every strength must be a finite number", k + 1)));
    }
    Ok((force, strength))
}

/// A force calibration: the pseudo-array's areas, one curve σ(F) = a·e^(−F/b) + c each (or
/// a·(1 + F/(k·b))^(−k) + c where the samples approach c more slowly than an exponential can).
///
/// Made with `Calibration.fit(spec, area, force, strength)` from samples or read with
/// `Calibration.load(path, spec)` (files of `eitskin calibrate`); `force(area, strength)` gives
/// newtons.
#[pyclass(module = "eitskin", frozen)]
pub(crate) struct Calibration {
    spec: eitskin::SensorSpec,
    file: eitskin_io::CalibrationFile,
}

#[pymethods]
impl Calibration {
    /// Fits one curve per area of the spec's pseudo-array (`grid` units, grouped by symmetry)
    /// from samples: `area` (from 1, as the paper, the CLI and the files count), `force` (0 to 1e5 N) and `strength` (the image's peak, S/m,
    /// for strength "peak"), one entry per sample; every area needs ≥ 3 distinct forces.
    #[staticmethod]
    #[pyo3(signature = (spec, area, force, strength, grid = [5, 5]))]
    fn fit(
        spec: &SensorSpec,
        area: &Bound<'_, PyAny>,
        force: &Bound<'_, PyAny>,
        strength: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = arguments::grid)] grid: [usize; 2],
    ) -> PyResult<Calibration> {
        let spec = spec.0.clone();
        let array = eitskin::pseudo_array::PseudoArray::of_sensor(&spec, grid).map_err(error)?;
        let area = areas(area, array.area_count())?;
        let (force, strength) = samples(force, strength)?;
        if force.len() != area.len() || strength.len() != area.len() {
            return Err(fail(format!(
                "area, force and strength need one entry per sample, got {}, {} and {}",
                area.len(),
                force.len(),
                strength.len()
            )));
        }
        let samples: Vec<eitskin::calibration::Sample> = (0..area.len())
            .map(|k| eitskin::calibration::Sample {
                area: area[k],
                force: force[k],
                peak: strength[k],
                std: None,
                place: None,
            })
            .collect();
        let calibration = eitskin::calibration::Calibration::fit(&samples, array.area_count()).map_err(error)?;
        let imaging = eitskin_io::Imaging::default();
        Ok(Calibration { spec, file: eitskin_io::CalibrationFile { array, calibration, imaging } })
    }

    /// The area (from 1) of the pseudo-array unit under (x, y) m, for `spec`'s array of `grid`
    /// units grouped by symmetry (the paper's 5 × 5 has 6 areas), or None off the array.
    #[staticmethod]
    #[pyo3(signature = (spec, x, y, grid = [5, 5]))]
    fn area_of(
        spec: &SensorSpec,
        #[pyo3(from_py_with = arguments::x)] x: f64,
        #[pyo3(from_py_with = arguments::y)] y: f64,
        #[pyo3(from_py_with = arguments::grid)] grid: [usize; 2],
    ) -> PyResult<Option<usize>> {
        let array = eitskin::pseudo_array::PseudoArray::of_sensor(&spec.0, grid).map_err(error)?;
        Ok(array.unit_at([x, y]).map(|u| array.area_of(u) + 1))
    }

    /// Reads a calibration file made for `spec` (by `eitskin calibrate` or `save`).
    #[staticmethod]
    fn load(path: std::path::PathBuf, spec: &SensorSpec) -> PyResult<Calibration> {
        let file = eitskin_io::read_calibration_file(&path, &spec.0).map_err(error)?;
        Ok(Calibration { spec: spec.0.clone(), file })
    }

    /// Writes it as JSON (the calibration file `eitskin run --calibration` reads), to a name ending
    /// in `.json` or in no format's extension.
    fn save(&self, path: std::path::PathBuf) -> PyResult<()> {
        crate::check_output_name(&path, &["json"])?;
        let f = &self.file;
        let text =
            eitskin_io::calibration_file_to_json(&self.spec, &f.array, &f.calibration, f.imaging).map_err(error)?;
        std::fs::write(&path, text).map_err(|e| fail(format!("cannot write {}: {e}", path.display())))
    }

    /// Number of areas.
    #[getter]
    fn areas(&self) -> usize {
        self.file.array.area_count()
    }

    /// The area (from 1) of the unit under (x, y) m, or None off the array.
    fn area_at(
        &self,
        #[pyo3(from_py_with = arguments::x)] x: f64,
        #[pyo3(from_py_with = arguments::y)] y: f64,
    ) -> Option<usize> {
        self.file.array.unit_at([x, y]).map(|u| self.file.array.area_of(u) + 1)
    }

    /// The force (N) for a touch of `strength` in `area` (from 1), and whether it is past the
    /// curve's range (saturated).
    fn force(
        &self,
        area: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = arguments::strength)] strength: f64,
    ) -> PyResult<(f64, bool)> {
        let areas = self.file.array.area_count();
        let area = arguments::whole::<usize>(area, "area", 1..=areas as i128)? - 1;
        let estimate = self.file.calibration.force(area, strength).map_err(error)?;
        Ok((estimate.newtons, estimate.saturated))
    }
}

/// A touch with what the pipeline read of it: where (m), how strong, and its force (N) when
/// calibrated.
#[pyclass(module = "eitskin", frozen, get_all)]
pub(crate) struct TouchForce {
    /// Centre of gravity, (x, y) in m.
    centre: (f64, f64),
    /// Largest change inside the touch, S/m.
    peak: f64,
    /// Area above the threshold, m².
    area: f64,
    /// The z of its peak against the measured noise, when the noise is known.
    significance: Option<f64>,
    /// The pseudo-array unit it falls in (from 1, row-major from the bottom-left), when calibrated.
    unit: Option<usize>,
    /// That unit's calibration area (from 1), when calibrated.
    calibration_area: Option<usize>,
    /// Its force in N, when calibrated.
    force: Option<f64>,
    /// The force's standard deviation from the noise in N, when calibrated and fitting presses.
    force_std: Option<f64>,
    /// The fitted press's centre, (x, y) in m, when the pipeline fits presses.
    press_centre: Option<(f64, f64)>,
}

#[pymethods]
impl TouchForce {
    fn __repr__(&self) -> String {
        let spread = self.force_std.map_or(String::new(), |s| format!(" ± {s:.2}"));
        let force = self.force.map_or(String::new(), |f| format!(", force={f:.2}{spread} N"));
        format!("TouchForce(centre=({:.4}, {:.4}) m, peak={:.4} S/m{force})", self.centre.0, self.centre.1, self.peak)
    }
}

/// The frame path: a reference from the first frames, then per frame the image, the touches
/// tested against the measured noise, and each touch's force when calibrated.
///
/// Parameters
/// ----------
/// spec : SensorSpec
///     The sensor.
/// calibration : Calibration, optional
///     Turns each touch's strength into newtons (and sets λ and the normalisation it was fitted with).
/// fit : bool, default False
///     Fit a press (centre, conductivity drop) to each touch.
/// reference_frames : int, default 10
///     Frames averaged into the reference, 1 to 10,000.
/// reference_limit : int, default 100
///     Frames the reference grows to, 1 to 1,000,000: each later frame without a touch joins its
///     mean until it holds this many (its noise is in every Δv).
/// false_alarm_rate : float, default 1e-3
///     False touches per no-touch frame that the noise test allows, in (0, 0.5].
/// average : int, default 1
///     Frames averaged into each image, 1 to 1,000 (adds (average − 1)/2 frames of latency).
/// hyperparameter : float or "auto", default "auto"
///     λ in [1e-6, 1000], or "auto": chosen from the reference frames' noise as ``eitskin run``
///     chooses it; a calibration sets its own (another value is refused).
///
/// Examples
/// --------
/// >>> spec = SensorSpec.square_hydrogel().with_triangles(1000)
/// >>> sensor, pipeline = VirtualSensor(spec, seed=1), Pipeline(spec)
/// >>> [pipeline.process(sensor.frame()) for _ in range(10)][-1]
/// 'referencing'
/// >>> sensor.press(0.05, 0.0, 10.0)
/// >>> pipeline.process(sensor.frame()), len(pipeline.touches)
/// ('processed', 1)
#[pyclass(module = "eitskin")]
pub(crate) struct Pipeline(eitskin::pipeline::Pipeline);

#[pymethods]
impl Pipeline {
    /// The pipeline of `spec`: `calibration` turns touches into forces; `fit` fits a press to
    /// each touch (as ``eitskin run`` does: each exact fit started from one press's tabulated
    /// response, built here); `reference_frames` (1–10,000) are averaged into the reference, which grows
    /// to `reference_limit` (1–1,000,000) on frames without a touch;
    /// `false_alarm_rate` (false touches per no-touch frame, in (0, 0.5]); `average` frames
    /// (1–1,000) per image; `hyperparameter` λ or "auto" (from the reference frames' noise).
    #[new]
    #[allow(clippy::too_many_arguments, reason = "Python's keyword arguments, one per setting")]
    #[pyo3(signature = (spec, calibration = None, fit = false, reference_frames = 10, false_alarm_rate = 1e-3, average = 1, hyperparameter = None, reference_limit = 100))]
    fn new(
        py: Python<'_>,
        spec: &SensorSpec,
        calibration: Option<&Calibration>,
        fit: bool,
        #[pyo3(from_py_with = arguments::reference_frames)] reference_frames: usize,
        #[pyo3(from_py_with = arguments::false_alarm_rate)] false_alarm_rate: f64,
        #[pyo3(from_py_with = arguments::average)] average: usize,
        hyperparameter: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = arguments::reference_limit)] reference_limit: usize,
    ) -> PyResult<Pipeline> {
        use eitskin::inverse::{Hyperparameter, HyperparameterRule};
        use eitskin::pipeline::{NoiseFloor, PipelineParams};
        use eitskin_io::build::ChainSetup;
        let spec = &spec.0;
        if let Some(c) = calibration {
            let key = |s: &eitskin::SensorSpec| eitskin_io::spec_key(s).map_err(error);
            if key(&c.spec)? != key(spec)? {
                return Err(fail(
                    "the calibration was made for another sensor spec than the pipeline's; calibrate this sensor",
                ));
            }
        }
        // λ as `eitskin run` sets it: the calibration's (a different one refused), else given,
        // else chosen from the reference frames' noise once they are in.
        let rule = hyperparameter.map(crate::imaging::rule).transpose()?;
        let hyperparameter = match (rule, calibration) {
            (None, None) => Hyperparameter::Auto,
            (Some(HyperparameterRule::Model(h)), None) => h,
            (Some(HyperparameterRule::Data(c)), _) => {
                let name = c.name();
                return Err(fail(format!("hyperparameter: a pipeline takes \"auto\" or a number, not {name}")));
            }
            (given, Some(c)) => {
                let lambda = c.file.imaging.hyperparameter;
                if given.is_some_and(|g| g != HyperparameterRule::Model(Hyperparameter::Fixed(lambda))) {
                    return Err(fail(format!(
                        "hyperparameter: the calibration was fitted on images made with λ = {lambda}, and its forces \
                         hold only for those; leave hyperparameter out (or give {lambda}), or calibrate again"
                    )));
                }
                Hyperparameter::Fixed(lambda)
            }
        };
        let params = PipelineParams {
            reference_frames,
            reference_limit,
            noise_floor: NoiseFloor::FalseAlarm { rate: false_alarm_rate },
            average,
            auto_hyperparameter: hyperparameter == Hyperparameter::Auto,
            ..PipelineParams::default()
        };
        let recon = eitskin::ReconstructorParams {
            hyperparameter: match hyperparameter {
                Hyperparameter::Fixed(value) => value,
                // Chosen once the reference frames are in; until then, the paper's.
                Hyperparameter::Auto => eitskin::ReconstructorParams::default().hyperparameter,
            },
            normalised: calibration.is_some_and(|c| c.file.imaging.normalised),
            ..eitskin::ReconstructorParams::default()
        };
        let calibration = calibration.map(|c| (c.file.array.clone(), c.file.calibration.clone()));
        let setup = ChainSetup { fit, calibration, ..ChainSetup::new(recon) };
        // The settings are checked before the chain is built (seconds, on a first run).
        let pipeline = py.detach(|| eitskin_io::build::pipeline(spec, setup, params));
        Ok(Pipeline(pipeline.map_err(|e| fail(crate::message(&e)))?))
    }

    /// Feeds one frame (V, protocol order): "referencing" while the reference is taken, then
    /// "processed", "channels dropped" or "noise updated".
    fn process(&mut self, py: Python<'_>, frame: &Bound<'_, PyAny>) -> PyResult<String> {
        use eitskin::pipeline::Status;
        let frame = crate::vector(frame, "frame")?;
        let frame = frame.as_slice()?;
        let pipeline = &mut self.0;
        let status = py.detach(|| pipeline.process(frame)).map_err(error)?;
        Ok(match status {
            Status::Referencing { .. } | Status::Deriving => "referencing",
            Status::Processed => "processed",
            Status::ChannelsDropped { .. } => "channels dropped",
            _ => "noise updated",
        }
        .into())
    }

    /// The last frame's touches, strongest first.
    #[getter]
    fn touches(&self) -> Vec<TouchForce> {
        self.0
            .touches()
            .iter()
            .map(|t| TouchForce {
                centre: (t.touch.centre[0], t.touch.centre[1]),
                peak: t.touch.peak,
                area: t.touch.area,
                significance: t.touch.significance,
                unit: t.unit.map(|u| u + 1),
                calibration_area: t.area.map(|a| a + 1),
                force: t.force.map(|f| f.newtons),
                force_std: t.force.and_then(|f| f.std),
                press_centre: t.press.map(|p| (p.centre[0], p.centre[1])),
            })
            .collect()
    }

    /// The last frame's image.
    #[getter]
    fn image(&self) -> crate::imaging::Image {
        crate::imaging::Image(self.0.image().clone())
    }

    /// Whether the reference has been taken.
    #[getter]
    fn has_reference(&self) -> bool {
        self.0.reference().is_some()
    }

    /// Forgets the reference; the next frames build a new one.
    fn retake_reference(&mut self) {
        self.0.retake_reference();
    }
}
