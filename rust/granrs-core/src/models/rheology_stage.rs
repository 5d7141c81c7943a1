//! The bi-projection of Aravena et al. eq. (11)–(12) on the model: the predictor ũ^{n+1}
//! coupled with Σ^{n+1} = P(Σ^{n+1} + r D(ũ^{n+1})) and s^{n+1} = P_b(s^{n+1} − r_b ũ_t^{n+1}),
//! solved by the Picard iteration with pseudo-relaxation θ (eq. 12):
//!
//!   ũ^{k+1} from the predictor with the forces div(τΣ^k) and τ_b s^k,
//!   Σ^{k+1} = P(Σ^k + r D(ũ^{k+1}) + θ(Σ^n − Σ^k)),   s^{k+1} = P_b(s^k − r_b ũ_t^{k+1} + θ(s^n − s^k)).
//!
//! The rheology's two pieces of a time step on the model (called from `models/step.rs`, which
//! states their place in the step); the state they work on is `rheology::stage::RheologyState`:
//!
//! - [`TwoPhaseModel::rheology_stage`] (before the predictor): yield stress τ(Φ) = τ(p^n) H_ε(Φ)
//!   (shifted by sε to the air side, s of `InterfaceYield`) at centres and
//!   nodes, wall friction τ_b, the lagged viscosity of variable-viscosity laws
//!   (μ(I) eq. 5, Papanastasiou, bi-viscous) from D(u^n), blended with the light phase by the
//!   harmonic mean as in `properties`, and the projection parameters r, r_b;
//! - [`TwoPhaseModel::momentum_solve`] (the end of the predictor, paper step 4, eq. 12): either
//!   the single predictor solve, or the Picard loop of the bi-projection coupling the predictor
//!   with the plastic projection of Σ and the friction projection of s.

use super::TwoPhaseModel;
use crate::error::Result;
use crate::exec::Exec;
use crate::grid::{Field, Side, HALO};
use crate::levelset::heaviside;
use crate::operators::{cell_to_node, fill_velocity_ghosts, for_each_interior_row, strain_rate, strain_rate_norm_centre, BcMode};
use crate::projection::fill_pressure_ghosts;
use crate::rheology::plastic::{not_converged, IncrementSite, PicardInfo};
use crate::rheology::stage::{surface_air_pressure, PICARD_MAX_HALVINGS, PICARD_STALL_WINDOW};
use crate::rheology::{WallNormalStress, YieldPressure};
use crate::solvers::SolveInfo;
use crate::time_stepping::momentum::{ViscousScheme, ViscousSystem};
use crate::time_stepping::StageSeconds;
use crate::walls::{default_r_wall, NormalStress};
use std::time::Instant;

