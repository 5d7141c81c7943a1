//! Execution policy: how a kernel runs (serially or on the rayon pool that the caller installed).
//!
//! Kernels never decide the thread count themselves: a model owns a `rayon::ThreadPool` of the
//! user's `threads` and runs its step inside `pool.install`, passing `Exec::parallel(..)` down.
//! Reductions add their rows' values in fixed blocks of rows ([`ROW_BLOCK`]), independent of
//! the number of threads, and the blocks' sums in block order; sweeps without a
//! reduction write each row independently and are split into tasks of [`task_rows`] rows. One
//! thread and many threads give bit-identical answers.

use rayon::prelude::*;

/// Rows per work block. Fixed (not derived from the thread count) so that reductions are
/// deterministic.
pub const ROW_BLOCK: usize = 8;

/// The sum of the rows' values in the reductions' fixed order: those of each block of
/// [`ROW_BLOCK`] rows added in order from 0, then the blocks' sums in order from 0.
#[inline]
pub fn add_by_blocks<const K: usize>(rows: &[[f64; K]]) -> [f64; K] {
    let mut total = [0.0; K];
    for block in rows.chunks(ROW_BLOCK) {
        let mut s = [0.0; K];
        for v in block {
            for c in 0..K {
                s[c] += v[c];
            }
        }
        for c in 0..K {
            total[c] += s[c];
        }
    }
    total
}

/// Rows whose values [`Exec::sum_rows`] keeps on the stack (32 KiB).
const STACK_ROWS: usize = 4096;

/// Below this many cells a kernel runs serially even when parallel execution is allowed:
/// the rayon overhead would dominate.
pub const PARALLEL_MIN_CELLS: usize = 4096;

/// Cells per parallel task of a sweep without reduction ([`Exec::for_each_row`],
/// [`Exec::max_each_row`]): a task is [`ROW_BLOCK`] rows, or fewer rows of at least this many
/// cells when the rows are long, then shared evenly among the threads ([`balanced_task_rows`]).
/// An active window of a few dozen rows of 2 000 cells then still splits into some thirty tasks
/// that balance the threads, where blocks of eight rows would leave one thread a block more than
/// the other. Such sweeps write each row independently of
/// the others, so the split does not change a bit of the result.
pub const TASK_CELLS: usize = 4096;

/// Rows per task of a sweep without reduction over rows of `stride` values: between 1 and
/// [`ROW_BLOCK`], at least [`TASK_CELLS`] cells where the rows allow it.
#[inline]
pub fn task_rows(stride: usize) -> usize {
    TASK_CELLS.div_ceil(stride.max(1)).clamp(1, ROW_BLOCK)
}

/// Rows per task of a sweep over `nrows` rows of `stride` values on the installed pool: at most
/// [`task_rows`]`(stride)`, in a number of tasks that is a multiple of the pool's threads, the
/// rows shared among them as evenly as that allows. A window 24 rows high in tasks of eight rows
/// gives one thread two tasks and the other one; in four tasks of six rows each thread takes
/// two. The split changes no result: each row is written by one task, and the reductions add
/// the rows' values in their fixed blocks whatever the tasks.
#[inline]
pub fn balanced_task_rows(nrows: usize, stride: usize) -> usize {
    let threads = rayon::current_num_threads().max(1);
    let tasks = nrows.div_ceil(task_rows(stride)).div_ceil(threads) * threads;
    nrows.div_ceil(tasks.max(1)).max(1)
}

/// How a kernel runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Exec {
    /// Whether kernels may use the installed rayon pool.
    pub parallel: bool,
}

impl Exec {
    /// Serial execution.
    pub const SERIAL: Exec = Exec { parallel: false };

    /// Parallel execution when `threads > 1`.
    pub fn with_threads(threads: usize) -> Self {
        Exec { parallel: threads > 1 }
    }

    /// Whether a sweep over `cells` cells should run in parallel.
    #[inline]
    pub fn use_parallel(self, cells: usize) -> bool {
        self.parallel && cells >= PARALLEL_MIN_CELLS
    }

