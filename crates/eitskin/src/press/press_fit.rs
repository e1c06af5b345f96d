//! Presses fitted to the measurements themselves (a parametric reconstruction): where the
//! indenter is and how much it lowered the conductivity, found by matching Δv against the
//! forward model's response to a press at each position.
//!
//! The image is a regularised inverse of thousands of unknowns from 120 values, and its peak
//! carries the noise of all of them. Once a touch is known to be one indenter-sized press, only
//! three numbers are unknown: its centre (x, y) and its contrast α. With the linearised model
//!
//!   Δv ≈ α·g(x, y),  g(x, y) = J·χ(x, y)·(−σ₀),
//!
//! (J the Jacobian at the background σ₀, χ the share of each triangle under a disk of the
//! indenter's radius at (x, y)), the least-squares α at a given centre is gᵀΔv / gᵀg and the
//! best centre maximises (gᵀΔv)² / gᵀg: a matched filter. On the paper's sensor at 80 dB it
//! leaves about 1/25 of the image peak's noise relative to the signal.
//!
//! α is the drop the linear model needs, a fraction of σ₀. It equals the true drop for small
//! drops and runs ahead of it for large ones (a strong inclusion's response is more than
//! proportional), differently near the edges; a ladder of full forward solves at each point of
//! a second grid maps it back to the true drop, [`PressFit::drop`], which is then the same
//! function of force anywhere on the sheet.
//!
//! g is tabulated once on a square grid (spacing a quarter of the indenter's radius by default)
//! and read bilinearly; the ladder on a grid of half the radius. The search scans the grid near
//! a starting point (the image's touch centre) at twice the spacing, then the neighbours of the
//! best point, then places the centre at the vertex of a parabola through the scores.
//!
//! Several presses are fitted in turn ([`PressModel::fit_into`]), each against Δv less the
//! others' linear responses, for a few sweeps. Since a strong press's response differs a little
//! in shape from the linear one, each biases the others (two presses of drop 0.5 and 0.3, 140 mm
//! apart: about 3 mm and 0.05 in drop, against 0.2 mm and 0.02 alone; test
//! `two_presses_are_fitted_together`). Presses found in Δv ([`PressDetection`]) are therefore
//! fitted together with their exact responses ([`ExactPresses`], [`refine()`]), which a model
//! made from a forward model carries.
//!
//! Not for: presses much larger than the indenter, or touches closer together than about two
//! indenter radii (their responses are then nearly the same vector).

use std::sync::Arc;

use crate::conductivity::circle_triangle_area;
use crate::forward::{ForwardModel, LowRankUpdate};
use crate::inverse::InverseError;
use crate::mesh::Mesh;
use crate::mesh::PointLocator;

/// Why a press model could not be built.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PressModelError {
    /// The indenter radius must be positive and finite.
    #[error("the indenter radius must be positive and finite, got {0} m")]
    IndenterRadius(f64),
    /// The forward model could not be solved or linearised at the background.
    #[error("the press model's responses could not be computed")]
    Inverse(#[from] InverseError),
}

impl From<crate::forward::ForwardError> for PressModelError {
    fn from(error: crate::forward::ForwardError) -> PressModelError {
        PressModelError::Inverse(InverseError::Forward(error))
    }
}

mod detect;
mod exact;
mod joint;
mod locate;
mod refine;
mod scan;
mod tabulated;
mod track;

pub use detect::PressDetection;
pub use exact::{Disk, DiskParameter, ExactPresses, ExactScratch, JOINT_PRESSES};
pub use locate::{Locator, STRIDE};
pub use refine::{
    refine, refine_from_table, refine_tabulated, RefineParams, RefineScratch, DEEPEST, TABLE_START_APART,
};
pub use tabulated::TabulatedPresses;
pub use track::{PressTrack, Tracked, WINDOW};

crate::parallel::widest! {
    /// Σ aᵢbᵢ over the shorter of `a` and `b`, in eight running sums: the scans' and the fits'
    /// products of responses of a hundred-odd values, which one running sum makes a chain of adds
    /// (the same sums in the same order on every processor, in its widest vectors).
    fn dot_widest = dot_portable(a: &[f64], b: &[f64]) -> f64
}

/// [`dot_widest`]: Σ aᵢbᵢ over the shorter of `a` and `b`; inline where too short for the
/// dispatch to pay (the carried presses' models take thousands of products of a dozen values).
#[inline]
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    if a.len().min(b.len()) < DISPATCHED {
        dot_portable(a, b)
    } else {
        dot_widest(a, b)
    }
}

/// The shortest products [`dot`] runs through the dispatch.
const DISPATCHED: usize = 32;

/// The kernel of [`dot_widest`].
#[inline(always)]
fn dot_portable(a: &[f64], b: &[f64]) -> f64 {
    // Plain loops: a closure's fold may be left uninlined, compiled for the baseline alone.
    let n = a.len().min(b.len());
    let (a, b) = (a[..n].chunks_exact(8), b[..n].chunks_exact(8));
    let mut tail = 0.0;
    for (x, y) in a.remainder().iter().zip(b.remainder()) {
        tail += x * y;
    }
    let mut sums = [0.0; 8];
    for (a, b) in a.zip(b) {
        for k in 0..8 {
            sums[k] += a[k] * b[k];
        }
    }
    let mut total = 0.0;
    for sum in sums {
        total += sum;
    }
    total + tail
}

/// A square grid of points over a box: the first at `lo`, row-major.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Grid {
    lo: [f64; 2],
    spacing: f64,
    dims: [usize; 2],
}

impl Grid {
    /// The grid of `spacing` (m) that covers the box `[lo, hi]` (m).
    fn over([lo, hi]: [[f64; 2]; 2], spacing: f64) -> Grid {
        let count = |k: usize| (((hi[k] - lo[k]) / spacing).round() as usize + 1).max(2);
        Grid { lo, spacing, dims: [count(0), count(1)] }
    }

    fn len(&self) -> usize {
        self.dims[0] * self.dims[1]
    }

    /// The box from the first grid point to the last, `[min, max]` in m.
    fn bounds(&self) -> [[f64; 2]; 2] {
        [self.lo, self.point(self.len() - 1)]
    }

    fn point(&self, j: usize) -> [f64; 2] {
        let (i, k) = (j % self.dims[0], j / self.dims[0]);
        [self.lo[0] + i as f64 * self.spacing, self.lo[1] + k as f64 * self.spacing]
    }

    /// The four grid points around `p` (clamped to the grid) with their bilinear weights.
    fn corners(&self, p: [f64; 2]) -> [(usize, f64); 4] {
        let coord = |k: usize| ((p[k] - self.lo[k]) / self.spacing).clamp(0.0, (self.dims[k] - 1) as f64);
        let (x, y) = (coord(0), coord(1));
        let (i, j) = ((x as usize).min(self.dims[0] - 2), (y as usize).min(self.dims[1] - 2));
        let (fx, fy) = (x - i as f64, y - j as f64);
        let at = |a: usize, b: usize| b * self.dims[0] + a;
        [
            (at(i, j), (1.0 - fx) * (1.0 - fy)),
            (at(i + 1, j), fx * (1.0 - fy)),
            (at(i, j + 1), (1.0 - fx) * fy),
            (at(i + 1, j + 1), fx * fy),
        ]
    }
}

