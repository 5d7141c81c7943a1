//! One time step t_n → t_{n+1} of the two-phase model, Aravena et al. eq. (10a)–(10f):
//! transport of Φ (10a), momentum (10b) and incompressibility (10c), the plastic projection
//! Σ = P(Σ + r D(u)) (10d), the walls' friction s = P_b(s − r_b u_t) (10e) and the pore pressure
//! ∂_t p_f + div(u p_f) = div(κ(Φ)∇p_f) (10f), discretised by the paper's steps 1–5 (§3.1).
//!
//! **This is the only place that states the
//! order of the stages** (Aravena et al. §3.1; step numbers of the paper in brackets). Each
//! stage is a room's method with explicit inputs and outputs; the functions here hand them the
//! shared fields (u, v, p, Φ, the BDF2 history) and attach the step and time to their errors.
//! The wall time of each goes to `StepInfo::stage_seconds`.
//!
//! 1. `choose_dt`: δt from the CFL rule or the fixed step; variable-step BDF2 coefficients.
//! 2. `interface` [step 1]: Φ^{n+1} by WENO5 + TVD-RK3 with u^{n+½}, redistancing every N steps
//!    (`levelset::Interface::advance`), then the optional global mass correction
//!    (`levelset::Interface::correct_mass`, to the area `reference_area`; weighted to spare thin
//!    films with `mass_correction_film`), then the optional
//!    removal of small detached pieces of {Φ > 0} (`levelset::Interface::remove_pieces`,
//!    `piece_removal_cells`), followed by the correction again when it removed any. With
//!    `interface_transport = "clsvof"` the dense volume fraction F is transported first (split
//!    PLIC fluxes, conservative) and Φ^{n+1} is rebuilt from F^{n+1} last, in place of the
//!    redistancing (`levelset/vof.rs`).
//! 3. `properties` [step 2]: ρ^{n+1} on faces, η^{n+1} at centres and nodes, from H_ε(Φ^{n+1})
//!    (`properties::MaterialProperties::update`).
//! 4. `pore_pressure` [step 3]: p_f^{n+1} (`pore_pressure::PorePressure::advance`, implicit
//!    BDF2 or explicit forward Euler; an explicit step past h²/(4κ) stops here, naming the cell;
//!    skipped when not fluidised).
//!
//! 4b. `rheology_stage` [step 2, continued]: τ^{n+1} = τ(p^n) H_ε(Φ^{n+1}) at centres and nodes
//!    (H_ε(Φ^{n+1} + sε) with the shift s = 0, 1, 2 of `InterfaceYield`),
//!    τ_b^{n+1} on Coulomb walls, (2/W)τ_w^{n+1} on every face with the channel's side walls
//!    (`RheologyConfig::side_walls`, `walls/side.rs`), the lagged viscosity of μ(I) and
//!    regularised laws, r and r_b (`rheology::stage::RheologyState::prepare`, its inputs in
//!    `models/rheology_stage.rs`).
//! 5. `predictor` [step 4]: ũ^{n+1} from BDF2 with extrapolated convection, the body force
//!    (ρ − ρ_ref) g (ρ_ref = ρ_f with `ModelConfig::ambient_hydrostatic`, else 0) and the viscous term
//!    (implicit or explicit; on open sides with backflow stabilisation ∇pⁿ takes the boundary
//!    pressure p_b − ½ρ(u·n)² where the flow enters, `projection::add_backflow_pressure`); with a
//!    yield stress or wall friction, the Picard loop of eq. (12)
//!    couples it with the plastic projection of Σ and the friction projections of s (the
//!    Coulomb walls' and, with side walls, the side walls')
//!    (`rheology::stage::RheologyState::bi_projection` over the predictor solve that
//!    `momentum_solve` in `models/rheology_stage.rs` gives it).
//!    `check_predictor`: a non-finite ũ (blow-up) stops the step here, naming the cell.
//! 6. `projection_stage` [step 5]: δp, u^{n+1}, p^{n+1} = p^n + δp (− η div ũ in the rotational
//!    form, `ModelConfig::rotational_pressure`; `projection::PressureStage::project`), then the
//!    pressure gauge (p = 0 under the lid when no
//!    side is open; `ModelConfig::pressure_gauge`).
//! 7. `checks`: non-finite u, v, p, Φ, p_f; the CFL number; the step collapsing (adaptive δt);
//!    the divergence; the BDF2 history moves on.
//!
//! The granular-only model (`ModelConfig::free_surface`) runs the same stages with these
//! changes (`projection/free_surface.rs`): the face density is ρ_s on every face beside a
//! granular cell (stage 3); the predictor's ∇pⁿ reads pⁿ = 0 on the surface Φ^{n+1} = 0
//! (ghost values) and the faces with no granular cell beside them are Dirichlet rows holding
//! their history value (stage 5); stage 6 is the free-surface projection with δp = 0 on Φ = 0,
//! followed by the extension of the velocity into the air; the divergence of stage 7 is
//! measured over the granular cells.
//!
//! Before the stages the state is copied; a step that fails is undone from that copy, so after
//! any error the model is bit for bit at its last accepted state. Stage 7 refuses a step that
//! blew up: a non-finite u, v, p, Φ or p_f, a CFL number above `cfl_abort`, or (adaptive δt)
//! the next CFL step below the floor of [`SPEED_BOUND`] (the step collapsing). With the
//! adaptive rule a step whose Picard iteration does not converge ([`Error::PicardNotConverged`])
//! or whose CFL number ends above `cfl_abort` ([`Error::CflExceeded`]: the flow accelerated
//! through a δt chosen from the speeds before the step) is rejected and retaken with δt halved
//! (`TimeConfig::step_retries`, `time_stepping/clock.rs`); a fixed δt is never changed.
//!
//! With `ModelConfig::active_region` the step first sizes the window around the dense phase and
//! runs these same stages on it (`models/window.rs`).

