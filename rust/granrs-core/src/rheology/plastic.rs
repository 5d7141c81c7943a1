//! The *plastic* projection Σ = P(Σ + r D(u)) and its Picard iteration (Aravena et al. eq. 7c,
//! 11, 12; Chupin & Dubois 2016, *Comput. Math. Appl.* 72, 1263–1286; Chalayer, Chupin & Dubois
//! 2018, *SIAM J. Numer. Anal.* 56; Chupin, Dubois, Phan & Roche 2021, *J. Comput. Phys.* 438).
//! Not to be confused with the *pressure* projection of `projection/`.
//!
//! Continuous problem: Σ symmetric, traceless, |Σ| ≤ 1 with |Σ|² = ½ Σᵢⱼ Σᵢⱼ, and
//! Σ = P(Σ + r D(u)) for any r > 0, P(Λ) = Λ / max(1, |Λ|). In 2D a symmetric traceless tensor is
//! (Σ_xx, Σ_xy) with Σ_yy = −Σ_xx, so |Σ|² = Σ_xx² + Σ_xy², and only the deviatoric part of D
//! matters: D_dev,xx = (D_xx − D_yy)/2, D_dev,xy = D_xy.
//!
//! Picard iteration with pseudo-relaxation θ (eq. 12), starting from Σ^{n+1,0} = Σ^n:
//!
//!   solve the predictor with the explicit force div(τ Σ^k)   → ũ^{k+1},
//!   Σ^{k+1} = P(Σ^k + r D_dev(ũ^{k+1}) + θ (Σ^n − Σ^k)),
//!
//! until max |τ(Σ^{k+1} − Σ^k)|/τ_max ≤ tol. Its fixed point solves Σ = P(Σ + r D + θ(Σ^n − Σ)), i.e. eq. (11)
//! up to the first-order-in-time term θ(Σ^n − Σ^{n+1}) (which vanishes at steady state).
//!
//! **Storage and discrete projection.** Σ_xx lives at cell centres (with D_xx, D_yy) and Σ_xy at
//! nodes (with D_xy), so that the force div(τΣ) has exactly the compact stencil of the viscous
//! term (τΣ_xx at centres and τΣ_xy at nodes, differenced onto the faces) and each component is
//! updated where its strain rate is exact. The projection of the pair is done twice: at centres
//! with Σ_xy (the trial value) averaged from the four corner nodes, and at nodes with Σ_xx
//! averaged from the four adjacent cells. In a plane shear flow (Poiseuille, Couette, layers)
//! Σ_xx ≡ 0, so both reduce to the exact scalar clamp of Σ_xy at the nodes where D_xy lives: the
//! discrete plug is exactly rigid (D_xy = 0 to the Picard tolerance wherever |Σ_xy| < 1).
//! This is the default (`SigmaLocation::Staggered`).
//!
//! `SigmaLocation::Centres` puts all of Σ at centres, as the paper's Figure 3 does: D_xy is
//! averaged from the four corner nodes to the centre, the pair is projected there once, and the
//! force takes τΣ_xy at a node as the average of τ_c Σ_xy,c over its four cells, the adjoint of
//! that average, so that the discrete plastic power is still Σ_cells τ Σ:D (`sigma_xy` then holds
//! this nodal equivalent for the energy budget and the views). Measured: the Bingham Poiseuille
//! profile has the same l2 errors and the same second order, but the stress settles 6 to more
//! than 14 times slower (166 steps against 29 at n = 16; the 400-step cap at 32 and 64) (the cell average does not see the zig-zag of D_xy between node rows); the
//! column runs 6–7 % further at ny = 32 and 2–5 % at ny = 64 (docs/validation.md, Column collapse).
//!
//! **Choice of r (contraction).** With the discrete force F(Σ) = −2 Dᵀ τ Σ and the predictor
//! operator A = c + Dᵀ(2η)D ≥ c + 4η DᵀD (c = a₀ρ/δt), the linearised iteration is
//! Σ ↦ (1 − θ)Σ − r K Σ + …, K = 2 D A⁻¹ Dᵀ τ, whose eigenvalues lie in [0, τ k_max] with
//! k_max = 2S/(c + 4ηS), S = 2(1/dx² + 1/dy²) ≥ ‖D‖². P is non-expansive, so the map contracts
//! with ratio max(1 − θ, |1 − θ − r τ k_max|) for r τ k_max ≤ 2(1 − θ).
//!
//! The fixed point of eq. (11) does not depend on r, even point by point (Σ = P(Σ + r D) says
//! Σ = D/|D| or D = 0 whatever r > 0 is), so the default takes a *local* r(x) = (1 − θ)/(τ(x) k̄(x))
//! with k̄ the largest k over a (2w + 1)² neighbourhood of the point, w =
//! `RheologyConfig::r_neighbourhood` (k evaluated with each cell's c and η): a Jacobi-like
//! scaling of the same bound. A single r = (1 − θ)/max(τ k) satisfies the bound rigorously but
//! crawls on layers under air: τ ∝ p varies with depth, and in the interface band the
//! harmonic-mean viscosity collapses to the air's, so k there is ~80 times the bulk value; Uzawa
//! (θ = 0) on a heap at rest did not converge in 20 000 iterations with it, and converges with
//! the local r (docs/validation.md).
//!
//! The relaxed fixed point of eq. (12) (θ > 0) *does* depend on r: a rigid zone deforms at
//! D = θ(Σ − Σⁿ)/r, an elastic body of compliance θδt/(τr). With w = 2 every cell within two
//! cells of the air takes the air face's k, about 1600 times the bulk value, so a band two cells
//! deep under every surface is 1600 times softer than the bulk; at the adaptive steps of the
//! column its elastic strains reach O(1) and the late run-out depends on δt by tens of per cent
//! (docs/validation.md, Column collapse). With w = 0 (k of the cell's own four faces, the
//! default) only the surface cells themselves are soft, and the run-out agrees across δt: at
//! ny = 16 the adaptive run-out is 1.0 % short of the run at δt = 1e-5 s, against 36 % with
//! w = 2. A larger w guards against k of the point alone flip-flopping (increment ≈ 2) in the
//! interface band, where k jumps by ~80 over two cells; no measured case does with w = 0, and
//! the stall safeguard of the Picard loop (`rheology/stage.rs`) halves r if one does.
//! Limits: Stokes (c → 0) r = 2η(1 − θ)/τ ("r ~ η/τ"); inertial (small δt) r = (1 − θ)c/(2Sτ).
//! A user-given `r` is used as a constant.

use super::SigmaLocation;
use crate::error::Error;
use crate::exec::Exec;
use crate::grid::{BoundaryConditions, Field, Grid, Location, Side, VelocityBc, HALO};
use crate::operators::{for_each_interior_row, for_each_interior_row_max, strain_rate, strain_rate_norm_centre};
pub(crate) use crate::plasticity::exceeds;
pub use crate::plasticity::{unit_ball_scale, weighted_max_abs_diff};

/// What the Picard iteration of one step did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PicardInfo {
    /// Iterations (predictor solves) taken; 0 when there is no plastic stress or wall friction.
    pub iterations: usize,
    /// max |Σ^{k+1} − Σ^k|, max |s^{k+1} − s^k| at the last iteration.
    pub increment: f64,
    /// r used in the step: the user's constant r, or the smallest local r [s].
    pub r: f64,
    /// r_b used in the step (0 without friction walls).
    pub r_wall: f64,
    /// Times r and r_b were halved because the increment stalled (see `PICARD_STALL_WINDOW`).
    pub r_halvings: usize,
    /// Proximal restarts of the anchor in the step (`RheologyConfig::proximal_restarts`).
    pub restarts: usize,
}

