//! `eitskin run` on Zenoh and ROS 2: the session's flags (as Zenoh's own tools take them), the
//! [`Publishing`] sink, and the frames of `--source zenoh:KEY`. What goes where, in which
//! encoding, is [`eitskin_io::middleware`]'s.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{bail, Result};
use eitskin::SensorSpec;
use eitskin_io::middleware::ros2::{Ros2Publisher, Ros2Settings, MAX_DOMAIN};
use eitskin_io::middleware::{self, Encoding, ImageMessage, Mode, SensorPublisher, ZenohSettings};
use eitskin_io::source::{Source, SourceSpec};
use eitskin_io::stream::{Event, Raster, Start};

use super::sink::{Flow, Processed, Sink};
use crate::ranges;

/// The prefix of the keys published on without one (`--publish zenoh`), and the ROS namespace
/// without one (`--publish ros2`).
pub const DEFAULT_PREFIX: &str = "eitskin";

/// Where results are published: eitskin's own keys, or ROS 2's topics.
#[derive(Debug, Clone, PartialEq)]
pub enum Target {
    /// `zenoh[:PREFIX]`: under PREFIX/SENSOR/…
    Zenoh(String),
    /// `ros2[:NAMESPACE]`: ROS 2 topics /NAMESPACE/SENSOR/…, through rmw_zenoh's layout.
    Ros2(String),
}

/// Flags of the Zenoh session and of what is published on it.
#[derive(Debug, Clone, clap::Args)]
pub struct ZenohArgs {
    /// Publish every frame's results: `zenoh[:PREFIX]`, the JSON line, the events and (with
    /// --publish-image) the image under PREFIX/SENSOR/{touches,events,image}; or `ros2[:NAMESPACE]`,
    /// ROS 2 messages on /NAMESPACE/SENSOR/{touches,wrench,markers,image} as rmw_zenoh carries
    /// them (PREFIX and NAMESPACE `eitskin` unless given; SENSOR from --sensor). Give both to
    /// publish both.
    #[arg(long, value_name = "zenoh[:PREFIX]|ros2[:NAMESPACE]", value_parser = parse_publish)]
    publish: Vec<Target>,
    /// The sensor's name in what is published: one chunk of a key expression (no `/`, no
    /// wildcard), and with ros2 a ROS name (letters, digits, `_`).
    #[arg(long, default_value = "skin", requires = "publish")]
    pub sensor: String,
    /// The ROS domain published in with --publish ros2, in [0, 232] (ROS_DOMAIN_ID, else 0).
    #[arg(long, value_name = "ID",
          value_parser = ranges::whole("a ROS domain", 0, MAX_DOMAIN as usize))]
    ros_domain: Option<usize>,
    /// How samples on eitskin's own keys (--publish zenoh) are encoded: `json` (the JSON lines'
    /// schema) or `cbor` (RFC 8949, the same fields).
    #[arg(long, default_value = "json", requires = "publish")]
    publish_encoding: Encoding,
    /// Publish each imaged frame's raster too (PREFIX/SENSOR/image, /NAMESPACE/SENSOR/image;
    /// about 4,000 numbers a frame).
    #[arg(long, requires = "publish")]
    publish_image: bool,
    /// Before the first frame, wait up to this many seconds, in (0, 3600], for a subscriber to
    /// the touches (of each --publish), and fail if none comes: for a replay whose every frame must be read
    /// (a serial board's frames are not read meanwhile); ROS 2 messages then wait for room on the
    /// link rather than being dropped.
    #[arg(long, value_name = "SECONDS", requires = "publish",
          value_parser = ranges::number("a wait", "(0, 3600] s", "10", |s| s > 0.0 && s <= 3600.0))]
    wait_for_subscriber: Option<f64>,
    #[command(flatten)]
    pub session: SessionArgs,
}

/// The Zenoh session's flags, as Zenoh's own tools take them.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct SessionArgs {
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

impl SessionArgs {
    /// The flags given, by name.
    pub fn given(&self) -> Vec<&'static str> {
        [
            (self.zenoh_config.is_some(), "--zenoh-config"),
            (self.zenoh_mode.is_some(), "--zenoh-mode"),
            (!self.connect.is_empty(), "--connect"),
            (!self.listen.is_empty(), "--listen"),
            (self.no_multicast_scouting, "--no-multicast-scouting"),
        ]
        .into_iter()
        .filter_map(|(set, flag)| set.then_some(flag))
        .collect()
    }

    /// Checks the settings (endpoints parsed, TCP only) before any work.
    pub fn check(&self) -> Result<()> {
        self.settings().config()?;
        Ok(())
    }

    /// The session, opened as the flags say.
    pub fn open(&self) -> Result<middleware::Session> {
        Ok(middleware::open(&self.settings())?)
    }

    /// The configuration file as given, made absolute (before `serve` moves into its fleet's folder).
    pub fn absolute(mut self) -> Result<SessionArgs> {
        if let Some(path) = &self.zenoh_config {
            self.zenoh_config = Some(std::path::absolute(path)?);
        }
        Ok(self)
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
}

