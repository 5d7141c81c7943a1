//! The exact step of the bi-projection: eq. (11) of Aravena et al. solved as one convex problem
//! by a semismooth Newton method (Hintermüller, Ito & Kunisch 2002, *SIAM J. Optim.* 13; for
//! viscoplastic flows: Saramito 2016, *J. Non-Newton. Fluid Mech.* 238; the two-location plastic
//! functional: Muravleva & Olshanskii 2008, *Russ. J. Numer. Anal. Math. Model.* 23).
//!
//! **The discrete problem.** With the yield stress τ = tan(α) p^n H_ε(Φ^{n+1}) and the walls'
//! τ_b lagged (fixed during the step), the predictor ũ of eq. (11) is the minimiser of
//!
//!   J(u) = ½ uᵀA u − bᵀu + Σ_c τ_c |B_c u + β_c| + Σ_n f_n τ_n |B_n u + β_n| + Σ_f (τ_b,f/h_n) |u_f|,
//!
//! per unit volume of a face, over the unknown faces u: A = c + Dᵀ(2η)D is the predictor's
//! operator (c = a₀ρ/δt), b its right-hand side. The plastic dissipation 2τ|D| is split half
//! at the cell centres c and half at the nodes n, each location with the full deviatoric rate:
//! B_c u = (½(D_xx − D_yy), D_xy averaged from the four corners) at a centre and
//! B_n u = (½(D_xx − D_yy) averaged over the in-domain neighbour cells, D_xy) at a node
//! (f_n: the node's share of a cell area inside the domain; nodes on free-slip and Coulomb
//! sides carry no plastic term: their tangential stress is the wall's); β the affine part of
//! the boundary data. The friction term runs over the Coulomb walls' tangential faces (the row
//! next to the wall, `walls/mod.rs`). J is strictly convex (A ≥ c > 0) and each term is a
//! Euclidean norm, so ũ is unique and is a second-order cone program's solution.
//!
//! Its optimality conditions are eq. (11) with one multiplier σ_k per term, |σ_k| ≤ 1:
//!
//!   F_u = A u − b + Σ_k w_k B_kᵀ σ_k = 0,    F_k = σ_k − P(σ_k + r_k (B_k u + β_k)) = 0,
//!
//! P the projection on the unit ball (of R² for a plastic location, R for a face), any r_k > 0:
//! σ_c is Σ at the centre, σ_n at the node, and a wall's σ_f = −s (s of eq. 9). The plastic force
//! −Σ w_k B_kᵀσ_k is div(τΣ) with τΣ_xx = ½(τ_c σ_c,xx + Σ_n f_n τ_n σ_n,xx/m_n) at a centre and
//! τΣ_xy = ½(τ_n σ_n,xy + Σ_c τ_c σ_c,xy/4) at a node (m_n the node's in-domain cells); those
//! are the Σ_xx, Σ_xy that the model stores and shows.
//!
//! **Semismooth Newton.** With z_k = σ_k + r_k(B_k u + β_k), G_k the generalised derivative of
//! P at z_k (I inside the ball, (I − nnᵀ)/|z_k| outside, n = z_k/|z_k|) and a small δ > 0, one
//! step eliminates the multipliers: dσ_k = S_k B_k du − t_k with
//! S_k = r_k (I − G_k + δI)⁻¹ G_k, t_k = (I − G_k + δI)⁻¹ F_k, and
//!
//!   (A + Σ_k w_k B_kᵀ S_k B_k) du = −F_u + Σ_k w_k B_kᵀ t_k,
//!
//! a sparse system on a pattern built once per step (`cone::Assembly`: the place of each
//! coefficient found once), factorised by faer's supernodal sparse Cholesky (LU where A is not
//! symmetric) and refined [`REFINEMENTS`] times against the matrix applied term by term. A
//! flowing location adds the Hessian of w|B u| (the viscosity w/|B u| across the flow
//! direction); a rigid one adds the penalty
//! (w r/δ) BᵀB that holds B u = 0, whose multiplier σ is updated from it. δ changes the step,
//! not the fixed point: at convergence F = 0 exactly. The step is damped by backtracking on
//! the merit ‖F_u‖²/s² + Σ|F_k|². A and B are read from the model's own matrix-free kernels
//! (`viscous_helmholtz`, `strain_rate`) by probing them with coloured unit vectors (faces five
//! apart in each direction never share a stencil), so the boundary rules are those of the
//! predictor and of the strain rate; B, which depends on the grid and the boundaries alone, is
//! probed on the first step only.
//!
//! **Block sweeps.** The terms reach only the faces G of the granular layer (1–14 % of the
//! unknowns on the column at ny = 16–64); on the rest R the step is linear, A_RR x_R = b_R −
//! A_RG x_G. Where A is symmetric and G at most [`SPLIT_SHARE`] of the unknowns, the step
//! alternates (block Gauss–Seidel): x_R for the current x_G, then the nonlinear problem on G
//! with x_R fixed (b_G − A_GR x_R on its right) by the three stages below, then x_R again, until
//! the whole problem's residuals (below) are within the tolerance, at most [`MAX_SWEEPS`] times.
//! x_R comes from a conjugate-gradient iteration on A masked to R, preconditioned by its
//! diagonal (`cone::solve_block`). G and R are coupled only by A's viscous part, about
//! 2ηδt/(ρh²) ≪ 1 of its diagonal on the column, so each sweep multiplies the coupling's error
//! by about its square: one sweep in most steps (ny = 32 to 0.1 s: 57 for 56 steps dry, 55 for
//! 50 fluidised), and from the second the stages start within `POLISH_START` (below). The
//! stages' test on G counts each face's scale and the largest of R's (`Scales`) as the whole
//! problem's test does, so it is the whole test with x_R fixed. Every factorisation is then of
//! G's size, and R costs a few products with A a sweep.
//!
//! **Three stages.** The semismooth loop starts from the previous step's u and σ (δ =
//! [`NEWTON_DELTA`]). Once its momentum residual (relative, 2-norm) and its projection residual
//! with the iteration's r_k are both below 1e-4 (`interior_point::POLISH_START`), or after
//! [`WARM_TRIES`] iterations if they are not (after [`WARM_CHECK`] if the stopping test's
//! projection residual is still above [`WARM_GIVE_UP`]: near rest, where the warm start's rigid
//! locations send the loop away), the method of multipliers of `augmented.rs` finishes
//! the step: in the second case from the interior-point solution of `interior_point.rs` (the
//! same cone program, solved afresh from the predictor without yield stress down to that
//! residual; its iteration count depends little on the grid). In the first case it has
//! [`NEAR_BUDGET`] factorisations; if it has not converged by then, the step goes on as in the
//! second (the loop's multipliers at rigid locations can be far from any solution's). Each update of the method of
//! multipliers leaves the momentum equation satisfied and moves σ by a proximal step on the
//! dual problem, so it converges where the multipliers are not unique: locations and friction
//! faces at rest on the edge of their ball (|z_k| = 1), whose share of the load the force
//! balance leaves free, and where a Newton step on (u, σ) together has no unique direction.
//!
//! **Measured (docs/validation.md "The exact step of eq. (11)").** Its solution agrees with an
//! independent interior-point solution of the same cone program to 3.1e-8 (x) at ny = 8–32.
//! Newton matrices solved per step, column to t = 0.1 s (median): dry 4–37 at ny = 8–128,
//! fluidised 2–7 at ny = 8–128 (the interior point's included where it runs); near rest about 35,
//! where every step takes the interior point. The dry and fluidised columns run to 3 s at ny = 32
//! and 64 and meet the rest criterion before 2.2 s. To t = 0.1 s it costs 2.4–2.8 times the Picard
//! iteration on the fluidised column and 5.9–13 times on the dry one at ny = 16–32; whole runs to
//! rest cost 8.6–10.6 times Picard's (which never rests) and 2.3–3.6 times the deposit-at-rest
//! recipe's at ny = 32–64 (`benchmarks/solver_cost.py`): the column's default is the Picard
//! iteration.
//!
//! **The iteration's r_k** is d_k/(w_k ‖B_k‖²) (d_k the largest diagonal of A on the term's
//! faces: the scale at which a unit change of σ_k and of r_k B_k u are comparable). It spans
//! 1e5–1e12 on the column (A's diagonal reaches 1e11 in the grains, w_k falls to 1e-5 at the
//! surface), so it is not the stopping test's.
//!
//! **Stopping test: the residual of eq. (11), in norms that do not grow with the grid or with
//! r_k.** The loop stops when both are below `newton_tol`:
//! - the momentum residual max_f |F_u,f| / max_f (|b_f| + |(Au)_f| + |(Σ w_k B_kᵀσ_k)_f|);
//! - the projection residual max_k |σ_k − P(σ_k + r̂_k(B_k u + β_k))| with one r̂ for all
//!   locations: r̂ = h/U at a plastic location and 1/U at a friction face, h = min(δx, δy) and
//!   U = max_f |b_f|/A_ff (the largest velocity a face reaches in the step with neither coupling
//!   nor yield stress). A rigid location then counts |B_k u| relative to U/h, and the residual's
//!   round-off floor is that of u, about 1e-16; with the iteration's r_k it would be up to
//!   r_k·1e-16|B_k||u| ~ 1e-4.
//!
//! It fails with the step, time and residual after `newton_max_iterations`.