    /// Runs `f(row_index, row)` on every row of a row-major buffer `data` with rows of length
    /// `stride`. Rows are independent; each row is visited exactly once.
    pub fn for_each_row<F>(self, data: &mut [f64], stride: usize, f: F)
    where
        F: Fn(usize, &mut [f64]) + Sync + Send,
    {
        if self.use_parallel(data.len()) {
            let rows = balanced_task_rows(data.len() / stride.max(1), stride);
            data.par_chunks_mut(stride * rows).enumerate().for_each(|(b, block)| {
                for (r, row) in block.chunks_mut(stride).enumerate() {
                    f(b * rows + r, row);
                }
            });
        } else {
            for (r, row) in data.chunks_mut(stride).enumerate() {
                f(r, row);
            }
        }
    }

    /// [`Exec::for_each_row`] over three buffers of the same length at once: `f(row_index,
    /// row_a, row_b, row_c)`, the rows of the three at the same index.
    pub fn for_each_row3<F>(self, a: &mut [f64], b: &mut [f64], c: &mut [f64], stride: usize, f: F)
    where
        F: Fn(usize, &mut [f64], &mut [f64], &mut [f64]) + Sync + Send,
    {
        assert!(a.len() == b.len() && b.len() == c.len(), "Exec::for_each_row3: lengths differ");
        if self.use_parallel(a.len()) {
            let rows = balanced_task_rows(a.len() / stride.max(1), stride);
            let n = stride * rows;
            a.par_chunks_mut(n).zip(b.par_chunks_mut(n)).zip(c.par_chunks_mut(n)).enumerate().for_each(|(k, ((ba, bb), bc))| {
                for (r, ((ra, rb), rc)) in ba.chunks_mut(stride).zip(bb.chunks_mut(stride)).zip(bc.chunks_mut(stride)).enumerate() {
                    f(k * rows + r, ra, rb, rc);
                }
            });
        } else {
            for (r, ((ra, rb), rc)) in a.chunks_mut(stride).zip(b.chunks_mut(stride)).zip(c.chunks_mut(stride)).enumerate() {
                f(r, ra, rb, rc);
            }
        }
    }

    /// `dst` = `src` (equal lengths), in tasks of [`TASK_CELLS`] values on the pool when large.
    pub fn copy(self, dst: &mut [f64], src: &[f64]) {
        assert_eq!(dst.len(), src.len(), "Exec::copy: lengths differ");
        if self.use_parallel(dst.len()) {
            dst.par_chunks_mut(TASK_CELLS).zip(src.par_chunks(TASK_CELLS)).for_each(|(d, s)| d.copy_from_slice(s));
        } else {
            dst.copy_from_slice(src);
        }
    }

    /// Runs `f(row_index, row)` on every row, as [`Exec::for_each_row`], and returns the largest
    /// of the values `f` returns (NaN propagates). A maximum is exact, so the result does not
    /// depend on the order of the rows or on the number of threads.
    pub fn max_each_row<F>(self, data: &mut [f64], stride: usize, f: F) -> f64
    where
        F: Fn(usize, &mut [f64]) -> f64 + Sync + Send,
    {
        if self.use_parallel(data.len()) {
            let rows = balanced_task_rows(data.len() / stride.max(1), stride);
            data.par_chunks_mut(stride * rows)
                .enumerate()
                .map(|(b, block)| block.chunks_mut(stride).enumerate().fold(f64::NEG_INFINITY, |m, (r, row)| max_nan(m, f(b * rows + r, row))))
                .reduce(|| f64::NEG_INFINITY, max_nan)
        } else {
            data.chunks_mut(stride).enumerate().fold(f64::NEG_INFINITY, |m, (r, row)| max_nan(m, f(r, row)))
        }
    }

    /// Deterministic sum over rows `0..nrows` of `f(row)`: the rows' values of each block of
    /// [`ROW_BLOCK`] rows added in order from 0, then the blocks' sums in order from 0
    /// ([`Exec::sum_rows_into`] with the rows' values on the stack up to [`STACK_ROWS`] rows;
    /// serially without a buffer, in the same order).
    pub fn sum_rows<F>(self, nrows: usize, cells: usize, f: F) -> f64
    where
        F: Fn(usize) -> f64 + Sync + Send,
    {
        if self.use_parallel(cells) {
            let mut stack = [[0.0f64; 1]; STACK_ROWS];
            let mut heap = Vec::new();
            let values: &mut [[f64; 1]] = if nrows <= STACK_ROWS {
                &mut stack[..nrows]
            } else {
                heap.resize(nrows, [0.0]);
                &mut heap
            };
            self.sum_rows_into(nrows, cells, values, |j| [f(j)])[0]
        } else {
            let mut total = 0.0;
            for b in 0..nrows.div_ceil(ROW_BLOCK) {
                let mut s = 0.0;
                for r in b * ROW_BLOCK..((b + 1) * ROW_BLOCK).min(nrows) {
                    s += f(r);
                }
                total += s;
            }
            total
        }
    }

