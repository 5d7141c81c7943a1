//! The augmented-Lagrangian stage of the exact step (`exact.rs`): the method of multipliers on
//! the cone program of eq. (11) of Aravena et al. (Hestenes 1969; Rockafellar 1976, *Math. Oper.
//! Res.* 1, the proximal point method on the multipliers; ALG1 of Glowinski & Le Tallec 1989,
//! *Augmented Lagrangian and Operator-Splitting Methods in Nonlinear Mechanics*, SIAM, ch. 2), its
//! subproblems solved by a semismooth Newton method with a line search on their objective.
//!
//! **Outer iteration.** With the multipliers σ_k fixed and c_k > 0, the primal step minimises
//!
//!   L(u; σ) = ½ uᵀA u − bᵀu + Σ_k w_k ψ_k(B_k u + β_k),   ψ_k(y) = max_{|s| ≤ 1} s·y − |s − σ_k|²/(2c_k),
//!
//! the Moreau envelope of the terms |y| at the multiplier σ_k: ψ_k is convex and C¹ with
//! ∇ψ_k(y) = P(σ_k + c_k y), P the projection on the unit ball. So L is strictly convex with a
//! semismooth gradient
//!
//!   ∇L(u) = A u − b + Σ_k w_k B_kᵀ P(σ_k + c_k (B_k u + β_k)),
//!
//! and its minimiser is unique whether or not the multipliers of eq. (11) are. The multipliers
//! then move to σ_k ← P(σ_k + c_k(B_k u + β_k)). At that point the momentum equation of eq. (11)
//! holds to the subproblem's tolerance, and the projection equation's residual is the change of
//! σ; the outer iteration is the proximal point method on the dual problem, which converges to
//! one solution of eq. (11) where there are many (locations and wall faces at rest on the edge
//! of their balls, whose multipliers the force balance does not determine).
//!
//! **Inner iteration.** Newton's matrix is A + Σ_k w_k c_k B_kᵀ G_k B_k (G_k = I inside the
//! ball, (I − nnᵀ)/|z_k| outside, n = z_k/|z_k|), symmetric positive definite where A is,
//! assembled on the step's pattern (`cone::Assembly`) and solved like the semismooth step's,
//! its solution refined once. The step is halved until the derivative of L along it,
//! φ'(α) = ∇L(u + α du)·du, is at most a tenth of |φ'(0)|: along the line L is convex, so φ' grows
//! with α and L decreases while φ' < 0. L's own value is not read: near the solution its change
//! is below its round-off, its derivative's is not. The subproblem stops when the momentum
//! residual (`exact.rs`) is below a tenth of the step's tolerance, or below the tolerance and
//! no longer halved by a step (the round-off floor of a matrix whose penalties reach 1/δ times
//! A's diagonal).
//!
//! **Penalties.** c_k = r_k/[`super::exact::AUGMENTED_DELTA`], r_k the iteration's scale of
//! `exact.rs` (c_k w_k ‖B_k‖² = d_k/δ against A's diagonal d_k): from the interior point's
//! hand-over one to three updates of the multipliers reach the tolerance. The penalties reach
//! 1/δ times A's diagonal, and the momentum residual of a subproblem has a round-off floor that
//! grows with them. When [`STALL`] Newton steps in a row have not halved the subproblem's best
//! momentum residual while it is above the step's tolerance, every c_k is divided by
//! [`SHRINK`] (at most [`MAX_SHRINKS`] times in a step) and the subproblem goes on from the same
//! u: any positive sequence of penalties leaves the method of multipliers a proximal point
//! method, with slower updates for smaller ones.

#![allow(clippy::needless_range_loop)] // the loops run over a term's one or two components

use super::cone::{apply, apply_ref, norm, onto_ball, Assembly, Program};
use crate::error::Result;

/// The step's stopping test at (x, σ).
type Converged<'a> = &'a mut dyn FnMut(&[f64], &[[f64; 2]]) -> bool;

/// Backtracking halvings of one Newton step at most.
const MAX_HALVINGS: usize = 30;

/// Newton steps without halving the subproblem's best momentum residual before the penalties shrink.
pub(crate) const STALL: usize = 3;

/// The factor by which a stalled subproblem's penalties are divided.
pub(crate) const SHRINK: f64 = 10.0;

/// Shrinks of the penalties in one step at most.
pub(crate) const MAX_SHRINKS: usize = 3;

/// What the stage returns: x, σ, the factorisations taken and the outer iterations.
pub(crate) struct Augmented {
    pub x: Vec<f64>,
    pub sigma: Vec<[f64; 2]>,
    pub iterations: usize,
    pub outer: usize,
    /// How many times the penalties shrank.
    pub shrinks: usize,
    /// Whether `converged(x, σ)` held at the end.
    pub converged: bool,
}

