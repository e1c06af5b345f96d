//! [`SensorPublisher`]: one sensor's results on Zenoh, under `PREFIX/SENSOR/{touches,events,image}`.

use std::time::{Duration, Instant};

use serde::Serialize;
use zenoh::pubsub::Publisher;
use zenoh::qos::CongestionControl;
use zenoh::{Session, Wait};

use super::{publish_key, Encoding, MiddlewareError};
use crate::stream::{Event, FrameLine, Raster};

/// The keys under `PREFIX/SENSOR/`: each frame's line, the events, the image.
pub const TOPICS: [&str; 3] = ["touches", "events", "image"];

/// An imaged frame's raster, as published on `PREFIX/SENSOR/image`.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct ImageMessage<'a> {
    /// The frame's sequence number, as in its line.
    pub seq: u64,
    /// The frame's time, in s, as in its line.
    pub t: f64,
    /// The image: Δσ in S/m row by row from the top, null outside the outline.
    pub raster: &'a Raster,
}

/// One sensor's publishers: frames, events and (optionally) images, each sample encoded as
/// chosen, sent reliably, waiting rather than dropping when the network is congested.
pub struct SensorPublisher {
    touches: Publisher<'static>,
    events: Publisher<'static>,
    image: Option<Publisher<'static>>,
    encoding: Encoding,
    /// The last sample's bytes, reused.
    buffer: Vec<u8>,
}

impl SensorPublisher {
    /// Publishers on `session` under `prefix/sensor/`, the images too if `image`. The prefix is
    /// a key expression without wildcards; the sensor's name is one chunk of it (no `/`).
    pub fn new(
        session: &Session,
        prefix: &str,
        sensor: &str,
        encoding: Encoding,
        image: bool,
    ) -> Result<SensorPublisher, MiddlewareError> {
        Self::check_keys(prefix, sensor)?;
        let declare = |topic: &str| -> Result<Publisher<'static>, MiddlewareError> {
            let key = format!("{prefix}/{sensor}/{topic}");
            let encoding = match encoding {
                Encoding::Json => zenoh::bytes::Encoding::APPLICATION_JSON,
                Encoding::Cbor => zenoh::bytes::Encoding::APPLICATION_CBOR,
            };
            session
                .declare_publisher(key.clone())
                .encoding(encoding)
                .congestion_control(CongestionControl::Block)
                .wait()
                .map_err(|e| MiddlewareError::Zenoh { key, reason: e.to_string() })
        };
        Ok(SensorPublisher {
            touches: declare(TOPICS[0])?,
            events: declare(TOPICS[1])?,
            image: if image { Some(declare(TOPICS[2])?) } else { None },
            encoding,
            buffer: Vec::new(),
        })
    }

    /// Refuses a prefix that is not a key expression to publish on (one with a wildcard), or a
    /// sensor's name that is not one chunk of one.
    pub fn check_keys(prefix: &str, sensor: &str) -> Result<(), MiddlewareError> {
        publish_key("the --publish prefix", prefix)?;
        publish_key("the sensor's name", sensor)?;
        if sensor.contains('/') {
            return Err(MiddlewareError::Key {
                what: "the sensor's name",
                key: sensor.to_owned(),
                use_: "publish on",
                reason: "it holds a `/`; a sensor's name is one chunk of the key (its prefix goes in --publish)"
                    .to_owned(),
            });
        }
        Ok(())
    }

    /// The key each frame's line goes to.
    pub fn touches_key(&self) -> &str {
        self.touches.key_expr().as_str()
    }

    /// Waits until a subscriber to the frames' key is there, up to `timeout`.
    pub fn wait_for_subscriber(&self, timeout: Duration) -> Result<(), MiddlewareError> {
        let start = Instant::now();
        loop {
            let status = self
                .touches
                .matching_status()
                .wait()
                .map_err(|e| MiddlewareError::Zenoh { key: self.touches_key().to_owned(), reason: e.to_string() })?;
            if status.matching() {
                return Ok(());
            }
            if start.elapsed() >= timeout {
                return Err(MiddlewareError::NoSubscriber {
                    key: self.touches_key().to_owned(),
                    waited_s: timeout.as_secs_f64(),
                });
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    /// Publishes a frame's line.
    pub fn frame(&mut self, line: &FrameLine) -> Result<(), MiddlewareError> {
        Self::put(&self.touches, self.encoding, &mut self.buffer, line)
    }

    /// Publishes an event (the start line is [`Event::Start`]).
    pub fn event(&mut self, event: &Event) -> Result<(), MiddlewareError> {
        Self::put(&self.events, self.encoding, &mut self.buffer, event)
    }

    /// Publishes a frame's image, if images were asked for.
    pub fn image(&mut self, image: &ImageMessage<'_>) -> Result<(), MiddlewareError> {
        match &self.image {
            Some(publisher) => Self::put(publisher, self.encoding, &mut self.buffer, image),
            None => Ok(()),
        }
    }

    /// Whether images are published.
    pub fn publishes_images(&self) -> bool {
        self.image.is_some()
    }

    fn put(
        publisher: &Publisher<'static>,
        encoding: Encoding,
        buffer: &mut Vec<u8>,
        value: &impl Serialize,
    ) -> Result<(), MiddlewareError> {
        encoding.encode_into(value, buffer)?;
        publisher.put(buffer.as_slice()).wait().map_err(|e| MiddlewareError::Zenoh {
            key: publisher.key_expr().as_str().to_owned(),
            reason: e.to_string(),
        })
    }
}

impl std::fmt::Debug for SensorPublisher {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SensorPublisher")
            .field("touches", &self.touches_key())
            .field("encoding", &self.encoding)
            .field("image", &self.image.is_some())
            .finish_non_exhaustive()
    }
}
