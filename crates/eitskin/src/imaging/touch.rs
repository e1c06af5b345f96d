//! Touches: the pressed regions of a conductivity-change image, with their centres and peaks.
//!
//! A press lowers the local conductivity, so a touch shows in an [`Image`] as a dip of Δσ. The
//! paper's extraction (its Fig. 2) is followed step by step:
//!
//! 1. intensity of each inside pixel in the press direction, s = −Δσ (or +Δσ, see [`Polarity`]),
//!    and the peak P = max s; no touch if P ≤ 0 or P < `min_peak`;
//! 2. keep the pixels with s ≥ 0.6·P (the `threshold`);
//! 3. label the connected components of the kept pixels (8-connectivity: a pixel touches its
//!    8 neighbours, so a diagonal chain is one region);
//! 4. per component, the centre of gravity c = Σ sᵢ·xᵢ / Σ sᵢ and the peak max sᵢ.
//!
//! Touches come strongest first. [`detect`] is the easy form; [`detect_into`] writes into
//! buffers the caller owns and allocates nothing once they have grown, for the per-frame path.
//!
//! Past the paper: [`PeakOf::Touch`] takes each touch's threshold from its own peak (a weak press
//! beside a strong one is kept), and [`detect_tested_into`] keeps only the touches whose peak
//! passes the noise test of a [`Significance`] (a stated false-alarm rate), each with its z.
//!
//! ```
//! use eitskin::{image::Image, touch::{self, TouchParams}};
//! let mut image = Image::new([32, 32], [[0.0, 0.0], [0.2, 0.2]], vec![true; 32 * 32]);
//! for row in 0..32 {
//!     for col in 0..32 {
//!         let [x, y] = image.pixel_centre(col, row);
//!         let r2 = (x - 0.05).powi(2) + (y - 0.15).powi(2); // a press at (50 mm, 150 mm)
//!         image.values[row * 32 + col] = (-0.3 * (-r2 / (2.0 * 0.012_f64.powi(2))).exp()) as f32;
//!     }
//! }
//! let touches = touch::detect(&image, &TouchParams::default());
//! assert_eq!(touches.len(), 1);
//! assert!((touches[0].centre[0] - 0.05).abs() < 1e-3 && (touches[0].centre[1] - 0.15).abs() < 1e-3);
//! ```
//!
//! Not for: locating the unit of a pseudo-array sensor that a touch falls on (that is
//! [`PseudoArray::unit_at`](crate::pseudo_array::PseudoArray::unit_at), from the touch's centre),
//! nor for force (that is the calibration's job, from a [`Touch`]).

use crate::image::Image;
pub use crate::image::Polarity;
use crate::noise::Significance;

/// What a touch's threshold is a fraction of.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PeakOf {
    /// The strongest change in the frame (the paper's rule): a press much weaker than the
    /// strongest one is lost under its threshold.
    #[default]
    Frame,
    /// Each touch's own peak: every local maximum that passes the noise test (or `min_peak`)
    /// starts a touch, grown downhill from it to the threshold of its own peak, so a weak press
    /// is found next to a strong one and two presses with a dip between them stay apart.
    Touch,
    /// Each sign's own peak: with [`Polarity::Both`], decreases are thresholded against the
    /// strongest decrease and increases against the strongest increase, so a weaker object of
    /// the other sign is kept (and so is the other sign's ringing: see
    /// [`segmentation`](crate::segmentation)); with one sign, the same as [`PeakOf::Frame`].
    Sign,
}

impl PeakOf {
    /// The name in files and flags: `frame` or `touch`.
    pub fn name(self) -> &'static str {
        match self {
            PeakOf::Frame => "frame",
            PeakOf::Touch => "touch",
            PeakOf::Sign => "sign",
        }
    }
}

impl std::str::FromStr for PeakOf {
    type Err = String;

    /// `frame`, `touch` or `sign`.
    fn from_str(text: &str) -> Result<PeakOf, String> {
        [PeakOf::Frame, PeakOf::Touch, PeakOf::Sign]
            .into_iter()
            .find(|p| p.name() == text)
            .ok_or_else(|| format!("\"{text}\" is not whose peak a threshold is of: use frame, touch or sign"))
    }
}

/// How touches are found; `Default` gives the paper's method.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TouchParams {
    /// Keep pixels at or above this fraction of the peak, dimensionless in (0, 1] (0.6 in the paper).
    pub threshold: f64,
    /// Peak change below which there is no touch (noise floor), in S/m, ≥ 0; default 0.
    pub min_peak: f64,
    /// Intensity-weighted centre of gravity (true, default) or the plain centroid of the pixels.
    pub weighted: bool,
    /// The sign of change a press makes.
    pub polarity: Polarity,
    /// Whose peak the threshold is a fraction of.
    pub peak_of: PeakOf,
}

impl Default for TouchParams {
    fn default() -> TouchParams {
        TouchParams {
            threshold: 0.6,
            min_peak: 0.0,
            weighted: true,
            polarity: Polarity::Decrease,
            peak_of: PeakOf::Frame,
        }
    }
}

