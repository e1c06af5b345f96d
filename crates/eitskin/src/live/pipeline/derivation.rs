//! What a pipeline derives from its reference and measured noise: λ and the channels' weights
//! (a new reconstructor), the noise test of touches ([`Significance`]) and the detection of
//! presses in Δv ([`PressDetection`]). Milliseconds to a fifth of a second of work, asked for
//! when the reference is taken and when the noise changes; a [`Derivation`] holds all it needs
//! (shared, not copied), so it can run on another thread while frames go on
//! ([`Pipeline::defer_derivations`](super::Pipeline::defer_derivations)).

use std::sync::Arc;

use crate::image::{Image, Polarity};
use crate::inverse::{Channels, InverseError, Reconstructor};
use crate::noise::{NoiseModel, Significance};
use crate::press_fit::{PressDetection, PressModel};

use super::{too_many_dropped, NoiseFloor, PipelineParams};

/// The reconstructor a derivation makes.
#[derive(Debug, Clone)]
pub(super) enum Rederive {
    /// The one the chain has.
    Keep,
    /// Derived for `channels`, λ chosen from their noise (`variance` relative, per channel;
    /// `None`: assumed), the channels weighted by it.
    Auto { channels: Channels, variance: Option<Vec<f64>> },
    /// Derived for `channels` at λ `hyperparameter`, unless the chain's already is that one.
    Fixed { hyperparameter: f64, channels: Channels },
}

/// Work a pipeline asks for: run it ([`Derivation::run`], on any thread) and hand the result
/// back ([`Pipeline::deliver`](super::Pipeline::deliver)).
#[derive(Debug, Clone)]
pub struct Derivation {
    pub(super) generation: u64,
    /// Whether it completes a reference just taken (frames are not imaged until it is in).
    pub(super) first: bool,
    pub(super) recon: Arc<Reconstructor>,
    pub(super) rederive: Rederive,
    pub(super) reference: Vec<f64>,
    pub(super) noise: NoiseModel,
    pub(super) params: PipelineParams,
    pub(super) polarity: Polarity,
    pub(super) press_model: Option<Arc<PressModel>>,
    /// The channels the chain came with, which a new reference may not lose more than a quarter of.
    pub(super) configured: Vec<bool>,
    /// The reference's own frames, imaged for their largest peak (the first derivation only).
    pub(super) reference_frames: Vec<Vec<f64>>,
    /// The relative noise variances and reference count it was asked for, which the pipeline
    /// records as derived once it is in (`None`: not a refresh of the noise).
    pub(super) variance: Option<Vec<f64>>,
    pub(super) reference_count: Option<usize>,
    /// The chain's frame forms ([`crate::chain::Chain::frame_forms`]), which a new
    /// reconstructor is readied in.
    pub(super) frame_forms: (bool, bool),
}

/// A derivation's result, for the pipeline that asked for it.
#[derive(Debug)]
pub struct Derived {
    pub(super) generation: u64,
    pub(super) first: bool,
    pub(super) variance: Option<Vec<f64>>,
    pub(super) reference_count: Option<usize>,
    pub(super) result: Result<Tests, InverseError>,
}

/// What a derivation made.
#[derive(Debug)]
pub(super) struct Tests {
    /// The new reconstructor; `None`: the chain's stays.
    pub(super) recon: Option<Reconstructor>,
    pub(super) significance: Option<Significance>,
    pub(super) detection: Option<PressDetection>,
    /// The largest |peak| of the reference frames' own images, S/m (0 when none were given).
    pub(super) noise_peak: f64,
}

impl Derivation {
    /// Does the work (milliseconds to a fifth of a second on the paper's sensor; allocates), in
    /// pieces of about a millisecond with a pause between where the thread asked for one
    /// ([`crate::parallel::set_step_aside`]).
    pub fn run(self) -> Derived {
        let result = self.derive();
        let Derivation { generation, first, variance, reference_count, .. } = self;
        Derived { generation, first, variance, reference_count, result }
    }

    /// Whether it completes a reference just taken.
    pub fn is_reference(&self) -> bool {
        self.first
    }

    /// Whether it may derive a new reconstructor (λ and the weights again); else only the noise
    /// tests.
    pub fn rederives(&self) -> bool {
        !matches!(self.rederive, Rederive::Keep)
    }

