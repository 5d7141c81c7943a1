//! The level set's stage of a step (Aravena et al. §3.1; the order is `models/step.rs`'s):
//! step 1, eq. (10a): ∂_t Φ + u·∇Φ = 0 by WENO5 + TVD-RK3 ([`super::transport`]) with the
//! time-centred velocity u^{n+½} ≈ (1 + ω/2)uⁿ − (ω/2)uⁿ⁻¹ (or its extension from the dense
//! phase, [`super::extension`], with `interface_velocity = "extended"`), and the redistancing of
//! [`super::redistance`] every N steps ([`Interface::advance`]); then, when asked, the global
//! mass correction Φ ← Φ + δ with the constant δ that restores the dense phase's reference area
//! A_ref = |{Φ > 0}| ([`Interface::correct_mass`]), and, when asked, the removal of the small
//! detached pieces of the dense phase that the transport or the correction's shift left
//! ([`Interface::remove_pieces`], [`super::pieces`]), whose area a second correction puts
//! back. With `interface_transport = "clsvof"` the dense volume fraction F is transported first
//! by the conservative split PLIC scheme of [`super::vof`] with the same u^{n+½} (its normals
//! from Φⁿ), and after Φ's transport Φ is rebuilt as the distance to F's interface
//! ([`Interface::advance`]); the rebuild replaces the redistancing, which then does not run.
//! The material properties of step 2 are the properties room's (`properties/mod.rs`).

use super::{DetachedPieces, FilmWeight, LevelSetTransport, RedistanceSettings, Redistancer, VelocityExtension, VolumeFraction};
use crate::error::Result;
use crate::exec::Exec;
use crate::grid::{BoundaryConditions, Field, Grid, HALO};
use crate::operators::{fill_velocity_ghosts, for_each_interior_row, BcMode};

/// The interface room's state: the transport's stage fields and the redistancer (allocated once).
pub struct Interface {
    pub transport: LevelSetTransport,
    pub redistancer: Redistancer,
    /// The transport velocity's extension from the dense phase (`interface_velocity = "extended"`).
    pub extension: Option<VelocityExtension>,
    /// The removal of small detached pieces of the dense phase (`piece_removal_cells` > 0).
    pub pieces: Option<DetachedPieces>,
    /// The weight of the film-sparing mass correction (`mass_correction_film` > 0, with its rest
    /// speed `mass_correction_film_speed`).
    pub film: Option<FilmWeight>,
    /// The dense volume fraction and its transport (`interface_transport = "clsvof"`).
    pub vof: Option<VolumeFraction>,
}

/// The velocity the interface is transported with, and where to put the time-centred one.
pub struct TransportVelocity<'a> {
    /// uⁿ, vⁿ with their ghosts filled.
    pub u: &'a Field,
    pub v: &'a Field,
    /// uⁿ⁻¹, vⁿ⁻¹.
    pub u_prev: &'a Field,
    pub v_prev: &'a Field,
    /// ω/2 = δt/(2 δt_{n−1}) (0 on a first step: uⁿ alone).
    pub half: f64,
    /// Work fields that receive u^{n+½}, v^{n+½}.
    pub out_u: &'a mut Field,
    pub out_v: &'a mut Field,
}

impl Interface {
    /// The state for `grid`.
    pub fn new(grid: &Grid, redistance: RedistanceSettings) -> Result<Self> {
        let extension = redistance.extended_velocity.then(|| VelocityExtension::new(grid, redistance.extension_depth, redistance.extension_rest_speed));
        let pieces = (redistance.piece_removal_cells > 0).then(|| DetachedPieces::new(grid, redistance.piece_removal_cells));
        let film =
            (redistance.mass_correction_film > 0.0).then(|| FilmWeight::new(grid, redistance.mass_correction_film, redistance.mass_correction_film_speed));
        Ok(Interface { transport: LevelSetTransport::new(grid), redistancer: Redistancer::new(grid, redistance)?, extension, pieces, film, vof: None })
    }

