//! The rheology room's state (Σ, the walls' friction, their work arrays, allocated once) and
//! its two stages of a time step (Aravena et al. eq. 10d, 10e, 11–12; the order is
//! `models/step.rs`'s):
//!
//! - [`RheologyState::prepare`] (before the predictor): yield stress τ(Φ) = τ(p^n) H_ε(Φ)
//!   (shifted by sε to the air side, s of `InterfaceYield`) at centres and nodes, wall friction
//!   τ_b, the lagged viscosity of variable-viscosity laws (μ(I) eq. 5, Papanastasiou,
//!   bi-viscous) from D(u^n), blended with the light phase by the harmonic mean as the
//!   properties are, and the projection parameters r, r_b;
//! - [`RheologyState::bi_projection`] (the end of the predictor, paper step 4): the predictor
//!   ũ^{n+1} coupled with Σ^{n+1} = P(Σ^{n+1} + r D(ũ^{n+1})) and
//!   s^{n+1} = P_b(s^{n+1} − r_b ũ_t^{n+1}), over a predictor solve it is given (the model's
//!   momentum solver), with the plastic projection (`rheology/plastic.rs`), the Coulomb walls
//!   (`walls/mod.rs`) and the side walls (`walls/side.rs`) as its projections.
//!
//! The bi-projection is solved by the Picard iteration with pseudo-relaxation θ (eq. 12):
//!
//!   ũ^{k+1} from the predictor with the forces div(τΣ^k) and τ_b s^k,
//!   Σ^{k+1} = P(Σ^k + r D(ũ^{k+1}) + θ(Σ^n − Σ^k)),   s^{k+1} = P_b(s^k − r_b ũ_t^{k+1} + θ(s^n − s^k)).

use super::anderson::Anderson;
use super::exact::{ExactStep, NewtonInfo};
use super::plastic::{not_converged, IncrementSite, PicardInfo, PlasticState};
use super::BiProjectionSolver;
use super::{RheologyConfig, WallNormalStress, YieldPressure, YieldTreatment};
use crate::error::Result;
use crate::exec::Exec;
use crate::grid::{BoundaryConditions, Field, Grid, Location, Side, VelocityBc, HALO};
use crate::levelset::heaviside;
use crate::operators::{cell_to_node, fill_velocity_ghosts, for_each_interior_row, strain_rate, strain_rate_norm_centre, BcMode};
use crate::solvers::par::partials_len;
use crate::solvers::SolveInfo;
use crate::walls::side::SideWallFriction;
use crate::walls::{CoulombWalls, NormalStress};

/// Stall safeguard of the Picard loop: the iterations of a step are taken in windows of
/// `PICARD_STALL_WINDOW`; if the largest increment of a window is above
/// `PICARD_STALL_DECAY` times the largest of the window before it (a cycle, not the slow
/// geometric decay of Uzawa-like settings, θ → 0), r and r_b are halved, and the next window
/// is compared with the one after the halving. The contraction bounds behind the default r, r_b
/// hold for each projection alone; with Coulomb walls and the plastic tensor on the same faces,
/// and at steps of a few ms, the iteration was seen to lock into cycles: increment 1.7e-2 for
/// 300 iterations (fluidised column at ny = 64, t = 0.013 s), and a cycle of period 4
/// (increments 9.15e-3, 9.36e-3, 3.83e-3, 3.63e-3, repeated to every digit) that returns after
/// each of four halvings (fluidised column at ny = 256 on the open window of 16 cells, t = 0.011
/// s); a smaller r_b breaks them. Comparing the windows' largest increments, not single
/// increments, sees a cycle whatever its phase, two windows after it forms.
pub const PICARD_STALL_WINDOW: usize = 10;

/// Decay of the largest increment from one window to the next below which the Picard loop is
/// said to stall: 0.95 per 40 iterations (a contraction slower than 0.9987 per iteration), as a
/// factor per window of `PICARD_STALL_WINDOW` iterations.
pub const PICARD_STALL_DECAY: f64 = 0.987_258_544_901_433_8;

