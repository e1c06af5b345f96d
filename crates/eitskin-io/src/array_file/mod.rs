//! Frame tables from the field's data files: MATLAB `.mat` (v5 and v7.3), numpy `.npy`, and the
//! text frames of [`crate::read_frame`].
//!
//! Published EIT data (EIDORS' examples, the KHU and Swisstom recordings, pyEIT's) come as a
//! matrix of measurements: one frame of N channels per column in MATLAB (`vv(:, k)`), one per row
//! in numpy. [`read_frames`] reads one numeric array and cuts it into frames:
//!
//! - **Which file kind** is decided by the first bytes, not the name: a MAT v5 header (MATLAB's
//!   `-v6`/`-v7`, `scipy.io.savemat`), a MAT v7.3 header (HDF5 inside, MATLAB's `-v7.3`), the
//!   NPY magic, or else text: a frame log (one frame per line, optionally labelled as boards
//!   print them, `magnitudes: 1.0, 2.0, …`, or a CSV matrix), else one frame (a JSON array,
//!   `forward`'s JSON or CSV, or plain numbers).
//! - **Which array**: [`FrameSelect::variable`] names a MAT variable, or a struct's field as
//!   `data.Uel` (MAT v7.3 only: the MAT v5 reader skips structs). Without a name, a MAT file that
//!   holds exactly one numeric array gives that one; otherwise the error lists the variables
//!   (name, shape, class). An NPY file holds one array and takes no name.
//! - **Rows or columns** ([`FrameLayout`]): `Auto` takes one frame per column for MAT files (the
//!   MATLAB habit) and one frame per row for NPY and text. A vector (a 1-D array, or a matrix
//!   with one row or one column under `Auto`) is one frame. `Rows` and `Columns` are obeyed as
//!   written, vectors included.
//! - **Values**: double, single and every integer class are read as `f64`; complex arrays give
//!   their imaginary parts in [`FrameTable::imaginary`]. NaN means a missing channel and is
//!   passed through; an infinity is refused, naming frame and channel (from 1).
//!
//! ```
//! use std::path::Path;
//! use eitskin_io::{read_frames, FrameLayout, FrameSelect};
//! // scipy.io.savemat of vv = [1 4; NaN 5; 3 6]: two frames of three channels, one per column.
//! let path = Path::new("tests/fixtures/double.mat");
//! let table = read_frames(path, &FrameSelect::default())?;
//! assert_eq!(table.frames.len(), 2);
//! assert_eq!(table.frames[1], [4.0, 5.0, 6.0]);
//! assert!(table.frames[0][1].is_nan() && table.imaginary.is_none()); // channel 2 missing
//! let rows = FrameSelect { variable: Some("vv".into()), layout: FrameLayout::Rows };
//! assert_eq!(read_frames(path, &rows)?.frames.len(), 3);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Not for: averaging, choosing magnitude or real part, or checking the channel count against a
//! protocol: the table holds what the file holds, and the caller decides.

mod mat5;
mod mat73;
mod npy;
mod text;

use std::fmt;
use std::path::Path;

use crate::Error;

/// Frames read from a file: real parts, and imaginary parts when the data were complex.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FrameTable {
    /// One `Vec` per frame, each with one value per channel (NaN = missing), in the file's unit.
    pub frames: Vec<Vec<f64>>,
    /// Imaginary parts, shaped as `frames`, when the array was complex; `None` for real data.
    pub imaginary: Option<Vec<Vec<f64>>>,
}

/// Which array of a file to read, and how its frames are laid out.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct FrameSelect {
    /// The MAT variable, or a struct's field as `data.Uel`; `None` takes the only numeric array.
    pub variable: Option<String>,
    /// Frames as rows or as columns of a matrix.
    pub layout: FrameLayout,
}

/// How the frames lie in a matrix.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FrameLayout {
    /// Columns for MAT files (MATLAB's `vv(:, k)`), rows for NPY and text; a vector is one frame.
    #[default]
    Auto,
    /// One frame per row.
    Rows,
    /// One frame per column.
    Columns,
}

/// A numeric variable of a MAT file, as listed when the choice is not clear.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ArrayVariable {
    /// Its name; a struct's field is `struct.field`.
    pub name: String,
    /// Its size as MATLAB gives it (rows, columns, …).
    pub shape: Vec<usize>,
    /// Its MATLAB class, e.g. `double`, `int16`, `complex double`.
    pub class: String,
}

impl fmt::Display for ArrayVariable {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} ({} {})", self.name, shape_text(&self.shape), self.class)
    }
}

