//! `eitskin sensitivity`: the paper's Fig. 3, the reconstructed peak of one inclusion against
//! its position along the x axis (CSV and PNG), and a map of the peak over the sheet (PNG).

use std::path::PathBuf;

use anyhow::{Context, Result};
use eitskin::conductivity::Inclusion;
use eitskin::memory::Stage;
use eitskin::sensitivity::{along_x, peaks};
use eitskin::{Reconstructor, ReconstructorParams};

use crate::{load, plot, ranges};

/// Flags of `eitskin sensitivity`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Sensor spec file (TOML); default: the paper's sensor.
    spec: Option<PathBuf>,
    /// Folder for profile.csv, profile.png and map.png.
    #[arg(long, default_value = "sensitivity")]
    out: PathBuf,
    /// Triangles of the finer mesh the frames are simulated on, as a multiple of the spec's, 1–64.
    #[arg(long, default_value_t = 4, value_parser = ranges::whole("a refinement factor", 1, 64))]
    refine: usize,
    /// Positions per side of the map grid, 2–200.
    #[arg(long, default_value_t = 17, value_parser = ranges::whole("a number of positions per side", 2, 200))]
    map: usize,
}

/// What the profile and the map show: the largest |Δσ| of an inclusion's image, in S/m.
const PEAK: &str = "peak |Δσ| (S/m)";

/// Runs `eitskin sensitivity`.
pub fn run(args: Args) -> Result<()> {
    let spec = load::spec(args.spec.as_deref())?;
    // The folder is made first, so that a path that cannot be one fails before the work.
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let model = spec.forward_model()?;
    let mut fine = spec.clone();
    fine.mesh.triangles = spec.mesh.triangles * args.refine;
    load::check_memory(&fine, Stage::ForwardModel)?;
    let truth = fine.forward_model()?;
    let recon = Reconstructor::new(&model, spec.conductivity, &ReconstructorParams::default())?;
    let [lo, hi] = spec.outline.bounds();
    let side = hi[0] - lo[0];
    let (radius, sigma) = (0.05 * side, 0.5 * spec.conductivity);
    let inclusions = along_x(side / 2.0, 0.05 * side, radius, sigma, 0.25 * radius);
    let mut bars = crate::progress::Bars::default();
    let profile = peaks_shown(&mut bars, "peaks along x", (&truth, spec.conductivity, &recon), &inclusions)?;
    let k = 1.0 / spec.length_unit.metres();
    let mut csv = format!("x_{},peak_s_per_m\n", spec.length_unit.symbol());
    for (inc, p) in inclusions.iter().zip(&profile) {
        csv += &format!("{},{p:e}\n", inc.centre[0] * k);
    }
    std::fs::write(args.out.join("profile.csv"), csv)?;
    let unit = spec.length_unit.symbol();
    let inclusion = format!("a {} {unit} inclusion of {} S/m", plot::number(2.0 * radius * k), plot::number(sigma));
    let points = inclusions.iter().zip(&profile).map(|(inc, &p)| (inc.centre[0] * k, p)).collect();
    plot::chart(
        &args.out.join("profile.png"),
        &format!("Peak |Δσ| of {inclusion} along y = 0"),
        (&format!("x ({unit})"), PEAK),
        &[plot::Series { name: "peak |Δσ|".into(), points, line: true }],
    )?;

    let n = args.map;
    let inset = |a: f64, b: f64, t: f64| a + radius * 1.25 + t * (b - a - 2.5 * radius);
    let step = |a: f64, b: f64| inset(a, b, 1.0 / (n - 1) as f64) - inset(a, b, 0.0);
    let grid: Vec<Inclusion> = (0..n * n)
        .map(|i| {
            let (col, row) = (i % n, i / n);
            let t = |k: usize| k as f64 / (n - 1) as f64;
            Inclusion {
                centre: [inset(lo[0], hi[0], t(col)), inset(lo[1], hi[1], 1.0 - t(row))],
                radius,
                conductivity: sigma,
            }
        })
        .filter(|inc| spec.outline.contains(inc.centre))
        .collect();
    let map = peaks_shown(&mut bars, "peaks over the sheet", (&truth, spec.conductivity, &recon), &grid)?;
    bars.finish();
    let centres: Vec<[f64; 2]> = grid.iter().map(|g| g.centre).collect();
    let cell = [step(lo[0], hi[0]), step(lo[1], hi[1])];
    let title = format!("Peak |Δσ| of {inclusion} centred at each point");
    plot::map_png(&centres, &map, cell, &spec, (&title, PEAK), &args.out.join("map.png"))?;
    let centre = profile[profile.len() / 2];
    println!(
        "{} positions along x, {} on the map; edge-to-centre peak ratio {:.2}; wrote {}",
        profile.len(),
        map.len(),
        profile[0].max(profile[profile.len() - 1]) / centre,
        args.out.display()
    );
    Ok(())
}

/// [`peaks`] of `inclusions` a few at a time, each step shown on `bars` as stage `stage`.
fn peaks_shown(
    bars: &mut crate::progress::Bars,
    stage: &str,
    (truth, background, recon): (&eitskin::forward::ForwardModel, f64, &Reconstructor),
    inclusions: &[Inclusion],
) -> Result<Vec<f64>> {
    // Each step solves the reference once more: steps of 16 keep that to a few percent.
    let mut values = Vec::with_capacity(inclusions.len());
    for chunk in inclusions.chunks(16) {
        bars.update(stage, values.len(), inclusions.len());
        values.extend(peaks(truth, background, recon, chunk)?);
    }
    bars.update(stage, values.len(), inclusions.len());
    Ok(values)
}
