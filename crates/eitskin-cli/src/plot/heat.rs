//! Heat maps over the sheet: the conductivity-change image and the sensitivity map, each with a
//! title, axes in the spec's length unit, the outline, the numbered electrodes and a colour bar.

use std::path::Path;

use anyhow::Result;
use eitskin::{Image, SensorSpec, Touch};
use plotters::coord::Shift;
use plotters::prelude::*;

use super::colour::{colour_bar, ColourMap};
use super::sheet::{self, SheetChart, PLOT_INSET};
use super::{png, Drawn, TITLE};

/// Size of a heat-map figure, in pixels.
const SIZE: (u32, u32) = (900, 780);
/// Width of the colour bar's column at the right, in pixels.
const BAR_COLUMN: u32 = 140;
/// Colour of the sheet where there is no value (masked pixels, the map's border).
const NO_VALUE: RGBColor = RGBColor(215, 215, 215);
/// Radius of the ring at a touch's centre, in pixels.
const TOUCH_RING: i32 = 9;

/// Draws a conductivity-change image (Δσ, S/m) over `spec`'s sheet to a PNG: decrease blue,
/// increase red, both scaled to the largest |Δσ|, masked pixels grey, a ring at each touch's centre.
pub fn image_png(image: &Image, touches: &[Touch], spec: &SensorSpec, title: &str, path: &Path) -> Result<()> {
    png(path, SIZE, |root| draw_image(root, image, touches, spec, title))
}

fn draw_image<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    image: &Image,
    touches: &[Touch],
    spec: &SensorSpec,
    title: &str,
) -> Result<()> {
    let map = ColourMap::symmetric(image.peak().map_or(1.0, |(_, v)| f64::from(v.abs())));
    let mut chart = figure(root, spec, title, map, "Δσ (S/m)")?;
    chart.draw_series(pixels(image, map)).drawn()?;
    sheet::draw_outline(&mut chart, &spec.outline)?;
    sheet::draw_electrodes(&mut chart, spec)?;
    let rings = touches.iter().map(|t| Circle::new((t.centre[0], t.centre[1]), TOUCH_RING, BLACK.stroke_width(2)));
    chart.draw_series(rings).drawn()?;
    Ok(())
}

/// Draws values at scattered `centres` (m) over `spec`'s sheet to a PNG, each as a `cell`-sized
/// rectangle (m) shaded from white (0) to red (the largest), the sheet grey where there is none;
/// `(title, colour)` are the figure's title and what the colour shows, with its unit.
pub fn map_png(
    centres: &[[f64; 2]],
    values: &[f64],
    cell: [f64; 2],
    spec: &SensorSpec,
    (title, colour): (&str, &str),
    path: &Path,
) -> Result<()> {
    png(path, SIZE, |root| {
        let map = ColourMap::magnitude(values.iter().fold(0.0, |m, &v| m.max(v)));
        let mut chart = figure(root, spec, title, map, colour)?;
        chart.draw_series([Polygon::new(sheet::ring(&spec.outline), NO_VALUE.filled())]).drawn()?;
        let half = [cell[0] / 2.0, cell[1] / 2.0];
        let cells = centres.iter().zip(values).map(|(c, &v)| {
            Rectangle::new([(c[0] - half[0], c[1] - half[1]), (c[0] + half[0], c[1] + half[1])], map.colour(v).filled())
        });
        chart.draw_series(cells).drawn()?;
        sheet::draw_outline(&mut chart, &spec.outline)?;
        sheet::draw_electrodes(&mut chart, spec)
    })
}

/// A heat map's frame on `root`: the title, axes over the sheet and, at the right, the colour bar
/// for `map` labelled `colour`; returns the axes to draw on.
fn figure<'a, DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    spec: &SensorSpec,
    title: &str,
    map: ColourMap,
    colour: &str,
) -> Result<SheetChart<'a, DB>> {
    let body = root.titled(title, TITLE).drawn()?;
    let (plot, bar) = body.split_horizontally(body.dim_in_pixel().0.saturating_sub(BAR_COLUMN));
    colour_bar(&bar, map, colour, PLOT_INSET)?;
    sheet::axes(&plot, spec)
}

/// Each pixel of `image` as a filled rectangle in m, coloured by `map`; grey where masked or not
/// a number.
fn pixels(image: &Image, map: ColourMap) -> impl Iterator<Item = Rectangle<(f64, f64)>> + '_ {
    let ([nx, ny], [lo, hi]) = (image.size, image.bounds);
    let (dx, dy) = ((hi[0] - lo[0]) / nx as f64, (hi[1] - lo[1]) / ny as f64);
    image.values.iter().zip(&image.inside).enumerate().map(move |(p, (&value, &inside))| {
        let (x, y) = (lo[0] + (p % nx) as f64 * dx, hi[1] - (p / nx) as f64 * dy);
        let colour = if inside && value.is_finite() { map.colour(f64::from(value)) } else { NO_VALUE };
        Rectangle::new([(x, y), (x + dx, y - dy)], colour.filled())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 4 × 4 image over a 200 mm square: one pixel at the top left raised by `high`, one at the
    /// bottom right lowered by `low`, the top-right pixel masked.
    fn small_image(high: f32, low: f32) -> Image {
        let bounds = [[-0.1, -0.1], [0.1, 0.1]];
        let mut inside = vec![true; 16];
        inside[3] = false;
        let mut image = Image::new([4, 4], bounds, inside);
        (image.values[0], image.values[15]) = (high, -low);
        image
    }

    #[test]
    fn the_image_figure_is_a_png_of_the_figure_size() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("image.png");
        image_png(&small_image(0.2, 0.5), &[], &SensorSpec::default(), "Conductivity change", &path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
        let word = |at: usize| u32::from_be_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]);
        assert_eq!((&bytes[12..16], word(16), word(20)), (&b"IHDR"[..], SIZE.0, SIZE.1));
    }

    #[test]
    fn each_pixel_is_drawn_where_the_axes_say_in_the_colour_of_its_value() {
        crate::plot::register_font().unwrap();
        let (w, h) = SIZE;
        let (spec, image) = (SensorSpec::default(), small_image(0.2, 0.5));
        let centres = [(-0.075, 0.075), (0.075, -0.075), (0.075, 0.075), (-0.025, 0.025)];
        let mut buffer = vec![0u8; (w * h * 3) as usize];
        let at: Vec<(i32, i32)> = {
            let root = BitMapBackend::with_buffer(&mut buffer, SIZE).into_drawing_area();
            let chart = figure(&root, &spec, "", ColourMap::symmetric(1.0), "").unwrap();
            centres.iter().map(|p| chart.backend_coord(p)).collect()
        };
        {
            let root = BitMapBackend::with_buffer(&mut buffer, SIZE).into_drawing_area();
            draw_image(&root, &image, &[], &spec, "test").unwrap();
            root.present().unwrap();
        }
        let colour = |(x, y): (i32, i32)| {
            let p = (y as usize * w as usize + x as usize) * 3;
            RGBColor(buffer[p], buffer[p + 1], buffer[p + 2])
        };
        // 0.2 of a peak of 0.5 is RdBu's salmon stop; -0.5 is the peak, its dark blue; 0 its middle.
        let expected = [RGBColor(244, 165, 130), RGBColor(5, 48, 97), NO_VALUE, RGBColor(247, 247, 247)];
        for ((centre, pixel), expected) in centres.iter().zip(at).zip(expected) {
            assert_eq!(colour(pixel), expected, "at {centre:?} m, pixel {pixel:?}");
        }
    }
}