#[inline]
fn base(f: &Field, j: isize) -> usize {
    ((j + HALO as isize) as usize) * f.stride() + HALO
}

/// Row kernels of the projection and of the force, on slices of the rows they read (no bounds
/// checks in the loops, which vectorise), each compiled for AVX2 as well ([`crate::multiversion`]:
/// the same operations in the same order, the same bits).
mod rows {
    use crate::plasticity::unit_ball_scale;

    /// The largest of |d| values ≥ 0 seen so far, NaN once a NaN was seen: (max, seen NaN).
    #[inline(always)]
    fn fold_max(m: f64, nan: bool, d: f64) -> (f64, bool) {
        (if d > m { d } else { m }, nan | d.is_nan())
    }

    crate::multiversion! {
        /// Σ_xx ← P at centres: `out[i]` = Λ_xx scaled onto the unit ball with Λ_xy the mean of
        /// the four corners (`n0`, `n1`: the node rows below and above, n + 1 values each);
        /// returns max |τ(new − old)| · `scale` over the row, NaN if any value is NaN.
        pub fn project_xx / project_xx_base(xx: &[f64], n0: &[f64], n1: &[f64], tau: &[f64], out: &mut [f64], scale: f64) -> f64 {
            let n = out.len();
            let (xx, n0, n1, tau) = (&xx[..n], &n0[..n + 1], &n1[..n + 1], &tau[..n]);
            let (mut m, mut nan) = (0.0f64, false);
            for i in 0..n {
                let a = xx[i];
                let b = 0.25 * (n0[i] + n0[i + 1] + n1[i] + n1[i + 1]);
                let new = a * unit_ball_scale(a, b);
                let d = (new - out[i]).abs() * tau[i] * scale;
                (m, nan) = fold_max(m, nan, d);
                out[i] = new;
            }
            if nan { f64::NAN } else { m }
        }
    }

    crate::multiversion! {
        /// Σ_xy ← P at nodes: `out[i]` = Λ_xy scaled onto the unit ball with Λ_xx the mean of the
        /// four adjacent cells (`c0`, `c1`: the centre rows below and above, from the cell left
        /// of node 0, n + 1 values each); returns the row's max as [`project_xx`].
        pub fn project_xy / project_xy_base(xy: &[f64], c0: &[f64], c1: &[f64], tau: &[f64], out: &mut [f64], scale: f64) -> f64 {
            let n = out.len();
            let (xy, c0, c1, tau) = (&xy[..n], &c0[..n + 1], &c1[..n + 1], &tau[..n]);
            let (mut m, mut nan) = (0.0f64, false);
            for i in 0..n {
                let b = xy[i];
                let a = 0.25 * (c0[i + 1] + c0[i] + c1[i + 1] + c1[i]);
                let new = b * unit_ball_scale(a, b);
                let d = (new - out[i]).abs() * tau[i] * scale;
                (m, nan) = fold_max(m, nan, d);
                out[i] = new;
            }
            if nan { f64::NAN } else { m }
        }
    }

    crate::multiversion! {
        /// Trial Λ_xx = Σ_xx + ½ r (D_xx − D_yy) + θ(Σ_xx^n − Σ_xx) along a row of centres where
        /// τ > 0 (0 elsewhere), with D_xx = (u[i + 1] − u[i])·idx (n + 1 faces) and D_yy =
        /// (v1[i] − v0[i])·idy (the face rows below and above).
        pub fn trial_xx / trial_xx_base(u: &[f64], v0: &[f64], v1: &[f64], sx: &[f64], sxn: &[f64], tau: &[f64], r: &[f64], idx: f64, idy: f64, theta: f64, out: &mut [f64]) {
            let n = out.len();
            let (u, v0, v1, sx, sxn, tau, r) = (&u[..n + 1], &v0[..n], &v1[..n], &sx[..n], &sxn[..n], &tau[..n], &r[..n]);
            for i in 0..n {
                let a = (u[i + 1] - u[i]) * idx;
                let b = (v1[i] - v0[i]) * idy;
                let t = sx[i] + 0.5 * r[i] * (a - b) + theta * (sxn[i] - sx[i]);
                out[i] = if tau[i] > 0.0 { t } else { 0.0 };
            }
        }
    }

    crate::multiversion! {
        /// Trial Λ_xy = Σ_xy + r D_xy + θ(Σ_xy^n − Σ_xy) along a row of nodes where τ > 0 (0
        /// elsewhere), with D_xy = ½((u1[i] − u0[i])·idy + (v[i + 1] − v[i])·idx): `u0`, `u1` the
        /// face rows below and above, `v` the row of v-faces from the one left of node 0.
        pub fn trial_xy / trial_xy_base(u0: &[f64], u1: &[f64], v: &[f64], sy: &[f64], syn: &[f64], tau: &[f64], r: &[f64], idx: f64, idy: f64, theta: f64, out: &mut [f64]) {
            let n = out.len();
            let (u0, u1, v, sy, syn, tau, r) = (&u0[..n], &u1[..n], &v[..n + 1], &sy[..n], &syn[..n], &tau[..n], &r[..n]);
            for i in 0..n {
                let c = 0.5 * ((u1[i] - u0[i]) * idy + (v[i + 1] - v[i]) * idx);
                let t = sy[i] + r[i] * c + theta * (syn[i] - sy[i]);
                out[i] = if tau[i] > 0.0 { t } else { 0.0 };
            }
        }
    }

    crate::multiversion! {
        /// `out[i]` = a[i] · b[i].
        pub fn product / product_base(a: &[f64], b: &[f64], out: &mut [f64]) {
            let n = out.len();
            let (a, b) = (&a[..n], &b[..n]);
            for i in 0..n {
                out[i] = a[i] * b[i];
            }
        }
    }

    crate::multiversion! {
        /// A row of u-faces: `out[i]` += (c[i + 1] − c[i])·idx + (n1[i] − n0[i])·idy, with `c` the
        /// τΣ_xx row from the cell left of face 0 (n + 1 values), `n0`, `n1` the τΣ_xy node rows
        /// below and above (n values).
        pub fn force_u / force_u_base(c: &[f64], n0: &[f64], n1: &[f64], idx: f64, idy: f64, out: &mut [f64]) {
            let n = out.len();
            let (c, n0, n1) = (&c[..n + 1], &n0[..n], &n1[..n]);
            for i in 0..n {
                out[i] += (c[i + 1] - c[i]) * idx + (n1[i] - n0[i]) * idy;
            }
        }
    }

    crate::multiversion! {
        /// A row of v-faces: `out[i]` += (nd[i + 1] − nd[i])·idx − (c1[i] − c0[i])·idy, with `nd` the
        /// τΣ_xy node row (n + 1 values), `c0`, `c1` the τΣ_xx rows below and above (n values).
        pub fn force_v / force_v_base(nd: &[f64], c0: &[f64], c1: &[f64], idx: f64, idy: f64, out: &mut [f64]) {
            let n = out.len();
            let (nd, c0, c1) = (&nd[..n + 1], &c0[..n], &c1[..n]);
            for i in 0..n {
                out[i] += (nd[i + 1] - nd[i]) * idx - (c1[i] - c0[i]) * idy;
            }
        }
    }
}

/// Copies the ghost rows (the HALO rows below and above the interior) of `from` into `to`.
fn copy_halo_rows(from: &Field, to: &mut Field) {
    debug_assert_eq!(from.data.dim(), to.data.dim());
    let (st, ny) = (from.stride(), from.ny);
    let (a, b) = (from.slice(), to.slice_mut());
    b[..HALO * st].copy_from_slice(&a[..HALO * st]);
    b[(HALO + ny) * st..].copy_from_slice(&a[(HALO + ny) * st..]);
}

