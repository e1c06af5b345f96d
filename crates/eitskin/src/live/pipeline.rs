//! The real-time frame path: reference, drift compensation, then the [`Chain`] (image,
//! touches, fitted presses, forces) on every frame.
//!
//! The reference (no-touch) frame is the mean of the first N frames (and again after
//! [`Pipeline::retake_reference`]); each later frame without a touch joins that mean until it
//! holds [`PipelineParams::reference_limit`] frames, since the reference's noise is in every Δv
//! (averaging, a frame joins as it leaves the average, if none of the means that held it showed
//! a touch).
//! While referencing, the pipeline also measures its noise, each
//! channel's ([`NoiseModel`]), and keeps measuring it on every later frame without a touch.
//! With [`NoiseFloor::FalseAlarm`] (the default) a touch's peak must stand out from that noise
//! at a stated false-alarm rate ([`Significance`]); with [`NoiseFloor::Auto`] it needs a peak
//! above a multiple of the reference frames' own image peaks. With
//! [`PipelineParams::auto_hyperparameter`] it also chooses λ from the measured noise and weights
//! the channels by it ([`Reconstructor::with_auto_hyperparameter`](crate::Reconstructor::with_auto_hyperparameter)).
//! As the noise model sees more frames (each time their number doubles, then every
//! [`REFRESH_MAX`] frames) it is compared with the noise λ, the weights and the threshold were
//! derived from; where it has changed ([`noise_changed`]) they are derived again, and
//! [`Status::NoiseUpdated`] says so: an event, like a dropped channel.
//!
//! Optional averaging ([`PipelineParams::average`]): each frame imaged is the mean of the last
//! N (a moving average, started from the reference frames), so the noise falls by √N and a
//! change shows (N − 1)/2 frames late on average.
//! An optional slow baseline update, while no touch is present, follows drift:
//! v_ref ← (1 − α)·v_ref + α·v (while the reference grows, a frame weighs the larger of α and
//! its share of the mean). Each later frame goes through the chain against the reference.
//!
//! Channels going bad. A channel whose value is not finite (NaN marks a missing value) in a
//! reference frame is dropped, and so is one whose reference is zero with normalised
//! differences; the reference is the mean of each channel's finite values. After the reference
//! is taken, a non-finite value on a used channel drops that channel: the reconstructor is
//! derived again without it (milliseconds, from its stored linearisation), the press fit skips
//! it too, the frame is imaged, and [`Status::ChannelsDropped`] says so
//! ([`Pipeline::newly_dropped`] says which). A dropped channel stays dropped until
//! [`Pipeline::retake_reference`], even if its values come back. A frame that would leave more
//! than a quarter of the channels dropped is refused ([`InverseError::TooManyBadChannels`]) and
//! changes nothing; a reference that would is refused as a whole, and the next frames start a
//! new one. A frame whose values are typically ten times (or a tenth, or the negative) of the
//! reference's ([`crate::inverse::typical_ratio`]) is from another unit, gain or board, not a
//! press: refused ([`InverseError::FrameScale`]) and changes nothing; while the reference is
//! taken, such a frame (against the first, or a first frame of zeros) starts it again.
//!
//! Derivations off the frame path. Taking the reference and each refresh derive λ, the weights
//! and the noise tests again (tens of milliseconds on the paper's sensor). By default
//! [`Pipeline::process`] does that work on the frame that asks for it; after
//! [`Pipeline::defer_derivations`] it hands the work out instead ([`Pipeline::take_derivation`],
//! a [`Derivation`] to run on any thread, its result given back by [`Pipeline::deliver`]) and
//! puts it in at the next frame after it came: frames go on meanwhile, imaged with what was
//! derived before ([`Status::Deriving`] until a new reference's first derivation is in, when
//! that one is deferred too: [`Deferred`]). A server of many sensors runs them at a lower
//! priority than frames; for a replay it derives each new reference's on its last frame
//! ([`Deferred::Refreshes`]), so that every frame after a reference is imaged as without
//! deferring.
//!
//! Plain data and no threads or I/O: the caller feeds frames (from a port, a file, the virtual
//! sensor) and reads the results. After the reference is taken, [`Pipeline::process`]
//! allocates nothing, except on the frame that drops a channel (an event, not the frame path)
//! and on the frames that derive: the derivation itself, or, deferred, the copies of the
//! reference and noise model it takes away (and the frame that puts its result in frees what it
//! replaces).

use std::ops::RangeInclusive;

use crate::chain::Chain;
pub use crate::chain::TouchForce;
use crate::image::Image;
use crate::inverse::{
    mean_of_finite, plausible_ratio, typical_ratio_in, Channels, InverseError, DEFAULT_RELATIVE_NOISE,
};
use crate::noise::{NoiseModel, Significance};
use crate::pseudo_array::PseudoArray;

mod derivation;

use derivation::Rederive;
pub use derivation::{Derivation, Derived};

/// The most bad channels an error names.
const NAMED: usize = 8;

/// The most frames between two refreshes of λ and the threshold from the noise model.
pub const REFRESH_MAX: f64 = 500.0;

/// Whether the relative noise variances `now` differ from `then` enough to derive λ, the
/// weights and the threshold again: the channels' noise level as a whole by more than 5 %
/// (the mean of ln(now/then) beyond ±0.1; its sampling spread over 120 channels and 500 frames
/// is about 0.006), or any one channel's by more than half (|ln(now/then)| > 0.81, about 13
/// sampling standard deviations at 500 frames). Channels not measured in both are left out.
pub fn noise_changed(then: &[f64], now: &[f64]) -> bool {
    if then.len() != now.len() {
        return true;
    }
    let ratios = || then.iter().zip(now).filter(|(a, b)| a.is_finite() && b.is_finite() && **a > 0.0 && **b > 0.0);
    let (mut count, mut total, mut largest) = (0.0, 0.0, 0.0f64);
    for (a, b) in ratios() {
        let log = (b / a).ln();
        count += 1.0;
        total += log;
        largest = largest.max(log.abs());
    }
    count == 0.0 || (total / count).abs() > 0.1 || largest > 0.81
}

