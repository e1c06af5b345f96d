//! The run's loop: each item of the source through the pipeline and out to every sink, with the
//! sinks' requests (re-take the reference) taken between items.

use std::sync::mpsc;

use anyhow::Result;
use eitskin::inverse::Hyperparameter;
use eitskin::pipeline::{Pipeline, Status};
use eitskin::values::ValueKind;
use eitskin_io::source::{Acquired, SourceError};
use eitskin_io::stream::{Counters, Event, FrameLine, Raster};

use super::events::{channel_event, say};
use super::learned::LearnedAnswers;
use super::sink::{to_all, Flow, Processed, Sink};
use crate::viewer;

/// How frames are read and written, besides the pipeline's own settings.
pub struct Settings {
    /// What the board's numbers are.
    pub kind: ValueKind,
    /// The spec's length unit, in m.
    pub metres: f64,
    /// Whether each imaged frame's raster goes into its line.
    pub stream_image: bool,
    /// λ as asked: given, or chosen from the reference frames' noise.
    pub hyperparameter: Hyperparameter,
    /// Whether a sink records every frame (each line then says `recorded`).
    pub recorded: bool,
    /// The channels the spec's mask drops, from 0.
    pub masked: Vec<usize>,
    /// Whether the reference, noise and channel events and refused frames are also said on
    /// stderr (`run`'s; `serve` reports its sensors' events itself).
    pub say: bool,
}

/// What came of a run: frames processed, input refused, and whether a sink's reader went away.
#[derive(Debug, Clone, Copy, Default)]
pub struct Tally {
    /// Frames the pipeline took.
    pub frames: u64,
    /// Bad frames, frames the pipeline refused, damaged records.
    pub bad: u64,
    /// A sink's reader went away (stdout closed) and the run ended there.
    pub stopped: bool,
}

/// Where a [`Processing::drain`] left a source.
#[derive(Debug, Clone, Copy)]
pub enum Drained {
    /// Every item taken; the source goes on.
    Waiting,
    /// The most asked for taken; more may wait.
    More,
    /// The source ended, or a sink stopped the run.
    Ended(Tally),
}

/// The pipeline, the learned model's answers, and the buffers of a frame (allocated once).
pub struct Processing {
    /// The pipeline every frame goes through.
    pub pipeline: Pipeline,
    learned: Option<LearnedAnswers>,
    settings: Settings,
    /// The model's frame at the background, which signs magnitudes.
    model: Vec<f64>,
    /// The signed frame the pipeline takes, from what the board sends.
    signed: Vec<f64>,
    line: FrameLine,
    tally: Tally,
}

impl Processing {
    /// Frames through `pipeline` (and `learned`, when given), read and written as `settings` say.
    pub fn new(pipeline: Pipeline, learned: Option<LearnedAnswers>, settings: Settings) -> Processing {
        let model = pipeline.chain().reconstructor().linearisation().background().to_vec();
        let signed = vec![0.0; model.len()];
        Processing { pipeline, learned, settings, model, signed, line: FrameLine::default(), tally: Tally::default() }
    }

    /// Says nothing on stderr: its events go to its sinks only (`serve`'s sensors).
    pub fn quiet(&mut self) {
        self.settings.say = false;
    }

    /// What the board's numbers are.
    pub fn kind(&self) -> ValueKind {
        self.settings.kind
    }

    /// Takes every item of `items` until the source ends or a sink stops the run.
    pub fn drive(
        &mut self,
        items: &mpsc::Receiver<Result<Acquired, SourceError>>,
        sinks: &mut [Box<dyn Sink>],
    ) -> Result<Tally> {
        loop {
            let item = match items.try_recv() {
                Ok(item) => item,
                // Nothing waiting: the sinks hand on what they hold, and the loop waits.
                Err(mpsc::TryRecvError::Empty) => match to_all(sinks, |s| s.idle())? {
                    Flow::Stop => return Ok(self.stopped()),
                    Flow::Go => match items.recv() {
                        Ok(item) => item,
                        Err(_) => break,
                    },
                },
                Err(mpsc::TryRecvError::Disconnected) => break,
            };
            if self.take(item, sinks)? == Flow::Stop {
                return Ok(self.stopped());
            }
        }
        if to_all(sinks, |s| s.idle())? == Flow::Stop {
            return Ok(self.stopped());
        }
        Ok(self.tally)
    }

    /// Takes up to `most` of the items `items` holds now, without waiting for more (`serve`'s
    /// step of a sensor).
    pub fn drain(
        &mut self,
        items: &mpsc::Receiver<Result<Acquired, SourceError>>,
        sinks: &mut [Box<dyn Sink>],
        most: usize,
    ) -> Result<Drained> {
        for _ in 0..most {
            match items.try_recv() {
                Ok(item) => {
                    if self.take(item, sinks)? == Flow::Stop {
                        return Ok(Drained::Ended(self.stopped()));
                    }
                }
                Err(mpsc::TryRecvError::Empty) => {
                    let flow = to_all(sinks, |s| s.idle())?;
                    return Ok(if flow == Flow::Stop { Drained::Ended(self.stopped()) } else { Drained::Waiting });
                }
                Err(mpsc::TryRecvError::Disconnected) => {
                    let flow = to_all(sinks, |s| s.idle())?;
                    return Ok(Drained::Ended(if flow == Flow::Stop { self.stopped() } else { self.tally }));
                }
            }
        }
        Ok(Drained::More)
    }

