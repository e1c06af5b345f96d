//! Colour: the library's one map ([`eitskin::colour`], blue for a decrease, red for an
//! increase) over a figure's values, and the bar that reads it.

use anyhow::Result;
use plotters::coord::Shift;
use plotters::prelude::*;

use super::{number, Drawn, AXIS_TITLE, LABELS};

/// [`eitskin::colour`]'s map, blue (decrease) through near white (0) to red (increase), over the
/// values from `low` to `high`: the same |value| is the same strength of colour on either side of 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ColourMap {
    /// The value at the bottom of the bar.
    pub low: f64,
    /// The value at the top of the bar.
    pub high: f64,
}

impl ColourMap {
    /// −`peak` to `peak`, for signed changes (a `peak` that is not positive and finite gives ±1).
    pub fn symmetric(peak: f64) -> ColourMap {
        let peak = positive_or_one(peak);
        ColourMap { low: -peak, high: peak }
    }

    /// 0 to `top`, for magnitudes (a `top` that is not positive and finite gives 1).
    pub fn magnitude(top: f64) -> ColourMap {
        ColourMap { low: 0.0, high: positive_or_one(top) }
    }

    /// The colour of `value`: the map's middle at 0, its ends at −m and +m, where m is the
    /// larger |end| of the map; values beyond the ends take the end's colour.
    pub fn colour(&self, value: f64) -> RGBColor {
        let [r, g, b] = eitskin::colour::colour(value / self.low.abs().max(self.high.abs()));
        RGBColor(r, g, b)
    }
}

fn positive_or_one(value: f64) -> f64 {
    if value.is_finite() && value > 0.0 {
        value
    } else {
        1.0
    }
}

/// Width of the bar itself, in pixels.
const BAR: u32 = 28;
/// Space left of the bar, in pixels.
const GAP: u32 = 12;
/// Space right of the label's column, in pixels: plotters sets the label outside it.
const RIGHT: u32 = 24;
/// Bands the bar is painted in, from `low` to `high`.
const BANDS: usize = 256;

/// Draws a vertical colour bar for `map` on `area`, its values ticked on the right and `label`
/// (what the colour shows, with its unit) beside them, leaving `(top, bottom)` pixels free so that
/// it stands level with a plot; returns the pixels of its low and high ends, on its middle line.
pub fn colour_bar<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    map: ColourMap,
    label: &str,
    (top, bottom): (u32, u32),
) -> Result<[(i32, i32); 2]> {
    let labels_width = area.dim_in_pixel().0.saturating_sub(GAP + BAR + RIGHT);
    let mut chart = ChartBuilder::on(area)
        .margin_top(top)
        .margin_bottom(bottom)
        .margin_left(GAP)
        .margin_right(RIGHT)
        .right_y_label_area_size(labels_width)
        .build_cartesian_2d(0.0..1.0, map.low..map.high)
        .drawn()?;
    chart
        .configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_desc(label)
        .y_label_formatter(&|v| number(*v))
        .label_style(LABELS)
        .axis_desc_style(AXIS_TITLE)
        .draw()
        .drawn()?;
    chart.draw_series(bands(map)).drawn()?;
    Ok([chart.backend_coord(&(0.5, map.low)), chart.backend_coord(&(0.5, map.high))])
}

/// The bar as [`BANDS`] stacked rectangles, the lowest exactly `map.low`'s colour and the
/// highest exactly `map.high`'s.
fn bands(map: ColourMap) -> impl Iterator<Item = Rectangle<(f64, f64)>> {
    let at = move |t: f64| map.low * (1.0 - t) + map.high * t;
    (0..BANDS).map(move |k| {
        // A filled rectangle leaves out its bottom pixel row: the lowest band reaches a band
        // further down (clipped at the plot's edge) so that the row of `map.low` is painted too.
        let bottom = if k == 0 { -1.0 } else { k as f64 };
        let (from, to) = (at(bottom / BANDS as f64), at((k + 1) as f64 / BANDS as f64));
        let colour = map.colour(at(k as f64 / (BANDS - 1) as f64));
        Rectangle::new([(0.0, from), (1.0, to)], colour.filled())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bar_runs_from_the_colour_of_its_low_end_to_that_of_its_high_end() {
        crate::plot::register_font().unwrap();
        let (w, h) = (140, 500);
        for (map, bottom, top) in [
            // ColorBrewer's RdBu ends, dark blue and dark red, and its near-white middle.
            (ColourMap::symmetric(0.3), RGBColor(5, 48, 97), RGBColor(103, 0, 31)),
            (ColourMap::magnitude(2.0), RGBColor(247, 247, 247), RGBColor(103, 0, 31)),
        ] {
            let mut buffer = vec![0u8; (w * h * 3) as usize];
            let ends = {
                let root = BitMapBackend::with_buffer(&mut buffer, (w, h)).into_drawing_area();
                root.fill(&WHITE).unwrap();
                let ends = colour_bar(&root, map, "Δσ (S/m)", (20, 40)).unwrap();
                root.present().unwrap();
                ends
            };
            let colour = |(x, y): (i32, i32)| {
                let p = (y as usize * w as usize + x as usize) * 3;
                RGBColor(buffer[p], buffer[p + 1], buffer[p + 2])
            };
            assert_eq!(ends[1].1, 20, "the bar's top is not where it was asked to be");
            assert_eq!((colour(ends[0]), colour(ends[1])), (bottom, top), "{map:?}, ends at {ends:?}");
        }
    }

    #[test]
    fn equal_changes_either_side_of_zero_are_equally_strong() {
        let map = ColourMap::symmetric(0.5);
        // ±0.2 of ±0.5 are RdBu's fourth stops from the middle, light blue and salmon.
        assert_eq!((map.colour(-0.2), map.colour(0.2)), (RGBColor(146, 197, 222), RGBColor(244, 165, 130)));
        assert_eq!((map.colour(0.0), map.colour(9.0)), (RGBColor(247, 247, 247), RGBColor(103, 0, 31)));
        assert_eq!(ColourMap::symmetric(f64::NAN), ColourMap { low: -1.0, high: 1.0 });
    }
}
