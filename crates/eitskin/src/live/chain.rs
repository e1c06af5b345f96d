//! The frame chain, written once: a frame against a reference → image → touches → presses
//! fitted to Δv → each touch's strength → its unit, area and force.
//!
//! [`Chain`] is what [`Pipeline`](crate::pipeline::Pipeline) runs on every frame, what the study
//! runs on its calibration and validation presses, and what `eitskin calibrate` and `evaluate`
//! run on recorded samples: a calibration fitted by one is applied by the others unchanged.
//!
//! 1. image Δσ = H·(v − v_ref) ([`Reconstructor::image_into`]);
//! 2. touches by the paper's threshold and components, or each by its own peak, tested against
//!    the measured noise where a [`Significance`] is set ([`touch::detect_tested_into`](crate::touch::detect_tested_into)),
//!    strongest first;
//! 3. with a [`PressModel`], one press fitted to Δv from each touch's centre (at most 16, jointly);
//!    or, with a [`PressDetection`] set (the pipeline sets one from the measured noise), steps 2
//!    and 3 are the presses found in Δv itself, each a touch at its centre;
//! 4. the strength of each touch ([`Strength::read`]: the peak, the fitted drop, or a reading
//!    of the [`ContrastMap`]);
//! 5. with a calibration, the unit and area its reading falls in and the force
//!    ([`Calibration::locate`]).
//!
//! ```
//! use eitskin::chain::Chain;
//! use eitskin::conductivity::{with_inclusions, Inclusion};
//! use eitskin::{Reconstructor, ReconstructorParams, SensorSpec, TouchParams};
//! let mut spec = SensorSpec::square_hydrogel();
//! spec.mesh.triangles = 800;
//! let model = spec.forward_model()?;
//! let recon = Reconstructor::new(&model, 1.0, &ReconstructorParams::default())?;
//! let mut chain = Chain::new(recon, TouchParams::default());
//! let v_ref = model.measure(&vec![1.0; model.mesh().triangles().len()])?;
//! let press = Inclusion { centre: [0.05, 0.05], radius: 0.01, conductivity: 0.5 };
//! let touches = chain.process(&v_ref, &model.measure(&with_inclusions(model.mesh(), 1.0, &[press]))?)?;
//! let [x, y] = touches[0].touch.centre;                 // metres from the sheet's centre
//! assert!((x - 0.05).hypot(y - 0.05) < 0.01 && touches[0].reading.is_some());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Not for: taking the reference, following drift or telling touches from noise over time
//! (that is [`Pipeline`](crate::pipeline::Pipeline)). After it has grown, [`Chain::process`]
//! allocates nothing.

use std::sync::Arc;

use thiserror::Error;

use crate::calibration::{Calibration, ForceEstimate, Sample};
use crate::contrast_map::ContrastMap;
use crate::image::Image;
use crate::inverse::{InverseError, Reconstructor};
use crate::noise::Significance;
use crate::press_fit::{PressDetection, PressFit, PressModel, PressScratch, PressTrack, Tracked};
use crate::pseudo_array::PseudoArray;
use crate::strength::{Reading, Strength};
use crate::touch::{detect_tested_into, Polarity, Touch, TouchParams, TouchScratch};

/// The most touches whose presses are fitted per frame.
pub const MAX_FITTED: usize = 16;

/// What a chain lacks for the strength or calibration it was given.
#[derive(Debug, Error, PartialEq)]
pub enum ChainError {
    /// The strength needs the press fitted to Δv, and the chain has no press model.
    #[error("the strength \"{strength}\" needs the press fitted to Δv, but the chain has no press model")]
    NeedsPressModel {
        /// The strength asked for.
        strength: Strength,
    },
    /// The strength needs the forward model's contrast map, and the chain has none.
    #[error("the strength \"{strength}\" needs the contrast map, but the chain has none")]
    NeedsContrastMap {
        /// The strength asked for.
        strength: Strength,
    },
    /// A labelled frame could not be imaged.
    #[error("sample {sample}: its frame cannot be imaged")]
    Frame {
        /// 1-based sample.
        sample: usize,
        /// Why.
        source: InverseError,
    },
    /// A labelled press off the pseudo-array.
    #[error("sample {sample} at ({x}, {y}) m is off the pseudo-array")]
    OffArray {
        /// 1-based sample.
        sample: usize,
        /// Its x, in m.
        x: f64,
        /// Its y, in m.
        y: f64,
    },
    /// A calibration whose curve count is not its pseudo-array's area count.
    #[error("the calibration has {curves} curves but its pseudo-array has {areas} areas")]
    CurveCount {
        /// Curves in the calibration.
        curves: usize,
        /// Areas of the pseudo-array.
        areas: usize,
    },
}