/// The plastic tensor Σ and the work arrays of its projection (allocated once).
pub struct PlasticState {
    /// Σ_xx at centres (Σ^{n+1,k} during the iteration, Σ^n between steps).
    pub sigma_xx: Field,
    /// Σ_xy at nodes.
    pub sigma_xy: Field,
    /// Σ^n.
    pub sigma_xx_n: Field,
    pub sigma_xy_n: Field,
    /// Yield stress τ at centres (ghosts filled) and nodes.
    pub tau_c: Field,
    pub tau_n: Field,
    /// Largest yield stress of the step (the scale of the Picard increment).
    pub tau_max: f64,
    /// r at centres and nodes.
    pub r_c: Field,
    pub r_n: Field,
    trial_c: Field,
    trial_n: Field,
    new_c: Field,
    new_n: Field,
    stress_c: Field,
    stress_n: Field,
    /// Boundary nodes where Σ_xy is held at 0: sides whose tangential stress is zero or given by
    /// friction (free-slip, Coulomb). On open sides (outflow, fully developed) Σ_xy is projected
    /// like inside: their ghosts give ∂u_t/∂n = 0, not a zero stress. Order left, right, bottom, top.
    zero_tangential: [bool; 4],
    /// When set, [`PlasticState::update`] also records where Σ changed most (`last_largest`);
    /// the Picard loop sets it for its last allowed iteration, to say where it failed.
    pub locate: bool,
    /// (weighted increment, location (centre: Σ_xx, node: Σ_xy), i, j) of the last located update.
    pub last_largest: Option<(f64, Location, usize, usize)>,
    /// Σ_xy at cell centres (`SigmaLocation::Centres`, the paper's Figure 3); `None` for the
    /// staggered layout. With it, `sigma_xy` holds Σ_xy's nodal equivalent, τ_n Σ_xy,n = the
    /// average of τ_c Σ_xy,c over the node's four cells (what the force uses), for the energy
    /// budget, the checkpoint and the Python view.
    pub centred: Option<CentredShear>,
}

/// Σ_xy at cell centres and its work arrays (`SigmaLocation::Centres`).
pub struct CentredShear {
    /// Σ_xy at centres (Σ^{n+1,k} during the iteration, Σ^n between steps).
    pub sigma: Field,
    /// Σ_xy^n at centres.
    pub sigma_n: Field,
    trial: Field,
    new: Field,
}

impl PlasticState {
    /// Σ = 0 on `grid`, stored as `location` says.
    pub fn new(grid: &Grid, bc: &BoundaryConditions, location: SigmaLocation) -> Self {
        let c = || Field::zeros(grid, Location::Centre);
        let n = || Field::zeros(grid, Location::Node);
        let zero = |s: Side| matches!(bc.get(s), VelocityBc::FreeSlip | VelocityBc::Coulomb);
        PlasticState {
            sigma_xx: c(),
            sigma_xy: n(),
            sigma_xx_n: c(),
            sigma_xy_n: n(),
            tau_c: c(),
            tau_n: n(),
            tau_max: 0.0,
            r_c: c(),
            r_n: n(),
            trial_c: c(),
            trial_n: n(),
            new_c: c(),
            new_n: n(),
            stress_c: c(),
            stress_n: n(),
            zero_tangential: Side::ALL.map(zero),
            locate: false,
            last_largest: None,
            centred: (location == SigmaLocation::Centres).then(|| CentredShear { sigma: c(), sigma_n: c(), trial: c(), new: c() }),
        }
    }

    /// The boundary-node holds (left, right, bottom, top): Σ_xy = 0 on free-slip and Coulomb
    /// sides.
    pub(crate) fn zero_tangential(&self) -> [bool; 4] {
        self.zero_tangential
    }

    /// max |τ(Σ − Σ^n)|/τ_max: how far Σ is from the anchor of eq. (12).
    pub fn anchor_distance(&self, exec: Exec) -> f64 {
        let xx = weighted_max_abs_diff(&self.sigma_xx, &self.sigma_xx_n, &self.tau_c, self.tau_max, exec);
        match &self.centred {
            Some(cs) => xx.max(weighted_max_abs_diff(&cs.sigma, &cs.sigma_n, &self.tau_c, self.tau_max, exec)),
            None => xx.max(weighted_max_abs_diff(&self.sigma_xy, &self.sigma_xy_n, &self.tau_n, self.tau_max, exec)),
        }
    }

    /// Start of a step: Σ^n ← Σ (the iteration starts from Σ^{n+1,0} = Σ^n); copies on the
    /// threads of `exec`.
    pub fn begin_step(&mut self, exec: Exec) {
        exec.copy(self.sigma_xx_n.slice_mut(), self.sigma_xx.slice());
        exec.copy(self.sigma_xy_n.slice_mut(), self.sigma_xy.slice());
        if let Some(cs) = self.centred.as_mut() {
            exec.copy(cs.sigma_n.slice_mut(), cs.sigma.slice());
        }
    }

    /// With Σ_xy at centres: `stress_n` ← τΣ_xy at nodes, the average of τ_c Σ_xy,c over the
    /// node's four cells (constant extrapolation across open sides; 0 on held boundary nodes),
    /// and `sigma_xy` ← its nodal equivalent stress_n/τ_n (0 where τ_n = 0).
    fn centred_shear_to_nodes(&mut self, exec: Exec) {
        let Some(cs) = self.centred.as_mut() else { return };
        {
            let (ts, ss, st) = (self.tau_c.slice(), cs.sigma.slice(), self.tau_c.stride());
            let n = cs.new.nx;
            for_each_interior_row(exec, &mut cs.new, |j, row| {
                let b = (j + HALO) * st + HALO;
                for i in 0..n {
                    row[HALO + i] = ts[b + i] * ss[b + i];
                }
            });
        }
        cs.new.extrapolate_ghosts_constant();
        let prod = &cs.new;
        let ps = prod.slice();
        let (nxn, nyn) = (self.stress_n.nx, self.stress_n.ny);
        let z = self.zero_tangential;
        for_each_interior_row(exec, &mut self.stress_n, |j, row| {
            let ji = j as isize;
            let (b0, b1) = (base(prod, ji - 1), base(prod, ji));
            for i in 0..nxn {
                row[HALO + i] = if node_held(&z, i, j, nxn, nyn) { 0.0 } else { 0.25 * (ps[b0 + i - 1] + ps[b0 + i] + ps[b1 + i - 1] + ps[b1 + i]) };
            }
        });
        let (sn, tn, st) = (self.stress_n.slice(), self.tau_n.slice(), self.stress_n.stride());
        for_each_interior_row(exec, &mut self.sigma_xy, |j, row| {
            let b = (j + HALO) * st + HALO;
            for i in 0..nxn {
                let t = tn[b + i];
                row[HALO + i] = if t > 0.0 { sn[b + i] / t } else { 0.0 };
            }
        });
    }