    fn derive(&self) -> Result<Tests, InverseError> {
        let mut recon = match &self.rederive {
            Rederive::Keep => None,
            Rederive::Auto { channels, variance } => {
                Some(self.recon.with_auto_hyperparameter(channels.clone(), variance.clone())?.0)
            }
            Rederive::Fixed { hyperparameter, channels } => {
                let same = self.recon.channels() == channels && self.recon.params().hyperparameter == *hyperparameter;
                if same {
                    None
                } else {
                    Some(self.recon.derive(*hyperparameter, channels.clone())?)
                }
            }
        };
        if let (true, Some(recon)) = (self.first, &recon) {
            too_many_dropped(recon.channels().used_mask(), &self.configured, 0)?;
        }
        // Imaged as the chain's is, its half-precision copy or shared basis made here rather
        // than on the frame that puts it in.
        let (half, shared) = self.frame_forms;
        if let (true, Some(recon)) = (half || shared, recon.as_mut()) {
            crate::parallel::step_aside();
            crate::chain::prepare_frames(recon, half, shared);
        }
        let recon_now = recon.as_ref().unwrap_or(&self.recon);
        let mut noise_peak = 0.0_f64;
        if !self.reference_frames.is_empty() {
            let mut image: Image = recon_now.blank_image();
            for frame in &self.reference_frames {
                // Channels missing from any reference frame are dropped, so imaging cannot fail.
                if recon_now.image_into(&self.reference, frame, &mut image).is_ok() {
                    noise_peak = noise_peak.max(image.peak().map_or(0.0, |(_, v)| f64::from(v.abs())));
                }
            }
        }
        crate::parallel::step_aside();
        let (significance, detection) = self.tests(recon_now)?;
        Ok(Tests { recon, significance, detection, noise_peak })
    }

    /// The noise test of `recon`'s images under the noise model, for the floor asked; with a
    /// press model, the detection of presses in Δv against the same noise.
    fn tests(&self, recon: &Reconstructor) -> Result<(Option<Significance>, Option<PressDetection>), InverseError> {
        let NoiseFloor::FalseAlarm { rate } = self.params.noise_floor else { return Ok((None, None)) };
        let detection = match &self.press_model {
            Some(model) => {
                let channels = recon.channels();
                // In the model's volts, as the chain gives the press fit its Δv.
                let model_values = recon.linearisation().background();
                let mut std = self.noise.difference_std(model_values, false, self.params.average);
                std.iter_mut().enumerate().filter(|(m, _)| !channels.is_used(*m)).for_each(|(_, s)| *s = f64::INFINITY);
                Some(PressDetection::new(model, &std, self.noise.frames(), rate)?)
            }
            None => None,
        };
        let significance =
            Significance::new(recon, &self.reference, &self.noise, self.params.average, self.polarity, rate)?;
        Ok((Some(significance), detection))
    }
}

#[cfg(test)]
mod tests {
    use super::super::{Deferred, Pipeline, PipelineParams, Status};
    use crate::chain::Chain;
    use crate::sim::VirtualSensor;
    use crate::{Reconstructor, ReconstructorParams, SensorSpec, TouchParams};

    /// Two pipelines of one chain, λ chosen from the noise: one deriving on its frame path, one
    /// deferring; and frames of the virtual sensor at rest.
    fn pair() -> (Pipeline, Pipeline, VirtualSensor) {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 800;
        let recon = Reconstructor::new(&spec.forward_model().unwrap(), 1.0, &ReconstructorParams::default()).unwrap();
        let chain = Chain::new(recon, TouchParams::default());
        let params = PipelineParams { auto_hyperparameter: true, ..PipelineParams::default() };
        let mut deferred = Pipeline::new(chain.clone(), params);
        deferred.defer_derivations(Deferred::All);
        (Pipeline::new(chain, params), deferred, VirtualSensor::new(&spec, 3).unwrap())
    }

    /// A pipeline asked to image through the shared basis (in half precision where there is
    /// none): until its reference's λ is chosen it images from the half copy, then every
    /// reconstructor derived goes through the basis, readied by the derivation; its
    /// frames' touches are the plain pipeline's (the same count, centres within 0.1 mm).
    #[test]
    fn derived_reconstructors_image_through_the_shared_basis() {
        let (mut plain, _, mut skin) = pair();
        let (mut shared, _, _) = pair();
        shared.set_shared_basis(true);
        shared.set_half_precision(true);
        assert!(shared.chain().reconstructor().half_precision() && !shared.chain().reconstructor().shared_basis());
        let mut touched = 0;
        for k in 0..300 {
            // At rest for the reference and the first refreshes, then pressed at one place, at two, and released.
            match k {
                150 => skin.press([0.03, -0.04], 8.0),
                200 => skin.press([-0.05, 0.05], 5.0),
                250 => skin.release(),
                _ => {}
            }
            let frame = skin.frame().unwrap();
            assert_eq!(plain.process(&frame).unwrap(), shared.process(&frame).unwrap());
            let (a, b) = (plain.touches(), shared.touches());
            assert_eq!(a.len(), b.len());
            for (a, b) in a.iter().zip(b) {
                let d = (a.touch.centre[0] - b.touch.centre[0]).hypot(a.touch.centre[1] - b.touch.centre[1]);
                assert!(d < 1e-4, "{:?} against {:?}", a.touch.centre, b.touch.centre);
            }
            touched += usize::from(!a.is_empty());
            if shared.imaging() {
                let recon = shared.chain().reconstructor();
                assert!(recon.shared_basis() && !recon.half_precision());
            }
        }
        assert!(touched > 10, "{touched} frames with touches");
    }