/// How touches are told from noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NoiseFloor {
    /// A touch's peak must pass the z-test of the measured noise ([`Significance`]) at `rate`
    /// false touches per frame without a touch.
    FalseAlarm {
        /// False touches per no-touch frame, in (0, 0.5].
        rate: f64,
    },
    /// A touch needs a peak above `factor` × the largest peak of the reference frames' own images.
    Auto {
        /// Multiple of the measured noise peak (dimensionless).
        factor: f64,
    },
    /// A touch needs a peak above this, in S/m.
    Fixed(f64),
}

/// Settings of the frame path; `Default` takes the mean of 10 frames, grows it to 100 frames
/// without a touch, no baseline update, tests
/// touches at 1 false touch per 1,000 frames, images single frames and keeps the chain's λ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PipelineParams {
    /// Frames averaged into the reference, counted in frames imaged: with [`average`](Self::average)
    /// N the reference is the mean of `reference_frames` × N frames
    /// ([`frames_in_reference`](Self::frames_in_reference)), so that it stays as much quieter
    /// than a frame imaged as without averaging (its noise is in every Δv).
    pub reference_frames: usize,
    /// Frames imaged the reference grows to: after it is taken, each frame without a touch joins
    /// its mean until it is the mean of `reference_limit` × [`average`](Self::average) frames
    /// (its noise's share of every Δv falls from 1/`reference_frames` of a frame's to
    /// 1/`reference_limit`); at or below `reference_frames` it stays as taken.
    pub reference_limit: usize,
    /// Baseline update weight α per frame without a touch (0 = off), dimensionless.
    pub baseline_rate: f64,
    /// How touches are told from noise (on top of the chain's own [`TouchParams::min_peak`](crate::TouchParams::min_peak)).
    pub noise_floor: NoiseFloor,
    /// Choose λ from the reference frames' noise each time the reference is taken (a noise
    /// figure of 0.5, see [`Hyperparameter::Auto`](crate::inverse::Hyperparameter::Auto)),
    /// instead of keeping the chain's reconstructor's.
    pub auto_hyperparameter: bool,
    /// Frames averaged into each frame imaged (a moving average; 1 = none).
    pub average: usize,
    /// Carry the presses found in Δv from frame to frame ([`PressTrack`](crate::press_fit::PressTrack)):
    /// a held press costs a few steps on a model of it made once, instead of an exact fit. Off
    /// where each frame is a scene of its own.
    pub carry_presses: bool,
}

impl Default for PipelineParams {
    fn default() -> Self {
        PipelineParams {
            reference_frames: 10,
            reference_limit: 100,
            baseline_rate: 0.0,
            noise_floor: NoiseFloor::FalseAlarm { rate: 1e-3 },
            auto_hyperparameter: false,
            average: 1,
            carry_presses: true,
        }
    }
}

/// The frames [`PipelineParams::reference_frames`] takes.
pub const REFERENCE_FRAMES: RangeInclusive<usize> = 1..=10_000;
/// The frames [`PipelineParams::reference_limit`] takes.
pub const REFERENCE_LIMIT: RangeInclusive<usize> = 1..=1_000_000;
/// The frames [`PipelineParams::average`] takes.
pub const AVERAGE: RangeInclusive<usize> = 1..=1000;
/// The largest false-alarm rate ([`NoiseFloor::FalseAlarm`]) taken, per frame without a touch;
/// the rate must be above 0.
pub const MAX_FALSE_ALARM_RATE: f64 = 0.5;

/// Whether `rate` is a false-alarm rate a pipeline takes: in (0, [`MAX_FALSE_ALARM_RATE`]].
pub fn false_alarm_rate_ok(rate: f64) -> bool {
    rate > 0.0 && rate <= MAX_FALSE_ALARM_RATE
}

/// A pipeline setting out of its range: its name, its value as given, and the range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{name} must be {range}, got {value}")]
pub struct RangeError {
    /// The setting, as [`PipelineParams`] names it.
    pub name: &'static str,
    /// The value given.
    pub value: String,
    /// The range it must lie in.
    pub range: String,
}

impl PipelineParams {
    /// Checks every setting against its range (the one check the CLI's flags and Python's
    /// keywords share): the first out of range is the error.
    pub fn check(&self) -> Result<(), RangeError> {
        let whole = |name, value: usize, range: RangeInclusive<usize>| match range.contains(&value) {
            true => Ok(()),
            false => Err(RangeError {
                name,
                value: value.to_string(),
                range: format!("{} to {}", range.start(), range.end()),
            }),
        };
        whole("reference_frames", self.reference_frames, REFERENCE_FRAMES)?;
        whole("reference_limit", self.reference_limit, REFERENCE_LIMIT)?;
        whole("average", self.average, AVERAGE)?;
        if !(0.0..=1.0).contains(&self.baseline_rate) {
            let value = self.baseline_rate.to_string();
            return Err(RangeError { name: "baseline_rate", value, range: "in [0, 1]".into() });
        }
        match self.noise_floor {
            NoiseFloor::FalseAlarm { rate } if !false_alarm_rate_ok(rate) => Err(RangeError {
                name: "false_alarm_rate",
                value: rate.to_string(),
                range: format!("in (0, {MAX_FALSE_ALARM_RATE}]"),
            }),
            _ => Ok(()),
        }
    }

    /// The frames the reference is the mean of: `reference_frames` × `average` (each at least 1).
    pub fn frames_in_reference(&self) -> usize {
        self.reference_frames.max(1).saturating_mul(self.average.max(1))
    }

    /// The frames the reference grows to, without a touch: `reference_limit` × `average`, at
    /// least [`frames_in_reference`](Self::frames_in_reference).
    pub fn reference_limit_frames(&self) -> usize {
        self.reference_limit.max(self.reference_frames).max(1).saturating_mul(self.average.max(1))
    }
}

