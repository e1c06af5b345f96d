//! Calibration samples (CSV with a header): where each press was, its force, and the peak of
//! its touch or the raw frame.
//!
//! Columns, by name: `unit` (counted from 1) or `x`, `y` (in the spec's units, from the
//! outline's centre); `force` (N, 0 or more; a calibration needs it, a learned position model
//! does not); `depth` (how far the indenter went in, in the spec's units, 0 or more; optional,
//! learned like the force); then either `peak` (S/m) or the frame's measurements (or Δv) in
//! protocol order in all remaining columns. Lines starting with `#` are comments.

use std::path::Path;

use eitskin::inverse::LARGEST_VALUE;
use eitskin::learn::LabelledPress;
use eitskin::SensorSpec;

use crate::Error;

/// Where a sample was pressed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Location {
    /// A pseudo-array unit, 0-based.
    Unit(usize),
    /// A point, in m from the outline's centre.
    Point([f64; 2]),
}

/// What was measured for a sample.
#[derive(Debug, Clone, PartialEq)]
pub enum Measured {
    /// The peak of the press's touch, in S/m.
    Peak(f64),
    /// The raw frame, in protocol order.
    Frame(Vec<f64>),
}

/// One row of a samples file.
#[derive(Debug, Clone, PartialEq)]
pub struct SampleRow {
    /// Where.
    pub location: Location,
    /// Force, in N, when the file has a `force` column.
    pub force: Option<f64>,
    /// The indenter's depth, in m, when the file has a `depth` column.
    pub depth: Option<f64>,
    /// The peak or the frame.
    pub measured: Measured,
}

/// Reads a samples file; `metres` converts x, y from the spec's units (e.g. 1e-3 for mm).
pub fn read_samples(path: &Path, metres: f64) -> Result<Vec<SampleRow>, Error> {
    parse_samples(&crate::read_text(path)?, metres).map_err(|e| e.in_file(path))
}

