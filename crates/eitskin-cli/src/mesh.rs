//! `eitskin mesh`: mesh the sensor, write the mesh (JSON) and a picture of it (PNG).

use std::path::PathBuf;

use anyhow::{bail, Context, Result};

use crate::{load, plot};

/// Flags of `eitskin mesh`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Sensor spec file (TOML); default: the paper's sensor.
    spec: Option<PathBuf>,
    /// Where to write the mesh (JSON); the picture goes beside it with a .png extension.
    #[arg(long, short, default_value = "mesh.json")]
    out: PathBuf,
    /// Mesh with about this many triangles instead of the spec's count.
    #[arg(long)]
    triangles: Option<usize>,
}

/// Runs `eitskin mesh`.
pub fn run(args: Args) -> Result<()> {
    let png = args.out.with_extension("png");
    if png == args.out {
        bail!(
            "--out {}: the mesh's picture goes beside it with a .png extension and would overwrite it; give the mesh a .json name",
            args.out.display()
        );
    }
    if let Some(spec) = args.spec.as_ref().filter(|spec| **spec == args.out || **spec == png) {
        bail!("--out {}: would overwrite the spec {}", args.out.display(), spec.display());
    }
    let mut spec = load::spec(args.spec.as_deref())?;
    if let Some(n) = args.triangles {
        spec.mesh.triangles = n;
    }
    let mesh = spec.mesh()?;
    std::fs::write(&args.out, eitskin_io::mesh_to_json(&mesh))
        .with_context(|| format!("writing {}", args.out.display()))?;
    plot::mesh_png(&mesh, &png)?;
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
