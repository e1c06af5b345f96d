//! `eitskin run` on Zenoh: the session's flags (as Zenoh's own tools take them), the
//! [`Publishing`] sink, and the frames of `--source zenoh:KEY`. What goes where, in which
//! encoding, is [`eitskin_io::middleware`]'s.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{bail, Result};
use eitskin_io::middleware::{self, Encoding, ImageMessage, Mode, SensorPublisher, ZenohSettings};
use eitskin_io::source::{Source, SourceSpec};
use eitskin_io::stream::{Event, Raster, Start};

use super::sink::{Flow, Processed, Sink};
use crate::ranges;

/// The prefix of the keys published on without one (`--publish zenoh`).
pub const DEFAULT_PREFIX: &str = "eitskin";

/// Flags of the Zenoh session and of what is published on it.
#[derive(Debug, Clone, clap::Args)]
pub struct ZenohArgs {
    /// Publish every frame's line, the events and (with --publish-image) the image on Zenoh:
    /// `zenoh` or `zenoh:PREFIX`, under PREFIX/SENSOR/touches, PREFIX/SENSOR/events and
    /// PREFIX/SENSOR/image (PREFIX `eitskin` unless given; SENSOR from --sensor).
    #[arg(long, value_name = "zenoh[:PREFIX]", value_parser = parse_publish)]
    publish: Option<String>,
    /// The sensor's name in the keys published on: one chunk of a key expression (no `/`, no
    /// wildcard).
    #[arg(long, default_value = "skin", requires = "publish")]
    sensor: String,
    /// How published samples are encoded: `json` (the JSON lines' schema) or `cbor` (RFC 8949,
    /// the same fields).
    #[arg(long, default_value = "json", requires = "publish")]
    publish_encoding: Encoding,
    /// Publish each imaged frame's raster too (PREFIX/SENSOR/image; about 4,000 numbers a frame).
    #[arg(long, requires = "publish")]
    publish_image: bool,
    /// Before the first frame, wait up to this many seconds, in (0, 3600], for a subscriber to
    /// PREFIX/SENSOR/touches, and fail if none comes: for a replay whose every frame must be read
    /// (a serial board's frames are not read meanwhile).
    #[arg(long, value_name = "SECONDS", requires = "publish",
          value_parser = ranges::number("a wait", "(0, 3600] s", "10", |s| s > 0.0 && s <= 3600.0))]
    wait_for_subscriber: Option<f64>,
    /// A Zenoh configuration file (JSON5, as zenohd and Zenoh's tools read), applied first.
    #[arg(long, value_name = "FILE")]
    zenoh_config: Option<PathBuf>,
    /// The Zenoh session's mode: `peer` (Zenoh's default) or `client`.
    #[arg(long, value_name = "MODE")]
    zenoh_mode: Option<Mode>,
    /// A Zenoh endpoint to connect to, e.g. tcp/192.168.1.10:7447 (repeat for several).
    #[arg(long, value_name = "ENDPOINT")]
    connect: Vec<String>,
    /// A Zenoh endpoint to listen on, e.g. tcp/0.0.0.0:7447 (repeat for several).
    #[arg(long, value_name = "ENDPOINT")]
    listen: Vec<String>,
    /// Do not look for Zenoh peers by multicast: reach only the endpoints given.
    #[arg(long)]
    no_multicast_scouting: bool,
}

/// `zenoh` or `zenoh:PREFIX` → the prefix.
fn parse_publish(text: &str) -> Result<String, String> {
    match text.strip_prefix("zenoh") {
        Some("") => Ok(DEFAULT_PREFIX.to_owned()),
        Some(rest) if rest.len() > 1 && rest.starts_with(':') => Ok(rest[1..].to_owned()),
        _ => Err(format!("{text:?}: write `zenoh` or `zenoh:PREFIX`, e.g. zenoh:robot/skin")),
    }
}

