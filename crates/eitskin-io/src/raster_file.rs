//! Images and element values written as data, for numpy, pandas, MATLAB or a spreadsheet.
//!
//! A raster [`Image`] covers the sensor's bounding box with `nx × ny` pixels, row 0 at the top;
//! the centre of the pixel in column `col` and row `row` is
//! x = x_min + (col + ½)·Δx, y = y_max − (row + ½)·Δy, with Δx = (x_max − x_min)/nx and
//! Δy = (y_max − y_min)/ny (the grid of [`eitskin::image`]). Positions are relative to the
//! outline's centre, as everywhere in eitskin.
//!
//! - [`write_raster_npy`]: `float32` of shape `(ny, nx)` (`img[row, col]`, row 0 at the top, as
//!   `matplotlib.pyplot.imshow` draws it), Δσ in S/m, NaN for pixels outside the sensor.
//! - [`write_raster_csv`]: one line per inside pixel, `x_mm,y_mm,delta_sigma_s_per_m` (the
//!   length columns in the caller's [`LengthUnit`]).
//! - [`write_elements_csv`]: one line per triangle of the mesh, `triangle,x_mm,y_mm,VALUE` at the
//!   triangle's centroid; triangles are numbered from 0, as in the mesh file's `elems`.
//! - [`write_labels_npy`]: `uint8` of shape `(ny, nx)`, a label per pixel.
//!
//! ```
//! use eitskin::{Image, LengthUnit};
//! let mut image = Image::new([2, 1], [[-0.01, -0.005], [0.01, 0.005]], vec![true, false]);
//! image.values[0] = -0.25;
//! let dir = tempfile::tempdir()?;
//! let csv = dir.path().join("image.csv");
//! eitskin_io::write_raster_csv(&csv, &image, LengthUnit::Millimetre)?;
//! assert_eq!(std::fs::read_to_string(&csv)?, "x_mm,y_mm,delta_sigma_s_per_m\n-5,0,-0.25\n");
//! eitskin_io::write_raster_npy(&dir.path().join("image.npy"), &image)?; // [[-0.25, NaN]]
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Not for: pictures (the CLI draws PNGs), nor for reading images back into eitskin.

use std::fmt::Write as _;
use std::path::Path;

use eitskin::{Image, LengthUnit, Mesh};
use npyz::WriterBuilder;

use crate::Error;

/// Writes the image as an NPY `float32` array of shape `(ny, nx)`, row 0 at the top, Δσ in S/m,
/// NaN outside the sensor.
pub fn write_raster_npy(path: &Path, image: &Image) -> Result<(), Error> {
    let values = image.values.iter().zip(&image.inside).map(|(&v, &inside)| if inside { v } else { f32::NAN });
    write_npy(path, image.size, values)
}

/// Writes a label image (`labels` row-major from the top row, `size` = `[nx, ny]`) as an NPY
/// `uint8` array of shape `(ny, nx)`; panics if `labels` does not hold nx·ny entries (a caller
/// contract).
#[track_caller]
pub fn write_labels_npy(path: &Path, labels: &[u8], size: [usize; 2]) -> Result<(), Error> {
    assert_eq!(labels.len(), size[0] * size[1], "a {size:?} label image needs nx·ny labels");
    write_npy(path, size, labels.iter().copied())
}

/// Writes the inside pixels as CSV `x_<unit>,y_<unit>,delta_sigma_s_per_m`, one line per pixel
/// centre, lengths in `unit`, Δσ in S/m.
pub fn write_raster_csv(path: &Path, image: &Image, unit: LengthUnit) -> Result<(), Error> {
    write_pixels_csv(path, image, unit, "delta_sigma_s_per_m", |i| image.values[i].to_string())
}

/// Writes the label of each inside pixel of `image` as CSV `x_<unit>,y_<unit>,label` (see
/// [`write_labels_npy`] for the labels), lengths in `unit`.
pub fn write_labels_csv(path: &Path, image: &Image, labels: &[u8], unit: LengthUnit) -> Result<(), Error> {
    assert_eq!(labels.len(), image.values.len(), "one label per pixel");
    write_pixels_csv(path, image, unit, "label", |i| labels[i].to_string())
}

