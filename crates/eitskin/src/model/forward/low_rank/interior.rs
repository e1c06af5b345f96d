//! A change's interior rows eliminated from the update (static condensation), so that its
//! dense system has the rim's rows only and G is read between them alone.
//!
//! A node all of whose triangles change, and which is not on the boundary (so carries no
//! electrode and no source), has rows of both K₀ and K₁ = K₀ + ΔK that involve the change's
//! rows alone. Eliminating those interior rows I from both systems leaves, on the rest, the
//! Schur complements K̃₀ and K̃₁ = K̃₀ + ΔS, whose difference lies on the rim Γ alone:
//!
//!   ΔS = ΔK_ΓΓ − K₁_ΓI·K₁_II⁻¹·K₁_IΓ + K₀_ΓI·K₀_II⁻¹·K₀_IΓ.
//!
//! The inverse of a Schur complement is the block of the inverse, so K̃₀⁻¹ on Γ is G_ΓΓ, and
//! with no source inside, the fields on the rest are the full system's: the update of the
//! module above holds on Γ with ΔS for ΔK,
//!
//!   X_Γ = (I + G_ΓΓ·ΔS)⁻¹·U_Γ,   ΔV = −U_Γᵀ·ΔS·X_Γ,
//!
//! exact (three presses on the virtual sensor's 12k-triangle mesh: 97 of 231 rows in the LU,
//! and 97 × 97 of G read where the rim's rows against all took 97 × 231). The interior's fields,
//! X_I = −K₁_II⁻¹·K₁_IΓ·X_Γ, are found only for a derivative that asks for them. ΔK and K_II
//! are block diagonal over the change's connected parts (presses apart), so each part's K₀_II
//! and K₁_II, a few dozen rows, are factored on their own by Cholesky (L·Lᵀ, with Y = L⁻¹·K_IΓ
//! the term is Yᵀ·Y): each is the part's stiffness with its rim held, positive definite while
//! the conductivity there is positive. Where either is not (a conductivity at or below 0), the
//! change is solved on all its rows instead, as is a change with no interior row.

use std::ops::Range;

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::{cholesky_in_place, cholesky_in_place_scratch, LltRegularization};
use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::{solve_lower_triangular_in_place, solve_upper_triangular_in_place};
use faer::{Accum, Mat, MatMut, MatRef, Par};

use super::{grow, LowRankUpdate, GROUNDED};

/// `rows` (rows of the system, each below `local`'s length) in increasing order again, each
/// once, `local` their indices (`bits` a buffer).
pub(super) fn sorted(rows: &mut Vec<usize>, local: &mut [u32], bits: &mut RowBits) {
    bits.clear(local.len());
    rows.iter().for_each(|&r| bits.insert(r));
    bits.drain_into(rows, local);
}

/// A set of the system's rows as bits, read back in increasing order a word at a time: a few
/// dozen words (a comparison sort of a change's few hundred rows had been 0.7 % of an exact
/// frame of three presses).
#[derive(Debug, Default)]
pub(super) struct RowBits {
    /// One bit a row; all zeros outside the words `first..=last`, and all zeros after a drain.
    words: Vec<u64>,
    first: usize,
    last: usize,
}

impl RowBits {
    /// Room for `rows` rows, so that a first change does not allocate.
    pub(super) fn reserve(&mut self, rows: usize) {
        super::room(&mut self.words, rows.div_ceil(64));
    }

    /// Empty, for rows below `rows`.
    pub(super) fn clear(&mut self, rows: usize) {
        self.words.resize(rows.div_ceil(64), 0);
        (self.first, self.last) = (usize::MAX, 0);
    }

    /// Adds row `r` (below the rows [`RowBits::clear`] was given; again: no change).
    pub(super) fn insert(&mut self, r: usize) {
        let w = r / 64;
        self.words[w] |= 1 << (r % 64);
        (self.first, self.last) = (self.first.min(w), self.last.max(w));
    }

    /// The rows added, in increasing order, into `rows` (cleared), each one's index into
    /// `local`; the set left empty.
    pub(super) fn drain_into(&mut self, rows: &mut Vec<usize>, local: &mut [u32]) {
        rows.clear();
        let words = self.words.iter_mut().enumerate().take(self.last + 1).skip(self.first);
        for (w, bits) in words {
            let mut word = std::mem::take(bits);
            while word != 0 {
                let r = w * 64 + word.trailing_zeros() as usize;
                local[r] = rows.len() as u32;
                rows.push(r);
                word &= word - 1;
            }
        }
        (self.first, self.last) = (usize::MAX, 0);
    }
}