use super::{ConvectionScheme, ModelConfig, TwoPhaseModel};
use crate::error::{Error, Result};
use crate::exec::Exec;
use crate::grid::{Field, HALO};
use crate::levelset::TransportVelocity;
use crate::operators::{
    convection, convection_weno5, divergence_max_abs, fill_velocity_ghosts, for_each_interior_row, for_each_interior_row2, gradient, max_speed,
    max_speed_where, BcMode,
};
use crate::projection::{fill_pressure_ghosts, ProjectionInputs};
use crate::rheology::PicardInfo;
use crate::solvers::SolveInfo;
use crate::time_stepping::clock::{bdf_coefficients, stable_dt, LIGHT_CFL_BAND, SPEED_BOUND};
use crate::time_stepping::momentum::ViscousScheme;
use crate::time_stepping::{StageSeconds, StepInfo};
use std::time::Instant;

/// Weight of the Dirichlet rows that hold the light phase's faces in the granular-only model's
/// predictor (c = FROZEN_FACE a₀ρ_s/δt): a node's stress moves such a face by 1e-8 of what it
/// moves a granular face.
const FROZEN_FACE: f64 = 1e8;

impl TwoPhaseModel {
    /// Advances the model by one step (stages in the order of this file's header).
    /// With the adaptive rule, a step whose Picard iteration does not converge or whose CFL
    /// number ends above `cfl_abort` is rejected and retaken with δt halved, at most
    /// `TimeConfig::step_retries` times (the window of an active region does this itself). A
    /// step that fails for good leaves the model bit for bit in its state before the step (the
    /// last accepted one).
    pub fn step(&mut self) -> Result<StepInfo> {
        let out = self.step_leaving_window();
        self.sync_from_window();
        out
    }

    /// [`TwoPhaseModel::step`] that leaves an active window's fields in the window (this
    /// model's fields lag until [`TwoPhaseModel::sync_from_window`]); the steps of
    /// [`TwoPhaseModel::advance`].
    pub(crate) fn step_leaving_window(&mut self) -> Result<StepInfo> {
        let mut info = self.step_accepted()?;
        let start = Instant::now();
        self.account_energy(info.dt);
        info.stage_seconds.diagnostics += start.elapsed().as_secs_f64();
        self.last.stage_seconds = info.stage_seconds;
        Ok(info)
    }

    /// [`TwoPhaseModel::step`] without the energy budget's accounting: the step (with its
    /// retries) on the whole domain or the window. The window's own steps come through here, so
    /// that the budget is kept once, on the whole model.
    pub(crate) fn step_accepted(&mut self) -> Result<StepInfo> {
        if let Some(ar) = self.config.active_region {
            return self.step_active(ar);
        }
        let retries = if self.config.time.fixed_dt.is_none() { self.config.time.step_retries } else { 0 };
        // the last accepted state, restored when the step fails (reused buffers)
        let mut snapshot = std::mem::take(&mut self.step_snapshot);
        self.checkpoint_into(&mut snapshot);
        self.step_snapshot = snapshot;
        let land = self.time_to_land;
        let mut attempt = 0usize;
        loop {
            match self.step_pooled() {
                Ok(mut info) => {
                    info.retries = attempt;
                    self.last.retries = attempt;
                    self.dt_ceiling *= crate::time_stepping::DT_CEILING_RECOVERY;
                    return Ok(info);
                }
                Err(e) if e.retakes_step() && attempt < retries => {
                    drop(e);
                    self.undo_step(land)?;
                    self.dt_ceiling = 0.5 * self.dt_attempt;
                    attempt += 1;
                }
                Err(e) => {
                    // the model is left at its last accepted state
                    self.undo_step(land)?;
                    let e = e.into_reported();
                    return Err(if attempt > 0 { with_retries(e, attempt) } else { e });
                }
            }
        }
    }

    /// Restores the state saved before the step in progress (and its landing target).
    fn undo_step(&mut self, land: Option<f64>) -> Result<()> {
        let snapshot = std::mem::take(&mut self.step_snapshot);
        let out = self.restore_state(&snapshot);
        self.step_snapshot = snapshot;
        self.time_to_land = land;
        out
    }

