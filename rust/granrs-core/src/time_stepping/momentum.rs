//! Momentum predictor (Aravena et al. §3.1 step 4, eq. 11, without the plastic term here):
//!
//!   ρ^{n+1} (a₀ ũ − a₁ u^n + a₂ u^{n−1})/δt + ρ^{n+1} N* + ∇(p^n + p_f^{n+1}) = ρ^{n+1} g + div(2η^{n+1} D(ũ)) + f_extra,
//!
//! N* = (1+ω) (u^n·∇)u^n − ω (u^{n−1}·∇)u^{n−1} (extrapolated convection). With the implicit
//! viscous scheme the linear system
//!
//!   A ũ = c ⊙ ũ − div(2η D(ũ)) = rhs,   c = a₀ ρ/δt on each face,
//!
//! is symmetric positive definite (the viscous part is Dᵀ(2η)D with the boundary ghosts of
//! `operators::fill_velocity_ghosts`) and is solved by Jacobi-preconditioned CG on the unknown
//! faces; the affine boundary data enter through the initial residual. The explicit scheme
//! evaluates div(2η D(u*)) at the extrapolated velocity instead (stable for
//! δt ≲ ρh²/(4η), see `clock.rs`).

use crate::error::{Error, Result};
use crate::exec::{add_by_blocks, balanced_task_rows, Exec, ROW_BLOCK};
use crate::grid::{BoundaryConditions, Field, Grid, Location, Side, HALO};
use crate::operators::{
    fill_velocity_ghosts, for_each_interior_row, sums_by_row, unknown_face_range, viscous, viscous_helmholtz, viscous_helmholtz_dots, BcMode, RowDots,
};
use crate::solvers::SolveInfo;
use std::ops::Range;

/// How the viscous term div(2η D(u)) is advanced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ViscousScheme {
    /// Backward (BDF) in time: unconditionally stable, one SPD solve per predictor.
    Implicit,
    /// Evaluated at the extrapolated velocity: no solve, stable for δt ≲ ρh²/(4η).
    Explicit,
}

impl ViscousScheme {
    /// Name used in Python and the docs.
    pub fn name(self) -> &'static str {
        match self {
            ViscousScheme::Implicit => "implicit",
            ViscousScheme::Explicit => "explicit",
        }
    }
}

/// The coefficients of one predictor system.
pub struct ViscousSystem<'a> {
    /// a₀ ρ/δt on u faces.
    pub c_u: &'a Field,
    /// a₀ ρ/δt on v faces.
    pub c_v: &'a Field,
    /// η at cell centres (ghosts filled).
    pub eta_c: &'a Field,
    /// η at nodes.
    pub eta_n: &'a Field,
    pub grid: &'a Grid,
    pub bc: &'a BoundaryConditions,
}

/// Work arrays for the implicit viscous solve, allocated once.
pub struct MomentumSolver {
    ru: Field,
    rv: Field,
    zu: Field,
    zv: Field,
    du: Field,
    dv: Field,
    qu: Field,
    qv: Field,
    diag_u: Field,
    diag_v: Field,
    /// Per-row sums of the fused passes: d·Ad on u and v rows.
    row_dq_u: Vec<f64>,
    row_dq_v: Vec<f64>,
    /// Per-row sums of the initial residual pass (rhs·rhs, r·r, r·z) on u and v rows.
    row_init_u: Vec<[f64; 3]>,
    row_init_v: Vec<[f64; 3]>,
    /// Per-row sums [r·z, r·r] of the update pass ([`rows3_dots`]).
    row_sums: Vec<[f64; 2]>,
    /// Relative residual tolerance ‖rhs − Aũ‖/‖rhs‖.
    pub rtol: f64,
    /// Iteration cap; reaching it is an error.
    pub max_iterations: usize,
}

fn ranges(grid: &Grid, bc: &BoundaryConditions) -> (Range<usize>, Range<usize>) {
    (unknown_face_range(bc.get(Side::Left), bc.get(Side::Right), grid.nx), unknown_face_range(bc.get(Side::Bottom), bc.get(Side::Top), grid.ny))
}

