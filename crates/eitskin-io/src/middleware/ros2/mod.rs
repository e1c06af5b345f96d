//! ROS 2 messages on Zenoh, laid out as ROS 2's own Zenoh middleware (`rmw_zenoh`) lays them
//! out: a ROS 2 node running `rmw_zenoh_cpp` (Jazzy or later) and reaching the same Zenoh
//! router receives eitskin's touches with no eitskin code in it, and `ros2 topic list` shows
//! them.
//!
//! | topic                     | type                                  | what                                  |
//! |---------------------------|---------------------------------------|---------------------------------------|
//! | `/NAMESPACE/SENSOR/touches` | `eitskin_msgs/msg/Touches`          | every frame's touches, forces and their standard deviations, counters (the JSON line's content, in m and N) |
//! | `/NAMESPACE/SENSOR/wrench`  | `geometry_msgs/msg/WrenchStamped`   | every frame's net force and torque of the presses on the sheet, about the sensor frame's origin |
//! | `/NAMESPACE/SENSOR/markers` | `visualization_msgs/msg/MarkerArray` | every frame's touches as cylinders (height by force) for RViz |
//! | `/NAMESPACE/SENSOR/image`   | `sensor_msgs/msg/Image`             | with images on: each imaged frame's Δσ, `32FC1` in S/m, row 0 the top |
//!
//! Why Zenoh rather than DDS: eitskin already holds a Zenoh session (for its own keys and for
//! frames from bridges), Zenoh reaches across networks through routers without multicast, and
//! `rmw_zenoh` is ROS 2's own middleware on it; a DDS stack would add a second transport and
//! multicast discovery, which the robots' networks (and this project's tests) keep off.
//!
//! Touches and wrenches are in the sensor's frame (`[mount] frame_id` of the spec, else the
//! sensor's name); markers are in the link the sensor is mounted on (`[mount] parent`), placed
//! by the mount's pose, so RViz draws them on the robot with the robot's own transforms. The
//! header's stamp is this host's clock when the frame was processed (one stamp for all of a
//! frame's messages); the frame's own counter and time are in `Touches`. Messages go reliably
//! and in order, each with the attachment `rmw_zenoh` requires (sequence number, time, publisher
//! id); as `rmw_zenoh` does for ROS 2's default QoS (keep the last 10), a message a congested
//! link cannot take is dropped rather than hold the sensor (and, in `serve`, the fleet) up.
//!
//! ```
//! use eitskin_io::middleware::ros2::{topic_key, Ros2Settings, TOUCHES};
//! let settings = Ros2Settings { domain: 0, namespace: "eitskin".into(), sensor: "palm".into(), mount: None, image: false, every_message: false };
//! settings.check()?;
//! assert_eq!(settings.topic("touches"), "/eitskin/palm/touches");
//! assert!(topic_key(0, "/eitskin/palm/touches", &TOUCHES).starts_with("0/eitskin/palm/touches/eitskin_msgs::msg::dds_::Touches_/RIHS01_"));
//! assert!(Ros2Settings { sensor: "palm-1".into(), ..settings }.check().is_err()); // not a ROS name
//! # Ok::<(), eitskin_io::middleware::MiddlewareError>(())
//! ```

mod messages;
mod rmw;

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{SystemTime, UNIX_EPOCH};

use byteorder::LittleEndian;
use eitskin::mount::Mount;
use serde::Serialize;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Publisher;
use zenoh::qos::CongestionControl;
use zenoh::{Session, Wait};

pub use messages::{
    imaged, pixels_of, pose_at, touches_of, wrench_of, ColorRgba, Header, Image, Marker, Point, Pose, Quaternion,
    Sequence, Time, Touch, Touches, WrenchStamped,
};
pub use rmw::{
    attachment, gid, node_token, publisher_token, topic_key, MessageType, CDR_LE_HEADER, IMAGE, MARKER_ARRAY, TOUCHES,
    WRENCH_STAMPED,
};

use super::MiddlewareError;
use crate::stream::{FrameLine, Raster};

