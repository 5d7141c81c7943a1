//! Variable-density pressure projection (Aravena et al. §3.1, step 5).
//!
//! Continuous problem, with a₀ the BDF coefficient of u^{n+1} (3/2 for BDF2, 1 for BDF1):
//!
//!   a₀ ρ^{n+1} (u^{n+1} − ũ^{n+1}) / δt + ∇δp^{n+1} = 0,   div u^{n+1} = 0,   (u^{n+1} − ũ^{n+1})·n = 0 on ∂Ω,
//!
//! hence div((1/ρ) ∇δp) = (a₀/δt) div ũ, then u^{n+1} = ũ − (δt/a₀)(1/ρ)∇δp and p^{n+1} = p^n + δp
//! (incremental projection, standard form; Guermond, Minev & Shen 2006, *CMAME* 195).
//!
//! Rotational form (optional, `ModelConfig::rotational_pressure`): p^{n+1} = p^n + δp − η div ũ
//! (Timmermans, Minev & Van De Vosse 1996, *Int. J. Numer. Meth. Fluids* 22; Guermond, Minev &
//! Shen 2006 §3.4), with η the cell viscosity of the predictor. For a Stokes-dominated step
//! (ηδt/(a₀ρh²) ≫ 1) the standard update reduces a pressure error of wavenumber k only by the
//! factor ηk²/(a₀ρ/δt + ηk²) per step — close to 1 for the grid-scale modes of corner
//! singularities, so steady states are reached over thousands of steps — while the rotational
//! term supplies the missing ηk² part of the Schur complement (exact for a periodic mode of
//! constant η). Its steady states are those of the standard form (div ũ = 0 there).
//!
//! Discretely: β = 1/ρ on faces, the 5-point operator of [`crate::solvers::PoissonSolver`],
//! δp warm-started from the previous step's increment. Homogeneous Neumann on walls and
//! prescribed-velocity sides, δp = 0 on outflow sides (p keeps its boundary value p_b there).

pub mod free_surface;
pub mod stage;

use crate::error::Result;
use crate::exec::Exec;
use crate::grid::{BoundaryConditions, Field, Grid, PressureBc, Side, HALO};
use crate::operators::{divergence, for_each_interior_row, max_speed, sums_by_row, unknown_face_range};
use crate::solvers::{par, PoissonSolver, SolveInfo, SolverSettings};

pub use stage::{PressureStage, ProjectionInputs};

/// Fills the ghost layers of a cell-centred pressure: even reflection on Neumann sides,
/// odd reflection about the boundary value p_b on Dirichlet sides, ghost = 2 p_b − interior
/// (p_b = 0 unless the side has an outlet pressure, [`BoundaryConditions::outlet_pressure`]).
pub fn fill_pressure_ghosts(p: &mut Field, bc: &BoundaryConditions) {
    fill_ghosts(p, bc, true);
}

/// Fills the ghost layers of a pressure increment δp: as [`fill_pressure_ghosts`] with δp = 0
/// on Dirichlet sides (the boundary value does not change).
pub fn fill_increment_ghosts(dp: &mut Field, bc: &BoundaryConditions) {
    fill_ghosts(dp, bc, false);
}

fn fill_ghosts(p: &mut Field, bc: &BoundaryConditions, boundary_values: bool) {
    let (nx, ny) = (p.nx as isize, p.ny as isize);
    let g = HALO as isize;
    let sign = |s: Side| if bc.pressure(s) == PressureBc::Dirichlet { -1.0 } else { 1.0 };
    // 2 p_b at position k along the side (0 on Neumann sides and for an increment)
    let twice = |s: Side, k: isize| if boundary_values { 2.0 * bc.outlet_pressure_at(s, k as f64) } else { 0.0 };
    let (sl, sr, sb, st) = (sign(Side::Left), sign(Side::Right), sign(Side::Bottom), sign(Side::Top));
    for j in 0..ny {
        let (bl, br) = (twice(Side::Left, j), twice(Side::Right, j));
        for k in 1..=g {
            let (a, b) = (sl * p.at(k - 1, j) + bl, sr * p.at(nx - k, j) + br);
            let (ia, ib) = (p.idx(-k, j), p.idx(nx - 1 + k, j));
            let s = p.slice_mut();
            s[ia] = a;
            s[ib] = b;
        }
    }
    for i in -g..nx + g {
        let (bb, bt) = (twice(Side::Bottom, i), twice(Side::Top, i));
        for k in 1..=g {
            let (a, b) = (sb * p.at(i, k - 1) + bb, st * p.at(i, ny - k) + bt);
            let (ia, ib) = (p.idx(i, -k), p.idx(i, ny - 1 + k));
            let s = p.slice_mut();
            s[ia] = a;
            s[ib] = b;
        }
    }
}

