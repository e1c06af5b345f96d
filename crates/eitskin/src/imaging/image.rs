//! Conductivity-change images: one value Δσ per pixel of a raster over the sensor.
//!
//! A one-step Gauss–Newton reconstruction gives, per frame, the change of conductivity
//! Δσ = σ − σ_ref on each triangle of the mesh; sampling it at the pixel centres of an `nx × ny`
//! grid (64 × 64 by default) over the sensor's bounding box gives an [`Image`]. Pixels whose
//! centre lies outside the sensor outline are masked (`inside = false`, value 0) and ignored by
//! everything that reads an image. A press lowers the local conductivity, so touches are where
//! Δσ is most negative; [`crate::touch`] finds them.
//!
//! Rows are stored from the top (largest y) down, as in a picture, and the pixel centres are
//! x = x_min + (col + ½)·Δx, y = y_max − (row + ½)·Δy with Δx = (x_max − x_min)/nx,
//! Δy = (y_max − y_min)/ny, the same grid as [`crate::mesh::RasterMap`].
//!
//! Not for: absolute conductivity (an image holds changes from a reference frame), nor for
//! display (the one colour map is [`crate::colour`]; figures and file formats live in
//! `eitskin-cli` and `eitskin-io`).

/// A raster image over the sensor's bounding box: one value per pixel, row-major from the top row.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    /// Columns and rows `[nx, ny]`.
    pub size: [usize; 2],
    /// The box covered, `[[x_min, y_min], [x_max, y_max]]`, in m.
    pub bounds: [[f64; 2]; 2],
    /// Conductivity change Δσ per pixel, in S/m; row-major, row 0 at the top (largest y). 0 outside.
    pub values: Vec<f32>,
    /// Whether each pixel centre lies inside the sensor (masked pixels are ignored everywhere).
    pub inside: Vec<bool>,
}

impl Image {
    /// An all-zero image; `inside` has nx·ny entries (panics otherwise: a caller contract).
    #[track_caller]
    pub fn new(size: [usize; 2], bounds: [[f64; 2]; 2], inside: Vec<bool>) -> Image {
        let [nx, ny] = size;
        assert!(
            inside.len() == nx * ny,
            "an image of {nx} × {ny} pixels needs {} mask entries, got {}",
            nx * ny,
            inside.len()
        );
        Image { size, bounds, values: vec![0.0; nx * ny], inside }
    }

    /// Width and height of one pixel `[Δx, Δy]`, in m.
    fn pixel_size(&self) -> [f64; 2] {
        let [lo, hi] = self.bounds;
        [(hi[0] - lo[0]) / self.size[0] as f64, (hi[1] - lo[1]) / self.size[1] as f64]
    }

    /// Centre of the pixel in column `col` and row `row` (row 0 at the top), in m.
    pub fn pixel_centre(&self, col: usize, row: usize) -> [f64; 2] {
        pixel_centre(self.bounds, self.size, col, row)
    }

    /// Area of one pixel, in m².
    pub fn pixel_area(&self) -> f64 {
        let [dx, dy] = self.pixel_size();
        dx * dy
    }

    /// The pixel (row-major index) whose square holds `p` (m), `None` outside the box.
    pub fn pixel_at(&self, p: [f64; 2]) -> Option<usize> {
        let [lo, hi] = self.bounds;
        let [dx, dy] = self.pixel_size();
        let (col, row) = ((p[0] - lo[0]) / dx, (hi[1] - p[1]) / dy);
        let [nx, ny] = self.size;
        let within = col >= 0.0 && row >= 0.0 && (col as usize) < nx && (row as usize) < ny;
        within.then(|| row as usize * nx + col as usize)
    }

    /// The inside pixel with the largest |Δσ| (row-major index) and its signed value in S/m, or
    /// `None` if no pixel is inside; NaN values are skipped, and ties go to the first pixel.
    pub fn peak(&self) -> Option<(usize, f32)> {
        let mut best: Option<(usize, f32)> = None;
        for (i, (&v, &inside)) in self.values.iter().zip(&self.inside).enumerate() {
            if !inside || v.is_nan() {
                continue;
            }
            if best.is_none_or(|(_, b)| v.abs() > b.abs()) {
                best = Some((i, v));
            }
        }
        best
    }
}

