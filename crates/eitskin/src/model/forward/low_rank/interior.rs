//! A change's interior rows eliminated onto its rim (static condensation), so that the
//! update's dense system has the rim's rows only.
//!
//! A node all of whose triangles change, and which is not on the boundary (so carries no
//! electrode and no source), has a row of the changed system K₁ = K₀ + ΔK that involves the
//! change's rows alone: K₁_II·u_I + K₁_IΓ·u_Γ = 0, so u_I = P·u_Γ with P = −K₁_II⁻¹·K₁_IΓ (the
//! interior's potentials are the rim's, spread by the new conductivity). Put into the update on
//! the rim's rows, u_Γ = u₀_Γ − G_ΓR·ΔK_RR·u_R, it leaves
//!
//!   (I + G_ΓR·Q)·u_Γ = u₀_Γ,   Q = ΔK_RΓ + ΔK_RI·P,
//!
//! exact, of the rim's rows Γ alone (three presses on the virtual sensor's 12k-triangle mesh: 97
//! of 231 rows, a twelfth of the LU's work, and 0.4 of G to gather). ΔK and K₁_II are block
//! diagonal over the change's connected parts (presses apart), so each part's K₁_II, a few
//! dozen rows, is factored on its own by Cholesky: it is the part's stiffness with its rim held,
//! positive definite while the conductivity there is positive. Where it is not (a conductivity
//! at or below 0), the change is solved on all its rows instead; so is a change of one part,
//! for which the elimination costs about what it saves ([`PARTS_TO_ELIMINATE`]).

use std::ops::Range;

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::{cholesky_in_place, cholesky_in_place_scratch, LltRegularization};
use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::{solve_lower_triangular_in_place, solve_upper_triangular_in_place};
use faer::{Accum, Mat, MatMut, MatRef, Par};

use super::{grow, LowRankUpdate, Nonzeros, GROUNDED};

/// Parts with an interior from which a change's interior is eliminated: the dense system's
/// work grows as the cube of all its rows, the elimination's as each part's, so for one part
/// it costs about what it saves (measured: a press on the truth mesh 79 → 88 µs), and for three
/// presses apart it saves a third of the frame (580 → 380 µs).
pub(super) const PARTS_TO_ELIMINATE: usize = 2;

