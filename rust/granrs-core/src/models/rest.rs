//! `TwoPhaseModel::balance_plastic_stress` (the state at rest, `rheology/rest.rs`).

use super::step::pressure_gradient;
use super::TwoPhaseModel;
use crate::error::{Error, Result};
use crate::grid::HALO;
use crate::projection::fill_pressure_ghosts;
use crate::rheology::plastic::node_held;
use crate::rheology::RestStress;

impl TwoPhaseModel {
    /// Sets Σ (and Σ^n) to the plastic tensor that holds the current state at rest, column by
    /// column (see the module header): Σ_xx = 0, Σ_xy = ∫ f_x / τ. Call it after the initial
    /// Φ, p_f and the balanced pressure (`initialise_pressure`) are set. Exact for a state
    /// uniform along x (a layer on a slope); for others, `x_residual` says how far from it.
    pub fn balance_plastic_stress(&mut self) -> Result<RestStress> {
        self.window = None;
        let exec = self.exec();
        if !self.rheology.as_ref().is_some_and(|r| r.has_plastic_tensor()) {
            return Err(Error::param(
                "rheology",
                self.config.rheology.law.name(),
                "a law with a yield stress treated by projection \
                 (Bingham, Drucker-Prager, mu(I) with treatment 'projection') for balance_plastic_stress",
            ));
        }
        if self.config.rheology.sigma_location != crate::rheology::SigmaLocation::Staggered {
            return Err(Error::param(
                "sigma_location",
                self.config.rheology.sigma_location.name(),
                "'staggered' for balance_plastic_stress (it builds Σ_xy at nodes)",
            ));
        }
        self.properties(exec);
        // τ at centres and nodes from the current p and Φ (δt does not enter τ)
        self.rheology_stage(1.0, exec)?;
        let cfg = &self.config;
        let grid = &cfg.grid;
        let gx = cfg.gravity[0];
        let rho_ref = cfg.reference_density();
        let wk = &mut self.work;
        // ∂_x(p + p_f) on the u-faces, as in the predictor
        fill_pressure_ghosts(&mut self.p, &cfg.bc);
        pressure_gradient(Some(&self.p), self.pore.as_mut(), &mut wk.ptot, &mut wk.gx, &mut wk.gy, grid, &cfg.bc, exec);
        let rs = self.rheology.as_mut().expect("checked above");
        let pl = &mut rs.plastic;
        pl.sigma_xx.fill(0.0);
        pl.sigma_xy.fill(0.0);
        let (nxn, nyn) = (pl.sigma_xy.nx, pl.sigma_xy.ny);
        let z = pl.zero_tangential();
        let (rho_u, grad_x) = (self.properties.density().0, &wk.gx);
        let mut out = RestStress::default();
        // stresses below this are the round-off of the pressure solve, not a weight to hold
        // (1e-9 of the full-height column's ρ g L_y)
        let rho_max = cfg.dense.density.max(cfg.light.map_or(0.0, |l| l.density));
        let g = cfg.gravity[0].hypot(cfg.gravity[1]);
        let floor = 1e-9 * rho_max * g * grid.dy * (nyn - 1) as f64;
        for i in 0..nxn {
            let mut t = 0.0;
            for j in (0..nyn).rev() {
                if j + 1 < nyn {
                    let k = rho_u.idx(i as isize, j as isize);
                    t += grid.dy * ((rho_u.slice()[k] - rho_ref) * gx - grad_x.slice()[k]);
                }
                let tau = pl.tau_n.at(i as isize, j as isize);
                if node_held(&z, i, j, nxn, nyn) {
                    continue;
                }
                let ratio = if t.abs() <= floor {
                    0.0
                } else if tau > 0.0 {
                    t.abs() / tau
                } else {
                    f64::INFINITY
                };
                if ratio > out.max_ratio {
                    out.max_ratio = ratio;
                    out.node = (i, j);
                }
                let s = if tau > 0.0 && t.abs() > floor {
                    if ratio > 1.0 {
                        out.clamped += 1;
                        t.signum()
                    } else {
                        t / tau
                    }
                } else {
                    0.0
                };
                pl.sigma_xy.set(i, j, s);
            }
        }
        pl.sigma_xx_n.assign(&pl.sigma_xx);
        pl.sigma_xy_n.assign(&pl.sigma_xy);
        // what the construction leaves in the y-balance where the state varies along x
        let (sn, tn) = (pl.sigma_xy.slice(), pl.tau_n.slice());
        let mut res = 0.0f64;
        let st = pl.sigma_xy.stride();
        for j in 0..nyn {
            for i in 0..nxn - 1 {
                let k = (j + HALO) * st + HALO + i;
                res = res.max((tn[k + 1] * sn[k + 1] - tn[k] * sn[k]).abs() / grid.dx);
            }
        }
        out.x_residual = if rho_max * g > 0.0 { res / (rho_max * g) } else { 0.0 };
        Ok(out)
    }
}