/// Parses samples CSV (see the module doc).
pub fn parse_samples(text: &str, metres: f64) -> Result<Vec<SampleRow>, Error> {
    let fail = |line: usize, reason: String| Error::Key {
        path: None,
        key: "samples",
        reason: format!("line {line}: {reason}"),
    };
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let Some((_, header)) = lines.next() else {
        return Err(fail(1, "no header line".into()));
    };
    if header.trim_start().starts_with(['{', '[']) {
        let what = crate::json_file_kind(text.as_bytes()).unwrap_or("a JSON file");
        return Err(fail(
            1,
            format!("this is {what}, not samples: those are CSV with a header such as x,y,force,v1,…"),
        ));
    }
    // Names as a spreadsheet may quote them ("x","y").
    let names: Vec<&str> = header.split(',').map(|n| n.trim().trim_matches('"')).collect();
    // A column named twice would leave its second copy read as a channel, or two channels as one.
    for (k, name) in names.iter().enumerate().filter(|(_, n)| !n.is_empty()) {
        let at: Vec<String> = (0..names.len()).filter(|j| names[*j] == *name).map(|j| (j + 1).to_string()).collect();
        if at.len() > 1 && at[0] == (k + 1).to_string() {
            return Err(fail(1, format!("column `{name}` is named {} times (columns {})", at.len(), at.join(", "))));
        }
    }
    let column = |name: &str| names.iter().position(|n| *n == name);
    let location = match (column("unit"), column("x"), column("y")) {
        (Some(_), Some(_), _) | (Some(_), _, Some(_)) => {
            return Err(fail(1, "names both a `unit` column and `x`/`y` columns: give one way to say where".into()))
        }
        (Some(u), _, _) => Ok(u),
        (None, Some(x), Some(y)) => Err((x, y)),
        _ => return Err(fail(1, "needs a `unit` column or `x` and `y` columns".into())),
    };
    let force = column("force");
    let depth = column("depth");
    let peak = column("peak");
    let used: Vec<usize> =
        [force, depth, peak, location.ok(), location.err().map(|p| p.0), location.err().map(|p| p.1)]
            .into_iter()
            .flatten()
            .collect();
    let mut rows = Vec::new();
    for (n, line) in lines {
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != names.len() {
            return Err(fail(
                n + 1,
                format!("holds {} values, and the header names {} columns", fields.len(), names.len()),
            ));
        }
        let number = |k: usize| -> Result<f64, Error> {
            let text = fields.get(k).copied().unwrap_or("");
            text.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| fail(n + 1, format!("column {} ({:?}) is not a finite number", k + 1, text)))
        };
        // A peak or a channel: finite and within what any measurement can be.
        let measurement = |k: usize| -> Result<f64, Error> {
            let value = number(k)?;
            if value.abs() > LARGEST_VALUE {
                let text = fields.get(k).copied().unwrap_or("");
                let reason = format!("column {} ({text}) is past ±{LARGEST_VALUE:e}, beyond any measurement", k + 1);
                return Err(fail(n + 1, reason));
            }
            Ok(value)
        };
        let location = match location {
            Ok(u) => {
                let unit = number(u)?;
                if unit < 1.0 || unit.fract() != 0.0 {
                    return Err(fail(n + 1, format!("unit {unit} is not a unit number (they count from 1)")));
                }
                Location::Unit(unit as usize - 1)
            }
            Err((x, y)) => Location::Point([number(x)? * metres, number(y)? * metres]),
        };
        let measured = match peak {
            Some(p) => match measurement(p)? {
                peak if peak < 0.0 => {
                    let text = fields.get(p).copied().unwrap_or("");
                    return Err(fail(
                        n + 1,
                        format!("peak {text} S/m is negative: a touch's peak is its size, 0 S/m or more"),
                    ));
                }
                peak => Measured::Peak(peak),
            },
            None => Measured::Frame(
                (0..fields.len())
                    .filter(|k| !used.contains(k))
                    .map(measurement)
                    .collect::<Result<Vec<f64>, Error>>()?,
            ),
        };
        // A force (N) or depth (the spec's unit) of 0 or more, as written.
        let label = |k: Option<usize>, what: &str, unit: &str| -> Result<Option<f64>, Error> {
            let Some(k) = k else { return Ok(None) };
            let value = number(k)?;
            if what == "force" && value > MAX_FORCE {
                let text = fields.get(k).copied().unwrap_or("");
                return Err(fail(n + 1, format!("force {text} N is past {MAX_FORCE:e} N, the most a label may hold")));
            }
            if value < 0.0 {
                let text = fields.get(k).copied().unwrap_or("");
                return Err(fail(
                    n + 1,
                    format!("{what} {text}{unit} is negative: a press's {what} is 0{unit} or more"),
                ));
            }
            Ok(Some(value))
        };
        let force = label(force, "force", " N")?;
        let depth = label(depth, "depth", "")?.map(|d| d * metres);
        rows.push(SampleRow { location, force, depth, measured });
    }
    if rows.is_empty() {
        return Err(fail(1, "a header and no samples under it".into()));
    }
    Ok(rows)
}

pub use eitskin::calibration::MAX_FORCE;

/// How far outside the outline's bounding box a press's label may lie, as a fraction of the
/// box's larger side: a robot's frame may be off by millimetres, not by a sheet.
pub const OFF_SHEET: f64 = 0.5;

/// Presses whose labels all lie within 1/`SPECK` of the sheet's size of each other (but not at
/// one place) are taken as written in a smaller unit than the spec's: metres read as mm span at
/// most 1/1000 of a sheet.
pub const SPECK: f64 = 500.0;

/// Whether a press centre (m) lies more than [`OFF_SHEET`] of the outline's size outside its
/// box on `spec`'s sheet: a unit or an origin gone wrong, not a press (labels, press scripts).
pub fn off_sheet([x, y]: [f64; 2], spec: &SensorSpec) -> bool {
    let [[x0, y0], [x1, y1]] = spec.outline.bounds();
    let margin = OFF_SHEET * (x1 - x0).max(y1 - y0);
    x < x0 - margin || x > x1 + margin || y < y0 - margin || y > y1 + margin
}

