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
    /// Frames a second of the clock.
    rate: f64,
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
        Ok(SimSource { skin, script, period, rate, wait: speed == Speed::Recorded, seq: 0, start: None })
    }
}

impl FrameSource for SimSource {
    fn acquire(&mut self) -> Option<Result<Acquired, SourceError>> {
        let seq = self.seq;
        // k / rate, rounded once: frame 3 at 20 frames/s is at 0.15 s, not 3 × 0.05.
        let t = seq as f64 / self.rate;
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

#[cfg(test)]
mod tests {
    use super::*;
    use eitskin::SensorSpec;

    /// Frame k is at k / rate, rounded once: the times a line carries read as written
    /// (frame 3 at 20 frames/s at 0.15 s, where 3 × 0.05 is 0.15000000000000002).
    #[test]
    fn frame_times_are_their_number_over_the_rate() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 300;
        let skin = VirtualSensor::new(&spec, 1).unwrap();
        let script = Script::random(&spec.outline, 1.0, 0, 1);
        let mut source = SimSource::new(skin, script, 20.0, Speed::AsFastAsPossible).unwrap();
        let times: Vec<f64> = (0..4)
            .map(|_| match source.acquire() {
                Some(Ok(Acquired::Frame { t, .. })) => t,
                other => panic!("{other:?}"),
            })
            .collect();
        assert_eq!(times, [0.0, 0.05, 0.1, 0.15]);
    }
}
