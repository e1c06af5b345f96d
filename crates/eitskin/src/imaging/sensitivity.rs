//! Location dependence of the reconstructed peak (the paper's Fig. 3): the same circular
//! inclusion placed at many positions, each frame simulated on a finer "truth" model than the
//! reconstructor's, and the peak |Δσ| of each image.
//!
//! The paper (and EIDORS' reference) uses an inclusion of radius 5 % of the side with half
//! the background conductivity, placed along the x axis every 5 % of the side. Not for
//! calibration (that needs forces): this measures the imaging chain's sensitivity alone.

use crate::conductivity::{with_inclusions, Inclusion};
use crate::forward::ForwardModel;
use crate::inverse::{InverseError, Reconstructor};
use crate::touch::{detect_into, Touch, TouchParams, TouchScratch};

/// Peak |Δσ| (S/m) of the image of each inclusion, simulated on `truth` with the `background`
/// conductivity (S/m) and reconstructed by `recon` against the homogeneous frame; in parallel.
pub fn peaks(
    truth: &ForwardModel,
    background: f64,
    recon: &Reconstructor,
    inclusions: &[Inclusion],
) -> Result<Vec<f64>, InverseError> {
    use rayon::prelude::*;
    let v_ref = truth.measure(&vec![background; truth.mesh().triangles().len()])?;
    inclusions
        .par_iter()
        .map_init(
            || recon.blank_image(),
            |image, inc| {
                let v = truth.measure(&with_inclusions(truth.mesh(), background, &[*inc]))?;
                recon.image_into(&v_ref, &v, image)?;
                Ok(image.peak().map_or(0.0, |(_, value)| f64::from(value.abs())))
            },
        )
        .collect()
}

/// The strongest touch (paper's method, default [`TouchParams`]) in the image of each
/// inclusion, simulated on `truth` with the `background` conductivity (S/m) and reconstructed by
/// `recon` against the homogeneous frame; `None` where the image has no touch; in parallel.
pub fn strongest_touches(
    truth: &ForwardModel,
    background: f64,
    recon: &Reconstructor,
    inclusions: &[Inclusion],
) -> Result<Vec<Option<Touch>>, InverseError> {
    use rayon::prelude::*;
    let v_ref = truth.measure(&vec![background; truth.mesh().triangles().len()])?;
    inclusions
        .par_iter()
        .map_init(
            || (recon.blank_image(), TouchScratch::default(), Vec::new()),
            |(image, scratch, touches), inc| {
                let v = truth.measure(&with_inclusions(truth.mesh(), background, &[*inc]))?;
                recon.image_into(&v_ref, &v, image)?;
                detect_into(image, &TouchParams::default(), scratch, touches);
                Ok(touches.first().copied())
            },
        )
        .collect()
}

/// The paper's inclusions along the x axis: radius `radius` (m), conductivity `conductivity`
/// (S/m), centres at x = k·`step` (m) for every k that keeps the disk `margin` (m) inside
/// the half-width `half_width` (m), from left to right.
pub fn along_x(half_width: f64, step: f64, radius: f64, conductivity: f64, margin: f64) -> Vec<Inclusion> {
    let n = ((half_width - radius - margin) / step + 1e-9).floor() as i64;
    (-n..=n).map(|k| Inclusion { centre: [k as f64 * step, 0.0], radius, conductivity }).collect()
}