/// `rows` in order again, `local` their indices.
pub(super) fn sorted(rows: &mut [usize], local: &mut [u32]) {
    rows.sort_unstable();
    rows.iter().enumerate().for_each(|(i, &r)| local[r] = i as u32);
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
    parts: Vec<Part>,
    /// Each row's part (index after ordering); in [`Interior::analyse`], 1 at each root with an
    /// interior row.
    part_of: Vec<u32>,
    /// Per part, K₁'s interior rows (k × (g + k), column-major: its rim's columns, then its
    /// interior's), then P in the first g columns.
    blocks: Vec<f64>,
    /// W = G_ΓR·ΔK, |Γ| × |R|.
    w: Mat<f64>,
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
            parts: Vec::new(),
            part_of: Vec::new(),
            blocks: Vec::new(),
            w: Mat::zeros(0, 0),
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

/// Part `part`'s P (its interior's rows × its rim's) in `blocks`.
fn p_of<'a>(blocks: &'a [f64], part: &Part) -> MatRef<'a, f64> {
    let (k, g) = (part.inner.len(), part.rim.len());
    MatRef::from_column_major_slice(&blocks[part.block..part.block + k * g], k, g)
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
        // A part's block is its interior's rows by all its rows, about |R|²/2 entries for a
        // press of |R| rows: 8 per row of the system holds a few presses of a hundred rows on
        // the meshes presses are fitted on (more grows by doubling). Then the parts, and the
        // Cholesky's scratch for a part as large as the system.
        super::room(&mut self.blocks, 8 * rows);
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

    /// Orders the change's rows `rows` as the rim's, then the interior's, each grouped by part
    /// (as [`Interior::analyse`] found them), and sets `local` to the new indices; returns how
    /// many are the rim's.
    pub(super) fn order_rows(&mut self, update: &LowRankUpdate, rows: &mut [usize], local: &mut [u32]) -> usize {
        let s = rows.len();
        self.order.clear();
        for (i, &row) in rows.iter().enumerate() {
            let inner = update.incident[row] == self.count[i];
            self.order.push((inner, root(&mut self.parent, i) as u32, row));
        }
        self.order.sort_unstable();
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

    /// P of each part from K₁ on its triangles (`local` the rows' indices after
    /// [`Interior::order_rows`], `rim` the rim's rows); `false` where a part's K₁_II is not
    /// positive definite.
    pub(super) fn eliminate(&mut self, update: &LowRankUpdate, local: &[u32], rim: usize) -> bool {
        let mut offset = 0;
        for part in &mut self.parts {
            part.block = offset;
            offset += part.inner.len() * (part.rim.len() + part.inner.len());
        }
        if offset == 0 {
            return true;
        }
        // Grown by doubling: sizes that vary from frame to frame settle.
        super::room(&mut self.blocks, offset.next_power_of_two());
        self.blocks.clear();
        self.blocks.resize(offset, 0.0);
        // Each triangle with an interior row adds its stiffness at the changed conductivity to
        // its part's block (all its rows are of one part), on the interior's rows only.
        let triangles = update.model.mesh.triangles();
        for &t in &self.triangles {
            let index = triangles[t].map(|node| {
                let row = update.model.row_of_node[node];
                (row != GROUNDED).then(|| local[row] as usize)
            });
            let Some(&inner) = index.iter().flatten().find(|&&i| i >= rim) else { continue };
            let part = &self.parts[self.part_of[inner] as usize];
            let (k, sigma) = (part.inner.len(), update.conductivity[t] + self.delta[t]);
            let column = index
                .map(|i| i.map(|i| if i < rim { i - part.rim.start } else { part.rim.len() + i - part.inner.start }));
            let block = &mut self.blocks[part.block..];
            for (&(a, b), coef) in super::LOCAL.iter().zip(update.model.pattern.triangle_coefs[t]) {
                let (Some(ia), Some(ib), Some(ca), Some(cb)) = (index[a], index[b], column[a], column[b]) else {
                    continue;
                };
                let value = sigma * coef;
                if ia >= rim {
                    block[cb * k + ia - part.inner.start] += value;
                }
                if a != b && ib >= rim {
                    block[ca * k + ib - part.inner.start] += value;
                }
            }
        }
        self.stack_for(self.parts.iter().map(|p| p.inner.len()).max().unwrap_or(0));
        for part in &self.parts {
            let (k, g) = (part.inner.len(), part.rim.len());
            if k == 0 {
                continue;
            }
            let block = &mut self.blocks[part.block..part.block + k * (g + k)];
            let (mut coupling, mut kii) = MatMut::from_column_major_slice_mut(block, k, g + k).split_at_col_mut(g);
            let stack = MemStack::new(&mut self.stack);
            let factored =
                cholesky_in_place(kii.as_mut(), LltRegularization::default(), Par::Seq, stack, Default::default());
            if factored.is_err() {
                return false;
            }
            solve_lower_triangular_in_place(kii.as_ref(), coupling.as_mut(), Par::Seq);
            solve_upper_triangular_in_place(kii.as_ref().transpose(), coupling.as_mut(), Par::Seq);
            coupling.col_iter_mut().for_each(|c| c.iter_mut().for_each(|p| *p = -*p));
        }
        true
    }

    /// Grows the Cholesky's scratch to parts of `k` interior rows (twice that: room for larger).
    fn stack_for(&mut self, k: usize) {
        let need = cholesky_in_place_scratch::<f64>(k, Par::Seq, Default::default());
        crate::scratch::stack_room(&mut self.stack, &mut self.stack_bytes, need);
    }

    /// I + G_ΓR·Q into `system` (`rim` × `rim`), from ΔK's columns `dk` and G_ΓR, the first
    /// `rim` rows of `green` (|R| columns): W = G_ΓR·ΔK first (each of ΔK's few entries in a
    /// column adds a column of G_ΓR), then, part by part, W's rim columns plus its interior
    /// columns times P (G_ΓR·Q = W_Γ + W_I·P, Q = ΔK_RΓ + ΔK_RI·P).
    pub(super) fn rim_system(&mut self, dk: &Nonzeros, green: &Mat<f64>, system: &mut Mat<f64>, rim: usize) {
        let s = green.ncols();
        grow(&mut self.w, rim, s);
        for j in 0..s {
            let column = self.w.col_as_slice_mut(j);
            column.fill(0.0);
            super::add_columns(column, green, dk.column(j));
        }
        grow(system, rim, rim);
        let w = self.w.as_ref();
        for part in &self.parts {
            let (cols, g, k) = (part.rim.start, part.rim.len(), part.inner.len());
            let mut to = system.as_mut().subcols_mut(cols, g);
            to.copy_from(w.subcols(cols, g));
            if k > 0 && g > 0 {
                matmul(to, Accum::Add, w.subcols(part.inner.start, k), p_of(&self.blocks, part), 1.0, Par::Seq);
            }
        }
        (0..rim).for_each(|i| system[(i, i)] += 1.0);
    }

    /// The interior's rows of `x` (|R| × patterns) from its rim's: X_I = P·X_Γ, part by part.
    pub(super) fn extend(&self, x: MatMut<'_, f64>, rim: usize) {
        let (rims, mut inner) = x.split_at_row_mut(rim);
        for part in self.parts.iter().filter(|p| !p.inner.is_empty()) {
            let to = inner.as_mut().subrows_mut(part.inner.start - rim, part.inner.len());
            let from = rims.as_ref().subrows(part.rim.start, part.rim.len());
            matmul(to, Accum::Replace, p_of(&self.blocks, part), from, 1.0, Par::Seq);
        }
    }
}
