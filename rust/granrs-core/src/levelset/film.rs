//! The weight of the film-sparing mass correction (option `mass_correction_film` = a > 0):
//!
//! ```text
//!   Φ ← Φ + δ w,   w_ij = min(1, max(0, M_ij / h − a)),   M_ij = max { Φ_kl : |k − i| ≤ r, |l − j| ≤ r },
//!   r = ⌈a⌉ + 3,
//! ```
//!
//! with δ the constant that restores the dense phase's reference area, as for the uniform shift
//! Φ ← Φ + δ of the global correction ([`super::Interface::correct_mass`]).
//!
//! Why: a uniform shift δ moves the zero level by δ along the normal, and where a film of the
//! dense phase tapers at a slope s it moves the film's end by about δ/s. At the tip of a deposit
//! at rest the correction then moves a front that the transport does not move (docs/validation.md,
//! "Arrest of the deposit": from the same arrested state the lowest-row front wanders over
//! 0.24–1.4 cells with the uniform correction and 0.02–0.08 cell without it). The weight leaves
//! the cells whose neighbourhood holds no Φ above a·h unchanged: a film of thickness T on a wall
//! has Φ ≤ T − h/2, so films thinner than about (a + ½) h keep their Φ to the last bit, and the
//! correction's area goes to the thicker parts of the deposit, where w = 1 (every cell of the
//! smoothed band |Φ| < 1.5 h of a deposit at least (a + 2) h thick sees Φ ≥ (a + 1) h within r
//! cells). — (granrs's own; no published reference.)
//!
//! With `mass_correction_film_speed` = u_r > 0 the films are spared only where the dense phase is
//! at rest: w ← max(w, min(1, max(0, |u|/u_r − 1))), |u| the cell-centre speed (the mean of the
//! two faces in each direction). A film that flows (|u| ≥ 2 u_r) gets the uniform shift, whose
//! return of the transport's losses keeps its end where it was while the flow spreads it; a film
//! at rest (|u| ≤ u_r) keeps its Φ.
//!
//! The weight is computed once per correction from Φ before the shift, by a separable maximum
//! over the interior cells (rows, then columns), with two centre fields allocated once; serial
//! and parallel results are the same (a maximum does not depend on the order).

use crate::exec::Exec;
use crate::grid::{Field, Grid, Location, HALO};
use crate::operators::for_each_interior_row;

/// The weight field w of the film-sparing correction and its scratch (allocated once).
pub struct FilmWeight {
    /// a: films whose largest Φ is below a·h are left alone (cells).
    thickness: f64,
    /// r = ⌈a⌉ + 3: the half-width of the neighbourhood (cells).
    radius: usize,
    /// u_r: films are spared only where the dense phase moves slower (m s⁻¹; 0: whatever their speed).
    rest_speed: f64,
    /// The maximum of Φ along each row over |k − i| ≤ r.
    row_max: Field,
    /// w at the cell centres (interior; the ghosts stay 0).
    pub w: Field,
}

impl FilmWeight {
    /// The weight for films thinner than about `thickness` cells (> 0) on `grid`, spared only
    /// where the dense phase moves slower than `rest_speed` (0: whatever their speed).
    pub fn new(grid: &Grid, thickness: f64, rest_speed: f64) -> Self {
        let radius = thickness.ceil() as usize + 3;
        let (row_max, w) = (Field::zeros(grid, Location::Centre), Field::zeros(grid, Location::Centre));
        FilmWeight { thickness, radius, rest_speed, row_max, w }
    }

    /// The neighbourhood's half-width r (cells).
    pub fn radius(&self) -> usize {
        self.radius
    }