/// Why an array file, or the array chosen in it, does not give frames.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ArrayProblem {
    /// The file is damaged or truncated: its first bytes announce `format`, the rest do not follow.
    #[error("is not a readable {format} file ({message})")]
    Malformed {
        /// `MAT v5`, `MAT v7.3`, `NPY` or `text`.
        format: &'static str,
        /// What the parser found.
        message: String,
    },
    /// No variable was named and the file does not hold exactly one, or the named one is absent.
    #[error("{}", variable_text(wanted, found))]
    Variable {
        /// The name asked for, if any.
        wanted: Option<String>,
        /// The numeric variables the file holds.
        found: Vec<ArrayVariable>,
    },
    /// A struct field was asked of a MAT v5 file, whose reader skips structs.
    #[error(
        "fields of structs are not read from MAT v5 files; save the field as a variable of its own \
         (in MATLAB: `Uel = data.Uel; save('f.mat', 'Uel')`), or save with -v7.3, whose structs are read"
    )]
    StructField,
    /// A variable was named for a file that holds one unnamed array (NPY) or one frame (text).
    #[error("a {format} file has no named variables; leave out the variable (--select)")]
    NoVariables {
        /// `NPY` or `text`.
        format: &'static str,
    },
    /// The array is neither a vector nor a matrix.
    #[error("has shape {}; accepted: a vector (one frame) or a matrix (frames as rows or columns)", shape_text(shape))]
    Shape {
        /// The shape found.
        shape: Vec<usize>,
    },
    /// The array holds no value.
    #[error("has shape {} and holds no value", shape_text(shape))]
    Empty {
        /// The shape found.
        shape: Vec<usize>,
    },
    /// The array's values are not numbers that frames can hold.
    #[error("holds {class} values; accepted: double, single, integer and complex arrays")]
    ElementType {
        /// The class or dtype found, e.g. `char`, `logical`, `|b1`.
        class: String,
    },
    /// A value is infinite (NaN is accepted: it marks a missing channel).
    #[error("frame {frame}, channel {channel} is infinite; only finite values and NaN (missing) are accepted")]
    NotFinite {
        /// The frame, from 1.
        frame: usize,
        /// The channel, from 1.
        channel: usize,
    },
    /// One frame was asked for and the array holds `frames`.
    #[error("holds {frames} frames where one was expected; pick one with --select NAME or a frame index")]
    FrameCount {
        /// How many frames the array holds.
        frames: usize,
    },
    /// One real frame was asked for and the values are complex.
    #[error("holds complex values; read them with read_frames, which gives real and imaginary parts")]
    Complex,
}

fn variable_text(wanted: &Option<String>, found: &[ArrayVariable]) -> String {
    let list = found.iter().map(ToString::to_string).collect::<Vec<_>>().join(", ");
    let hint = "pick one with --select NAME (a struct's field as NAME.FIELD)";
    match (wanted, found.len()) {
        (_, 0) => "holds no numeric array (MAT v5 structs, cells, strings and sparse arrays are not read)".into(),
        (Some(_), _) => format!("has no such numeric variable; it holds {list}; {hint}"),
        (None, n) => format!("holds {n} numeric arrays: {list}; {hint}"),
    }
}

fn shape_text(shape: &[usize]) -> String {
    if shape.is_empty() {
        return "() (a scalar)".into();
    }
    shape.iter().map(ToString::to_string).collect::<Vec<_>>().join("×")
}

/// A numeric array as a file holds it, before it is cut into frames.
#[derive(Debug)]
struct Array {
    /// Extent of each dimension (MATLAB's size for MAT files, numpy's shape for NPY).
    shape: Vec<usize>,
    /// Whether the first index varies fastest (MATLAB, Fortran order) rather than the last.
    column_major: bool,
    /// Real parts.
    real: Vec<f64>,
    /// Imaginary parts, for complex arrays.
    imaginary: Option<Vec<f64>>,
}

/// The file kinds told apart by their first bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Mat5,
    Mat73,
    Npy,
    Text,
}

fn kind(bytes: &[u8]) -> Kind {
    if bytes.starts_with(b"\x93NUMPY") {
        return Kind::Npy;
    }
    // MAT header: 116 bytes of text, 8 of subsystem offset, a version (0x0100 for v5, 0x0200 for
    // v7.3) and the endian indicator "IM" (little-endian writer) or "MI".
    if bytes.len() >= 128 && bytes.starts_with(b"MATLAB") {
        let version = match &bytes[126..128] {
            b"IM" => u16::from_le_bytes([bytes[124], bytes[125]]),
            b"MI" => u16::from_be_bytes([bytes[124], bytes[125]]),
            _ => 0,
        };
        if version == 0x0200 || bytes.get(512..520) == Some(b"\x89HDF\r\n\x1a\n") {
            return Kind::Mat73;
        }
        return Kind::Mat5;
    }
    Kind::Text
}

