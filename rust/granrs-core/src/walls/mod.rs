//! Coulomb friction walls (Aravena et al. eq. 8–9, 10e and the wall part of eq. 12; Ionescu,
//! Mangeney, Bouchut & Roche 2015, *J. Non-Newton. Fluid Mech.* 219, for the projection form).
//!
//! On a side with `VelocityBc::Coulomb` the normal velocity vanishes and the granular phase feels
//! the tangential stress
//!
//!   σ_t = τ_b s,   s = P_b(s − r_b u_t)   (r_b > 0),   τ_b(Φ) = tan(α_b) (−σ_n)⁺ H_ε(Φ),
//!
//! (H_ε(Φ + sε) with the shift s of [`crate::rheology::InterfaceYield`]),
//!
//! where P_b clamps to [−1, 1] (the unit ball of the 1D tangent space): s = −u_t/|u_t| while the
//! material slides, |s| ≤ 1 when it sticks. Picard update, in the same loop as Σ (eq. 12):
//!
//!   s^{k+1} = P_b(s^k − r_b ũ_t^{k+1} + θ (s^n − s^k)).
//!
//! **Discretisation.** The tangential velocity row next to the wall (u on the bottom and top, v
//! on the left and right) sees a free-slip ghost (no viscous or plastic flux through the wall:
//! Σ_xy is held at 0 on the wall nodes) and the wall flux τ_b s / h_n as a force per unit volume
//! (h_n the cell size normal to the wall); u_t is that row's velocity, half a cell from the wall.
//! The normal stress is taken as −σ_n = p (or p − T_nn, [`crate::rheology::WallNormalStress`]), linearly extrapolated to the wall from the two
//! adjacent cells (p_wall = 1.5 p₀ − 0.5 p₁, exact for a hydrostatic pressure; the paper takes p
//! "from the adjacent cell", which is first-order: its O(h/H) error on the friction would show as
//! a 2–3 % error in the sliding-block acceleration at 32 cells), and Φ likewise.
//!
//! **Choice of r_b.** A unit change of s changes the force on one face by τ_b/h_n, and the face
//! velocity by at most τ_b/(h_n c) (c = a₀ρ/δt: the predictor operator is ≥ c, and a sliding
//! block's translation mode has no viscous resistance). The default r_b = (1 − θ)/max(τ_b/(h_n c))
//! keeps the wall part of the iteration contracting with ratio 1 − θ
//! ([`WallR::Single`]). A face whose τ_b is a small share of the largest (the thin tip of a
//! deposit, where p and H_ε are small) then moves s by r_b u_t and its own velocity by only
//! (1 − θ)(τ_b/max τ_b) u_t per iteration: it contracts with ratio 1 − (1 − θ)τ_b/max τ_b, and
//! its increment, weighted by τ_b/max τ_b, passes the test while it still slides.
//!
//! [`WallR::Local`] gives each face its own bound, r_b = (1 − θ) h_n c/τ_b. With the faces' map
//! s ↦ s − R G T s (R = diag r_b, T = diag τ_b/h_n, G the wall rows' block of A⁻¹ ≤ diag 1/c
//! since A ≥ diag c), the eigenvalues of R G T are those of (RT)^{1/2} G (RT)^{1/2} ≤
//! diag(r_b τ_b/(h_n c)) = 1 − θ: the same contraction bound, now reached by every face. A stuck
//! face's increment τ_b|Δs|/max τ_b = (1 − θ) h_n c |u_t|/max τ_b is then the same multiple of
//! its slip on every face, and the relaxed fixed point's slip θ(s^n − s)/r_b on a stuck face
//! (the proximal anchor's) is smallest where τ_b is. The fixed point of the unrelaxed law
//! (θ = 0) does not depend on r_b.
//!
//! The loops here run over one row of faces per side (O(nx + ny) work) and are serial.

pub mod side;