/// Per point of `grid`, the triangles of `mesh` a disk of `radius` (m) there covers, each with
/// the share of its area covered (in (1e-9, 1]).
fn disk_shares(mesh: &Mesh, grid: &Grid, radius: f64) -> Vec<Vec<(usize, f64)>> {
    let mut shares = vec![Vec::new(); grid.len()];
    for t in 0..mesh.triangles().len() {
        let corners = mesh.corners(t);
        let area = mesh.area(t);
        // The grid points whose disk can reach the triangle's bounding box.
        let range = |k: usize| {
            let (min, max) =
                corners.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), c| (a.min(c[k]), b.max(c[k])));
            let first = ((min - radius - grid.lo[k]) / grid.spacing).floor().max(0.0) as usize;
            let last = (((max + radius - grid.lo[k]) / grid.spacing).ceil().max(0.0) as usize).min(grid.dims[k] - 1);
            first..=last
        };
        for gj in range(1) {
            for gi in range(0) {
                let j = gj * grid.dims[0] + gi;
                let share = (circle_triangle_area(grid.point(j), radius, corners) / area).min(1.0);
                // Rounding leaves a share of about 1e-16 on some triangles the disk misses.
                if share > 1e-9 {
                    shares[j].push((t, share));
                }
            }
        }
    }
    shares
}

/// Conductivity drops (fractions of the background) of the ladder that undoes the linearisation.
const LADDER: [f64; 9] = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9];

/// The drops solved with the full forward model at each ladder point; the rungs between follow
/// α(d) = d / (1 − k·d − q·d²) through them (a small disk far from edges has k = ½, q = 0: its
/// polarisation; k and q absorb the indenter's size and the edges; tabulated with 9 solves per
/// point instead, the rungs differ by at most 1.3 % on the paper's sensor).
const SOLVED: [f64; 2] = [0.5, 0.9];

/// The response table of presses: Δv of a full-depth press (σ = 0 under the indenter) at
/// each point of a grid over the sheet, linearised at the background; and, on a second grid,
/// the contrast the linear fit gives for each drop of [`PressModel::LADDER`], from full forward solves;
/// and, when made from a forward model, the exact responses ([`ExactPresses`]) that presses
/// found are fitted with.
#[derive(Debug, Clone)]
pub struct PressModel {
    grid: Grid,
    measurements: usize,
    radius: f64,
    search: f64,
    /// Per grid point (row-major from `lo`), its response, `measurements` values in V; empty
    /// outside the outline.
    responses: Vec<f64>,
    /// Per grid point: gᵀg (V²), 0 outside the outline.
    norms: Vec<f64>,
    /// The coarse grid of the ladder (spacing half a radius).
    coarse: Grid,
    /// Per coarse point, the contrast fitted to a press of each drop of [`PressModel::LADDER`] there; NaN
    /// outside the outline.
    ladder: Vec<[f64; LADDER.len()]>,
    /// Per grid point, the largest contrast whose drop there is at most [`MAX_DROP`]
    /// ([`PressModel::drop_limit`]; NaN where the ladder read there is not increasing): the
    /// scans' test of every point, without the ladder's interpolation.
    drop_limits: Vec<f64>,
    /// The exact responses, shared by the model's copies (`None` for one read from its table).
    exact: Option<Arc<ExactPresses>>,
    /// One press's exact response tabulated ([`PressModel::with_tabulated`]), shared likewise.
    tabulated: Option<Arc<TabulatedPresses>>,
    /// What the table is for: fits on it, or exact fits started from it.
    table_use: TableUse,
    /// Whether every press's radius is fitted, not only where the misfit asks for it
    /// ([`PressModel::with_every_radius`]).
    every_radius: bool,
}

impl PartialEq for PressModel {
    /// Equal tables (the exact responses follow from the same sensor).
    fn eq(&self, other: &Self) -> bool {
        (self.grid, self.measurements, self.radius, self.search, &self.responses, &self.norms, self.coarse)
            == (
                other.grid,
                other.measurements,
                other.radius,
                other.search,
                &other.responses,
                &other.norms,
                other.coarse,
            )
            && self.ladder.len() == other.ladder.len()
            && self.ladder.iter().flatten().zip(other.ladder.iter().flatten()).all(|(a, b)| a.to_bits() == b.to_bits())
    }
}

/// A [`PressModel`] as plain data, for saving and loading it (`eitskin-io` caches it).
#[derive(Debug, Clone, PartialEq)]
pub struct PressTable {
    /// First grid point `[x, y]`, in m.
    pub lo: [f64; 2],
    /// Spacing of the response grid, in m.
    pub spacing: f64,
    /// Points of the response grid `[nx, ny]`, row-major from `lo`.
    pub dims: [usize; 2],
    /// Values per response.
    pub measurements: usize,
    /// Indenter radius, in m.
    pub radius: f64,
    /// Search distance from a starting point, in m.
    pub search: f64,
    /// Responses (V), `measurements` per grid point; zero outside the outline.
    pub responses: Vec<f64>,
    /// Spacing of the ladder's coarse grid (same `lo`), in m.
    pub coarse_spacing: f64,
    /// Points of the coarse grid `[nx, ny]`.
    pub coarse_dims: [usize; 2],
    /// Per coarse point, the contrast fitted to each drop of [`PressModel::LADDER`]; NaN outside.
    pub ladder: Vec<[f64; 9]>,
}

/// One fitted press.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PressFit {
    /// Centre of the indenter, in m.
    pub centre: [f64; 2],
    /// Radius of the press, in m: the model's indenter's, or fitted.
    pub radius: f64,
    /// Linearised conductivity drop under the indenter, as a fraction of the background
    /// (dimensionless, positive for a press).
    pub contrast: f64,
    /// The conductivity drop under the indenter (fraction of the background) whose full
    /// forward response gives that contrast at that centre; past 0.9 extrapolated.
    pub drop: f64,
    /// Its response against Δv less the other presses', over the response's norm, gᵀr/|g|:
    /// with Δv and the model whitened by the noise ([`PressModel::whitened`]) a z-score, else in V.
    pub z: f64,
    /// The standard deviation the noise gives its drop at the indenter's radius,
    /// [`PressFit::equivalent_drop`] (dimensionless): from the exact fit's covariance, the
    /// others' parameters unknown too, scaled up by the fit's misfit per degree of freedom where
    /// that is over 1 (a press carried from frame to frame keeps its last fit's); `None` for a
    /// fit on the linear responses alone.
    pub equivalent_drop_std: Option<f64>,
}

