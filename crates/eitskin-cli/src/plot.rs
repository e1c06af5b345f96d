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

/// Draws a conductivity-change image as a heat map (decrease blue, increase red, both scaled to
/// the largest |change|; masked pixels grey) with a black ring at each touch's centre.
pub fn image_png(image: &eitskin::Image, touches: &[eitskin::Touch], path: &Path) -> Result<()> {
    let [nx, ny] = image.size;
    let cell = (640 / nx.max(ny)).max(1) as u32;
    let (w, h) = (nx as u32 * cell, ny as u32 * cell);
    let root = BitMapBackend::new(path, (w, h)).into_drawing_area();
    let fail = |e: &dyn std::fmt::Display| anyhow!("drawing {}: {e}", path.display());
    root.fill(&WHITE).map_err(|e| fail(&e))?;
    let scale = image.peak().map_or(1.0, |(_, v)| v.abs().max(f32::MIN_POSITIVE));
    for row in 0..ny {
        for col in 0..nx {
            let p = row * nx + col;
            let colour = if !image.inside[p] {
                RGBColor(200, 200, 200)
            } else {
                let t = (image.values[p] / scale).clamp(-1.0, 1.0);
                let fade = |c: f32| (255.0 * (1.0 - c.abs())) as u8;
                if t < 0.0 {
                    RGBColor(fade(t), fade(t), 255)
                } else {
                    RGBColor(255, fade(t), fade(t))
                }
            };
            let (x, y) = ((col as u32 * cell) as i32, (row as u32 * cell) as i32);
            root.draw(&Rectangle::new([(x, y), (x + cell as i32, y + cell as i32)], colour.filled()))
                .map_err(|e| fail(&e))?;
        }
    }
    let [lo, hi] = image.bounds;
    for t in touches {
        let x = ((t.centre[0] - lo[0]) / (hi[0] - lo[0]) * w as f64) as i32;
        let y = ((hi[1] - t.centre[1]) / (hi[1] - lo[1]) * h as f64) as i32;
        root.draw(&Circle::new((x, y), 8, BLACK.stroke_width(3))).map_err(|e| fail(&e))?;
    }
    root.present().map_err(|e| fail(&e))?;
    Ok(())
}

/// A line through (x, y) points scaled to fill the picture, with a dot at each point.
pub fn profile_png(xs: &[f64], ys: &[f64], path: &Path) -> Result<()> {
    let (w, h) = (800u32, 500u32);
    let root = BitMapBackend::new(path, (w, h)).into_drawing_area();
    let fail = |e: &dyn std::fmt::Display| anyhow!("drawing {}: {e}", path.display());
    root.fill(&WHITE).map_err(|e| fail(&e))?;
    let (x0, x1) = xs.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)));
    let y1 = ys.iter().fold(0.0f64, |m, &y| m.max(y)).max(f64::MIN_POSITIVE);
    let px = |x: f64, y: f64| {
        (
            40 + ((x - x0) / (x1 - x0).max(f64::MIN_POSITIVE) * (w - 80) as f64) as i32,
            (h - 40) as i32 - (y / y1 * (h - 80) as f64) as i32,
        )
    };
    root.draw(&PathElement::new(vec![(40, (h - 40) as i32), ((w - 40) as i32, (h - 40) as i32)], BLACK))
        .map_err(|e| fail(&e))?;
    let points: Vec<(i32, i32)> = xs.iter().zip(ys).map(|(&x, &y)| px(x, y)).collect();
    root.draw(&PathElement::new(points.clone(), BLUE.stroke_width(2))).map_err(|e| fail(&e))?;
    for p in points {
        root.draw(&Circle::new(p, 4, BLUE.filled())).map_err(|e| fail(&e))?;
    }
    root.present().map_err(|e| fail(&e))?;
    Ok(())
}