/// Σ a·b over the unknown faces of one component (deterministic block sum; row slices so the
/// inner loop has no bounds checks): the order of the solver's sums, which compute each row's
/// part inside the pass that writes the row ([`rows3_blocks`], `viscous_helmholtz_dots`).
#[cfg(test)]
fn dot(a: &Field, b: &Field, ri: &Range<usize>, rj: &Range<usize>, exec: Exec) -> f64 {
    let (sa, sb, st) = (a.slice(), b.slice(), a.stride());
    let (rj0, i0, i1) = (rj.start, ri.start, ri.end);
    exec.sum_rows(rj.len(), a.nx * a.ny, |r| {
        let bse = (r + rj0 + HALO) * st + HALO;
        let (x, y) = (&sa[bse + i0..bse + i1], &sb[bse + i0..bse + i1]);
        x.iter().zip(y).fold(0.0, |s, (p, q)| s + p * q)
    })
}

/// Σ over the rows `rj` of per-row sums computed elsewhere (`rows[j]` for interior row j):
/// blocks of `ROW_BLOCK` rows added in order (`Exec::sum_rows`), the order of a dot product
/// over the unknown faces whatever the number of threads. The few hundred row sums are added
/// on the calling thread: a parallel region would cost more than the additions.
fn sum_row_sums(rows: &[f64], rj: &Range<usize>) -> f64 {
    let rj0 = rj.start;
    Exec::SERIAL.sum_rows(rj.len(), rows.len(), |r| rows[r + rj0])
}

impl MomentumSolver {
    /// Work arrays for `grid`.
    pub fn new(grid: &Grid) -> Self {
        let fu = || Field::zeros(grid, Location::XFace);
        let fv = || Field::zeros(grid, Location::YFace);
        MomentumSolver {
            ru: fu(),
            rv: fv(),
            zu: fu(),
            zv: fv(),
            du: fu(),
            dv: fv(),
            qu: fu(),
            qv: fv(),
            diag_u: fu(),
            diag_v: fv(),
            row_dq_u: vec![0.0; grid.ny],
            row_dq_v: vec![0.0; grid.ny + 1],
            row_init_u: vec![[0.0; 3]; grid.ny],
            row_init_v: vec![[0.0; 3]; grid.ny + 1],
            row_sums: vec![[0.0; 2]; grid.ny + 1],
            rtol: 1e-10,
            max_iterations: 2000,
        }
    }

    /// out = A(u) = c ⊙ u − div(2η D(u)) on every face (ghosts of u, v filled by the caller), in
    /// one sweep ([`viscous_helmholtz`]).
    fn apply(sys: &ViscousSystem, u: &Field, v: &Field, out_u: &mut Field, out_v: &mut Field, exec: Exec) {
        viscous_helmholtz(u, v, sys.eta_c, sys.eta_n, sys.c_u, sys.c_v, sys.grid, out_u, out_v, exec);
    }