    /// The stages on the model's rayon pool (built once, in [`TwoPhaseModel::new`]).
    fn step_pooled(&mut self) -> Result<StepInfo> {
        let exec = self.exec();
        let pool = std::sync::Arc::clone(&self.pool);
        pool.install(|| crate::exec::with_active_workers(|| self.step_stages(exec)))
    }

    fn step_stages(&mut self, exec: Exec) -> Result<StepInfo> {
        // the wall time of each stage (StepInfo::stage_seconds)
        let mut secs = StageSeconds::default();
        let mut clock = Instant::now();
        let mut lap = |slot: &mut f64| {
            let now = Instant::now();
            *slot += (now - clock).as_secs_f64();
            clock = now;
        };
        let dt = self.choose_dt(exec)?;
        self.dt_attempt = dt;
        let (a0, a1, a2, w) = bdf_coefficients(dt, self.dt_prev);
        lap(&mut secs.choose_dt);
        let (pieces_removed, mass_shift) = self.interface(dt, exec)?;
        lap(&mut secs.interface);
        self.properties(exec);
        lap(&mut secs.properties);
        self.pore_pressure(dt, (a0, a1, a2, w), exec)?;
        lap(&mut secs.pore_pressure);
        self.rheology_stage(a0 / dt, exec)?;
        lap(&mut secs.rheology);
        let (viscous, picard) = self.predictor(dt, a0, a1, a2, w, &mut secs, exec)?;
        // the predictor's time less its solves and projections (measured inside)
        lap(&mut secs.predictor_setup);
        secs.predictor_setup -= secs.predictor_solves + secs.projections;
        self.check_predictor(dt, exec)?;
        lap(&mut secs.diagnostics);
        let pressure = self.projection_stage(dt / a0, exec)?;
        lap(&mut secs.pressure_projection);
        let mut info = self.checks(dt, viscous, pressure, picard, exec)?;
        lap(&mut secs.diagnostics);
        info.stage_seconds = secs;
        self.last.stage_seconds = secs;
        info.pieces_removed = pieces_removed;
        self.last.pieces_removed = pieces_removed;
        info.mass_shift = mass_shift;
        self.last.mass_shift = mass_shift;
        Ok(info)
    }

    /// Balances the body force at rest: sets p so that (1/ρ)∇p = g − P(g), where P is the
    /// discrete projection onto divergence-free fields (one pressure solve). A stratified fluid
    /// at rest then stays exactly at rest; any initial velocity is left unchanged.
    pub fn initialise_pressure(&mut self) -> Result<SolveInfo> {
        self.window = None;
        let exec = self.exec();
        self.properties(exec);
        let cfg = &self.config;
        let [gx, gy] = cfg.gravity;
        // g on the unknown faces, zero on fixed boundary faces; project it with δt/a₀ = 1.
        let wk = &mut self.work;
        let (rho_u, rho_v) = self.properties.density();
        wk.rhs_u.fill(gx);
        wk.rhs_v.fill(gy);
        let rho_ref = cfg.reference_density();
        if rho_ref != 0.0 {
            // (1 − ρ_f/ρ) g: the ambient hydrostatic pressure is not part of p
            for (f, rho) in [(&mut wk.rhs_u, rho_u), (&mut wk.rhs_v, rho_v)] {
                let (rs, st, n) = (rho.slice(), f.stride(), f.nx);
                for_each_interior_row(exec, f, |j, row| {
                    let b = (j + HALO) * st;
                    for i in HALO..HALO + n {
                        row[i] *= 1.0 - rho_ref / rs[b + i];
                    }
                });
            }
        }
        if let Some(pore) = &mut self.pore {
            // the pore-pressure force −∇p_f/ρ is balanced as well
            pore.pf.extrapolate_ghosts_constant();
            gradient(&pore.pf, &cfg.grid, &mut wk.gx, &mut wk.gy, exec);
            for (f, gr, rho) in [(&mut wk.rhs_u, &wk.gx, rho_u), (&mut wk.rhs_v, &wk.gy, rho_v)] {
                let (gs, rs, st, n) = (gr.slice(), rho.slice(), f.stride(), f.nx);
                for_each_interior_row(exec, f, |j, row| {
                    let b = (j + HALO) * st;
                    for i in HALO..HALO + n {
                        row[i] -= gs[b + i] / rs[b + i];
                    }
                });
            }
        }
        fill_velocity_ghosts(&mut wk.rhs_u, &mut wk.rhs_v, &cfg.bc, &cfg.grid, BcMode::Homogeneous);
        self.p.fill(0.0);
        if cfg.free_surface {
            self.phi.extrapolate_ghosts_linear();
        }
        let input = ProjectionInputs { rho_u, rho_v, phi: &self.phi, dense_density: cfg.dense.density, rotational: None, grid: &cfg.grid, bc: &cfg.bc };
        let info = self.pressure.balance(&mut wk.rhs_u, &mut wk.rhs_v, &mut self.p, &input, exec);
        self.gauge_pressure();
        info
    }