/// One touch: a connected region of the thresholded image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Touch {
    /// The sign of the change: [`Polarity::Decrease`] (less conductive) or [`Polarity::Increase`].
    pub polarity: Polarity,
    /// Centre of gravity of the region, in m.
    pub centre: [f64; 2],
    /// Strongest change in the press direction inside the region, a positive number in S/m.
    pub peak: f64,
    /// Centre of the pixel where that peak is, in m.
    pub peak_at: [f64; 2],
    /// Area of the region, in m².
    pub area: f64,
    /// The change in the press direction summed over the region times the pixel area, in
    /// S/m·m²: a less noisy measure of strength than the peak.
    pub volume: f64,
    /// Number of pixels in the region.
    pub pixels: usize,
    /// Bounding box of the region's pixel centres, `[[x_min, y_min], [x_max, y_max]]`, in m.
    pub bounding_box: [[f64; 2]; 2],
    /// The peak over the noise's standard deviation at its pixel (a z-score, dimensionless),
    /// when touches were tested against a measured noise ([`Significance`]).
    pub significance: Option<f64>,
}

/// Reusable buffers for [`detect_into`], so that it allocates nothing once they have grown.
#[derive(Debug, Clone, Default)]
pub struct TouchScratch {
    /// Per pixel: 0, or 1 + the index of the region that holds it.
    claim: Vec<u32>,
    /// Row-major indices of the pixels waiting to be visited by the flood fill.
    stack: Vec<usize>,
    /// Local maxima that may start a touch: (intensity, pixel).
    seeds: Vec<(f32, usize)>,
    /// The regions found, in the order they were grown.
    regions: Vec<Region>,
}

impl TouchScratch {
    /// Buffers for images of `[nx, ny]` pixels (`Default` gives empty ones that grow on first use).
    pub fn new([nx, ny]: [usize; 2]) -> TouchScratch {
        let n = nx * ny;
        TouchScratch {
            claim: Vec::with_capacity(n),
            stack: Vec::with_capacity(n),
            seeds: Vec::with_capacity(n),
            regions: Vec::with_capacity(n),
        }
    }
}

/// The touches of `image`, strongest first.
///
/// Allocates its buffers on every call; per frame, use [`detect_into`].
#[track_caller]
pub fn detect(image: &Image, params: &TouchParams) -> Vec<Touch> {
    let mut touches = Vec::new();
    detect_into(image, params, &mut TouchScratch::new(image.size), &mut touches);
    touches
}

/// The touches of `image`, strongest first, into `touches` (cleared first); allocates nothing
/// once `scratch` has seen an image this size and `touches` has room for as many touches.
///
/// Panics if `image.values` or `image.inside` does not have nx·ny entries (a caller contract).
#[track_caller]
pub fn detect_into(image: &Image, params: &TouchParams, scratch: &mut TouchScratch, touches: &mut Vec<Touch>) {
    detect_tested_into(image, params, None, scratch, touches);
}

/// [`detect_into`], with each touch tested against the noise: a touch's peak must reach the
/// `significance` threshold (z, for its false-alarm rate) at its pixel, and carries its z.
///
/// Panics if `image.values`, `image.inside` or the significance map does not have nx·ny entries.
#[track_caller]
pub fn detect_tested_into(
    image: &Image,
    params: &TouchParams,
    significance: Option<&Significance>,
    scratch: &mut TouchScratch,
    touches: &mut Vec<Touch>,
) {
    let [nx, ny] = image.size;
    let n = nx * ny;
    assert!(
        image.values.len() == n && image.inside.len() == n,
        "an image of {nx} × {ny} pixels needs {n} values and mask entries, got {} and {}",
        image.values.len(),
        image.inside.len()
    );
    if let Some(significance) = significance {
        assert_eq!(significance.inverse_std().len(), n, "a significance map for this raster");
    }
    touches.clear();
    scratch.regions.clear();
    scratch.stack.clear();
    // A touch's z is its peak pixel's, so where no pixel reaches the threshold there is no
    // touch: one pass (the same z as the regions' test) spares an untouched frame the flood
    // fill of its noise blobs.
    if let Some(significance) = significance {
        // Lowered by more than f32's rounding of z: the exact test is the regions'.
        if significance.strongest(&image.values, params.polarity) < significance.threshold() * (1.0 - 1e-5) {
            return;
        }
    }
    scratch.claim.clear();
    scratch.claim.resize(n, 0);
    scratch.stack.reserve(n); // each pixel is pushed at most once, so the stack never grows past n
    match params.peak_of {
        PeakOf::Frame => {
            // The peak over the inside pixels in each press direction asked for; with both,
            // the threshold is a fraction of the larger, so a weak opposite change is not a touch.
            let signs = params.polarity.signs().into_iter().flatten();
            let peak = signs.map(|p| peak_toward(image, p)).fold(0.0, f64::max);
            if peak <= 0.0 || peak < params.min_peak {
                return;
            }
            for polarity in params.polarity.signs().into_iter().flatten() {
                frame_regions(image, params, polarity, peak, scratch);
            }
        }
        PeakOf::Touch => {
            for polarity in params.polarity.signs().into_iter().flatten() {
                own_peak_regions(image, params, polarity, significance, scratch);
            }
        }
        PeakOf::Sign => {
            for polarity in params.polarity.signs().into_iter().flatten() {
                let peak = peak_toward(image, polarity);
                if peak > 0.0 && peak >= params.min_peak {
                    frame_regions(image, params, polarity, peak, scratch);
                }
            }
        }
    }
    let pixel_area = image.pixel_area();
    for region in scratch.regions.iter().filter(|r| r.merged_into.is_none()) {
        let z = significance.map(|s| (s.z(region.peak_index, region.peak), s.threshold()));
        if z.is_some_and(|(z, threshold)| z < threshold) {
            continue;
        }
        touches.push(region.touch(pixel_area, z.map(|(z, _)| z)));
    }

    // Strongest first; equal peaks by the peak's position (top to bottom, left to right), so
    // the order never depends on the sort.
    touches.sort_unstable_by(|a, b| {
        b.peak
            .total_cmp(&a.peak)
            .then(b.peak_at[1].total_cmp(&a.peak_at[1]))
            .then(a.peak_at[0].total_cmp(&b.peak_at[0]))
    });
}

