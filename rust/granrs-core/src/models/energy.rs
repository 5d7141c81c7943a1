//! The energy budget of the model (`diagnostics/energy.rs`: its terms and their discretisation).

use super::TwoPhaseModel;
use crate::diagnostics::{EnergyBudget, EnergyRates};
use crate::exec::Exec;
use crate::grid::{Field, Side, HALO};
use crate::levelset::heaviside;
use crate::operators::{fill_velocity_ghosts, periodic_pair, BcMode};
use crate::solvers::par::partials_len;

impl TwoPhaseModel {
    /// Kinetic energy ½ Σ ρ_face u² h² over the solved faces, and the potential energy
    /// Σ (ρ − ρ_light)(−g·x) h² over the cells [J m⁻¹].
    fn kinetic_potential(&self, partials: &mut Vec<[f64; 4]>) -> (f64, f64) {
        let g = &self.config.grid;
        let exec = self.exec();
        let (nx, ny) = (g.nx, g.ny);
        if partials.len() < partials_len(ny + 1) {
            partials.resize(partials_len(ny + 1), [0.0; 4]);
        }
        let (ps, us, vs) = (self.phi.slice(), self.u.slice(), self.v.slice());
        let (gx, gy) = (self.config.gravity[0], self.config.gravity[1]);
        let cfg = &self.config;
        let light = cfg.light.unwrap_or(cfg.dense).density;
        let eps = cfg.interface_width * g.h();
        let rho_c = |phi: f64| -> f64 {
            if cfg.free_surface {
                if phi > 0.0 {
                    cfg.dense.density - light
                } else {
                    0.0
                }
            } else if cfg.light.is_some() {
                (cfg.dense.density - light) * heaviside(phi, eps)
            } else {
                0.0
            }
        };
        let phi = &self.phi;
        let (u, v) = (&self.u, &self.v);
        let per = periodicity(self);
        let (nxu, nyv) = (if per.0 { nx - 1 } else { nx }, if per.1 { ny - 1 } else { ny });
        let s = self.pool.install(|| {
            exec.sum_rows_into::<4, _>(ny + 1, g.cells(), partials, |j| {
                let mut out = [0.0; 4];
                let ji = j as isize;
                if j < ny {
                    let (bp, bu) = (base(phi, ji), base(u, ji));
                    for i in 0..=nxu {
                        // Φ beside the u face (the wall faces take the inner cell twice)
                        let (a, b) = (ps[bp + i.saturating_sub(1)], ps[bp + i.min(nx - 1)]);
                        if cfg.face_is_solved(a, b) {
                            out[0] += 0.5 * cfg.face_density(a, b) * us[bu + i] * us[bu + i];
                        }
                    }
                    let y = g.yc(ji);
                    for i in 0..nx {
                        out[1] += rho_c(ps[bp + i]) * (-gx * g.xc(i as isize) - gy * y);
                    }
                }
                let (b0, b1, bv) = (base(phi, (ji - 1).max(0)), base(phi, ji.min(ny as isize - 1)), base(v, ji));
                for i in 0..if j <= nyv { nx } else { 0 } {
                    let (a, b) = (ps[b0 + i], ps[b1 + i]);
                    if cfg.face_is_solved(a, b) {
                        out[0] += 0.5 * cfg.face_density(a, b) * vs[bv + i] * vs[bv + i];
                    }
                }
                out
            })
        });
        let area = g.dx * g.dy;
        (s[0] * area, s[1] * area)
    }

