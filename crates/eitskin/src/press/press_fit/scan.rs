//! The scan of the sheet: for a whitened Δv, the grid point whose press matches it best, the
//! largest z = gᵀΔv/|g| over every point of a grid (the matched filter of
//! [`super::detect`]), which the search for presses runs a dozen times a frame.
//!
//! The responses of the points span few directions: on the paper's sheet the 1,681 points'
//! 120 values lie within 1 % of their own length of their first 55 right singular vectors V.
//! So each scan reads them in that basis: y = VᵀΔv (r values), c̃ = (GV)·y in f32 (points × r,
//! the image product's blocks), against the full G·Δv (points × 120). What the basis misses is
//! bounded, |c − c̃| ≤ |g − VVᵀg|·|Δv − VVᵀΔv| + the f32 rounding of c̃ (per point, both known),
//! so the best point is still the best of the exact z: the largest z any point surely reaches
//! (its bound taken against it) sets a floor, and only the points whose bound reaches over it
//! (a handful around the peak) are scored again exactly, in f64 from their responses. The pick
//! and its z are those of the exact product, from a product of under half its size. (Where the
//! measurements are more than [`MAX_RANK`], the scan reads the responses whole, as before.)
//!
//! Any floor some point surely reaches gives the same pick (a lower one only scores a few more
//! points), so a scan against each point's whole gᵀg takes it at the one point a pass in f32
//! steers to, the largest c̃/|g| under its drop limit and away from the presses found, where
//! that point passes the same test; only elsewhere are all points tested in f64 ([`surest`]).

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, Par, Side};

use super::{dot, PressModel};
use crate::inverse::BlockedMatrix;

/// The largest share of a point's |g| the basis of a scan may miss: the scan's rank is the
/// smallest that leaves every point within it. Smaller costs more rank a product, larger more
/// points scored again around the peak (the bound grows with it).
const MISSED: f64 = 0.01;

/// The responses of a grid's points (every `stride`-th point of the response grid each way), as
/// one matrix, and in the basis its scan reads them in.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Scan {
    /// The response-grid index of each row.
    pub(crate) points: Vec<usize>,
    /// The responses, points × measurements.
    pub(crate) matrix: Mat<f64>,
    /// Per point, gᵀg.
    pub(crate) norms: Vec<f64>,
    /// V: the responses' leading right singular vectors, measurements × rank, row-major, each
    /// row padded with zeros to [`padded`]`(rank)`; `None` where the responses are read whole
    /// (V = I).
    basis: Option<Vec<f64>>,
    /// G·V in f32, in the image product's blocks: every scan's product.
    reduced: BlockedMatrix,
    /// Per point, |g − VVᵀg| (a bound, the rounding of its computation added).
    missed: Vec<f64>,
    /// Per point, |g|.
    roots: Vec<f64>,
    /// Per point, its x and its y (m).
    xs: Vec<f64>,
    ys: Vec<f64>,
    /// Per point, the largest contrast of a press there (the model's; NaN: read from its ladder).
    limits: Vec<f64>,
    /// In f32, for the pass that steers the floor ([`likeliest`]): per point 1/|g|, the
    /// largest c a press there may give (`limits` times gᵀg), x and y.
    steering: Steering,
}

/// A scan's points in f32, for [`likeliest`].
#[derive(Debug, Clone, PartialEq)]
struct Steering {
    inverse_roots: Vec<f32>,
    ceilings: Vec<f32>,
    xs: Vec<f32>,
    ys: Vec<f32>,
}

impl Scan {
    /// The scan of every `stride`-th point of `model`'s response grid each way, outside points
    /// left out.
    pub(crate) fn with_stride(model: &PressModel, stride: usize) -> Scan {
        Scan::read(model, stride, model.measurements <= MAX_RANK)
    }

    /// [`Scan::with_stride`], its responses read in a basis of their own or (`reduce_them`
    /// false) whole.
    fn read(model: &PressModel, stride: usize, reduce_them: bool) -> Scan {
        let [nx, ny] = model.grid.dims;
        let points: Vec<usize> = (0..ny)
            .step_by(stride)
            .flat_map(|row| (0..nx).step_by(stride).map(move |col| row * nx + col))
            .filter(|&j| model.norms[j] > 0.0)
            .collect();
        let m = model.measurements;
        let matrix = Mat::from_fn(points.len(), m, |i, k| model.responses[points[i] * m + k]);
        let norms: Vec<f64> = points.iter().map(|&j| model.norms[j]).collect();
        let (basis, projections, missed) = if reduce_them {
            let (basis, projections, missed) = reduce(&matrix, &norms);
            // Each row padded with zeros to whole blocks of the projection's kernel.
            let (rank, padded) = (basis.ncols(), padded(basis.ncols()));
            let rows =
                (0..m)
                    .flat_map(|q| (0..padded).map(move |k| (q, k)))
                    .map(|(q, k)| if k < rank { basis[(q, k)] } else { 0.0 });
            (Some(rows.collect()), projections, missed)
        } else {
            (None, matrix.clone(), vec![0.0; points.len()])
        };
        let rank = projections.ncols();
        let mut reduced = BlockedMatrix::zeros(points.len(), rank);
        for i in 0..points.len() {
            (0..rank).for_each(|k| reduced.set(i, k, projections[(i, k)] as f32));
        }
        let roots: Vec<f64> = norms.iter().map(|n| n.sqrt()).collect();
        let (xs, ys): (Vec<f64>, Vec<f64>) = points.iter().map(|&j| model.grid.point(j)).map(|[x, y]| (x, y)).unzip();
        let limits: Vec<f64> = points.iter().map(|&j| model.drop_limits[j]).collect();
        let steering = Steering {
            inverse_roots: roots.iter().map(|r| (1.0 / r) as f32).collect(),
            ceilings: limits.iter().zip(&norms).map(|(l, n)| (l * n) as f32).collect(),
            xs: xs.iter().map(|&x| x as f32).collect(),
            ys: ys.iter().map(|&y| y as f32).collect(),
        };
        Scan { points, matrix, norms, basis, reduced, missed, roots, xs, ys, limits, steering }
    }

