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

use super::weno5::{weno5_with, WenoWeights};
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
///
/// Each row reads the rows of `src`, u and v it needs as slices (no bounds checks in the inner
/// loop); the upwind choice of the WENO5 stencil is a select of the five differences by the
/// sign of the velocity, so that the loop has no branch and vectorises ([`upwind`]); on x86-64
/// with AVX2 the row is compiled for 256-bit vectors and chosen at run time (no FMA: the
/// results do not depend on the path).
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
        let k = r * stride + HALO;
        let urow = r * ustride + HALO;
        let vrow = r * vstride + HALO;
        let rows = StageRow {
            x: &s[k - 3..k + nx + 3],
            y: std::array::from_fn(|m| &s[k + m * stride - 3 * stride..k + m * stride - 3 * stride + nx]),
            u: &us[urow..urow + nx + 1],
            v0: &vs[vrow..vrow + nx],
            v1: &vs[vrow + vstride..vrow + vstride + nx],
            coef: StageCoef { a, b, dt, inv_dx, inv_dy },
        };
        let out = &mut row[HALO..HALO + nx];
        let base = match base {
            Some(bs) => RowBase::Other(&bs[k..k + nx]),
            None if in_place => RowBase::InPlace,
            None => RowBase::None,
        };
        if MAPPED {
            stage_row_mapped(&rows, base, out);
        } else {
            stage_row_js(&rows, base, out);
        }
    });
}

/// The rows read by one row of a Runge–Kutta stage (nx cells): `x[i + 3 + m]` = Φ_{i+m,j}
/// (m = −3..=3), `y[m + 3][i]` = Φ_{i,j+m}, `u[i]`, `u[i + 1]` the x-faces of cell i, `v0[i]`,
/// `v1[i]` its y-faces.
struct StageRow<'a> {
    x: &'a [f64],
    y: [&'a [f64]; 7],
    u: &'a [f64],
    v0: &'a [f64],
    v1: &'a [f64],
    coef: StageCoef,
}

/// The stage's scalars: out = a·base + b·(Φ + δt L(Φ)), L with the inverse spacings.
#[derive(Clone, Copy)]
struct StageCoef {
    a: f64,
    b: f64,
    dt: f64,
    inv_dx: f64,
    inv_dy: f64,
}

/// The `a·Φ_base` term of one row of a stage.
#[derive(Clone, Copy)]
enum RowBase<'a> {
    /// No base term (a = 0).
    None,
    /// The output row's current value.
    InPlace,
    /// The row of another field.
    Other(&'a [f64]),
}

/// h·(Φ_x)^upwind of the seven values `w` = Φ_{i−3..=i+3} for the velocity `a`: the five
/// undivided differences of the upwind stencil are selected by the sign of `a`
/// ((Φ_x)⁻ where a > 0, (Φ_x)⁺ otherwise: [`weno5_minus_with`](super::weno5::weno5_minus_with),
/// [`weno5_plus_with`](super::weno5::weno5_plus_with)) and
/// combined once. The caller discards the value where a = 0.
#[inline(always)]
fn upwind<const MAPPED: bool>(w: &[f64; 7], a: f64) -> f64 {
    let d: [f64; 6] = std::array::from_fn(|m| w[m + 1] - w[m]);
    let minus = a > 0.0;
    let pick = |m: usize, p: usize| if minus { d[m] } else { d[p] };
    weno5_with::<MAPPED>(pick(0, 5), pick(1, 4), pick(2, 3), pick(3, 2), pick(4, 1))
}

