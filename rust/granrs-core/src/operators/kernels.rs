//! Row-parallel stencil kernels on MAC fields (second-order centred finite volumes).

use super::for_each_interior_row;
use crate::exec::Exec;
use crate::grid::{Field, Grid, Location, HALO};

#[inline]
fn base(f: &Field, j: isize) -> usize {
    ((j + HALO as isize) as usize) * f.stride() + HALO
}

/// out (Centre) = div u = (u_{i+1,j} − u_{ij})/dx + (v_{i,j+1} − v_{ij})/dy.
pub fn divergence(u: &Field, v: &Field, grid: &Grid, out: &mut Field, exec: Exec) {
    debug_assert_eq!(out.loc, Location::Centre);
    let (us, vs) = (u.slice(), v.slice());
    let (idx, idy, nx) = (1.0 / grid.dx, 1.0 / grid.dy, grid.nx);
    for_each_interior_row(exec, out, |j, row| {
        let j = j as isize;
        let (bu, bv0, bv1) = (base(u, j), base(v, j), base(v, j + 1));
        for i in 0..nx {
            row[HALO + i] = (us[bu + i + 1] - us[bu + i]) * idx + (vs[bv1 + i] - vs[bv0 + i]) * idy;
        }
    });
}

/// max |div u| over the cells.
pub fn divergence_max_abs(u: &Field, v: &Field, grid: &Grid, exec: Exec) -> f64 {
    let (us, vs) = (u.slice(), v.slice());
    let (idx, idy, nx) = (1.0 / grid.dx, 1.0 / grid.dy, grid.nx);
    exec.max_rows(grid.ny, grid.cells(), |j| {
        let j = j as isize;
        let (bu, bv0, bv1) = (base(u, j), base(v, j), base(v, j + 1));
        let mut m = 0.0f64;
        for i in 0..nx {
            let d = (us[bu + i + 1] - us[bu + i]) * idx + (vs[bv1 + i] - vs[bv0 + i]) * idy;
            m = if d.is_nan() { f64::NAN } else { m.max(d.abs()) };
        }
        m
    })
}

/// Gradient of a cell-centred scalar onto all faces, boundary faces included (the ghost values
/// of `p` must be filled): gx_{ij} = (p_{ij} − p_{i−1,j})/dx on XFace, gy_{ij} = (p_{ij} − p_{i,j−1})/dy
/// on YFace.
pub fn gradient(p: &Field, grid: &Grid, gx: &mut Field, gy: &mut Field, exec: Exec) {
    let ps = p.slice();
    let (idx, idy, nx) = (1.0 / grid.dx, 1.0 / grid.dy, grid.nx);
    for_each_interior_row(exec, gx, |j, row| {
        let b = base(p, j as isize);
        for i in 0..=nx {
            row[HALO + i] = (ps[b + i] - ps[b + i - 1]) * idx;
        }
    });
    for_each_interior_row(exec, gy, |j, row| {
        let (b0, b1) = (base(p, j as isize - 1), base(p, j as isize));
        for i in 0..nx {
            row[HALO + i] = (ps[b1 + i] - ps[b0 + i]) * idy;
        }
    });
}

/// Strain rate D(u) = ½(∇u + ∇uᵀ): D_xx = ∂u/∂x and D_yy = ∂v/∂y at centres, D_xy = ½(∂u/∂y + ∂v/∂x)
/// at nodes (all (nx+1) × (ny+1) of them; velocity ghosts must be filled).
pub fn strain_rate(u: &Field, v: &Field, grid: &Grid, dxx: &mut Field, dyy: &mut Field, dxy: &mut Field, exec: Exec) {
    let (us, vs) = (u.slice(), v.slice());
    let (idx, idy, nx) = (1.0 / grid.dx, 1.0 / grid.dy, grid.nx);
    for_each_interior_row(exec, dxx, |j, row| {
        let bu = base(u, j as isize);
        for i in 0..nx {
            row[HALO + i] = (us[bu + i + 1] - us[bu + i]) * idx;
        }
    });
    for_each_interior_row(exec, dyy, |j, row| {
        let (b0, b1) = (base(v, j as isize), base(v, j as isize + 1));
        for i in 0..nx {
            row[HALO + i] = (vs[b1 + i] - vs[b0 + i]) * idy;
        }
    });
    for_each_interior_row(exec, dxy, |j, row| {
        let j = j as isize;
        let (bu0, bu1, bv) = (base(u, j - 1), base(u, j), base(v, j));
        for i in 0..=nx {
            row[HALO + i] = 0.5 * ((us[bu1 + i] - us[bu0 + i]) * idy + (vs[bv + i] - vs[bv + i - 1]) * idx);
        }
    });
}

/// |D| = √(½ Σ D_ij²) = √(½(D_xx² + D_yy²) + D_xy²) at cell centres, with D_xy averaged from the
/// four corner nodes (the paper's tensor norm).
pub fn strain_rate_norm_centre(dxx: &Field, dyy: &Field, dxy: &Field, out: &mut Field, exec: Exec) {
    let (a, b, c) = (dxx.slice(), dyy.slice(), dxy.slice());
    let nx = out.nx;
    for_each_interior_row(exec, out, |j, row| {
        let j = j as isize;
        let (bc, bn0, bn1) = (base(dxx, j), base(dxy, j), base(dxy, j + 1));
        for i in 0..nx {
            let xy = 0.25 * (c[bn0 + i] + c[bn0 + i + 1] + c[bn1 + i] + c[bn1 + i + 1]);
            row[HALO + i] = (0.5 * (a[bc + i] * a[bc + i] + b[bc + i] * b[bc + i]) + xy * xy).sqrt();
        }
    });
}