/// Refuses presses labelled more than [`OFF_SHEET`] of the outline's size outside its box on
/// `spec`'s sheet (a unit or an origin gone wrong, not a press), or all within a speck of it
/// ([`SPECK`]), quoting the labels and the outline's span in the spec's unit.
pub fn check_labels_on_sheet(presses: &[LabelledPress], spec: &SensorSpec) -> Result<(), Error> {
    let [[x0, y0], [x1, y1]] = spec.outline.bounds();
    let size = (x1 - x0).max(y1 - y0);
    let (per_metre, unit) = (1.0 / spec.length_unit.metres(), spec.length_unit.symbol());
    // Labels all within a speck of the sheet: written in metres where the spec reads mm, say.
    let span = |axis: usize| {
        let values = presses.iter().map(|p| p.position[axis]);
        values.clone().fold(f64::NEG_INFINITY, f64::max) - values.fold(f64::INFINITY, f64::min)
    };
    let spread = span(0).max(span(1));
    if presses.len() >= 3 && spread > 0.0 && spread < size / SPECK {
        let (spread, size) = (spread * per_metre, crate::Quoted(size * per_metre));
        let reason = format!(
            "of the {} presses span only {spread:.3} {unit} on a sheet {size} {unit} across: are they written in a smaller unit than the spec's ({unit})?",
            presses.len()
        );
        return Err(Error::Key { path: None, key: "x, y", reason });
    }
    let Some(k) = presses.iter().position(|p| off_sheet(p.position, spec)) else { return Ok(()) };
    let [x, y] = presses[k].position.map(|v| crate::Quoted(v * per_metre));
    let [x0, x1, y0, y1] = [x0, x1, y0, y1].map(|v| v * per_metre);
    let reason = format!(
        "of press {} are ({x}, {y}) {unit}, far off the sheet (its outline spans {x0}–{x1} by {y0}–{y1} {unit}): give them in the spec's unit ({unit}), from the outline's origin",
        k + 1
    );
    Err(Error::Key { path: None, key: "x, y", reason })
}

/// Reads a samples file of labelled presses for a learned model on `spec`'s sheet (`x`, `y` in
/// its unit, optional `force`, then the channels), positions in m; labels far off the sheet
/// are refused ([`check_labels_on_sheet`]).
pub fn read_labelled_presses(path: &Path, spec: &SensorSpec) -> Result<Vec<LabelledPress>, Error> {
    let fail = |reason: String| Error::Key { path: Some(path.to_path_buf()), key: "samples", reason };
    let presses = read_samples(path, spec.length_unit.metres())?
        .into_iter()
        .enumerate()
        .map(|(k, row)| {
            let Location::Point(position) = row.location else {
                return Err(fail(format!("sample {}: a learned model needs `x` and `y`, not a unit", k + 1)));
            };
            let Measured::Frame(inputs) = row.measured else {
                return Err(fail(format!("sample {}: a learned model needs the channels, not a peak", k + 1)));
            };
            Ok(LabelledPress { inputs, position, force: row.force, depth: row.depth })
        })
        .collect::<Result<Vec<_>, _>>()?;
    check_labels_on_sheet(&presses, spec).map_err(|e| e.in_file(path))?;
    Ok(presses)
}