use crate::grid::{BoundaryConditions, Field, Grid, Side, VelocityBc};
use crate::levelset::heaviside;
use crate::operators::unknown_face_range;
use crate::plasticity::InterfaceYield;
use std::ops::Range;

/// The normal stress T_xx = 2η D_xx(u) + τ Σ_xx of the granular phase at a cell centre, for
/// the wall friction of [`crate::rheology::WallNormalStress::Total`]; `plastic` (τ, Σ_xx) None
/// without a plastic tensor.
pub struct NormalStress<'a> {
    pub u: &'a Field,
    pub eta_c: &'a Field,
    pub plastic: Option<(&'a Field, &'a Field)>,
    pub dx: f64,
}

impl NormalStress<'_> {
    /// T_xx at cell (i, j).
    #[inline]
    pub fn txx(&self, i: isize, j: isize) -> f64 {
        let viscous = 2.0 * self.eta_c.at(i, j) * (self.u.at(i + 1, j) - self.u.at(i, j)) / self.dx;
        viscous + self.plastic.map_or(0.0, |(tau, sxx)| tau.at(i, j) * sxx.at(i, j))
    }
}

/// How the default r_b is chosen (`RheologyConfig::wall_r`; module doc, "Choice of r_b").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum WallR {
    /// One r_b = (1 − θ)/max(τ_b/(h_n c)) for every face, from the stiffest.
    #[default]
    Single,
    /// Each face's own r_b = (1 − θ) h_n c/τ_b.
    Local,
}

impl WallR {
    /// Every value, in the order of the names.
    pub const ALL: [WallR; 2] = [WallR::Single, WallR::Local];

    /// Name used in Python and the docs.
    pub fn name(&self) -> &'static str {
        match self {
            WallR::Single => "single",
            WallR::Local => "local",
        }
    }
}

/// One Coulomb side: s, s^n, τ_b and r_b on its tangential faces.
#[derive(Clone, Debug)]
struct WallSide {
    side: Side,
    /// Faces (along the side) that are unknowns.
    faces: Range<usize>,
    s: Vec<f64>,
    s_n: Vec<f64>,
    tau_b: Vec<f64>,
    r: Vec<f64>,
}

/// The friction state of every Coulomb side.
#[derive(Clone, Debug, Default)]
pub struct CoulombWalls {
    sides: Vec<WallSide>,
    /// Where the last [`CoulombWalls::update`] changed s most: (weighted increment, side, face).
    pub last_largest: Option<(f64, Side, usize)>,
}

impl CoulombWalls {
    /// The Coulomb sides of `bc` (none if `enabled` is false: frictionless walls).
    pub fn new(grid: &Grid, bc: &BoundaryConditions, enabled: bool) -> Self {
        let mut sides = Vec::new();
        if enabled {
            for side in Side::ALL {
                if bc.get(side) != VelocityBc::Coulomb {
                    continue;
                }
                let (faces, n) = if side.is_x() {
                    (unknown_face_range(bc.get(Side::Bottom), bc.get(Side::Top), grid.ny), grid.ny + 1)
                } else {
                    (unknown_face_range(bc.get(Side::Left), bc.get(Side::Right), grid.nx), grid.nx + 1)
                };
                sides.push(WallSide { side, faces, s: vec![0.0; n], s_n: vec![0.0; n], tau_b: vec![0.0; n], r: vec![0.0; n] });
            }
        }
        CoulombWalls { sides, last_largest: None }
    }

    /// Whether any side has friction.
    pub fn is_active(&self) -> bool {
        !self.sides.is_empty()
    }

    /// Start of a step: s^n ← s.
    pub fn begin_step(&mut self) {
        for w in &mut self.sides {
            w.s_n.copy_from_slice(&w.s);
        }
    }

    /// max |s − s^n| over the faces with friction: how far s is from the anchor of eq. (12).
    pub fn anchor_distance(&self) -> f64 {
        self.sides.iter().flat_map(|w| w.s.iter().zip(&w.s_n).zip(&w.tau_b)).filter(|(_, &t)| t > 0.0).map(|((a, b), _)| (a - b).abs()).fold(0.0, f64::max)
    }

