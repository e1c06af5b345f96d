//! Custom protocol files (JSON): drive and measurement quads, or whole patterns.
//!
//! ```json
//! { "description": "my board", "electrodes": 16, "index_base": 1,
//!   "quads": [[1, 2, 3, 4], [1, 2, 4, 5]] }
//! ```
//! Each quad is `[drive+, drive−, measure+, measure−]` with 1 A from drive+ to drive− and the
//! value U(measure+) − U(measure−). Electrodes count from 1 unless `index_base` is 0 (as in
//! EIDORS' exported files, which this reads as they are). Instead of `quads`, a file may give
//! `stimulations` (current per electrode, A) and `measurements` (`{"stimulation": k, "weights": […]}`
//! with k counted from `index_base`). Other keys are ignored, so files of other tools load.
//!
//! Each stimulation's currents sum to 0 and each measurement's weights sum to 0 (a
//! difference). A stimulation must drive some current and a measurement weigh some electrode
//! (all zeros are refused), and no current may be past ±1e3 A nor any weight past ±1e3 in
//! size ([`MAX_CURRENT`], [`MAX_WEIGHT`]): boards drive mA and weigh by ±1, so a larger value is
//! a unit slip. A sensor takes a protocol of as many electrodes as its spec's
//! `electrodes.count` ([`read_protocol_for`]).
//!
//! [`MAX_CURRENT`]: eitskin::protocol::MAX_CURRENT
//! [`MAX_WEIGHT`]: eitskin::protocol::MAX_WEIGHT
//!
//! Published data sets give the patterns as two matrices instead, in a MAT file
//! ([`read_protocol_matrices`]): the currents of each stimulation (electrodes × stimulations,
//! e.g. `Inj`) and the weights of each measurement pattern (electrodes × patterns, e.g. `Mpat`),
//! every stimulation measured with every pattern, stimulation by stimulation (EIDORS' order).

use std::path::Path;

use eitskin::{Measurement, Protocol};
use serde::Deserialize;

use crate::{Error, FrameLayout, FrameSelect};

#[derive(Debug, Deserialize)]
struct ProtocolJson {
    #[serde(default)]
    description: Option<String>,
    #[serde(default)]
    electrodes: Option<usize>,
    #[serde(default = "one")]
    index_base: usize,
    #[serde(default)]
    quads: Option<Vec<[usize; 4]>>,
    #[serde(default)]
    stimulations: Option<Vec<Vec<f64>>>,
    #[serde(default)]
    measurements: Option<Vec<MeasurementJson>>,
}

#[derive(Debug, Deserialize)]
struct MeasurementJson {
    stimulation: usize,
    weights: Vec<f64>,
}

fn one() -> usize {
    1
}

/// Reads a protocol file.
pub fn read_protocol(path: &Path) -> Result<Protocol, Error> {
    let text = crate::read_text(path)?;
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    parse_protocol(&text, &name).map_err(|e| e.in_file(path))
}

/// Reads a protocol file for a sensor of `electrodes` electrodes, refusing one of another
/// count, naming the file.
pub fn read_protocol_for(path: &Path, electrodes: usize) -> Result<Protocol, Error> {
    let protocol = read_protocol(path)?;
    check_electrodes(&protocol, electrodes).map_err(|e| e.in_file(path))?;
    Ok(protocol)
}

/// Refuses `protocol` unless it has `electrodes` electrodes (the spec's `electrodes.count`).
fn check_electrodes(protocol: &Protocol, electrodes: usize) -> Result<(), Error> {
    let count = protocol.electrode_count();
    if count == electrodes {
        return Ok(());
    }
    Err(Error::Key {
        path: None,
        key: "electrodes",
        reason: format!(
            "is {count} (as given, or the most its patterns name), but the sensor has {electrodes} electrodes (the spec's `electrodes.count`): is it another sensor's protocol?"
        ),
    })
}

/// A protocol from two matrices of a MAT file: `stimulation` (the current of each electrode in
/// each stimulation, one column per stimulation) and `measurement` (the weights of each
/// electrode in each measurement pattern, one column per pattern), for `electrodes`
/// electrodes; a matrix given the other way round (one row per pattern) is read as such. The
/// measurements are every pattern for stimulation 1, then every pattern for stimulation 2, …
pub fn read_protocol_matrices(
    path: &Path,
    stimulation: &str,
    measurement: &str,
    electrodes: usize,
) -> Result<Protocol, Error> {
    let patterns = |variable: &str| -> Result<Vec<Vec<f64>>, Error> {
        let mut shape = None;
        for layout in [FrameLayout::Columns, FrameLayout::Rows] {
            let table = crate::read_frames(path, &FrameSelect { variable: Some(variable.to_string()), layout })?;
            let columns = table.frames.first().map_or(0, Vec::len);
            if table.imaginary.is_none() && columns == electrodes {
                return Ok(table.frames);
            }
            shape.get_or_insert((columns, table.frames.len(), table.imaginary.is_some()));
        }
        let (rows, columns, complex) = shape.unwrap_or_default();
        let what = if complex { "complex" } else { "real" };
        Err(Error::Key {
            path: Some(path.to_path_buf()),
            key: "protocol",
            reason: format!(
                "`{variable}` is a {what} {rows} × {columns} matrix; a pattern matrix must be real with one side of {electrodes} (the spec's electrodes)"
            ),
        })
    };
    let stimulations = patterns(stimulation)?;
    let weights = patterns(measurement)?;
    let measurements = (0..stimulations.len())
        .flat_map(|s| weights.iter().map(move |w| Measurement { stimulation: s, weights: w.clone() }))
        .collect();
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let description = format!("{stimulation} × {measurement} from {name}");
    Protocol::new(description, electrodes, stimulations, measurements).map_err(|e| Error::from(e).in_file(path))
}