/// Reads the frames of one numeric array from a MAT (v5, v7.3), NPY or text frame file (see the
/// module doc for the rules); NaN passes through as a missing channel.
pub fn read_frames(path: &Path, select: &FrameSelect) -> Result<FrameTable, Error> {
    let bytes = std::fs::read(path).map_err(|source| Error::Read { path: path.to_path_buf(), source })?;
    let problem =
        |variable: Option<String>, problem: ArrayProblem| Error::Array { path: path.to_path_buf(), variable, problem };
    let kind = kind(&bytes);
    // A MAT header's text with less than the header's 128 bytes: a MAT file cut short.
    if kind == Kind::Text && bytes.starts_with(b"MATLAB ") && bytes.windows(8).take(24).any(|w| w == b"MAT-file") {
        let message = format!("its header is {} of 128 bytes: the file was cut short", bytes.len());
        return Err(problem(None, ArrayProblem::Malformed { format: "MAT", message }));
    }
    let (array, variable) = match kind {
        Kind::Mat5 | Kind::Mat73 => {
            let read = if kind == Kind::Mat5 { mat5::read } else { mat73::read };
            read(bytes, select.variable.as_deref()).map_err(|(variable, p)| problem(variable, p))?
        }
        Kind::Npy | Kind::Text => {
            let format = if kind == Kind::Npy { "NPY" } else { "text" };
            if select.variable.is_some() {
                return Err(problem(select.variable.clone(), ArrayProblem::NoVariables { format }));
            }
            let array = if kind == Kind::Npy {
                npy::read(&bytes).map_err(|p| problem(None, p))?
            } else {
                let text = String::from_utf8(bytes).map_err(|e| {
                    let io = std::io::Error::new(std::io::ErrorKind::InvalidData, e);
                    Error::Read { path: path.to_path_buf(), source: io }
                })?;
                let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
                match text::frame_log(text) {
                    Some(log) => log.map_err(|p| problem(None, p))?,
                    None => {
                        let real = crate::frame_file::parse_values(text).map_err(|e| e.in_file(path))?;
                        Array { shape: vec![real.len()], column_major: false, real, imaginary: None }
                    }
                }
            };
            (array, None)
        }
    };
    let columns_by_default = matches!(kind, Kind::Mat5 | Kind::Mat73);
    frames_of(array, select.layout, columns_by_default).map_err(|p| problem(variable, p))
}

/// Reads a file that holds one real frame (see [`read_frames`]): refuses tables of several
/// frames, saying how many, and complex data.
pub fn read_one_frame(path: &Path, select: &FrameSelect) -> Result<Vec<f64>, Error> {
    let table = read_frames(path, select)?;
    let problem = |problem| Error::Array { path: path.to_path_buf(), variable: select.variable.clone(), problem };
    if table.imaginary.is_some() {
        return Err(problem(ArrayProblem::Complex));
    }
    let frames = table.frames.len();
    match <[Vec<f64>; 1]>::try_from(table.frames) {
        Ok([frame]) => Ok(frame),
        Err(_) => Err(problem(ArrayProblem::FrameCount { frames })),
    }
}