    /// Diagonal of A on the unknown faces, used as the Jacobi preconditioner: exact, including
    /// the ghost factors of the boundary rules, except on open (outflow, fully developed) boundary
    /// faces and on the tangential rows beside open sides, which get the interior value. There the viscous operator is not symmetric (the
    /// tangential row beside the side sees ∂u_n/∂t at the boundary node, the normal row does not
    /// see the tangential velocity), and an exact diagonal would make the preconditioned residual
    /// of a flow that is invariant along the normal vary along it and excite that asymmetry: CG
    /// then stalls near 1e-10 (seen on the x-invariant Poiseuille channel). With the interior
    /// value such flows stay in the invariant subspace, where the operator is symmetric.
    pub fn set_diagonal(&mut self, sys: &ViscousSystem, exec: Exec) {
        let g = sys.grid;
        let (idx2, idy2) = (1.0 / (g.dx * g.dx), 1.0 / (g.dy * g.dy));
        // tangential ghost factor a of each side; open sides get the interior value (factor 0)
        let factor = |side: Side, h: f64| {
            let b = sys.bc.get(side);
            if b.normal_is_unknown() {
                0.0
            } else {
                b.tangential_ghost(h).0
            }
        };
        let (ab, at) = (factor(Side::Bottom, g.dy), factor(Side::Top, g.dy));
        let (al, ar) = (factor(Side::Left, g.dx), factor(Side::Right, g.dx));
        let (ru, rv) = ranges(g, sys.bc);
        let (ec, en) = (sys.eta_c, sys.eta_n);
        // row by row on the raw slices (elementwise: serial == parallel); rows outside the
        // unknown range are untouched
        let (cu, cv, ecs, ens) = (sys.c_u.slice(), sys.c_v.slice(), ec.slice(), en.slice());
        let (scu, scv, sec, sen) = (sys.c_u.stride(), sys.c_v.stride(), ec.stride(), en.stride());
        let h = HALO;
        for_each_interior_row(exec, &mut self.diag_u, |j, row| {
            if j >= g.ny {
                return;
            }
            // ∂u/∂x at the cells on each side (interior value also on open boundary faces)
            let (fr, fl) = (1.0, 1.0);
            let ft = if j + 1 == g.ny { 1.0 - at } else { 1.0 };
            let fb = if j == 0 { 1.0 - ab } else { 1.0 };
            let (bc, be, bn, bn1) = ((j + h) * scu + h, (j + h) * sec + h, (j + h) * sen + h, (j + 1 + h) * sen + h);
            for i in ru.clone() {
                row[h + i] = cu[bc + i] + 2.0 * idx2 * (fr * ecs[be + i] + fl * ecs[be + i - 1]) + idy2 * (ft * ens[bn1 + i] + fb * ens[bn + i]);
            }
        });
        for_each_interior_row(exec, &mut self.diag_v, |j, row| {
            if !rv.contains(&j) {
                return;
            }
            let (ft, fb) = (1.0, 1.0);
            let (bc, be, be1, bn) = ((j + h) * scv + h, (j + h) * sec + h, (j + h - 1) * sec + h, (j + h) * sen + h);
            for i in 0..g.nx {
                let fr = if i + 1 == g.nx { 1.0 - ar } else { 1.0 };
                let fl = if i == 0 { 1.0 - al } else { 1.0 };
                row[h + i] = cv[bc + i] + 2.0 * idy2 * (ft * ecs[be + i] + fb * ecs[be1 + i]) + idx2 * (fr * ens[bn + i + 1] + fl * ens[bn + i]);
            }
        });
    }

    /// Solves A ũ = rhs on the unknown faces by Jacobi-preconditioned CG. On entry `u`, `v` hold
    /// the initial guess; their boundary values are set from the boundary conditions.
    pub fn solve_implicit(&mut self, sys: &ViscousSystem, u: &mut Field, v: &mut Field, rhs_u: &Field, rhs_v: &Field, exec: Exec) -> Result<SolveInfo> {
        self.set_diagonal(sys, exec);
        self.solve_implicit_with_diagonal(sys, u, v, rhs_u, rhs_v, exec)
    }