    /// Adds the plastic force div(τΣ) to `out_u`, `out_v` on every face (the caller uses the
    /// unknown ones):
    ///
    ///   u-face (i, j): [τ_c Σ_xx]_{i−1}^{i}/dx + [τ_n Σ_xy]_{j}^{j+1}/dy,
    ///   v-face (i, j): [τ_n Σ_xy]_{i}^{i+1}/dx − [τ_c Σ_xx]_{j−1}^{j}/dy   (Σ_yy = −Σ_xx).
    ///
    /// With `base = Some((b_u, b_v))` the result is out = b + div(τΣ): each row of b is copied
    /// into `out` in the force's own sweep (the same values as a copy followed by the addition).
    pub fn add_force(&mut self, grid: &Grid, base_rhs: Option<(&Field, &Field)>, out_u: &mut Field, out_v: &mut Field, exec: Exec) {
        let centred = self.centred.is_some();
        if centred {
            self.centred_shear_to_nodes(exec);
        }
        let pairs = [(&mut self.stress_c, &self.tau_c, &self.sigma_xx), (&mut self.stress_n, &self.tau_n, &self.sigma_xy)];
        for (stress, tau, sigma) in pairs.into_iter().take(if centred { 1 } else { 2 }) {
            let (ts, ss, st) = (tau.slice(), sigma.slice(), tau.stride());
            let n = stress.nx;
            for_each_interior_row(exec, stress, |j, row| {
                let b = (j + HALO) * st + HALO;
                rows::product(&ts[b..b + n], &ss[b..b + n], &mut row[HALO..HALO + n]);
            });
        }
        self.stress_c.extrapolate_ghosts_constant();
        let (sc, sn) = (self.stress_c.slice(), self.stress_n.slice());
        let (idx, idy, nx) = (1.0 / grid.dx, 1.0 / grid.dy, grid.nx);
        let (stress_c, stress_n) = (&self.stress_c, &self.stress_n);
        if let Some((bu, bv)) = base_rhs {
            copy_halo_rows(bu, out_u);
            copy_halo_rows(bv, out_v);
        }
        let base_u = base_rhs.map(|(bu, _)| (bu.slice(), bu.stride()));
        let base_v = base_rhs.map(|(_, bv)| (bv.slice(), bv.stride()));
        for_each_interior_row(exec, out_u, |j, row| {
            if let Some((b, st)) = base_u {
                row.copy_from_slice(&b[(j + HALO) * st..(j + HALO + 1) * st]);
            }
            let j = j as isize;
            let (bc, bn0, bn1) = (base(stress_c, j), base(stress_n, j), base(stress_n, j + 1));
            let n = nx + 1;
            rows::force_u(&sc[bc - 1..bc + n], &sn[bn0..bn0 + n], &sn[bn1..bn1 + n], idx, idy, &mut row[HALO..HALO + n]);
        });
        for_each_interior_row(exec, out_v, |j, row| {
            if let Some((b, st)) = base_v {
                row.copy_from_slice(&b[(j + HALO) * st..(j + HALO + 1) * st]);
            }
            let j = j as isize;
            let (bc0, bcm, bn) = (base(stress_c, j), base(stress_c, j - 1), base(stress_n, j));
            rows::force_v(&sn[bn..bn + nx + 1], &sc[bcm..bcm + nx], &sc[bc0..bc0 + nx], idx, idy, &mut row[HALO..HALO + nx]);
        });
    }

    /// One Picard update Σ^{k+1} = P(Σ^k + r D_dev(ũ) + θ(Σ^n − Σ^k)) from the strain rate of ũ
    /// (D_xx, D_yy at centres, D_xy at nodes), with r from the fields `r_c`, `r_n`. Σ is kept at
    /// 0 where τ = 0 (outside the granular phase) and on held boundary nodes. Returns the
    /// increment of the plastic stress that enters the momentum equation,
    /// max |τ (Σ^{k+1} − Σ^k)| / τ_max (= max |Σ^{k+1} − Σ^k| for a constant yield stress): Σ in
    /// the interface band, where τ → 0, converges slowest and matters least.
    pub fn update(&mut self, dxx: &Field, dyy: &Field, dxy: &Field, theta: f64, exec: Exec) -> f64 {
        // trial values at centres and nodes
        {
            let (sx, sxn, tc, a, b) = (self.sigma_xx.slice(), self.sigma_xx_n.slice(), self.tau_c.slice(), dxx.slice(), dyy.slice());
            let rc = self.r_c.slice();
            let st = self.sigma_xx.stride();
            let n = self.trial_c.nx;
            for_each_interior_row(exec, &mut self.trial_c, |j, row| {
                let bb = (j + HALO) * st + HALO;
                for i in 0..n {
                    let k = bb + i;
                    row[HALO + i] = if tc[k] > 0.0 { sx[k] + 0.5 * rc[k] * (a[k] - b[k]) + theta * (sxn[k] - sx[k]) } else { 0.0 };
                }
            });
        }
        self.trial_c.extrapolate_ghosts_constant();
        if self.centred.is_some() {
            return self.update_centred(dxy, theta, exec);
        }
        {
            let (sy, syn, tn, c) = (self.sigma_xy.slice(), self.sigma_xy_n.slice(), self.tau_n.slice(), dxy.slice());
            let rn = self.r_n.slice();
            let st = self.sigma_xy.stride();
            let (nxn, nyn) = (self.trial_n.nx, self.trial_n.ny);
            let z = self.zero_tangential;
            let held = move |i: usize, j: usize| node_held(&z, i, j, nxn, nyn);
            for_each_interior_row(exec, &mut self.trial_n, |j, row| {
                let bb = (j + HALO) * st + HALO;
                for i in 0..nxn {
                    let k = bb + i;
                    row[HALO + i] = if tn[k] > 0.0 && !held(i, j) { sy[k] + rn[k] * c[k] + theta * (syn[k] - sy[k]) } else { 0.0 };
                }
            });
        }
        if !self.locate {
            return self.project_in_place(exec);
        }
        // projections: at centres with Σ_xy averaged from the corners, at nodes with Σ_xx
        // averaged from the adjacent cells
        {
            let (tcs, tns) = (self.trial_c.slice(), self.trial_n.slice());
            let (trial_c, trial_n) = (&self.trial_c, &self.trial_n);
            let n = self.new_c.nx;
            for_each_interior_row(exec, &mut self.new_c, |j, row| {
                let j = j as isize;
                let (bc, bn0, bn1) = (base(trial_c, j), base(trial_n, j), base(trial_n, j + 1));
                for i in 0..n {
                    let xx = tcs[bc + i];
                    let xy = 0.25 * (tns[bn0 + i] + tns[bn0 + i + 1] + tns[bn1 + i] + tns[bn1 + i + 1]);
                    row[HALO + i] = xx * unit_ball_scale(xx, xy);
                }
            });
            let n = self.new_n.nx;
            for_each_interior_row(exec, &mut self.new_n, |j, row| {
                let j = j as isize;
                let (bn, bc0, bc1) = (base(trial_n, j), base(trial_c, j - 1), base(trial_c, j));
                for i in 0..n {
                    let xy = tns[bn + i];
                    let xx = 0.25 * (tcs[bc0 + i] + tcs[bc0 + i - 1] + tcs[bc1 + i] + tcs[bc1 + i - 1]);
                    row[HALO + i] = xy * unit_ball_scale(xx, xy);
                }
            });
        }
        let tau_ref = self.tau_max;
        let inc = weighted_max_abs_diff(&self.new_c, &self.sigma_xx, &self.tau_c, tau_ref, exec).max(weighted_max_abs_diff(
            &self.new_n,
            &self.sigma_xy,
            &self.tau_n,
            tau_ref,
            exec,
        ));
        if self.locate {
            let mut best: Option<(f64, Location, usize, usize)> = None;
            for (new, old, w, loc) in [(&self.new_c, &self.sigma_xx, &self.tau_c, Location::Centre), (&self.new_n, &self.sigma_xy, &self.tau_n, Location::Node)]
            {
                for j in 0..new.ny {
                    for i in 0..new.nx {
                        let (ii, jj) = (i as isize, j as isize);
                        let d = (new.at(ii, jj) - old.at(ii, jj)).abs() * w.at(ii, jj);
                        if best.is_none_or(|b| exceeds(d, b.0)) {
                            best = Some((d, loc, i, j));
                        }
                    }
                }
            }
            self.last_largest = best.map(|(d, l, i, j)| (if tau_ref > 0.0 { d / tau_ref } else { 0.0 }, l, i, j));
        }
        self.sigma_xx.assign(&self.new_c);
        self.sigma_xy.assign(&self.new_n);
        inc
    }

