//! Fifth-order WENO one-sided derivatives for Hamilton–Jacobi equations.
//!
//! Equation: the one-sided derivatives (∂Φ/∂x)⁻ and (∂Φ/∂x)⁺ at a cell centre x_i, from the
//! divided differences v_k of Φ on a five-point stencil (Jiang & Peng 2000, "Weighted ENO schemes
//! for Hamilton–Jacobi equations", SIAM J. Sci. Comput. 21; weights and smoothness indicators of
//! Jiang & Shu 1996, "Efficient implementation of weighted ENO schemes", J. Comput. Phys. 126;
//! notation of Osher & Fedkiw 2003, *Level Set Methods and Dynamic Implicit Surfaces*, §3.4):
//!
//! ```text
//!   (Φ_x)⁻_i :  v1..v5 = D⁻Φ_{i−2}, D⁻Φ_{i−1}, D⁻Φ_i, D⁻Φ_{i+1}, D⁻Φ_{i+2}      (stencil i−3..i+2)
//!   (Φ_x)⁺_i :  v1..v5 = D⁺Φ_{i+2}, D⁺Φ_{i+1}, D⁺Φ_i, D⁺Φ_{i−1}, D⁺Φ_{i−2}      (stencil i−2..i+3)
//!
//!   q1 =  v1/3 − 7 v2/6 + 11 v3/6,   q2 = −v2/6 + 5 v3/6 + v4/3,   q3 = v3/3 + 5 v4/6 − v5/6
//!   β1 = 13/12 (v1 − 2v2 + v3)² + 1/4 (v1 − 4v2 + 3v3)²
//!   β2 = 13/12 (v2 − 2v3 + v4)² + 1/4 (v2 − v4)²
//!   β3 = 13/12 (v3 − 2v4 + v5)² + 1/4 (3v3 − 4v4 + v5)²
//!   α_k = d_k / (β_k + ε)²,  (d1, d2, d3) = (0.1, 0.6, 0.3),   ω_k = α_k / Σα
//!   Φ_x ≈ ω1 q1 + ω2 q2 + ω3 q3
//! ```
//!
//! ε is *scaled*: ε = 10⁻⁶ · max(v_k²) + 10⁻⁹⁹ (Fedkiw, Merriman & Osher 2000; Osher & Fedkiw
//! eq. 3.32). With a fixed ε = 10⁻⁶ the weights would depend on the units of Φ and of x (the
//! paper's cells are 1.76 mm wide, so a signed-distance Φ has undivided differences of 10⁻³);
//! the scaled ε makes the scheme invariant under Φ → cΦ and x → cx. The kernels below work on
//! *undivided* differences (Φ_{k+1} − Φ_k): the result is h·Φ_x, and the caller multiplies by 1/h
//! once. Because ε scales like v², this is exactly the divided-difference scheme.
//!
//! Option [`WenoWeights::Mapped`]: the mapped weights of Henrick, Aslam & Powers (2005, J. Comput.
//! Phys. 207), ω_k ← g_k(ω_k) / Σ g, g_k(ω) = ω (d_k + d_k² − 3 d_k ω + ω²) / (d_k² + ω (1 − 2 d_k)),
//! which bring the Jiang–Shu weights closer to the optimal d_k where the data are smooth (same
//! stencils, same indicators, less numerical dissipation). The default is Jiang–Shu, the paper's
//! scheme.

/// Which nonlinear weights the WENO5 derivative uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum WenoWeights {
    /// Jiang & Shu (1996): α_k = d_k / (β_k + ε)².
    #[default]
    JiangShu,
    /// Henrick, Aslam & Powers (2005) mapping of the Jiang–Shu weights.
    Mapped,
}

/// Relative WENO regularisation: ε = `WENO_EPS` · max(v_k²) + 10⁻⁹⁹.
pub const WENO_EPS: f64 = 1e-6;