/// Viscous force div(2η D(u)) on every face (boundary faces included; the caller keeps the
/// unknown ones). η_c at centres (ghosts filled), η_n at nodes; velocity ghosts filled.
///
/// u-face (i, j): [2η_c D_xx]_{i−1}^{i} / dx + [2η_n D_xy]_{j}^{j+1} / dy;
/// v-face (i, j): [2η_n D_xy]_{i}^{i+1} / dx + [2η_c D_yy]_{j−1}^{j} / dy.
#[allow(clippy::too_many_arguments)]
pub fn viscous(u: &Field, v: &Field, eta_c: &Field, eta_n: &Field, grid: &Grid, out_u: &mut Field, out_v: &mut Field, exec: Exec) {
    viscous_rows(u, v, eta_c, eta_n, grid, out_u, out_v, None, None, exec);
}

/// The implicit viscous operator c ⊙ u − div(2η D(u)) on every face, in one pass: out_u =
/// c_u u − [`viscous`]_u and out_v = c_v v − [`viscous`]_v, bit for bit (the same operations in
/// the same order as the two sweeps). `c_u`, `c_v` have the shapes of u and v.
#[allow(clippy::too_many_arguments)]
pub fn viscous_helmholtz(
    u: &Field,
    v: &Field,
    eta_c: &Field,
    eta_n: &Field,
    c_u: &Field,
    c_v: &Field,
    grid: &Grid,
    out_u: &mut Field,
    out_v: &mut Field,
    exec: Exec,
) {
    viscous_rows(u, v, eta_c, eta_n, grid, out_u, out_v, Some((c_u, c_v)), None, exec);
}

/// Per-row dot products of the input with the output of [`viscous_helmholtz_dots`]: for each
/// interior row j, `rows_u[j]` = Σ_{i ∈ cols_u} u_{ij} out_u_{ij} summed left to right from 0
/// (the order of a row of `Iterator::fold`), and likewise for v.
pub struct RowDots<'a> {
    /// Columns (interior face indices) of the u-faces summed.
    pub cols_u: std::ops::Range<usize>,
    /// Columns of the v-faces summed.
    pub cols_v: std::ops::Range<usize>,
    /// One sum per interior row of u-faces (length ny).
    pub rows_u: &'a mut [f64],
    /// One sum per interior row of v-faces (length ny + 1).
    pub rows_v: &'a mut [f64],
}

/// [`viscous_helmholtz`] and, in the same sweep, the per-row sums of u·out_u and v·out_v of
/// `dots` (each row summed while it is in cache): out_u, out_v are those of
/// [`viscous_helmholtz`] bit for bit, and the row sums those of a separate pass.
#[allow(clippy::too_many_arguments)]
pub fn viscous_helmholtz_dots(
    u: &Field,
    v: &Field,
    eta_c: &Field,
    eta_n: &Field,
    c_u: &Field,
    c_v: &Field,
    grid: &Grid,
    out_u: &mut Field,
    out_v: &mut Field,
    dots: RowDots<'_>,
    exec: Exec,
) {
    viscous_rows(u, v, eta_c, eta_n, grid, out_u, out_v, Some((c_u, c_v)), Some(dots), exec);
}

/// Runs `f(j, row)` over the interior rows of `field` like [`for_each_interior_row`]; with
/// `dots = Some((sums, input, cols))` it then stores in `sums[j]` the dot product of the row's
/// columns `cols` (interior indices) with the same columns of `input`'s row j (a field of the
/// same layout), each summed left to right from 0 ([`super::row_sums`]): the rows of a task of
/// at most [`ROW_BLOCK`](crate::exec::ROW_BLOCK) rows are computed first, then their dots
/// ([`super::sums_by_row`]; each row's dot has the same bits whatever the task).
fn interior_rows_dots<F>(exec: Exec, field: &mut Field, dots: Option<(&mut [f64], &Field, std::ops::Range<usize>)>, f: F)
where
    F: Fn(usize, &mut [f64]) + Sync + Send,
{
    use crate::exec::{balanced_task_rows, ROW_BLOCK};
    use rayon::prelude::*;
    let Some((sums, input, cols)) = dots else {
        for_each_interior_row(exec, field, f);
        return;
    };
    let (stride, ny) = (field.stride(), field.ny);
    assert!(input.stride() == stride && input.ny == ny, "the dot's input has the layout of the field");
    let sums = &mut sums[..ny];
    let inp = input.slice();
    let data = &mut field.slice_mut()[HALO * stride..(HALO + ny) * stride];
    let (c0, n) = (HALO + cols.start, cols.len());
    let block = |j0: usize, rows: &mut [f64], out: &mut [f64]| {
        for (r, row) in rows.chunks_mut(stride).enumerate() {
            f(j0 + r, row);
        }
        let rows = &*rows;
        let a_row = |k: usize| &inp[(j0 + k + HALO) * stride + c0..][..n];
        let b_row = |k: usize| &rows[k * stride + c0..][..n];
        let mut sums = [[0.0; 1]; ROW_BLOCK];
        let sums = &mut sums[..out.len()];
        super::sums_by_row(sums, n, |k| [a_row(k), b_row(k)], |[a, b]| [a * b]);
        for (o, s) in out.iter_mut().zip(sums.iter()) {
            *o = s[0];
        }
    };
    if exec.use_parallel(data.len()) {
        let rows = balanced_task_rows(data.len() / stride.max(1), stride);
        data.par_chunks_mut(stride * rows).zip(sums.par_chunks_mut(rows)).enumerate().for_each(|(t, (r, out))| block(t * rows, r, out));
    } else {
        for (b, (rows, out)) in data.chunks_mut(stride * ROW_BLOCK).zip(sums.chunks_mut(ROW_BLOCK)).enumerate() {
            block(b * ROW_BLOCK, rows, out);
        }
    }
}