/// A row that is never interior: a node on the boundary, or an electrode's unknown
/// ([`incident_triangles`]).
const RIM_ONLY: u32 = u32::MAX;

/// Per row of `update`'s system, the triangles its node is in; [`RIM_ONLY`] for a node on the
/// boundary (where electrodes and their sources are) and for rows without a node.
pub(super) fn incident_triangles(model: &crate::forward::ForwardModel) -> Vec<u32> {
    let mut incident = vec![RIM_ONLY; model.system_size()];
    let row = |node: usize| Some(model.row_of_node[node]).filter(|&r| r != GROUNDED);
    model.row_of_node.iter().filter(|&&r| r != GROUNDED).for_each(|&r| incident[r] = 0);
    for node in model.mesh().triangles().iter().flatten() {
        if let Some(r) = row(*node) {
            incident[r] = incident[r].saturating_add(1);
        }
    }
    for node in model.mesh().boundary_edges().iter().flatten() {
        if let Some(r) = row(*node) {
            incident[r] = RIM_ONLY;
        }
    }
    incident
}

/// A connected part of a change: its rim's and its interior's indices among the change's rows.
#[derive(Debug, Clone)]
struct Part {
    rim: Range<usize>,
    inner: Range<usize>,
    /// Where its block starts in [`Interior::blocks`].
    block: usize,
}

/// Buffers of the elimination, kept by [`super::ChangeScratch`].
pub(super) struct Interior {
    /// Per triangle of the mesh, the change's sum on it (S/m), valid where `seen` is `generation`.
    delta: Vec<f64>,
    seen: Vec<u32>,
    generation: u32,
    /// The change's triangles, each once.
    triangles: Vec<usize>,
    /// Per row of the change (its index before ordering), its node's changed triangles.
    count: Vec<u32>,
    /// Union–find over the change's rows (before ordering), for its connected parts.
    parent: Vec<u32>,
    /// (interior, part, row) of each row, sorted: the new order.
    order: Vec<(bool, u32, usize)>,
    /// The same in the rows' own order, before the sort.
    unsorted: Vec<(bool, u32, usize)>,
    /// Per (interior, part), where its rows start in the sorted order (the counting sort's).
    starts: Vec<u32>,
    parts: Vec<Part>,
    /// Each row's part (index after ordering); in [`Interior::analyse`], 1 at each root with an
    /// interior row.
    part_of: Vec<u32>,
    /// Per part, K₁'s interior rows and K₀'s (each k × (g + k), column-major: its rim's
    /// columns, then its interior's; then L in the interior's and Y = L⁻¹·K_IΓ in the rim's),
    /// then ΔS (g × g).
    blocks: Vec<f64>,
    stack: MemBuffer,
    /// Bytes `stack` holds.
    stack_bytes: usize,
}

impl Default for Interior {
    fn default() -> Self {
        Interior {
            delta: Vec::new(),
            seen: Vec::new(),
            generation: 0,
            triangles: Vec::new(),
            count: Vec::new(),
            parent: Vec::new(),
            order: Vec::new(),
            unsorted: Vec::new(),
            starts: Vec::new(),
            parts: Vec::new(),
            part_of: Vec::new(),
            blocks: Vec::new(),
            stack: MemBuffer::new(StackReq::EMPTY),
            stack_bytes: 0,
        }
    }
}

impl std::fmt::Debug for Interior {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Interior").field("parts", &self.parts.len()).finish_non_exhaustive()
    }
}

/// The root of `i` (path halving).
fn root(parent: &mut [u32], mut i: usize) -> usize {
    while parent[i] as usize != i {
        parent[i] = parent[parent[i] as usize];
        i = parent[i] as usize;
    }
    i
}

impl Interior {
    /// Room for changes of up to `rows` rows.
    pub(super) fn reserve(&mut self, rows: usize) {
        for v in [&mut self.count, &mut self.parent, &mut self.part_of] {
            super::room(v, rows);
        }
        super::room(&mut self.order, rows);
        super::room(&mut self.unsorted, rows);
        super::room(&mut self.starts, 2 * rows + 1);
        // A part's blocks are its interior's rows by all its rows twice (K₀'s and K₁'s) and its
        // rim's square, about 1.3·|R|² entries for a press of |R| rows: 24 per row of the
        // system holds a few presses of a hundred rows on the meshes presses are fitted on (more
        // grows by doubling). Then the parts, and the Cholesky's scratch for a part as large as
        // the system.
        super::room(&mut self.blocks, 24 * rows);
        super::room(&mut self.parts, 16);
        self.stack_for(rows);
    }

