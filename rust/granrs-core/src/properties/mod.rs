//! The properties room: step 2 of the time scheme (Aravena et al. §3.1), the material
//! properties of the mixture from the level set Φ^{n+1},
//!
//! ```text
//!   ρ(Φ)   = ρ_d H_ε(Φ) + ρ_l (1 − H_ε(Φ))       on the faces (Φ averaged to the face)
//!   1/η(Φ) = H_ε(Φ)/η_d + (1 − H_ε(Φ))/η_l       at centres and nodes (Φ averaged to the node)
//! ```
//!
//! with the smoothed Heaviside H_ε of half-width ε (paper §2.4; d the dense phase, l the light
//! one; the laws are [`crate::levelset::blend`] and [`crate::levelset::blend_harmonic`]). The granular-only model
//! (`ModelConfig::free_surface`) takes ρ_d on every face beside a granular cell and the light
//! phase's density elsewhere (the free-surface projection's density).
//!
//! The room owns ρ on the x and y faces and η at centres and nodes ([`MaterialProperties`]); its
//! stage is [`MaterialProperties::update`]. The rheology's stage writes the viscosity of a law
//! with a lagged viscosity (μ(I), regularised laws) over η
//! ([`MaterialProperties::density_and_viscosity_mut`]); the momentum predictor, the pressure
//! projection and the energy budget read both.

use crate::exec::Exec;
use crate::grid::{Field, Grid, Location, HALO};
use crate::levelset::{blend, blend_harmonic};
use crate::operators::{cell_to_node, for_each_interior_row};

/// The laws of step 2: the two phases' densities and viscosities, the half-width ε of the
/// smoothed interface, and whether the light phase is a free surface (the granular-only model).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PropertyLaws {
    /// ρ, η of the phase where Φ > 0.
    pub dense_density: f64,
    pub dense_viscosity: f64,
    /// ρ, η of the phase where Φ < 0 (the dense phase's for a single-phase flow).
    pub light_density: f64,
    pub light_viscosity: f64,
    /// Half-width ε of the smoothed interface [m].
    pub eps: f64,
    /// The granular-only model: ρ_d on the faces beside a granular cell, the light phase's
    /// elsewhere.
    pub free_surface: bool,
}

impl PropertyLaws {
    /// Density of a face between cells whose level set is `a` and `b`: ρ(Φ) of Φ averaged to the
    /// face; in the granular-only model ρ_d on every face beside a granular cell, the light
    /// phase's elsewhere.
    #[inline]
    pub fn face_density(&self, a: f64, b: f64) -> f64 {
        if !self.free_surface {
            blend(0.5 * (a + b), self.eps, self.dense_density, self.light_density)
        } else if self.face_is_solved(a, b) {
            self.dense_density
        } else {
            self.light_density
        }
    }

    /// Whether the momentum of a face between cells `a` and `b` is solved for: always, except
    /// the granular-only model's faces with no granular cell beside them (extended, not solved).
    #[inline]
    pub fn face_is_solved(&self, a: f64, b: f64) -> bool {
        !self.free_surface || a > 0.0 || b > 0.0
    }

    /// η(Φ), the harmonic blend of the two viscosities.
    #[inline]
    pub fn viscosity(&self, phi: f64) -> f64 {
        blend_harmonic(phi, self.eps, self.dense_viscosity, self.light_viscosity)
    }
}

/// The room's state: ρ on the x and y faces, η at centres (ghosts extrapolated) and nodes, as
/// last computed (allocated once), and whether they are those of the current Φ.
pub struct MaterialProperties {
    rho_u: Field,
    rho_v: Field,
    eta_c: Field,
    eta_n: Field,
    current: bool,
}

impl MaterialProperties {
    /// The state for `grid` (zero until the first [`MaterialProperties::update`]).
    pub fn new(grid: &Grid) -> Self {
        MaterialProperties {
            rho_u: Field::zeros(grid, Location::XFace),
            rho_v: Field::zeros(grid, Location::YFace),
            eta_c: Field::zeros(grid, Location::Centre),
            eta_n: Field::zeros(grid, Location::Node),
            current: false,
        }
    }

    /// Whether the stage has to run: always, unless the properties are those of the current Φ
    /// and Φ is held fixed (`phi_fixed`: a single-phase flow or a frozen interface).
    pub fn needs_update(&self, phi_fixed: bool) -> bool {
        !(self.current && phi_fixed)
    }

    /// Marks the properties as stale (Φ changed: transported, set from outside, restored).
    pub fn invalidate(&mut self) {
        self.current = false;
    }

