//! The image product y = H·d at the memory limit: H (pixels × measurements, f32) is stored in
//! blocks of [`BLOCK`] pixels, each block measurement by measurement, so that one pass reads the
//! matrix once, in order, while the block's partial sums stay in registers (four 16-lane
//! AVX-512 or eight 8-lane AVX2 registers), and the image is written once. The widest vectors
//! the processor has are chosen at run time; elsewhere the same loop runs portably.
//!
//! Column-major storage, the obvious layout, adds each measurement's column into the image:
//! the image is read and written once per measurement (120 times a frame on the paper's board).

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
}

impl BlockedMatrix {
    /// An all-zero matrix of `rows` × `columns`.
    pub fn zeros(rows: usize, columns: usize) -> BlockedMatrix {
        BlockedMatrix { rows, columns, data: vec![0.0; rows.div_ceil(BLOCK) * BLOCK * columns] }
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
    }

    /// Entry (`row`, `column`).
    pub fn get(&self, row: usize, column: usize) -> f32 {
        self.data[self.index(row, column)]
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
            for (m, d) in buffer[..count].iter_mut().enumerate() {
                *d = difference(first + m);
            }
            product(out, &self.data, self.columns, first, &buffer[..count], first > 0);
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
        for (b, block) in self.data.chunks_exact(BLOCK * self.columns).enumerate() {
            let rows = (self.rows - b * BLOCK).min(BLOCK);
            let h = MatRef::from_column_major_slice_with_stride(block, BLOCK, self.columns, BLOCK).subrows(0, rows);
            let part = out.as_mut().subrows_mut(b * BLOCK, rows);
            matmul(part, Accum::Replace, h, d, 1.0, faer::get_global_parallelism());
        }
    }
}

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

#[cfg(test)]
mod tests {
    use super::*;

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