/// A press with a known place and force, and the frame measured under it (for calibrating
/// and validating).
#[derive(Debug, Clone, PartialEq)]
pub struct LabelledFrame {
    /// Where the press was, in m from the outline's centre.
    pub position: [f64; 2],
    /// Its force, in N.
    pub force: f64,
    /// The frame, in protocol order.
    pub frame: Vec<f64>,
}

/// A touch with what the chain found from it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TouchForce {
    /// The touch (centre in m, peak in S/m …).
    pub touch: Touch,
    /// The press fitted to Δv from it, with a press model (centre in m, drop).
    pub press: Option<PressFit>,
    /// Its strength by the chain's [`Strength`], and where its unit is looked up.
    pub reading: Option<Reading>,
    /// The pseudo-array unit holding the reading's centre (0-based), with a calibration.
    pub unit: Option<usize>,
    /// That unit's area (0-based), with a calibration.
    pub area: Option<usize>,
    /// The force, with a calibration.
    pub force: Option<ForceEstimate>,
}

/// The frame chain of one sensor: reconstructor, touch settings, optional press model,
/// contrast map and calibration, and the buffers of the frame path.
#[derive(Debug, Clone)]
pub struct Chain {
    /// Shared with the derivations that replace it ([`crate::pipeline::Derivation`]).
    recon: Arc<Reconstructor>,
    touch: TouchParams,
    strength: Strength,
    press_model: Option<Arc<PressModel>>,
    /// The press model blind to the reconstructor's dropped channels, while any are dropped.
    masked_press: Option<PressModel>,
    contrast_map: Option<ContrastMap>,
    calibration: Option<(PseudoArray, Calibration)>,
    significance: Option<Significance>,
    /// Presses found in Δv itself, tested against the noise, instead of touches from the image.
    press_detection: Option<PressDetection>,
    /// Whether presses found in Δv are carried from frame to frame, what is carried, and how
    /// the last frame's were had.
    carry_presses: bool,
    /// Whether every reconstructor set images from a half-precision copy of its matrix.
    half_precision: bool,
    /// Whether every reconstructor set that has a shared basis images through it (and needs
    /// no half-precision copy then).
    shared_basis: bool,
    press_track: PressTrack,
    tracked: Option<Tracked>,
    whitened: Vec<f64>,
    detected: Vec<PressFit>,
    image: Image,
    scratch: TouchScratch,
    found: Vec<Touch>,
    difference: Vec<f64>,
    starts: Vec<[f64; 2]>,
    press_scratch: PressScratch,
    fits: Vec<Option<PressFit>>,
    touches: Vec<TouchForce>,
}

impl Chain {
    /// The chain of `recon` finding touches by `touch`; strength: the peak; no calibration.
    pub fn new(recon: Reconstructor, touch: TouchParams) -> Chain {
        let image = recon.blank_image();
        let scratch = TouchScratch::new(image.size);
        Chain {
            whitened: Vec::with_capacity(recon.measurements()),
            difference: vec![0.0; recon.measurements()],
            recon: Arc::new(recon),
            touch,
            strength: Strength::Peak,
            press_model: None,
            masked_press: None,
            contrast_map: None,
            calibration: None,
            significance: None,
            press_detection: None,
            carry_presses: false,
            half_precision: false,
            shared_basis: false,
            press_track: PressTrack::default(),
            tracked: None,
            detected: Vec::with_capacity(MAX_FITTED),
            image,
            scratch,
            found: Vec::with_capacity(MAX_FITTED),
            starts: Vec::with_capacity(MAX_FITTED),
            press_scratch: PressScratch::default(),
            fits: Vec::with_capacity(MAX_FITTED),
            touches: Vec::with_capacity(MAX_FITTED),
        }
    }

    /// The same chain, fitting a press to Δv from each touch.
    pub fn with_press_model(mut self, model: PressModel) -> Chain {
        self.press_model = Some(Arc::new(model.with_every_radius(self.strength == Strength::SizedDrop)));
        self.mask_press_model();
        self
    }