    /// One item through the pipeline (a frame) or straight to the sinks (an event), after the
    /// sinks' requests.
    fn take(&mut self, item: Result<Acquired, SourceError>, sinks: &mut [Box<dyn Sink>]) -> Result<Flow> {
        Ok(self.requests(sinks)?.and(match item? {
            Acquired::Frame { seq, t, values } => self.frame(seq, t, &values, sinks)?,
            other => {
                if matches!(other, Acquired::Bad(_) | Acquired::Skipped { .. }) {
                    self.tally.bad += 1;
                }
                // Only frames have no event line, and this is not one.
                match Event::of(&other) {
                    Some(event) => to_all(sinks, |s| s.event(&event))?,
                    None => Flow::Go,
                }
            }
        }))
    }

    fn stopped(&self) -> Tally {
        Tally { stopped: true, ..self.tally }
    }

    /// Does what the sinks' readers asked, saying so to every sink.
    fn requests(&mut self, sinks: &mut [Box<dyn Sink>]) -> Result<Flow> {
        let mut flow = Flow::Go;
        for at in 0..sinks.len() {
            while let Some(request) = sinks[at].request() {
                let event = match request {
                    viewer::Command::RetakeReference => {
                        self.pipeline.retake_reference();
                        Event::Reference { detail: "re-taking the reference, as the viewer asked".into() }
                    }
                };
                flow = flow.and(to_all(sinks, |s| s.event(&event))?);
            }
        }
        Ok(flow)
    }

    /// One frame through the pipeline and out to every sink: its events first (the reference
    /// taken, channels dropped), then its line; a frame refused is a `bad` event.
    fn frame(&mut self, seq: u64, t: f64, values: &[f64], sinks: &mut [Box<dyn Sink>]) -> Result<Flow> {
        let kind = self.settings.kind;
        let processed = signed_frame(kind, values, &self.model, &mut self.signed)
            .and_then(|frame| self.pipeline.process(frame).map(|status| (status, frame)));
        let (status, frame) = match processed {
            Ok(done) => done,
            Err(e) => {
                if let (true, eitskin::InverseError::TooManyBadChannels { .. }) = (self.settings.say, &e) {
                    eprintln!("warning: frame seq {seq}: {e}");
                }
                self.tally.bad += 1;
                let event = Event::Bad { seq: Some(seq), reason: e.to_string() };
                return to_all(sinks, |s| s.event(&event));
            }
        };
        let mut flow = Flow::Go;
        if let Some(event) =
            channel_event(seq, status, &self.pipeline, self.settings.hyperparameter, &self.settings.masked)
        {
            if self.settings.say {
                say(&event);
            }
            flow = to_all(sinks, |s| s.event(&event))?;
        }
        self.tally.frames += 1;
        let mut counters = Counters { frames: self.tally.frames, bad: self.tally.bad, viewer_dropped: None };
        sinks.iter().for_each(|s| s.count(&mut counters));
        let (pipeline, metres, line) = (&self.pipeline, self.settings.metres, &mut self.line);
        fill_frame_line(line, seq, t, status, pipeline, metres, counters);
        set_raster(line, self.settings.stream_image && status.imaged(), pipeline, metres);
        line.learned = self.learned.as_mut().and_then(|l| l.answer(frame, pipeline, metres));
        line.recorded = self.settings.recorded;
        let processed = Processed { line, values, status, pipeline };
        Ok(flow.and(to_all(sinks, |s| s.frame(&processed))?))
    }
}

/// The signed frame of what a board sent (`kind`), in `signed` unless it already is one; a
/// frame of the wrong length is refused.
fn signed_frame<'a>(
    kind: ValueKind,
    values: &'a [f64],
    model: &[f64],
    signed: &'a mut [f64],
) -> Result<&'a [f64], eitskin::InverseError> {
    if kind == ValueKind::Signed {
        return Ok(values);
    }
    let expected = signed.len() * kind.per_measurement();
    if values.len() != expected {
        return Err(eitskin::InverseError::FrameLength { expected, got: values.len() });
    }
    kind.signed_into(values, model, signed);
    Ok(signed)
}

/// Puts the pipeline's image into `line` (in units of `metres` m) when `on`, reusing its memory;
/// takes it out otherwise.
fn set_raster(line: &mut FrameLine, on: bool, pipeline: &Pipeline, metres: f64) {
    match (on, &mut line.raster) {
        (false, raster) => *raster = None,
        (true, Some(raster)) => raster.set(pipeline.image(), metres),
        (true, raster) => {
            let mut new = Raster::default();
            new.set(pipeline.image(), metres);
            *raster = Some(new);
        }
    }
}

/// Fills `line` with a processed frame: its status, the pipeline's touches (positions in units of
/// `metres` m; unit and area from 1; force in N; the fitted press or null) and `counters`; not
/// recorded (yet).
pub(crate) fn fill_frame_line(
    line: &mut FrameLine,
    seq: u64,
    t: f64,
    status: Status,
    pipeline: &Pipeline,
    metres: f64,
    counters: Counters,
) {
    line.seq = seq;
    line.t = t;
    line.status = status.into();
    line.set_touches(pipeline.touches(), metres);
    line.counters = counters;
    line.recorded = false;
}
