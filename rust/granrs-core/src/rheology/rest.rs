//! The plastic tensor of a layer at rest ("lithostatic" initial stress).
//!
//! Equation: for a state at rest (u = 0) that does not vary along x, the x-momentum balance
//! (Aravena et al. eq. 10b with u = 0) reduces to
//!
//!   ∂_y(τ Σ_xy) + f_x = 0,   f_x = (ρ − ρ_ref) g_x − ∂_x(p + p_f),
//!
//! so that τ Σ_xy(y) = ∫_y^H f_x dy' (the shear stress of an infinite slope: ρ' g sin θ times the
//! depth in a uniform layer, Savage & Hutter 1989, *J. Fluid Mech.* 199). The rest state is
//! admissible for the plastic law iff |Σ| ≤ 1 everywhere (the Drucker–Prager criterion
//! |σ_dev| ≤ tan(α) p: tan θ ≤ tan α for a uniform layer on a slope θ).
//!
//! Why it is needed: the Picard iteration of eq. (12) starts from Σ^{n+1,0} = Σ^n and its fixed
//! point is Σ = P(Σ + r D + θ(Σ^n − Σ)). Started from Σ = 0, a "rigid" zone deforms at
//! D = θ(Σ − Σ^n)/r per step until Σ has built up: a layer that should stay at rest moves
//! (0.67 m/s after 0.2 s in `granrs validate fluidised-layer`, docs/validation.md). Starting from
//! the balancing Σ, the first Picard iterate already solves eq. (11) with ũ = 0.
//!
//! Discretisation: the discrete force of `PlasticState::add_force` on the u-face (i, j) is
//! [τ_n Σ_xy]_{j}^{j+1}/dy (Σ_xx = 0), and f_x is the predictor's right-hand side at rest
//! (ρ_u g_x − ρ_ref g_x − [p + p_f]_{i−1}^{i}/dx, `time_stepping/step.rs`). Node by node from the
//! top (τΣ_xy = 0 at the top nodes) T_j = T_{j+1} + dy f_x(i, j) and Σ_xy = T_j/τ_n, so the
//! discrete balance holds to round-off in every column (|T| below 1e-9 ρ g L_y, the round-off of
//! the pressure solve in the air, is taken as 0). Where |T|/τ_n > 1 the state cannot be at
//! rest: Σ_xy is clamped to ±1 there (the material yields) and the largest ratio is reported.
//! Boundary nodes whose Σ_xy is held at 0 (free-slip or Coulomb sides) carry nothing: on a
//! Coulomb base the wall friction builds up by its own iteration.

use super::plastic::node_held;
use crate::error::{Error, Result};
use crate::grid::HALO;
use crate::models::TwoPhaseModel;
use crate::projection::fill_pressure_ghosts;
use crate::time_stepping::step::pressure_gradient;

/// What [`TwoPhaseModel::balance_plastic_stress`] found.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RestStress {
    /// Largest |τΣ_xy| / τ needed for rest over the nodes (≤ 1: the state can stay at rest).
    pub max_ratio: f64,
    /// Node (i, j) of the largest ratio.
    pub node: (usize, usize),
    /// Nodes where the ratio exceeded 1 (Σ_xy clamped to ±1 there).
    pub clamped: usize,
    /// max over the v-faces of |[τΣ_xy]_i^{i+1}/dx| / max |ρ g|: 0 for a state uniform in x, the
    /// size of the y-force the construction leaves unbalanced otherwise.
    pub x_residual: f64,
}

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
        if self.config.rheology.sigma_location != super::SigmaLocation::Staggered {
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
        let (rho_u, grad_x) = (&wk.rho_u, &wk.gx);
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