/// At most this many halvings per step (r/64): beyond, a stall is not a cycle that a smaller r
/// breaks (θ = 0 Uzawa iterations near their tolerance were driven to r = 1e-152 without it).
/// Uzawa (θ = 0) is left alone: its slow geometric decay is not a cycle.
pub const PICARD_MAX_HALVINGS: usize = 6;

/// Iteration cap of each viscous solve inside the Picard loop.
pub const PICARD_SOLVE_MAX_ITERATIONS: usize = 500;

/// State and work arrays of the rheology (allocated once, only for non-Newtonian laws or
/// friction walls).
pub struct RheologyState {
    pub plastic: PlasticState,
    pub walls: CoulombWalls,
    /// Friction of the channel's side walls (`RheologyConfig::side_walls`).
    pub side_walls: Option<SideWallFriction>,
    pub(crate) dxx: Field,
    pub(crate) dyy: Field,
    pub(crate) dxy: Field,
    pub(crate) dnorm_c: Field,
    pub(crate) dnorm_n: Field,
    pub(crate) p_n: Field,
    pub(crate) phi_n: Field,
    pub(crate) rhs_u: Field,
    pub(crate) rhs_v: Field,
    pub(crate) ustar_u: Field,
    pub(crate) ustar_v: Field,
    /// |Σ + r D_dev + θ(Σ^n − Σ)| at centres after the last step (≤ 1: rigid).
    pub trial_norm: Field,
    /// Whether the Picard loop runs (projection of a yield stress, or friction walls).
    pub(crate) picard: bool,
    /// Whether Σ is iterated (a yield stress treated by projection).
    pub(crate) projection: bool,
    /// Increments of the Picard iterations of the last step (capacity reserved once).
    pub history: Vec<f64>,
    /// r of the current step (a user's constant r, or the smallest local r), and r_b (a user's
    /// constant, or the single bound, the smallest of the faces' r_b).
    pub r: f64,
    pub r_wall: f64,
    /// p_s of `YieldPressure::SurfaceAir` at the current step (0 with `Absolute`) [Pa].
    pub p_surface: f64,
    /// Block partial sums of `surface_air_pressure` (allocated once).
    pub(crate) surface_partials: Vec<[f64; 2]>,
    /// Anderson mixing of Σ (`RheologyConfig::anderson_depth` > 0 with a projected yield stress).
    pub(crate) anderson: Option<Anderson>,
    /// The exact step's multipliers and work arrays (`RheologyConfig::solver` = Newton).
    pub(crate) exact: Option<ExactStep>,
}

impl RheologyState {
    /// `None` for a Newtonian law without friction walls.
    pub fn new(grid: &Grid, bc: &BoundaryConditions, cfg: &RheologyConfig) -> Option<Self> {
        let coulomb = Side::ALL.iter().any(|&s| bc.get(s) == VelocityBc::Coulomb);
        let walls = CoulombWalls::new(grid, bc, cfg.wall_friction_angle.is_some());
        if !cfg.law.has_yield_stress() && !walls.is_active() && !cfg.variable_viscosity() && cfg.side_walls.is_none() {
            return None;
        }
        let c = || Field::zeros(grid, Location::Centre);
        let n = || Field::zeros(grid, Location::Node);
        let plastic = PlasticState::new(grid, bc, cfg.sigma_location);
        let projection = cfg.law.has_yield_stress() && cfg.treatment == YieldTreatment::Projection;
        let anderson = (projection && cfg.anderson_depth > 0).then(|| Anderson::new(cfg.anderson_depth, &plastic));
        Some(RheologyState {
            plastic,
            walls,
            side_walls: cfg.side_walls.map(|_| SideWallFriction::new(grid)),
            dxx: c(),
            dyy: c(),
            dxy: n(),
            dnorm_c: c(),
            dnorm_n: n(),
            p_n: n(),
            phi_n: n(),
            rhs_u: Field::zeros(grid, Location::XFace),
            rhs_v: Field::zeros(grid, Location::YFace),
            ustar_u: Field::zeros(grid, Location::XFace),
            ustar_v: Field::zeros(grid, Location::YFace),
            trial_norm: c(),
            history: Vec::with_capacity(cfg.picard_max_iterations.min(100_000)),
            picard: cfg.needs_picard(coulomb),
            projection,
            r: 0.0,
            r_wall: 0.0,
            p_surface: 0.0,
            surface_partials: vec![[0.0; 2]; partials_len(grid.ny)],
            anderson,
            exact: (cfg.solver == BiProjectionSolver::Newton).then(|| ExactStep::new(grid, bc)),
        })
    }
}

