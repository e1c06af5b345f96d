//! Pictures: the mesh with its electrodes.

use std::path::Path;

use anyhow::{anyhow, Result};
use eitskin::Mesh;
use plotters::prelude::*;

/// Draws `mesh` (grey edges) with its electrodes (thick; electrode 1 red, the rest blue) to a PNG.
pub fn mesh_png(mesh: &Mesh, path: &Path) -> Result<()> {
    let size = 900u32;
    let [lo, hi] = mesh.bounds();
    let span = (hi[0] - lo[0]).max(hi[1] - lo[1]);
    let margin = 20.0;
    let scale = (size as f64 - 2.0 * margin) / span;
    let px = |p: [f64; 2]| {
        ((margin + (p[0] - lo[0]) * scale) as i32, (size as f64 - margin - (p[1] - lo[1]) * scale) as i32)
    };
    let root = BitMapBackend::new(path, (size, size)).into_drawing_area();
    let fail = |e: &dyn std::fmt::Display| anyhow!("drawing {}: {e}", path.display());
    root.fill(&WHITE).map_err(|e| fail(&e))?;
    for t in 0..mesh.triangles().len() {
        let c = mesh.corners(t);
        let ring = vec![px(c[0]), px(c[1]), px(c[2]), px(c[0])];
        root.draw(&PathElement::new(ring, RGBColor(150, 150, 150))).map_err(|e| fail(&e))?;
    }
    for l in 0..mesh.electrodes().len() {
        let colour = if l == 0 { RED } else { BLUE };
        for [a, b] in mesh.electrode_edges(l) {
            let line = vec![px(mesh.nodes()[a]), px(mesh.nodes()[b])];
            root.draw(&PathElement::new(line, colour.stroke_width(5))).map_err(|e| fail(&e))?;
        }
        if let [n] = mesh.electrodes()[l][..] {
            root.draw(&Circle::new(px(mesh.nodes()[n]), 5, colour.filled())).map_err(|e| fail(&e))?;
        }
    }
    root.present().map_err(|e| fail(&e))?;
    Ok(())
}
