//! An imperfect virtual skin: the sheet as built, not as specified, to learn calibrations on.
//!
//! The outline is another size than the spec's (or a circle instead of its polygon), each
//! electrode sits up to a few mm from its place along the boundary, each channel has its own
//! gain, one drive's channels are dead, the gel drifts, and the board may send magnitudes only.
//! What it yields is what a robot-pressed data set holds: per press, the frame pressed less
//! the frame just before it (no shared reference), and the press's position and force.

use crate::SeededRng;
use rand::{RngExt, SeedableRng};

use super::{SimParams, VirtualSensor};
use crate::geometry::Outline;
use crate::learn::LabelledPress;
use crate::spec::{Numbering, Placement, SensorSpec, SpecError};
use crate::ForwardError;

/// How the skin differs from its spec.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Imperfections {
    /// The outline's size relative to the spec's (e.g. 1.1: 10 % larger), in (0.5, 2).
    pub scale: f64,
    /// A circle of the same area instead of the spec's outline.
    pub circle: bool,
    /// The largest shift of an electrode along the boundary, in m (each drawn uniformly within ±).
    pub electrode_shift: f64,
    /// The spread of the per-channel gains: each drawn uniformly in 1 ± this.
    pub gain_spread: f64,
    /// The stimulation (0-based) whose measurements are dead (read as 0), if any.
    pub dead_drive: Option<usize>,
    /// The relative change of every gain per press (the gel drying), dimensionless.
    pub drift_per_press: f64,
    /// The board sends |v| only.
    pub magnitudes: bool,
    /// Relative noise per value and frame, as the virtual sensor's (0.3–0.5 % on open boards).
    pub noise_relative: f64,
    /// Frames averaged for each state (before, pressed), as a robot holding each press still
    /// while the board streams: 1 for single frames.
    pub frames_per_press: usize,
}

impl Default for Imperfections {
    /// 10 % larger, electrodes within ±3 mm, gains ±20 %, the first drive dead, 1e-5 drift per
    /// press, magnitudes only, 0.3 % noise, single frames.
    fn default() -> Imperfections {
        Imperfections {
            scale: 1.1,
            circle: false,
            electrode_shift: 0.003,
            gain_spread: 0.2,
            dead_drive: Some(0),
            drift_per_press: 1e-5,
            magnitudes: true,
            noise_relative: 0.003,
            frames_per_press: 1,
        }
    }
}

/// The radius of a disc of robot presses: `fraction` of the half-width of `outline`'s box (its
/// smaller side), in m.
pub fn disc_radius(outline: &Outline, fraction: f64) -> f64 {
    let [lo, hi] = outline.bounds();
    fraction * 0.5 * (hi[0] - lo[0]).min(hi[1] - lo[1])
}

/// The skin as built: a virtual sensor of the changed spec, and what the board does to its values.
#[derive(Debug)]
pub struct ImperfectSkin {
    sensor: VirtualSensor,
    /// Per measurement: its gain, 0 for a dead one.
    gains: Vec<f64>,
    magnitudes: bool,
    drift_per_press: f64,
    frames_per_press: usize,
    /// The common gain the drift has reached.
    drift: f64,
    rng: SeededRng,
}

/// The spec as built: another outline and electrodes moved along it.
pub fn built_spec(
    spec: &SensorSpec,
    imperfections: &Imperfections,
    rng: &mut SeededRng,
) -> Result<SensorSpec, SpecError> {
    let mut built = spec.clone();
    let s = imperfections.scale;
    built.outline = match &spec.outline {
        _ if imperfections.circle => {
            Outline::Circle { radius: s * (spec.outline.area() / std::f64::consts::PI).sqrt() }
        }
        Outline::Rectangle { width, height } => Outline::Rectangle { width: s * width, height: s * height },
        Outline::Circle { radius } => Outline::Circle { radius: s * radius },
        Outline::Polygon { points } => {
            Outline::Polygon { points: points.iter().map(|p| [s * p[0], s * p[1]]).collect() }
        }
    };
    // The electrodes where the spec puts them, carried to the built outline along the ray from
    // the centre (else at the same fraction of the perimeter), each moved along it.
    let (perimeter, spec_perimeter) = (built.outline.perimeter(), spec.outline.perimeter());
    let shift = imperfections.electrode_shift;
    let positions = spec
        .electrode_positions()?
        .iter()
        .map(|e| {
            let p = spec.outline.point_at(e.centre);
            let carried = built
                .outline
                .arc_length_at_angle(p[1].atan2(p[0]).to_degrees())
                .unwrap_or(e.centre / spec_perimeter * perimeter);
            let moved = carried + if shift > 0.0 { rng.random_range(-shift..=shift) } else { 0.0 };
            built.outline.point_at(moved.rem_euclid(perimeter))
        })
        .collect();
    // Listed in electrode order, as explicit positions are: the spec's numbering is in them.
    built.electrodes.placement = Placement::Explicit { positions };
    built.electrodes.numbering = Numbering::CounterClockwise;
    built.validate()?;
    Ok(built)
}

