//! A Zenoh session opened as Zenoh's own tools (`z_pub`, `z_sub`) open one: a configuration file,
//! then the mode, the endpoints and multicast scouting given on the command line over it.

use std::path::PathBuf;

use zenoh::config::{Config, EndPoint};
use zenoh::Wait;

use super::MiddlewareError;

/// Whether the session is a peer (talks to peers directly, listens) or a client (through a
/// router or a peer it connects to).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// A peer: Zenoh's default.
    Peer,
    /// A client of the peer or router it connects to.
    Client,
}

impl std::str::FromStr for Mode {
    type Err = String;

    /// `peer` or `client`.
    fn from_str(text: &str) -> Result<Mode, String> {
        match text {
            "peer" => Ok(Mode::Peer),
            "client" => Ok(Mode::Client),
            _ => Err(format!("{text:?} is not a Zenoh mode; use `peer` or `client`")),
        }
    }
}

/// How to open the session; what is not set is Zenoh's default (or the file's).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ZenohSettings {
    /// A Zenoh configuration file (JSON5), read first.
    pub config: Option<PathBuf>,
    /// The mode, over the file's.
    pub mode: Option<Mode>,
    /// Endpoints to connect to (`tcp/HOST:PORT`), over the file's.
    pub connect: Vec<String>,
    /// Endpoints to listen on (`tcp/HOST:PORT`), over the file's.
    pub listen: Vec<String>,
    /// Whether peers are looked for by multicast (Zenoh's default: yes); off, only the
    /// endpoints given are reached.
    pub multicast_scouting: bool,
}

impl Default for ZenohSettings {
    /// Zenoh's defaults: a peer, multicast scouting on.
    fn default() -> ZenohSettings {
        ZenohSettings { config: None, mode: None, connect: Vec::new(), listen: Vec::new(), multicast_scouting: true }
    }
}

impl ZenohSettings {
    /// The configuration these settings give, each setting checked (an endpoint that is not
    /// one, or not TCP, is refused here, with its flag and value).
    pub fn config(&self) -> Result<Config, MiddlewareError> {
        let mut config = match &self.config {
            Some(path) => Config::from_file(path)
                .map_err(|e| MiddlewareError::Config { path: path.display().to_string(), reason: e.to_string() })?,
            None => Config::default(),
        };
        let mut set = |key: &str, value: String, flag: &'static str, written: &str| {
            config.insert_json5(key, &value).map_err(|e| MiddlewareError::Setting {
                flag,
                value: written.to_owned(),
                reason: e.to_string(),
            })
        };
        if let Some(mode) = self.mode {
            let name = if mode == Mode::Peer { "peer" } else { "client" };
            set("mode", format!("{name:?}"), "--zenoh-mode", name)?;
        }
        for (flag, endpoints, key) in
            [("--connect", &self.connect, "connect/endpoints"), ("--listen", &self.listen, "listen/endpoints")]
        {
            if endpoints.is_empty() {
                continue;
            }
            for endpoint in endpoints {
                check_endpoint(flag, endpoint)?;
            }
            let list = serde_json::to_string(endpoints).unwrap_or_default();
            set(key, list, flag, &endpoints.join(" "))?;
        }
        if !self.multicast_scouting {
            set("scouting/multicast/enabled", "false".to_owned(), "--no-multicast-scouting", "")?;
        }
        Ok(config)
    }
}

/// Refuses an endpoint that is not `PROTOCOL/ADDRESS`, or whose protocol this build cannot use.
fn check_endpoint(flag: &'static str, endpoint: &str) -> Result<(), MiddlewareError> {
    let refuse = |reason: String| MiddlewareError::Setting { flag, value: endpoint.to_owned(), reason };
    let parsed: EndPoint =
        endpoint.parse().map_err(|e| refuse(format!("not an endpoint ({e}); write e.g. tcp/127.0.0.1:7447")))?;
    let protocol = parsed.protocol();
    if protocol.as_str() != "tcp" {
        return Err(refuse(format!(
            "eitskin is built with Zenoh's TCP links only, not `{}`; write tcp/HOST:PORT",
            protocol.as_str()
        )));
    }
    Ok(())
}

/// Opens a session as `settings` say.
pub fn open(settings: &ZenohSettings) -> Result<zenoh::Session, MiddlewareError> {
    let config = settings.config()?;
    zenoh::open(config).wait().map_err(|e| MiddlewareError::Open { reason: e.to_string() })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_go_over_the_defaults_and_bad_ones_name_their_flag_and_value() {
        let settings = ZenohSettings {
            mode: Some(Mode::Client),
            connect: vec!["tcp/127.0.0.1:7447".into()],
            multicast_scouting: false,
            ..ZenohSettings::default()
        };
        let config = settings.config().unwrap().to_string();
        assert!(config.contains("127.0.0.1:7447") && config.contains("client"), "{config}");
        for (settings, says) in [
            (
                ZenohSettings { connect: vec!["127.0.0.1:7447".into()], ..ZenohSettings::default() },
                "--connect \"127.0.0.1:7447\"",
            ),
            (ZenohSettings { listen: vec!["udp/127.0.0.1:7447".into()], ..ZenohSettings::default() }, "TCP links only"),
            (
                ZenohSettings { config: Some("/nonexistent/zenoh.json5".into()), ..ZenohSettings::default() },
                "--zenoh-config /nonexistent/zenoh.json5",
            ),
        ] {
            let error = settings.config().unwrap_err().to_string();
            assert!(error.contains(says), "{error}");
        }
        assert!("router".parse::<Mode>().unwrap_err().contains("\"router\""));
    }
}
