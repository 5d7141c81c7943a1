//! Smoothed Heaviside function and the two-phase material laws built on it (paper §2.4, §3.1
//! step 2).
//!
//! Equations (Aravena et al. §2.4; the regularisation of Sussman, Smereka & Osher 1994):
//!
//! ```text
//!   H_ε(Φ) = 0                                    if Φ < −ε
//!          = ½ (1 + Φ/ε + sin(πΦ/ε)/π)            if |Φ| ≤ ε
//!          = 1                                    if Φ > ε
//!   δ_ε(Φ) = dH_ε/dΦ = (1 + cos(πΦ/ε)) / (2ε)     if |Φ| ≤ ε, 0 otherwise
//!
//!   ρ(Φ)   = ρ_d H_ε(Φ) + ρ_l (1 − H_ε(Φ))                         (density)
//!   1/η(Φ) = H_ε(Φ)/η_d + (1 − H_ε(Φ))/η_l                          (harmonic mean, ref. [4])
//!   q(Φ)   = q_d H_ε(Φ) + q_l (1 − H_ε(Φ))                         (κ(Φ), τ(Φ), τ_b(Φ): [`blend`])
//! ```
//!
//! Φ > 0 is the dense (granular) phase, Φ < 0 the light one (air). ε is a length: the default is
//! ε = 1.5 h ([`DEFAULT_EPS_CELLS`]), the usual choice for a level set kept close to a distance
//! function (interface band of 3 cells; Sussman et al. 1994 use ε = 1.5 h). It is configurable
//! through [`TwoPhaseProperties::eps`].

use crate::error::{check_positive, Result};
use crate::exec::Exec;
use crate::grid::{Field, Grid, Location, HALO};
use std::f64::consts::PI;

/// Default half-width of the smoothed interface, in cells: ε = 1.5 h.
pub const DEFAULT_EPS_CELLS: f64 = 1.5;

/// The default ε = 1.5 · min(dx, dy) for `grid`.
pub fn default_eps(grid: &Grid) -> f64 {
    DEFAULT_EPS_CELLS * grid.h()
}

/// Smoothed Heaviside H_ε(Φ) (0 in the light phase, 1 in the dense phase).
#[inline]
pub fn heaviside(phi: f64, eps: f64) -> f64 {
    if phi < -eps {
        0.0
    } else if phi > eps {
        1.0
    } else {
        let r = phi / eps;
        0.5 * (1.0 + r + (PI * r).sin() / PI)
    }
}

/// Smoothed Dirac δ_ε(Φ) = dH_ε/dΦ.
#[inline]
pub fn dirac(phi: f64, eps: f64) -> f64 {
    if phi.abs() > eps {
        0.0
    } else {
        (1.0 + (PI * phi / eps).cos()) / (2.0 * eps)
    }
}

/// Arithmetic blend q_d H_ε(Φ) + q_l (1 − H_ε(Φ)) of a dense-phase and a light-phase value.
#[inline]
pub fn blend(phi: f64, eps: f64, dense: f64, light: f64) -> f64 {
    let h = heaviside(phi, eps);
    dense * h + light * (1.0 - h)
}

/// Harmonic blend 1/q = H_ε(Φ)/q_d + (1 − H_ε(Φ))/q_l (both values > 0).
#[inline]
pub fn blend_harmonic(phi: f64, eps: f64, dense: f64, light: f64) -> f64 {
    let h = heaviside(phi, eps);
    dense * light / (h * light + (1.0 - h) * dense)
}

/// Densities and viscosities of the two phases, and the interface half-width ε.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TwoPhaseProperties {
    /// Density of the dense (granular) phase ρ_d, kg/m³.
    pub rho_dense: f64,
    /// Density of the light phase (air) ρ_l, kg/m³.
    pub rho_light: f64,
    /// Viscosity of the dense phase η_d, Pa s.
    pub eta_dense: f64,
    /// Viscosity of the light phase η_l, Pa s.
    pub eta_light: f64,
    /// Half-width ε of the smoothed interface, m.
    pub eps: f64,
}

impl TwoPhaseProperties {
    /// Properties with ε = [`DEFAULT_EPS_CELLS`] · h on `grid`; validated.
    pub fn new(rho_dense: f64, rho_light: f64, eta_dense: f64, eta_light: f64, grid: &Grid) -> Result<Self> {
        let p = TwoPhaseProperties { rho_dense, rho_light, eta_dense, eta_light, eps: default_eps(grid) };
        p.validate()?;
        Ok(p)
    }

    /// Checks every value is finite and > 0; errors name the offending parameter.
    pub fn validate(&self) -> Result<()> {
        check_positive("rho_dense", self.rho_dense)?;
        check_positive("rho_light", self.rho_light)?;
        check_positive("eta_dense", self.eta_dense)?;
        check_positive("eta_light", self.eta_light)?;
        check_positive("eps", self.eps)?;
        Ok(())
    }

    /// H_ε(Φ).
    #[inline]
    pub fn heaviside(&self, phi: f64) -> f64 {
        heaviside(phi, self.eps)
    }

    /// ρ(Φ) = ρ_d H + ρ_l (1 − H).
    #[inline]
    pub fn density(&self, phi: f64) -> f64 {
        blend(phi, self.eps, self.rho_dense, self.rho_light)
    }

    /// η(Φ) with 1/η = H/η_d + (1 − H)/η_l.
    #[inline]
    pub fn viscosity(&self, phi: f64) -> f64 {
        blend_harmonic(phi, self.eps, self.eta_dense, self.eta_light)
    }

    /// q_d H + q_l (1 − H) with this ε (for κ(Φ), τ(Φ), τ_b(Φ)).
    #[inline]
    pub fn blend(&self, phi: f64, dense: f64, light: f64) -> f64 {
        blend(phi, self.eps, dense, light)
    }
}

/// out(i, j) = f(Φ(i, j)) on the interior of two cell-centre fields (step 2 of the paper's
/// scheme: ρⁿ⁺¹ = ρ(Φⁿ⁺¹), …). Ghosts of `out` are left untouched.
pub fn map_centre_field(phi: &Field, out: &mut Field, exec: Exec, f: impl Fn(f64) -> f64 + Sync + Send) -> Result<()> {
    if phi.loc != Location::Centre || out.loc != Location::Centre || phi.data.dim() != out.data.dim() {
        return Err(crate::error::Error::Shape {
            name: "out (same shape as the cell-centre field phi)".into(),
            got: vec![out.ny, out.nx],
            expected: vec![phi.ny, phi.nx],
        });
    }
    let (nx, ny, stride) = (phi.nx, phi.ny, phi.stride());
    let p = phi.slice();
    exec.for_each_row(out.slice_mut(), stride, |r, row| {
        if (HALO..ny + HALO).contains(&r) {
            for c in HALO..nx + HALO {
                row[c] = f(p[r * stride + c]);
            }
        }
    });
    Ok(())
}