    /// Deterministic sum over rows `0..nrows` of `f(row)` (K components): the rows' values in
    /// `partials` (at least one per row), made on the pool in tasks of [`task_rows`] rows (equal
    /// shares for the threads whatever the blocks), then added by [`add_by_blocks`]. A buffer
    /// allocated once by the caller: the solvers' reductions allocate nothing.
    pub fn sum_rows_into<const K: usize, F>(self, nrows: usize, cells: usize, partials: &mut [[f64; K]], f: F) -> [f64; K]
    where
        F: Fn(usize) -> [f64; K] + Sync + Send,
    {
        let partials = &mut partials[..nrows];
        if self.use_parallel(cells) {
            let rows = balanced_task_rows(nrows, cells / nrows.max(1));
            partials.par_chunks_mut(rows).enumerate().for_each(|(t, out)| {
                for (k, o) in out.iter_mut().enumerate() {
                    *o = f(t * rows + k);
                }
            });
        } else {
            for (j, o) in partials.iter_mut().enumerate() {
                *o = f(j);
            }
        }
        add_by_blocks(partials)
    }

    /// Deterministic maximum over rows of `f(row)` (NaN propagates).
    pub fn max_rows<F>(self, nrows: usize, cells: usize, f: F) -> f64
    where
        F: Fn(usize) -> f64 + Sync + Send,
    {
        if self.use_parallel(cells) {
            (0..nrows).into_par_iter().map(&f).reduce(|| f64::NEG_INFINITY, max_nan)
        } else {
            (0..nrows).map(&f).fold(f64::NEG_INFINITY, max_nan)
        }
    }
}

/// max(a, b), NaN when either is NaN.
#[inline]
fn max_nan(a: f64, b: f64) -> f64 {
    if a.is_nan() || b.is_nan() {
        f64::NAN
    } else {
        a.max(b)
    }
}

/// Runs `f` on the current thread of a rayon pool while the pool's other threads wait actively
/// for work: each runs a job that takes the pool's pending jobs as they appear
/// (`rayon::yield_now`) until `f` returns, instead of going to sleep when no work is queued.
///
/// A step alternates short parallel sweeps (tens of microseconds on an active window) with
/// serial work (coarse multigrid levels, the coarse Cholesky solve, the Picard loop's control,
/// fast sweeping). A rayon thread that finds no work sleeps, and waking it costs a parallel
/// sweep 10 to 30 µs on a virtual machine: more than the sweep saves. Kept awake, the other
/// threads start on a sweep at once, as the workers of an OpenMP code spin between its parallel
/// regions. The results do not depend on which thread runs what. While `f` runs, the other
/// threads use their cores even in its serial parts: `threads` should not exceed the free cores.
pub fn with_active_workers<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    use std::sync::atomic::{AtomicBool, Ordering};
    let n = rayon::current_num_threads();
    let me = rayon::current_thread_index();
    if n < 2 || me.is_none() {
        return f();
    }
    let done = AtomicBool::new(false);
    rayon::scope(|s| {
        for _ in 1..n {
            let done = &done;
            s.spawn(move |_| {
                // the thread running `f` may take this job while it waits inside `f` for a
                // parallel sweep: it must not stay here, `f` could not return
                if rayon::current_thread_index() == me {
                    return;
                }
                while !done.load(Ordering::Acquire) {
                    if rayon::yield_now() != Some(rayon::Yield::Executed) {
                        // look again after a short pause, not at once: the look touches the
                        // pool's shared queues, which the working thread uses too
                        for _ in 0..SPIN_PAUSES {
                            std::hint::spin_loop();
                        }
                    }
                }
            });
        }
        let out = f();
        done.store(true, Ordering::Release);
        out
    })
}

/// Pause instructions between two looks for work of a thread kept awake by
/// [`with_active_workers`] (about a microsecond).
const SPIN_PAUSES: usize = 32;