/// What the rheology stage reads: the state at t_n (ghosts filled) and the step's properties.
pub struct RheologyInputs<'a> {
    /// uⁿ, vⁿ.
    pub u: &'a Field,
    pub v: &'a Field,
    /// pⁿ.
    pub p: &'a Field,
    /// Φ^{n+1}.
    pub phi: &'a Field,
    /// ρ^{n+1} on x and y faces.
    pub rho_u: &'a Field,
    pub rho_v: &'a Field,
    pub grid: &'a Grid,
    /// The interface half-width ε [m].
    pub eps: f64,
    /// Whether there is a light phase (else H_ε = 1 everywhere).
    pub two_phase: bool,
    /// η of the dense and light phases [Pa s].
    pub dense_viscosity: f64,
    pub light_viscosity: f64,
    /// a₀/δt of the BDF step.
    pub a0_over_dt: f64,
}

impl RheologyState {
    /// Whether Σ is iterated (a yield stress treated by projection).
    pub fn has_plastic_tensor(&self) -> bool {
        self.projection
    }

    /// Whether the predictor runs the Picard loop of [`RheologyState::bi_projection`] (a yield
    /// stress treated by projection, or friction walls).
    pub fn iterates(&self) -> bool {
        self.picard
    }

    /// The rheology stage (before the predictor): the yield stress τ(Φ) = τ(p^n − p_s) H_ε(Φ + sε)
    /// at centres and nodes, the walls' friction τ_b and (2/W)τ_w, the lagged viscosity of
    /// variable-viscosity laws from D(u^n) into `eta_c`, `eta_n` (blended with the light phase
    /// by the harmonic mean, as the properties are), and the projections' parameters r, r_b.
    /// The fields of `input` with their ghosts filled.
    pub fn prepare(&mut self, rc: &RheologyConfig, input: &RheologyInputs, eta_c: &mut Field, eta_n: &mut Field, exec: Exec) {
        let rc = *rc;
        let grid = input.grid;
        let eps = input.eps;
        let two_phase = input.two_phase;
        let (dense_viscosity, light_viscosity) = (input.dense_viscosity, input.light_viscosity);
        let a0_over_dt = input.a0_over_dt;
        cell_to_node(input.p, &mut self.p_n, exec);
        cell_to_node(input.phi, &mut self.phi_n, exec);
        let law = rc.law;
        let yield_stress = law.yield_stress_fn();
        let iy = rc.interface_yield;
        let hv = |phi: f64| if two_phase { heaviside(iy.shift(phi, eps), eps) } else { 1.0 };
        // the pressure the yield stress reads: p, or p − p_s (YieldPressure::SurfaceAir)
        self.p_surface = if two_phase && rc.yield_pressure == YieldPressure::SurfaceAir {
            surface_air_pressure(input.p, input.phi, eps, grid.h(), &mut self.surface_partials, exec)
        } else {
            0.0
        };
        let p_s = self.p_surface;
        // yield stress τ(Φ) = τ(p − p_s) H_ε(Φ + sε) at centres and nodes
        for (tau, p, phi) in [(&mut self.plastic.tau_c, input.p, input.phi), (&mut self.plastic.tau_n, &self.p_n, &self.phi_n)] {
            let (ps, fs, st) = (p.slice(), phi.slice(), p.stride());
            let n = tau.nx;
            for_each_interior_row(exec, tau, |j, row| {
                let b = (j + HALO) * st + HALO;
                for i in 0..n {
                    row[HALO + i] = yield_stress.at(ps[b + i] - p_s) * hv(fs[b + i]);
                }
            });
        }
        self.plastic.tau_c.extrapolate_ghosts_constant();
        self.plastic.tau_max = crate::operators::max_abs(&self.plastic.tau_c, exec).max(crate::operators::max_abs(&self.plastic.tau_n, exec));
        // lagged viscosity of variable-viscosity laws, from D(u^n)
        if rc.variable_viscosity() {
            strain_rate(input.u, input.v, grid, &mut self.dxx, &mut self.dyy, &mut self.dxy, exec);
            strain_rate_norm_centre(&self.dxx, &self.dyy, &self.dxy, &mut self.dnorm_c, exec);
            self.dxx.extrapolate_ghosts_constant();
            self.dyy.extrapolate_ghosts_constant();
            {
                let (a, b, c) = (self.dxx.slice(), self.dyy.slice(), self.dxy.slice());
                let (dxx, dxy) = (&self.dxx, &self.dxy);
                let n = self.dnorm_n.nx;
                for_each_interior_row(exec, &mut self.dnorm_n, |j, row| {
                    let j = j as isize;
                    let (b0, b1, bn) = (base(dxx, j - 1), base(dxx, j), base(dxy, j));
                    for i in 0..n {
                        let avg = |s: &[f64]| 0.25 * (s[b0 + i] + s[b0 + i - 1] + s[b1 + i] + s[b1 + i - 1]);
                        let (xx, yy, xy) = (avg(a), avg(b), c[bn + i]);
                        row[HALO + i] = (0.5 * (xx * xx + yy * yy) + xy * xy).sqrt();
                    }
                });
            }
            let treatment = rc.treatment;
            let eta = |d: f64, p: f64, phi: f64| {
                let p = p - p_s;
                let tau = yield_stress.at(p);
                let ed = dense_viscosity + law.extra_viscosity(d, p) + treatment.regularised_viscosity(tau, d, dense_viscosity);
                if two_phase {
                    let h = heaviside(phi, eps);
                    1.0 / (h / ed + (1.0 - h) / light_viscosity)
                } else {
                    ed
                }
            };
            for (out, d, p, phi) in [(&mut *eta_c, &self.dnorm_c, input.p, input.phi), (&mut *eta_n, &self.dnorm_n, &self.p_n, &self.phi_n)] {
                let (ds, ps, fs, st) = (d.slice(), p.slice(), phi.slice(), d.stride());
                let n = out.nx;
                for_each_interior_row(exec, out, |j, row| {
                    let b = (j + HALO) * st + HALO;
                    for i in 0..n {
                        row[HALO + i] = eta(ds[b + i], ps[b + i], fs[b + i]);
                    }
                });
            }
            eta_c.extrapolate_ghosts_constant();
        }
        // parameters of the projections
        if self.projection {
            self.r = self.plastic.set_r(rc.r, rc.theta, rc.r_neighbourhood, eta_c, input.rho_u, input.rho_v, a0_over_dt, grid, exec);
        }
        if self.walls.is_active() {
            let tan_b = rc.wall_friction_angle.unwrap_or(0.0).to_radians().tan();
            let tnn = (rc.wall_normal_stress == WallNormalStress::Total).then(|| NormalStress {
                u: input.u,
                eta_c: &*eta_c,
                plastic: self.projection.then_some((&self.plastic.tau_c, &self.plastic.sigma_xx)),
                dx: grid.dx,
            });
            self.walls.set_friction(input.p, p_s, tnn, input.phi, tan_b, two_phase.then_some(eps), rc.interface_yield, grid);
            self.r_wall = self.walls.set_r(rc.r_wall, rc.wall_r, rc.theta, input.rho_u, input.rho_v, a0_over_dt, grid);
        }
        if let (Some(sw), Some(walls)) = (self.side_walls.as_mut(), rc.side_walls) {
            sw.set_friction(walls, input.p, p_s, input.phi, two_phase.then_some(eps), rc.interface_yield, input.rho_u, input.rho_v, a0_over_dt, rc.theta, exec);
        }
    }