/// Parses protocol JSON; `name` describes it when the file has no `description`.
pub fn parse_protocol(text: &str, name: &str) -> Result<Protocol, Error> {
    // serde names the shapes it expected by their Rust names: say them in the file's words.
    let file: ProtocolJson = serde_json::from_str(text).map_err(|e| {
        let message = e
            .to_string()
            .replace("struct ProtocolJson", "a protocol object (`quads`, or `stimulations` and `measurements`)")
            .replace("struct MeasurementJson", "a measurement (`stimulation` and `weights`)");
        Error::Json { path: None, message }
    })?;
    let description = file.description.unwrap_or_else(|| format!("custom protocol from {name}"));
    if file.index_base > 1 {
        return Err(Error::Key {
            path: None,
            key: "index_base",
            reason: format!("must be 0 or 1, got {}", file.index_base),
        });
    }
    let base = file.index_base;
    match (file.quads, file.stimulations, file.measurements) {
        (Some(quads), None, None) => {
            let count =
                file.electrodes.unwrap_or_else(|| quads.iter().flatten().map(|&e| e + 1 - base).max().unwrap_or(0));
            // Shift to 1-based; a 0 in a 1-based file stays 0 and is reported by `from_quads`.
            let quads: Vec<[usize; 4]> = quads.iter().map(|q| q.map(|e| e + 1 - base)).collect();
            Ok(Protocol::from_quads(description, count, &quads)?)
        }
        (None, Some(stimulations), Some(measurements)) => {
            let count = file.electrodes.unwrap_or_else(|| stimulations.first().map_or(0, Vec::len));
            let mut checked = Vec::with_capacity(measurements.len());
            for (row, m) in measurements.into_iter().enumerate() {
                let Some(stimulation) = m.stimulation.checked_sub(base) else {
                    return Err(Error::Key {
                        path: None,
                        key: "measurements",
                        reason: format!("measurement {} names stimulation 0, but they count from 1", row + 1),
                    });
                };
                checked.push(Measurement { stimulation, weights: m.weights });
            }
            Ok(Protocol::new(description, count, stimulations, checked)?)
        }
        _ => Err(Error::Key {
            path: None,
            key: "quads",
            reason: "give either `quads`, or both `stimulations` and `measurements`".into(),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_and_one_based_quads_agree_with_the_builtin() {
        let one = r#"{"electrodes": 16, "quads": [[2,1,3,4],[2,1,4,5]]}"#;
        let zero = r#"{"index_base": 0, "electrodes": 16, "quads": [[1,0,2,3],[1,0,3,4]], "v_homog": [1, 2]}"#;
        let a = parse_protocol(one, "a").unwrap();
        let b = parse_protocol(zero, "b").unwrap();
        assert_eq!(a.measurements(), b.measurements());
        let builtin = Protocol::adjacent(16, true).unwrap();
        assert_eq!(a.stimulations()[0], builtin.stimulations()[0]);
        assert_eq!(a.measurements()[0], builtin.measurements()[0]);
    }

    /// All-zero and huge patterns are refused, naming the file and the pattern; a protocol
    /// of another electrode count than the sensor's names the file.
    #[test]
    fn empty_huge_and_other_sensors_patterns_name_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let write = |name: &str, text: &str| {
            let path = dir.path().join(name);
            std::fs::write(&path, text).unwrap();
            path
        };
        let message = |path: &Path| crate::full_message(&read_protocol_for(path, 3).unwrap_err());
        let zero = write(
            "zero.json",
            r#"{"stimulations": [[1, -1, 0], [0, 0, 0]], "measurements": [{"stimulation": 1, "weights": [0, 1, -1]}]}"#,
        );
        let text = message(&zero);
        assert!(text.contains("zero.json") && text.contains("stimulation 2 drives no current"), "{text}");
        let huge = write(
            "huge.json",
            r#"{"stimulations": [[1e300, -1e300, 0]], "measurements": [{"stimulation": 1, "weights": [0, 1, -1]}]}"#,
        );
        let text = message(&huge);
        assert!(text.contains("huge.json") && text.contains("1e300 A on electrode 1: past ±1e3 A"), "{text}");
        let eight = write("pr_el8.json", r#"{"quads": [[1, 2, 3, 4], [1, 2, 7, 8]]}"#);
        let text = message(&eight);
        assert!(text.starts_with(&format!("{}: `electrodes` is 8", eight.display())), "{text}");
        assert!(text.contains("the sensor has 3 electrodes"), "{text}");
        let three = write("three.json", r#"{"quads": [[1, 2, 2, 3]]}"#);
        assert_eq!(read_protocol_for(&three, 3).unwrap().electrode_count(), 3);
    }

    #[test]
    fn bad_files_say_what() {
        let err = parse_protocol(r#"{"electrodes": 16, "quads": [[1,2,3,17]]}"#, "x").unwrap_err();
        assert_eq!(
            crate::full_message(&err),
            "the protocol is not valid: row 1 names electrode 17, but electrodes are numbered 1 to 16"
        );
        let err = parse_protocol(r#"{"electrodes": 16}"#, "x").unwrap_err();
        assert!(err.to_string().contains("give either `quads`"), "{err}");
        // JSON of another shape is named in the file's words, not serde's names for its types.
        for other in ["[1, 2, 3]", r#"{"measurements": [5]}"#] {
            let err = crate::full_message(&parse_protocol(other, "x").unwrap_err());
            assert!(err.contains("expected a ") && !err.contains("Json"), "{other}: {err}");
        }
    }
}
