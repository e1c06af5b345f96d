//! The sheet as a figure shows it: axes labelled in the spec's length unit at equal scale in x
//! and y, the outline, and the electrodes numbered from 1. Coordinates stay in m throughout;
//! only the tick labels are in the spec's unit.

use std::ops::Range;

use anyhow::Result;
use eitskin::{Outline, SensorSpec};
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::{number, Drawn, AXIS_TITLE, LABELS};

/// A chart over the sheet, in m.
pub type SheetChart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// Space around the axes, in pixels.
const MARGIN: u32 = 15;
/// Height of the x axis' tick labels and title, in pixels.
const X_LABELS: u32 = 55;
/// Width of the y axis' tick labels and title, in pixels.
const Y_LABELS: u32 = 75;
/// Pixels above and below the plot inside the area given to [`axes`]: a colour bar beside it
/// leaves the same to stand level with it.
pub const PLOT_INSET: (u32, u32) = (MARGIN, MARGIN + X_LABELS);
/// Room around the outline for the electrode numbers, as a fraction of its larger side.
const ROOM: f64 = 0.1;
/// Distance of an electrode's number from the outline, as a fraction of its larger side.
const NUMBER_GAP: f64 = 0.045;
/// Points a curved outline is drawn through.
const RING_POINTS: usize = 256;

/// Draws axes over `spec`'s sheet on `area`: in m, ticked in the spec's length unit, the same
/// scale in x and y, with room around the outline for the electrode numbers.
pub fn axes<'a, DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, spec: &SensorSpec) -> Result<SheetChart<'a, DB>> {
    let (w, h) = area.dim_in_pixel();
    let plot = (w.saturating_sub(2 * MARGIN + Y_LABELS), h.saturating_sub(2 * MARGIN + X_LABELS));
    let (x, y) = equal_scale(with_room(spec.outline.bounds()), plot);
    let mut chart = ChartBuilder::on(area)
        .margin(MARGIN)
        .x_label_area_size(X_LABELS)
        .y_label_area_size(Y_LABELS)
        .build_cartesian_2d(x, y)
        .drawn()?;
    let unit = spec.length_unit;
    let tick = |metres: &f64| number(metres / unit.metres());
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc(format!("x ({})", unit.symbol()))
        .y_desc(format!("y ({})", unit.symbol()))
        .x_label_formatter(&tick)
        .y_label_formatter(&tick)
        .label_style(LABELS)
        .axis_desc_style(AXIS_TITLE)
        .draw()
        .drawn()?;
    Ok(chart)
}

/// The box `[lo, hi]` (m) grown by [`ROOM`] of its larger side on every side.
fn with_room([lo, hi]: [[f64; 2]; 2]) -> [[f64; 2]; 2] {
    let room = ROOM * (hi[0] - lo[0]).max(hi[1] - lo[1]);
    [[lo[0] - room, lo[1] - room], [hi[0] + room, hi[1] + room]]
}

/// Ranges in x and y that hold the box `[lo, hi]`, centred, with the same length per pixel on a
/// plot of `(w, h)` pixels.
fn equal_scale([lo, hi]: [[f64; 2]; 2], (w, h): (u32, u32)) -> (Range<f64>, Range<f64>) {
    let (w, h) = (f64::from(w.max(1)), f64::from(h.max(1)));
    let per_pixel = ((hi[0] - lo[0]) / w).max((hi[1] - lo[1]) / h);
    let around = |a: f64, b: f64, pixels: f64| {
        let (centre, half) = ((a + b) / 2.0, per_pixel * pixels / 2.0);
        centre - half..centre + half
    };
    (around(lo[0], hi[0], w), around(lo[1], hi[1], h))
}

/// The outline as a closed path, in m.
pub fn ring(outline: &Outline) -> Vec<(f64, f64)> {
    outline.ring(RING_POINTS).into_iter().map(|[x, y]| (x, y)).collect()
}

