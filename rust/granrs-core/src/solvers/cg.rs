//! Preconditioned conjugate gradients (Saad 2003, Algorithm 9.1) for A p = b with A = −L and
//! b = −f, preconditioned by one multigrid cycle per iteration (MGCG, Tatebe 1993).
//!
//! Convergence is declared when the recursively updated residual satisfies
//! ‖r‖₂ ≤ rtol ‖b‖₂; the true residual b − A p is then recomputed, and if rounding has made it
//! larger than the tolerance the iteration restarts from it (one extra operator application per
//! solve; in practice the true residual is reported). Every reduction is a deterministic sum over
//! fixed blocks of rows ([`super::par`]), so the iterates do not depend on the number of threads.

use super::level::Level;
use super::multigrid::Multigrid;
use super::par;
use super::{SolveInfo, SolverSettings};
use crate::error::{Error, Result};
use crate::exec::Exec;
use crate::operators::{row_sums, sums_by_row};

/// Name used in errors.
pub(crate) const SOLVER: &str = "multigrid-preconditioned CG";

/// Work arrays of the fine level (allocated once).
#[derive(Debug)]
pub(crate) struct CgWork {
    /// Right-hand side b = −f (projected onto zero mean in the singular case).
    pub rhs: Vec<f64>,
    /// Residual.
    pub r: Vec<f64>,
    /// Preconditioned residual.
    pub z: Vec<f64>,
    /// Search direction.
    pub d: Vec<f64>,
    /// A d.
    pub q: Vec<f64>,
    /// Per-block partial sums (single component).
    pub partials1: Vec<[f64; 1]>,
}

impl CgWork {
    /// Work arrays for an `nx × ny` grid.
    pub fn new(nx: usize, ny: usize) -> Self {
        let n = nx * ny;
        CgWork { rhs: vec![0.0; n], r: vec![0.0; n], z: vec![0.0; n], d: vec![0.0; n], q: vec![0.0; n], partials1: vec![[0.0; 1]; par::partials_len(ny)] }
    }
}

/// Deterministic dot product of two row-major arrays with rows of length `nx`: each row's
/// products added left to right, the rows in order within blocks of
/// [`ROW_BLOCK`](crate::exec::ROW_BLOCK) rows, the blocks in order ([`par::sum_row_blocks`];
/// four rows' sums in one loop by [`sums_by_row`]).
pub(crate) fn dot(exec: Exec, a: &[f64], b: &[f64], nx: usize, partials: &mut [[f64; 1]]) -> f64 {
    let ny = a.len() / nx;
    let [s] = par::sum_row_blocks(exec, ny, a.len(), partials, |j0, out| {
        sums_by_row(out, nx, |k| [&a[(j0 + k) * nx..], &b[(j0 + k) * nx..]], |[x, y]| [x * y]);
    });
    s
}

/// Deterministic sum of a row-major array with rows of length `nx` (the order of [`dot`]).
pub(crate) fn sum(exec: Exec, a: &[f64], nx: usize, partials: &mut [[f64; 1]]) -> f64 {
    let ny = a.len() / nx;
    let [s] = par::sum_row_blocks(exec, ny, a.len(), partials, |j0, out| {
        sums_by_row(out, nx, |k| [&a[(j0 + k) * nx..]], |[x]| [x]);
    });
    s
}

/// Subtracts the mean of `v`; returns the mean that was removed.
pub(crate) fn remove_mean(exec: Exec, v: &mut [f64], nx: usize, partials: &mut [[f64; 1]]) -> f64 {
    let m = sum(exec, v, nx, partials) / v.len() as f64;
    exec.for_each_row(v, nx, |_, row| row.iter_mut().for_each(|x| *x -= m));
    m
}

