//! What `eitskin run` images with: λ and normalisation from the flags, or from a calibration,
//! which fixes both (its curves were fitted on images made so, and hold only for those).

use std::path::Path;
use std::str::FromStr;

use anyhow::{bail, Result};
use eitskin::inverse::Hyperparameter;

/// `--hyperparameter` as parsed, with the text as written (quoted back in refusals).
#[derive(Debug, Clone, PartialEq)]
pub struct HyperparameterFlag {
    /// The flag's text.
    written: String,
    /// What it says.
    value: Hyperparameter,
}

impl FromStr for HyperparameterFlag {
    type Err = String;

    /// `auto`, or a number in [1e-6, 1000], as [`Hyperparameter`] reads it.
    fn from_str(text: &str) -> Result<HyperparameterFlag, String> {
        Ok(HyperparameterFlag { written: text.to_owned(), value: text.parse()? })
    }
}

/// λ and normalisation of a run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Imaging {
    /// λ given, or chosen from the reference frames' noise.
    pub hyperparameter: Hyperparameter,
    /// Normalised differences Δv/v_ref.
    pub normalised: bool,
}

/// The imaging of a run from its flags (`--hyperparameter`, default `auto`; `--normalised`) or,
/// with a calibration at `path` made as `fitted`, the calibration's: a different explicit λ,
/// `auto`, or `--normalised` for an absolute calibration is refused, naming both.
pub fn resolve(
    flag: Option<&HyperparameterFlag>,
    normalised: bool,
    calibration: Option<(&Path, eitskin_io::Imaging)>,
) -> Result<Imaging> {
    let Some((path, fitted)) = calibration else {
        let hyperparameter = flag.map_or(Hyperparameter::Auto, |f| f.value);
        return Ok(Imaging { hyperparameter, normalised });
    };
    let lambda = fitted.hyperparameter;
    if let Some(flag) = flag.filter(|f| f.value != Hyperparameter::Fixed(lambda)) {
        bail!(
            "--hyperparameter {}: the calibration {} was fitted on images made with λ = {lambda}, and its \
             forces hold only for those; leave --hyperparameter out (or give {lambda}), or calibrate again",
            flag.written,
            path.display()
        );
    }
    if normalised && !fitted.normalised {
        bail!(
            "--normalised: the calibration {} was fitted on absolute differences (\"normalised\": false); \
             leave --normalised out, or calibrate again with normalised differences",
            path.display()
        );
    }
    Ok(Imaging { hyperparameter: Hyperparameter::Fixed(lambda), normalised: fitted.normalised })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flag(text: &str) -> HyperparameterFlag {
        text.parse().unwrap()
    }

    #[test]
    fn a_calibration_fixes_lambda_and_normalisation() {
        let path = Path::new("cal.json");
        let paper = eitskin_io::Imaging::default();
        assert_eq!(
            resolve(None, false, None).unwrap(),
            Imaging { hyperparameter: Hyperparameter::Auto, normalised: false }
        );
        assert_eq!(resolve(Some(&flag("0.05")), true, None).unwrap().hyperparameter, Hyperparameter::Fixed(0.05));
        let fixed = Imaging { hyperparameter: Hyperparameter::Fixed(0.1), normalised: false };
        assert_eq!(resolve(None, false, Some((path, paper))).unwrap(), fixed);
        assert_eq!(resolve(Some(&flag("0.10")), false, Some((path, paper))).unwrap(), fixed);
        let err = resolve(Some(&flag("0.050")), false, Some((path, paper))).unwrap_err().to_string();
        assert!(
            err.starts_with("--hyperparameter 0.050: the calibration cal.json") && err.contains("λ = 0.1"),
            "{err}"
        );
        assert!(resolve(Some(&flag("auto")), false, Some((path, paper))).unwrap_err().to_string().contains("auto"));
        let err = resolve(None, true, Some((path, paper))).unwrap_err().to_string();
        assert!(err.contains("--normalised") && err.contains("absolute differences"), "{err}");
        let normalised = eitskin_io::Imaging { hyperparameter: 0.02, normalised: true };
        let got = resolve(None, false, Some((path, normalised))).unwrap();
        assert_eq!(got, Imaging { hyperparameter: Hyperparameter::Fixed(0.02), normalised: true });
    }
}