/// One row of a stage, the body of both copies of [`stage_row_js`] and [`stage_row_mapped`].
/// Where both velocities of a cell are zero its value is b·(Φ + δt·0) (see [`stage_cells`]):
/// the cells outside the span of the row's moving cells take it without the two WENO5
/// reconstructions, with the same bits (a granular-only window's light phase is at rest beyond
/// the velocity extension); the span goes through [`stage_cells`].
#[inline(always)]
fn stage_row_body<const MAPPED: bool>(r: &StageRow<'_>, base: RowBase<'_>, out: &mut [f64]) {
    let n = out.len();
    let (u, v0, v1) = (&r.u[..n + 1], &r.v0[..n], &r.v1[..n]);
    let moving = |i: usize| 0.5 * (u[i] + u[i + 1]) != 0.0 || 0.5 * (v0[i] + v1[i]) != 0.0;
    let lo = (0..n).find(|&i| moving(i)).unwrap_or(n);
    let hi = (lo..n).rev().find(|&i| moving(i)).map_or(lo, |i| i + 1);
    let StageCoef { a, b, dt, .. } = r.coef;
    let x = &r.x[..n + 6];
    for i in (0..lo).chain(hi..n) {
        let new = b * (x[i + 3] + dt * 0.0);
        out[i] = match base {
            RowBase::None => new,
            RowBase::InPlace => a * out[i] + new,
            RowBase::Other(bs) => a * bs[i] + new,
        };
    }
    if lo < hi {
        let span = StageRow {
            x: &r.x[lo..hi + 6],
            y: std::array::from_fn(|m| &r.y[m][lo..hi]),
            u: &r.u[lo..hi + 1],
            v0: &r.v0[lo..hi],
            v1: &r.v1[lo..hi],
            coef: r.coef,
        };
        let base = match base {
            RowBase::Other(bs) => RowBase::Other(&bs[lo..hi]),
            other => other,
        };
        stage_cells::<MAPPED>(&span, base, &mut out[lo..hi]);
    }
}

/// `out` = a·base + b·(Φ + δt L(Φ)) over the cells of `r`, L = −(u_c Φ_x + v_c Φ_y).
#[inline(always)]
fn stage_cells<const MAPPED: bool>(r: &StageRow<'_>, base: RowBase<'_>, out: &mut [f64]) {
    let n = out.len();
    let (x, u, v0, v1) = (&r.x[..n + 6], &r.u[..n + 1], &r.v0[..n], &r.v1[..n]);
    let y: [&[f64]; 7] = std::array::from_fn(|m| &r.y[m][..n]);
    let StageCoef { a, b, dt, inv_dx, inv_dy } = r.coef;
    // b·(Φ + δt L(Φ)) at cell i, L = −(u_c Φ_x + v_c Φ_y); a term whose velocity is zero is
    // skipped (a macro, not a closure: inlined in both copies of the kernel)
    macro_rules! new {
        ($i:expr) => {{
            let i = $i;
            let uc = 0.5 * (u[i] + u[i + 1]);
            let vc = 0.5 * (v0[i] + v1[i]);
            let wx = [x[i], x[i + 1], x[i + 2], x[i + 3], x[i + 4], x[i + 5], x[i + 6]];
            let wy = [y[0][i], y[1][i], y[2][i], y[3][i], y[4][i], y[5][i], y[6][i]];
            let lx = 0.0 - uc * upwind::<MAPPED>(&wx, uc) * inv_dx;
            let l = if uc != 0.0 { lx } else { 0.0 };
            let ly = l - vc * upwind::<MAPPED>(&wy, vc) * inv_dy;
            let l = if vc != 0.0 { ly } else { l };
            b * (x[i + 3] + dt * l)
        }};
    }
    match base {
        RowBase::None => {
            for (i, o) in out.iter_mut().enumerate() {
                *o = new!(i);
            }
        }
        RowBase::InPlace => {
            for (i, o) in out.iter_mut().enumerate() {
                *o = a * *o + new!(i);
            }
        }
        RowBase::Other(bs) => {
            let bs = &bs[..n];
            for (i, o) in out.iter_mut().enumerate() {
                *o = a * bs[i] + new!(i);
            }
        }
    }
}

crate::multiversion! {
    /// One row of a stage with Jiang–Shu weights.
    fn stage_row_js / stage_row_js_base(r: &StageRow<'_>, base: RowBase<'_>, out: &mut [f64]) {
        stage_row_body::<false>(r, base, out)
    }
}