/// Which derivations [`Pipeline::defer_derivations`] hands out rather than doing them on the
/// frame that asks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Deferred {
    /// None (the default): each is done on the frame that asks.
    #[default]
    None,
    /// The refreshes as the noise model grows; a new reference's is done on its last frame, so
    /// every frame after it is imaged, as without deferring.
    Refreshes,
    /// All, a new reference's too: the frames until it is in are [`Status::Deriving`].
    All,
}

impl Deferred {
    /// Whether a derivation (`first`: a new reference's) is handed out.
    fn defers(self, first: bool) -> bool {
        match self {
            Deferred::None => false,
            Deferred::Refreshes => !first,
            Deferred::All => true,
        }
    }
}

/// What [`Pipeline::process`] did with a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// The frame went into the reference; `collected` of `needed` so far (deferred, `collected`
    /// = `needed` comes on the frame that puts the reference's derivation in, not part of it).
    Referencing {
        /// Frames collected.
        collected: usize,
        /// Frames needed.
        needed: usize,
    },
    /// The frame was imaged; its touches are in [`Pipeline::touches`].
    Processed,
    /// The frame was imaged without `count` channels that went bad in it (not finite), dropped
    /// from now until [`Pipeline::retake_reference`]; which ones: [`Pipeline::newly_dropped`].
    ChannelsDropped {
        /// Channels dropped by this frame.
        count: usize,
    },
    /// The frame was imaged, and then the noise model, grown by it, gave a new λ, channel
    /// weights and threshold for the frames after it (or the reference, grown by it, a new
    /// threshold: its own noise is less of Δv's); deferred, the frame was imaged with them,
    /// derived from the noise of some frames before.
    NoiseUpdated,
    /// The reference is taken and what it asks for is being derived off the frame path
    /// ([`Pipeline::defer_derivations`]); the frame was not imaged.
    Deriving,
}

impl Status {
    /// Whether the frame was imaged (its touches are in [`Pipeline::touches`]).
    pub fn imaged(self) -> bool {
        !matches!(self, Status::Referencing { .. } | Status::Deriving)
    }
}

/// The frame path of one sensor: the [`Chain`], its reference and the noise it measured.
#[derive(Debug)]
pub struct Pipeline {
    chain: Chain,
    params: PipelineParams,
    /// The chain's own minimum peak, under the noise floor (S/m).
    min_peak: f64,
    /// λ of the chain's reconstructor as given, for each new reference unless λ is chosen.
    given_hyperparameter: f64,
    reference: Vec<f64>,
    /// Frames the reference was the mean of when the threshold was last derived (the noise
    /// model holds how many it is now).
    derived_reference_count: usize,
    /// Frames imaged since the reference was taken, and of them the last ones in a row without
    /// a touch.
    since_reference: usize,
    quiet: usize,
    collected: Vec<Vec<f64>>,
    /// Per channel, whether a reference frame collected so far missed it.
    missing: Vec<bool>,
    noise_peak: f64,
    /// Channels the last frame dropped, 0-based (room for every channel, so no allocation).
    newly_dropped: Vec<usize>,
    /// Scratch for each frame's ratios to the reference, a channel's worth of capacity.
    ratios: Vec<f64>,
    /// The channels the chain came with (a spec's mask left the others out): only these are
    /// imaged, and only their losses count towards the limit.
    configured: Vec<bool>,
    /// Each channel's measured noise, once the reference is taken.
    noise: Option<NoiseModel>,
    /// Whether the noise model was measured (false: assumed, from one reference frame).
    noise_measured: bool,
    /// Frames the noise model had seen at its last refresh, and frames added since.
    refreshed_at: f64,
    since_refresh: f64,
    /// Each channel's relative noise variance that λ, the weights and the threshold were last
    /// derived from.
    refreshed_variance: Vec<f64>,
    /// The last `average` frames (a ring, frame after frame), the next slot, and their mean.
    ring: Vec<f64>,
    ring_next: usize,
    averaged: Vec<f64>,
    /// Whether derivations are handed out rather than done on the frame path.
    deferred: Deferred,
    /// Counts the reference re-taken and channels dropped: a derivation asked for before is stale.
    generation: u64,
    /// A derivation asked for and not yet in; the one not yet taken; the one given back.
    in_flight: bool,
    asked: Option<Derivation>,
    delivered: Option<Derived>,
    /// The reference is taken, its first derivation not yet in: frames are not imaged.
    deriving_reference: bool,
    /// A refresh was put in before the frames imaged since: the next one says so.
    updated: bool,
    /// Whether the last frame was imaged (else it has no touches).
    imaged: bool,
}

impl Pipeline {
    /// A pipeline running `chain` that starts by taking its reference.
    pub fn new(mut chain: Chain, params: PipelineParams) -> Pipeline {
        chain.set_carry_presses(params.carry_presses);
        let count = chain.reconstructor().measurements();
        let configured = chain.reconstructor().channels().used_mask().to_vec();
        Pipeline {
            min_peak: chain.touch_params().min_peak,
            given_hyperparameter: chain.reconstructor().params().hyperparameter,
            chain,
            params,
            reference: Vec::new(),
            derived_reference_count: 0,
            since_reference: 0,
            quiet: 0,
            collected: Vec::with_capacity(params.frames_in_reference()),
            missing: vec![false; count],
            noise_peak: 0.0,
            newly_dropped: Vec::with_capacity(count),
            ratios: Vec::with_capacity(count),
            configured,
            noise: None,
            noise_measured: false,
            refreshed_at: 0.0,
            since_refresh: 0.0,
            refreshed_variance: Vec::new(),
            ring: vec![0.0; count * params.average.max(1)],
            ring_next: 0,
            averaged: vec![0.0; count],
            deferred: Deferred::None,
            generation: 0,
            in_flight: false,
            asked: None,
            delivered: None,
            deriving_reference: false,
            updated: false,
            imaged: false,
        }
    }

