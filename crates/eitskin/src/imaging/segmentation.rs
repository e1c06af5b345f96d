//! Which signs of change an image holds objects of, when each sign is judged on its own:
//! against its own peak, against the noise, and against the shadow the other sign casts.
//!
//! The paper's rule thresholds every pixel at a fraction of the frame's strongest change, so in a
//! tank with a strong resistive object a weaker conductive one falls under the threshold and
//! vanishes. Each sign's own peak ([`PeakOf::Sign`]) keeps it, but would also label the
//! reconstruction's own ringing: a one-step image of any object carries a lobe of the other
//! sign beside it (4–15 % of its peak on a 32-electrode tank, largest near the boundary). So:
//!
//! 1. each sign's regions are thresholded at a fraction of that sign's own peak, and tested
//!    against the measured noise (a [`Significance`]: the peak's z must reach its threshold);
//! 2. the weaker sign is kept ([`signs`]) only if its peak exceeds [`SHADOW_MARGIN`] times the
//!    shadow the stronger sign casts: the strongest other-sign change of the image that the
//!    stronger sign's objects alone would give ([`shadow`]). That image is the reconstructor's
//!    own point spread through the linearised model, summed over disks at the stronger sign's
//!    touches (every local maximum at least as strong as the weaker sign's peak: two objects'
//!    ringing adds up), each disk's contrast fitted so that the image matches the touches'
//!    peaks. (A shadow compared region by region was tried: near the boundary the disks' shadow
//!    falls 1.5–2.6 times short of an extended object's there, and ringing was labelled.)
//!
//! ```
//! use eitskin::{segmentation, Reconstructor, ReconstructorParams, SensorSpec};
//! use eitskin::conductivity::{with_inclusions, Inclusion};
//! use eitskin::touch::{self, PeakOf, TouchParams, Polarity, LESS_CONDUCTIVE, MORE_CONDUCTIVE};
//! let mut spec = SensorSpec::square_hydrogel();
//! spec.mesh.triangles = 800;
//! let model = spec.forward_model()?;
//! let params = ReconstructorParams { raster: [32, 32], ..ReconstructorParams::default() };
//! let recon = Reconstructor::new(&model, 1.0, &params)?;
//! let v_ref = model.measure(&vec![1.0; model.mesh().triangles().len()])?;
//! // One less conductive object: the image's ringing of the other sign is not labelled.
//! let object = Inclusion { centre: [0.06, 0.05], radius: 0.02, conductivity: 0.2 };
//! let v = model.measure(&with_inclusions(model.mesh(), 1.0, &[object]))?;
//! let image = recon.image(&v_ref, &v)?;
//! let both = TouchParams { polarity: Polarity::Both, peak_of: PeakOf::Sign, ..TouchParams::default() };
//! let kept = TouchParams { polarity: segmentation::signs(&recon, &image, &both, None)?, ..both };
//! let labels = touch::labels(&image, &kept, None);
//! assert!(labels.contains(&LESS_CONDUCTIVE) && !labels.contains(&MORE_CONDUCTIVE));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use faer::linalg::solvers::Solve;
use faer::Mat;

use crate::image::Image;
use crate::inverse::{InverseError, Reconstructor};
use crate::noise::Significance;
use crate::touch::{self, PeakOf, Polarity, Touch, TouchParams};

/// How far the weaker sign's peak must rise above the stronger sign's predicted shadow
/// (dimensionless). The shadow is predicted from disks in a 2-D model, so it misses some of an
/// extended object's, and more of a real tank's: ringing alone read 0.5–1.9 times the predicted
/// shadow on a simulated 32-electrode tank (objects of one sign, two of one sign; truth on a
/// finer mesh; 0, 0.1 and 0.3 % noise) and 1.9–2.3 times on EIDORS' golf-ball tank (six frames
/// of one or two non-conductive balls in a 3-D tank), while a real object of the other sign
/// read 2.2–6.2 times (or about 1, too weak to tell from ringing at all). 3 labels no ringing
/// seen and keeps the stronger half of those objects.
pub const SHADOW_MARGIN: f64 = 3.0;

