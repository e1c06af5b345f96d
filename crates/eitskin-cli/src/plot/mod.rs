//! Pictures: the mesh with its electrodes, heat maps over the sheet (a conductivity-change
//! image, a sensitivity map) with axes in the spec's unit and a colour bar, and line charts.

mod colour;
mod heat;
mod sheet;

use std::path::Path;

use anyhow::{anyhow, Context, Result};
use eitskin::Mesh;
use plotters::coord::Shift;
use plotters::prelude::*;

pub use heat::{image_png, map_png};

/// A figure's title font.
const TITLE: (&str, u32) = ("sans-serif", 24);
/// The font of tick labels and electrode numbers.
const LABELS: (&str, u32) = ("sans-serif", 15);
/// The font of an axis' title.
const AXIS_TITLE: (&str, u32) = ("sans-serif", 17);

/// Draws a picture of `size` pixels with `draw` on a white ground, and writes it to `path` as PNG.
///
/// The picture is drawn in memory and encoded here, so that a file that cannot be written is
/// said in words ("writing x.png: Permission denied") rather than as plotters' nested errors.
fn png(
    path: &Path,
    size: (u32, u32),
    draw: impl FnOnce(&DrawingArea<BitMapBackend, Shift>) -> Result<()>,
) -> Result<()> {
    register_font()?;
    let mut rgb = vec![0u8; size.0 as usize * size.1 as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
        let drawn = root.fill(&WHITE).drawn().and_then(|()| draw(&root)).and_then(|()| root.present().drawn());
        drawn.with_context(|| format!("drawing {}", path.display()))?;
    }
    write_png(path, size, &rgb).with_context(|| format!("writing {}", path.display()))
}

/// Encodes 8-bit RGB pixels, row by row from the top, to a PNG file.
fn write_png(path: &Path, (width, height): (u32, u32), rgb: &[u8]) -> Result<()> {
    let file = std::io::BufWriter::new(std::fs::File::create(path)?);
    let mut encoder = ::png::Encoder::new(file, width, height);
    encoder.set_color(::png::ColorType::Rgb);
    encoder.set_depth(::png::BitDepth::Eight);
    let mut writer = encoder.write_header()?;
    writer.write_image_data(rgb)?;
    writer.finish()?;
    Ok(())
}

/// Plotters' errors as anyhow's.
trait Drawn<T> {
    /// The error, if any, as an [`anyhow::Error`] that quotes it.
    fn drawn(self) -> Result<T>;
}

impl<T, E: std::fmt::Display> Drawn<T> for std::result::Result<T, E> {
    fn drawn(self) -> Result<T> {
        self.map_err(|e| anyhow!("{e}"))
    }
}

/// A number as a tick label: at most 4 decimals, trailing zeros dropped, a true minus sign;
/// in scientific notation below 0.001.
pub fn number(value: f64) -> String {
    let text = if value.abs() >= 1e-3 || value.abs() < 1e-12 {
        let fixed = format!("{value:.4}");
        fixed.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        format!("{value:.1e}")
    };
    match text.as_str() {
        "-0" => "0".to_string(),
        _ => text.replace('-', "\u{2212}"),
    }
}

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
    png(path, (size, size), |root| {
        for t in 0..mesh.triangles().len() {
            let c = mesh.corners(t);
            let ring = vec![px(c[0]), px(c[1]), px(c[2]), px(c[0])];
            root.draw(&PathElement::new(ring, RGBColor(150, 150, 150))).drawn()?;
        }
        for l in 0..mesh.electrodes().len() {
            let colour = if l == 0 { RED } else { BLUE };
            for [a, b] in mesh.electrode_edges(l) {
                let line = vec![px(mesh.nodes()[a]), px(mesh.nodes()[b])];
                root.draw(&PathElement::new(line, colour.stroke_width(5))).drawn()?;
            }
            if let [n] = mesh.electrodes()[l][..] {
                root.draw(&Circle::new(px(mesh.nodes()[n]), 5, colour.filled())).drawn()?;
            }
        }
        Ok(())
    })
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
const FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");

fn register_font() -> Result<()> {
    static ONCE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let ok = *ONCE.get_or_init(|| plotters::style::register_font("sans-serif", FontStyle::Normal, FONT).is_ok());
    if ok {
        Ok(())
    } else {
        Err(anyhow!("the bundled font could not be loaded"))
    }
}

/// A titled chart with labelled axes and, for more than one series, a legend, to a PNG.
pub fn chart(path: &Path, title: &str, labels: (&str, &str), series: &[Series]) -> Result<()> {
    chart_on(path, title, labels, series, false)
}

/// [`chart`] with a logarithmic x axis (points with x ≤ 0 left out).
pub fn chart_log_x(path: &Path, title: &str, labels: (&str, &str), series: &[Series]) -> Result<()> {
    chart_on(path, title, labels, series, true)
}