/// One CSV line per inside pixel centre of `image`: x, y in `unit`, then `value(pixel)`.
fn write_pixels_csv(
    path: &Path,
    image: &Image,
    unit: LengthUnit,
    column: &str,
    value: impl Fn(usize) -> String,
) -> Result<(), Error> {
    let symbol = unit.symbol();
    let mut text = format!("x_{symbol},y_{symbol},{column}\n");
    let [nx, ny] = image.size;
    for row in 0..ny {
        for col in 0..nx {
            let i = row * nx + col;
            if image.inside[i] {
                let [x, y] = image.pixel_centre(col, row);
                // Writing to a String cannot fail.
                let _ = writeln!(text, "{},{},{}", x / unit.metres(), y / unit.metres(), value(i));
            }
        }
    }
    std::fs::write(path, text).map_err(|source| Error::Write { path: path.to_path_buf(), source })
}

/// Writes one value per triangle as CSV `triangle,x_<unit>,y_<unit>,<value_column>`, at each
/// triangle's centroid in `unit`; triangles from 0, as in the mesh file. `values` holds one value
/// per triangle (panics otherwise: a caller contract), in the unit `value_column` names.
#[track_caller]
pub fn write_elements_csv(
    path: &Path,
    mesh: &Mesh,
    values: &[f64],
    unit: LengthUnit,
    value_column: &str,
) -> Result<(), Error> {
    let triangles = mesh.triangles().len();
    assert_eq!(values.len(), triangles, "the mesh has {triangles} triangles, one value each");
    let symbol = unit.symbol();
    let mut text = format!("triangle,x_{symbol},y_{symbol},{value_column}\n");
    for (t, value) in values.iter().enumerate() {
        let [x, y] = mesh.centroid(t);
        // Writing to a String cannot fail.
        let _ = writeln!(text, "{t},{},{},{value}", x / unit.metres(), y / unit.metres());
    }
    std::fs::write(path, text).map_err(|source| Error::Write { path: path.to_path_buf(), source })
}

/// Writes `[nx, ny]` values, row-major from the top row, as an NPY array of shape `(ny, nx)`.
fn write_npy<T: npyz::AutoSerialize>(
    path: &Path,
    [nx, ny]: [usize; 2],
    values: impl IntoIterator<Item = T>,
) -> Result<(), Error> {
    let failed = |source| Error::Write { path: path.to_path_buf(), source };
    let mut bytes = Vec::new();
    let mut writer = npyz::WriteOptions::new()
        .default_dtype()
        .shape(&[ny as u64, nx as u64])
        .writer(&mut bytes)
        .begin_nd()
        .map_err(failed)?;
    writer.extend(values).map_err(failed)?;
    writer.finish().map_err(failed)?;
    std::fs::write(path, bytes).map_err(failed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_positions_are_pixel_centres_in_the_callers_unit() {
        // 2 × 2 pixels over [0, 4] × [0, 2] m: centres x ∈ {1, 3}, y ∈ {1.5, 0.5} (row 0 on top).
        let mut image = Image::new([2, 2], [[0.0, 0.0], [4.0, 2.0]], vec![true, true, false, true]);
        image.values = vec![1.0, 2.0, 3.0, 4.0];
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("image.csv");
        write_raster_csv(&path, &image, LengthUnit::Millimetre).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(text, "x_mm,y_mm,delta_sigma_s_per_m\n1000,1500,1\n3000,1500,2\n3000,500,4\n");
    }

    #[test]
    fn a_folder_that_is_not_there_is_a_write_error_naming_the_file() {
        let image = Image::new([1, 1], [[0.0, 0.0], [1.0, 1.0]], vec![true]);
        let path = Path::new("/nonexistent-folder/image.npy");
        let e = write_raster_npy(path, &image).unwrap_err();
        assert!(matches!(&e, Error::Write { path: p, .. } if p == path), "{e}");
    }
}
