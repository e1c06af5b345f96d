//! The forward model's view of the sheet for the continuous force methods ([`Strength::Sensitivity`]
//! and the `Contrast…` strengths of [`crate::strength`]).
//!
//! At each point of an n×n grid of touch centres (inset by the indenter's radius), the
//! reconstructed peak and volume of an inclusion of the indenter's size for conductivity drops
//! 0.1, 0.2 … 0.9, simulated on the reconstruction model itself (no knowledge of the sheet
//! that will be pressed); read bilinearly. S(x), the sensitivity, is the peak of the 0.5 drop;
//! a touch's peak (or volume) is read back as the drop d̂ that explains it at its centre.
//! Touches are looked up by their centre of gravity, which is pulled away from the press near
//! the edges, so each map inclusion is moved until its image's centre of gravity sits on its
//! grid point: the map is indexed the way it is read.
//!
//! [`Strength::Sensitivity`]: crate::strength::Strength::Sensitivity
//!
//! Not for: the press fitted to Δv (that is [`crate::press_fit`]), which needs no image.

use crate::conductivity::Inclusion;
use crate::forward::ForwardModel;
use crate::inverse::{InverseError, Reconstructor};
use crate::sensitivity::{strongest_touches, InclusionFrames};
use crate::touch::Touch;

/// Settings of [`ContrastMap::new`]; `Default` is the study's: 41 × 41 points, a 10 mm indenter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContrastMapParams {
    /// Grid points per side, ≥ 2.
    pub points: usize,
    /// Radius of the simulated press, in m.
    pub radius: f64,
}

impl Default for ContrastMapParams {
    fn default() -> Self {
        ContrastMapParams { points: 41, radius: 0.010 }
    }
}

/// Peaks and volumes of simulated presses over the sheet, for a ladder of drops (see the module doc).
#[derive(Debug, Clone, PartialEq)]
pub struct ContrastMap {
    lo: [f64; 2],
    step: [f64; 2],
    n: usize,
    drops: Vec<f64>,
    /// `peaks[k][j]`: peak (S/m) at grid point j for drop k.
    peaks: Vec<Vec<f64>>,
    /// `volumes[k][j]`: volume (S/m·m²) at grid point j for drop k.
    volumes: Vec<Vec<f64>>,
}

/// A [`ContrastMap`] as plain data, for saving and loading it (`eitskin-io` caches it).
#[derive(Debug, Clone, PartialEq)]
pub struct ContrastTable {
    /// First grid point `[x, y]`, in m.
    pub lo: [f64; 2],
    /// Grid spacing `[dx, dy]`, in m.
    pub step: [f64; 2],
    /// Grid points per side.
    pub points: usize,
    /// The ladder's drops, fractions of the background.
    pub drops: Vec<f64>,
    /// Per drop, the peak (S/m) at each grid point, row-major from `lo`.
    pub peaks: Vec<Vec<f64>>,
    /// Per drop, the volume (S/m·m²) at each grid point.
    pub volumes: Vec<Vec<f64>>,
}

/// The drop whose peak is the sensitivity S(x) of the plain continuous calibration.
const REFERENCE_DROP: usize = 4; // 0.5

/// Fixed-point steps that move map inclusions so their images' centres land on the grid.
const MAP_ITERATIONS: usize = 2;

impl ContrastMap {
    /// The map of `model` (background conductivity `background`, S/m) seen through `recon`, over
    /// `bounds` (the outline's box, m).
    pub fn new(
        model: &ForwardModel,
        background: f64,
        recon: &Reconstructor,
        bounds: [[f64; 2]; 2],
        params: &ContrastMapParams,
    ) -> Result<ContrastMap, InverseError> {
        let n = params.points.max(2);
        let radius = params.radius;
        let [lo, hi] = bounds;
        let lo = [lo[0] + radius, lo[1] + radius];
        let step = [(hi[0] - radius - lo[0]) / (n - 1) as f64, (hi[1] - radius - lo[1]) / (n - 1) as f64];
        let drops: Vec<f64> = (1..=9).map(|k| 0.1 * k as f64).collect();
        let grid: Vec<[f64; 2]> =
            (0..n * n).map(|k| [lo[0] + (k % n) as f64 * step[0], lo[1] + (k / n) as f64 * step[1]]).collect();
        let frames = InclusionFrames::new(model, background, grid.len() * (MAP_ITERATIONS + drops.len()), radius)?;
        let at = |centres: &[[f64; 2]], drop: f64| -> Result<Vec<Option<Touch>>, InverseError> {
            let inclusions: Vec<Inclusion> = centres
                .iter()
                .map(|&centre| Inclusion { centre, radius, conductivity: (1.0 - drop) * background })
                .collect();
            strongest_touches(&frames, recon, &inclusions)
        };
        // Move each map inclusion until its image's centre of gravity sits on the grid point.
        let mut centres = grid.clone();
        for _ in 0..MAP_ITERATIONS {
            let touches = at(&centres, drops[REFERENCE_DROP])?;
            for ((c, g), t) in centres.iter_mut().zip(&grid).zip(touches) {
                if let Some(t) = t {
                    for k in 0..2 {
                        c[k] = (c[k] + g[k] - t.centre[k]).clamp(lo[k], hi[k] - radius);
                    }
                }
            }
        }
        let ladder: Vec<Vec<Option<Touch>>> = drops.iter().map(|&d| at(&centres, d)).collect::<Result<_, _>>()?;
        let of = |f: fn(&Touch) -> f64| -> Vec<Vec<f64>> {
            ladder.iter().map(|row| row.iter().map(|t| t.as_ref().map_or(0.0, f)).collect()).collect()
        };
        Ok(ContrastMap { lo, step, n, peaks: of(|t| t.peak), volumes: of(|t| t.volume), drops })
    }