fn chart_on(path: &Path, title: &str, labels: (&str, &str), series: &[Series], log_x: bool) -> Result<()> {
    let shown = |p: &&(f64, f64)| p.0.is_finite() && p.1.is_finite() && (!log_x || p.0 > 0.0);
    let all = series.iter().flat_map(|s| s.points.iter()).filter(shown);
    let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for &(x, y) in all {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    if x0.is_nan() || x1.is_nan() || x0 >= x1 {
        let mid = if x0.is_finite() { x0 } else { 1.0 };
        (x0, x1) = if log_x { (mid / 2.0, mid * 2.0) } else { (mid - 1.0, mid + 1.0) };
    }
    if !y0.is_finite() || !y1.is_finite() {
        (y0, y1) = (0.0, 1.0);
    }
    let pad = 0.05 * (y1 - y0).max(f64::MIN_POSITIVE);
    let (y0, y1) = (y0.min(0.0) - pad, y1 + pad);
    png(path, (900, 600), |root| {
        let mut builder = ChartBuilder::on(root);
        builder.caption(title, ("sans-serif", 24)).margin(15).x_label_area_size(45).y_label_area_size(70);
        if log_x {
            // Ticks at the data's own x when there are few (N = 25, 50, 100, …), else at 1, 2, 5 per decade.
            let mut ticks: Vec<f64> = series.iter().flat_map(|s| s.points.iter()).filter(shown).map(|p| p.0).collect();
            ticks.sort_by(f64::total_cmp);
            ticks.dedup();
            if ticks.len() > 12 {
                let decades = x0.log10().floor() as i32..=x1.log10().ceil() as i32;
                ticks = decades
                    .flat_map(|d| [1.0, 2.0, 5.0].map(|m| m * 10f64.powi(d)))
                    .filter(|t| (x0..=x1).contains(t))
                    .collect();
            }
            let x_range = (x0..x1).log_scale().with_key_points(ticks);
            let mut chart = builder.build_cartesian_2d(x_range, y0..y1).drawn()?;
            // Falling curves against a growing x: the upper right is free.
            draw_series(&mut chart, labels, series, shown, SeriesLabelPosition::UpperRight)
        } else {
            let mut chart = builder.build_cartesian_2d(x0..x1, y0..y1).drawn()?;
            draw_series(&mut chart, labels, series, shown, SeriesLabelPosition::UpperLeft)
        }
    })
}

/// The mesh, the series and (for more than one) their legend, on `chart`.
fn draw_series<'a, 'b: 'a, X>(
    chart: &mut ChartContext<'a, BitMapBackend<'b>, Cartesian2d<X, plotters::coord::types::RangedCoordf64>>,
    (x_label, y_label): (&str, &str),
    series: &[Series],
    shown: impl Fn(&&(f64, f64)) -> bool,
    legend: SeriesLabelPosition,
) -> Result<()>
where
    X: Ranged<ValueType = f64> + plotters::coord::ranged1d::ValueFormatter<f64>,
{
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .x_label_formatter(&|v| number(*v))
        .y_label_formatter(&|v| number(*v))
        .label_style(LABELS)
        .draw()
        .drawn()?;
    for (k, s) in series.iter().enumerate() {
        // Ten colours that stay apart (Tableau's, matplotlib's default cycle); past ten, the
        // colours again, dashed, with hollow marks and hollow legend boxes.
        let colour = SERIES_COLOURS[k % SERIES_COLOURS.len()];
        let second = k >= SERIES_COLOURS.len();
        let style = if second { colour.stroke_width(2) } else { colour.filled() };
        let points: Vec<(f64, f64)> = s.points.iter().filter(&shown).copied().collect();
        if s.line && second {
            chart.draw_series(DashedLineSeries::new(points.iter().copied(), 6, 4, colour.stroke_width(2))).drawn()?;
        } else if s.line {
            chart.draw_series(LineSeries::new(points.iter().copied(), colour.stroke_width(2))).drawn()?;
        }
        let radius = if s.line { 3 } else { 2 };
        chart
            .draw_series(points.iter().map(|&p| Circle::new(p, radius, style)))
            .drawn()?
            .label(s.name.clone())
            .legend(move |(x, y)| Rectangle::new([(x, y - 4), (x + 16, y + 4)], style));
    }
    if series.len() < 2 {
        return Ok(());
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 15))
        .position(legend)
        .draw()
        .drawn()
}

/// The colours of a chart's series, in order: Tableau's ten (matplotlib's default cycle).
const SERIES_COLOURS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_short_and_signed_with_a_true_minus() {
        let cases =
            [(50.00000000000001, "50"), (-100.0, "−100"), (0.0125, "0.0125"), (-2.7e-17, "0"), (-2e-5, "−2.0e−5")];
        for (value, text) in cases {
            assert_eq!(number(value), text, "{value}");
        }
    }
}
