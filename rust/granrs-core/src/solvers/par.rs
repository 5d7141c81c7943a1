//! Row-block execution helpers of the pressure solvers.
//!
//! Every reduction of the solvers adds its rows' sums in fixed blocks of [`ROW_BLOCK`] rows,
//! whatever the number of threads: each block's rows in order from 0, then the blocks in order
//! from 0. The rows' sums themselves are made on the pool in tasks of [`balanced_task_rows`] rows
//! (a few thousand cells each, as many tasks for each thread, so that the threads get equal
//! shares of a window a few dozen rows high)
//! into a buffer of one partial per row that was allocated once ([`partials_len`]); the blocks
//! are added afterwards on the calling thread. One thread and many threads give bit-identical
//! results, and `solve` allocates nothing. These helpers complement [`Exec::for_each_row`] with
//! reductions (also over passes that write) and with an index-only loop over balanced blocks for
//! the red–black smoother, whose result does not depend on its blocks.

use rayon::prelude::*;

use crate::exec::{add_by_blocks, balanced_task_rows, Exec, ROW_BLOCK};

/// Length of the partials buffer of a reduction over `nrows` rows: one partial per row.
#[inline]
pub(crate) fn partials_len(nrows: usize) -> usize {
    nrows
}

/// Rows per task of a reduction over `nrows` rows holding `cells` values in all.
#[inline]
fn reduction_rows(nrows: usize, cells: usize) -> usize {
    balanced_task_rows(nrows, cells / nrows.max(1))
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

/// The sum of [`Exec::sum_rows_into`] with the rows' sums made a few rows at a time: `f(j0,
/// sums)` writes the sums of rows j0 .. j0 + sums.len() (at most [`ROW_BLOCK`] rows; each as
/// `sum_rows_into`'s `f(j)` would return it: [`crate::operators::sums_by_row`] makes them four rows at a time with
/// the bits of one fold per row), and they are added by [`add_by_blocks`], so that the result
/// has the bits of [`Exec::sum_rows_into`] with the same rows' sums.
pub(crate) fn sum_row_blocks<const K: usize, F>(exec: Exec, nrows: usize, cells: usize, partials: &mut [[f64; K]], f: F) -> [f64; K]
where
    F: Fn(usize, &mut [[f64; K]]) + Sync + Send,
{
    let partials = &mut partials[..nrows];
    if exec.use_parallel(cells) {
        let rows = reduction_rows(nrows, cells);
        partials.par_chunks_mut(rows).enumerate().for_each(|(t, out)| f(t * rows, out));
    } else {
        for (b, out) in partials.chunks_mut(ROW_BLOCK).enumerate() {
            f(b * ROW_BLOCK, out);
        }
    }
    add_by_blocks(partials)
}

/// [`sum_row_blocks`] over a pass that writes a row-major array (rows of `nx` values): `f(j0,
/// rows, sums)` writes the rows from row j0 (at most [`ROW_BLOCK`]) and their sums.
pub(crate) fn write_row_blocks<const K: usize, F>(exec: Exec, a: &mut [f64], nx: usize, partials: &mut [[f64; K]], f: F) -> [f64; K]
where
    F: Fn(usize, &mut [f64], &mut [[f64; K]]) + Sync + Send,
{
    let nrows = a.len() / nx;
    let partials = &mut partials[..nrows];
    if exec.use_parallel(a.len()) {
        let rows = reduction_rows(nrows, a.len());
        a.par_chunks_mut(rows * nx).zip(partials.par_chunks_mut(rows)).enumerate().for_each(|(t, (ca, out))| f(t * rows, ca, out));
    } else {
        for (b, (ca, out)) in a.chunks_mut(ROW_BLOCK * nx).zip(partials.chunks_mut(ROW_BLOCK)).enumerate() {
            f(b * ROW_BLOCK, ca, out);
        }
    }
    add_by_blocks(partials)
}

/// [`sum_row_blocks`] over a pass that writes two row-major arrays (rows of `nx` values): `f(j0,
/// a_rows, b_rows, sums)` writes the rows of `a` and `b` from row j0 (at most [`ROW_BLOCK`]) and
/// their sums.
pub(crate) fn write2_row_blocks<const K: usize, F>(exec: Exec, a: &mut [f64], b: &mut [f64], nx: usize, partials: &mut [[f64; K]], f: F) -> [f64; K]
where
    F: Fn(usize, &mut [f64], &mut [f64], &mut [[f64; K]]) + Sync + Send,
{
    let nrows = a.len() / nx;
    let partials = &mut partials[..nrows];
    if exec.use_parallel(a.len()) {
        let rows = reduction_rows(nrows, a.len());
        a.par_chunks_mut(rows * nx)
            .zip(b.par_chunks_mut(rows * nx))
            .zip(partials.par_chunks_mut(rows))
            .enumerate()
            .for_each(|(t, ((ca, cb), out))| f(t * rows, ca, cb, out));
    } else {
        for (blk, ((ca, cb), out)) in a.chunks_mut(ROW_BLOCK * nx).zip(b.chunks_mut(ROW_BLOCK * nx)).zip(partials.chunks_mut(ROW_BLOCK)).enumerate() {
            f(blk * ROW_BLOCK, ca, cb, out);
        }
    }
    add_by_blocks(partials)
}

/// A raw pointer to a buffer that several threads update at disjoint locations (the cells of one
/// colour in a red–black sweep, the new faces of one layer of the free surface's velocity
/// extension, the strips of a pipelined fast sweep). Used by [`super::level::Level::smooth`],
/// `projection::free_surface` and `levelset::redistance`.
#[derive(Clone, Copy)]
pub(crate) struct SharedMut(pub(crate) *mut f64);

impl SharedMut {
    /// The pointer (a method, so that closures capture the whole `Sync` wrapper).
    #[inline]
    pub(crate) fn get(self) -> *mut f64 {
        self.0
    }
}

// SAFETY: the pointer is only dereferenced by the red–black sweep, the extension layers and the
// strips of fast sweeping, where threads write disjoint cells and never read a cell while another
// thread writes it (the sweep's strips order their accesses by per-row progress counters).
unsafe impl Send for SharedMut {}
// SAFETY: as for `Send`: concurrent uses touch disjoint or read-only locations.
unsafe impl Sync for SharedMut {}

#[cfg(test)]
mod tests {
    //! The reductions against their definition, bit for bit, on rows short enough for blocks of
    //! eight rows per task and long enough for tasks of one to three rows.
    use super::*;

    /// Each row's values added left to right from 0, the rows of each block of [`ROW_BLOCK`]
    /// rows in order from 0, the blocks in order from 0.
    fn by_definition(a: &[f64], nx: usize, term: impl Fn(f64) -> f64) -> f64 {
        let rows: Vec<f64> = a.chunks(nx).map(|r| r.iter().fold(0.0, |s, &x| s + term(x))).collect();
        rows.chunks(ROW_BLOCK).map(|blk| blk.iter().fold(0.0, |s, v| s + v)).fold(0.0, |s, v| s + v)
    }

    #[test]
    fn the_reductions_are_their_definition_bit_for_bit_whatever_the_tasks() {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        for (nx, ny) in [(5, 1), (70, 13), (700, 37), (3000, 19), (1500, 3)] {
            let wave = |k: usize| (0.77 * k as f64).sin() * 10f64.powi((k % 7) as i32 - 3 + ((k / nx) % 5) as i32 * 4 - 8);
            let a: Vec<f64> = (0..nx * ny).map(wave).collect();
            let (want_sum, want_sq) = (by_definition(&a, nx, |x| x), by_definition(&a, nx, |x| x * x));
            for exec in [Exec::SERIAL, Exec::with_threads(2)] {
                let mut partials = vec![[f64::NAN; 1]; partials_len(ny)];
                let mut partials2 = vec![[f64::NAN; 2]; partials_len(ny)];
                let got = pool.install(|| {
                    let [s1] = exec.sum_rows_into(ny, nx * ny, &mut partials, |j| [a[j * nx..(j + 1) * nx].iter().fold(0.0, |s, &x| s + x)]);
                    let [s2] = sum_row_blocks(exec, ny, nx * ny, &mut partials, |j0, out| {
                        for (k, o) in out.iter_mut().enumerate() {
                            *o = [a[(j0 + k) * nx..(j0 + k + 1) * nx].iter().fold(0.0, |s, &x| s + x)];
                        }
                    });
                    let mut w = a.clone();
                    let [s3] = write_row_blocks(exec, &mut w, nx, &mut partials, |j0, rows, out| {
                        for (k, (row, o)) in rows.chunks_mut(nx).zip(out.iter_mut()).enumerate() {
                            assert_eq!(row, &a[(j0 + k) * nx..(j0 + k + 1) * nx], "the task's rows start at row j0");
                            row.iter_mut().for_each(|x| *x *= *x);
                            *o = [row.iter().fold(0.0, |s, &x| s + x)];
                        }
                    });
                    let (mut w1, mut w2) = (a.clone(), a.clone());
                    let [s4, s5] = write2_row_blocks(exec, &mut w1, &mut w2, nx, &mut partials2, |_, r1, r2, out| {
                        for ((x, y), o) in r1.chunks_mut(nx).zip(r2.chunks_mut(nx)).zip(out.iter_mut()) {
                            y.iter_mut().for_each(|v| *v *= *v);
                            *o = [x.iter().fold(0.0, |s, &v| s + v), y.iter().fold(0.0, |s, &v| s + v)];
                        }
                    });
                    let s6 = exec.sum_rows(ny, nx * ny, |j| a[j * nx..(j + 1) * nx].iter().fold(0.0, |s, &x| s + x));
                    [s1, s2, s3, s4, s5, s6]
                });
                let want = [want_sum, want_sum, want_sq, want_sum, want_sq, want_sum];
                for (k, (g, w)) in got.iter().zip(want).enumerate() {
                    assert_eq!(g.to_bits(), w.to_bits(), "reduction {k}, {nx} x {ny}, {exec:?}: {g} != {w}");
                }
            }
        }
        // the check can fail: the rows' sums added in tasks of three rows, then the tasks in
        // order, differ from the definition (rows whose sums span sixteen orders of magnitude)
        let (nx, ny) = (700, 37);
        let a: Vec<f64> = (0..nx * ny).map(|k| (0.77 * k as f64).sin() * 10f64.powi(((k / nx) % 5) as i32 * 4 - 8)).collect();
        let rows: Vec<f64> = a.chunks(nx).map(|r| r.iter().fold(0.0, |s, &x| s + x)).collect();
        let by_tasks = rows.chunks(3).map(|t| t.iter().fold(0.0, |s, v| s + v)).fold(0.0, |s, v| s + v);
        assert_ne!(by_tasks.to_bits(), by_definition(&a, nx, |x| x).to_bits());
    }
}