    /// [`PlasticState::update`] from the velocity ũ itself: D_dev(ũ) is computed in the sweeps
    /// that form the trial values, where Σ has a layout of its own (Σ_xy at nodes) and the
    /// largest increment is not located; otherwise the strain rate is written to `dxx`, `dyy`,
    /// `dxy` by [`crate::operators::strain_rate`] and [`PlasticState::update`] runs on them.
    /// Each D component and each trial value is computed by the same operations in the same
    /// order as in the separate sweeps: the result is the same bit for bit. With the fused
    /// sweeps `dxx`, `dyy`, `dxy` are not written.
    #[allow(clippy::too_many_arguments)]
    pub fn update_from_velocity(
        &mut self,
        u: &Field,
        v: &Field,
        grid: &Grid,
        (dxx, dyy, dxy): (&mut Field, &mut Field, &mut Field),
        theta: f64,
        exec: Exec,
    ) -> f64 {
        if self.centred.is_some() || self.locate {
            strain_rate(u, v, grid, dxx, dyy, dxy, exec);
            return self.update(dxx, dyy, dxy, theta, exec);
        }
        let (us, vs) = (u.slice(), v.slice());
        let (idx, idy) = (1.0 / grid.dx, 1.0 / grid.dy);
        {
            let (sx, sxn, tc) = (self.sigma_xx.slice(), self.sigma_xx_n.slice(), self.tau_c.slice());
            let rc = self.r_c.slice();
            let st = self.sigma_xx.stride();
            let n = self.trial_c.nx;
            for_each_interior_row(exec, &mut self.trial_c, |j, row| {
                let k = (j + HALO) * st + HALO..(j + HALO) * st + HALO + n;
                let (bu, bv0, bv1) = (base(u, j as isize), base(v, j as isize), base(v, j as isize + 1));
                rows::trial_xx(
                    &us[bu..bu + n + 1],
                    &vs[bv0..bv0 + n],
                    &vs[bv1..bv1 + n],
                    &sx[k.clone()],
                    &sxn[k.clone()],
                    &tc[k.clone()],
                    &rc[k],
                    idx,
                    idy,
                    theta,
                    &mut row[HALO..HALO + n],
                );
            });
        }
        self.trial_c.extrapolate_ghosts_constant();
        {
            let (sy, syn, tn) = (self.sigma_xy.slice(), self.sigma_xy_n.slice(), self.tau_n.slice());
            let rn = self.r_n.slice();
            let st = self.sigma_xy.stride();
            let (nxn, nyn) = (self.trial_n.nx, self.trial_n.ny);
            let z = self.zero_tangential;
            let held = move |i: usize, j: usize| node_held(&z, i, j, nxn, nyn);
            for_each_interior_row(exec, &mut self.trial_n, |j, row| {
                let k = (j + HALO) * st + HALO..(j + HALO) * st + HALO + nxn;
                let jj = j as isize;
                let (bu0, bu1, bv) = (base(u, jj - 1), base(u, jj), base(v, jj));
                let out = &mut row[HALO..HALO + nxn];
                rows::trial_xy(
                    &us[bu0..bu0 + nxn],
                    &us[bu1..bu1 + nxn],
                    &vs[bv - 1..bv + nxn],
                    &sy[k.clone()],
                    &syn[k.clone()],
                    &tn[k.clone()],
                    &rn[k],
                    idx,
                    idy,
                    theta,
                    out,
                );
                // held boundary nodes keep Σ_xy = 0 (the wall's tangential stress): a whole row
                // at a held bottom or top, the end nodes at a held left or right side
                if (j == 0 && z[2]) || (j + 1 == nyn && z[3]) {
                    out.fill(0.0);
                } else {
                    for i in [0, nxn - 1] {
                        if held(i, j) {
                            out[i] = 0.0;
                        }
                    }
                }
            });
        }
        self.project_in_place(exec)
    }

    /// The projections of [`PlasticState::update`] written straight into Σ, with the increment's
    /// maximum taken in the same sweep: Σ_xx ← P at centres (Λ_xy averaged from the corners),
    /// Σ_xy ← P at nodes (Λ_xx averaged from the adjacent cells), each value compared with the
    /// one it replaces. Every new value and every |τ(Σ^{k+1} − Σ^k)|/τ_max is computed by the
    /// same operations as in the separate sweeps (new values, then the two increments, then the
    /// copies), and a maximum does not depend on the order: the result is the same bit for bit.
    fn project_in_place(&mut self, exec: Exec) -> f64 {
        let scale = if self.tau_max > 0.0 { 1.0 / self.tau_max } else { 0.0 };
        let (tcs, tns) = (self.trial_c.slice(), self.trial_n.slice());
        let (trial_c, trial_n) = (&self.trial_c, &self.trial_n);
        let (tc, tn) = (self.tau_c.slice(), self.tau_n.slice());
        let n = self.sigma_xx.nx;
        let xx = for_each_interior_row_max(exec, &mut self.sigma_xx, |j, row| {
            let j = j as isize;
            let (bc, bn0, bn1) = (base(trial_c, j), base(trial_n, j), base(trial_n, j + 1));
            rows::project_xx(&tcs[bc..bc + n], &tns[bn0..bn0 + n + 1], &tns[bn1..bn1 + n + 1], &tc[bc..bc + n], &mut row[HALO..HALO + n], scale)
        });
        let n = self.sigma_xy.nx;
        let xy = for_each_interior_row_max(exec, &mut self.sigma_xy, |j, row| {
            let j = j as isize;
            let (bn, bc0, bc1) = (base(trial_n, j), base(trial_c, j - 1), base(trial_c, j));
            rows::project_xy(&tns[bn..bn + n], &tcs[bc0 - 1..bc0 + n], &tcs[bc1 - 1..bc1 + n], &tn[bn..bn + n], &mut row[HALO..HALO + n], scale)
        });
        xx.max(xy)
    }