    /// τ_b = tan(α_b) (p − p_s − T_nn)_wall⁺ H_ε(Φ_wall) on every tangential face of every Coulomb side,
    /// with p, T_nn and Φ extrapolated linearly to the wall and averaged over the two cells beside
    /// the face; `tnn` the stress of [`crate::rheology::WallNormalStress::Total`] (T_nn = T_xx on
    /// the left and right sides, −T_xx on the bottom and top; read only in the two cell rows
    /// next to each wall), None: −σ_n = p; `eps` None: a single-phase model (H = 1); `iy` places
    /// the smoothed jump ([`InterfaceYield::shift`]); `p_s` the reference pressure of
    /// [`crate::rheology::YieldPressure`] (0: p itself).
    #[allow(clippy::too_many_arguments)]
    pub fn set_friction(
        &mut self,
        p: &Field,
        p_s: f64,
        tnn: Option<NormalStress>,
        phi: &Field,
        tan_alpha_b: f64,
        eps: Option<f64>,
        iy: InterfaceYield,
        grid: &Grid,
    ) {
        let hv = |x: f64| eps.map_or(1.0, |e| heaviside(iy.shift(x, e), e));
        let (nx, ny) = (grid.nx as isize, grid.ny as isize);
        // value extrapolated to the wall from the cells (i, j) inward
        let wall = |at: &dyn Fn(isize, isize) -> f64, side: Side, k: isize| -> f64 {
            match side {
                Side::Bottom => 1.5 * at(k, 0) - 0.5 * at(k, 1),
                Side::Top => 1.5 * at(k, ny - 1) - 0.5 * at(k, ny - 2),
                Side::Left => 1.5 * at(0, k) - 0.5 * at(1, k),
                Side::Right => 1.5 * at(nx - 1, k) - 0.5 * at(nx - 2, k),
            }
        };
        let (pa, fa) = (|i, j| p.at(i, j), |i, j| phi.at(i, j));
        for w in &mut self.sides {
            let ncells = if w.side.is_x() { ny } else { nx };
            for f in w.faces.clone() {
                let (k0, k1) = ((f as isize - 1).clamp(0, ncells - 1), (f as isize).clamp(0, ncells - 1));
                let mut pw = 0.5 * (wall(&pa, w.side, k0) + wall(&pa, w.side, k1)) - p_s;
                if let Some(t) = &tnn {
                    let ta = |i, j| t.txx(i, j);
                    let txx = 0.5 * (wall(&ta, w.side, k0) + wall(&ta, w.side, k1));
                    pw -= if w.side.is_x() { txx } else { -txx };
                }
                let hw = 0.5 * (hv(wall(&fa, w.side, k0)) + hv(wall(&fa, w.side, k1)));
                w.tau_b[f] = tan_alpha_b * pw.max(0.0) * hw;
            }
        }
    }

    /// τ_b/(h_n c) of face `f` of side `w`, c = a₀ρ/δt with ρ on the face.
    fn response(w: &WallSide, f: usize, rho_u: &Field, rho_v: &Field, a0_over_dt: f64, grid: &Grid) -> f64 {
        let (nx, ny, fi) = (grid.nx as isize, grid.ny as isize, f as isize);
        let (rho, h) = match w.side {
            Side::Bottom => (rho_u.at(fi, 0), grid.dy),
            Side::Top => (rho_u.at(fi, ny - 1), grid.dy),
            Side::Left => (rho_v.at(0, fi), grid.dx),
            Side::Right => (rho_v.at(nx - 1, fi), grid.dx),
        };
        w.tau_b[f] / (h * a0_over_dt * rho)
    }