    /// Fixes the pressure's constant by the configured gauge (see
    /// [`crate::models::PressureGauge`]): with `Top`, p ← p − ⟨p⟩_top row, so that the air under
    /// a closed lid sits at p ≈ 0 as under the paper's open top. Velocities are unaffected.
    pub(crate) fn gauge_pressure(&mut self) {
        if self.config.resolved_pressure_gauge() != Some(crate::models::PressureGauge::Top) {
            return;
        }
        let (nx, ny) = (self.p.nx as isize, self.p.ny as isize);
        let from = (self.config.pressure_top_from as isize).min(nx - 1);
        let mean = (from..nx).map(|i| self.p.at(i, ny - 1)).sum::<f64>() / (nx - from) as f64 - self.config.pressure_top_value;
        if mean == 0.0 || !mean.is_finite() {
            return;
        }
        // ghosts included (a constant shift keeps the even reflections of Neumann sides)
        for x in self.p.slice_mut() {
            *x -= mean;
        }
    }

    /// The adaptive rule's step at the current speeds, before the caps (`max_dt`, the growth
    /// factor, a rejected step's ceiling, landing on t_end): `stable_dt` with C_cfl at the
    /// largest speeds, prescribed boundary speeds included; with `cfl_light` (and a light phase
    /// beside a dense one), the smaller of `stable_dt` with C_cfl at the largest speeds on the
    /// faces next to a cell with Φ > −LIGHT_CFL_BAND·h and `stable_dt` with `cfl_light` at the
    /// largest speeds everywhere (time_stepping/clock.rs).
    pub fn cfl_dt(&self, exec: Exec) -> f64 {
        let cfg = &self.config;
        let g = &cfg.grid;
        let (mut umax, mut vmax) = max_speed(&self.u, &self.v, exec);
        // prescribed boundary speeds (a lid drives a fluid at rest)
        for side in crate::grid::Side::ALL {
            if let crate::grid::VelocityBc::Velocity { normal, tangential } = cfg.bc.get(side) {
                let (un, ut) = (normal.abs(), tangential.abs());
                if side.is_x() {
                    umax = umax.max(un);
                    vmax = vmax.max(ut);
                } else {
                    umax = umax.max(ut);
                    vmax = vmax.max(un);
                }
            }
        }
        let nu = if cfg.viscous == ViscousScheme::Explicit {
            let mut nu = cfg.dense.viscosity / cfg.dense.density;
            if let Some(l) = cfg.light {
                nu = nu.max(l.viscosity / l.density);
            }
            nu
        } else {
            0.0
        };
        let gmag = (cfg.gravity[0].powi(2) + cfg.gravity[1].powi(2)).sqrt();
        match (cfg.time.cfl_light, cfg.light.is_some() && !cfg.free_surface) {
            (Some(cfl_light), true) => {
                let (ud, vd) = max_speed_where(&self.u, &self.v, &self.phi, -LIGHT_CFL_BAND * g.h(), exec);
                stable_dt(cfg.time.cfl, ud, vd, g.dx, g.dy, gmag, nu).min(stable_dt(cfl_light, umax, vmax, g.dx, g.dy, gmag, nu))
            }
            _ => stable_dt(cfg.time.cfl, umax, vmax, g.dx, g.dy, gmag, nu),
        }
    }

    /// Stage 1: the time step.
    fn choose_dt(&mut self, exec: Exec) -> Result<f64> {
        let cfg = &self.config;
        let land = |dt: f64| match self.time_to_land {
            Some(r) if r <= dt * (1.0 + 1e-9) => r,
            Some(r) if r < 2.0 * dt => 0.5 * r,
            _ => dt,
        };
        if let Some(dt) = cfg.time.fixed_dt {
            return Ok(land(dt));
        }
        let mut dt = self.cfl_dt(exec).min(cfg.time.max_dt);
        match self.dt_prev {
            Some(prev) => dt = dt.min(prev * cfg.time.max_growth),
            // start from a tenth of the stable step: an impulsive start (a column released from
            // rest) accelerates faster than g near corners; the growth cap recovers the full step
            // in about 13 steps
            None => dt *= 0.1,
        }
        let dt = land(dt.min(self.dt_ceiling));
        if !dt.is_finite() {
            return Err(Error::Simulation {
                what: "no finite time step: the fluid is at rest with no forcing; set `dt` or `max_dt`".into(),
                step: self.step_count,
                time: self.time,
                location: None,
            });
        }
        Ok(dt)
    }

