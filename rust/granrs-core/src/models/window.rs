//! Active region of the two-phase model: each step runs on a window of the grid around
//! the dense phase instead of on the whole domain.
//!
//! Equations: the same as the whole-domain model (Aravena et al. eq. 10a–f, stages in
//! `models/step.rs`), on the window W = (x0, x0 + n_x^W dx) × (y0, y0 + n_y^W dy) anchored at
//! the domain's lower-left corner, with the domain's own boundary conditions on all four sides of
//! W (but open right and top sides with [`WindowSides`], below). Outside W the light phase is taken at
//! rest with its hydrostatic pressure, so that on the window's right and top sides (walls: no
//! normal flow) and under the `Top` gauge the only change is the gauge value: the mean
//! pressure of W's top row is the hydrostatic pressure of the light phase there,
//! (ρ_f − ρ_ref) g·(x_top^W − x_top^Ω) above the domain's top-row mean 0.
//!
//! **Open right side** (`WindowSides::OpenRight`). A wall b cells ahead of the front turns back the air
//! the front pushes, which the whole domain lets go on along the channel; the window then lags
//! the whole-domain front by 2–3 % (docs/models.md). With an open right side the window's right side
//! (where it lies inside the domain) is an outflow side, ∂u/∂n = 0, at the ambient pressure
//! p_a(x) = p_top + (ρ_f − ρ_ref) g·(x − x_top), the hydrostatic light phase of the domain's gauge
//! ([`crate::grid::BoundaryConditions::with_outlet_pressure`]; δp = 0 there, so p keeps p_a). The
//! window's pressure is then fixed by that side and needs no gauge. The flux through the open
//! side is copied back with the state, so the first cell outside W holds a divergence until W
//! grows over it; the projection of the next step on the grown W removes it.
//!
//! **Open top** (`WindowSides::OpenRightTop`, with the right side open too). The top side too is an outflow at
//! p_a, and both open sides have backflow stabilisation: on a face where air enters, the
//! predictor's boundary pressure is p_a − ½ρ(u·n)² (the air arrives from the ambient at rest
//! and pays its dynamic pressure; [`crate::grid::BoundaryConditions::backflow`]). Without it an
//! open top over the deposit, tried at ny = 64, drew jets of air in and out of it (4.9 m/s
//! against at most 1.6 m/s in the whole domain after t = 1.5 s), the backflow instability of
//! open boundaries where air enters; with it the window's largest speed stays at 1.7–2.4 m/s
//! (BAND = 8) and the band can be narrowed to 4 cells (docs/models.md).
//!
//! **Window.** Let i_max, j_max be the largest column and row of a cell with Φ > −3ε: the
//! support of the smoothed properties H_ε(Φ + sε), s ≤ 2, of the dense phase (a film with Φ ≈ 0
//! along a wall can change sign over several cells in one step). W is grown before a step that
//! starts with that support less than b cells (the band) from W's right or top side, to
//! i_max + 1 + 2b and j_max + 1 + 2b cells, and shrunk when these sizes are at most 3/4 of W's in
//! either direction. The interface moves less than a cell per step (CFL < 1) and the
//! redistancing moves the support's far edge by a few cells at most, so the dense phase keeps
//! more than b/2 cells of light phase to W's sides (asserted by the tests). Sizes are rounded up
//! to a multiple of `align` cells (the multigrid coarsens a window as far as the whole grid)
//! and clipped to the domain.
//!
//! **State transfer.** W is a [`TwoPhaseModel`] of its own. Its whole state (fields with ghost
//! layers, BDF2 history, Σ, s, p_f and its history, the pressure increment, the clock) is copied
//! from this model's when W is built; W's interior (boundary faces and nodes included) is copied
//! back after every [`TwoPhaseModel::step`], and once at the end of
//! [`TwoPhaseModel::advance`] (the steps within it copy only the clock, and the copy is made
//! before W is rebuilt), so this model's fields — and the zero-copy views Python holds on
//! them — are the whole-domain state whenever a call returns. On a shrink the velocity and its history
//! outside the new W are set to zero (the light phase at rest); the faces of W's new sides are
//! walls, and the divergence their old flux leaves in W's edge cells is removed by the next
//! projection. On a growth the cells that join W are at rest, consistent with the wall they
//! were behind.
//!
//! **Where it is exact and where not.** Inside W the stages are those of the whole-domain step.
//! The difference is the light phase outside W, frozen at rest instead of moved by the flow:
//! with a density ratio ρ_f/ρ_s ≈ 1/1450 (air and the paper's beads) its inertia and its
//! pressure on the granular surface are small, but not zero; `band` sets the distance to the
//! walls that stand in for it. The run-out change is measured against the whole-domain run in
//! docs/models.md (active region).
//!
//! **Granular-only model** (`ModelConfig::free_surface`): there is no light phase to freeze.
//! The window's walls meet only faces beyond the velocity extension (EXTENSION_LAYERS < band
//! faces from the dense phase), which are zero in the whole-domain step as well, and the
//! surface pressure is p = 0 in both; the window then differs from the whole domain only by
//! the pressure solve's tolerance (its multigrid hierarchy is the window's) and by the
//! redistancing far from the surface. No pressure gauge is involved.

