//! Preconditioned conjugate gradients (Saad 2003, Algorithm 9.1) for A p = b with A = −L and
//! b = −f, preconditioned by one multigrid cycle per iteration (MGCG, Tatebe 1993).
//!
//! Convergence is declared when the recursively updated residual satisfies
//! ‖r‖₂ ≤ rtol ‖b‖₂; the true residual b − A p is then recomputed, and if rounding has made it
//! larger than the tolerance the iteration restarts from it (one extra operator application per
//! solve; in practice the true residual is reported). Every reduction is a deterministic sum over
//! fixed blocks of rows ([`super::par`]), so the iterates do not depend on the number of threads.

use super::multigrid::Multigrid;
use super::par;
use super::{SolveInfo, SolverSettings};
use crate::error::{Error, Result};
use crate::exec::Exec;

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
    /// Per-block partial sums.
    pub partials: Vec<[f64; 2]>,
    /// Per-block partial sums (single component).
    pub partials1: Vec<[f64; 1]>,
}

impl CgWork {
    /// Work arrays for an `nx × ny` grid.
    pub fn new(nx: usize, ny: usize) -> Self {
        let n = nx * ny;
        CgWork {
            rhs: vec![0.0; n],
            r: vec![0.0; n],
            z: vec![0.0; n],
            d: vec![0.0; n],
            q: vec![0.0; n],
            partials: vec![[0.0; 2]; par::n_blocks(ny)],
            partials1: vec![[0.0; 1]; par::n_blocks(ny)],
        }
    }
}

/// Deterministic dot product of two row-major arrays with rows of length `nx`.
pub(crate) fn dot(exec: Exec, a: &[f64], b: &[f64], nx: usize, partials: &mut [[f64; 1]]) -> f64 {
    let ny = a.len() / nx;
    let [s] = par::sum_rows(exec, ny, a.len(), partials, |j| {
        let (ra, rb) = (&a[j * nx..(j + 1) * nx], &b[j * nx..(j + 1) * nx]);
        [ra.iter().zip(rb).map(|(x, y)| x * y).sum()]
    });
    s
}

/// Deterministic sum of a row-major array with rows of length `nx`.
pub(crate) fn sum(exec: Exec, a: &[f64], nx: usize, partials: &mut [[f64; 1]]) -> f64 {
    let ny = a.len() / nx;
    let [s] = par::sum_rows(exec, ny, a.len(), partials, |j| [a[j * nx..(j + 1) * nx].iter().sum()]);
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
    let mut rho = precondition(mg, w, singular, exec, 0)?;
    w.d.copy_from_slice(&w.z);
    let mut iterations = 0;
    while iterations < max_iterations {
        iterations += 1;
        // q = A d and d·q in one pass.
        let level = &mg.levels[0];
        let d = &w.d;
        let [dq, _] = par::rows_sum(exec, &mut w.q, nx, &mut w.partials, |j, row| {
            let dr = &d[j * nx..(j + 1) * nx];
            let mut s = 0.0;
            level.stencil_row(j, d, |i, v| {
                row[i] = v;
                s += dr[i] * v;
            });
            [s, 0.0]
        });
        if !(dq > 0.0 && dq.is_finite()) {
            return Err(Error::SolverFailure {
                solver: SOLVER.to_string(),
                message: format!("breakdown at iteration {iterations}: dᵀAd = {dq:e} (operator or preconditioner not positive definite)"),
            });
        }
        let alpha = rho / dq;
        // x += α d, r −= α q, and ‖r‖² in one pass.
        let (d, q) = (&w.d, &w.q);
        let rr = rows_update(exec, x, &mut w.r, nx, &mut w.partials, |j, xr, rrow| {
            let (dr, qr) = (&d[j * nx..(j + 1) * nx], &q[j * nx..(j + 1) * nx]);
            let mut s = 0.0;
            for i in 0..xr.len() {
                xr[i] += alpha * dr[i];
                let r = rrow[i] - alpha * qr[i];
                rrow[i] = r;
                s += r * r;
            }
            s
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
            rho = precondition(mg, w, singular, exec, iterations)?;
            w.d.copy_from_slice(&w.z);
            continue;
        }
        let rho_new = precondition(mg, w, singular, exec, iterations)?;
        let beta = rho_new / rho;
        rho = rho_new;
        let z = &w.z;
        exec.for_each_row(&mut w.d, nx, |j, row| {
            let zr = &z[j * nx..(j + 1) * nx];
            for (dv, zv) in row.iter_mut().zip(zr) {
                *dv = zv + beta * *dv;
            }
        });
    }
    Err(Error::NotConverged { solver: SOLVER.to_string(), iterations, residual: rel, tolerance: rtol })
}

/// z = M r (one multigrid cycle, projected onto zero mean in the singular case); returns r·z,
/// or an error if it is not positive (M not positive definite: CG would break down).
fn precondition(mg: &mut Multigrid, w: &mut CgWork, singular: bool, exec: Exec, iteration: usize) -> Result<f64> {
    let nx = mg.levels[0].nx;
    mg.precondition(&w.r, &mut w.z, exec);
    if singular {
        remove_mean(exec, &mut w.z, nx, &mut w.partials1);
    }
    let rho = dot(exec, &w.r, &w.z, nx, &mut w.partials1);
    if rho > 0.0 && rho.is_finite() {
        Ok(rho)
    } else {
        Err(Error::SolverFailure {
            solver: SOLVER.to_string(),
            message: format!("breakdown at iteration {iteration}: rᵀMr = {rho:e} (the multigrid preconditioner is not positive definite)"),
        })
    }
}

/// Runs `f(j, a_row, b_row)` on every row of two arrays and returns the deterministic sum of its
/// results (per-block partial sums added in block order).
fn rows_update<F>(exec: Exec, a: &mut [f64], b: &mut [f64], nx: usize, partials: &mut [[f64; 2]], f: F) -> f64
where
    F: Fn(usize, &mut [f64], &mut [f64]) -> f64 + Sync + Send,
{
    use rayon::prelude::*;
    let rows = crate::exec::ROW_BLOCK * nx;
    let nb = par::n_blocks(a.len() / nx);
    let partials = &mut partials[..nb];
    let block = |blk: usize, ca: &mut [f64], cb: &mut [f64]| -> f64 {
        let mut s = 0.0;
        for (r, (ra, rb)) in ca.chunks_mut(nx).zip(cb.chunks_mut(nx)).enumerate() {
            s += f(blk * crate::exec::ROW_BLOCK + r, ra, rb);
        }
        s
    };
    if exec.use_parallel(a.len()) {
        a.par_chunks_mut(rows)
            .zip(b.par_chunks_mut(rows))
            .zip(partials.par_iter_mut())
            .enumerate()
            .for_each(|(blk, ((ca, cb), out))| out[0] = block(blk, ca, cb));
    } else {
        for (blk, ((ca, cb), out)) in a.chunks_mut(rows).zip(b.chunks_mut(rows)).zip(partials.iter_mut()).enumerate() {
            out[0] = block(blk, ca, cb);
        }
    }
    partials.iter().map(|p| p[0]).fold(0.0, |acc, v| acc + v)
}