    /// The row of response-grid point `point`, if it is a scan point.
    pub(crate) fn row(&self, point: usize) -> Option<usize> {
        self.points.binary_search(&point).ok()
    }

    /// The basis's rank: the scan's product's columns.
    pub(crate) fn rank(&self) -> usize {
        self.reduced.columns()
    }

    /// c̃ = (GV)·(VᵀΔv) into `correlations`, in units of the power of two returned with it in
    /// [`Bounds`] (so that the f32 product neither overflows nor leaves the normal range,
    /// whatever Δv's scale); the bound on |c − c̃| is then `missed[i]·outside + rounding·|g|`.
    fn correlate<'a>(
        &'a self,
        dv: &[f64],
        projection: &mut [f64; MAX_RANK],
        correlations: &mut Vec<f32>,
    ) -> Bounds<'a> {
        let r = self.rank();
        let y = match &self.basis {
            Some(basis) => {
                project(basis, dv, &mut projection[..padded(r)]);
                &projection[..r]
            }
            None => dv,
        };
        let largest = y.iter().fold(0.0_f64, |a, y| a.max(y.abs()));
        let unit = if largest > 0.0 && largest.is_finite() { 2.0_f64.powi(largest.log2().ceil() as i32) } else { 1.0 };
        correlations.resize(self.points.len(), 0.0);
        self.reduced.mul_into(correlations, |k| (y[k] / unit) as f32);
        let (dd, yy) = (dot(dv, dv), dot(y, y));
        // |Δv − VVᵀΔv|, its cancellation's rounding added.
        let outside = ((dd - yy).max(0.0) + 1e-12 * dd).sqrt();
        // Each of the r products and sums and the two roundings to f32 within 2⁻²⁴ of itself,
        // and f32's epsilon 2⁻²³ (twice that, for the terms of higher order): of the sum of
        // |aₖyₖ|, at most |a||y| ≤ |g||y| (a = Vᵀg). Then 10⁻¹⁰|Δv| for f64's own rounding of y,
        // of `missed` and of V's departure from orthonormality, whatever the measurements.
        let rounding = (r + 2) as f64 * f64::from(f32::EPSILON) * yy.sqrt() + 1e-10 * dd.sqrt();
        let n = self.points.len();
        Bounds { missed: &self.missed[..n], roots: &self.roots[..n], outside, rounding, unit }
    }
}

/// Points a pass of the scan's selection tests at once.
const LANES: usize = 8;

/// The bound on |c − c̃| of each point of a scan, for one Δv.
struct Bounds<'a> {
    missed: &'a [f64],
    roots: &'a [f64],
    /// |Δv − VVᵀΔv|.
    outside: f64,
    /// The rounding of c̃ per unit of |g|.
    rounding: f64,
    /// The power of two the correlations are in units of.
    unit: f64,
}

impl Bounds<'_> {
    /// The bound at point `i`.
    fn at(&self, i: usize) -> f64 {
        self.missed[i] * self.outside + self.rounding * self.roots[i]
    }

    /// c̃ at point `i` (of `correlations`, in their unit) less and plus its bound.
    fn range(&self, correlations: &[f32], i: usize) -> (f64, f64) {
        let (c, e) = (self.unit * f64::from(correlations[i]), self.at(i));
        (c - e, c + e)
    }
}

/// What [`PressModel::best_point_reaching`] asks of a pick: its z at least `threshold`, with at
/// least `least` of each point's gᵀg unexplained, `share` a point's (its row's) unexplained gᵀg.
pub(crate) struct Reach<F> {
    pub(crate) threshold: f64,
    pub(crate) least: f64,
    pub(crate) share: F,
}

/// The scan points a pick may not be: those within a distance of the presses already found.
struct Away<'a> {
    /// Per point, its x and its y (m).
    xs: &'a [f64],
    ys: &'a [f64],
    /// The presses' centres (m).
    found: &'a [[f64; 2]],
    /// The distance's square (m²).
    apart: f64,
}

/// Whether (`x`, `y`) is not within √`apart` of `centre` (m; squared, without hypot: the test
/// runs for every point a scan tests). A centre not a number is near no point.
#[inline(always)]
fn apart_from(centre: [f64; 2], apart: f64, x: f64, y: f64) -> bool {
    let squared = (centre[0] - x) * (centre[0] - x) + (centre[1] - y) * (centre[1] - y);
    squared >= apart || squared.is_nan()
}

crate::parallel::widest! {
    /// The largest z² some point away from the presses found surely reaches: over the points
    /// whose c̃ less its bound (`low`) is positive and finite and whose c̃ plus it is a contrast
    /// of at most their `limits` (a NaN limit: never sure), the largest low²/`left`; 0 if none.
    fn surest = surest_portable(bounds: &Bounds<'_>, away: &Away<'_>, c: &[f32], left: &[f64], norms: &[f64], limits: &[f64]) -> f64
}

/// Per lane of [`surest`], the largest low²/left so far, as a fraction (no division a point).
struct Largest {
    num: [f64; LANES],
    den: [f64; LANES],
}