use super::active_region::{ActiveRegion, WindowSides};
use super::two_phase::{ModelConfig, PressureGauge, TwoPhaseModel};
use crate::error::{Error, Result};
use crate::exec::Exec;
use crate::grid::{Field, Grid, PressureBc, Side, VelocityBc, WindowState, HALO};
use crate::time_stepping::StepInfo;
use ndarray::s;

/// Copies the block of `src` that `dst` covers when both are anchored at the lower-left corner:
/// `dst`'s whole array, ghosts included.
fn copy_block(src: &Field, dst: &mut Field) {
    let (rows, cols) = dst.data.dim();
    dst.data.assign(&src.data.slice(s![0..rows, 0..cols]));
}

/// Copies `win`'s interior (low ghosts included) into the same block of `full`.
fn copy_back(win: &Field, full: &mut Field, exec: Exec) {
    let (rows, cols) = (HALO + win.ny, HALO + win.nx);
    let (ws, fs) = (win.data.dim().1, full.data.dim().1);
    let src = win.slice();
    exec.for_each_row(&mut full.slice_mut()[..rows * fs], fs, |j, row| row[..cols].copy_from_slice(&src[j * ws..j * ws + cols]));
}

/// Sets `f` to zero outside the interior block of a window of `nxw × nyw` cells.
fn zero_outside(f: &mut Field, nxw: usize, nyw: usize) {
    let (ni, nj) = f.loc.interior_shape(nxw, nyw);
    let (rows, cols) = f.data.dim();
    f.data.slice_mut(s![HALO + nj..rows, ..]).fill(0.0);
    f.data.slice_mut(s![0..HALO + nj, HALO + ni..cols]).fill(0.0);
}

/// Copies the flat interior vector of an `nx_src`-wide grid into an `nx_dst`-wide one, rows
/// 0..rows and columns 0..min(nx_src, nx_dst) (row-major, index j nx + i).
fn copy_flat(src: &[f64], nx_src: usize, dst: &mut [f64], nx_dst: usize) {
    let rows = (src.len() / nx_src).min(dst.len() / nx_dst);
    let n = nx_src.min(nx_dst);
    for j in 0..rows {
        dst[j * nx_dst..j * nx_dst + n].copy_from_slice(&src[j * nx_src..j * nx_src + n]);
    }
}

impl TwoPhaseModel {
    /// The current active window's size (n_x^W, n_y^W), if one is built.
    pub fn active_window(&self) -> Option<(usize, usize)> {
        self.window.as_ref().map(|w| (w.config.grid.nx, w.config.grid.ny))
    }

