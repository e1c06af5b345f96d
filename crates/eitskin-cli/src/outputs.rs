//! Output paths checked before any work starts: each is named as the format its flag writes,
//! goes into a folder that exists, and is neither an input nor another output of the same command.

use std::path::{Path, PathBuf};

use anyhow::{bail, Result};

/// Refuses `outputs` (each a flag and its path) whose folder does not exist, that name an
/// input (a flag, or "the spec", and its path) or that name each other.
pub fn check(outputs: &[(&str, &Path)], inputs: &[(&str, &Path)]) -> Result<()> {
    for (k, &(flag, path)) in outputs.iter().enumerate() {
        let folder = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        if !folder.is_dir() {
            bail!("{flag} {}: the folder {} does not exist", path.display(), folder.display());
        }
        if path.is_dir() {
            bail!("{flag} {}: is a folder; give the path of a file to write", path.display());
        }
        let target = resolved(path);
        if let Some((input, given)) = inputs.iter().find(|(_, p)| resolved(p) == target) {
            bail!(
                "{flag} {}: would overwrite the input {} ({input}); give another path",
                path.display(),
                given.display()
            );
        }
        if let Some((other, _)) = outputs[..k].iter().find(|(_, p)| resolved(p) == target) {
            bail!("{flag} {}: {other} writes there too; give each output its own path", path.display());
        }
    }
    Ok(())
}

/// Refuses an output folder (made if missing) that is a file, or inside one, before any work.
pub fn check_folder(flag: &str, path: &Path) -> Result<()> {
    match path.ancestors().find(|a| !a.as_os_str().is_empty() && a.exists()) {
        Some(found) if !found.is_dir() && found == path => {
            bail!("{flag} {}: is a file; give a folder to write into", path.display())
        }
        Some(found) if !found.is_dir() => {
            bail!("{flag} {}: {} is a file, so no folder can be made inside it", path.display(), found.display())
        }
        _ => Ok(()),
    }
}

/// A command's output files written all or nothing: each is written to a hidden file beside its
/// target (its name ending in the target's, so that a writer choosing a format by extension
/// still finds it), and all are renamed into place by [`Staged::commit`] once the command has
/// succeeded. Dropped uncommitted (an error on the way), the hidden files are removed and every
/// target is left as it was.
#[derive(Debug, Default)]
pub struct Staged {
    /// (hidden file, target) of each output, in the order given.
    files: Vec<(PathBuf, PathBuf)>,
}

impl Staged {
    /// The path to write `target` at until [`Staged::commit`].
    pub fn path(&mut self, target: &Path) -> PathBuf {
        let name = target.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        let hidden = target.with_file_name(format!(".eitskin-partial-{}-{name}", std::process::id()));
        self.files.push((hidden.clone(), target.to_path_buf()));
        hidden
    }

    /// Renames every output into place (each rename replaces its target at once).
    pub fn commit(mut self) -> Result<()> {
        for (hidden, target) in std::mem::take(&mut self.files) {
            if let Err(e) = std::fs::rename(&hidden, &target) {
                let _ = std::fs::remove_file(&hidden);
                bail!("cannot write {}: {e}", target.display());
            }
        }
        Ok(())
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        for (hidden, _) in &self.files {
            let _ = std::fs::remove_file(hidden);
        }
    }
}

/// A parser for an output flag that writes one of `formats` (extensions, the first the usual
/// one): [`eitskin_io::check_output_name`] before any work starts.
pub fn writes(formats: &'static [&'static str]) -> impl Fn(&str) -> Result<PathBuf, String> + Clone + Send + Sync {
    move |value: &str| {
        let path = PathBuf::from(value);
        eitskin_io::check_output_name(&path, formats)
            .map(|()| path)
            .map_err(|e| e.replacen("this writes", "this flag writes", 1))
    }
}

/// Whether `path` names a file of that extension (`"npy"`), in any case: `X.NPY` is NPY too.
pub fn has_extension(path: &Path, extension: &str) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case(extension))
}