impl PressFit {
    /// The drop of a press of radius `indenter_radius` (m) with the same polarisation
    /// ([`Disk::equivalent_drop`]): what Δv fixes best when the radius is fitted too (a wider
    /// press of a smaller drop changes Δv much as a narrower, deeper one), so the strength a
    /// force is read from ([`Strength::FittedDrop`](crate::strength::Strength::FittedDrop));
    /// the drop itself at the indenter's radius.
    pub fn equivalent_drop(&self, indenter_radius: f64) -> f64 {
        Disk { centre: self.centre, radius: self.radius, drop: self.drop }.equivalent_drop(indenter_radius).0
    }
}

/// Settings of [`PressModel::new`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PressModelParams {
    /// Radius of the indenter, in m.
    pub radius: f64,
    /// Grid spacing, in m (a quarter of the radius when `None`).
    pub spacing: Option<f64>,
    /// How far from its starting point a press is searched for, in m (3 radii when `None`).
    pub search: Option<f64>,
}

impl Default for PressModelParams {
    fn default() -> Self {
        PressModelParams { radius: 0.010, spacing: None, search: None }
    }
}

/// Buffers for [`PressModel::fit_into`], so that it allocates nothing once they have grown.
#[derive(Debug, Clone, Default)]
pub struct PressScratch {
    residual: Vec<f64>,
    response: Vec<f64>,
    responses: Vec<f64>,
    /// Detection: the centres of the other presses, and each scan point's correlation with Δv.
    centres: Vec<[f64; 2]>,
    correlations: Vec<f32>,
    /// The exact fit: the presses as disks, its buffers, and a set of presses kept aside.
    disks: Vec<Disk>,
    refine: RefineScratch,
    saved: Vec<PressFit>,
    saved_responses: Vec<f64>,
    rejected: Vec<[f64; 2]>,
    sizes: Vec<joint::Size>,
    /// A solve of the presses for their size tests where the fit's own is not near them.
    exact: ExactScratch,
    /// The disks `exact` was last solved at (none after a solve that failed, or a new frame).
    exact_at: Vec<Disk>,
    /// Exact fits made in this frame.
    refits: usize,
    /// The scan for a new press next to fitted ones: an orthonormal basis of their Jacobian,
    /// and what of each scan point's gᵀg it leaves (where a new press could be found).
    basis: Vec<f64>,
    /// The fit (its count in `refits`) whose Jacobian `basis` is of, and its rank; `None` in a
    /// new frame.
    basis_of: Option<(usize, usize)>,
    /// Whether this frame's fits are still read from the table ([`TableUse::Auto`]).
    on_table: bool,
    unexplained: Vec<f64>,
    /// Per press of the last exact fit, its equivalent drop's variance (whitened noise of 1).
    variances: Vec<f64>,
}

/// Triangles of the mesh the exact responses are solved on when the sensor's own mesh is too
/// fine to keep its inverse whole ([`crate::forward::DENSE_LIMIT`] unknowns): a 10 mm press is
/// resolved at 4,000 (the study's mesh; its presses are simulated on a mesh 3× finer).
pub const EXACT_TRIANGLES: usize = 5000;

/// The model the exact responses of `spec`'s presses are solved on, if not `model` (the spec's
/// own): when `model` is too fine to keep its inverse whole, the spec meshed at
/// [`EXACT_TRIANGLES`] (building the part of the inverse a fine model needs takes every column
/// of it: 82 s at 100k triangles).
pub fn exact_model_for(
    spec: &crate::SensorSpec,
    model: &ForwardModel,
) -> Result<Option<ForwardModel>, crate::SpecError> {
    if model.system_size() <= crate::forward::DENSE_LIMIT {
        return Ok(None);
    }
    let mut coarse = spec.clone();
    coarse.mesh.triangles = EXACT_TRIANGLES;
    coarse.mesh.max_element_size = None;
    coarse.forward_model().map(Some)
}

/// What a press model's tabulated response ([`TabulatedPresses`]) is used for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TableUse {
    /// Presses are fitted on the table ([`refine_tabulated`]: no exact solve where they are at
    /// least [`TABLE_START_APART`] radii apart, one per fit for what it leaves where nearer):
    /// `eitskin run --press-table fit`.
    Fit,
    /// Each exact fit of presses of the table's radius (their radii not fitted), at least
    /// [`TABLE_START_APART`] radii apart and not already where the last exact solve was, starts
    /// where a fit on the table alone leaves them ([`refine_from_table`]): the exact fit
    /// decides, from nearer its optimum.
    Start,
    /// [`TableUse::Fit`] while every press is of the table's radius and each pair at least
    /// [`TABLE_START_APART`] radii apart; [`TableUse::Start`] for the rest of the frame from the
    /// first fit that would not be: a press whose size is in question (its score test, a weaker
    /// neighbour, or held at the deepest drop), a candidate press nearer another, or a fit on
    /// the table that leaves two nearer. The fits then compared are exact on both sides. Presses of the indenter's kind far apart cost no
    /// exact solve; a press of another size, and presses close together, are decided by the
    /// exact fit.
    Auto,
}

impl TableUse {
    /// What `eitskin run`, the studies and the Python `Pipeline` build the table for.
    pub const DEFAULT: Option<TableUse> = Some(TableUse::Auto);
}

/// The most bytes a press model's tabulated response (with its radius derivative) may take
/// ([`PressModel::with_tabulated`]), 256 MiB: a sheet of 500 × 500 mm under a 10 mm indenter
/// takes 244 MiB, the paper's sheet 41 MiB, and under an indenter narrower than 4 mm more than
/// the limit.
pub const TABLE_LIMIT: f64 = 268_435_456.0;

/// The largest drop a fitted press may have (a fraction of the background): all of it.
pub const MAX_DROP: f64 = 1.0;

/// Sweeps over the presses when there are several.
const SWEEPS: usize = 3;

impl PressModel {
    /// The conductivity drops (fractions of the background) of the ladder.
    pub const LADDER: [f64; 9] = LADDER;

    /// The model as plain data.
    pub fn table(&self) -> PressTable {
        PressTable {
            lo: self.grid.lo,
            spacing: self.grid.spacing,
            dims: self.grid.dims,
            measurements: self.measurements,
            radius: self.radius,
            search: self.search,
            responses: self.responses.clone(),
            coarse_spacing: self.coarse.spacing,
            coarse_dims: self.coarse.dims,
            ladder: self.ladder.clone(),
        }
    }