/// Runs the stage from (x, σ) with the penalties `c` (one per term; shrunk where a subproblem
/// stalls, module doc). `apply_b(t, x)` is B_k x + β_k; `converged(x, σ)` the step's stopping
/// test (`exact.rs`), read after each update of the multipliers; `tol` its tolerance; at most
/// `max_iterations` factorisations.
pub(crate) fn solve(
    program: Program<'_>,
    assembly: &mut Assembly,
    (x0, sigma0): (Vec<f64>, Vec<[f64; 2]>),
    c: &[f64],
    converged: Converged<'_>,
    tol: f64,
    max_iterations: usize,
) -> Result<Augmented> {
    let Program { n, a_trip, a_mat, b, terms, cols, vals, apply_b, cache, symmetric } = program;
    let kc = terms.len();
    let mut c = c.to_vec();
    let mut x = x0;
    let mut sig = sigma0;
    let (mut iterations, mut outer, mut shrinks) = (0, 0, 0);
    let (mut ax, mut force) = (vec![0.0; n], vec![0.0; n]);
    // ∇L into g and the momentum residual of ∇L at x; the multipliers P(σ + c y) into p
    let eval = |x: &[f64], sig: &[[f64; 2]], c: &[f64], p: &mut Vec<[f64; 2]>, g: &mut Vec<f64>, ax: &mut [f64], force: &mut [f64]| -> f64 {
        apply(a_mat, x, ax);
        g.clear();
        force.fill(0.0);
        p.clear();
        for (idx, t) in terms.iter().enumerate() {
            let y = apply_b(t, x);
            let s = sig[idx];
            let q = onto_ball([s[0] + c[idx] * y[0], s[1] + c[idx] * y[1]]);
            for cc in 0..t.dim {
                for e in t.rows[cc].clone() {
                    force[cols[e]] += t.w * vals[e] * q[cc];
                }
            }
            p.push(q);
        }
        let (mut max_r, mut max_s) = (0.0f64, 0.0f64);
        for k in 0..n {
            let r = ax[k] - b[k] + force[k];
            g.push(r);
            max_r = if r.is_nan() { f64::NAN } else { max_r.max(r.abs()) };
            max_s = max_s.max(b[k].abs() + ax[k].abs() + force[k].abs());
        }
        if max_s > 0.0 {
            max_r / max_s
        } else {
            max_r
        }
    };
    let (mut p, mut g) = (Vec::with_capacity(kc), Vec::with_capacity(n));
    let (mut pt, mut gt) = (Vec::with_capacity(kc), Vec::with_capacity(n));
    let (mut dx, mut kd, mut res, mut xt) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut blocks: Vec<[[f64; 2]; 2]> = vec![[[0.0; 2]; 2]; kc];
    while iterations < max_iterations {
        // the subproblem: minimise L(·; σ)
        let mut mom = eval(&x, &sig, &c, &mut p, &mut g, &mut ax, &mut force);
        let (mut best, mut since) = (mom, 0);
        while mom > 0.1 * tol && iterations < max_iterations {
            iterations += 1;
            let before = mom;
            for (idx, t) in terms.iter().enumerate() {
                let y = apply_b(t, &x);
                let s = sig[idx];
                let z = [s[0] + c[idx] * y[0], s[1] + c[idx] * y[1]];
                let nz = if t.dim == 1 { z[0].abs() } else { norm(z[0], z[1]) };
                let wc = t.w * c[idx];
                blocks[idx] = if nz <= 1.0 {
                    [[wc, 0.0], [0.0, wc]]
                } else if t.dim == 1 {
                    [[0.0; 2]; 2]
                } else {
                    let (nv, rho) = ([z[0] / nz, z[1] / nz], wc / nz);
                    [[rho * (1.0 - nv[0] * nv[0]), -rho * nv[0] * nv[1]], [-rho * nv[1] * nv[0], rho * (1.0 - nv[1] * nv[1])]]
                };
            }
            assembly.assemble(a_trip, terms, vals, |k| blocks[k]);
            let fac = assembly.factor(cache, symmetric)?;
            dx.iter_mut().zip(&g).for_each(|(d, r)| *d = -r);
            fac.solve_in_place(&mut dx)?;
            // one refinement against the assembled matrix
            apply_ref(fac.matrix(), &dx, &mut kd);
            res.iter_mut().zip(g.iter().zip(&kd)).for_each(|(e, (r, k))| *e = -r - k);
            fac.solve_in_place(&mut res)?;
            dx.iter_mut().zip(&res).for_each(|(d, r)| *d += r);
            // the line search on the derivative of L along dx, φ'(α) = ∇L(x + α dx)·dx: φ is
            // convex, so φ' grows with α and φ decreases wherever φ' < 0; its value would be
            // lost to round-off near the solution, its derivative is not
            let slope: f64 = g.iter().zip(&dx).map(|(g, d)| g * d).sum();
            let mut alpha = 1.0;
            let mut accepted = false;
            if slope < 0.0 {
                for _ in 0..=MAX_HALVINGS {
                    xt.iter_mut().zip(x.iter().zip(&dx)).for_each(|(t, (a, d))| *t = a + alpha * d);
                    let mt = eval(&xt, &sig, &c, &mut pt, &mut gt, &mut ax, &mut force);
                    let dphi: f64 = gt.iter().zip(&dx).map(|(g, d)| g * d).sum();
                    if dphi <= 0.1 * slope.abs() {
                        std::mem::swap(&mut x, &mut xt);
                        std::mem::swap(&mut p, &mut pt);
                        std::mem::swap(&mut g, &mut gt);
                        mom = mt;
                        accepted = true;
                        break;
                    }
                    alpha *= 0.5;
                }
            }
            // no step, or one that no longer halves a residual already within the step's
            // tolerance (the subproblem's round-off floor): the multipliers' update
            if !accepted || (mom <= tol && mom > 0.5 * before) {
                break;
            }
            // a subproblem stalled above the tolerance: smaller penalties, the same u
            if mom < 0.5 * best {
                (best, since) = (mom, 0);
            } else {
                since += 1;
            }
            if since >= STALL && mom > tol && shrinks < MAX_SHRINKS {
                shrinks += 1;
                c.iter_mut().for_each(|c| *c /= SHRINK);
                mom = eval(&x, &sig, &c, &mut p, &mut g, &mut ax, &mut force);
                (best, since) = (mom, 0);
            }
        }
        // the multipliers' update
        outer += 1;
        sig.clone_from(&p);
        if converged(&x, &sig) {
            return Ok(Augmented { x, sigma: sig, iterations, outer, shrinks, converged: true });
        }
    }
    Ok(Augmented { x, sigma: sig, iterations, outer, shrinks, converged: false })
}
