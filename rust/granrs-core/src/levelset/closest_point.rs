//! Distance from a point to the zero level set of a piecewise-bicubic interpolant of Φ (used by
//! the redistancing for the cells next to the interface).
//!
//! Equation: d(p) = min { |x − p| : Φ̃(x) = 0 }, where Φ̃ is the C¹ piecewise-bicubic Hermite
//! interpolant of the cell-centre values on the dual lattice (nodes = cell centres), with nodal
//! slopes from fourth-order central differences,
//!
//! ```text
//!   h Φ_x ≈ (−Φ_{i+2} + 8Φ_{i+1} − 8Φ_{i−1} + Φ_{i−2}) / 12,     (same along y)
//!   h² Φ_xy ≈ (Φ_{i+1,j+1} − Φ_{i+1,j−1} − Φ_{i−1,j+1} + Φ_{i−1,j−1}) / 4.
//! ```
//!
//! The foot point is found by the Newton-type iteration of Chopp (2001, "Some improvements of the
//! fast marching method", SIAM J. Sci. Comput. 23), which solves Φ̃(x) = 0 and ∇Φ̃(x) ∥ (x − p):
//!
//! ```text
//!   δ₁ = −Φ̃(x) ∇Φ̃/|∇Φ̃|²,   δ₂ = (p − x) − ((p − x)·∇Φ̃) ∇Φ̃/|∇Φ̃|²,   x ← x + δ₁ + δ₂.
//! ```
//!
//! Started from p itself and from the grid-line crossings next to p, it keeps the best converged
//! foot point. The interpolant reproduces cubic Φ, so the zero set of a smooth Φ is located to
//! O(h⁴) and the distance has the same accuracy. Values beyond the interior are extrapolated
//! linearly (the same rule as [`Field::extrapolate_ghosts_linear`]), so the ghost layers of Φ
//! need not be up to date.

use crate::grid::{Field, Grid};

/// The piecewise-bicubic Hermite interpolant of a cell-centre field (ghost layers must be valid).
pub(crate) struct Bicubic<'a> {
    phi: &'a Field,
    grid: &'a Grid,
}

/// 1D Hermite basis on [0, 1]: value weights (V0, V1), slope weights (D0, D1), and their
/// derivatives.
#[inline(always)]
fn hermite(s: f64) -> ([f64; 4], [f64; 4]) {
    let s2 = s * s;
    let s3 = s2 * s;
    let b = [2.0 * s3 - 3.0 * s2 + 1.0, -2.0 * s3 + 3.0 * s2, s3 - 2.0 * s2 + s, s3 - s2];
    let d = [6.0 * s2 - 6.0 * s, -6.0 * s2 + 6.0 * s, 3.0 * s2 - 4.0 * s + 1.0, 3.0 * s2 - 2.0 * s];
    (b, d)
}

impl<'a> Bicubic<'a> {
    pub(crate) fn new(phi: &'a Field, grid: &'a Grid) -> Self {
        Bicubic { phi, grid }
    }

    /// Φ at centre (i, j), extrapolated linearly beyond the interior (x first, then y).
    #[inline]
    fn val(&self, i: isize, j: isize) -> f64 {
        let (nx, ny) = (self.phi.nx as isize, self.phi.ny as isize);
        let col = |j: isize| -> f64 {
            if i < 0 {
                let a = self.phi.at(0, j);
                a + (-i) as f64 * (a - self.phi.at(1, j))
            } else if i >= nx {
                let a = self.phi.at(nx - 1, j);
                a + (i - nx + 1) as f64 * (a - self.phi.at(nx - 2, j))
            } else {
                self.phi.at(i, j)
            }
        };
        if j < 0 {
            let a = col(0);
            a + (-j) as f64 * (a - col(1))
        } else if j >= ny {
            let a = col(ny - 1);
            a + (j - ny + 1) as f64 * (a - col(ny - 2))
        } else {
            col(j)
        }
    }

    /// Nodal data at centre (i, j), in cell units: [Φ, hΦ_x, hΦ_y, h²Φ_xy].
    #[inline]
    fn node(&self, i: isize, j: isize) -> [f64; 4] {
        let f = |a: isize, b: isize| self.val(i + a, j + b);
        let fx = (-f(2, 0) + 8.0 * f(1, 0) - 8.0 * f(-1, 0) + f(-2, 0)) / 12.0;
        let fy = (-f(0, 2) + 8.0 * f(0, 1) - 8.0 * f(0, -1) + f(0, -2)) / 12.0;
        let fxy = (f(1, 1) - f(1, -1) - f(-1, 1) + f(-1, -1)) * 0.25;
        [f(0, 0), fx, fy, fxy]
    }