    /// The bi-projection of eq. (11)–(12): the Picard iteration of the predictor `solve`, with
    /// the forces div(τΣ^k), τ_b s^k and the side walls' added to its right-hand side
    /// `rhs_u`, `rhs_v`, and the projections of Σ, s and the side walls' directions from each
    /// ũ^{k+1}. `u`, `v` hold the initial guess and receive ũ^{n+1}; `explicit`: `solve` is the
    /// explicit viscous step (restarted from the initial guess each iteration). `step` and
    /// `time` name the step in a non-convergence error. Returns the viscous solves (iterations
    /// summed) and the loop's info.
    #[allow(clippy::too_many_arguments)]
    pub fn bi_projection(
        &mut self,
        rc: &RheologyConfig,
        mut solve: impl FnMut(&mut Field, &mut Field, &Field, &Field) -> Result<SolveInfo>,
        explicit: bool,
        u: &mut Field,
        v: &mut Field,
        rhs_u: &Field,
        rhs_v: &Field,
        grid: &Grid,
        bc: &BoundaryConditions,
        (step, time): (u64, f64),
        exec: Exec,
    ) -> Result<(SolveInfo, PicardInfo)> {
        let rc = *rc;
        self.plastic.begin_step(exec);
        self.walls.begin_step();
        if let Some(sw) = self.side_walls.as_mut() {
            sw.begin_step();
        }
        if explicit {
            self.ustar_u.assign(u);
            self.ustar_v.assign(v);
        }
        let mut total = SolveInfo::default();
        let mut inc = f64::INFINITY;
        self.history.clear();
        // largest increment of the current window, and of the window before it (∞: none yet)
        let (mut window_max, mut previous_max, mut in_window) = (0.0f64, f64::INFINITY, 0usize);
        let mut halvings = 0usize;
        let mut restarts = 0usize;
        if let Some(a) = self.anderson.as_mut() {
            a.begin_step(&self.plastic);
        }
        for k in 1..=rc.picard_max_iterations {
            // rhs + div(τΣ^k) + wall friction τ_b s^k / h
            if self.projection {
                self.plastic.add_force(grid, Some((rhs_u, rhs_v)), &mut self.rhs_u, &mut self.rhs_v, exec);
            } else {
                exec.copy(self.rhs_u.slice_mut(), rhs_u.slice());
                exec.copy(self.rhs_v.slice_mut(), rhs_v.slice());
            }
            self.walls.add_force(&mut self.rhs_u, &mut self.rhs_v, grid);
            if let Some(sw) = self.side_walls.as_ref() {
                sw.add_force(&mut self.rhs_u, &mut self.rhs_v, exec);
            }
            if explicit {
                u.assign(&self.ustar_u);
                v.assign(&self.ustar_v);
                solve(u, v, &self.rhs_u, &self.rhs_v)?;
            } else {
                // A solve that stalls within 1000× of the tightened tolerance (or below 1e-7) is
                // accepted: the Picard test below judges the result. CG stalls near 1e-9 and then
                // drifts when round-off variations along an open side meet the asymmetry of the
                // viscous operator there (see `MomentumSolver::diagonal`).
                let info = match solve(u, v, &self.rhs_u, &self.rhs_v) {
                    Ok(info) => info,
                    Err(crate::error::Error::NotConverged { iterations, residual, tolerance, .. }) if residual <= (1e3 * tolerance).max(1e-7) => {
                        fill_velocity_ghosts(u, v, bc, grid, BcMode::Full);
                        SolveInfo { iterations, residual, initial_residual: 0.0, rhs_mean_removed: 0.0 }
                    }
                    Err(e) => return Err(e),
                };
                total.iterations += info.iterations;
                total.residual = info.residual;
                if k == 1 {
                    total.initial_residual = info.initial_residual;
                }
            }
            // Σ^{k+1}, s^{k+1} from ũ^{k+1} (ghosts filled by the solve)
            inc = 0.0;
            // where Σ moves most, recorded only when this iteration may be the last
            self.plastic.locate = k == rc.picard_max_iterations || (halvings == PICARD_MAX_HALVINGS && in_window + 1 == PICARD_STALL_WINDOW);
            if self.projection {
                if let Some(a) = self.anderson.as_mut() {
                    a.save_iterate(&self.plastic);
                }
                inc = self.plastic.update_from_velocity(u, v, grid, (&mut self.dxx, &mut self.dyy, &mut self.dxy), rc.theta, exec);
            }
            if self.walls.is_active() {
                let d = self.walls.update(u, v, rc.theta, grid);
                inc = if d.is_nan() { d } else { inc.max(d) };
            }
            if let Some(sw) = self.side_walls.as_mut() {
                let d = sw.update(u, v, rc.theta, exec);
                inc = if d.is_nan() || inc.is_nan() { f64::NAN } else { inc.max(d) };
            }
            if self.history.len() < self.history.capacity() {
                self.history.push(inc);
            }
            if inc.is_nan() {
                break;
            }
            if inc <= rc.picard_tol && restarts < rc.proximal_restarts {
                // proximal restart: the relaxed fixed point becomes the anchor (see
                // `RheologyConfig::proximal_restarts`)
                let moved = if self.projection { self.plastic.anchor_distance(exec) } else { 0.0 }
                    .max(self.walls.anchor_distance())
                    .max(self.side_walls.as_ref().map_or(0.0, |sw| sw.anchor_distance(exec)));
                if moved > rc.picard_tol {
                    self.plastic.begin_step(exec);
                    self.walls.begin_step();
                    if let Some(sw) = self.side_walls.as_mut() {
                        sw.begin_step();
                    }
                    if let Some(a) = self.anderson.as_mut() {
                        a.reset();
                    }
                    restarts += 1;
                    (window_max, previous_max, in_window) = (0.0, f64::INFINITY, 0);
                    continue;
                }
            }
            if inc <= rc.picard_tol {
                self.plastic.end_step(exec);
                self.plastic.trial_norm_centre(&mut self.trial_norm, exec);
                return Ok((total, PicardInfo { iterations: k, increment: inc, r: self.r, r_wall: self.r_wall, r_halvings: halvings, restarts }));
            }
            if let Some(a) = self.anderson.as_mut() {
                a.mix(&mut self.plastic);
            }
            window_max = window_max.max(inc);
            in_window += 1;
            if in_window == PICARD_STALL_WINDOW {
                // only the default (contraction-bound) parameters adapt; a user's r is kept
                let stalled = rc.theta > 0.0 && window_max > PICARD_STALL_DECAY * previous_max && (rc.r.is_none() || rc.r_wall.is_none());
                if stalled && halvings == PICARD_MAX_HALVINGS {
                    // a cycle that r/64 did not break: give up now rather than at the cap
                    return Err(self.picard_failure(&rc, inc, k, step, time));
                }
                if stalled {
                    if rc.r.is_none() {
                        self.plastic.scale_r(0.5);
                        self.r *= 0.5;
                        if let Some(a) = self.anderson.as_mut() {
                            a.reset();
                        }
                    }
                    if rc.r_wall.is_none() {
                        self.r_wall *= 0.5;
                        self.walls.scale_r(0.5);
                    }
                    halvings += 1;
                }
                // after a halving the next window is compared with the first one of the new r
                previous_max = if stalled { f64::INFINITY } else { window_max };
                (window_max, in_window) = (0.0, 0);
            }
        }
        Err(self.picard_failure(&rc, inc, rc.picard_max_iterations, step, time))
    }