    /// Step 2: ρ(Φ) on the faces, `laws.face_density(Φ_a, Φ_b)` of the level set of the two
    /// cells beside a face, and η(Φ) = `laws.viscosity(Φ)` at centres and at nodes (Φ averaged
    /// to the node). `phi` (Φ^{n+1}) with its ghosts filled.
    pub fn update(&mut self, phi: &Field, laws: &PropertyLaws, exec: Exec) {
        let ps = phi.slice();
        let st = phi.stride();
        let nxc = phi.nx;
        // density on faces from Φ averaged to the face
        let nxu = self.rho_u.nx;
        for_each_interior_row(exec, &mut self.rho_u, |j, row| {
            let b = (j + HALO) * st + HALO;
            for i in 0..nxu {
                row[HALO + i] = laws.face_density(ps[b + i], ps[b + i - 1]);
            }
        });
        for_each_interior_row(exec, &mut self.rho_v, |j, row| {
            let (b0, b1) = ((j + HALO - 1) * st + HALO, (j + HALO) * st + HALO);
            for i in 0..nxc {
                row[HALO + i] = laws.face_density(ps[b0 + i], ps[b1 + i]);
            }
        });
        // viscosity at centres (with ghosts) and nodes
        for_each_interior_row(exec, &mut self.eta_c, |j, row| {
            let b = (j + HALO) * st + HALO;
            for i in 0..nxc {
                row[HALO + i] = laws.viscosity(ps[b + i]);
            }
        });
        self.eta_c.extrapolate_ghosts_constant();
        cell_to_node(phi, &mut self.eta_n, exec);
        let nxn = self.eta_n.nx;
        for_each_interior_row(exec, &mut self.eta_n, |_, row| {
            for x in &mut row[HALO..HALO + nxn] {
                *x = laws.viscosity(*x);
            }
        });
        self.current = true;
    }

    /// ρ on the x and y faces.
    pub fn density(&self) -> (&Field, &Field) {
        (&self.rho_u, &self.rho_v)
    }

    /// η at centres and nodes.
    pub fn viscosity(&self) -> (&Field, &Field) {
        (&self.eta_c, &self.eta_n)
    }

    /// ρ on the faces to read and η at centres and nodes to overwrite (the rheology's lagged
    /// viscosity, its stage of step 2).
    pub fn density_and_viscosity_mut(&mut self) -> ((&Field, &Field), (&mut Field, &mut Field)) {
        ((&self.rho_u, &self.rho_v), (&mut self.eta_c, &mut self.eta_n))
    }
}

impl crate::grid::WindowState for MaterialProperties {
    /// None: the properties are rebuilt from Φ by the window's own steps.
    fn state_fields(&self) -> Vec<&Field> {
        Vec::new()
    }
    fn state_fields_mut(&mut self) -> Vec<&mut Field> {
        Vec::new()
    }
    /// η at centres (the model shows the viscosity of the last step).
    fn shown_fields(&self) -> Vec<&Field> {
        vec![&self.eta_c]
    }
    fn shown_fields_mut(&mut self) -> Vec<&mut Field> {
        vec![&mut self.eta_c]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Φ = x − 0.5 on the unit square: ρ and η take the phases' values beyond ε from the
    /// interface and the blends' midpoints on it (H_ε(0) = ½: ρ = (ρ_d + ρ_l)/2 exactly,
    /// η = 2η_dη_l/(η_d + η_l)), and the state is current until invalidated.
    #[test]
    fn properties_of_a_planar_interface() {
        let grid = Grid::new(8, 4, 1.0, 0.5).unwrap();
        let mut phi = Field::from_fn(&grid, Location::Centre, |x, _| x - 0.5);
        phi.extrapolate_ghosts_linear();
        let laws = PropertyLaws { dense_density: 1500.0, dense_viscosity: 1e-3, light_density: 1.0, light_viscosity: 2e-5, eps: 0.1, free_surface: false };
        let mut props = MaterialProperties::new(&grid);
        assert!(props.needs_update(true));
        props.update(&phi, &laws, Exec::SERIAL);
        assert!(!props.needs_update(true) && props.needs_update(false));
        let (rho_u, rho_v) = props.density();
        // u-faces at x = i/8: the interface face i = 4, the dense phase beyond x = 0.6
        assert_eq!(rho_u.at(4, 1), 0.5 * (1500.0 + 1.0));
        assert_eq!(rho_u.at(7, 1), 1500.0);
        assert_eq!(rho_u.at(1, 1), 1.0);
        assert_eq!(rho_v.at(0, 2), 1.0);
        let (eta_c, eta_n) = props.viscosity();
        // η_dη_l/η_l and η_dη_l/η_d: a few round-offs from the phases' values
        let close = |a: f64, b: f64| (a - b).abs() <= 4.0 * f64::EPSILON * b;
        assert!(close(eta_c.at(7, 0), 1e-3) && close(eta_c.at(0, 0), 2e-5));
        assert!(close(eta_n.at(4, 2), 2.0 * 1e-3 * 2e-5 / (1e-3 + 2e-5)));
        props.invalidate();
        assert!(props.needs_update(true));
    }

    /// The granular-only model: ρ_d on every face beside a granular cell, ρ_l elsewhere.
    #[test]
    fn free_surface_face_density() {
        let laws = PropertyLaws { dense_density: 1500.0, dense_viscosity: 1e-3, light_density: 1.0, light_viscosity: 2e-5, eps: 0.1, free_surface: true };
        assert_eq!(laws.face_density(0.01, -0.3), 1500.0);
        assert_eq!(laws.face_density(-0.01, -0.3), 1.0);
        assert!(laws.face_is_solved(-0.2, 1e-9) && !laws.face_is_solved(-0.2, 0.0));
    }
}
