//! The JSON-lines stream of `eitskin run`: one JSON object per line, what other programs read
//! from its standard output, what the live viewer receives, and (the touches) what a recording
//! made with `--record` attaches to each frame.
//!
//! # Version
//!
//! The stream says its version once, in its first line, the [`Start`] event: format
//! `"eitskin-run"`, [`VERSION`], with what a reader needs to understand the rest (the length
//! unit, the number of measurements). One line at the start rather than a field in every line:
//! frames stay short, and the unit, which the numbers cannot carry, is stated once. The version
//! goes up whenever a field or an event is added, removed or changes meaning, so the types here,
//! which refuse unknown fields, read exactly their version. Version 2 added the start line's
//! `normalised` and `polarity`, each touch's `sign`, the frame line's optional `raster` and the
//! `reference_taken` and `channels_dropped` events; a version-1 touch (no `sign`) reads as a
//! decrease, which was then the only kind. Version 3 added the noise test: the start line's
//! `average`, `peak_of` and `false_alarm_rate`, each touch's `z`, the `reference_taken` event's
//! `threshold`, `noise` and `noise_measured`, and the `noise_updated` event; read from an older
//! line they are absent (`null`, or 1 frame averaged and the frame's peak). Version 4 added the
//! press's `radius` (the indenter's, or fitted where the data ask for it); absent before.
//! Version 5 added the start line's `reference_limit` (`null` before), and a `noise_updated`
//! event also when the grown reference gave the threshold anew.
//! Version 6 added each touch's `force_std` (`null` before); with presses fitted to Δv, a
//! touch's `force` is since then the mean of its posterior over the calibrated range, no longer
//! the curve's inverse clamped to it. Version 7 named a touch's pseudo-array area
//! `calibration_area`. Version 8 added the `silent` and `resumed` events of a network source.
//!
//! # Lines
//!
//! A line with an `"event"` field is an [`Event`]; any other is a [`FrameLine`]. Frames come in
//! order; events come where they happened, between frames.
//!
//! ```text
//! {"event":"start","format":"eitskin-run","version":6,"source":"sim","length_unit":"mm","measurements":120,"reference_frames":10,"reference_limit":100,"normalised":false,"polarity":"decrease","average":1,"peak_of":"frame","false_alarm_rate":0.001}
//! {"event":"reference_taken","hyperparameter":0.031,"chosen":true,"normalised":false,"channels_dropped":[],"threshold":4.6,"noise":0.0005,"noise_measured":true,"detail":"…"}
//! {"seq":10,"t":0.5,"status":"ok","touches":[{"sign":"decrease","x":-49.1,"y":41.7,"peak":0.63,"z":48.2,"unit":7,"calibration_area":2,"force":8.7,"force_std":0.3,"saturated":false,"press":{"x":-50.2,"y":40.1,"drop":0.41,"radius":10.0}}],"counters":{"frames":11,"bad":0},"recorded":true}
//! {"event":"bad","seq":11,"reason":"frame seq 11 has 3 values, expected 120; …"}
//! ```
//!
//! The frame line ([`FrameLine`]):
//!
//! | field       | meaning                                                                         |
//! |-------------|---------------------------------------------------------------------------------|
//! | `seq`       | the frame's sequence number from the source (board counter; lines or table rows counted from 0; as recorded); messages call it "frame seq" |
//! | `t`         | the frame's time, in s (the source's clock, as recorded, or since the port opened) |
//! | `status`    | `"referencing"` (the reference is being taken, or what it gives derived; no touches) or `"ok"` (imaged) |
//! | `touches`   | the touches found, strongest first; each a [`Touch`], below                      |
//! | `counters`  | `frames`: frames processed so far, this one included; `bad`: input skipped so far (bad frames, damaged records); `viewer_dropped`: messages that did not reach a viewer page, only when a viewer runs |
//! | `recorded`  | `true` once the frame is in the recording; absent when not recording            |
//! | `raster`    | with `eitskin run --stream-image` only: the frame's image, a [`Raster`]: `nx`, `ny`, `bounds` (`[[x_min, y_min], [x_max, y_max]]` in the length unit) and `values`, Δσ in S/m, `ny` rows of `nx` from the top row (largest y), `null` outside the outline |
//! | `learned`   | with `eitskin run --model` and a touch only: the learned model's answer, a [`Learned`]: `x`, `y` (the length unit), and when it has them `force` (N), `position_std` (the length unit) and `force_std` (N) |
//!
//! A touch ([`Touch`]): `sign`, `"decrease"` (less conductive, a press on a hydrogel) or
//! `"increase"`; `x`, `y`, its centre of gravity in the spec's length unit (`length_unit`
//! of the start line), relative to the outline's centre; `peak`, the strongest conductivity
//! change in the touch's own direction, in S/m (positive); `z`, that peak over the noise's
//! standard deviation at its pixel (its detection confidence; `null` without the noise test);
//! `unit` and `calibration_area`, the pseudo-array unit holding the centre and the area of
//! symmetry it belongs to (the paper's six), each counted from 1, or `null` without a
//! calibration (`area` before version 7; `area` elsewhere is a touch's size); `force`, in N,
//! `force_std`, its standard deviation from the noise in N (with a press fitted to Δv whitened
//! by the measured noise: the force is then the mean of its posterior over the calibrated
//! range, see [`eitskin::calibration::Curve::force_given`]; else, and before version 6, `null`),
//! and `saturated`, whether the reading lay where the curve's inverse leaves the calibrated
//! range (the force is then its end, or with `force_std` what forces in the range could have
//! given it), or `null` without a calibration; `press`, the press fitted to Δv, `{x, y, drop}` (centre in the length unit,
//! conductivity drop under the indenter as a fraction of the background), or `null` without
//! press fitting.
//!
//! The events ([`Event`]), by their `event` field:
//!
//! | `event`        | fields                                                                       |
//! |----------------|------------------------------------------------------------------------------|
//! | `start`        | `format` (`"eitskin-run"`), `version`, `source` (as given), `length_unit` (`"mm"` or `"m"`), `measurements` (values per frame), `reference_frames` (frames averaged into the reference), `reference_limit` (frames the reference grows to on frames without a touch, or `null` before version 5), `normalised` (differences Δv/v_ref), `polarity` (`"decrease"`, `"increase"` or `"both"`: which changes are touches), `average` (frames averaged into each frame imaged), `peak_of` (`"frame"` or `"touch"`: whose peak a touch's threshold is a fraction of), `false_alarm_rate` (false touches allowed per frame without a touch, or `null` without the noise test) |
//! | `reference_taken` | the reference is taken: `hyperparameter` (λ imaged with), `chosen` (whether λ was chosen from the reference frames' noise), `normalised`, `channels_dropped` (1-based: missing from a reference frame, or with a zero reference when normalised), `threshold` (the z a touch's peak must reach, or `null`), `noise` (the median channel's noise standard deviation relative to its value), `noise_measured` (false: assumed, from a single reference frame), `image_noise` (the image's noise standard deviation at its median pixel, in S/m: times `threshold`, the change a touch must reach there), `detail` |
//! | `noise_updated` | the noise model, grown on the frames without a touch, gave λ, channel weights and the threshold anew after frame `seq` (or the reference, grown on them, the threshold): `frames` (frames behind the noise model), `hyperparameter`, `threshold`, `noise`, `image_noise`, `detail` |
//! | `channels_dropped` | channels went bad (not finite) in frame `seq` and are dropped until the reference is taken again: `channels` (1-based), `dropped` (channels dropped in all), `detail` |
//! | `bad`          | `seq` (where in the stream, or `null` for bytes that belong to no frame), `reason` (a sentence) |
//! | `skipped`      | a damaged record of a recording: `line` (from 1, the header is line 1), `torn` (the last record, torn by a crash), `reason` |
//! | `disconnected` | `path` (the port), `detail` (why, as the operating system said it)            |
//! | `reconnected`  | `path`, `outage_s` (how long the port was away, in s), `detail`               |
//! | `silent`       | a network source's frames stopped: `source` (as given), `after_s` (s since its last frame), `detail` |
//! | `resumed`      | they came again: `source`, `outage_s` (s from the last frame before to the first after), `detail` |
//! | `reference`    | the reference is taken again from the next frames; `detail` (who asked)       |
//!
//! Reading a stream back:
//!
//! ```
//! use eitskin_io::stream::{Event, Line, Status};
//! let text = r#"{"event":"start","format":"eitskin-run","version":2,"source":"sim","length_unit":"mm","measurements":120,"reference_frames":10,"normalised":false,"polarity":"decrease"}
//! {"seq":0,"t":0.0,"status":"referencing","touches":[],"counters":{"frames":1,"bad":0}}"#;
//! let lines: Vec<Line> = text.lines().map(Line::parse).collect::<Result<_, _>>()?;
//! assert!(matches!(&lines[0], Line::Event(Event::Start(start)) if start.length_unit == "mm"));
//! assert!(matches!(&lines[1], Line::Frame(frame) if frame.status == Status::Referencing));
//! assert!(Line::parse(r#"{"seq":0,"t":0.0,"status":"ok","touches":[],"counters":{"frames":1,"bad":0},"x":1}"#).is_err());
//! # Ok::<(), serde_json::Error>(())
//! ```
//!
//! Writing reuses the caller's buffers: [`write_line`] prints straight into a writer, and a
//! [`FrameLine`] kept from frame to frame refills its touches in place ([`FrameLine::set_touches`]).
//!
//! Not for: the recording format (that is [`recorder`](crate::recorder)), or the viewer's setup
//! message.