    /// The bi-projection's step by the exact solver (`rheology/exact.rs`): ũ^{n+1}, Σ^{n+1} and
    /// s^{n+1} of eq. (11) to the residual `newton_tol`. `sys` is the predictor's (c_u, c_v, η_c,
    /// η_n); `u`, `v` hold the initial guess and receive ũ^{n+1}.
    #[allow(clippy::too_many_arguments)]
    pub fn exact_step(
        &mut self,
        rc: &RheologyConfig,
        sys: (&Field, &Field, &Field, &Field),
        u: &mut Field,
        v: &mut Field,
        rhs: (&Field, &Field),
        grid: &Grid,
        bc: &BoundaryConditions,
        at: (u64, f64),
        exec: Exec,
    ) -> Result<NewtonInfo> {
        let exact = self.exact.as_mut().expect("the exact step's state (solver = newton)");
        self.walls.begin_step();
        let tau_n_zero;
        let (tau_c, tau_n) = if self.projection {
            (&self.plastic.tau_c, &self.plastic.tau_n)
        } else {
            tau_n_zero = Field::zeros(grid, Location::Node);
            self.plastic.tau_c.fill(0.0);
            (&self.plastic.tau_c, &tau_n_zero)
        };
        let info = exact.solve(
            sys,
            grid,
            bc,
            u,
            v,
            rhs,
            (tau_c, tau_n),
            &mut self.walls,
            (&mut self.plastic.sigma_xx, &mut self.plastic.sigma_xy, &mut self.trial_norm),
            (rc.newton_tol, rc.newton_max_iterations),
            at,
            exec,
        )?;
        self.history.clear();
        self.history.push(info.residual());
        Ok(info)
    }