    /// The map as plain data.
    pub fn table(&self) -> ContrastTable {
        let ContrastMap { lo, step, n, drops, peaks, volumes } = self.clone();
        ContrastTable { lo, step, points: n, drops, peaks, volumes }
    }

    /// The map of a table, or `None` if its sizes do not agree (≥ 2 points a side, the
    /// reference drop in the ladder, one value per point per drop) or a value is not finite.
    pub fn from_table(table: ContrastTable) -> Option<ContrastMap> {
        let ContrastTable { lo, step, points: n, drops, peaks, volumes } = table;
        let cells = n.checked_mul(n)?;
        let shaped = |rows: &[Vec<f64>]| rows.len() == drops.len() && rows.iter().all(|r| r.len() == cells);
        let finite = |rows: &[Vec<f64>]| rows.iter().flatten().all(|v| v.is_finite());
        let ok = n >= 2
            && drops.len() > REFERENCE_DROP
            && shaped(&peaks)
            && shaped(&volumes)
            && finite(&peaks)
            && finite(&volumes)
            && lo.iter().chain(&step).chain(&drops).all(|v| v.is_finite())
            && step.iter().all(|&s| s > 0.0);
        ok.then_some(ContrastMap { lo, step, n, drops, peaks, volumes })
    }

    /// Bilinear weights and grid indices at `p` (m), clamped to the grid.
    fn corners(&self, p: [f64; 2]) -> [(usize, f64); 4] {
        let coord = |k: usize| ((p[k] - self.lo[k]) / self.step[k]).clamp(0.0, (self.n - 1) as f64);
        let (x, y) = (coord(0), coord(1));
        let (i, j) = ((x as usize).min(self.n - 2), (y as usize).min(self.n - 2));
        let (fx, fy) = (x - i as f64, y - j as f64);
        let at = |a: usize, b: usize| b * self.n + a;
        [
            (at(i, j), (1.0 - fx) * (1.0 - fy)),
            (at(i + 1, j), fx * (1.0 - fy)),
            (at(i, j + 1), (1.0 - fx) * fy),
            (at(i + 1, j + 1), fx * fy),
        ]
    }

    /// The peak (S/m), or with `volume` the volume (S/m·m²), of drop number `k` at `p` (m).
    fn strength(&self, k: usize, p: [f64; 2], volume: bool) -> f64 {
        let table = if volume { &self.volumes } else { &self.peaks };
        self.corners(p).iter().map(|&(j, w)| w * table[k][j]).sum()
    }

    /// S(x): the peak of the reference drop at `p` (m), in S/m.
    pub fn sensitivity(&self, p: [f64; 2]) -> f64 {
        self.strength(REFERENCE_DROP, p, false)
    }

    /// The drop (fraction of the background) whose peak at `p` (m) is `peak` (S/m; with
    /// `volume`, the volume in S/m·m²): piecewise linear
    /// through (0, 0) and the ladder, extended past its ends along the nearest segment.
    pub fn drop(&self, peak: f64, p: [f64; 2], volume: bool) -> f64 {
        let ladder: Vec<(f64, f64)> = std::iter::once((0.0, 0.0))
            .chain(self.drops.iter().enumerate().map(|(k, &d)| (self.strength(k, p, volume), d)))
            .collect();
        let segment = ladder.windows(2).position(|w| peak <= w[1].0).unwrap_or(ladder.len() - 2);
        let ((p0, d0), (p1, d1)) = (ladder[segment], ladder[segment + 1]);
        if p1 > p0 {
            d0 + (peak - p0) * (d1 - d0) / (p1 - p0)
        } else {
            d0
        }
    }
}