/// Rows of [`viscous`] (`shift` None) or [`viscous_helmholtz`] (`shift` the face coefficients c).
/// Each row works on slices of the rows it reads, so that the inner loops carry no bounds checks
/// and vectorise; on x86-64 with AVX2 the same code is compiled for 256-bit vectors and chosen at
/// run time (no FMA: the results do not depend on the path).
#[allow(clippy::too_many_arguments)]
fn viscous_rows(
    u: &Field,
    v: &Field,
    eta_c: &Field,
    eta_n: &Field,
    grid: &Grid,
    out_u: &mut Field,
    out_v: &mut Field,
    shift: Option<(&Field, &Field)>,
    dots: Option<RowDots<'_>>,
    exec: Exec,
) {
    let (cols_u, cols_v, rows_u, rows_v) = match dots {
        Some(d) => (Some(d.cols_u), Some(d.cols_v), Some(d.rows_u), Some(d.rows_v)),
        None => (None, None, None, None),
    };
    let (us, vs, ec, en) = (u.slice(), v.slice(), eta_c.slice(), eta_n.slice());
    let (idx, idy, nx) = (1.0 / grid.dx, 1.0 / grid.dy, grid.nx);
    let cu = shift.map(|(c, _)| (c.slice(), c.stride()));
    interior_rows_dots(exec, out_u, rows_u.map(|r| (r, u, cols_u.clone().unwrap())), |j, row| {
        let ji = j as isize;
        let (bu, bum, bup) = (base(u, ji), base(u, ji - 1), base(u, ji + 1));
        let (bv0, bv1) = (base(v, ji), base(v, ji + 1));
        let bc = base(eta_c, ji);
        let (bn0, bn1) = (base(eta_n, ji), base(eta_n, ji + 1));
        let n = nx + 1;
        let r = UxRow {
            uc: &us[bu - 1..bu + n + 1],
            un: &us[bup..bup + n],
            us: &us[bum..bum + n],
            v1: &vs[bv1 - 1..bv1 + n],
            v0: &vs[bv0 - 1..bv0 + n],
            e: &ec[bc - 1..bc + n],
            n1: &en[bn1..bn1 + n],
            n0: &en[bn0..bn0 + n],
            idx,
            idy,
        };
        let out = &mut row[HALO..HALO + n];
        let c = cu.map(|(cs, st)| &cs[(j + HALO) * st + HALO..(j + HALO) * st + HALO + n]);
        ux_row(&r, out, c);
    });
    let cv = shift.map(|(_, c)| (c.slice(), c.stride()));
    interior_rows_dots(exec, out_v, rows_v.map(|r| (r, v, cols_v.clone().unwrap())), |j, row| {
        let ji = j as isize;
        let (bv, bvm, bvp) = (base(v, ji), base(v, ji - 1), base(v, ji + 1));
        let (bu0, bum) = (base(u, ji), base(u, ji - 1));
        let (bc0, bcm) = (base(eta_c, ji), base(eta_c, ji - 1));
        let bn = base(eta_n, ji);
        let n = nx;
        let r = VyRow {
            vc: &vs[bv - 1..bv + n + 1],
            vp: &vs[bvp..bvp + n],
            vm: &vs[bvm..bvm + n],
            u0: &us[bu0..bu0 + n + 1],
            um: &us[bum..bum + n + 1],
            e0: &ec[bc0..bc0 + n],
            em: &ec[bcm..bcm + n],
            nn: &en[bn..bn + n + 1],
            idx,
            idy,
        };
        let out = &mut row[HALO..HALO + n];
        let c = cv.map(|(cs, st)| &cs[(j + HALO) * st + HALO..(j + HALO) * st + HALO + n]);
        vy_row(&r, out, c);
    });
}

/// The rows read by one row of u-faces of [`viscous`] (n = nx + 1 faces): `uc[i + 1]` = u_{i,j}
/// (i = −1..=n), `un`, `us` the rows j ± 1, `v1[i + 1]`, `v0[i + 1]` = v_{i,j+1}, v_{i,j}
/// (i = −1..n), `e[i + 1]` = η_c (i = −1..n), `n1`, `n0` η_n on the nodes above and below.
struct UxRow<'a> {
    uc: &'a [f64],
    un: &'a [f64],
    us: &'a [f64],
    v1: &'a [f64],
    v0: &'a [f64],
    e: &'a [f64],
    n1: &'a [f64],
    n0: &'a [f64],
    idx: f64,
    idy: f64,
}

crate::multiversion! {
    /// One row of u-faces of [`viscous`] (`c` None) or [`viscous_helmholtz`] (`c` the row of c_u).
    fn ux_row / ux_row_base(r: &UxRow<'_>, out: &mut [f64], c: Option<&[f64]>) {
        let n = out.len();
        let (uc, un, us, v1, v0, e, n1, n0) = (&r.uc[..n + 2], &r.un[..n], &r.us[..n], &r.v1[..n + 1], &r.v0[..n + 1], &r.e[..n + 1], &r.n1[..n], &r.n0[..n]);
        let (idx, idy) = (r.idx, r.idy);
        // the face's value (a macro, not a closure: inlined in both copies of the kernel)
        macro_rules! value {
            ($i:expr) => {{
                let i = $i;
                let txx_r = 2.0 * e[i + 1] * (uc[i + 2] - uc[i + 1]) * idx;
                let txx_l = 2.0 * e[i] * (uc[i + 1] - uc[i]) * idx;
                let txy_t = n1[i] * ((un[i] - uc[i + 1]) * idy + (v1[i + 1] - v1[i]) * idx);
                let txy_b = n0[i] * ((uc[i + 1] - us[i]) * idy + (v0[i + 1] - v0[i]) * idx);
                (txx_r - txx_l) * idx + (txy_t - txy_b) * idy
            }};
        }
        match c {
            None => {
                for (i, o) in out.iter_mut().enumerate() {
                    *o = value!(i);
                }
            }
            Some(c) => {
                let c = &c[..n];
                for (i, o) in out.iter_mut().enumerate() {
                    *o = c[i] * uc[i + 1] - value!(i);
                }
            }
        }
    }
}