    /// [`PlasticState::update`] with Σ_xy at centres (`trial_c` holds Λ_xx): the trial
    /// Λ_xy = Σ_xy + r D_xy + θ(Σ_xy^n − Σ_xy) with D_xy averaged from the four corner nodes
    /// (held boundary nodes count as 0: their tangential stress is the wall's), then the pair is
    /// projected at the centre.
    fn update_centred(&mut self, dxy: &Field, theta: f64, exec: Exec) -> f64 {
        let cs = self.centred.as_mut().expect("centred layout");
        {
            let (sy, syn, tc, rc, d) = (cs.sigma.slice(), cs.sigma_n.slice(), self.tau_c.slice(), self.r_c.slice(), dxy.slice());
            let st = cs.sigma.stride();
            let n = cs.trial.nx;
            let (nxn, nyn) = (dxy.nx, dxy.ny);
            let z = self.zero_tangential;
            let dn = |i: usize, j: usize| if node_held(&z, i, j, nxn, nyn) { 0.0 } else { d[base(dxy, j as isize) + i] };
            for_each_interior_row(exec, &mut cs.trial, |j, row| {
                let bb = (j + HALO) * st + HALO;
                for i in 0..n {
                    let k = bb + i;
                    row[HALO + i] = if tc[k] > 0.0 {
                        let dc = 0.25 * (dn(i, j) + dn(i + 1, j) + dn(i, j + 1) + dn(i + 1, j + 1));
                        sy[k] + rc[k] * dc + theta * (syn[k] - sy[k])
                    } else {
                        0.0
                    };
                }
            });
        }
        if !self.locate {
            // the pair projected straight into Σ, each component's increment in its sweep (the
            // same values and the same maximum as the separate sweeps below)
            let scale = if self.tau_max > 0.0 { 1.0 / self.tau_max } else { 0.0 };
            let (xxs, xys, tc, st) = (self.trial_c.slice(), cs.trial.slice(), self.tau_c.slice(), cs.trial.stride());
            let n = self.sigma_xx.nx;
            let project = |component: usize| {
                move |j: usize, row: &mut [f64]| {
                    let b = (j + HALO) * st + HALO;
                    let mut m = 0.0f64;
                    for i in 0..n {
                        let (xx, xy) = (xxs[b + i], xys[b + i]);
                        let new = (if component == 0 { xx } else { xy }) * unit_ball_scale(xx, xy);
                        let d = (new - row[HALO + i]).abs() * tc[b + i] * scale;
                        m = if d.is_nan() { f64::NAN } else { m.max(d) };
                        row[HALO + i] = new;
                    }
                    m
                }
            };
            let xx = for_each_interior_row_max(exec, &mut self.sigma_xx, project(0));
            return xx.max(for_each_interior_row_max(exec, &mut cs.sigma, project(1)));
        }
        {
            let (xxs, xys, st) = (self.trial_c.slice(), cs.trial.slice(), cs.trial.stride());
            let n = self.new_c.nx;
            let new_xy = &mut cs.new;
            // both components of the pair at once: rows of new_c and of new_xy
            for_each_interior_row(exec, &mut self.new_c, |j, row| {
                let b = (j + HALO) * st + HALO;
                for i in 0..n {
                    let (xx, xy) = (xxs[b + i], xys[b + i]);
                    row[HALO + i] = xx * unit_ball_scale(xx, xy);
                }
            });
            for_each_interior_row(exec, new_xy, |j, row| {
                let b = (j + HALO) * st + HALO;
                for i in 0..n {
                    let (xx, xy) = (xxs[b + i], xys[b + i]);
                    row[HALO + i] = xy * unit_ball_scale(xx, xy);
                }
            });
        }
        let tau_ref = self.tau_max;
        let inc = weighted_max_abs_diff(&self.new_c, &self.sigma_xx, &self.tau_c, tau_ref, exec).max(weighted_max_abs_diff(
            &cs.new,
            &cs.sigma,
            &self.tau_c,
            tau_ref,
            exec,
        ));
        if self.locate {
            let mut best: Option<(f64, Location, usize, usize)> = None;
            for (new, old) in [(&self.new_c, &self.sigma_xx), (&cs.new, &cs.sigma)] {
                for j in 0..new.ny {
                    for i in 0..new.nx {
                        let (ii, jj) = (i as isize, j as isize);
                        let d = (new.at(ii, jj) - old.at(ii, jj)).abs() * self.tau_c.at(ii, jj);
                        if best.is_none_or(|b| exceeds(d, b.0)) {
                            best = Some((d, Location::Centre, i, j));
                        }
                    }
                }
            }
            self.last_largest = best.map(|(d, l, i, j)| (if tau_ref > 0.0 { d / tau_ref } else { 0.0 }, l, i, j));
        }
        self.sigma_xx.assign(&self.new_c);
        cs.sigma.assign(&cs.new);
        inc
    }

    /// End of a converged Picard loop: with Σ_xy at centres, brings the nodal equivalent in
    /// `sigma_xy` (energy budget, checkpoint, views) up to the final Σ (the force refreshes it at
    /// the start of each iteration; nothing to do for the staggered layout).
    pub fn end_step(&mut self, exec: Exec) {
        self.centred_shear_to_nodes(exec);
    }

    /// |Λ| of the argument Λ = Σ + r D_dev + θ(Σ^n − Σ) of the last centre projection (Λ_xy
    /// averaged from the corners) into `out`: at the fixed point |Λ| ≤ 1 exactly where the
    /// material is rigid (D = 0), > 1 where it yields (there Σ = Λ/|Λ|).
    pub fn trial_norm_centre(&self, out: &mut Field, exec: Exec) {
        if let Some(cs) = &self.centred {
            let (a, b, st, n) = (self.trial_c.slice(), cs.trial.slice(), out.stride(), out.nx);
            for_each_interior_row(exec, out, |j, row| {
                let k = (j + HALO) * st + HALO;
                for i in 0..n {
                    row[HALO + i] = a[k + i].hypot(b[k + i]);
                }
            });
            return;
        }
        // Λ is traceless (Λ_yy = −Λ_xx), so ½(Λ_xx² + Λ_yy²) + Λ_xy² = Λ_xx² + Λ_xy²: the strain-rate
        // norm kernel with Λ_xx in both diagonal slots gives |Λ| exactly
        strain_rate_norm_centre(&self.trial_c, &self.trial_c, &self.trial_n, out, exec);
    }
}

/// Whether the node (i, j) of an `nxn` × `nyn` node array lies on a side whose tangential
/// stress is not carried by Σ (flags in the order left, right, bottom, top).
#[inline]
pub(crate) fn node_held(z: &[bool; 4], i: usize, j: usize, nxn: usize, nyn: usize) -> bool {
    (i == 0 && z[0]) || (i + 1 == nxn && z[1]) || (j == 0 && z[2]) || (j + 1 == nyn && z[3])
}

/// Largest half-width (in cells) of the neighbourhood over which the default r takes the
/// largest k (`RheologyConfig::r_neighbourhood`).
pub const MAX_R_NEIGHBOURHOOD: usize = 4;

impl PlasticState {
    /// Sets r at centres and nodes: the constant `r` if given, else the local default
    /// r = (1 − θ)/(τ k̄), with k̄ the largest k = 2S/(c + 4ηS) (S = 2(1/dx² + 1/dy²),
    /// c = a₀ρ/δt with ρ the lightest of the cell's four faces, η of the cell) over the
    /// (2w + 1)² cells around the point, w = `neighbourhood` (for a node: around its four cells).
    /// Returns the smallest r where τ > 0 (the value reported per step; 0 if τ = 0 everywhere).
    #[allow(clippy::too_many_arguments)]
    /// Multiplies r at centres and nodes by `f` (the stall safeguard of the Picard loop).
    pub fn scale_r(&mut self, f: f64) {
        self.r_c.slice_mut().iter_mut().for_each(|v| *v *= f);
        self.r_n.slice_mut().iter_mut().for_each(|v| *v *= f);
    }