    /// [`Self::solve_implicit`] with the Jacobi preconditioner that [`Self::set_diagonal`] last
    /// computed, which must be that of `sys` (c and η unchanged since): the solves of one Picard
    /// loop share their system and compute its diagonal once.
    pub fn solve_implicit_with_diagonal(
        &mut self,
        sys: &ViscousSystem,
        u: &mut Field,
        v: &mut Field,
        rhs_u: &Field,
        rhs_v: &Field,
        exec: Exec,
    ) -> Result<SolveInfo> {
        let (ru, rv) = ranges(sys.grid, sys.bc);
        fill_velocity_ghosts(u, v, sys.bc, sys.grid, BcMode::Full);
        Self::apply(sys, u, v, &mut self.qu, &mut self.qv, exec);
        // r = rhs − A u, z = r / diag, d = z (zero off the unknown faces), and per row
        // rhs·rhs, r·r and r·z over the unknown faces in the same pass (summed below in the
        // blocks of `dot`: the bits of three `dot` calls)
        let (mut bnorm2, mut rr0, mut rz0) = (0.0, 0.0, 0.0);
        for (r, q, rhs, z, d, diag, ri, rj, sums) in [
            (&mut self.ru, &self.qu, rhs_u, &mut self.zu, &mut self.du, &self.diag_u, ru.clone(), 0..sys.grid.ny, &mut self.row_init_u),
            (&mut self.rv, &self.qv, rhs_v, &mut self.zv, &mut self.dv, &self.diag_v, 0..sys.grid.nx, rv.clone(), &mut self.row_init_v),
        ] {
            let cells = r.nx * r.ny;
            // zero everywhere but on the unknown faces, where r = rhs − A u, z = d = r / diag:
            // the halo rows here, the interior rows row by row (elementwise: serial == parallel)
            let st = r.stride();
            let nyf = r.ny;
            for buf in [r.slice_mut(), z.slice_mut(), d.slice_mut()] {
                buf[..HALO * st].fill(0.0);
                buf[(nyf + HALO) * st..].fill(0.0);
            }
            let (qs, bs, dg) = (q.slice(), rhs.slice(), diag.slice());
            let (i0, i1) = (HALO + ri.start, HALO + ri.end);
            let cols = i0..i1;
            rows3_blocks(exec, st, 0..nyf, r.slice_mut(), z.slice_mut(), d.slice_mut(), &mut sums[..nyf], |j0, rb, zb, db, sb| {
                for (k, ((rr_, zr), dr)) in rb.chunks_mut(st).zip(zb.chunks_mut(st)).zip(db.chunks_mut(st)).enumerate() {
                    if rj.contains(&(j0 + k)) {
                        for b in [&mut *rr_, &mut *zr, &mut *dr] {
                            b[..cols.start].fill(0.0);
                            b[cols.end..].fill(0.0);
                        }
                        let row = (j0 + k + HALO) * st + cols.start..(j0 + k + HALO) * st + cols.end;
                        cg_residual_row(&bs[row.clone()], &qs[row.clone()], &dg[row], &mut rr_[cols.clone()], &mut zr[cols.clone()], &mut dr[cols.clone()]);
                    } else {
                        rr_.fill(0.0);
                        zr.fill(0.0);
                        dr.fill(0.0);
                    }
                }
                // per row, rhs·rhs, r·r and r·z in column order from 0.0 (zero off the rows `rj`)
                let (rb, zb) = (&*rb, &*zb);
                let (lo, hi) = (rj.start.clamp(j0, j0 + sb.len()) - j0, rj.end.clamp(j0, j0 + sb.len()) - j0);
                sb[..lo].fill([0.0; 3]);
                sb[hi..].fill([0.0; 3]);
                sums_by_row(
                    &mut sb[lo..hi],
                    cols.len(),
                    |k| {
                        let (g, l) = ((j0 + lo + k + HALO) * st, (lo + k) * st);
                        [&bs[g + cols.start..g + cols.end], &rb[l + cols.start..l + cols.end], &zb[l + cols.start..l + cols.end]]
                    },
                    |[b, r, z]| [b * b, r * r, r * z],
                );
            });
            let rj0 = rj.start;
            // on the calling thread, as in `sum_row_sums`
            bnorm2 += Exec::SERIAL.sum_rows(rj.len(), cells, |k| sums[k + rj0][0]);
            rr0 += Exec::SERIAL.sum_rows(rj.len(), cells, |k| sums[k + rj0][1]);
            rz0 += Exec::SERIAL.sum_rows(rj.len(), cells, |k| sums[k + rj0][2]);
        }
        let bnorm = bnorm2.sqrt();
        let rnorm0 = rr0.sqrt();
        if !rnorm0.is_finite() {
            return Err(Error::SolverFailure {
                solver: "viscous CG".into(),
                message: "non-finite residual in the momentum predictor (NaN or inf in the velocity or forces)".into(),
            });
        }
        let scale = if bnorm > 0.0 { bnorm } else { 1.0 };
        let mut res = rnorm0 / scale;
        let initial = res;
        let mut rz = rz0;
        let mut it = 0;
        while res > self.rtol && rnorm0 > 0.0 {
            if it >= self.max_iterations {
                return Err(Error::NotConverged { solver: "viscous CG (momentum predictor)".into(), iterations: it, residual: res, tolerance: self.rtol });
            }
            fill_velocity_ghosts(&mut self.du, &mut self.dv, sys.bc, sys.grid, BcMode::Homogeneous);
            // q = A d with the rows of d·q in the same sweep
            let dots = RowDots { cols_u: ru.clone(), cols_v: 0..sys.grid.nx, rows_u: &mut self.row_dq_u, rows_v: &mut self.row_dq_v };
            viscous_helmholtz_dots(&self.du, &self.dv, sys.eta_c, sys.eta_n, sys.c_u, sys.c_v, sys.grid, &mut self.qu, &mut self.qv, dots, exec);
            let dq = sum_row_sums(&self.row_dq_u, &(0..sys.grid.ny)) + sum_row_sums(&self.row_dq_v, &rv);
            let alpha = rz / dq;
            let mut rz_new = 0.0;
            let mut rr = 0.0;
            for (x, r, z, d, q, diag, ri, rj) in [
                (&mut *u, &mut self.ru, &mut self.zu, &self.du, &self.qu, &self.diag_u, ru.clone(), 0..sys.grid.ny),
                (&mut *v, &mut self.rv, &mut self.zv, &self.dv, &self.qv, &self.diag_v, 0..sys.grid.nx, rv.clone()),
            ] {
                let st = x.stride();
                let (ds, qs, dg) = (d.slice(), q.slice(), diag.slice());
                let (i0, i1) = (ri.start, ri.end);
                // x += α d, r −= α q, z = r / diag, row by row (elementwise: serial == parallel),
                // with r·z and r·r summed in the same pass (the block order of `dot`)
                let cols = HALO + i0..HALO + i1;
                let (a, b) =
                    rows3_dots(exec, st, rj.clone(), cols.clone(), x.slice_mut(), r.slice_mut(), z.slice_mut(), &mut self.row_sums, |j, xr, rr_, zr| {
                        let row = (j + HALO) * st + cols.start..(j + HALO) * st + cols.end;
                        cg_update_row(
                            alpha,
                            &ds[row.clone()],
                            &qs[row.clone()],
                            &dg[row],
                            &mut xr[cols.clone()],
                            &mut rr_[cols.clone()],
                            &mut zr[cols.clone()],
                        );
                    });
                rz_new += a;
                rr += b;
            }
            res = rr.sqrt() / scale;
            let beta = rz_new / rz;
            rz = rz_new;
            for (d, z, ri, rj) in [(&mut self.du, &self.zu, ru.clone(), 0..sys.grid.ny), (&mut self.dv, &self.zv, 0..sys.grid.nx, rv.clone())] {
                let st = d.stride();
                let zs = z.slice();
                let rows = &mut d.slice_mut()[(rj.start + HALO) * st..(rj.end + HALO) * st];
                exec.for_each_row(rows, st, |k, row| {
                    let (base, cols) = ((rj.start + k + HALO) * st, HALO + ri.start..HALO + ri.end);
                    cg_direction_row(beta, &zs[base + cols.start..base + cols.end], &mut row[cols]);
                });
            }
            it += 1;
        }
        fill_velocity_ghosts(u, v, sys.bc, sys.grid, BcMode::Full);
        Ok(SolveInfo { iterations: it, residual: res, initial_residual: initial, rhs_mean_removed: 0.0 })
    }