#![allow(clippy::needless_range_loop)] // the loops run over a term's one or two components

use faer::sparse::Triplet;

use super::cone::{apply, compress, is_symmetric, norm, onto_ball, solve_block, solve_predictor, Assembly, Program, Slot, SymbolicCache, Term};
use super::{augmented, interior_point};
use crate::error::{Error, Result};
use crate::exec::Exec;
use crate::grid::{BoundaryConditions, Field, Grid, Location, Side, VelocityBc};
use crate::operators::{fill_velocity_ghosts, periodic_pair, strain_rate, unknown_face_range, viscous_helmholtz, BcMode};
use crate::walls::CoulombWalls;
use std::ops::Range;

/// δ of the Newton matrix (module doc): the relative stiffness 1/δ of a rigid location's penalty.
pub const NEWTON_DELTA: f64 = 1e-4;

/// The augmented-Lagrangian stage's penalties c_k = r_k/AUGMENTED_DELTA (`augmented.rs`).
pub const AUGMENTED_DELTA: f64 = 1e-5;

/// Semismooth Newton iterations from the warm start before the interior point takes over.
pub const WARM_TRIES: usize = 6;

/// Semismooth Newton iterations from the warm start after which a projection residual (the
/// stopping test's) above [`WARM_GIVE_UP`] hands the step to the interior point.
pub const WARM_CHECK: usize = 2;

/// See [`WARM_CHECK`]: a multiplier still off by half its ball's radius.
pub const WARM_GIVE_UP: f64 = 0.5;

/// Factorisations the method of multipliers may take from the semismooth loop's point (its
/// residuals below `interior_point::POLISH_START`) before the step goes to the interior point.
/// Where the loop's multipliers are good (the fluidised column) it converges in 0–2; where they
/// are not (the dry column at ny = 32 to 0.1 s) it took 10–39, and once 77 updates without
/// reaching 1e-9 in 100 factorisations (t = 0.062 s), against 8–27 for the interior point and
/// the method of multipliers from its point.
pub const NEAR_BUDGET: usize = 5;

/// Iterative refinements of each Newton solve.
pub const REFINEMENTS: usize = 2;

/// Backtracking halvings of one Newton step at most.
const MAX_HALVINGS: usize = 12;

/// The largest share of the unknowns that the faces the terms reach (G) may hold for the step to
/// run as block sweeps over G and the rest (`sweeps`); above it, or where A is not symmetric,
/// the whole problem is iterated at once.
pub const SPLIT_SHARE: f64 = 0.5;

/// Block sweeps of one step at most.
pub const MAX_SWEEPS: usize = 10;

/// Colour period of the strain rate's probes along a non-periodic direction: faces five apart
/// never share a stencil or its ghosts (the strain rate and A on the first step).
const PERIOD: usize = 5;

/// Colour period of A's probes after the first step: A's rows reach one index in each
/// direction, ghosts included (`fill_velocity_ghosts` mirrors a ghost onto the face next to
/// the side), so faces three apart never share a row; the test
/// `a_probed_three_apart_is_a_probed_five_apart` checks it on every kind of side.
const PERIOD_A: usize = 3;

/// What the exact step did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct NewtonInfo {
    /// Iterations (sparse factorisations) taken, the interior point's included.
    pub iterations: usize,
    /// Of which interior-point iterations (zero when the warm semismooth loop converged).
    pub interior_iterations: usize,
    /// Momentum residual max_f |F_u,f| / max_f (|b_f| + |(Au)_f| + |(Σ w Bᵀσ)_f|) at the end.
    pub momentum_residual: f64,
    /// max_k |σ_k − P(σ_k + r̂_k(B_k u + β_k))| at the end (r̂: the stopping test's, module doc).
    pub projection_residual: f64,
    /// Number of unknown faces and of terms (plastic locations and friction faces).
    pub unknowns: usize,
    pub terms: usize,
}

impl NewtonInfo {
    /// The larger of the two residuals of eq. (11).
    pub fn residual(&self) -> f64 {
        self.momentum_residual.max(self.projection_residual)
    }
}

/// The discrete problem of the last exact step, for an independent check of its solution
/// (module doc): minimise ½xᵀAx − bᵀx + Σ_k w_k |B_k x + β_k| over the unknown faces x (u faces
/// row by row, then v faces). B's rows are stacked term by term (`dim` rows each) in compressed
/// rows; `x` and `sigma` (stacked like B's rows) are the solution the exact step returned.
#[derive(Clone, Debug, Default)]
pub struct ExactProblem {
    pub n: usize,
    /// A as triplets (duplicates summed).
    pub a_rows: Vec<usize>,
    pub a_cols: Vec<usize>,
    pub a_vals: Vec<f64>,
    pub b: Vec<f64>,
    pub w: Vec<f64>,
    pub dim: Vec<usize>,
    pub b_indptr: Vec<usize>,
    pub b_indices: Vec<usize>,
    pub b_data: Vec<f64>,
    pub beta: Vec<f64>,
    pub x: Vec<f64>,
    pub sigma: Vec<f64>,
}

/// Sparse rows of one location's strain-rate component, built by probing.
#[derive(Clone, Debug, Default)]
struct RowSet {
    /// For each location (row-major over its grid), its (unknown, value) entries.
    entries: Vec<Vec<(usize, f64)>>,
}

/// The exact step's state: the multipliers of every location (warm start of the next step) and
/// the work arrays (allocated once).
pub struct ExactStep {
    /// σ at centres and nodes: (xx, xy) components, row-major.
    sigma_c: Vec<[f64; 2]>,
    sigma_n: Vec<[f64; 2]>,
    ru: Range<usize>,
    rv: Range<usize>,
    n_u: usize,
    n: usize,
    periods: (usize, usize),
    periods_a: (usize, usize),
    periodic: (bool, bool),
    probe_u: Field,
    probe_v: Field,
    out_u: Field,
    out_v: Field,
    dxx: Field,
    dyy: Field,
    dxy: Field,
    /// The last step's problem and solution.
    pub last: Option<ExactProblem>,
    /// The rows of ½(D_xx − D_yy) at centres and of D_xy at nodes (`probe`), probed on the first
    /// step: they depend on the grid and the boundary conditions alone.
    rows: Option<std::sync::Arc<(RowSet, RowSet)>>,
    /// The symbolic LU of the last Newton matrix and its pattern, reused while it is unchanged.
    symbolic: SymbolicCache,
    /// The same for A alone (the interior point's start).
    symbolic_a: SymbolicCache,
    /// The same for A's block on the faces no term reaches (`sweeps`).
    symbolic_r: SymbolicCache,
    /// Whether A is symmetric (`is_symmetric`), read on the first step.
    symmetric: Option<bool>,
}

impl ExactStep {
    /// The state for `grid` and `bc`, with σ = 0.
    pub fn new(grid: &Grid, bc: &BoundaryConditions) -> Self {
        let ru = unknown_face_range(bc.get(Side::Left), bc.get(Side::Right), grid.nx);
        let rv = unknown_face_range(bc.get(Side::Bottom), bc.get(Side::Top), grid.ny);
        let n_u = ru.len() * grid.ny;
        let n = n_u + rv.len() * grid.nx;
        let periodic = (periodic_pair(bc.get(Side::Left), bc.get(Side::Right)), periodic_pair(bc.get(Side::Bottom), bc.get(Side::Top)));
        let period = |p: usize, periodic: bool, m: usize| if !periodic || m % p == 0 { p } else { m };
        let periods = (period(PERIOD, periodic.0, grid.nx), period(PERIOD, periodic.1, grid.ny));
        let periods_a = (period(PERIOD_A, periodic.0, grid.nx), period(PERIOD_A, periodic.1, grid.ny));
        ExactStep {
            sigma_c: vec![[0.0; 2]; grid.nx * grid.ny],
            sigma_n: vec![[0.0; 2]; (grid.nx + 1) * (grid.ny + 1)],
            ru,
            rv,
            n_u,
            n,
            periods,
            periods_a,
            periodic,
            probe_u: Field::zeros(grid, Location::XFace),
            probe_v: Field::zeros(grid, Location::YFace),
            out_u: Field::zeros(grid, Location::XFace),
            out_v: Field::zeros(grid, Location::YFace),
            dxx: Field::zeros(grid, Location::Centre),
            dyy: Field::zeros(grid, Location::Centre),
            dxy: Field::zeros(grid, Location::Node),
            last: None,
            rows: None,
            symbolic: std::sync::Mutex::new(None),
            symbolic_a: std::sync::Mutex::new(None),
            symbolic_r: std::sync::Mutex::new(None),
            symmetric: None,
        }
    }