use std::borrow::Cow;
use std::io::Write;

use eitskin::pipeline::TouchForce;
use serde::{Deserialize, Deserializer, Serialize};

use crate::source::Acquired;

/// Writes a value an image holds in single precision (a pixel's Δσ, S/m) as the shortest decimal
/// that reads back as that `f32`: widened to `f64` it would print 0.32798558473587036 where
/// 0.32798558 says all it holds.
pub fn single_precision<S: serde::Serializer>(value: &f64, serializer: S) -> Result<S::Ok, S::Error> {
    serializer.serialize_f32(*value as f32)
}

/// The `format` of the start line.
pub const FORMAT: &str = "eitskin-run";

/// The version of the stream this crate writes and reads.
pub const VERSION: u32 = 8;

/// Any line of the stream, for readers: an event if it has an `event` field, else a frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Line {
    /// A line with an `event` field.
    Event(Event),
    /// A processed frame.
    Frame(FrameLine),
}

impl Line {
    /// Reads one line of text.
    pub fn parse(text: &str) -> serde_json::Result<Line> {
        serde_json::from_str(text)
    }
}

impl<'de> Deserialize<'de> for Line {
    /// An event if the object has an `event` field, else a frame: the errors are those of the one
    /// type it must be (an unknown field named), not "matches no variant".
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Line, D::Error> {
        use serde::de::Error;
        let value = serde_json::Value::deserialize(deserializer)?;
        if value.get("event").is_some() {
            Event::deserialize(value).map(Line::Event).map_err(D::Error::custom)
        } else {
            FrameLine::deserialize(value).map(Line::Frame).map_err(D::Error::custom)
        }
    }
}