    /// Replaces the reconstructor by `recon` (the same one derived for another λ or other
    /// channels, see [`Reconstructor::derive`]); the press fit then skips its dropped channels
    /// too. Allocates (a copy of the press table while channels are dropped): an event, not the
    /// frame path.
    #[track_caller]
    pub fn set_reconstructor(&mut self, mut recon: Reconstructor) {
        assert_eq!(recon.measurements(), self.recon.measurements(), "the same protocol");
        assert_eq!(recon.blank_image().size, self.image.size, "the same raster");
        prepare_frames(&mut recon, self.half_precision, self.shared_basis);
        self.recon = Arc::new(recon);
        self.mask_press_model();
    }

    /// Images frames through the shared basis of each reconstructor set that has one, this one
    /// and every one set later, when `on` ([`Reconstructor::set_shared_basis`]); one without
    /// it images as before. Allocates.
    pub fn set_shared_basis(&mut self, on: bool) {
        self.shared_basis = on;
        self.ready_frames();
    }

    /// The reconstructor readied for the frame forms asked ([`prepare_frames`]), copied only
    /// where it changes.
    fn ready_frames(&mut self) {
        let (half, shared) = (self.half_precision, self.shared_basis);
        if !frames_ready(&self.recon, half, shared) {
            prepare_frames(Arc::make_mut(&mut self.recon), half, shared);
        }
    }

    /// The forms frames are imaged in, as asked: (from a half-precision copy, through a shared
    /// basis where there is one).
    pub fn frame_forms(&self) -> (bool, bool) {
        (self.half_precision, self.shared_basis)
    }

    /// Images frames from a half-precision copy of the reconstructor's matrix when `on`, this
    /// one's and every one set later ([`Reconstructor::set_half_precision`]), but where one
    /// images through its shared basis ([`Chain::set_shared_basis`]). Allocates.
    pub fn set_half_precision(&mut self, on: bool) {
        self.half_precision = on;
        self.ready_frames();
    }

    fn mask_press_model(&mut self) {
        let channels = self.recon.channels();
        let all = channels.used_mask().iter().all(|u| *u);
        self.masked_press = match &self.press_model {
            Some(model) if !all => Some(model.masked(channels.used_mask())),
            _ => None,
        };
    }

    /// The same chain, with the contrast map the continuous strengths read.
    pub fn with_contrast_map(mut self, map: ContrastMap) -> Chain {
        self.contrast_map = Some(map);
        self
    }

    /// The same chain, reading each touch's strength as `strength`; an error if it lacks the
    /// press model or contrast map that strength needs (give those first).
    pub fn with_strength(mut self, strength: Strength) -> Result<Chain, ChainError> {
        if strength.needs_press_model() && self.press_model.is_none() {
            return Err(ChainError::NeedsPressModel { strength });
        }
        if strength.needs_contrast_map() && self.contrast_map.is_none() {
            return Err(ChainError::NeedsContrastMap { strength });
        }
        self.strength = strength;
        // The sized drop fits every press's radius; the others fit it where the misfit asks.
        let every_radius = strength == Strength::SizedDrop;
        self.press_model =
            self.press_model.take().map(|model| Arc::new(Arc::unwrap_or_clone(model).with_every_radius(every_radius)));
        self.masked_press = self.masked_press.take().map(|model| model.with_every_radius(every_radius));
        Ok(self)
    }

    /// The same chain, giving forces through `calibration` on `array` (its strength becomes
    /// the chain's); an error as for [`Chain::with_strength`], or if the two do not match.
    pub fn with_calibration(self, array: PseudoArray, calibration: Calibration) -> Result<Chain, ChainError> {
        if calibration.curves.len() != array.area_count() {
            return Err(ChainError::CurveCount { curves: calibration.curves.len(), areas: array.area_count() });
        }
        let mut chain = self.with_strength(calibration.strength)?;
        chain.calibration = Some((array, calibration));
        Ok(chain)
    }

    /// The reconstructor.
    pub fn reconstructor(&self) -> &Reconstructor {
        &self.recon
    }

    /// The reconstructor, shared: for work that derives its successor off the frame path.
    pub fn shared_reconstructor(&self) -> &Arc<Reconstructor> {
        &self.recon
    }

    /// How touches are found.
    pub fn touch_params(&self) -> &TouchParams {
        &self.touch
    }