    fn index_u(&self, i: usize, j: usize) -> usize {
        j * self.ru.len() + (i - self.ru.start)
    }

    fn index_v(&self, nx: usize, i: usize, j: usize) -> usize {
        self.n_u + (j - self.rv.start) * nx + i
    }

    /// The unknown of component `comp` (0: u, 1: v) of colour (ci, cj), colour periods
    /// (px, py), next to index (i, j) of an output location, if there is one.
    #[allow(clippy::too_many_arguments)]
    fn source(&self, grid: &Grid, (px, py): (usize, usize), comp: usize, (ci, cj): (usize, usize), i: isize, j: isize) -> Option<usize> {
        // the index ≡ c (mod p) within (p − 1)/2 of k; across a periodic pair, modulo its length
        // (p = m: one face per colour)
        let pick = |c: usize, k: isize, p: usize, m: usize, periodic: bool| -> isize {
            if periodic && p == m {
                return c as isize;
            }
            let lo = k - (p as isize - 1) / 2;
            let x = lo + (c as isize - lo).rem_euclid(p as isize);
            if periodic {
                x.rem_euclid(m as isize)
            } else {
                x
            }
        };
        let (si, sj) = (pick(ci, i, px, grid.nx, self.periodic.0), pick(cj, j, py, grid.ny, self.periodic.1));
        if si < 0 || sj < 0 {
            return None;
        }
        let (si, sj) = (si as usize, sj as usize);
        if comp == 0 {
            (self.ru.contains(&si) && sj < grid.ny).then(|| self.index_u(si, sj))
        } else {
            (si < grid.nx && self.rv.contains(&sj)).then(|| self.index_v(grid.nx, si, sj))
        }
    }

    /// Probes A (matrix-free `viscous_helmholtz` with homogeneous ghosts) and, with `strain`,
    /// the strain rate: returns A's triplets and the rows of ½(D_xx − D_yy) at centres and of
    /// D_xy at nodes (empty without `strain`). The colours are [`PERIOD`] apart with `strain`,
    /// [`PERIOD_A`] without.
    #[allow(clippy::too_many_arguments)]
    fn probe(
        &mut self,
        grid: &Grid,
        bc: &BoundaryConditions,
        eta_c: &Field,
        eta_n: &Field,
        c_u: &Field,
        c_v: &Field,
        strain: bool,
        exec: Exec,
    ) -> (Vec<Triplet<usize, usize, f64>>, RowSet, RowSet) {
        let (nx, ny) = (grid.nx, grid.ny);
        let mut a = Vec::with_capacity(14 * self.n);
        let rows = |m: usize| RowSet { entries: vec![Vec::new(); if strain { m } else { 0 }] };
        let (mut dev, mut shear) = (rows(nx * ny), rows((nx + 1) * (ny + 1)));
        let periods = if strain { self.periods } else { self.periods_a };
        let (px, py) = periods;
        for comp in 0..2 {
            for cj in 0..py {
                for ci in 0..px {
                    self.probe_u.fill(0.0);
                    self.probe_v.fill(0.0);
                    let mut any = false;
                    if comp == 0 {
                        for j in (cj..ny).step_by(py) {
                            for i in self.ru.clone().filter(|i| i % px == ci) {
                                self.probe_u.set(i, j, 1.0);
                                any = true;
                            }
                        }
                    } else {
                        for j in self.rv.clone().filter(|j| j % py == cj) {
                            for i in (ci..nx).step_by(px) {
                                self.probe_v.set(i, j, 1.0);
                                any = true;
                            }
                        }
                    }
                    if !any {
                        continue;
                    }
                    fill_velocity_ghosts(&mut self.probe_u, &mut self.probe_v, bc, grid, BcMode::Homogeneous);
                    viscous_helmholtz(&self.probe_u, &self.probe_v, eta_c, eta_n, c_u, c_v, grid, &mut self.out_u, &mut self.out_v, exec);
                    for j in 0..ny {
                        for i in self.ru.clone() {
                            let q = self.out_u.at(i as isize, j as isize);
                            if q != 0.0 {
                                if let Some(s) = self.source(grid, periods, comp, (ci, cj), i as isize, j as isize) {
                                    a.push(Triplet::new(self.index_u(i, j), s, q));
                                }
                            }
                        }
                    }
                    for j in self.rv.clone() {
                        for i in 0..nx {
                            let q = self.out_v.at(i as isize, j as isize);
                            if q != 0.0 {
                                if let Some(s) = self.source(grid, periods, comp, (ci, cj), i as isize, j as isize) {
                                    a.push(Triplet::new(self.index_v(nx, i, j), s, q));
                                }
                            }
                        }
                    }
                    if !strain {
                        continue;
                    }
                    strain_rate(&self.probe_u, &self.probe_v, grid, &mut self.dxx, &mut self.dyy, &mut self.dxy, exec);
                    for j in 0..ny {
                        for i in 0..nx {
                            let d = 0.5 * (self.dxx.at(i as isize, j as isize) - self.dyy.at(i as isize, j as isize));
                            if d != 0.0 {
                                if let Some(s) = self.source(grid, periods, comp, (ci, cj), i as isize, j as isize) {
                                    dev.entries[j * nx + i].push((s, d));
                                }
                            }
                        }
                    }
                    for j in 0..=ny {
                        for i in 0..=nx {
                            let d = self.dxy.at(i as isize, j as isize);
                            if d != 0.0 {
                                if let Some(s) = self.source(grid, periods, comp, (ci, cj), i as isize, j as isize) {
                                    shear.entries[j * (nx + 1) + i].push((s, d));
                                }
                            }
                        }
                    }
                }
            }
        }
        (a, dev, shear)
    }

