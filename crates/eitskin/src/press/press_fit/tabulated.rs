//! One press's exact response ([`ExactPresses`]) at the indenter's radius, tabulated over the
//! sheet and over its drop, read back with its derivatives along x, y and the drop in about a
//! microsecond: what lets a joint fit of presses found afresh iterate without a solve.
//!
//! At each point of a square grid (a quarter of the indenter's radius apart, one ring before
//! the box the centres may take and two past it) Δv(d)/d is solved at [`NODES`] Chebyshev drops in [0, [`DEEPEST`]] and kept
//! as its Chebyshev coefficients (f32): Δv(d)/d = 1/(1 − k·d − …) along each channel is smooth
//! on that interval (its pole lies past d = 1), so the series is within 3·10⁻⁴ of the solved
//! response at the median drop on the paper's sensor. Between grid points it is read by
//! Catmull–Rom cubics in x and y (within 0.2 % at the median place; next to an electrode,
//! where a press's response turns within a grid step, up to 10 %).
//!
//! Beside it, the response's derivative along the radius, tabulated the same way (each point's
//! solve gives it for a few microseconds more): what a fit's test of a press's size reads.
//!
//! The table knows one press alone; what presses nearer each other than
//! [`TABLE_START_APART`](super::TABLE_START_APART) radii change of each other's field, and what
//! it misses of one, a fit takes from one exact solve of them together
//! ([`refine_tabulated`](super::refine_tabulated)).

use rayon::prelude::*;

use super::exact::{Disk, DiskParameter, ExactPresses, ExactScratch};
use super::refine::DEEPEST;
use super::Grid;
use crate::forward::ForwardError;

/// Drops solved per grid point: the Chebyshev series' terms.
pub const NODES: usize = 6;

/// Rows of coefficients per grid point: the response's series, then its radius derivative's.
const PER_POINT: usize = 2 * NODES;

/// Grid points read around a place: 4 × 4 for the bicubic.
const STENCIL: usize = 16;

/// Channels summed at once (a 512-bit vector of f32): each point's rows are padded to a
/// multiple of it.
const LANES: usize = 16;

/// One press's exact response at one radius, tabulated over the sheet and its drop.
#[derive(Debug, Clone)]
pub struct TabulatedPresses {
    grid: Grid,
    radius: f64,
    measurements: usize,
    /// `measurements` rounded up to [`LANES`].
    stride: usize,
    /// Per grid point (row-major from the grid's first), per Chebyshev term, `stride`
    /// coefficients of Δv(d)/d (V), then as many of (∂Δv/∂r)(d)/d (V/m); the last `stride −
    /// measurements` of each row 0.
    coefficients: Vec<f32>,
    /// Whether every point's radius derivative was solved (not where a press is solved in full).
    radius_derivatives: bool,
}

/// Where a [`TabulatedPresses::jet_into`] reads: each of the 16 grid points' first coefficient,
/// and its weights for the value and its derivatives along x and y (per m).
struct Stencil {
    rows: [usize; STENCIL],
    weights: [[f32; 3]; STENCIL],
}