    /// Stage 2 (paper step 1): transport of the level set. A single-phase model or a frozen
    /// interface skips it. Returns the cells of the detached pieces turned to air and the mass
    /// correction's shift δ of Φ (m).
    fn interface(&mut self, dt: f64, exec: Exec) -> Result<(usize, f64)> {
        if self.config.light.is_none() || !self.config.transport_interface {
            return Ok((0, 0.0));
        }
        let cfg = &self.config;
        fill_velocity_ghosts(&mut self.u, &mut self.v, &cfg.bc, &cfg.grid, BcMode::Full);
        let wk = &mut self.work;
        let half = match self.dt_prev {
            Some(prev) => 0.5 * dt / prev,
            None => 0.0,
        };
        let vel = TransportVelocity { u: &self.u, v: &self.v, u_prev: &self.u_prev, v_prev: &self.v_prev, half, out_u: &mut wk.rhs_u, out_v: &mut wk.rhs_v };
        let n = self.step_count + 1;
        let redistance = cfg.redistance_every > 0 && n % cfg.redistance_every as u64 == 0;
        // the volume fraction's split order alternates with the step number
        let r = self.levelset.advance(&mut self.phi, vel, &cfg.grid, &cfg.bc, dt, redistance, n % 2 == 1, exec);
        r.map_err(|e| self.at_step(e))?;
        let mut shift = 0.0;
        if cfg.mass_correction {
            shift += self.levelset.correct_mass(&mut self.phi, self.reference_area, Some((&self.u, &self.v)), &cfg.grid, exec);
        }
        // the small detached pieces the transport or the correction's shift left, their area put
        // back by a second correction (`piece_removal_cells`)
        let removed = self.levelset.remove_pieces(&mut self.phi);
        if removed > 0 && cfg.mass_correction {
            shift += self.levelset.correct_mass(&mut self.phi, self.reference_area, Some((&self.u, &self.v)), &cfg.grid, exec);
        }
        self.properties.invalidate();
        Ok((removed, shift))
    }

    /// Stage 3 (paper step 2): material properties from the level set
    /// ([`crate::properties::MaterialProperties::update`]; skipped when Φ is held fixed and they
    /// are current).
    pub(crate) fn properties(&mut self, exec: Exec) {
        let phi_fixed = self.config.light.is_none() || !self.config.transport_interface;
        if !self.properties.needs_update(phi_fixed) {
            return;
        }
        self.phi.extrapolate_ghosts_linear();
        let laws = self.config.property_laws();
        let phi = self.levelset.properties_level_set(&self.phi, laws.eps, &self.config.grid, exec);
        self.properties.update(phi, &laws, exec);
        self.pressure.density_changed();
    }

    /// Stage 4 (paper step 3): the pore gas pressure p_f^{n+1} (skipped when not fluidised).
    fn pore_pressure(&mut self, dt: f64, coeffs: (f64, f64, f64, f64), exec: Exec) -> Result<()> {
        let first = self.dt_prev.is_none();
        let eps = self.config.interface_width * self.config.grid.h();
        let Some(pore) = self.pore.as_mut() else { return Ok(()) };
        fill_velocity_ghosts(&mut self.u, &mut self.v, &self.config.bc, &self.config.grid, BcMode::Full);
        self.phi.extrapolate_ghosts_linear();
        let r = pore.advance(&self.phi, &self.u, &self.v, &self.config.grid, dt, coeffs, first, eps, exec);
        match r {
            Ok(_) => Ok(()),
            // an unstable or non-finite p_f: the room names the cell, the step and time are added here
            Err(Error::Simulation { what, location, .. }) => Err(Error::Simulation { what, step: self.step_count + 1, time: self.time + dt, location }),
            Err(e) => Err(self.at_step(Error::SolverFailure { solver: "pore-pressure solve".into(), message: e.to_string() })),
        }
    }