    /// Reads the change: its triangles (each once, their changes summed), each row's changed
    /// triangles and the parts they connect (`rows` the change's rows, `local` each one's index
    /// in it); returns how many parts have interior rows.
    pub(super) fn analyse(
        &mut self,
        update: &LowRankUpdate,
        changes: &[(usize, f64)],
        rows: &[usize],
        local: &[u32],
    ) -> usize {
        let triangles = update.model.mesh.triangles();
        if self.seen.len() < triangles.len() {
            self.seen.resize(triangles.len(), 0);
            self.delta.resize(triangles.len(), 0.0);
            super::room(&mut self.triangles, triangles.len());
        }
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 {
            self.seen.fill(0);
            self.generation = 1;
        }
        self.triangles.clear();
        for &(t, d) in changes {
            if self.seen[t] == self.generation {
                self.delta[t] += d;
            } else {
                (self.seen[t], self.delta[t]) = (self.generation, d);
                self.triangles.push(t);
            }
        }
        let s = rows.len();
        self.count.clear();
        self.count.resize(s, 0);
        self.parent.clear();
        self.parent.extend(0..s as u32);
        for &t in &self.triangles {
            let mut first = None;
            for &node in &triangles[t] {
                let row = update.model.row_of_node[node];
                if row == GROUNDED {
                    continue;
                }
                let i = local[row] as usize;
                self.count[i] += 1;
                let Some(f) = first else {
                    first = Some(i);
                    continue;
                };
                let (a, b) = (root(&mut self.parent, f), root(&mut self.parent, i));
                self.parent[a.max(b)] = a.min(b) as u32;
            }
        }
        // Parts with an interior row, each counted at its root's first such row.
        self.part_of.clear();
        self.part_of.resize(s, 0);
        let mut parts = 0;
        for (i, &row) in rows.iter().enumerate() {
            if update.incident[row] == self.count[i] {
                let r = root(&mut self.parent, i);
                parts += usize::from(self.part_of[r] == 0);
                self.part_of[r] = 1;
            }
        }
        parts
    }

    /// Orders the change's rows `rows` (in increasing order) as the rim's, then the interior's,
    /// each grouped by part (as [`Interior::analyse`] found them) and in order within it, and
    /// sets `local` to the new indices; returns how many are the rim's.
    pub(super) fn order_rows(&mut self, update: &LowRankUpdate, rows: &mut [usize], local: &mut [u32]) -> usize {
        let s = rows.len();
        debug_assert!(rows.windows(2).all(|w| w[0] < w[1]), "rows in increasing order");
        self.unsorted.clear();
        for (i, &row) in rows.iter().enumerate() {
            let inner = update.incident[row] == self.count[i];
            self.unsorted.push((inner, root(&mut self.parent, i) as u32, row));
        }
        // Sorted by (interior, part, row): a counting sort on (interior, part), a part's root
        // being one of the s rows, which keeps the rows' own order within each (what a
        // comparison sort of the triples did: 2.6 % of an exact frame of three presses).
        let key = |&(inner, part, _): &(bool, u32, usize)| usize::from(inner) * s + part as usize;
        self.starts.clear();
        self.starts.resize(2 * s + 1, 0);
        self.unsorted.iter().for_each(|o| self.starts[key(o) + 1] += 1);
        for k in 1..self.starts.len() {
            self.starts[k] += self.starts[k - 1];
        }
        self.order.clear();
        self.order.resize(s, (false, 0, 0));
        for o in &self.unsorted {
            let at = &mut self.starts[key(o)];
            self.order[*at as usize] = *o;
            *at += 1;
        }
        debug_assert!(self.order.windows(2).all(|w| w[0] < w[1]), "sorted");
        let rim = self.order.iter().take_while(|o| !o.0).count();
        for (i, &(_, _, row)) in self.order.iter().enumerate() {
            rows[i] = row;
            local[row] = i as u32;
        }
        // The parts: runs of one root among the rim's rows and among the interior's, paired.
        let Interior { order, parts, part_of, .. } = self;
        parts.clear();
        part_of.clear();
        part_of.resize(s, 0);
        let key = |j: usize| order[j].1;
        let (mut i, mut k) = (0, rim);
        while i < rim || k < s {
            let part = match (i < rim, k < s) {
                (true, true) => key(i).min(key(k)),
                (true, false) => key(i),
                _ => key(k),
            };
            let (a, b) = (i, k);
            while i < rim && key(i) == part {
                i += 1;
            }
            while k < s && key(k) == part {
                k += 1;
            }
            let index = parts.len() as u32;
            part_of[a..i].fill(index);
            part_of[b..k].fill(index);
            parts.push(Part { rim: a..i, inner: b..k, block: 0 });
        }
        rim
    }