    /// max over the friction faces of τ_b/(h_n c), c = a₀ρ/δt with ρ on the face (0 if none).
    pub fn max_response(&self, rho_u: &Field, rho_v: &Field, a0_over_dt: f64, grid: &Grid) -> f64 {
        let mut m = 0.0f64;
        for w in &self.sides {
            for f in w.faces.clone() {
                m = m.max(Self::response(w, f, rho_u, rho_v, a0_over_dt, grid));
            }
        }
        m
    }

    /// Sets r_b on every face after [`CoulombWalls::set_friction`]: `user`'s constant, else the
    /// bound of `choice` (module doc, "Choice of r_b"; a face without friction takes the single
    /// bound, which it never uses). Returns the single bound (or the user's r_b): the smallest
    /// r_b of the faces, since every face's own bound (1 − θ)/(τ_b/(h_n c)) is at least it.
    #[allow(clippy::too_many_arguments)]
    pub fn set_r(&mut self, user: Option<f64>, choice: WallR, theta: f64, rho_u: &Field, rho_v: &Field, a0_over_dt: f64, grid: &Grid) -> f64 {
        let single = user.unwrap_or_else(|| default_r_wall(theta, self.max_response(rho_u, rho_v, a0_over_dt, grid)));
        let local = user.is_none() && choice == WallR::Local;
        for w in &mut self.sides {
            w.r.fill(single);
            for f in w.faces.clone().filter(|&f| local && w.tau_b[f] > 0.0) {
                w.r[f] = default_r_wall(theta, Self::response(w, f, rho_u, rho_v, a0_over_dt, grid));
            }
        }
        single
    }

    /// Multiplies r_b on every face by `factor` (the Picard loop's stall safeguard).
    pub fn scale_r(&mut self, factor: f64) {
        for w in &mut self.sides {
            w.r.iter_mut().for_each(|r| *r *= factor);
        }
    }

    /// Adds the wall force τ_b s / h_n to the tangential row next to each Coulomb side.
    pub fn add_force(&self, out_u: &mut Field, out_v: &mut Field, grid: &Grid) {
        let (nx, ny) = (grid.nx, grid.ny);
        for w in &self.sides {
            for f in w.faces.clone() {
                let force = w.tau_b[f] * w.s[f];
                match w.side {
                    Side::Bottom => add(out_u, f, 0, force / grid.dy),
                    Side::Top => add(out_u, f, ny - 1, force / grid.dy),
                    Side::Left => add(out_v, 0, f, force / grid.dx),
                    Side::Right => add(out_v, nx - 1, f, force / grid.dx),
                }
            }
        }
    }

    /// The friction faces (τ_b > 0) of every side: (side, face, τ_b, s), for the exact step
    /// (`rheology/exact.rs`).
    pub fn friction_faces(&self) -> Vec<(Side, usize, f64, f64)> {
        self.sides.iter().flat_map(|w| w.faces.clone().filter(|&f| w.tau_b[f] > 0.0).map(move |f| (w.side, f, w.tau_b[f], w.s[f]))).collect()
    }

    /// Sets s on face `face` of `side` (the exact step's multiplier, −σ_f).
    pub fn set_direction(&mut self, side: Side, face: usize, s: f64) {
        if let Some(w) = self.sides.iter_mut().find(|w| w.side == side) {
            w.s[face] = s;
        }
    }

