//! The fleet file of `eitskin serve` (TOML): the sensors one process serves, each a name and the
//! arguments of an `eitskin run` of it (its spec, source, calibration or learned model, what it
//! publishes), so that every flag `run` takes works in a fleet, checked the same way.
//!
//! ```toml
//! [[sensor]]
//! name = "palm"
//! run = ["palm.toml", "--source", "serial:/dev/ttyACM0", "--calibration", "palm-cal.json", "--publish", "ros2"]
//!
//! [[sensor]]
//! name = "forearm"
//! run = ["forearm.toml", "--source", "zenoh:robot/boards/forearm", "--publish", "zenoh:robot/skin"]
//! ```
//!
//! ```
//! let fleet = eitskin_io::parse_fleet("[[sensor]]\nname = \"palm\"\nrun = [\"--source\", \"sim\"]\n")?;
//! assert_eq!((fleet.sensors[0].name.as_str(), fleet.sensors[0].run.len()), ("palm", 2));
//! assert!(eitskin_io::parse_fleet("[[sensor]]\nname = \"a b\"\nrun = []\n").is_err());
//! # Ok::<(), eitskin_io::Error>(())
//! ```

use std::path::Path;

use serde::Deserialize;

use crate::Error;

/// The most sensors one fleet holds.
pub const MAX_SENSORS: usize = 10_000;

/// The sensors of a fleet, in the file's order.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Fleet {
    /// The sensors.
    #[serde(rename = "sensor")]
    pub sensors: Vec<FleetSensor>,
}

/// One sensor of a fleet.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FleetSensor {
    /// Its name: `run --sensor`, in its keys, topics and reports (letters, digits, `_`).
    pub name: String,
    /// The arguments of `eitskin run` for it, after `run` (its spec first, if any).
    pub run: Vec<String>,
}

/// Reads and checks a fleet file.
pub fn read_fleet(path: &Path) -> Result<Fleet, Error> {
    parse_fleet(&crate::read_text(path)?).map_err(|e| e.in_file(path))
}

/// Parses and checks fleet text: 1 to [`MAX_SENSORS`] sensors, each named once, with a name of
/// letters, digits and `_` that does not start with a digit (a Zenoh key's chunk and a ROS name).
pub fn parse_fleet(text: &str) -> Result<Fleet, Error> {
    let fleet: Fleet = toml::from_str(text).map_err(|e| Error::Toml { path: None, message: e.to_string() })?;
    let key = |reason: String| Error::Key { path: None, key: "sensor", reason };
    if fleet.sensors.is_empty() || fleet.sensors.len() > MAX_SENSORS {
        return Err(key(format!("lists {} sensors; a fleet has 1 to {MAX_SENSORS}", fleet.sensors.len())));
    }
    for (k, sensor) in fleet.sensors.iter().enumerate() {
        let name = &sensor.name;
        let good = name.bytes().next().is_some_and(|b| !b.is_ascii_digit())
            && name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_');
        if !good {
            return Err(key(format!(
                "{}: name {name:?} is not a sensor's name (letters, digits and `_`, not starting with a digit)",
                k + 1
            )));
        }
        if let Some(first) = fleet.sensors[..k].iter().position(|s| &s.name == name) {
            return Err(key(format!("{}: name {name:?} is sensor {}'s already; name each once", k + 1, first + 1)));
        }
    }
    Ok(fleet)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_fleets_are_refused_with_the_sensor_and_the_name() {
        let one = "[[sensor]]\nname = \"palm\"\nrun = []\n";
        assert!(parse_fleet(one).is_ok());
        let message = |text: &str| parse_fleet(text).unwrap_err().to_string();
        assert!(message(&format!("{one}{one}")).contains("2: name \"palm\" is sensor 1's already"));
        assert!(message("sensor = []\n").contains("lists 0 sensors"));
        assert!(message(&one.replace("palm", "1palm")).contains("\"1palm\" is not a sensor's name"));
        assert!(message(&one.replace("run = []", "run = []\nspec = \"x\"")).contains("spec"));
        assert!(message(&one.replace("run = []\n", "")).contains("run"));
        // Not TOML, the wrong types, another kind of file.
        assert!(message("[[sensor]\nname = \"palm\"").contains("line 1"));
        assert!(message(&one.replace("run = []", "run = \"--fast\"")).contains("run"));
        assert!(message(&one.replace("name = \"palm\"", "name = 3")).contains("name"));
        assert!(message("{\"sensor\": []}").contains("line 1"));
        let too_many = one.repeat(MAX_SENSORS + 1);
        assert!(message(&too_many).contains(&format!("lists {} sensors", MAX_SENSORS + 1)));
    }
}