    /// Stage 5 (paper step 4): the momentum predictor ũ^{n+1}.
    #[allow(clippy::too_many_arguments)]
    fn predictor(&mut self, dt: f64, a0: f64, a1: f64, a2: f64, w: f64, secs: &mut StageSeconds, exec: Exec) -> Result<(SolveInfo, PicardInfo)> {
        let cfg = &self.config;
        let (grid, bc) = (&cfg.grid, &cfg.bc);
        let [gxv, gyv] = cfg.gravity;
        let rho_ref = cfg.reference_density();
        fill_velocity_ghosts(&mut self.u, &mut self.v, bc, grid, BcMode::Full);
        fill_pressure_ghosts(&mut self.p, bc);
        let wk = &mut self.work;
        let (rho_u, rho_v) = self.properties.density();
        if cfg.convection {
            match cfg.convection_scheme {
                ConvectionScheme::Centred => convection(&self.u, &self.v, grid, &mut wk.conv_u, &mut wk.conv_v, exec),
                ConvectionScheme::Weno5 => convection_weno5(&self.u, &self.v, grid, &mut wk.conv_u, &mut wk.conv_v, exec),
            }
        } else {
            // Stokes flow (Re = 0), or a flow whose convection vanishes identically (x-invariant
            // layers, where an explicit convection of round-off perturbations through open
            // sides is unstable)
            wk.conv_u.fill(0.0);
            wk.conv_v.fill(0.0);
        }
        if cfg.free_surface {
            // granular-only model: ∇p_f, then ∇pⁿ with pⁿ = 0 on the surface Φ^{n+1} = 0
            // (Φ's ghosts were filled by `properties` this step; Φ has not changed since)
            pressure_gradient(None, self.pore.as_mut(), &mut wk.ptot, &mut wk.gx, &mut wk.gy, grid, bc, exec);
            crate::projection::free_surface::FreeSurfaceProjection::add_pressure_gradient(&self.p, &self.phi, &mut wk.gx, &mut wk.gy, grid, exec);
        } else {
            pressure_gradient(Some(&self.p), self.pore.as_mut(), &mut wk.ptot, &mut wk.gx, &mut wk.gy, grid, bc, exec);
        }
        // open sides with backflow stabilisation: p_b − ½ρ(u·n)² on the faces where air enters
        crate::projection::add_backflow_pressure(&self.u, &self.v, rho_u, rho_v, &mut wk.gx, &mut wk.gy, grid, bc);
        let first = self.dt_prev.is_none();
        // rhs = ρ[(a₁uⁿ − a₂uⁿ⁻¹)/δt − N* + g] − ρ_ref g − ∇pⁿ ;  c = a₀ρ/δt
        // (ρ_ref = ρ_f with `ambient_hydrostatic`, else 0: the same floating-point result)
        for (rhs, c, rho, un, um, nn, nm, gp, gcomp) in [
            (&mut wk.rhs_u, &mut wk.c_u, rho_u, &self.u, &self.u_prev, &wk.conv_u, &self.conv_prev_u, &wk.gx, gxv),
            (&mut wk.rhs_v, &mut wk.c_v, rho_v, &self.v, &self.v_prev, &wk.conv_v, &self.conv_prev_v, &wk.gy, gyv),
        ] {
            let st = rhs.stride();
            let n = rhs.nx;
            let (rs, uns, ums, nns, nms, gps) = (rho.slice(), un.slice(), um.slice(), nn.slice(), nm.slice(), gp.slice());
            let (we, wm) = if first { (1.0, 0.0) } else { (1.0 + w, w) };
            for_each_interior_row(exec, c, |j, row| {
                let b = (j + HALO) * st + HALO;
                for i in 0..n {
                    row[HALO + i] = a0 * rs[b + i] / dt;
                }
            });
            for_each_interior_row(exec, rhs, |j, row| {
                let b = (j + HALO) * st + HALO;
                for i in 0..n {
                    let k = b + i;
                    let nstar = we * nns[k] - wm * nms[k];
                    row[HALO + i] = rs[k] * ((a1 * uns[k] - a2 * ums[k]) / dt - nstar + gcomp) - rho_ref * gcomp - gps[k];
                }
            });
        }
        if cfg.free_surface {
            // granular-only model: the faces with no granular cell beside them are not unknowns;
            // they keep their BDF history value (a₁uⁿ − a₂uⁿ⁻¹)/a₀ of the extended velocity (a
            // Dirichlet row: c ← FROZEN c, rhs ← c u), so that the stresses of the nodes on the
            // surface act on the grains only and no light-phase dynamics enters the predictor
            let cf = FROZEN_FACE * a0 * cfg.dense.density / dt;
            let (ps, sp) = (self.phi.slice(), self.phi.stride());
            for (rhs, c, un, um, horizontal) in
                [(&mut wk.rhs_u, &mut wk.c_u, &self.u, &self.u_prev, true), (&mut wk.rhs_v, &mut wk.c_v, &self.v, &self.v_prev, false)]
            {
                let (mx, st) = (rhs.nx, rhs.stride());
                let (us, ums) = (un.slice(), um.slice());
                // the cell before the face: left (u) or below (v); row by row (elementwise)
                let back = if horizontal { 1 } else { sp };
                for_each_interior_row2(exec, rhs, c, |j, rrow, crow| {
                    for i in 0..mx {
                        let k = (j + HALO) * sp + i + HALO;
                        if ps[k - back] > 0.0 || ps[k] > 0.0 {
                            continue;
                        }
                        let f = (j + HALO) * st + i + HALO;
                        crow[HALO + i] = cf;
                        rrow[HALO + i] = cf * (a1 * us[f] - a2 * ums[f]) / a0;
                    }
                });
            }
        }
        // history: u_prev ← uⁿ, u ← initial guess u* = (1+ω)uⁿ − ω uⁿ⁻¹ (in place: the
        // buffers of u, v, p, Φ never move, Python holds views of them)
        let (we, wm) = if first { (1.0, 0.0) } else { (1.0 + w, w) };
        for (x, xm) in [(&mut self.u, &mut self.u_prev), (&mut self.v, &mut self.v_prev)] {
            let n = x.nx;
            for_each_interior_row2(exec, x, xm, |_, row, rowm| {
                for i in HALO..HALO + n {
                    let un = row[i];
                    row[i] = we * un - wm * rowm[i];
                    rowm[i] = un;
                }
            });
        }
        std::mem::swap(&mut wk.conv_u, &mut self.conv_prev_u);
        std::mem::swap(&mut wk.conv_v, &mut self.conv_prev_v);
        self.momentum_solve(secs, exec).map_err(|e| self.at_step(e))
    }