/// A processed frame; see the [module doc](self) for every field.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameLine {
    /// The frame's sequence number from the source.
    pub seq: u64,
    /// The frame's time, in s.
    pub t: f64,
    /// Whether the frame went into the reference or was imaged.
    pub status: Status,
    /// The touches found (none while referencing).
    pub touches: Vec<Touch>,
    /// Frames and bad input so far.
    pub counters: Counters,
    /// Whether the frame is in the recording (written only when true).
    #[serde(default, skip_serializing_if = "is_false")]
    pub recorded: bool,
    /// The frame's image, with `eitskin run --stream-image` (written only then).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub raster: Option<Raster>,
    /// A learned model's answer for the frame's press, with `eitskin run --model` when the
    /// frame has a touch (written only then).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub learned: Option<Learned>,
}

/// A learned model's answer (`eitskin learn`): where, how hard, how sure.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Learned {
    /// The position, in the length unit.
    pub x: f64,
    /// The position, in the length unit.
    pub y: f64,
    /// The force in N, when the model learned forces.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force: Option<f64>,
    /// The position's standard deviation, in the length unit (a Gaussian process's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position_std: Option<f64>,
    /// The force's standard deviation, in N.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force_std: Option<f64>,
    /// The indenter's depth, in the length unit, when the model learned depths.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depth: Option<f64>,
    /// The depth's standard deviation, in the length unit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub depth_std: Option<f64>,
}