/// Label of a background pixel in [`labels`].
pub const BACKGROUND: u8 = 0;
/// Label of a less conductive pixel (a decrease) in [`labels`].
pub const LESS_CONDUCTIVE: u8 = 1;
/// Label of a more conductive pixel (an increase) in [`labels`].
pub const MORE_CONDUCTIVE: u8 = 2;

/// A label per pixel, row-major from the top: [`LESS_CONDUCTIVE`] or [`MORE_CONDUCTIVE`] where
/// the pixel belongs to a touch of that sign, else [`BACKGROUND`] (masked pixels included).
///
/// The rule is the touches' own, untuned: exactly the pixels of the touches
/// [`detect_tested_into`] finds (with `significance`, those whose peak passes the noise test).
pub fn labels(image: &Image, params: &TouchParams, significance: Option<&Significance>) -> Vec<u8> {
    let mut scratch = TouchScratch::new(image.size);
    detect_tested_into(image, params, significance, &mut scratch, &mut Vec::new());
    let regions = &scratch.regions;
    let label = |k: usize| {
        let region = &regions[k];
        if significance.is_some_and(|s| s.z(region.peak_index, region.peak) < s.threshold()) {
            return BACKGROUND;
        }
        match region.polarity {
            Polarity::Increase => MORE_CONDUCTIVE,
            _ => LESS_CONDUCTIVE,
        }
    };
    let mut labels = vec![BACKGROUND; image.values.len()];
    for (pixel, &c) in labels.iter_mut().zip(&scratch.claim) {
        if let Some(mut k) = (c as usize).checked_sub(1) {
            while let Some(root) = regions[k].merged_into {
                k = root;
            }
            *pixel = label(k);
        }
    }
    labels
}

/// The largest change toward `polarity` over the inside pixels, at least 0, in S/m.
pub(crate) fn peak_toward(image: &Image, polarity: Polarity) -> f64 {
    // The press direction as a sign, so the pass stays in f32 and vectorises. Eight
    // independent running maxima, so the comparisons do not wait on each other; NaN never
    // wins a comparison.
    let sign = polarity.intensity(1.0) as f32;
    let mut lanes = [0.0_f32; 8];
    let values = image.values.chunks_exact(8).zip(image.inside.chunks_exact(8));
    for (v, inside) in values {
        for k in 0..8 {
            let x = if inside[k] { sign * v[k] } else { 0.0 };
            if x > lanes[k] {
                lanes[k] = x;
            }
        }
    }
    let tail = image.values.len() - image.values.len() % 8;
    for (&v, &inside) in image.values[tail..].iter().zip(&image.inside[tail..]) {
        if inside && sign * v > lanes[0] {
            lanes[0] = sign * v;
        }
    }
    f64::from(lanes.iter().fold(0.0_f32, |m, &x| if x > m { x } else { m }))
}

/// The 8 neighbours of pixel `i` (fewer at the edges) in an image `nx` wide and `ny` high, in
/// row-major order: a fixed array and how many of it are neighbours (no iterator chain in the
/// flood fill's inner loop).
fn neighbours(i: usize, nx: usize, ny: usize) -> ([usize; 8], usize) {
    let (col, row) = (i % nx, i / nx);
    let mut list = [0; 8];
    let mut count = 0;
    for r in row.saturating_sub(1)..=(row + 1).min(ny - 1) {
        for c in col.saturating_sub(1)..=(col + 1).min(nx - 1) {
            let j = r * nx + c;
            if j != i {
                list[count] = j;
                count += 1;
            }
        }
    }
    (list, count)
}

/// The paper's steps 2–4 for one press direction: the regions at or above `threshold × peak`
/// (`peak` the frame's), added to the scratch's regions.
fn frame_regions(image: &Image, params: &TouchParams, polarity: Polarity, peak: f64, scratch: &mut TouchScratch) {
    let [nx, ny] = image.size;
    let sign = polarity.intensity(1.0) as f32;
    // 2. Keep the pixels at or above the threshold; a pixel with no change is never kept, so
    //    every kept weight is positive whatever the threshold.
    let cutoff = (params.threshold * peak) as f32;
    let kept = |i: usize| image.inside[i] & (sign * image.values[i] >= cutoff) & (sign * image.values[i] > 0.0);
    // 3. Flood-fill each region from its first pixel in row-major order, with an explicit stack.
    //    Runs of pixels none of which is kept (most of a frame) are passed over by one
    //    branch-free test each, which the compiler vectorises.
    let n = nx * ny;
    let any_kept = |start: usize| {
        let end = (start + RUN).min(n);
        let (values, inside) = (&image.values[start..end], &image.inside[start..end]);
        values.iter().zip(inside).fold(false, |any, (v, i)| any | (*i & (sign * v >= cutoff) & (sign * v > 0.0)))
    };
    for seed in (0..n).step_by(RUN).filter(|&start| any_kept(start)).flat_map(|start| start..(start + RUN).min(n)) {
        if scratch.claim[seed] != 0 || !kept(seed) {
            continue;
        }
        let label = scratch.regions.len() as u32 + 1;
        let mut region = Region::new(polarity);
        scratch.claim[seed] = label;
        scratch.stack.push(seed);
        while let Some(i) = scratch.stack.pop() {
            let (col, row) = (i % nx, i / nx);
            region.add(i, image.pixel_centre(col, row), polarity.intensity(image.values[i]), params.weighted);
            let (list, count) = neighbours(i, nx, ny);
            for &j in &list[..count] {
                if scratch.claim[j] == 0 && kept(j) {
                    scratch.claim[j] = label;
                    scratch.stack.push(j);
                }
            }
        }
        // 4. Centre of gravity and peak of the region.
        scratch.regions.push(region);
    }
}