    /// The rates of the budget at the current state (see the module header); fills the velocity
    /// ghosts first.
    fn energy_rates(&mut self, partials: &mut Vec<[f64; 4]>) -> EnergyRates {
        let g = self.config.grid.clone();
        let exec: Exec = self.exec();
        let (nx, ny) = (g.nx, g.ny);
        fill_velocity_ghosts(&mut self.u, &mut self.v, &self.config.bc, &g, BcMode::Full);
        if partials.len() < partials_len(ny + 1) {
            partials.resize(partials_len(ny + 1), [0.0; 4]);
        }
        let (gx, gy) = (self.config.gravity[0], self.config.gravity[1]);
        let rho_ref = self.config.reference_density();
        let free_surface = self.config.free_surface;
        let (idx, idy) = (1.0 / g.dx, 1.0 / g.dy);
        let (u, v, phi) = (&self.u, &self.v, &self.phi);
        let (us, vs, ps) = (u.slice(), v.slice(), phi.slice());
        let (eta_c, eta_n) = self.properties.viscosity();
        let (ec, en) = (eta_c.slice(), eta_n.slice());
        let plastic = self.rheology.as_ref().map(|r| (&r.plastic.tau_c, &r.plastic.tau_n, &r.plastic.sigma_xx, &r.plastic.sigma_xy));
        // the face densities of the step just taken (stage 3 of `step.rs`; `start_energy_budget`
        // computes them for the initial state)
        let (rho_u, rho_v) = self.properties.density();
        let (ru, rv) = (rho_u.slice(), rho_v.slice());
        let cfg = &self.config;
        let per = periodicity(self);
        let (nxu, nyv) = (if per.0 { nx - 1 } else { nx }, if per.1 { ny - 1 } else { ny });
        // rows 0..=ny: centres and u faces of row j < ny, v faces and nodes of row j. Each row's
        // terms are made by vectorised kernels a chunk at a time and added in the order of the
        // faces, cells and nodes (the budget's bits do not depend on the chunks).
        let s = self.pool.install(|| {
            exec.sum_rows_into::<4, _>(ny + 1, g.cells(), partials, |j| {
                let mut out = [0.0; 4]; // gravity, plastic, plastic negative, viscous
                let ji = j as isize;
                let (mut t, mut w, mut m) = ([0.0; RATE_CHUNK], [0.0; RATE_CHUNK], [0.0; RATE_CHUNK]);
                if j < ny {
                    let (bp, bu, bv0, bv1) = (base(phi, ji), base(u, ji), base(v, ji), base(v, ji + 1));
                    let bru = base(rho_u, ji);
                    for c0 in (0..=nxu).step_by(RATE_CHUNK) {
                        let n = RATE_CHUNK.min(nxu + 1 - c0);
                        gravity_terms(&mut t[..n], &ru[bru + c0..bru + c0 + n], &us[bu + c0..bu + c0 + n], rho_ref, gx);
                        for (k, tk) in t[..n].iter().enumerate() {
                            let i = c0 + k;
                            if !free_surface || cfg.face_is_solved(ps[bp + i.saturating_sub(1)], ps[bp + i.min(nx - 1)]) {
                                out[0] += tk;
                            }
                        }
                    }
                    let bc = base(eta_c, ji);
                    let plastic_row = plastic.map(|(tau_c, _, sxx, _)| (&tau_c.slice()[base(tau_c, ji)..], &sxx.slice()[base(sxx, ji)..]));
                    for c0 in (0..nx).step_by(RATE_CHUNK) {
                        let n = RATE_CHUNK.min(nx - c0);
                        let (ue, uw) = (&us[bu + c0 + 1..bu + c0 + 1 + n], &us[bu + c0..bu + c0 + n]);
                        let (vn, vs_) = (&vs[bv1 + c0..bv1 + c0 + n], &vs[bv0 + c0..bv0 + c0 + n]);
                        let plastic_chunk = plastic_row.map(|(tc, sxx)| (&tc[c0..c0 + n], &sxx[c0..c0 + n]));
                        cell_terms(&mut t[..n], &mut w[..n], &mut m[..n], ue, uw, vn, vs_, &ec[bc + c0..bc + c0 + n], plastic_chunk, idx, idy);
                        // a cell is skipped where Φ ≤ 0 (a NaN Φ is not skipped)
                        let solved = |k: usize| ps[bp + c0 + k] > 0.0 || ps[bp + c0 + k].is_nan();
                        add_terms(&mut out, &t[..n], plastic.is_some().then_some((&w[..n], &m[..n])), !free_surface, solved);
                    }
                }
                let (b0, b1, bv) = (base(phi, (ji - 1).max(0)), base(phi, ji.min(ny as isize - 1)), base(v, ji));
                let brv = base(rho_v, ji);
                let nv = if j <= nyv { nx } else { 0 };
                for c0 in (0..nv).step_by(RATE_CHUNK) {
                    let n = RATE_CHUNK.min(nv - c0);
                    gravity_terms(&mut t[..n], &rv[brv + c0..brv + c0 + n], &vs[bv + c0..bv + c0 + n], rho_ref, gy);
                    for (k, tk) in t[..n].iter().enumerate() {
                        if !free_surface || cfg.face_is_solved(ps[b0 + c0 + k], ps[b1 + c0 + k]) {
                            out[0] += tk;
                        }
                    }
                }
                // nodes (i, j), i = 0..=nx: D_xy from the faces around the node (ghosts at walls)
                let (bu0, bu1, bvn, bn) = (base(u, ji - 1), base(u, ji), base(v, ji), base(eta_n, ji));
                let plastic_row = plastic.map(|(_, tau_n, _, sxy)| (&tau_n.slice()[base(tau_n, ji)..], &sxy.slice()[base(sxy, ji)..]));
                // an air node (free surface): its Φ (the mean of its four cells, as
                // `cell_to_node` gives the node viscosity) ≤ 0
                let air_node = |i: usize| {
                    let c = |ii: isize, jj: isize| ps[base(phi, jj.clamp(0, ny as isize - 1)) + ii.clamp(0, nx as isize - 1) as usize];
                    let (ii, jj) = (i as isize, ji);
                    c(ii - 1, jj - 1) + c(ii, jj - 1) + c(ii - 1, jj) + c(ii, jj) <= 0.0
                };
                let wy = node_weight(1, j, nx, ny, per);
                for c0 in (0..=nx).step_by(RATE_CHUNK) {
                    let n = RATE_CHUNK.min(nx + 1 - c0);
                    let (un, us_) = (&us[bu1 + c0..bu1 + c0 + n], &us[bu0 + c0..bu0 + c0 + n]);
                    // v at i and i − 1 (the ghost left of the row for i = 0)
                    let (ve, vw) = (&vs[bvn + c0..bvn + c0 + n], &vs[bvn + c0 - 1..bvn + c0 - 1 + n]);
                    let plastic_chunk = plastic_row.map(|(tn, sxy)| (&tn[c0..c0 + n], &sxy[c0..c0 + n]));
                    node_terms(&mut t[..n], &mut w[..n], &mut m[..n], un, us_, ve, vw, &en[bn + c0..bn + c0 + n], plastic_chunk, wy, idx, idy);
                    // the end nodes' own weight, by the same expressions
                    for k in [0, n - 1] {
                        let i = c0 + k;
                        if i == 0 || i == nx {
                            let wgt = node_weight(i, j, nx, ny, per);
                            let one = k..k + 1;
                            let p1 = plastic_chunk.map(|(tn, sxy)| (&tn[one.clone()], &sxy[one.clone()]));
                            let (t1, w1, m1) = (&mut t[one.clone()], &mut w[one.clone()], &mut m[one.clone()]);
                            node_terms(
                                t1,
                                w1,
                                m1,
                                &un[one.clone()],
                                &us_[one.clone()],
                                &ve[one.clone()],
                                &vw[one.clone()],
                                &en[bn + i..bn + i + 1],
                                p1,
                                wgt,
                                idx,
                                idy,
                            );
                        }
                    }
                    let solved = |k: usize| !air_node(c0 + k);
                    add_terms(&mut out, &t[..n], plastic.is_some().then_some((&w[..n], &m[..n])), !free_surface, solved);
                }
                out
            })
        });
        let area = g.dx * g.dy;
        let mut wall = [0.0; 4];
        if let Some(r) = self.rheology.as_ref() {
            for (k, side) in Side::ALL.iter().enumerate() {
                if let Some((sdir, tau_b)) = r.walls.side(*side) {
                    let mut p = 0.0;
                    // s and τ_b run along the side's tangential faces (the row beside the wall)
                    for f in 0..sdir.len() {
                        let fi = f as isize;
                        let (ut, len) = match side {
                            Side::Bottom => (self.u.at(fi, 0), g.dx),
                            Side::Top => (self.u.at(fi, ny as isize - 1), g.dx),
                            Side::Left => (self.v.at(0, fi), g.dy),
                            Side::Right => (self.v.at(nx as isize - 1, fi), g.dy),
                        };
                        p -= tau_b[f] * sdir[f] * ut * len;
                    }
                    wall[k] = p;
                }
            }
        }
        let side_walls = self
            .rheology
            .as_ref()
            .and_then(|r| r.side_walls.as_ref())
            .map_or(0.0, |sw| sw.dissipation(&self.u, &self.v, &g, |i, _| !(per.0 && i == nx), |_, j| !(per.1 && j == ny)));
        EnergyRates { gravity: s[0] * area, plastic: s[1] * area, plastic_negative: s[2] * area, viscous: s[3] * area, wall, side_walls }
    }

