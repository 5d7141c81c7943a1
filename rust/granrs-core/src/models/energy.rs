//! The energy budget of the model (`diagnostics/energy.rs`: its terms and their discretisation).

use super::TwoPhaseModel;
use crate::diagnostics::{EnergyBudget, EnergyRates};
use crate::exec::Exec;
use crate::grid::{Field, Side, HALO};
use crate::levelset::heaviside;
use crate::operators::{fill_velocity_ghosts, periodic_pair, BcMode};
use crate::solvers::par::{partials_len, sum_rows};

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
            sum_rows::<4, _>(exec, ny + 1, g.cells(), partials, |j| {
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
        // rows 0..=ny: centres and u faces of row j < ny, v faces and nodes of row j
        let s = self.pool.install(|| {
            sum_rows::<4, _>(exec, ny + 1, g.cells(), partials, |j| {
                let mut out = [0.0; 4]; // gravity, plastic, plastic negative, viscous
                let ji = j as isize;
                if j < ny {
                    let (bp, bu, bv0, bv1) = (base(phi, ji), base(u, ji), base(v, ji), base(v, ji + 1));
                    let bru = base(rho_u, ji);
                    for i in 0..=nxu {
                        if cfg.face_is_solved(ps[bp + i.saturating_sub(1)], ps[bp + i.min(nx - 1)]) {
                            out[0] += (ru[bru + i] - rho_ref) * gx * us[bu + i];
                        }
                    }
                    let bc = base(eta_c, ji);
                    for i in 0..nx {
                        if free_surface && ps[bp + i] <= 0.0 {
                            continue;
                        }
                        let dxx = (us[bu + i + 1] - us[bu + i]) * idx;
                        let dyy = (vs[bv1 + i] - vs[bv0 + i]) * idy;
                        out[3] += 2.0 * ec[bc + i] * (dxx * dxx + dyy * dyy);
                        if let Some((tau_c, _, sxx, _)) = plastic {
                            let k = base(tau_c, ji) + i;
                            let w = tau_c.slice()[k] * sxx.slice()[base(sxx, ji) + i] * (dxx - dyy);
                            out[1] += w;
                            out[2] += w.min(0.0);
                        }
                    }
                }
                let (b0, b1, bv) = (base(phi, (ji - 1).max(0)), base(phi, ji.min(ny as isize - 1)), base(v, ji));
                let brv = base(rho_v, ji);
                for i in 0..if j <= nyv { nx } else { 0 } {
                    if cfg.face_is_solved(ps[b0 + i], ps[b1 + i]) {
                        out[0] += (rv[brv + i] - rho_ref) * gy * vs[bv + i];
                    }
                }
                // nodes (i, j), i = 0..=nx: D_xy from the faces around the node (ghosts at walls)
                let (bu0, bu1, bvn, bn) = (base(u, ji - 1), base(u, ji), base(v, ji), base(eta_n, ji));
                for i in 0..=nx {
                    if free_surface {
                        // an air node: its Φ (the mean of its four cells, as `cell_to_node` gives the
                        // node viscosity) ≤ 0
                        let c = |ii: isize, jj: isize| ps[base(phi, jj.clamp(0, ny as isize - 1)) + ii.clamp(0, nx as isize - 1) as usize];
                        let (ii, jj) = (i as isize, ji);
                        if c(ii - 1, jj - 1) + c(ii, jj - 1) + c(ii - 1, jj) + c(ii, jj) <= 0.0 {
                            continue;
                        }
                    }
                    let dxy = 0.5 * ((us[bu1 + i] - us[bu0 + i]) * idy + (vs[bvn + i] - vs[bvn + i - 1]) * idx);
                    let wgt = node_weight(i, j, nx, ny, per);
                    out[3] += wgt * 4.0 * en[bn + i] * dxy * dxy;
                    if let Some((_, tau_n, _, sxy)) = plastic {
                        let w = wgt * tau_n.slice()[base(tau_n, ji) + i] * 2.0 * sxy.slice()[base(sxy, ji) + i] * dxy;
                        out[1] += w;
                        out[2] += w.min(0.0);
                    }
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
