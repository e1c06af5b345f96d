//! The ROS 2 messages eitskin publishes, field for field as their `.msg` files declare them
//! (Jazzy and later), so that serde writes them in CDR's order; and how a frame's line becomes
//! each of them (lengths in m, forces in N).

use serde::{Serialize, Serializer};

use crate::stream::{FrameLine, Raster, Sign, Status};
use eitskin::mount::Mount;

/// `builtin_interfaces/Time`.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Time {
    /// Seconds since the UNIX epoch.
    pub sec: i32,
    /// Nanoseconds within the second.
    pub nanosec: u32,
}

impl Time {
    /// The time `ns` nanoseconds after the UNIX epoch.
    pub fn from_nanos(ns: i64) -> Time {
        let (sec, nanosec) = (ns.div_euclid(1_000_000_000), ns.rem_euclid(1_000_000_000));
        Time { sec: sec.clamp(i32::MIN as i64, i32::MAX as i64) as i32, nanosec: nanosec as u32 }
    }
}

/// `std_msgs/Header`.
#[derive(Debug, Clone, Serialize)]
pub struct Header<'a> {
    /// When.
    pub stamp: Time,
    /// The frame the message's coordinates are in.
    pub frame_id: &'a str,
}

/// `geometry_msgs/Point` (also `Vector3`'s layout), in m.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Point {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

impl From<[f64; 3]> for Point {
    fn from([x, y, z]: [f64; 3]) -> Point {
        Point { x, y, z }
    }
}

/// `geometry_msgs/Quaternion`.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

/// `geometry_msgs/Pose`.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Pose {
    /// Where, in m.
    pub position: Point,
    /// Which way.
    pub orientation: Quaternion,
}

/// `geometry_msgs/WrenchStamped`: force in N, torque in N·m.
#[derive(Debug, Clone, Serialize)]
pub struct WrenchStamped<'a> {
    /// When, and the frame.
    pub header: Header<'a>,
    /// Force (N).
    pub force: Point,
    /// Torque (N·m).
    pub torque: Point,
}

/// `std_msgs/ColorRGBA`, each in [0, 1].
#[derive(Debug, Clone, Copy, Serialize)]
pub struct ColorRgba {
    /// Red.
    pub r: f32,
    /// Green.
    pub g: f32,
    /// Blue.
    pub b: f32,
    /// Opacity.
    pub a: f32,
}

/// `visualization_msgs/Marker` (Jazzy's fields), as eitskin fills it: one shape, no points,
/// texture or mesh.
#[derive(Debug, Clone, Serialize)]
pub struct Marker<'a> {
    /// When, and the frame.
    pub header: Header<'a>,
    /// The markers' namespace.
    pub ns: &'a str,
    /// Its number in the namespace.
    pub id: i32,
    /// Its shape ([`Marker::CYLINDER`]).
    #[serde(rename = "type")]
    pub kind: i32,
    /// [`Marker::ADD`] or [`Marker::DELETEALL`].
    pub action: i32,
    /// Where.
    pub pose: Pose,
    /// Its size along x, y, z, in m.
    pub scale: Point,
    /// Its colour.
    pub color: ColorRgba,
    /// How long it stays (`builtin_interfaces/Duration`; 0: until replaced).
    pub lifetime: Time,
    /// Whether it follows its frame.
    pub frame_locked: bool,
    /// `points` (none).
    pub points: &'a [Point],
    /// `colors` (none).
    pub colors: &'a [ColorRgba],
    /// `texture_resource` (none).
    pub texture_resource: &'a str,
    /// `texture`: a `sensor_msgs/CompressedImage` (empty).
    pub texture: (Header<'a>, &'a str, &'a [u8]),
    /// `uv_coordinates` (none).
    pub uv_coordinates: &'a [[f32; 2]],
    /// `text` (none).
    pub text: &'a str,
    /// `mesh_resource` (none).
    pub mesh_resource: &'a str,
    /// `mesh_file`: a `visualization_msgs/MeshFile` (empty).
    pub mesh_file: (&'a str, &'a [u8]),
    /// `mesh_use_embedded_materials`.
    pub mesh_use_embedded_materials: bool,
}