    /// From now on, hands the derivations `which` names out ([`Pipeline::take_derivation`])
    /// instead of doing them on the frame that asks (see the module doc).
    pub fn defer_derivations(&mut self, which: Deferred) {
        self.deferred = which;
        // One asked for, not taken and no longer deferred is done now, for the next frame.
        if let Some(job) = self.asked.take_if(|job| !which.defers(job.first)) {
            self.deliver(job.run());
        }
    }

    /// The derivation asked for and not yet taken, if any: run it ([`Derivation::run`]) and give
    /// the result to [`Pipeline::deliver`]. Only with [`Pipeline::defer_derivations`].
    pub fn take_derivation(&mut self) -> Option<Derivation> {
        self.asked.take()
    }

    /// Gives back a derivation's result; the next [`Pipeline::process`] puts it in (a new
    /// reference's first is then [`Status::Referencing`] with every frame collected, a refresh's
    /// [`Status::NoiseUpdated`]). One asked for before the reference was re-taken or a channel
    /// dropped is stale, and dropped.
    pub fn deliver(&mut self, derived: Derived) {
        if derived.generation == self.generation && self.in_flight {
            self.delivered = Some(derived);
        }
    }

    /// Whether a derivation is asked for and not yet in.
    pub fn deriving(&self) -> bool {
        self.in_flight
    }

    /// Whether frames are imaged: the reference is taken and what it gives is in.
    pub fn imaging(&self) -> bool {
        !self.reference.is_empty() && !self.deriving_reference
    }

    /// Images frames from a half-precision copy of the reconstruction matrix when `on`
    /// ([`Chain::set_half_precision`]), and every reference derived later. Allocates: setup.
    pub fn set_half_precision(&mut self, on: bool) {
        self.chain.set_half_precision(on);
    }

    /// Images frames through the shared basis of every reconstructor derived that has one
    /// ([`Chain::set_shared_basis`]): for many sensors of one spec. Allocates: setup.
    pub fn set_shared_basis(&mut self, on: bool) {
        self.chain.set_shared_basis(on);
    }

    /// The frame path's settings.
    pub fn params(&self) -> &PipelineParams {
        &self.params
    }

    /// Forgets the reference, and with it every dropped channel; the next frames build a new one.
    pub fn retake_reference(&mut self) {
        self.reference.clear();
        self.collected.clear();
        self.missing.fill(false);
        self.newly_dropped.clear();
        self.forget_derivation();
    }

    /// Makes any derivation asked for so far stale.
    fn forget_derivation(&mut self) {
        self.generation += 1;
        (self.in_flight, self.asked, self.delivered, self.deriving_reference) = (false, None, None, false);
        self.updated = false;
    }

    /// The reference frame, once taken (NaN on a channel no reference frame had).
    pub fn reference(&self) -> Option<&[f64]> {
        (!self.reference.is_empty()).then_some(self.reference.as_slice())
    }

    /// The largest peak of the reference frames' own images, in S/m: the noise the floor is set from.
    pub fn noise_peak(&self) -> f64 {
        self.noise_peak
    }

    /// Each channel's noise as measured (or assumed, with one reference frame), once the reference is taken.
    pub fn noise(&self) -> Option<&NoiseModel> {
        self.noise.as_ref()
    }

    /// Whether the noise model was measured from frames (false: [`DEFAULT_RELATIVE_NOISE`] assumed).
    pub fn noise_measured(&self) -> bool {
        self.noise_measured
    }

    /// The noise test touches pass, with [`NoiseFloor::FalseAlarm`] once the reference is taken.
    pub fn significance(&self) -> Option<&Significance> {
        self.chain.significance()
    }

    /// Frames by which averaging delays a change, on average ((N − 1)/2 for N frames averaged).
    pub fn latency_frames(&self) -> f64 {
        (self.params.average.max(1) - 1) as f64 / 2.0
    }

    /// The hyperparameter λ imaged with (dimensionless): given, or chosen once the reference is taken.
    pub fn hyperparameter(&self) -> f64 {
        self.chain.reconstructor().params().hyperparameter
    }

    /// The channels dropped so far, 0-based: at the reference and by later frames.
    pub fn dropped_channels(&self) -> Vec<usize> {
        self.chain.reconstructor().channels().dropped()
    }

    /// The channels the last frame dropped, 0-based (empty unless it was [`Status::ChannelsDropped`]).
    pub fn newly_dropped(&self) -> &[usize] {
        &self.newly_dropped
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
        if self.imaged {
            self.chain.touches()
        } else {
            &[]
        }
    }

    /// The pseudo-array of the calibration, if one was given.
    pub fn pseudo_array(&self) -> Option<&PseudoArray> {
        self.chain.pseudo_array()
    }