/// The kernel: [`LANES`] lanes without a branch (a smooth field scanned row after row sets a
/// new largest at most points on its way up to a peak), the last chunk overlapping the one
/// before it (a point counted twice leaves a largest as it is).
#[inline(always)]
fn surest_portable(
    bounds: &Bounds<'_>,
    away: &Away<'_>,
    c: &[f32],
    left: &[f64],
    norms: &[f64],
    limits: &[f64],
) -> f64 {
    let n = c.len().min(left.len()).min(norms.len()).min(limits.len()).min(bounds.missed.len());
    let n = n.min(bounds.roots.len()).min(away.xs.len()).min(away.ys.len());
    let mut largest = Largest { num: [0.0; LANES], den: [1.0; LANES] };
    let (c, left, norms, limits) = (&c[..n], &left[..n], &norms[..n], &limits[..n]);
    if n < LANES {
        (0..n).for_each(|at| consider::<1>(bounds, away, c, left, [norms, limits], at, &mut largest));
    } else {
        let mut at = 0;
        while at < n {
            consider::<LANES>(bounds, away, c, left, [norms, limits], at.min(n - LANES), &mut largest);
            at += LANES;
        }
    }
    largest.num.iter().zip(&largest.den).fold(0.0, |floor: f64, (num, den)| floor.max(num / den))
}

/// [`surest`]'s points `at`..`at + L` into the first `L` lanes of `largest`, each test in a
/// plain loop over the lanes (a closure called a point may be left uninlined).
#[inline(always)]
fn consider<const L: usize>(
    bounds: &Bounds<'_>,
    away: &Away<'_>,
    c: &[f32],
    left: &[f64],
    [norms, limits]: [&[f64]; 2],
    at: usize,
    largest: &mut Largest,
) {
    let Bounds { missed, roots, outside, rounding, unit } = *bounds;
    let Away { xs, ys, found, apart } = *away;
    let (c, left, norms, limits) = (&c[at..at + L], &left[at..at + L], &norms[at..at + L], &limits[at..at + L]);
    let (missed, roots, xs, ys) = (&missed[at..at + L], &roots[at..at + L], &xs[at..at + L], &ys[at..at + L]);
    // low², 0 where not sure (then never larger): selections of values, not masks of bytes.
    let mut q = [0.0; L];
    for k in 0..L {
        let (c, e) = (unit * f64::from(c[k]), missed[k] * outside + rounding * roots[k]);
        let (low, high) = (c - e, c + e);
        // low positive and finite (it is at most high); compared as values, which stay in vectors.
        // (high ≤ limit·norm in place of high/norm ≤ limit: c is under high by more than the
        // product's rounding, the bound's own margin.)
        let sure = (low > 0.0) & (high < f64::INFINITY) & (high <= limits[k] * norms[k]);
        q[k] = if sure { low * low } else { 0.0 };
    }
    for f in found {
        for k in 0..L {
            q[k] = if apart_from(*f, apart, xs[k], ys[k]) { q[k] } else { 0.0 };
        }
    }
    for k in 0..L {
        let larger = q[k] * largest.den[k] > largest.num[k] * left[k];
        largest.num[k] = if larger { q[k] } else { largest.num[k] };
        largest.den[k] = if larger { left[k] } else { largest.den[k] };
    }
}

crate::parallel::widest! {
    /// The point of the largest c̃/|g| (`c` times the inverse roots, f32) among those whose c̃ is
    /// at most its ceiling times `per_unit` (the inverse of the correlations' unit; NaN: none)
    /// and at least √`apart` from each of `found`: where the largest sure z is likeliest to
    /// be, so that [`surest`]'s floor can be had from that point alone. `None` if no point's
    /// c̃ there is positive.
    fn likeliest = likeliest_portable(c: &[f32], steering: &Steering, per_unit: f32, found: &[[f32; 2]], apart: f32) -> Option<usize>
}

/// Points [`likeliest`] takes at once (a 512-bit vector of f32).
const STEER_LANES: usize = 16;

/// The kernel: [`STEER_LANES`] lanes without a branch, each keeping its largest and where; the
/// last chunk overlapping the one before it (a point seen twice is not larger than itself).
#[inline(always)]
fn likeliest_portable(c: &[f32], steering: &Steering, per_unit: f32, found: &[[f32; 2]], apart: f32) -> Option<usize> {
    let Steering { inverse_roots, ceilings, xs, ys } = steering;
    let n = c.len().min(inverse_roots.len()).min(ceilings.len()).min(xs.len()).min(ys.len());
    let points = [&c[..n], &inverse_roots[..n], &ceilings[..n], &xs[..n], &ys[..n]];
    let mut largest = ([0.0_f32; STEER_LANES], [0_u32; STEER_LANES]);
    if n < STEER_LANES {
        (0..n).for_each(|at| steer::<1>(points, per_unit, found, apart, at, &mut largest));
    } else {
        let mut at = 0;
        while at < n {
            steer::<STEER_LANES>(points, per_unit, found, apart, at.min(n - STEER_LANES), &mut largest);
            at += STEER_LANES;
        }
    }
    let (values, places) = largest;
    let lane = (0..STEER_LANES).fold(0, |best, k| if values[k] > values[best] { k } else { best });
    (values[lane] > 0.0).then_some(places[lane] as usize + lane)
}