    /// Each part's ΔS from K₀ and K₁ on its triangles (`local` the rows' indices after
    /// [`Interior::order_rows`], `rim` the rim's rows): both conductivities' interior rows
    /// assembled, each K_II factored (L·Lᵀ) with Y = L⁻¹·K_IΓ, and ΔS = ΔK_ΓΓ − Y₁ᵀ·Y₁ + Y₀ᵀ·Y₀;
    /// `false` where a part's K₁_II or K₀_II is not positive definite.
    pub(super) fn condense(&mut self, update: &LowRankUpdate, local: &[u32], rim: usize) -> bool {
        let mut offset = 0;
        for part in &mut self.parts {
            part.block = offset;
            let (k, g) = (part.inner.len(), part.rim.len());
            offset += 2 * k * (g + k) + g * g;
        }
        // Grown by doubling: sizes that vary from frame to frame settle.
        super::room(&mut self.blocks, offset.next_power_of_two());
        self.blocks.clear();
        self.blocks.resize(offset, 0.0);
        // Each changed triangle adds, on its part's rows: its stiffness at the changed and at the
        // background conductivity to the interior's rows of K₁ and K₀, and its change to ΔK_ΓΓ.
        let triangles = update.model.mesh.triangles();
        for &t in &self.triangles {
            let index_of = |node: usize| {
                let row = update.model.row_of_node[node];
                (row != GROUNDED).then(|| local[row] as usize)
            };
            // Not `triangles[t].map(..)`: the map was left a call.
            let [a, b, c] = triangles[t];
            let index = [index_of(a), index_of(b), index_of(c)];
            let Some(&any) = index.iter().flatten().next() else { continue };
            let part = &self.parts[self.part_of[any] as usize];
            let (k, g) = (part.inner.len(), part.rim.len());
            let (background, delta) = (update.conductivity[t], self.delta[t]);
            let column = index.map(|i| i.map(|i| if i < rim { i - part.rim.start } else { g + i - part.inner.start }));
            let (k1, rest) = self.blocks[part.block..].split_at_mut(k * (g + k));
            let (k0, rest) = rest.split_at_mut(k * (g + k));
            let ds = &mut rest[..g * g];
            for (&(a, b), coef) in super::LOCAL.iter().zip(update.model.pattern.triangle_coefs[t]) {
                let (Some(ca), Some(cb)) = (column[a], column[b]) else { continue };
                let mut add = |row: usize, col: usize| {
                    if row >= g {
                        k1[col * k + row - g] += (background + delta) * coef;
                        k0[col * k + row - g] += background * coef;
                    } else if col < g {
                        ds[col * g + row] += delta * coef;
                    }
                };
                add(ca, cb);
                if a != b {
                    add(cb, ca);
                }
            }
        }
        self.stack_for(self.parts.iter().map(|p| p.inner.len()).max().unwrap_or(0));
        for part in &self.parts {
            let (k, g) = (part.inner.len(), part.rim.len());
            if k == 0 {
                continue;
            }
            let (k1, rest) = self.blocks[part.block..].split_at_mut(k * (g + k));
            let (k0, rest) = rest.split_at_mut(k * (g + k));
            let mut ds = MatMut::from_column_major_slice_mut(&mut rest[..g * g], g, g);
            for (block, sign) in [(k1, -1.0), (k0, 1.0)] {
                let (mut coupling, mut kii) = MatMut::from_column_major_slice_mut(block, k, g + k).split_at_col_mut(g);
                let stack = MemStack::new(&mut self.stack);
                let factored =
                    cholesky_in_place(kii.as_mut(), LltRegularization::default(), Par::Seq, stack, Default::default());
                if factored.is_err() {
                    return false;
                }
                solve_lower_triangular_in_place(kii.as_ref(), coupling.as_mut(), Par::Seq);
                matmul(ds.as_mut(), Accum::Add, coupling.as_ref().transpose(), coupling.as_ref(), sign, Par::Seq);
            }
        }
        true
    }