    /// Adds the step just taken (δt `dt`) to the energy ledger (called by `step` after an
    /// accepted step; with an active region the window's forces are the step's).
    pub(crate) fn account_energy(&mut self, dt: f64) {
        let mut ledger = std::mem::take(&mut self.energy);
        let mut partials = std::mem::take(&mut ledger.partials);
        let rates = match self.window.as_deref_mut() {
            Some(w) => w.energy_rates(&mut partials),
            None => self.energy_rates(&mut partials),
        };
        let l = ledger.last;
        ledger.gravity_work += 0.5 * dt * (l.gravity + rates.gravity);
        ledger.plastic_work += 0.5 * dt * (l.plastic + rates.plastic);
        ledger.plastic_negative_work += 0.5 * dt * (l.plastic_negative + rates.plastic_negative);
        ledger.viscous_work += 0.5 * dt * (l.viscous + rates.viscous);
        for k in 0..4 {
            ledger.wall_work[k] += 0.5 * dt * (l.wall[k] + rates.wall[k]);
        }
        ledger.side_wall_work += 0.5 * dt * (l.side_walls + rates.side_walls);
        ledger.last = rates;
        ledger.partials = partials;
        self.energy = ledger;
    }

    /// Starts the budget from the current state (kinetic and potential energy, and the rates
    /// that open the first step's trapezoid): called when the state is set from outside.
    pub(crate) fn start_energy_budget(&mut self) {
        let mut ledger = std::mem::take(&mut self.energy);
        ledger.reset();
        let mut partials = std::mem::take(&mut ledger.partials);
        let (ek, ep) = self.kinetic_potential(&mut partials);
        // the rates of the initial state open the first trapezoid (a state set in motion from
        // outside, like a vortex, dissipates from t = 0)
        let exec = self.exec();
        self.properties(exec);
        ledger.last = self.energy_rates(&mut partials);
        ledger.partials = partials;
        ledger.kinetic_initial = ek;
        ledger.potential_initial = ep;
        self.energy = ledger;
    }

