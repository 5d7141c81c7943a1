//! The interior-point stage of the exact step (`exact.rs`): eq. (11) of Aravena et al. posed as
//! the second-order cone program
//!
//!   minimise ½xᵀA x − bᵀx + Σ_k w_k t_k  subject to  s_k = (t_k, B_k x + β_k) ∈ K_k,
//!
//! K_k the second-order cone {(t, y): t ≥ |y|} of R^{1+dim_k}, and solved by a primal–dual
//! path-following method with Nesterov–Todd scaling and Mehrotra's predictor–corrector
//! (Nesterov & Todd 1998, *SIAM J. Optim.* 8; Vandenberghe 2010, "The CVXOPT linear and
//! quadratic cone program solvers", §§ 3–5; for viscoplastic flows: Bleyer 2018, *Comput.
//! Methods Appl. Mech. Eng.* 330).
//!
//! **Conditions.** With the dual z_k = (z_0,k, z_y,k) ∈ K_k, stationarity in t gives
//! z_0,k = w_k (kept exactly: the iteration starts there and never moves it) and stationarity
//! in x gives A x − b − Σ_k B_kᵀ z_y,k = 0, the momentum equation of eq. (11) with the multiplier
//! σ_k = −z_y,k/w_k (|σ_k| ≤ 1 because z_k ∈ K_k). The central path is s_k ∘ z_k = μ e (∘ the
//! Jordan product of the cone, e = (1, 0)).
//!
//! **One iteration.** With W_k the Nesterov–Todd scaling of (s_k, z_k) (W_k z_k = W_k⁻¹ s_k =
//! λ_k) and H_k = W_k⁻², the Newton equations eliminate t and z cone by cone:
//! dz_k = W_k⁻¹q_k − H_k ds_k, ds_k = (dt_k, B_k dx), dz_0,k = 0, and
//!
//!   (A + Σ_k B_kᵀ M_k B_k) dx = −r_x + Σ_k B_kᵀ g_k,   M_k = H_yy − H_y0 H_0y/H_00,
//!
//! g_k = [W⁻¹q]_y − H_y0 [W⁻¹q]_0/H_00, the matrix of the semismooth Newton step's pattern,
//! solved once per iteration like the semismooth step's. The predictor takes q_k = −λ_k, the
//! corrector q_k = λ_k \ (−λ_k∘λ_k − (W_k⁻¹ds_k^a)∘(W_k dz_k^a) + σ_c μ e) with
//! σ_c = (μ_a/μ)³, and the step is 0.99 of the largest that keeps s and z in the cones.
//!
//! **Start and stop.** x starts at the predictor without yield stress or friction (A x = b),
//! t_k = 2|B_k x + β_k| (a positive floor where it vanishes) and z_k = (w_k, 0). The stage stops
//! when the projection residual of eq. (11) at (x, σ), with the iteration's r_k (`exact.rs`), is
//! below [`POLISH_START`]: the semismooth Newton loop then finishes the step from that point,
//! where the interior point would slow down (the scaled system's condition grows as 1/μ).

#![allow(clippy::needless_range_loop)] // the loops run over a cone's one or two components
#![allow(clippy::type_complexity)] // a Newton direction's four parts, named where it is built

use super::cone::{apply, norm, Assembly, Program};
use crate::error::{Error, Result};

/// The projection residual of eq. (11) at which the interior point hands over to the
/// semismooth Newton loop.
pub const POLISH_START: f64 = 1e-4;

/// Fraction of the largest step that keeps s and z inside their cones.
const STEP_FRACTION: f64 = 0.99;

/// The relative drop of μ below which the interior point stops whatever the residual (the
/// scaled system has lost its precision): the semismooth loop takes over.
const MU_FLOOR: f64 = 1e-14;

/// Largest α ≥ 0 (at most `f64::INFINITY`) with (u0, u1) + α(d0, d1) in the cone, for (u0, u1)
/// inside it.
fn max_step(u0: f64, u1: [f64; 2], d0: f64, d1: [f64; 2]) -> f64 {
    let a = d0 * d0 - (d1[0] * d1[0] + d1[1] * d1[1]);
    let b = u0 * d0 - (u1[0] * d1[0] + u1[1] * d1[1]);
    let c = u0 * u0 - (u1[0] * u1[0] + u1[1] * u1[1]);
    let mut alpha = f64::INFINITY;
    // a α² + 2 b α + c ≥ 0 with c > 0: the smallest positive root
    if a == 0.0 {
        if b < 0.0 {
            alpha = -c / (2.0 * b);
        }
    } else {
        let disc = b * b - a * c;
        if disc >= 0.0 {
            let sq = disc.sqrt();
            for r in [(-b - sq) / a, (-b + sq) / a] {
                if r > 0.0 {
                    alpha = alpha.min(r);
                }
            }
        }
    }
    if d0 < 0.0 {
        alpha = alpha.min(-u0 / d0);
    }
    alpha
}