/// The largest ROS domain id (ROS 2's documented range is 0 to 232).
pub const MAX_DOMAIN: u32 = 232;

/// Where and what one sensor publishes on ROS 2.
#[derive(Debug, Clone, PartialEq)]
pub struct Ros2Settings {
    /// The ROS domain, in [0, 232].
    pub domain: u32,
    /// The topics' namespace, without its leading `/`, e.g. `eitskin` or `robot/skin`.
    pub namespace: String,
    /// The sensor's name: the last part of the namespace of its topics, and of its node's name.
    pub sensor: String,
    /// The sensor's frame and pose on the robot, from the spec.
    pub mount: Option<Mount>,
    /// Whether images are published too.
    pub image: bool,
    /// Whether a message waits for room to be sent (a replay whose every frame must be read)
    /// rather than being dropped when the link is full (rmw_zenoh's default for a history kept
    /// to its last messages: a robot wants the newest).
    pub every_message: bool,
}

impl Ros2Settings {
    /// Refuses a domain out of [0, 232], or a namespace or sensor's name that is not a ROS name
    /// (letters, digits and `_`, not starting with a digit; a namespace's parts joined by `/`).
    pub fn check(&self) -> Result<(), MiddlewareError> {
        if self.domain > MAX_DOMAIN {
            return Err(MiddlewareError::RosName {
                what: "the ROS domain",
                name: self.domain.to_string(),
                reason: "a domain id is in [0, 232]",
            });
        }
        for part in self.namespace.split('/') {
            ros_token("the ROS namespace", &self.namespace, part)?;
        }
        ros_token("the sensor's name", &self.sensor, &self.sensor)
    }

    /// The topic `/NAMESPACE/SENSOR/leaf`.
    pub fn topic(&self, leaf: &str) -> String {
        format!("/{}/{}/{leaf}", self.namespace, self.sensor)
    }

    /// The frame touches are given in: the mount's, else the sensor's name.
    pub fn frame_id(&self) -> &str {
        self.mount.as_ref().map_or(&self.sensor, |m| &m.frame_id)
    }

    /// The ROS node eitskin appears as: `eitskin_SENSOR`.
    pub fn node(&self) -> String {
        format!("eitskin_{}", self.sensor)
    }
}

/// Refuses `part` of `name` unless it is a ROS name's token.
fn ros_token(what: &'static str, name: &str, part: &str) -> Result<(), MiddlewareError> {
    let reason = match part.bytes().next() {
        None => Some("it has an empty part (a ROS name has no `//`, and no leading or trailing `/`)"),
        Some(b) if b.is_ascii_digit() => Some("a part starts with a digit"),
        _ if !part.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_') => {
            Some("a ROS name holds letters, digits and `_` only (parts joined by `/` in a namespace)")
        }
        _ => None,
    };
    match reason {
        Some(reason) => Err(MiddlewareError::RosName { what, name: name.to_owned(), reason }),
        None => Ok(()),
    }
}

/// Node and entity ids, each given once in this process (rmw_zenoh gives each once a session).
static NEXT_ID: AtomicU64 = AtomicU64::new(0);

/// One declared ROS 2 publisher: its Zenoh publisher, its liveliness token, its id and count.
struct Topic {
    publisher: Publisher<'static>,
    _token: LivelinessToken,
    gid: [u8; 16],
    /// Messages sent so far.
    sent: i64,
}

/// One sensor's ROS 2 publishers, on a Zenoh session.
pub struct Ros2Publisher {
    settings: Ros2Settings,
    _node: LivelinessToken,
    touches: Topic,
    wrench: Topic,
    markers: Topic,
    image: Option<Topic>,
    /// The markers' namespace, `eitskin/SENSOR`.
    marker_ns: String,
    /// The stamp of the last frame's messages (ns since the UNIX epoch), its image's too.
    stamp: i64,
    /// Reused: the touches in m, a message's bytes, an image's pixels.
    touch_buffer: Vec<Touch>,
    bytes: Vec<u8>,
    pixels: Vec<u8>,
}

