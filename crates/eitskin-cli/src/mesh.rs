//! `eitskin mesh`: mesh the sensor, write the mesh (JSON) and a picture of it (PNG).

use std::path::PathBuf;

use anyhow::{Context, Result};
use eitskin::memory::Stage;

use crate::{load, outputs, plot, ranges};

/// Flags of `eitskin mesh`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Sensor spec file (TOML); default: the paper's sensor.
    spec: Option<PathBuf>,
    /// Where to write the mesh (JSON); the picture goes beside it with a .png extension.
    #[arg(long, short, default_value = "mesh.json", value_parser = outputs::writes(&["json"]))]
    out: PathBuf,
    /// Mesh with about this many triangles instead of the spec's count, 1–100,000,000 (refused
    /// when the mesh and what is built on it would not fit in the memory available; a count
    /// under the fewest the mesher makes on the sheet, about 200 on the paper's sensor, is
    /// raised to it with a warning).
    #[arg(long, value_parser = ranges::triangles())]
    triangles: Option<usize>,
}

/// Runs `eitskin mesh`.
pub fn run(args: Args) -> Result<()> {
    // `--out` is never a .png (its parser), so the picture beside it is another file.
    let png = args.out.with_extension("png");
    let spec: Vec<_> = args.spec.iter().map(|s| ("the spec", s.as_path())).collect();
    outputs::check(&[("--out", &args.out), ("--out's picture", &png)], &spec)?;
    let spec = load::sized(load::spec(args.spec.as_deref())?, args.triangles, Stage::Mesh)?;
    let mesh = spec.mesh()?;
    ranges::warn_raised_triangles(args.triangles, &mesh, &spec)?;
    let mut staged = outputs::Staged::default();
    std::fs::write(staged.path(&args.out), eitskin_io::mesh_to_json(&mesh))
        .with_context(|| format!("writing {}", args.out.display()))?;
    plot::mesh_png(&mesh, &staged.path(&png))?;
    staged.commit()?;
    println!(
        "{} nodes, {} triangles, smallest angle {:.1}°: wrote {} and {}",
        mesh.nodes().len(),
        mesh.triangles().len(),
        mesh.min_angle_deg(),
        args.out.display(),
        png.display()
    );
    Ok(())
}
