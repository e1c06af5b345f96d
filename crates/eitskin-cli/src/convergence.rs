//! `eitskin convergence`: mesh the sensor ever finer and report how fast its measurements
//! approach the converged answer, and what 1 % and 0.1 % accuracy cost.

use std::path::PathBuf;

use anyhow::{bail, Result};
use eitskin::conductivity::Inclusion;
use eitskin::memory::Stage;
use eitskin::SensorSpec;
use eitskin_study::convergence::{default_inclusion, study, Convergence, Elements};
use serde::Serialize;

use crate::forward::{check_elements, ElementsArg};
use crate::{load, ranges};

/// Flags of `eitskin convergence`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Sensor spec file (TOML); default: the paper's sensor.
    spec: Option<PathBuf>,
    /// Triangle counts to mesh at, comma-separated, at least 3, coarse to fine (each larger than
    /// the one before), each 1–100,000,000; a count under the fewest the mesher makes on the
    /// sheet, about 200 on the paper's sensor, is raised to it with a warning, and two levels
    /// that would mesh alike are refused.
    #[arg(long, value_delimiter = ',', default_value = "500,1000,2000,4000,8000,16000,32000,64000,128000", value_parser = ranges::triangles())]
    triangles: Vec<usize>,
    /// Override the mesh grading toward electrode edges: the element size there as a fraction
    /// of the interior's, in (0, 1] (1 = uniform).
    #[arg(long, value_parser = ranges::number("a grading", "(0, 1]", "0.2", |g| g > 0.0 && g <= 1.0))]
    grading: Option<f64>,
    /// Protocol: two-terminal, adjacent, adjacent-all, opposite, skip-S, skip-S-all (S = 0, 1, …),
    /// or a protocol JSON file.
    #[arg(long)]
    protocol: Option<String>,
    /// Inclusion x,y,r,sigma for the difference signal (spec units; S/m). Default: radius 5 % of
    /// the width at a quarter of the width right of centre, half the background conductivity.
    #[arg(long, allow_hyphen_values = true)]
    inclusion: Option<String>,
    /// Elements of the forward model: `p1` (linear, the one images, touches and presses are built on) or `p2`
    /// (quadratic on the same mesh: a second unknown on every edge, complete electrodes only).
    #[arg(long, value_enum, default_value = "p1")]
    elements: ElementsArg,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

#[derive(Serialize)]
struct Row {
    triangles: usize,
    setup_seconds: f64,
    value_error: f64,
    difference_error: f64,
}

#[derive(Serialize)]
struct Report {
    elements: &'static str,
    reference: &'static str,
    value_order: Option<f64>,
    difference_order: Option<f64>,
    levels: Vec<Row>,
}