    /// Feeds one frame (protocol order). A frame of the wrong length, or one that leaves more
    /// than a quarter of the channels dropped, is refused and changes nothing; a non-finite
    /// value on a used channel drops that channel (see the module doc).
    pub fn process(&mut self, frame: &[f64]) -> Result<Status, InverseError> {
        let count = self.chain.reconstructor().measurements();
        if frame.len() != count {
            return Err(InverseError::FrameLength { expected: count, got: frame.len() });
        }
        self.newly_dropped.clear();
        self.imaged = false;
        let installed = match self.delivered.take() {
            Some(derived) => Some(self.install(derived)?),
            None => None,
        };
        if self.reference.is_empty() {
            return self.collect(frame);
        }
        // A new reference's derivation put in: this frame says so (and is not imaged), whatever
        // it holds.
        if installed == Some(true) {
            let needed = self.params.frames_in_reference();
            return Ok(Status::Referencing { collected: needed, needed });
        }
        // A refresh put in: the next frame imaged says so.
        self.updated |= installed == Some(false);
        if let Some(ratio) = typical_ratio_in(frame, &self.reference, &mut self.ratios).filter(|r| !plausible_ratio(*r))
        {
            return Err(InverseError::FrameScale { ratio, restarted: false });
        }
        if self.deriving_reference {
            return Ok(Status::Deriving);
        }
        let channels = self.chain.reconstructor().channels();
        self.newly_dropped.extend((0..count).filter(|&m| channels.is_used(m) && !frame[m].is_finite()));
        if !self.newly_dropped.is_empty() {
            if let Err(e) = self.drop_new_channels() {
                self.newly_dropped.clear();
                return Err(e);
            }
        }
        let n = self.params.average.max(1);
        let imaged = if n > 1 {
            // The frame about to leave the ring joins the reference if none of the N means that
            // held it showed a touch: a press's first frames, in means that do not show it yet,
            // stay out.
            if let (true, Some(noise)) = (self.since_reference >= n && self.quiet >= n, self.noise.as_mut()) {
                let oldest = &self.ring[self.ring_next * count..(self.ring_next + 1) * count];
                grow_reference(&mut self.reference, noise, &self.params, oldest);
            }
            self.average(frame);
            &self.averaged
        } else {
            frame
        };
        self.since_reference += 1;
        let touched = !self.chain.process(&self.reference, imaged)?.is_empty();
        self.imaged = true;
        self.quiet = if touched { 0 } else { self.quiet + 1 };
        let mut status = match self.newly_dropped.len() {
            0 if std::mem::take(&mut self.updated) => Status::NoiseUpdated,
            0 => Status::Processed,
            count => Status::ChannelsDropped { count },
        };
        if !touched {
            if let Some(noise) = self.noise.as_mut() {
                noise.update(&self.reference, frame);
                self.since_refresh += 1.0;
                if self.since_refresh >= self.refreshed_at.clamp(1.0, REFRESH_MAX)
                    && status == Status::Processed
                    && !self.in_flight
                    && self.refresh()?
                {
                    status = Status::NoiseUpdated;
                }
            }
            if let (1, Some(noise)) = (n, self.noise.as_mut()) {
                grow_reference(&mut self.reference, noise, &self.params, frame);
            }
        }
        Ok(status)
    }

    /// Puts `frame` into the ring of the last frames, and their mean into `averaged`.
    fn average(&mut self, frame: &[f64]) {
        let count = frame.len();
        let n = self.params.average;
        self.ring[self.ring_next * count..(self.ring_next + 1) * count].copy_from_slice(frame);
        self.ring_next = (self.ring_next + 1) % n;
        self.averaged.fill(0.0);
        for past in self.ring.chunks_exact(count) {
            self.averaged.iter_mut().zip(past).for_each(|(a, v)| *a += v);
        }
        self.averaged.iter_mut().for_each(|a| *a /= n as f64);
    }

    /// λ, the channel weights and the threshold again, from the noise model as it is now, when
    /// the noise has changed since they were last derived ([`noise_changed`]), or the threshold
    /// alone when the reference has doubled or reached its limit since; whether they were
    /// (deferred: whether they were asked for; they come in later). Deriving takes a fifth of a
    /// second on the paper's sensor, so a steady sensor is not made to wait for it every
    /// [`REFRESH_MAX`] frames.
    fn refresh(&mut self) -> Result<bool, InverseError> {
        let Some(noise) = &self.noise else { return Ok(false) };
        self.refreshed_at = noise.frames();
        self.since_refresh = 0.0;
        let variance = noise.relative_variance();
        let changed = noise_changed(&self.refreshed_variance, &variance);
        let (count, derived) = (noise.reference_frames(), self.derived_reference_count);
        let grown = count >= 2 * derived || (count == self.params.reference_limit_frames() && derived < count);
        if !changed && !grown {
            return Ok(false);
        }
        let rederive = match (changed, self.params.auto_hyperparameter) {
            (true, true) => Rederive::Auto {
                channels: self.chain.reconstructor().channels().clone(),
                variance: Some(variance.clone()),
            },
            _ => Rederive::Keep,
        };
        let mut job = self.derivation(rederive, Vec::new());
        (job.variance, job.reference_count) = (changed.then_some(variance), Some(count));
        self.ask(job)?;
        Ok(!self.deferred.defers(false))
    }

    /// A derivation of `rederive` and the noise tests from the reference and noise as they are
    /// now (`frames`: the reference's own, to image for their peak).
    fn derivation(&self, rederive: Rederive, frames: Vec<Vec<f64>>) -> Derivation {
        Derivation {
            generation: self.generation,
            first: !frames.is_empty(),
            recon: std::sync::Arc::clone(self.chain.shared_reconstructor()),
            rederive,
            reference: self.reference.clone(),
            noise: self
                .noise
                .clone()
                .unwrap_or_else(|| NoiseModel::assumed(DEFAULT_RELATIVE_NOISE, self.reference.len(), 1)),
            params: self.params,
            polarity: self.chain.touch_params().polarity,
            press_model: self.chain.shared_press_model().cloned(),
            configured: self.configured.clone(),
            reference_frames: frames,
            variance: None,
            reference_count: None,
            frame_forms: self.chain.frame_forms(),
        }
    }

    /// Does `job` now, or hands it out when deferred.
    fn ask(&mut self, job: Derivation) -> Result<(), InverseError> {
        self.in_flight = true;
        self.deriving_reference = job.first;
        if self.deferred.defers(job.first) {
            self.asked = Some(job);
            return Ok(());
        }
        self.install(job.run()).map(|_| ())
    }