    /// Solves eq. (11) for ũ (module doc). `u`, `v` hold the initial guess on entry and receive ũ
    /// (ghosts filled); `rhs_u`, `rhs_v` the predictor's right-hand side without the plastic and
    /// friction forces; `tau_c`, `tau_n` the yield stress; `walls` the Coulomb walls (their s
    /// receives −σ_f). Writes Σ's stored equivalents into `sigma_xx` (centres), `sigma_xy`
    /// (nodes) and |z_c| into `trial_norm`.
    #[allow(clippy::too_many_arguments)]
    pub fn solve(
        &mut self,
        sys: (&Field, &Field, &Field, &Field),
        grid: &Grid,
        bc: &BoundaryConditions,
        u: &mut Field,
        v: &mut Field,
        (rhs_u, rhs_v): (&Field, &Field),
        (tau_c, tau_n): (&Field, &Field),
        walls: &mut CoulombWalls,
        (sigma_xx, sigma_xy, trial_norm): (&mut Field, &mut Field, &mut Field),
        (tol, max_iterations): (f64, usize),
        (step, time): (u64, f64),
        exec: Exec,
    ) -> Result<NewtonInfo> {
        let (c_u, c_v, eta_c, eta_n) = sys;
        let (nx, ny) = (grid.nx, grid.ny);
        let n = self.n;
        // the strain rate's rows depend on the grid and the boundary conditions alone: probed once
        let strain = self.rows.is_none();
        let (a_trip, dev, shear) = self.probe(grid, bc, eta_c, eta_n, c_u, c_v, strain, exec);
        if strain {
            self.rows = Some(std::sync::Arc::new((dev, shear)));
        }
        let rows = self.rows.clone().expect("probed above");
        let (dev, shear) = (&rows.0, &rows.1);
        // the affine parts: A and D of the boundary data alone (unknowns zero)
        self.probe_u.assign(u);
        self.probe_v.assign(v);
        for j in 0..ny {
            for i in self.ru.clone() {
                self.probe_u.set(i, j, 0.0);
            }
        }
        for j in self.rv.clone() {
            for i in 0..nx {
                self.probe_v.set(i, j, 0.0);
            }
        }
        fill_velocity_ghosts(&mut self.probe_u, &mut self.probe_v, bc, grid, BcMode::Full);
        viscous_helmholtz(&self.probe_u, &self.probe_v, eta_c, eta_n, c_u, c_v, grid, &mut self.out_u, &mut self.out_v, exec);
        strain_rate(&self.probe_u, &self.probe_v, grid, &mut self.dxx, &mut self.dyy, &mut self.dxy, exec);
        let mut b = vec![0.0; n];
        let mut x = vec![0.0; n];
        for j in 0..ny {
            for i in self.ru.clone() {
                let k = self.index_u(i, j);
                b[k] = rhs_u.at(i as isize, j as isize) - self.out_u.at(i as isize, j as isize);
                x[k] = u.at(i as isize, j as isize);
            }
        }
        for j in self.rv.clone() {
            for i in 0..nx {
                let k = self.index_v(nx, i, j);
                b[k] = rhs_v.at(i as isize, j as isize) - self.out_v.at(i as isize, j as isize);
                x[k] = v.at(i as isize, j as isize);
            }
        }
        let beta_dev = |s: &Self, i: usize, j: usize| 0.5 * (s.dxx.at(i as isize, j as isize) - s.dyy.at(i as isize, j as isize));
        // A as a compressed matrix (for products) and its diagonal
        let a_mat = compress(n, &a_trip)?;
        // A symmetric (walls on every side): the Newton and interior-point matrices are
        // symmetric positive definite, factorised by Cholesky. Whether it is depends on the kinds
        // of side alone: read on the first step
        let symmetric = *self.symmetric.get_or_insert_with(|| is_symmetric(&a_mat));
        let mut diag = vec![0.0; n];
        for t in &a_trip {
            if t.row == t.col {
                diag[t.row] += t.val;
            }
        }
        // the terms
        let held = |side: Side| matches!(bc.get(side), VelocityBc::FreeSlip | VelocityBc::Coulomb);
        let (mut cols, mut vals) = (Vec::<usize>::new(), Vec::<f64>::new());
        let mut terms: Vec<Term> = Vec::new();
        // a row of B with one entry per face: the parts' coefficients of a face summed (the
        // four corners of a centre share faces), in the order the faces first appear
        let push_row = |cols: &mut Vec<usize>, vals: &mut Vec<f64>, parts: &[(&[(usize, f64)], f64)]| -> Range<usize> {
            let start = cols.len();
            for (entries, weight) in parts {
                for &(k, val) in entries.iter() {
                    if let Some(q) = cols[start..].iter().position(|&c| c == k) {
                        vals[start + q] += weight * val;
                    } else {
                        cols.push(k);
                        vals.push(weight * val);
                    }
                }
            }
            start..cols.len()
        };
        for j in 0..ny {
            for i in 0..nx {
                let w = tau_c.at(i as isize, j as isize);
                if w <= 0.0 {
                    continue;
                }
                let corners = [(i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1)];
                let r0 = push_row(&mut cols, &mut vals, &[(&dev.entries[j * nx + i], 1.0)]);
                let parts: Vec<(&[(usize, f64)], f64)> = corners.iter().map(|&(a, c)| (&shear.entries[c * (nx + 1) + a][..], 0.25)).collect();
                let r1 = push_row(&mut cols, &mut vals, &parts);
                let b1 = corners.iter().map(|&(a, c)| 0.25 * self.dxy.at(a as isize, c as isize)).sum();
                terms.push(Term {
                    w,
                    dim: 2,
                    rows: [r0, r1],
                    beta: [beta_dev(self, i, j), b1],
                    r: 0.0,
                    sigma: self.sigma_c[j * nx + i],
                    slot: Slot::Centre(i, j),
                });
            }
        }
        let (hl, hr, hb, ht) = (held(Side::Left), held(Side::Right), held(Side::Bottom), held(Side::Top));
        for j in 0..=ny {
            for i in 0..=nx {
                if (i == 0 && hl) || (i == nx && hr) || (j == 0 && hb) || (j == ny && ht) {
                    continue;
                }
                let tau = tau_n.at(i as isize, j as isize);
                if tau <= 0.0 {
                    continue;
                }
                let cells = node_cells(i, j, nx, ny);
                let m = cells.len() as f64;
                let parts: Vec<(&[(usize, f64)], f64)> = cells.iter().map(|&(a, c)| (&dev.entries[c * nx + a][..], 1.0 / m)).collect();
                let r0 = push_row(&mut cols, &mut vals, &parts);
                let r1 = push_row(&mut cols, &mut vals, &[(&shear.entries[j * (nx + 1) + i], 1.0)]);
                let b0 = cells.iter().map(|&(a, c)| beta_dev(self, a, c)).sum::<f64>() / m;
                let b1 = self.dxy.at(i as isize, j as isize);
                terms.push(Term {
                    w: tau * m / 4.0,
                    dim: 2,
                    rows: [r0, r1],
                    beta: [b0, b1],
                    r: 0.0,
                    sigma: self.sigma_n[j * (nx + 1) + i],
                    slot: Slot::Node(i, j),
                });
            }
        }
        for (side, f, tau_b, s) in walls.friction_faces() {
            let (k, h) = match side {
                Side::Bottom => (self.index_u(f, 0), grid.dy),
                Side::Top => (self.index_u(f, ny - 1), grid.dy),
                Side::Left => (self.index_v(nx, 0, f), grid.dx),
                Side::Right => (self.index_v(nx, nx - 1, f), grid.dx),
            };
            let r0 = push_row(&mut cols, &mut vals, &[(&[(k, 1.0)], 1.0)]);
            terms.push(Term { w: tau_b / h, dim: 1, rows: [r0, 0..0], beta: [0.0; 2], r: 0.0, sigma: [-s, 0.0], slot: Slot::Wall(side, f) });
        }
        // r_k = d_k/(w_k‖B_k‖²)
        for t in terms.iter_mut() {
            let (mut d, mut norm2) = (0.0f64, 0.0);
            for c in 0..t.dim {
                for e in t.rows[c].clone() {
                    d = d.max(diag[cols[e]]);
                    norm2 += vals[e] * vals[e];
                }
            }
            t.r = if norm2 > 0.0 { d / (t.w * norm2) } else { 0.0 };
            t.sigma = onto_ball(t.sigma);
        }
        let apply_b = |t: &Term, x: &[f64]| -> [f64; 2] { apply_term(t, &cols, &vals, x) };
        // the stopping test's scales (module doc): U the largest |b_f|/A_ff, the velocity a face
        // reaches in the step with neither coupling nor yield stress; r̂ = h/U at a plastic
        // location (B u a strain rate), 1/U at a friction face
        let u_ref = {
            let u = b.iter().zip(&diag).fold(0.0f64, |m, (b, d)| if *d > 0.0 { m.max((b / d).abs()) } else { m });
            if u > 0.0 && u.is_finite() {
                u
            } else {
                1.0
            }
        };
        let scales = Scales { u_ref, h: grid.dx.min(grid.dy), coupling: &[], floor: 0.0 };
        let sig: Vec<[f64; 2]> = terms.iter().map(|t| t.sigma).collect();
        let whole =
            Program { n, a_trip: &a_trip, a_mat: &a_mat, b: &b, terms: &terms, cols: &cols, vals: &vals, apply_b: &apply_b, cache: &self.symbolic, symmetric };
        let caches = (&self.symbolic_a, &self.symbolic_r);
        let outcome = match symmetric.then(|| Partition::new(n, &terms, &cols)).flatten() {
            Some(part) => sweeps(whole, &part, &scales, caches, x, sig, (tol, max_iterations))?,
            None => iterate(whole, &mut Assembly::new(n, &a_trip, &terms, &cols)?, &scales, caches.0, x, sig, (tol, max_iterations))?,
        };
        let Outcome { x, sig, iterations, interior_iterations, momentum_residual: mom_max, projection_residual: proj, failure } = outcome;
        self.last = Some(problem(n, &b, &a_trip, &terms, &cols, &vals, &x, &sig));
        if let Some(failure) = failure {
            return Err(Error::PicardNotConverged {
                what: format!(
                    "the exact step of eq. (11) did not converge: momentum residual {mom_max:.3e}, projection residual {proj:.3e} after {iterations} iterations ({interior_iterations} interior-point{failure}) (newton_tol {tol:.1e})"
                ),
                step,
                time,
            });
        }
        // write back ũ, σ and the stored equivalents
        for j in 0..ny {
            for i in self.ru.clone() {
                u.set(i, j, x[self.index_u(i, j)]);
            }
        }
        for j in self.rv.clone() {
            for i in 0..nx {
                v.set(i, j, x[self.index_v(nx, i, j)]);
            }
        }
        fill_velocity_ghosts(u, v, bc, grid, BcMode::Full);
        self.sigma_c.iter_mut().for_each(|s| *s = [0.0; 2]);
        self.sigma_n.iter_mut().for_each(|s| *s = [0.0; 2]);
        sigma_xx.fill(0.0);
        sigma_xy.fill(0.0);
        trial_norm.fill(0.0);
        // τΣ_xx at centres and τΣ_xy at nodes (module doc), divided by τ below
        let mut txx = vec![0.0; nx * ny];
        let mut txy = vec![0.0; (nx + 1) * (ny + 1)];
        for (t, s) in terms.iter().zip(&sig) {
            match t.slot {
                Slot::Centre(i, j) => {
                    self.sigma_c[j * nx + i] = *s;
                    txx[j * nx + i] += 0.5 * t.w * s[0];
                    for (a, c) in [(i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1)] {
                        txy[c * (nx + 1) + a] += 0.125 * t.w * s[1];
                    }
                    let y = apply_b(t, &x);
                    let z = [s[0] + t.r * y[0], s[1] + t.r * y[1]];
                    trial_norm.set(i, j, z[0].hypot(z[1]));
                }
                Slot::Node(i, j) => {
                    self.sigma_n[j * (nx + 1) + i] = *s;
                    txy[j * (nx + 1) + i] += 0.5 * t.w * s[1];
                    let cells = node_cells(i, j, nx, ny);
                    let m = cells.len() as f64;
                    for (a, c) in cells {
                        txx[c * nx + a] += 0.5 * t.w * s[0] / m;
                    }
                }
                Slot::Wall(side, f) => walls.set_direction(side, f, -s[0]),
            }
        }
        for j in 0..ny {
            for i in 0..nx {
                let tau = tau_c.at(i as isize, j as isize);
                if tau > 0.0 {
                    sigma_xx.set(i, j, txx[j * nx + i] / tau);
                }
            }
        }
        for j in 0..=ny {
            for i in 0..=nx {
                let tau = tau_n.at(i as isize, j as isize);
                if tau > 0.0 {
                    sigma_xy.set(i, j, txy[j * (nx + 1) + i] / tau);
                }
            }
        }
        Ok(NewtonInfo { iterations, interior_iterations, momentum_residual: mom_max, projection_residual: proj, unknowns: n, terms: terms.len() })
    }
}

