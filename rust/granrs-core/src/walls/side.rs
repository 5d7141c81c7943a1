//! Friction of the channel's side walls on a 2D flow (an optional term, not in Aravena et al.;
//! Jop, Forterre & Pouliquen 2005, "Crucial role of sidewalls in granular surface flows",
//! *J. Fluid Mech.* 541, 167–192; Taberlet et al. 2003, *Phys. Rev. Lett.* 91, 264301; Rousseau
//! et al. 2023, "Revisiting the role of friction coefficients in granular collapses",
//! *J. Fluid Mech.*, on side-wall friction in collapses in narrow channels).
//!
//! The paper's experiment runs in a channel W = 10 cm wide; its model is 2D and has no side
//! walls. Averaging the momentum balance across the width of a channel whose two vertical walls
//! (the planes z = 0 and z = W) rub on the granular phase with Coulomb friction tan(α_w) and a
//! normal stress equal to the pressure (Jop et al.'s isotropic closure) adds the body force
//!
//!   f = −(2/W) τ_w s,   τ_w = tan(α_w) (p − p_s)⁺ H_ε(Φ + sε),
//!   s = u/|u| where the material slides, |s| ≤ 1 where it sticks,
//!
//! which, like Σ and the base's s (eq. 9), is a projection: s = P(s + r_w u) for any r_w > 0, P
//! the projection on the unit disc of R². Picard update, in the loop of eq. (12):
//!
//!   s^{k+1} = P(s^k + r_w ũ^{k+1} + θ (s^n − s^k)).
//!
//! p⁺ and H_ε are those of the yield stress τ(Φ) (`rheology/stage.rs`, `RheologyState::prepare`): the pore pressure
//! relieves the side walls as it relieves the base.
//!
//! **Discretisation.** s_x lives on the u-faces, s_y on the v-faces, with τ_w from the two cells
//! beside the face. The pair is projected twice, as the staggered Σ is (`rheology/plastic.rs`):
//! on u-faces with s_y averaged from the four neighbouring v-faces, on v-faces with s_x averaged
//! from the four neighbouring u-faces; a rigid translation is exact (s_y = 0 everywhere).
//!
//! **Choice of r_w.** A unit change of s on one face changes the force there by (2/W) τ_w and the
//! face velocity by at most (2/W) τ_w / c (c = a₀ρ/δt, the predictor operator is ≥ c), so the
//! local r_w = (1 − θ) c / ((2/W) τ_w) keeps this part of the iteration contracting with ratio
//! 1 − θ (the w = 0 choice of the plastic r: each face its own response).
//!
//! The dissipation −∫ f·u = (2/W) ∫ τ_w s·u ≥ 0 enters the energy budget
//! (`diagnostics/energy.rs`) as `side_wall_work`.

use crate::exec::Exec;
use crate::grid::{Field, Grid, Location, HALO};
use crate::levelset::heaviside;
use crate::operators::for_each_interior_row;
// the plastic tensor's projection: the pair (Λ_xx, Λ_xy) with |Λ|² = Λ_xx² + Λ_xy² is the same
// Euclidean unit disc as (s_x, s_y)
use crate::plasticity::InterfaceYield;
use crate::plasticity::{unit_ball_scale, weighted_max_abs_diff};

/// The side walls of a channel (`RheologyConfig::side_walls`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SideWalls {
    /// Width W of the channel [m] (the paper's experiment: 0.10 m).
    pub width: f64,
    /// Friction angle α_w of the granular phase on the walls [degrees].
    pub friction_angle: f64,
}

/// Largest channel width accepted [m].
pub const MAX_CHANNEL_WIDTH: f64 = 1.0e3;

/// The friction state of the side walls: s, s^n, (2/W)τ_w and r_w on every face.
pub struct SideWallFriction {
    /// s_x on u-faces, s_y on v-faces (s^{n+1,k} during the iteration, s^n between steps).
    pub s_u: Field,
    pub s_v: Field,
    s_u_n: Field,
    s_v_n: Field,
    /// (2/W) τ_w on the faces [Pa m⁻¹].
    pub tau_u: Field,
    pub tau_v: Field,
    tau_max: f64,
    r_u: Field,
    r_v: Field,
    trial_u: Field,
    trial_v: Field,
    new_u: Field,
    new_v: Field,
}

