//! Single frames from files: the measurements of one frame in protocol order.
//!
//! Accepted: a JSON array of numbers; a JSON object with a `measurements` array (what
//! `eitskin forward` prints); CSV with a `measurement,value_ohm` header (what
//! `eitskin forward --format csv` prints), whose second column is read; or plain numbers
//! separated by commas, semicolons, spaces or new lines.

use std::path::Path;

use crate::Error;

/// Reads one frame from a file.
pub fn read_frame(path: &Path) -> Result<Vec<f64>, Error> {
    parse_frame(&crate::read_text(path)?).map_err(|e| e.in_file(path))
}

/// Parses one frame (see the module doc for the accepted shapes); NaN and infinities are refused.
pub fn parse_frame(text: &str) -> Result<Vec<f64>, Error> {
    let values = parse_values(text)?;
    if let Some(i) = values.iter().position(|x| !x.is_finite()) {
        return Err(frame_error(&format!("value {} is not a finite number", i + 1)));
    }
    Ok(values)
}

/// The numbers of one frame in any accepted shape, NaN and infinities included; at least one.
pub(crate) fn parse_values(text: &str) -> Result<Vec<f64>, Error> {
    let trimmed = text.trim_start();
    let values: Vec<f64> = if trimmed.starts_with('[') || trimmed.starts_with('{') {
        let value: serde_json::Value =
            serde_json::from_str(text).map_err(|e| Error::Json { path: None, message: e.to_string() })?;
        let array = value.get("measurements").unwrap_or(&value);
        let Some(items) = array.as_array() else {
            return Err(frame_error("expected an array of numbers, or an object with a `measurements` array"));
        };
        items
            .iter()
            .enumerate()
            .map(|(i, x)| x.as_f64().ok_or_else(|| frame_error(&format!("value {} is not a number", i + 1))))
            .collect::<Result<_, _>>()?
    } else {
        let mut lines = text.lines().enumerate().peekable();
        let header = lines.peek().is_some_and(|(_, l)| l.trim() == "measurement,value_ohm");
        if header {
            lines.next();
        }
        let mut values = Vec::new();
        for (n, line) in lines {
            let fields = line.split([',', ';', ' ', '\t']).map(str::trim).filter(|f| !f.is_empty());
            let mut fields: Vec<&str> = fields.collect();
            // Under the header, each row is `measurement,value`, the measurements counted from 1
            // in order: a row elsewhere would put its value on another channel.
            if header && !fields.is_empty() {
                let want = values.len() + 1;
                if fields[0].parse::<f64>().ok() != Some(want as f64) {
                    let found = fields[0];
                    return Err(frame_error(&format!(
                        "line {}: measurement {found:?} where measurement {want} is due (rows count 1, 2, 3, … in order)",
                        n + 1
                    )));
                }
                fields.remove(0);
            }
            for field in fields {
                let x: f64 =
                    field.parse().map_err(|_| frame_error(&format!("line {}: {field:?} is not a number", n + 1)))?;
                values.push(x);
            }
        }
        values
    };
    if values.is_empty() {
        return Err(frame_error("the frame holds no value"));
    }
    Ok(values)
}

fn frame_error(reason: &str) -> Error {
    Error::Key { path: None, key: "frame", reason: reason.to_string() }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_shape_reads_the_same_values() {
        let want = vec![1.5, 2.0, -3.25];
        assert_eq!(parse_frame("[1.5, 2, -3.25]").unwrap(), want);
        assert_eq!(parse_frame(r#"{"protocol": "x", "measurements": [1.5, 2, -3.25]}"#).unwrap(), want);
        assert_eq!(parse_frame("measurement,value_ohm\n1,1.5\n2,2e0\n3,-3.25\n").unwrap(), want);
        assert_eq!(parse_frame("1.5; 2\r\n-3.25\n").unwrap(), want);
    }

    #[test]
    fn bad_frames_say_where() {
        assert_eq!(parse_frame("1,2\n3,x\n").unwrap_err().to_string(), "`frame` line 2: \"x\" is not a number");
        assert!(parse_frame("[1, NaN]").is_err());
        assert!(parse_frame("1, inf").unwrap_err().to_string().contains("value 2 is not a finite number"));
        assert!(parse_frame("").is_err());
        let err = parse_frame("measurement,value_ohm\n2,1.5\n1,2\n").unwrap_err().to_string();
        assert_eq!(
            err,
            "`frame` line 2: measurement \"2\" where measurement 1 is due (rows count 1, 2, 3, … in order)"
        );
        assert!(parse_frame("measurement,value_ohm\n1,1.5\n1,2\n")
            .unwrap_err()
            .to_string()
            .contains("measurement 2 is due"));
    }
}