impl TabulatedPresses {
    /// Tabulates `exact`'s response to a press of `radius` (m) over the box `bounds` (m, `[min,
    /// max]`: the centres a fit may take) at `spacing` (m), the grid points in parallel.
    pub fn new(
        exact: &ExactPresses,
        bounds: [[f64; 2]; 2],
        radius: f64,
        spacing: f64,
    ) -> Result<TabulatedPresses, ForwardError> {
        let grid = grid_over(bounds, spacing);
        let measurements = exact.measurements();
        let stride = padded(measurements);
        let drops = nodes();
        let per_point = (0..grid.len()).into_par_iter().map_init(
            || (ExactScratch::default(), vec![0.0; measurements], vec![0.0; measurements]),
            |(scratch, dv, dr), j| {
                let centre = grid.point(j);
                let mut coefficients = vec![0.0_f32; PER_POINT * stride];
                let mut derived = true;
                for &drop in &drops {
                    let disks = [Disk { centre, radius, drop }];
                    exact.response_into(&disks, scratch, dv)?;
                    derived &= exact.derivative_into(&disks, 0, DiskParameter::Radius, scratch, dr);
                    // c_k = (2 − δ_k0)/N · Σ_n f(t_n)·T_k(t_n), f = Δv/d (and (∂Δv/∂r)/d).
                    let (terms, _) = chebyshev(t_of(drop));
                    for (k, term) in terms.iter().enumerate() {
                        let factor = if k == 0 { 1.0 } else { 2.0 } / NODES as f64 * term / drop;
                        for (at, values) in [(k, &*dv), (NODES + k, &*dr)] {
                            let row = &mut coefficients[at * stride..at * stride + measurements];
                            row.iter_mut().zip(values).for_each(|(c, v)| *c += (factor * v) as f32);
                        }
                    }
                }
                Ok((coefficients, derived))
            },
        );
        let per_point: Vec<(Vec<f32>, bool)> = per_point.collect::<Result<_, ForwardError>>()?;
        let radius_derivatives = per_point.iter().all(|(_, derived)| *derived);
        let coefficients = per_point.into_iter().flat_map(|(c, _)| c).collect();
        Ok(TabulatedPresses { grid, radius, measurements, stride, coefficients, radius_derivatives })
    }

    /// Bytes a table of `measurements` values over `bounds` (m) at `spacing` (m) takes.
    pub fn bytes_for(bounds: [[f64; 2]; 2], spacing: f64, measurements: usize) -> f64 {
        let points = grid_over(bounds, spacing).len() as f64;
        points * (PER_POINT * padded(measurements) * size_of::<f32>()) as f64
    }

    /// The radius of the press it tabulates, in m.
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// Values per response.
    pub fn measurements(&self) -> usize {
        self.measurements
    }

    /// Bytes its coefficients take.
    pub fn bytes(&self) -> usize {
        self.coefficients.len() * size_of::<f32>()
    }

    /// Δv (V) of a press of the table's radius at `centre` (m, clamped into the box it was made
    /// for) with `drop` (a fraction of the background, clamped to [0, [`DEEPEST`]]), and its
    /// derivatives along x and y (V/m) and the drop (V), into `jet` (4 × measurements: value,
    /// x, y, drop). `work` is a buffer. Allocates nothing once `work` has grown (to 4 ×
    /// measurements rounded up to 16).
    pub fn jet_into(&self, centre: [f64; 2], drop: f64, work: &mut Vec<f32>, jet: &mut [f64]) {
        let m = self.measurements;
        assert_eq!(jet.len(), 4 * m, "a jet holds the value and three derivatives");
        let stencil = self.stencil(centre);
        let drop = drop.clamp(0.0, DEEPEST);
        let (terms, slopes) = chebyshev(t_of(drop));
        // d/dd of T_k(t(d)) = T_k'(t)·dt/dd.
        let dt = 2.0 / DEEPEST;
        let terms = terms.map(|t| t as f32);
        let slopes = slopes.map(|s| (s * dt) as f32);
        let stride = self.stride;
        work.clear();
        work.resize(work_len(m), 0.0);
        sum_stencil(work, &self.coefficients, stride, &stencil.rows, &stencil.weights, &terms, &slopes);
        let (sums, derivatives) = work.split_at(stride);
        let (along_x, rest) = derivatives.split_at(stride);
        let (along_y, along_drop) = rest.split_at(stride);
        let (value, rest) = jet.split_at_mut(m);
        let (x, rest) = rest.split_at_mut(m);
        let (y, d) = rest.split_at_mut(m);
        for q in 0..m {
            let f = f64::from(sums[q]);
            value[q] = drop * f;
            x[q] = drop * f64::from(along_x[q]);
            y[q] = drop * f64::from(along_y[q]);
            d[q] = f + drop * f64::from(along_drop[q]);
        }
    }

