//! `eitskin forward`: the measurements a sensor would give, for a background and inclusions.

use std::path::PathBuf;

use anyhow::{Context, Result};
use eitskin::conductivity::{check_inclusion, with_inclusions, Inclusion};
use eitskin::memory::Stage;
use eitskin::{LengthUnit, Mesh};
use serde::Serialize;

use crate::{load, ranges};

/// Flags of `eitskin forward`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Sensor spec file (TOML); default: the paper's sensor.
    spec: Option<PathBuf>,
    /// Protocol: two-terminal, adjacent, adjacent-all, opposite, skip-S, skip-S-all (S = 0, 1, …),
    /// or a protocol JSON file.
    #[arg(long)]
    protocol: Option<String>,
    /// A circular inclusion x,y,r,sigma (spec units from the outline's centre; S/m). Repeatable.
    #[arg(long, allow_hyphen_values = true)]
    inclusion: Vec<String>,
    /// Use this mesh file (JSON, as `eitskin mesh` writes it or EIDORS exports it).
    #[arg(long)]
    mesh: Option<PathBuf>,
    /// Mesh with about this many triangles instead of the spec's count, 1–100,000,000 (refused
    /// when the mesh and what is built on it would not fit in the memory available; a count
    /// under the fewest the mesher makes on the sheet, about 200 on the paper's sensor, is
    /// raised to it with a warning).
    #[arg(long, value_parser = ranges::triangles())]
    triangles: Option<usize>,
    /// Elements: `p2` (quadratic on the same mesh, a second unknown on every edge: the default
    /// with complete electrodes, 0.55 % from the converged values on the paper's sensor where
    /// linear ones are 2.9 % off) or `p1` (linear: the model every other command images with,
    /// and EIDORS's; the default with point electrodes, which P2 does not take).
    #[arg(long, value_enum)]
    elements: Option<ElementsArg>,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Json)]
    format: Format,
}

/// `--elements`: the forward model's elements.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ElementsArg {
    /// Linear.
    P1,
    /// Quadratic.
    P2,
}

impl ElementsArg {
    /// The flag's value as written.
    pub fn name(self) -> &'static str {
        match self {
            ElementsArg::P1 => "p1",
            ElementsArg::P2 => "p2",
        }
    }
}

/// Refuses quadratic elements for a sensor with point electrodes.
pub fn check_elements(elements: ElementsArg, spec: &eitskin::SensorSpec) -> Result<()> {
    if elements == ElementsArg::P2 && spec.electrodes.point {
        anyhow::bail!(
            "--elements p2: the sensor has point electrodes, and quadratic elements are for complete electrodes only"
        );
    }
    Ok(())
}

/// How `forward` prints.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum Format {
    /// One JSON object with the protocol and a `measurements` array.
    Json,
    /// `measurement,value` lines, measurements counted from 1.
    Csv,
}

#[derive(Serialize)]
struct Output<'a> {
    protocol: &'a str,
    elements: &'a str,
    electrodes: usize,
    nodes: usize,
    triangles: usize,
    unit: &'a str,
    measurements: &'a [f64],
}

/// Runs `eitskin forward`.
pub fn run(args: Args) -> Result<()> {
    let mut spec = load::spec(args.spec.as_deref())?;
    if let Some(p) = &args.protocol {
        spec.protocol = eitskin_io::protocol_by_name(p, std::path::Path::new("."), spec.electrodes.count)?;
    }
    // A mesh file sets the size itself: nothing is meshed.
    let spec = if args.mesh.is_none() { load::sized(spec, args.triangles, Stage::ForwardModel)? } else { spec };
    let elements = args.elements.unwrap_or(if spec.electrodes.point { ElementsArg::P1 } else { ElementsArg::P2 });
    check_elements(elements, &spec)?;
    let inclusions = args.inclusion.iter().map(|t| load::inclusion(t, &spec)).collect::<Result<Vec<_>>>()?;
    let mesh = match &args.mesh {
        Some(path) => eitskin_io::read_mesh(path)?,
        None => {
            let mesh = spec.mesh()?;
            ranges::warn_raised_triangles(args.triangles, &mesh, &spec)?;
            mesh
        }
    };
    check_inclusions(&args.inclusion, &inclusions, &mesh, spec.length_unit)?;
    let model = spec.forward_model_on(mesh)?;
    let sigma = with_inclusions(model.mesh(), spec.conductivity, &inclusions);
    let values = match elements {
        ElementsArg::P1 => model.measure(&sigma)?,
        ElementsArg::P2 => model.measure_quadratic(&sigma)?,
    };
    match args.format {
        Format::Json => {
            let out = Output {
                protocol: model.protocol().description(),
                elements: elements.name(),
                electrodes: model.protocol().electrode_count(),
                nodes: model.mesh().nodes().len(),
                triangles: model.mesh().triangles().len(),
                unit: "V at 1 A (ohm)",
                measurements: &values,
            };
            println!("{}", serde_json::to_string_pretty(&out)?);
        }
        Format::Csv => {
            println!("measurement,value_ohm");
            for (i, v) in values.iter().enumerate() {
                println!("{},{v:e}", i + 1);
            }
        }
    }
    Ok(())
}

/// Refuses an inclusion that would change nothing on `mesh` (off the sheet, or covering no
/// triangle's centroid), quoting its `--inclusion` text; lengths in `unit`, the spec's.
fn check_inclusions(texts: &[String], inclusions: &[Inclusion], mesh: &Mesh, unit: LengthUnit) -> Result<()> {
    for (text, inclusion) in texts.iter().zip(inclusions) {
        check_inclusion(mesh, inclusion, unit).with_context(|| format!("--inclusion {text:?}"))?;
    }
    Ok(())
}