/// B_k x + β_k for term `t`, B's rows in `cols`/`vals`.
fn apply_term(t: &Term, cols: &[usize], vals: &[f64], x: &[f64]) -> [f64; 2] {
    let mut y = t.beta;
    for c in 0..t.dim {
        for e in t.rows[c].clone() {
            y[c] += vals[e] * x[cols[e]];
        }
    }
    y
}

/// The stopping test's scales (module doc) and, for the block of the faces the terms reach,
/// what the rest of the faces adds to it: `coupling` = A_GR x_R on G (empty for the whole
/// problem), so that a face's scale |b_f| + |(A x)_f| + |force_f| is the whole problem's, and
/// `floor` = the largest scale over R.
struct Scales<'a> {
    u_ref: f64,
    h: f64,
    coupling: &'a [f64],
    floor: f64,
}

impl Scales<'_> {
    /// r̂ of term `t`: h/U at a plastic location, 1/U at a friction face.
    fn r_hat(&self, t: &Term) -> f64 {
        if t.dim == 1 {
            1.0 / self.u_ref
        } else {
            self.h / self.u_ref
        }
    }
}

/// F_u, F_k and the residuals of program `p` at (x, σ): ‖F_u‖₂ relative and max_k |F_k| with
/// the iteration's r_k, which the merit uses; the stopping test's momentum and projection
/// residuals, in the maximum norm and with r̂.
fn residuals(p: &Program, sc: &Scales, x: &[f64], sig: &[[f64; 2]], fu: &mut Vec<f64>, fk: &mut Vec<[f64; 2]>) -> (f64, f64, f64, f64) {
    let n = p.n;
    let mut ax = vec![0.0; n];
    apply(p.a_mat, x, &mut ax);
    let mut force = vec![0.0; n];
    let (mut proj, mut proj_hat) = (0.0f64, 0.0f64);
    let nan_max = |a: f64, b: f64| if a.is_nan() || b.is_nan() { f64::NAN } else { a.max(b) };
    fk.clear();
    for (t, s) in p.terms.iter().zip(sig) {
        let y = (p.apply_b)(t, x);
        let f = natural_residual(*s, y, t.r);
        proj = nan_max(proj, norm(f[0], f[1]));
        let g = natural_residual(*s, y, sc.r_hat(t));
        proj_hat = nan_max(proj_hat, norm(g[0], g[1]));
        fk.push(f);
        for c in 0..t.dim {
            for e in t.rows[c].clone() {
                force[p.cols[e]] += t.w * p.vals[e] * s[c];
            }
        }
    }
    fu.clear();
    let (mut n_b, mut n_a, mut n_f, mut n_r) = (0.0, 0.0, 0.0, 0.0);
    let (mut max_r, mut max_s) = (0.0f64, sc.floor);
    for k in 0..n {
        let r = ax[k] - p.b[k] + force[k];
        let c = sc.coupling.get(k).copied().unwrap_or(0.0);
        let (bk, ak) = (p.b[k] + c, ax[k] + c);
        fu.push(r);
        n_b += bk * bk;
        n_a += ak * ak;
        n_f += force[k] * force[k];
        n_r += r * r;
        max_r = nan_max(max_r, r.abs());
        max_s = max_s.max(bk.abs() + ak.abs() + force[k].abs());
    }
    let relative = |r: f64, s: f64| {
        if s > 0.0 {
            r / s
        } else if r == 0.0 {
            0.0
        } else {
            f64::NAN
        }
    };
    let mom = relative(n_r.sqrt(), n_b.sqrt() + n_a.sqrt() + n_f.sqrt());
    (mom, proj, relative(max_r, max_s), proj_hat)
}

/// What one solve of a program returned: its point, its factorisations, its residuals and,
/// where it stopped short of the tolerance, why.
struct Outcome {
    x: Vec<f64>,
    sig: Vec<[f64; 2]>,
    iterations: usize,
    interior_iterations: usize,
    momentum_residual: f64,
    projection_residual: f64,
    failure: Option<String>,
}