    /// ∂Δv/∂r (V/m) of a press of the table's radius at `centre` (m, clamped into the box it was
    /// made for) with `drop` (clamped to [0, [`DEEPEST`]]), into `out` (measurements); `false`,
    /// `out` untouched, where the table has no radius derivatives. `work` as
    /// [`TabulatedPresses::jet_into`]'s.
    pub fn radius_derivative_into(&self, centre: [f64; 2], drop: f64, work: &mut Vec<f32>, out: &mut [f64]) -> bool {
        if !self.radius_derivatives {
            return false;
        }
        let mut stencil = self.stencil(centre);
        stencil.rows.iter_mut().for_each(|row| *row += NODES * self.stride);
        let drop = drop.clamp(0.0, DEEPEST);
        let (terms, slopes) = chebyshev(t_of(drop));
        let (terms, slopes) = (terms.map(|t| t as f32), slopes.map(|s| s as f32));
        work.clear();
        work.resize(work_len(self.measurements), 0.0);
        sum_stencil(work, &self.coefficients, self.stride, &stencil.rows, &stencil.weights, &terms, &slopes);
        out.iter_mut().zip(&work[..self.measurements]).for_each(|(o, f)| *o = drop * f64::from(*f));
        true
    }

    /// The 4 × 4 grid points around `centre` and their bicubic weights.
    fn stencil(&self, centre: [f64; 2]) -> Stencil {
        let Grid { lo, spacing, dims } = self.grid;
        let cell = |k: usize| {
            // max and min, not clamp: a NaN centre reads the first cell, never outside the grid.
            let x = ((centre[k] - lo[k]) / spacing).max(1.0).min((dims[k] - 2) as f64);
            let i = (x.floor() as usize).min(dims[k] - 3);
            (i - 1, catmull_rom(x - i as f64))
        };
        let ((i, wx), (j, wy)) = (cell(0), cell(1));
        let mut stencil = Stencil { rows: [0; STENCIL], weights: [[0.0; 3]; STENCIL] };
        for (b, (y, dy)) in wy.into_iter().enumerate() {
            for (a, (x, dx)) in wx.into_iter().enumerate() {
                let s = 4 * b + a;
                stencil.rows[s] = ((j + b) * dims[0] + i + a) * PER_POINT * self.stride;
                stencil.weights[s] = [(x * y) as f32, (dx * y / spacing) as f32, (x * dy / spacing) as f32];
            }
        }
        stencil
    }
}

/// The grid a table over `bounds` at `spacing` is made on: one ring before the box and two
/// past it, so that every place in it has its 4 × 4 stencil.
fn grid_over([lo, hi]: [[f64; 2]; 2], spacing: f64) -> Grid {
    Grid::over([[lo[0] - spacing, lo[1] - spacing], [hi[0] + 2.0 * spacing, hi[1] + 2.0 * spacing]], spacing)
}

/// `measurements` rounded up to [`LANES`]: the length of each row of coefficients.
fn padded(measurements: usize) -> usize {
    measurements.div_ceil(LANES) * LANES
}

/// The length of a [`TabulatedPresses::jet_into`]'s buffer for `measurements` values.
pub(crate) fn work_len(measurements: usize) -> usize {
    4 * padded(measurements)
}

/// The drops the table is solved at: Chebyshev points of [0, [`DEEPEST`]], none at 0.
fn nodes() -> [f64; NODES] {
    std::array::from_fn(|n| {
        let angle = (2 * n + 1) as f64 * std::f64::consts::PI / (2 * NODES) as f64;
        0.5 * DEEPEST * (1.0 - angle.cos())
    })
}

/// The drop's place on the Chebyshev interval [−1, 1].
fn t_of(drop: f64) -> f64 {
    2.0 * drop / DEEPEST - 1.0
}

