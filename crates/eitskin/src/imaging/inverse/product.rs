//! The image product y = H·d at the memory limit: H (pixels × measurements, f32) is stored in
//! blocks of [`BLOCK`] pixels, each block measurement by measurement, so that one pass reads the
//! matrix once, in order, while the block's partial sums stay in registers (four 16-lane
//! AVX-512 or eight 8-lane AVX2 registers), and the image is written once. The widest vectors
//! the processor has are chosen at run time; elsewhere the same loop runs portably.
//!
//! Column-major storage, the obvious layout, adds each measurement's column into the image:
//! the image is read and written once per measurement (120 times a frame on the paper's board).
//!
//! Half precision ([`BlockedMatrix::keep_half`]): a copy in IEEE binary16, each measurement's
//! column scaled so that its largest entry is 2¹⁵, halves what a frame reads. Where many
//! sensors' matrices share the cache (a server of a whole skin), a frame's product is the
//! matrix read from memory, so it takes about half the time. Each entry is then within 2⁻¹¹
//! of itself, so each pixel within 2⁻¹¹·Σ|H·d| of the single-precision product, except that
//! entries below 2⁻²⁹ of their column's largest become 0 (add 2⁻²⁹·Σ_m max|H_m|·|d_m|);
//! conversion to f32 is exact, and the sums are the same on every path (no operation fused).
//! The vector path is AVX-512's; elsewhere the portable loop runs, on one core.

use faer::linalg::matmul::matmul;
use faer::{Accum, MatMut, MatRef};

/// Pixels per block.
pub const BLOCK: usize = 64;

/// Differences handled per pass, so that the product needs no allocation (a protocol with
/// more measurements takes several passes, each adding into the image).
const PASS: usize = 512;

/// A pixels × measurements matrix in f32, stored in pixel blocks for [`BlockedMatrix::mul_into`].
#[derive(Debug, Clone, PartialEq)]
pub struct BlockedMatrix {
    rows: usize,
    columns: usize,
    /// Block b, measurement m, lane l at `(b·columns + m)·BLOCK + l`; lanes past the last row are 0.
    data: Vec<f32>,
    /// The half-precision copy the frame's product reads instead, if kept.
    half: Option<Half>,
}

/// A [`BlockedMatrix`] in binary16, in the same blocks, each column divided by its scale.
#[derive(Debug, Clone, PartialEq)]
struct Half {
    bits: Vec<u16>,
    /// Per column, what its entries were divided by (1 for a column of zeros).
    scales: Vec<f32>,
}

impl BlockedMatrix {
    /// An all-zero matrix of `rows` × `columns`.
    pub fn zeros(rows: usize, columns: usize) -> BlockedMatrix {
        BlockedMatrix { rows, columns, data: vec![0.0; rows.div_ceil(BLOCK) * BLOCK * columns], half: None }
    }

    /// From now on, [`BlockedMatrix::mul_into`] reads a half-precision copy (see the module
    /// doc); [`set`](Self::set) drops it. Allocates the copy (a quarter of a second's worth of
    /// frames: setup, not the frame path).
    pub fn keep_half(&mut self) {
        use half::slice::{HalfBitsSliceExt, HalfFloatSliceExt};
        debug_assert!(self.data.iter().all(|h| h.is_finite()), "a finite matrix");
        let mut largest = vec![0.0_f32; self.columns];
        for (_, m, lanes) in self.blocks() {
            largest[m] = lanes.iter().fold(largest[m], |a, h| a.max(h.abs()));
        }
        let scales: Vec<f32> =
            largest.iter().map(|&l| if l > 0.0 && l.is_finite() { l / HALF_TOP } else { 1.0 }).collect();
        let mut bits = vec![0_u16; self.data.len()];
        let mut scaled = [0.0_f32; BLOCK];
        for (k, (lanes, out)) in self.data.chunks_exact(BLOCK).zip(bits.chunks_exact_mut(BLOCK)).enumerate() {
            let scale = scales[k % self.columns];
            scaled.iter_mut().zip(lanes).for_each(|(x, h)| *x = h / scale);
            // Rounded to nearest, ties to even, as one conversion each (the processor's F16C where it has it).
            out.reinterpret_cast_mut::<half::f16>().convert_from_f32_slice(&scaled);
            out.iter_mut().for_each(|b| *b = flushed(*b));
        }
        self.half = Some(Half { bits, scales });
    }

    /// Drops the half-precision copy: the frame's product reads the matrix itself again.
    pub fn drop_half(&mut self) {
        self.half = None;
    }

