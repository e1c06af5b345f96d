//! The real-time frame path: reference, drift compensation, then the [`Chain`] (image,
//! touches, fitted presses, forces) on every frame.
//!
//! The reference (no-touch) frame is the mean of the first N frames (and again after
//! [`Pipeline::retake_reference`]). While referencing, the pipeline also measures its own noise:
//! the peak of each reference frame's image against the mean; with [`NoiseFloor::Auto`] a touch
//! needs a peak above a multiple of that. An optional slow baseline update, while no touch is
//! present, follows drift: v_ref ← (1 − α)·v_ref + α·v. Each later frame goes through the
//! chain against the reference.
//!
//! Plain data and no threads or I/O: the caller feeds frames (from a port, a file, the virtual
//! sensor) and reads the results. After the reference is taken, [`Pipeline::process`]
//! allocates nothing.

use crate::chain::Chain;
pub use crate::chain::TouchForce;
use crate::image::Image;
use crate::inverse::InverseError;
use crate::pseudo_array::PseudoArray;

/// How touches are told from noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NoiseFloor {
    /// A touch needs a peak above `factor` × the largest peak of the reference frames' own images.
    Auto {
        /// Multiple of the measured noise peak (dimensionless).
        factor: f64,
    },
    /// A touch needs a peak above this, in S/m.
    Fixed(f64),
}

/// Settings of the frame path; `Default` takes the mean of 10 frames and no baseline update.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PipelineParams {
    /// Frames averaged into the reference.
    pub reference_frames: usize,
    /// Baseline update weight α per frame without a touch (0 = off), dimensionless.
    pub baseline_rate: f64,
    /// How touches are told from noise (on top of the chain's own [`TouchParams::min_peak`](crate::TouchParams::min_peak)).
    pub noise_floor: NoiseFloor,
}

impl Default for PipelineParams {
    fn default() -> Self {
        PipelineParams { reference_frames: 10, baseline_rate: 0.0, noise_floor: NoiseFloor::Auto { factor: 2.0 } }
    }
}

/// What [`Pipeline::process`] did with a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// The frame went into the reference; `collected` of `needed` so far.
    Referencing {
        /// Frames collected.
        collected: usize,
        /// Frames needed.
        needed: usize,
    },
    /// The frame was imaged; its touches are in [`Pipeline::touches`].
    Processed,
}

/// The frame path of one sensor: the [`Chain`], its reference and the noise it measured.
#[derive(Debug, Clone)]
pub struct Pipeline {
    chain: Chain,
    params: PipelineParams,
    /// The chain's own minimum peak, under the noise floor (S/m).
    min_peak: f64,
    reference: Vec<f64>,
    collected: Vec<Vec<f64>>,
    noise_peak: f64,
}

impl Pipeline {
    /// A pipeline running `chain` that starts by taking its reference.
    pub fn new(chain: Chain, params: PipelineParams) -> Pipeline {
        Pipeline {
            min_peak: chain.touch_params().min_peak,
            chain,
            params,
            reference: Vec::new(),
            collected: Vec::with_capacity(params.reference_frames.max(1)),
            noise_peak: 0.0,
        }
    }

    /// Forgets the reference; the next frames build a new one.
    pub fn retake_reference(&mut self) {
        self.reference.clear();
        self.collected.clear();
    }

    /// The reference frame, once taken.
    pub fn reference(&self) -> Option<&[f64]> {
        (!self.reference.is_empty()).then_some(self.reference.as_slice())
    }

    /// The largest peak of the reference frames' own images, in S/m: the noise the floor is set from.
    pub fn noise_peak(&self) -> f64 {
        self.noise_peak
    }

    /// The chain it runs.
    pub fn chain(&self) -> &Chain {
        &self.chain
    }

    /// The image of the last processed frame (Δσ, S/m).
    pub fn image(&self) -> &Image {
        self.chain.image()
    }

    /// The touches of the last processed frame, strongest first (none while referencing).
    pub fn touches(&self) -> &[TouchForce] {
        if self.reference.is_empty() {
            &[]
        } else {
            self.chain.touches()
        }
    }