impl Learned {
    /// The answer `p` (positions in m) with positions in units of `metres` m.
    pub fn new(p: &eitskin::learn::Prediction, metres: f64) -> Learned {
        Learned {
            x: p.position[0] / metres,
            y: p.position[1] / metres,
            force: p.force,
            position_std: p.position_std.map(|s| s / metres),
            force_std: p.force_std,
            depth: p.depth.map(|d| d / metres),
            depth_std: p.depth_std.map(|s| s / metres),
        }
    }
}

/// A frame's image as data: Δσ per pixel, row 0 at the top, `null` outside the outline.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Raster {
    /// Columns.
    pub nx: usize,
    /// Rows.
    pub ny: usize,
    /// The box covered, `[[x_min, y_min], [x_max, y_max]]`, in the length unit.
    pub bounds: [[f64; 2]; 2],
    /// Δσ per pixel, in S/m, row-major from the top row; `None` (null) outside the outline.
    pub values: Vec<Option<f32>>,
}

impl Raster {
    /// Refills this raster with `image` (positions in m) in units of `metres` m, reusing its memory.
    pub fn set(&mut self, image: &eitskin::image::Image, metres: f64) {
        [self.nx, self.ny] = image.size;
        self.bounds = image.bounds.map(|p| p.map(|c| c / metres));
        self.values.clear();
        self.values.extend(image.values.iter().zip(&image.inside).map(|(v, inside)| inside.then_some(*v)));
    }
}

impl FrameLine {
    /// Replaces the touches by `touches` (positions in m) with positions in units of `metres` m,
    /// reusing the list's memory.
    pub fn set_touches(&mut self, touches: &[TouchForce], metres: f64) {
        self.touches.clear();
        self.touches.extend(touches.iter().map(|t| Touch::new(t, metres)));
    }
}

/// The line as JSON text, without its new line (for printing one line now and then; a loop over
/// frames writes with [`write_line`], which allocates nothing).
impl std::fmt::Display for FrameLine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&serde_json::to_string(self).map_err(|_| std::fmt::Error)?)
    }
}

/// What became of a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    /// The frame went into the reference (`"referencing"`).
    #[default]
    Referencing,
    /// The frame was imaged (`"ok"`).
    Ok,
}

impl From<eitskin::pipeline::Status> for Status {
    fn from(status: eitskin::pipeline::Status) -> Status {
        match status {
            eitskin::pipeline::Status::Referencing { .. } | eitskin::pipeline::Status::Deriving => Status::Referencing,
            eitskin::pipeline::Status::Processed
            | eitskin::pipeline::Status::ChannelsDropped { .. }
            | eitskin::pipeline::Status::NoiseUpdated => Status::Ok,
        }
    }
}

/// A touch; lengths in the stream's length unit, relative to the outline's centre.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Touch {
    /// The sign of the change (a version-1 touch, without it, was a decrease).
    #[serde(default)]
    pub sign: Sign,
    /// Centre of gravity, x.
    pub x: f64,
    /// Centre of gravity, y.
    pub y: f64,
    /// The strongest conductivity change in the touch's own direction, in S/m (positive), in
    /// the image's single precision (written as the shortest decimal that reads back as it).
    pub peak: f32,
    /// That peak over the noise's standard deviation at its pixel (dimensionless), with the noise test.
    #[serde(default)]
    pub z: Option<f64>,
    /// The pseudo-array unit holding the centre, from 1, with a calibration.
    pub unit: Option<usize>,
    /// That unit's calibration area (of the pseudo-array's symmetry), from 1, with a calibration
    /// (`area` before version 7).
    #[serde(alias = "area")]
    pub calibration_area: Option<usize>,
    /// The force, in N, with a calibration.
    pub force: Option<f64>,
    /// The force's standard deviation from the noise, in N, where it is known (from version 6).
    #[serde(default)]
    pub force_std: Option<f64>,
    /// Whether the reading lay where the curve's inverse leaves the calibrated range, with a
    /// calibration.
    pub saturated: Option<bool>,
    /// The press fitted to Δv, with press fitting.
    pub press: Option<Press>,
}