/// Solves A x = w.rhs by MGCG from the initial guess in `x`. `bnorm` = ‖w.rhs‖₂ > 0. The
/// returned `rhs_mean_removed` is 0: the caller fills it in.
pub(crate) fn pcg(mg: &mut Multigrid, w: &mut CgWork, x: &mut [f64], bnorm: f64, settings: &SolverSettings, singular: bool, exec: Exec) -> Result<SolveInfo> {
    let nx = mg.levels[0].nx;
    let (rtol, max_iterations) = (settings.rtol, settings.max_iterations);
    if singular {
        remove_mean(exec, x, nx, &mut w.partials1);
    }
    mg.levels[0].residual(x, &w.rhs, &mut w.r, exec);
    let mut rel = dot(exec, &w.r, &w.r, nx, &mut w.partials1).sqrt() / bnorm;
    let initial_residual = rel;
    if !rel.is_finite() {
        return Err(Error::SolverFailure { solver: SOLVER.to_string(), message: format!("initial residual is {rel}") });
    }
    if rel <= rtol {
        return Ok(SolveInfo { iterations: 0, residual: rel, initial_residual, rhs_mean_removed: 0.0 });
    }
    // Where b and the initial x are zero outside the spans of the fine level (isolated cells),
    // so are every residual, preconditioned residual and direction below: their coupling to
    // the other cells is zero. The cycle may then skip those cells (Multigrid::precondition).
    let spans = mg.spans_admit(&[&w.rhs, x], exec);
    let exec = mg.levels[0].exec_for(exec, spans);
    if spans {
        // q is written on the spans only below; outside them it is A d = 0
        mg.levels[0].fill_outside_spans(&mut w.q, exec);
    }
    let mut rho = precondition(mg, w, singular, spans, exec, 0)?;
    w.d.copy_from_slice(&w.z);
    let mut iterations = 0;
    while iterations < max_iterations {
        iterations += 1;
        // q = A d and d·q in one pass over each block of rows.
        let level = &mg.levels[0];
        let d = &w.d;
        let [dq] = par::write_row_blocks(exec, &mut w.q, nx, &mut w.partials1, |j0, qb, out| {
            for (k, row) in qb.chunks_mut(nx).enumerate() {
                let (lo, hi) = level.span(j0 + k, spans);
                level.apply_range(j0 + k, d, lo, hi, &mut row[lo..hi]);
            }
            row_dots(out, level, j0, spans, |k| [&d[(j0 + k) * nx..], &qb[k * nx..]]);
        });
        if !(dq > 0.0 && dq.is_finite()) {
            return Err(Error::SolverFailure {
                solver: SOLVER.to_string(),
                message: format!("breakdown at iteration {iterations}: dᵀAd = {dq:e} (operator or preconditioner not positive definite)"),
            });
        }
        let alpha = rho / dq;
        // x += α d, r −= α q, and ‖r‖² in one pass over each block of rows.
        let (d, q) = (&w.d, &w.q);
        let [rr] = par::write2_row_blocks(exec, x, &mut w.r, nx, &mut w.partials1, |j0, xb, rb, out| {
            for k in 0..xb.len() / nx {
                let (lo, hi) = level.span(j0 + k, spans);
                let (grid, block) = ((j0 + k) * nx, k * nx);
                update_rows(alpha, &d[grid + lo..grid + hi], &q[grid + lo..grid + hi], &mut xb[block + lo..block + hi], &mut rb[block + lo..block + hi]);
            }
            let rb = &*rb;
            row_dots(out, level, j0, spans, |k| [&rb[k * nx..], &rb[k * nx..]]);
        });
        rel = rr.sqrt() / bnorm;
        if !rel.is_finite() {
            return Err(Error::SolverFailure { solver: SOLVER.to_string(), message: format!("residual became {rel} at iteration {iterations}") });
        }
        if rel <= rtol {
            // Check the true residual.
            mg.levels[0].residual(x, &w.rhs, &mut w.r, exec);
            rel = dot(exec, &w.r, &w.r, nx, &mut w.partials1).sqrt() / bnorm;
            if rel <= rtol {
                if singular {
                    remove_mean(exec, x, nx, &mut w.partials1);
                }
                return Ok(SolveInfo { iterations, residual: rel, initial_residual, rhs_mean_removed: 0.0 });
            }
            // Restart from the true residual.
            rho = precondition(mg, w, singular, spans, exec, iterations)?;
            w.d.copy_from_slice(&w.z);
            continue;
        }
        let rho_new = precondition(mg, w, singular, spans, exec, iterations)?;
        let beta = rho_new / rho;
        rho = rho_new;
        let (z, level) = (&w.z, &mg.levels[0]);
        exec.for_each_row(&mut w.d, nx, |j, row| {
            let (lo, hi) = level.span(j, spans);
            let zr = &z[j * nx + lo..j * nx + hi];
            for (dv, zv) in row[lo..hi].iter_mut().zip(zr) {
                *dv = zv + beta * *dv;
            }
        });
    }
    Err(Error::NotConverged { solver: SOLVER.to_string(), iterations, residual: rel, tolerance: rtol })
}

