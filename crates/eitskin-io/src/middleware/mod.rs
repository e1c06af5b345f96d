//! Zenoh, the robot's middleware: a sensor's results published under key expressions that any
//! Zenoh client reads (Rust, Python's `eclipse-zenoh`, C, ROS 2 through `rmw_zenoh`), and raw
//! frames read from a key that a board's bridge publishes on, so that boards on one computer
//! feed the processing on another. Zenoh routes; eitskin only publishes and subscribes.
//!
//! | key expression          | what                                                    | payload |
//! |-------------------------|---------------------------------------------------------|---------|
//! | `PREFIX/SENSOR/touches` | every processed frame: the JSON line's [`FrameLine`](crate::stream::FrameLine) | [`Encoding`] |
//! | `PREFIX/SENSOR/events`  | every event: the start line first, then [`Event`](crate::stream::Event)s | [`Encoding`] |
//! | `PREFIX/SENSOR/image`   | with images on: each frame's raster ([`ImageMessage`])  | [`Encoding`] |
//! | `PREFIX/SENSOR/start`   | a query's answer: the start line, for a late subscriber | [`Encoding`] |
//! | `PREFIX/SENSOR/alive`   | a liveliness token, held from the start line while the sensor runs | — |
//! | any (`--source zenoh:KEY`) | raw frames in: [`FrameMessage`] (seq, t_s, values)   | JSON or CBOR |
//!
//! The payloads are the schema of the JSON lines ([`crate::stream`]), field for field, encoded as
//! JSON (`application/json`) or CBOR (RFC 8949, `application/cbor`: the same fields in about
//! half the bytes; f32 fields stay f32), so that a reader needs a JSON or CBOR library and the
//! schema, not eitskin. Results are published reliably, and a publisher waits rather than drop
//! a sample when the network is congested: a subscriber gets every frame, in order (a subscriber
//! that stalls holds the sensor up, until Zenoh gives its link up; 5 s by default).
//!
//! ```
//! use eitskin_io::middleware::{Encoding, FrameMessage};
//! let frame = FrameMessage { seq: 7, t: 0.35, values: vec![1.5, -2.0] };
//! for encoding in [Encoding::Json, Encoding::Cbor] {
//!     let mut bytes = Vec::new();
//!     encoding.encode_into(&frame, &mut bytes)?;
//!     assert_eq!(FrameMessage::decode(&bytes)?, frame); // JSON or CBOR, told by the first byte
//! }
//! assert!(FrameMessage::decode(b"{\"seq\": 1}").is_err());
//! # Ok::<(), eitskin_io::middleware::MiddlewareError>(())
//! ```
//!
//! Sessions are opened as Zenoh's own tools open them ([`ZenohSettings`]: a configuration file,
//! a mode, endpoints to connect to and listen on, multicast scouting on or off).
//!
//! ROS 2's own messages (CDR, laid out as `rmw_zenoh` lays them) go on the same session: see
//! [`ros2`].

mod publisher;
pub mod ros2;
mod session;
mod source;

use serde::{Deserialize, Serialize};

pub use publisher::{ImageMessage, SensorPublisher, ALIVE, EVENTS, IMAGE, START, TOUCHES};
pub use session::{open, Mode, ZenohSettings};
pub use source::ZenohSource;
/// The session publishers and sources are declared on (Zenoh's own).
pub use zenoh::Session;