/// Builds a rayon pool with exactly `threads` threads.
pub fn build_pool(threads: usize) -> crate::error::Result<rayon::ThreadPool> {
    if threads == 0 || threads > 1024 {
        return Err(crate::error::Error::param("threads", threads, "an integer in [1, 1024]"));
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| crate::error::Error::param("threads", threads, &format!("a thread count the OS accepts ({e})")))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The tasks of a sweep: never more rows than `task_rows`, as many tasks for each thread,
    /// the rows shared evenly (the windows of the reference configuration at ny = 64, 128 and
    /// 256, 24, 40 and 72 rows of 398, 814 and 1 702 values, and a few others).
    #[test]
    fn the_tasks_of_a_sweep_are_shared_evenly_among_the_threads() {
        for threads in [1, 2, 3, 4] {
            let pool = build_pool(threads).unwrap();
            pool.install(|| {
                for (nrows, stride) in [(24, 398), (25, 398), (40, 814), (72, 1702), (40, 238), (1, 5000), (3, 100), (200, 30)] {
                    let r = balanced_task_rows(nrows, stride);
                    assert!(r >= 1 && r <= task_rows(stride), "{threads} threads, {nrows} x {stride}: {r} rows");
                    let tasks = nrows.div_ceil(r);
                    // no fewer rows per task than needed for as many tasks as the threads' multiple
                    let needed = nrows.div_ceil(task_rows(stride)).div_ceil(threads) * threads;
                    assert!(tasks <= needed && nrows.div_ceil(needed) == r, "{threads} threads, {nrows} x {stride}: {tasks} tasks of {r}");
                }
                if threads == 2 {
                    // ny = 64: four tasks of six rows (eight-row tasks would give one thread two, the other one)
                    assert_eq!(balanced_task_rows(24, 398), 6);
                    assert_eq!(balanced_task_rows(40, 814), 5);
                    assert_eq!(balanced_task_rows(72, 1702), 3);
                }
            });
        }
    }

    /// The three buffers' rows reach `f` together, each row once, with its index: serial and
    /// parallel write the same values.
    #[test]
    fn for_each_row3_hands_the_rows_of_the_three_buffers_together() {
        let run = |exec: Exec| {
            let (mut a, mut b, mut c) = (vec![0.0; 64 * 4096], vec![1.0; 64 * 4096], vec![2.0; 64 * 4096]);
            exec.for_each_row3(&mut a, &mut b, &mut c, 4096, |j, ra, rb, rc| {
                for ((x, y), z) in ra.iter_mut().zip(rb.iter_mut()).zip(rc.iter_mut()) {
                    *x += j as f64;
                    *y += *x;
                    *z += *y + 1.0;
                }
            });
            (a, b, c)
        };
        let serial = run(Exec::SERIAL);
        for j in 0..64 {
            assert!(serial.0[j * 4096..(j + 1) * 4096].iter().all(|&x| x == j as f64));
            assert!(serial.2[j * 4096..(j + 1) * 4096].iter().all(|&x| x == j as f64 + 4.0));
        }
        let pool = build_pool(2).unwrap();
        assert_eq!(pool.install(|| run(Exec::with_threads(2))), serial);
    }

    /// `with_active_workers` returns what `f` returns, outside a pool, on one thread and on
    /// several, with parallel sweeps (and the joins in which the calling thread may take a
    /// waiting job) inside `f`, and the sweeps give the same sums as serially.
    #[test]
    fn active_workers_run_f_and_its_sweeps_to_the_same_result() {
        let sweep = |exec: Exec| {
            let mut v = vec![1.0; 64 * 4096];
            let mut total = 0.0;
            for k in 0..50 {
                exec.for_each_row(&mut v, 4096, |j, row| row.iter_mut().for_each(|x| *x = (*x + (j + k) as f64).sqrt()));
                total += exec.sum_rows(64, v.len(), |j| v[j * 4096..(j + 1) * 4096].iter().sum());
            }
            total
        };
        let serial = sweep(Exec::SERIAL);
        assert_eq!(with_active_workers(|| sweep(Exec::SERIAL)).to_bits(), serial.to_bits());
        for threads in [1, 2, 3] {
            let pool = build_pool(threads).unwrap();
            let got = pool.install(|| with_active_workers(|| sweep(Exec::with_threads(threads))));
            assert_eq!(got.to_bits(), serial.to_bits(), "{threads} threads");
        }
    }
}