/// [`likeliest`]'s points `at`..`at + L` into the first `L` lanes of `largest` (values, and the
/// first point of the chunk each was found in: lane k's point is that plus k).
#[inline(always)]
fn steer<const L: usize>(
    [c, inverse_roots, ceilings, xs, ys]: [&[f32]; 5],
    per_unit: f32,
    found: &[[f32; 2]],
    apart: f32,
    at: usize,
    (values, places): &mut ([f32; STEER_LANES], [u32; STEER_LANES]),
) {
    let (c, inverse_roots, ceilings) = (&c[at..at + L], &inverse_roots[at..at + L], &ceilings[at..at + L]);
    let (xs, ys) = (&xs[at..at + L], &ys[at..at + L]);
    // Both products for every lane, then a selection (a product under a condition was branched).
    let (mut v, mut below) = ([0.0_f32; L], [false; L]);
    for k in 0..L {
        v[k] = c[k] * inverse_roots[k];
        below[k] = c[k] <= ceilings[k] * per_unit;
    }
    for k in 0..L {
        v[k] = if below[k] { v[k] } else { 0.0 };
    }
    for f in found {
        for k in 0..L {
            let (dx, dy) = (xs[k] - f[0], ys[k] - f[1]);
            v[k] = if dx * dx + dy * dy < apart { 0.0 } else { v[k] };
        }
    }
    // Each lane's chunk, not its point: one value for all lanes, so the selections stay in vectors.
    let chunk = at as u32;
    for k in 0..L {
        let larger = v[k] > values[k];
        values[k] = if larger { v[k] } else { values[k] };
        places[k] = if larger { chunk } else { places[k] };
    }
}

/// The most presses found [`likeliest`] steers with (more: [`surest`] alone).
const STEERED: usize = 64;

/// [`surest`]'s z² at the one point [`likeliest`] steers to, if that point is sure (the same
/// test, in f64): no higher than `surest`'s floor, so the pick is the same, and one pass over
/// the points in f32 where `surest`'s tests each in f64. `left` must be each point's gᵀg.
fn steered_floor(scan: &Scan, bounds: &Bounds<'_>, away: &Away<'_>, c: &[f32], left: &[f64]) -> Option<f64> {
    if away.found.len() > STEERED {
        return None;
    }
    let mut centres = [[0.0_f32; 2]; STEERED];
    centres.iter_mut().zip(away.found).for_each(|(to, f)| *to = [f[0] as f32, f[1] as f32]);
    let per_unit = (1.0 / bounds.unit) as f32;
    let i = likeliest(c, &scan.steering, per_unit, &centres[..away.found.len()], away.apart as f32)?;
    let n = c.len();
    let mut one = Largest { num: [0.0; LANES], den: [1.0; LANES] };
    consider::<1>(bounds, away, c, left, [&scan.norms[..n], &scan.limits[..n]], i, &mut one);
    let floor = one.num[0] / one.den[0];
    (floor > 0.0).then_some(floor)
}

crate::parallel::widest! {
    /// The first point from `start` on, away from the presses found, whose c̃ plus its bound
    /// is positive with a square of at least `floor`·`left`, or not a number: whose c may be
    /// as large; if any.
    fn next_reaching = next_reaching_portable(bounds: &Bounds<'_>, away: &Away<'_>, c: &[f32], left: &[f64], floor: f64, start: usize) -> Option<usize>
}

/// The kernel: [`LANES`] points tested at once without a branch (c's sign, the noise's where
/// there is no press, is a coin toss), then the first of a chunk that passes.
#[inline(always)]
fn next_reaching_portable(
    bounds: &Bounds<'_>,
    away: &Away<'_>,
    c: &[f32],
    left: &[f64],
    floor: f64,
    start: usize,
) -> Option<usize> {
    let Bounds { missed, roots, outside, rounding, unit } = *bounds;
    let Away { xs, ys, found, apart } = *away;
    let n = c.len().min(left.len()).min(missed.len()).min(roots.len()).min(xs.len()).min(ys.len());
    let reaches = |c: f32, missed: f64, root: f64, left: f64| {
        let v = unit * f64::from(c) + (missed * outside + rounding * root);
        ((v > 0.0) & (v * v >= floor * left)) | v.is_nan()
    };
    let passes = |i: usize| {
        reaches(c[i], missed[i], roots[i], left[i]) && found.iter().all(|f| apart_from(*f, apart, xs[i], ys[i]))
    };
    let first = |from: usize, to: usize| (from..to).find(|&i| passes(i));
    let mut at = start;
    while at + LANES <= n {
        let mut pass = [false; LANES];
        let (cs, ms, rs, ls) =
            (&c[at..at + LANES], &missed[at..at + LANES], &roots[at..at + LANES], &left[at..at + LANES]);
        for (k, pass) in pass.iter_mut().enumerate() {
            *pass = reaches(cs[k], ms[k], rs[k], ls[k]);
        }
        // None reaches (most chunks): no distances to the presses found.
        if !pass.iter().fold(false, |any, p| any | p) {
            at += LANES;
            continue;
        }
        // Each press found against the chunk's eight points at once.
        let (x, y) = (&xs[at..at + LANES], &ys[at..at + LANES]);
        for f in found {
            for (k, pass) in pass.iter_mut().enumerate() {
                *pass &= apart_from(*f, apart, x[k], y[k]);
            }
        }
        if pass.iter().fold(false, |any, p| any | p) {
            return first(at, at + LANES);
        }
        at += LANES;
    }
    first(at.min(n), n)
}

crate::parallel::widest! {
    /// y = Vᵀ·`dv`, V `basis` (measurements × `y.len()`, row-major; `y.len()` a multiple of
    /// [`BLOCK`]): each measurement's row added in.
    fn project = project_portable(basis: &[f64], dv: &[f64], y: &mut [f64]) -> ()
}