/// What can go wrong opening a Zenoh session, publishing or reading frames.
#[derive(Debug, thiserror::Error)]
pub enum MiddlewareError {
    /// The configuration file could not be read or is not Zenoh's.
    #[error("--zenoh-config {path}: {reason}")]
    Config {
        /// The file, as given.
        path: String,
        /// Zenoh's words.
        reason: String,
    },
    /// A setting Zenoh refused (an endpoint, a mode).
    #[error("{flag} {value:?}: {reason}")]
    Setting {
        /// The flag, e.g. `--connect`.
        flag: &'static str,
        /// The value as written.
        value: String,
        /// Why it was refused.
        reason: String,
    },
    /// A key expression that is not one, or not one to publish on.
    #[error("{what} {key:?} is not a key expression to {use_}: {reason}")]
    Key {
        /// Which key, e.g. `the --publish prefix`.
        what: &'static str,
        /// The key as written.
        key: String,
        /// Publish on or subscribe to.
        use_: &'static str,
        /// Why.
        reason: String,
    },
    /// The session could not be opened (an endpoint that cannot be reached or bound).
    #[error("cannot open a Zenoh session: {reason}")]
    Open {
        /// Zenoh's words.
        reason: String,
    },
    /// A publisher or subscriber could not be declared, or a sample not sent.
    #[error("Zenoh, on {key}: {reason}")]
    Zenoh {
        /// The key expression.
        key: String,
        /// Zenoh's words.
        reason: String,
    },
    /// No subscriber appeared within the time asked to wait for one.
    #[error("no subscriber to {key} appeared within {waited_s} s (--wait-for-subscriber)")]
    NoSubscriber {
        /// The key expression.
        key: String,
        /// The wait, in s.
        waited_s: f64,
    },
    /// A payload that could not be encoded.
    #[error("cannot encode a sample as {encoding}: {reason}")]
    Encode {
        /// The encoding.
        encoding: Encoding,
        /// Why.
        reason: String,
    },
    /// A ROS name or domain that ROS would refuse.
    #[error("{what} {name:?} is not one ROS takes: {reason}")]
    RosName {
        /// Which, e.g. `the ROS namespace`.
        what: &'static str,
        /// The value as written.
        name: String,
        /// Why.
        reason: &'static str,
    },
    /// A payload that is not a frame message.
    #[error("not a frame message ({{\"seq\", \"t_s\", \"values\"}} in JSON or CBOR): {reason}")]
    Decode {
        /// Why, with the place.
        reason: String,
    },
}

/// How a sample's payload is encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Encoding {
    /// JSON text, as the JSON lines (without the new line).
    #[default]
    Json,
    /// CBOR (RFC 8949) of the same fields.
    Cbor,
}

impl Encoding {
    /// `value` encoded into `out` (cleared first).
    pub fn encode_into(self, value: &impl Serialize, out: &mut Vec<u8>) -> Result<(), MiddlewareError> {
        out.clear();
        match self {
            Encoding::Json => serde_json::to_writer(&mut *out, value).map_err(|e| e.to_string()),
            Encoding::Cbor => ciborium::into_writer(value, &mut *out).map_err(|e| e.to_string()),
        }
        .map_err(|reason| MiddlewareError::Encode { encoding: self, reason })
    }

    /// Zenoh's tag for it.
    pub(crate) fn zenoh(self) -> zenoh::bytes::Encoding {
        match self {
            Encoding::Json => zenoh::bytes::Encoding::APPLICATION_JSON,
            Encoding::Cbor => zenoh::bytes::Encoding::APPLICATION_CBOR,
        }
    }

    /// The media type Zenoh tags each sample with.
    pub fn media_type(self) -> &'static str {
        match self {
            Encoding::Json => "application/json",
            Encoding::Cbor => "application/cbor",
        }
    }
}

impl std::str::FromStr for Encoding {
    type Err = String;

    /// `json` or `cbor`, as on the command line.
    fn from_str(text: &str) -> Result<Encoding, String> {
        match text {
            "json" => Ok(Encoding::Json),
            "cbor" => Ok(Encoding::Cbor),
            _ => Err(format!("{text:?} is not an encoding; use `json` or `cbor`")),
        }
    }
}

impl std::fmt::Display for Encoding {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Encoding::Json => "json",
            Encoding::Cbor => "cbor",
        })
    }
}