    /// Bytes one product reads: the half-precision copy's where kept, else the matrix's.
    pub fn bytes_read(&self) -> usize {
        match &self.half {
            Some(half) => 2 * half.bits.len() + 4 * half.scales.len(),
            None => 4 * self.data.len(),
        }
    }

    /// Whether the frame's product reads a half-precision copy.
    pub fn is_half(&self) -> bool {
        self.half.is_some()
    }

    /// Rows (pixels).
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Columns (measurements).
    pub fn columns(&self) -> usize {
        self.columns
    }

    /// Sets entry (`row`, `column`).
    pub fn set(&mut self, row: usize, column: usize, value: f32) {
        let index = self.index(row, column);
        self.data[index] = value;
        self.half = None;
    }

    /// Entry (`row`, `column`).
    pub fn get(&self, row: usize, column: usize) -> f32 {
        self.data[self.index(row, column)]
    }

    /// Each block's part of each column, in storage order: (its first row, the column, its
    /// entries, rows past the last left out).
    pub fn blocks(&self) -> impl Iterator<Item = (usize, usize, &[f32])> + '_ {
        self.data.chunks_exact(BLOCK).enumerate().map(move |(k, lanes)| {
            let first = k / self.columns * BLOCK;
            (first, k % self.columns, &lanes[..(self.rows - first).min(BLOCK)])
        })
    }

    /// [`BlockedMatrix::blocks`] to write (dropping the half-precision copy).
    pub fn blocks_mut(&mut self) -> impl Iterator<Item = (usize, usize, &mut [f32])> + '_ {
        self.half = None;
        let (rows, columns) = (self.rows, self.columns);
        self.data.chunks_exact_mut(BLOCK).enumerate().map(move |(k, lanes)| {
            let first = k / columns * BLOCK;
            (first, k % columns, &mut lanes[..(rows - first).min(BLOCK)])
        })
    }

    /// Column `column`, row by row.
    pub fn column(&self, column: usize) -> impl Iterator<Item = f32> + '_ {
        (0..self.rows).map(move |row| self.get(row, column))
    }

    fn index(&self, row: usize, column: usize) -> usize {
        assert!(row < self.rows && column < self.columns, "({row}, {column}) is outside the matrix");
        ((row / BLOCK) * self.columns + column) * BLOCK + row % BLOCK
    }

    /// `out` = H·d, where `difference(m)` gives d's entry m; allocates nothing.
    pub fn mul_into(&self, out: &mut [f32], difference: impl Fn(usize) -> f32) {
        assert_eq!(out.len(), self.rows, "one output per row");
        out.fill(0.0);
        let mut buffer = [0.0f32; PASS];
        let mut first = 0;
        while first < self.columns {
            let count = (self.columns - first).min(PASS);
            match &self.half {
                None => {
                    for (m, d) in buffer[..count].iter_mut().enumerate() {
                        *d = difference(first + m);
                    }
                    product(out, &self.data, self.columns, first, &buffer[..count], first > 0);
                }
                Some(half) => {
                    for (m, d) in buffer[..count].iter_mut().enumerate() {
                        *d = difference(first + m) * half.scales[first + m];
                    }
                    product_half(out, &half.bits, self.columns, first, &buffer[..count], first > 0);
                }
            }
            first += count;
        }
    }
}

impl BlockedMatrix {
    /// `out` = H·D for several difference vectors at once (D columns × frames, `out` rows ×
    /// frames): each block of rows is a column-major matrix of its own, times D in one matrix
    /// product, so that H is read once for all the frames (a frame alone reads it once each).
    pub fn mul_frames_into(&self, d: MatRef<'_, f32>, mut out: MatMut<'_, f32>) {
        assert!(d.nrows() == self.columns && out.nrows() == self.rows && out.ncols() == d.ncols(), "H·D's shapes");
        if self.columns == 0 {
            out.fill(0.0);
            return;
        }
        // A block of the paper's size (64 × 120 × 100 frames) split across cores took twice as
        // long as on one; thousands of channels share well.
        let par = match BLOCK * self.columns * d.ncols() {
            ..SHARED_BLOCK => faer::Par::Seq,
            _ => faer::get_global_parallelism(),
        };
        for (b, block) in self.data.chunks_exact(BLOCK * self.columns).enumerate() {
            let rows = (self.rows - b * BLOCK).min(BLOCK);
            let h = MatRef::from_column_major_slice_with_stride(block, BLOCK, self.columns, BLOCK).subrows(0, rows);
            let part = out.as_mut().subrows_mut(b * BLOCK, rows);
            matmul(part, Accum::Replace, h, d, 1.0, par);
        }
    }
}