    /// After stage 5: a predictor that blew up (NaN or inf) is reported as such, with its cell,
    /// rather than as an invalid right-hand side of the pressure solve.
    fn check_predictor(&self, dt: f64, exec: Exec) -> Result<()> {
        let (umax, vmax) = max_speed(&self.u, &self.v, exec);
        if umax.is_finite() && vmax.is_finite() {
            return Ok(());
        }
        let (fu, fv) = (self.u.max_abs_with_location(), self.v.max_abs_with_location());
        let (which, loc) = if !fu.0.is_finite() { ("u", fu.1) } else { ("v", fv.1) };
        Err(Error::Simulation {
            what: format!("non-finite velocity ({which} is NaN or inf) after the momentum predictor (blow-up)"),
            step: self.step_count + 1,
            time: self.time + dt,
            location: Some(loc),
        })
    }

    /// Stage 6 (paper step 5): pressure projection.
    fn projection_stage(&mut self, dt_over_a0: f64, exec: Exec) -> Result<SolveInfo> {
        let cfg = &self.config;
        let ((rho_u, rho_v), (eta_c, _)) = (self.properties.density(), self.properties.viscosity());
        let input = ProjectionInputs {
            rho_u,
            rho_v,
            phi: &self.phi,
            dense_density: cfg.dense.density,
            rotational: cfg.rotational_pressure.then_some(eta_c),
            grid: &cfg.grid,
            bc: &cfg.bc,
        };
        let r = self.pressure.project(&mut self.u, &mut self.v, &mut self.p, &input, dt_over_a0, exec);
        self.gauge_pressure();
        r.map_err(|e| self.at_step(e))
    }

    /// Stage 7: checks and bookkeeping.
    fn checks(&mut self, dt: f64, viscous: SolveInfo, pressure: SolveInfo, picard: PicardInfo, exec: Exec) -> Result<StepInfo> {
        let cfg = &self.config;
        let g = &cfg.grid;
        fill_velocity_ghosts(&mut self.u, &mut self.v, &cfg.bc, g, BcMode::Full);
        let (umax, vmax) = max_speed(&self.u, &self.v, exec);
        let next_time = self.time + dt;
        if !(umax.is_finite() && vmax.is_finite()) {
            let (fu, fv) = (self.u.max_abs_with_location(), self.v.max_abs_with_location());
            let (which, loc) = if !fu.0.is_finite() { ("u", fu.1) } else { ("v", fv.1) };
            return Err(Error::Simulation {
                what: format!("non-finite velocity ({which} is NaN or inf) after the projection"),
                step: self.step_count + 1,
                time: next_time,
                location: Some(loc),
            });
        }
        let cfl = dt * (umax / g.dx + vmax / g.dy);
        if cfl > cfg.time.cfl_abort {
            let (fu, fv) = (self.u.max_abs_with_location(), self.v.max_abs_with_location());
            let loc = if fu.0 / g.dx >= fv.0 / g.dy { fu.1 } else { fv.1 };
            return Err(Error::CflExceeded {
                what: format!(
                    "CFL number {cfl:.3} exceeds the limit cfl_abort = {} (δt = {dt:.3e} s, max|u| = {umax:.3e}, max|v| = {vmax:.3e} m/s)",
                    cfg.time.cfl_abort
                ),
                step: self.step_count + 1,
                time: next_time,
                location: Some(loc),
            });
        }
        // the other fields of the state (a NaN there does not always reach u within the step)
        let pf = self.pore.as_ref().map(|pore| &pore.pf);
        for (name, f) in [("p", Some(&self.p)), ("phi", Some(&self.phi)), ("pf", pf)] {
            if let Some(loc) = f.and_then(|f| first_non_finite(f, exec)) {
                return Err(Error::Simulation {
                    what: format!("non-finite {name} (NaN or inf) after the step (blow-up)"),
                    step: self.step_count + 1,
                    time: next_time,
                    location: Some(loc),
                });
            }
        }
        // the step collapsing: the adaptive rule's next step at the speeds reached
        if cfg.time.fixed_dt.is_none() {
            if let Some((floor, u_ref)) = dt_floor(cfg) {
                let gmag = (cfg.gravity[0].powi(2) + cfg.gravity[1].powi(2)).sqrt();
                let dt_next = stable_dt(cfg.time.cfl, umax, vmax, g.dx, g.dy, gmag, 0.0);
                if dt_next < floor {
                    let (fu, fv) = (self.u.max_abs_with_location(), self.v.max_abs_with_location());
                    let loc = if fu.0 / g.dx >= fv.0 / g.dy { fu.1 } else { fv.1 };
                    return Err(Error::Simulation {
                        what: format!(
                            "the time step collapsed (blow-up): the CFL rule gives δt = {dt_next:.3e} s at max|u| = {umax:.3e}, max|v| = {vmax:.3e} m/s, \
                             below the floor {floor:.3e} s (the step at {SPEED_BOUND} times the reference speed {u_ref:.3e} m/s, \
                             the free-fall speed √(2|g|(Lx + Ly)) or the largest boundary speed)"
                        ),
                        step: self.step_count + 1,
                        time: next_time,
                        location: Some(loc),
                    });
                }
            }
        }
        let divergence = if cfg.free_surface {
            crate::projection::free_surface::divergence_max_abs_granular(&self.u, &self.v, &self.phi, g, exec)
        } else {
            divergence_max_abs(&self.u, &self.v, g, exec)
        };
        self.time = next_time;
        self.step_count += 1;
        self.dt_prev = Some(dt);
        self.last = StepInfo {
            dt,
            time: self.time,
            pressure,
            viscous,
            pore: self.pore.as_ref().map(|p| p.last).unwrap_or_default(),
            max_speed: umax.max(vmax),
            cfl,
            divergence,
            picard_iterations: picard.iterations,
            picard_increment: picard.increment,
            picard_r_halvings: picard.r_halvings,
            picard_restarts: picard.restarts,
            retries: 0,
            pieces_removed: 0,
            mass_shift: 0.0,
            stage_seconds: StageSeconds::default(),
        };
        Ok(self.last)
    }