/// The kernel: y's r values in lanes, one row of V a measurement.
#[inline(always)]
fn project_portable(basis: &[f64], dv: &[f64], y: &mut [f64]) {
    let width = y.len();
    if width == 0 {
        return;
    }
    // A block of y in registers while every row adds into it (a row of y in memory read and
    // written back each measurement, and a tail of a row done one value at a time, took three
    // times as long); each value's sum in the order of the measurements, as before.
    for (at, out) in y.chunks_exact_mut(BLOCK).enumerate().map(|(b, out)| (b * BLOCK, out)) {
        let mut sums = [0.0; BLOCK];
        for (row, d) in basis.chunks_exact(width).zip(dv) {
            let row = &row[at..at + BLOCK];
            for k in 0..BLOCK {
                sums[k] += d * row[k];
            }
        }
        out.copy_from_slice(&sums);
    }
}

/// Values of y [`project`] holds in registers at once (eight of the widest vectors).
const BLOCK: usize = 64;

/// `rank` rounded up to whole blocks of [`project`].
fn padded(rank: usize) -> usize {
    rank.div_ceil(BLOCK) * BLOCK
}

/// The most measurements whose scan reads its responses in a basis of their own (the projection
/// of Δv, at most as many values, lives on the stack; past it, the basis's decomposition would
/// cost seconds).
const MAX_RANK: usize = 512;

/// V, G·V and per row |g − VVᵀg| of `matrix` (points × measurements, rows' gᵀg `norms`): the
/// eigenvectors of GᵀG by decreasing eigenvalue, as many as leave every row within
/// [`MISSED`] of its length (all of them where the eigen-decomposition fails).
fn reduce(matrix: &Mat<f64>, norms: &[f64]) -> (Mat<f64>, Mat<f64>, Vec<f64>) {
    let (points, m) = (matrix.nrows(), matrix.ncols());
    let mut gram = Mat::<f64>::zeros(m, m);
    matmul(gram.as_mut(), Accum::Replace, matrix.transpose(), matrix.as_ref(), 1.0, Par::Seq);
    // Decreasing eigenvalue; the identity where there is no decomposition (every row kept whole).
    let order = match gram.self_adjoint_eigen(Side::Lower) {
        Ok(eigen) => Mat::from_fn(m, m, |q, k| eigen.U()[(q, m - 1 - k)]),
        Err(_) => Mat::identity(m, m),
    };
    let mut projections = Mat::<f64>::zeros(points, m);
    matmul(projections.as_mut(), Accum::Replace, matrix.as_ref(), order.as_ref(), 1.0, Par::Seq);
    // Per row, Σ over the directions left out of its projection's squares: the tail sums.
    let tail = |i: usize, r: usize| (r..m).map(|k| projections[(i, k)].powi(2)).sum::<f64>();
    let fits = |r: usize| (0..points).all(|i| tail(i, r) <= MISSED * MISSED * norms[i]);
    let rank = (1..=m).find(|&r| fits(r)).unwrap_or(m);
    // The eigenvectors' own departure from orthonormality is about 1e-14 of a row's length.
    let missed = (0..points).map(|i| tail(i, rank).sqrt() + 1e-12 * norms[i].sqrt()).collect();
    let basis = order.subcols(0, rank).to_owned();
    let projections = projections.subcols(0, rank).to_owned();
    (basis, projections, missed)
}

impl PressModel {
    /// The point of `scan` whose press matches `dv` best, with its z = gᵀΔv/|g| (for a press:
    /// gᵀΔv > 0, and a drop of at most the whole conductivity), leaving out points within two
    /// indenter radii of `found` (m); `None` if no point's does. The fit then refines it on the
    /// full grid. `correlations` is a buffer.
    pub(crate) fn best_point(
        &self,
        scan: &Scan,
        dv: &[f64],
        found: &[[f64; 2]],
        correlations: &mut Vec<f32>,
    ) -> Option<(usize, f64)> {
        let mut projection = [0.0; MAX_RANK];
        let bounds = scan.correlate(dv, &mut projection, correlations);
        self.pick(scan, &bounds, dv, found, &scan.norms, correlations, true)
    }

    /// [`PressModel::best_point`] with z = gᵀΔv/√`unexplained`: per scan point, the part of gᵀg
    /// the presses already fitted cannot take up by moving (for a Δv orthogonal to what they can;
    /// positive). `scan` must be of this model (its points' responses are read to score them
    /// exactly); points past `unexplained`'s length are not scanned.
    pub(crate) fn best_point_in(
        &self,
        scan: &Scan,
        dv: &[f64],
        found: &[[f64; 2]],
        unexplained: &[f64],
        correlations: &mut Vec<f32>,
    ) -> Option<(usize, f64)> {
        let mut projection = [0.0; MAX_RANK];
        let bounds = scan.correlate(dv, &mut projection, correlations);
        self.pick(scan, &bounds, dv, found, unexplained, correlations, false)
    }

    /// [`PressModel::best_point_in`] where only the pick matters if its z reaches `reach`'s
    /// threshold: the unexplained share is computed (`reach.share` of a point's row, into
    /// `unexplained`) only at the points whose z could reach it, at least `reach.least` of their
    /// gᵀg left; the others' share is +∞ (never picked). So the pick is `best_point_in`'s with
    /// every share computed wherever that pick's z reaches the threshold.
    pub(crate) fn best_point_reaching(
        &self,
        scan: &Scan,
        dv: &[f64],
        found: &[[f64; 2]],
        reach: Reach<impl Fn(usize) -> f64>,
        unexplained: &mut Vec<f64>,
        correlations: &mut Vec<f32>,
    ) -> Option<(usize, f64)> {
        let mut projection = [0.0; MAX_RANK];
        let bounds = scan.correlate(dv, &mut projection, correlations);
        // z = c/√u ≤ high/√(least·gᵀg): within reach where high² ≥ threshold²·least·gᵀg, the
        // test [`next_reaching`] makes of a floor against each point's gᵀg (a few points a scan).
        let within = reach.threshold.powi(2) * reach.least;
        let away = Away { xs: &scan.xs, ys: &scan.ys, found, apart: self.apart() };
        unexplained.clear();
        unexplained.resize(scan.points.len(), f64::INFINITY);
        let mut i = 0;
        while let Some(at) = next_reaching(&bounds, &away, correlations, &scan.norms, within, i) {
            unexplained[at] = (reach.share)(at);
            i = at + 1;
        }
        self.pick(scan, &bounds, dv, found, unexplained, correlations, false)
    }