    /// The smallest peak that is a touch, in S/m (the noise floor; see [`TouchParams::min_peak`]).
    pub fn set_min_peak(&mut self, min_peak: f64) {
        self.touch.min_peak = min_peak;
    }

    /// Tests each touch against the measured noise from now on (`None`: no test); the map must
    /// be for this chain's raster.
    pub fn set_significance(&mut self, significance: Option<Significance>) {
        self.significance = significance;
    }

    /// Finds touches as presses in Δv itself from now on, each tested against the noise
    /// (`None`: touches from the image); needs the chain's press model (whitened by the same
    /// noise in `detection`) to fit them.
    pub fn set_press_detection(&mut self, detection: Option<PressDetection>) {
        self.press_detection = detection;
        self.press_track.clear();
    }

    /// Carries the presses found in Δv from each frame to the next (frames of one stream, against
    /// one reference; see [`PressTrack`]) when `carry`, else finds them afresh in every frame (frames
    /// each of its own scene). Off by default.
    pub fn set_carry_presses(&mut self, carry: bool) {
        self.carry_presses = carry;
        self.press_track.clear();
    }

    /// How the last frame's presses in Δv were had (carried, fitted again or found afresh);
    /// `None` when presses are not found in Δv.
    pub fn tracked(&self) -> Option<Tracked> {
        self.tracked
    }

    /// The detection of presses in Δv, if one is set.
    pub fn press_detection(&self) -> Option<&PressDetection> {
        self.press_detection.as_ref()
    }

    /// The noise test touches pass, if one is set.
    pub fn significance(&self) -> Option<&Significance> {
        self.significance.as_ref()
    }

    /// What each touch's strength is.
    pub fn strength(&self) -> Strength {
        self.strength
    }

    /// The pseudo-array of the calibration, if one was given.
    pub fn pseudo_array(&self) -> Option<&PseudoArray> {
        self.calibration.as_ref().map(|c| &c.0)
    }

    /// The press model, if one was given.
    pub fn press_model(&self) -> Option<&PressModel> {
        self.press_model.as_deref()
    }

    /// The press model, shared: for work that derives its noise test off the frame path.
    pub fn shared_press_model(&self) -> Option<&Arc<PressModel>> {
        self.press_model.as_ref()
    }

    /// The image of the last frame (Δσ, S/m).
    pub fn image(&self) -> &Image {
        &self.image
    }

    /// The touches of the last processed frame, strongest first.
    pub fn touches(&self) -> &[TouchForce] {
        &self.touches
    }

    /// Images `frame` against `reference` only (no touches), checking both as the
    /// reconstructor does; the image is then [`Chain::image`].
    pub fn image_only(&mut self, reference: &[f64], frame: &[f64]) -> Result<&Image, InverseError> {
        self.recon.image_into(reference, frame, &mut self.image)?;
        Ok(&self.image)
    }

    /// One calibration sample per labelled frame, against `reference`: the area of `array` that
    /// holds the press, its force and the strength of the frame's strongest touch; `None` where
    /// the frame has no touch.
    pub fn samples(
        &mut self,
        reference: &[f64],
        array: &PseudoArray,
        frames: &[LabelledFrame],
    ) -> Result<Vec<Option<Sample>>, ChainError> {
        frames
            .iter()
            .enumerate()
            .map(|(k, labelled)| {
                let [x, y] = labelled.position;
                let unit = array.unit_at(labelled.position).ok_or(ChainError::OffArray { sample: k + 1, x, y })?;
                let touches = self
                    .process(reference, &labelled.frame)
                    .map_err(|source| ChainError::Frame { sample: k + 1, source })?;
                Ok(touches
                    .first()
                    .and_then(|t| t.reading)
                    .map(|reading| Sample::read(array.area_of(unit), labelled.force, labelled.position, reading)))
            })
            .collect()
    }

