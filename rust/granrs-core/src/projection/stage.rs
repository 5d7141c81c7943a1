//! The pressure projection stage (Aravena et al. §3.1, step 5): a₀ρ(u^{n+1} − ũ)/δt + ∇δp = 0,
//! div u^{n+1} = 0, p^{n+1} = p^n + δp; the two-phase projection of `projection/mod.rs` or the
//! granular-only model's free-surface projection of `projection/free_surface.rs`.
//!
//! The room's state: the projection in use, its last increment δp (the warm start of the next
//! solve, part of a checkpoint) and whether its coefficients 1/ρ must be rebuilt.

use super::free_surface::FreeSurfaceProjection;
use super::PressureProjection;
use crate::error::Result;
use crate::exec::Exec;
use crate::grid::{BoundaryConditions, Field, Grid, StateArrays};
use crate::solvers::{SolveInfo, SolverSettings};

/// What the projection stage reads besides the velocity and the pressure it updates.
pub struct ProjectionInputs<'a> {
    /// ρ on x and y faces (the two-phase projection's coefficients).
    pub rho_u: &'a Field,
    pub rho_v: &'a Field,
    /// Φ with its ghosts filled (the free-surface projection's surface).
    pub phi: &'a Field,
    /// ρ_s of the free-surface projection.
    pub dense_density: f64,
    /// The cell viscosity η of the rotational pressure update (None: the standard update).
    pub rotational: Option<&'a Field>,
    pub grid: &'a Grid,
    pub bc: &'a BoundaryConditions,
}

/// The pressure projection stage and its state.
pub struct PressureStage {
    two_phase: PressureProjection,
    free_surface: Option<FreeSurfaceProjection>,
    /// The coefficients 1/ρ of the two-phase projection must be rebuilt.
    stale: bool,
}

impl PressureStage {
    /// The stage for `grid` and `bc`; `free_surface`: the granular-only model's projection.
    pub fn new(grid: &Grid, bc: &BoundaryConditions, settings: SolverSettings, free_surface: bool) -> Result<Self> {
        let two_phase = PressureProjection::new(grid, bc, settings)?;
        let free_surface = if free_surface { Some(FreeSurfaceProjection::new(grid, bc, settings)?) } else { None };
        Ok(PressureStage { two_phase, free_surface, stale: true })
    }

    /// The face densities changed: the two-phase projection rebuilds its coefficients before
    /// its next solve.
    pub fn density_changed(&mut self) {
        self.stale = true;
    }

    /// The projection step: projects ũ (in `u`, `v`, boundary values set) with δt/a₀ =
    /// `dt_over_a0` and adds δp to `p` (the free-surface projection also extends the velocity
    /// into the air). The pressure gauge is the caller's.
    pub fn project(&mut self, u: &mut Field, v: &mut Field, p: &mut Field, input: &ProjectionInputs, dt_over_a0: f64, exec: Exec) -> Result<SolveInfo> {
        if let Some(fs) = self.free_surface.as_mut() {
            return fs.project(u, v, p, input.phi, input.dense_density, dt_over_a0, input.grid, input.bc, exec);
        }
        self.two_phase_coefficients(input, exec)?;
        self.two_phase.project(u, v, p, input.rho_u, input.rho_v, dt_over_a0, input.grid, input.bc, input.rotational, exec)
    }

    /// The pressure that balances a body force at rest: the projection of the force (in `u`,
    /// `v`) with δt/a₀ = 1 into `p`; the increment is forgotten afterwards (it is no warm start
    /// of a step).
    pub fn balance(&mut self, u: &mut Field, v: &mut Field, p: &mut Field, input: &ProjectionInputs, exec: Exec) -> Result<SolveInfo> {
        if let Some(fs) = self.free_surface.as_mut() {
            let info = fs.project(u, v, p, input.phi, input.dense_density, 1.0, input.grid, input.bc, exec);
            fs.increment_mut().fill(0.0);
            return info;
        }
        self.two_phase_coefficients(input, exec)?;
        let info = self.two_phase.project(u, v, p, input.rho_u, input.rho_v, 1.0, input.grid, input.bc, None, exec);
        self.two_phase.reset_increment();
        info
    }

    fn two_phase_coefficients(&mut self, input: &ProjectionInputs, exec: Exec) -> Result<()> {
        if self.stale {
            self.two_phase.set_density(input.rho_u, input.rho_v, exec)?;
            self.stale = false;
        }
        Ok(())
    }

    /// The last pressure increment δp of the projection in use (row-major, nx·ny: the warm start
    /// of the next solve).
    pub fn increment(&self) -> &[f64] {
        match &self.free_surface {
            Some(fs) => fs.increment(),
            None => self.two_phase.increment(),
        }
    }

    /// [`PressureStage::increment`], writable (a restore, the active window).
    pub fn increment_mut(&mut self) -> &mut [f64] {
        match &mut self.free_surface {
            Some(fs) => fs.increment_mut(),
            None => self.two_phase.increment_mut(),
        }
    }
}

impl StateArrays for PressureStage {
    /// The last increment δp.
    fn visit_state(&self, f: &mut dyn FnMut(&str, &[f64])) {
        f("pressure_increment", self.increment());
    }

    fn visit_state_mut(&mut self, f: &mut dyn FnMut(&str, &mut [f64])) {
        f("pressure_increment", self.increment_mut());
    }
}
