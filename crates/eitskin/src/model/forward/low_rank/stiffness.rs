//! ΔK_RR, the change of the system's stiffness on a change's rows, column by column.
//!
//! The changed triangles add their stiffness into the system pattern's slots (a slot is one
//! entry of the lower triangle, shared by the triangles of an edge), and each column of ΔK_RR
//! is then read off its row's neighbours in the pattern: no entry is sorted or merged, and the
//! slots are cleared again by the same triangles.

use super::super::assemble::{Pattern, GROUNDED};
use super::{room, LowRankUpdate, UNUSED};

/// Each row's neighbours in a symmetric pattern stored as its lower triangle: (row, slot) pairs,
/// rows increasing, the diagonal included.
#[derive(Debug, Clone)]
pub(super) struct Adjacency {
    /// Per row, where its neighbours start (one more entry than rows).
    start: Vec<usize>,
    /// (neighbour's row, slot of the entry between them).
    entries: Vec<(u32, u32)>,
}

impl Adjacency {
    /// The neighbours of every row of `pattern`.
    pub(super) fn of(pattern: &Pattern) -> Adjacency {
        let n = pattern.size;
        // Rows and slots as u32: a system of billions of entries is far past any this solves.
        debug_assert!(pattern.row_idx.len() <= u32::MAX as usize);
        let mut start = vec![0; n + 2];
        for c in 0..n {
            for &r in &pattern.row_idx[pattern.col_ptr[c]..pattern.col_ptr[c + 1]] {
                start[c + 2] += 1;
                if r != c {
                    start[r + 2] += 1;
                }
            }
        }
        for r in 2..start.len() {
            start[r] += start[r - 1];
        }
        // Columns in order put each row's neighbours in order: those before it (from their
        // columns), then its own column's (the diagonal first).
        let mut entries = vec![(0, 0); start[n + 1]];
        for c in 0..n {
            for slot in pattern.col_ptr[c]..pattern.col_ptr[c + 1] {
                let r = pattern.row_idx[slot];
                entries[start[c + 1]] = (r as u32, slot as u32);
                start[c + 1] += 1;
                if r != c {
                    entries[start[r + 1]] = (c as u32, slot as u32);
                    start[r + 1] += 1;
                }
            }
        }
        start.pop();
        Adjacency { start, entries }
    }

    fn of_row(&self, row: usize) -> &[(u32, u32)] {
        &self.entries[self.start[row]..self.start[row + 1]]
    }
}

/// The nonzero entries of ΔK_RR, column by column (built from the changed triangles,
/// [`Nonzeros::stiffness_change`]).
#[derive(Debug, Default)]
pub(super) struct Nonzeros {
    /// Per column, where its entries start (one more than columns).
    start: Vec<usize>,
    /// (row, value).
    entries: Vec<(usize, f64)>,
    /// Per slot of the system's pattern, the change's sum there (zero outside a call; grown at
    /// the first change).
    sums: Vec<f64>,
}

impl Nonzeros {
    /// ΔK_RR of `changes` from the triangles' stiffness, column by column: `rows` the change's
    /// rows in R's order, `local` each row of the system's index in R ([`UNUSED`] outside it;
    /// every row of a changed triangle is in R, or grounded). A column's entries come in the
    /// order of the system's rows, repeats (an edge of two changed triangles) summed in the
    /// order of `changes`, zeros left out.
    pub(super) fn stiffness_change(
        &mut self,
        update: &LowRankUpdate,
        changes: &[(usize, f64)],
        rows: &[usize],
        local: &[u32],
    ) {
        let pattern = &update.model.pattern;
        if self.sums.len() != pattern.row_idx.len() {
            self.sums.clear();
            self.sums.resize(pattern.row_idx.len(), 0.0);
        }
        for &(t, delta) in changes {
            for (&slot, &coef) in pattern.triangle_slots[t].iter().zip(&pattern.triangle_coefs[t]) {
                if slot != GROUNDED {
                    self.sums[slot] += delta * coef;
                }
            }
        }
        self.start.clear();
        self.entries.clear();
        for &row in rows {
            self.start.push(self.entries.len());
            for &(other, slot) in update.adjacency.of_row(row) {
                let (i, value) = (local[other as usize], self.sums[slot as usize]);
                if i != UNUSED && value != 0.0 {
                    self.entries.push((i as usize, value));
                }
            }
        }
        self.start.push(self.entries.len());
        for &(t, _) in changes {
            for &slot in &pattern.triangle_slots[t] {
                if slot != GROUNDED {
                    self.sums[slot] = 0.0;
                }
            }
        }
    }

    /// Column `j`'s entries, (row in R, value).
    pub(super) fn column(&self, j: usize) -> &[(usize, f64)] {
        &self.entries[self.start[j]..self.start[j + 1]]
    }

    /// Room for changes of up to `columns` rows.
    pub(super) fn reserve(&mut self, columns: usize) {
        room(&mut self.start, columns + 1);
        // A node of a triangulation has about six neighbours and itself.
        room(&mut self.entries, 8 * columns);
    }
}