    /// Puts a derivation's result in; whether it completed a reference. A new reference that
    /// failed is dropped, and the next frames start another.
    fn install(&mut self, derived: Derived) -> Result<bool, InverseError> {
        self.in_flight = false;
        self.deriving_reference = false;
        let tests = match derived.result {
            Ok(tests) => tests,
            Err(e) => {
                if derived.first {
                    self.retake_reference();
                }
                return Err(e);
            }
        };
        if let Some(variance) = derived.variance {
            self.refreshed_variance = variance;
        }
        if let Some(count) = derived.reference_count {
            self.derived_reference_count = count;
        }
        if let Some(recon) = tests.recon {
            self.chain.set_reconstructor(recon);
        }
        if derived.first {
            self.noise_peak = tests.noise_peak;
            let floor = match self.params.noise_floor {
                NoiseFloor::Auto { factor } => factor * self.noise_peak,
                NoiseFloor::Fixed(value) => value,
                NoiseFloor::FalseAlarm { .. } => 0.0,
            };
            self.chain.set_min_peak(self.min_peak.max(floor));
        }
        self.chain.set_press_detection(tests.detection);
        self.chain.set_significance(tests.significance);
        Ok(derived.first)
    }

    /// Derives the reconstructor again without the channels of `newly_dropped`.
    fn drop_new_channels(&mut self) -> Result<(), InverseError> {
        let recon = self.chain.reconstructor();
        let mut used = recon.channels().used_mask().to_vec();
        self.newly_dropped.iter().for_each(|&m| used[m] = false);
        too_many_dropped(&used, &self.configured, self.newly_dropped.len())?;
        let rederive = Rederive::Fixed {
            hyperparameter: recon.params().hyperparameter,
            channels: recon.channels().clone().masked(&used),
        };
        // On this frame, whatever the mode: the frame is imaged without them. A derivation
        // asked for before is stale (it has them).
        self.forget_derivation();
        let job = self.derivation(rederive, Vec::new());
        self.in_flight = true;
        self.install(job.run()).map(|_| ())
    }

    /// Adds a frame to the reference, and takes it once enough are collected.
    fn collect(&mut self, frame: &[f64]) -> Result<Status, InverseError> {
        let needed = self.params.frames_in_reference();
        let used: Vec<bool> = self.missing.iter().zip(frame).map(|(missing, v)| !missing && v.is_finite()).collect();
        let lost = |m: usize| self.configured[m] && !self.missing[m] && !frame[m].is_finite();
        let new = (0..frame.len()).filter(|&m| lost(m)).count();
        too_many_dropped(&used, &self.configured, new)?;
        // A frame unlike the first of the reference (or a first frame of zeros) is refused, and
        // the reference starts again: which of the two is wrong cannot be told, and neither may
        // enter the mean.
        let first = self.collected.first().map_or(frame, Vec::as_slice);
        let ratio =
            if frame.iter().all(|v| *v == 0.0) { Some(0.0) } else { typical_ratio_in(frame, first, &mut self.ratios) };
        if let Some(ratio) = ratio.filter(|r| !plausible_ratio(*r)) {
            self.retake_reference();
            return Err(InverseError::FrameScale { ratio, restarted: true });
        }
        self.missing.iter_mut().zip(&used).for_each(|(missing, used)| *missing = !used);
        self.collected.push(frame.to_vec());
        if self.collected.len() < needed {
            return Ok(Status::Referencing { collected: self.collected.len(), needed });
        }
        if let Err(e) = self.take_reference() {
            self.retake_reference();
            return Err(e);
        }
        Ok(if self.deriving_reference { Status::Deriving } else { Status::Referencing { collected: needed, needed } })
    }

    /// Takes the mean of the frames collected as the reference, measures their noise, and asks
    /// for what they give ([`Derivation`]: λ, the weights, the noise tests).
    fn take_reference(&mut self) -> Result<(), InverseError> {
        self.reference = mean_of_finite(&self.collected);
        self.derived_reference_count = self.collected.len();
        (self.since_reference, self.quiet) = (0, 0);
        let measured = NoiseModel::from_frames(&self.collected);
        self.noise_measured = measured.is_some();
        let count = self.reference.len();
        let noise =
            measured.unwrap_or_else(|| NoiseModel::assumed(DEFAULT_RELATIVE_NOISE, count, self.collected.len()));
        self.refreshed_at = noise.frames();
        self.since_refresh = 0.0;
        self.refreshed_variance = noise.relative_variance();
        self.noise = Some(noise);
        self.noise_peak = 0.0;
        // The moving average starts from the last reference frames (the reference itself where
        // there are fewer).
        let n = self.params.average.max(1);
        for k in 0..n {
            let past = (self.collected.len() + k).checked_sub(n).and_then(|i| self.collected.get(i));
            let slot = &mut self.ring[k * count..(k + 1) * count];
            slot.copy_from_slice(past.unwrap_or(&self.reference));
        }
        self.ring_next = 0;
        let frames = std::mem::take(&mut self.collected);
        let job = self.derivation(self.reference_rederive(), frames);
        self.ask(job)
    }

    /// The reconstructor for the new reference: without the channels it lacks or whose
    /// reference is zero, with λ given or chosen from the reference frames' noise.
    fn reference_rederive(&self) -> Rederive {
        // A reference of exactly zero is a dead channel (a board prints 0 for a broken contact).
        let alive: Vec<bool> = self.reference.iter().map(|r| *r != 0.0).collect();
        let keep: Vec<bool> = self.missing.iter().map(|missing| !missing).collect();
        let channels = Channels::all(self.reference.len()).masked(&self.configured).masked(&keep).masked(&alive);
        if self.params.auto_hyperparameter {
            let variance = self.noise.as_ref().filter(|_| self.noise_measured).map(NoiseModel::relative_variance);
            return Rederive::Auto { channels, variance };
        }
        Rederive::Fixed { hyperparameter: self.given_hyperparameter, channels }
    }
}