    /// Runs the whole chain on `frame` against `reference` (both in protocol order); the
    /// touches, strongest first. A bad frame (wrong length, NaN on a used channel) is an error and
    /// leaves no touches; the reconstructor's dropped channels are ignored, in the image and the
    /// press fit alike.
    pub fn process(&mut self, reference: &[f64], frame: &[f64]) -> Result<&[TouchForce], InverseError> {
        self.touches.clear();
        self.recon.image_into(reference, frame, &mut self.image)?;
        self.fits.clear();
        let channels = self.recon.channels();
        let model = self.masked_press.as_ref().or(self.press_model.as_deref());
        if model.is_some() || self.press_detection.is_some() {
            // Δv in the model's volts: each channel's relative change times the model's own
            // value (v/v_ref − 1)·v₀, so a board's unit and gains do not scale the fitted drop.
            // A dropped channel's Δv is 0 (it may be NaN): the masked model ignores it.
            let model_values = self.recon.linearisation().background();
            let values = frame.iter().zip(reference).zip(model_values);
            for (m, (d, ((v, r), v0))) in self.difference.iter_mut().zip(values).enumerate() {
                *d = if channels.is_used(m) && *r != 0.0 { (v - r) * v0 / r } else { 0.0 };
            }
        }
        self.tracked = None;
        if let Some(detection) = &self.press_detection {
            let (dv, whitened, scratch, out) =
                (&self.difference, &mut self.whitened, &mut self.press_scratch, &mut self.detected);
            self.tracked = Some(if self.carry_presses {
                detection.track_into(dv, whitened, scratch, &mut self.press_track, out)?
            } else {
                detection.detect_into(dv, whitened, scratch, out)?;
                Tracked::Found
            });
            self.found.clear();
            let radius = detection.radius();
            for press in self.detected.iter().take(MAX_FITTED) {
                self.found.push(touch_of_press(press, radius, &self.image));
                self.fits.push(Some(*press));
            }
        } else {
            let significance = self.significance.as_ref();
            detect_tested_into(&self.image, &self.touch, significance, &mut self.scratch, &mut self.found);
            if let Some(model) = model {
                self.starts.clear();
                self.starts.extend(self.found.iter().take(MAX_FITTED).map(|t| t.centre));
                model.fit_into(&self.difference, &self.starts, &mut self.press_scratch, &mut self.fits)?;
            }
        }
        for (k, touch) in self.found.iter().enumerate() {
            let press = self.fits.get(k).copied().flatten();
            // The radius of the model that fitted it: the detection's when presses are found in Δv.
            let indenter = self.press_detection.as_ref().map(PressDetection::radius).or(model.map(PressModel::radius));
            let fitted = press.as_ref().zip(indenter);
            let reading = self.strength.read(touch, fitted, self.contrast_map.as_ref());
            // Calibrations are fitted on presses: a conductivity increase gets no unit or force.
            let located = match (&self.calibration, reading) {
                (Some((array, calibration)), Some(reading)) if touch.polarity == Polarity::Decrease => {
                    calibration.locate(array, reading)
                }
                _ => None,
            };
            self.touches.push(TouchForce {
                touch: *touch,
                press,
                reading,
                unit: located.map(|l| l.unit),
                area: located.map(|l| l.area),
                force: located.and_then(|l| l.force),
            });
        }
        Ok(&self.touches)
    }
}

/// The touch a press found in Δv makes: at the press's centre, its peak the image's change
/// there (in the press direction, at least 0), its region the indenter's disk of `radius` (m),
/// its significance the press's z.
fn touch_of_press(press: &PressFit, radius: f64, image: &Image) -> Touch {
    let pixel = image.pixel_at(press.centre);
    let peak = pixel.map_or(0.0, |p| Polarity::Decrease.intensity(image.values[p]).max(0.0));
    let [x, y] = press.centre;
    let area = std::f64::consts::PI * radius * radius;
    Touch {
        polarity: Polarity::Decrease,
        centre: press.centre,
        peak,
        peak_at: press.centre,
        area,
        volume: peak * area,
        pixels: (area / image.pixel_area()).round() as usize,
        bounding_box: [[x - radius, y - radius], [x + radius, y + radius]],
        significance: Some(press.z),
    }
}

/// Readies `recon` to image frames as a chain asked: through its shared basis where `shared`
/// and it has one, else from a half-precision copy where `half`, else from its matrix; what it
/// already has is kept. Allocates (what it did not have).
pub(crate) fn prepare_frames(recon: &mut Reconstructor, half: bool, shared: bool) {
    if !frames_ready(recon, half, shared) {
        let through = shared && recon.set_shared_basis(true);
        if !through {
            recon.set_shared_basis(false);
        }
        recon.set_half_precision(half && !through);
    }
}