impl Ros2Publisher {
    /// Declares the node and its publishers on `session`, as rmw_zenoh would.
    pub fn new(session: &Session, settings: Ros2Settings) -> Result<Ros2Publisher, MiddlewareError> {
        settings.check()?;
        let zid = session.zid().to_string();
        let (domain, node) = (settings.domain, settings.node());
        let node_id = NEXT_ID.fetch_add(1, Ordering::Relaxed);
        let node_key = node_token(domain, &zid, node_id, &node);
        let liveliness = |key: String| {
            session
                .liveliness()
                .declare_token(key.clone())
                .wait()
                .map_err(|e| MiddlewareError::Zenoh { key, reason: e.to_string() })
        };
        let node_alive = liveliness(node_key)?;
        let declare = |leaf: &str, kind: &MessageType| -> Result<Topic, MiddlewareError> {
            let entity_id = NEXT_ID.fetch_add(1, Ordering::Relaxed);
            let topic = settings.topic(leaf);
            let key = topic_key(domain, &topic, kind);
            let publisher = session
                .declare_publisher(key.clone())
                .congestion_control(if settings.every_message {
                    CongestionControl::Block
                } else {
                    CongestionControl::Drop
                })
                .wait()
                .map_err(|e| MiddlewareError::Zenoh { key, reason: e.to_string() })?;
            let token = publisher_token(domain, &zid, node_id, entity_id, &node, &topic, kind);
            Ok(Topic { publisher, gid: gid(&token), _token: liveliness(token)?, sent: 0 })
        };
        let touches = declare("touches", &TOUCHES)?;
        let wrench = declare("wrench", &WRENCH_STAMPED)?;
        let markers = declare("markers", &MARKER_ARRAY)?;
        let image = if settings.image { Some(declare("image", &IMAGE)?) } else { None };
        Ok(Ros2Publisher {
            marker_ns: format!("eitskin/{}", settings.sensor),
            settings,
            _node: node_alive,
            touches,
            wrench,
            markers,
            image,
            stamp: 0,
            touch_buffer: Vec::new(),
            bytes: Vec::new(),
            pixels: Vec::new(),
        })
    }

    /// The key the touches go to.
    pub fn touches_key(&self) -> &str {
        self.touches.publisher.key_expr().as_str()
    }

    /// Waits until a subscriber to the touches is there, up to `timeout`.
    pub fn wait_for_subscriber(&self, timeout: std::time::Duration) -> Result<(), MiddlewareError> {
        super::publisher::wait_for_subscriber(&self.touches.publisher, timeout)
    }

    /// Publishes a frame's touches, wrench and markers; `metres` is the length unit of `line`.
    pub fn frame(&mut self, line: &FrameLine, metres: f64) -> Result<(), MiddlewareError> {
        let now = now_ns();
        self.stamp = now;
        let frame_id = self.settings.frame_id();
        let header = Header { stamp: Time::from_nanos(now), frame_id };
        touches_of(line, metres, &mut self.touch_buffer);
        let message = Touches {
            header: header.clone(),
            seq: line.seq,
            t: line.t,
            imaged: imaged(line),
            touches: &self.touch_buffer,
            frames: line.counters.frames,
            bad: line.counters.bad,
        };
        put(&mut self.touches, &mut self.bytes, now, &message)?;
        let (force, torque) = wrench_of(&self.touch_buffer);
        put(&mut self.wrench, &mut self.bytes, now, &WrenchStamped { header, force, torque })?;
        let mount = self.settings.mount.as_ref();
        let marker_frame = mount.map_or(frame_id, |m| m.parent.as_str());
        let markers = markers(&self.touch_buffer, mount, marker_frame, &self.marker_ns, Time::from_nanos(now));
        put(&mut self.markers, &mut self.bytes, now, &markers)
    }

    /// Whether images are published.
    pub fn publishes_images(&self) -> bool {
        self.image.is_some()
    }