/// Multiply-adds of one block's product from which [`BlockedMatrix::mul_frames_into`] shares it
/// with other cores (a 64-pixel block of 2,356 channels times 100 frames has 15 million).
const SHARED_BLOCK: usize = 1 << 22;

/// Blocks per chunk that one core takes at a time (128 pixels, 61 kB of a 120-column matrix).
const CHUNK: usize = 2;

/// Matrices of at least this many entries (256 kB) share the product with a second core.
const SHARED: usize = 1 << 16;

/// out (+)= H[:, first..first + d.len()]·d over the blocked `data` of `columns` columns; a
/// large matrix in chunks of blocks shared with a second core while it is free.
#[allow(unsafe_code, reason = "hands each chunk of the output to whichever core claims it")]
fn product(out: &mut [f32], data: &[f32], columns: usize, first: usize, d: &[f32], add: bool) {
    if data.len() < SHARED || columns == 0 {
        return product_blocks(out, data, columns, first, d, add);
    }
    /// The output's start, shared by the cores: each writes only the chunks it claimed.
    struct Output(*mut f32);
    // SAFETY: see the kernel below; chunks are disjoint and each is run once.
    unsafe impl Sync for Output {}
    impl Output {
        fn start(&self) -> *mut f32 {
            self.0
        }
    }
    let (rows, output) = (out.len(), &Output(out.as_mut_ptr()));
    let block_data = BLOCK * columns;
    let chunks = (data.len() / block_data).div_ceil(CHUNK);
    crate::parallel::run_split(chunks, &|chunk| {
        let blocks = chunk * CHUNK..((chunk + 1) * CHUNK).min(data.len() / block_data);
        let pixels = blocks.start * BLOCK..(blocks.end * BLOCK).min(rows);
        // SAFETY: `pixels` lies inside `out`, and `run_split` runs each chunk exactly once, so
        // no two calls (on either core) touch the same pixels; `out` is borrowed mutably for
        // the whole of `run_split`, which returns only when every chunk is done.
        let out = unsafe { std::slice::from_raw_parts_mut(output.start().add(pixels.start), pixels.len()) };
        product_blocks(out, &data[blocks.start * block_data..blocks.end * block_data], columns, first, d, add);
    });
}

crate::parallel::widest! {
    /// [`product`] on one core, over whole blocks of `data` and their pixels in `out`.
    fn product_blocks = product_portable(out: &mut [f32], data: &[f32], columns: usize, first: usize, d: &[f32], add: bool) -> ()
}

/// The kernel: for each block, its partial sums over the measurements, then one write.
#[inline(always)]
fn product_portable(out: &mut [f32], data: &[f32], columns: usize, first: usize, d: &[f32], add: bool) {
    for (block, rows) in data.chunks_exact(BLOCK * columns).zip(out.chunks_mut(BLOCK)) {
        let mut sums = [0.0f32; BLOCK];
        let part = &block[first * BLOCK..(first + d.len()) * BLOCK];
        for (lanes, &dm) in part.chunks_exact(BLOCK).zip(d) {
            for (sum, h) in sums.iter_mut().zip(lanes) {
                *sum += h * dm;
            }
        }
        for (row, sum) in rows.iter_mut().zip(sums) {
            *row = if add { *row + sum } else { sum };
        }
    }
}

/// The largest entry of a column in the half-precision copy (2¹⁵: below binary16's largest,
/// 65504, with the smallest normal 2⁻¹⁴ at 2⁻²⁹ of it).
const HALF_TOP: f32 = 32768.0;

/// `x` (|x| ≤ [`HALF_TOP`]) in binary16, rounded to nearest; below the smallest normal, 0 (so
/// that every path converts it back alike).
#[cfg(test)]
fn to_half(x: f32) -> u16 {
    flushed(half::f16::from_f32(x).to_bits())
}

/// A binary16's `bits` with a subnormal made zero (its sign kept).
#[inline(always)]
fn flushed(bits: u16) -> u16 {
    if bits & 0x7c00 == 0 {
        bits & 0x8000
    } else {
        bits
    }
}

/// A binary16 (normal or zero) in f32, exactly: its sign, exponent rebased, mantissa widened.
#[inline(always)]
fn from_half(h: u16) -> f32 {
    let h = u32::from(h);
    let magnitude = h & 0x7fff;
    let bits = if magnitude == 0 { 0 } else { (magnitude << 13) + (112 << 23) };
    f32::from_bits(((h & 0x8000) << 16) | bits)
}

