//! Value parsers for numeric flags: each takes a number in its stated range and refuses any
//! other (not a number, NaN, infinite, out of range) before work starts, quoting the value as
//! written and naming the range.

use eitskin::{SensorSpec, SpecError};

/// A parser of a finite number for which `within` holds, described as `what` (e.g. "a baseline
/// rate"), its range as written in the help (e.g. "[0, 1]") and an example value.
pub fn number(
    what: &'static str,
    range: &'static str,
    example: &'static str,
    within: fn(f64) -> bool,
) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync + 'static {
    move |text: &str| match text.trim().parse::<f64>() {
        Ok(value) if value.is_finite() && within(value) => Ok(value),
        _ => Err(format!("\"{text}\" is not {what}: give a number in {range}, e.g. {example}")),
    }
}

/// [`whole`] over a range the library states.
pub fn within(
    what: &'static str,
    range: std::ops::RangeInclusive<usize>,
) -> impl Fn(&str) -> Result<usize, String> + Clone + Send + Sync + 'static {
    whole(what, *range.start(), *range.end())
}

/// A parser of a whole number from `lo` to `hi`, described as `what` (e.g. "a number of
/// reference frames").
pub fn whole(
    what: &'static str,
    lo: usize,
    hi: usize,
) -> impl Fn(&str) -> Result<usize, String> + Clone + Send + Sync + 'static {
    move |text: &str| match text.trim().parse::<usize>() {
        Ok(value) if (lo..=hi).contains(&value) => Ok(value),
        _ => Err(format!("\"{text}\" is not {what}: give a whole number from {lo} to {hi}")),
    }
}

/// The parser of `--triangles`: about how many triangles to mesh with, 1 to 100,000,000 (what
/// the mesh and the models built on it would need is checked against the memory available
/// before any is built). The fewest the mesher makes depends on the sheet (its corners and
/// electrodes; about 200 on the paper's sensor), so a count below it is raised with a warning
/// ([`raised_triangles`]), not refused here.
pub fn triangles() -> impl Fn(&str) -> Result<usize, String> + Clone + Send + Sync + 'static {
    whole("a triangle count", 1, MAX_TRIANGLES)
}

/// A mesh off the count asked for by more than this fraction may have been raised to the
/// fewest the mesher makes (it otherwise lands within a few per cent).
const RAISED_BY: f64 = 0.1;

/// The warning for stderr when `--triangles` `asked` for fewer triangles than the mesher makes
/// on `spec`'s sheet, which made `made`; `None` when the mesh has about the count asked for.
pub fn raised_triangles(asked: usize, made: usize, spec: &SensorSpec) -> Result<Option<String>, SpecError> {
    if spec.mesh.max_element_size.is_some() {
        return Ok(Some(format!(
            "warning: --triangles {asked} is not used: the spec's mesh.max_element_size sets the size ({made} triangles)"
        )));
    }
    if made as f64 <= (1.0 + RAISED_BY) * asked as f64 {
        return Ok(None);
    }
    let fewest = spec.fewest_triangles()?;
    Ok((asked < fewest)
        .then(|| format!("warning: --triangles {asked} is {}: the mesh has {made}", below_fewest(fewest, spec))))
}

/// Prints [`raised_triangles`]'s warning, if any, for a `--triangles` of `asked` (when given)
/// and the `mesh` made from `spec`.
pub fn warn_raised_triangles(asked: Option<usize>, mesh: &eitskin::Mesh, spec: &SensorSpec) -> Result<(), SpecError> {
    if let Some(asked) = asked {
        raised_triangles(asked, mesh.triangles().len(), spec)?.into_iter().for_each(|w| eprintln!("{w}"));
    }
    Ok(())
}

/// "below the fewest the mesher makes on this sheet, about 200 (…)", for a count below `fewest`.
pub fn below_fewest(fewest: usize, spec: &SensorSpec) -> String {
    format!(
        "below the fewest the mesher makes on this sheet, about {fewest} (set by its outline, its electrodes and mesh.grading = {})",
        spec.mesh.grading
    )
}

/// The most triangles `--triangles` takes.
pub const MAX_TRIANGLES: usize = 100_000_000;

/// The parser of `--seed`: any whole number from 0 to 2⁶⁴ − 1.
pub fn seed(text: &str) -> Result<u64, String> {
    text.trim()
        .parse::<u64>()
        .map_err(|_| format!("\"{text}\" is not a seed: give a whole number from 0 to {}", u64::MAX))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_outside_their_range_are_named_with_it() {
        let rate = number("a baseline rate", "[0, 1]", "0.01", |v| (0.0..=1.0).contains(&v));
        assert_eq!(rate("0.5"), Ok(0.5));
        for bad in ["nan", "inf", "-0.1", "1.5", "1e300", "x", ""] {
            assert_eq!(rate(bad), Err(format!("\"{bad}\" is not a baseline rate: give a number in [0, 1], e.g. 0.01")));
        }
        let frames = whole("a number of frames", 1, 10);
        assert_eq!(frames("10"), Ok(10));
        for bad in ["0", "11", "-1", "2.5", "nan"] {
            assert_eq!(
                frames(bad),
                Err(format!("\"{bad}\" is not a number of frames: give a whole number from 1 to 10"))
            );
        }
    }

    /// A count under the fewest the mesher makes is raised with a warning saying so; one it
    /// can make is not, nor a mesh that lands near the count asked for.
    #[test]
    fn a_count_under_the_fewest_is_raised_with_a_warning() {
        let spec = SensorSpec::square_hydrogel();
        let fewest = spec.fewest_triangles().unwrap();
        let warning = raised_triangles(1, fewest, &spec).unwrap().unwrap();
        assert_eq!(
            warning,
            format!(
                "warning: --triangles 1 is below the fewest the mesher makes on this sheet, about {fewest} (set by its outline, its electrodes and mesh.grading = 0.2): the mesh has {fewest}"
            )
        );
        assert_eq!(raised_triangles(4000, 4050, &spec).unwrap(), None);
        assert_eq!(raised_triangles(fewest, fewest + fewest / 4, &spec).unwrap(), None);
        let mut sized = spec.clone();
        sized.mesh.max_element_size = Some(0.01);
        assert!(raised_triangles(4000, 500, &sized).unwrap().unwrap().contains("mesh.max_element_size sets the size"));
    }
}