/// The three stages (module doc) on program `p` from (x, σ), to `tol` in at most
/// `max_iterations` factorisations, its Newton matrices assembled on `assembly` (`p`'s
/// pattern); `symbolic_a` the cache of A's factorisation (the interior
/// point's start where its conjugate-gradient iteration stalls).
#[allow(clippy::too_many_arguments)]
fn iterate(
    p: Program,
    assembly: &mut Assembly,
    sc: &Scales,
    symbolic_a: &SymbolicCache,
    mut x: Vec<f64>,
    mut sig: Vec<[f64; 2]>,
    (tol, max_iterations): (f64, usize),
) -> Result<Outcome> {
    let Program { n, a_trip, a_mat, b, terms, cols, vals, apply_b, cache, symmetric } = p;
    let (mut fu, mut fk) = (Vec::with_capacity(n), Vec::with_capacity(terms.len()));
    let (mut mom, mut proj_r, mut mom_max, mut proj) = residuals(&p, sc, &x, &sig, &mut fu, &mut fk);
    let mut iterations = 0;
    let mut s_mat: Vec<[[f64; 2]; 2]> = vec![[[0.0; 2]; 2]; terms.len()];
    let mut t_vec: Vec<[f64; 2]> = vec![[0.0; 2]; terms.len()];
    let (mut fu_trial, mut fk_trial) = (Vec::with_capacity(n), Vec::with_capacity(terms.len()));
    // the semismooth loop from the warm start; the augmented-Lagrangian stage from its point
    // once its residuals are below POLISH_START, or from the interior point's if they are
    // not after WARM_TRIES iterations
    let mut interior_iterations = 0;
    while !(mom_max <= tol && proj <= tol) {
        let near = mom <= interior_point::POLISH_START && proj_r <= interior_point::POLISH_START;
        // a loop whose projection residual is still above WARM_GIVE_UP after WARM_CHECK
        // iterations has left the warm start's neighbourhood: the interior point takes over
        let lost = iterations >= WARM_CHECK && proj > WARM_GIVE_UP;
        if near || lost || iterations == WARM_TRIES || !mom.is_finite() || !proj.is_finite() {
            let c: Vec<f64> = terms.iter().map(|t| t.r / AUGMENTED_DELTA).collect();
            let converged = |x: &[f64], sig: &[[f64; 2]], fu: &mut Vec<f64>, fk: &mut Vec<[f64; 2]>| {
                let (_, _, m, p) = residuals(&p, sc, x, sig, fu, fk);
                m <= tol && p <= tol
            };
            if near {
                // the method of multipliers from the semismooth loop's point, for at most
                // NEAR_BUDGET factorisations
                let budget = NEAR_BUDGET.min(max_iterations.saturating_sub(iterations));
                let mut test = |x: &[f64], sig: &[[f64; 2]]| converged(x, sig, &mut fu_trial, &mut fk_trial);
                let al = augmented::solve(p, assembly, (x.clone(), sig.clone()), &c, &mut test, tol, budget)?;
                iterations += al.iterations;
                (_, _, mom_max, proj) = residuals(&p, sc, &al.x, &al.sigma, &mut fu, &mut fk);
                if al.converged && mom_max <= tol && proj <= tol {
                    return Ok(Outcome {
                        x: al.x,
                        sig: al.sigma,
                        iterations,
                        interior_iterations,
                        momentum_residual: mom_max,
                        projection_residual: proj,
                        failure: None,
                    });
                }
            }
            // the interior point from the predictor without yield stress, then the method of
            // multipliers from its point
            let mut x0 = b.to_vec();
            solve_predictor(a_mat, symbolic_a, symmetric, &mut x0)?;
            let mut projection = |x: &[f64], sig: &[[f64; 2]]| residuals(&p, sc, x, sig, &mut fu_trial, &mut fk_trial).1;
            let ip = interior_point::solve(p, assembly, x0, &mut projection, max_iterations.saturating_sub(iterations))?;
            interior_iterations = ip.iterations;
            iterations += ip.iterations;
            let mut test = |x: &[f64], sig: &[[f64; 2]]| converged(x, sig, &mut fu_trial, &mut fk_trial);
            let al = augmented::solve(p, assembly, (ip.x, ip.sigma), &c, &mut test, tol, max_iterations.saturating_sub(iterations))?;
            iterations += al.iterations;
            (_, _, mom_max, proj) = residuals(&p, sc, &al.x, &al.sigma, &mut fu, &mut fk);
            let failure = (!(al.converged && mom_max <= tol && proj <= tol))
                .then(|| format!(", {} augmented-Lagrangian updates, penalties shrunk {} times", al.outer, al.shrinks));
            return Ok(Outcome { x: al.x, sig: al.sigma, iterations, interior_iterations, momentum_residual: mom_max, projection_residual: proj, failure });
        }
        iterations += 1;
        // S_k, t_k and the Newton matrix
        let delta = NEWTON_DELTA;
        let mut rhs: Vec<f64> = fu.iter().map(|r| -r).collect();
        for (idx, t) in terms.iter().enumerate() {
            let y = apply_b(t, &x);
            let s = sig[idx];
            let z = [s[0] + t.r * y[0], s[1] + t.r * y[1]];
            let nz = if t.dim == 1 { z[0].abs() } else { norm(z[0], z[1]) };
            let f = fk[idx];
            let (sm, tv) = if nz <= 1.0 {
                let a = t.r / delta;
                ([[a, 0.0], [0.0, a]], [f[0] / delta, f[1] / delta])
            } else {
                let rho = 1.0 / nz;
                let nv = [z[0] / nz, z[1] / nz];
                // (I − G + δI)⁻¹ = (I − nnᵀ)/(1 − ρ + δ) + nnᵀ/(1 + δ)
                let (p, q) = (1.0 / (1.0 - rho + delta), 1.0 / (1.0 + delta));
                let perp = [[1.0 - nv[0] * nv[0], -nv[0] * nv[1]], [-nv[1] * nv[0], 1.0 - nv[1] * nv[1]]];
                let par = [[nv[0] * nv[0], nv[0] * nv[1]], [nv[1] * nv[0], nv[1] * nv[1]]];
                let g = t.r * rho * p;
                let sm = if t.dim == 1 { [[0.0; 2]; 2] } else { [[g * perp[0][0], g * perp[0][1]], [g * perp[1][0], g * perp[1][1]]] };
                let inv = |a: usize, c: usize| p * perp[a][c] + q * par[a][c];
                let tv = if t.dim == 1 { [q * f[0], 0.0] } else { [inv(0, 0) * f[0] + inv(0, 1) * f[1], inv(1, 0) * f[0] + inv(1, 1) * f[1]] };
                (sm, tv)
            };
            s_mat[idx] = sm;
            t_vec[idx] = tv;
            // w Bᵀ t (w Bᵀ S B: the assembly below)
            for c in 0..t.dim {
                for e in t.rows[c].clone() {
                    rhs[cols[e]] += t.w * vals[e] * tv[c];
                }
            }
        }
        // the solve, refined against the matrix applied term by term: the penalty w r/δ
        // of a rigid location scales the round-off of one solve by about 1/δ
        // every coefficient, zero ones too: the pattern (and its symbolic factorisation) is
        // the same for every iteration of the step
        assembly.assemble(a_trip, terms, vals, |k| {
            let (w, m) = (terms[k].w, s_mat[k]);
            [[w * m[0][0], w * m[0][1]], [w * m[1][0], w * m[1][1]]]
        });
        let fac = assembly.factor(cache, symmetric)?;
        let mut dx = rhs.clone();
        fac.solve_in_place(&mut dx)?;
        let (mut res, mut adx) = (vec![0.0; n], vec![0.0; n]);
        for _ in 0..REFINEMENTS {
            apply(a_mat, &dx, &mut adx);
            res.iter_mut().zip(&rhs).zip(&adx).for_each(|((r, b), a)| *r = b - a);
            for (idx, t) in terms.iter().enumerate() {
                let by = apply_b(t, &dx);
                let bd = [by[0] - t.beta[0], by[1] - t.beta[1]];
                let sm = s_mat[idx];
                for c in 0..t.dim {
                    let q = t.w * (sm[c][0] * bd[0] + sm[c][1] * bd[1]);
                    for e in t.rows[c].clone() {
                        res[cols[e]] -= vals[e] * q;
                    }
                }
            }
            fac.solve_in_place(&mut res)?;
            dx.iter_mut().zip(&res).for_each(|(d, r)| *d += r);
        }
        let dsig: Vec<[f64; 2]> = terms
            .iter()
            .enumerate()
            .map(|(idx, t)| {
                let by = apply_b(t, &dx);
                let bd = [by[0] - t.beta[0], by[1] - t.beta[1]];
                let sm = s_mat[idx];
                [sm[0][0] * bd[0] + sm[0][1] * bd[1] - t_vec[idx][0], sm[1][0] * bd[0] + sm[1][1] * bd[1] - t_vec[idx][1]]
            })
            .collect();
        // backtracking on the merit
        let merit = |m: f64, p: &Vec<[f64; 2]>| m * m + p.iter().map(|f| f[0] * f[0] + f[1] * f[1]).sum::<f64>();
        let m0 = merit(mom, &fk);
        let mut alpha = 1.0;
        // (merit, x, σ) of the best trial
        let mut best: Option<(f64, Vec<f64>, Vec<[f64; 2]>)> = None;
        for _ in 0..=MAX_HALVINGS {
            let xt: Vec<f64> = x.iter().zip(&dx).map(|(a, d)| a + alpha * d).collect();
            let st: Vec<[f64; 2]> = sig.iter().zip(&dsig).map(|(a, d)| [a[0] + alpha * d[0], a[1] + alpha * d[1]]).collect();
            let (mt, _, _, _) = residuals(&p, sc, &xt, &st, &mut fu_trial, &mut fk_trial);
            let m = merit(mt, &fk_trial);
            if best.as_ref().is_none_or(|b| m < b.0) {
                best = Some((m, xt, st));
            }
            if m <= (1.0 - 1e-4 * alpha) * m0 {
                break;
            }
            alpha *= 0.5;
        }
        let (_, xt, st) = best.expect("one trial at least");
        x = xt;
        sig = st;
        (mom, proj_r, mom_max, proj) = residuals(&p, sc, &x, &sig, &mut fu, &mut fk);
    }
    Ok(Outcome { x, sig, iterations, interior_iterations, momentum_residual: mom_max, projection_residual: proj, failure: None })
}

/// The faces G that some term's B reaches and the rest R, where G is at most [`SPLIT_SHARE`] of
/// the unknowns (`sweeps`).
struct Partition {
    /// G's faces, ascending, and each face's index in G (`usize::MAX` in R).
    faces: Vec<usize>,
    local: Vec<usize>,
}