impl ImperfectSkin {
    /// The skin of `spec` as built with `imperfections`, drawn from `seed`.
    pub fn new(spec: &SensorSpec, imperfections: &Imperfections, seed: u64) -> Result<ImperfectSkin, SpecError> {
        let mut rng = SeededRng::seed_from_u64(seed);
        let built = built_spec(spec, imperfections, &mut rng)?;
        let protocol = built.protocol()?;
        let spread = imperfections.gain_spread;
        let gains = protocol
            .measurements()
            .iter()
            .map(|m| {
                if imperfections.dead_drive == Some(m.stimulation) {
                    0.0
                } else {
                    1.0 + if spread > 0.0 { rng.random_range(-spread..=spread) } else { 0.0 }
                }
            })
            .collect();
        let params = SimParams { noise_relative: imperfections.noise_relative, ..SimParams::default() };
        let sensor = VirtualSensor::with_params(&built, params, rng.random())?;
        Ok(ImperfectSkin {
            sensor,
            gains,
            magnitudes: imperfections.magnitudes,
            drift_per_press: imperfections.drift_per_press,
            frames_per_press: imperfections.frames_per_press.max(1),
            drift: 1.0,
            rng,
        })
    }

    /// The virtual sensor underneath (the built spec's).
    pub fn sensor(&self) -> &VirtualSensor {
        &self.sensor
    }

    /// The mean of `frames_per_press` frames as the board sends them: noise, gains, dead
    /// channels, magnitudes.
    fn board_frame(&mut self) -> Result<Vec<f64>, ForwardError> {
        let clean = self.sensor.clean_frame()?;
        let mut mean = vec![0.0; clean.len()];
        let k = self.frames_per_press;
        for _ in 0..k {
            let mut frame = self.sensor.noisy(&clean);
            for ((v, g), m) in frame.iter_mut().zip(&self.gains).zip(&mut mean) {
                *v *= g * self.drift;
                *m += if self.magnitudes { v.abs() } else { *v } / k as f64;
            }
        }
        Ok(mean)
    }

    /// One press at `position` (m) with `force` (N): the frame pressed less the frame just
    /// before it, as the board sends them; every gain drifts a little with each press (the gel
    /// drying scales all values alike).
    pub fn press(&mut self, position: [f64; 2], force: f64) -> Result<Vec<f64>, ForwardError> {
        self.sensor.release();
        let before = self.board_frame()?;
        self.sensor.press(position, force);
        let pressed = self.board_frame()?;
        self.sensor.release();
        self.drift *= 1.0 + self.drift_per_press;
        Ok(pressed.iter().zip(&before).map(|(p, b)| p - b).collect())
    }

    /// `count` robot presses at random places within `radius` (m) of the centre and random forces
    /// in `forces` (N), labelled with where and how hard.
    pub fn robot_presses(
        &mut self,
        count: usize,
        radius: f64,
        forces: std::ops::Range<f64>,
    ) -> Result<Vec<LabelledPress>, ForwardError> {
        (0..count)
            .map(|_| {
                // Uniform over the disc.
                let (r, angle) =
                    (radius * self.rng.random::<f64>().sqrt(), self.rng.random_range(0.0..std::f64::consts::TAU));
                let position = [r * angle.cos(), r * angle.sin()];
                let force = self.rng.random_range(forces.clone());
                Ok(LabelledPress { inputs: self.press(position, force)?, position, force: Some(force), depth: None })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Without shifts, a larger outline carries each electrode out along its ray from the centre,
    /// onto a circle too (where the spec's per-side placement has no meaning), electrode k to
    /// electrode k's place whichever way the spec numbers them.
    #[test]
    fn electrodes_are_carried_to_the_built_outline_along_their_rays() {
        let points = |s: &SensorSpec| -> Vec<[f64; 2]> {
            s.electrode_positions().unwrap().iter().map(|e| s.outline.point_at(e.centre)).collect()
        };
        for (numbering, circle) in
            [false, true].into_iter().flat_map(|c| [(Numbering::CounterClockwise, c), (Numbering::Clockwise, c)])
        {
            let mut spec = SensorSpec::square_hydrogel();
            spec.electrodes.numbering = numbering;
            let nominal = points(&spec);
            let imperfections = Imperfections { circle, electrode_shift: 0.0, ..Imperfections::default() };
            let built = built_spec(&spec, &imperfections, &mut SeededRng::seed_from_u64(1)).unwrap();
            for (a, b) in nominal.iter().zip(points(&built)) {
                let turn = a[1].atan2(a[0]) - b[1].atan2(b[0]);
                assert!(turn.sin().abs() < 1e-9 && turn.cos() > 0.0, "{a:?} → {b:?}");
                if !circle {
                    assert!((b[0] - 1.1 * a[0]).abs() < 1e-9 && (b[1] - 1.1 * a[1]).abs() < 1e-9, "{a:?} → {b:?}");
                }
            }
        }
    }
}