    /// Step 1: Φ^{n+1} from Φⁿ (in `phi`) transported over δt with u^{n+½}, then redistanced
    /// when `redistance`. With the volume fraction ([`Interface::vof`]) F is transported first
    /// with u^{n+½} (the one-fluid velocity, whose discrete divergence is the pressure solve's
    /// residual; the x-sweep first when `x_first`), and Φ^{n+1} is rebuilt from F^{n+1} last,
    /// in place of the redistancing (`redistance` is then not read).
    ///
    /// Transport with the time-centred velocity: advecting Φ with uⁿ alone lags the interface
    /// behind the flow, which feeds interfacial gravity waves (a heavy layer at rest then grows
    /// round-off exponentially).
    #[allow(clippy::too_many_arguments)]
    pub fn advance(
        &mut self,
        phi: &mut Field,
        vel: TransportVelocity,
        grid: &Grid,
        bc: &BoundaryConditions,
        dt: f64,
        redistance: bool,
        x_first: bool,
        exec: Exec,
    ) -> Result<()> {
        let half = vel.half;
        for (x, xn, xm) in [(&mut *vel.out_u, vel.u, vel.u_prev), (&mut *vel.out_v, vel.v, vel.v_prev)] {
            let (ns, ms, st) = (xn.slice(), xm.slice(), x.stride());
            exec.for_each_row(x.slice_mut(), st, |r, row| {
                for (i, o) in row.iter_mut().enumerate() {
                    let k = r * st + i;
                    *o = (1.0 + half) * ns[k] - half * ms[k];
                }
            });
        }
        fill_velocity_ghosts(vel.out_u, vel.out_v, bc, grid, BcMode::Full);
        if let Some(vof) = self.vof.as_mut() {
            vof.transport(phi, vel.out_u, vel.out_v, grid, dt, x_first, exec)?;
        }
        if let Some(ext) = self.extension.as_mut() {
            phi.extrapolate_ghosts_linear();
            ext.extend(phi, vel.out_u, vel.out_v, grid, exec);
            fill_velocity_ghosts(&mut ext.u, &mut ext.v, bc, grid, BcMode::Full);
            self.transport.advect(phi, &ext.u, &ext.v, grid, dt, exec)?;
        } else {
            self.transport.advect(phi, vel.out_u, vel.out_v, grid, dt, exec)?;
        }
        if redistance && self.vof.is_none() {
            self.redistancer.redistance(phi, grid, exec)?;
        }
        if let Some(vof) = self.vof.as_mut() {
            vof.rebuild_level_set(phi, grid, exec);
        }
        Ok(())
    }

    /// Φ as the material properties read it: `phi` itself, or with the volume fraction Φ whose
    /// H_ε is F in thin zones ([`VolumeFraction::properties_level_set`]). `phi` has its ghosts
    /// filled.
    pub fn properties_level_set<'a>(&'a mut self, phi: &'a Field, eps: f64, grid: &Grid, exec: Exec) -> &'a Field {
        match self.vof.as_mut() {
            Some(vof) => vof.properties_level_set(phi, eps, grid, exec),
            None => phi,
        }
    }

    /// With `piece_removal_cells` > 0, turns the regions of {Φ > 0} of at most that many cells,
    /// other than the largest, to air ([`super::pieces`]) and returns how many cells changed (0
    /// without the option).
    pub fn remove_pieces(&mut self, phi: &mut Field) -> usize {
        let Some(pieces) = self.pieces.as_mut() else { return 0 };
        let changed = pieces.remove(phi);
        if changed > 0 {
            phi.extrapolate_ghosts_linear();
        }
        changed
    }