/// Values at scattered centres drawn as squares shaded from white (0) to red (largest).
pub fn map_png(centres: &[[f64; 2]], values: &[f64], [lo, hi]: [[f64; 2]; 2], path: &Path) -> Result<()> {
    let size = 600u32;
    let root = BitMapBackend::new(path, (size, size)).into_drawing_area();
    let fail = |e: &dyn std::fmt::Display| anyhow!("drawing {}: {e}", path.display());
    root.fill(&RGBColor(200, 200, 200)).map_err(|e| fail(&e))?;
    let top = values.iter().fold(0.0f64, |m, &v| m.max(v)).max(f64::MIN_POSITIVE);
    let n = (centres.len() as f64).sqrt().ceil().max(1.0);
    let half = (size as f64 / n / 2.0).ceil() as i32;
    for (c, v) in centres.iter().zip(values) {
        let x = ((c[0] - lo[0]) / (hi[0] - lo[0]) * size as f64) as i32;
        let y = ((hi[1] - c[1]) / (hi[1] - lo[1]) * size as f64) as i32;
        let fade = (255.0 * (1.0 - v / top)) as u8;
        root.draw(&Rectangle::new([(x - half, y - half), (x + half, y + half)], RGBColor(255, fade, fade).filled()))
            .map_err(|e| fail(&e))?;
    }
    root.present().map_err(|e| fail(&e))?;
    Ok(())
}

/// One series of a chart: named points, joined by a line or drawn as dots.
pub struct Series {
    /// Legend text.
    pub name: String,
    /// (x, y) points.
    pub points: Vec<(f64, f64)>,
    /// Join the points with a line (else dots).
    pub line: bool,
}

/// The bundled font (DejaVu Sans, Bitstream Vera licence: `assets/DejaVuSans-LICENSE.txt`).
const FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

fn register_font() -> Result<()> {
    static ONCE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let ok = *ONCE.get_or_init(|| plotters::style::register_font("sans-serif", FontStyle::Normal, FONT).is_ok());
    if ok {
        Ok(())
    } else {
        Err(anyhow!("the bundled font could not be loaded"))
    }
}

/// A titled chart with labelled axes and a legend, to a PNG.
pub fn chart(path: &Path, title: &str, (x_label, y_label): (&str, &str), series: &[Series]) -> Result<()> {
    register_font()?;
    let fail = |e: &dyn std::fmt::Display| anyhow!("drawing {}: {e}", path.display());
    let all = series.iter().flat_map(|s| s.points.iter()).filter(|p| p.0.is_finite() && p.1.is_finite());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for &(x, y) in all {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    if x0.is_nan() || x1.is_nan() || x0 >= x1 {
        let mid = if x0.is_finite() { x0 } else { 0.0 };
        (x0, x1) = (mid - 1.0, mid + 1.0);
    }
    if !y0.is_finite() || !y1.is_finite() {
        (y0, y1) = (0.0, 1.0);
    }
    let pad = 0.05 * (y1 - y0).max(f64::MIN_POSITIVE);
    let (y0, y1) = (y0.min(0.0) - pad, y1 + pad);
    let root = BitMapBackend::new(path, (900, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| fail(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 24))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| fail(&e))?;
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .label_style(("sans-serif", 15))
        .draw()
        .map_err(|e| fail(&e))?;
    for (k, s) in series.iter().enumerate() {
        let colour = Palette99::pick(k).to_rgba();
        let points = s.points.iter().copied().filter(|p| p.0.is_finite() && p.1.is_finite());
        let drawn = if s.line {
            chart.draw_series(LineSeries::new(points, colour.stroke_width(2))).map_err(|e| fail(&e))?
        } else {
            chart.draw_series(points.map(|p| Circle::new(p, 2, colour.filled()))).map_err(|e| fail(&e))?
        };
        drawn
            .label(s.name.clone())
            .legend(move |(x, y)| Rectangle::new([(x, y - 4), (x + 16, y + 4)], colour.filled()));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 15))
        .position(SeriesLabelPosition::UpperLeft)
        .draw()
        .map_err(|e| fail(&e))?;
    root.present().map_err(|e| fail(&e))?;
    Ok(())
}