    #[test]
    fn deferred_frames_go_on_while_derived_elsewhere_and_end_as_on_the_frame_path() {
        let (mut inline, mut deferred, mut skin) = pair();
        for k in 1..=10 {
            let frame = skin.frame().unwrap();
            inline.process(&frame).unwrap();
            let status = deferred.process(&frame).unwrap();
            assert_eq!(
                status,
                if k < 10 { Status::Referencing { collected: k, needed: 10 } } else { Status::Deriving }
            );
        }
        let job = deferred.take_derivation().expect("the reference's derivation is asked for");
        assert!(job.is_reference() && deferred.deriving() && deferred.take_derivation().is_none());
        // Frames while it runs elsewhere: not imaged, and nothing asked twice.
        for _ in 0..3 {
            assert_eq!(deferred.process(&skin.frame().unwrap()).unwrap(), Status::Deriving);
            assert!(deferred.take_derivation().is_none());
        }
        deferred.deliver(job.run());
        let status = deferred.process(&skin.frame().unwrap()).unwrap();
        assert_eq!(status, Status::Referencing { collected: 10, needed: 10 }, "the reference's event, once it is in");
        assert!(!deferred.deriving());
        assert_eq!(deferred.hyperparameter(), inline.hyperparameter(), "λ from the same frames' noise");
        let threshold = |p: &Pipeline| p.significance().map(|s| s.threshold());
        assert_eq!(threshold(&deferred), threshold(&inline));

        // A refresh (the reference doubles at 20 frames): asked for, frames imaged meanwhile
        // with what was derived before, then it comes in on the frame after it is given back.
        let mut refresh = None;
        for _ in 0..30 {
            assert_eq!(deferred.process(&skin.frame().unwrap()).unwrap(), Status::Processed);
            refresh = deferred.take_derivation();
            if refresh.is_some() {
                break;
            }
        }
        let refresh = refresh.expect("a refresh within 30 frames");
        assert!(!refresh.is_reference());
        assert_eq!(deferred.process(&skin.frame().unwrap()).unwrap(), Status::Processed);
        deferred.deliver(refresh.run());
        assert_eq!(deferred.process(&skin.frame().unwrap()).unwrap(), Status::NoiseUpdated);

        // A press: found at the same place as on the frame path.
        for _ in 0..20 {
            let frame = skin.frame().unwrap();
            inline.process(&frame).unwrap();
            deferred.process(&frame).unwrap();
            if let Some(job) = deferred.take_derivation() {
                deferred.deliver(job.run());
            }
        }
        skin.press([0.04, -0.03], 10.0);
        let frame = skin.frame().unwrap();
        inline.process(&frame).unwrap();
        deferred.process(&frame).unwrap();
        assert_eq!((inline.touches().len(), deferred.touches().len()), (1, 1));
        let [a, b] = [&inline, &deferred].map(|p| p.touches()[0].touch.centre);
        assert!((a[0] - b[0]).hypot(a[1] - b[1]) < 1e-3, "{a:?} against {b:?}");
    }

    #[test]
    fn deferring_only_refreshes_images_every_frame_after_the_reference_as_on_the_frame_path() {
        let (mut inline, mut deferred, mut skin) = pair();
        deferred.defer_derivations(Deferred::Refreshes);
        let mut refreshes = 0;
        for k in 1..=400 {
            if k == 200 {
                skin.press([0.04, -0.03], 10.0);
            }
            let frame = skin.frame().unwrap();
            let (a, b) = (inline.process(&frame).unwrap(), deferred.process(&frame).unwrap());
            // The same status on every frame, but those that put a refresh in (later, deferred).
            if !matches!(a, Status::NoiseUpdated) && !matches!(b, Status::NoiseUpdated) {
                assert_eq!(a, b, "frame {k}");
            }
            assert_eq!(a.imaged(), k > 10, "frame {k}");
            assert_eq!(b.imaged(), k > 10, "frame {k}");
            if let Some(job) = deferred.take_derivation() {
                assert!(!job.is_reference(), "a reference's is done on its frame");
                refreshes += 1;
                deferred.deliver(job.run());
            }
        }
        assert!(refreshes > 0, "the refreshes are handed out");
        let (a, b) = (inline.touches(), deferred.touches());
        assert!(a.len() == 1 && b.len() == 1);
        assert!((a[0].touch.centre[0] - b[0].touch.centre[0]).abs() < 1e-3, "{a:?} against {b:?}");
    }

