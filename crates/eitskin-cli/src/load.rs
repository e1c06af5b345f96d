//! Loading what the subcommands share: the spec (file or built-in), inclusion flags, and the
//! frame chain and nominal sensor, saying so on stderr when their press model must be built.

use std::path::Path;

use anyhow::{bail, Context, Result};
use eitskin::chain::Chain;
use eitskin::conductivity::Inclusion;
use eitskin::memory::{self, Stage};
use eitskin::pipeline::{Pipeline, PipelineParams};
use eitskin::SensorSpec;
use eitskin_io::build::ChainSetup;

/// The frame chain of [`eitskin_io::build::chain`], `command` saying on stderr when the press
/// model it needs is not in the cache and is built first.
pub fn chain(command: &str, spec: &SensorSpec, setup: ChainSetup) -> Result<Chain> {
    if setup.needs_press_model() {
        announce_press_model(command, spec);
    }
    Ok(eitskin_io::build::chain(spec, setup)?)
}

/// The live pipeline of [`eitskin_io::build::pipeline`], announced as [`chain`] is.
pub fn pipeline(command: &str, spec: &SensorSpec, setup: ChainSetup, params: PipelineParams) -> Result<Pipeline> {
    if setup.needs_press_model() {
        announce_press_model(command, spec);
    }
    Ok(eitskin_io::build::pipeline(spec, setup, params)?)
}

/// The nominal sensor of [`eitskin_io::build::nominal_sensor`], announced as [`chain`] does.
pub fn nominal_sensor(command: &str, spec: &SensorSpec) -> Result<eitskin::learn::NominalSensor> {
    announce_press_model(command, spec);
    Ok(eitskin_io::build::nominal_sensor(spec)?)
}

/// Says on stderr that `spec`'s press model is about to be built, where it is not in the cache.
fn announce_press_model(command: &str, spec: &SensorSpec) {
    if !eitskin_io::build::press_model_cached(spec) {
        let cached = match eitskin_io::build::cache_dir() {
            Some(dir) => format!("kept in {} for later runs", dir.display()),
            None => "not kept: set EITSKIN_CACHE to keep it".to_string(),
        };
        eprintln!("eitskin {command}: building the press model of this sheet first ({cached})…");
    }
}

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