/// Pixels per run of the seed scan.
const RUN: usize = 32;

/// The dip, as a fraction of a touch's own peak, that keeps it apart from a stronger touch it
/// meets; where the noise is known the dip must also be [`SEPARATION_Z`] standard deviations.
pub const SEPARATION: f64 = 0.1;
/// The dip, in standard deviations of the noise at a touch's peak, that keeps it apart.
pub const SEPARATION_Z: f64 = 2.0;

/// Touches by their own peaks for one press direction, added to the scratch's regions.
///
/// Seeds are the local maxima (a pixel at least as strong as its 8 neighbours, ties to the
/// first in row-major order) that reach `min_peak` and, with a significance, its threshold.
/// From the strongest seed down, each grows downhill (to neighbours no stronger than the pixel
/// it comes from) over pixels at or above `threshold` × its own peak not yet taken. A touch that
/// meets a stronger one at a saddle less than [`SEPARATION`] of its peak (and [`SEPARATION_Z`]
/// σ) below its peak is a shoulder of that one, and joins it.
fn own_peak_regions(
    image: &Image,
    params: &TouchParams,
    polarity: Polarity,
    significance: Option<&Significance>,
    scratch: &mut TouchScratch,
) {
    let [nx, ny] = image.size;
    let sign = polarity.intensity(1.0) as f32;
    let s = |i: usize| if image.inside[i] { sign * image.values[i] } else { f32::NEG_INFINITY };
    scratch.seeds.clear();
    candidates(image, sign, params.min_peak, significance, |i| {
        let si = s(i);
        let strong = si > 0.0 && f64::from(si) >= params.min_peak;
        if !strong || scratch.claim[i] != 0 || significance.is_some_and(|z| z.z(i, f64::from(si)) < z.threshold()) {
            return;
        }
        let (list, count) = neighbours(i, nx, ny);
        if list[..count].iter().all(|&j| s(j) < si || (s(j) == si && j > i)) {
            scratch.seeds.push((si, i));
        }
    });
    scratch.seeds.sort_unstable_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    for k in 0..scratch.seeds.len() {
        let (peak, seed) = scratch.seeds[k];
        if scratch.claim[seed] != 0 {
            continue;
        }
        let index = scratch.regions.len();
        let label = index as u32 + 1;
        let cutoff = (params.threshold * f64::from(peak)) as f32;
        let mut region = Region::new(polarity);
        // The highest saddle where this touch meets an earlier one: (height, that region).
        let mut saddle: Option<(f32, usize)> = None;
        scratch.claim[seed] = label;
        scratch.stack.push(seed);
        while let Some(i) = scratch.stack.pop() {
            let (col, row) = (i % nx, i / nx);
            let si = s(i);
            region.add(i, image.pixel_centre(col, row), f64::from(si), params.weighted);
            let (list, count) = neighbours(i, nx, ny);
            for &j in &list[..count] {
                let (sj, claim) = (s(j), scratch.claim[j]);
                if !(sj >= cutoff && sj > 0.0) || claim == label {
                    continue;
                }
                if claim != 0 {
                    let height = si.min(sj);
                    if saddle.is_none_or(|(h, _)| height > h) {
                        saddle = Some((height, claim as usize - 1));
                    }
                } else if sj <= si {
                    scratch.claim[j] = label;
                    scratch.stack.push(j);
                }
            }
        }
        if let Some((height, other)) = saddle {
            let dip = f64::from(peak - height);
            let noise = significance.map_or(0.0, |z| SEPARATION_Z / f64::from(z.inverse_std()[seed]).max(1e-30));
            if dip < (SEPARATION * f64::from(peak)).max(noise) {
                let mut root = other;
                while let Some(next) = scratch.regions[root].merged_into {
                    root = next;
                }
                scratch.regions[root].absorb(&region);
                region.merged_into = Some(root);
            }
        }
        scratch.regions.push(region);
    }
}