    /// Explicit predictor: ũ = (rhs + div(2η D(u*)))/c on the unknown faces, with u* in `u`, `v`
    /// on entry (ghosts are filled here).
    pub fn solve_explicit(&mut self, sys: &ViscousSystem, u: &mut Field, v: &mut Field, rhs_u: &Field, rhs_v: &Field, exec: Exec) {
        let (ru, rv) = ranges(sys.grid, sys.bc);
        fill_velocity_ghosts(u, v, sys.bc, sys.grid, BcMode::Full);
        viscous(u, v, sys.eta_c, sys.eta_n, sys.grid, &mut self.qu, &mut self.qv, exec);
        for (x, q, rhs, c, ri, rj) in [(&mut *u, &self.qu, rhs_u, sys.c_u, ru, 0..sys.grid.ny), (&mut *v, &self.qv, rhs_v, sys.c_v, 0..sys.grid.nx, rv)] {
            let st = x.stride();
            let (qs, rs, cs) = (q.slice(), rhs.slice(), c.slice());
            let rj2 = rj.clone();
            for_each_interior_row(exec, x, |j, row| {
                if !rj2.contains(&j) {
                    return;
                }
                let b = (j + HALO) * st + HALO;
                for i in ri.clone() {
                    row[HALO + i] = (rs[b + i] + qs[b + i]) / cs[b + i];
                }
            });
        }
        fill_velocity_ghosts(u, v, sys.bc, sys.grid, BcMode::Full);
    }
}