/// Whether `recon` images frames as [`prepare_frames`] would ready it to.
fn frames_ready(recon: &Reconstructor, half: bool, shared: bool) -> bool {
    let through = shared && recon.can_share_basis();
    recon.shared_basis() == through && recon.half_precision() == (half && !through)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::conductivity::{with_inclusions, Inclusion};
    use crate::sim::Hydrogel;
    use crate::{ReconstructorParams, SensorSpec};

    /// With touches of both signs, a calibration (fitted on presses) gives a press its force and
    /// a more conductive object none.
    #[test]
    fn only_a_decrease_gets_a_force_from_the_calibration() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 800;
        let model = spec.forward_model().unwrap();
        let recon = Reconstructor::new(&model, 1.0, &ReconstructorParams::default()).unwrap();
        let array = PseudoArray::of_sensor(&spec, [1, 1]).unwrap();
        let calibration = Calibration { curves: vec![Hydrogel::default().drop_curve(16.0)], strength: Strength::Peak };
        let touch = TouchParams { polarity: Polarity::Both, ..TouchParams::default() };
        let mut chain = Chain::new(recon, touch).with_calibration(array, calibration).unwrap();
        let reference = model.measure(&vec![1.0; model.mesh().triangles().len()]).unwrap();
        for (conductivity, polarity) in [(0.3, Polarity::Decrease), (3.0, Polarity::Increase)] {
            let object = Inclusion { centre: [0.04, -0.03], radius: 0.015, conductivity };
            let frame = model.measure(&with_inclusions(model.mesh(), 1.0, &[object])).unwrap();
            let found = chain.process(&reference, &frame).unwrap();
            assert_eq!(found[0].touch.polarity, polarity);
            let force = found[0].force.is_some();
            assert_eq!(force, polarity == Polarity::Decrease, "{polarity:?}: {:?}", found[0]);
        }
    }

    /// Imaged from the half-precision matrix, a frame's image is within its rounding bound of
    /// the single-precision one and its touches are the same; a reconstructor set later is
    /// halved too, and switching back gives the single-precision image exactly.
    #[test]
    fn half_precision_images_keep_their_touches() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 800;
        let model = spec.forward_model().unwrap();
        let recon = Reconstructor::new(&model, 1.0, &ReconstructorParams::default()).unwrap();
        let reference = model.measure(&vec![1.0; model.mesh().triangles().len()]).unwrap();
        let presses = [([0.04, -0.03], 0.3), ([-0.05, 0.05], 0.6)].map(|(centre, conductivity)| Inclusion {
            centre,
            radius: 0.012,
            conductivity,
        });
        let frame = model.measure(&with_inclusions(model.mesh(), 1.0, &presses)).unwrap();
        let mut single = Chain::new(recon.clone(), TouchParams::default());
        let mut halved = Chain::new(recon.clone(), TouchParams::default());
        halved.set_half_precision(true);
        let want: Vec<[f64; 2]> = single.process(&reference, &frame).unwrap().iter().map(|t| t.touch.centre).collect();
        let got: Vec<[f64; 2]> = halved.process(&reference, &frame).unwrap().iter().map(|t| t.touch.centre).collect();
        assert_eq!(want.len(), 2);
        assert_eq!(got.len(), want.len());
        for (a, b) in want.iter().zip(&got) {
            assert!((a[0] - b[0]).hypot(a[1] - b[1]) < 1e-4, "{a:?} against {b:?}");
        }
        // Each pixel within 2⁻¹¹·Σ|H·Δv| (and the sums' own f32 rounding).
        let matrix = recon.matrix();
        for (p, (x, y)) in single.image().values.iter().zip(&halved.image().values).enumerate() {
            let terms: f32 =
                (0..frame.len()).map(|m| (matrix.get(p, m) * (frame[m] - reference[m]) as f32).abs()).sum();
            assert!((x - y).abs() <= terms / 2048.0 + 1e-5 * terms, "pixel {p}: {x} against {y}, terms {terms}");
        }
        halved.set_reconstructor(
            recon
                .rederive(&ReconstructorParams { hyperparameter: 0.2, ..*recon.params() }, recon.channels().clone())
                .unwrap(),
        );
        assert!(halved.reconstructor().half_precision());
        halved.set_half_precision(false);
        halved.process(&reference, &frame).unwrap();
        single.set_reconstructor(halved.reconstructor().clone());
        single.process(&reference, &frame).unwrap();
        assert_eq!(single.image().values, halved.image().values);
    }
}