impl Marker<'_> {
    /// A cylinder.
    pub const CYLINDER: i32 = 3;
    /// Add or replace.
    pub const ADD: i32 = 0;
    /// Remove every marker (RViz clears its display's).
    pub const DELETEALL: i32 = 3;
}

/// `eitskin_msgs/Touch`: SI units, NaN where the sensor has no value (see `Touch.msg`).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Touch {
    /// -1: less conductive (a press), 1: more.
    pub sign: i8,
    /// Centre of gravity, m.
    pub position: Point,
    /// Peak change, S/m.
    pub peak: f32,
    /// Peak over the noise.
    pub z: f64,
    /// Pseudo-array unit from 1, or 0.
    pub unit: u16,
    /// Calibration area from 1, or 0.
    pub calibration_area: u16,
    /// N.
    pub force: f64,
    /// N.
    pub force_std: f64,
    /// Outside the calibrated range.
    pub saturated: bool,
    /// Whether the press fields hold a fitted press.
    pub has_press: bool,
    /// The press's centre, m.
    pub press_position: Point,
    /// The drop, a fraction of the background.
    pub press_drop: f64,
    /// m.
    pub press_radius: f64,
}

/// `eitskin_msgs/Touches`: a frame's line.
#[derive(Debug, Clone, Serialize)]
pub struct Touches<'a> {
    /// When processed, and the sensor's frame.
    pub header: Header<'a>,
    /// The frame's sequence number.
    pub seq: u64,
    /// The frame's time in its source's clock, s.
    pub t: f64,
    /// Whether the frame was imaged.
    pub imaged: bool,
    /// The touches, strongest first.
    pub touches: &'a [Touch],
    /// Frames so far.
    pub frames: u64,
    /// Input skipped so far.
    pub bad: u64,
}

/// The touches of `line` (lengths in units of `metres` m) in m, into `out` (reused).
pub fn touches_of(line: &FrameLine, metres: f64, out: &mut Vec<Touch>) {
    out.clear();
    out.extend(line.touches.iter().map(|t| {
        let press = t.press.as_ref();
        Touch {
            sign: if t.sign == Sign::Increase { 1 } else { -1 },
            position: Point { x: t.x * metres, y: t.y * metres, z: 0.0 },
            peak: t.peak,
            z: t.z.unwrap_or(f64::NAN),
            unit: t.unit.map_or(0, |u| u.min(u16::MAX as usize) as u16),
            calibration_area: t.calibration_area.map_or(0, |a| a.min(u16::MAX as usize) as u16),
            force: t.force.unwrap_or(f64::NAN),
            force_std: t.force_std.unwrap_or(f64::NAN),
            saturated: t.saturated.unwrap_or(false),
            has_press: press.is_some(),
            press_position: press.map_or(Point { x: f64::NAN, y: f64::NAN, z: f64::NAN }, |p| Point {
                x: p.x * metres,
                y: p.y * metres,
                z: 0.0,
            }),
            press_drop: press.map_or(f64::NAN, |p| p.drop),
            press_radius: press.and_then(|p| p.radius).map_or(f64::NAN, |r| r * metres),
        }
    }));
}

/// Whether the line's frame was imaged.
pub fn imaged(line: &FrameLine) -> bool {
    line.status == Status::Ok
}

/// The net force and torque the presses (`touches` in m, N) put on the sheet, about the sensor
/// frame's origin: each press pushes along −z at its centre. NaN where a press has no force.
pub fn wrench_of(touches: &[Touch]) -> (Point, Point) {
    let (mut force, mut torque) = (Point::default(), Point::default());
    for t in touches.iter().filter(|t| t.sign < 0) {
        // r × (0, 0, −f) = (−y f, x f, 0).
        force.z -= t.force;
        torque.x -= t.position.y * t.force;
        torque.y += t.position.x * t.force;
    }
    (force, torque)
}

/// A marker's pose: the point `p` of the sensor's frame (m) in the mount's parent frame with the
/// sensor's orientation, or in the sensor's frame without a mount.
pub fn pose_at(mount: Option<&Mount>, p: Point) -> Pose {
    match mount {
        Some(m) => {
            let [x, y, z, w] = m.unit_orientation();
            Pose { position: m.to_parent([p.x, p.y, p.z]).into(), orientation: Quaternion { x, y, z, w } }
        }
        None => Pose { position: p, orientation: Quaternion { x: 0.0, y: 0.0, z: 0.0, w: 1.0 } },
    }
}