impl Touch {
    /// The touch of the pipeline `t` (positions in m, unit and calibration area from 0), positions
    /// in units of `metres` m, unit and calibration area from 1.
    pub fn new(t: &TouchForce, metres: f64) -> Touch {
        Touch {
            sign: Sign::of(t.touch.polarity),
            x: t.touch.centre[0] / metres,
            y: t.touch.centre[1] / metres,
            peak: t.touch.peak as f32,
            z: t.touch.significance,
            unit: t.unit.map(|u| u + 1),
            calibration_area: t.area.map(|a| a + 1),
            force: t.force.map(|f| f.newtons),
            force_std: t.force.and_then(|f| f.std),
            saturated: t.force.map(|f| f.saturated),
            press: t.press.map(|p| Press {
                x: p.centre[0] / metres,
                y: p.centre[1] / metres,
                drop: p.drop,
                radius: Some(p.radius / metres),
            }),
        }
    }
}

/// The sign of a touch's change, written as [`Polarity::name`](eitskin::touch::Polarity::name).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Sign {
    /// Less conductive (a press on a hydrogel).
    #[default]
    Decrease,
    /// More conductive.
    Increase,
}

impl Sign {
    /// The sign of a touch's polarity (a touch has one sign; `Both` never tags one).
    pub fn of(polarity: eitskin::touch::Polarity) -> Sign {
        match polarity {
            eitskin::touch::Polarity::Increase => Sign::Increase,
            _ => Sign::Decrease,
        }
    }
}

/// A press fitted to Δv.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Press {
    /// Centre of the indenter, x, in the length unit.
    pub x: f64,
    /// Centre of the indenter, y, in the length unit.
    pub y: f64,
    /// The conductivity drop under the indenter, as a fraction of the background.
    pub drop: f64,
    /// Radius of the press, in the length unit: the indenter's, or fitted (absent before
    /// version 4).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
}

/// How many frames were processed and how much input was skipped, so far.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Counters {
    /// Frames processed, this one included.
    pub frames: u64,
    /// Input skipped: bad frames, frames the pipeline refused, damaged records.
    pub bad: u64,
    /// Messages that did not reach a viewer page, when a viewer runs (written only then).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub viewer_dropped: Option<u64>,
}

/// A line that is not a frame; see the [module doc](self) for every field.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "event", rename_all = "snake_case", deny_unknown_fields)]
pub enum Event {
    /// The first line: format, version and what the rest needs.
    Start(Start),
    /// Input that was skipped.
    Bad {
        /// Where in the stream, if it belongs to a frame.
        seq: Option<u64>,
        /// Why, as a sentence.
        reason: String,
    },
    /// A damaged record of a recording, skipped.
    Skipped {
        /// Its line, from 1 (the header is line 1).
        line: usize,
        /// Whether it is the last record, torn by a crash while it was written.
        torn: bool,
        /// What is wrong with it.
        reason: String,
    },
    /// The serial port went away; it is being reopened.
    Disconnected {
        /// The port.
        path: String,
        /// What happened, as a sentence.
        detail: String,
    },
    /// The serial port is back.
    Reconnected {
        /// The port.
        path: String,
        /// How long it was away, in s.
        outage_s: f64,
        /// What happened, as a sentence.
        detail: String,
    },
    /// A network source's frames stopped.
    Silent {
        /// The source, as given.
        source: String,
        /// Time since its last frame, in s.
        after_s: f64,
        /// What happened, as a sentence.
        detail: String,
    },
    /// A network source's frames came again.
    Resumed {
        /// The source, as given.
        source: String,
        /// Time from its last frame before to the first after, in s.
        outage_s: f64,
        /// What happened, as a sentence.
        detail: String,
    },
    /// The reference is taken again from the next frames.
    Reference {
        /// Who asked, as a sentence.
        detail: String,
    },
    /// The reference is taken: what the frames after it are imaged with.
    ReferenceTaken {
        /// λ imaged with (dimensionless).
        hyperparameter: f64,
        /// Whether λ was chosen from the reference frames' noise (`--hyperparameter auto`).
        chosen: bool,
        /// Whether differences are normalised (Δv/v_ref).
        normalised: bool,
        /// Channels left out from the start, 1-based.
        channels_dropped: Vec<usize>,
        /// The z a touch's peak must reach, with the noise test.
        #[serde(default)]
        threshold: Option<f64>,
        /// The median channel's noise standard deviation relative to its value (dimensionless).
        #[serde(default)]
        noise: Option<f64>,
        /// Whether the noise was measured (false: assumed, from a single reference frame).
        #[serde(default)]
        noise_measured: bool,
        /// The image's noise at its median pixel, in S/m: with `threshold`, the change a touch
        /// must reach there.
        #[serde(default)]
        image_noise: Option<f64>,
        /// The same, as a sentence.
        detail: String,
    },
    /// The noise model, grown on frames without a touch, gave λ, weights and threshold anew.
    NoiseUpdated {
        /// The frame after which it did.
        seq: u64,
        /// Frames behind the noise model.
        frames: f64,
        /// λ imaged with from now on (dimensionless).
        hyperparameter: f64,
        /// The z a touch's peak must reach, with the noise test.
        threshold: Option<f64>,
        /// The median channel's noise standard deviation relative to its value (dimensionless).
        noise: f64,
        /// The image's noise at its median pixel, in S/m.
        image_noise: Option<f64>,
        /// The same, as a sentence.
        detail: String,
    },
    /// Channels went bad in a frame and are dropped until the reference is taken again.
    ChannelsDropped {
        /// The frame.
        seq: u64,
        /// The channels that went bad, 1-based.
        channels: Vec<usize>,
        /// Channels dropped in all, these included.
        dropped: usize,
        /// What happened, as a sentence.
        detail: String,
    },
}