    /// The global mass correction after step 1: Φ ← Φ + δ with the constant δ that restores
    /// the dense-phase area to `reference_area` (secant iterations on the sub-cell area A(δ) of
    /// [`super::dense_area`]; the first guess δ = (A_ref − A)/L uses the interface length
    /// L ≈ ∫ δ_ε(Φ) dx). With `mass_correction_film` = a > 0 the shift is δ w, with the weight w
    /// of [`super::film`] computed from Φ before the shift (films thinner than about a cells keep
    /// their Φ; with `mass_correction_film_speed` > 0 only where the dense phase is at rest, its
    /// speed from `velocity` = (u, v), the faces' velocity), and L ≈ ∫ δ_ε(Φ) w dx. Nothing is
    /// done for a reference area ≤ 0, an area already within 1e-12 of it, or no (weighted)
    /// interface. Switchable: `mass_correction`. Returns δ (m; 0 when nothing was done): the
    /// shift where w = 1.
    pub fn correct_mass(&mut self, phi: &mut Field, reference_area: f64, velocity: Option<(&Field, &Field)>, grid: &Grid, exec: Exec) -> f64 {
        let target = reference_area;
        let area = |phi: &Field| super::dense_area(phi, grid, exec);
        let a0 = area(phi);
        if target <= 0.0 || (a0 - target).abs() <= 1e-12 * target {
            return 0.0;
        }
        let eps = 1.5 * grid.h();
        if let Some(film) = self.film.as_mut() {
            film.update(phi, velocity, grid, exec);
        }
        // the weight (a centre field, Φ's layout): w = 1 everywhere without the option, where
        // δ·1 and δ_ε·1 are δ and δ_ε exactly
        let weight = self.film.as_ref().map(|f| f.w.slice());
        let (ps, st, nx) = (phi.slice(), phi.stride(), phi.nx);
        let cells = (0..phi.ny).flat_map(|j| (j + HALO) * st + HALO..(j + HALO) * st + HALO + nx);
        let length = cells.map(|k| super::dirac(ps[k], eps) * weight.map_or(1.0, |w| w[k])).sum::<f64>() * grid.dx * grid.dy;
        if length <= 0.0 {
            return 0.0;
        }
        let shift = |phi: &mut Field, d: f64| {
            let n = phi.nx;
            for_each_interior_row(exec, phi, |j, row| {
                let row = &mut row[HALO..HALO + n];
                match weight {
                    None => row.iter_mut().for_each(|x| *x += d),
                    Some(w) => row.iter_mut().zip(&w[(j + HALO) * st + HALO..]).for_each(|(x, &c)| *x += d * c),
                }
            });
        };
        let (mut d_prev, mut a_prev) = (0.0, a0);
        let mut d = (target - a0) / length;
        shift(phi, d);
        for _ in 0..4 {
            let a = area(phi);
            if (a - target).abs() <= 1e-10 * target || (a - a_prev).abs() < 1e-300 {
                break;
            }
            let d_new = d + (target - a) * (d - d_prev) / (a - a_prev);
            shift(phi, d_new - d);
            (d_prev, a_prev, d) = (d, a, d_new);
        }
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Location;
    use crate::levelset::dense_area;

    #[test]
    fn the_correction_of_a_flat_layer_returns_the_shift_that_restores_its_area() {
        // a layer Φ = H − y over the whole width L: A = L H, so restoring L (H + d) takes δ = d
        let grid = Grid::new(32, 16, 2.0, 1.0).unwrap();
        let (h0, d) = (0.4, 0.013);
        let mut phi = Field::from_fn(&grid, Location::Centre, |_, y| h0 - y);
        let mut interface = Interface::new(&grid, RedistanceSettings::default()).unwrap();
        let shift = interface.correct_mass(&mut phi, 2.0 * (h0 + d), None, &grid, Exec::SERIAL);
        assert!((shift - d).abs() < 1e-10, "δ = {shift}, expected {d}");
        assert!((dense_area(&phi, &grid, Exec::SERIAL) - 2.0 * (h0 + d)).abs() < 1e-10);
        // an area already right: nothing done, δ = 0
        let area = dense_area(&phi, &grid, Exec::SERIAL);
        assert_eq!(interface.correct_mass(&mut phi, area, None, &grid, Exec::SERIAL), 0.0);
    }

    #[test]
    fn the_film_sparing_correction_restores_the_area_and_leaves_a_thin_film_and_its_end_alone() {
        // a layer 8 cells thick over x < 1, a film one cell thick from x = 1 to its end at
        // x = 1.5, air beyond; Φ the distance to the top and to the film's end (the bottom is a
        // wall, not an interface)
        let grid = Grid::new(64, 32, 2.0, 1.0).unwrap();
        let h = grid.h();
        let phi_of = |x: f64, y: f64| if x < 1.0 { 8.0 * h - y } else { (h - y).min(1.5 - x) };
        let phi0 = Field::from_fn(&grid, Location::Centre, phi_of);
        let film_end = |phi: &Field| crate::levelset::interface_points(phi, &grid).iter().filter(|p| p[1] < 0.6 * h).map(|p| p[0]).fold(0.0, f64::max);
        let a0 = dense_area(&phi0, &grid, Exec::SERIAL);
        let settings = RedistanceSettings { mass_correction_film: 1.0, ..RedistanceSettings::default() };
        let mut results = Vec::new();
        for exec in [Exec::SERIAL, Exec::with_threads(2)] {
            for gain in [1.002, 0.998] {
                let mut phi = phi0.clone();
                let mut interface = Interface::new(&grid, settings).unwrap();
                let d = interface.correct_mass(&mut phi, gain * a0, None, &grid, exec);
                assert!(d != 0.0);
                assert!((dense_area(&phi, &grid, exec) / (gain * a0) - 1.0).abs() < 1e-10);
                // the film's cells, more than r = 4 cells beyond the layer, keep Φ to the last bit
                for j in 0..grid.ny {
                    for i in 37..grid.nx {
                        assert_eq!(phi.data[[j + HALO, i + HALO]], phi0.data[[j + HALO, i + HALO]], "({i}, {j})");
                    }
                }
                assert_eq!(film_end(&phi), film_end(&phi0));
                results.push(phi);
            }
        }
        // one thread and two give the same Φ to the last bit
        assert_eq!(results[0].data, results[2].data);
        assert_eq!(results[1].data, results[3].data);
        // the uniform shift moves the film's end: by δ along x where the end is vertical
        let mut phi = phi0.clone();
        let mut interface = Interface::new(&grid, RedistanceSettings::default()).unwrap();
        let d = interface.correct_mass(&mut phi, 1.002 * a0, None, &grid, Exec::SERIAL);
        assert!(film_end(&phi) > film_end(&phi0) + 0.5 * d, "{} {} {d}", film_end(&phi), film_end(&phi0));
    }
}
