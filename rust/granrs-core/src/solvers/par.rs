//! Row-block execution helpers of the pressure solvers.
//!
//! Every reduction of the solvers works on fixed blocks of [`ROW_BLOCK`] rows, whatever the
//! number of threads, and adds per-block partial sums in block order into a buffer that was
//! allocated once: one thread and many threads give bit-identical results, and `solve`
//! allocates nothing. These helpers complement [`Exec::for_each_row`] with reductions (also over
//! passes that write) and with an index-only loop over balanced blocks for the red–black
//! smoother, whose result does not depend on its blocks.

use rayon::prelude::*;

use crate::exec::{Exec, ROW_BLOCK};

/// Number of row blocks of a grid with `nrows` rows.
#[inline]
pub(crate) fn n_blocks(nrows: usize) -> usize {
    nrows.div_ceil(ROW_BLOCK)
}

/// Runs `f(rows)` on `nblocks` disjoint blocks of consecutive rows that cover `0..nrows`, in
/// parallel when `exec` allows it for a grid of `cells` cells. Without `work` the blocks' sizes
/// differ by at most one row; with `work` (nrows + 1 non-decreasing prefix sums of the rows'
/// work, from 0) block b ends at the first row whose prefix reaches (b + 1)/nblocks of the
/// total, so that the blocks hold equal work (a block may then be empty).
pub(crate) fn for_balanced_blocks<F>(exec: Exec, nrows: usize, cells: usize, nblocks: usize, work: Option<&[usize]>, f: F)
where
    F: Fn(std::ops::Range<usize>) + Sync + Send,
{
    let nb = nblocks.clamp(1, nrows.max(1));
    let end = |b: usize| match work {
        None => b * nrows / nb,
        Some(w) => {
            let target = b * w[nrows] / nb;
            if b == nb {
                nrows
            } else {
                w[..=nrows].partition_point(|&v| v < target).min(nrows)
            }
        }
    };
    let block = |b: usize| end(b)..end(b + 1);
    if exec.use_parallel(cells) {
        (0..nb).into_par_iter().for_each(|b| f(block(b)));
    } else {
        (0..nb).for_each(|b| f(block(b)));
    }
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

/// The sum of [`sum_rows`] with the rows' sums made a block at a time: `f(j0, sums)` writes the
/// sums of rows j0 .. j0 + sums.len() (each as [`sum_rows`]'s `f(j)` would return it;
/// [`crate::operators::sums_by_row`] makes them four rows at a time with the bits of one fold
/// per row); each block adds its rows' sums in row order from 0 and the blocks are added in block
/// order, so that the result has the bits of [`sum_rows`] with the same rows' sums.
pub(crate) fn sum_row_blocks<const K: usize, F>(exec: Exec, nrows: usize, cells: usize, partials: &mut [[f64; K]], f: F) -> [f64; K]
where
    F: Fn(usize, &mut [[f64; K]]) + Sync + Send,
{
    let nb = n_blocks(nrows);
    let partials = &mut partials[..nb];
    let block = |b: usize| -> [f64; K] {
        let j0 = b * ROW_BLOCK;
        let mut sums = [[0.0; K]; ROW_BLOCK];
        let sums = &mut sums[..(nrows - j0).min(ROW_BLOCK)];
        f(j0, sums);
        add_in_order(sums)
    };
    if exec.use_parallel(cells) {
        partials.par_iter_mut().enumerate().for_each(|(b, out)| *out = block(b));
    } else {
        for (b, out) in partials.iter_mut().enumerate() {
            *out = block(b);
        }
    }
    add_in_order(partials)
}

/// [`sum_row_blocks`] over a pass that writes a row-major array (rows of `nx` values): `f(j0,
/// rows, sums)` writes the block's rows (from row j0) and their sums.
pub(crate) fn write_row_blocks<const K: usize, F>(exec: Exec, a: &mut [f64], nx: usize, partials: &mut [[f64; K]], f: F) -> [f64; K]
where
    F: Fn(usize, &mut [f64], &mut [[f64; K]]) + Sync + Send,
{
    let nb = n_blocks(a.len() / nx);
    let partials = &mut partials[..nb];
    let chunk = ROW_BLOCK * nx;
    let block = |blk: usize, ca: &mut [f64]| -> [f64; K] {
        let mut sums = [[0.0; K]; ROW_BLOCK];
        let sums = &mut sums[..ca.len() / nx];
        f(blk * ROW_BLOCK, ca, sums);
        add_in_order(sums)
    };
    if exec.use_parallel(a.len()) {
        a.par_chunks_mut(chunk).zip(partials.par_iter_mut()).enumerate().for_each(|(blk, (ca, out))| *out = block(blk, ca));
    } else {
        for (blk, (ca, out)) in a.chunks_mut(chunk).zip(partials.iter_mut()).enumerate() {
            *out = block(blk, ca);
        }
    }
    add_in_order(partials)
}

/// [`sum_row_blocks`] over a pass that writes two row-major arrays (rows of `nx` values): `f(j0,
/// a_rows, b_rows, sums)` writes the block's rows of `a` and `b` (from row j0) and their sums.
pub(crate) fn write2_row_blocks<const K: usize, F>(exec: Exec, a: &mut [f64], b: &mut [f64], nx: usize, partials: &mut [[f64; K]], f: F) -> [f64; K]
where
    F: Fn(usize, &mut [f64], &mut [f64], &mut [[f64; K]]) + Sync + Send,
{
    let nrows = a.len() / nx;
    let nb = n_blocks(nrows);
    let partials = &mut partials[..nb];
    let chunk = ROW_BLOCK * nx;
    let block = |blk: usize, ca: &mut [f64], cb: &mut [f64]| -> [f64; K] {
        let mut sums = [[0.0; K]; ROW_BLOCK];
        let sums = &mut sums[..ca.len() / nx];
        f(blk * ROW_BLOCK, ca, cb, sums);
        add_in_order(sums)
    };
    if exec.use_parallel(a.len()) {
        a.par_chunks_mut(chunk)
            .zip(b.par_chunks_mut(chunk))
            .zip(partials.par_iter_mut())
            .enumerate()
            .for_each(|(blk, ((ca, cb), out))| *out = block(blk, ca, cb));
    } else {
        for (blk, ((ca, cb), out)) in a.chunks_mut(chunk).zip(b.chunks_mut(chunk)).zip(partials.iter_mut()).enumerate() {
            *out = block(blk, ca, cb);
        }
    }
    add_in_order(partials)
}

/// The sum of `values` added in their order from 0.
#[inline]
fn add_in_order<const K: usize>(values: &[[f64; K]]) -> [f64; K] {
    let mut total = [0.0; K];
    for v in values {
        for c in 0..K {
            total[c] += v[c];
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
