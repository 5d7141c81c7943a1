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
    let (us, vs, ec, en) = (u.slice(), v.slice(), eta_c.slice(), eta_n.slice());
    let (idx, idy, nx) = (1.0 / grid.dx, 1.0 / grid.dy, grid.nx);
    for_each_interior_row(exec, out_u, |j, row| {
        let j = j as isize;
        let (bu, bum, bup) = (base(u, j), base(u, j - 1), base(u, j + 1));
        let (bv0, bv1) = (base(v, j), base(v, j + 1));
        let bc = base(eta_c, j);
        let (bn0, bn1) = (base(eta_n, j), base(eta_n, j + 1));
        for i in 0..=nx {
            let txx_r = 2.0 * ec[bc + i] * (us[bu + i + 1] - us[bu + i]) * idx;
            let txx_l = 2.0 * ec[bc + i - 1] * (us[bu + i] - us[bu + i - 1]) * idx;
            let txy_t = en[bn1 + i] * ((us[bup + i] - us[bu + i]) * idy + (vs[bv1 + i] - vs[bv1 + i - 1]) * idx);
            let txy_b = en[bn0 + i] * ((us[bu + i] - us[bum + i]) * idy + (vs[bv0 + i] - vs[bv0 + i - 1]) * idx);
            row[HALO + i] = (txx_r - txx_l) * idx + (txy_t - txy_b) * idy;
        }
    });
    for_each_interior_row(exec, out_v, |j, row| {
        let j = j as isize;
        let (bv, bvm, bvp) = (base(v, j), base(v, j - 1), base(v, j + 1));
        let (bu0, bum) = (base(u, j), base(u, j - 1));
        let (bc0, bcm) = (base(eta_c, j), base(eta_c, j - 1));
        let bn = base(eta_n, j);
        for i in 0..nx {
            let tyy_t = 2.0 * ec[bc0 + i] * (vs[bvp + i] - vs[bv + i]) * idy;
            let tyy_b = 2.0 * ec[bcm + i] * (vs[bv + i] - vs[bvm + i]) * idy;
            let txy_r = en[bn + i + 1] * ((us[bu0 + i + 1] - us[bum + i + 1]) * idy + (vs[bv + i + 1] - vs[bv + i]) * idx);
            let txy_l = en[bn + i] * ((us[bu0 + i] - us[bum + i]) * idy + (vs[bv + i] - vs[bv + i - 1]) * idx);
            row[HALO + i] = (txy_r - txy_l) * idx + (tyy_t - tyy_b) * idy;
        }
    });
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
    use super::weno5::{weno5_minus, weno5_plus, window};
    let (us, vs) = (u.slice(), v.slice());
    let (sx, sy) = (1.0 / grid.dx, 1.0 / grid.dy);
    let nx = grid.nx;
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
    for_each_interior_row(exec, out_u, |j, row| {
        let j = j as isize;
        let bu = base(u, j);
        let (bv0, bv1) = (base(v, j), base(v, j + 1));
        for i in 0..=nx {
            let uu = us[bu + i];
            let vv = 0.25 * (vs[bv0 + i - 1] + vs[bv0 + i] + vs[bv1 + i - 1] + vs[bv1 + i]);
            row[HALO + i] = uu * upwind(us, bu + i, 1, uu) * sx + vv * upwind(us, bu + i, su, vv) * sy;
        }
    });
    for_each_interior_row(exec, out_v, |j, row| {
        let j = j as isize;
        let bv = base(v, j);
        let (bu0, bum) = (base(u, j), base(u, j - 1));
        for i in 0..nx {
            let vv = vs[bv + i];
            let uu = 0.25 * (us[bum + i] + us[bum + i + 1] + us[bu0 + i] + us[bu0 + i + 1]);
            row[HALO + i] = uu * upwind(vs, bv + i, 1, uu) * sx + vv * upwind(vs, bv + i, sv, vv) * sy;
        }
    });
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

/// Largest |u| over XFace points and |v| over YFace points, as (max |u|, max |v|) (NaN propagates).
pub fn max_speed(u: &Field, v: &Field, exec: Exec) -> (f64, f64) {
    let row_max = |f: &Field, j: usize| {
        let s = f.slice();
        let b = base(f, j as isize);
        let mut m = 0.0f64;
        for i in 0..f.nx {
            let a = s[b + i];
            // NaN is sticky (f64::max would drop it when a finite value follows)
            m = if a.is_nan() || m.is_nan() { f64::NAN } else { m.max(a.abs()) };
        }
        m
    };
    (exec.max_rows(u.ny, u.nx * u.ny, |j| row_max(u, j)), exec.max_rows(v.ny, v.nx * v.ny, |j| row_max(v, j)))
}