/// Centre of pixel (col, row) of an `[nx, ny]` grid over `bounds`, row 0 at the top, in m.
pub(crate) fn pixel_centre([lo, hi]: [[f64; 2]; 2], [nx, ny]: [usize; 2], col: usize, row: usize) -> [f64; 2] {
    let (dx, dy) = ((hi[0] - lo[0]) / nx as f64, (hi[1] - lo[1]) / ny as f64);
    [lo[0] + (col as f64 + 0.5) * dx, hi[1] - (row as f64 + 0.5) * dy]
}

/// Which sign of conductivity change a press makes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Polarity {
    /// A press lowers the conductivity (the default, as in a hydrogel skin).
    #[default]
    Decrease,
    /// A press raises the conductivity.
    Increase,
    /// Either: decreases and increases are both touches, each tagged with its sign.
    Both,
}

impl Polarity {
    /// The change `change` (Δσ, in S/m) in the press direction, in S/m: positive where pressed.
    /// For [`Polarity::Both`], the magnitude |Δσ|.
    pub fn intensity(self, change: f32) -> f64 {
        match self {
            Polarity::Decrease => -f64::from(change),
            Polarity::Increase => f64::from(change),
            Polarity::Both => f64::from(change.abs()),
        }
    }

    /// The one-sign directions this stands for: itself, or decrease then increase for `Both`.
    pub fn signs(self) -> [Option<Polarity>; 2] {
        match self {
            Polarity::Both => [Some(Polarity::Decrease), Some(Polarity::Increase)],
            one => [Some(one), None],
        }
    }

    /// The name in files and flags: `decrease`, `increase` or `both`.
    pub fn name(self) -> &'static str {
        match self {
            Polarity::Decrease => "decrease",
            Polarity::Increase => "increase",
            Polarity::Both => "both",
        }
    }
}

impl std::str::FromStr for Polarity {
    type Err = String;

    /// `decrease`, `increase` or `both`.
    fn from_str(text: &str) -> Result<Polarity, String> {
        [Polarity::Decrease, Polarity::Increase, Polarity::Both]
            .into_iter()
            .find(|p| p.name() == text)
            .ok_or_else(|| format!("\"{text}\" is not a polarity: use decrease, increase or both"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(size: [usize; 2]) -> Image {
        Image::new(size, [[-0.1, 0.0], [0.1, 0.1]], vec![true; size[0] * size[1]])
    }

    #[test]
    fn pixel_centres_tile_the_box_from_the_top_left() {
        let image = square([4, 2]); // pixels 0.05 m wide, 0.05 m high
        let close = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() < 1e-12 && (a[1] - b[1]).abs() < 1e-12;
        assert!(close(image.pixel_centre(0, 0), [-0.075, 0.075]));
        assert!(close(image.pixel_centre(3, 1), [0.075, 0.025]));
        assert!((image.pixel_area() - 0.05 * 0.05).abs() < 1e-15);
        assert_eq!(image.values, vec![0.0; 8]);
    }

    #[test]
    fn peak_is_the_largest_magnitude_inside_with_its_sign() {
        let mut image = square([3, 3]);
        image.values = vec![0.1, -0.4, 0.2, 0.0, 0.3, f32::NAN, -9.0, 0.0, 0.0];
        image.inside[6] = false; // the -9 is masked
        assert_eq!(image.peak(), Some((1, -0.4)));
        image.inside = vec![false; 9];
        assert_eq!(image.peak(), None);
    }

    #[test]
    #[should_panic(expected = "needs 6 mask entries, got 5")]
    fn new_rejects_a_mask_of_the_wrong_length() {
        let _ = Image::new([3, 2], [[0.0, 0.0], [1.0, 1.0]], vec![true; 5]);
    }
}