/// Calls `seed(i)` for each inside pixel i whose change toward `sign` (±1) is positive and,
/// to within f32 rounding, at least `min_peak` (S/m) and at the significance map's threshold of
/// z: a superset of the pixels that may start a touch, for the exact test. Sixteen pixels a
/// step, so that the pass over an image vectorises and only the few candidates branch.
fn candidates(
    image: &Image,
    sign: f32,
    min_peak: f64,
    significance: Option<&Significance>,
    mut seed: impl FnMut(usize),
) {
    const LANES: usize = 16;
    // Lowered by more than f32's rounding, so that no pixel the exact test keeps is missed.
    let slack = 1.0 - 1e-5;
    let floor = (min_peak * slack) as f32;
    let (threshold, inverse) = match significance {
        Some(z) => ((z.threshold() * slack) as f32, Some(z.inverse_std())),
        None => (f32::NEG_INFINITY, None),
    };
    let n = image.values.len();
    let mut first = 0;
    while first < n {
        let count = (n - first).min(LANES);
        let mut mask = 0u32;
        for k in 0..count {
            let i = first + k;
            let x = sign * image.values[i];
            let z = inverse.map_or(f32::INFINITY, |w| x * w[i]);
            let keep = image.inside[i] && x > 0.0 && x >= floor && z >= threshold;
            mask |= u32::from(keep) << k;
        }
        while mask != 0 {
            seed(first + mask.trailing_zeros() as usize);
            mask &= mask - 1;
        }
        first += count;
    }
}

/// Running sums over the pixels of one region.
#[derive(Debug, Clone, Copy)]
struct Region {
    polarity: Polarity,
    weight: f64,
    intensity: f64,
    moment: [f64; 2],
    pixels: usize,
    peak: f64,
    peak_index: usize,
    peak_at: [f64; 2],
    lo: [f64; 2],
    hi: [f64; 2],
    /// The region it joined, as a shoulder of it.
    merged_into: Option<usize>,
}

impl Region {
    fn new(polarity: Polarity) -> Region {
        Region {
            polarity,
            weight: 0.0,
            intensity: 0.0,
            moment: [0.0; 2],
            pixels: 0,
            peak: f64::NEG_INFINITY,
            peak_index: usize::MAX,
            peak_at: [0.0; 2],
            lo: [f64::INFINITY; 2],
            hi: [f64::NEG_INFINITY; 2],
            merged_into: None,
        }
    }

    /// Adds pixel `index` at `p` (m) with intensity `s` (S/m, positive).
    fn add(&mut self, index: usize, p: [f64; 2], s: f64, weighted: bool) {
        let w = if weighted { s } else { 1.0 };
        self.weight += w;
        self.intensity += s;
        self.moment[0] += w * p[0];
        self.moment[1] += w * p[1];
        self.pixels += 1;
        // Equal peaks go to the first pixel in row-major order, not to the flood-fill order.
        if s > self.peak || (s == self.peak && index < self.peak_index) {
            self.peak = s;
            self.peak_index = index;
            self.peak_at = p;
        }
        self.lo = [self.lo[0].min(p[0]), self.lo[1].min(p[1])];
        self.hi = [self.hi[0].max(p[0]), self.hi[1].max(p[1])];
    }

    /// Takes in the pixels of `other` (a shoulder of this region).
    fn absorb(&mut self, other: &Region) {
        self.weight += other.weight;
        self.intensity += other.intensity;
        self.moment = [self.moment[0] + other.moment[0], self.moment[1] + other.moment[1]];
        self.pixels += other.pixels;
        if other.peak > self.peak {
            (self.peak, self.peak_index, self.peak_at) = (other.peak, other.peak_index, other.peak_at);
        }
        self.lo = [self.lo[0].min(other.lo[0]), self.lo[1].min(other.lo[1])];
        self.hi = [self.hi[0].max(other.hi[0]), self.hi[1].max(other.hi[1])];
    }