/// The rows read by one row of v-faces of [`viscous`] (n = nx faces): `vc[i + 1]` = v_{i,j}
/// (i = −1..=n), `vp`, `vm` the rows j ± 1, `u0`, `um` u_{i,j}, u_{i,j−1} (i = 0..=n), `e0`, `em`
/// η_c of the cells above and below, `nn` η_n on the nodes of row j (i = 0..=n).
struct VyRow<'a> {
    vc: &'a [f64],
    vp: &'a [f64],
    vm: &'a [f64],
    u0: &'a [f64],
    um: &'a [f64],
    e0: &'a [f64],
    em: &'a [f64],
    nn: &'a [f64],
    idx: f64,
    idy: f64,
}

crate::multiversion! {
    /// One row of v-faces of [`viscous`] (`c` None) or [`viscous_helmholtz`] (`c` the row of c_v).
    fn vy_row / vy_row_base(r: &VyRow<'_>, out: &mut [f64], c: Option<&[f64]>) {
        let n = out.len();
        let (vc, vp, vm, u0, um, e0, em, nn) = (&r.vc[..n + 2], &r.vp[..n], &r.vm[..n], &r.u0[..n + 1], &r.um[..n + 1], &r.e0[..n], &r.em[..n], &r.nn[..n + 1]);
        let (idx, idy) = (r.idx, r.idy);
        // the face's value (a macro, not a closure: inlined in both copies of the kernel)
        macro_rules! value {
            ($i:expr) => {{
                let i = $i;
                let tyy_t = 2.0 * e0[i] * (vp[i] - vc[i + 1]) * idy;
                let tyy_b = 2.0 * em[i] * (vc[i + 1] - vm[i]) * idy;
                let txy_r = nn[i + 1] * ((u0[i + 1] - um[i + 1]) * idy + (vc[i + 2] - vc[i + 1]) * idx);
                let txy_l = nn[i] * ((u0[i] - um[i]) * idy + (vc[i + 1] - vc[i]) * idx);
                (txy_r - txy_l) * idx + (tyy_t - tyy_b) * idy
            }};
        }
        match c {
            None => {
                for (i, o) in out.iter_mut().enumerate() {
                    *o = value!(i);
                }
            }
            Some(c) => {
                let c = &c[..n];
                for (i, o) in out.iter_mut().enumerate() {
                    *o = c[i] * vc[i + 1] - value!(i);
                }
            }
        }
    }
}

/// Convective acceleration (u·∇)u on every face, centred second order, advective form. The
/// transverse velocity is the average of the four nearest values (velocity ghosts filled).
pub fn convection(u: &Field, v: &Field, grid: &Grid, out_u: &mut Field, out_v: &mut Field, exec: Exec) {
    let (us, vs) = (u.slice(), v.slice());
    let (h2x, h2y, nx) = (0.5 / grid.dx, 0.5 / grid.dy, grid.nx);
    for_each_interior_row(exec, out_u, |j, row| {
        let j = j as isize;
        let (bu, bum, bup) = (base(u, j), base(u, j - 1), base(u, j + 1));
        let (bv0, bv1) = (base(v, j), base(v, j + 1));
        for i in 0..=nx {
            let uu = us[bu + i];
            let vv = 0.25 * (vs[bv0 + i - 1] + vs[bv0 + i] + vs[bv1 + i - 1] + vs[bv1 + i]);
            row[HALO + i] = uu * (us[bu + i + 1] - us[bu + i - 1]) * h2x + vv * (us[bup + i] - us[bum + i]) * h2y;
        }
    });
    for_each_interior_row(exec, out_v, |j, row| {
        let j = j as isize;
        let (bv, bvm, bvp) = (base(v, j), base(v, j - 1), base(v, j + 1));
        let (bu0, bum) = (base(u, j), base(u, j - 1));
        for i in 0..nx {
            let vv = vs[bv + i];
            let uu = 0.25 * (us[bum + i] + us[bum + i + 1] + us[bu0 + i] + us[bu0 + i + 1]);
            row[HALO + i] = uu * (vs[bv + i + 1] - vs[bv + i - 1]) * h2x + vv * (vs[bvp + i] - vs[bvm + i]) * h2y;
        }
    });
}

/// Convective acceleration (u·∇)u on every face, advective form, each derivative by the upwind
/// WENO5 reconstruction of Jiang & Shu (1996) (the level set's scheme, `operators::weno5`),
/// upwinded by the sign of the advecting component; the transverse velocity is the average of
/// the four nearest values. Dissipative where the velocity is under-resolved (the shear layer of
/// the light phase over a flowing dense phase), where the centred form of [`convection`] feeds
/// grid-scale oscillations: with BDF2 and an extrapolated explicit term the centred scheme's
/// purely imaginary eigenvalues lie outside the stability region (SBDF2 has no imaginary-axis
/// interval), and at a cell Reynolds number of ~10³ (air) viscosity does not damp them.
/// Needs three valid ghost layers of u and v.
pub fn convection_weno5(u: &Field, v: &Field, grid: &Grid, out_u: &mut Field, out_v: &mut Field, exec: Exec) {
    let (us, vs) = (u.slice(), v.slice());
    let (sx, sy) = (1.0 / grid.dx, 1.0 / grid.dy);
    let nx = grid.nx;
    let (su, sv) = (u.stride(), v.stride());
    for_each_interior_row(exec, out_u, |j, row| {
        let ji = j as isize;
        let (bu, n) = (base(u, ji), nx + 1);
        let (bv0, bv1) = (base(v, ji), base(v, ji + 1));
        let r = WenoRow {
            x: &us[bu - 3..bu + n + 3],
            y: std::array::from_fn(|m| &us[bu + m * su - 3 * su..bu + m * su - 3 * su + n]),
            t0: &vs[bv0 - 1..bv0 + n],
            t1: &vs[bv1 - 1..bv1 + n],
            sx,
            sy,
        };
        weno_u_row(&r, &mut row[HALO..HALO + n]);
    });
    for_each_interior_row(exec, out_v, |j, row| {
        let ji = j as isize;
        let (bv, n) = (base(v, ji), nx);
        let (bu0, bum) = (base(u, ji), base(u, ji - 1));
        let r = WenoRow {
            x: &vs[bv - 3..bv + n + 3],
            y: std::array::from_fn(|m| &vs[bv + m * sv - 3 * sv..bv + m * sv - 3 * sv + n]),
            t0: &us[bum..bum + n + 1],
            t1: &us[bu0..bu0 + n + 1],
            sx,
            sy,
        };
        weno_v_row(&r, &mut row[HALO..HALO + n]);
    });
}