    /// The model from its plain data; `None` if the sizes disagree or a length is not positive.
    pub fn from_table(table: PressTable) -> Option<PressModel> {
        let PressTable {
            lo,
            spacing,
            dims,
            measurements,
            radius,
            search,
            responses,
            coarse_spacing,
            coarse_dims,
            ladder,
        } = table;
        let grid = Grid { lo, spacing, dims };
        let coarse = Grid { lo, spacing: coarse_spacing, dims: coarse_dims };
        let positive = [spacing, radius, search, coarse_spacing].iter().all(|x| *x > 0.0 && x.is_finite());
        let consistent = positive
            && dims.iter().chain(&coarse_dims).all(|&n| n >= 2)
            && measurements > 0
            && responses.len() == grid.len().checked_mul(measurements)?
            && ladder.len() == coarse.len();
        if !consistent {
            return None;
        }
        let norms = responses.chunks_exact(measurements).map(|g| g.iter().map(|x| x * x).sum()).collect();
        let mut model = PressModel {
            grid,
            measurements,
            radius,
            search,
            responses,
            norms,
            coarse,
            ladder,
            drop_limits: Vec::new(),
            exact: None,
            tabulated: None,
            table_use: TableUse::Fit,
            every_radius: false,
        };
        model.drop_limits = model.drop_limits();
        Some(model)
    }

    /// Tabulates the responses of `model` linearised at the homogeneous `background` (S/m).
    pub fn new(
        model: &ForwardModel,
        background: f64,
        params: &PressModelParams,
    ) -> Result<PressModel, PressModelError> {
        PressModel::with_exact_model(model, model, background, params)
    }

    /// [`PressModel::new`], its exact responses (and ladder) solved on `exact_model`: another
    /// mesh of the same sensor and protocol, scaled channel by channel to `model`'s values (see
    /// [`exact_model_for`]: a coarser one when `model` is too fine to keep its inverse whole).
    pub fn with_exact_model(
        model: &ForwardModel,
        exact_model: &ForwardModel,
        background: f64,
        params: &PressModelParams,
    ) -> Result<PressModel, PressModelError> {
        if !(params.radius > 0.0 && params.radius.is_finite()) {
            return Err(PressModelError::IndenterRadius(params.radius));
        }
        let mesh = model.mesh();
        let sigma = vec![background; mesh.triangles().len()];
        let solution = model.solve(&sigma)?;
        let jacobian = model.jacobian(&solution);
        let measurements = jacobian.nrows();
        let spacing = params.spacing.unwrap_or(params.radius / 4.0);
        let grid = Grid::over(mesh.bounds(), spacing);
        let points = grid.len();
        let locator = PointLocator::new(mesh);
        let mut responses = vec![0.0; points * measurements];
        for (j, shares) in disk_shares(mesh, &grid, params.radius).iter().enumerate() {
            if locator.locate(grid.point(j)).is_none() {
                continue;
            }
            let response = &mut responses[j * measurements..(j + 1) * measurements];
            for &(t, share) in shares {
                for (r, d) in response.iter_mut().zip(jacobian.col(t).iter()) {
                    *r -= background * share * d;
                }
            }
        }
        let norms = responses.chunks_exact(measurements).map(|g| g.iter().map(|x| x * x).sum()).collect();
        let search = params.search.unwrap_or(3.0 * params.radius);
        let coarse = Grid::over(mesh.bounds(), params.radius / 2.0);
        let mut press_model = PressModel {
            grid,
            measurements,
            radius: params.radius,
            search,
            responses,
            norms,
            coarse,
            ladder: Vec::new(),
            drop_limits: Vec::new(),
            exact: None,
            tabulated: None,
            table_use: TableUse::Fit,
            every_radius: false,
        };
        let values = solution.measurements(model.protocol());
        let exact = press_model.exact_of(exact_model, background, &values)?;
        press_model.ladder = press_model.ladder(&exact, &locator)?;
        press_model.drop_limits = press_model.drop_limits();
        press_model.exact = Some(Arc::new(exact));
        Ok(press_model)
    }

    /// The exact responses of `exact_model` at `background`, scaled to `values` (V, the table's
    /// model's measurements); an error if its protocol has another number of values.
    fn exact_of(
        &self,
        exact_model: &ForwardModel,
        background: f64,
        values: &[f64],
    ) -> Result<ExactPresses, InverseError> {
        let got = exact_model.protocol().measurements().len();
        if got != self.measurements {
            return Err(InverseError::FrameLength { expected: self.measurements, got });
        }
        Ok(ExactPresses::new(self.update(exact_model, background)?, background).scaled_to(values))
    }

    /// The same model with the exact responses of `exact_model` at the homogeneous `background`
    /// (S/m), scaled to `values` (V, the measurements of the model the table was made from, at
    /// that background): a model read from its table has none.
    pub fn with_exact(
        mut self,
        exact_model: &ForwardModel,
        background: f64,
        values: &[f64],
    ) -> Result<PressModel, InverseError> {
        self.exact = Some(Arc::new(self.exact_of(exact_model, background, values)?));
        // A table made from other exact responses would no longer be theirs.
        self.tabulated = None;
        Ok(self)
    }

    /// The exact responses it fits presses with, if it has them.
    pub fn exact(&self) -> Option<&ExactPresses> {
        self.exact.as_deref()
    }

    /// The same model with one press's exact response at the indenter's radius tabulated over
    /// the sheet, with its radius derivative ([`TabulatedPresses`], at the response grid's
    /// spacing: 41 MiB and about 0.36 s on two cores for the paper's sensor), so that presses
    /// found afresh are fitted on the table with no exact solve where they are apart, one per fit
    /// where nearer ([`refine_tabulated`]), instead of several per iteration: three presses at
    /// 0.05 % noise in 80–85 µs where exact fits started from the table
    /// ([`PressModel::with_table_start`]) take 216–228 µs (`eitskin bench`). Throughout,
    /// not only while it holds ([`TableUse::Auto`], the default): in the harder cases the exact
    /// fit's tests settle (a wide press's neighbour, a weak press half taken up by a strong one)
    /// its tests compare a fit on the table with exact ones and decide otherwise. A model
    /// without exact responses, or whose table would
    /// take more than [`TABLE_LIMIT`] bytes (a sheet wide against its indenter: the table grows
    /// as their ratio squared), is returned as it is.
    pub fn with_tabulated(self) -> Result<PressModel, PressModelError> {
        self.with_table(TableUse::Fit)
    }

    /// The same model with the table of [`PressModel::with_tabulated`], used only where each
    /// exact fit of presses starts ([`TableUse::Start`]): the exact fit and its tests decide as
    /// without it, in fewer solves (`eitskin run --press-table start`).
    pub fn with_table_start(self) -> Result<PressModel, PressModelError> {
        self.with_table(TableUse::Start)
    }

    /// The same model with a table for `table_use` (`None`: as it is).
    pub fn with_table_use(self, table_use: Option<TableUse>) -> Result<PressModel, PressModelError> {
        match table_use {
            Some(table_use) => self.with_table(table_use),
            None => Ok(self),
        }
    }