/// `zenoh[:PREFIX]` or `ros2[:NAMESPACE]` → where to publish.
fn parse_publish(text: &str) -> Result<Target, String> {
    let named = |kind: &str| match text.strip_prefix(kind) {
        Some("") => Some(Ok(DEFAULT_PREFIX.to_owned())),
        Some(rest) if rest.len() > 1 && rest.starts_with(':') => Some(Ok(rest[1..].to_owned())),
        Some(_) => Some(Err(())),
        None => None,
    };
    match (named("zenoh"), named("ros2")) {
        (Some(Ok(prefix)), _) => Ok(Target::Zenoh(prefix)),
        (_, Some(Ok(namespace))) => Ok(Target::Ros2(namespace.trim_matches('/').to_owned())),
        _ => Err(format!("{text:?}: write `zenoh`, `zenoh:PREFIX`, `ros2` or `ros2:NAMESPACE`, e.g. zenoh:robot/skin")),
    }
}

impl ZenohArgs {
    /// Whether a Zenoh session is needed (publishing, or frames from Zenoh), the keys and
    /// endpoints checked before any work; session flags without either are refused.
    pub fn check(&self, source: &SourceSpec) -> Result<bool> {
        let needed = !self.publish.is_empty() || matches!(source, SourceSpec::Zenoh { .. });
        if let (false, Some(flag)) = (needed, self.session.given().first()) {
            bail!("{flag} sets up Zenoh, which this run does not use; add --publish zenoh or --source zenoh:KEY");
        }
        let (zenoh, ros2) = (self.zenoh_prefix(), self.ros_namespace());
        if self.publish.len() > usize::from(zenoh.is_some()) + usize::from(ros2.is_some()) {
            bail!("--publish names zenoh or ros2 more than once; give each at most once");
        }
        if let Some(prefix) = zenoh {
            SensorPublisher::check_keys(prefix, &self.sensor)?;
        } else if self.publish_encoding != Encoding::Json {
            bail!("--publish-encoding applies to --publish zenoh (ROS 2 messages are CDR)");
        }
        match (ros2, self.ros_domain) {
            (Some(_), _) => self.ros2(None)?.check()?,
            (None, Some(domain)) => {
                bail!("--ros-domain {domain} applies to --publish ros2, which this run does not use")
            }
            (None, None) => {}
        }
        if needed {
            self.session.check()?;
        }
        Ok(needed)
    }

    /// The session, opened as the flags say.
    pub fn open(&self) -> Result<middleware::Session> {
        self.session.open()
    }

    /// Whether anything is published.
    pub fn publishes(&self) -> bool {
        !self.publish.is_empty()
    }

    fn zenoh_prefix(&self) -> Option<&str> {
        self.publish.iter().find_map(|t| if let Target::Zenoh(p) = t { Some(p.as_str()) } else { None })
    }

    fn ros_namespace(&self) -> Option<&str> {
        self.publish.iter().find_map(|t| if let Target::Ros2(n) = t { Some(n.as_str()) } else { None })
    }

    /// The ROS 2 settings: the domain from --ros-domain, else ROS_DOMAIN_ID, else 0.
    fn ros2(&self, spec: Option<&SensorSpec>) -> Result<Ros2Settings> {
        let domain = match (self.ros_domain, std::env::var("ROS_DOMAIN_ID")) {
            (Some(domain), _) => domain as u32,
            (None, Ok(text)) if !text.trim().is_empty() => match text.trim().parse::<u32>() {
                Ok(domain) if domain <= MAX_DOMAIN => domain,
                _ => bail!("ROS_DOMAIN_ID={text:?} is not a ROS domain (an integer in [0, {MAX_DOMAIN}]); set it right, or give --ros-domain"),
            },
            _ => 0,
        };
        Ok(Ros2Settings {
            domain,
            namespace: self.ros_namespace().unwrap_or(DEFAULT_PREFIX).to_owned(),
            sensor: self.sensor.clone(),
            mount: spec.and_then(|s| s.mount.clone()),
            image: self.publish_image,
            // Waiting for a subscriber is for a replay whose every frame must be read.
            every_message: self.wait_for_subscriber.is_some(),
        })
    }