/// Backflow stabilisation of outflow sides ([`BoundaryConditions::backflow`]): on each boundary
/// face of such a side where the outward normal velocity u·n of `u`, `v` is negative (the flow
/// enters), the boundary pressure p_b of the predictor's ∇p is lowered by q = ½ρ(u·n)², ρ the
/// face density. With ghost = 2p_b − interior the face's gradient moves by 2q/h: −2q/h on the
/// right and top sides, +2q/h on the left and bottom ones. Lowering p_b where fluid enters
/// decelerates the inflow (the work of the boundary pressure on the entering fluid pays its
/// kinetic energy), which is what removes the backflow instability of open sides. Faces where
/// the flow leaves are untouched, so a side with outflow only is the plain Dirichlet side.
#[allow(clippy::too_many_arguments)]
pub fn add_backflow_pressure(u: &Field, v: &Field, rho_u: &Field, rho_v: &Field, gx: &mut Field, gy: &mut Field, grid: &Grid, bc: &BoundaryConditions) {
    let (nx, ny) = (grid.nx as isize, grid.ny as isize);
    for side in Side::ALL.into_iter().filter(|&s| bc.backflow_on(s)) {
        // the side's normal velocity, density and gradient; its faces along it; the outward sign
        let (w, rho, g, h, along) = if side.is_x() { (u, rho_u, &mut *gx, grid.dx, ny) } else { (v, rho_v, &mut *gy, grid.dy, nx) };
        let (face, sign) = match side {
            Side::Left | Side::Bottom => (0, -1.0),
            Side::Right => (nx, 1.0),
            Side::Top => (ny, 1.0),
        };
        for k in 0..along {
            let (i, j) = if side.is_x() { (face, k) } else { (k, face) };
            let un = sign * w.at(i, j); // u·n, outward
            if un < 0.0 {
                let q = 0.5 * rho.at(i, j) * un * un;
                let at = g.idx(i, j);
                g.slice_mut()[at] -= sign * 2.0 * q / h;
            }
        }
    }
}

/// The pressure projection: owns the Poisson solver, its coefficients and work arrays.
pub struct PressureProjection {
    solver: PoissonSolver,
    beta_x: Vec<f64>,
    beta_y: Vec<f64>,
    rhs: Vec<f64>,
    dp: Vec<f64>,
    work: Vec<f64>,
    div: Field,
    dp_field: Field,
    /// Per-block partial sums of the norms (allocated once).
    partials: Vec<[f64; 1]>,
}

/// Σ term(a_i, b_i) over two row-major arrays with rows of `nx` values, each row left to right,
/// the rows and their blocks in order ([`par::sum_row_blocks`]: the same on any number of
/// threads).
fn row_sum(exec: Exec, nx: usize, partials: &mut [[f64; 1]], [a, b]: [&[f64]; 2], term: impl Fn([f64; 2]) -> f64 + Sync + Send) -> f64 {
    let ny = a.len() / nx;
    let [s] = par::sum_row_blocks(exec, ny, a.len(), partials, |j0, out| {
        sums_by_row(out, nx, |k| [&a[(j0 + k) * nx..], &b[(j0 + k) * nx..]], |t| [term(t)]);
    });
    s
}

impl PressureProjection {
    /// A projection for `grid` with the pressure conditions implied by `bc`.
    pub fn new(grid: &Grid, bc: &BoundaryConditions, settings: SolverSettings) -> Result<Self> {
        let solver = PoissonSolver::new(grid.nx, grid.ny, grid.dx, grid.dy, bc.pressure_all(), settings)?;
        let n = grid.cells();
        Ok(PressureProjection {
            solver,
            beta_x: vec![1.0; grid.ny * (grid.nx + 1)],
            beta_y: vec![1.0; (grid.ny + 1) * grid.nx],
            rhs: vec![0.0; n],
            dp: vec![0.0; n],
            work: vec![0.0; n],
            div: Field::zeros(grid, crate::Location::Centre),
            partials: vec![[0.0]; par::partials_len(grid.ny)],
            dp_field: Field::zeros(grid, crate::Location::Centre),
        })
    }

    /// Sets β = 1/ρ from the face densities ρ_u (XFace) and ρ_v (YFace).
    pub fn set_density(&mut self, rho_u: &Field, rho_v: &Field, exec: Exec) -> Result<()> {
        let (nxu, nxv) = (rho_u.nx, rho_v.nx);
        for j in 0..rho_u.ny {
            for i in 0..nxu {
                self.beta_x[j * nxu + i] = 1.0 / rho_u.at(i as isize, j as isize);
            }
        }
        for j in 0..rho_v.ny {
            for i in 0..nxv {
                self.beta_y[j * nxv + i] = 1.0 / rho_v.at(i as isize, j as isize);
            }
        }
        self.solver.set_coefficients(&self.beta_x, &self.beta_y, exec)
    }