    /// The nodal data of the dual cell whose lower-left node is centre (a, b): corners in the
    /// order (a, b), (a+1, b), (a, b+1), (a+1, b+1).
    pub(crate) fn patch(&self, a: isize, b: isize) -> [[f64; 4]; 4] {
        [self.node(a, b), self.node(a + 1, b), self.node(a, b + 1), self.node(a + 1, b + 1)]
    }

    /// Φ̃ at local coordinates (s, t) ∈ [0, 1]² of a dual cell with nodal data `patch`.
    #[inline]
    pub(crate) fn patch_value(patch: &[[f64; 4]; 4], s: f64, t: f64) -> f64 {
        let (bs, _) = hermite(s);
        let (bt, _) = hermite(t);
        let mut v = 0.0;
        for (c, &(m, n)) in [(0usize, 0usize), (1, 0), (0, 1), (1, 1)].iter().enumerate() {
            let [f, fx, fy, fxy] = patch[c];
            v += f * bs[m] * bt[n] + fx * bs[2 + m] * bt[n] + fy * bs[m] * bt[2 + n] + fxy * bs[2 + m] * bt[2 + n];
        }
        v
    }

    /// Φ̃ and its gradient at (x, y).
    pub(crate) fn eval(&self, x: f64, y: f64) -> (f64, f64, f64) {
        let g = self.grid;
        let sc = (x - g.x0) / g.dx - 0.5;
        let tc = (y - g.y0) / g.dy - 0.5;
        // Dual cells with both nodes inside the ghost-extended range (slopes need ±2 more).
        let a = (sc.floor() as isize).clamp(-1, g.nx as isize - 1);
        let b = (tc.floor() as isize).clamp(-1, g.ny as isize - 1);
        let (s, t) = (sc - a as f64, tc - b as f64);
        let (bs, ds) = hermite(s);
        let (bt, dt) = hermite(t);
        let (mut v, mut vs, mut vt) = (0.0, 0.0, 0.0);
        for (m, n) in [(0usize, 0usize), (1, 0), (0, 1), (1, 1)] {
            let [f, fx, fy, fxy] = self.node(a + m as isize, b + n as isize);
            // value-weight index m, slope-weight index 2 + m
            let (ws, wsd, ws_s, wsd_s) = (bs[m], bs[2 + m], ds[m], ds[2 + m]);
            let (wt, wtd, wt_t, wtd_t) = (bt[n], bt[2 + n], dt[n], dt[2 + n]);
            v += f * ws * wt + fx * wsd * wt + fy * ws * wtd + fxy * wsd * wtd;
            vs += f * ws_s * wt + fx * wsd_s * wt + fy * ws_s * wtd + fxy * wsd_s * wtd;
            vt += f * ws * wt_t + fx * wsd * wt_t + fy * ws * wtd_t + fxy * wsd * wtd_t;
        }
        (v, vs / g.dx, vt / g.dy)
    }

    /// Chopp's iteration from `start` towards the foot point of `p`; the distance |x − p| if it
    /// converges to a point of the zero set within `max_dist`.
    fn foot_from(&self, p: (f64, f64), start: (f64, f64), max_dist: f64) -> Option<f64> {
        let h = self.grid.h();
        let (mut x, mut y) = start;
        for _ in 0..40 {
            let (f, gx, gy) = self.eval(x, y);
            let g2 = gx * gx + gy * gy;
            if g2.is_nan() || g2 <= 1e-24 {
                return None;
            }
            let (d1x, d1y) = (-f * gx / g2, -f * gy / g2);
            let (qx, qy) = (p.0 - x, p.1 - y);
            let proj = (qx * gx + qy * gy) / g2;
            let (d2x, d2y) = (qx - proj * gx, qy - proj * gy);
            let (dx, dy) = (d1x + d2x, d1y + d2y);
            // Limit the step to a cell (keeps the iteration local near kinks).
            let len = dx.hypot(dy);
            let scale = if len > h { h / len } else { 1.0 };
            x += scale * dx;
            y += scale * dy;
            if len < 1e-10 * h {
                let (f, _, _) = self.eval(x, y);
                let d = (x - p.0).hypot(y - p.1);
                return (f.abs() < 1e-8 * h && d <= max_dist).then_some(d);
            }
        }
        None
    }

    /// Distance from `p` to the zero set, trying p and each of `starts`; `None` if no start
    /// converges within `max_dist`.
    pub(crate) fn distance(&self, p: (f64, f64), starts: &[(f64, f64)], max_dist: f64) -> Option<f64> {
        let mut best: Option<f64> = None;
        for &s in std::iter::once(&p).chain(starts) {
            if let Some(d) = self.foot_from(p, s, max_dist) {
                best = Some(best.map_or(d, |b: f64| b.min(d)));
            }
        }
        best
    }
}