/// The signs of `params.polarity` that `image` holds objects of: one sign asked for is that
/// sign; with [`Polarity::Both`], both when the weaker sign's peak (each sign's touches at
/// `params.threshold` of its own peak, tested against `significance`) exceeds
/// [`SHADOW_MARGIN`] times the strongest other-sign change of the stronger sign's [`shadow`],
/// else the stronger sign alone.
pub fn signs(
    recon: &Reconstructor,
    image: &Image,
    params: &TouchParams,
    significance: Option<&Significance>,
) -> Result<Polarity, InverseError> {
    if params.polarity != Polarity::Both {
        return Ok(params.polarity);
    }
    let params = &TouchParams { peak_of: PeakOf::Sign, ..*params };
    let mut touches = Vec::new();
    touch::detect_tested_into(image, params, significance, &mut touch::TouchScratch::new(image.size), &mut touches);
    let Some(strongest) = touches.first() else { return Ok(Polarity::Both) };
    let strong = strongest.polarity;
    let weak = if strong == Polarity::Decrease { Polarity::Increase } else { Polarity::Decrease };
    let weak_peak = touches.iter().filter(|t| t.polarity == weak).map(|t| t.peak).fold(0.0, f64::max);
    if weak_peak <= 0.0 {
        return Ok(strong);
    }
    // The shadow is cast by every object of the stronger sign at least as strong as the weaker
    // sign's peak, not only by the strongest: each local maximum's own touch.
    let own = &TouchParams { polarity: strong, peak_of: PeakOf::Touch, ..*params };
    let mut stronger = Vec::new();
    touch::detect_tested_into(image, own, significance, &mut touch::TouchScratch::new(image.size), &mut stronger);
    stronger.retain(|t| t.peak >= weak_peak);
    let cast = shadow(recon, &stronger)?.map_or(0.0, |shadow| touch::peak_toward(&shadow, weak));
    Ok(if weak_peak > SHADOW_MARGIN * cast { Polarity::Both } else { strong })
}

/// The image that objects in the place of `touches` (all of one sign) alone would give (S/m):
/// each touch stands as a disk of its centre and area, imaged through `recon`'s linearised
/// model (Δv = J·δσ), the disks' contrasts fitted so that the image matches each touch's peak
/// at its peak pixel (a negative contrast taken as none). Its changes of the other sign are the
/// reconstruction's own ringing, the shadow the touches cast. `None` without touches.
pub fn shadow(recon: &Reconstructor, touches: &[Touch]) -> Result<Option<Image>, InverseError> {
    let Some(first) = touches.first() else { return Ok(None) };
    let own = first.polarity;
    let lin = recon.linearisation();
    let (mesh, v0, jacobian) = (lin.mesh(), lin.background(), lin.jacobian());
    // Each disk's Δv; the image being linear in Δv, only the touches' peak pixels are imaged per
    // disk, and the shadow once, of the disks' fitted sum.
    let mut disks = Vec::with_capacity(touches.len());
    for touch in touches {
        let disk = mesh.triangles_near(touch.centre, (touch.area / std::f64::consts::PI).sqrt());
        let sign = own.intensity(1.0);
        let dv: Vec<f64> = (0..v0.len()).map(|m| sign * disk.iter().map(|&t| jacobian[(m, t)]).sum::<f64>()).collect();
        disks.push(dv);
    }
    let template = recon.blank_image();
    let plus = |dv: &[f64], a: f64| -> Vec<f64> { v0.iter().zip(dv).map(|(v, d)| v + a * d).collect() };
    let k = touches.len();
    let mut gain = Mat::zeros(k, k);
    for (i, dv) in disks.iter().enumerate() {
        let v = plus(dv, 1.0);
        for (j, touch) in touches.iter().enumerate() {
            if let Some(pixel) = template.pixel_at(touch.peak_at) {
                gain[(j, i)] = own.intensity(recon.pixel_value(v0, &v, pixel)?);
            }
        }
    }
    let peaks = Mat::from_fn(k, 1, |j, _| touches[j].peak);
    let contrast = gain.partial_piv_lu().solve(&peaks);
    let mut sum = vec![0.0; v0.len()];
    for (i, dv) in disks.iter().enumerate() {
        let a = contrast[(i, 0)];
        if a.is_finite() && a > 0.0 {
            sum.iter_mut().zip(dv).for_each(|(s, d)| *s += a * d);
        }
    }
    recon.image(v0, &plus(&sum, 1.0)).map(Some)
}