/// Adds `frame`, without a touch, to `reference`, the mean of as many frames as `noise` says:
/// as one more frame of its mean while it holds fewer than the limit of `params` (`noise` told),
/// and with the baseline rate α (the larger weight of the two).
fn grow_reference(reference: &mut [f64], noise: &mut NoiseModel, params: &PipelineParams, frame: &[f64]) {
    let count = noise.reference_frames();
    let growing = count < params.reference_limit_frames();
    let share = if growing { 1.0 / (count + 1) as f64 } else { 0.0 };
    let weight = share.max(params.baseline_rate);
    if growing {
        noise.set_reference_frames(count + 1);
    }
    if weight > 0.0 {
        for (r, v) in reference.iter_mut().zip(frame).filter(|(_, v)| v.is_finite()) {
            *r += weight * (v - *r);
        }
    }
}

/// Refuses a set of used channels that drops more than a quarter of the `configured` ones
/// (`new` of them for the first time).
fn too_many_dropped(used: &[bool], configured: &[bool], new: usize) -> Result<(), InverseError> {
    let bad: Vec<usize> = (0..used.len()).filter(|&m| configured[m] && !used[m]).map(|m| m + 1).collect();
    if bad.len() * 4 <= configured.iter().filter(|c| **c).count() {
        return Ok(());
    }
    Err(InverseError::TooManyBadChannels {
        bad: bad.len(),
        new,
        channels: used.len(),
        first: bad.into_iter().take(NAMED).collect(),
    })
}

#[cfg(test)]
mod tests {

    #[test]
    fn a_steady_noise_is_not_derived_again_but_a_changed_one_is() {
        let then = vec![1e-6; 120];
        let mut now: Vec<f64> = (0..120).map(|m| 1e-6 * (1.0 + 0.05 * ((m % 7) as f64 - 3.0) / 3.0)).collect();
        assert!(!noise_changed(&then, &now), "sampling wobble of ±5 % per channel");
        now.iter_mut().for_each(|v| *v *= 1.25);
        assert!(noise_changed(&then, &now), "the whole board 12 % noisier (25 % in variance)");
        let mut one = then.clone();
        one[17] *= 4.0;
        assert!(noise_changed(&then, &one), "one channel twice as noisy");
        assert!(noise_changed(&[], &then), "nothing derived yet");
    }
    use super::*;