    /// One Picard update s^{k+1} = P_b(s^k − r_b u_t + θ(s^n − s^k)) from the velocity ũ^{k+1},
    /// with each face's r_b of [`CoulombWalls::set_r`]; returns max |τ_b (s^{k+1} − s^k)| / max
    /// τ_b (the increment of the wall stress). Faces with τ_b = 0 keep s = 0.
    pub fn update(&mut self, u: &Field, v: &Field, theta: f64, grid: &Grid) -> f64 {
        let (nx, ny) = (grid.nx as isize, grid.ny as isize);
        let tau_ref = self.sides.iter().flat_map(|w| w.tau_b.iter()).fold(0.0f64, |a, &b| a.max(b));
        let scale = if tau_ref > 0.0 { 1.0 / tau_ref } else { 0.0 };
        let mut inc = 0.0f64;
        let mut largest = None;
        for w in &mut self.sides {
            for f in w.faces.clone() {
                let fi = f as isize;
                let ut = match w.side {
                    Side::Bottom => u.at(fi, 0),
                    Side::Top => u.at(fi, ny - 1),
                    Side::Left => v.at(0, fi),
                    Side::Right => v.at(nx - 1, fi),
                };
                let new = if w.tau_b[f] > 0.0 { (w.s[f] - w.r[f] * ut + theta * (w.s_n[f] - w.s[f])).clamp(-1.0, 1.0) } else { 0.0 };
                let d = (new - w.s[f]).abs() * w.tau_b[f] * scale;
                if largest.is_none_or(|(m, _, _): (f64, Side, usize)| crate::plasticity::exceeds(d, m)) {
                    largest = Some((d, w.side, f));
                }
                inc = if d.is_nan() { f64::NAN } else { inc.max(d) };
                w.s[f] = new;
            }
        }
        self.last_largest = largest;
        inc
    }

    /// Copies s, s^n and τ_b of every side from `other` (a model of the same boundary conditions
    /// on a grid sharing this one's lower-left corner) over the faces both have (r_b is set
    /// afresh by each step's [`CoulombWalls::set_r`]).
    pub(crate) fn copy_prefix_from(&mut self, other: &CoulombWalls) {
        for (a, b) in self.sides.iter_mut().zip(&other.sides) {
            let n = a.s.len().min(b.s.len());
            a.s[..n].copy_from_slice(&b.s[..n]);
            a.s_n[..n].copy_from_slice(&b.s_n[..n]);
            a.tau_b[..n].copy_from_slice(&b.tau_b[..n]);
        }
    }

    /// Copies of the friction directions s of every Coulomb side, in side order (checkpoints).
    pub fn directions(&self) -> Vec<Vec<f64>> {
        self.sides.iter().map(|w| w.s.clone()).collect()
    }

    /// The friction directions s of every Coulomb side, in side order (checkpoints).
    pub fn directions_mut(&mut self) -> Vec<&mut Vec<f64>> {
        self.sides.iter_mut().map(|w| &mut w.s).collect()
    }

    /// The friction direction s and coefficient τ_b of one side along its faces (None if the side
    /// has no friction): (s, τ_b).
    pub fn side(&self, side: Side) -> Option<(&[f64], &[f64])> {
        self.sides.iter().find(|w| w.side == side).map(|w| (&w.s[..], &w.tau_b[..]))
    }
}

#[inline]
fn add(f: &mut Field, i: usize, j: usize, x: f64) {
    let k = f.idx(i as isize, j as isize);
    f.slice_mut()[k] += x;
}

