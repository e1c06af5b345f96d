//! Where a run's results go: the sinks of the loop source → pipeline → sinks. Each takes every
//! event and every processed frame; [`Lines`] writes the JSON lines to stdout, [`Recording`]
//! appends each frame to a recording, [`Viewing`] offers both to the web viewer and passes on
//! its page's requests. A publisher is one more [`Sink`].
//!
//! Sinks run in the order given: the recorder first, so that a frame is on disk before any other
//! sink shows it as recorded. A sink whose reader went away (stdout closed) says
//! [`Flow::Stop`], and the run ends without an error; a sink that fails (a full disk) ends it
//! with its error.

use std::borrow::Cow;
use std::io::Write;
use std::path::Path;

use anyhow::Result;
use eitskin::pipeline::{Pipeline, Status};
use eitskin::pseudo_array::PseudoArray;
use eitskin::SensorSpec;
use eitskin_io::recorder::{Header, Recorder};
use eitskin_io::stream::{self, Counters, Event, FrameLine, Recorded, Start};

use crate::viewer::{self, Viewer};

/// Whether the run goes on after a sink took an item.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flow {
    /// Go on.
    Go,
    /// The sink's reader went away: end the run, without an error.
    Stop,
}

impl Flow {
    /// [`Flow::Stop`] when either is.
    pub fn and(self, other: Flow) -> Flow {
        if self == Flow::Stop {
            Flow::Stop
        } else {
            other
        }
    }
}

/// A processed frame as the sinks see it.
pub struct Processed<'a> {
    /// The frame's line (touches, forces, counters), as printed.
    pub line: &'a FrameLine,
    /// The values as the source gave them (complex pairs are two numbers per measurement).
    pub values: &'a [f64],
    /// What the pipeline did with the frame.
    pub status: Status,
    /// The pipeline, for its image.
    pub pipeline: &'a Pipeline,
}

/// A receiver of a run's results; Send, so that `serve` runs each sensor on any thread of its pool.
pub trait Sink: Send {
    /// Takes the run's first line (nothing else comes before it).
    fn start(&mut self, _start: &Start) -> Result<Flow> {
        Ok(Flow::Go)
    }
    /// Takes an event (reference taken, a bad frame, a port unplugged…).
    fn event(&mut self, event: &Event) -> Result<Flow>;
    /// Takes a processed frame.
    fn frame(&mut self, frame: &Processed<'_>) -> Result<Flow>;
    /// Nothing is waiting: hands on what it holds back.
    fn idle(&mut self) -> Result<Flow> {
        Ok(Flow::Go)
    }
    /// Adds its own counters to a frame's line.
    fn count(&self, _counters: &mut Counters) {}
    /// The next request of its reader (the viewer's "re-take the reference"), if any.
    fn request(&mut self) -> Option<viewer::Command> {
        None
    }
}

/// `each` applied to every sink in turn; [`Flow::Stop`] if any said so, the first error if any failed.
pub fn to_all(sinks: &mut [Box<dyn Sink>], mut each: impl FnMut(&mut dyn Sink) -> Result<Flow>) -> Result<Flow> {
    let mut flow = Flow::Go;
    for sink in sinks {
        flow = flow.and(each(sink.as_mut())?);
    }
    Ok(flow)
}

/// The JSON lines of the [`stream`] schema on a writer (stdout), written through a buffer that
/// goes out whenever no frame is waiting: a reader sees each frame as it comes, and a replay's
/// queued frames go out in larger writes. A closed writer stops the run.
pub struct Lines<W: Write> {
    out: std::io::BufWriter<W>,
}

impl<W: Write> Lines<W> {
    /// Lines on `out`.
    pub fn new(out: W) -> Lines<W> {
        Lines { out: std::io::BufWriter::new(out) }
    }