/// The Jordan product u∘v of the cone.
fn jordan(u0: f64, u1: [f64; 2], v0: f64, v1: [f64; 2]) -> (f64, [f64; 2]) {
    (u0 * v0 + u1[0] * v1[0] + u1[1] * v1[1], [u0 * v1[0] + v0 * u1[0], u0 * v1[1] + v0 * u1[1]])
}

/// u with λ∘u = v.
fn jordan_div(l0: f64, l1: [f64; 2], v0: f64, v1: [f64; 2]) -> (f64, [f64; 2]) {
    let det = l0 * l0 - (l1[0] * l1[0] + l1[1] * l1[1]);
    let u0 = (l0 * v0 - (l1[0] * v1[0] + l1[1] * v1[1])) / det;
    (u0, [(v1[0] - u0 * l1[0]) / l0, (v1[1] - u0 * l1[1]) / l0])
}

/// The Nesterov–Todd scaling of one cone: W v = η(w̄₀v₀ + w̄₁·v₁, w̄₁v₀ + v₁ + (w̄₁·v₁)w̄₁/(1 + w̄₀)).
#[derive(Clone, Copy, Debug, Default)]
struct Scaling {
    eta: f64,
    w0: f64,
    w1: [f64; 2],
}

impl Scaling {
    fn new(t: f64, y: [f64; 2], z0: f64, zy: [f64; 2]) -> Self {
        // t² − |y|² as (t − |y|)(t + |y|): no cancellation near the cone's boundary
        let (ny, nz) = (norm(y[0], y[1]), norm(zy[0], zy[1]));
        let sn = ((t - ny) * (t + ny)).sqrt();
        let zn = ((z0 - nz) * (z0 + nz)).sqrt();
        let (s0, s1) = (t / sn, [y[0] / sn, y[1] / sn]);
        let (q0, q1) = (z0 / zn, [zy[0] / zn, zy[1] / zn]);
        let gamma = ((1.0 + s0 * q0 + s1[0] * q1[0] + s1[1] * q1[1]) / 2.0).sqrt();
        Scaling { eta: (sn / zn).sqrt(), w0: (s0 + q0) / (2.0 * gamma), w1: [(s1[0] - q1[0]) / (2.0 * gamma), (s1[1] - q1[1]) / (2.0 * gamma)] }
    }

    fn mul(&self, v0: f64, v1: [f64; 2]) -> (f64, [f64; 2]) {
        let dot = self.w1[0] * v1[0] + self.w1[1] * v1[1];
        let c = dot / (1.0 + self.w0);
        let e = self.eta;
        (e * (self.w0 * v0 + dot), [e * (self.w1[0] * v0 + v1[0] + c * self.w1[0]), e * (self.w1[1] * v0 + v1[1] + c * self.w1[1])])
    }

    fn inv(&self, v0: f64, v1: [f64; 2]) -> (f64, [f64; 2]) {
        let dot = self.w1[0] * v1[0] + self.w1[1] * v1[1];
        let c = dot / (1.0 + self.w0);
        let e = 1.0 / self.eta;
        (e * (self.w0 * v0 - dot), [e * (-self.w1[0] * v0 + v1[0] + c * self.w1[0]), e * (-self.w1[1] * v0 + v1[1] + c * self.w1[1])])
    }

    /// H = W⁻² = η⁻²(2 J w̄ w̄ᵀ J − J): (H_00, H_0y, H_yy).
    fn inv_square(&self) -> (f64, [f64; 2], [[f64; 2]; 2]) {
        let e2 = 1.0 / (self.eta * self.eta);
        let (w0, w1) = (self.w0, self.w1);
        let h00 = e2 * (2.0 * w0 * w0 - 1.0);
        let h0y = [-2.0 * e2 * w0 * w1[0], -2.0 * e2 * w0 * w1[1]];
        let hyy = [[e2 * (2.0 * w1[0] * w1[0] + 1.0), e2 * 2.0 * w1[0] * w1[1]], [e2 * 2.0 * w1[1] * w1[0], e2 * (2.0 * w1[1] * w1[1] + 1.0)]];
        (h00, h0y, hyy)
    }
}