    #[test]
    fn every_setting_is_checked_against_its_range() {
        assert_eq!(PipelineParams::default().check(), Ok(()));
        let refused = |params: PipelineParams| params.check().unwrap_err().to_string();
        let default = PipelineParams::default;
        assert_eq!(
            refused(PipelineParams { reference_frames: 0, ..default() }),
            "reference_frames must be 1 to 10000, got 0"
        );
        assert_eq!(
            refused(PipelineParams { reference_limit: 2_000_000, ..default() }),
            "reference_limit must be 1 to 1000000, got 2000000"
        );
        assert_eq!(refused(PipelineParams { average: 1001, ..default() }), "average must be 1 to 1000, got 1001");
        assert_eq!(
            refused(PipelineParams { baseline_rate: f64::NAN, ..default() }),
            "baseline_rate must be in [0, 1], got NaN"
        );
        for rate in [0.0, 0.6, f64::NAN] {
            let params = PipelineParams { noise_floor: NoiseFloor::FalseAlarm { rate }, ..default() };
            assert!(refused(params).starts_with("false_alarm_rate must be in (0, 0.5], got "));
        }
        let edge = PipelineParams { noise_floor: NoiseFloor::FalseAlarm { rate: 0.5 }, average: 1000, ..default() };
        assert_eq!(edge.check(), Ok(()));
    }
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
        let array = PseudoArray::of_sensor(&spec, [1, 1]).unwrap();
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
        // 31 of 120 channels missing is more than a quarter.
        let mut holes = skin.frame().unwrap();
        holes[..31].fill(f64::NAN);
        let err = pipeline.process(&holes).unwrap_err();
        let first = (1..=8).collect();
        assert_eq!(err, InverseError::TooManyBadChannels { bad: 31, new: 31, channels: 120, first });
        assert!(err.to_string().starts_with("31 of 120 channels are missing or not finite"), "{err}");
        assert_eq!(pipeline.process(&skin.frame().unwrap()).unwrap(), Status::Referencing { collected: 1, needed: 10 });
    }

    /// A frame of zeros, of the other sign or in another unit is no press: while the reference is
    /// taken it starts the reference again, after it it is refused and changes nothing.
    #[test]
    fn a_frame_unlike_its_reference_is_refused_and_never_averaged_in() {
        let (mut pipeline, mut skin) = setup();
        let zeros = vec![0.0; 120];
        let refused = |e: InverseError| matches!(e, InverseError::FrameScale { .. });
        assert!(refused(pipeline.process(&zeros).unwrap_err()));
        let good = skin.frame().unwrap();
        assert_eq!(pipeline.process(&good).unwrap(), Status::Referencing { collected: 1, needed: 10 });
        let negated: Vec<f64> = good.iter().map(|v| -v).collect();
        let err = pipeline.process(&negated).unwrap_err();
        assert!(err.to_string().contains("starts again"), "{err}");
        assert!(refused(err));
        for k in 1..=10 {
            assert_eq!(
                pipeline.process(&skin.frame().unwrap()).unwrap(),
                Status::Referencing { collected: k, needed: 10 }
            );
        }
        let reference = pipeline.reference().unwrap().to_vec();
        for bad in [zeros, negated, good.iter().map(|v| v * 1e3).collect()] {
            let err = pipeline.process(&bad).unwrap_err();
            assert!(!err.to_string().contains("starts again"), "{err}");
            assert!(refused(err));
        }
        assert_eq!(pipeline.reference().unwrap(), reference.as_slice());
        assert_eq!(pipeline.process(&skin.frame().unwrap()).unwrap(), Status::Processed);
    }

    /// A channel missing from a reference frame is dropped; the reference is the mean of the rest.
    #[test]
    fn a_channel_missing_from_the_reference_is_dropped() {
        let (mut pipeline, mut skin) = setup();
        for k in 0..10 {
            let mut frame = skin.frame().unwrap();
            if k == 4 {
                frame[3] = f64::NAN;
            }
            pipeline.process(&frame).unwrap();
        }
        assert_eq!(pipeline.dropped_channels(), [3]);
        assert!(pipeline.reference().unwrap().iter().all(|r| r.is_finite()));
        skin.press([-0.05, 0.02], 10.0);
        assert_eq!(pipeline.process(&skin.frame().unwrap()).unwrap(), Status::Processed);
        let c = pipeline.touches()[0].touch.centre;
        assert!((c[0] + 0.05).hypot(c[1] - 0.02) < 0.015, "{c:?}");
        // The reference frames named the channel; taking the reference again restores it.
        pipeline.retake_reference();
        skin.release();
        for _ in 0..10 {
            pipeline.process(&skin.frame().unwrap()).unwrap();
        }
        assert!(pipeline.dropped_channels().is_empty());
    }

    /// Averaging N frames takes a reference N times as long: its noise, in every Δv, stays the
    /// same share of a frame imaged's.
    #[test]
    fn averaging_lengthens_the_reference() {
        let (pipeline, mut skin) = setup();
        let params = PipelineParams { reference_frames: 3, average: 4, ..PipelineParams::default() };
        let mut pipeline = Pipeline::new(pipeline.chain().clone(), params);
        for k in 1..=12 {
            let status = pipeline.process(&skin.frame().unwrap()).unwrap();
            assert_eq!(status, Status::Referencing { collected: k, needed: 12 });
        }
        assert_eq!(pipeline.noise().map(|n| n.reference_frames()), Some(12));
        assert_eq!(pipeline.process(&skin.frame().unwrap()).unwrap(), Status::Processed);
    }

    /// Frames without a touch join the reference's mean up to its limit; a touched frame does not.
    #[test]
    fn the_reference_grows_on_frames_without_a_touch_up_to_its_limit() {
        let (pipeline, mut skin) = setup();
        let params = PipelineParams { reference_frames: 4, reference_limit: 12, ..PipelineParams::default() };
        let mut pipeline = Pipeline::new(pipeline.chain().clone(), params);
        let untouched: Vec<Vec<f64>> = (0..15).map(|_| skin.frame().unwrap()).collect();
        skin.press([0.03, 0.02], 10.0);
        let pressed = skin.frame().unwrap();
        for frame in &untouched[..8] {
            pipeline.process(frame).unwrap();
        }
        pipeline.process(&pressed).unwrap();
        assert_eq!(pipeline.touches().len(), 1, "the pressed frame has its touch");
        for frame in &untouched[8..] {
            pipeline.process(frame).unwrap();
            assert!(pipeline.touches().is_empty(), "{:?}", pipeline.touches());
        }
        let mean: Vec<f64> = (0..120).map(|m| untouched[..12].iter().map(|f| f[m]).sum::<f64>() / 12.0).collect();
        let reference = pipeline.reference().unwrap();
        let off = reference.iter().zip(&mean).map(|(r, m)| ((r - m) / m).abs()).fold(0.0, f64::max);
        assert!(off < 1e-12, "the reference is the mean of the first 12 untouched frames, off by {off:e}");
        assert_eq!(pipeline.noise().map(NoiseModel::reference_frames), Some(12));
    }

    /// Averaging N frames, a frame joins the reference as it leaves the ring, and only if none of
    /// the N means that held it showed a touch: the frames beside a press stay out with it.
    #[test]
    fn averaged_frames_join_the_reference_only_when_no_mean_that_held_them_was_touched() {
        let (pipeline, mut skin) = setup();
        let params =
            PipelineParams { reference_frames: 2, average: 4, reference_limit: 4, ..PipelineParams::default() };
        let mut pipeline = Pipeline::new(pipeline.chain().clone(), params);
        let reference: Vec<Vec<f64>> = (0..8).map(|_| skin.frame().unwrap()).collect();
        let untouched: Vec<Vec<f64>> = (0..18).map(|_| skin.frame().unwrap()).collect();
        skin.press([0.03, 0.02], 15.0);
        let pressed = skin.frame().unwrap();
        for frame in &reference {
            pipeline.process(frame).unwrap();
        }
        // Frames imaged: u0…u5, the pressed one, u6…u17; the four means that hold it are touched.
        let stream: Vec<&[f64]> = untouched[..6]
            .iter()
            .map(Vec::as_slice)
            .chain([pressed.as_slice()])
            .chain(untouched[6..].iter().map(Vec::as_slice))
            .collect();
        let mut touched = Vec::new();
        for frame in &stream {
            pipeline.process(frame).unwrap();
            touched.push(!pipeline.touches().is_empty());
        }
        let expected: Vec<bool> = (0..stream.len()).map(|t| (6..10).contains(&t)).collect();
        assert_eq!(touched, expected);
        // u0, u1 and u2 left the ring before the press; u3…u8 shared a mean with it; u9…u13 then
        // filled the reference to its 16 frames.
        let joined: Vec<&Vec<f64>> = reference.iter().chain(&untouched[..3]).chain(&untouched[9..14]).collect();
        let mean: Vec<f64> = (0..120).map(|m| joined.iter().map(|f| f[m]).sum::<f64>() / 16.0).collect();
        let off = pipeline.reference().unwrap().iter().zip(&mean).map(|(r, m)| ((r - m) / m).abs()).fold(0.0, f64::max);
        assert!(off < 1e-12, "the reference is off the mean of its 16 frames by {off:e}");
        assert_eq!(pipeline.noise().map(NoiseModel::reference_frames), Some(16));
    }

    #[test]
    fn baseline_update_follows_drift_without_touches() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 800;
        let recon = Reconstructor::new(&spec.forward_model().unwrap(), 1.0, &ReconstructorParams::default()).unwrap();
        let params = PipelineParams {
            reference_frames: 3,
            reference_limit: 3,
            baseline_rate: 0.5,
            noise_floor: NoiseFloor::Fixed(0.01),
            auto_hyperparameter: false,
            average: 1,
            carry_presses: true,
        };
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