/// Labelled presses as a samples file: a `#` comment line, then `x`, `y` (in units of `metres`
/// m), `force` (N) and `depth` (in units of `metres` m) when every press has one, and the
/// channels `v1`… .
pub fn labelled_presses_to_csv(presses: &[LabelledPress], metres: f64, comment: &str) -> String {
    let forces = !presses.is_empty() && presses.iter().all(|p| p.force.is_some());
    let depths = !presses.is_empty() && presses.iter().all(|p| p.depth.is_some());
    let channels: Vec<String> = (1..=presses.first().map_or(0, |p| p.inputs.len())).map(|c| format!("v{c}")).collect();
    let labels = format!("{}{}", if forces { "force," } else { "" }, if depths { "depth," } else { "" });
    let mut text = format!("# {comment}\nx,y,{labels}{}\n", channels.join(","));
    for p in presses {
        let values: Vec<String> = p.inputs.iter().map(|v| format!("{v:e}")).collect();
        let force = p.force.filter(|_| forces).map_or(String::new(), |f| format!("{f},"));
        let depth = p.depth.filter(|_| depths).map_or(String::new(), |d| format!("{},", d / metres));
        text += &format!("{},{},{force}{depth}{}\n", p.position[0] / metres, p.position[1] / metres, values.join(","));
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_points_peaks_and_frames_are_read() {
        let rows = parse_samples("# from the study\nunit,force,peak\n1,0,0.001\n25,15,0.2\n", 1e-3).unwrap();
        assert_eq!(
            rows[1],
            SampleRow { location: Location::Unit(24), force: Some(15.0), depth: None, measured: Measured::Peak(0.2) }
        );
        let rows = parse_samples("x,y,force,v1,v2,v3\n10,-20,5,1.5,2.5,3.5\n", 1e-3).unwrap();
        assert_eq!(rows[0].location, Location::Point([0.01, -0.02]));
        assert_eq!(rows[0].measured, Measured::Frame(vec![1.5, 2.5, 3.5]));
        let rows = parse_samples("x,y,v1,v2\n10,-20,1.5,2.5\n", 1e-3).unwrap();
        assert_eq!((rows[0].force, &rows[0].measured), (None, &Measured::Frame(vec![1.5, 2.5])));
    }

    #[test]
    fn labelled_presses_round_trip() {
        let press =
            |x: f64, force, depth| LabelledPress { inputs: vec![x, -2.5e-7], position: [x, 0.25 * x], force, depth };
        for presses in [
            vec![press(0.01, Some(3.5), None), press(-0.02, Some(0.0), None)],
            vec![press(0.03, None, None)],
            vec![press(0.03, None, Some(0.002)), press(0.01, None, Some(0.0))],
            vec![press(0.03, Some(2.0), Some(0.002))],
        ] {
            let text = labelled_presses_to_csv(&presses, 1e-3, "test");
            let rows = parse_samples(&text, 1e-3).unwrap();
            for (row, p) in rows.iter().zip(&presses) {
                assert_eq!(row.force, p.force);
                assert_eq!(row.depth.map(|d| (d * 1e9).round()), p.depth.map(|d| (d * 1e9).round()), "{text}");
                assert_eq!(row.measured, Measured::Frame(p.inputs.clone()));
                let Location::Point(at) = row.location else { panic!("{row:?}") };
                assert!((at[0] - p.position[0]).abs() < 1e-15 && (at[1] - p.position[1]).abs() < 1e-15);
            }
        }
    }

    #[test]
    fn bad_rows_say_where() {
        let err = parse_samples("unit,force,peak\n1,2,x\n", 1.0).unwrap_err().to_string();
        assert_eq!(err, "`samples` line 2: column 3 (\"x\") is not a finite number");
        let err = parse_samples("unit,force,peak\n0,2,1\n", 1.0).unwrap_err().to_string();
        assert!(err.contains("count from 1"), "{err}");
        assert!(parse_samples("force,peak\n1,2\n", 1.0).unwrap_err().to_string().contains("`unit` column"));
        let err = parse_samples("unit,force,peak\n1,2,1\n2,-0.5,1\n", 1.0).unwrap_err().to_string();
        assert_eq!(err, "`samples` line 3: force -0.5 N is negative: a press's force is 0 N or more");
        let err = parse_samples("unit,force,peak\n1,1e300,1\n", 1.0).unwrap_err().to_string();
        assert_eq!(err, "`samples` line 2: force 1e300 N is past 1e5 N, the most a label may hold");
        let err = parse_samples("x,y,force,v1,v2,v1\n1,2,3,1,1,1\n", 1.0).unwrap_err().to_string();
        assert_eq!(err, "`samples` line 1: column `v1` is named 2 times (columns 4, 6)");
        let err = parse_samples("unit,x,y,force,peak\n1,1,2,3,1\n", 1.0).unwrap_err().to_string();
        assert!(err.contains("both a `unit` column and `x`/`y` columns"), "{err}");
        let quoted = parse_samples("\"unit\",\"force\",\"peak\"\n1,2,0.5\n", 1.0).unwrap();
        assert_eq!(quoted[0].force, Some(2.0));
        let err = parse_samples("x,y,depth,v1\n1,2,-3,1\n", 1e-3).unwrap_err().to_string();
        assert_eq!(err, "`samples` line 2: depth -3 is negative: a press's depth is 0 or more");
        let err = parse_samples("# made by hand\nx,y,force,v1\n", 1.0).unwrap_err().to_string();
        assert_eq!(err, "`samples` line 1: a header and no samples under it");
        let err = parse_samples("x,y,force,v1,v2\n1,2,3,4,5\n1,2,3,4\n", 1.0).unwrap_err().to_string();
        assert_eq!(err, "`samples` line 3: holds 4 values, and the header names 5 columns");
        let err = parse_samples("x,y,force,v1,force\n1,2,3,4,5\n", 1.0).unwrap_err().to_string();
        assert_eq!(err, "`samples` line 1: column `force` is named 2 times (columns 3, 5)");
        // A spreadsheet's "CSV UTF-8" starts with a byte-order mark.
        let rows = parse_samples("\u{feff}x,y,force,v1\n1,2,3,4\n", 1e-3).unwrap();
        assert_eq!(rows[0].force, Some(3.0));
    }
}