impl Partition {
    fn new(n: usize, terms: &[Term], cols: &[usize]) -> Option<Self> {
        let mut local = vec![usize::MAX; n];
        for t in terms {
            for c in 0..t.dim {
                for e in t.rows[c].clone() {
                    local[cols[e]] = 0;
                }
            }
        }
        let faces: Vec<usize> = (0..n).filter(|&f| local[f] == 0).collect();
        if faces.is_empty() || faces.len() as f64 > SPLIT_SHARE * n as f64 {
            return None;
        }
        for (k, &f) in faces.iter().enumerate() {
            local[f] = k;
        }
        Some(Partition { faces, local })
    }
}

/// The whole program `p` (A symmetric) by block Gauss–Seidel sweeps over the partition (module
/// doc): the three stages on G with x_R fixed (b_G − A_GR x_R on the right), then the linear
/// A_RR x_R = b_R − A_RG x_G; until the whole problem's residuals are below `tol`.
fn sweeps(
    p: Program,
    part: &Partition,
    sc: &Scales,
    (symbolic_a, symbolic_r): (&SymbolicCache, &SymbolicCache),
    mut x: Vec<f64>,
    mut sig: Vec<[f64; 2]>,
    (tol, max_iterations): (f64, usize),
) -> Result<Outcome> {
    let ng = part.faces.len();
    // A's block on G and its coupling to R, in the order of A's triplets (the same sums on
    // every thread setting)
    let (mut a_gg, mut a_gr) = (Vec::new(), Vec::new());
    for t in p.a_trip {
        match (part.local[t.row], part.local[t.col]) {
            (usize::MAX, _) => {}
            (g, usize::MAX) => a_gr.push((g, t.col, t.val)),
            (g, h) => a_gg.push(Triplet::new(g, h, t.val)),
        }
    }
    let a_gg_mat = compress(ng, &a_gg)?;
    let in_rest: Vec<bool> = part.local.iter().map(|&g| g == usize::MAX).collect();
    let cols_g: Vec<usize> = p.cols.iter().map(|&c| part.local[c]).collect();
    let apply_g = |t: &Term, x: &[f64]| apply_term(t, &cols_g, p.vals, x);
    let mut assembly = Assembly::new(ng, &a_gg, p.terms, &cols_g)?;
    // x_R ← A_RR⁻¹(b_R − A_RG x_G)
    let (mut xg, mut y) = (vec![0.0; p.n], vec![0.0; p.n]);
    let mut solve_rest = |x: &mut [f64]| -> Result<()> {
        for &f in &part.faces {
            xg[f] = x[f];
        }
        apply(p.a_mat, &xg, &mut y);
        for f in 0..p.n {
            y[f] = if in_rest[f] { p.b[f] - y[f] } else { 0.0 };
        }
        solve_block(p.a_mat, &in_rest, symbolic_r, &mut y)?;
        for f in (0..p.n).filter(|&f| in_rest[f]) {
            x[f] = y[f];
        }
        Ok(())
    };
    // the largest scale |b_f| + |(A x)_f| over R (no term reaches R)
    let rest_scale = |x: &[f64], ax: &mut Vec<f64>| {
        ax.resize(p.n, 0.0);
        apply(p.a_mat, x, ax);
        (0..p.n).filter(|&f| in_rest[f]).fold(0.0f64, |m, f| m.max(p.b[f].abs() + ax[f].abs()))
    };
    let (mut coupling, mut b_g, mut ax) = (vec![0.0; ng], vec![0.0; ng], Vec::new());
    let (mut fu, mut fk) = (Vec::new(), Vec::new());
    let (mut iterations, mut interior_iterations) = (0, 0);
    solve_rest(&mut x)?;
    for _ in 0..MAX_SWEEPS {
        coupling.iter_mut().for_each(|c| *c = 0.0);
        for &(g, r, v) in &a_gr {
            coupling[g] += v * x[r];
        }
        for (k, &f) in part.faces.iter().enumerate() {
            b_g[k] = p.b[f] - coupling[k];
        }
        let block = Program { n: ng, a_trip: &a_gg, a_mat: &a_gg_mat, b: &b_g, apply_b: &apply_g, cols: &cols_g, ..p };
        let sc_g = Scales { coupling: &coupling, floor: rest_scale(&x, &mut ax), ..*sc };
        let x_g: Vec<f64> = part.faces.iter().map(|&f| x[f]).collect();
        let out = iterate(block, &mut assembly, &sc_g, symbolic_a, x_g, sig, (tol, max_iterations.saturating_sub(iterations)))?;
        iterations += out.iterations;
        interior_iterations += out.interior_iterations;
        for (k, &f) in part.faces.iter().enumerate() {
            x[f] = out.x[k];
        }
        sig = out.sig;
        if out.failure.is_some() {
            return Ok(Outcome { x, sig, iterations, interior_iterations, ..out });
        }
        solve_rest(&mut x)?;
        let (_, _, mom_max, proj) = residuals(&p, sc, &x, &sig, &mut fu, &mut fk);
        if mom_max <= tol && proj <= tol {
            return Ok(Outcome { x, sig, iterations, interior_iterations, momentum_residual: mom_max, projection_residual: proj, failure: None });
        }
    }
    let (_, _, mom_max, proj) = residuals(&p, sc, &x, &sig, &mut fu, &mut fk);
    Ok(Outcome {
        x,
        sig,
        iterations,
        interior_iterations,
        momentum_residual: mom_max,
        projection_residual: proj,
        failure: Some(format!(", {MAX_SWEEPS} block sweeps")),
    })
}

/// σ − P(σ + r y), P the projection on the unit ball.
fn natural_residual(s: [f64; 2], y: [f64; 2], r: f64) -> [f64; 2] {
    let p = onto_ball([s[0] + r * y[0], s[1] + r * y[1]]);
    [s[0] - p[0], s[1] - p[1]]
}

/// The step's problem (`ExactProblem`) with the point (x, σ).
#[allow(clippy::too_many_arguments)]
fn problem(
    n: usize,
    b: &[f64],
    a_trip: &[Triplet<usize, usize, f64>],
    terms: &[Term],
    cols: &[usize],
    vals: &[f64],
    x: &[f64],
    sig: &[[f64; 2]],
) -> ExactProblem {
    let mut pb = ExactProblem { n, b: b.to_vec(), x: x.to_vec(), ..Default::default() };
    for t in a_trip {
        pb.a_rows.push(t.row);
        pb.a_cols.push(t.col);
        pb.a_vals.push(t.val);
    }
    pb.b_indptr.push(0);
    for (t, s) in terms.iter().zip(sig) {
        pb.w.push(t.w);
        pb.dim.push(t.dim);
        for c in 0..t.dim {
            for e in t.rows[c].clone() {
                pb.b_indices.push(cols[e]);
                pb.b_data.push(vals[e]);
            }
            pb.b_indptr.push(pb.b_indices.len());
            pb.beta.push(t.beta[c]);
            pb.sigma.push(s[c]);
        }
    }
    pb
}

/// The in-domain cells around node (i, j) of an nx × ny grid (four inside, two on a side, one
/// at a corner).
fn node_cells(i: usize, j: usize, nx: usize, ny: usize) -> Vec<(usize, usize)> {
    let (i, j) = (i as isize, j as isize);
    [(i - 1, j - 1), (i, j - 1), (i - 1, j), (i, j)]
        .into_iter()
        .filter(|&(a, c)| a >= 0 && c >= 0 && (a as usize) < nx && (c as usize) < ny)
        .map(|(a, c)| (a as usize, c as usize))
        .collect()
}

impl crate::grid::StateArrays for ExactStep {
    /// The multipliers σ at centres and nodes (the warm start of the next step).
    fn visit_state(&self, f: &mut dyn FnMut(&str, &[f64])) {
        f("exact_sigma_centre", self.sigma_c.as_flattened());
        f("exact_sigma_node", self.sigma_n.as_flattened());
    }