/// `path` made absolute with its folder's links resolved, so that two spellings of one file
/// compare equal whether or not the file exists yet.
fn resolved(path: &Path) -> PathBuf {
    if let Ok(full) = path.canonicalize() {
        return full;
    }
    let folder = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    match (folder.canonicalize(), path.file_name()) {
        (Ok(dir), Some(name)) => dir.join(name),
        _ => path.to_path_buf(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Committed, every output is in place; dropped on an error, none is touched and nothing
    /// is left beside them.
    #[test]
    fn outputs_are_written_all_or_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let (first, second) = (dir.path().join("a.csv"), dir.path().join("b.png"));
        std::fs::write(&first, "old").unwrap();
        let mut staged = Staged::default();
        let hidden = staged.path(&first);
        assert!(hidden.to_string_lossy().ends_with("a.csv"), "{}", hidden.display());
        std::fs::write(&hidden, "new").unwrap();
        let _ = staged.path(&second);
        drop(staged); // the second output failed
        assert_eq!(std::fs::read_to_string(&first).unwrap(), "old");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        let mut staged = Staged::default();
        std::fs::write(staged.path(&first), "new").unwrap();
        std::fs::write(staged.path(&second), "png").unwrap();
        staged.commit().unwrap();
        assert_eq!(std::fs::read_to_string(&first).unwrap(), "new");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
    }

    #[test]
    fn an_output_named_as_another_format_is_refused_and_any_other_name_taken() {
        let png = writes(&["png"]);
        assert_eq!(png("figure.jpg").unwrap_err(), "this flag writes .png, not .jpg: name the file so");
        assert_eq!(png("out/figure.PNG").unwrap(), PathBuf::from("out/figure.PNG"));
        assert!(png("figure").is_ok() && png("figure.v2").is_ok());
        let raster = writes(&["npy", "csv"]);
        assert_eq!(raster("x.txt").unwrap_err(), "this flag writes .npy or .csv, not .txt: name the file so");
        assert!(raster("X.NPY").is_ok() && raster("x.csv").is_ok());
        // The extension chooses the format: without one of them, nothing says which.
        for name in ["image", "out/image.v2"] {
            let refusal = raster(name).unwrap_err();
            assert!(refusal.contains("chosen by the file's extension") && refusal.contains(name), "{refusal}");
        }
    }

    #[test]
    fn an_output_folder_that_is_a_file_or_inside_one_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("notes.txt");
        std::fs::write(&file, "x").unwrap();
        let refusal = check_folder("--plots", &file).unwrap_err().to_string();
        assert!(refusal.ends_with("notes.txt: is a file; give a folder to write into"), "{refusal}");
        let refusal = check_folder("--plots", &file.join("plots/a")).unwrap_err().to_string();
        assert!(refusal.contains("notes.txt is a file, so no folder can be made inside it"), "{refusal}");
        assert!(check_folder("--plots", &dir.path().join("new/plots")).is_ok());
        assert!(check_folder("--plots", dir.path()).is_ok() && check_folder("--plots", Path::new("plots")).is_ok());
    }

    #[test]
    fn extensions_are_read_in_any_case() {
        assert!(has_extension(Path::new("out/X.NPY"), "npy") && has_extension(Path::new("x.npy"), "npy"));
        assert!(!has_extension(Path::new("x.npy.csv"), "npy") && !has_extension(Path::new("npy"), "npy"));
    }

    #[test]
    fn outputs_that_overwrite_inputs_or_each_other_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let frame = dir.path().join("frame.json");
        std::fs::write(&frame, "[]").unwrap();
        let png = dir.path().join("image.png");
        assert!(check(&[("--png", &png)], &[("--frame", &frame)]).is_ok());
        let again = dir.path().join(".").join("frame.json");
        let err = check(&[("--png", &again)], &[("--frame", &frame)]).unwrap_err();
        assert_eq!(
            err.to_string(),
            format!(
                "--png {}: would overwrite the input {} (--frame); give another path",
                again.display(),
                frame.display()
            )
        );
        let err = check(&[("--out", &png), ("--png", &png)], &[]).unwrap_err();
        assert_eq!(
            err.to_string(),
            format!("--png {}: --out writes there too; give each output its own path", png.display())
        );
        let lost = dir.path().join("missing").join("x.png");
        let err = check(&[("--png", &lost)], &[]).unwrap_err();
        assert_eq!(
            err.to_string(),
            format!("--png {}: the folder {} does not exist", lost.display(), dir.path().join("missing").display())
        );
    }
}