    /// The same model with one press's exact response tabulated, for `table_use` (a table it
    /// has already kept, put to that use).
    fn with_table(mut self, table_use: TableUse) -> Result<PressModel, PressModelError> {
        if self.tabulated.is_some() {
            self.table_use = table_use;
            return Ok(self);
        }
        let bytes = TabulatedPresses::bytes_for(self.grid.bounds(), self.grid.spacing, self.measurements);
        if bytes > TABLE_LIMIT {
            return Ok(self);
        }
        if let Some(exact) = &self.exact {
            let table = TabulatedPresses::new(exact, self.grid.bounds(), self.radius, self.grid.spacing)?;
            (self.tabulated, self.table_use) = (Some(Arc::new(table)), table_use);
        }
        Ok(self)
    }

    /// The tabulated response, if it has one ([`PressModel::with_tabulated`],
    /// [`PressModel::with_table_start`]).
    pub fn tabulated(&self) -> Option<&TabulatedPresses> {
        self.tabulated.as_deref()
    }

    /// What its tabulated response is used for; `None` where it has none.
    pub fn table_use(&self) -> Option<TableUse> {
        self.tabulated.as_ref().map(|_| self.table_use)
    }

    /// The background's factorisation, ready for the presses' low-rank updates: with the part
    /// of K₀⁻¹ between nodes a press can join (on a model too large to keep it whole).
    fn update(&self, model: &ForwardModel, background: f64) -> Result<LowRankUpdate, InverseError> {
        let mesh = model.mesh();
        let reach = crate::forward::disk_reach(mesh, self.radius);
        Ok(LowRankUpdate::with_reach(model, &vec![background; mesh.triangles().len()], reach)?)
    }

    /// The contrast fitted, at its own centre, to the exact response of a press of each drop
    /// of [`PressModel::LADDER`] at each coarse grid point (in parallel), each from the
    /// background's factorisation by a low-rank update ([`LowRankUpdate`]).
    fn ladder(
        &self,
        exact: &ExactPresses,
        locator: &PointLocator<'_>,
    ) -> Result<Vec<[f64; LADDER.len()]>, InverseError> {
        use rayon::prelude::*;
        let ladder = (0..self.coarse.len()).into_par_iter().map_init(ExactScratch::default, |scratch, j| {
            let centre = self.coarse.point(j);
            let mut contrasts = [f64::NAN; LADDER.len()];
            let mut g = vec![0.0; self.measurements];
            if locator.locate(centre).is_none() || !self.response_into(centre, &mut g) {
                return Ok(contrasts);
            }
            let gg: f64 = g.iter().map(|g| g * g).sum();
            // The contrast at the two solved drops, then the rational law through them.
            let mut solved = [0.0; 2];
            let mut dv = vec![0.0; self.measurements];
            for (c, drop) in solved.iter_mut().zip(SOLVED) {
                exact.response_into(&[Disk { centre, radius: self.radius, drop }], scratch, &mut dv)?;
                *c = g.iter().zip(&dv).map(|(g, d)| g * d).sum::<f64>() / gg;
            }
            let [(d1, c1), (d2, c2)] = [(SOLVED[0], solved[0]), (SOLVED[1], solved[1])];
            let (y1, y2) = (1.0 - d1 / c1, 1.0 - d2 / c2);
            let det = d1 * d2 * d2 - d1 * d1 * d2;
            let (k, q) = ((y1 * d2 * d2 - y2 * d1 * d1) / det, (y2 * d1 - y1 * d2) / det);
            for (c, d) in contrasts.iter_mut().zip(LADDER) {
                let denominator = 1.0 - k * d - q * d * d;
                *c = if denominator > 0.0 { d / denominator } else { f64::NAN };
            }
            Ok(contrasts)
        });
        ladder.collect()
    }

    /// The drop (fraction of the background) whose press at `p` (m) fits to `contrast`: piecewise
    /// linear through (0, 0) and the ladder read bilinearly at `p`, extended past its ends.
    pub fn drop(&self, contrast: f64, p: [f64; 2]) -> f64 {
        let Some(rungs) = self.rungs(p) else { return contrast };
        let mut previous = (0.0, 0.0);
        for (k, (&r, d)) in rungs.iter().zip(LADDER).enumerate() {
            let rung = (r, d);
            if contrast <= rung.0 || k == LADDER.len() - 1 {
                let ((c0, d0), (c1, d1)) = (previous, rung);
                return if c1 > c0 { d0 + (contrast - c0) * (d1 - d0) / (c1 - c0) } else { d0 };
            }
            previous = rung;
        }
        contrast
    }

    /// The ladder's contrasts read bilinearly at `p` (m), one per drop of [`PressModel::LADDER`];
    /// `None` where no coarse point around `p` has them.
    fn rungs(&self, p: [f64; 2]) -> Option<[f64; LADDER.len()]> {
        let mut rungs = [0.0; LADDER.len()];
        let mut total = 0.0;
        for (j, w) in self.coarse.corners(p) {
            if w > 0.0 && self.ladder[j][0].is_finite() {
                total += w;
                rungs.iter_mut().zip(&self.ladder[j]).for_each(|(r, c)| *r += w * c);
            }
        }
        (total > 0.0).then(|| rungs.map(|r| r / total))
    }

    /// The largest contrast whose drop at `p` (m) is at most [`MAX_DROP`]: where the rungs
    /// increase, [`PressModel::drop`] is increasing and exceeds it past this one contrast; NaN
    /// where they do not (the drop itself must then be read).
    fn drop_limit(&self, p: [f64; 2]) -> f64 {
        let Some(rungs) = self.rungs(p) else { return MAX_DROP };
        let mut previous = (0.0, 0.0);
        for (k, (&c, d)) in rungs.iter().zip(LADDER).enumerate() {
            let ((c0, d0), (c1, d1)) = (previous, (c, d));
            if c1.partial_cmp(&c0) != Some(std::cmp::Ordering::Greater) {
                return f64::NAN;
            }
            if MAX_DROP <= d1 || k == LADDER.len() - 1 {
                return c0 + (MAX_DROP - d0) * (c1 - c0) / (d1 - d0);
            }
            previous = (c1, d1);
        }
        f64::NAN
    }

    /// [`PressModel::drop_limit`] at each grid point.
    fn drop_limits(&self) -> Vec<f64> {
        (0..self.grid.len()).map(|j| self.drop_limit(self.grid.point(j))).collect()
    }

    /// The response of a press at grid point `j` (V per unit contrast, protocol order).
    fn grid_response(&self, j: usize) -> &[f64] {
        &self.responses[j * self.measurements..(j + 1) * self.measurements]
    }

    /// Whether a press of `contrast` at grid point `j` would lower the conductivity by more
    /// than [`MAX_DROP`]: a blend of presses elsewhere (a weakly sensitive middle between them).
    fn too_deep(&self, contrast: f64, j: usize) -> bool {
        let limit = self.drop_limits[j];
        if limit.is_nan() {
            self.drop(contrast, self.grid.point(j)) > MAX_DROP
        } else {
            contrast > limit
        }
    }

