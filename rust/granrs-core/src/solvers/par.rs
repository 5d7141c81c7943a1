//! Row-block execution helpers of the pressure solvers.
//!
//! Every kernel of the solvers works on fixed blocks of [`ROW_BLOCK`] rows, whatever the number
//! of threads, and every reduction adds per-block partial sums in block order into a buffer that
//! was allocated once: one thread and many threads give bit-identical results, and `solve`
//! allocates nothing. These helpers complement [`Exec::for_each_row`] (which they mirror) with
//! reductions that also write, and with an index-only loop for the red–black smoother.

use rayon::prelude::*;

use crate::exec::{Exec, ROW_BLOCK};

/// Number of row blocks of a grid with `nrows` rows.
#[inline]
pub(crate) fn n_blocks(nrows: usize) -> usize {
    nrows.div_ceil(ROW_BLOCK)
}

/// Runs `f(rows)` on every block of `block_rows` rows of `0..nrows`, in parallel when `exec`
/// allows it for a grid of `cells` cells. Blocks are disjoint.
pub(crate) fn for_blocks_of<F>(exec: Exec, nrows: usize, cells: usize, block_rows: usize, f: F)
where
    F: Fn(std::ops::Range<usize>) + Sync + Send,
{
    let nb = nrows.div_ceil(block_rows);
    let block = |b: usize| b * block_rows..((b + 1) * block_rows).min(nrows);
    if exec.use_parallel(cells) {
        (0..nb).into_par_iter().for_each(|b| f(block(b)));
    } else {
        (0..nb).for_each(|b| f(block(b)));
    }
}

/// Runs `f(row_index, row)` on every row of `data` (rows of length `stride`) and returns the
/// deterministic sum of the values `f` returns: per-block partial sums are stored in `partials`
/// (length ≥ number of blocks) and added in block order. Each component of the returned array is
/// reduced the same way.
pub(crate) fn rows_sum<const K: usize, F>(exec: Exec, data: &mut [f64], stride: usize, partials: &mut [[f64; K]], f: F) -> [f64; K]
where
    F: Fn(usize, &mut [f64]) -> [f64; K] + Sync + Send,
{
    let nrows = data.len() / stride;
    let nb = n_blocks(nrows);
    let partials = &mut partials[..nb];
    let block = |b: usize, chunk: &mut [f64]| -> [f64; K] {
        let mut s = [0.0; K];
        for (r, row) in chunk.chunks_mut(stride).enumerate() {
            let v = f(b * ROW_BLOCK + r, row);
            for c in 0..K {
                s[c] += v[c];
            }
        }
        s
    };
    if exec.use_parallel(data.len()) {
        data.par_chunks_mut(stride * ROW_BLOCK).zip(partials.par_iter_mut()).enumerate().for_each(|(b, (chunk, out))| *out = block(b, chunk));
    } else {
        for (b, (chunk, out)) in data.chunks_mut(stride * ROW_BLOCK).zip(partials.iter_mut()).enumerate() {
            *out = block(b, chunk);
        }
    }
    let mut total = [0.0; K];
    for p in partials.iter() {
        for c in 0..K {
            total[c] += p[c];
        }
    }
    total
}

/// Deterministic sum over rows `0..nrows` of `f(row)` (nothing written), with the same block
/// structure as [`rows_sum`].
pub(crate) fn sum_rows<const K: usize, F>(exec: Exec, nrows: usize, cells: usize, partials: &mut [[f64; K]], f: F) -> [f64; K]
where
    F: Fn(usize) -> [f64; K] + Sync + Send,
{
    let nb = n_blocks(nrows);
    let partials = &mut partials[..nb];
    let block = |b: usize| -> [f64; K] {
        let mut s = [0.0; K];
        for r in b * ROW_BLOCK..((b + 1) * ROW_BLOCK).min(nrows) {
            let v = f(r);
            for c in 0..K {
                s[c] += v[c];
            }
        }
        s
    };
    if exec.use_parallel(cells) {
        partials.par_iter_mut().enumerate().for_each(|(b, out)| *out = block(b));
    } else {
        for (b, out) in partials.iter_mut().enumerate() {
            *out = block(b);
        }
    }
    let mut total = [0.0; K];
    for p in partials.iter() {
        for c in 0..K {
            total[c] += p[c];
        }
    }
    total
}

/// A raw pointer to a buffer that several threads update at disjoint locations (the cells of one
/// colour in a red–black sweep, the new faces of one layer of the free surface's velocity
/// extension). Used by [`super::level::Level::smooth`] and `projection::free_surface`.
#[derive(Clone, Copy)]
pub(crate) struct SharedMut(pub(crate) *mut f64);

impl SharedMut {
    /// The pointer (a method, so that closures capture the whole `Sync` wrapper).
    #[inline]
    pub(crate) fn get(self) -> *mut f64 {
        self.0
    }
}

// SAFETY: the pointer is only dereferenced by the red–black sweep and the extension layers, where
// threads write disjoint cells and never read a cell that another thread writes in the same phase.
unsafe impl Send for SharedMut {}
// SAFETY: as for `Send`: concurrent uses touch disjoint or read-only locations.
unsafe impl Sync for SharedMut {}