/// Runs `f(j, row_x, row_r, row_z)` over the rows `rows` (interior indices) of three fields
/// with the same stride, in parallel when `exec` says so (rows are whole, ghosts included), and
/// returns (r·z, r·r) over the columns `cols` (raw indices) of the updated rows. Each row's
/// products are added in column order from 0.0, [`SUM_ROWS`](crate::operators::SUM_ROWS) rows at a time once a task's
/// rows are updated (tasks of at most [`ROW_BLOCK`] rows, into `row_sums`, one entry per row),
/// then the rows' sums in row order within blocks of [`ROW_BLOCK`] rows, the blocks in order:
/// the summation order of [`dot`] (`Exec::sum_rows`), so the sums are bit for bit those of two
/// `dot` calls after the update, serial or parallel, with one pass over the rows and one
/// parallel region instead of three.
#[allow(clippy::too_many_arguments)]
fn rows3_dots<F>(
    exec: Exec,
    st: usize,
    rows: Range<usize>,
    cols: Range<usize>,
    x: &mut [f64],
    r: &mut [f64],
    z: &mut [f64],
    row_sums: &mut [[f64; 2]],
    f: F,
) -> (f64, f64)
where
    F: Fn(usize, &mut [f64], &mut [f64], &mut [f64]) + Sync + Send,
{
    // each row's (r·z, r·r), the rows of a task written first
    rows3_blocks(exec, st, rows.clone(), x, r, z, row_sums, |j0, xb, rb, zb, out| {
        for (k, ((xr, rrow), zr)) in xb.chunks_mut(st).zip(rb.chunks_mut(st)).zip(zb.chunks_mut(st)).enumerate() {
            f(j0 + k, xr, rrow, zr);
        }
        let (rb, zb) = (&*rb, &*zb);
        sums_by_row(out, cols.len(), |k| [&rb[k * st + cols.start..k * st + cols.end], &zb[k * st + cols.start..k * st + cols.end]], |[r, z]| [r * z, r * r]);
    });
    let sums = &row_sums[..rows.len()];
    // the rows' sums in blocks of ROW_BLOCK rows from the first row, then the blocks
    let [rz, rr] = add_by_blocks(sums);
    (rz, rr)
}

crate::multiversion! {
    /// The CG update of a row: x += α d, r −= α q, z = r / g.
    fn cg_update_row / cg_update_row_base(alpha: f64, d: &[f64], q: &[f64], g: &[f64], x: &mut [f64], r: &mut [f64], z: &mut [f64]) {
        let n = x.len();
        let (d, q, g, r, z) = (&d[..n], &q[..n], &g[..n], &mut r[..n], &mut z[..n]);
        for i in 0..n {
            x[i] += alpha * d[i];
            r[i] -= alpha * q[i];
            z[i] = r[i] / g[i];
        }
    }
}

crate::multiversion! {
    /// The new search direction along a row: d = z + β d.
    fn cg_direction_row / cg_direction_row_base(beta: f64, z: &[f64], d: &mut [f64]) {
        let n = d.len();
        let z = &z[..n];
        for i in 0..n {
            d[i] = z[i] + beta * d[i];
        }
    }
}

/// Runs `f(j0, block_x, block_r, block_z, block_sums)` over blocks of at most [`ROW_BLOCK`] rows of
/// `rows` (interior indices; `j0` the block's first row) of three fields with the same stride
/// (rows whole, ghosts included), in parallel when `exec` says so; `block_sums` is the block's
/// part of `sums` (one entry per row of `rows`).
#[allow(clippy::too_many_arguments)]
fn rows3_blocks<const K: usize, F>(exec: Exec, st: usize, rows: Range<usize>, x: &mut [f64], r: &mut [f64], z: &mut [f64], sums: &mut [[f64; K]], f: F)
where
    F: Fn(usize, &mut [f64], &mut [f64], &mut [f64], &mut [[f64; K]]) + Sync + Send,
{
    let span = (rows.start + HALO) * st..(rows.end + HALO) * st;
    let (x, r, z) = (&mut x[span.clone()], &mut r[span.clone()], &mut z[span]);
    let sums = &mut sums[..rows.len()];
    if exec.use_parallel(x.len()) {
        use rayon::prelude::*;
        let n = balanced_task_rows(rows.len(), st);
        let blk = st * n;
        x.par_chunks_mut(blk)
            .zip(r.par_chunks_mut(blk))
            .zip(z.par_chunks_mut(blk))
            .zip(sums.par_chunks_mut(n))
            .enumerate()
            .for_each(|(t, (((a, bb), c), s))| f(rows.start + t * n, a, bb, c, s));
    } else {
        let blk = st * ROW_BLOCK;
        for (b, (((a, bb), c), s)) in x.chunks_mut(blk).zip(r.chunks_mut(blk)).zip(z.chunks_mut(blk)).zip(sums.chunks_mut(ROW_BLOCK)).enumerate() {
            f(rows.start + b * ROW_BLOCK, a, bb, c, s);
        }
    }
}