/// Cuts an array into frames by the layout rule of the module doc, and checks the values.
fn frames_of(array: Array, layout: FrameLayout, columns_by_default: bool) -> Result<FrameTable, ArrayProblem> {
    let mut shape = array.shape.clone();
    while shape.len() > 2 && shape.last() == Some(&1) {
        shape.pop(); // MATLAB's trailing singleton dimensions
    }
    if shape.contains(&0) {
        return Err(ArrayProblem::Empty { shape });
    }
    let (rows, columns) = match shape[..] {
        [n] => (1, n),
        [r, c] => (r, c),
        _ => return Err(ArrayProblem::Shape { shape }),
    };
    if array.real.len() != rows * columns || array.imaginary.as_ref().is_some_and(|im| im.len() != array.real.len()) {
        return Err(ArrayProblem::Malformed {
            format: "array",
            message: format!("{} values for shape {}", array.real.len(), shape_text(&shape)),
        });
    }
    let vector = shape.len() == 1 || (layout == FrameLayout::Auto && (rows == 1 || columns == 1));
    let as_rows = match layout {
        _ if vector => true,
        FrameLayout::Rows => true,
        FrameLayout::Columns => false,
        FrameLayout::Auto => !columns_by_default,
    };
    let (rows, columns) = if vector { (1, rows * columns) } else { (rows, columns) };
    let at = |i: usize, j: usize| if array.column_major && !vector { i + j * rows } else { i * columns + j };
    let cut = |values: &[f64]| -> Vec<Vec<f64>> {
        if as_rows {
            (0..rows).map(|i| (0..columns).map(|j| values[at(i, j)]).collect()).collect()
        } else {
            (0..columns).map(|j| (0..rows).map(|i| values[at(i, j)]).collect()).collect()
        }
    };
    let table = FrameTable { frames: cut(&array.real), imaginary: array.imaginary.as_deref().map(cut) };
    for part in std::iter::once(&table.frames).chain(&table.imaginary) {
        for (f, frame) in part.iter().enumerate() {
            if let Some(c) = frame.iter().position(|x| x.is_infinite()) {
                return Err(ArrayProblem::NotFinite { frame: f + 1, channel: c + 1 });
            }
        }
    }
    Ok(table)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn matrix(column_major: bool, real: Vec<f64>) -> Array {
        Array { shape: vec![2, 3], column_major, real, imaginary: None }
    }

    #[test]
    fn rows_and_columns_cut_the_same_matrix_both_ways() {
        // [[1, 2, 3], [4, 5, 6]] stored row-major and column-major.
        let want_rows = vec![vec![1.0, 2.0, 3.0], vec![4.0, 5.0, 6.0]];
        let want_columns = vec![vec![1.0, 4.0], vec![2.0, 5.0], vec![3.0, 6.0]];
        for (column_major, real) in
            [(false, vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0]), (true, vec![1.0, 4.0, 2.0, 5.0, 3.0, 6.0])]
        {
            let rows = frames_of(matrix(column_major, real.clone()), FrameLayout::Rows, true).unwrap();
            assert_eq!(rows.frames, want_rows);
            let columns = frames_of(matrix(column_major, real.clone()), FrameLayout::Columns, false).unwrap();
            assert_eq!(columns.frames, want_columns);
            let auto_mat = frames_of(matrix(column_major, real.clone()), FrameLayout::Auto, true).unwrap();
            assert_eq!(auto_mat.frames, want_columns);
            let auto_npy = frames_of(matrix(column_major, real), FrameLayout::Auto, false).unwrap();
            assert_eq!(auto_npy.frames, want_rows);
        }
    }

    #[test]
    fn a_vector_is_one_frame_under_auto_and_is_cut_as_told_otherwise() {
        let column = || Array { shape: vec![3, 1], column_major: true, real: vec![1.0, 2.0, 3.0], imaginary: None };
        assert_eq!(frames_of(column(), FrameLayout::Auto, true).unwrap().frames, vec![vec![1.0, 2.0, 3.0]]);
        assert_eq!(frames_of(column(), FrameLayout::Columns, true).unwrap().frames, vec![vec![1.0, 2.0, 3.0]]);
        assert_eq!(frames_of(column(), FrameLayout::Rows, true).unwrap().frames.len(), 3);
    }

    #[test]
    fn shapes_and_values_that_make_no_frames_say_why() {
        let cube = Array { shape: vec![2, 2, 2], column_major: false, real: vec![0.0; 8], imaginary: None };
        assert_eq!(
            frames_of(cube, FrameLayout::Auto, false).unwrap_err(),
            ArrayProblem::Shape { shape: vec![2, 2, 2] }
        );
        let empty = Array { shape: vec![0, 3], column_major: false, real: vec![], imaginary: None };
        assert!(matches!(frames_of(empty, FrameLayout::Auto, false), Err(ArrayProblem::Empty { .. })));
        let inf = matrix(false, vec![1.0, 2.0, 3.0, 4.0, f64::NEG_INFINITY, 6.0]);
        assert_eq!(
            frames_of(inf, FrameLayout::Columns, false).unwrap_err(),
            ArrayProblem::NotFinite { frame: 2, channel: 2 }
        );
        let trailing = Array { shape: vec![2, 3, 1], column_major: true, real: vec![0.0; 6], imaginary: None };
        assert_eq!(frames_of(trailing, FrameLayout::Auto, true).unwrap().frames.len(), 3);
    }

    #[test]
    fn the_file_kind_comes_from_the_first_bytes() {
        let mut mat = b"MATLAB 5.0 MAT-file".to_vec();
        mat.resize(128, b' ');
        mat[124..128].copy_from_slice(&[0x00, 0x01, b'I', b'M']);
        assert_eq!(kind(&mat), Kind::Mat5);
        mat[124..126].copy_from_slice(&[0x00, 0x02]);
        assert_eq!(kind(&mat), Kind::Mat73);
        assert_eq!(kind(b"\x93NUMPY\x01\x00"), Kind::Npy);
        assert_eq!(kind(b"MATLAB"), Kind::Text);
        let dir = tempfile::tempdir().unwrap();
        let cut = dir.path().join("cut.mat");
        std::fs::write(&cut, &mat[..100]).unwrap();
        let err = read_frames(&cut, &FrameSelect::default()).unwrap_err().to_string();
        assert!(
            err.contains("is not a readable MAT file (its header is 100 of 128 bytes: the file was cut short)"),
            "{err}"
        );
        assert_eq!(kind(b"1, 2, 3"), Kind::Text);
    }
}
