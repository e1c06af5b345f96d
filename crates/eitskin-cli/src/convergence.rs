//! `eitskin convergence`: mesh the sensor ever finer and report how fast its measurements
//! approach the converged answer, and what 1 % and 0.1 % accuracy cost.

use std::path::PathBuf;

use anyhow::{bail, Result};
use eitskin::conductivity::Inclusion;
use eitskin::convergence::{disk_values, levels, observed_order, relative_error, richardson, Level};
use serde::Serialize;

use crate::load;

/// Flags of `eitskin convergence`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Sensor spec file (TOML); default: the paper's sensor.
    spec: Option<PathBuf>,
    /// Triangle counts to mesh at, comma-separated, coarse to fine.
    #[arg(long, value_delimiter = ',', default_value = "500,1000,2000,4000,8000,16000,32000,64000,128000")]
    triangles: Vec<usize>,
    /// Override the mesh grading toward electrode edges (1 = uniform).
    #[arg(long)]
    grading: Option<f64>,
    /// Protocol: two-terminal, adjacent, adjacent-all, opposite, or a protocol JSON file.
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
    if args.triangles.len() < 3 {
        bail!("--triangles needs at least 3 levels to estimate an order");
    }
    let inclusion = match &args.inclusion {
        Some(text) => load::inclusion(text, &spec)?,
        None => {
            let [lo, hi] = spec.outline.bounds();
            let width = hi[0] - lo[0];
            Inclusion { centre: [0.25 * width, 0.0], radius: 0.05 * width, conductivity: 0.5 * spec.conductivity }
        }
    };
    let levels = levels(&spec, &args.triangles, &[inclusion])?;
    let n = levels.len();
    let tri = |k: usize| levels[k].triangles;
    let order_of = |f: fn(&Level) -> &[f64]| {
        observed_order([f(&levels[n - 3]), f(&levels[n - 2]), f(&levels[n - 1])], [tri(n - 3), tri(n - 2), tri(n - 1)])
    };
    let value_order = order_of(|l| &l.values);
    let difference_order = order_of(|l| &l.difference);
    let extrapolate = |f: fn(&Level) -> &[f64], order: Option<f64>| {
        let ratio = (tri(n - 1) as f64 / tri(n - 2) as f64).sqrt();
        richardson(f(&levels[n - 2]), f(&levels[n - 1]), ratio, order.unwrap_or(1.0).max(0.5))
    };
    let (reference, value_truth) = match disk_values(&spec)? {
        Some(v) => ("analytic (Fourier series) for values, Richardson for differences", v),
        None => ("Richardson extrapolation of the two finest levels", extrapolate(|l| &l.values, value_order)),
    };
    let difference_truth = extrapolate(|l| &l.difference, difference_order);
    let rows: Vec<Row> = levels
        .iter()
        .map(|l| Row {
            triangles: l.triangles,
            setup_seconds: l.setup_seconds,
            value_error: relative_error(&l.values, &value_truth),
            difference_error: relative_error(&l.difference, &difference_truth),
        })
        .collect();
    let report = Report { reference, value_order, difference_order, levels: rows };
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
    println!("observed order in h: values {}, differences {}", show(value_order), show(difference_order));
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