/// [`product_blocks`] on the half-precision copy `bits` (`d` already scaled), on the calling
/// core, with the widest conversion the processor has.
#[allow(
    unsafe_code,
    reason = "calls a kernel compiled for vector extensions only once the processor is known to have them"
)]
fn product_half(out: &mut [f32], bits: &[u16], columns: usize, first: usize, d: &[f32], add: bool) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: AVX-512F was just detected.
            return unsafe { product_half_avx512(out, bits, columns, first, d, add) };
        }
    }
    product_half_portable(out, bits, columns, first, d, add)
}

/// The half-precision kernel, portably: for each block, its partial sums, then one write.
fn product_half_portable(out: &mut [f32], bits: &[u16], columns: usize, first: usize, d: &[f32], add: bool) {
    for (block, rows) in bits.chunks_exact(BLOCK * columns).zip(out.chunks_mut(BLOCK)) {
        let mut sums = [0.0f32; BLOCK];
        let part = &block[first * BLOCK..(first + d.len()) * BLOCK];
        for (lanes, &dm) in part.chunks_exact(BLOCK).zip(d) {
            for (sum, h) in sums.iter_mut().zip(lanes) {
                *sum += from_half(*h) * dm;
            }
        }
        for (row, sum) in rows.iter_mut().zip(sums) {
            *row = if add { *row + sum } else { sum };
        }
    }
}

