//! Where a sensor sits on a robot: the name of its frame and its pose on a parent link, as ROS
//! names them (a `frame_id`, and the transform from the parent link to it).
//!
//! The sensor's frame has its origin at the outline's centre, x and y as the spec's, and z out
//! of the touched face: a press pushes along −z.
//!
//! ```
//! use eitskin::mount::Mount;
//! use eitskin::LengthUnit;
//! let half = std::f64::consts::FRAC_1_SQRT_2;
//! // 90° about the link's z, 0.1 m up it.
//! let mount = Mount { frame_id: "skin_palm".into(), parent: "hand_link".into(),
//!                     position: [0.0, 0.0, 0.1], orientation: [0.0, 0.0, half, half] };
//! mount.check(LengthUnit::Millimetre)?;
//! let p = mount.to_parent([0.05, 0.0, 0.0]); // the sensor's x is the link's y
//! assert!(p[0].abs() < 1e-12 && (p[1] - 0.05).abs() < 1e-12 && (p[2] - 0.1).abs() < 1e-12);
//! # Ok::<(), eitskin::SpecError>(())
//! ```

use crate::spec::{LengthUnit, SpecError, MAX_LENGTH};

/// A sensor's frame and its pose on a robot's link.
#[derive(Debug, Clone, PartialEq)]
pub struct Mount {
    /// The sensor's frame, e.g. `skin_palm`: what its touches are given in.
    pub frame_id: String,
    /// The link the sensor is fixed to, e.g. `hand_link`.
    pub parent: String,
    /// The sensor frame's origin in the parent's frame, in m.
    pub position: [f64; 3],
    /// The sensor frame's orientation in the parent's frame: a unit quaternion `[x, y, z, w]`.
    pub orientation: [f64; 4],
}

/// How far a quaternion's norm may be from 1 (rounding in a file written by hand).
const NORM_TOLERANCE: f64 = 1e-3;

impl Mount {
    /// Refuses a frame name that is not one (empty, blank, with a leading `/`, not printable
    /// ASCII), a position not finite or beyond 1 km, or an orientation that is not a unit
    /// quaternion (within 0.1 %); lengths are quoted in `unit`.
    pub fn check(&self, unit: LengthUnit) -> Result<(), SpecError> {
        frame("mount.frame_id", &self.frame_id)?;
        frame("mount.parent", &self.parent)?;
        if self.frame_id == self.parent {
            return Err(SpecError::Mount {
                key: "mount.parent",
                value: format!("{:?}", self.parent),
                reason: "it is the sensor's own frame_id; name the link the sensor is fixed to",
            });
        }
        if !self.position.iter().all(|c| c.is_finite() && c.abs() <= MAX_LENGTH) {
            let [x, y, z] = self.position.map(|c| unit.quote(c).to_string());
            return Err(SpecError::Mount {
                key: "mount.position",
                value: format!("[{x}, {y}, {z}]"),
                reason: "each coordinate must be a finite number within ±1 km",
            });
        }
        let norm = self.orientation.iter().map(|c| c * c).sum::<f64>().sqrt();
        if !(norm.is_finite() && (norm - 1.0).abs() <= NORM_TOLERANCE) {
            let [x, y, z, w] = self.orientation;
            return Err(SpecError::Mount {
                key: "mount.orientation",
                value: format!("[{x}, {y}, {z}, {w}]"),
                reason: "it must be a unit quaternion [x, y, z, w] (norm 1 within 0.1 %), e.g. [0, 0, 0, 1] for none",
            });
        }
        Ok(())
    }

    /// The orientation scaled to norm 1 exactly.
    pub fn unit_orientation(&self) -> [f64; 4] {
        let norm = self.orientation.iter().map(|c| c * c).sum::<f64>().sqrt();
        self.orientation.map(|c| c / norm)
    }

    /// A point of the sensor's frame (m) in the parent's frame (m).
    pub fn to_parent(&self, point: [f64; 3]) -> [f64; 3] {
        let [x, y, z, w] = self.unit_orientation();
        // p' = p + 2w (q × p) + 2 q × (q × p), q = (x, y, z).
        let cross = |a: [f64; 3], b: [f64; 3]| {
            [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
        };
        let q = [x, y, z];
        let t = cross(q, point).map(|c| 2.0 * c);
        let u = cross(q, t);
        std::array::from_fn(|i| point[i] + w * t[i] + u[i] + self.position[i])
    }
}

/// Refuses a frame name a ROS tool would not take.
fn frame(key: &'static str, name: &str) -> Result<(), SpecError> {
    let reason = if name.is_empty() {
        Some("a frame's name must not be empty")
    } else if name.starts_with('/') {
        Some("a frame's name has no leading `/` (tf2 refuses one)")
    } else if !name.bytes().all(|b| b.is_ascii_graphic()) {
        Some("a frame's name is printable ASCII without spaces, e.g. skin_palm")
    } else {
        None
    };
    match reason {
        Some(reason) => Err(SpecError::Mount { key, value: format!("{name:?}"), reason }),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mount(orientation: [f64; 4]) -> Mount {
        Mount { frame_id: "skin".into(), parent: "link".into(), position: [1.0, 2.0, 3.0], orientation }
    }

    #[test]
    fn rotation_keeps_lengths_and_matches_a_rotation_matrix() {
        // 120° about (1, 1, 1)/√3 permutes the axes: x → y → z → x.
        let h = 0.5;
        let m = mount([h, h, h, h]);
        let p = m.to_parent([0.3, -0.2, 0.7]);
        let expected = [1.0 + 0.7, 2.0 + 0.3, 3.0 - 0.2];
        for (a, b) in p.iter().zip(expected) {
            assert!((a - b).abs() < 1e-12, "{p:?}");
        }
        assert_eq!(mount([0.0, 0.0, 0.0, 1.0]).to_parent([0.0; 3]), [1.0, 2.0, 3.0]);
    }

    #[test]
    fn bad_values_are_refused_with_their_key_and_value() {
        let unit = LengthUnit::Millimetre;
        let err = |m: Mount| m.check(unit).unwrap_err().to_string();
        assert!(err(mount([0.0, 0.0, 0.0, 2.0])).contains("`mount.orientation` = [0, 0, 0, 2]"));
        assert!(err(mount([f64::NAN, 0.0, 0.0, 1.0])).contains("mount.orientation"));
        let far = Mount { position: [0.0, 2e3, 0.0], ..mount([0.0, 0.0, 0.0, 1.0]) };
        let message = err(far);
        assert!(message.contains("`mount.position` = [0 mm, 2000000 mm, 0 mm]"), "{message}");
        for (frame_id, parent) in [("", "link"), ("/skin", "link"), ("my skin", "link"), ("skin", "skin")] {
            let m = Mount { frame_id: frame_id.into(), parent: parent.into(), ..mount([0.0, 0.0, 0.0, 1.0]) };
            assert!(err(m).contains("mount."), "{frame_id:?}");
        }
        assert!(mount([0.0, 0.0, 0.0, 1.0005]).check(unit).is_ok());
    }
}