    #[allow(clippy::too_many_arguments)]
    pub fn set_r(
        &mut self,
        r: Option<f64>,
        theta: f64,
        neighbourhood: usize,
        eta_c: &Field,
        rho_u: &Field,
        rho_v: &Field,
        a0_over_dt: f64,
        grid: &Grid,
        exec: Exec,
    ) -> f64 {
        if let Some(r) = r {
            self.r_c.fill(r);
            self.r_n.fill(r);
            return r;
        }
        let s = 2.0 * (1.0 / (grid.dx * grid.dx) + 1.0 / (grid.dy * grid.dy));
        let (nx, ny) = (grid.nx as isize, grid.ny as isize);
        // k at centres (scratch: new_c), its neighbourhood maximum (scratch: trial_c)
        {
            let (rs, rvs, es) = (rho_u.slice(), rho_v.slice(), eta_c.slice());
            let n = self.new_c.nx;
            for_each_interior_row(exec, &mut self.new_c, |j, row| {
                let (bc, bu) = (base(eta_c, j as isize), base(rho_u, j as isize));
                let (bv0, bv1) = (base(rho_v, j as isize), base(rho_v, j as isize + 1));
                for i in 0..n {
                    // the lightest of the cell's four faces (the largest velocity response)
                    let rho = rs[bu + i].min(rs[bu + i + 1]).min(rvs[bv0 + i]).min(rvs[bv1 + i]);
                    let c = a0_over_dt * rho;
                    row[HALO + i] = 2.0 * s / (c + 4.0 * es[bc + i] * s);
                }
            });
        }
        {
            let k = &self.new_c;
            let w = neighbourhood as isize;
            for_each_interior_row(exec, &mut self.trial_c, |j, row| {
                let j = j as isize;
                for i in 0..nx {
                    let mut m = 0.0f64;
                    for jj in (j - w).max(0)..=(j + w).min(ny - 1) {
                        for ii in (i - w).max(0)..=(i + w).min(nx - 1) {
                            m = m.max(k.at(ii, jj));
                        }
                    }
                    row[HALO + i as usize] = m;
                }
            });
        }
        self.trial_c.extrapolate_ghosts_constant();
        let kmax = &self.trial_c;
        let ks = kmax.slice();
        {
            let ts = self.tau_c.slice();
            let n = self.r_c.nx;
            for_each_interior_row(exec, &mut self.r_c, |j, row| {
                let b = base(kmax, j as isize);
                for i in 0..n {
                    let t = ts[b + i];
                    row[HALO + i] = if t > 0.0 { (1.0 - theta) / (t * ks[b + i]) } else { 0.0 };
                }
            });
        }
        {
            let ts = self.tau_n.slice();
            let tau_n = &self.tau_n;
            let n = self.r_n.nx;
            for_each_interior_row(exec, &mut self.r_n, |j, row| {
                let j = j as isize;
                let (bn, b0, b1) = (base(tau_n, j), base(kmax, j - 1), base(kmax, j));
                for i in 0..n {
                    let k = ks[b0 + i].max(ks[b0 + i - 1]).max(ks[b1 + i]).max(ks[b1 + i - 1]);
                    let t = ts[bn + i];
                    row[HALO + i] = if t > 0.0 { (1.0 - theta) / (t * k) } else { 0.0 };
                }
            });
        }
        let (rc, tc, st, n) = (self.r_c.slice(), self.tau_c.slice(), self.r_c.stride(), self.r_c.nx);
        let m = exec.max_rows(self.r_c.ny, n * self.r_c.ny, |j| {
            let b = (j + HALO) * st + HALO;
            let mut m = 0.0f64;
            for i in 0..n {
                if tc[b + i] > 0.0 {
                    m = m.max(1.0 / rc[b + i]);
                }
            }
            m
        });
        if m > 0.0 {
            1.0 / m
        } else {
            0.0
        }
    }
}

/// Where the last Picard iteration changed the stresses most: the plastic tensor at a cell
/// centre (Σ_xx) or node (Σ_xy), or the friction direction s on a wall face.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum IncrementSite {
    Plastic { location: Location, i: usize, j: usize, increment: f64 },
    Wall { side: Side, face: usize, increment: f64 },
}

impl IncrementSite {
    /// The weighted increment there.
    pub fn increment(&self) -> f64 {
        match *self {
            IncrementSite::Plastic { increment, .. } | IncrementSite::Wall { increment, .. } => increment,
        }
    }
}

/// How the message of a Picard non-convergence ([`Error::PicardNotConverged`]) begins.
pub const PICARD_FAILURE: &str = "Picard iteration of the plastic projection did not converge";