    /// Publishes an imaged frame's raster, if images were asked for, with the stamp of the
    /// frame's other messages ([`Ros2Publisher::frame`] first).
    pub fn image(&mut self, raster: &Raster) -> Result<(), MiddlewareError> {
        let Some(topic) = &mut self.image else { return Ok(()) };
        let now = self.stamp;
        pixels_of(raster, &mut self.pixels);
        let image = Image {
            header: Header { stamp: Time::from_nanos(now), frame_id: self.settings.frame_id() },
            height: raster.ny as u32,
            width: raster.nx as u32,
            encoding: "32FC1",
            is_bigendian: 0,
            step: 4 * raster.nx as u32,
            data: Sequence(&self.pixels),
        };
        put(topic, &mut self.bytes, now, &image)
    }
}

impl std::fmt::Debug for Ros2Publisher {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ros2Publisher").field("settings", &self.settings).finish_non_exhaustive()
    }
}

/// The markers of `touches` (m): one that clears the last (RViz's DELETEALL), then a cylinder a touch, on the
/// sheet, as high as 2 mm a newton (5 mm without a force), as wide as the fitted press (20 mm
/// without one); presses red, increases blue.
fn markers<'a>(
    touches: &[Touch],
    mount: Option<&Mount>,
    frame_id: &'a str,
    ns: &'a str,
    stamp: Time,
) -> Vec<Marker<'a>> {
    let header = Header { stamp, frame_id };
    let marker = |id: i32, action: i32, pose: Pose, scale: Point, color: ColorRgba| Marker {
        header: header.clone(),
        ns,
        id,
        kind: Marker::CYLINDER,
        action,
        pose,
        scale,
        color,
        lifetime: Time::default(),
        frame_locked: false,
        points: &[],
        colors: &[],
        texture_resource: "",
        texture: (header.clone(), "", &[]),
        uv_coordinates: &[],
        text: "",
        mesh_resource: "",
        mesh_file: ("", &[]),
        mesh_use_embedded_materials: false,
    };
    let clear = ColorRgba { r: 0.0, g: 0.0, b: 0.0, a: 0.0 };
    let mut out = vec![marker(0, Marker::DELETEALL, pose_at(None, Point::default()), Point::default(), clear)];
    for (i, t) in touches.iter().enumerate() {
        let height = if t.force.is_finite() { (0.002 * t.force).max(0.001) } else { 0.005 };
        let width = if t.has_press && t.press_radius.is_finite() { 2.0 * t.press_radius } else { 0.02 };
        let centre = Point { z: height / 2.0, ..t.position };
        let color = if t.sign < 0 {
            ColorRgba { r: 0.9, g: 0.2, b: 0.1, a: 0.8 }
        } else {
            ColorRgba { r: 0.1, g: 0.3, b: 0.9, a: 0.8 }
        };
        let id = i32::try_from(i + 1).unwrap_or(i32::MAX);
        out.push(marker(id, Marker::ADD, pose_at(mount, centre), Point { x: width, y: width, z: height }, color));
    }
    out
}

/// `value` in CDR after its 4-byte header, into `bytes`, put on `topic` with rmw_zenoh's attachment.
fn put(topic: &mut Topic, bytes: &mut Vec<u8>, now: i64, value: &impl Serialize) -> Result<(), MiddlewareError> {
    let key = || topic.publisher.key_expr().as_str().to_owned();
    bytes.clear();
    bytes.extend_from_slice(&CDR_LE_HEADER);
    cdr_encoding::to_writer::<_, LittleEndian, _>(&mut *bytes, value)
        .map_err(|e| MiddlewareError::Zenoh { key: key(), reason: format!("cannot write the message in CDR: {e}") })?;
    topic.sent += 1;
    let attachment = attachment(topic.sent, now, &topic.gid);
    topic
        .publisher
        .put(bytes.as_slice())
        .attachment(attachment.to_vec())
        .wait()
        .map_err(|e| MiddlewareError::Zenoh { key: key(), reason: e.to_string() })
}

/// This host's clock, ns since the UNIX epoch.
fn now_ns() -> i64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| i64::try_from(d.as_nanos()).unwrap_or(i64::MAX))
}
