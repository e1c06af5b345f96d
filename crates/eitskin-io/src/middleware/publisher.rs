//! [`SensorPublisher`]: one sensor's results on Zenoh, under `PREFIX/SENSOR/{touches,events,image}`.

use std::time::{Duration, Instant};

use serde::Serialize;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Publisher;
use zenoh::qos::CongestionControl;
use zenoh::query::Queryable;
use zenoh::{Session, Wait};

use super::{publish_key, Encoding, MiddlewareError};
use crate::stream::{Event, FrameLine, Raster, Start};

/// The key under `PREFIX/SENSOR/` of each frame's line.
pub const TOUCHES: &str = "touches";
/// The key of the events (the start line first).
pub const EVENTS: &str = "events";
/// The key of the images.
pub const IMAGE: &str = "image";
/// The key a query for the start line is answered on.
pub const START: &str = "start";
/// The key of the sensor's liveliness token.
pub const ALIVE: &str = "alive";

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
    session: Session,
    /// `PREFIX/SENSOR`.
    base: String,
    touches: Publisher<'static>,
    events: Publisher<'static>,
    image: Option<Publisher<'static>>,
    encoding: Encoding,
    /// Answers `PREFIX/SENSOR/start` with the start line, once it is known.
    start: Option<Queryable<()>>,
    /// Held while the sensor runs, from its start line on: `PREFIX/SENSOR/alive`'s token, gone
    /// when the process is.
    alive: Option<LivelinessToken>,
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
        let base = format!("{prefix}/{sensor}");
        let declare = |topic: &str| -> Result<Publisher<'static>, MiddlewareError> {
            let key = format!("{base}/{topic}");
            session
                .declare_publisher(key.clone())
                .encoding(encoding.zenoh())
                .congestion_control(CongestionControl::Block)
                .wait()
                .map_err(|e| MiddlewareError::Zenoh { key, reason: e.to_string() })
        };
        Ok(SensorPublisher {
            session: session.clone(),
            touches: declare(TOUCHES)?,
            events: declare(EVENTS)?,
            image: if image { Some(declare(IMAGE)?) } else { None },
            base,
            encoding,
            start: None,
            alive: None,
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
        wait_for_subscriber(&self.touches, timeout)
    }

    /// Publishes the run's start line on the events, answers queries on `PREFIX/SENSOR/start`
    /// with it from now on (a subscriber that joins late learns the unit and settings), then
    /// declares the sensor alive: whoever sees the token can fetch the start line.
    pub fn start(&mut self, start: &Start) -> Result<(), MiddlewareError> {
        let event = Event::Start(start.clone());
        self.encoding.encode_into(&event, &mut self.buffer)?;
        let (key, bytes, encoding) = (format!("{}/{START}", self.base), self.buffer.clone(), self.encoding.zenoh());
        let reply_key = key.clone();
        let queryable = self
            .session
            .declare_queryable(key.clone())
            .callback(move |query| {
                // A querier that went away is no error of the sensor's.
                let _ = query.reply(reply_key.as_str(), bytes.as_slice()).encoding(encoding.clone()).wait();
            })
            .wait()
            .map_err(|e| MiddlewareError::Zenoh { key, reason: e.to_string() })?;
        self.start = Some(queryable);
        let key = format!("{}/{ALIVE}", self.base);
        let token = self.session.liveliness().declare_token(key.clone()).wait();
        self.alive = Some(token.map_err(|e| MiddlewareError::Zenoh { key, reason: e.to_string() })?);
        self.event(&event)
    }

    /// Publishes a frame's line.
    pub fn frame(&mut self, line: &FrameLine) -> Result<(), MiddlewareError> {
        Self::put(&self.touches, self.encoding, &mut self.buffer, line)
    }

    /// Publishes an event (the start line goes through [`SensorPublisher::start`]).
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

/// Waits until `publisher` has a subscriber, up to `timeout`.
pub(crate) fn wait_for_subscriber(publisher: &Publisher<'_>, timeout: Duration) -> Result<(), MiddlewareError> {
    let start = Instant::now();
    let key = || publisher.key_expr().as_str().to_owned();
    loop {
        let status = publisher
            .matching_status()
            .wait()
            .map_err(|e| MiddlewareError::Zenoh { key: key(), reason: e.to_string() })?;
        if status.matching() {
            return Ok(());
        }
        if start.elapsed() >= timeout {
            return Err(MiddlewareError::NoSubscriber { key: key(), waited_s: timeout.as_secs_f64() });
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}