/// The rows read by one row of [`convection_weno5`] (n faces): `x[i + 3 + m]` = the component at
/// face i + m of the row (m = −3..=3), `y[m + 3][i]` the same at row j + m, `t0`, `t1` the two rows
/// of the transverse component around the face.
struct WenoRow<'a> {
    x: &'a [f64],
    y: [&'a [f64]; 7],
    t0: &'a [f64],
    t1: &'a [f64],
    sx: f64,
    sy: f64,
}

/// The upwind WENO5 derivative of a seven-value window by the sign of `a` (0 when a = 0 or NaN):
/// the five undivided differences of the upwind stencil are selected by the sign of `a` and
/// combined once, and the result is selected, so that the loop has no branch and vectorises;
/// the selected value is the one the branch over [`weno5_minus`](super::weno5::weno5_minus) and
/// [`weno5_plus`](super::weno5::weno5_plus) would compute.
#[inline(always)]
fn upwind_select(w: &[f64; 7], a: f64) -> f64 {
    let d: [f64; 6] = std::array::from_fn(|m| w[m + 1] - w[m]);
    let minus = a > 0.0;
    let pick = |m: usize, p: usize| if minus { d[m] } else { d[p] };
    let r = super::weno5::weno5(pick(0, 5), pick(1, 4), pick(2, 3), pick(3, 2), pick(4, 1));
    if minus || a < 0.0 {
        r
    } else {
        0.0
    }
}

crate::multiversion! {
    /// One row of u-faces of [`convection_weno5`]: u (u_x)^upwind + v̄ (u_y)^upwind.
    fn weno_u_row / weno_u_row_base(r: &WenoRow<'_>, out: &mut [f64]) {
        let n = out.len();
        let (x, t0, t1) = (&r.x[..n + 6], &r.t0[..n + 1], &r.t1[..n + 1]);
        let y: [&[f64]; 7] = std::array::from_fn(|m| &r.y[m][..n]);
        for (i, o) in out.iter_mut().enumerate() {
            let uu = x[i + 3];
            let vv = 0.25 * (t0[i] + t0[i + 1] + t1[i] + t1[i + 1]);
            let wx = [x[i], x[i + 1], x[i + 2], x[i + 3], x[i + 4], x[i + 5], x[i + 6]];
            let wy = [y[0][i], y[1][i], y[2][i], y[3][i], y[4][i], y[5][i], y[6][i]];
            *o = uu * upwind_select(&wx, uu) * r.sx + vv * upwind_select(&wy, vv) * r.sy;
        }
    }
}

crate::multiversion! {
    /// One row of v-faces of [`convection_weno5`]: ū (v_x)^upwind + v (v_y)^upwind.
    fn weno_v_row / weno_v_row_base(r: &WenoRow<'_>, out: &mut [f64]) {
        let n = out.len();
        let (x, t0, t1) = (&r.x[..n + 6], &r.t0[..n + 1], &r.t1[..n + 1]);
        let y: [&[f64]; 7] = std::array::from_fn(|m| &r.y[m][..n]);
        for (i, o) in out.iter_mut().enumerate() {
            let vv = x[i + 3];
            let uu = 0.25 * (t0[i] + t0[i + 1] + t1[i] + t1[i + 1]);
            let wx = [x[i], x[i + 1], x[i + 2], x[i + 3], x[i + 4], x[i + 5], x[i + 6]];
            let wy = [y[0][i], y[1][i], y[2][i], y[3][i], y[4][i], y[5][i], y[6][i]];
            *o = uu * upwind_select(&wx, uu) * r.sx + vv * upwind_select(&wy, vv) * r.sy;
        }
    }
}

/// Average of the two cells on each side of every vertical face (ghosts of `c` filled).
pub fn cell_to_face_x(c: &Field, out: &mut Field, exec: Exec) {
    let cs = c.slice();
    let n = out.nx;
    for_each_interior_row(exec, out, |j, row| {
        let b = base(c, j as isize);
        for i in 0..n {
            row[HALO + i] = 0.5 * (cs[b + i] + cs[b + i - 1]);
        }
    });
}

/// Average of the two cells below and above every horizontal face (ghosts of `c` filled).
pub fn cell_to_face_y(c: &Field, out: &mut Field, exec: Exec) {
    let cs = c.slice();
    let n = out.nx;
    for_each_interior_row(exec, out, |j, row| {
        let (b0, b1) = (base(c, j as isize - 1), base(c, j as isize));
        for i in 0..n {
            row[HALO + i] = 0.5 * (cs[b0 + i] + cs[b1 + i]);
        }
    });
}

/// Average of the four cells around every node (ghosts of `c` filled).
pub fn cell_to_node(c: &Field, out: &mut Field, exec: Exec) {
    let cs = c.slice();
    let n = out.nx;
    for_each_interior_row(exec, out, |j, row| {
        let (b0, b1) = (base(c, j as isize - 1), base(c, j as isize));
        for i in 0..n {
            row[HALO + i] = 0.25 * (cs[b0 + i] + cs[b0 + i - 1] + cs[b1 + i] + cs[b1 + i - 1]);
        }
    });
}