    /// The non-convergence error after `iterations`, naming where the stresses moved most.
    fn picard_failure(&mut self, rc: &RheologyConfig, inc: f64, iterations: usize, step: u64, time: f64) -> crate::error::Error {
        self.plastic.locate = false;
        let plastic =
            self.plastic.last_largest.filter(|_| self.projection).map(|(increment, location, i, j)| IncrementSite::Plastic { location, i, j, increment });
        let wall = self.walls.last_largest.filter(|_| self.walls.is_active()).map(|(increment, side, face)| IncrementSite::Wall { side, face, increment });
        let site = plastic.into_iter().chain(wall).reduce(|a, b| if b.increment() > a.increment() { b } else { a });
        not_converged(inc, iterations, rc.picard_tol, self.r, rc.theta, step, time, site)
    }
}

#[inline]
fn base(f: &Field, j: isize) -> usize {
    ((j + HALO as isize) as usize) * f.stride() + HALO
}

/// Mean pressure of the air on the granular surface (`YieldPressure::SurfaceAir`): the average of
/// p over the cells with −ε − h ≤ Φ < −ε (one layer of air cells just outside the smoothed band,
/// Φ a distance), equal weights; 0 when there is none. A fixed-order row-block reduction
/// ([`Exec::sum_rows_into`], `partials` one per row at least), so serial and parallel
/// runs agree bit for bit.
pub(crate) fn surface_air_pressure(p: &Field, phi: &Field, eps: f64, h: f64, partials: &mut [[f64; 2]], exec: Exec) -> f64 {
    let (nx, ny) = (p.nx, p.ny);
    let (ps, fs) = (p.slice(), phi.slice());
    let [sum, count] = exec.sum_rows_into::<2, _>(ny, nx * ny, partials, |j| {
        let b = (j + HALO) * p.stride() + HALO;
        let mut out = [0.0; 2];
        for i in 0..nx {
            let f = fs[b + i];
            if f < -eps && f >= -eps - h {
                out[0] += ps[b + i];
                out[1] += 1.0;
            }
        }
        out
    });
    if count > 0.0 {
        sum / count
    } else {
        0.0
    }
}