#[inline]
fn base(f: &Field, j: isize) -> usize {
    ((j + HALO as isize) as usize) * f.stride() + HALO
}

impl SideWallFriction {
    /// s = 0 on `grid`.
    pub fn new(grid: &Grid) -> Self {
        let u = || Field::zeros(grid, Location::XFace);
        let v = || Field::zeros(grid, Location::YFace);
        SideWallFriction {
            s_u: u(),
            s_v: v(),
            s_u_n: u(),
            s_v_n: v(),
            tau_u: u(),
            tau_v: v(),
            tau_max: 0.0,
            r_u: u(),
            r_v: v(),
            trial_u: u(),
            trial_v: v(),
            new_u: u(),
            new_v: v(),
        }
    }

    /// Start of a step: s^n ← s.
    pub fn begin_step(&mut self) {
        self.s_u_n.assign(&self.s_u);
        self.s_v_n.assign(&self.s_v);
    }

    /// max (2/W)τ_w|s − s^n| / max (2/W)τ_w: how far s is from the anchor of eq. (12).
    pub fn anchor_distance(&self, exec: Exec) -> f64 {
        let w = |a: &Field, b: &Field, t: &Field| weighted_max_abs_diff(a, b, t, self.tau_max, exec);
        w(&self.s_u, &self.s_u_n, &self.tau_u).max(w(&self.s_v, &self.s_v_n, &self.tau_v))
    }

    /// Sets (2/W)τ_w and r_w on the faces from p (cell centres, ghosts filled), the surface
    /// pressure p_s, Φ (ghosts filled), the face densities and c = a₀ρ/δt. `walls` the channel,
    /// `eps` the interface half-width (None: one phase, H = 1 wherever Φ > 0 counts as granular).
    #[allow(clippy::too_many_arguments)]
    pub fn set_friction(
        &mut self,
        walls: SideWalls,
        p: &Field,
        p_s: f64,
        phi: &Field,
        eps: Option<f64>,
        iy: InterfaceYield,
        rho_u: &Field,
        rho_v: &Field,
        a0_over_dt: f64,
        theta: f64,
        exec: Exec,
    ) {
        let coeff = 2.0 * walls.friction_angle.to_radians().tan() / walls.width;
        let hv = move |f: f64| match eps {
            Some(e) => heaviside(iy.shift(f, e), e),
            None => {
                if f > 0.0 {
                    1.0
                } else {
                    0.0
                }
            }
        };
        let (ps, fs) = (p.slice(), phi.slice());
        // u-face (i, j) lies between cells (i − 1, j) and (i, j); v-face (i, j) between (i, j − 1) and (i, j)
        for (tau, r, rho, dx, dy) in [(&mut self.tau_u, &mut self.r_u, rho_u, 1usize, 0isize), (&mut self.tau_v, &mut self.r_v, rho_v, 0, 1)] {
            let n = tau.nx;
            let rs = rho.slice();
            for_each_interior_row(exec, tau, |j, row| {
                let ji = j as isize;
                let (b1, b0) = (base(p, ji), base(p, ji - dy));
                for i in 0..n {
                    let (k1, k0) = (b1 + i, b0 + i - dx);
                    let pf = 0.5 * (ps[k0] + ps[k1]) - p_s;
                    let h = hv(0.5 * (fs[k0] + fs[k1]));
                    row[HALO + i] = coeff * pf.max(0.0) * h;
                }
            });
            let (ts, n) = (tau.slice(), r.nx);
            for_each_interior_row(exec, r, |j, row| {
                let b = base(rho, j as isize);
                for i in 0..n {
                    let t = ts[b + i];
                    row[HALO + i] = if t > 0.0 { (1.0 - theta) * a0_over_dt * rs[b + i] / t } else { 0.0 };
                }
            });
        }
        self.tau_max = self.tau_u.max_abs().max(self.tau_v.max_abs());
    }

    /// Adds the force −(2/W)τ_w s to `out_u`, `out_v` on every face (the caller uses the unknown ones).
    pub fn add_force(&self, out_u: &mut Field, out_v: &mut Field, exec: Exec) {
        for (out, tau, s) in [(out_u, &self.tau_u, &self.s_u), (out_v, &self.tau_v, &self.s_v)] {
            let (ts, ss, n) = (tau.slice(), s.slice(), out.nx);
            for_each_interior_row(exec, out, |j, row| {
                let b = base(tau, j as isize);
                for i in 0..n {
                    row[HALO + i] -= ts[b + i] * ss[b + i];
                }
            });
        }
    }