    /// w from `phi` (interior cells only: the ghosts are not read), and with a rest speed u_r > 0
    /// and `velocity` = (u, v) on the faces, raised to 1 where the cell-centre speed reaches 2 u_r.
    pub fn update(&mut self, phi: &Field, velocity: Option<(&Field, &Field)>, grid: &Grid, exec: Exec) {
        let (nx, ny, r) = (phi.nx, phi.ny, self.radius);
        let (ps, st) = (phi.slice(), phi.stride());
        for_each_interior_row(exec, &mut self.row_max, |j, row| {
            let src = &ps[(j + HALO) * st + HALO..(j + HALO) * st + HALO + nx];
            for (i, out) in row[HALO..HALO + nx].iter_mut().enumerate() {
                let (lo, hi) = (i.saturating_sub(r), (i + r).min(nx - 1));
                *out = src[lo..=hi].iter().fold(f64::NEG_INFINITY, |m, &x| m.max(x));
            }
        });
        let (rs, rst) = (self.row_max.slice(), self.row_max.stride());
        let (inv_h, a) = (1.0 / grid.h(), self.thickness);
        for_each_interior_row(exec, &mut self.w, |j, row| {
            let (lo, hi) = (j.saturating_sub(r), (j + r).min(ny - 1));
            for (i, out) in row[HALO..HALO + nx].iter_mut().enumerate() {
                let m = (lo..=hi).map(|l| rs[(l + HALO) * rst + HALO + i]).fold(f64::NEG_INFINITY, f64::max);
                *out = (m * inv_h - a).clamp(0.0, 1.0);
            }
        });
        let Some((u, v)) = velocity.filter(|_| self.rest_speed > 0.0) else { return };
        let (us, ust, vs, vst) = (u.slice(), u.stride(), v.slice(), v.stride());
        let inv_r = 1.0 / self.rest_speed;
        for_each_interior_row(exec, &mut self.w, |j, row| {
            let (ub, vb, vt) = ((j + HALO) * ust + HALO, (j + HALO) * vst + HALO, (j + 1 + HALO) * vst + HALO);
            for (i, out) in row[HALO..HALO + nx].iter_mut().enumerate() {
                let uc = 0.5 * (us[ub + i] + us[ub + i + 1]);
                let vc = 0.5 * (vs[vb + i] + vs[vt + i]);
                *out = out.max((uc.hypot(vc) * inv_r - 1.0).clamp(0.0, 1.0));
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_weight_is_zero_on_a_thin_film_and_one_over_the_band_of_a_thick_layer() {
        // a layer 8 cells thick over x < 1 and a film 1 cell thick beyond, on the bottom wall;
        // Φ the distance to the top (the wall is not an interface)
        let grid = Grid::new(64, 32, 2.0, 1.0).unwrap();
        let h = grid.h();
        let top = |x: f64| if x < 1.0 { 8.0 * h } else { h };
        let phi = Field::from_fn(&grid, Location::Centre, |x, y| top(x) - y);
        let mut f = FilmWeight::new(&grid, 1.0, 0.0);
        assert_eq!(f.radius(), 4);
        f.update(&phi, None, &grid, Exec::SERIAL);
        let w = |i: usize, j: usize| f.w.data[[j + HALO, i + HALO]];
        // the film, more than r cells beyond the step: max Φ = h/2 < a h
        for i in 40..64 {
            for j in 0..32 {
                assert_eq!(w(i, j), 0.0, "({i}, {j})");
            }
        }
        // the thick layer's smoothed band |Φ| < 1.5 h, more than r cells before the step
        for i in 0..26 {
            for j in 0..32 {
                let p = phi.data[[j + HALO, i + HALO]];
                if p.abs() < 1.5 * h {
                    assert_eq!(w(i, j), 1.0, "({i}, {j}), Φ/h = {}", p / h);
                }
            }
        }
        // serial == parallel, to the last bit
        let mut g = FilmWeight::new(&grid, 1.0, 0.0);
        g.update(&phi, None, &grid, Exec::with_threads(2));
        assert_eq!(f.w.data, g.w.data);
        // with a rest speed: a film that flows at 2 u_r or faster is weighted 1, one at rest 0
        let u_r = 0.005;
        let mut g = FilmWeight::new(&grid, 1.0, u_r);
        let u = Field::from_fn(&grid, Location::XFace, |x, _| if x > 1.6 { 2.0 * u_r } else { 0.2 * u_r });
        let v = Field::zeros(&grid, Location::YFace);
        for exec in [Exec::SERIAL, Exec::with_threads(2)] {
            g.update(&phi, Some((&u, &v)), &grid, exec);
            let wg = |i: usize, j: usize| g.w.data[[j + HALO, i + HALO]];
            for j in 0..32 {
                assert_eq!(wg(45, j), 0.0, "film at rest");
                assert_eq!(wg(60, j), 1.0, "flowing film");
            }
        }
    }
}