    /// The publishing sink, if asked for, once a subscriber is there when asked to wait for one;
    /// the sensor's mount comes from `spec`.
    pub fn sink(&self, session: Option<&middleware::Session>, spec: &SensorSpec) -> Result<Option<Publishing>> {
        let Some(session) = session.filter(|_| !self.publish.is_empty()) else { return Ok(None) };
        let wait = self.wait_for_subscriber.map(Duration::from_secs_f64);
        let zenoh = match self.zenoh_prefix() {
            Some(prefix) => {
                let publisher =
                    SensorPublisher::new(session, prefix, &self.sensor, self.publish_encoding, self.publish_image)?;
                eprintln!(
                    "eitskin run: publishing on {} ({})",
                    publisher.touches_key(),
                    self.publish_encoding.media_type()
                );
                if let Some(wait) = wait {
                    publisher.wait_for_subscriber(wait)?;
                }
                Some(publisher)
            }
            None => None,
        };
        let ros2 = match self.ros_namespace() {
            Some(_) => {
                let settings = self.ros2(Some(spec))?;
                let publisher = Ros2Publisher::new(session, settings.clone())?;
                eprintln!(
                    "eitskin run: publishing ROS 2 topics {} (domain {}, frame {})",
                    settings.topic("{touches,wrench,markers}"),
                    settings.domain,
                    settings.frame_id()
                );
                if let Some(m) = &settings.mount {
                    let ([x, y, z], [qx, qy, qz, qw]) = (m.position, m.unit_orientation());
                    eprintln!(
                        "eitskin run: markers are drawn on {}; the sensor's frame is placed there by: ros2 run tf2_ros \
                         static_transform_publisher --x {x} --y {y} --z {z} --qx {qx} --qy {qy} --qz {qz} --qw {qw} \
                         --frame-id {} --child-frame-id {}",
                        m.parent, m.parent, m.frame_id
                    );
                }
                if let Some(wait) = wait {
                    publisher.wait_for_subscriber(wait)?;
                }
                Some(publisher)
            }
            None => None,
        };
        Ok(Some(Publishing { zenoh, ros2, raster: Raster::default(), metres: spec.length_unit.metres() }))
    }
}

/// The frames of `--source zenoh:KEY` on `session`, at most `frames` of them.
pub fn source(session: &middleware::Session, key: &str, measurements: usize, frames: Option<u64>) -> Result<Source> {
    let source = middleware::ZenohSource::open(session, key, measurements)?;
    Ok(Source::new(Box::new(source), frames))
}

/// Every event and frame published on Zenoh, on eitskin's keys and ROS 2's topics (see
/// [`eitskin_io::middleware`]); a sample that cannot be sent ends the run with Zenoh's error.
pub struct Publishing {
    zenoh: Option<SensorPublisher>,
    ros2: Option<Ros2Publisher>,
    /// The last image's raster, reused.
    raster: Raster,
    /// Metres per length unit of the spec.
    metres: f64,
}

impl Sink for Publishing {
    fn start(&mut self, start: &Start) -> Result<Flow> {
        if let Some(zenoh) = &mut self.zenoh {
            zenoh.start(start)?;
        }
        Ok(Flow::Go)
    }
    fn event(&mut self, event: &Event) -> Result<Flow> {
        if let Some(zenoh) = &mut self.zenoh {
            zenoh.event(event)?;
        }
        Ok(Flow::Go)
    }
    fn frame(&mut self, frame: &Processed<'_>) -> Result<Flow> {
        let images = self.zenoh.as_ref().is_some_and(|z| z.publishes_images())
            || self.ros2.as_ref().is_some_and(|r| r.publishes_images());
        if images && frame.status.imaged() {
            self.raster.set(frame.pipeline.image(), self.metres);
        }
        if let Some(zenoh) = &mut self.zenoh {
            zenoh.frame(frame.line)?;
            if zenoh.publishes_images() && frame.status.imaged() {
                zenoh.image(&ImageMessage { seq: frame.line.seq, t: frame.line.t, raster: &self.raster })?;
            }
        }
        if let Some(ros2) = &mut self.ros2 {
            ros2.frame(frame.line, self.metres)?;
            if frame.status.imaged() {
                ros2.image(&self.raster)?;
            }
        }
        Ok(Flow::Go)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn publish_takes_zenoh_or_ros2_with_or_without_a_prefix() {
        assert_eq!(parse_publish("zenoh").unwrap(), Target::Zenoh(DEFAULT_PREFIX.into()));
        assert_eq!(parse_publish("zenoh:robot/arm").unwrap(), Target::Zenoh("robot/arm".into()));
        assert_eq!(parse_publish("ros2").unwrap(), Target::Ros2(DEFAULT_PREFIX.into()));
        assert_eq!(parse_publish("ros2:/robot/skin/").unwrap(), Target::Ros2("robot/skin".into()));
        for bad in ["zenoh:", "ros2:", "ros", "zenohx", ""] {
            assert!(parse_publish(bad).unwrap_err().contains(&format!("{bad:?}")), "{bad}");
        }
    }
}