    /// Grows the Cholesky's scratch to parts of `k` interior rows (twice that: room for larger).
    fn stack_for(&mut self, k: usize) {
        let need = cholesky_in_place_scratch::<f64>(k, Par::Seq, Default::default());
        crate::scratch::stack_room(&mut self.stack, &mut self.stack_bytes, need);
    }

    /// I + G_ΓΓ·ΔS into `system` (`rim` × `rim`), G_ΓΓ in `green`: part by part, its rim's
    /// columns of G times its ΔS.
    pub(super) fn rim_system(&self, green: &Mat<f64>, system: &mut Mat<f64>, rim: usize) {
        grow(system, rim, rim);
        let green = green.as_ref().submatrix(0, 0, rim, rim);
        for part in &self.parts {
            let (cols, g) = (part.rim.start, part.rim.len());
            let to = system.as_mut().subcols_mut(cols, g);
            matmul(to, Accum::Replace, green.subcols(cols, g), self.schur(part), 1.0, Par::Seq);
        }
        (0..rim).for_each(|i| system[(i, i)] += 1.0);
    }

    /// The part of the last change whose triangles include triangle `t` (`local` the rows'
    /// indices after [`Interior::order_rows`]), if `t` was one of them and its part has interior
    /// rows.
    pub(super) fn part_holding(&self, update: &LowRankUpdate, local: &[u32], t: usize) -> Option<usize> {
        if self.seen.get(t) != Some(&self.generation) {
            return None;
        }
        let row = update.model.mesh.triangles()[t]
            .iter()
            .map(|&node| update.model.row_of_node[node])
            .find(|&row| row != GROUNDED)?;
        let index = *self.part_of.get(*local.get(row)? as usize)? as usize;
        self.parts.get(index).filter(|part| !part.inner.is_empty()).map(|_| index)
    }

    /// Part `part`'s rim (its indices among the change's rows, which come first) and ΔS, if it
    /// has interior rows.
    pub(super) fn part_rim(&self, part: usize) -> Option<(Range<usize>, MatRef<'_, f64>)> {
        let part = self.parts.get(part).filter(|part| !part.inner.is_empty())?;
        Some((part.rim.clone(), self.schur(part)))
    }

    /// Part `part`'s ΔS (its rim's rows × its rim's).
    fn schur(&self, part: &Part) -> MatRef<'_, f64> {
        let (k, g) = (part.inner.len(), part.rim.len());
        let at = part.block + 2 * k * (g + k);
        MatRef::from_column_major_slice(&self.blocks[at..at + g * g], g, g)
    }

    /// ΔS·X_Γ into `z` (`rim` × patterns), part by part.
    pub(super) fn schur_times(&self, x: MatRef<'_, f64>, mut z: MatMut<'_, f64>) {
        for part in &self.parts {
            let (rows, g) = (part.rim.start, part.rim.len());
            let to = z.as_mut().subrows_mut(rows, g);
            matmul(to, Accum::Replace, self.schur(part), x.subrows(rows, g), 1.0, Par::Seq);
        }
    }

    /// The interior's rows of `x` (|R| × patterns) from its rim's: X_I = −K₁_II⁻¹·K₁_IΓ·X_Γ =
    /// −L⁻ᵀ·(Y·X_Γ), part by part.
    pub(super) fn extend(&self, x: MatMut<'_, f64>, rim: usize) {
        let (rims, mut inner) = x.split_at_row_mut(rim);
        for part in self.parts.iter().filter(|p| !p.inner.is_empty()) {
            let (k, g) = (part.inner.len(), part.rim.len());
            let block = MatRef::from_column_major_slice(&self.blocks[part.block..part.block + k * (g + k)], k, g + k);
            let (y, l) = block.split_at_col(g);
            let mut to = inner.as_mut().subrows_mut(part.inner.start - rim, k);
            matmul(to.as_mut(), Accum::Replace, y, rims.as_ref().subrows(part.rim.start, g), -1.0, Par::Seq);
            solve_upper_triangular_in_place(l.transpose(), to, Par::Seq);
        }
    }
}
