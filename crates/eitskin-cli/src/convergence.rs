//! `eitskin convergence`: mesh the sensor ever finer and report how fast its measurements
//! approach the converged answer, and what 1 % and 0.1 % accuracy cost.

use std::path::PathBuf;

use anyhow::{bail, Result};
use eitskin::memory::Stage;
use eitskin_study::convergence::{default_inclusion, study};
use serde::Serialize;

use crate::{load, ranges};

/// Flags of `eitskin convergence`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Sensor spec file (TOML); default: the paper's sensor.
    spec: Option<PathBuf>,
    /// Triangle counts to mesh at, comma-separated, coarse to fine, each 1–100,000,000.
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
        spec.protocol = eitskin_io::protocol_by_name(p, std::path::Path::new("."))?;
    }
    load::sized(spec.clone(), args.triangles.iter().max().copied(), Stage::ForwardModel)?;
    let inclusion = match &args.inclusion {
        Some(text) => load::inclusion(text, &spec)?,
        None => default_inclusion(&spec),
    };
    let Some(found) = study(&spec, &args.triangles, inclusion)? else {
        bail!("--triangles needs at least 3 levels to estimate an order, got {}", args.triangles.len());
    };
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
        reference: found.reference,
        value_order: found.value_order,
        difference_order: found.difference_order,
        levels,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!("reference: {}; grading {}", report.reference, spec.mesh.grading);
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