    /// The touch this region makes, with pixels of `pixel_area` m² and the peak's z.
    fn touch(&self, pixel_area: f64, significance: Option<f64>) -> Touch {
        Touch {
            polarity: self.polarity,
            centre: [self.moment[0] / self.weight, self.moment[1] / self.weight],
            peak: self.peak,
            peak_at: self.peak_at,
            area: self.pixels as f64 * pixel_area,
            volume: self.intensity * pixel_area,
            pixels: self.pixels,
            bounding_box: [self.lo, self.hi],
            significance,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 64 × 64 image over a 200 mm square, masked to the inscribed disk (3.125 mm pixels).
    fn disk() -> Image {
        let (n, radius) = (64, 0.1);
        let mut image = Image::new([n, n], [[-radius, -radius], [radius, radius]], vec![false; n * n]);
        for row in 0..n {
            for col in 0..n {
                let [x, y] = image.pixel_centre(col, row);
                image.inside[row * n + col] = x * x + y * y <= radius * radius;
            }
        }
        image
    }

    const PIXEL: f64 = 0.2 / 64.0;

    /// Adds a Gaussian change `depth·exp(−r²/2σ²)` (S/m) at `centre` (m) to the inside pixels.
    fn add_gaussian(image: &mut Image, centre: [f64; 2], sigma: f64, depth: f64) {
        let [nx, ny] = image.size;
        for row in 0..ny {
            for col in 0..nx {
                let i = row * nx + col;
                if image.inside[i] {
                    let [x, y] = image.pixel_centre(col, row);
                    let r2 = (x - centre[0]).powi(2) + (y - centre[1]).powi(2);
                    image.values[i] += (depth * (-r2 / (2.0 * sigma * sigma)).exp()) as f32;
                }
            }
        }
    }

    fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
        (a[0] - b[0]).hypot(a[1] - b[1])
    }

    /// With both polarities a dip and a bump are each a touch, tagged with their sign, and a
    /// weak opposite change under the threshold of the stronger one is not.
    #[test]
    fn either_sign_is_a_touch_with_both_polarities() {
        let (dip, bump) = ([-0.04, 0.0], [0.04, 0.01]);
        let mut image = disk();
        add_gaussian(&mut image, dip, 0.01, -1.0);
        add_gaussian(&mut image, bump, 0.01, 0.8);
        let both = TouchParams { polarity: Polarity::Both, ..TouchParams::default() };
        let touches = detect(&image, &both);
        assert_eq!(touches.len(), 2, "{touches:?}");
        assert_eq!((touches[0].polarity, touches[1].polarity), (Polarity::Decrease, Polarity::Increase));
        assert!(distance(touches[0].centre, dip) < PIXEL && distance(touches[1].centre, bump) < PIXEL);
        let increase = detect(&image, &TouchParams { polarity: Polarity::Increase, ..TouchParams::default() });
        assert_eq!(increase.len(), 1);
        assert_eq!(increase[0].polarity, Polarity::Increase);
        add_gaussian(&mut image, bump, 0.01, -0.5); // now only 0.3 S/m: under 60 % of the dip
        assert_eq!(detect(&image, &both).len(), 1);
        let labelled = labels(&image, &both, None);
        let count = |l| labelled.iter().filter(|&&x| x == l).count();
        let pixels: usize = detect(&image, &both).iter().map(|t| t.pixels).sum();
        assert_eq!(count(LESS_CONDUCTIVE), pixels, "the labels are the touches' pixels");
        assert_eq!(count(MORE_CONDUCTIVE), 0);
        // Against each sign's own peak the weak bump is kept, with the pixels over 60 % of it.
        let per_sign = TouchParams { peak_of: PeakOf::Sign, ..both };
        let touches = detect(&image, &per_sign);
        assert_eq!(touches.len(), 2, "{touches:?}");
        assert!(distance(touches[1].centre, bump) < PIXEL && (touches[1].peak - 0.3).abs() < 0.02, "{touches:?}");
        let labelled = labels(&image, &per_sign, None);
        assert_eq!(labelled.iter().filter(|&&x| x == MORE_CONDUCTIVE).count(), touches[1].pixels);
        assert_eq!("sign".parse(), Ok(PeakOf::Sign));
        assert_eq!("both".parse(), Ok(Polarity::Both));
        assert!("up".parse::<Polarity>().is_err());
    }

    /// Each touch by its own peak: a weak press far from a strong one is found, two presses
    /// with a dip between them stay apart, and a shoulder on a press's flank is not a touch.
    #[test]
    fn touches_by_their_own_peaks() {
        let own = TouchParams { peak_of: PeakOf::Touch, ..TouchParams::default() };
        let (strong, weak) = ([0.05, -0.05], [-0.04, 0.03]);
        let mut image = disk();
        add_gaussian(&mut image, strong, 0.01, -1.0);
        add_gaussian(&mut image, weak, 0.01, -0.2);
        assert_eq!(detect(&image, &TouchParams::default()).len(), 1, "under 60 % of the strongest");
        let touches = detect(&image, &own);
        assert_eq!(touches.len(), 2, "{touches:?}");
        assert!(distance(touches[1].centre, weak) < 0.5 * PIXEL && (touches[1].peak - 0.2).abs() < 0.01);
        assert_eq!(touches[0].significance, None);

        // 25 mm apart, σ 10 mm: the saddle is 88 % of the peaks, so the frame's 60 % joins them.
        let (a, b) = ([-0.0125, 0.0], [0.0125, 0.0]);
        let mut image = disk();
        add_gaussian(&mut image, a, 0.01, -1.0);
        add_gaussian(&mut image, b, 0.01, -1.0);
        assert_eq!(detect(&image, &TouchParams::default()).len(), 1);
        let touches = detect(&image, &own);
        assert_eq!(touches.len(), 2, "{touches:?}");
        let near = |t: &Touch, p| distance(t.peak_at, p) < PIXEL;
        assert!(touches.iter().any(|t| near(t, a)) && touches.iter().any(|t| near(t, b)), "{touches:?}");
        let labelled = labels(&image, &own, None);
        let pixels: usize = touches.iter().map(|t| t.pixels).sum();
        assert_eq!(labelled.iter().filter(|&&l| l == LESS_CONDUCTIVE).count(), pixels);

        // A small bump on the flank of a press is a local maximum, but a shoulder of the press.
        let mut image = disk();
        add_gaussian(&mut image, strong, 0.012, -1.0);
        add_gaussian(&mut image, [0.05 + 0.014, -0.05], 0.003, -0.1);
        let touches = detect(&image, &own);
        assert_eq!(touches.len(), 1, "{touches:?}");
        assert!(distance(touches[0].peak_at, strong) < PIXEL);

        // Without a floor, noise would start touches everywhere; the noise test keeps the
        // weak press (z 20) and drops a bump of z 2.
        let mut image = disk();
        add_gaussian(&mut image, strong, 0.01, -1.0);
        add_gaussian(&mut image, weak, 0.01, -0.2);
        add_gaussian(&mut image, [0.0, -0.07], 0.01, -0.02);
        let noise = Significance::uniform(image.values.len(), 0.01, 4.5);
        let mut found = Vec::new();
        detect_tested_into(&image, &own, Some(&noise), &mut TouchScratch::default(), &mut found);
        assert_eq!(found.len(), 2, "{found:?}");
        assert!(found[1].significance.is_some_and(|z| (z - 20.0).abs() < 1.0), "{found:?}");
        assert_eq!(detect(&image, &own).len(), 3);
    }

    #[test]
    fn one_gaussian_dip_gives_one_touch_at_its_centre() {
        let (centre, sigma, depth) = ([0.0213, -0.0371], 0.012, 2.0);
        let mut image = disk();
        add_gaussian(&mut image, centre, sigma, -depth);
        let touches = detect(&image, &TouchParams::default());
        assert_eq!(touches.len(), 1, "{touches:?}");
        let t = touches[0];
        let error = distance(t.centre, centre);
        assert!(error < 0.1 * PIXEL, "centre {:?} is {:.3} pixels off", t.centre, error / PIXEL);
        // The peak is the deepest sample: the Gaussian at the pixel centre nearest the dip.
        let nearest = distance(t.peak_at, centre);
        assert!(nearest <= PIXEL * std::f64::consts::FRAC_1_SQRT_2, "peak at {:?}", t.peak_at);
        let sampled = depth * (-nearest * nearest / (2.0 * sigma * sigma)).exp();
        assert!((t.peak - sampled).abs() < 1e-6 * depth, "peak {} vs sampled {sampled}", t.peak);
        assert!(t.bounding_box[0][0] < centre[0] && centre[0] < t.bounding_box[1][0]);
        assert!(t.bounding_box[0][1] < centre[1] && centre[1] < t.bounding_box[1][1]);
        assert_eq!(t.area, t.pixels as f64 * image.pixel_area());
    }

    #[test]
    fn peak_is_the_dip_depth_when_the_dip_sits_on_a_pixel_centre() {
        let mut image = disk();
        let centre = image.pixel_centre(20, 37);
        add_gaussian(&mut image, centre, 0.01, -0.75);
        let touches = detect(&image, &TouchParams::default());
        assert_eq!(touches.len(), 1);
        assert_eq!(touches[0].peak, 0.75);
        assert_eq!(touches[0].peak_at, centre);
        assert!(distance(touches[0].centre, centre) < 1e-9, "a symmetric region is centred on its peak");
    }

    #[test]
    fn two_separated_dips_give_two_touches_strongest_first() {
        // The weaker dip comes first in row-major order, so the order must come from the sort.
        let (weak, strong) = ([-0.05, 0.04], [0.04, -0.05]);
        let mut image = disk();
        add_gaussian(&mut image, weak, 0.01, -0.8);
        add_gaussian(&mut image, strong, 0.01, -1.0);
        let touches = detect(&image, &TouchParams::default());
        assert_eq!(touches.len(), 2, "{touches:?}");
        assert!(distance(touches[0].centre, strong) < 0.5 * PIXEL, "{:?}", touches[0]);
        assert!(distance(touches[1].centre, weak) < 0.5 * PIXEL, "{:?}", touches[1]);
        assert!((touches[0].peak - 1.0).abs() < 0.05 && (touches[1].peak - 0.8).abs() < 0.05);
    }

    #[test]
    fn a_diagonal_bridge_joins_two_dips_into_one_touch() {
        // Two 2 × 2 blocks at (2..4, 2..4) and (8..10, 8..10) (col, row), and a chain of pixels
        // (4, 4) … (7, 7) above the threshold that meets them and each other only at corners.
        let n = 12;
        let mut image = Image::new([n, n], [[0.0, 0.0], [0.012, 0.012]], vec![true; n * n]);
        let mut set = |col: usize, row: usize, v: f32| image.values[row * n + col] = v;
        for k in 0..2 {
            for l in 0..2 {
                set(2 + k, 2 + l, -1.0);
                set(8 + k, 8 + l, -1.0);
            }
        }
        for d in 4..8 {
            set(d, d, -0.7);
        }
        let touches = detect(&image, &TouchParams::default());
        assert_eq!(touches.len(), 1, "8-connectivity joins diagonal neighbours: {touches:?}");
        assert_eq!(touches[0].pixels, 12);
        assert_eq!(touches[0].bounding_box, [image.pixel_centre(2, 9), image.pixel_centre(9, 2)]);
        assert_eq!(touches[0].peak_at, image.pixel_centre(2, 2), "equal peaks go to the first pixel");

        // Control: with one bridge pixel below the threshold the dips come apart.
        image.values[6 * n + 6] = -0.5;
        let touches = detect(&image, &TouchParams::default());
        assert_eq!(touches.len(), 2, "{touches:?}");
        assert_eq!(touches.iter().map(|t| t.pixels).sum::<usize>(), 11);
    }

    #[test]
    fn noise_below_the_floor_gives_no_touch() {
        let mut image = disk();
        let mut state = 0x2545_f491_4f6c_dd1d_u64; // fixed seed; xorshift noise in ±1 mS/m
        for v in &mut image.values {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            *v = ((state >> 11) as f64 / (1u64 << 53) as f64 * 2e-3 - 1e-3) as f32;
        }
        let floor = TouchParams { min_peak: 0.01, ..TouchParams::default() };
        assert!(detect(&image, &floor).is_empty());
        // Control: without the floor the noise's own peaks are reported.
        assert!(!detect(&image, &TouchParams::default()).is_empty());
    }

    #[test]
    fn a_flat_or_raised_image_gives_no_press() {
        let mut image = disk();
        assert!(detect(&image, &TouchParams::default()).is_empty(), "all zero");
        add_gaussian(&mut image, [0.0, 0.0], 0.01, 1.0);
        assert!(detect(&image, &TouchParams::default()).is_empty(), "a rise is not a press");
    }

    #[test]
    fn masked_pixels_are_ignored() {
        let centre = [-0.02, 0.03];
        let mut image = disk();
        add_gaussian(&mut image, centre, 0.01, -1.0);
        for (v, &inside) in image.values.iter_mut().zip(&image.inside) {
            if !inside {
                *v = -100.0; // far stronger than the dip, but outside the sensor
            }
        }
        assert_eq!(image.values[0], -100.0, "the corner pixel is masked");
        let touches = detect(&image, &TouchParams::default());
        assert_eq!(touches.len(), 1, "{touches:?}");
        assert!(touches[0].peak <= 1.0 && touches[0].peak > 0.9);
        assert!(distance(touches[0].centre, centre) < 0.5 * PIXEL);
        assert!(image.peak().is_some_and(|(_, v)| v > -1.0 - 1e-6));
    }

    #[test]
    fn increase_polarity_finds_rises_and_ignores_dips() {
        let (rise, dip) = ([0.03, 0.02], [-0.04, -0.03]);
        let mut image = disk();
        add_gaussian(&mut image, rise, 0.01, 0.5);
        add_gaussian(&mut image, dip, 0.01, -2.0);
        let params = TouchParams { polarity: Polarity::Increase, ..TouchParams::default() };
        let touches = detect(&image, &params);
        assert_eq!(touches.len(), 1, "{touches:?}");
        assert!(distance(touches[0].centre, rise) < 0.5 * PIXEL);
        assert!((touches[0].peak - 0.5).abs() < 0.05);
        let touches = detect(&image, &TouchParams::default());
        assert_eq!(touches.len(), 1);
        assert!(distance(touches[0].centre, dip) < 0.5 * PIXEL);
    }

    #[test]
    fn a_higher_threshold_gives_a_smaller_area() {
        let (centre, sigma) = ([0.0113, -0.0071], 0.012);
        let mut image = disk();
        add_gaussian(&mut image, centre, sigma, -1.0);
        let mut last = f64::INFINITY;
        for threshold in [0.2, 0.4, 0.6, 0.8] {
            let touches = detect(&image, &TouchParams { threshold, ..TouchParams::default() });
            assert_eq!(touches.len(), 1);
            let area = touches[0].area;
            assert!(area < last, "threshold {threshold}: area {area} m² is not below {last} m²");
            // The level set s ≥ t·P of a Gaussian is a disk of area 2πσ²·ln(1/t).
            let exact = 2.0 * std::f64::consts::PI * sigma * sigma * (1.0 / threshold).ln();
            assert!((area / exact - 1.0).abs() < 0.1, "threshold {threshold}: area {area} vs {exact}");
            last = area;
        }
    }

    #[test]
    fn unweighted_centre_is_the_plain_centroid() {
        // Three pixels in a row, 1 mm wide, the right one weaker: kept at 60 %, centres 0.5, 1.5, 2.5 mm.
        let mut image = Image::new([5, 1], [[0.0, 0.0], [0.005, 0.001]], vec![true; 5]);
        image.values[..3].copy_from_slice(&[-1.0, -1.0, -0.7]);
        let plain = detect(&image, &TouchParams { weighted: false, ..TouchParams::default() });
        assert!((plain[0].centre[0] - 0.0015).abs() < 1e-12, "{:?}", plain[0]);
        let weighted = detect(&image, &TouchParams::default());
        let expected = (1.0 * 0.0005 + 1.0 * 0.0015 + 0.7 * 0.0025) / 2.7;
        assert!((weighted[0].centre[0] - expected).abs() < 1e-9, "{:?}", weighted[0]);
        assert!((weighted[0].centre[1] - 0.0005).abs() < 1e-12);
    }

    #[test]
    fn detect_into_reuses_its_buffers() {
        let mut image = disk();
        add_gaussian(&mut image, [-0.05, 0.04], 0.01, -0.8);
        add_gaussian(&mut image, [0.04, -0.05], 0.01, -1.0);
        let params = TouchParams::default();
        let mut scratch = TouchScratch::default(); // grows on first use
        let mut touches = Vec::new();
        detect_into(&image, &params, &mut scratch, &mut touches);
        let first = touches.clone();
        let capacities = (scratch.claim.capacity(), scratch.stack.capacity(), touches.capacity());
        let pointers = (scratch.claim.as_ptr(), scratch.stack.as_ptr(), touches.as_ptr());
        detect_into(&image, &params, &mut scratch, &mut touches);
        assert_eq!(touches, first);
        assert_eq!(touches, detect(&image, &params));
        assert_eq!((scratch.claim.capacity(), scratch.stack.capacity(), touches.capacity()), capacities);
        assert_eq!((scratch.claim.as_ptr(), scratch.stack.as_ptr(), touches.as_ptr()), pointers);

        // Preallocated buffers do not grow at all.
        let mut scratch = TouchScratch::new(image.size);
        let sized = (scratch.claim.capacity(), scratch.stack.capacity());
        detect_into(&image, &params, &mut scratch, &mut touches);
        assert_eq!((scratch.claim.capacity(), scratch.stack.capacity()), sized);
        assert_eq!(touches, first);
    }

    #[test]
    #[should_panic(expected = "needs 4 values and mask entries, got 3 and 4")]
    fn detect_into_rejects_an_image_of_the_wrong_length() {
        let mut image = Image::new([2, 2], [[0.0, 0.0], [1.0, 1.0]], vec![true; 4]);
        image.values.pop();
        let _ = detect(&image, &TouchParams::default());
    }
}