    fn write(&mut self, line: &impl serde::Serialize) -> Result<Flow> {
        Ok(match stream::write_line(&mut self.out, line) {
            Ok(()) => Flow::Go,
            Err(_) => Flow::Stop,
        })
    }
}

impl<W: Write + Send> Sink for Lines<W> {
    fn start(&mut self, start: &Start) -> Result<Flow> {
        self.write(&Event::Start(start.clone()))
    }
    fn event(&mut self, event: &Event) -> Result<Flow> {
        self.write(event)
    }
    fn frame(&mut self, frame: &Processed<'_>) -> Result<Flow> {
        self.write(frame.line)
    }
    fn idle(&mut self) -> Result<Flow> {
        Ok(match self.out.flush() {
            Ok(()) => Flow::Go,
            Err(_) => Flow::Stop,
        })
    }
}

/// Every frame and its touches appended to a recording (crash-safe JSON lines), flushed before
/// the later sinks see the frame.
pub struct Recording(Recorder);

impl Recording {
    /// A new recording at `path` of frames of `numbers` values, measured as `protocol` says.
    pub fn create(path: &Path, numbers: usize, protocol: &str) -> Result<Recording> {
        Ok(Recording(Recorder::create(path, &Header::now(numbers, protocol))?))
    }
}

impl Sink for Recording {
    fn event(&mut self, _event: &Event) -> Result<Flow> {
        Ok(Flow::Go)
    }
    fn frame(&mut self, frame: &Processed<'_>) -> Result<Flow> {
        let touches = Recorded { touches: Cow::Borrowed(&frame.line.touches) };
        self.0.record_with(frame.line.seq, frame.line.t, frame.values, &touches)?;
        Ok(Flow::Go)
    }
}

/// The web viewer: each event and frame offered to its pages without waiting, its button's
/// requests passed on.
pub struct Viewing(Viewer);

impl Viewing {
    /// The viewer serving the page of `spec`'s sheet, as `pipeline` images it, at `addr`.
    pub fn start(addr: std::net::SocketAddr, spec: &SensorSpec, pipeline: &Pipeline) -> Result<Viewing> {
        let viewer = Viewer::start(addr, &setup(spec, pipeline)?)?;
        eprintln!("eitskin run: viewer at http://{}/", viewer.addr());
        Ok(Viewing(viewer))
    }
}

impl Sink for Viewing {
    fn event(&mut self, event: &Event) -> Result<Flow> {
        self.0.offer_event(event);
        Ok(Flow::Go)
    }
    fn frame(&mut self, frame: &Processed<'_>) -> Result<Flow> {
        let referencing = match frame.status {
            Status::Referencing { collected, needed } => Some([collected, needed]),
            // Every frame is in; what they give is being derived.
            Status::Deriving => Some([frame.pipeline.params().frames_in_reference(); 2]),
            Status::Processed | Status::ChannelsDropped { .. } | Status::NoiseUpdated => None,
        };
        let image = &frame.pipeline.image().values;
        self.0.offer_frame(&viewer::Frame { line: frame.line, referencing, image });
        Ok(Flow::Go)
    }
    fn count(&self, counters: &mut Counters) {
        counters.viewer_dropped = Some(self.0.dropped());
    }
    fn request(&mut self) -> Option<viewer::Command> {
        self.0.commands().next()
    }
}

/// What the viewer's page needs to draw frames, in the spec's units: the calibration's
/// pseudo-array, or 5 × 5 units over the outline's box without one.
fn setup(spec: &SensorSpec, pipeline: &Pipeline) -> Result<viewer::Setup> {
    let metres = spec.length_unit.metres();
    let scale = |p: [f64; 2]| [p[0] / metres, p[1] / metres];
    let default_array;
    let array = match pipeline.pseudo_array() {
        Some(array) => array,
        None => {
            default_array = PseudoArray::one_area_per_unit(spec.outline.bounds(), [5, 5])?;
            &default_array
        }
    };
    let image = pipeline.image();
    let [lo, hi] = image.bounds;
    let [glo, ghi] = array.bounds();
    Ok(viewer::Setup {
        unit: spec.length_unit.symbol(),
        image_size: image.size,
        image_bounds: [scale(lo), scale(hi)],
        inside: image.inside.clone(),
        outline: spec.outline.corners().into_iter().map(scale).collect(),
        electrodes: spec.electrode_positions()?.iter().map(|e| scale(spec.outline.point_at(e.centre))).collect(),
        grid: array.grid(),
        grid_bounds: [scale(glo), scale(ghi)],
        areas: (0..array.unit_count()).map(|u| array.area_of(u) + 1).collect(),
        calibrated: pipeline.pseudo_array().is_some(),
        colours: &eitskin::colour::COLOUR_STOPS,
    })
}