    /// The same model blind to the channels with `used[m] = false`: their responses are zeroed,
    /// so whatever finite value their Δv holds adds nothing to a fit (a channel gone bad: pass
    /// its Δv as 0, since 0·NaN is NaN). Copies the table (milliseconds): an event, not the frame path.
    pub fn masked(&self, used: &[bool]) -> PressModel {
        assert_eq!(used.len(), self.measurements, "one flag per measurement");
        let mut masked = self.clone();
        for g in masked.responses.chunks_exact_mut(self.measurements) {
            g.iter_mut().zip(used).filter(|(_, u)| !**u).for_each(|(g, _)| *g = 0.0);
        }
        masked.norms =
            masked.responses.chunks_exact(self.measurements).map(|g| g.iter().map(|x| x * x).sum()).collect();
        masked
    }

    /// Number of values a Δv must have.
    pub fn measurements(&self) -> usize {
        self.measurements
    }

    /// Radius of the indenter it models, in m.
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// The same model fitting every press's radius too (`true`), not only where the misfit
    /// falls by more than chance would (`false`, the default): each press's polarisation is then
    /// that of its own size, at the price of a noisier drop, which reads presses wider or
    /// narrower than the indenter without the bias of an indenter-sized fit
    /// ([`Strength::SizedDrop`](crate::strength::Strength::SizedDrop)).
    pub fn with_every_radius(mut self, every_radius: bool) -> PressModel {
        self.every_radius = every_radius;
        self
    }

    /// Whether it fits every press's radius ([`PressModel::with_every_radius`]).
    pub fn every_radius(&self) -> bool {
        self.every_radius
    }

    /// The response (V) of a full-depth press at `p` (m), bilinear between grid points inside
    /// the outline, into `out`; false if no grid point around `p` is inside.
    pub fn response_into(&self, p: [f64; 2], out: &mut [f64]) -> bool {
        out.fill(0.0);
        let mut total = 0.0;
        for (k, w) in self.grid.corners(p) {
            if self.norms[k] > 0.0 && w > 0.0 {
                total += w;
                let g = &self.responses[k * self.measurements..(k + 1) * self.measurements];
                out.iter_mut().zip(g).for_each(|(o, g)| *o += w * g);
            }
        }
        if total > 0.0 {
            out.iter_mut().for_each(|o| *o /= total);
        }
        total > 0.0
    }

    /// The best single press near `start` (m) for the difference `dv` (V), `None` if nothing
    /// there looks like a press; an error if `dv` has the wrong length.
    pub fn fit(&self, dv: &[f64], start: [f64; 2]) -> Result<Option<PressFit>, InverseError> {
        let mut scratch = PressScratch::default();
        let mut out = Vec::with_capacity(1);
        self.fit_into(dv, &[start], &mut scratch, &mut out)?;
        Ok(out.first().copied().flatten())
    }

    /// Fits one press per starting point (m, at most 16) to `dv` (V), each searched near its
    /// start, into `out` (cleared; one entry per start, `None` where nothing looks like a press).
    /// Allocates nothing once `scratch` and `out` have grown. Non-finite values in `dv` find
    /// no press; a `dv` of the wrong length is an error.
    pub fn fit_into(
        &self,
        dv: &[f64],
        starts: &[[f64; 2]],
        scratch: &mut PressScratch,
        out: &mut Vec<Option<PressFit>>,
    ) -> Result<(), InverseError> {
        out.clear();
        let m = self.measurements;
        if dv.len() != m {
            return Err(InverseError::FrameLength { expected: m, got: dv.len() });
        }
        let k = starts.len();
        scratch.residual.resize(m, 0.0);
        scratch.response.resize(m, 0.0);
        scratch.responses.clear();
        scratch.responses.resize(k * m, 0.0);
        let mut fits: [Option<PressFit>; 16] = [None; 16];
        let k = k.min(fits.len());
        for sweep in 0..if k > 1 { SWEEPS } else { 1 } {
            for i in 0..k {
                // Δv less the other presses' fitted responses.
                scratch.residual.copy_from_slice(dv);
                for (other, g) in scratch.responses.chunks_exact(m).enumerate().take(k) {
                    if other != i {
                        scratch.residual.iter_mut().zip(g).for_each(|(r, g)| *r -= g);
                    }
                }
                let start = fits[i].map_or(starts[i], |f| f.centre);
                let window = if sweep == 0 { self.search } else { 2.0 * self.grid.spacing };
                fits[i] = self.fit_one(&scratch.residual, start, window, &mut scratch.response);
                let g = &mut scratch.responses[i * m..(i + 1) * m];
                match fits[i] {
                    Some(fit) => g.iter_mut().zip(&scratch.response).for_each(|(g, r)| *g = fit.contrast * r),
                    None => g.fill(0.0),
                }
            }
        }
        out.extend(fits.iter().take(k));
        Ok(())
    }

    /// The score (gᵀΔv)² / gᵀg of grid point `j` for a press (gᵀΔv > 0, and a drop of at
    /// most [`MAX_DROP`]), or `None`.
    fn score(&self, dv: &[f64], j: usize) -> Option<f64> {
        let norm = self.norms[j];
        if norm <= 0.0 {
            return None;
        }
        let c = dot(&self.responses[j * self.measurements..(j + 1) * self.measurements], dv);
        // A press lowers the conductivity by at most all of it: a point that would need more
        // is a blend of presses elsewhere (a weakly sensitive middle between them), not a press.
        (c > 0.0 && !self.too_deep(c / norm, j)).then(|| c * c / norm)
    }