    /// The pseudo-array of the calibration, if one was given.
    pub fn pseudo_array(&self) -> Option<&PseudoArray> {
        self.chain.pseudo_array()
    }

    /// Feeds one frame (protocol order); a bad frame (wrong length, NaN) is refused and changes nothing.
    pub fn process(&mut self, frame: &[f64]) -> Result<Status, InverseError> {
        let needed = self.params.reference_frames.max(1);
        if self.reference.is_empty() {
            // Check the frame as the reconstructor will, before it joins the reference.
            self.chain.image_only(frame, frame)?;
            self.collected.push(frame.to_vec());
            if self.collected.len() < needed {
                return Ok(Status::Referencing { collected: self.collected.len(), needed });
            }
            self.take_reference();
            return Ok(Status::Referencing { collected: needed, needed });
        }
        let touched = !self.chain.process(&self.reference, frame)?.is_empty();
        let alpha = self.params.baseline_rate;
        if alpha > 0.0 && !touched {
            for (r, v) in self.reference.iter_mut().zip(frame) {
                *r += alpha * (v - *r);
            }
        }
        Ok(Status::Processed)
    }

    fn take_reference(&mut self) {
        let n = self.collected.len() as f64;
        self.reference = vec![0.0; self.collected[0].len()];
        for frame in &self.collected {
            for (r, v) in self.reference.iter_mut().zip(frame) {
                *r += v / n;
            }
        }
        self.noise_peak = 0.0;
        for frame in &self.collected {
            // Frames were checked when collected, so imaging them cannot fail.
            if let Ok(image) = self.chain.image_only(&self.reference, frame) {
                let peak = image.peak().map_or(0.0, |(_, v)| f64::from(v.abs()));
                self.noise_peak = self.noise_peak.max(peak);
            }
        }
        let floor = match self.params.noise_floor {
            NoiseFloor::Auto { factor } => factor * self.noise_peak,
            NoiseFloor::Fixed(value) => value,
        };
        self.chain.set_min_peak(self.min_peak.max(floor));
        self.collected.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::{Calibration, Strength};
    use crate::press_fit::PressModel;
    use crate::sim::VirtualSensor;
    use crate::{Reconstructor, ReconstructorParams, SensorSpec};

    fn setup() -> (Pipeline, VirtualSensor) {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 800;
        let recon = Reconstructor::new(&spec.forward_model().unwrap(), 1.0, &ReconstructorParams::default()).unwrap();
        let chain = Chain::new(recon, crate::TouchParams::default());
        (Pipeline::new(chain, PipelineParams::default()), VirtualSensor::new(&spec, 3).unwrap())
    }

    #[test]
    fn reference_then_touches_then_none_after_release() {
        let (mut pipeline, mut skin) = setup();
        for k in 1..=10 {
            let status = pipeline.process(&skin.frame().unwrap()).unwrap();
            assert_eq!(status, Status::Referencing { collected: k, needed: 10 });
        }
        assert!(pipeline.reference().is_some() && pipeline.noise_peak() > 0.0);
        assert_eq!(pipeline.process(&skin.frame().unwrap()).unwrap(), Status::Processed);
        assert!(pipeline.touches().is_empty(), "noise alone is no touch: {:?}", pipeline.touches());
        skin.press([0.04, -0.03], 10.0);
        pipeline.process(&skin.frame().unwrap()).unwrap();
        assert_eq!(pipeline.touches().len(), 1);
        let c = pipeline.touches()[0].touch.centre;
        assert!((c[0] - 0.04).hypot(c[1] + 0.03) < 0.015, "{c:?}");
        skin.release();
        pipeline.process(&skin.frame().unwrap()).unwrap();
        assert!(pipeline.touches().is_empty());
    }

    #[test]
    fn a_fitted_drop_calibration_gives_the_force_through_the_gels_own_law() {
        use crate::press_fit::PressModelParams;
        use crate::sim::Hydrogel;
        let spec = SensorSpec::square_hydrogel();
        let model = spec.forward_model().unwrap();
        let recon = Reconstructor::new(&model, 1.0, &ReconstructorParams::default()).unwrap();
        let press_model = PressModel::new(&model, 1.0, &PressModelParams::default()).unwrap();
        // One area for the whole sheet, its curve the virtual gel's law drop = 0.9·(1 − e^(−F/5.54 N)),
        // written down rather than fitted: the fitted drop must be the physical one.
        let array = PseudoArray::by_symmetry(&spec.outline, &spec.electrode_positions().unwrap(), [1, 1]).unwrap();
        let gel = Hydrogel::default().drop_curve(16.0);
        let calibration = Calibration { curves: vec![gel], strength: Strength::FittedDrop };
        let chain = Chain::new(recon, crate::TouchParams::default())
            .with_press_model(press_model)
            .with_calibration(array, calibration)
            .unwrap();
        let mut pipeline = Pipeline::new(chain, PipelineParams::default());
        let mut skin = VirtualSensor::new(&spec, 5).unwrap();
        for _ in 0..10 {
            pipeline.process(&skin.frame().unwrap()).unwrap();
        }
        for (at, force) in [([0.02, -0.03], 5.0), ([-0.05, 0.04], 9.0)] {
            skin.release();
            skin.press(at, force);
            pipeline.process(&skin.frame().unwrap()).unwrap();
            let found = pipeline.touches()[0];
            let press = found.press.unwrap();
            assert!((press.centre[0] - at[0]).hypot(press.centre[1] - at[1]) < 3e-3, "{at:?}: {press:?}");
            let drop = Hydrogel::default().drop(force);
            assert!((press.drop - drop).abs() < 0.03, "{at:?}: drop {} for {drop}", press.drop);
            // Near saturation a small drop error is a larger force error (dF/dd = 5.54 N/(0.9 − d)).
            let newtons = found.force.unwrap().newtons;
            assert!((newtons - force).abs() < 0.1 * force, "{at:?}: {newtons} N for {force} N");
            assert_eq!((found.unit, found.area), (Some(0), Some(0)));
        }
    }

    #[test]
    fn a_bad_frame_is_refused_and_changes_nothing() {
        let (mut pipeline, mut skin) = setup();
        let err = pipeline.process(&[1.0; 119]).unwrap_err();
        assert_eq!(err, InverseError::FrameLength { expected: 120, got: 119 });
        let mut nan = skin.frame().unwrap();
        nan[3] = f64::NAN;
        assert!(pipeline.process(&nan).is_err());
        assert_eq!(pipeline.process(&skin.frame().unwrap()).unwrap(), Status::Referencing { collected: 1, needed: 10 });
    }

    #[test]
    fn baseline_update_follows_drift_without_touches() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 800;
        let recon = Reconstructor::new(&spec.forward_model().unwrap(), 1.0, &ReconstructorParams::default()).unwrap();
        let params = PipelineParams { reference_frames: 3, baseline_rate: 0.5, noise_floor: NoiseFloor::Fixed(0.01) };
        let mut pipeline = Pipeline::new(Chain::new(recon, crate::TouchParams::default()), params);
        let sim = crate::sim::SimParams { drift_per_hour: 0.05, noise_relative: 0.0, ..Default::default() };
        let mut skin = VirtualSensor::with_params(&spec, sim, 1).unwrap();
        for _ in 0..3 {
            pipeline.process(&skin.frame().unwrap()).unwrap();
        }
        for _ in 0..20 {
            skin.advance(60.0);
            pipeline.process(&skin.frame().unwrap()).unwrap();
        }
        let now = skin.clean_frame().unwrap();
        let lag = pipeline.reference().unwrap().iter().zip(&now).map(|(r, v)| ((r - v) / v).abs()).fold(0.0, f64::max);
        // With α = 0.5 an exponential filter trails a ramp by one step: 0.05/60 ≈ 8.3e-4 per minute,
        // against 1.7e-2 of drift over the 20 minutes without the update.
        assert!(lag < 1.2e-3, "the reference lags the drift by {lag:e}");
    }
}
