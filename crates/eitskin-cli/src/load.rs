//! Loading what the subcommands share: the spec (file or built-in) and inclusion flags.

use std::path::Path;
use std::sync::Arc;

use anyhow::{bail, Context, Result};
use eitskin::chain::Chain;
use eitskin::conductivity::Inclusion;
use eitskin::contrast_map::{ContrastMap, ContrastMapParams};
use eitskin::inverse::{choose_hyperparameter, Channels, Linearisation};
use eitskin::memory::{self, Stage};
use eitskin::strength::Strength;
use eitskin::{Reconstructor, ReconstructorParams, SensorSpec, TouchParams};

/// The spec in `path`, or the built-in paper sensor.
pub fn spec(path: Option<&Path>) -> Result<SensorSpec> {
    Ok(match path {
        Some(p) => eitskin_io::read_spec(p)?,
        None => SensorSpec::square_hydrogel(),
    })
}

/// `spec` meshed with about `triangles` triangles when given, checked to fit in the memory
/// available for building `stage`.
pub fn sized(mut spec: SensorSpec, triangles: Option<usize>, stage: Stage) -> Result<SensorSpec> {
    if let Some(n) = triangles {
        spec.mesh.triangles = n;
    }
    check_memory(&spec, stage)?;
    Ok(spec)
}

/// Refuses to build `stage` for `spec` when its estimated peak memory exceeds what the system
/// has available, saying what it would need and the most triangles that would fit.
pub fn check_memory(spec: &SensorSpec, stage: Stage) -> Result<()> {
    match eitskin_io::available_memory() {
        Some(available) => fits(spec, stage, available),
        None => Ok(()),
    }
}

/// [`check_memory`] with `available` bytes.
fn fits(spec: &SensorSpec, stage: Stage, available: f64) -> Result<()> {
    let triangles = spec.expected_triangles();
    let measurements = spec.protocol()?.measurements().len();
    let needed = memory::needed_bytes(stage, triangles, measurements);
    if needed > available {
        let most = memory::most_triangles(stage, available, measurements);
        bail!(
            "{} on about {} triangles needs about {:.1} GB of memory, and {:.1} GB is available: ask for at most about {} triangles ({})",
            stage.name(),
            round_count(triangles),
            needed / 1e9,
            available / 1e9,
            round_count(most),
            match spec.mesh.max_element_size {
                Some(_) => "the spec's mesh.max_element_size sets the size: make it larger",
                None => "--triangles, or the spec's mesh.triangles",
            }
        );
    }
    Ok(())
}

/// A count rounded to three significant figures, for a message.
fn round_count(n: f64) -> u64 {
    if n < 1000.0 {
        return n.round() as u64;
    }
    let unit = 10f64.powi(n.log10().floor() as i32 - 2);
    ((n / unit).floor() * unit) as u64
}

/// An inclusion from `x,y,r,sigma`: centre and radius in the spec's units (relative to the
/// outline's centre), conductivity in S/m.
pub fn inclusion(text: &str, spec: &SensorSpec) -> Result<Inclusion> {
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("--inclusion {text:?}: expected four numbers x,y,r,sigma"))?;
    let [x, y, r, sigma] = values[..] else {
        bail!("--inclusion {text:?}: expected four numbers x,y,r,sigma, got {}", values.len());
    };
    if !(r > 0.0 && sigma > 0.0 && x.is_finite() && y.is_finite() && r.is_finite() && sigma.is_finite()) {
        bail!("--inclusion {text:?}: radius and conductivity must be positive and every value finite");
    }
    let k = spec.length_unit.metres();
    Ok(Inclusion { centre: [x * k, y * k], radius: r * k, conductivity: sigma })
}

/// The reconstructor of `spec` with `params`, from the cache when there is one (and
/// `use_cache`), without the channels the spec's mask drops.
pub fn reconstructor(spec: &SensorSpec, params: &ReconstructorParams, use_cache: bool) -> Result<Reconstructor> {
    let recon = match cache_dir().filter(|_| use_cache) {
        Some(dir) => eitskin_io::load_or_build(&dir, spec, params)?.0,
        None => Reconstructor::new(&spec.forward_model()?, spec.conductivity, params)?,
    };
    let used = spec.used_channels()?;
    if used.contains(&false) {
        return Ok(recon.derive(params.hyperparameter, Channels::all(used.len()).masked(&used))?);
    }
    Ok(recon)
}

/// The linearisation of `spec`, from the cache when there is one (and `use_cache`).
pub fn linearisation(spec: &SensorSpec, use_cache: bool) -> Result<Arc<Linearisation>> {
    Ok(Arc::new(match cache_dir().filter(|_| use_cache) {
        Some(dir) => eitskin_io::load_linearisation(&dir, spec)?.0,
        None => Linearisation::new(&spec.forward_model()?, spec.conductivity)?,
    }))
}