    fn fit_one(&self, dv: &[f64], start: [f64; 2], search: f64, response: &mut [f64]) -> Option<PressFit> {
        let Grid { lo, spacing, dims: [nx, ny] } = self.grid;
        let index = |p: f64, k: usize, n: usize| ((p - lo[k]) / spacing).round().clamp(0.0, (n - 1) as f64);
        let (si, sj) = (index(start[0], 0, nx) as isize, index(start[1], 1, ny) as isize);
        let reach = (search / spacing).ceil() as isize;
        let cell = |i: isize, j: isize| {
            (i >= 0 && j >= 0 && (i as usize) < nx && (j as usize) < ny).then(|| j as usize * nx + i as usize)
        };
        let mut best: Option<(f64, isize, isize)> = None;
        let consider = |i: isize, j: isize, best: &mut Option<(f64, isize, isize)>| {
            if let Some(s) = cell(i, j).and_then(|c| self.score(dv, c)) {
                if best.is_none_or(|(b, _, _)| s > b) {
                    *best = Some((s, i, j));
                }
            }
        };
        // Coarse scan at twice the spacing inside the search disk, then the best point's neighbours.
        for dj in (-reach..=reach).step_by(2) {
            for di in (-reach..=reach).step_by(2) {
                if (di * di + dj * dj) as f64 * spacing * spacing <= search * search {
                    consider(si + di, sj + dj, &mut best);
                }
            }
        }
        let (_, ci, cj) = best?;
        for (di, dj) in [(-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)] {
            consider(ci + di, cj + dj, &mut best);
        }
        let (s0, bi, bj) = best?;
        // Sub-grid: the vertex of the parabola through the scores along each axis.
        let score_at = |i: isize, j: isize| cell(i, j).and_then(|c| self.score(dv, c));
        let vertex = |minus: Option<f64>, plus: Option<f64>| match (minus, plus) {
            (Some(a), Some(b)) if a - 2.0 * s0 + b < 0.0 => (0.5 * (a - b) / (a - 2.0 * s0 + b)).clamp(-0.5, 0.5),
            _ => 0.0,
        };
        let dx = vertex(score_at(bi - 1, bj), score_at(bi + 1, bj));
        let dy = vertex(score_at(bi, bj - 1), score_at(bi, bj + 1));
        let centre = [lo[0] + (bi as f64 + dx) * spacing, lo[1] + (bj as f64 + dy) * spacing];
        if !self.response_into(centre, response) {
            return None;
        }
        let (gg, gv) = (dot(response, response), dot(response, dv));
        let (contrast, z) = (gv / gg, gv / gg.sqrt());
        let drop = self.drop(contrast, centre);
        (gg > 0.0 && gv > 0.0).then_some(PressFit {
            centre,
            radius: self.radius,
            contrast,
            drop,
            z,
            equivalent_drop_std: None,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::conductivity::{with_inclusions, Inclusion};
    use crate::sim::VirtualSensor;
    use crate::touch::{detect, TouchParams};
    use crate::{Reconstructor, ReconstructorParams, SensorSpec};

    /// Presses as (centre in m, drop).
    type Presses<'a> = &'a [([f64; 2], f64)];

    /// The press model of the paper's sensor on a coarse mesh, and Δv of presses simulated on a
    /// finer, different one.
    fn setup() -> (PressModel, impl Fn(Presses<'_>) -> Vec<f64>) {
        setup_on(SensorSpec::square_hydrogel())
    }

    fn setup_on(mut spec: SensorSpec) -> (PressModel, impl Fn(Presses<'_>) -> Vec<f64>) {
        spec.mesh.triangles = 1500;
        let press_model = PressModel::new(&spec.forward_model().unwrap(), 1.0, &PressModelParams::default()).unwrap();
        let mut fine = spec.clone();
        fine.mesh.triangles = 5000;
        let truth = fine.forward_model().unwrap();
        let v0 = truth.measure(&fine.homogeneous(truth.mesh())).unwrap();
        let dv = move |presses: Presses<'_>| {
            let inclusions: Vec<Inclusion> = presses
                .iter()
                .map(|&(centre, drop)| Inclusion { centre, radius: 0.01, conductivity: 1.0 - drop })
                .collect();
            let v = truth.measure(&with_inclusions(truth.mesh(), 1.0, &inclusions)).unwrap();
            v.iter().zip(&v0).map(|(v, v0)| v - v0).collect()
        };
        (press_model, dv)
    }

    fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
        (a[0] - b[0]).hypot(a[1] - b[1])
    }

    #[test]
    fn an_indenter_of_no_size_is_a_press_model_error() {
        let mut spec = crate::SensorSpec::square_hydrogel();
        spec.mesh.triangles = 300;
        let model = spec.forward_model().unwrap();
        for radius in [0.0, -0.01, f64::NAN] {
            let err = PressModel::new(&model, 1.0, &PressModelParams { radius, ..PressModelParams::default() });
            assert!(matches!(err, Err(PressModelError::IndenterRadius(r)) if r.to_bits() == radius.to_bits()));
        }
    }

    /// A table past the limit is not made: a 3 mm indenter on the paper's sheet would take
    /// 450 MB; the model keeps fitting on its exact responses.
    #[test]
    fn a_table_too_large_is_not_made() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 300;
        let model = spec.forward_model().unwrap();
        let params = PressModelParams { radius: 0.003, ..PressModelParams::default() };
        let bytes = TabulatedPresses::bytes_for(model.mesh().bounds(), 0.00075, 120);
        assert!(bytes > TABLE_LIMIT, "{bytes}");
        let press_model = PressModel::new(&model, 1.0, &params).unwrap().with_tabulated().unwrap();
        assert!(press_model.tabulated().is_none() && press_model.exact().is_some());
        let small = TabulatedPresses::bytes_for(model.mesh().bounds(), 0.0025, 120);
        assert!((small / 2f64.powi(20) - 41.34).abs() < 0.01, "{small}");
    }

    #[test]
    fn presses_are_found_where_they_are_with_their_drop() {
        let (model, dv) = setup();
        for centre in [[0.0, 0.0], [0.05, -0.03], [-0.07, 0.06]] {
            // Small drop: the linear model holds, contrast = drop.
            let start = [centre[0] + 0.01, centre[1] - 0.008];
            let fit = model.fit(&dv(&[(centre, 0.05)]), start).unwrap().unwrap();
            assert!(distance(fit.centre, centre) < 2e-3, "{centre:?}: found at {:?}", fit.centre);
            assert!((fit.contrast / 0.05 - 1.0).abs() < 0.1, "{centre:?}: contrast {}", fit.contrast);
            assert!((fit.drop / 0.05 - 1.0).abs() < 0.1, "{centre:?}: drop {}", fit.drop);
            // Strong drop: the response saturates, the contrast overshoots, the ladder undoes it.
            let fit = model.fit(&dv(&[(centre, 0.8)]), start).unwrap().unwrap();
            assert!(distance(fit.centre, centre) < 3e-3, "{centre:?}: found at {:?}", fit.centre);
            assert!(fit.contrast > 1.2 * 0.8, "{centre:?}: contrast {}", fit.contrast);
            assert!((fit.drop - 0.8).abs() < 0.05, "{centre:?}: drop {}", fit.drop);
        }
    }

    /// The scans' test of a contrast against each grid point's limit says what the ladder's
    /// drop says: at most [`MAX_DROP`] just under the limit, more just over it; and a model read
    /// from its table has the same limits.
    #[test]
    fn the_drop_limit_is_where_the_drop_passes_its_most() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 300;
        let model = PressModel::new(&spec.forward_model().unwrap(), 1.0, &PressModelParams::default()).unwrap();
        let mut tested = 0;
        for j in (0..model.grid.len()).filter(|&j| model.norms[j] > 0.0) {
            let (limit, p) = (model.drop_limits[j], model.grid.point(j));
            assert!(limit.is_finite(), "the ladder increases at {p:?}");
            assert!(model.drop(limit * (1.0 - 1e-9), p) <= MAX_DROP, "{p:?}");
            assert!(model.drop(limit * (1.0 + 1e-9), p) > MAX_DROP, "{p:?}");
            assert!(!model.too_deep(limit * (1.0 - 1e-9), j) && model.too_deep(limit * (1.0 + 1e-9), j));
            tested += 1;
        }
        assert!(tested > 1000, "{tested} points");
        let back = PressModel::from_table(model.table()).unwrap();
        assert!(back.drop_limits.iter().zip(&model.drop_limits).all(|(a, b)| a.to_bits() == b.to_bits()));
        // Rungs that do not increase leave the drop to be read.
        let mut flat = model.clone();
        flat.ladder.iter_mut().for_each(|rungs| rungs[3] = rungs[2]);
        assert!(flat.drop_limits().iter().all(|l| l.is_nan() || *l == MAX_DROP));
    }

    #[test]
    fn a_model_survives_its_table() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 300;
        let model = PressModel::new(&spec.forward_model().unwrap(), 1.0, &PressModelParams::default()).unwrap();
        let back = PressModel::from_table(model.table()).unwrap();
        // The ladder holds NaN outside the outline, so compare bits.
        let bits = |m: &PressModel| m.ladder.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(
            (&back.responses, &back.norms, back.grid, back.coarse),
            (&model.responses, &model.norms, model.grid, model.coarse)
        );
        assert_eq!(bits(&back), bits(&model));
        let mut torn = model.table();
        torn.responses.pop();
        assert_eq!(PressModel::from_table(torn), None);
    }