/// The error of a Picard iteration that reached its cap, naming where the largest increment was.
#[allow(clippy::too_many_arguments)]
pub fn not_converged(increment: f64, iterations: usize, tol: f64, r: f64, theta: f64, step: u64, time: f64, site: Option<IncrementSite>) -> Error {
    let place = match site {
        Some(IncrementSite::Plastic { location, i, j, increment }) => {
            let what = if location == Location::Node { "Sigma_xy at node" } else { "Sigma_xx at cell" };
            format!("; largest increment {increment:.3e} in {what} (i={i}, j={j})")
        }
        Some(IncrementSite::Wall { side, face, increment }) => {
            format!("; largest increment {increment:.3e} in the wall friction of the {side:?} side, face {face}")
        }
        None => String::new(),
    };
    Error::PicardNotConverged {
        what: format!(
            "{PICARD_FAILURE}: increment {increment:.3e} after {iterations} iterations \
             (picard_tol = {tol:.1e}, r = {r:.3e} (smallest), theta = {theta}){place}; raise picard_max_iterations or theta, or lower r"
        ),
        step,
        time,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The row kernels' two copies (AVX2 where the CPU has it, and the build target's) give the
    /// same bits on rows whose trial values lie inside and outside the unit ball, and a NaN
    /// anywhere in a row makes the projection's row maximum NaN.
    #[test]
    fn row_kernels_agree_across_instruction_sets_and_propagate_nan() {
        let mut rows = crate::operators::random_rows(7);
        let mut rnd = |n: usize, amp: f64| -> Vec<f64> { rows(n).iter().map(|v| amp * v).collect() };
        let n = 37;
        let (a, b0, b1, tau) = (rnd(n + 1, 3.0), rnd(n + 1, 3.0), rnd(n + 1, 3.0), rnd(n, 1.0).iter().map(|t| t.abs()).collect::<Vec<_>>());
        let old = rnd(n, 1.0);
        for (f, g) in [
            (
                rows::project_xx as fn(&[f64], &[f64], &[f64], &[f64], &mut [f64], f64) -> f64,
                rows::project_xx_base as fn(&[f64], &[f64], &[f64], &[f64], &mut [f64], f64) -> f64,
            ),
            (rows::project_xy, rows::project_xy_base),
        ] {
            let (mut o1, mut o2) = (old.clone(), old.clone());
            let (m1, m2) = (f(&a, &b0, &b1, &tau, &mut o1, 0.5), g(&a, &b0, &b1, &tau, &mut o2, 0.5));
            assert!(m1 > 0.0 && m1.to_bits() == m2.to_bits());
            assert_eq!(o1.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), o2.iter().map(|v| v.to_bits()).collect::<Vec<_>>());
            assert!(o1.iter().any(|v| v.abs() < 1.0) && a.iter().any(|v| v.abs() > 1.0), "rows inside and outside the ball");
            let mut bad = a.clone();
            bad[n / 2] = f64::NAN;
            assert!(f(&bad, &b0, &b1, &tau, &mut old.clone(), 0.5).is_nan() && g(&bad, &b0, &b1, &tau, &mut old.clone(), 0.5).is_nan());
        }
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let (mut u1, mut u2) = (old.clone(), old.clone());
        rows::force_u(&a, &b0[..n], &b1[..n], 3.0, 7.0, &mut u1);
        rows::force_u_base(&a, &b0[..n], &b1[..n], 3.0, 7.0, &mut u2);
        assert_eq!(bits(&u1), bits(&u2));
        rows::force_v(&a, &b0[..n], &b1[..n], 3.0, 7.0, &mut u1);
        rows::force_v_base(&a, &b0[..n], &b1[..n], 3.0, 7.0, &mut u2);
        assert_eq!(bits(&u1), bits(&u2));
        rows::product(&a, &b0, &mut u1);
        rows::product_base(&a, &b0, &mut u2);
        assert_eq!(bits(&u1), bits(&u2));
        let signed_tau = rnd(n, 1.0);
        rows::trial_xx(&a, &b0, &b1, &old, &b0, &signed_tau, &tau, 3.0, 7.0, 0.8, &mut u1);
        rows::trial_xx_base(&a, &b0, &b1, &old, &b0, &signed_tau, &tau, 3.0, 7.0, 0.8, &mut u2);
        assert_eq!(bits(&u1), bits(&u2));
        assert!(u1.iter().zip(&signed_tau).all(|(t, s)| (*s > 0.0) != (*t == 0.0)), "zero exactly where τ ≤ 0");
        rows::trial_xy(&b0, &b1, &a, &old, &b1, &signed_tau, &tau, 3.0, 7.0, 0.8, &mut u1);
        rows::trial_xy_base(&b0, &b1, &a, &old, &b1, &signed_tau, &tau, 3.0, 7.0, 0.8, &mut u2);
        assert_eq!(bits(&u1), bits(&u2));
    }

    /// A state on an 80 × 64 grid (more cells than the parallel threshold) with a yield stress
    /// that vanishes in a corner, Σ, Σⁿ, r and a strain rate from a fixed pseudo-random sequence
    /// scaled so that part of the trial values lie outside the unit ball.
    fn state(location: SigmaLocation) -> (PlasticState, [Field; 3]) {
        let grid = Grid::new(80, 64, 1.0, 0.8).unwrap();
        let bc = BoundaryConditions::uniform(VelocityBc::FreeSlip).with(Side::Top, VelocityBc::Outflow);
        let mut p = PlasticState::new(&grid, &bc, location);
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut fill = |f: &mut Field, scale: f64, zero_corner: bool| {
            for j in 0..f.ny {
                for i in 0..f.nx {
                    let v = if zero_corner && i < 10 && j + 10 > f.ny { 0.0 } else { scale * next() };
                    f.set(i, j, v);
                }
            }
        };
        fill(&mut p.tau_c, 1.0, true);
        fill(&mut p.tau_n, 1.0, true);
        for f in [&mut p.tau_c, &mut p.tau_n] {
            f.slice_mut().iter_mut().for_each(|x| *x = x.abs());
        }
        p.tau_max = 0.5;
        fill(&mut p.sigma_xx, 1.2, false);
        fill(&mut p.sigma_xy, 1.2, false);
        fill(&mut p.sigma_xx_n, 1.2, false);
        fill(&mut p.sigma_xy_n, 1.2, false);
        fill(&mut p.r_c, 1.0, false);
        fill(&mut p.r_n, 1.0, false);
        if let Some(cs) = p.centred.as_mut() {
            fill(&mut cs.sigma, 1.2, false);
            fill(&mut cs.sigma_n, 1.2, false);
        }
        let mut d = [Field::zeros(&grid, Location::Centre), Field::zeros(&grid, Location::Centre), Field::zeros(&grid, Location::Node)];
        for f in d.iter_mut() {
            fill(f, 3.0, false);
        }
        (p, d)
    }

    #[test]
    fn force_onto_a_base_equals_the_copy_and_the_addition() {
        let grid = Grid::new(80, 64, 1.0, 0.8).unwrap();
        for location in [SigmaLocation::Staggered, SigmaLocation::Centres] {
            let (mut p, _) = state(location);
            let mut base = [Field::zeros(&grid, Location::XFace), Field::zeros(&grid, Location::YFace)];
            for (k, f) in base.iter_mut().enumerate() {
                f.slice_mut().iter_mut().enumerate().for_each(|(n, x)| *x = ((n * 7 + k * 3) % 23) as f64 - 11.0);
            }
            let (mut ru, mut rv) = (base[0].clone(), base[1].clone());
            p.add_force(&grid, None, &mut ru, &mut rv, Exec::SERIAL);
            for exec in [Exec::SERIAL, Exec { parallel: true }] {
                let (mut fu, mut fv) = (Field::zeros(&grid, Location::XFace), Field::zeros(&grid, Location::YFace));
                let pool = crate::exec::build_pool(2).unwrap();
                pool.install(|| p.add_force(&grid, Some((&base[0], &base[1])), &mut fu, &mut fv, exec));
                let bits = |f: &Field| f.slice().iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&fu), bits(&ru), "{location:?} {exec:?}");
                assert_eq!(bits(&fv), bits(&rv), "{location:?} {exec:?}");
            }
        }
    }

    fn interior_bits(f: &Field) -> Vec<u64> {
        (0..f.ny).flat_map(|j| (0..f.nx).map(move |i| (i, j))).map(|(i, j)| f.at(i as isize, j as isize).to_bits()).collect()
    }

    #[test]
    fn projection_in_place_equals_the_separate_sweeps_bit_for_bit() {
        for location in [SigmaLocation::Staggered, SigmaLocation::Centres] {
            let (mut reference, d) = state(location);
            reference.locate = true;
            let inc_ref = reference.update(&d[0], &d[1], &d[2], 0.8, Exec::SERIAL);
            assert!(inc_ref > 0.0 && inc_ref.is_finite());
            let clamped = (0..reference.sigma_xx.ny).any(|j| (0..reference.sigma_xx.nx).any(|i| reference.trial_c.at(i as isize, j as isize).abs() > 1.0));
            assert!(clamped, "some trial values must lie outside the unit ball");
            for exec in [Exec::SERIAL, Exec { parallel: true }] {
                let (mut fused, d) = state(location);
                fused.locate = false;
                let pool = crate::exec::build_pool(2).unwrap();
                let inc = pool.install(|| fused.update(&d[0], &d[1], &d[2], 0.8, exec));
                assert_eq!(inc.to_bits(), inc_ref.to_bits(), "{location:?} {exec:?}");
                assert_eq!(interior_bits(&fused.sigma_xx), interior_bits(&reference.sigma_xx));
                assert_eq!(interior_bits(&fused.sigma_xy), interior_bits(&reference.sigma_xy));
                if let (Some(a), Some(b)) = (&fused.centred, &reference.centred) {
                    assert_eq!(interior_bits(&a.sigma), interior_bits(&b.sigma));
                }
            }
        }
    }

    #[test]
    fn update_from_the_velocity_equals_the_strain_rate_then_the_update_bit_for_bit() {
        let grid = Grid::new(80, 64, 1.0, 0.8).unwrap();
        let mut vel = [Field::zeros(&grid, Location::XFace), Field::zeros(&grid, Location::YFace)];
        for (k, f) in vel.iter_mut().enumerate() {
            // ghosts included: both paths read the velocity's ghost rows and columns
            f.slice_mut().iter_mut().enumerate().for_each(|(n, x)| *x = 0.04 * (((n * 13 + k * 5) % 31) as f64 - 15.0));
        }
        for location in [SigmaLocation::Staggered, SigmaLocation::Centres] {
            let (mut reference, mut d) = state(location);
            reference.locate = true;
            let [dxx, dyy, dxy] = &mut d;
            strain_rate(&vel[0], &vel[1], &grid, dxx, dyy, dxy, Exec::SERIAL);
            let inc_ref = reference.update(&d[0], &d[1], &d[2], 0.8, Exec::SERIAL);
            assert!(inc_ref > 0.0 && inc_ref.is_finite());
            for exec in [Exec::SERIAL, Exec { parallel: true }] {
                let (mut fused, mut d) = state(location);
                fused.locate = false;
                let pool = crate::exec::build_pool(2).unwrap();
                let [dxx, dyy, dxy] = &mut d;
                let inc = pool.install(|| fused.update_from_velocity(&vel[0], &vel[1], &grid, (dxx, dyy, dxy), 0.8, exec));
                assert_eq!(inc.to_bits(), inc_ref.to_bits(), "{location:?} {exec:?}");
                assert_eq!(interior_bits(&fused.trial_c), interior_bits(&reference.trial_c));
                assert_eq!(interior_bits(&fused.sigma_xx), interior_bits(&reference.sigma_xx));
                assert_eq!(interior_bits(&fused.sigma_xy), interior_bits(&reference.sigma_xy));
                if let (Some(a), Some(b)) = (&fused.centred, &reference.centred) {
                    assert_eq!(interior_bits(&a.sigma), interior_bits(&b.sigma));
                }
            }
        }
    }
}