    #[test]
    fn a_frame_not_imaged_has_no_touches_and_no_event_is_lost_to_a_refused_frame() {
        let (_, mut pipeline, mut skin) = pair();
        let step = |pipeline: &mut Pipeline, skin: &mut VirtualSensor| {
            let status = pipeline.process(&skin.frame().unwrap());
            if let Some(job) = pipeline.take_derivation() {
                pipeline.deliver(job.run());
            }
            status
        };
        for _ in 0..40 {
            step(&mut pipeline, &mut skin).unwrap();
        }
        skin.press([0.04, -0.03], 10.0);
        step(&mut pipeline, &mut skin).unwrap();
        assert_eq!(pipeline.touches().len(), 1);
        // Re-taken under the press: no frame until the new reference's derivation is in has
        // touches (the last imaged frame's are not carried over).
        pipeline.retake_reference();
        for _ in 0..10 {
            pipeline.process(&skin.frame().unwrap()).unwrap();
            assert!(pipeline.touches().is_empty());
        }
        let job = pipeline.take_derivation().unwrap();
        assert_eq!(pipeline.process(&skin.frame().unwrap()).unwrap(), Status::Deriving);
        assert!(pipeline.touches().is_empty());
        pipeline.deliver(job.run());
        assert_eq!(
            pipeline.process(&skin.frame().unwrap()).unwrap(),
            Status::Referencing { collected: 10, needed: 10 }
        );
        assert!(pipeline.touches().is_empty() && pipeline.imaging());
        // Still pressed as when re-taken, frames are quiet and grow the noise model until it
        // asks for a refresh; it comes in on a frame that is refused (another board's scale):
        // the next frame imaged says it.
        let refresh = (0..2000)
            .find_map(|_| {
                pipeline.process(&skin.frame().unwrap()).unwrap();
                pipeline.take_derivation()
            })
            .expect("quiet frames ask for a refresh");
        pipeline.deliver(refresh.run());
        let tenfold: Vec<f64> = skin.frame().unwrap().iter().map(|v| 10.0 * v).collect();
        assert!(pipeline.process(&tenfold).is_err());
        assert_eq!(pipeline.process(&skin.frame().unwrap()).unwrap(), Status::NoiseUpdated);
    }

    #[test]
    fn a_derivation_asked_before_the_reference_was_retaken_or_a_channel_dropped_is_dropped() {
        let (_, mut pipeline, mut skin) = pair();
        for _ in 0..10 {
            pipeline.process(&skin.frame().unwrap()).unwrap();
        }
        let stale = pipeline.take_derivation().expect("asked for");
        pipeline.retake_reference();
        pipeline.deliver(stale.run());
        assert!(!pipeline.deriving());
        let status = pipeline.process(&skin.frame().unwrap()).unwrap();
        assert_eq!(status, Status::Referencing { collected: 1, needed: 10 }, "a new reference");

        for _ in 0..9 {
            pipeline.process(&skin.frame().unwrap()).unwrap();
        }
        let job = pipeline.take_derivation().expect("asked for");
        pipeline.deliver(job.run());
        let mut refresh = None;
        for _ in 0..40 {
            pipeline.process(&skin.frame().unwrap()).unwrap();
            refresh = pipeline.take_derivation();
            if refresh.is_some() {
                break;
            }
        }
        let refresh = refresh.expect("a refresh within 40 frames");
        // Channel 6 goes bad while the refresh is away: dropped at once; the refresh, derived
        // with it, would bring it back, so it is dropped when it comes.
        let mut frame = skin.frame().unwrap();
        frame[5] = f64::NAN;
        assert_eq!(pipeline.process(&frame).unwrap(), Status::ChannelsDropped { count: 1 });
        pipeline.deliver(refresh.run());
        assert!(!pipeline.deriving());
        assert_eq!(pipeline.process(&skin.frame().unwrap()).unwrap(), Status::Processed);
        assert_eq!(pipeline.dropped_channels(), vec![5]);
    }
}