/// Draws the outline as a thin black line.
pub fn draw_outline<DB: DrawingBackend>(chart: &mut SheetChart<DB>, outline: &Outline) -> Result<()> {
    chart.draw_series([PathElement::new(ring(outline), BLACK.stroke_width(1))]).drawn()?;
    Ok(())
}

/// Draws each electrode of `spec` as a thick black stretch of the outline (a dot for a point
/// electrode), numbered from 1 just outside it.
pub fn draw_electrodes<DB: DrawingBackend>(chart: &mut SheetChart<DB>, spec: &SensorSpec) -> Result<()> {
    let outline = &spec.outline;
    let [lo, hi] = outline.bounds();
    let gap = NUMBER_GAP * (hi[0] - lo[0]).max(hi[1] - lo[1]);
    let style = LABELS.into_font().color(&BLACK).pos(Pos::new(HPos::Center, VPos::Center));
    for (l, electrode) in spec.electrode_positions()?.iter().enumerate() {
        let at = |offset: f64| {
            let [x, y] = outline.point_at(electrode.centre + offset);
            (x, y)
        };
        let stretch: Vec<(f64, f64)> = (0..=8).map(|k| at(electrode.width * (k as f64 / 8.0 - 0.5))).collect();
        chart.draw_series([PathElement::new(stretch, BLACK.stroke_width(5))]).drawn()?;
        if electrode.width <= 0.0 {
            chart.draw_series([Circle::new(at(0.0), 4, BLACK.filled())]).drawn()?;
        }
        let ([x, y], [nx, ny]) = (outline.point_at(electrode.centre), outward(outline, electrode.centre));
        chart.draw_series([Text::new((l + 1).to_string(), (x + gap * nx, y + gap * ny), style.clone())]).drawn()?;
    }
    Ok(())
}

/// The unit normal pointing out of the outline at arc length `s` (m): the boundary runs
/// counter-clockwise, so outward is its direction turned clockwise.
fn outward(outline: &Outline, s: f64) -> [f64; 2] {
    let step = 1e-4 * outline.perimeter();
    let ([ax, ay], [bx, by]) = (outline.point_at(s - step), outline.point_at(s + step));
    let (tx, ty) = (bx - ax, by - ay);
    let length = tx.hypot(ty).max(f64::MIN_POSITIVE);
    [ty / length, -tx / length]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axes_have_the_same_scale_in_x_and_y_and_hold_the_sheet() {
        crate::plot::register_font().unwrap();
        let spec = SensorSpec { outline: Outline::Rectangle { width: 0.3, height: 0.1 }, ..SensorSpec::default() };
        let (w, h) = (700, 500);
        let mut buffer = vec![0u8; (w * h * 3) as usize];
        let root = BitMapBackend::with_buffer(&mut buffer, (w, h)).into_drawing_area();
        let chart = axes(&root, &spec).unwrap();
        let (x, y) = (chart.x_range(), chart.y_range());
        let (px, py) = chart.plotting_area().dim_in_pixel();
        let (x_per_pixel, y_per_pixel) = ((x.end - x.start) / f64::from(px), (y.end - y.start) / f64::from(py));
        assert!((x_per_pixel / y_per_pixel - 1.0).abs() < 0.01, "{x_per_pixel} m/px across, {y_per_pixel} down");
        assert!(x.start < -0.15 && x.end > 0.15 && y.start < -0.05 && y.end > 0.05, "{x:?} × {y:?}");
    }

    #[test]
    fn outward_points_away_from_the_centre_on_every_side() {
        let outline = Outline::Rectangle { width: 0.2, height: 0.2 };
        for (s, expected) in [(0.1, [0.0, -1.0]), (0.3, [1.0, 0.0]), (0.5, [0.0, 1.0]), (0.7, [-1.0, 0.0])] {
            let n = outward(&outline, s);
            assert!((n[0] - expected[0]).abs() < 1e-9 && (n[1] - expected[1]).abs() < 1e-9, "at {s}: {n:?}");
        }
    }
}
