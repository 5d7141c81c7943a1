//! The level set's two stages of a step (Aravena et al. §3.1; the order is `models/step.rs`'s):
//!
//! - step 1, eq. (10a): ∂_t Φ + u·∇Φ = 0 by WENO5 + TVD-RK3 ([`super::transport`]) with the
//!   time-centred velocity u^{n+½} ≈ (1 + ω/2)uⁿ − (ω/2)uⁿ⁻¹ (or its extension from the dense
//!   phase, [`super::extension`], with `interface_velocity = "extended"`), and the redistancing of
//!   [`super::redistance`] every N steps ([`Interface::advance`]);
//! - step 2: the material properties from Φ^{n+1}, ρ(Φ) on the faces and η(Φ) (harmonic blend)
//!   at centres and nodes ([`material_properties`], the laws of [`super::heaviside`]).

use super::{LevelSetTransport, RedistanceSettings, Redistancer, VelocityExtension};
use crate::error::Result;
use crate::exec::Exec;
use crate::grid::{BoundaryConditions, Field, Grid, HALO};
use crate::operators::{cell_to_node, fill_velocity_ghosts, for_each_interior_row, BcMode};

/// The interface room's state: the transport's stage fields and the redistancer (allocated once).
pub struct Interface {
    pub transport: LevelSetTransport,
    pub redistancer: Redistancer,
    /// The transport velocity's extension from the dense phase (`interface_velocity = "extended"`).
    pub extension: Option<VelocityExtension>,
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
        let extension = redistance.extended_velocity.then(|| VelocityExtension::new(grid));
        Ok(Interface { transport: LevelSetTransport::new(grid), redistancer: Redistancer::new(grid, redistance)?, extension })
    }

    /// Step 1: Φ^{n+1} from Φⁿ (in `phi`) transported over δt with u^{n+½}, then redistanced
    /// when `redistance`.
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
        exec: Exec,
    ) -> Result<()> {
        let half = vel.half;
        for (x, xn, xm) in [(&mut *vel.out_u, vel.u, vel.u_prev), (&mut *vel.out_v, vel.v, vel.v_prev)] {
            let (ns, ms) = (xn.slice(), xm.slice());
            for (k, o) in x.slice_mut().iter_mut().enumerate() {
                *o = (1.0 + half) * ns[k] - half * ms[k];
            }
        }
        fill_velocity_ghosts(vel.out_u, vel.out_v, bc, grid, BcMode::Full);
        if let Some(ext) = self.extension.as_mut() {
            phi.extrapolate_ghosts_linear();
            let s = self.redistancer.settings();
            ext.extend(phi, vel.out_u, vel.out_v, grid, s.extension_depth, s.extension_rest_speed, exec);
            fill_velocity_ghosts(&mut ext.u, &mut ext.v, bc, grid, BcMode::Full);
            self.transport.advect(phi, &ext.u, &ext.v, grid, dt, exec)?;
        } else {
            self.transport.advect(phi, vel.out_u, vel.out_v, grid, dt, exec)?;
        }
        if redistance {
            self.redistancer.redistance(phi, grid, exec)?;
        }
        Ok(())
    }
}

/// The fields step 2 fills: ρ on x and y faces, η at centres (ghosts extrapolated) and nodes.
pub struct MaterialFields<'a> {
    pub rho_u: &'a mut Field,
    pub rho_v: &'a mut Field,
    pub eta_c: &'a mut Field,
    pub eta_n: &'a mut Field,
}

/// Step 2: ρ(Φ) on the faces, `rho_face(Φ_a, Φ_b)` of the level set of the two cells beside a
/// face, and η(Φ) = `eta(Φ)` at centres and at nodes (Φ averaged to the node). `phi` with its
/// ghosts filled.
pub fn material_properties(phi: &Field, rho_face: impl Fn(f64, f64) -> f64 + Sync, eta: impl Fn(f64) -> f64 + Sync, out: MaterialFields, exec: Exec) {
    let ps = phi.slice();
    let st = phi.stride();
    let nxc = phi.nx;
    // density on faces from Φ averaged to the face
    let nxu = out.rho_u.nx;
    for_each_interior_row(exec, out.rho_u, |j, row| {
        let b = (j + HALO) * st + HALO;
        for i in 0..nxu {
            row[HALO + i] = rho_face(ps[b + i], ps[b + i - 1]);
        }
    });
    for_each_interior_row(exec, out.rho_v, |j, row| {
        let (b0, b1) = ((j + HALO - 1) * st + HALO, (j + HALO) * st + HALO);
        for i in 0..nxc {
            row[HALO + i] = rho_face(ps[b0 + i], ps[b1 + i]);
        }
    });
    // viscosity at centres (with ghosts) and nodes
    for_each_interior_row(exec, out.eta_c, |j, row| {
        let b = (j + HALO) * st + HALO;
        for i in 0..nxc {
            row[HALO + i] = eta(ps[b + i]);
        }
    });
    out.eta_c.extrapolate_ghosts_constant();
    cell_to_node(phi, out.eta_n, exec);
    let nxn = out.eta_n.nx;
    for_each_interior_row(exec, out.eta_n, |_, row| {
        for x in &mut row[HALO..HALO + nxn] {
            *x = eta(*x);
        }
    });
}
