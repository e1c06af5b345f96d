//! The frame path's working memory: buffers grown to their largest size once and then reused
//! ([`grow`], [`room`]), and a dense LU solver that keeps its own ([`DenseLu`]), so that a
//! frame allocates nothing once they have grown. Shared by the forward model's low-rank
//! updates and the press fit.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::lu::partial_pivoting::factor::{lu_in_place, lu_in_place_scratch};
use faer::linalg::lu::partial_pivoting::solve::{solve_in_place, solve_in_place_scratch};
use faer::{Mat, Par};

/// Resizes `mat` to `rows` × `cols` (new entries 0), its capacity a power of two each way: sizes
/// that vary from frame to frame (a press's rows as it moves) then settle after a few
/// doublings, and the frame path stops allocating.
pub(crate) fn grow(mat: &mut Mat<f64>, rows: usize, cols: usize) {
    reserve(mat, rows, cols);
    mat.resize_with(rows, cols, |_, _| 0.0);
}

/// Makes room in `mat` for `rows` × `cols` as [`grow`] does, leaving its size as it is.
pub(crate) fn reserve(mat: &mut Mat<f64>, rows: usize, cols: usize) {
    mat.reserve(rows.max(8).next_power_of_two(), cols.max(8).next_power_of_two());
}

/// Makes room in `v` for `total` elements in all (`Vec::reserve` counts beyond its length).
pub(crate) fn room<T>(v: &mut Vec<T>, total: usize) {
    v.reserve(total.saturating_sub(v.len()));
}

/// Grows `stack` (holding `bytes`) to `need`, and twice that (room for larger systems to come),
/// when it holds less: a solve's scratch that then settles.
pub(crate) fn stack_room(stack: &mut MemBuffer, bytes: &mut usize, need: StackReq) {
    if *bytes < need.unaligned_bytes_required() {
        let twice = need.and(need);
        *stack = MemBuffer::new(twice);
        *bytes = twice.unaligned_bytes_required();
    }
}

/// Solves small dense systems in place by LU with partial pivoting (faer's), keeping its
/// buffers, so that a solve allocates nothing once they have grown.
pub(crate) struct DenseLu {
    perm: Vec<usize>,
    perm_inv: Vec<usize>,
    stack: MemBuffer,
    /// Bytes `stack` holds.
    stack_bytes: usize,
}

impl Default for DenseLu {
    fn default() -> Self {
        DenseLu { perm: Vec::new(), perm_inv: Vec::new(), stack: MemBuffer::new(StackReq::EMPTY), stack_bytes: 0 }
    }
}

impl std::fmt::Debug for DenseLu {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DenseLu").field("size", &self.perm.len()).finish_non_exhaustive()
    }
}

impl DenseLu {
    /// Grows the row permutations at once to systems of `n` rows, so that a larger system than
    /// the last does not reallocate them.
    pub(crate) fn reserve(&mut self, n: usize) {
        room(&mut self.perm, n);
        room(&mut self.perm_inv, n);
    }

    /// Overwrites `rhs` with `a`⁻¹·`rhs` (`a` square, overwritten by its factors).
    pub(crate) fn solve_in_place(&mut self, mut a: faer::MatMut<'_, f64>, rhs: faer::MatMut<'_, f64>) {
        let n = a.nrows();
        let need = lu_in_place_scratch::<usize, f64>(n, n, Par::Seq, Default::default()).or(solve_in_place_scratch::<
            usize,
            f64,
        >(
            n, rhs.ncols(), Par::Seq
        ));
        stack_room(&mut self.stack, &mut self.stack_bytes, need);
        self.perm.resize(n, 0);
        self.perm_inv.resize(n, 0);
        let (_, permutation) = lu_in_place(
            a.as_mut(),
            &mut self.perm,
            &mut self.perm_inv,
            Par::Seq,
            MemStack::new(&mut self.stack),
            Default::default(),
        );
        solve_in_place(a.as_ref(), a.as_ref(), permutation, rhs, Par::Seq, MemStack::new(&mut self.stack));
    }
}