    /// The mechanical energy budget since the state was last set (module [`crate::diagnostics::energy`]).
    pub fn energy_budget(&self) -> EnergyBudget {
        let l = &self.energy;
        let mut partials = Vec::new();
        let (ek, ep) = self.kinetic_potential(&mut partials);
        let wall: f64 = l.wall_work.iter().sum();
        EnergyBudget {
            kinetic: ek,
            kinetic_initial: l.kinetic_initial,
            potential: ep,
            potential_initial: l.potential_initial,
            gravity_work: l.gravity_work,
            plastic_work: l.plastic_work,
            plastic_negative_work: l.plastic_negative_work,
            viscous_work: l.viscous_work,
            wall_work: l.wall_work,
            side_wall_work: l.side_wall_work,
            residual: ek - l.kinetic_initial - l.gravity_work + l.viscous_work + l.plastic_work + wall + l.side_wall_work,
            rates: l.last,
        }
    }
}

/// Adds a chunk's terms in order: `t` to the viscous power (out[3]) and, with the plastic terms,
/// `w` and `m` to out[1] and out[2], for every cell or node (`all`) or for those where `solved`.
#[inline(always)]
fn add_terms(out: &mut [f64; 4], t: &[f64], plastic: Option<(&[f64], &[f64])>, all: bool, solved: impl Fn(usize) -> bool) {
    match plastic {
        Some((w, m)) => {
            for k in 0..t.len() {
                if all || solved(k) {
                    out[3] += t[k];
                    out[1] += w[k];
                    out[2] += m[k];
                }
            }
        }
        None => {
            for (k, tk) in t.iter().enumerate() {
                if all || solved(k) {
                    out[3] += tk;
                }
            }
        }
    }
}