impl crate::grid::StateArrays for RheologyState {
    /// Σ (and Σ_xy at centres), the side walls' directions, the Coulomb walls' directions.
    fn visit_state(&self, f: &mut dyn FnMut(&str, &[f64])) {
        f("sigma_xx", self.plastic.sigma_xx.slice());
        f("sigma_xy", self.plastic.sigma_xy.slice());
        if let Some(cs) = &self.plastic.centred {
            f("sigma_xy_centre", cs.sigma.slice());
        }
        if let Some(sw) = &self.side_walls {
            f("side_wall_s_u", sw.s_u.slice());
            f("side_wall_s_v", sw.s_v.slice());
        }
        for (k, s) in self.walls.directions().iter().enumerate() {
            f(&format!("wall_direction_{k}"), s);
        }
    }

    fn visit_state_mut(&mut self, f: &mut dyn FnMut(&str, &mut [f64])) {
        f("sigma_xx", self.plastic.sigma_xx.slice_mut());
        f("sigma_xy", self.plastic.sigma_xy.slice_mut());
        if let Some(cs) = &mut self.plastic.centred {
            f("sigma_xy_centre", cs.sigma.slice_mut());
        }
        if let Some(sw) = &mut self.side_walls {
            f("side_wall_s_u", sw.s_u.slice_mut());
            f("side_wall_s_v", sw.s_v.slice_mut());
        }
        for (k, s) in self.walls.directions_mut().into_iter().enumerate() {
            f(&format!("wall_direction_{k}"), s);
        }
    }
}

