//! `eitskin bench`: times each stage of the setup chain over repeated runs, prints medians.
//!
//! Stages: `mesh` (triangulation and refinement), `model` (sparsity pattern and symbolic
//! Cholesky, once per mesh), `assembly`, `factorisation` (numeric Cholesky), `solves` (all
//! L−1 current patterns), `measurements` (the protocol's values from the fields).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Result;

use crate::load;

/// Flags of `eitskin bench`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Sensor spec file (TOML); default: the paper's sensor.
    spec: Option<PathBuf>,
    /// Mesh with about this many triangles instead of the spec's count.
    #[arg(long)]
    triangles: Option<usize>,
    /// Runs per stage; the median is reported.
    #[arg(long, default_value_t = 15)]
    repeat: usize,
    /// Print one JSON object with a field per stage, in seconds.
    #[arg(long)]
    json: bool,
}

/// The median of `runs` timings of `f`, in s, and its last result.
fn time<T>(runs: usize, mut f: impl FnMut() -> Result<T>) -> Result<(f64, T)> {
    let mut times = Vec::with_capacity(runs);
    let mut last = None;
    for _ in 0..runs.max(1) {
        let start = Instant::now();
        let out = std::hint::black_box(f()?);
        times.push(start.elapsed().as_secs_f64());
        last = Some(out);
    }
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    // `runs.max(1)` iterations ran, so `last` is set.
    Ok((median, last.ok_or_else(|| anyhow::anyhow!("no run"))?))
}

/// Runs `eitskin bench`.
pub fn run(args: Args) -> Result<()> {
    let mut spec = load::spec(args.spec.as_deref())?;
    if let Some(n) = args.triangles {
        spec.mesh.triangles = n;
    }
    let n = args.repeat;
    let (t_mesh, mesh) = time(n, || Ok(spec.mesh()?))?;
    let (t_model, model) = time(n, || Ok(spec.forward_model_on(mesh.clone())?))?;
    let sigma = spec.homogeneous(model.mesh());
    let (t_assembly, matrix) = time(n, || Ok(model.assemble(&sigma)?))?;
    let (t_factor, factor) = time(n, || Ok(model.factorize(&matrix)?))?;
    let (t_solves, solution) = time(n, || Ok(model.solve_patterns(&factor)))?;
    let mut values = vec![0.0; model.protocol().len()];
    let (t_measure, ()) = time(n.max(101), || {
        solution.measurements_into(model.protocol(), &mut values);
        Ok(())
    })?;
    let stages = [
        ("mesh", t_mesh),
        ("model", t_model),
        ("assembly", t_assembly),
        ("factorisation", t_factor),
        ("solves", t_solves),
        ("measurements", t_measure),
    ];
    let total: f64 = stages.iter().map(|s| s.1).sum();
    if args.json {
        let mut out = serde_json::Map::new();
        out.insert("triangles".into(), model.mesh().triangles().len().into());
        out.insert("nodes".into(), model.mesh().nodes().len().into());
        out.insert("repeat".into(), n.into());
        for (name, t) in stages {
            out.insert(name.into(), t.into());
        }
        out.insert("total".into(), total.into());
        println!("{}", serde_json::Value::Object(out));
    } else {
        println!(
            "{} triangles, {} nodes, {} measurements; medians of {n} runs:",
            model.mesh().triangles().len(),
            model.mesh().nodes().len(),
            values.len()
        );
        for (name, t) in stages {
            println!("  {name:<14} {:>10.3} ms", t * 1e3);
        }
        println!("  {:<14} {:>10.3} ms", "total", total * 1e3);
    }
    Ok(())
}