/// z = M r (one multigrid cycle, projected onto zero mean in the singular case); returns r·z,
/// or an error if it is not positive (M not positive definite: CG would break down).
fn precondition(mg: &mut Multigrid, w: &mut CgWork, singular: bool, spans: bool, exec: Exec, iteration: usize) -> Result<f64> {
    let nx = mg.levels[0].nx;
    mg.precondition_on_spans(&w.r, &mut w.z, spans, exec);
    if singular {
        remove_mean(exec, &mut w.z, nx, &mut w.partials1);
    }
    let (level, r, z) = (&mg.levels[0], &w.r, &w.z);
    let [rho] = par::sum_row_blocks(exec, level.ny, r.len(), &mut w.partials1, |j0, out| {
        row_dots(out, level, j0, spans, |k| [&r[(j0 + k) * nx..], &z[(j0 + k) * nx..]]);
    });
    if rho > 0.0 && rho.is_finite() {
        Ok(rho)
    } else {
        Err(Error::SolverFailure {
            solver: SOLVER.to_string(),
            message: format!("breakdown at iteration {iteration}: rᵀMr = {rho:e} (the multigrid preconditioner is not positive definite)"),
        })
    }
}

/// `out[k]` = the products a·b of row j0 + k (`rows(k)` = [a, b] from the row's first cell)
/// added left to right from 0: over the whole rows ([`sums_by_row`]), or over the rows' spans
/// when `spans`. Outside the spans the products are ±0 (a and b are zero there), which leave a
/// left-to-right sum from +0 unchanged: both give the same bits.
#[inline(always)]
fn row_dots<'a>(out: &mut [[f64; 1]], level: &Level, j0: usize, spans: bool, rows: impl Fn(usize) -> [&'a [f64]; 2]) {
    if !spans {
        sums_by_row(out, level.nx, rows, |[a, b]| [a * b]);
        return;
    }
    for (k, o) in out.iter_mut().enumerate() {
        let (lo, hi) = level.spans[j0 + k];
        let [a, b] = rows(k);
        *o = row_sums::<1, 1>(hi - lo, |_, c| [a[lo + c] * b[lo + c]])[0];
    }
}

crate::multiversion! {
    /// The CG update of a block of rows: x += α d, r −= α q.
    fn update_rows / update_rows_base(alpha: f64, d: &[f64], q: &[f64], x: &mut [f64], r: &mut [f64]) {
        let n = x.len();
        let (d, q, r) = (&d[..n], &q[..n], &mut r[..n]);
        for i in 0..n {
            x[i] += alpha * d[i];
            r[i] -= alpha * q[i];
        }
    }
}

#[cfg(test)]
mod tests {
    //! The dot product by blocks of rows against its definition, bit for bit.
    use super::*;
    use crate::exec::ROW_BLOCK;

    /// Each row's products added left to right from 0, the rows of a block in order from 0, the
    /// blocks in order from 0.
    fn dot_by_definition(a: &[f64], b: &[f64], nx: usize) -> f64 {
        let rows: Vec<f64> = a.chunks(nx).zip(b.chunks(nx)).map(|(x, y)| x.iter().zip(y).fold(0.0, |s, (p, q)| s + p * q)).collect();
        rows.chunks(ROW_BLOCK).map(|blk| blk.iter().fold(0.0, |s, v| s + v)).fold(0.0, |s, v| s + v)
    }

    #[test]
    fn dot_is_its_definition_bit_for_bit_on_one_and_two_threads() {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        for (nx, ny) in [(1, 1), (3, 5), (257, 23), (130, 64), (2000, 37), (1500, 3)] {
            let wave = |k: usize, f: f64| (f * k as f64).sin() * 10f64.powi((k % 7) as i32 - 3);
            let a: Vec<f64> = (0..nx * ny).map(|k| wave(k, 0.77)).collect();
            let b: Vec<f64> = (0..nx * ny).map(|k| wave(k, 1.31)).collect();
            let want = dot_by_definition(&a, &b, nx);
            let mut partials = vec![[0.0]; par::partials_len(ny)];
            assert_eq!(dot(Exec::SERIAL, &a, &b, nx, &mut partials).to_bits(), want.to_bits(), "{nx} x {ny}");
            let par = pool.install(|| dot(Exec::with_threads(2), &a, &b, nx, &mut partials));
            assert_eq!(par.to_bits(), want.to_bits(), "{nx} x {ny}, two threads");
        }
    }
}