    #[test]
    fn presses_on_a_disk_sensor_are_found_too() {
        use crate::spec::{ElectrodeSpec, Placement};
        use crate::Outline;
        let square = SensorSpec::square_hydrogel();
        let electrodes = ElectrodeSpec { placement: Placement::Equal { start_angle_deg: 0.0 }, ..square.electrodes };
        let (model, dv) = setup_on(SensorSpec { outline: Outline::Circle { radius: 0.1 }, electrodes, ..square });
        for (centre, drop) in [([0.03, -0.02], 0.6), ([0.0, 0.07], 0.4), ([-0.05, -0.04], 0.2)] {
            let fit = model.fit(&dv(&[(centre, drop)]), [centre[0] - 0.008, centre[1] + 0.006]).unwrap().unwrap();
            assert!(distance(fit.centre, centre) < 3e-3, "{centre:?}: found at {:?}", fit.centre);
            assert!((fit.drop - drop).abs() < 0.05, "{centre:?}: drop {} for {drop}", fit.drop);
        }
    }

    /// A masked channel's Δv, however wrong, moves nothing; unmasked, the same value ruins the fit.
    #[test]
    fn a_masked_channel_adds_nothing_to_the_fit() {
        let (model, dv) = setup();
        let (centre, drop) = ([0.03, -0.04], 0.5);
        let clean = model.fit(&dv(&[(centre, drop)]), [0.035, -0.045]).unwrap().unwrap();
        let mut wrong = dv(&[(centre, drop)]);
        wrong[40] = 1e3 * wrong.iter().fold(0.0, |a, x| f64::max(a, x.abs()));
        let mut used = vec![true; 120];
        used[40] = false;
        let masked = model.masked(&used).fit(&wrong, [0.035, -0.045]).unwrap().unwrap();
        assert!(distance(masked.centre, centre) < 4e-3, "found at {:?}", masked.centre);
        assert!((masked.drop - clean.drop).abs() < 0.03, "drop {} for {}", masked.drop, clean.drop);
        let unmasked = model.fit(&wrong, [0.035, -0.045]).unwrap();
        assert!(unmasked.is_none_or(|f| (f.drop - clean.drop).abs() > 0.1), "{unmasked:?}");
    }

    #[test]
    fn two_presses_are_fitted_together() {
        let (model, dv) = setup();
        let presses = [([-0.05, -0.05], 0.5), ([0.05, 0.04], 0.3)];
        let starts = [[-0.042, -0.055], [0.045, 0.048]];
        let mut out = Vec::new();
        model.fit_into(&dv(&presses), &starts, &mut PressScratch::default(), &mut out).unwrap();
        assert_eq!(out.len(), 2);
        // Far-apart presses superpose: what is left is the linear model's, not the physics'.
        let (a, b, ab) = (dv(&presses[..1]), dv(&presses[1..]), dv(&presses));
        let norm = |x: &mut dyn Iterator<Item = f64>| x.map(|x| x * x).sum::<f64>().sqrt();
        let superposition =
            norm(&mut a.iter().zip(&b).zip(&ab).map(|((a, b), t)| a + b - t)) / norm(&mut ab.iter().copied());
        assert!(superposition < 1e-2, "{superposition}");
        // Each press's shape differs a little from the linear response the other is fitted with,
        // which moves both: about 3 mm and 0.05 in drop here (alone: 0.2 mm, 0.02).
        for (fit, (centre, drop)) in out.iter().flatten().zip(presses) {
            assert!(distance(fit.centre, centre) < 4e-3, "{centre:?}: found at {:?}", fit.centre);
            assert!((fit.drop - drop).abs() < 0.06, "{centre:?}: drop {} for {drop}", fit.drop);
        }
        // Nothing but a rise in conductivity: no press.
        let rise: Vec<f64> = dv(&[([0.0, 0.0], 0.5)]).iter().map(|x| -x).collect();
        assert_eq!(model.fit(&rise, [0.0, 0.0]), Ok(None));
        // A wrong length is an error, a NaN finds nothing.
        assert!(matches!(
            model.fit(&rise[1..], [0.0, 0.0]),
            Err(InverseError::FrameLength { expected: 120, got: 119 })
        ));
        let mut nan = dv(&presses);
        nan[3] = f64::NAN;
        assert_eq!(model.fit(&nan, [0.0, 0.0]), Ok(None));
    }

    #[test]
    fn fitted_drop_is_far_less_noisy_than_the_image_peak() {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 1500;
        let model = spec.forward_model().unwrap();
        let recon = Reconstructor::new(&model, spec.conductivity, &ReconstructorParams::default()).unwrap();
        let press_model = PressModel::new(&model, spec.conductivity, &PressModelParams::default()).unwrap();
        let mut skin = VirtualSensor::new(&spec, 7).unwrap();
        let v_ref = skin.clean_frame().unwrap();
        skin.press([0.0, 0.0], 6.0);
        let clean = skin.clean_frame().unwrap();
        let (mut peaks, mut drops) = (Vec::new(), Vec::new());
        for _ in 0..40 {
            let mut v = clean.clone();
            skin.add_noise(&mut v);
            let touch = detect(&recon.image(&v_ref, &v).unwrap(), &TouchParams::default())[0];
            let dv: Vec<f64> = v.iter().zip(&v_ref).map(|(v, r)| v - r).collect();
            drops.push(press_model.fit(&dv, touch.centre).unwrap().unwrap().drop);
            peaks.push(touch.peak);
        }
        let spread = |x: &[f64]| {
            let mean = x.iter().sum::<f64>() / x.len() as f64;
            (x.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / x.len() as f64).sqrt() / mean
        };
        let (peak, drop) = (spread(&peaks), spread(&drops));
        assert!(drop < peak / 5.0, "relative spread: fitted drop {drop:.4}, image peak {peak:.4}");
    }
}