/// Default r_b = (1 − θ)/max(τ_b/(h_n c)) (1 if no face has friction).
pub fn default_r_wall(theta: f64, max_response: f64) -> f64 {
    if max_response > 0.0 && max_response.is_finite() {
        (1.0 - theta) / max_response
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::{Field, Location};

    /// The faces' map of "Choice of r_b" on a base whose τ_b falls a hundredfold along it (p from
    /// 1000 Pa to 10 Pa, as under a deposit thinning to its tip), with the response of a predictor
    /// A = c (no viscous coupling): u_t = u₀ + τ_b s/(h c), every face stuck at s = −u₀ h c/τ_b, |s| ≤ 1/2.
    /// Uzawa updates (θ = 0) from s = 0. With `Local` every face's ratio is 1 − r_b τ_b/(h c) = 0:
    /// stuck after one update, its slip zero to round-off. With `Single` the thinnest face's ratio
    /// is 1 − τ_b/max τ_b = 1 − 0.0136 (the faces average two cells): after 50 updates it still
    /// slides at 0.504 of u₀, exactly that ratio to the 50th power, while its
    /// increment, weighted by τ_b/max τ_b, is already below 1e-2 (of the order of what the
    /// column's tolerance 1e-3 lets pass: it would stop there with the tip sliding).
    #[test]
    fn each_face_s_own_r_b_sticks_the_thin_faces_in_one_update() {
        let grid = Grid::new(16, 4, 1.6, 0.4).unwrap();
        let bc = BoundaryConditions::uniform(VelocityBc::FreeSlip).with(Side::Bottom, VelocityBc::Coulomb);
        let (rho, a0_over_dt, theta, tan_b) = (1500.0, 1.5 / 1e-3, 0.0, 15f64.to_radians().tan());
        // p falls geometrically from 1000 Pa in the first cell to 10 Pa in the last
        let p = Field::from_fn(&grid, Location::Centre, |x, _| 1000.0 * 0.01f64.powf((x / 0.1 - 0.5) / 15.0));
        let phi = Field::from_fn(&grid, Location::Centre, |_, _| 1.0);
        let (rho_u, rho_v) = (Field::from_fn(&grid, Location::XFace, |_, _| rho), Field::from_fn(&grid, Location::YFace, |_, _| rho));
        let c = a0_over_dt * rho;
        let run = |choice: WallR, updates: usize| -> (Vec<f64>, Vec<f64>, f64, f64) {
            let mut walls = CoulombWalls::new(&grid, &bc, true);
            walls.set_friction(&p, 0.0, None, &phi, tan_b, None, InterfaceYield::Paper, &grid);
            let smallest = walls.set_r(None, choice, theta, &rho_u, &rho_v, a0_over_dt, &grid);
            let tau_b = walls.side(Side::Bottom).unwrap().1.to_vec();
            let tau_min = walls.sides[0].faces.clone().map(|f| tau_b[f]).fold(f64::INFINITY, f64::min);
            let u0 = 0.5 * tau_min / (grid.dy * c);
            let (mut u, v) = (Field::zeros(&grid, Location::XFace), Field::zeros(&grid, Location::YFace));
            let mut inc = 0.0;
            walls.begin_step();
            for _ in 0..updates {
                let s = walls.side(Side::Bottom).unwrap().0.to_vec();
                for f in walls.sides[0].faces.clone() {
                    u.set(f, 0, u0 + tau_b[f] * s[f] / (grid.dy * c));
                }
                inc = walls.update(&u, &v, theta, &grid);
            }
            let s = walls.side(Side::Bottom).unwrap().0.to_vec();
            let slip = walls.sides[0].faces.clone().map(|f| (u0 + tau_b[f] * s[f] / (grid.dy * c)) / u0).collect();
            (slip, walls.sides[0].r.clone(), inc, smallest)
        };
        let (slip, r, _, smallest) = run(WallR::Local, 1);
        let faces = 1..grid.nx;
        for f in faces.clone() {
            assert!(slip[f - 1].abs() < 1e-12, "local: face {f} still slips at {} of u0", slip[f - 1]);
        }
        // r_b = (1 − θ) h c/τ_b on each face; the smallest is the stiffest face's, the single bound
        let (_, r_single, _, single) = run(WallR::Single, 1);
        assert!(r_single.iter().all(|&x| x == single) && (smallest - single).abs() < 1e-12 * single, "{smallest} {single}");
        assert!(r[faces.end - 1] > 50.0 * single, "the thin end's r_b {} against {single}", r[faces.end - 1]);
        assert!(r[faces.clone()].iter().all(|&x| x >= single), "a face's own bound below the single one");
        let (slip, _, inc, _) = run(WallR::Single, 50);
        let thin = slip[faces.len() - 1];
        // the thin face's ratio 1 − τ_b/max τ_b (faces average two cells: τ_b/max τ_b = 0.0136)
        let ratio = 1.0 - single / r[faces.end - 1];
        assert!((thin - ratio.powi(50)).abs() < 1e-9 && thin > 0.5, "single: the thin face slips at {thin} of u0, {ratio}^50 expected");
        assert!(inc < 1e-2, "single: weighted increment {inc}");
    }
}
