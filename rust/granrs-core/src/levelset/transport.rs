//! Transport of the level-set function by the MAC velocity (paper eq. 10a, §3.1 step 1).
//!
//! Equation:  ∂Φ/∂t + u·∇Φ = 0  in Ω.
//!
//! Space: non-conservative upwind form L(Φ) = −(u_c Φ_x + v_c Φ_y) at cell centres, with the
//! cell-centre velocity u_c(i,j) = ½(u_{i,j} + u_{i+1,j}) (the two x-faces of the cell),
//! v_c(i,j) = ½(v_{i,j} + v_{i,j+1}), and the upwind WENO5 derivative of [`super::weno5`]:
//! Φ_x = (Φ_x)⁻ if u_c > 0, (Φ_x)⁺ if u_c < 0 (Jiang & Peng 2000; Osher & Fedkiw 2003, §3.4),
//! with Jiang–Shu weights (default) or Henrick's mapped weights ([`WenoWeights`]).
//!
//! Time: the third-order TVD Runge–Kutta scheme of Shu & Osher (1988, J. Comput. Phys. 77),
//!
//! ```text
//!   Φ⁽¹⁾   = Φⁿ + δt L(Φⁿ)
//!   Φ⁽²⁾   = ¾ Φⁿ + ¼ (Φ⁽¹⁾ + δt L(Φ⁽¹⁾))
//!   Φⁿ⁺¹  = ⅓ Φⁿ + ⅔ (Φ⁽²⁾ + δt L(Φ⁽²⁾))
//! ```
//!
//! Before each stage the ghost cells of the stage's Φ are filled by linear extrapolation (keeps
//! |∇Φ| of a distance function across the boundary; inflow boundaries then see a smooth Φ).
//!
//! Stability: the scheme is used with δt · max(|u_c|/dx + |v_c|/dy) ≤ CFL; linear stability of
//! WENO5 + RK3 allows CFL up to about 1.4 in 1D, we recommend 0.5 ([`DEFAULT_CFL`]).
//!
//! Work is split by rows with [`Exec`]; each cell's arithmetic does not depend on the split, so
//! serial and parallel runs are bit-identical. Scratch fields are allocated once in
//! [`LevelSetTransport::new`]; [`LevelSetTransport::advect`] allocates nothing.

use super::weno5::{weno5_minus_with, weno5_plus_with, window, WenoWeights};
use crate::error::{Error, Result};
use crate::exec::Exec;
use crate::grid::{Field, Grid, Location, HALO};

/// Recommended Courant number δt · max(|u_c|/dx + |v_c|/dy) for the level-set transport.
pub const DEFAULT_CFL: f64 = 0.5;

/// Checks that `f` lives at `loc` on `grid`.
pub(crate) fn check_field(name: &str, f: &Field, grid: &Grid, loc: Location) -> Result<()> {
    let (nx, ny) = loc.interior_shape(grid.nx, grid.ny);
    if f.loc != loc || f.nx != nx || f.ny != ny || f.data.dim() != (ny + 2 * HALO, nx + 2 * HALO) {
        return Err(Error::Shape { name: format!("{name} ({:?} field, expected {:?})", f.loc, loc), got: vec![f.ny, f.nx], expected: vec![ny, nx] });
    }
    Ok(())
}

/// The level-set transport step: TVD-RK3 in time, upwind WENO5 in space.
#[derive(Clone, Debug)]
pub struct LevelSetTransport {
    weights: WenoWeights,
    phi1: Field,
    phi2: Field,
}

impl LevelSetTransport {
    /// Allocates the two Runge–Kutta stage fields for `grid`; Jiang–Shu weights.
    pub fn new(grid: &Grid) -> Self {
        Self::with_weights(grid, WenoWeights::JiangShu)
    }

    /// Same as [`new`](Self::new) with a choice of WENO weights.
    pub fn with_weights(grid: &Grid, weights: WenoWeights) -> Self {
        LevelSetTransport { weights, phi1: Field::zeros(grid, Location::Centre), phi2: Field::zeros(grid, Location::Centre) }
    }

    /// The WENO weights in use.
    pub fn weights(&self) -> WenoWeights {
        self.weights
    }

    /// Advances Φ by one step δt of ∂Φ/∂t + u·∇Φ = 0 with the MAC velocity (u on x-faces, v on
    /// y-faces) frozen over the step. On return the interior of `phi` holds Φⁿ⁺¹ (its ghosts hold
    /// the linear extrapolation of Φⁿ).
    pub fn advect(&mut self, phi: &mut Field, u: &Field, v: &Field, grid: &Grid, dt: f64, exec: Exec) -> Result<()> {
        self.advect_stages(phi, [(u, v), (u, v), (u, v)], grid, dt, exec)
    }

