//! Output paths checked before any work starts: each goes into a folder that exists, and none
//! is an input or another output of the same command.

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
