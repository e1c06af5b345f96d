//! Location dependence of the reconstructed peak (the paper's Fig. 3): the same circular
//! inclusion placed at many positions, each frame simulated on a finer "truth" model than the
//! reconstructor's, and the peak |Δσ| of each image.
//!
//! The paper (and EIDORS' reference) uses an inclusion of radius 5 % of the side with half
//! the background conductivity, placed along the x axis every 5 % of the side. Not for
//! calibration (that needs forces): this measures the imaging chain's sensitivity alone.

use crate::conductivity::{mixed, with_inclusions, Inclusion};
use crate::forward::{disk_reach, ChangeScratch, ForwardError, ForwardModel, LowRankUpdate, UPDATE_AFTER};
use crate::inverse::{InverseError, Reconstructor};
use crate::mesh::TriangleBuckets;
use crate::touch::{detect_into, Touch, TouchParams, TouchScratch};

/// Frames (V) of one inclusion at a time on a model at a homogeneous background: by a
/// low-rank update of the background's factorisation (the triangles each inclusion covers)
/// where enough are asked for to repay its setup ([`UPDATE_AFTER`]), else each solved in full;
/// the same to rounding either way.
pub struct InclusionFrames<'a> {
    model: &'a ForwardModel,
    background: f64,
    /// The homogeneous frame (V).
    reference: Vec<f64>,
    update: Option<(LowRankUpdate, TriangleBuckets)>,
}

impl<'a> InclusionFrames<'a> {
    /// Frames on `model` at `background` (S/m) for `count` inclusions of at most `radius` (m).
    pub fn new(model: &'a ForwardModel, background: f64, count: usize, radius: f64) -> Result<Self, ForwardError> {
        let sigma = vec![background; model.mesh().triangles().len()];
        let update = if count >= UPDATE_AFTER {
            let reach = disk_reach(model.mesh(), radius);
            Some((LowRankUpdate::with_reach(model, &sigma, reach)?, TriangleBuckets::new(model.mesh())))
        } else {
            None
        };
        let reference = match &update {
            Some((update, _)) => update.background_measurements().to_vec(),
            None => model.measure(&sigma)?,
        };
        Ok(InclusionFrames { model, background, reference, update })
    }

    /// The homogeneous frame (V).
    pub fn reference(&self) -> &[f64] {
        &self.reference
    }

    /// The frame of `inclusion` over the background (V); `scratch` holds the update's buffers.
    pub fn frame(&self, inclusion: &Inclusion, scratch: &mut ChangeScratch) -> Result<Vec<f64>, ForwardError> {
        let Some((update, buckets)) = &self.update else {
            return self.model.measure(&with_inclusions(self.model.mesh(), self.background, &[*inclusion]));
        };
        let mesh = self.model.mesh();
        let ([x, y], r) = (inclusion.centre, inclusion.radius);
        let mut near = Vec::new();
        buckets.near_once_into([x - r, y - r], [x + r, y + r], &mut near);
        let changes: Vec<(usize, f64)> = near
            .into_iter()
            .map(|t| (t, mixed(mesh.corners(t), mesh.area(t), self.background, &[*inclusion]) - self.background))
            .filter(|(_, d)| *d != 0.0)
            .collect();
        update.measurements_with(&changes, scratch)
    }
}

/// Peak |Δσ| (S/m) of the image of each inclusion, simulated on `truth` with the `background`
/// conductivity (S/m) ([`InclusionFrames`]) and reconstructed by `recon` against the homogeneous
/// frame; in parallel.
pub fn peaks(
    truth: &ForwardModel,
    background: f64,
    recon: &Reconstructor,
    inclusions: &[Inclusion],
) -> Result<Vec<f64>, InverseError> {
    use rayon::prelude::*;
    let radius = inclusions.iter().map(|i| i.radius).fold(0.0, f64::max);
    let frames = InclusionFrames::new(truth, background, inclusions.len(), radius)?;
    inclusions
        .par_iter()
        .map_init(
            || (recon.blank_image(), ChangeScratch::default()),
            |(image, change), inc| {
                let v = frames.frame(inc, change)?;
                recon.image_into(frames.reference(), &v, image)?;
                Ok(image.peak().map_or(0.0, |(_, value)| f64::from(value.abs())))
            },
        )
        .collect()
}

/// The strongest touch (paper's method, default [`TouchParams`]) in the image of each
/// inclusion, its frame from `frames`, reconstructed by `recon` against their homogeneous frame;
/// `None` where the image has no touch; in parallel.
pub fn strongest_touches(
    frames: &InclusionFrames<'_>,
    recon: &Reconstructor,
    inclusions: &[Inclusion],
) -> Result<Vec<Option<Touch>>, InverseError> {
    use rayon::prelude::*;
    inclusions
        .par_iter()
        .map_init(
            || (recon.blank_image(), TouchScratch::default(), Vec::new(), ChangeScratch::default()),
            |(image, scratch, touches, change), inc| {
                let v = frames.frame(inc, change)?;
                recon.image_into(frames.reference(), &v, image)?;
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Frames asked for in bulk come through the update, a few by full solves: the same to
    /// rounding, for inclusions crossing triangles, at the edge and over each other's places.
    #[test]
    fn inclusion_frames_are_full_solves() {
        let mut spec = crate::SensorSpec::square_hydrogel();
        spec.mesh.triangles = 600;
        let model = spec.forward_model().unwrap();
        let few = InclusionFrames::new(&model, 1.0, 3, 0.012).unwrap();
        let many = InclusionFrames::new(&model, 1.0, UPDATE_AFTER, 0.012).unwrap();
        assert!(few.update.is_none() && many.update.is_some());
        let mut scratch = ChangeScratch::default();
        for (centre, radius, conductivity) in
            [([0.013, -0.021], 0.01, 0.5), ([0.085, 0.0], 0.012, 0.2), ([-0.04, 0.06], 0.005, 1.7)]
        {
            let inclusion = Inclusion { centre, radius, conductivity };
            let solved = model.measure(&with_inclusions(model.mesh(), 1.0, &[inclusion])).unwrap();
            assert_eq!(few.frame(&inclusion, &mut scratch).unwrap(), solved);
            let updated = many.frame(&inclusion, &mut scratch).unwrap();
            let worst = updated.iter().zip(&solved).map(|(a, b)| ((a - b) / b).abs()).fold(0.0, f64::max);
            assert!(worst < 1e-10, "{centre:?}: {worst:e}");
        }
        let worst = many.reference().iter().zip(few.reference()).map(|(a, b)| ((a - b) / b).abs()).fold(0.0, f64::max);
        assert!(worst < 1e-12, "{worst:e}");
    }
}