/// A raw frame as a board's bridge publishes it (`--source zenoh:KEY`): a recording's record
/// without its touches (`{"seq", "t_s", "values"}`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameMessage {
    /// The board's frame counter: frames lost or out of order are told by it.
    pub seq: u64,
    /// When the frame was measured, in s, on the bridge's clock (`t_s`, as in a recording's records).
    #[serde(rename = "t_s")]
    pub t: f64,
    /// The measurements in protocol order, as the board sends them (V or Ω; complex as re, im pairs).
    pub values: Vec<f64>,
}

impl FrameMessage {
    /// A frame message from its payload: JSON if it starts with `{` (after white space), else CBOR.
    pub fn decode(payload: &[u8]) -> Result<FrameMessage, MiddlewareError> {
        let json = payload.iter().find(|b| !b.is_ascii_whitespace()) == Some(&b'{');
        let decoded: Result<FrameMessage, String> = if json {
            serde_json::from_slice(payload).map_err(|e| format!("JSON: {e}"))
        } else {
            let mut rest = payload;
            match ciborium::from_reader(&mut rest) {
                Ok(_) if !rest.is_empty() => Err(format!("CBOR: {} bytes after the frame", rest.len())),
                decoded => decoded.map_err(|e| format!("CBOR: {e}")),
            }
        };
        match decoded {
            Ok(frame) if !frame.t.is_finite() => Err(format!("its time t_s is {}", frame.t)),
            decoded => decoded,
        }
        .map_err(|reason| MiddlewareError::Decode { reason })
    }
}

/// Checks that `key` is a key expression to publish on (no wildcards), for messages.
pub(crate) fn publish_key(what: &'static str, key: &str) -> Result<(), MiddlewareError> {
    let error = |reason: String| MiddlewareError::Key { what, key: key.to_owned(), use_: "publish on", reason };
    let parsed = zenoh::key_expr::KeyExpr::try_from(key).map_err(|e| error(e.to_string()))?;
    if parsed.is_wild() {
        return Err(error("it holds a wildcard (`*`, `**` or `$*`); name one place".to_owned()));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_messages_read_back_in_both_encodings_and_bad_ones_say_why() {
        let frame = FrameMessage { seq: u64::MAX, t: 1e-9, values: vec![f64::MIN_POSITIVE, -0.0, 1e300] };
        for encoding in [Encoding::Json, Encoding::Cbor] {
            let mut bytes = vec![1, 2, 3];
            encoding.encode_into(&frame, &mut bytes).unwrap();
            assert_eq!(FrameMessage::decode(&bytes).unwrap(), frame, "{encoding}");
        }
        for (payload, says) in [
            (&b"{\"seq\": 1, \"t_s\": 0, \"values\": [1], \"extra\": 2}"[..], "extra"),
            (b"  {\"seq\": -1, \"t_s\": 0, \"values\": []}", "JSON"),
            (b"{\"seq\": 1, \"t\": 0, \"values\": [1]}", "unknown field `t`"),
            (b"{\"seq\": 1, \"t_s\": 0, \"values\": [1, \"2\"]", "JSON"),
            (b"", "CBOR"),
            (b"\xa1\x63seq\x01", "CBOR"),
            (b"\xa3\x63seq\x01\x63t_s\xf9\x7e\x00\x66values\x80", "t_s is NaN"),
            (b"\xa3\x63seq\x01\x63t_s\xf9\x00\x00\x66values\x80\x00", "1 bytes after the frame"),
        ] {
            let error = FrameMessage::decode(payload).unwrap_err().to_string();
            assert!(error.contains(says) && error.contains("not a frame message"), "{error}");
        }
    }

    #[test]
    fn encodings_parse_as_written_and_keys_to_publish_on_have_no_wildcards() {
        assert_eq!("cbor".parse::<Encoding>(), Ok(Encoding::Cbor));
        assert!("CBOR".parse::<Encoding>().unwrap_err().contains("\"CBOR\""));
        publish_key("the prefix", "robot/skin").unwrap();
        for bad in ["robot/*", "a/**", "a//b", "", "/a", "a?b"] {
            let error = publish_key("the prefix", bad).unwrap_err().to_string();
            assert!(error.contains(&format!("{bad:?}")), "{error}");
        }
    }
}