    /// The square of the distance from a press found within which no point is picked (m²):
    /// two indenter radii.
    fn apart(&self) -> f64 {
        (2.0 * self.radius).powi(2)
    }

    /// The pick of a scan whose correlations of `dv` and their `bounds` are made (see
    /// [`PressModel::best_point_in`]); with `steer` (`unexplained` each point's gᵀg), the floor
    /// from the point [`likeliest`] steers to where it is sure.
    #[allow(clippy::too_many_arguments, reason = "the scan's pieces and the one choice of how its floor is found")]
    fn pick(
        &self,
        scan: &Scan,
        bounds: &Bounds<'_>,
        dv: &[f64],
        found: &[[f64; 2]],
        unexplained: &[f64],
        correlations: &[f32],
        steer: bool,
    ) -> Option<(usize, f64)> {
        // Not within two indenter radii of a press found.
        let n = scan.points.len().min(unexplained.len());
        let away = Away { xs: &scan.xs[..n], ys: &scan.ys[..n], found, apart: self.apart() };
        let (c, left) = (&correlations[..n], &unexplained[..n]);
        // The largest z² some point surely reaches (its c's bound below, its drop's above), or
        // one sure point's: a floor no higher, so the same pick.
        let steered = if steer { steered_floor(scan, bounds, &away, c, left) } else { None };
        let floor = steered.unwrap_or_else(|| surest(bounds, &away, c, left, &scan.norms[..n], &scan.limits[..n]));
        // Every point whose bound reaches that floor, scored exactly; the first of the largest.
        let mut best: Option<(usize, f64)> = None;
        let mut i = 0;
        while let Some(at) = next_reaching(bounds, &away, c, left, floor, i) {
            i = at + 1;
            let (j, (_, high)) = (scan.points[at], bounds.range(c, at));
            if best.is_some_and(|(_, b)| high * high <= b * b * left[at]) {
                continue;
            }
            let c = dot(self.grid_response(j), dv);
            if c <= 0.0 || self.too_deep(c / scan.norms[at], j) {
                continue;
            }
            let z = c / left[at].sqrt();
            if best.is_none_or(|(_, b)| z > b) {
                best = Some((j, z));
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::press_fit::PressModelParams;
    use crate::{SeededRng, SensorSpec};
    use rand::{RngExt, SeedableRng};
    use rand_distr::StandardNormal;

    /// A whitened press model of the paper's sheet on a coarse mesh, and its scan.
    fn whitened() -> (PressModel, Scan) {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 1500;
        let model = spec.forward_model().unwrap();
        let values = model.measure(&spec.homogeneous(model.mesh())).unwrap();
        let press = PressModel::new(&model, spec.conductivity, &PressModelParams::default()).unwrap();
        let std: Vec<f64> = values.iter().map(|v| 5e-4 * v.abs()).collect();
        let press = press.whitened(&std);
        let scan = Scan::with_stride(&press, 2);
        (press, scan)
    }

    /// Δv of whitened noise and up to two presses of z up to 60, at random places; for `case`
    /// 1 and 2 of every five the same scaled by 10⁴⁰ and 10⁻⁴⁵ (past f32's range), for 3 and 4
    /// only its part outside the scan's basis and only its part inside it (where the bound is
    /// tightest and where it is rounding alone).
    fn frame(press: &PressModel, scan: &Scan, case: usize, rng: &mut SeededRng) -> Vec<f64> {
        let m = press.measurements();
        let mut dv: Vec<f64> = (0..m).map(|_| rng.sample(StandardNormal)).collect();
        let mut g = vec![0.0; m];
        for _ in 0..rng.random_range(0..3) {
            let p = [rng.random_range(-0.09..0.09), rng.random_range(-0.09..0.09)];
            if press.response_into(p, &mut g) {
                let scale = rng.random_range(0.0..60.0) / dot(&g, &g).sqrt();
                dv.iter_mut().zip(&g).for_each(|(d, g)| *d += scale * g);
            }
        }
        let (r, basis) = (padded(scan.rank()), scan.basis.as_deref().unwrap_or(&[]));
        let mut y = vec![0.0; r];
        project(basis, &dv, &mut y);
        let inside: Vec<f64> = (0..m).map(|q| dot(&basis[q * r..(q + 1) * r], &y)).collect();
        match case % 5 {
            1 => dv.iter_mut().for_each(|d| *d *= 1e40),
            2 => dv.iter_mut().for_each(|d| *d *= 1e-45),
            3 if r > 0 => dv.iter_mut().zip(&inside).for_each(|(d, i)| *d -= i),
            4 if r > 0 => dv.copy_from_slice(&inside),
            _ => {}
        }
        dv
    }

    /// The scan's basis leaves out most directions of the paper's sheet, and its bound holds at
    /// every point, in that basis and with the responses read whole: |c − c̃| for c in f64 from
    /// the responses themselves.
    #[test]
    fn the_bound_holds_at_every_point() {
        let (press, scan) = whitened();
        let m = press.measurements();
        assert!(scan.rank() < m * 2 / 3, "rank {} of {m}", scan.rank());
        let mut rng = SeededRng::seed_from_u64(5);
        let (mut projection, mut correlations) = ([0.0; MAX_RANK], Vec::new());
        let whole = Scan::read(&press, 2, false);
        for case in 0..50 {
            let dv = frame(&press, &scan, case, &mut rng);
            for scan in [&scan, &whole] {
                let bounds = scan.correlate(&dv, &mut projection, &mut correlations);
                for (i, &j) in scan.points.iter().enumerate() {
                    let c = dot(&press.responses[j * m..(j + 1) * m], &dv);
                    let off = (c - bounds.unit * f64::from(correlations[i])).abs();
                    assert!(off <= bounds.at(i), "point {i}: {off} over its bound {}", bounds.at(i));
                }
            }
        }
    }

    /// The pick and its z are those of scoring every point exactly, with presses found left out
    /// and the share of gᵀg left unexplained in the z, and with the whole gᵀg (the floor
    /// steered to one point); with the responses in their basis, and read whole.
    #[test]
    fn the_pick_is_the_exact_scans() {
        let (press, scan) = whitened();
        let whole = Scan::read(&press, 2, false);
        assert_eq!(whole.rank(), press.measurements());
        let m = press.measurements();
        let mut rng = SeededRng::seed_from_u64(6);
        let mut correlations = Vec::new();
        let apart = (2.0 * press.radius()).powi(2);
        let mut steered_floors = 0;
        for case in 0..200 {
            let dv = frame(&press, &scan, case, &mut rng);
            let found: Vec<[f64; 2]> = (0..rng.random_range(0..3))
                .map(|_| [rng.random_range(-0.1..0.1), rng.random_range(-0.1..0.1)])
                .collect();
            let unexplained: Vec<f64> = scan.norms.iter().map(|n| n * rng.random_range(0.25..=1.0)).collect();
            let exact_with = |left: &[f64]| {
                let mut exact: Option<(usize, f64)> = None;
                for (i, &j) in scan.points.iter().enumerate() {
                    let p = press.grid.point(j);
                    let c = dot(&press.responses[j * m..(j + 1) * m], &dv);
                    let near = found.iter().any(|f| (f[0] - p[0]).powi(2) + (f[1] - p[1]).powi(2) < apart);
                    if c <= 0.0 || near || press.too_deep(c / scan.norms[i], j) {
                        continue;
                    }
                    let z = c / left[i].sqrt();
                    if exact.is_none_or(|(_, b)| z > b) {
                        exact = Some((j, z));
                    }
                }
                exact
            };
            let (exact, exact_whole) = (exact_with(&unexplained), exact_with(&scan.norms));
            for scan in [&scan, &whole] {
                let picked = press.best_point_in(scan, &dv, &found, &unexplained, &mut correlations);
                assert_eq!(picked.map(|(j, _)| j), exact.map(|(j, _)| j), "case {case}");
                // The same z to the bit: the same product, the same division.
                assert_eq!(picked.map(|(_, z)| z.to_bits()), exact.map(|(_, z)| z.to_bits()), "case {case}");
                let steered = press.best_point(scan, &dv, &found, &mut correlations);
                let bits = |p: Option<(usize, f64)>| p.map(|(j, z)| (j, z.to_bits()));
                assert_eq!(bits(steered), bits(exact_whole), "case {case}, steered");
                // How often the floor came from the steered point (else every point was tested).
                let mut projection = [0.0; MAX_RANK];
                let bounds = scan.correlate(&dv, &mut projection, &mut correlations);
                let away = Away { xs: &scan.xs, ys: &scan.ys, found: &found, apart };
                steered_floors +=
                    usize::from(steered_floor(scan, &bounds, &away, &correlations, &scan.norms).is_some());
            }
        }
        assert!(press.best_point(&scan, &vec![0.0; m], &[], &mut correlations).is_none());
        assert!(steered_floors >= 200, "the floor steered in {steered_floors} of 400 scans");
    }

    /// A new press's scan computes each point's unexplained share only where a z of the
    /// threshold is within reach: wherever the pick with every share computed reaches the
    /// threshold, it is the same point and the same z to the bit; else nothing reaches it. Each
    /// point's share is the tracker's, computed for all points at once.
    #[test]
    fn the_pick_within_reach_is_the_pick_with_every_share() {
        use crate::press_fit::joint::{orthonormal_rows, unexplained_at, unexplained_into, UNEXPLAINED_FLOOR};
        let (press, scan) = whitened();
        let m = press.measurements();
        let mut rng = SeededRng::seed_from_u64(9);
        let (mut correlations, mut unexplained, mut basis) = (Vec::new(), Vec::new(), Vec::new());
        let (mut projections, mut whole_product) = (Mat::zeros(0, 0), Vec::new());
        let mut reached = 0;
        for case in 0..200 {
            let dv = frame(&press, &scan, case, &mut rng);
            // Responses of a few scan points: the points near them keep little of their gᵀg.
            let picks: Vec<usize> =
                (0..rng.random_range(1..10)).map(|_| rng.random_range(0..scan.points.len())).collect();
            let rows = Mat::from_fn(picks.len(), m, |a, q| press.responses[scan.points[picks[a]] * m + q]);
            let rank = orthonormal_rows(rows.as_ref(), &mut basis);
            let found: Vec<[f64; 2]> = (0..rng.random_range(0..3))
                .map(|_| [rng.random_range(-0.1..0.1), rng.random_range(-0.1..0.1)])
                .collect();
            let every: Vec<f64> = (0..scan.points.len())
                .map(|i| unexplained_at(&press.responses[scan.points[i] * m..][..m], scan.norms[i], &basis, rank))
                .collect();
            // The same shares as the tracker's one product for every point, to rounding.
            unexplained_into(&scan, &basis, rank, &mut projections, &mut whole_product);
            for (a, b) in every.iter().zip(&whole_product) {
                assert!((a - b).abs() <= 1e-12 * b, "case {case}: {a} against {b}");
            }
            let whole = press.best_point_in(&scan, &dv, &found, &every, &mut correlations);
            let threshold = rng.random_range(2.0..8.0);
            let reach = Reach { threshold, least: UNEXPLAINED_FLOOR, share: |i: usize| every[i] };
            let within = press.best_point_reaching(&scan, &dv, &found, reach, &mut unexplained, &mut correlations);
            match whole {
                Some((j, z)) if z >= threshold => {
                    reached += 1;
                    assert_eq!(within.map(|(j, z)| (j, z.to_bits())), Some((j, z.to_bits())), "case {case}");
                }
                _ => assert!(within.is_none_or(|(_, z)| z < threshold), "case {case}"),
            }
        }
        assert!(reached >= 40, "{reached} of 200 picks reached the threshold");
    }

    /// The steering pass takes the point of the largest c/|g| under its ceiling and away from the
    /// presses found, at any count of points (fewer than a chunk, a last chunk overlapping the
    /// one before): against one point after another.
    #[test]
    fn the_steering_takes_the_largest_eligible_ratio() {
        let mut rng = SeededRng::seed_from_u64(10);
        for trial in 0..400 {
            let n = trial % 50;
            let values = |rng: &mut SeededRng, lo: f32, hi: f32| (0..n).map(|_| rng.random_range(lo..hi)).collect();
            let mut c: Vec<f32> = values(&mut rng, -1.0, 4.0);
            c.iter_mut().skip(3).step_by(11).for_each(|c| *c = f32::NAN);
            let mut ceilings: Vec<f32> = values(&mut rng, 0.0, 6.0);
            ceilings.iter_mut().step_by(7).for_each(|l| *l = f32::NAN);
            let steering = Steering {
                inverse_roots: values(&mut rng, 0.5, 2.0),
                ceilings,
                xs: values(&mut rng, 0.0, 1.0),
                ys: values(&mut rng, 0.0, 1.0),
            };
            let found = [[0.3_f32, 0.4], [0.8, 0.1]];
            let found = &found[..trial % 3];
            let per_unit = 0.5;
            let eligible = |i: usize| {
                c[i] <= steering.ceilings[i] * per_unit
                    && found.iter().all(|f| (steering.xs[i] - f[0]).powi(2) + (steering.ys[i] - f[1]).powi(2) >= 0.04)
            };
            let ratio = |i: usize| c[i] * steering.inverse_roots[i];
            let best = (0..n).filter(|&i| eligible(i) && ratio(i) > 0.0).map(ratio).fold(0.0_f32, f32::max);
            match likeliest(&c, &steering, per_unit, found, 0.04) {
                Some(i) => assert!(eligible(i) && ratio(i) == best, "trial {trial}, {n} points: {i}"),
                None => assert_eq!(best, 0.0, "trial {trial}, {n} points"),
            }
        }
    }

    /// The floor's kernel takes the largest low²/left of the points surely reached, eligible and
    /// away from the presses found, at any count of points (fewer than a chunk, a last chunk
    /// overlapping the one before): against one point after another.
    #[test]
    fn the_floor_is_the_largest_sure_z() {
        let mut rng = SeededRng::seed_from_u64(8);
        for trial in 0..400 {
            let n = trial % 40;
            let values = |rng: &mut SeededRng, lo: f64, hi: f64| (0..n).map(|_| rng.random_range(lo..hi)).collect();
            let c: Vec<f32> = (0..n).map(|_| rng.random_range(-1.0..4.0)).collect();
            let (missed, roots): (Vec<f64>, Vec<f64>) = (values(&mut rng, 0.0, 0.1), values(&mut rng, 0.5, 2.0));
            let (left, norms): (Vec<f64>, Vec<f64>) = (values(&mut rng, 0.5, 2.0), values(&mut rng, 0.5, 2.0));
            let mut limits: Vec<f64> = values(&mut rng, 0.5, 4.0);
            limits.iter_mut().step_by(7).for_each(|l| *l = f64::NAN);
            // Points never picked (an unexplained share not computed) and a correlation not a number.
            let (mut left, mut c) = (left, c);
            left.iter_mut().skip(2).step_by(5).for_each(|l| *l = f64::INFINITY);
            c.iter_mut().skip(3).step_by(11).for_each(|c| *c = f32::NAN);
            let (xs, ys): (Vec<f64>, Vec<f64>) = (values(&mut rng, 0.0, 1.0), values(&mut rng, 0.0, 1.0));
            let bounds = Bounds { missed: &missed, roots: &roots, outside: 1.3, rounding: 1e-3, unit: 0.5 };
            let found = [[0.3, 0.4], [0.8, 0.1]];
            let away = Away { xs: &xs, ys: &ys, found: &found[..trial % 3], apart: 0.04 };
            let mut expected = 0.0_f64;
            for i in 0..n {
                let (low, high) = bounds.range(&c, i);
                let apart = away.found.iter().all(|f| (f[0] - xs[i]).powi(2) + (f[1] - ys[i]).powi(2) >= 0.04);
                if low > 0.0 && high <= limits[i] * norms[i] && apart {
                    expected = expected.max(low * low / left[i]);
                }
            }
            let floor = surest(&bounds, &away, &c, &left, &norms, &limits);
            assert_eq!(floor.to_bits(), expected.to_bits(), "trial {trial}, {n} points");
        }
    }
}