    /// Projects ũ (in `u`, `v`, boundary values already set) onto discretely divergence-free
    /// fields and adds the increment to `p`. `dt_over_a0` is δt/a₀. With `rotational` (the
    /// cell viscosity η, ghosts not read), p also receives −η div ũ (the rotational form).
    #[allow(clippy::too_many_arguments, clippy::neg_cmp_op_on_partial_ord)] // !(warm < ‖b‖) also catches NaN
    pub fn project(
        &mut self,
        u: &mut Field,
        v: &mut Field,
        p: &mut Field,
        rho_u: &Field,
        rho_v: &Field,
        dt_over_a0: f64,
        grid: &Grid,
        bc: &BoundaryConditions,
        rotational: Option<&Field>,
        exec: Exec,
    ) -> Result<SolveInfo> {
        let nx = grid.nx;
        divergence(u, v, grid, &mut self.div, exec);
        let scale = 1.0 / dt_over_a0;
        {
            let (ds, st) = (self.div.slice(), self.div.stride());
            exec.for_each_row(&mut self.rhs, nx, |j, row| {
                let b = (j + HALO) * st + HALO;
                for (r, d) in row.iter_mut().zip(&ds[b..b + nx]) {
                    *r = scale * d;
                }
            });
        }
        // Round-off floor: when div ũ is below 1e-13 of the velocity scale over the cell size,
        // ũ is already divergence-free to machine precision and there is nothing to project
        // (a relative tolerance on a right-hand side of pure round-off cannot be met).
        let (umax, vmax) = max_speed(u, v, exec);
        let vel_scale = umax.max(vmax).max(f64::MIN_POSITIVE);
        let floor = 1e-13 * vel_scale / grid.h() * scale * (grid.cells() as f64).sqrt();
        let rhs_norm = row_sum(exec, nx, &mut self.partials, [&self.rhs, &self.rhs], |[f, _]| f * f).sqrt();
        if rhs_norm <= floor {
            return Ok(SolveInfo { iterations: 0, residual: 0.0, initial_residual: 0.0, rhs_mean_removed: 0.0 });
        }
        if let Some(eta) = rotational {
            let (es, ds, st) = (eta.slice(), self.div.slice(), eta.stride());
            for_each_interior_row(exec, p, |j, row| {
                let b = (j + HALO) * st + HALO;
                for i in 0..nx {
                    row[HALO + i] -= es[b + i] * ds[b + i];
                }
            });
        }
        // Warm start from the last increment only when it beats the zero guess (after a large
        // increment, e.g. the pressure initialisation, it would leave a residual far above a
        // small right-hand side and a round-off floor the relative tolerance cannot pass).
        self.solver.apply(&self.dp, &mut self.work, exec);
        let warm = row_sum(exec, nx, &mut self.partials, [&self.rhs, &self.work], |[f, l]| (f - l) * (f - l)).sqrt();
        if !(warm < rhs_norm) {
            self.dp.fill(0.0);
        }
        let info = self.solver.solve(&self.rhs, &mut self.dp, exec)?;
        // δp into a field with ghosts, then correct the unknown faces.
        {
            let dp = &self.dp;
            for_each_interior_row(exec, &mut self.dp_field, |j, row| {
                row[HALO..HALO + nx].copy_from_slice(&dp[j * nx..(j + 1) * nx]);
            });
        }
        fill_increment_ghosts(&mut self.dp_field, bc);
        let dpf = &self.dp_field;
        let (idx, idy) = (1.0 / grid.dx, 1.0 / grid.dy);
        let ru = unknown_face_range(bc.get(Side::Left), bc.get(Side::Right), grid.nx);
        let rv = unknown_face_range(bc.get(Side::Bottom), bc.get(Side::Top), grid.ny);
        let ds = dpf.slice();
        let stride = dpf.stride();
        {
            let rs = rho_u.slice();
            let ru = ru.clone();
            for_each_interior_row(exec, u, |j, row| {
                let b = (j + HALO) * stride + HALO;
                let bu = (j + HALO) * rho_u.stride() + HALO;
                for i in ru.clone() {
                    row[HALO + i] -= dt_over_a0 / rs[bu + i] * (ds[b + i] - ds[b + i - 1]) * idx;
                }
            });
        }
        {
            let rs = rho_v.slice();
            let ny = grid.ny;
            for_each_interior_row(exec, v, |j, row| {
                if !rv.contains(&j) || j > ny {
                    return;
                }
                let (b0, b1) = ((j - 1 + HALO) * stride + HALO, (j + HALO) * stride + HALO);
                let bv = (j + HALO) * rho_v.stride() + HALO;
                for i in 0..nx {
                    row[HALO + i] -= dt_over_a0 / rs[bv + i] * (ds[b1 + i] - ds[b0 + i]) * idy;
                }
            });
        }
        for_each_interior_row(exec, p, |j, row| {
            let b = (j + HALO) * stride + HALO;
            for i in 0..nx {
                row[HALO + i] += ds[b + i];
            }
        });
        fill_pressure_ghosts(p, bc);
        Ok(info)
    }

    /// Forgets the last increment (the next solve starts from zero).
    pub fn reset_increment(&mut self) {
        self.dp.fill(0.0);
    }

    /// The last pressure increment δp (row-major, nx·ny).
    /// The last pressure increment δp (the next solve's warm start), for checkpoints.
    pub fn increment_mut(&mut self) -> &mut [f64] {
        &mut self.dp
    }

    pub fn increment(&self) -> &[f64] {
        &self.dp
    }

    /// The Poisson solver (for diagnostics and benchmarks).
    pub fn solver(&self) -> &PoissonSolver {
        &self.solver
    }
}