impl ZenohArgs {
    /// Whether a Zenoh session is needed (publishing, or frames from Zenoh), the keys and
    /// endpoints checked before any work; session flags without either are refused.
    pub fn check(&self, source: &SourceSpec) -> Result<bool> {
        let needed = self.publish.is_some() || matches!(source, SourceSpec::Zenoh { .. });
        let given = [
            (self.zenoh_config.is_some(), "--zenoh-config"),
            (self.zenoh_mode.is_some(), "--zenoh-mode"),
            (!self.connect.is_empty(), "--connect"),
            (!self.listen.is_empty(), "--listen"),
            (self.no_multicast_scouting, "--no-multicast-scouting"),
        ];
        if let (false, Some((_, flag))) = (needed, given.iter().find(|(set, _)| *set)) {
            bail!("{flag} sets up Zenoh, which this run does not use; add --publish zenoh or --source zenoh:KEY");
        }
        if let Some(prefix) = &self.publish {
            SensorPublisher::check_keys(prefix, &self.sensor)?;
        }
        if needed {
            self.settings().config()?;
        }
        Ok(needed)
    }

    /// The session, opened as the flags say.
    pub fn open(&self) -> Result<middleware::Session> {
        Ok(middleware::open(&self.settings())?)
    }

    fn settings(&self) -> ZenohSettings {
        ZenohSettings {
            config: self.zenoh_config.clone(),
            mode: self.zenoh_mode,
            connect: self.connect.clone(),
            listen: self.listen.clone(),
            multicast_scouting: !self.no_multicast_scouting,
        }
    }

    /// The publishing sink, if asked for, once a subscriber is there when asked to wait for one.
    pub fn sink(&self, session: Option<&middleware::Session>, metres: f64) -> Result<Option<Publishing>> {
        let (Some(prefix), Some(session)) = (&self.publish, session) else { return Ok(None) };
        let publisher = SensorPublisher::new(session, prefix, &self.sensor, self.publish_encoding, self.publish_image)?;
        eprintln!("eitskin run: publishing on {} ({})", publisher.touches_key(), self.publish_encoding.media_type());
        if let Some(seconds) = self.wait_for_subscriber {
            publisher.wait_for_subscriber(Duration::from_secs_f64(seconds))?;
        }
        Ok(Some(Publishing { publisher, raster: Raster::default(), metres }))
    }
}

/// The frames of `--source zenoh:KEY` on `session`, at most `frames` of them.
pub fn source(session: &middleware::Session, key: &str, measurements: usize, frames: Option<u64>) -> Result<Source> {
    let source = middleware::ZenohSource::open(session, key, measurements)?;
    Ok(Source::new(Box::new(source), frames))
}

/// Every event and frame published on Zenoh (see [`eitskin_io::middleware`]); a sample that
/// cannot be sent ends the run with Zenoh's error.
pub struct Publishing {
    publisher: SensorPublisher,
    /// The last image's raster, reused.
    raster: Raster,
    /// Metres per length unit of the spec.
    metres: f64,
}

impl Sink for Publishing {
    fn start(&mut self, start: &Start) -> Result<Flow> {
        self.publisher.start(start)?;
        Ok(Flow::Go)
    }
    fn event(&mut self, event: &Event) -> Result<Flow> {
        self.publisher.event(event)?;
        Ok(Flow::Go)
    }
    fn frame(&mut self, frame: &Processed<'_>) -> Result<Flow> {
        self.publisher.frame(frame.line)?;
        if self.publisher.publishes_images() && frame.status.imaged() {
            self.raster.set(frame.pipeline.image(), self.metres);
            self.publisher.image(&ImageMessage { seq: frame.line.seq, t: frame.line.t, raster: &self.raster })?;
        }
        Ok(Flow::Go)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn publish_takes_zenoh_with_or_without_a_prefix() {
        assert_eq!(parse_publish("zenoh").unwrap(), DEFAULT_PREFIX);
        assert_eq!(parse_publish("zenoh:robot/arm").unwrap(), "robot/arm");
        for bad in ["zenoh:", "ros2", "zenohx", ""] {
            assert!(parse_publish(bad).unwrap_err().contains(&format!("{bad:?}")), "{bad}");
        }
    }
}