crate::multiversion! {
    /// One row of a stage with Henrick's mapped weights.
    fn stage_row_mapped / stage_row_mapped_base(r: &StageRow<'_>, base: RowBase<'_>, out: &mut [f64]) {
        stage_row_body::<true>(r, base, out)
    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::levelset::weno5::{weno5_minus_with, weno5_plus_with, window};

    /// A stage as a branching sweep over seven-value windows: the formulas of [`stage`], one cell
    /// at a time.
    #[allow(clippy::too_many_arguments)]
    fn stage_reference<const MAPPED: bool>(out: &mut Field, base: Option<&Field>, a: f64, b: f64, src: &Field, (u, v): (&Field, &Field), grid: &Grid, dt: f64) {
        let (nx, ny) = (grid.nx, grid.ny);
        let stride = out.stride();
        let (ustride, vstride) = (u.stride(), v.stride());
        let (inv_dx, inv_dy) = (1.0 / grid.dx, 1.0 / grid.dy);
        let (s, us, vs) = (src.slice(), u.slice(), v.slice());
        let bs = base.map(|f| f.slice().to_vec());
        let o = out.slice_mut();
        for j in 0..ny {
            let r = j + HALO;
            let (urow, vrow) = (r * ustride + HALO, r * vstride + HALO);
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
                o[k] = match &bs {
                    Some(bs) => a * bs[k] + new,
                    None if a != 0.0 => a * o[k] + new,
                    None => new,
                };
            }
        }
    }

    fn random(grid: &Grid, loc: Location, seed: u64, zero_every: usize) -> Field {
        let mut f = Field::zeros(grid, loc);
        let mut s = seed;
        for (k, x) in f.slice_mut().iter_mut().enumerate() {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            *x = if zero_every > 0 && k % zero_every == 0 { 0.0 } else { ((s >> 11) as f64 / (1u64 << 53) as f64) - 0.4 };
        }
        f
    }

    fn bits(f: &Field) -> Vec<u64> {
        f.slice().iter().map(|x| x.to_bits()).collect()
    }

    /// The TVD-RK3 step of [`LevelSetTransport::advect`] (row slices, selected stencils, AVX2
    /// where the CPU has it, the cells at rest beyond a row's moving span without WENO5) gives
    /// the bits of the branching reference sweep, for both weights, serially and on two threads,
    /// with velocities of both signs and exact zeros (cell-centre velocities u_c = 0 where the
    /// two faces cancel, and where both are zero), and with a fluid at rest over whole rows and
    /// at both ends of others.
    #[test]
    fn advect_is_the_branching_sweep_bit_for_bit() {
        let grid = Grid::new(53, 37, 1.3, 0.8).unwrap();
        let (u, mut v) = (random(&grid, Location::XFace, 12, 7), random(&grid, Location::YFace, 13, 5));
        // faces of opposite values: v_c = 0 exactly with nonzero faces
        for j in 0..4 {
            let (a, b) = (v.idx(9, j), v.idx(9, j + 1));
            let val = v.slice()[a];
            v.slice_mut()[b] = -val;
        }
        // the same flow at rest from row 25 up and over the first 10 and the last 8 cells of rows
        // 5-15 (both faces of each such cell zero)
        let (mut u_rest, mut v_rest) = (u.clone(), v.clone());
        for j in 0..grid.ny {
            for i in 0..grid.nx {
                if j >= 25 || ((5..=15).contains(&j) && (i < 10 || i >= grid.nx - 8)) {
                    u_rest.set(i, j, 0.0);
                    u_rest.set(i + 1, j, 0.0);
                    v_rest.set(i, j, 0.0);
                    v_rest.set(i, j + 1, 0.0);
                }
            }
        }
        // cells that move along one direction only: u_c = 0 at the start of row 20, v_c = 0 at
        // the start of row 22
        for i in 0..=5 {
            u_rest.set(i, 20, 0.0);
            v_rest.set(i, 22, 0.0);
            v_rest.set(i, 23, 0.0);
        }
        for (k, (u, v)) in [(&u, &v), (&u_rest, &v_rest)].into_iter().enumerate() {
            advect_matches_the_reference(&grid, u, v, 11 + k as u64);
        }
    }

    fn advect_matches_the_reference(grid: &Grid, u: &Field, v: &Field, seed: u64) {
        let grid = grid.clone();
        let phi0 = random(&grid, Location::Centre, seed, 0);
        let dt = 0.3 * stable_dt(u, v, &grid, 0.5, Exec::SERIAL).unwrap();
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        for weights in [WenoWeights::JiangShu, WenoWeights::Mapped] {
            let mut want = phi0.clone();
            let (mut p1, mut p2) = (Field::zeros(&grid, Location::Centre), Field::zeros(&grid, Location::Centre));
            let reference = match weights {
                WenoWeights::JiangShu => stage_reference::<false>,
                WenoWeights::Mapped => stage_reference::<true>,
            };
            want.extrapolate_ghosts_linear();
            reference(&mut p1, None, 0.0, 1.0, &want, (u, v), &grid, dt);
            p1.extrapolate_ghosts_linear();
            reference(&mut p2, Some(&want), 0.75, 0.25, &p1, (u, v), &grid, dt);
            p2.extrapolate_ghosts_linear();
            reference(&mut want, None, 1.0 / 3.0, 2.0 / 3.0, &p2, (u, v), &grid, dt);
            assert_ne!(bits(&want), bits(&phi0));
            for exec in [Exec::SERIAL, Exec::with_threads(2)] {
                let mut tr = LevelSetTransport::with_weights(&grid, weights);
                let mut phi = phi0.clone();
                pool.install(|| tr.advect(&mut phi, u, v, &grid, dt, exec)).unwrap();
                assert_eq!(bits(&phi), bits(&want), "{weights:?}, {exec:?}");
            }
        }
    }

    /// A copy of a stage's row kernel.
    type RowKernel = fn(&StageRow<'_>, RowBase<'_>, &mut [f64]);

    /// The AVX2 and the baseline copies of a stage's row agree bit for bit, for both weights and
    /// the three kinds of base term.
    #[test]
    fn stage_row_copies_agree_bit_for_bit() {
        let grid = Grid::new(61, 12, 1.0, 0.3).unwrap();
        let (s, base) = (random(&grid, Location::Centre, 21, 0), random(&grid, Location::Centre, 22, 0));
        let (u, v) = (random(&grid, Location::XFace, 23, 6), random(&grid, Location::YFace, 24, 4));
        let (nx, stride) = (grid.nx, s.stride());
        let r = 5 + HALO;
        let k = r * stride + HALO;
        let (urow, vrow) = (r * u.stride() + HALO, r * v.stride() + HALO);
        let (ss, us, vs, bs) = (s.slice(), u.slice(), v.slice(), base.slice());
        let rows = StageRow {
            x: &ss[k - 3..k + nx + 3],
            y: std::array::from_fn(|m| &ss[k + m * stride - 3 * stride..k + m * stride - 3 * stride + nx]),
            u: &us[urow..urow + nx + 1],
            v0: &vs[vrow..vrow + nx],
            v1: &vs[vrow + v.stride()..vrow + v.stride() + nx],
            coef: StageCoef { a: 0.75, b: 0.25, dt: 0.01, inv_dx: 1.0 / grid.dx, inv_dy: 1.0 / grid.dy },
        };
        for mode in [RowBase::None, RowBase::InPlace, RowBase::Other(&bs[k..k + nx])] {
            let kernels: [(RowKernel, RowKernel); 2] = [(stage_row_js, stage_row_js_base), (stage_row_mapped, stage_row_mapped_base)];
            for (dispatched, baseline) in kernels {
                let (mut a, mut b) = (bs[k..k + nx].to_vec(), bs[k..k + nx].to_vec());
                dispatched(&rows, mode, &mut a);
                baseline(&rows, mode, &mut b);
                assert_eq!(a.iter().map(|x| x.to_bits()).collect::<Vec<_>>(), b.iter().map(|x| x.to_bits()).collect::<Vec<_>>());
            }
        }
    }
}
