//! Frame logs in text: one frame per line, as boards print them to a serial console and as
//! captures save them (OpenEIT's `magnitudes:  251.5 ,  178.3 , …`), or a numeric CSV matrix.
//!
//! Each non-empty line is an optional label up to the first `:`, then numbers separated by
//! commas, semicolons, spaces or tabs (a trailing separator is allowed), as the `lines` codec
//! reads them from a port. The text is a log when a line carries a label, or when at least two
//! lines hold the same number (at least two) of values; anything else is one frame, read by
//! [`crate::frame_file`].

use super::{Array, ArrayProblem};

/// The frame log in `text` as a lines × values matrix; `None` when the text is not a log.
pub(super) fn frame_log(text: &str) -> Option<Result<Array, ArrayProblem>> {
    let start = text.trim_start();
    if start.starts_with('[') || start.starts_with('{') || start.starts_with("measurement,value_ohm") {
        return None;
    }
    let mut rows: Vec<(usize, Vec<f64>)> = Vec::new();
    let mut labelled = false;
    for (n, line) in text.lines().enumerate() {
        let body = match line.split_once(':') {
            Some((_, body)) => {
                labelled = true;
                body
            }
            None => line,
        };
        let fields = body.split([',', ';', ' ', '\t']).map(str::trim).filter(|f| !f.is_empty());
        let values: Vec<f64> = fields.map(str::parse).collect::<Result<_, _>>().ok()?;
        if !values.is_empty() {
            rows.push((n + 1, values));
        }
    }
    let (first_line, first) = rows.first()?;
    let columns = first.len();
    let same = rows.iter().all(|(_, r)| r.len() == columns);
    if !labelled && (rows.len() < 2 || columns < 2 || !same) {
        return None;
    }
    if let Some((line, row)) = rows.iter().find(|(_, r)| r.len() != columns) {
        let message = format!("line {line} holds {} values where line {first_line} holds {columns}", row.len());
        return Some(Err(ArrayProblem::Malformed { format: "text", message }));
    }
    let shape = vec![rows.len(), columns];
    let real = rows.into_iter().flat_map(|(_, r)| r).collect();
    Some(Ok(Array { shape, column_major: false, real, imaginary: None }))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shape(text: &str) -> Option<Vec<usize>> {
        frame_log(text).map(|a| a.unwrap().shape)
    }

    #[test]
    fn a_board_log_is_one_frame_per_line_and_anything_else_is_one_frame() {
        let log = "\nmagnitudes:   1.5 ,   2.0 ,  3 ,\r\nmagnitudes :   4 ,   5 ,  6 ,\r\n";
        let array = frame_log(log).unwrap().unwrap();
        assert_eq!((array.shape.clone(), array.real), (vec![2, 3], vec![1.5, 2.0, 3.0, 4.0, 5.0, 6.0]));
        assert_eq!(shape("1, 2, 3\n4, 5, 6\n"), Some(vec![2, 3]));
        assert_eq!(shape("magnitudes: 1 2 3"), Some(vec![1, 3]));
        // One frame: a column of numbers, one line, ragged lines, JSON, forward's CSV.
        for one in ["1\n2\n3\n", "1, 2, 3", "1 2 3\n4 5\n", "[1, 2]", "measurement,value_ohm\n1,2.0\n2,3.0\n"] {
            assert_eq!(shape(one), None, "{one:?}");
        }
        let torn = frame_log("v: 1, 2, 3\nv: 4, 5\n").unwrap().unwrap_err();
        assert_eq!(torn.to_string(), "is not a readable text file (line 2 holds 2 values where line 1 holds 3)");
    }
}