    /// Checks that the configuration admits an active window (called by `ModelConfig::validate`).
    pub(crate) fn validate_active_region(cfg: &ModelConfig) -> Result<()> {
        let Some(ar) = cfg.active_region else { return Ok(()) };
        ar.validate()?;
        if cfg.light.is_none() {
            return Err(Error::param("active_region", "set", "only for a two-phase model (a light phase)"));
        }
        for side in [Side::Right, Side::Top] {
            let bc = cfg.bc.get(side);
            let wall = matches!(bc, VelocityBc::NoSlip | VelocityBc::FreeSlip | VelocityBc::Coulomb | VelocityBc::NavierSlip { .. });
            if !wall || cfg.bc.pressure(side) == PressureBc::Dirichlet {
                return Err(Error::param(
                    "active_region",
                    format!("{} side '{}'", side.name(), bc.name()),
                    "right and top sides that are walls (no-slip, free-slip, Navier or Coulomb): a window's sides are walls",
                ));
            }
        }
        if cfg.free_surface && ar.sides != WindowSides::Walls {
            return Err(Error::param(
                "active_region_sides",
                ar.sides.name(),
                "'walls' with the granular-only model (free surface): it carries no air to let through an open side",
            ));
        }
        if !cfg.free_surface && cfg.resolved_pressure_gauge() != Some(PressureGauge::Top) {
            return Err(Error::param(
                "active_region",
                "with this pressure gauge",
                "the 'top' pressure gauge (pressure_gauge 'top', or 'auto' with a pressure-dependent law)",
            ));
        }
        Ok(())
    }

    /// The current window's size: the built window's, or the one a restored checkpoint held
    /// until the next step rebuilds it.
    pub(crate) fn window_size(&self) -> Option<(usize, usize)> {
        self.active_window().or(self.restored_window)
    }

    /// The window size the dense phase needs now: (n_x, n_y) before rounding.
    fn window_needed(&self, ar: ActiveRegion) -> (usize, usize) {
        // the dense phase is inside the current window (or anywhere if none): scan that block
        let (sx, sy) = self.window_size().unwrap_or((self.config.grid.nx, self.config.grid.ny));
        let phi = self.window.as_ref().map_or(&self.phi, |w| &w.phi);
        let support = -3.0 * self.config.interface_width * self.config.grid.h();
        let (mut imax, mut jmax) = (0usize, 0usize);
        for j in 0..sy {
            let row = phi.data.slice(s![HALO + j, HALO..HALO + sx]);
            if let Some(i) = row.iter().rposition(|&v| v > support) {
                imax = imax.max(i + 1);
                jmax = j + 1;
            }
        }
        (imax + ar.band, jmax + ar.band)
    }

    /// One step on the active window (rebuilt first if the dense phase needs it).
    pub(crate) fn step_active(&mut self, ar: ActiveRegion) -> Result<StepInfo> {
        let (gx, gy) = (self.config.grid.nx, self.config.grid.ny);
        let round = |n: usize, full: usize| n.div_ceil(ar.align).saturating_mul(ar.align).min(full);
        let (need_x, need_y) = self.window_needed(ar);
        let rebuild = match self.window_size() {
            None => true,
            Some((wx, wy)) => {
                let near = |need: usize, w: usize, full: usize| w < full && need > w;
                let loose = |need: usize, w: usize, full: usize| 4 * round(need + ar.band, full) <= 3 * w;
                near(need_x, wx, gx) || near(need_y, wy, gy) || loose(need_x, wx, gx) || loose(need_y, wy, gy)
            }
        };
        if rebuild {
            self.sync_from_window();
            self.build_window(round(need_x + ar.band, gx).max(2), round(need_y + ar.band, gy).max(2), ar)?;
        } else if let (None, Some((wx, wy))) = (self.active_window(), self.restored_window) {
            // after a restore: the window the checkpointed run had, which it would have kept
            self.build_window(wx, wy, ar)?;
        }
        self.restored_window = None;
        let w = self.window.as_mut().expect("built above");
        w.time_to_land = self.time_to_land;
        let out = w.step_accepted();
        // the clock now; the fields when a call returns (`TwoPhaseModel::sync_from_window`)
        let w = self.window.take().expect("built above");
        copy_clock(&w, self);
        self.window = Some(w);
        self.window_ahead = true;
        out
    }

