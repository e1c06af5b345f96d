//! The virtual sensor as a source: a [`VirtualSensor`] pressed by a [`Script`] on a clock.

use std::time::{Duration, Instant};

use eitskin::sim::{Script, VirtualSensor};

use super::{wait_for_frame, Acquired, FrameSource, SourceError};
use crate::replay::Speed;

/// Frames of the virtual sensor: frame k is taken at t = k / rate s of its clock, with the
/// script's presses at that time on the sheet, and delivered then (in real time) or at once.
///
/// It never ends by itself: give [`Source`](super::Source) a frame limit.
#[derive(Debug)]
pub struct SimSource {
    /// The sensor.
    skin: VirtualSensor,
    /// Who presses where, when.
    script: Script,
    /// The clock's period, one frame.
    period: Duration,
    /// Whether to wait until each frame is due.
    wait: bool,
    /// The number of the next frame.
    seq: u64,
    /// When the first frame was delivered.
    start: Option<Instant>,
}

impl SimSource {
    /// The sensor `skin` pressed by `script`, at `rate` frames/s of its clock (positive), delivered
    /// at `speed`.
    pub fn new(skin: VirtualSensor, script: Script, rate: f64, speed: Speed) -> Result<SimSource, SourceError> {
        let period =
            Duration::try_from_secs_f64(1.0 / rate).ok().filter(|p| !p.is_zero()).ok_or(SourceError::Rate { rate })?;
        Ok(SimSource { skin, script, period, wait: speed == Speed::Recorded, seq: 0, start: None })
    }
}

impl FrameSource for SimSource {
    fn acquire(&mut self) -> Option<Result<Acquired, SourceError>> {
        let seq = self.seq;
        let t = seq as f64 * self.period.as_secs_f64();
        if self.wait {
            wait_for_frame(*self.start.get_or_insert_with(Instant::now), self.period, seq);
        }
        self.skin.release();
        for press in self.script.at(t) {
            self.skin.press(press.position, press.force);
        }
        Some(match self.skin.frame() {
            Ok(values) => {
                self.seq += 1;
                Ok(Acquired::Frame { seq, t, values })
            }
            Err(e) => Err(SourceError::Simulate(e)),
        })
    }
}