    /// Attaches the step and time to a solver error ([`Error::SolverInStep`]).
    fn at_step(&self, e: Error) -> Error {
        e.in_step(self.step_count + 1, self.time)
    }
}

/// The floor of the adaptive step ([`SPEED_BOUND`]) and the reference speed; None when the flow
/// has no forcing that sets a speed (no gravity, no moving boundary).
fn dt_floor(cfg: &ModelConfig) -> Option<(f64, f64)> {
    let g = &cfg.grid;
    let gmag = (cfg.gravity[0].powi(2) + cfg.gravity[1].powi(2)).sqrt();
    let mut u_ref = (2.0 * gmag * (g.lx + g.ly)).sqrt();
    for side in crate::grid::Side::ALL {
        if let crate::grid::VelocityBc::Velocity { normal, tangential } = cfg.bc.get(side) {
            u_ref = u_ref.max(normal.abs()).max(tangential.abs());
        }
    }
    let u_bound = SPEED_BOUND * u_ref;
    (u_ref > 0.0).then(|| (stable_dt(cfg.time.cfl, u_bound, u_bound, g.dx, g.dy, gmag, 0.0), u_ref))
}

/// The first interior cell (i, j) of `f` holding NaN or inf, if any (the rows checked on the
/// threads of `exec`, the cell searched for only when one holds such a value).
fn first_non_finite(f: &Field, exec: Exec) -> Option<(usize, usize)> {
    let (s, st, nx) = (f.slice(), f.stride(), f.nx);
    let bad = exec.max_rows(f.ny, nx * f.ny, |j| {
        let b = (j + HALO) * st + HALO;
        let finite = s[b..b + nx].iter().fold(true, |all, x| all & x.is_finite());
        if finite {
            0.0
        } else {
            1.0
        }
    });
    if bad == 0.0 {
        return None;
    }
    let a = f.interior();
    a.indexed_iter().find(|(_, x)| !x.is_finite()).map(|((j, i), _)| (i, j))
}

/// `e` with the number of rejected attempts before it in its message.
fn with_retries(e: Error, attempts: usize) -> Error {
    match e {
        Error::Simulation { what, step, time, location } => {
            Error::Simulation { what: format!("{what} (the step was retaken {attempts} times with δt halved each time)"), step, time, location }
        }
        e => e,
    }
}

/// ∇(p + p_f) on the faces into `gx`, `gy` (the predictor's pressure force, paper eq. 10b: the
/// pore pressure pushes the grains apart); `p` with its ghosts filled (None: p left out, as in
/// the free-surface model's predictor), `ptot` a work field.
#[allow(clippy::too_many_arguments)]
pub(crate) fn pressure_gradient(
    p: Option<&Field>,
    pore: Option<&mut crate::pore_pressure::PorePressure>,
    ptot: &mut Field,
    gx: &mut Field,
    gy: &mut Field,
    grid: &crate::grid::Grid,
    bc: &crate::grid::BoundaryConditions,
    exec: Exec,
) {
    match (p, pore) {
        (Some(p), None) => gradient(p, grid, gx, gy, exec),
        (None, None) => {
            gx.fill(0.0);
            gy.fill(0.0);
        }
        (p, Some(pore)) => {
            pore.pf.extrapolate_ghosts_constant();
            match p {
                Some(p) => exec.copy(ptot.slice_mut(), p.slice()),
                None => ptot.fill(0.0),
            }
            let (st, n, pfs) = (ptot.stride(), ptot.nx, pore.pf.slice());
            for_each_interior_row(exec, ptot, |j, row| {
                let b = (j + HALO) * st;
                for i in HALO..HALO + n {
                    row[i] += pfs[b + i];
                }
            });
            fill_pressure_ghosts(ptot, bc);
            gradient(ptot, grid, gx, gy, exec);
        }
    }
}
