//! Checkpoint and restart: the whole state a step reads, so that a restored model continues
//! bit for bit as the uninterrupted one would.
//!
//! The state of step n → n+1 is: u^n, v^n and the BDF2 history u^{n−1}, v^{n−1}, (u·∇u)^{n−1};
//! p^n and the last pressure increment δp^n (the warm start of the next projection); Φ^n and,
//! with `interface_transport = "clsvof"`, the volume fraction F^n; the
//! pore pressure p_f^n, p_f^{n−1} and its advection at n−1; the plastic tensor Σ^n and the
//! Coulomb wall directions s^n (the anchors of the Picard iteration, eq. 12); the clock t_n, n,
//! δt_{n−1}; the area the mass correction restores; with an active region, the window's size
//! (it grows and shrinks with a hysteresis, so it is not a function of the fields; a
//! checkpoint without it rebuilds the window from the dense phase's extent). Everything else (densities, viscosities,
//! yield stresses, r, solver coefficients) is rebuilt from these by the next step.
//! Fields are stored with their ghost layers, exactly as held.

use super::two_phase::TwoPhaseModel;
use crate::error::{Error, Result};
use crate::grid::{StateArrays, StateEntry};

/// The checkpoint entry of the active window's size (n_x^W, n_y^W); (0, 0) before the first step.
const WINDOW_ENTRY: &str = "active_window";

impl TwoPhaseModel {
    /// The model's state as named flat arrays (see the module docs).
    pub fn checkpoint(&self) -> Vec<StateEntry> {
        let mut out = Vec::new();
        self.checkpoint_into(&mut out);
        out
    }

    /// [`TwoPhaseModel::checkpoint`] into `out`, reusing its buffers when it already holds a
    /// checkpoint of this model (no allocation then: the snapshot of every step with retries).
    /// The copies run on the model's threads.
    pub fn checkpoint_into(&self, out: &mut Vec<StateEntry>) {
        let exec = self.exec();
        std::sync::Arc::clone(&self.pool).install(|| self.state_into(out, exec));
    }

    fn state_into(&self, out: &mut Vec<StateEntry>, exec: crate::exec::Exec) {
        let mut k = 0usize;
        let mut f = |name: &str, data: &[f64]| {
            match out.get_mut(k) {
                Some((n, d)) if n == name && d.len() == data.len() => exec.copy(d, data),
                Some(e) => *e = (name.to_string(), data.to_vec()),
                None => out.push((name.to_string(), data.to_vec())),
            }
            k += 1;
        };
        f("u", self.u.slice());
        f("v", self.v.slice());
        f("u_prev", self.u_prev.slice());
        f("v_prev", self.v_prev.slice());
        f("conv_prev_u", self.conv_prev_u.slice());
        f("conv_prev_v", self.conv_prev_v.slice());
        f("p", self.p.slice());
        f("phi", self.phi.slice());
        // the rooms' own state arrays
        if let Some(vof) = &self.levelset.vof {
            vof.visit_state(&mut f);
        }
        self.pressure.visit_state(&mut f);
        if let Some(pore) = &self.pore {
            pore.visit_state(&mut f);
        }
        if let Some(rs) = &self.rheology {
            rs.visit_state(&mut f);
        }
        f("time", &[self.time]);
        f("step_count", &[self.step_count as f64]);
        f("dt_prev", &[self.dt_prev.unwrap_or(f64::NAN)]);
        f("reference_area", &[self.reference_area]);
        if self.config.active_region.is_some() {
            // the window's size is state: it grows and shrinks with a hysteresis, so a window
            // rebuilt from the dense phase's extent alone can differ from the one the run had
            let (wx, wy) = self.window_size().unwrap_or((0, 0));
            f(WINDOW_ENTRY, &[wx as f64, wy as f64]);
        }
        out.truncate(k);
    }

    /// Restores a state exported by [`TwoPhaseModel::checkpoint`] from a model built with the same
    /// configuration. Every entry must be present with its length; nothing is changed otherwise.
    /// The energy budget starts again from the restored state.
    pub fn restore(&mut self, state: &[StateEntry]) -> Result<()> {
        self.restore_state(state)?;
        self.start_energy_budget();
        Ok(())
    }

    /// [`TwoPhaseModel::restore`] without restarting the energy budget (a rejected step is undone
    /// inside the budget's step).
    pub(crate) fn restore_state(&mut self, state: &[StateEntry]) -> Result<()> {
        let expected = self.checkpoint();
        for (name, data) in &expected {
            match state.iter().find(|(n, _)| n == name) {
                // a checkpoint without the window's size rebuilds the window from the dense phase
                None if name == WINDOW_ENTRY => {}
                None => return Err(Error::param("state", name, "a checkpoint of a model with the same configuration (entry missing)")),
                Some((_, d)) if d.len() != data.len() => {
                    return Err(Error::Shape { name: format!("checkpoint entry `{name}`"), got: vec![d.len()], expected: vec![data.len()] })
                }
                _ => {}
            }
        }
        if let Some((extra, _)) = state.iter().find(|(n, _)| !expected.iter().any(|(e, _)| e == n)) {
            return Err(Error::param("state", extra, "only entries of a model with the same configuration"));
        }
        let restored_window = match state.iter().find(|(n, _)| n == WINDOW_ENTRY) {
            Some((_, d)) if d[0] == 0.0 && d[1] == 0.0 => None,
            Some((_, d)) => {
                let (nx, ny) = (self.config.grid.nx as f64, self.config.grid.ny as f64);
                let size = |v: f64, n: f64| v >= 2.0 && v <= n && v.fract() == 0.0;
                if !(size(d[0], nx) && size(d[1], ny)) {
                    return Err(Error::param(WINDOW_ENTRY, format!("{:?}", d), &format!("(0, 0), or whole numbers of cells in [2, {nx}] × [2, {ny}]")));
                }
                Some((d[0] as usize, d[1] as usize))
            }
            None => None,
        };
        let get = |name: &str| -> &[f64] { &state.iter().find(|(n, _)| n == name).expect("checked above").1 };
        self.u.slice_mut().copy_from_slice(get("u"));
        self.v.slice_mut().copy_from_slice(get("v"));
        self.u_prev.slice_mut().copy_from_slice(get("u_prev"));
        self.v_prev.slice_mut().copy_from_slice(get("v_prev"));
        self.conv_prev_u.slice_mut().copy_from_slice(get("conv_prev_u"));
        self.conv_prev_v.slice_mut().copy_from_slice(get("conv_prev_v"));
        self.p.slice_mut().copy_from_slice(get("p"));
        self.phi.slice_mut().copy_from_slice(get("phi"));
        let mut put = |name: &str, data: &mut [f64]| data.copy_from_slice(get(name));
        if let Some(vof) = &mut self.levelset.vof {
            vof.visit_state_mut(&mut put);
        }
        self.pressure.visit_state_mut(&mut put);
        if let Some(pore) = &mut self.pore {
            pore.visit_state_mut(&mut put);
        }
        if let Some(rs) = &mut self.rheology {
            rs.visit_state_mut(&mut put);
        }
        self.time = get("time")[0];
        self.step_count = get("step_count")[0] as u64;
        let dt_prev = get("dt_prev")[0];
        self.dt_prev = if dt_prev.is_nan() { None } else { Some(dt_prev) };
        self.reference_area = get("reference_area")[0];
        self.properties.invalidate();
        self.pressure.density_changed();
        self.time_to_land = None;
        self.window = None;
        self.restored_window = restored_window;
        Ok(())
    }
}
