//! Output names checked against the format written: a file named as one format of data, tables
//! or pictures must be in that format, whoever writes it (the CLI's flags, Python's `save`).

use std::path::Path;

/// Extensions that name a format of data, tables or pictures.
const FORMATS: &[&str] = &[
    "bmp", "csv", "gif", "h5", "hdf5", "jpeg", "jpg", "json", "jsonl", "mat", "ndjson", "npy", "npz", "pdf", "png",
    "svg", "tif", "tiff", "toml", "tsv", "txt", "webp", "xls", "xlsx",
];

/// Refuses `path` as the name of a file written as one of `formats` (extensions, the first the
/// usual one) where its extension names another format (`x.jpg` for a PNG). A writer of one
/// format takes any other name as given; a writer of several chooses by the extension, so a
/// name with none of them (`image`, `x.v2`) is refused rather than written in a format the
/// user did not name. The message reads after the path or the flag that named it.
///
/// ```
/// use std::path::Path;
/// assert!(eitskin_io::check_output_name(Path::new("model.json"), &["json"]).is_ok());
/// assert!(eitskin_io::check_output_name(Path::new("model.npy"), &["json"]).is_err());
/// assert!(eitskin_io::check_output_name(Path::new("image"), &["npy", "csv"]).is_err());
/// ```
pub fn check_output_name(path: &Path, formats: &[&str]) -> Result<(), String> {
    let names = || formats.iter().map(|f| format!(".{f}")).collect::<Vec<String>>().join(" or ");
    let known = |e: &str| formats.iter().any(|f| f.eq_ignore_ascii_case(e));
    match path.extension().and_then(|e| e.to_str()) {
        Some(e) if known(e) => Ok(()),
        Some(e) if FORMATS.iter().any(|f| f.eq_ignore_ascii_case(e)) => {
            Err(format!("this writes {}, not .{e}: name the file so", names()))
        }
        _ if formats.len() > 1 => Err(format!(
            "this writes {}, chosen by the file's extension, and {:?} ends in neither: name the file so",
            names(),
            path.display().to_string()
        )),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Extensions are read in any case; a name of another known format is refused; a name of no
    /// known format is taken by a writer of one format and refused by a writer of several.
    #[test]
    fn names_are_held_to_the_format_written() {
        let json = |name: &str| check_output_name(Path::new(name), &["json"]);
        assert!(json("out/MODEL.JSON").is_ok() && json("model").is_ok() && json("model.v2").is_ok());
        assert_eq!(json("model.npy").unwrap_err(), "this writes .json, not .npy: name the file so");
        let raster = |name: &str| check_output_name(Path::new(name), &["npy", "csv"]);
        assert!(raster("x.Npy").is_ok() && raster("x.csv").is_ok());
        assert_eq!(raster("x.txt").unwrap_err(), "this writes .npy or .csv, not .txt: name the file so");
        let refusal = raster("x.v2").unwrap_err();
        assert!(refusal.contains("chosen by the file's extension") && refusal.contains("\"x.v2\""), "{refusal}");
        assert!(raster("").is_err() && raster(".npy").is_err(), "a hidden name has no extension");
    }
}