    /// Same as [`advect`](Self::advect) with one velocity per Runge–Kutta stage: `vel[0]` at
    /// tⁿ, `vel[1]` at tⁿ + δt, `vel[2]` at tⁿ + δt/2 (the stage times of TVD-RK3). Used when the
    /// velocity is a known function of time (single-vortex test), keeping third order in time.
    pub fn advect_stages(&mut self, phi: &mut Field, vel: [(&Field, &Field); 3], grid: &Grid, dt: f64, exec: Exec) -> Result<()> {
        check_field("phi", phi, grid, Location::Centre)?;
        for (u, v) in vel {
            check_field("u", u, grid, Location::XFace)?;
            check_field("v", v, grid, Location::YFace)?;
        }
        check_field("scratch", &self.phi1, grid, Location::Centre)?;
        if !(dt.is_finite() && dt >= 0.0) {
            return Err(Error::param("dt", dt, "a finite number >= 0"));
        }
        let (phi1, phi2) = (&mut self.phi1, &mut self.phi2);
        let stage = match self.weights {
            WenoWeights::JiangShu => stage::<false>,
            WenoWeights::Mapped => stage::<true>,
        };
        // Φ⁽¹⁾ = Φⁿ + δt L(Φⁿ)
        phi.extrapolate_ghosts_linear();
        stage(phi1, Base::None, 0.0, 1.0, phi, vel[0], grid, dt, exec);
        // Φ⁽²⁾ = ¾ Φⁿ + ¼ (Φ⁽¹⁾ + δt L(Φ⁽¹⁾))
        phi1.extrapolate_ghosts_linear();
        stage(phi2, Base::Other(phi), 0.75, 0.25, phi1, vel[1], grid, dt, exec);
        // Φⁿ⁺¹ = ⅓ Φⁿ + ⅔ (Φ⁽²⁾ + δt L(Φ⁽²⁾)), written in place over Φⁿ
        phi2.extrapolate_ghosts_linear();
        stage(phi, Base::InPlace, 1.0 / 3.0, 2.0 / 3.0, phi2, vel[2], grid, dt, exec);
        Ok(())
    }
}

/// Where the `a·Φ_base` term of a Runge–Kutta stage comes from.
#[derive(Clone, Copy)]
enum Base<'a> {
    /// No base term (a = 0).
    None,
    /// The output field's current value.
    InPlace,
    /// Another field.
    Other(&'a Field),
}

/// out = a·base + b·(src + δt·L(src)) on the interior; `src` must have valid ghosts.
#[allow(clippy::too_many_arguments)]
fn stage<const MAPPED: bool>(out: &mut Field, base: Base, a: f64, b: f64, src: &Field, (u, v): (&Field, &Field), grid: &Grid, dt: f64, exec: Exec) {
    let (nx, ny) = (grid.nx, grid.ny);
    let stride = out.stride();
    let (ustride, vstride) = (u.stride(), v.stride());
    let (inv_dx, inv_dy) = (1.0 / grid.dx, 1.0 / grid.dy);
    let (s, us, vs) = (src.slice(), u.slice(), v.slice());
    let base = match base {
        Base::Other(f) => Some(f.slice()),
        _ => None,
    };
    let in_place = a != 0.0 && base.is_none();
    exec.for_each_row(out.slice_mut(), stride, |r, row| {
        if r < HALO || r >= ny + HALO {
            return;
        }
        let j = r - HALO;
        let urow = (j + HALO) * ustride + HALO;
        let vrow = (j + HALO) * vstride + HALO;
        for i in 0..nx {
            let k = r * stride + i + HALO;
            let uc = 0.5 * (us[urow + i] + us[urow + i + 1]);
            let vc = 0.5 * (vs[vrow + i] + vs[vrow + vstride + i]);
            let mut l = 0.0;
            if uc != 0.0 {
                let w = window(s, k, 1);
                let d = if uc > 0.0 { weno5_minus_with::<MAPPED>(&w) } else { weno5_plus_with::<MAPPED>(&w) };
                l -= uc * d * inv_dx;
            }
            if vc != 0.0 {
                let w = window(s, k, stride);
                let d = if vc > 0.0 { weno5_minus_with::<MAPPED>(&w) } else { weno5_plus_with::<MAPPED>(&w) };
                l -= vc * d * inv_dy;
            }
            let new = b * (s[k] + dt * l);
            let c = i + HALO;
            row[c] = match base {
                Some(bs) => a * bs[k] + new,
                None if in_place => a * row[c] + new,
                None => new,
            };
        }
    });
}

/// max over cells of |u_c|/dx + |v_c|/dy (1/s): δt times this is the transport's Courant number.
pub fn max_transport_rate(u: &Field, v: &Field, grid: &Grid, exec: Exec) -> Result<f64> {
    check_field("u", u, grid, Location::XFace)?;
    check_field("v", v, grid, Location::YFace)?;
    let (inv_dx, inv_dy) = (1.0 / grid.dx, 1.0 / grid.dy);
    let r = exec.max_rows(grid.ny, grid.cells(), |j| {
        let j = j as isize;
        let mut m = 0.0f64;
        for i in 0..grid.nx as isize {
            let uc = 0.5 * (u.at(i, j) + u.at(i + 1, j));
            let vc = 0.5 * (v.at(i, j) + v.at(i, j + 1));
            let rate = uc.abs() * inv_dx + vc.abs() * inv_dy;
            if rate.is_nan() {
                return f64::NAN;
            }
            m = m.max(rate);
        }
        m
    });
    if r.is_nan() {
        return Err(Error::param("u, v", "NaN", "finite velocities"));
    }
    Ok(r.max(0.0))
}

/// The largest δt with δt · max(|u_c|/dx + |v_c|/dy) ≤ `cfl` (infinite for a fluid at rest).
pub fn stable_dt(u: &Field, v: &Field, grid: &Grid, cfl: f64, exec: Exec) -> Result<f64> {
    if !(cfl.is_finite() && cfl > 0.0 && cfl <= 1.4) {
        return Err(Error::param("cfl", cfl, "a number in (0, 1.4] (WENO5 + TVD-RK3 linear stability)"));
    }
    let rate = max_transport_rate(u, v, grid, exec)?;
    Ok(if rate > 0.0 { cfl / rate } else { f64::INFINITY })
}

/// The transport Courant number δt · max(|u_c|/dx + |v_c|/dy) of a step δt.
pub fn cfl_number(u: &Field, v: &Field, grid: &Grid, dt: f64, exec: Exec) -> Result<f64> {
    Ok(dt * max_transport_rate(u, v, grid, exec)?)
}