/// Faces, cells or nodes of a row whose terms of the rates are made in one call of the kernels
/// below (three stack buffers of 2 KiB).
const RATE_CHUNK: usize = 256;

crate::multiversion! {
    /// Gravity's power on a row of faces: t = (ρ − ρ_ref) g u.
    fn gravity_terms / gravity_terms_base(t: &mut [f64], rho: &[f64], vel: &[f64], rho_ref: f64, g: f64) {
        let n = t.len();
        let (rho, vel) = (&rho[..n], &vel[..n]);
        for k in 0..n {
            t[k] = (rho[k] - rho_ref) * g * vel[k];
        }
    }
}

crate::multiversion! {
    /// A row of cells: the viscous power 2η (D_xx² + D_yy²) in `t`, and with the plastic stress
    /// (τ, Σ_xx) its power w = τ Σ_xx (D_xx − D_yy) and min(w, 0) in `w`, `m`; D_xx = (u_e −
    /// u_w)/dx, D_yy = (v_n − v_s)/dy.
    #[allow(clippy::too_many_arguments)]
    fn cell_terms / cell_terms_base(t: &mut [f64], w: &mut [f64], m: &mut [f64], ue: &[f64], uw: &[f64], vn: &[f64], vs: &[f64], eta: &[f64], plastic: Option<(&[f64], &[f64])>, idx: f64, idy: f64) {
        let n = t.len();
        let (ue, uw, vn, vs, eta) = (&ue[..n], &uw[..n], &vn[..n], &vs[..n], &eta[..n]);
        for k in 0..n {
            let dxx = (ue[k] - uw[k]) * idx;
            let dyy = (vn[k] - vs[k]) * idy;
            t[k] = 2.0 * eta[k] * (dxx * dxx + dyy * dyy);
        }
        if let Some((tau, sxx)) = plastic {
            let (w, m, tau, sxx) = (&mut w[..n], &mut m[..n], &tau[..n], &sxx[..n]);
            for k in 0..n {
                let dxx = (ue[k] - uw[k]) * idx;
                let dyy = (vn[k] - vs[k]) * idy;
                w[k] = tau[k] * sxx[k] * (dxx - dyy);
                m[k] = w[k].min(0.0);
            }
        }
    }
}

crate::multiversion! {
    /// A row of nodes with weight `wgt`: the viscous power wgt·4η D_xy² in `t`, and with the
    /// plastic stress (τ, Σ_xy) w = wgt·τ·2Σ_xy D_xy and min(w, 0) in `w`, `m`; D_xy = ½((u_n −
    /// u_s)/dy + (v_e − v_w)/dx).
    #[allow(clippy::too_many_arguments)]
    fn node_terms / node_terms_base(t: &mut [f64], w: &mut [f64], m: &mut [f64], un: &[f64], us: &[f64], ve: &[f64], vw: &[f64], eta: &[f64], plastic: Option<(&[f64], &[f64])>, wgt: f64, idx: f64, idy: f64) {
        let n = t.len();
        let (un, us, ve, vw, eta) = (&un[..n], &us[..n], &ve[..n], &vw[..n], &eta[..n]);
        for k in 0..n {
            let dxy = 0.5 * ((un[k] - us[k]) * idy + (ve[k] - vw[k]) * idx);
            t[k] = wgt * 4.0 * eta[k] * dxy * dxy;
        }
        if let Some((tau, sxy)) = plastic {
            let (w, m, tau, sxy) = (&mut w[..n], &mut m[..n], &tau[..n], &sxy[..n]);
            for k in 0..n {
                let dxy = 0.5 * ((un[k] - us[k]) * idy + (ve[k] - vw[k]) * idx);
                w[k] = wgt * tau[k] * 2.0 * sxy[k] * dxy;
                m[k] = w[k].min(0.0);
            }
        }
    }
}