/// T_k(t) and T_k'(t) for k below [`NODES`].
fn chebyshev(t: f64) -> ([f64; NODES], [f64; NODES]) {
    let (mut terms, mut slopes) = ([0.0; NODES], [0.0; NODES]);
    // T_k' = k·U_{k−1}; U_0 = 1, U_1 = 2t.
    let (mut u_prev, mut u) = (0.0, 1.0);
    for k in 0..NODES {
        terms[k] = match k {
            0 => 1.0,
            1 => t,
            _ => 2.0 * t * terms[k - 1] - terms[k - 2],
        };
        if k > 0 {
            slopes[k] = k as f64 * u;
            (u_prev, u) = (u, 2.0 * t * u - u_prev);
        }
    }
    (terms, slopes)
}

/// Catmull–Rom weights of the points at −1, 0, 1, 2 for a place `f` in [0, 1], each with its
/// derivative along `f`.
fn catmull_rom(f: f64) -> [(f64, f64); 4] {
    let (f2, f3) = (f * f, f * f * f);
    [
        ((-f3 + 2.0 * f2 - f) / 2.0, (-3.0 * f2 + 4.0 * f - 1.0) / 2.0),
        ((3.0 * f3 - 5.0 * f2 + 2.0) / 2.0, (9.0 * f2 - 10.0 * f) / 2.0),
        ((-3.0 * f3 + 4.0 * f2 + f) / 2.0, (-9.0 * f2 + 8.0 * f + 1.0) / 2.0),
        ((f3 - f2) / 2.0, (3.0 * f2 - 2.0 * f) / 2.0),
    ]
}

crate::parallel::widest! {
    /// Into `out` (4 × `stride`: the series' value, along x, along y, along the drop) the
    /// stencil's grid points' series, each weighted.
    fn sum_stencil = sum_stencil_portable(
        out: &mut [f32],
        coefficients: &[f32],
        stride: usize,
        rows: &[usize; STENCIL],
        weights: &[[f32; 3]; STENCIL],
        terms: &[f32; NODES],
        slopes: &[f32; NODES]
    ) -> ()
}

/// Blocks of [`LANES`] channels at a time, their four sums held in registers across the 16
/// points: each coefficient is read once. Each point's series is summed over its terms first
/// (at the drop, and its slope there), then added into the four sums with the point's three
/// weights: 2 multiply-adds a term and 4 a point, where a factor per point and term took 4 a
/// term. Four blocks at once where the processor has 32 vector registers of 16 lanes (AVX-512:
/// their sums and series take 24 of them), one at once elsewhere (AVX2: 6 of its 16 registers
/// of 8 lanes); each sum's order the same either way.
#[inline(always)]
fn sum_stencil_portable(
    out: &mut [f32],
    coefficients: &[f32],
    stride: usize,
    rows: &[usize; STENCIL],
    weights: &[[f32; 3]; STENCIL],
    terms: &[f32; NODES],
    slopes: &[f32; NODES],
) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx512f") {
        return sum_groups::<4>(out, coefficients, stride, rows, weights, terms, slopes);
    }
    sum_groups::<1>(out, coefficients, stride, rows, weights, terms, slopes)
}

