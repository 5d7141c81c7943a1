//! Primitives shared by the plastic projection of Σ (`rheology/plastic.rs`, eq. 12) and the
//! friction projections of the walls (`walls/`, eq. 8–9): the projection P on the unit ball
//! (paper eq. 6–7: Σ = P(Σ + r D(u)), s = P_b(s − r_b u_t)), the increment of a projected field,
//! and where the smoothed jump of the yield stress and of the friction sits across the interface
//! (the blending τ(Φ) = τ H_ε(Φ + sε), τ_b(Φ) = tan(α_b)(−σ_n)⁺ H_ε(Φ + sε)). They sit below
//! both rooms, so that neither imports the other's internals.

use crate::exec::Exec;
use crate::grid::{Field, HALO};

/// P: orthogonal projection on the unit ball of symmetric traceless 2×2 tensors, on the pair
/// (Λ_xx, Λ_xy) with |Λ|² = Λ_xx² + Λ_xy². Returns the scale factor 1/max(1, |Λ|).
#[inline]
pub fn unit_ball_scale(xx: f64, xy: f64) -> f64 {
    let n2 = xx * xx + xy * xy;
    if n2 > 1.0 {
        1.0 / n2.sqrt()
    } else {
        1.0
    }
}

/// max over the interior of |a − b| w / w_ref (deterministic; NaN propagates).
pub fn weighted_max_abs_diff(a: &Field, b: &Field, w: &Field, w_ref: f64, exec: Exec) -> f64 {
    let (sa, sb, sw) = (a.slice(), b.slice(), w.slice());
    let scale = if w_ref > 0.0 { 1.0 / w_ref } else { 0.0 };
    let (st, nx) = (a.stride(), a.nx);
    exec.max_rows(a.ny, a.nx * a.ny, |j| {
        let bb = (j + HALO) * st + HALO;
        let mut m = 0.0f64;
        for i in 0..nx {
            let d = (sa[bb + i] - sb[bb + i]).abs() * sw[bb + i] * scale;
            m = if d.is_nan() { f64::NAN } else { m.max(d) };
        }
        m
    })
}

/// Whether the increment `d` beats the largest so far, `m` (a NaN beats any number: it is
/// where a blow-up starts).
#[inline]
pub fn exceeds(d: f64, m: f64) -> bool {
    d > m || (d.is_nan() && !m.is_nan())
}

/// Where the smoothed jump of the yield stress τ(Φ) and of the wall friction τ_b(Φ) sits across
/// the interface band |Φ| < ε of the two-phase model.
///
/// The density is ρ(Φ) = ρ_f + (ρ_s − ρ_f) H_ε(Φ) (paper §2.4), so the band carries granular
/// weight from Φ = −ε on. With the paper's τ(Φ) = tan(α) p H_ε(Φ) the band's Coulomb ratio is
/// τ/p = tan(α) H_ε(Φ) < tan α: a band element whose shear-to-normal stress ratio exceeds
/// tan(α) H_ε(Φ) yields although the material is below its friction angle. On a slope θ < α
/// the part of the band where H_ε(Φ) < tan θ / tan α slides (about the upper half of the band
/// at θ = 20°, α = 27°), and in a tongue decelerated by basal friction (tan α_b / tan α = 0.53
/// in the paper's column) the upper half of the band cannot be decelerated with the rest.
/// Measured on the paper's column (docs/validation.md): at ny = 32 / 64 the fluidised run-out
/// is 2.03 / 2.12 m with `Paper` and 1.66 / 1.98 m with `GranularSide`. The paper's form stays
/// the default until the column's grid convergence decides between them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum InterfaceYield {
    /// τ(Φ) = τ(p) H_ε(Φ), τ_b(Φ) = tan(α_b)(−σ_n)⁺ H_ε(Φ): the paper's eq. after (10f).
    #[default]
    Paper,
    /// τ(Φ) = τ(p) H_ε(Φ + ε), τ_b likewise: full strength wherever Φ > 0 (the same smoothed
    /// function, shifted by ε to the air side, where p ≈ 0 under the top gauge).
    GranularSide,
    /// τ(Φ) = τ(p) H_ε(Φ + 2ε), τ_b likewise: full strength on the whole support of the
    /// smoothed density (Φ > −ε, where the band carries granular weight), so that the Coulomb
    /// ratio is tan α wherever there is granular weight to hold; H_ε rises to it over the air
    /// cells −3ε < Φ < −ε, where p ≈ 0 under the top gauge and there is no weight. The only
    /// form with which an inclined free surface can be at rest (the band's required ratio is
    /// tan θ at every depth of it: `granrs validate fluidised-layer`, docs/validation.md).
    DensitySupport,
}

impl InterfaceYield {
    /// The argument of H_ε for the level-set value `phi`.
    #[inline]
    pub fn shift(self, phi: f64, eps: f64) -> f64 {
        match self {
            InterfaceYield::Paper => phi,
            InterfaceYield::GranularSide => phi + eps,
            InterfaceYield::DensitySupport => phi + 2.0 * eps,
        }
    }
}
