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
//! The frames of a recording, imaged with one raster, are written as a stack by the `_stack`
//! writers: NPY arrays of shape `(frames, ny, nx)`, and CSV files with a first column `frame`
//! (each frame's number in its file, from 1) before the one-frame columns.
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
    let [nx, ny] = image.size;
    write_npy(path, &[ny, nx], raster_values(image))
}

/// Writes images of one raster (a recording's frames) as an NPY `float32` array of shape
/// `(frames, ny, nx)`, each as [`write_raster_npy`] writes one; panics if their sizes differ (a
/// caller contract).
#[track_caller]
pub fn write_raster_stack_npy(path: &Path, images: &[&Image]) -> Result<(), Error> {
    let [nx, ny] = images.first().map_or([0, 0], |image| image.size);
    assert!(images.iter().all(|image| image.size == [nx, ny]), "a stack's images share one raster");
    write_npy(path, &[images.len(), ny, nx], images.iter().flat_map(|image| raster_values(image)))
}

/// Δσ per pixel, NaN outside the sensor.
fn raster_values(image: &Image) -> impl Iterator<Item = f32> + '_ {
    image.values.iter().zip(&image.inside).map(|(&v, &inside)| if inside { v } else { f32::NAN })
}

/// Writes a label image (`labels` row-major from the top row, `size` = `[nx, ny]`) as an NPY
/// `uint8` array of shape `(ny, nx)`; panics if `labels` does not hold nx·ny entries (a caller
/// contract).
#[track_caller]
pub fn write_labels_npy(path: &Path, labels: &[u8], size: [usize; 2]) -> Result<(), Error> {
    write_labels_stack(path, &[labels], size, false)
}

/// Writes label images of one raster (a recording's frames) as an NPY `uint8` array of shape
/// `(frames, ny, nx)`; panics if one does not hold nx·ny labels (a caller contract).
#[track_caller]
pub fn write_labels_stack_npy(path: &Path, labels: &[&[u8]], size: [usize; 2]) -> Result<(), Error> {
    write_labels_stack(path, labels, size, true)
}

#[track_caller]
fn write_labels_stack(path: &Path, labels: &[&[u8]], [nx, ny]: [usize; 2], stacked: bool) -> Result<(), Error> {
    assert!(labels.iter().all(|l| l.len() == nx * ny), "a {:?} label image needs nx·ny labels", [nx, ny]);
    let shape = if stacked { vec![labels.len(), ny, nx] } else { vec![ny, nx] };
    write_npy(path, &shape, labels.iter().flat_map(|l| l.iter().copied()))
}

/// Writes the inside pixels as CSV `x_<unit>,y_<unit>,delta_sigma_s_per_m`, one line per pixel
/// centre, lengths in `unit`, Δσ in S/m.
pub fn write_raster_csv(path: &Path, image: &Image, unit: LengthUnit) -> Result<(), Error> {
    write_pixels_csv(path, image, None, unit, "delta_sigma_s_per_m", |_, i| image.values[i].to_string())
}

/// Writes the inside pixels of each frame's image as CSV
/// `frame,x_<unit>,y_<unit>,delta_sigma_s_per_m` (`frames`: each image with its number in its
/// file); panics if there are none or their rasters differ (a caller contract).
#[track_caller]
pub fn write_raster_stack_csv(path: &Path, frames: &[(usize, &Image)], unit: LengthUnit) -> Result<(), Error> {
    let Some((_, grid)) = frames.first() else { panic!("a stack holds at least one image") };
    assert!(frames.iter().all(|(_, image)| image.size == grid.size), "a stack's images share one raster");
    let numbers: Vec<usize> = frames.iter().map(|(k, _)| *k).collect();
    write_pixels_csv(path, grid, Some(&numbers), unit, "delta_sigma_s_per_m", |k, i| frames[k].1.values[i].to_string())
}

/// Writes the label of each inside pixel of `image` as CSV `x_<unit>,y_<unit>,label` (see
/// [`write_labels_npy`] for the labels), lengths in `unit`.
pub fn write_labels_csv(path: &Path, image: &Image, labels: &[u8], unit: LengthUnit) -> Result<(), Error> {
    assert_eq!(labels.len(), image.values.len(), "one label per pixel");
    write_pixels_csv(path, image, None, unit, "label", |_, i| labels[i].to_string())
}

/// Writes the labels of each frame as CSV `frame,x_<unit>,y_<unit>,label` at the inside pixels
/// of `grid`, the frames' one raster (`frames`: each label image with its frame's number).
#[track_caller]
pub fn write_labels_stack_csv(
    path: &Path,
    grid: &Image,
    frames: &[(usize, &[u8])],
    unit: LengthUnit,
) -> Result<(), Error> {
    assert!(frames.iter().all(|(_, l)| l.len() == grid.values.len()), "one label per pixel");
    let numbers: Vec<usize> = frames.iter().map(|(k, _)| *k).collect();
    write_pixels_csv(path, grid, Some(&numbers), unit, "label", |k, i| frames[k].1[i].to_string())
}