impl TwoPhaseModel {
    /// Rheology stage (before the predictor): τ, τ_b, lagged variable viscosity, r and r_b.
    /// `a0_over_dt` is a₀/δt of the BDF step.
    pub(crate) fn rheology_stage(&mut self, a0_over_dt: f64, exec: Exec) -> Result<()> {
        let Some(rs) = self.rheology.as_mut() else { return Ok(()) };
        let cfg = &self.config;
        let rc = cfg.rheology;
        let (grid, bc) = (&cfg.grid, &cfg.bc);
        let eps = cfg.interface_width * grid.h();
        let dense = cfg.dense;
        let light = cfg.light.unwrap_or(dense);
        let two_phase = cfg.light.is_some();
        fill_velocity_ghosts(&mut self.u, &mut self.v, bc, grid, BcMode::Full);
        fill_pressure_ghosts(&mut self.p, bc);
        self.phi.extrapolate_ghosts_linear();
        cell_to_node(&self.p, &mut rs.p_n, exec);
        cell_to_node(&self.phi, &mut rs.phi_n, exec);
        let law = rc.law;
        let iy = rc.interface_yield;
        let hv = |phi: f64| if two_phase { heaviside(iy.shift(phi, eps), eps) } else { 1.0 };
        // the pressure the yield stress reads: p, or p − p_s (YieldPressure::SurfaceAir)
        rs.p_surface = if two_phase && rc.yield_pressure == YieldPressure::SurfaceAir {
            surface_air_pressure(&self.p, &self.phi, eps, grid.h(), &mut rs.surface_partials, exec)
        } else {
            0.0
        };
        let p_s = rs.p_surface;
        // yield stress τ(Φ) = τ(p − p_s) H_ε(Φ + sε) at centres and nodes
        for (tau, p, phi) in [(&mut rs.plastic.tau_c, &self.p, &self.phi), (&mut rs.plastic.tau_n, &rs.p_n, &rs.phi_n)] {
            let (ps, fs, st) = (p.slice(), phi.slice(), p.stride());
            let n = tau.nx;
            for_each_interior_row(exec, tau, |j, row| {
                let b = (j + HALO) * st + HALO;
                for i in 0..n {
                    row[HALO + i] = law.yield_stress(ps[b + i] - p_s) * hv(fs[b + i]);
                }
            });
        }
        rs.plastic.tau_c.extrapolate_ghosts_constant();
        rs.plastic.tau_max = rs.plastic.tau_c.max_abs().max(rs.plastic.tau_n.max_abs());
        // lagged viscosity of variable-viscosity laws, from D(u^n)
        if rc.variable_viscosity() {
            strain_rate(&self.u, &self.v, grid, &mut rs.dxx, &mut rs.dyy, &mut rs.dxy, exec);
            strain_rate_norm_centre(&rs.dxx, &rs.dyy, &rs.dxy, &mut rs.dnorm_c, exec);
            rs.dxx.extrapolate_ghosts_constant();
            rs.dyy.extrapolate_ghosts_constant();
            {
                let (a, b, c) = (rs.dxx.slice(), rs.dyy.slice(), rs.dxy.slice());
                let (dxx, dxy) = (&rs.dxx, &rs.dxy);
                let n = rs.dnorm_n.nx;
                for_each_interior_row(exec, &mut rs.dnorm_n, |j, row| {
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
                let tau = law.yield_stress(p);
                let ed = dense.viscosity + law.extra_viscosity(d, p) + treatment.regularised_viscosity(tau, d, dense.viscosity);
                if two_phase {
                    let h = heaviside(phi, eps);
                    1.0 / (h / ed + (1.0 - h) / light.viscosity)
                } else {
                    ed
                }
            };
            let wk = &mut self.work;
            for (out, d, p, phi) in [(&mut wk.eta_c, &rs.dnorm_c, &self.p, &self.phi), (&mut wk.eta_n, &rs.dnorm_n, &rs.p_n, &rs.phi_n)] {
                let (ds, ps, fs, st) = (d.slice(), p.slice(), phi.slice(), d.stride());
                let n = out.nx;
                for_each_interior_row(exec, out, |j, row| {
                    let b = (j + HALO) * st + HALO;
                    for i in 0..n {
                        row[HALO + i] = eta(ds[b + i], ps[b + i], fs[b + i]);
                    }
                });
            }
            wk.eta_c.extrapolate_ghosts_constant();
        }
        // parameters of the projections
        if rs.projection {
            let wk = &self.work;
            rs.r = rs.plastic.set_r(rc.r, rc.theta, rc.r_neighbourhood, &wk.eta_c, &wk.rho_u, &wk.rho_v, a0_over_dt, grid, exec);
        }
        if rs.walls.is_active() {
            let tan_b = rc.wall_friction_angle.unwrap_or(0.0).to_radians().tan();
            let tnn = (rc.wall_normal_stress == WallNormalStress::Total).then(|| NormalStress {
                u: &self.u,
                eta_c: &self.work.eta_c,
                plastic: rs.projection.then_some((&rs.plastic.tau_c, &rs.plastic.sigma_xx)),
                dx: grid.dx,
            });
            rs.walls.set_friction(&self.p, p_s, tnn, &self.phi, tan_b, two_phase.then_some(eps), rc.interface_yield, grid);
            rs.r_wall = rc.r_wall.unwrap_or_else(|| default_r_wall(rc.theta, rs.walls.max_response(&self.work.rho_u, &self.work.rho_v, a0_over_dt, grid)));
        }
        if let (Some(sw), Some(walls)) = (rs.side_walls.as_mut(), rc.side_walls) {
            sw.set_friction(
                walls,
                &self.p,
                p_s,
                &self.phi,
                two_phase.then_some(eps),
                rc.interface_yield,
                &self.work.rho_u,
                &self.work.rho_v,
                a0_over_dt,
                rc.theta,
                exec,
            );
        }
        Ok(())
    }

    /// The end of the predictor: solves for ũ^{n+1} (rhs and c in the work arrays, the initial
    /// guess in u, v), with the Picard loop of eq. (12) when there is a plastic stress or wall
    /// friction. Returns the viscous solves (iterations summed over the loop) and the loop's info.
    /// Adds the time of the viscous solves to `secs.predictor_solves` and the rest of the loop
    /// (the projections, their forces and the strain rate) to `secs.projections`.
    pub(crate) fn momentum_solve(&mut self, secs: &mut StageSeconds, exec: Exec) -> Result<(SolveInfo, PicardInfo)> {
        let start = Instant::now();
        let mut solves = 0.0;
        let out = self.momentum_solve_timed(&mut solves, exec);
        secs.predictor_solves += solves;
        secs.projections += start.elapsed().as_secs_f64() - solves;
        out
    }

    /// [`TwoPhaseModel::momentum_solve`], adding the time of its viscous solves to `solves`.
    fn momentum_solve_timed(&mut self, solves: &mut f64, exec: Exec) -> Result<(SolveInfo, PicardInfo)> {
        let cfg = &self.config;
        let (grid, bc) = (&cfg.grid, &cfg.bc);
        let wk = &self.work;
        let sys = ViscousSystem { c_u: &wk.c_u, c_v: &wk.c_v, eta_c: &wk.eta_c, eta_n: &wk.eta_n, grid, bc };
        let explicit = cfg.viscous == ViscousScheme::Explicit;
        let Some(rs) = self.rheology.as_mut().filter(|r| r.picard) else {
            let start = Instant::now();
            let info = if explicit {
                self.momentum.solve_explicit(&sys, &mut self.u, &mut self.v, &wk.rhs_u, &wk.rhs_v, exec);
                SolveInfo::default()
            } else {
                self.momentum.solve_implicit(&sys, &mut self.u, &mut self.v, &wk.rhs_u, &wk.rhs_v, exec)?
            };
            *solves += start.elapsed().as_secs_f64();
            return Ok((info, PicardInfo::default()));
        };
        rs.plastic.begin_step();
        rs.walls.begin_step();
        if let Some(sw) = rs.side_walls.as_mut() {
            sw.begin_step();
        }
        if explicit {
            rs.ustar_u.assign(&self.u);
            rs.ustar_v.assign(&self.v);
        }
        // The inner solves must be more accurate than the fixed point sought: without θ nothing
        // damps their error in the directions of Σ the velocity does not see, and the increment
        // stalls at the level of the solver tolerance (seen: 5e-10 with rtol = 1e-10).
        // Each inner solve is capped at `picard_solve_max_iterations` (default
        // PICARD_SOLVE_MAX_ITERATIONS): on open sides CG reaches
        // ~1e-9 and then drifts (see below), and a warm-started solve inside the loop needs far
        // fewer iterations than that otherwise.
        let (rtol_outer, cap_outer) = (self.momentum.rtol, self.momentum.max_iterations);
        self.momentum.rtol = rtol_outer.min(1e-2 * cfg.rheology.picard_tol).max(1e-12);
        self.momentum.max_iterations = cap_outer.min(cfg.rheology.picard_solve_max_iterations);
        let result = self.picard_loop(solves, exec);
        self.momentum.rtol = rtol_outer;
        self.momentum.max_iterations = cap_outer;
        result
    }

    fn picard_loop(&mut self, solves: &mut f64, exec: Exec) -> Result<(SolveInfo, PicardInfo)> {
        let cfg = &self.config;
        let (grid, bc) = (&cfg.grid, &cfg.bc);
        let wk = &self.work;
        let sys = ViscousSystem { c_u: &wk.c_u, c_v: &wk.c_v, eta_c: &wk.eta_c, eta_n: &wk.eta_n, grid, bc };
        let explicit = cfg.viscous == ViscousScheme::Explicit;
        let rc = cfg.rheology;
        let rs = self.rheology.as_mut().expect("picard_loop runs with a rheology state");
        let mut total = SolveInfo::default();
        let mut inc = f64::INFINITY;
        rs.history.clear();
        let mut window_start = f64::INFINITY;
        let mut halvings = 0usize;
        let mut restarts = 0usize;
        if let Some(a) = rs.anderson.as_mut() {
            a.begin_step(&rs.plastic);
        }
        for k in 1..=rc.picard_max_iterations {
            // rhs + div(τΣ^k) + wall friction τ_b s^k / h
            rs.rhs_u.assign(&wk.rhs_u);
            rs.rhs_v.assign(&wk.rhs_v);
            if rs.projection {
                rs.plastic.add_force(grid, &mut rs.rhs_u, &mut rs.rhs_v, exec);
            }
            rs.walls.add_force(&mut rs.rhs_u, &mut rs.rhs_v, grid);
            if let Some(sw) = rs.side_walls.as_ref() {
                sw.add_force(&mut rs.rhs_u, &mut rs.rhs_v, exec);
            }
            let solve_start = Instant::now();
            if explicit {
                self.u.assign(&rs.ustar_u);
                self.v.assign(&rs.ustar_v);
                self.momentum.solve_explicit(&sys, &mut self.u, &mut self.v, &rs.rhs_u, &rs.rhs_v, exec);
            } else {
                // A solve that stalls within 1000× of the tightened tolerance (or below 1e-7) is
                // accepted: the Picard test below judges the result. CG stalls near 1e-9 and then
                // drifts when round-off variations along an open side meet the asymmetry of the
                // viscous operator there (see `MomentumSolver::diagonal`).
                let info = match self.momentum.solve_implicit(&sys, &mut self.u, &mut self.v, &rs.rhs_u, &rs.rhs_v, exec) {
                    Ok(info) => info,
                    Err(crate::Error::NotConverged { iterations, residual, tolerance, .. }) if residual <= (1e3 * tolerance).max(1e-7) => {
                        fill_velocity_ghosts(&mut self.u, &mut self.v, bc, grid, BcMode::Full);
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
            *solves += solve_start.elapsed().as_secs_f64();
            // Σ^{k+1}, s^{k+1} from ũ^{k+1} (ghosts filled by the solve)
            inc = 0.0;
            // where Σ moves most, recorded only when this iteration may be the last
            rs.plastic.locate = k == rc.picard_max_iterations || (halvings == PICARD_MAX_HALVINGS && k % PICARD_STALL_WINDOW == 0);
            if rs.projection {
                strain_rate(&self.u, &self.v, grid, &mut rs.dxx, &mut rs.dyy, &mut rs.dxy, exec);
                if let Some(a) = rs.anderson.as_mut() {
                    a.save_iterate(&rs.plastic);
                }
                inc = rs.plastic.update(&rs.dxx, &rs.dyy, &rs.dxy, rc.theta, exec);
            }
            if rs.walls.is_active() {
                let d = rs.walls.update(&self.u, &self.v, rs.r_wall, rc.theta, grid);
                inc = if d.is_nan() { d } else { inc.max(d) };
            }
            if let Some(sw) = rs.side_walls.as_mut() {
                let d = sw.update(&self.u, &self.v, rc.theta, exec);
                inc = if d.is_nan() || inc.is_nan() { f64::NAN } else { inc.max(d) };
            }
            if rs.history.len() < rs.history.capacity() {
                rs.history.push(inc);
            }
            if inc.is_nan() {
                break;
            }
            if inc <= rc.picard_tol && restarts < rc.proximal_restarts {
                // proximal restart: the relaxed fixed point becomes the anchor (see
                // `RheologyConfig::proximal_restarts`)
                let moved = if rs.projection { rs.plastic.anchor_distance(exec) } else { 0.0 }
                    .max(rs.walls.anchor_distance())
                    .max(rs.side_walls.as_ref().map_or(0.0, |sw| sw.anchor_distance(exec)));
                if moved > rc.picard_tol {
                    rs.plastic.begin_step();
                    rs.walls.begin_step();
                    if let Some(sw) = rs.side_walls.as_mut() {
                        sw.begin_step();
                    }
                    if let Some(a) = rs.anderson.as_mut() {
                        a.reset();
                    }
                    restarts += 1;
                    window_start = f64::INFINITY;
                    continue;
                }
            }
            if inc <= rc.picard_tol {
                rs.plastic.end_step(exec);
                rs.plastic.trial_norm_centre(&mut rs.trial_norm, exec);
                return Ok((total, PicardInfo { iterations: k, increment: inc, r: rs.r, r_wall: rs.r_wall, r_halvings: halvings, restarts }));
            }
            if let Some(a) = rs.anderson.as_mut() {
                a.mix(&mut rs.plastic);
            }
            if k % PICARD_STALL_WINDOW == 0 {
                // only the default (contraction-bound) parameters adapt; a user's r is kept
                let stalled = rc.theta > 0.0 && inc > 0.95 * window_start && (rc.r.is_none() || rc.r_wall.is_none());
                if stalled && halvings == PICARD_MAX_HALVINGS {
                    // a cycle that r/64 did not break: give up now rather than at the cap
                    return Err(self.picard_failure(inc, k));
                }
                if stalled {
                    if rc.r.is_none() {
                        rs.plastic.scale_r(0.5);
                        rs.r *= 0.5;
                        if let Some(a) = rs.anderson.as_mut() {
                            a.reset();
                        }
                    }
                    if rc.r_wall.is_none() {
                        rs.r_wall *= 0.5;
                    }
                    halvings += 1;
                }
                window_start = inc;
            }
        }
        Err(self.picard_failure(inc, rc.picard_max_iterations))
    }

    /// The non-convergence error after `iterations`, naming where the stresses moved most.
    fn picard_failure(&mut self, inc: f64, iterations: usize) -> crate::Error {
        let rc = self.config.rheology;
        let rs = self.rheology.as_mut().expect("picard_loop runs with a rheology state");
        rs.plastic.locate = false;
        let plastic = rs.plastic.last_largest.filter(|_| rs.projection).map(|(increment, location, i, j)| IncrementSite::Plastic { location, i, j, increment });
        let wall = rs.walls.last_largest.filter(|_| rs.walls.is_active()).map(|(increment, side, face)| IncrementSite::Wall { side, face, increment });
        let site = plastic.into_iter().chain(wall).reduce(|a, b| if b.increment() > a.increment() { b } else { a });
        not_converged(inc, iterations, rc.picard_tol, rs.r, rc.theta, self.step_count + 1, self.time, site)
    }

    /// The plastic tensor (Σ_xx at centres, Σ_xy at nodes), if the rheology has one.
    pub fn plastic_tensor(&self) -> Option<(&Field, &Field)> {
        self.rheology.as_ref().map(|r| (&r.plastic.sigma_xx, &r.plastic.sigma_xy))
    }

    /// |Σ + r D_dev + θ(Σ^n − Σ)| (the argument of the plastic projection) at cell centres after
    /// the last step, if the rheology has a plastic tensor: ≤ 1 exactly where the material is
    /// rigid.
    pub fn plastic_trial_norm(&self) -> Option<&Field> {
        self.rheology.as_ref().map(|r| &r.trial_norm)
    }

    /// Increments max |τ(Σ^{k+1} − Σ^k)|/τ_max (and of the wall stress) of the Picard iterations
    /// of the last step (empty without plastic stress or wall friction).
    pub fn picard_history(&self) -> &[f64] {
        self.rheology.as_ref().map(|r| &r.history[..]).unwrap_or(&[])
    }

    /// The yield stress τ(Φ) at cell centres of the last step.
    pub fn yield_stress(&self) -> Option<&Field> {
        self.rheology.as_ref().map(|r| &r.plastic.tau_c)
    }

    /// Friction (s, τ_b) along a Coulomb side, if it has friction.
    pub fn wall_friction(&self, side: Side) -> Option<(&[f64], &[f64])> {
        self.rheology.as_ref().and_then(|r| r.walls.side(side))
    }
}

#[inline]
fn base(f: &Field, j: isize) -> usize {
    ((j + HALO as isize) as usize) * f.stride() + HALO
}