impl crate::grid::WindowState for RheologyState {
    /// Σ (and Σ_xy at centres) and the side walls' directions.
    fn state_fields(&self) -> Vec<&Field> {
        let mut out = vec![&self.plastic.sigma_xx, &self.plastic.sigma_xy];
        if let Some(cs) = &self.plastic.centred {
            out.push(&cs.sigma);
        }
        if let Some(sw) = &self.side_walls {
            out.extend([&sw.s_u, &sw.s_v]);
        }
        out
    }

    fn state_fields_mut(&mut self) -> Vec<&mut Field> {
        let mut out = vec![&mut self.plastic.sigma_xx, &mut self.plastic.sigma_xy];
        if let Some(cs) = &mut self.plastic.centred {
            out.push(&mut cs.sigma);
        }
        if let Some(sw) = &mut self.side_walls {
            out.extend([&mut sw.s_u, &mut sw.s_v]);
        }
        out
    }

    /// The yield stress at centres and the plastic trial norm.
    fn shown_fields(&self) -> Vec<&Field> {
        vec![&self.plastic.tau_c, &self.trial_norm]
    }

    fn shown_fields_mut(&mut self) -> Vec<&mut Field> {
        vec![&mut self.plastic.tau_c, &mut self.trial_norm]
    }

    /// The Coulomb walls' s, s^n and τ_b over the faces both grids have; after the window's
    /// step, the Picard increments too.
    fn copy_other_state(&mut self, src: &Self, back: bool) {
        self.walls.copy_prefix_from(&src.walls);
        if back {
            self.history.clear();
            self.history.extend_from_slice(&src.history);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stall_decay_is_five_percent_per_forty_iterations() {
        // the window's factor is the single-increment rule's 0.95 over 40 iterations
        let per_window = 0.95f64.powf(PICARD_STALL_WINDOW as f64 / 40.0);
        assert!((PICARD_STALL_DECAY - per_window).abs() < 1e-15, "{PICARD_STALL_DECAY} against {per_window}");
    }
}