/// The half-precision kernel with AVX-512: four 16-lane sums a block, each lane's entries
/// converted by `vcvtph2ps` (exact), multiplied and added as the portable kernel does.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[allow(unsafe_code, reason = "loads 16 entries at a time from slices whose bounds are checked first")]
fn product_half_avx512(out: &mut [f32], bits: &[u16], columns: usize, first: usize, d: &[f32], add: bool) {
    use std::arch::x86_64::{
        __m256i, _mm256_loadu_si256, _mm512_add_ps, _mm512_cvtph_ps, _mm512_mul_ps, _mm512_set1_ps, _mm512_setzero_ps,
        _mm512_storeu_ps,
    };
    for (block, rows) in bits.chunks_exact(BLOCK * columns).zip(out.chunks_mut(BLOCK)) {
        let part = &block[first * BLOCK..(first + d.len()) * BLOCK];
        let mut sums = [_mm512_setzero_ps(); BLOCK / 16];
        for (lanes, &dm) in part.chunks_exact(BLOCK).zip(d) {
            let dm = _mm512_set1_ps(dm);
            for (k, sum) in sums.iter_mut().enumerate() {
                let sixteen = &lanes[k * 16..(k + 1) * 16];
                // SAFETY: `sixteen` holds 16 u16, the 32 bytes the unaligned load reads.
                let h = unsafe { _mm256_loadu_si256(sixteen.as_ptr().cast::<__m256i>()) };
                *sum = _mm512_add_ps(*sum, _mm512_mul_ps(_mm512_cvtph_ps(h), dm));
            }
        }
        let mut all = [0.0f32; BLOCK];
        for (k, sum) in sums.iter().enumerate() {
            let sixteen = &mut all[k * 16..(k + 1) * 16];
            // SAFETY: `sixteen` holds 16 f32, the 64 bytes the unaligned store writes.
            unsafe { _mm512_storeu_ps(sixteen.as_mut_ptr(), *sum) };
        }
        for (row, sum) in rows.iter_mut().zip(all) {
            *row = if add { *row + sum } else { sum };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The half-precision copy's product is within 2⁻¹⁰·Σ|h·d| of the single-precision one, the
    /// same on the vector path as on the portable one; every binary16 comes back exactly.
    #[test]
    fn the_half_precision_product_is_within_its_rounding_and_alike_on_every_path() {
        for h in (0..=u16::MAX).filter(|h| h & 0x7c00 != 0 && h & 0x7c00 != 0x7c00) {
            assert_eq!(from_half(h), half::f16::from_bits(h).to_f32(), "{h:#06x}");
        }
        assert_eq!((from_half(0), from_half(0x8000).to_bits()), (0.0, (-0.0f32).to_bits()));
        // An entry below 2⁻²⁹ of its column's largest is 0 (a binary16 subnormal, flushed), its sign kept.
        let mut tiny = BlockedMatrix::zeros(3, 1);
        [1.0, -1e-10, 1e-3].iter().enumerate().for_each(|(r, h)| tiny.set(r, 0, *h));
        tiny.keep_half();
        let bits = tiny.half.as_ref().map(|h| h.bits[..3].to_vec()).unwrap_or_default();
        assert_eq!(bits, [to_half(32768.0), 0x8000, to_half(32.768)]);
        for (rows, columns) in [(1, 1), (63, 5), (64, 120), (200, 7), (130, PASS + 3), (5, 0)] {
            let entry = |r: usize, c: usize| (((r * 31 + c * 17) % 13) as f32 - 6.0) * 10f32.powi((c % 7) as i32 - 3);
            let mut matrix = BlockedMatrix::zeros(rows, columns);
            for r in 0..rows {
                for c in 0..columns {
                    matrix.set(r, c, entry(r, c));
                }
            }
            let d = |c: usize| (c % 5) as f32 * 0.25 - 0.5;
            let mut single = vec![f32::NAN; rows];
            matrix.mul_into(&mut single, d);
            matrix.keep_half();
            assert!(matrix.is_half());
            // Converted in bulk, each entry as one conversion would give it.
            if let Some(half) = &matrix.half {
                for (r, c) in (0..rows).flat_map(|r| (0..columns).map(move |c| (r, c))) {
                    let want = to_half(entry(r, c) / half.scales[c]);
                    assert_eq!(half.bits[matrix.index(r, c)], want, "{rows}×{columns}: ({r}, {c})");
                }
            }
            let mut halved = vec![f32::NAN; rows];
            matrix.mul_into(&mut halved, d);
            for r in 0..rows {
                let bound: f32 = (0..columns).map(|c| (entry(r, c) * d(c)).abs()).sum::<f32>() / 1024.0;
                assert!((halved[r] - single[r]).abs() <= bound + 1e-6, "{rows}×{columns}, row {r}");
            }
            // (On a processor without AVX-512 both are the portable loop.)
            if let (Some(half), true) = (&matrix.half, columns > 0 && columns <= PASS) {
                let scaled: Vec<f32> = (0..columns).map(|c| d(c) * half.scales[c]).collect();
                let mut portable = vec![f32::NAN; rows];
                product_half_portable(&mut portable, &half.bits, columns, 0, &scaled, false);
                assert_eq!(portable, halved, "{rows}×{columns}: the same sums on every path");
            }
            if columns > 0 {
                matrix.set(0, 0, 1.0);
                assert!(!matrix.is_half(), "a change drops the copy");
            }
        }
    }

    /// The blocked product equals the plain one, on sizes that fill no block exactly and on
    /// more columns than one pass takes, frame by frame and several frames at once.
    #[test]
    fn the_blocked_product_is_the_plain_product() {
        for (rows, columns) in [(1, 1), (63, 5), (64, 120), (200, 7), (130, PASS + 3), (5, 0)] {
            let entry = |r: usize, c: usize| ((r * 31 + c * 17) % 13) as f32 - 6.0;
            let mut matrix = BlockedMatrix::zeros(rows, columns);
            for r in 0..rows {
                for c in 0..columns {
                    matrix.set(r, c, entry(r, c));
                }
            }
            let d = |c: usize| (c % 5) as f32 * 0.25 - 0.5;
            let mut out = vec![f32::NAN; rows];
            matrix.mul_into(&mut out, d);
            for (r, y) in out.iter().enumerate() {
                let want: f32 = (0..columns).map(|c| entry(r, c) * d(c)).sum();
                assert!((y - want).abs() <= 1e-4 * want.abs().max(1.0), "{rows}×{columns}, row {r}: {y} vs {want}");
            }
            // Several frames at once: each column as the product of one.
            let frames = faer::Mat::from_fn(columns, 3, |c, f| d(c) * (f as f32 - 1.0));
            let mut many = faer::Mat::from_fn(rows, 3, |_, _| f32::NAN);
            matrix.mul_frames_into(frames.as_ref(), many.as_mut());
            for f in 0..3 {
                for (r, y) in out.iter().enumerate() {
                    let want = y * (f as f32 - 1.0);
                    assert!((many[(r, f)] - want).abs() <= 1e-4 * want.abs().max(1.0), "frame {f}, row {r}");
                }
            }
            if columns > 0 {
                assert_eq!(
                    matrix.column(columns - 1).collect::<Vec<_>>(),
                    (0..rows).map(|r| entry(r, columns - 1)).collect::<Vec<_>>()
                );
            }
        }
    }
}