    /// Copies the window's state into this model's fields where they lag it: after a step
    /// ([`TwoPhaseModel::step`]), at the end of [`TwoPhaseModel::advance`], before a rebuild.
    pub(crate) fn sync_from_window(&mut self) {
        if self.window_ahead && self.window.is_some() {
            let (pool, exec) = (std::sync::Arc::clone(&self.pool), self.exec());
            pool.install(|| self.copy_from_window(exec));
        }
        self.window_ahead = false;
    }

    /// Builds the window of nxw × nyw cells from this model's state.
    fn build_window(&mut self, nxw: usize, nyw: usize, ar: ActiveRegion) -> Result<()> {
        if let Some((wx, wy)) = self.window_size() {
            if nxw < wx || nyw < wy {
                // shrink: the light phase outside the new window at rest
                for f in flow_state_mut(self).into_iter().take(6) {
                    zero_outside(f, nxw, nyw);
                }
            }
        }
        let cfg = &self.config;
        let g = &cfg.grid;
        let mut wc = cfg.clone();
        wc.grid = Grid::with_origin(nxw, nyw, g.x0, g.y0, nxw as f64 * g.dx, nyw as f64 * g.dy)?;
        wc.active_region = None;
        // the ambient light phase at rest: p_a(x) = p_top + c g·(x − x_top), c = ρ_f − ρ_ref,
        // x_top the mean centre of the domain's gauge cells (its top row from pressure_top_from)
        let c = cfg.light.expect("validated: two-phase").density - cfg.reference_density();
        let [gx, gy] = cfg.gravity;
        let xm = |from: usize, n: usize| 0.5 * (from + n) as f64 * g.dx;
        let (x_top, y_top) = (xm(cfg.pressure_top_from, g.nx), (g.ny as f64 - 0.5) * g.dy);
        // the window's gauge cells: the part of its top row beyond the band's inner edge (when
        // the window is narrower than the domain), the air farthest from the dense phase; their
        // mean is p_a there
        wc.pressure_top_from = if nxw < g.nx { nxw - ar.band.min(nxw) } else { 0 };
        let dx_top = xm(wc.pressure_top_from, nxw) - x_top;
        let dy_top = (nyw as f64 - g.ny as f64) * g.dy;
        wc.pressure_top_value = cfg.pressure_top_value + c * (gx * dx_top + gy * dy_top);
        let (open_right, open_top) = (ar.sides.right_open(), ar.sides.top_open());
        if open_right && nxw < g.nx {
            // open right side: outflow at p_a, its k-th face centre at (n_x^W dx, (k + ½) dy)
            let p0 = cfg.pressure_top_value + c * (gx * (nxw as f64 * g.dx - x_top) + gy * (0.5 * g.dy - y_top));
            wc.bc = wc.bc.with(Side::Right, VelocityBc::Outflow).with_outlet_pressure(Side::Right, p0, c * gy * g.dy);
            if open_top {
                wc.bc = wc.bc.with_backflow_stabilisation(Side::Right);
            }
        }
        if open_top && nyw < g.ny {
            // open top side: outflow at p_a, its k-th face centre at ((k + ½) dx, n_y^W dy)
            let p0 = cfg.pressure_top_value + c * (gx * (0.5 * g.dx - x_top) + gy * (nyw as f64 * g.dy - y_top));
            wc.bc = wc.bc.with(Side::Top, VelocityBc::Outflow).with_outlet_pressure(Side::Top, p0, c * gx * g.dx).with_backflow_stabilisation(Side::Top);
        }
        let mut w = TwoPhaseModel::new(wc)?;
        for (src, dst) in flow_state(self).into_iter().zip(flow_state_mut(&mut w)) {
            copy_block(src, dst);
        }
        if nyw < g.ny && !open_top {
            // the window's top side is a wall
            let vs = &mut w.v;
            vs.data.slice_mut(s![HALO + nyw, ..]).fill(0.0);
        }
        if nxw < g.nx && !open_right {
            let us = &mut w.u;
            us.data.slice_mut(s![.., HALO + nxw]).fill(0.0);
        }
        copy_flat(self.pressure_increment(), g.nx, w.pressure_increment_mut(), nxw);
        crop_room(self.pore.as_ref(), w.pore.as_mut());
        crop_room(self.rheology.as_ref(), w.rheology.as_mut());
        crop_room(self.levelset.vof.as_ref(), w.levelset.vof.as_mut());
        copy_clock(self, &mut w);
        self.window = Some(Box::new(w));
        Ok(())
    }