/// Largest |value| over the interior points of `f` (0 for a field of zeros, NaN when any is
/// NaN): [`Field::max_abs`] row by row on the threads of `exec`, the same value.
pub fn max_abs(f: &Field, exec: Exec) -> f64 {
    exec.max_rows(f.ny, f.nx * f.ny, |j| {
        let b = base(f, j as isize);
        row_max_abs(&f.slice()[b..b + f.nx])
    })
}

/// Largest |u| over XFace points and |v| over YFace points, as (max |u|, max |v|) (NaN propagates).
pub fn max_speed(u: &Field, v: &Field, exec: Exec) -> (f64, f64) {
    let row_max = |f: &Field, j: usize| {
        let b = base(f, j as isize);
        row_max_abs(&f.slice()[b..b + f.nx])
    };
    (exec.max_rows(u.ny, u.nx * u.ny, |j| row_max(u, j)), exec.max_rows(v.ny, v.nx * v.ny, |j| row_max(v, j)))
}

/// Largest |u| over the XFace points and |v| over the YFace points next to a cell with Φ > `level`
/// (either of the face's two cells; the faces of the domain's sides look at their one interior
/// cell), as (max |u|, max |v|); 0 where no face qualifies, NaN propagates.
pub fn max_speed_where(u: &Field, v: &Field, phi: &Field, level: f64, exec: Exec) -> (f64, f64) {
    let (nx, ny) = (phi.nx, phi.ny);
    let (us, vs, ps) = (u.slice(), v.slice(), phi.slice());
    let umax = exec.max_rows(ny, (nx + 1) * ny, |j| {
        let bp = base(phi, j as isize);
        let near = |i: usize| (i > 0 && ps[bp + i - 1] > level) || (i < nx && ps[bp + i] > level);
        max_abs_where(&us[base(u, j as isize)..][..=nx], near)
    });
    let vmax = exec.max_rows(ny + 1, nx * (ny + 1), |j| {
        let (below, above) = (base(phi, j as isize - 1), base(phi, j as isize));
        let near = |i: usize| (j > 0 && ps[below + i] > level) || (j < ny && ps[above + i] > level);
        max_abs_where(&vs[base(v, j as isize)..][..nx], near)
    });
    (umax, vmax)
}

/// The largest |row[i]| over the i where `near(i)` (0 for none), NaN when any of them is NaN.
fn max_abs_where(row: &[f64], near: impl Fn(usize) -> bool) -> f64 {
    let (mut m, mut nan) = (0.0f64, false);
    for (i, &x) in row.iter().enumerate() {
        if near(i) {
            nan |= x.is_nan();
            m = m.max(x.abs());
        }
    }
    if nan {
        f64::NAN
    } else {
        m
    }
}