    fn visit_state_mut(&mut self, f: &mut dyn FnMut(&str, &mut [f64])) {
        f("exact_sigma_centre", self.sigma_c.as_flattened_mut());
        f("exact_sigma_node", self.sigma_n.as_flattened_mut());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tridiagonal A (diagonal d, off-diagonals −e) on n unknowns and one term per i in
    /// [lo, hi) with B_k x = (x_{i+1} − x_i, x_{i+2} − x_i) and yield weights that leave some
    /// terms rigid and others flowing: the shape of the column's step (the terms on a minority
    /// of the faces, a weak viscous coupling elsewhere). Returns A's triplets, b and the terms
    /// with B's rows.
    #[allow(clippy::type_complexity)] // the program's five parts, named where they are built
    fn program(n: usize, d: f64, e: f64, (lo, hi): (usize, usize)) -> (Vec<Triplet<usize, usize, f64>>, Vec<f64>, Vec<Term>, Vec<usize>, Vec<f64>) {
        let mut a_trip = Vec::new();
        for i in 0..n {
            a_trip.push(Triplet::new(i, i, d));
            if i + 1 < n {
                a_trip.push(Triplet::new(i, i + 1, -e));
                a_trip.push(Triplet::new(i + 1, i, -e));
            }
        }
        let (mut cols, mut vals, mut terms) = (Vec::new(), Vec::new(), Vec::new());
        for i in lo..hi {
            let r0 = cols.len()..cols.len() + 2;
            cols.extend([i + 1, i]);
            vals.extend([1.0, -1.0]);
            let r1 = cols.len()..cols.len() + 2;
            cols.extend([i + 2, i]);
            vals.extend([1.0, -1.0]);
            let w = if (i / 7) % 2 == 0 { 400.0 } else { 2.0 };
            // r_k = d_k/(w_k‖B_k‖²), ‖B_k‖² = 4
            terms.push(Term { w, dim: 2, rows: [r0, r1], beta: [0.0; 2], r: d / (4.0 * w), sigma: [0.0; 2], slot: Slot::Centre(i, 0) });
        }
        let b: Vec<f64> = (0..n).map(|i| 40.0 * (((i * 7919) % 13) as f64 - 6.0)).collect();
        (a_trip, b, terms, cols, vals)
    }

    #[test]
    fn block_sweeps_reach_the_whole_problems_solution() {
        let (n, tol) = (400, 1e-10);
        let (a_trip, b, terms, cols, vals) = program(n, 1e3, 1.0, (150, 250));
        let a_mat = compress(n, &a_trip).expect("A");
        let apply_b = |t: &Term, x: &[f64]| apply_term(t, &cols, &vals, x);
        let caches: [SymbolicCache; 4] = std::array::from_fn(|_| std::sync::Mutex::new(None));
        let p = Program {
            n,
            a_trip: &a_trip,
            a_mat: &a_mat,
            b: &b,
            terms: &terms,
            cols: &cols,
            vals: &vals,
            apply_b: &apply_b,
            cache: &caches[0],
            symmetric: true,
        };
        let sc = Scales { u_ref: 1.0, h: 1.0, coupling: &[], floor: 0.0 };
        let sig0 = vec![[0.0; 2]; terms.len()];
        let mut assembly = Assembly::new(n, &a_trip, &terms, &cols).expect("pattern");
        let whole = iterate(p, &mut assembly, &sc, &caches[1], vec![0.0; n], sig0.clone(), (tol, 200)).expect("whole");
        let part = Partition::new(n, &terms, &cols).expect("the terms reach a minority of the faces");
        assert_eq!((part.faces.len(), n - part.faces.len()), (102, 298));
        let split = sweeps(p, &part, &sc, (&caches[2], &caches[3]), vec![0.0; n], sig0, (tol, 200)).expect("sweeps");
        assert!(whole.failure.is_none() && split.failure.is_none());
        // both stop on the whole problem's residuals of eq. (11)
        assert!(whole.momentum_residual.max(whole.projection_residual) <= tol);
        assert!(split.momentum_residual.max(split.projection_residual) <= tol);
        // some terms rigid (|z| < 1) and some flowing at the solution
        let flowing = terms.iter().zip(&split.sig).filter(|(t, s)| {
            let y = apply_b(t, &split.x);
            (s[0] + t.r * y[0]).hypot(s[1] + t.r * y[1]) > 1.0
        });
        let k = flowing.count();
        assert!(k > 0 && k < terms.len(), "{k} of {} terms flowing", terms.len());
        // J is strictly convex: one x. The residual tol bounds |x − x*| by about tol·κ(A) ≈ 1e-10
        // relative (A's diagonal 1e3 against its coupling 1); measured 2.9e-11, 50 of the 100
        // terms flowing
        let scale = whole.x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let diff = whole.x.iter().zip(&split.x).fold(0.0f64, |m, (a, b)| m.max((a - b).abs())) / scale;
        assert!(diff <= 1e-9, "{diff:e}");
    }

    #[test]
    fn a_probed_three_apart_is_a_probed_five_apart() {
        // every kind of side, alone and mixed, on grids whose sizes 3 and 5 divide or not (a
        // periodic direction of a size they do not divide takes one face per colour)
        use VelocityBc::*;
        let velocity = Velocity { normal: 0.3, tangential: -0.2 };
        let sides: [[VelocityBc; 4]; 6] = [
            [NoSlip; 4],
            [NoSlip, FreeSlip, Coulomb, FreeSlip],
            [velocity, Outflow, NoSlip, NavierSlip { slip_length: 0.05 }],
            [FullyDeveloped, FullyDeveloped, Coulomb, FreeSlip],
            [NoSlip, Outflow, FullyDeveloped, FullyDeveloped],
            [FullyDeveloped; 4],
        ];
        for (nx, ny) in [(10, 7), (9, 15), (11, 6)] {
            let grid = Grid::new(nx, ny, 1.0, 0.7).expect("grid");
            let eta_c = Field::from_fn(&grid, Location::Centre, |x, y| 1e-3 + x * x + 0.3 * y);
            let eta_n = Field::from_fn(&grid, Location::Node, |x, y| 2e-3 + 0.5 * x + y * y);
            let c_u = Field::from_fn(&grid, Location::XFace, |x, y| 1e3 * (1.0 + x * y));
            let c_v = Field::from_fn(&grid, Location::YFace, |x, y| 1e3 * (1.5 - x + y));
            for [l, r, b, t] in sides {
                let bc = BoundaryConditions::uniform(NoSlip).with(Side::Left, l).with(Side::Right, r).with(Side::Bottom, b).with(Side::Top, t);
                let mut step = ExactStep::new(&grid, &bc);
                let sorted = |mut a: Vec<Triplet<usize, usize, f64>>| {
                    a.sort_by_key(|t| (t.col, t.row));
                    a.into_iter().map(|t| (t.row, t.col, t.val.to_bits())).collect::<Vec<_>>()
                };
                let (a5, dev, _) = step.probe(&grid, &bc, &eta_c, &eta_n, &c_u, &c_v, true, Exec::SERIAL);
                let (a3, ..) = step.probe(&grid, &bc, &eta_c, &eta_n, &c_u, &c_v, false, Exec::SERIAL);
                assert!(!dev.entries.is_empty() && a5.len() > 5 * step.n, "{nx} × {ny}, {l:?} {r:?} {b:?} {t:?}");
                assert_eq!(sorted(a3), sorted(a5), "{nx} × {ny}, {l:?} {r:?} {b:?} {t:?}");
            }
        }
    }

    #[test]
    fn the_predictor_and_block_solves_reach_round_off_weakly_or_strongly_coupled() {
        // the conjugate-gradient path (coupling 1e-3 of the diagonal) and the factorisation it
        // falls back on (0.49999: κ ≈ 1e5, the iteration stalls)
        for (d, e) in [(1e3, 1.0), (1.0, 0.49999)] {
            let n = 500;
            let (a_trip, b, ..) = program(n, d, e, (0, 0));
            let a = compress(n, &a_trip).expect("A");
            let cache: SymbolicCache = std::sync::Mutex::new(None);
            let mut x = b.clone();
            solve_predictor(&a, &cache, true, &mut x).expect("solve");
            let mut ax = vec![0.0; n];
            apply(&a, &x, &mut ax);
            let norm = |v: &mut dyn Iterator<Item = f64>| v.map(|a| a * a).sum::<f64>().sqrt();
            let res = norm(&mut ax.iter().zip(&b).map(|(a, b)| a - b)) / norm(&mut b.iter().copied());
            // the acceptance of the iteration (1e-11) or a backward-stable factorisation
            assert!(res <= 1e-11, "({d}, {e}): {res:e}");
            // the block on the faces i with i mod 50 ≠ 0 (`solve_block`): x zero off the block
            let rest: Vec<bool> = (0..n).map(|i| i % 50 != 0).collect();
            let rhs: Vec<f64> = b.iter().zip(&rest).map(|(b, &r)| if r { *b } else { 0.0 }).collect();
            let mut x = rhs.clone();
            solve_block(&a, &rest, &cache, &mut x).expect("block solve");
            apply(&a, &x, &mut ax);
            let res = norm(&mut (0..n).filter(|&i| rest[i]).map(|i| ax[i] - rhs[i])) / norm(&mut rhs.iter().copied());
            assert!(res <= 1e-11 && (0..n).all(|i| rest[i] || x[i] == 0.0), "({d}, {e}) block: {res:e}");
        }
    }
}