crate::multiversion! {
    /// The initial residual of a row: r = b − q, z = d = r / g.
    fn cg_residual_row / cg_residual_row_base(b: &[f64], q: &[f64], g: &[f64], r: &mut [f64], z: &mut [f64], d: &mut [f64]) {
        let n = r.len();
        let (b, q, g, z, d) = (&b[..n], &q[..n], &g[..n], &mut z[..n], &mut d[..n]);
        for i in 0..n {
            r[i] = b[i] - q[i];
            z[i] = r[i] / g[i];
            d[i] = z[i];
        }
    }
}

/// The update of [`rows3_dots`] without the sums.
#[cfg(test)]
fn rows3<F>(exec: Exec, st: usize, rows: std::ops::Range<usize>, x: &mut [f64], r: &mut [f64], z: &mut [f64], f: F)
where
    F: Fn(usize, &mut [f64], &mut [f64], &mut [f64]) + Sync + Send,
{
    let span = (rows.start + HALO) * st..(rows.end + HALO) * st;
    let (x, r, z) = (&mut x[span.clone()], &mut r[span.clone()], &mut z[span]);
    if exec.use_parallel(x.len()) {
        use rayon::prelude::*;
        x.par_chunks_mut(st).zip(r.par_chunks_mut(st)).zip(z.par_chunks_mut(st)).enumerate().for_each(|(k, ((a, b), c))| f(rows.start + k, a, b, c));
    } else {
        for (k, ((a, b), c)) in x.chunks_mut(st).zip(r.chunks_mut(st)).zip(z.chunks_mut(st)).enumerate() {
            f(rows.start + k, a, b, c);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The update pass with its sums ([`rows3_dots`]) gives the bits of the update followed by
    /// two `dot` calls (the CG's r·z and r·r), serially and on a 2-thread pool, on ranges of rows
    /// that do not start at 0 and leave every remainder of the groups of [`SUM_ROWS`](crate::operators::SUM_ROWS) rows and
    /// of the row blocks; the row kernels' AVX2 and baseline copies agree bit for bit.
    #[test]
    fn rows3_dots_is_the_update_then_two_dots_bit_for_bit() {
        // rows short enough for tasks of eight rows, and long enough for tasks of three
        for (nx, cases) in [
            (97usize, vec![(1..97usize, 3..44usize), (0..98, 0..45), (2..50, 5..6), (1..97, 2..9), (1..96, 1..12), (1..96, 4..14)]),
            (1500, vec![(1..1500, 0..45), (0..1501, 2..43), (3..1400, 4..9)]),
        ] {
            rows3_dots_case(nx, &cases);
        }
    }

    fn rows3_dots_case(nx: usize, cases: &[(Range<usize>, Range<usize>)]) {
        let grid = Grid::new(nx, 45, nx as f64 / 97.0, 0.5).unwrap();
        let mk = |seed: u64| {
            let mut f = Field::zeros(&grid, Location::XFace);
            let mut s = seed;
            for v in f.slice_mut() {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                *v = ((s >> 11) as f64 / (1u64 << 53) as f64) - 0.5;
            }
            f
        };
        let (d, q) = (mk(1), mk(2));
        let mut dg = mk(3);
        dg.slice_mut().iter_mut().for_each(|g| *g += 2.0);
        let alpha = 0.37;
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        for (ri, rj) in cases.iter().cloned() {
            for exec in [Exec::SERIAL, Exec::with_threads(2)] {
                let (mut x1, mut r1, mut z1) = (mk(4), mk(5), mk(6));
                let (mut x2, mut r2, mut z2) = (x1.clone(), r1.clone(), z1.clone());
                let st = x1.stride();
                let (ds, qs, gs) = (d.slice(), q.slice(), dg.slice());
                let cols = HALO + ri.start..HALO + ri.end;
                // the solver's row kernel, and the same arithmetic written out
                let upd = |j: usize, xr: &mut [f64], rr: &mut [f64], zr: &mut [f64]| {
                    let row = (j + HALO) * st + cols.start..(j + HALO) * st + cols.end;
                    cg_update_row(alpha, &ds[row.clone()], &qs[row.clone()], &gs[row], &mut xr[cols.clone()], &mut rr[cols.clone()], &mut zr[cols.clone()]);
                };
                let plain = |j: usize, xr: &mut [f64], rr: &mut [f64], zr: &mut [f64]| {
                    let base = (j + HALO) * st;
                    for c in cols.clone() {
                        xr[c] += alpha * ds[base + c];
                        rr[c] -= alpha * qs[base + c];
                        zr[c] = rr[c] / gs[base + c];
                    }
                };
                let mut row_sums = vec![[f64::NAN; 2]; rj.len()];
                let (fused, reference) = pool.install(|| {
                    let fused = rows3_dots(exec, st, rj.clone(), cols.clone(), x1.slice_mut(), r1.slice_mut(), z1.slice_mut(), &mut row_sums, upd);
                    rows3(exec, st, rj.clone(), x2.slice_mut(), r2.slice_mut(), z2.slice_mut(), plain);
                    (fused, (dot(&r2, &z2, &ri, &rj, exec), dot(&r2, &r2, &ri, &rj, exec)))
                });
                assert_eq!(fused.0.to_bits(), reference.0.to_bits(), "r·z, {rj:?}, {exec:?}");
                assert_eq!(fused.1.to_bits(), reference.1.to_bits(), "r·r, {rj:?}, {exec:?}");
                assert_eq!(x1.slice(), x2.slice());
                assert_eq!(r1.slice(), r2.slice());
                assert_eq!(z1.slice(), z2.slice());
            }
        }
        let (a, b, g) = (mk(7), mk(8), dg.clone());
        let (mut x1, mut r1, mut z1) = (mk(4), mk(5), mk(6));
        let (mut x2, mut r2, mut z2) = (x1.clone(), r1.clone(), z1.clone());
        cg_update_row(0.3, a.slice(), b.slice(), g.slice(), x1.slice_mut(), r1.slice_mut(), z1.slice_mut());
        cg_update_row_base(0.3, a.slice(), b.slice(), g.slice(), x2.slice_mut(), r2.slice_mut(), z2.slice_mut());
        cg_direction_row(0.7, z1.slice(), x1.slice_mut());
        cg_direction_row_base(0.7, z2.slice(), x2.slice_mut());
        for (p, q) in [(&x1, &x2), (&r1, &r2), (&z1, &z2)] {
            assert!(p.slice().iter().zip(q.slice()).all(|(a, b)| a.to_bits() == b.to_bits()));
        }
    }

    /// The initial residual's row kernel: r = b − q, z = d = r / g, in both copies bit for bit.
    #[test]
    fn initial_residual_row_is_the_plain_arithmetic_bit_for_bit() {
        let mut row = crate::operators::random_rows(3);
        let n = 53;
        let (b, q) = (row(n), row(n));
        let g: Vec<f64> = row(n).iter().map(|x| x + 2.0).collect();
        let (mut r1, mut z1, mut d1) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let (mut r2, mut z2, mut d2) = (vec![1.0; n], vec![1.0; n], vec![1.0; n]);
        cg_residual_row(&b, &q, &g, &mut r1, &mut z1, &mut d1);
        cg_residual_row_base(&b, &q, &g, &mut r2, &mut z2, &mut d2);
        for i in 0..n {
            let r = b[i] - q[i];
            assert_eq!([r1[i], z1[i], d1[i]].map(f64::to_bits), [r, r / g[i], r / g[i]].map(f64::to_bits));
            assert_eq!([r1[i], z1[i], d1[i]].map(f64::to_bits), [r2[i], z2[i], d2[i]].map(f64::to_bits));
        }
    }
}
