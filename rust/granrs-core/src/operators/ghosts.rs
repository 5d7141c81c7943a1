//! Ghost values of the MAC velocity that impose the boundary conditions of [`BoundaryConditions`].
//!
//! Normal components on the boundary are set to the prescribed normal velocity (walls: 0); ghost
//! layers beyond a wall are odd reflections about the wall value, u_n(−k) = 2u_n(0) − u_n(k);
//! beyond an outflow or fully developed boundary they are constant, u_n(−k) = u_n(0). Tangential ghosts follow
//! `VelocityBc::tangential_ghost`: u_t(−k) = a u_t(k−1) + b.
//!
//! Between two fully developed sides the velocity is periodic instead (face n is a copy of face 0
//! and the ghosts wrap around), which is exact for flows invariant along that direction and keeps
//! the viscous operator symmetric (zero-gradient ghosts do not: CG then stalls near 1e-9).
//!
//! With [`BcMode::Homogeneous`] every inhomogeneous datum (b, prescribed normal velocity) is
//! taken as zero: this is the linear part of the affine boundary map, used inside Krylov solves.

use crate::grid::{BoundaryConditions, Field, Grid, Side, VelocityBc, HALO};
use std::ops::Range;

/// Whether boundary data are applied or taken as zero.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BcMode {
    /// The boundary conditions as given.
    Full,
    /// The linear part only (all prescribed values zero).
    Homogeneous,
}

/// Indices of the normal-velocity faces that are unknowns along one direction with `n` cells:
/// faces 1..n−1 are always unknown, face 0 (resp. n) only if that side is an outflow or fully
/// developed side; between two fully developed sides face n is the periodic copy of face 0.
pub fn unknown_face_range(low: VelocityBc, high: VelocityBc, n: usize) -> Range<usize> {
    let start = if low.normal_is_unknown() { 0 } else { 1 };
    let end = if periodic_pair(low, high) {
        n
    } else if high.normal_is_unknown() {
        n + 1
    } else {
        n
    };
    start..end
}

/// Whether two opposite sides are both fully developed: the velocity is then periodic between
/// them (ghosts wrap around), which keeps the viscous operator symmetric.
#[inline]
pub fn periodic_pair(low: VelocityBc, high: VelocityBc) -> bool {
    low == VelocityBc::FullyDeveloped && high == VelocityBc::FullyDeveloped
}

/// Fills boundary values and ghost layers of u (XFace) and v (YFace).
pub fn fill_velocity_ghosts(u: &mut Field, v: &mut Field, bc: &BoundaryConditions, grid: &Grid, mode: BcMode) {
    let xper = periodic_pair(bc.get(Side::Left), bc.get(Side::Right));
    let yper = periodic_pair(bc.get(Side::Bottom), bc.get(Side::Top));
    fill_velocity_ghosts_walls(u, v, bc, grid, mode);
    if xper {
        wrap_x(u, grid.nx as isize, true);
        wrap_x(v, grid.nx as isize, false);
    }
    if yper {
        wrap_y(v, grid.ny as isize, true);
        wrap_y(u, grid.ny as isize, false);
    }
}

/// Periodic ghosts along x with period `n` cells: a face field (`faces`, n+1 points) gets
/// f(n) = f(0), f(−k) = f(n−k), f(n+k) = f(k); a centred one f(−k) = f(n−k), f(n−1+k) = f(k−1).
fn wrap_x(f: &mut Field, n: isize, faces: bool) {
    let g = HALO as isize;
    for j in -g..f.ny as isize + g {
        let get = |f: &Field, i: isize| f.at(i, j);
        if faces {
            let a = get(f, 0);
            let k0 = f.idx(n, j);
            f.slice_mut()[k0] = a;
        }
        for k in 1..=g {
            let (lo_src, hi_dst, hi_src) = if faces { (n - k, n + k, k) } else { (n - k, n - 1 + k, k - 1) };
            let (a, b) = (get(f, lo_src), get(f, hi_src));
            let (ia, ib) = (f.idx(-k, j), f.idx(hi_dst, j));
            let s = f.slice_mut();
            s[ia] = a;
            s[ib] = b;
        }
    }
}