/// The automatic λ of `lin` (of `spec`) for `params` and the noise-weighted `channels`
/// ([`eitskin::inverse::choose_hyperparameter`]), from the cache when chosen before for exactly
/// these (and `use_cache`).
pub fn auto_hyperparameter(
    spec: &SensorSpec,
    lin: &Linearisation,
    params: &ReconstructorParams,
    channels: &Channels,
    use_cache: bool,
) -> Result<f64> {
    let choose = || choose_hyperparameter(lin, &params.prior, params.normalized, channels);
    Ok(match cache_dir().filter(|_| use_cache) {
        Some(dir) => eitskin_io::cached_hyperparameter(&dir, spec, params, channels, || Ok(choose()?))?.0,
        None => choose()?,
    })
}

/// The frame chain of `spec` reading each touch's strength as `strength`: the reconstructor
/// (from the cache), the paper's touch settings, the press model when the strength needs it or
/// `fit` asks for it, the contrast map when the strength reads it.
pub fn chain(spec: &SensorSpec, strength: Strength, fit: bool) -> Result<Chain> {
    chain_with(spec, &ReconstructorParams::default(), TouchParams::default(), strength, fit)
}

/// [`chain`] with these reconstructor parameters (λ, normalisation) and touch settings.
pub fn chain_with(
    spec: &SensorSpec,
    params: &ReconstructorParams,
    touch: TouchParams,
    strength: Strength,
    fit: bool,
) -> Result<Chain> {
    let recon = reconstructor(spec, params, true)?;
    let map = if strength.needs_contrast_map() {
        let map_params = ContrastMapParams::default();
        Some(match cache_dir() {
            Some(dir) => eitskin_io::load_or_build_contrast_map(&dir, spec, &recon, &map_params)?.0,
            None => {
                ContrastMap::new(&spec.forward_model()?, spec.conductivity, &recon, spec.outline.bounds(), &map_params)?
            }
        })
    } else {
        None
    };
    let mut chain = Chain::new(recon, touch);
    if fit || strength.needs_press_model() {
        chain = chain.with_press_model(press_model(spec)?);
    }
    if let Some(map) = map {
        chain = chain.with_contrast_map(map);
    }
    Ok(chain.with_strength(strength)?)
}

/// The press model of `spec` (default indenter), from the cache when there is one.
pub fn press_model(spec: &SensorSpec) -> anyhow::Result<eitskin::press_fit::PressModel> {
    let params = eitskin::press_fit::PressModelParams::default();
    Ok(match cache_dir() {
        Some(dir) => eitskin_io::load_or_build_press_model(&dir, spec, &params)?.0,
        None => eitskin_io::build_press_model(spec, &params)?,
    })
}

/// `spec` as specified, for a learned model's press features (its press model from the cache
/// when there is one).
pub fn nominal_sensor(spec: &SensorSpec) -> anyhow::Result<eitskin::learn::NominalSensor> {
    Ok(eitskin_io::nominal_sensor(spec, cache_dir().as_deref())?)
}

/// Where precomputed reconstructors and press models are cached: `$EITSKIN_CACHE`, else `$XDG_CACHE_HOME/eitskin`,
/// else `~/.cache/eitskin`; `None` when none of these is set.
pub fn cache_dir() -> Option<std::path::PathBuf> {
    let var = |name| std::env::var_os(name).filter(|v| !v.is_empty()).map(std::path::PathBuf::from);
    var("EITSKIN_CACHE")
        .or_else(|| var("XDG_CACHE_HOME").map(|d| d.join("eitskin")))
        .or_else(|| var("HOME").map(|d| d.join(".cache/eitskin")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_job_larger_than_the_memory_is_refused_with_its_size() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 50_000_000;
        assert!(fits(&spec, Stage::Mesh, 40e9).is_ok());
        assert_eq!(
            fits(&spec, Stage::Mesh, 16e9).unwrap_err().to_string(),
            "a mesh on about 50000000 triangles needs about 32.6 GB of memory, and 16.0 GB is available: ask for at most about 24500000 triangles (--triangles, or the spec's mesh.triangles)"
        );
        spec.mesh.triangles = 4000;
        spec.mesh.max_element_size = Some(1e-5);
        let err = fits(&spec, Stage::Reconstructor, 16e9).unwrap_err().to_string();
        assert_eq!(
            err,
            "a reconstructor on about 923000000 triangles needs about 6965.2 GB of memory, and 16.0 GB is available: ask for at most about 2110000 triangles (the spec's mesh.max_element_size sets the size: make it larger)"
        );
    }

    #[test]
    fn inclusion_converts_millimetres_and_refuses_garbage() {
        let spec = SensorSpec::square_hydrogel();
        let inc = inclusion("50, -20, 10, 0.5", &spec).unwrap();
        assert_eq!(inc.centre, [0.05, -0.02]);
        assert!((inc.radius - 0.01).abs() < 1e-15 && inc.conductivity == 0.5);
        assert!(inclusion("1,2,3", &spec).unwrap_err().to_string().contains("got 3"));
        assert!(inclusion("1,2,x,4", &spec).is_err());
        assert!(inclusion("1,2,3,-4", &spec).is_err());
    }
}