/// [`sum_stencil_portable`] `G` blocks at a time.
#[inline(always)]
fn sum_groups<const G: usize>(
    out: &mut [f32],
    coefficients: &[f32],
    stride: usize,
    rows: &[usize; STENCIL],
    weights: &[[f32; 3]; STENCIL],
    terms: &[f32; NODES],
    slopes: &[f32; NODES],
) {
    for first in (0..stride).step_by(G * LANES) {
        let blocks = (stride - first).div_ceil(LANES).min(G);
        let mut sums = [[[0.0_f32; LANES]; 4]; G];
        for (&row, &[w, wx, wy]) in rows.iter().zip(weights) {
            // The point's series at the drop and its slope, block by block.
            let mut series = [[[0.0_f32; LANES]; 2]; G];
            for k in 0..NODES {
                let start = row + k * stride + first;
                // The last group's blocks past the row's end (where the row is not a whole number
                // of groups) read the next row's, or nothing at the table's end: they are summed
                // but not written.
                for (b, [at_drop, slope]) in series.iter_mut().enumerate() {
                    let at = start + b * LANES;
                    let Some(c) = coefficients.get(at..).and_then(|c| c.first_chunk::<LANES>()) else { continue };
                    for l in 0..LANES {
                        at_drop[l] += terms[k] * c[l];
                        slope[l] += slopes[k] * c[l];
                    }
                }
            }
            for (sums, [at_drop, slope]) in sums.iter_mut().zip(&series) {
                for l in 0..LANES {
                    sums[0][l] += w * at_drop[l];
                    sums[1][l] += wx * at_drop[l];
                    sums[2][l] += wy * at_drop[l];
                    sums[3][l] += w * slope[l];
                }
            }
        }
        for (b, sums) in sums.iter().enumerate().take(blocks) {
            for (part, sum) in sums.iter().enumerate() {
                out[part * stride + first + b * LANES..][..LANES].copy_from_slice(sum);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forward::LowRankUpdate;
    use crate::SensorSpec;

    /// The paper's sensor on a coarse mesh, its exact presses and their table.
    fn setup() -> (ExactPresses, TabulatedPresses) {
        let mut spec = SensorSpec::square_hydrogel();
        spec.mesh.triangles = 600;
        let model = spec.forward_model().unwrap();
        let sigma = vec![1.0; model.mesh().triangles().len()];
        let exact = ExactPresses::new(LowRankUpdate::new(&model, &sigma).unwrap(), 1.0);
        let table = TabulatedPresses::new(&exact, [[-0.1, -0.1], [0.1, 0.1]], 0.01, 0.0025).unwrap();
        (exact, table)
    }

    /// At a grid point the table is the series alone; between them it is close to the solve,
    /// and its derivatives are the central differences of its own values.
    #[test]
    fn the_table_reads_back_the_exact_response_and_its_derivatives() {
        let (exact, table) = setup();
        let m = table.measurements();
        let (mut work, mut jet, mut other) = (Vec::new(), vec![0.0; 4 * m], vec![0.0; 4 * m]);
        let mut solved = vec![0.0; m];
        let mut scratch = ExactScratch::default();
        let relative = |a: &[f64], b: &[f64]| {
            let diff: f64 = a.iter().zip(b).map(|(a, b)| (a - b).powi(2)).sum();
            (diff / b.iter().map(|b| b * b).sum::<f64>()).sqrt()
        };
        for (centre, drop, within) in
            [([0.0, 0.0], 0.5, 2e-3), ([0.03, -0.02], 0.3, 2e-3), ([0.0213, 0.0371], 0.77, 1e-2)]
        {
            exact.response_into(&[Disk { centre, radius: 0.01, drop }], &mut scratch, &mut solved).unwrap();
            table.jet_into(centre, drop, &mut work, &mut jet);
            let off = relative(&jet[..m], &solved);
            assert!(off < within, "{centre:?} at {drop}: {off}");
            // Derivatives: central differences of the table itself.
            let h = [1e-5, 1e-5, 1e-4];
            for (k, step) in h.iter().enumerate() {
                let shifted = |s: f64| {
                    let mut c = centre;
                    let mut d = drop;
                    if k < 2 {
                        c[k] += s
                    } else {
                        d += s
                    }
                    (c, d)
                };
                let (c, d) = shifted(*step);
                table.jet_into(c, d, &mut work, &mut other);
                let plus = other[..m].to_vec();
                let (c, d) = shifted(-*step);
                table.jet_into(c, d, &mut work, &mut other);
                let difference: Vec<f64> = plus.iter().zip(&other[..m]).map(|(p, q)| (p - q) / (2.0 * step)).collect();
                let off = relative(&jet[(k + 1) * m..(k + 2) * m], &difference);
                assert!(off < 1e-3, "{centre:?} derivative {k}: {off}");
            }
        }
    }

    /// The radius derivative read back is the exact response's: against the central difference
    /// of exact solves at radii 10 µm either side, within 10⁻⁵ at grid points (measured: 3·10⁻⁶
    /// and 1·10⁻⁶, the f32 series), and within 5 % between them on this coarse mesh (measured:
    /// 3.8 %, where the value is within 1 %: the derivative turns as the disk's edge crosses the
    /// mesh's nodes, which the bicubic smooths).
    #[test]
    fn the_table_reads_back_the_radius_derivative() {
        let (exact, table) = setup();
        let m = table.measurements();
        let (mut work, mut read) = (Vec::new(), vec![0.0; m]);
        let (mut plus, mut minus) = (vec![0.0; m], vec![0.0; m]);
        let mut scratch = ExactScratch::default();
        for (centre, drop, within) in
            [([0.0, 0.0], 0.5, 1e-5), ([0.03, -0.02], 0.3, 1e-5), ([0.0213, 0.0371], 0.77, 0.05)]
        {
            let h = 1e-5;
            let solve = |radius: f64, scratch: &mut ExactScratch, out: &mut [f64]| {
                exact.response_into(&[Disk { centre, radius, drop }], scratch, out).unwrap()
            };
            solve(0.01 + h, &mut scratch, &mut plus);
            solve(0.01 - h, &mut scratch, &mut minus);
            let difference: Vec<f64> = plus.iter().zip(&minus).map(|(p, q)| (p - q) / (2.0 * h)).collect();
            assert!(table.radius_derivative_into(centre, drop, &mut work, &mut read));
            let diff: f64 = read.iter().zip(&difference).map(|(a, b)| (a - b).powi(2)).sum();
            let off = (diff / difference.iter().map(|b| b * b).sum::<f64>()).sqrt();
            assert!(off < within, "{centre:?} at {drop}: {off}");
        }
    }

    /// The stencil's sums are each point's series (its terms added in turn, at the drop and for
    /// its slope) times the point's weights, added in the order of the points, to the bit, a
    /// block or four at a time, whatever the rows' length (here
    /// not a whole number of groups of blocks) and where the points lie (the last of the
    /// table's among them).
    #[test]
    fn the_stencils_sums_are_its_terms_added_in_turn() {
        let (points, stride) = (24, 3 * LANES);
        let value = |i: usize| ((i * 7919 % 1013) as f32 - 506.0) / 97.0;
        let coefficients: Vec<f32> = (0..points * NODES * stride).map(value).collect();
        let rows: [usize; STENCIL] = std::array::from_fn(|s| (points - 1 - s) * NODES * stride);
        let weights: [[f32; 3]; STENCIL] = std::array::from_fn(|s| [value(3 * s), value(3 * s + 1), value(3 * s + 2)]);
        let (terms, slopes) = chebyshev(0.3);
        let (terms, slopes) = (terms.map(|t| t as f32), slopes.map(|t| t as f32));
        let (mut out, mut one, mut four) = (vec![f32::NAN; 4 * stride], vec![0.0; 4 * stride], vec![0.0; 4 * stride]);
        sum_stencil(&mut out, &coefficients, stride, &rows, &weights, &terms, &slopes);
        // Both group sizes, whatever this processor takes.
        sum_groups::<1>(&mut one, &coefficients, stride, &rows, &weights, &terms, &slopes);
        sum_groups::<4>(&mut four, &coefficients, stride, &rows, &weights, &terms, &slopes);
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!((bits(&one), bits(&four)), (bits(&out), bits(&out)));
        for q in 0..stride {
            let mut sums = [0.0_f32; 4];
            for (&row, &[w, wx, wy]) in rows.iter().zip(&weights) {
                let (mut at_drop, mut slope) = (0.0_f32, 0.0_f32);
                for k in 0..NODES {
                    let c = coefficients[row + k * stride + q];
                    at_drop += terms[k] * c;
                    slope += slopes[k] * c;
                }
                let products = [w * at_drop, wx * at_drop, wy * at_drop, w * slope];
                sums.iter_mut().zip(products).for_each(|(s, p)| *s += p);
            }
            for (part, sum) in sums.iter().enumerate() {
                assert_eq!(out[part * stride + q].to_bits(), sum.to_bits(), "channel {q}, sum {part}");
            }
        }
    }
}