impl Event {
    /// The event line of an item of a source; `None` for a frame, which becomes a [`FrameLine`].
    pub fn of(item: &Acquired) -> Option<Event> {
        Some(match item {
            Acquired::Frame { .. } => return None,
            Acquired::Bad(bad) => Event::Bad { seq: bad.seq(), reason: bad.to_string() },
            Acquired::Skipped { record, torn_tail } => {
                Event::Skipped { line: record.line, torn: *torn_tail, reason: record.damage.to_string() }
            }
            Acquired::Disconnected { path, error } => Event::Disconnected {
                path: path.display().to_string(),
                detail: format!("{} disconnected ({error}); reopening", path.display()),
            },
            Acquired::Reconnected { path, outage } => Event::Reconnected {
                path: path.display().to_string(),
                outage_s: outage.as_secs_f64(),
                detail: format!("{} is back after {:.2} s", path.display(), outage.as_secs_f64()),
            },
            Acquired::Silent { source, after } => Event::Silent {
                source: source.clone(),
                after_s: after.as_secs_f64(),
                detail: format!("{source}: no frame for {:.2} s; waiting for them to come again", after.as_secs_f64()),
            },
            Acquired::Resumed { source, outage } => Event::Resumed {
                source: source.clone(),
                outage_s: outage.as_secs_f64(),
                detail: format!("{source}: frames again, after {:.2} s without", outage.as_secs_f64()),
            },
        })
    }
}

/// The first line of the stream.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Start {
    /// Always [`FORMAT`].
    pub format: String,
    /// The stream's version, [`VERSION`] for this crate.
    pub version: u32,
    /// Where the frames come from, as given (`sim`, `file:PATH`, `serial:PATH@BAUD`).
    pub source: String,
    /// The unit of every length in the stream, `"mm"` or `"m"`.
    pub length_unit: String,
    /// The number of values in a frame.
    pub measurements: usize,
    /// The number of frames averaged into the reference.
    pub reference_frames: usize,
    /// The frames the reference grows to on frames without a touch (absent before version 5).
    #[serde(default)]
    pub reference_limit: Option<usize>,
    /// Whether differences are normalised (Δv/v_ref).
    pub normalised: bool,
    /// Which changes are touches: `"decrease"`, `"increase"` or `"both"`.
    pub polarity: String,
    /// Frames averaged into each frame imaged (1 before version 3).
    #[serde(default = "one")]
    pub average: usize,
    /// Whose peak a touch's threshold is a fraction of: `"frame"` or `"touch"`.
    #[serde(default = "frame_peak")]
    pub peak_of: String,
    /// False touches allowed per frame without a touch, with the noise test.
    #[serde(default)]
    pub false_alarm_rate: Option<f64>,
}

fn one() -> usize {
    1
}

fn frame_peak() -> String {
    eitskin::touch::PeakOf::Frame.name().to_owned()
}