/// `sensor_msgs/Image` of a raster: `32FC1`, Δσ in S/m, row 0 the top row (largest y), NaN
/// outside the outline.
#[derive(Debug, Clone, Serialize)]
pub struct Image<'a> {
    /// When, and the sensor's frame.
    pub header: Header<'a>,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// `32FC1`.
    pub encoding: &'a str,
    /// 0: little-endian.
    pub is_bigendian: u8,
    /// Bytes a row.
    pub step: u32,
    /// The pixels' bytes.
    pub data: Sequence<'a>,
}

/// The pixels of `raster` as little-endian f32 bytes, into `out` (reused).
pub fn pixels_of(raster: &Raster, out: &mut Vec<u8>) {
    out.clear();
    out.extend(raster.values.iter().flat_map(|v| v.unwrap_or(f32::NAN).to_le_bytes()));
}

/// A CDR `sequence<uint8>`: its length, then its bytes in one write.
#[derive(Debug, Clone, Copy)]
pub struct Sequence<'a>(pub &'a [u8]);

impl Serialize for Sequence<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeTuple;
        /// Bytes written as they are (CDR's serializer writes `bytes` without a length).
        struct Raw<'a>(&'a [u8]);
        impl Serialize for Raw<'_> {
            fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
                serializer.serialize_bytes(self.0)
            }
        }
        let length = u32::try_from(self.0.len()).map_err(serde::ser::Error::custom)?;
        let mut tuple = serializer.serialize_tuple(2)?;
        tuple.serialize_element(&length)?;
        tuple.serialize_element(&Raw(self.0))?;
        tuple.end()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stream::{Counters, Press};

    fn touch(sign: Sign, x: f64, y: f64, force: Option<f64>) -> crate::stream::Touch {
        crate::stream::Touch {
            sign,
            x,
            y,
            peak: 0.5,
            z: None,
            unit: Some(3),
            calibration_area: Some(2),
            force,
            force_std: None,
            saturated: Some(false),
            press: Some(Press { x, y, drop: 0.4, radius: Some(10.0) }),
        }
    }

    #[test]
    fn a_line_becomes_touches_in_metres_and_a_wrench_of_its_presses() {
        let line = FrameLine {
            seq: 4,
            status: Status::Ok,
            touches: vec![
                touch(Sign::Decrease, 50.0, 0.0, Some(2.0)),
                touch(Sign::Decrease, 0.0, -20.0, Some(1.0)),
                touch(Sign::Increase, 10.0, 10.0, Some(9.0)),
            ],
            counters: Counters { frames: 5, bad: 0, viewer_dropped: None },
            ..FrameLine::default()
        };
        let mut touches = Vec::new();
        touches_of(&line, 1e-3, &mut touches);
        assert_eq!((touches[0].sign, touches[0].position, touches[0].unit), (-1, Point { x: 0.05, y: 0.0, z: 0.0 }, 3));
        assert!(touches[0].z.is_nan() && touches[0].force_std.is_nan() && touches[0].has_press);
        assert!((touches[0].press_radius - 0.01).abs() < 1e-15);
        // Presses push along −z: 3 N down; torque r × F about the origin; the increase is no press.
        let (force, torque) = wrench_of(&touches);
        assert_eq!(force, Point { x: 0.0, y: 0.0, z: -3.0 });
        assert!((torque.x - 0.02).abs() < 1e-15 && (torque.y - 0.1).abs() < 1e-15 && torque.z == 0.0, "{torque:?}");
        // A press without a force makes the wrench unknown, not smaller.
        let unknown = FrameLine { touches: vec![touch(Sign::Decrease, 0.0, 0.0, None)], ..line };
        touches_of(&unknown, 1e-3, &mut touches);
        assert!(wrench_of(&touches).0.z.is_nan());
    }

    #[test]
    fn times_split_into_seconds_and_nanoseconds() {
        assert_eq!((Time::from_nanos(1_500_000_000).sec, Time::from_nanos(1_500_000_000).nanosec), (1, 500_000_000));
        assert_eq!((Time::from_nanos(-1).sec, Time::from_nanos(-1).nanosec), (-1, 999_999_999));
    }
}