crate::multiversion! {
    /// The largest |a| of a row (0 for an empty row), NaN when any value is NaN (f64::max would
    /// drop it when a finite value follows). A maximum is exact: four running maxima in one
    /// loop give the value of one left to right.
    fn row_max_abs / row_max_abs_base(row: &[f64]) -> f64 {
        let (mut m, mut nan) = ([0.0f64; 4], false);
        let chunks = row.chunks_exact(4);
        let rest = chunks.remainder();
        for c in chunks {
            for k in 0..4 {
                let a = c[k].abs();
                nan |= a.is_nan();
                m[k] = if a > m[k] { a } else { m[k] };
            }
        }
        for &x in rest {
            let a = x.abs();
            nan |= a.is_nan();
            m[0] = if a > m[0] { a } else { m[0] };
        }
        if nan {
            f64::NAN
        } else {
            m[0].max(m[1]).max(m[2].max(m[3]))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn row_max_abs_is_the_sticky_nan_maximum() {
        let naive = |r: &[f64]| r.iter().fold(0.0f64, |m, &a| if a.is_nan() || m.is_nan() { f64::NAN } else { m.max(a.abs()) });
        let mut rnd = crate::operators::random_rows(11);
        for n in [0, 1, 3, 4, 5, 17, 130] {
            let mut row = rnd(n);
            for f in [row_max_abs, row_max_abs_base] {
                assert_eq!(f(&row).to_bits(), naive(&row).to_bits(), "n = {n}");
            }
            if n > 0 {
                row[n / 2] = f64::NAN;
                assert!(row_max_abs(&row).is_nan() && row_max_abs_base(&row).is_nan());
                row[n / 2] = f64::NEG_INFINITY;
                assert_eq!(row_max_abs(&row), f64::INFINITY);
            }
        }
    }

    /// The viscous force as two plain sweeps over the field storage (the formulas of
    /// [`viscous`], indexed from the row bases).
    fn viscous_reference(u: &Field, v: &Field, ec: &Field, en: &Field, grid: &Grid, out_u: &mut Field, out_v: &mut Field) {
        let (us, vs, ecs, ens) = (u.slice(), v.slice(), ec.slice(), en.slice());
        let (idx, idy, nx) = (1.0 / grid.dx, 1.0 / grid.dy, grid.nx);
        for j in 0..out_u.ny as isize {
            let (bu, bum, bup, bv0, bv1, bc, bn0, bn1) =
                (base(u, j), base(u, j - 1), base(u, j + 1), base(v, j), base(v, j + 1), base(ec, j), base(en, j), base(en, j + 1));
            for i in 0..=nx {
                let txx_r = 2.0 * ecs[bc + i] * (us[bu + i + 1] - us[bu + i]) * idx;
                let txx_l = 2.0 * ecs[bc + i - 1] * (us[bu + i] - us[bu + i - 1]) * idx;
                let txy_t = ens[bn1 + i] * ((us[bup + i] - us[bu + i]) * idy + (vs[bv1 + i] - vs[bv1 + i - 1]) * idx);
                let txy_b = ens[bn0 + i] * ((us[bu + i] - us[bum + i]) * idy + (vs[bv0 + i] - vs[bv0 + i - 1]) * idx);
                let k = out_u.idx(i as isize, j);
                out_u.slice_mut()[k] = (txx_r - txx_l) * idx + (txy_t - txy_b) * idy;
            }
        }
        for j in 0..out_v.ny as isize {
            let (bv, bvm, bvp, bu0, bum, bc0, bcm, bn) =
                (base(v, j), base(v, j - 1), base(v, j + 1), base(u, j), base(u, j - 1), base(ec, j), base(ec, j - 1), base(en, j));
            for i in 0..nx {
                let tyy_t = 2.0 * ecs[bc0 + i] * (vs[bvp + i] - vs[bv + i]) * idy;
                let tyy_b = 2.0 * ecs[bcm + i] * (vs[bv + i] - vs[bvm + i]) * idy;
                let txy_r = ens[bn + i + 1] * ((us[bu0 + i + 1] - us[bum + i + 1]) * idy + (vs[bv + i + 1] - vs[bv + i]) * idx);
                let txy_l = ens[bn + i] * ((us[bu0 + i] - us[bum + i]) * idy + (vs[bv + i] - vs[bv + i - 1]) * idx);
                let k = out_v.idx(i as isize, j);
                out_v.slice_mut()[k] = (txy_r - txy_l) * idx + (tyy_t - tyy_b) * idy;
            }
        }
    }

    fn random(grid: &Grid, loc: Location, seed: u64) -> Field {
        let mut f = Field::zeros(grid, loc);
        let mut s = seed;
        for x in f.slice_mut() {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            *x = ((s >> 11) as f64 / (1u64 << 53) as f64) - 0.3;
        }
        f
    }

    /// `viscous_helmholtz_dots` writes the faces of `viscous_helmholtz` and, per row, the sums of
    /// a separate left-to-right pass over the chosen columns, serially and on two threads.
    #[test]
    fn viscous_helmholtz_dots_are_the_operator_then_the_row_sums_bit_for_bit() {
        // rows short enough for tasks of eight rows, and long enough for tasks of two
        for (nx, ny, lx) in [(67, 41, 1.3), (1900, 21, 38.0)] {
            viscous_helmholtz_dots_case(&Grid::new(nx, ny, lx, 0.7).unwrap());
        }
    }

    fn viscous_helmholtz_dots_case(grid: &Grid) {
        let grid = grid.clone();
        let (u, v) = (random(&grid, Location::XFace, 11), random(&grid, Location::YFace, 12));
        let (ec, en) = (random(&grid, Location::Centre, 13), random(&grid, Location::Node, 14));
        let (cu, cv) = (random(&grid, Location::XFace, 15), random(&grid, Location::YFace, 16));
        let (cols_u, cols_v) = (1..grid.nx, 0..grid.nx);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        for exec in [Exec::SERIAL, Exec::with_threads(2)] {
            let (mut hu, mut hv) = (Field::zeros(&grid, Location::XFace), Field::zeros(&grid, Location::YFace));
            let (mut fu, mut fv) = (Field::zeros(&grid, Location::XFace), Field::zeros(&grid, Location::YFace));
            let (mut rows_u, mut rows_v) = (vec![f64::NAN; grid.ny], vec![f64::NAN; grid.ny + 1]);
            pool.install(|| {
                viscous_helmholtz(&u, &v, &ec, &en, &cu, &cv, &grid, &mut hu, &mut hv, exec);
                let dots = RowDots { cols_u: cols_u.clone(), cols_v: cols_v.clone(), rows_u: &mut rows_u, rows_v: &mut rows_v };
                viscous_helmholtz_dots(&u, &v, &ec, &en, &cu, &cv, &grid, &mut fu, &mut fv, dots, exec);
            });
            assert_eq!(hu.slice(), fu.slice(), "{exec:?}");
            assert_eq!(hv.slice(), fv.slice(), "{exec:?}");
            for (w, out, cols, rows) in [(&u, &hu, &cols_u, &rows_u), (&v, &hv, &cols_v, &rows_v)] {
                for (j, got) in rows.iter().enumerate().take(out.ny) {
                    let want = cols.clone().fold(0.0, |s, i| s + w.at(i as isize, j as isize) * out.at(i as isize, j as isize));
                    assert_eq!(got.to_bits(), want.to_bits(), "row {j}, {exec:?}");
                }
            }
        }
    }

    /// `viscous` and `viscous_helmholtz` (row slices, AVX2 where the CPU has it) give the bits of
    /// the plain sweeps, and of c ⊙ u − viscous, serially and on two threads; the AVX2 and the
    /// baseline code of a row agree bit for bit.
    #[test]
    fn viscous_rows_are_the_plain_sweeps_bit_for_bit() {
        let grid = Grid::new(67, 41, 1.3, 0.7).unwrap();
        let (u, v) = (random(&grid, Location::XFace, 1), random(&grid, Location::YFace, 2));
        let (ec, en) = (random(&grid, Location::Centre, 3), random(&grid, Location::Node, 4));
        let (cu, cv) = (random(&grid, Location::XFace, 5), random(&grid, Location::YFace, 6));
        let (mut ru, mut rv) = (Field::zeros(&grid, Location::XFace), Field::zeros(&grid, Location::YFace));
        viscous_reference(&u, &v, &ec, &en, &grid, &mut ru, &mut rv);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        for exec in [Exec::SERIAL, Exec::with_threads(2)] {
            let (mut ou, mut ov) = (Field::zeros(&grid, Location::XFace), Field::zeros(&grid, Location::YFace));
            let (mut hu, mut hv) = (Field::zeros(&grid, Location::XFace), Field::zeros(&grid, Location::YFace));
            pool.install(|| {
                viscous(&u, &v, &ec, &en, &grid, &mut ou, &mut ov, exec);
                viscous_helmholtz(&u, &v, &ec, &en, &cu, &cv, &grid, &mut hu, &mut hv, exec);
            });
            for (out, reference, h, c, w) in [(&ou, &ru, &hu, &cu, &u), (&ov, &rv, &hv, &cv, &v)] {
                for j in 0..out.ny as isize {
                    for i in 0..out.nx as isize {
                        assert_eq!(out.at(i, j).to_bits(), reference.at(i, j).to_bits(), "viscous at ({i}, {j}), {exec:?}");
                        let want = c.at(i, j) * w.at(i, j) - reference.at(i, j);
                        assert_eq!(h.at(i, j).to_bits(), want.to_bits(), "helmholtz at ({i}, {j}), {exec:?}");
                    }
                }
            }
        }
        // one row of u-faces through both instruction sets
        let (us, vs, ecs, ens) = (u.slice(), v.slice(), ec.slice(), en.slice());
        let j = 7isize;
        let (bu, n) = (base(&u, j), grid.nx + 1);
        let row = UxRow {
            uc: &us[bu - 1..bu + n + 1],
            un: &us[base(&u, j + 1)..base(&u, j + 1) + n],
            us: &us[base(&u, j - 1)..base(&u, j - 1) + n],
            v1: &vs[base(&v, j + 1) - 1..base(&v, j + 1) + n],
            v0: &vs[base(&v, j) - 1..base(&v, j) + n],
            e: &ecs[base(&ec, j) - 1..base(&ec, j) + n],
            n1: &ens[base(&en, j + 1)..base(&en, j + 1) + n],
            n0: &ens[base(&en, j)..base(&en, j) + n],
            idx: 1.0 / grid.dx,
            idy: 1.0 / grid.dy,
        };
        let (mut a, mut b) = (vec![0.0; n], vec![0.0; n]);
        ux_row_base(&row, &mut a, None);
        ux_row(&row, &mut b, None);
        assert_eq!(a.iter().map(|x| x.to_bits()).collect::<Vec<_>>(), b.iter().map(|x| x.to_bits()).collect::<Vec<_>>());
    }

    /// `convection_weno5` (row slices, the upwind stencil selected by the sign, AVX2 where the CPU has
    /// it) gives the bits of the branching sweep over seven-value windows, serially and on two
    /// threads, with velocities of both signs and exact zeros.
    #[test]
    fn weno5_convection_rows_are_the_branching_sweep_bit_for_bit() {
        use super::super::weno5::{weno5_minus, weno5_plus, window};
        let grid = Grid::new(45, 29, 1.1, 0.6).unwrap();
        let (mut u, mut v) = (random(&grid, Location::XFace, 7), random(&grid, Location::YFace, 8));
        for (k, x) in u.slice_mut().iter_mut().enumerate() {
            if k % 11 == 0 {
                *x = 0.0;
            }
        }
        for (k, x) in v.slice_mut().iter_mut().enumerate() {
            if k % 13 == 0 {
                *x = 0.0;
            }
        }
        let (us, vs) = (u.slice(), v.slice());
        let (sx, sy, nx) = (1.0 / grid.dx, 1.0 / grid.dy, grid.nx);
        let (su, sv) = (u.stride(), v.stride());
        let upwind = |data: &[f64], k: usize, step: usize, a: f64| -> f64 {
            let w = window(data, k, step);
            if a > 0.0 {
                weno5_minus(&w)
            } else if a < 0.0 {
                weno5_plus(&w)
            } else {
                0.0
            }
        };
        let (mut ru, mut rv) = (Field::zeros(&grid, Location::XFace), Field::zeros(&grid, Location::YFace));
        for j in 0..ru.ny as isize {
            let (bu, bv0, bv1) = (base(&u, j), base(&v, j), base(&v, j + 1));
            for i in 0..=nx {
                let uu = us[bu + i];
                let vv = 0.25 * (vs[bv0 + i - 1] + vs[bv0 + i] + vs[bv1 + i - 1] + vs[bv1 + i]);
                let k = ru.idx(i as isize, j);
                ru.slice_mut()[k] = uu * upwind(us, bu + i, 1, uu) * sx + vv * upwind(us, bu + i, su, vv) * sy;
            }
        }
        for j in 0..rv.ny as isize {
            let (bv, bu0, bum) = (base(&v, j), base(&u, j), base(&u, j - 1));
            for i in 0..nx {
                let vv = vs[bv + i];
                let uu = 0.25 * (us[bum + i] + us[bum + i + 1] + us[bu0 + i] + us[bu0 + i + 1]);
                let k = rv.idx(i as isize, j);
                rv.slice_mut()[k] = uu * upwind(vs, bv + i, 1, uu) * sx + vv * upwind(vs, bv + i, sv, vv) * sy;
            }
        }
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        for exec in [Exec::SERIAL, Exec::with_threads(2)] {
            let (mut ou, mut ov) = (Field::zeros(&grid, Location::XFace), Field::zeros(&grid, Location::YFace));
            pool.install(|| convection_weno5(&u, &v, &grid, &mut ou, &mut ov, exec));
            for (out, reference) in [(&ou, &ru), (&ov, &rv)] {
                for j in 0..out.ny as isize {
                    for i in 0..out.nx as isize {
                        assert_eq!(out.at(i, j).to_bits(), reference.at(i, j).to_bits(), "at ({i}, {j}), {exec:?}");
                    }
                }
            }
        }
        // one row through both instruction sets
        let (j, n) = (5isize, nx + 1);
        let bu = base(&u, j);
        let row = WenoRow {
            x: &us[bu - 3..bu + n + 3],
            y: std::array::from_fn(|m| &us[bu + m * su - 3 * su..bu + m * su - 3 * su + n]),
            t0: &vs[base(&v, j) - 1..base(&v, j) + n],
            t1: &vs[base(&v, j + 1) - 1..base(&v, j + 1) + n],
            sx,
            sy,
        };
        let (mut a, mut b) = (vec![0.0; n], vec![0.0; n]);
        weno_u_row_base(&row, &mut a);
        weno_u_row(&row, &mut b);
        assert_eq!(a.iter().map(|x| x.to_bits()).collect::<Vec<_>>(), b.iter().map(|x| x.to_bits()).collect::<Vec<_>>());
    }
}