/// Runs `eitskin convergence`.
pub fn run(args: Args) -> Result<()> {
    let mut spec = load::spec(args.spec.as_deref())?;
    if let Some(g) = args.grading {
        spec.mesh.grading = g;
    }
    if let Some(p) = &args.protocol {
        spec.protocol = eitskin_io::protocol_by_name(p, std::path::Path::new("."), spec.electrodes.count)?;
    }
    check_elements(args.elements, &spec)?;
    load::sized(spec.clone(), args.triangles.iter().max().copied(), Stage::ForwardModel)?;
    let inclusion = match &args.inclusion {
        Some(text) => load::inclusion(text, &spec)?,
        None => default_inclusion(&spec),
    };
    let finest = check_levels(&args.triangles, &spec)?;
    check_inclusion(args.inclusion.as_deref(), &inclusion, finest, &spec)?;
    let elements = match args.elements {
        ElementsArg::P1 => Elements::Linear,
        ElementsArg::P2 => Elements::Quadratic,
    };
    let Some(found) = study(&spec, &args.triangles, inclusion, elements)? else {
        bail!("--triangles needs at least 3 levels to estimate an order, got {}", args.triangles.len());
    };
    check_found(&args.triangles, &found)?;
    let levels = found
        .levels
        .iter()
        .map(|l| Row {
            triangles: l.triangles,
            setup_seconds: l.setup_seconds,
            value_error: l.value_error,
            difference_error: l.difference_error,
        })
        .collect();
    let report = Report {
        elements: args.elements.name(),
        reference: found.reference,
        value_order: found.value_order,
        difference_order: found.difference_order,
        levels,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!("{} elements; reference: {}; grading {}", report.elements, report.reference, spec.mesh.grading);
    println!("{:>10} {:>12} {:>14} {:>18}", "triangles", "setup ms", "value error", "difference error");
    for r in &report.levels {
        println!(
            "{:>10} {:>12.2} {:>14.2e} {:>18.2e}",
            r.triangles,
            r.setup_seconds * 1e3,
            r.value_error,
            r.difference_error
        );
    }
    let show = |o: Option<f64>| o.map_or("none (not converging)".to_string(), |p| format!("{p:.2}"));
    println!("observed order in h: values {}, differences {}", show(report.value_order), show(report.difference_order));
    for target in [1e-2, 1e-3] {
        let first = |f: fn(&Row) -> f64| report.levels.iter().find(|r| f(r) <= target);
        for (what, hit) in [("values", first(|r| r.value_error)), ("differences", first(|r| r.difference_error))] {
            match hit {
                Some(r) => println!(
                    "{:>5} % on {what}: {} triangles, setup {:.1} ms",
                    target * 100.0,
                    r.triangles,
                    r.setup_seconds * 1e3
                ),
                None => println!("{:>5} % on {what}: not reached", target * 100.0),
            }
        }
    }
    Ok(())
}

/// The levels as written on the command line.
fn written(levels: &[usize]) -> String {
    levels.iter().map(usize::to_string).collect::<Vec<_>>().join(",")
}

/// Refuses fewer than 3 levels, and levels that are not coarse to fine once a count under the
/// fewest the mesher makes on `spec`'s sheet is raised to it (warning of a raised one); gives
/// the finest level's count.
fn check_levels(levels: &[usize], spec: &SensorSpec) -> Result<usize> {
    let list = written(levels);
    if levels.len() < 3 {
        bail!("--triangles {list}: needs at least 3 levels to estimate an order, got {}", levels.len());
    }
    let fewest = spec.fewest_triangles()?;
    for (k, pair) in levels.windows(2).enumerate() {
        let (coarse, fine) = (pair[0], pair[1]);
        if fine <= coarse {
            bail!(
                "--triangles {list}: level {} ({fine}) is not more than level {} ({coarse}): give the counts coarse to fine, each larger than the one before",
                k + 2,
                k + 1
            );
        }
        if fine <= fewest {
            bail!(
                "--triangles {list}: levels {} and {} ({coarse} and {fine}) are both {}, so both would mesh alike: start from {fewest} or more",
                k + 1,
                k + 2,
                ranges::below_fewest(fewest, spec)
            );
        }
    }
    if levels[0] < fewest {
        eprintln!(
            "warning: --triangles {list}: level 1 ({}) is {}: it meshes with about that many",
            levels[0],
            ranges::below_fewest(fewest, spec)
        );
    }
    Ok(levels.iter().copied().max().unwrap_or(fewest).max(fewest))
}

/// Refuses an inclusion that would give no difference signal: as the background, or covering
/// no triangle of the finest level's mesh (off the sheet, or smaller than its triangles);
/// `text` is its `--inclusion`, `None` for the default.
fn check_inclusion(text: Option<&str>, inclusion: &Inclusion, finest: usize, spec: &SensorSpec) -> Result<()> {
    let flag = text.map_or("the default inclusion".to_string(), |t| format!("--inclusion {t:?}"));
    if inclusion.conductivity == spec.conductivity {
        bail!(
            "{flag}: its conductivity is the background's ({} S/m), so there is no difference signal to converge: give another",
            spec.conductivity
        );
    }
    let mut finest_spec = spec.clone();
    (finest_spec.mesh.triangles, finest_spec.mesh.max_element_size) = (finest, None);
    let mesh = finest_spec.mesh()?;
    eitskin::conductivity::check_inclusion(&mesh, inclusion, spec.length_unit)
        .map_err(|e| anyhow::anyhow!("{flag}: on the finest level's mesh, {e}"))?;
    Ok(())
}

/// Refuses a study whose levels did not mesh finer and finer, or whose errors are not numbers,
/// rather than print them.
fn check_found(levels: &[usize], found: &Convergence) -> Result<()> {
    let list = written(levels);
    for (k, pair) in found.levels.windows(2).enumerate() {
        if pair[1].triangles <= pair[0].triangles {
            bail!(
                "--triangles {list}: levels {} and {} gave meshes of {} and {} triangles, not finer and finer: space the counts further apart (e.g. each twice the one before)",
                k + 1,
                k + 2,
                pair[0].triangles,
                pair[1].triangles
            );
        }
    }
    if let Some(l) = found.levels.iter().find(|l| !(l.value_error.is_finite() && l.difference_error.is_finite())) {
        bail!(
            "the level of {} triangles has an error that is not a number (values {}, differences {}): the converged answer is 0 everywhere",
            l.triangles,
            l.value_error,
            l.difference_error
        );
    }
    Ok(())
}