#[inline]
fn base(f: &Field, j: isize) -> usize {
    ((j + HALO as isize) as usize) * f.stride() + HALO
}

/// Node weight for the summation by parts: ½ on a wall row or column (¼ at a corner); between
/// two periodic (fully developed) sides the last column (row) is the first one again and weighs 0.
#[inline]
fn node_weight(i: usize, j: usize, nx: usize, ny: usize, per: (bool, bool)) -> f64 {
    let wx = if per.0 {
        if i == nx {
            0.0
        } else {
            1.0
        }
    } else if i == 0 || i == nx {
        0.5
    } else {
        1.0
    };
    let wy = if per.1 {
        if j == ny {
            0.0
        } else {
            1.0
        }
    } else if j == 0 || j == ny {
        0.5
    } else {
        1.0
    };
    wx * wy
}

/// Whether the x and y directions are periodic (a fully developed pair of sides), in which case
/// face nx (ny) is face 0 again and is not counted twice.
fn periodicity(model: &TwoPhaseModel) -> (bool, bool) {
    let bc = &model.config.bc;
    (periodic_pair(bc.get(Side::Left), bc.get(Side::Right)), periodic_pair(bc.get(Side::Bottom), bc.get(Side::Top)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bits(v: &[f64]) -> Vec<u64> {
        v.iter().map(|x| x.to_bits()).collect()
    }

    /// Both copies of the term kernels give the expressions of the budget value by value (a
    /// NaN plastic power gives min(w, 0) = 0, as `f64::min` does).
    #[test]
    fn the_rate_kernels_are_the_budget_terms_value_by_value() {
        let n = 37;
        let wave = |k: usize, a: f64| (a * k as f64).sin() * 10f64.powi((k % 5) as i32 - 2);
        let col = |a: f64| -> Vec<f64> { (0..n).map(|k| wave(k, a)).collect() };
        let (a, b, c, d, eta, tau) = (col(0.7), col(1.3), col(2.1), col(0.4), col(0.9).iter().map(|x| x.abs()).collect::<Vec<_>>(), col(1.7));
        let mut s = col(2.9);
        s[5] = f64::NAN;
        let (idx, idy, wgt) = (71.3, 64.0, 0.5);
        let mut want = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        for k in 0..n {
            want.0[k] = (a[k] - 1.2) * -9.81 * b[k];
            let dxx = (a[k] - b[k]) * idx;
            let dyy = (c[k] - d[k]) * idy;
            want.1[k] = 2.0 * eta[k] * (dxx * dxx + dyy * dyy);
            want.2[k] = tau[k] * s[k] * (dxx - dyy);
            want.3[k] = want.2[k].min(0.0);
            let dxy = 0.5 * ((a[k] - b[k]) * idy + (c[k] - d[k]) * idx);
            want.4[k] = wgt * 4.0 * eta[k] * dxy * dxy;
            want.5[k] = wgt * tau[k] * 2.0 * s[k] * dxy;
            want.6[k] = want.5[k].min(0.0);
        }
        assert_eq!(want.3[5], 0.0);
        let (mut t, mut w, mut m) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        for vectorised in [true, false] {
            let gravity = if vectorised { gravity_terms } else { gravity_terms_base };
            gravity(&mut t, &a, &b, 1.2, -9.81);
            assert_eq!(bits(&t), bits(&want.0));
            let cells = if vectorised { cell_terms } else { cell_terms_base };
            cells(&mut t, &mut w, &mut m, &a, &b, &c, &d, &eta, Some((&tau, &s)), idx, idy);
            assert_eq!((bits(&t), bits(&w), bits(&m)), (bits(&want.1), bits(&want.2), bits(&want.3)));
            let nodes = if vectorised { node_terms } else { node_terms_base };
            nodes(&mut t, &mut w, &mut m, &a, &b, &c, &d, &eta, Some((&tau, &s)), wgt, idx, idy);
            assert_eq!((bits(&t), bits(&w), bits(&m)), (bits(&want.4), bits(&want.5), bits(&want.6)));
        }
    }
}