    /// Copies the window's state (and its last step's diagnostics) back into this model.
    /// The copies run on the model's threads (`exec`, inside its pool).
    fn copy_from_window(&mut self, exec: Exec) {
        let w = self.window.take().expect("a window");
        for (src, dst) in flow_state(&w).into_iter().zip(flow_state_mut(self)) {
            copy_back(src, dst, exec);
        }
        let nx = self.config.grid.nx;
        copy_flat(w.pressure_increment(), w.config.grid.nx, self.pressure_increment_mut(), nx);
        room_back(w.pore.as_ref(), self.pore.as_mut(), exec);
        room_back(w.rheology.as_ref(), self.rheology.as_mut(), exec);
        room_back(w.levelset.vof.as_ref(), self.levelset.vof.as_mut(), exec);
        room_back(Some(&w.properties), Some(&mut self.properties), exec);
        copy_clock(&w, self);
        self.properties.invalidate();
        self.pressure.density_changed();
        self.window = Some(w);
    }
}

/// The fields of the flow state a step reads and writes on the grid (order shared by the two
/// functions): u, v, their BDF2 history and convection at n − 1, p, Φ.
fn flow_state(m: &TwoPhaseModel) -> [&Field; 8] {
    [&m.u, &m.v, &m.u_prev, &m.v_prev, &m.conv_prev_u, &m.conv_prev_v, &m.p, &m.phi]
}

/// The clock (t, n, δt_{n−1}), the area the mass correction keeps and the last step's diagnostics.
fn copy_clock(src: &TwoPhaseModel, dst: &mut TwoPhaseModel) {
    dst.time = src.time;
    dst.step_count = src.step_count;
    dst.dt_prev = src.dt_prev;
    dst.reference_area = src.reference_area;
    dst.last = src.last;
    dst.dt_ceiling = src.dt_ceiling;
}

/// A room's state from the whole model's `src` into the window's `dst` (the block the window
/// covers).
fn crop_room<T: WindowState>(src: Option<&T>, dst: Option<&mut T>) {
    if let (Some(a), Some(b)) = (src, dst) {
        for (s, d) in a.state_fields().into_iter().zip(b.state_fields_mut()) {
            copy_block(s, d);
        }
        b.copy_other_state(a, false);
    }
}

/// A room's state and shown fields from the window's `win` back into the whole model's `full`.
fn room_back<T: WindowState>(win: Option<&T>, full: Option<&mut T>, exec: Exec) {
    if let (Some(a), Some(b)) = (win, full) {
        for (s, d) in a.state_fields().into_iter().zip(b.state_fields_mut()) {
            copy_back(s, d, exec);
        }
        for (s, d) in a.shown_fields().into_iter().zip(b.shown_fields_mut()) {
            copy_back(s, d, exec);
        }
        b.copy_other_state(a, true);
    }
}

fn flow_state_mut(m: &mut TwoPhaseModel) -> [&mut Field; 8] {
    [&mut m.u, &mut m.v, &mut m.u_prev, &mut m.v_prev, &mut m.conv_prev_u, &mut m.conv_prev_v, &mut m.p, &mut m.phi]
}
