//! The rheology room's two stages on the model (`rheology/stage.rs`: τ, τ_b, the lagged
//! viscosity and r before the predictor; the bi-projection of eq. 11–12, the Picard loop, at its
//! end), called from `models/step.rs`, which states their place in the step: the model's side
//! gives each its inputs, the predictor's viscous solve (`time_stepping/momentum.rs`) and the
//! tightened tolerance of the solves inside the loop.

use super::TwoPhaseModel;
use crate::error::Result;
use crate::exec::Exec;
use crate::grid::{Field, Side};
use crate::operators::{fill_velocity_ghosts, BcMode};
use crate::projection::fill_pressure_ghosts;
use crate::rheology::stage::RheologyInputs;
use crate::rheology::PicardInfo;
use crate::solvers::SolveInfo;
use crate::time_stepping::momentum::{ViscousScheme, ViscousSystem};
use crate::time_stepping::StageSeconds;
use std::time::Instant;

impl TwoPhaseModel {
    /// Rheology stage (before the predictor): τ, τ_b, lagged variable viscosity, r and r_b
    /// ([`crate::rheology::stage::RheologyState::prepare`]). `a0_over_dt` is a₀/δt of the BDF
    /// step.
    pub(crate) fn rheology_stage(&mut self, a0_over_dt: f64, exec: Exec) -> Result<()> {
        let Some(rs) = self.rheology.as_mut() else { return Ok(()) };
        let cfg = &self.config;
        let (grid, bc) = (&cfg.grid, &cfg.bc);
        let dense = cfg.dense;
        let light = cfg.light.unwrap_or(dense);
        fill_velocity_ghosts(&mut self.u, &mut self.v, bc, grid, BcMode::Full);
        fill_pressure_ghosts(&mut self.p, bc);
        self.phi.extrapolate_ghosts_linear();
        let ((rho_u, rho_v), (eta_c, eta_n)) = self.properties.density_and_viscosity_mut();
        let input = RheologyInputs {
            u: &self.u,
            v: &self.v,
            p: &self.p,
            phi: &self.phi,
            rho_u,
            rho_v,
            grid,
            eps: cfg.interface_width * grid.h(),
            two_phase: cfg.light.is_some(),
            dense_viscosity: dense.viscosity,
            light_viscosity: light.viscosity,
            a0_over_dt,
        };
        rs.prepare(&cfg.rheology, &input, eta_c, eta_n, exec);
        Ok(())
    }

    /// The end of the predictor: solves for ũ^{n+1} (rhs and c in the work arrays, the initial
    /// guess in u, v), with the Picard loop of eq. (12)
    /// ([`crate::rheology::stage::RheologyState::bi_projection`]) when there is a plastic stress
    /// or wall friction. Returns the viscous solves (iterations summed over the loop) and the
    /// loop's info. Adds the time of the viscous solves to `secs.predictor_solves` and the rest
    /// (the projections, their forces and the strain rate) to `secs.projections`.
    pub(crate) fn momentum_solve(&mut self, secs: &mut StageSeconds, exec: Exec) -> Result<(SolveInfo, PicardInfo)> {
        let start = Instant::now();
        let mut solves = 0.0;
        let cfg = &self.config;
        let (grid, bc) = (&cfg.grid, &cfg.bc);
        let explicit = cfg.viscous == ViscousScheme::Explicit;
        let picard = self.rheology.as_ref().is_some_and(|r| r.iterates());
        // The inner solves must be more accurate than the fixed point sought: without θ nothing
        // damps their error in the directions of Σ the velocity does not see, and the increment
        // stalls at the level of the solver tolerance (seen: 5e-10 with rtol = 1e-10).
        // Each inner solve is capped at `picard_solve_max_iterations` (default
        // PICARD_SOLVE_MAX_ITERATIONS): on open sides CG reaches
        // ~1e-9 and then drifts (see `RheologyState::bi_projection`), and a warm-started solve
        // inside the loop needs far fewer iterations than that otherwise.
        let (rtol_outer, cap_outer) = (self.momentum.rtol, self.momentum.max_iterations);
        if picard {
            self.momentum.rtol = rtol_outer.min(1e-2 * cfg.rheology.picard_tol).max(1e-12);
            self.momentum.max_iterations = cap_outer.min(cfg.rheology.picard_solve_max_iterations);
        }
        let wk = &self.work;
        let (eta_c, eta_n) = self.properties.viscosity();
        let sys = ViscousSystem { c_u: &wk.c_u, c_v: &wk.c_v, eta_c, eta_n, grid, bc };
        let momentum = &mut self.momentum;
        // c and η are those of the whole loop: the Jacobi preconditioner is computed once
        if !explicit {
            let t = Instant::now();
            momentum.set_diagonal(&sys, exec);
            solves += t.elapsed().as_secs_f64();
        }
        let mut solve = |u: &mut Field, v: &mut Field, rhs_u: &Field, rhs_v: &Field| {
            let t = Instant::now();
            let info = if explicit {
                momentum.solve_explicit(&sys, u, v, rhs_u, rhs_v, exec);
                Ok(SolveInfo::default())
            } else {
                momentum.solve_implicit_with_diagonal(&sys, u, v, rhs_u, rhs_v, exec)
            };
            solves += t.elapsed().as_secs_f64();
            info
        };
        let newton = cfg.rheology.solver == crate::rheology::BiProjectionSolver::Newton;
        let result = match self.rheology.as_mut().filter(|r| r.iterates()) {
            Some(rs) if newton => {
                let at = (self.step_count + 1, self.time);
                let t = Instant::now();
                let info = rs.exact_step(&cfg.rheology, (&wk.c_u, &wk.c_v, eta_c, eta_n), &mut self.u, &mut self.v, (&wk.rhs_u, &wk.rhs_v), grid, bc, at, exec);
                solves += t.elapsed().as_secs_f64();
                info.map(|i| {
                    (
                        SolveInfo { iterations: i.iterations, residual: i.momentum_residual, initial_residual: 0.0, rhs_mean_removed: 0.0 },
                        PicardInfo { iterations: i.iterations, increment: i.residual(), r: 0.0, r_wall: 0.0, r_halvings: 0, restarts: 0 },
                    )
                })
            }
            Some(rs) => {
                let at = (self.step_count + 1, self.time);
                rs.bi_projection(&cfg.rheology, solve, explicit, &mut self.u, &mut self.v, &wk.rhs_u, &wk.rhs_v, grid, bc, at, exec)
            }
            None => solve(&mut self.u, &mut self.v, &wk.rhs_u, &wk.rhs_v).map(|info| (info, PicardInfo::default())),
        };
        self.momentum.rtol = rtol_outer;
        self.momentum.max_iterations = cap_outer;
        secs.predictor_solves += solves;
        secs.projections += start.elapsed().as_secs_f64() - solves;
        result
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

    /// The discrete problem and solution of the last exact step (`bi_projection.solver` =
    /// "newton"), if one was taken.
    pub fn exact_problem(&self) -> Option<&crate::rheology::exact::ExactProblem> {
        self.rheology.as_ref().and_then(|r| r.exact.as_ref()).and_then(|e| e.last.as_ref())
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