    /// One Picard update s^{k+1} = P(s^k + r_w ũ + θ(s^n − s^k)) from the face velocities (the
    /// projection of each component with the other averaged from its four neighbours). s = 0
    /// where τ_w = 0. Returns max (2/W)τ_w|s^{k+1} − s^k| / max (2/W)τ_w.
    pub fn update(&mut self, u: &Field, v: &Field, theta: f64, exec: Exec) -> f64 {
        for (trial, s, s_n, tau, r, vel) in
            [(&mut self.trial_u, &self.s_u, &self.s_u_n, &self.tau_u, &self.r_u, u), (&mut self.trial_v, &self.s_v, &self.s_v_n, &self.tau_v, &self.r_v, v)]
        {
            let (ss, sn, ts, rs, vs, n) = (s.slice(), s_n.slice(), tau.slice(), r.slice(), vel.slice(), trial.nx);
            for_each_interior_row(exec, trial, |j, row| {
                let b = base(tau, j as isize);
                for i in 0..n {
                    let k = b + i;
                    row[HALO + i] = if ts[k] > 0.0 { ss[k] + rs[k] * vs[k] + theta * (sn[k] - ss[k]) } else { 0.0 };
                }
            });
        }
        let (tu, tv) = (&self.trial_u, &self.trial_v);
        let (tus, tvs) = (tu.slice(), tv.slice());
        // u-face (i, j): v-faces (i − 1, j), (i, j), (i − 1, j + 1), (i, j + 1); ghosts are 0
        {
            let n = self.new_u.nx;
            for_each_interior_row(exec, &mut self.new_u, |j, row| {
                let ji = j as isize;
                let (bu, bv0, bv1) = (base(tu, ji), base(tv, ji), base(tv, ji + 1));
                for i in 0..n {
                    let x = tus[bu + i];
                    let y = 0.25 * (tvs[bv0 + i - 1] + tvs[bv0 + i] + tvs[bv1 + i - 1] + tvs[bv1 + i]);
                    row[HALO + i] = x * unit_ball_scale(x, y);
                }
            });
        }
        // v-face (i, j): u-faces (i, j − 1), (i + 1, j − 1), (i, j), (i + 1, j)
        {
            let n = self.new_v.nx;
            for_each_interior_row(exec, &mut self.new_v, |j, row| {
                let ji = j as isize;
                let (bv, bu0, bu1) = (base(tv, ji), base(tu, ji - 1), base(tu, ji));
                for i in 0..n {
                    let y = tvs[bv + i];
                    let x = 0.25 * (tus[bu0 + i] + tus[bu0 + i + 1] + tus[bu1 + i] + tus[bu1 + i + 1]);
                    row[HALO + i] = y * unit_ball_scale(x, y);
                }
            });
        }
        let w = |a: &Field, b: &Field, t: &Field| weighted_max_abs_diff(a, b, t, self.tau_max, exec);
        let inc = w(&self.new_u, &self.s_u, &self.tau_u).max(w(&self.new_v, &self.s_v, &self.tau_v));
        self.s_u.assign(&self.new_u);
        self.s_v.assign(&self.new_v);
        inc
    }

    /// (2/W) Σ τ_w s·u h² over the faces [W m⁻¹]: the power the side walls dissipate (≥ 0 at the
    /// fixed point). `solved_u(i, j)`, `solved_v(i, j)` say which faces are unknowns.
    pub fn dissipation(&self, u: &Field, v: &Field, grid: &Grid, solved_u: impl Fn(usize, usize) -> bool, solved_v: impl Fn(usize, usize) -> bool) -> f64 {
        let mut sum = 0.0;
        for (tau, s, vel, solved) in [(&self.tau_u, &self.s_u, u, &solved_u as &dyn Fn(usize, usize) -> bool), (&self.tau_v, &self.s_v, v, &solved_v)] {
            for j in 0..tau.ny {
                for i in 0..tau.nx {
                    if solved(i, j) {
                        let (ii, jj) = (i as isize, j as isize);
                        sum += tau.at(ii, jj) * s.at(ii, jj) * vel.at(ii, jj);
                    }
                }
            }
        }
        sum * grid.dx * grid.dy
    }
}