/// Periodic ghosts along y (see [`wrap_x`]).
fn wrap_y(f: &mut Field, n: isize, faces: bool) {
    let g = HALO as isize;
    for i in -g..f.nx as isize + g {
        if faces {
            let a = f.at(i, 0);
            let k0 = f.idx(i, n);
            f.slice_mut()[k0] = a;
        }
        for k in 1..=g {
            let (lo_src, hi_dst, hi_src) = if faces { (n - k, n + k, k) } else { (n - k, n - 1 + k, k - 1) };
            let (a, b) = (f.at(i, lo_src), f.at(i, hi_src));
            let (ia, ib) = (f.idx(i, -k), f.idx(i, hi_dst));
            let s = f.slice_mut();
            s[ia] = a;
            s[ib] = b;
        }
    }
}

/// The normal velocity on a boundary face and its ghosts along one grid line: `at(m)` is the
/// flat index of the line's point m, `face` the boundary face, `inward` the direction into the
/// domain (±1). With a prescribed value w the face takes w and the ghost at distance m the odd
/// reflection 2w − (the point at distance m inside); without one the ghosts copy the face.
fn normal_ghosts(s: &mut [f64], at: impl Fn(isize) -> usize, face: isize, inward: isize, value: Option<f64>) {
    let g = HALO as isize;
    match value {
        Some(w) => {
            s[at(face)] = w;
            for m in 1..=g {
                s[at(face - inward * m)] = 2.0 * w - s[at(face + inward * m)];
            }
        }
        None => {
            let w = s[at(face)];
            for m in 1..=g {
                s[at(face - inward * m)] = w;
            }
        }
    }
}

/// The tangential velocity's ghosts along one grid line of `n` interior points (`at(m)`: the
/// flat index of point m): the ghost at distance m beyond each end is a·(its mirror point) + c,
/// with (a, c) = `lo` at the start and `hi` at the end.
fn tangential_ghosts(s: &mut [f64], at: impl Fn(isize) -> usize, n: isize, lo: (f64, f64), hi: (f64, f64)) {
    for m in 1..=HALO as isize {
        s[at(-m)] = lo.0 * s[at(m - 1)] + lo.1;
        s[at(n - 1 + m)] = hi.0 * s[at(n - m)] + hi.1;
    }
}

fn fill_velocity_ghosts_walls(u: &mut Field, v: &mut Field, bc: &BoundaryConditions, grid: &Grid, mode: BcMode) {
    let (nx, ny) = (grid.nx as isize, grid.ny as isize);
    let g = HALO as isize;
    let hom = mode == BcMode::Homogeneous;
    let data = |b: VelocityBc, h: f64| {
        let (a, bb) = b.tangential_ghost(h);
        (a, if hom { 0.0 } else { bb })
    };
    let normal = |b: VelocityBc| if hom { 0.0 } else { b.normal_inflow().unwrap_or(0.0) };

    // ---- u: normal on left/right, tangential on bottom/top ----
    // on the raw storage: k(i, j) is the flat index of point (i, j), ghosts included
    let (bl, br, bb, bt) = (bc.get(Side::Left), bc.get(Side::Right), bc.get(Side::Bottom), bc.get(Side::Top));
    {
        let st = u.stride() as isize;
        let k = |i: isize, j: isize| ((j + g) * st + i + g) as usize;
        let s = u.slice_mut();
        for j in 0..ny {
            // left boundary face i = 0; right boundary face i = nx (inflow into the domain is −x)
            normal_ghosts(s, |i| k(i, j), 0, 1, (!bl.normal_is_unknown()).then(|| normal(bl)));
            normal_ghosts(s, |i| k(i, j), nx, -1, (!br.normal_is_unknown()).then(|| -normal(br)));
        }
        let (lo, hi) = (data(bb, grid.dy), data(bt, grid.dy));
        for i in -g..=nx + g {
            tangential_ghosts(s, |j| k(i, j), ny, lo, hi);
        }
    }

    // ---- v: normal on bottom/top, tangential on left/right ----
    {
        let st = v.stride() as isize;
        let k = |i: isize, j: isize| ((j + g) * st + i + g) as usize;
        let s = v.slice_mut();
        for i in 0..nx {
            normal_ghosts(s, |j| k(i, j), 0, 1, (!bb.normal_is_unknown()).then(|| normal(bb)));
            normal_ghosts(s, |j| k(i, j), ny, -1, (!bt.normal_is_unknown()).then(|| -normal(bt)));
        }
        let (lo, hi) = (data(bl, grid.dx), data(br, grid.dx));
        for j in -g..=ny + g {
            tangential_ghosts(s, |i| k(i, j), nx, lo, hi);
        }
    }
}