/// One CSV line per inside pixel centre of `grid` (per frame when `frames` numbers them, the
/// frame's number first): x, y in `unit`, then `value(k, pixel)` for the k-th frame.
fn write_pixels_csv(
    path: &Path,
    grid: &Image,
    frames: Option<&[usize]>,
    unit: LengthUnit,
    column: &str,
    value: impl Fn(usize, usize) -> String,
) -> Result<(), Error> {
    let symbol = unit.symbol();
    let mut text = format!("{}x_{symbol},y_{symbol},{column}\n", if frames.is_some() { "frame," } else { "" });
    let [nx, ny] = grid.size;
    let numbers = frames.map_or(vec![None], |f| f.iter().copied().map(Some).collect());
    for (k, number) in numbers.into_iter().enumerate() {
        for row in 0..ny {
            for col in 0..nx {
                let i = row * nx + col;
                if grid.inside[i] {
                    let [x, y] = grid.pixel_centre(col, row);
                    if let Some(number) = number {
                        let _ = write!(text, "{number},");
                    }
                    // Writing to a String cannot fail.
                    let _ = writeln!(text, "{},{},{}", x / unit.metres(), y / unit.metres(), value(k, i));
                }
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
    write_elements(path, mesh, &[(None, values)], unit, value_column)
}

/// Writes each frame's value per triangle as CSV `frame,triangle,x_<unit>,y_<unit>,<value_column>`
/// (`frames`: each frame's values with its number in its file), as [`write_elements_csv`] writes
/// one frame.
#[track_caller]
pub fn write_elements_stack_csv(
    path: &Path,
    mesh: &Mesh,
    frames: &[(usize, &[f64])],
    unit: LengthUnit,
    value_column: &str,
) -> Result<(), Error> {
    let frames: Vec<(Option<usize>, &[f64])> = frames.iter().map(|(k, values)| (Some(*k), *values)).collect();
    write_elements(path, mesh, &frames, unit, value_column)
}

#[track_caller]
fn write_elements(
    path: &Path,
    mesh: &Mesh,
    frames: &[(Option<usize>, &[f64])],
    unit: LengthUnit,
    value_column: &str,
) -> Result<(), Error> {
    let triangles = mesh.triangles().len();
    assert!(frames.iter().all(|(_, v)| v.len() == triangles), "the mesh has {triangles} triangles, one value each");
    let symbol = unit.symbol();
    let stacked = frames.iter().any(|(k, _)| k.is_some());
    let mut text = format!("{}triangle,x_{symbol},y_{symbol},{value_column}\n", if stacked { "frame," } else { "" });
    for (number, values) in frames {
        for (t, value) in values.iter().enumerate() {
            let [x, y] = mesh.centroid(t);
            // Writing to a String cannot fail.
            if let Some(number) = number {
                let _ = write!(text, "{number},");
            }
            let _ = writeln!(text, "{t},{},{},{value}", x / unit.metres(), y / unit.metres());
        }
    }
    std::fs::write(path, text).map_err(|source| Error::Write { path: path.to_path_buf(), source })
}

/// Writes `values` in row-major order as an NPY array of `shape`.
fn write_npy<T: npyz::AutoSerialize>(
    path: &Path,
    shape: &[usize],
    values: impl IntoIterator<Item = T>,
) -> Result<(), Error> {
    let failed = |source| Error::Write { path: path.to_path_buf(), source };
    let shape: Vec<u64> = shape.iter().map(|&n| n as u64).collect();
    let mut bytes = Vec::new();
    let mut writer =
        npyz::WriteOptions::new().default_dtype().shape(&shape).writer(&mut bytes).begin_nd().map_err(failed)?;
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
    fn a_stack_numbers_each_frame_and_stacks_its_arrays() {
        let mut a = Image::new([2, 1], [[0.0, 0.0], [2.0, 1.0]], vec![true, false]);
        let mut b = a.clone();
        (a.values[0], b.values[0]) = (1.5, -2.5);
        let dir = tempfile::tempdir().unwrap();
        let csv = dir.path().join("stack.csv");
        write_raster_stack_csv(&csv, &[(3, &a), (7, &b)], LengthUnit::Metre).unwrap();
        let text = std::fs::read_to_string(&csv).unwrap();
        assert_eq!(text, "frame,x_m,y_m,delta_sigma_s_per_m\n3,0.5,0.5,1.5\n7,0.5,0.5,-2.5\n");
        write_labels_stack_csv(&csv, &a, &[(3, &[1, 0]), (7, &[2, 0])], LengthUnit::Metre).unwrap();
        assert_eq!(std::fs::read_to_string(&csv).unwrap(), "frame,x_m,y_m,label\n3,0.5,0.5,1\n7,0.5,0.5,2\n");
        let npy = dir.path().join("stack.npy");
        write_raster_stack_npy(&npy, &[&a, &b]).unwrap();
        let bytes = std::fs::read(&npy).unwrap();
        let array = npyz::NpyFile::new(bytes.as_slice()).unwrap();
        assert_eq!(array.shape(), &[2, 1, 2]);
        let values: Vec<f32> = array.into_vec().unwrap();
        assert_eq!(values[0], 1.5);
        assert!(values[1].is_nan());
        assert_eq!(values[2], -2.5);
        write_labels_stack_npy(&npy, &[&[1, 0], &[2, 0]], [2, 1]).unwrap();
        let bytes = std::fs::read(&npy).unwrap();
        let array = npyz::NpyFile::new(bytes.as_slice()).unwrap();
        assert_eq!(array.shape(), &[2, 1, 2]);
        assert_eq!(array.into_vec::<u8>().unwrap(), [1, 0, 2, 0]);
    }

    #[test]
    fn a_folder_that_is_not_there_is_a_write_error_naming_the_file() {
        let image = Image::new([1, 1], [[0.0, 0.0], [1.0, 1.0]], vec![true]);
        let path = Path::new("/nonexistent-folder/image.npy");
        let e = write_raster_npy(path, &image).unwrap_err();
        assert!(matches!(&e, Error::Write { path: p, .. } if p == path), "{e}");
    }
}