/// What the interior-point stage returns: x, σ_k = −z_y,k/w_k and its iterations.
pub(crate) struct InteriorPoint {
    pub x: Vec<f64>,
    pub sigma: Vec<[f64; 2]>,
    pub iterations: usize,
}

/// Runs the interior-point stage (module doc) from the predictor without yield stress,
/// `x0` (A x0 = b). `apply_b(t, x)` is B_k x + β_k; `projection(x, σ)` the projection residual
/// of eq. (11); at most `max_iterations` iterations.
pub(crate) fn solve(
    program: Program<'_>,
    assembly: &mut Assembly,
    x0: Vec<f64>,
    projection: &mut dyn FnMut(&[f64], &[[f64; 2]]) -> f64,
    max_iterations: usize,
) -> Result<InteriorPoint> {
    let Program { n, a_trip, a_mat, b, terms, cols, vals, apply_b, cache, symmetric } = program;
    let kc = terms.len();
    let mut x = x0;
    let mut y: Vec<[f64; 2]> = terms.iter().map(|t| apply_b(t, &x)).collect();
    let floor = {
        let mut m: Vec<f64> = y.iter().map(|v| v[0].hypot(v[1])).filter(|&m| m > 0.0).collect();
        m.sort_by(f64::total_cmp);
        m.get(m.len() / 2).copied().unwrap_or(1.0).max(f64::MIN_POSITIVE) * 1e-3
    };
    let mut t: Vec<f64> = y.iter().map(|v| 2.0 * v[0].hypot(v[1]) + floor).collect();
    let mut zy: Vec<[f64; 2]> = vec![[0.0; 2]; kc];
    let w: Vec<f64> = terms.iter().map(|t| t.w).collect();
    let mu0 = (0..kc).map(|k| t[k] * w[k]).sum::<f64>() / kc as f64;
    let sigma_of = |zy: &[[f64; 2]]| -> Vec<[f64; 2]> { zy.iter().zip(&w).map(|(z, w)| [-z[0] / w, -z[1] / w]).collect() };
    let mut ax = vec![0.0; n];
    let mut iterations = 0;
    loop {
        let proj = projection(&x, &sigma_of(&zy));
        let mu = (0..kc).map(|k| t[k] * w[k] + y[k][0] * zy[k][0] + y[k][1] * zy[k][1]).sum::<f64>() / kc as f64;
        if proj <= POLISH_START || mu <= MU_FLOOR * mu0 || iterations >= max_iterations {
            break;
        }
        if !mu.is_finite() {
            return Err(Error::SolverFailure {
                solver: "interior point of the exact step".into(), message: format!("μ = {mu} after {iterations} iterations")
            });
        }
        // r_x = A x − b − Σ B_kᵀ z_y,k
        apply(a_mat, &x, &mut ax);
        let mut rx: Vec<f64> = ax.iter().zip(b).map(|(a, b)| a - b).collect();
        for (k, term) in terms.iter().enumerate() {
            for c in 0..term.dim {
                for e in term.rows[c].clone() {
                    rx[cols[e]] -= vals[e] * zy[k][c];
                }
            }
        }
        // scalings, λ, the reduced matrix
        let mut scal = Vec::with_capacity(kc);
        let mut hs = Vec::with_capacity(kc);
        let mut lam = Vec::with_capacity(kc);
        let mut blocks = Vec::with_capacity(kc);
        let scalings: Vec<Scaling> = (0..kc).map(|k| Scaling::new(t[k], y[k], w[k], zy[k])).collect();
        if scalings.iter().any(|s| !(s.eta.is_finite() && s.eta > 0.0 && s.w0.is_finite() && s.w1[0].is_finite() && s.w1[1].is_finite())) {
            // a point on a cone's boundary to round-off: the semismooth loop takes over
            break;
        }
        iterations += 1;
        for (k, term) in terms.iter().enumerate() {
            let s = scalings[k];
            let (h00, mut h0y, mut hyy) = s.inv_square();
            if term.dim == 1 {
                h0y[1] = 0.0;
                hyy[0][1] = 0.0;
                hyy[1][0] = 0.0;
                hyy[1][1] = 0.0;
            }
            let m = [
                [hyy[0][0] - h0y[0] * h0y[0] / h00, hyy[0][1] - h0y[0] * h0y[1] / h00],
                [hyy[1][0] - h0y[1] * h0y[0] / h00, hyy[1][1] - h0y[1] * h0y[1] / h00],
            ];
            blocks.push(m);
            lam.push(s.mul(w[k], zy[k]));
            scal.push(s);
            hs.push((h00, h0y, hyy));
        }
        assembly.assemble(a_trip, terms, vals, |k| blocks[k]);
        let lu = assembly.factor(cache, symmetric)?;
        // one Newton direction for the right-hand sides q_k: (dx, dt, B dx, dz_y)
        let direction = |q: &[(f64, [f64; 2])]| -> Result<(Vec<f64>, Vec<f64>, Vec<[f64; 2]>, Vec<[f64; 2]>)> {
            let mut rhs: Vec<f64> = rx.iter().map(|r| -r).collect();
            let mut a: Vec<(f64, [f64; 2])> = Vec::with_capacity(kc);
            for (k, term) in terms.iter().enumerate() {
                let (a0, mut a1) = scal[k].inv(q[k].0, q[k].1);
                if term.dim == 1 {
                    a1[1] = 0.0;
                }
                let (h00, h0y, _) = hs[k];
                let g = [a1[0] - h0y[0] * a0 / h00, a1[1] - h0y[1] * a0 / h00];
                for c in 0..term.dim {
                    for e in term.rows[c].clone() {
                        rhs[cols[e]] += vals[e] * g[c];
                    }
                }
                a.push((a0, a1));
            }
            lu.solve_in_place(&mut rhs)?;
            let dx = rhs;
            let (mut dt, mut bdx, mut dz) = (Vec::with_capacity(kc), Vec::with_capacity(kc), Vec::with_capacity(kc));
            for (k, term) in terms.iter().enumerate() {
                let by = apply_b(term, &dx);
                let bd = [by[0] - term.beta[0], by[1] - term.beta[1]];
                let (h00, h0y, hyy) = hs[k];
                let (a0, a1) = a[k];
                let d = (a0 - (h0y[0] * bd[0] + h0y[1] * bd[1])) / h00;
                let mut z = [a1[0] - h0y[0] * d - (hyy[0][0] * bd[0] + hyy[0][1] * bd[1]), a1[1] - h0y[1] * d - (hyy[1][0] * bd[0] + hyy[1][1] * bd[1])];
                if term.dim == 1 {
                    z[1] = 0.0;
                }
                dt.push(d);
                bdx.push(bd);
                dz.push(z);
            }
            Ok((dx, dt, bdx, dz))
        };
        let largest = |dt: &[f64], bdx: &[[f64; 2]], dz: &[[f64; 2]]| -> f64 {
            (0..kc).map(|k| max_step(t[k], y[k], dt[k], bdx[k]).min(max_step(w[k], zy[k], 0.0, dz[k]))).fold(f64::INFINITY, f64::min)
        };
        // predictor
        let ll: Vec<(f64, [f64; 2])> = lam.iter().map(|&(l0, l1)| jordan(l0, l1, l0, l1)).collect();
        let q: Vec<(f64, [f64; 2])> = lam.iter().map(|&(l0, l1)| (-l0, [-l1[0], -l1[1]])).collect();
        let (_, dt, bdx, dz) = direction(&q)?;
        let aa = largest(&dt, &bdx, &dz).min(1.0);
        let mu_aff = (0..kc)
            .map(|k| {
                (t[k] + aa * dt[k]) * w[k] + (y[k][0] + aa * bdx[k][0]) * (zy[k][0] + aa * dz[k][0]) + (y[k][1] + aa * bdx[k][1]) * (zy[k][1] + aa * dz[k][1])
            })
            .sum::<f64>()
            / kc as f64;
        let sigma_c = (mu_aff / mu).clamp(0.0, 1.0).powi(3);
        // corrector
        let q: Vec<(f64, [f64; 2])> = (0..kc)
            .map(|k| {
                let (ws0, ws1) = scal[k].inv(dt[k], bdx[k]);
                let (wz0, wz1) = scal[k].mul(0.0, dz[k]);
                let (c0, c1) = jordan(ws0, ws1, wz0, wz1);
                let (l0, l1) = lam[k];
                jordan_div(l0, l1, -ll[k].0 - c0 + sigma_c * mu, [-ll[k].1[0] - c1[0], -ll[k].1[1] - c1[1]])
            })
            .collect();
        let (dx, dt, bdx, dz) = direction(&q)?;
        let alpha = (STEP_FRACTION * largest(&dt, &bdx, &dz)).min(1.0);
        let finite = alpha.is_finite() && dx.iter().chain(&dt).all(|v| v.is_finite()) && dz.iter().all(|v| v[0].is_finite() && v[1].is_finite());
        if !finite || alpha <= 0.0 {
            // the scaled system has lost its precision (a cone at its boundary to round-off):
            // the semismooth loop takes over from the last point
            break;
        }
        for (xi, d) in x.iter_mut().zip(&dx) {
            *xi += alpha * d;
        }
        for k in 0..kc {
            t[k] += alpha * dt[k];
            zy[k] = [zy[k][0] + alpha * dz[k][0], zy[k][1] + alpha * dz[k][1]];
        }
        y = terms.iter().map(|term| apply_b(term, &x)).collect();
    }
    Ok(InteriorPoint { sigma: sigma_of(&zy), x, iterations })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Interior points of the cone R × R²: (t, y) with t > |y|.
    fn points() -> Vec<(f64, [f64; 2])> {
        vec![(1.0, [0.0, 0.0]), (2.0, [1.5, -0.7]), (1e-3, [6e-4, 7e-4]), (350.0, [-120.0, 300.0]), (1.0, [0.999_999, 0.0])]
    }

    /// |a − b| within 1e-12 of `scale`: the tests' scales include the points' conditioning (the
    /// point 1e-6 from the boundary: 1/(t − |y|) ~ 1e6 amplifies round-off, hence factors up to
    /// 1e4 on unit data)
    fn close(a: f64, b: f64, scale: f64) -> bool {
        (a - b).abs() <= 1e-12 * scale
    }

    #[test]
    fn the_scaling_maps_z_and_s_to_the_same_point() {
        // W z = W⁻¹ s = λ (Vandenberghe 2010, eq. 31), to round-off of the points' size
        for &(t, y) in &points() {
            for &(z0, zy) in &points() {
                let w = Scaling::new(t, y, z0, zy);
                let (a0, a1) = w.mul(z0, zy);
                let (b0, b1) = w.inv(t, y);
                let scale = t.max(z0).max(1.0);
                assert!(close(a0, b0, scale) && close(a1[0], b1[0], scale) && close(a1[1], b1[1], scale), "{t} {y:?} {z0} {zy:?}");
                // W⁻¹ W v = v and H v = W⁻¹ W⁻¹ v
                let v = (0.3, [-1.2, 0.8]);
                let (c0, c1) = w.mul(v.0, v.1);
                let (d0, d1) = w.inv(c0, c1);
                assert!(close(d0, v.0, 1.0) && close(d1[0], v.1[0], 1.0) && close(d1[1], v.1[1], 1.0));
                let (h00, h0y, hyy) = w.inv_square();
                let (e0, e1) = w.inv(v.0, v.1);
                let (f0, f1) = w.inv(e0, e1);
                let hv0 = h00 * v.0 + h0y[0] * v.1[0] + h0y[1] * v.1[1];
                let hv1 = [h0y[0] * v.0 + hyy[0][0] * v.1[0] + hyy[0][1] * v.1[1], h0y[1] * v.0 + hyy[1][0] * v.1[0] + hyy[1][1] * v.1[1]];
                let s = f0.abs().max(f1[0].abs()).max(f1[1].abs()).max(1.0);
                assert!(close(hv0, f0, 1e3 * s) && close(hv1[0], f1[0], 1e3 * s) && close(hv1[1], f1[1], 1e3 * s), "{hv0} {f0} {hv1:?} {f1:?}");
            }
        }
    }

    #[test]
    fn the_jordan_division_inverts_the_product() {
        for &(l0, l1) in &points() {
            let v = (0.4, [2.0, -1.0]);
            let (u0, u1) = jordan_div(l0, l1, v.0, v.1);
            let (p0, p1) = jordan(l0, l1, u0, u1);
            assert!(close(p0, v.0, 1e4) && close(p1[0], v.1[0], 1e4) && close(p1[1], v.1[1], 1e4), "{l0} {l1:?}");
        }
    }

    #[test]
    fn the_largest_step_lands_on_the_cone_boundary() {
        for &(u0, u1) in &points() {
            for d in [(-1.0, [0.0, 0.0]), (0.0, [1.0, 0.0]), (0.5, [-3.0, 2.0]), (-0.1, [0.05, 0.0])] {
                let a = max_step(u0, u1, d.0, d.1);
                assert!(a > 0.0 && a.is_finite());
                let (t, y) = (u0 + a * d.0, [u1[0] + a * d.1[0], u1[1] + a * d.1[1]]);
                // on the boundary: t = |y| (relative to the step's size)
                assert!((t - y[0].hypot(y[1])).abs() <= 1e-9 * (u0 + a * (d.0.abs() + d.1[0].abs() + d.1[1].abs())), "{u0} {u1:?} {d:?}: {t} {y:?}");
            }
            // a direction into the cone has no bound
            assert_eq!(max_step(u0, u1, 1.0, [0.0, 0.0]), f64::INFINITY);
        }
    }
}