/// The WENO5 combination of five (undivided or divided) differences, ordered from the upwind
/// side: `v1` is the farthest upwind difference, `v3` the one adjacent to the point.
/// `MAPPED` selects [`WenoWeights::Mapped`].
#[inline(always)]
pub fn weno5_with<const MAPPED: bool>(v1: f64, v2: f64, v3: f64, v4: f64, v5: f64) -> f64 {
    let q1 = v1 * (1.0 / 3.0) - v2 * (7.0 / 6.0) + v3 * (11.0 / 6.0);
    let q2 = -v2 * (1.0 / 6.0) + v3 * (5.0 / 6.0) + v4 * (1.0 / 3.0);
    let q3 = v3 * (1.0 / 3.0) + v4 * (5.0 / 6.0) - v5 * (1.0 / 6.0);

    let a = v1 - 2.0 * v2 + v3;
    let b = v1 - 4.0 * v2 + 3.0 * v3;
    let s1 = (13.0 / 12.0) * a * a + 0.25 * b * b;
    let a = v2 - 2.0 * v3 + v4;
    let b = v2 - v4;
    let s2 = (13.0 / 12.0) * a * a + 0.25 * b * b;
    let a = v3 - 2.0 * v4 + v5;
    let b = 3.0 * v3 - 4.0 * v4 + v5;
    let s3 = (13.0 / 12.0) * a * a + 0.25 * b * b;

    let vmax = (v1 * v1).max(v2 * v2).max(v3 * v3).max(v4 * v4).max(v5 * v5);
    let eps = WENO_EPS * vmax + 1e-99;
    let e1 = s1 + eps;
    let e2 = s2 + eps;
    let e3 = s3 + eps;
    // α_k = d_k / e_k²; multiplying all three by (e1 e2 e3 / e_max³)² leaves ω unchanged and
    // needs only two divisions. Since ε ≥ 10⁻⁶ max v² and β_k ≤ 20 max v², every ratio
    // e_k / e_max is ≥ 5·10⁻⁸, so the products below can neither underflow nor overflow.
    let inv = 1.0 / e1.max(e2).max(e3);
    let (e1, e2, e3) = (e1 * inv, e2 * inv, e3 * inv);
    let (e1, e2, e3) = (e1 * e1, e2 * e2, e3 * e3);
    let a1 = 0.1 * e2 * e3;
    let a2 = 0.6 * e1 * e3;
    let a3 = 0.3 * e1 * e2;
    if MAPPED {
        let inv = 1.0 / (a1 + a2 + a3);
        let (b1, b2, b3) = (map_weight(a1 * inv, 0.1), map_weight(a2 * inv, 0.6), map_weight(a3 * inv, 0.3));
        (b1 * q1 + b2 * q2 + b3 * q3) / (b1 + b2 + b3)
    } else {
        (a1 * q1 + a2 * q2 + a3 * q3) / (a1 + a2 + a3)
    }
}

/// The Jiang–Shu WENO5 combination ([`weno5_with`] with Jiang–Shu weights).
#[inline(always)]
pub fn weno5(v1: f64, v2: f64, v3: f64, v4: f64, v5: f64) -> f64 {
    weno5_with::<false>(v1, v2, v3, v4, v5)
}

/// Henrick et al.'s mapping g_d(ω) (g(d) = d, g'(d) = g''(d) = 0).
#[inline(always)]
fn map_weight(w: f64, d: f64) -> f64 {
    w * (d + d * d - 3.0 * d * w + w * w) / (d * d + w * (1.0 - 2.0 * d))
}

/// h·(Φ_x)⁻ at the centre of a seven-value window `p = [Φ_{i−3}, …, Φ_{i+3}]` (uses p[0..6]).
#[inline(always)]
pub fn weno5_minus(p: &[f64; 7]) -> f64 {
    weno5_minus_with::<false>(p)
}

/// h·(Φ_x)⁺ at the centre of a seven-value window `p = [Φ_{i−3}, …, Φ_{i+3}]` (uses p[1..7]).
#[inline(always)]
pub fn weno5_plus(p: &[f64; 7]) -> f64 {
    weno5_plus_with::<false>(p)
}

/// [`weno5_minus`] with a choice of weights.
#[inline(always)]
pub fn weno5_minus_with<const MAPPED: bool>(p: &[f64; 7]) -> f64 {
    weno5_with::<MAPPED>(p[1] - p[0], p[2] - p[1], p[3] - p[2], p[4] - p[3], p[5] - p[4])
}

/// [`weno5_plus`] with a choice of weights.
#[inline(always)]
pub fn weno5_plus_with<const MAPPED: bool>(p: &[f64; 7]) -> f64 {
    weno5_with::<MAPPED>(p[6] - p[5], p[5] - p[4], p[4] - p[3], p[3] - p[2], p[2] - p[1])
}

/// The seven values `data[k + m·step]`, m = −3..=3 (a WENO5 window along a row when `step = 1`,
/// along a column when `step` is the row stride).
#[inline(always)]
pub fn window(data: &[f64], k: usize, step: usize) -> [f64; 7] {
    let b = k - 3 * step;
    let w = &data[b..=b + 6 * step];
    [w[0], w[step], w[2 * step], w[3 * step], w[4 * step], w[5 * step], w[6 * step]]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_for_linear_and_quadratic_data() {
        // Each candidate stencil is exact for polynomials of degree ≤ 2 (in Φ), so the
        // combination is exact whatever the weights.
        let p: [f64; 7] = std::array::from_fn(|m| {
            let x = m as f64 - 3.0;
            1.0 + 2.0 * x + 0.5 * x * x
        });
        assert!((weno5_minus(&p) - 2.0).abs() < 1e-13);
        assert!((weno5_plus(&p) - 2.0).abs() < 1e-13);
        assert!((weno5_minus_with::<true>(&p) - 2.0).abs() < 1e-13);
        assert!((weno5_plus_with::<true>(&p) - 2.0).abs() < 1e-13);
    }

    #[test]
    fn scale_invariant() {
        let p: [f64; 7] = [0.0, 0.1, 0.5, 0.4, 2.0, 2.1, 1.0];
        let q: [f64; 7] = p.map(|x| 1e-4 * x);
        let (a, b) = (weno5_minus(&p), weno5_minus(&q));
        assert!((a * 1e-4 - b).abs() <= 1e-15 * a.abs().max(1e-300));
    }
}