impl Start {
    /// The start line of this crate's format and version, for absolute differences and presses
    /// that lower the conductivity (set `normalised` and `polarity` otherwise).
    pub fn new(source: String, length_unit: &str, measurements: usize, reference_frames: usize) -> Start {
        Start {
            format: FORMAT.to_owned(),
            version: VERSION,
            source,
            length_unit: length_unit.to_owned(),
            measurements,
            reference_frames,
            reference_limit: None,
            normalised: false,
            polarity: eitskin::touch::Polarity::Decrease.name().to_owned(),
            average: 1,
            peak_of: frame_peak(),
            false_alarm_rate: None,
        }
    }
}

/// What `eitskin run --record` attaches to each record of a recording (its `result`): the frame's
/// touches, as in its line.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Recorded<'a> {
    /// The touches, as in the frame's line.
    pub touches: Cow<'a, [Touch]>,
}

/// Writes `line` as one line of JSON (and its new line) straight into `out`.
pub fn write_line(out: &mut impl Write, line: &impl Serialize) -> std::io::Result<()> {
    serde_json::to_writer(&mut *out, line)?;
    out.write_all(b"\n")
}

/// Whether a flag is off (for `skip_serializing_if`).
fn is_false(flag: &bool) -> bool {
    !flag
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame() -> FrameLine {
        let touch = Touch {
            sign: Sign::Decrease,
            x: -50.5,
            y: 40.0,
            peak: 0.6,
            z: None,
            unit: Some(7),
            calibration_area: Some(2),
            force: Some(8.5),
            force_std: Some(0.25),
            saturated: Some(false),
            press: Some(Press { x: -50.0, y: 41.0, drop: 0.4, radius: Some(10.0) }),
        };
        FrameLine {
            seq: 12,
            t: 0.6,
            status: Status::Ok,
            touches: vec![touch],
            counters: Counters { frames: 13, bad: 1, viewer_dropped: None },
            recorded: false,
            raster: None,
            learned: None,
        }
    }

    fn text(line: &impl Serialize) -> String {
        let mut out = Vec::new();
        write_line(&mut out, line).unwrap();
        String::from_utf8(out).unwrap()
    }

    #[test]
    fn a_frame_line_keeps_the_field_names_consumers_read() {
        let line = text(&frame());
        assert_eq!(
            line,
            "{\"seq\":12,\"t\":0.6,\"status\":\"ok\",\"touches\":[{\"sign\":\"decrease\",\"x\":-50.5,\"y\":40.0,\"peak\":0.6,\"z\":null,\"unit\":7,\
             \"calibration_area\":2,\"force\":8.5,\"force_std\":0.25,\"saturated\":false,\"press\":{\"x\":-50.0,\"y\":41.0,\"drop\":0.4,\"radius\":10.0}}],\
             \"counters\":{\"frames\":13,\"bad\":1}}\n"
        );
        assert_eq!(Line::parse(line.trim_end()).unwrap(), Line::Frame(frame()));
        let mut recorded = FrameLine { recorded: true, ..frame() };
        recorded.counters.viewer_dropped = Some(3);
        let line = text(&recorded);
        assert!(line.contains("\"viewer_dropped\":3}") && line.ends_with(",\"recorded\":true}\n"), "{line}");
        assert_eq!(Line::parse(&line).unwrap(), Line::Frame(recorded));
    }

    #[test]
    fn without_a_calibration_unit_area_force_and_press_are_null() {
        let touch = Touch {
            unit: None,
            calibration_area: None,
            force: None,
            force_std: None,
            saturated: None,
            press: None,
            ..frame().touches[0]
        };
        assert_eq!(
            text(&touch),
            "{\"sign\":\"decrease\",\"x\":-50.5,\"y\":40.0,\"peak\":0.6,\"z\":null,\"unit\":null,\"calibration_area\":null,\"force\":null,\"force_std\":null,\"saturated\":null,\
             \"press\":null}\n"
        );
    }

    #[test]
    fn events_are_tagged_and_read_back() {
        let events = [
            Event::Start(Start::new("sim".into(), "mm", 120, 10)),
            Event::Bad { seq: None, reason: "12 bytes were skipped".into() },
            Event::Skipped { line: 4, torn: true, reason: "cut".into() },
            Event::Disconnected { path: "/dev/ttyACM0".into(), detail: "gone".into() },
            Event::Reconnected { path: "/dev/ttyACM0".into(), outage_s: 0.25, detail: "back".into() },
            Event::Silent { source: "zenoh:board/a".into(), after_s: 1.0, detail: "gone".into() },
            Event::Resumed { source: "zenoh:board/a".into(), outage_s: 4.5, detail: "back".into() },
            Event::Reference { detail: "asked".into() },
            Event::ReferenceTaken {
                hyperparameter: 0.03,
                chosen: true,
                normalised: false,
                channels_dropped: vec![4],
                threshold: Some(4.6),
                noise: Some(5e-4),
                noise_measured: true,
                image_noise: Some(2e-3),
                detail: "λ".into(),
            },
            Event::NoiseUpdated {
                seq: 30,
                frames: 19.0,
                hyperparameter: 2.5,
                threshold: Some(4.5),
                noise: 4.9e-4,
                image_noise: None,
                detail: "grown".into(),
            },
            Event::ChannelsDropped { seq: 40, channels: vec![7, 9], dropped: 3, detail: "gone".into() },
        ];
        for event in events {
            let line = text(&event);
            let tag = line.split('"').nth(3).unwrap().to_owned();
            assert!(line.starts_with("{\"event\":"), "{line}");
            assert_eq!(Line::parse(&line).unwrap(), Line::Event(event), "{tag}");
        }
        assert_eq!(
            text(&Event::Bad { seq: Some(3), reason: "r".into() }),
            "{\"event\":\"bad\",\"seq\":3,\"reason\":\"r\"}\n"
        );
    }

    /// Each touch says its sign as the library names polarities; a version-1 touch, without
    /// one, reads as a decrease; the raster writes nulls outside the outline.
    #[test]
    fn signs_and_rasters_are_written_as_documented() {
        use eitskin::touch::Polarity;
        for polarity in [Polarity::Decrease, Polarity::Increase] {
            let touch = Touch { sign: Sign::of(polarity), ..frame().touches[0] };
            assert!(text(&touch).starts_with(&format!("{{\"sign\":\"{}\",", polarity.name())));
        }
        let old = r#"{"x":1.0,"y":2.0,"peak":0.5,"unit":null,"area":null,"force":null,"saturated":null,"press":null}"#;
        assert_eq!(serde_json::from_str::<Touch>(old).unwrap().sign, Sign::Decrease);
        let mut image = eitskin::image::Image::new([2, 1], [[-0.1, -0.05], [0.1, 0.05]], vec![true, false]);
        image.values[0] = -0.25;
        let mut raster = Raster::default();
        raster.set(&image, 1e-3);
        let line = FrameLine { raster: Some(raster), ..frame() };
        let written = text(&line);
        assert!(
            written.ends_with(
                ",\"raster\":{\"nx\":2,\"ny\":1,\"bounds\":[[-100.0,-50.0],[100.0,50.0]],\"values\":[-0.25,null]}}\n"
            ),
            "{written}"
        );
        assert_eq!(Line::parse(&written).unwrap(), Line::Frame(line));
    }

    #[test]
    fn unknown_fields_and_events_are_refused_by_name() {
        let error = Line::parse(r#"{"event":"bad","seq":1,"reason":"r","extra":2}"#).unwrap_err().to_string();
        assert!(error.contains("extra"), "{error}");
        let error = Line::parse(r#"{"event":"start","format":"eitskin-run","version":2,"source":"sim","length_unit":"mm","measurements":1,"reference_frames":1,"normalised":false,"polarity":"both","more":0}"#)
            .unwrap_err()
            .to_string();
        assert!(error.contains("more"), "{error}");
        assert!(Line::parse(r#"{"event":"party"}"#).unwrap_err().to_string().contains("party"));
        let error = Line::parse(r#"{"seq":1,"t":0,"status":"ok","touches":[],"counters":{"frames":1,"bad":0,"x":1}}"#)
            .unwrap_err()
            .to_string();
        assert!(error.contains("`x`"), "{error}");
    }

    #[test]
    fn what_a_recording_attaches_is_the_touches() {
        let line = frame();
        let recorded = Recorded { touches: Cow::Borrowed(&line.touches) };
        let value = serde_json::to_value(&recorded).unwrap();
        let back: Recorded<'static> = serde_json::from_value(value).unwrap();
        assert_eq!(back.touches.as_ref(), line.touches.as_slice());
    }
}
