//! Redistancing: brings Φ back to a signed distance function without moving its zero level set
//! (paper §2.4 and §3.1 step 1, "the redistancing algorithm proposed in \[14\]", applied about
//! every ten time steps — the caller decides when).
//!
//! Equation (Sussman, Smereka & Osher 1994, J. Comput. Phys. 114): the pseudo-time PDE
//!
//! ```text
//!   ∂Φ/∂τ + S(Φ⁰) (|∇Φ| − 1) = 0,   Φ(τ = 0) = Φ⁰,
//! ```
//!
//! whose steady state is the signed distance to {Φ⁰ = 0}; information travels outwards from the
//! interface at unit speed, so after a pseudo time τ a band |Φ| ≲ τ is redistanced.
//!
//! Discretisation:
//! - S(Φ⁰) = sign(Φ⁰) (exact sign: the cells next to the interface are treated separately, so
//!   the smoothed sign of SSO 1994 is not needed). Cells with Φ⁰ = 0 are kept at 0.
//! - |∇Φ| by Godunov's Hamiltonian on one-sided derivatives a = Φ_x⁻, b = Φ_x⁺, c = Φ_y⁻,
//!   d = Φ_y⁺ (Rouy & Tourin 1992; Osher & Fedkiw 2003 eq. 7.6):
//!   S > 0: |∇Φ|² = max(a⁺², b⁻²) + max(c⁺², d⁻²);  S < 0: |∇Φ|² = max(a⁻², b⁺²) + max(c⁻², d⁺²),
//!   with the WENO5 one-sided derivatives of [`super::weno5`].
//! - Pseudo time: TVD-RK3 (Shu & Osher 1988); Δτ = cfl · h away from the interface, so that
//!   [`RedistanceSettings::iterations`] iterations redistance a band of about
//!   iterations · cfl cells on each side; ghosts of every stage by linear extrapolation.
//!
//! Keeping the interface in place. Russo & Smereka (2000, J. Comput. Phys. 163) showed that the
//! SSO scheme moves the interface because the cells next to it (where Φ⁰ changes sign with a
//! neighbour) use differences across it; they treat those cells with the interface position
//! itself. Two such "subcell fixes" are offered ([`InterfaceTreatment`]):
//!
//! - [`InterfaceTreatment::ClosestPoint`] (default): a frozen subcell band. Each cell next to the
//!   interface is set, once per call, to ±(its distance to the zero set of the C¹ bicubic
//!   interpolant of Φ⁰), found by Chopp's (2001) closest-point iteration (module `closest_point`);
//!   these values are held fixed (Dirichlet data) while the PDE redistances the other cells. The
//!   interface is reproduced to O(h⁴) where Φ⁰ is smooth, and redistancing a distance function
//!   again leaves it (almost) unchanged, so frequent redistancing does not make the interface
//!   creep. Where the bicubic's stencil sees a kink of Φ⁰ (a corner of the interface, a layer
//!   thinner than about three cells) the interpolant would oscillate; there the cell keeps Φ⁰
//!   (no rescaling, but no displacement either). A kink is flagged when the largest undivided
//!   second difference of Φ⁰ in the 5 × 5 cells around exceeds [`KINK_RATIO`] times the
//!   undivided gradient (≈ h/r for an interface of radius r, so r ≳ 2h counts as smooth). If
//!   the iteration does not converge, the cell falls back to the PDE treatment below.
//!   On bumps a few cells wide the reset is not exact and moves the surface by a few 1e-4 h per
//!   call, always the same way: called at every step, millimetres in a second on a deposit at
//!   rest. With [`RedistanceSettings::tolerance`] t > 0 a cell whose |Φ⁰| is already within t·h of
//!   its closest-point distance keeps Φ⁰, so that a distance function redistanced again keeps
//!   its interface cells, and the zero level between them, to the bit.
//! - [`InterfaceTreatment::SubcellPde`]: the second-order subcell PDE of Chéné, Min & Gibou (2008,
//!   J. Sci. Comput. 35) and Min (2010, J. Comput. Phys. 229). Where Φ⁰ changes sign between
//!   cell i and i+1, the interface distance s = θ h along the grid line is taken from the
//!   quadratic ENO interpolant of Φ⁰,
//!
//!   ```text
//!     Φ⁰(x_i + t h) ≈ Φ⁰_i + (Φ⁰_{i+1} − Φ⁰_i − D/2) t + (D/2) t²,
//!     D = minmod(Φ⁰_{i−1} − 2Φ⁰_i + Φ⁰_{i+1}, Φ⁰_i − 2Φ⁰_{i+1} + Φ⁰_{i+2}),   θ = its root in (0, 1),
//!   ```
//!
//!   and the one-sided derivative towards the interface uses it as a Dirichlet node Φ = 0:
//!   Φ_x⁺ = (0 − Φ_i)/s − (s/2) Φ_xx,  Φ_x⁻ = (Φ_i − 0)/s + (s/2) Φ_xx, Φ_xx = minmod(D²Φ_i,
//!   D²Φ_{i±1}), with a local pseudo-time step Δτ_i = cfl · min(h, s). One call keeps the
//!   interface to O(h²) (0.02 h on the stretched-ellipse test), but each call shrinks convex
//!   features by about 0.04 h (h/r)², which adds up over many calls.
//!
//! Optional narrow band ([`RedistanceSettings::band`]): cells with |Φ⁰| above the band keep Φ⁰
//! (the model only needs the distance near the interface: H_ε and the transport's stencils).
//!
//! Serial and parallel runs are bit-identical (rows are independent within a stage). Scratch
//! fields are allocated once in [`Redistancer::new`].

use super::closest_point::Bicubic;
use super::transport::check_field;
#[cfg(test)]
use super::weno5::window;
use super::weno5::{weno5_minus, weno5_plus};
use crate::error::{Error, Result};
use crate::exec::Exec;
use crate::grid::{Field, Grid, Location, HALO};
use crate::operators::for_each_interior_row;
use crate::options::{self, Configurable, OptionSpec, Value};
use crate::solvers::par::SharedMut;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Kink detector of [`InterfaceTreatment::ClosestPoint`]: max |undivided second difference| of
/// Φ⁰ over 5 × 5 cells above `KINK_RATIO` × |undivided gradient| marks a kink.
pub const KINK_RATIO: f64 = 0.5;

/// How the cells next to the interface are treated (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum InterfaceTreatment {
    /// Frozen band: distance to the bicubic zero set of Φ⁰ (Chopp 2001); Φ⁰ kept at kinks.
    #[default]
    ClosestPoint,
    /// Second-order subcell PDE (Chéné, Min & Gibou 2008; Min 2010).
    SubcellPde,
}

/// Parameters of the redistancing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RedistanceSettings {
    /// Number of pseudo-time iterations (each a three-stage TVD-RK3 step). The redistanced band
    /// is about `iterations · cfl` cells wide on each side of the interface.
    pub iterations: usize,
    /// Pseudo-time step Δτ / h, in (0, ½] (Godunov + explicit RK stability in 2D).
    pub cfl: f64,
    /// Narrow band in cells: cells with |Φ⁰| > band · h are left unchanged. `None`: whole domain.
    pub band: Option<f64>,
    /// Treatment of the cells next to the interface.
    pub interface: InterfaceTreatment,
    /// [`InterfaceTreatment::ClosestPoint`]: a cell next to the interface whose |Φ⁰| is already
    /// within this many cells of its closest-point distance keeps Φ⁰ (0: every such cell is
    /// reset to its distance).
    pub tolerance: f64,
    /// The velocity that transports Φ: the one-fluid velocity (default) or its extension from
    /// the level Φ = `extension_depth` · h of the dense phase ([`super::extension`]).
    pub extended_velocity: bool,
    /// The source level of the extension, in cells (Φ ≥ depth · h keeps its velocity).
    pub extension_depth: f64,
    /// The extension only where the dense phase moves slower than this [m s⁻¹] (0: everywhere).
    pub extension_rest_speed: f64,
    /// Regions of {Φ > 0} of at most this many cells, other than the largest, are turned to air
    /// after each step's transport ([`super::pieces`]; 0: none).
    pub piece_removal_cells: usize,
    /// The global mass correction leaves films thinner than about this many cells alone
    /// ([`super::film`]; 0: the uniform shift).
    pub mass_correction_film: f64,
    /// With `mass_correction_film` > 0: the films are spared only where the dense phase moves
    /// slower than this [m s⁻¹] (0: whatever their speed).
    pub mass_correction_film_speed: f64,
}

/// The options of [`RedistanceSettings`] (`ModelConfig::redistance`).
pub const REDISTANCE_OPTIONS: &[OptionSpec] = &[
    options::int(
        "interface",
        "redistance_iterations",
        20,
        1,
        100_000,
        "1",
        "pseudo-time iterations of a redistancing (TVD-RK3 steps; the band redistanced is about iterations × cfl cells wide)",
    ),
    options::float("interface", "redistance_cfl", 0.5, 0.0, 0.5, "1", "pseudo-time step Δτ/h of the redistancing").open(true, false),
    options::float(
        "interface",
        "redistance_band",
        10.0,
        1.0,
        f64::INFINITY,
        "cells",
        "narrow band: cells with |Φ⁰| > band h are left unchanged (None: the whole domain)",
    )
    .open(false, true)
    .off_by_default(),
    options::choice(
        "interface",
        "redistance_interface",
        "closest-point",
        &["closest-point", "subcell-pde"],
        "treatment of the cells next to the interface: frozen band at the bicubic zero set (Chopp 2001) or the subcell PDE (Min 2010)",
    )
    .variant(),
    options::float(
        "interface",
        "redistance_tolerance",
        0.0,
        0.0,
        0.5,
        "cells",
        "with redistance_interface = closest-point: a cell next to the interface whose |Φ| is already within this many cells of its closest-point distance keeps Φ, so that redistancing a distance function again leaves its interface cells to the bit (0: every such cell is reset)",
    )
    .variant(),
    options::choice(
        "interface",
        "interface_velocity",
        "one-fluid",
        &["one-fluid", "extended"],
        "the velocity that transports Φ: the one-fluid velocity, or the dense phase's extended along the normal from Φ = extension_depth·h (Adalsteinsson & Sethian 1999)",
    )
    .variant(),
    options::float(
        "interface",
        "extension_depth",
        0.0,
        0.0,
        20.0,
        "cells",
        "with interface_velocity = extended: faces with Φ ≥ depth·h keep their velocity, the others take the one at Φ = (depth + 1.5)·h along the normal",
    )
    .variant(),
    options::float(
        "interface",
        "extension_rest_speed",
        0.0,
        0.0,
        f64::INFINITY,
        "m/s",
        "with interface_velocity = extended: the extension only where the dense phase moves slower than this, blended to the one-fluid velocity above (0: everywhere)",
    )
    .variant(),
    options::int(
        "interface",
        "piece_removal_cells",
        0,
        0,
        1_000_000,
        "cells",
        "regions of Φ > 0 (8-connected cells) of at most this many cells, other than the largest, are turned to air after each step's transport, their area put back by the mass correction (0: none)",
    )
    .variant(),
    options::float(
        "interface",
        "mass_correction_film",
        0.0,
        0.0,
        20.0,
        "cells",
        "the global mass correction's shift δ weighted by w = min(1, max(0, M/h − a)), M the largest Φ within ⌈a⌉ + 3 cells: films of the dense phase thinner than about a cells keep their Φ and their ends stay put (0: the uniform shift Φ + δ)",
    )
    .variant(),
    options::float(
        "interface",
        "mass_correction_film_speed",
        0.0,
        0.0,
        f64::INFINITY,
        "m/s",
        "with mass_correction_film > 0: the films are spared only where the dense phase is at rest, w raised to min(1, max(0, |u|/u_r − 1)) with u_r this speed (0: whatever their speed)",
    )
    .variant(),
];

impl InterfaceTreatment {
    /// Name used in Python and the docs.
    pub fn name(&self) -> &'static str {
        match self {
            InterfaceTreatment::ClosestPoint => "closest-point",
            InterfaceTreatment::SubcellPde => "subcell-pde",
        }
    }
}

impl Default for RedistanceSettings {
    /// 20 iterations at Δτ = h/2: a band of about 10 cells.
    fn default() -> Self {
        let o = |k| options::spec(REDISTANCE_OPTIONS, k);
        RedistanceSettings {
            iterations: o("redistance_iterations").usize(),
            cfl: o("redistance_cfl").float(),
            band: None,
            interface: InterfaceTreatment::ClosestPoint,
            tolerance: o("redistance_tolerance").float(),
            extended_velocity: options::as_name(&o("interface_velocity").default) == "extended",
            extension_depth: o("extension_depth").float(),
            extension_rest_speed: o("extension_rest_speed").float(),
            piece_removal_cells: o("piece_removal_cells").usize(),
            mass_correction_film: o("mass_correction_film").float(),
            mass_correction_film_speed: o("mass_correction_film_speed").float(),
        }
    }
}

impl Configurable for RedistanceSettings {
    fn options() -> &'static [OptionSpec] {
        REDISTANCE_OPTIONS
    }

    fn get(&self, key: &str) -> Value {
        match key {
            "redistance_iterations" => Value::Int(self.iterations.min(i64::MAX as usize) as i64),
            "redistance_cfl" => Value::Float(self.cfl),
            "redistance_band" => Value::opt_f64(self.band),
            "redistance_interface" => Value::str(self.interface.name()),
            "redistance_tolerance" => Value::Float(self.tolerance),
            "interface_velocity" => Value::str(if self.extended_velocity { "extended" } else { "one-fluid" }),
            "extension_depth" => Value::Float(self.extension_depth),
            "extension_rest_speed" => Value::Float(self.extension_rest_speed),
            "piece_removal_cells" => Value::Int(self.piece_removal_cells.min(i64::MAX as usize) as i64),
            "mass_correction_film" => Value::Float(self.mass_correction_film),
            "mass_correction_film_speed" => Value::Float(self.mass_correction_film_speed),
            _ => Value::None,
        }
    }

    fn set(&mut self, key: &str, v: &Value) -> Result<()> {
        match key {
            "redistance_iterations" => self.iterations = options::as_usize(v),
            "redistance_cfl" => self.cfl = v.as_f64().unwrap_or(self.cfl),
            "redistance_band" => self.band = v.as_f64(),
            "redistance_interface" => {
                self.interface = if options::as_name(v) == "subcell-pde" { InterfaceTreatment::SubcellPde } else { InterfaceTreatment::ClosestPoint }
            }
            "redistance_tolerance" => self.tolerance = v.as_f64().unwrap_or(self.tolerance),
            "interface_velocity" => self.extended_velocity = options::as_name(v) == "extended",
            "extension_depth" => self.extension_depth = v.as_f64().unwrap_or(self.extension_depth),
            "extension_rest_speed" => self.extension_rest_speed = v.as_f64().unwrap_or(self.extension_rest_speed),
            "piece_removal_cells" => self.piece_removal_cells = options::as_usize(v),
            "mass_correction_film" => self.mass_correction_film = v.as_f64().unwrap_or(self.mass_correction_film),
            "mass_correction_film_speed" => self.mass_correction_film_speed = v.as_f64().unwrap_or(self.mass_correction_film_speed),
            _ => {}
        }
        Ok(())
    }
}

impl RedistanceSettings {
    /// Checks the parameters against [`REDISTANCE_OPTIONS`]; an error names the field
    /// (`iterations`, `cfl`, `band`: the settings are used on their own by the level-set tests).
    pub fn validate(&self) -> Result<()> {
        for s in REDISTANCE_OPTIONS {
            s.check_named(s.key.trim_start_matches("redistance_"), &self.get(s.key))?;
        }
        Ok(())
    }
}

/// What a redistancing call did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RedistanceInfo {
    /// Pseudo-time iterations done.
    pub iterations: usize,
    /// Cells next to the interface (Φ⁰ changes sign with a neighbour).
    pub interface_cells: usize,
    /// Of those, cells frozen at their closest-point distance ([`InterfaceTreatment::ClosestPoint`]).
    pub closest_point_cells: usize,
    /// Of those, cells kept at Φ⁰ because of a kink ([`InterfaceTreatment::ClosestPoint`]).
    pub kink_cells: usize,
    /// Pseudo time reached away from the interface, iterations · Δτ (a length: the band width).
    pub pseudo_time: f64,
    /// max |ΔΦ| over the last iteration (how far from the steady state the band still is).
    pub last_change: f64,
    /// Cells brought back inside the bounds the continuous equation guarantees (sign of Φ⁰
    /// kept, |Φ| ≤ |Φ⁰| + pseudo time): 0 on smooth interfaces; non-zero where the discrete
    /// iteration misbehaved (seen once, in an air pocket one cell high trapped under a granular
    /// front at ny = 32, where it produced |Φ| ≈ 1900 h).
    pub clamped_cells: usize,
    /// Cells beyond the pseudo-time band set to the fast-sweeping distance.
    pub far_field_cells: usize,
}

/// The redistancing operator, with its scratch fields.
#[derive(Clone, Debug)]
pub struct Redistancer {
    settings: RedistanceSettings,
    phi0: Field,
    phi1: Field,
    phi2: Field,
    prev: Field,
    /// Distance from the cell centre to the interface towards −x, +x, −y, +y (∞ if none).
    sub: [Field; 4],
    /// Frozen values of the cells next to the interface (NaN elsewhere).
    frozen: Field,
    /// Fast-sweeping distance to the interface cells before the pseudo-time iterations: the
    /// iterations only touch cells within the band they can reach (τ + 3h), the far field sets
    /// the rest.
    dist: Field,
    /// Which cells are interface cells (fast sweeping's scratch, one per storage point).
    interface: Vec<bool>,
}

impl Redistancer {
    /// A redistancer for `grid` with validated `settings`.
    pub fn new(grid: &Grid, settings: RedistanceSettings) -> Result<Self> {
        settings.validate()?;
        let z = || Field::zeros(grid, Location::Centre);
        let interface = vec![false; Field::zeros(grid, Location::Centre).slice().len()];
        Ok(Redistancer { settings, phi0: z(), phi1: z(), phi2: z(), prev: z(), sub: [z(), z(), z(), z()], frozen: z(), dist: z(), interface })
    }

    /// The settings in use.
    pub fn settings(&self) -> &RedistanceSettings {
        &self.settings
    }

    /// Redistances `phi` in place (interior; ghosts left linearly extrapolated).
    pub fn redistance(&mut self, phi: &mut Field, grid: &Grid, exec: Exec) -> Result<RedistanceInfo> {
        check_field("phi", phi, grid, Location::Centre)?;
        check_field("scratch", &self.phi0, grid, Location::Centre)?;
        let st = self.settings;
        let h = grid.h();
        phi.extrapolate_ghosts_linear();
        exec.copy(self.phi0.slice_mut(), phi.slice());
        let interface_cells = self.find_interface(grid, exec);

        let band = st.band.map_or(f64::INFINITY, |b| b * h);
        let (closest_point_cells, kink_cells) = self.freeze_interface(grid, exec);
        // The frozen cells start (and stay) at their frozen values.
        let fz = self.frozen.slice();
        let stride = phi.stride();
        for_each_interior_row(exec, phi, |j, row| {
            let b = (j + HALO) * stride;
            row[HALO..HALO + grid.nx].iter_mut().zip(&fz[b + HALO..b + HALO + grid.nx]).for_each(|(p, &f)| {
                if f.is_finite() {
                    *p = f
                }
            });
        });
        // Only cells the pseudo time can reach are iterated: beyond τ + 3h (three cells of WENO
        // stencil past the reach) the far field below overwrites whatever the iterations did
        // (it keeps only d ≤ τ − 2h). On the column at ny = 256 this is ~10 % of the domain.
        let tau = st.iterations as f64 * st.cfl * h;
        let reach = if sweep_distance(phi, &self.sub, grid, &mut self.dist, &mut self.interface, exec) { tau + 3.0 * h } else { f64::INFINITY };
        let ctx = Ctx { phi0: &self.phi0, sub: &self.sub, frozen: &self.frozen, dist: &self.dist, reach, grid, cfl: st.cfl, band };
        let (phi1, phi2) = (&mut self.phi1, &mut self.phi2);
        for it in 0..st.iterations {
            if it + 1 == st.iterations {
                exec.copy(self.prev.slice_mut(), phi.slice());
            }
            phi.extrapolate_ghosts_linear();
            ctx.stage(phi1, Base::None, 0.0, 1.0, phi, exec);
            phi1.extrapolate_ghosts_linear();
            ctx.stage(phi2, Base::Other(phi), 0.75, 0.25, phi1, exec);
            phi2.extrapolate_ghosts_linear();
            ctx.stage(phi, Base::InPlace, 1.0 / 3.0, 2.0 / 3.0, phi2, exec);
        }
        // Guard: φ_τ = S(Φ⁰)(1 − |∇φ|) changes |φ| at rate ≤ 1 outward and cannot cross zero
        // (the zero set is frozen), so |Φ| ≤ |Φ⁰| + τ and sign Φ = sign Φ⁰ hold exactly for the
        // continuous equation; cells outside are reset into that range.
        let clamped = {
            let p0 = self.phi0.slice();
            count_each_interior_row(phi, grid, exec, |b, row| {
                let mut clamped = 0;
                for (i, p) in row.iter_mut().enumerate() {
                    let (f0, v) = (p0[b + i], *p);
                    let bound = f0.abs() + tau;
                    let fixed = if v * f0 < 0.0 {
                        f0
                    } else if v.abs() > bound {
                        bound.copysign(f0)
                    } else {
                        v
                    };
                    if fixed != v {
                        *p = fixed;
                        clamped += 1;
                    }
                }
                clamped
            })
        };
        // Far field: beyond the band the pseudo time reached (τ − 2h), Φ becomes ±(first-order
        // distance to the interface cells) by fast sweeping (Zhao 2005). Without it the light
        // phase's recirculation carries near-zero values of Φ from beside the interface to the far
        // field (seen under the lid of the column's channel), where transport noise flips their
        // sign into spurious granular droplets (+6–8 % dense area at ny = 32 by t = 3 s).
        let far = self.far_field(phi, grid, (tau - 2.0 * h).max(h), exec);
        phi.extrapolate_ghosts_linear();
        let prev = &self.prev;
        let (ps, qs, sp) = (phi.slice(), prev.slice(), phi.stride());
        let last_change = exec.max_rows(grid.ny, grid.cells(), |j| {
            let b = (j + HALO) * sp + HALO;
            ps[b..b + grid.nx].iter().zip(&qs[b..b + grid.nx]).map(|(a, c)| (a - c).abs()).fold(0.0, f64::max)
        });
        if !last_change.is_finite() {
            let (_, (i, j)) = phi.max_abs_with_location();
            return Err(Error::SolverFailure { solver: "level-set redistancing".into(), message: format!("non-finite level set near cell (i={i}, j={j})") });
        }
        Ok(RedistanceInfo {
            iterations: st.iterations,
            interface_cells,
            closest_point_cells,
            kink_cells,
            pseudo_time: st.iterations as f64 * st.cfl * h,
            last_change,
            clamped_cells: clamped,
            far_field_cells: far,
        })
    }

    /// Sets Φ = sign(Φ⁰)·d where the fast-sweeping distance d to the interface cells (those next
    /// to a sign change of Φ⁰, at their current |Φ|) exceeds `keep`; returns how many cells.
    /// First-order Godunov update of |∇d| = 1 with dx ≠ dy allowed, four sweep orderings, twice.
    fn far_field(&mut self, phi: &mut Field, grid: &Grid, keep: f64, exec: Exec) -> usize {
        let d = &mut self.phi1;
        if !sweep_distance(phi, &self.sub, grid, d, &mut self.interface, exec) {
            return 0;
        }
        let (ds, p0) = (d.slice(), self.phi0.slice());
        count_each_interior_row(phi, grid, exec, |b, row| {
            let mut count = 0;
            for (i, p) in row.iter_mut().enumerate() {
                let c = b + i;
                let dist = ds[c];
                if dist.is_finite() && dist > keep {
                    let s = p0[c];
                    let s = if s != 0.0 { s.signum() } else { p.signum() };
                    *p = s * dist;
                    count += 1;
                }
            }
            count
        })
    }

    /// [`InterfaceTreatment::ClosestPoint`]: fills `frozen` with ±(distance to the bicubic zero
    /// set of Φ⁰) in the smooth cells next to the interface, with Φ⁰ in those at a kink, NaN
    /// elsewhere (and everywhere for [`InterfaceTreatment::SubcellPde`]). Returns the numbers of
    /// closest-point and kink cells.
    fn freeze_interface(&mut self, grid: &Grid, exec: Exec) -> (usize, usize) {
        let (nx, ny) = (grid.nx, grid.ny);
        let stride = self.phi0.stride();
        let on = self.settings.interface == InterfaceTreatment::ClosestPoint;
        let bic = Bicubic::new(&self.phi0, grid);
        let p0 = self.phi0.slice();
        let [sxm, sxp, sym, syp] = [0, 1, 2, 3].map(|d| self.sub[d].slice());
        let h = grid.h();
        // A tolerance of 0 keeps no cell: d = |Φ⁰| to the bit gives the same value either way.
        let keep = self.settings.tolerance * h;
        exec.for_each_row(self.frozen.slice_mut(), stride, |r, row| {
            row.fill(f64::NAN);
            if !on || !(HALO..ny + HALO).contains(&r) {
                return;
            }
            let j = r - HALO;
            for i in 0..nx {
                let k = r * stride + i + HALO;
                let s = [sxm[k], sxp[k], sym[k], syp[k]];
                if !s.iter().any(|v| v.is_finite()) {
                    continue;
                }
                if is_kink(p0, k, stride) {
                    row[i + HALO] = p0[k];
                    continue;
                }
                let (x, y) = (grid.xc(i as isize), grid.yc(j as isize));
                // Start points: the cell centre and the grid-line crossings next to it.
                let mut starts = [(x, y); 4];
                let mut n = 0;
                for (d, &v) in s.iter().enumerate() {
                    if v.is_finite() {
                        starts[n] = match d {
                            0 => (x - v, y),
                            1 => (x + v, y),
                            2 => (x, y - v),
                            _ => (x, y + v),
                        };
                        n += 1;
                    }
                }
                // A crossing lies within h along a grid line: the foot point is within h.
                if let Some(d) = bic.distance((x, y), &starts[..n], 1.5 * h) {
                    row[i + HALO] = if (d - p0[k].abs()).abs() <= keep { p0[k] } else { p0[k].signum() * d };
                }
            }
        });
        if !on {
            return (0, 0);
        }
        let (frozen, phi0) = (&self.frozen, &self.phi0);
        let count = |kink: bool| {
            exec.sum_rows(ny, grid.cells(), |j| {
                let mut c = 0usize;
                for i in 0..nx {
                    let k = phi0.idx(i as isize, j as isize);
                    let f = frozen.slice()[k];
                    if f.is_finite() && is_kink(phi0.slice(), k, stride) == kink {
                        c += 1;
                    }
                }
                c as f64
            }) as usize
        };
        (count(false), count(true))
    }

    /// Fills the four subcell-distance fields from Φ⁰ (ghosts valid); returns the number of
    /// cells next to the interface.
    fn find_interface(&mut self, grid: &Grid, exec: Exec) -> usize {
        let (nx, ny) = (grid.nx, grid.ny);
        let p0 = self.phi0.slice();
        let stride = self.phi0.stride();
        // (direction index, step in storage, cell size, in-domain test for the neighbour)
        for (d, f) in self.sub.iter_mut().enumerate() {
            let (step, h): (isize, f64) = match d {
                0 => (-1, grid.dx),
                1 => (1, grid.dx),
                2 => (-(stride as isize), grid.dy),
                _ => (stride as isize, grid.dy),
            };
            exec.for_each_row(f.slice_mut(), stride, |r, row| {
                row.fill(f64::INFINITY);
                if !(HALO..ny + HALO).contains(&r) {
                    return;
                }
                let j = r - HALO;
                for i in 0..nx {
                    let inside = match d {
                        0 => i > 0,
                        1 => i + 1 < nx,
                        2 => j > 0,
                        _ => j + 1 < ny,
                    };
                    if !inside {
                        continue;
                    }
                    let k = (r * stride + i + HALO) as isize;
                    let at = |m: isize| p0[(k + m * step) as usize];
                    let (pm, a, b, pp) = (at(-1), at(0), at(1), at(2));
                    if a * b < 0.0 {
                        row[i + HALO] = h * interface_fraction(pm, a, b, pp);
                    }
                }
            });
        }
        let sub = &self.sub;
        exec.sum_rows(ny, grid.cells(), |j| (0..nx as isize).filter(|&i| sub.iter().any(|f| f.at(i, j as isize).is_finite())).count() as f64) as usize
    }
}

/// Whether Φ⁰ has a kink in the 5 × 5 cells around storage index `k` (see [`KINK_RATIO`]).
#[inline]
fn is_kink(p0: &[f64], k: usize, stride: usize) -> bool {
    let at = |a: isize, b: isize| p0[(k as isize + a + b * stride as isize) as usize];
    let g = (0.5 * (at(1, 0) - at(-1, 0))).hypot(0.5 * (at(0, 1) - at(0, -1)));
    let mut d2max = 0.0f64;
    for b in -2..=2 {
        for a in -2..=2 {
            let c = at(a, b);
            d2max = d2max.max((at(a + 1, b) - 2.0 * c + at(a - 1, b)).abs());
            d2max = d2max.max((at(a, b + 1) - 2.0 * c + at(a, b - 1)).abs());
        }
    }
    // NaN (a non-finite Φ⁰) counts as a kink.
    let smooth = d2max <= KINK_RATIO * g;
    !smooth
}

/// Fraction θ ∈ (0, 1] of the way from a (at t = 0) to b (at t = 1) where the quadratic ENO
/// interpolant through (pm, a, b, pp) at t = −1, 0, 1, 2 vanishes (a·b < 0).
#[inline]
pub fn interface_fraction(pm: f64, a: f64, b: f64, pp: f64) -> f64 {
    let linear = a / (a - b);
    let d2 = minmod(pm - 2.0 * a + b, a - 2.0 * b + pp);
    let c2 = 0.5 * d2;
    let c1 = b - a - c2;
    let theta = if c2.abs() <= 1e-12 * (b - a).abs() {
        linear
    } else {
        let disc = c1 * c1 - 4.0 * c2 * a;
        if disc < 0.0 {
            linear
        } else {
            let q = -0.5 * (c1 + c1.signum() * disc.sqrt());
            let (t1, t2) = (q / c2, a / q);
            if (0.0..=1.0).contains(&t1) {
                t1
            } else if (0.0..=1.0).contains(&t2) {
                t2
            } else {
                linear
            }
        }
    };
    theta.clamp(1e-8, 1.0)
}

#[inline(always)]
fn minmod(a: f64, b: f64) -> f64 {
    if a * b <= 0.0 {
        0.0
    } else if a.abs() < b.abs() {
        a
    } else {
        b
    }
}

/// One-sided derivatives (backward, forward) of Φ at the centre of the window `w` along one
/// axis: WENO5, or, on a side whose neighbour lies across the interface at distance `lm` / `lp`
/// (finite), the subcell fix φ/l ± ½ l minmod(Φ'') (Russo & Smereka 2000; Min 2010).
#[cfg(test)]
#[inline(always)]
fn one_sided(w: &[f64; 7], phi: f64, lm: f64, lp: f64, inv_h: f64, inv_h2: f64) -> (f64, f64) {
    if !(lm.is_finite() || lp.is_finite()) {
        return (weno5_minus(w) * inv_h, weno5_plus(w) * inv_h);
    }
    let d2 = (w[4] - 2.0 * w[3] + w[2]) * inv_h2;
    let back = if lm.is_finite() {
        let d2m = (w[3] - 2.0 * w[2] + w[1]) * inv_h2;
        phi / lm + 0.5 * lm * minmod(d2, d2m)
    } else {
        weno5_minus(w) * inv_h
    };
    let fwd = if lp.is_finite() {
        let d2p = (w[5] - 2.0 * w[4] + w[3]) * inv_h2;
        -phi / lp - 0.5 * lp * minmod(d2, d2p)
    } else {
        weno5_plus(w) * inv_h
    };
    (back, fwd)
}

#[derive(Clone, Copy)]
enum Base<'a> {
    None,
    InPlace,
    Other(&'a Field),
}

/// Read-only data of one redistancing call.
struct Ctx<'a> {
    phi0: &'a Field,
    frozen: &'a Field,
    sub: &'a [Field; 4],
    /// Distance to the interface cells, and how far the iterations reach.
    dist: &'a Field,
    reach: f64,
    grid: &'a Grid,
    cfl: f64,
    band: f64,
}

impl Ctx<'_> {
    /// out = a·base + b·(src + Δτ_i L(src)) with L = −S(Φ⁰)(|∇Φ| − 1); `src` has valid ghosts.
    fn stage(&self, out: &mut Field, base: Base, a: f64, b: f64, src: &Field, exec: Exec) {
        let g = self.grid;
        let (nx, ny) = (g.nx, g.ny);
        let stride = out.stride();
        let (inv_dx, inv_dy) = (1.0 / g.dx, 1.0 / g.dy);
        let coef = StageCoef {
            a,
            b,
            inv_dx,
            inv_dy,
            inv_dx2: inv_dx * inv_dx,
            inv_dy2: inv_dy * inv_dy,
            dtau_far: self.cfl * g.h(),
            cfl: self.cfl,
            band: self.band,
            reach: self.reach,
        };
        let (s, p0, fz, dist) = (src.slice(), self.phi0.slice(), self.frozen.slice(), self.dist.slice());
        let sub = [0, 1, 2, 3].map(|d| self.sub[d].slice());
        let base_s = match base {
            Base::Other(f) => Some(f.slice()),
            _ => None,
        };
        let in_place = matches!(base, Base::InPlace);
        exec.for_each_row(out.slice_mut(), stride, |r, row| {
            if !(HALO..ny + HALO).contains(&r) {
                return;
            }
            let k0 = r * stride + HALO;
            let cells = k0..k0 + nx;
            let rows = RedistanceRow {
                x: &s[k0 - 3..k0 + nx + 3],
                y: std::array::from_fn(|m| &s[k0 + m * stride - 3 * stride..k0 + m * stride - 3 * stride + nx]),
                p0: &p0[cells.clone()],
                frozen: &fz[cells.clone()],
                dist: &dist[cells.clone()],
                sub: sub.map(|d| &d[cells.clone()]),
            };
            let rb = match base_s {
                Some(bs) => RowBase::Other(&bs[cells]),
                None if in_place => RowBase::InPlace,
                None => RowBase::None,
            };
            redistance_row(&rows, coef, rb, &mut row[HALO..HALO + nx]);
        });
    }
}

/// The stage's scalars.
#[derive(Clone, Copy)]
struct StageCoef {
    a: f64,
    b: f64,
    inv_dx: f64,
    inv_dy: f64,
    inv_dx2: f64,
    inv_dy2: f64,
    dtau_far: f64,
    cfl: f64,
    band: f64,
    reach: f64,
}

/// The rows read by one row of a stage (nx cells): `x[i + 3 + m]` = Φ_{i+m,j} (m = −3..=3),
/// `y[m + 3][i]` = Φ_{i,j+m}, and Φ⁰, the frozen values, the distance to the interface cells and
/// the four sub-cell distances (x−, x+, y−, y+) of cell i.
struct RedistanceRow<'a> {
    x: &'a [f64],
    y: [&'a [f64]; 7],
    p0: &'a [f64],
    frozen: &'a [f64],
    dist: &'a [f64],
    sub: [&'a [f64]; 4],
}

/// The `a·base` term of one row of a stage.
#[derive(Clone, Copy)]
enum RowBase<'a> {
    None,
    InPlace,
    Other(&'a [f64]),
}

/// [`one_sided`] from the WENO5 derivatives `wm`, `wp` of the window `w` (already divided by
/// h): the sub-cell fix on a side whose distance `lm` / `lp` is finite, the WENO5 value
/// otherwise; the same values, bit for bit.
#[inline(always)]
fn one_sided_from(w: &[f64; 7], wm: f64, wp: f64, phi: f64, lm: f64, lp: f64, inv_h2: f64) -> (f64, f64) {
    if !(lm.is_finite() || lp.is_finite()) {
        return (wm, wp);
    }
    let d2 = (w[4] - 2.0 * w[3] + w[2]) * inv_h2;
    let back = if lm.is_finite() {
        let d2m = (w[3] - 2.0 * w[2] + w[1]) * inv_h2;
        phi / lm + 0.5 * lm * minmod(d2, d2m)
    } else {
        wm
    };
    let fwd = if lp.is_finite() {
        let d2p = (w[5] - 2.0 * w[4] + w[3]) * inv_h2;
        -phi / lp - 0.5 * lp * minmod(d2, d2p)
    } else {
        wp
    };
    (back, fwd)
}

/// Cells per chunk of [`redistance_row_body`]'s WENO5 pass (its buffers live on the stack).
const CHUNK: usize = 64;

/// One row of a stage, the body of both copies of [`redistance_row`]. Cells outside the span of
/// the row's iterated cells take b·(Φ + 0). Inside it, chunk by chunk, a first pass computes the
/// four WENO5 one-sided derivatives of every cell (straight-line arithmetic the compiler
/// vectorises), and a second pass the Godunov update of the iterated cells from them, with the
/// arithmetic of `Ctx::stage_reference` (so the same bits).
#[inline(always)]
fn redistance_row_body(r: &RedistanceRow<'_>, c: StageCoef, base: RowBase<'_>, out: &mut [f64]) {
    let n = out.len();
    let (x, p0, fz, dist) = (&r.x[..n + 6], &r.p0[..n], &r.frozen[..n], &r.dist[..n]);
    let y: [&[f64]; 7] = std::array::from_fn(|m| &r.y[m][..n]);
    let [sxm, sxp, sym, syp] = r.sub.map(|d| &d[..n]);
    let iterated = |i: usize| {
        let f0 = p0[i];
        f0 != 0.0 && f0.abs() <= c.band && dist[i] <= c.reach && !fz[i].is_finite()
    };
    let lo = (0..n).find(|&i| iterated(i)).unwrap_or(n);
    let hi = (lo..n).rev().find(|&i| iterated(i)).map_or(lo, |i| i + 1);
    let combine = |i: usize, o: f64, new: f64| match base {
        RowBase::None => new,
        RowBase::InPlace => c.a * o + new,
        RowBase::Other(bs) => c.a * bs[i] + new,
    };
    for i in (0..lo).chain(hi..n) {
        out[i] = combine(i, out[i], c.b * (x[i + 3] + 0.0));
    }
    let mut c0 = lo;
    while c0 < hi {
        let m = CHUNK.min(hi - c0);
        let (mut dxm, mut dxp, mut dym, mut dyp) = ([0.0; CHUNK], [0.0; CHUNK], [0.0; CHUNK], [0.0; CHUNK]);
        for t in 0..m {
            let i = c0 + t;
            let wx = [x[i], x[i + 1], x[i + 2], x[i + 3], x[i + 4], x[i + 5], x[i + 6]];
            let wy = [y[0][i], y[1][i], y[2][i], y[3][i], y[4][i], y[5][i], y[6][i]];
            dxm[t] = weno5_minus(&wx) * c.inv_dx;
            dxp[t] = weno5_plus(&wx) * c.inv_dx;
            dym[t] = weno5_minus(&wy) * c.inv_dy;
            dyp[t] = weno5_plus(&wy) * c.inv_dy;
        }
        for t in 0..m {
            let i = c0 + t;
            let phi = x[i + 3];
            let mut dphi = 0.0;
            if iterated(i) {
                let f0 = p0[i];
                let (lxm, lxp, lym, lyp) = (sxm[i], sxp[i], sym[i], syp[i]);
                let wx = [x[i], x[i + 1], x[i + 2], x[i + 3], x[i + 4], x[i + 5], x[i + 6]];
                let wy = [y[0][i], y[1][i], y[2][i], y[3][i], y[4][i], y[5][i], y[6][i]];
                let (dxa, dxb) = one_sided_from(&wx, dxm[t], dxp[t], phi, lxm, lxp, c.inv_dx2);
                let (dya, dyb) = one_sided_from(&wy, dym[t], dyp[t], phi, lym, lyp, c.inv_dy2);
                let (gx2, gy2, sign) = if f0 > 0.0 {
                    (dxa.max(0.0).powi(2).max(dxb.min(0.0).powi(2)), dya.max(0.0).powi(2).max(dyb.min(0.0).powi(2)), 1.0)
                } else {
                    (dxa.min(0.0).powi(2).max(dxb.max(0.0).powi(2)), dya.min(0.0).powi(2).max(dyb.max(0.0).powi(2)), -1.0)
                };
                let dtau = c.dtau_far.min(c.cfl * lxm.min(lxp).min(lym).min(lyp));
                dphi = -dtau * sign * ((gx2 + gy2).sqrt() - 1.0);
            }
            out[i] = combine(i, out[i], c.b * (phi + dphi));
        }
        c0 += m;
    }
}

crate::multiversion! {
    /// One row of a redistancing stage.
    fn redistance_row / redistance_row_base(r: &RedistanceRow<'_>, c: StageCoef, base: RowBase<'_>, out: &mut [f64]) {
        redistance_row_body(r, c, base, out)
    }
}

#[cfg(test)]
impl Ctx<'_> {
    /// The stage cell by cell (the reference the row kernel is tested against bit for bit).
    fn stage_reference(&self, out: &mut Field, base: Base, a: f64, b: f64, src: &Field) {
        let g = self.grid;
        let (nx, ny) = (g.nx, g.ny);
        let stride = out.stride();
        let (inv_dx, inv_dy) = (1.0 / g.dx, 1.0 / g.dy);
        let (inv_dx2, inv_dy2) = (inv_dx * inv_dx, inv_dy * inv_dy);
        let dtau_far = self.cfl * g.h();
        let (s, p0, fz, dist) = (src.slice(), self.phi0.slice(), self.frozen.slice(), self.dist.slice());
        let reach = self.reach;
        let [sxm, sxp, sym, syp] = [0, 1, 2, 3].map(|d| self.sub[d].slice());
        let base_s = match base {
            Base::Other(f) => Some(f.slice().to_vec()),
            _ => None,
        };
        let in_place = matches!(base, Base::InPlace);
        let (cfl, band) = (self.cfl, self.band);
        let os = out.slice_mut();
        for r in HALO..ny + HALO {
            for c in HALO..nx + HALO {
                let k = r * stride + c;
                let f0 = p0[k];
                let phi = s[k];
                let mut dphi = 0.0;
                if f0 != 0.0 && f0.abs() <= band && dist[k] <= reach && !fz[k].is_finite() {
                    let (lxm, lxp, lym, lyp) = (sxm[k], sxp[k], sym[k], syp[k]);
                    let (dxa, dxb) = one_sided(&window(s, k, 1), phi, lxm, lxp, inv_dx, inv_dx2);
                    let (dya, dyb) = one_sided(&window(s, k, stride), phi, lym, lyp, inv_dy, inv_dy2);
                    let (gx2, gy2, sign) = if f0 > 0.0 {
                        (dxa.max(0.0).powi(2).max(dxb.min(0.0).powi(2)), dya.max(0.0).powi(2).max(dyb.min(0.0).powi(2)), 1.0)
                    } else {
                        (dxa.min(0.0).powi(2).max(dxb.max(0.0).powi(2)), dya.min(0.0).powi(2).max(dyb.max(0.0).powi(2)), -1.0)
                    };
                    let dtau = dtau_far.min(cfl * lxm.min(lxp).min(lym).min(lyp));
                    dphi = -dtau * sign * ((gx2 + gy2).sqrt() - 1.0);
                }
                let new = b * (phi + dphi);
                os[k] = match &base_s {
                    Some(bs) => a * bs[k] + new,
                    None if in_place => a * os[k] + new,
                    None => new,
                };
            }
        }
    }
}

/// Runs `f(b, row)` on the interior cells of every row of `field` (`b`: the storage index of
/// the row's first interior cell) and returns the sum of the counts `f` returns; rows on the
/// pool when `exec` allows (each row written by one task: serial == parallel).
fn count_each_interior_row<F>(field: &mut Field, grid: &Grid, exec: Exec, f: F) -> usize
where
    F: Fn(usize, &mut [f64]) -> usize + Sync + Send,
{
    let (nx, ny, st) = (grid.nx, grid.ny, field.stride());
    let rows = &mut field.slice_mut()[HALO * st..(HALO + ny) * st];
    let row = |(j, r): (usize, &mut [f64])| f((j + HALO) * st + HALO, &mut r[HALO..HALO + nx]);
    if exec.use_parallel(nx * ny) {
        use rayon::prelude::*;
        rows.par_chunks_mut(st).enumerate().map(row).sum()
    } else {
        rows.chunks_mut(st).enumerate().map(row).sum()
    }
}

/// d ← the first-order distance to the interface cells (those with a finite sub-cell distance,
/// at their current |Φ|) by fast sweeping (Zhao 2005, *Math. Comp.* 74): Godunov update of
/// |∇d| = 1 with dx ≠ dy allowed, four sweep orderings, twice. Returns false (d = ∞) when there
/// is no interface.
///
/// `interface` (scratch of the field's storage size) receives which cells are interface cells:
/// the sweeps read one byte per cell for it instead of the four sub-cell distances.
///
/// On several threads each sweep is pipelined over strips of columns ([`sweep_strips`]) and
/// gives the serial sweep's distances bit for bit.
fn sweep_distance(phi: &Field, sub: &[Field; 4], grid: &Grid, d: &mut Field, interface: &mut [bool], exec: Exec) -> bool {
    let strips = if exec.use_parallel(grid.cells()) { (grid.nx / SWEEP_STRIP_MIN_COLUMNS).clamp(1, rayon::current_num_threads()) } else { 1 };
    sweep_distance_in_strips(phi, sub, grid, d, interface, exec, strips)
}

/// [`sweep_distance`] with each sweep pipelined over `strips` strips of columns.
fn sweep_distance_in_strips(phi: &Field, sub: &[Field; 4], grid: &Grid, d: &mut Field, interface: &mut [bool], exec: Exec, strips: usize) -> bool {
    let (nx, ny) = (grid.nx, grid.ny);
    let st = d.stride();
    debug_assert!(phi.stride() == st && sub.iter().all(|f| f.stride() == st));
    let [s0, s1, s2, s3] = [0, 1, 2, 3].map(|m| sub[m].slice());
    let ps = phi.slice();
    assert_eq!(interface.len(), ps.len(), "sweep_distance: the interface mask has the field's storage size");
    // the interface mask and the initial distances, row by row (elementwise: serial == parallel)
    let (ds, mask) = (d.slice_mut(), &mut interface[..]);
    let any = {
        let rows_d = &mut ds[HALO * st..(HALO + ny) * st];
        let rows_m = &mut mask[HALO * st..(HALO + ny) * st];
        let init = |j: usize, drow: &mut [f64], mrow: &mut [bool]| -> bool {
            let b = (j + HALO) * st + HALO;
            let mut any = false;
            for i in 0..nx {
                let c = b + i;
                let f = s0[c].is_finite() || s1[c].is_finite() || s2[c].is_finite() || s3[c].is_finite();
                any |= f;
                mrow[HALO + i] = f;
                drow[HALO + i] = if f { ps[c].abs() } else { f64::INFINITY };
            }
            any
        };
        if exec.use_parallel(nx * ny) {
            use rayon::prelude::*;
            rows_d.par_chunks_mut(st).zip(rows_m.par_chunks_mut(st)).enumerate().map(|(j, (dr, mr))| init(j, dr, mr)).reduce(|| false, |a, b| a | b)
        } else {
            rows_d.chunks_mut(st).zip(rows_m.chunks_mut(st)).enumerate().fold(false, |a, (j, (dr, mr))| init(j, dr, mr) | a)
        }
    };
    if !any {
        return false;
    }
    let (dx, dy) = (grid.dx, grid.dy);
    let sweeper = Sweeper { ds: SharedMut(ds.as_mut_ptr()), interface: &*mask, nx, ny, st, dx, dy, wa: 1.0 / (dx * dx), wb: 1.0 / (dy * dy) };
    for _ in 0..2 {
        for (rx, ry) in [(false, false), (true, false), (false, true), (true, true)] {
            sweep_strips(&sweeper, rx, ry, strips);
        }
    }
    true
}

/// Narrowest strip of columns a pipelined sweep gives a thread ([`sweep_strips`]).
const SWEEP_STRIP_MIN_COLUMNS: usize = 128;

/// Most strips of a pipelined sweep (their progress counters live on the stack).
const SWEEP_MAX_STRIPS: usize = 64;

/// One fast-sweeping ordering over the cells, its constant data.
///
/// The strips of a sweep share the distances through `ds`: they read and write disjoint cells
/// at any one time, in the order of the serial sweep, which the rows' progress counters enforce
/// ([`sweep_strips`]).
struct Sweeper<'a> {
    ds: SharedMut,
    interface: &'a [bool],
    nx: usize,
    ny: usize,
    st: usize,
    dx: f64,
    dy: f64,
    /// 1/dx² and 1/dy².
    wa: f64,
    wb: f64,
}

impl Sweeper<'_> {
    /// Godunov update of |∇d| = 1 at cell (i, j) from the smaller neighbour on each axis (∞
    /// outside), in place.
    #[inline(always)]
    fn update(&self, i: usize, j: usize) {
        let (nx, ny, st) = (self.nx, self.ny, self.st);
        let c = (j + HALO) * st + i + HALO;
        if self.interface[c] {
            return;
        }
        // SAFETY: c ± 1 and c ± st lie inside the field's storage (one halo layer at least);
        // no other strip writes them now (`sweep_strips`).
        let get = |k: usize| unsafe { *self.ds.get().add(k) };
        let a = (if i > 0 { get(c - 1) } else { f64::INFINITY }).min(if i + 1 < nx { get(c + 1) } else { f64::INFINITY });
        let b = (if j > 0 { get(c - st) } else { f64::INFINITY }).min(if j + 1 < ny { get(c + st) } else { f64::INFINITY });
        if !a.is_finite() && !b.is_finite() {
            return;
        }
        let (dx, dy, wa, wb) = (self.dx, self.dy, self.wa, self.wb);
        let (lo, hi, hlo) = if a + dx <= b + dy { (a, b, dx) } else { (b, a, dy) };
        let one_axis = lo + hlo;
        // ((d − a)/dx)² + ((d − b)/dy)² = 1, computed always and taken where it applies (a
        // selection, not a branch the processor would mispredict half of the time)
        let (qa, qb) = (wa + wb, -2.0 * (wa * a + wb * b));
        let qc = wa * a * a + wb * b * b - 1.0;
        let disc = qb * qb - 4.0 * qa * qc;
        let two_axes = (-qb + disc.sqrt()) / (2.0 * qa);
        let new = if one_axis > hi && disc >= 0.0 { two_axes } else { one_axis };
        let old = get(c);
        // SAFETY: as above; this strip owns cell c
        unsafe { *self.ds.get().add(c) = if new < old { new } else { old } };
    }

    /// The cells of visiting positions `ii ∈ cols` of every row in the ordering (rx, ry): row by
    /// row, each row once `before` (the strip visited just before in each row) has finished it,
    /// and `done` counts this strip's finished rows.
    fn strip(&self, rx: bool, ry: bool, cols: std::ops::Range<usize>, before: Option<&AtomicUsize>, done: &AtomicUsize) {
        let (nx, ny) = (self.nx, self.ny);
        for jj in 0..ny {
            if let Some(b) = before {
                while b.load(Ordering::Acquire) <= jj {
                    std::hint::spin_loop();
                }
            }
            let j = if ry { ny - 1 - jj } else { jj };
            for ii in cols.clone() {
                self.update(if rx { nx - 1 - ii } else { ii }, j);
            }
            done.store(jj + 1, Ordering::Release);
        }
    }
}

/// One sweep ordering (rx, ry) over `strips` strips of columns, counted in visiting order, each
/// on a task of the pool (`rayon::join`, the earlier strip on the calling thread).
///
/// Why this is the serial sweep bit for bit: in the serial order the update of the cell at
/// visiting position (ii, jj) reads its neighbours ii − 1 and jj − 1 after their update in this
/// sweep and ii + 1 and jj + 1 before it. Strip s enters row jj only once strip s − 1 has
/// finished row jj (its counter), so the one cell of strip s − 1 it reads in that row is
/// updated; strip s − 1 reads strip s's first cell of row jj while strip s has not entered row
/// jj, so that cell is not updated yet; rows jj ± 1 are read within the strip. A strip waits
/// only on the strip before it, which runs (or has run) on the thread that started the strip's
/// task, so the pipeline cannot stall, whatever the number of threads.
fn sweep_strips(sw: &Sweeper<'_>, rx: bool, ry: bool, strips: usize) {
    let nx = sw.nx;
    let strips = strips.clamp(1, nx.max(1)).min(SWEEP_MAX_STRIPS);
    let counters: [AtomicUsize; SWEEP_MAX_STRIPS] = std::array::from_fn(|_| AtomicUsize::new(0));
    let counters = &counters[..strips];
    let cols = |s: usize| s * nx / strips..(s + 1) * nx / strips;
    fn run(sw: &Sweeper<'_>, rx: bool, ry: bool, s: usize, counters: &[AtomicUsize], cols: &(dyn Fn(usize) -> std::ops::Range<usize> + Sync)) {
        let before = s.checked_sub(1).map(|b| &counters[b]);
        if s + 1 == counters.len() {
            sw.strip(rx, ry, cols(s), before, &counters[s]);
        } else {
            rayon::join(|| sw.strip(rx, ry, cols(s), before, &counters[s]), || run(sw, rx, ry, s + 1, counters, cols));
        }
    }
    if strips == 1 {
        sw.strip(rx, ry, 0..nx, None, &counters[0]);
    } else {
        run(sw, rx, ry, 0, counters, &cols);
    }
}

/// [`sweep_distance`] point by point, with the four sub-cell distances and the branching Godunov
/// update (the reference its mask and branch-free selection are tested against bit for bit).
#[cfg(test)]
fn sweep_distance_reference(phi: &Field, sub: &[Field; 4], grid: &Grid, d: &mut Field) -> bool {
    let (nx, ny) = (grid.nx as isize, grid.ny as isize);
    let (dx, dy) = (grid.dx, grid.dy);
    let interface = |i: isize, j: isize| sub.iter().any(|f| f.at(i, j).is_finite());
    let mut any = false;
    for j in 0..ny {
        for i in 0..nx {
            any |= interface(i, j);
            d.set(i as usize, j as usize, if interface(i, j) { phi.at(i, j).abs() } else { f64::INFINITY });
        }
    }
    let get = |d: &Field, i: isize, j: isize| if (0..nx).contains(&i) && (0..ny).contains(&j) { d.at(i, j) } else { f64::INFINITY };
    for _ in 0..2 {
        for (rx, ry) in [(false, false), (true, false), (false, true), (true, true)] {
            for jj in 0..ny {
                for ii in 0..nx {
                    let (i, j) = (if rx { nx - 1 - ii } else { ii }, if ry { ny - 1 - jj } else { jj });
                    let a = get(d, i - 1, j).min(get(d, i + 1, j));
                    let b = get(d, i, j - 1).min(get(d, i, j + 1));
                    if interface(i, j) || (!a.is_finite() && !b.is_finite()) {
                        continue;
                    }
                    let (lo, hi, hlo) = if a + dx <= b + dy { (a, b, dx) } else { (b, a, dy) };
                    let mut new = lo + hlo;
                    if new > hi {
                        let (wa, wb) = (1.0 / (dx * dx), 1.0 / (dy * dy));
                        let (qa, qb, qc) = (wa + wb, -2.0 * (wa * a + wb * b), wa * a * a + wb * b * b - 1.0);
                        let disc = qb * qb - 4.0 * qa * qc;
                        if disc >= 0.0 {
                            new = (-qb + disc.sqrt()) / (2.0 * qa);
                        }
                    }
                    if new < d.at(i, j) {
                        d.set(i as usize, j as usize, new);
                    }
                }
            }
        }
    }
    any
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Φ of a column with a sloping top, a thin film on the bed beyond it (thinner than a cell,
    /// so some rows have only negative values) and a corner, plus noise, so that every branch of
    /// the stage is taken: cells beyond the reach, frozen cells, sub-cell sides, both signs.
    fn column_phi(grid: &Grid) -> Field {
        let mut phi = Field::zeros(grid, Location::Centre);
        let mut rnd = crate::operators::random_rows(5);
        for j in 0..grid.ny {
            let noise = rnd(grid.nx);
            for (i, e) in noise.iter().enumerate() {
                let (x, y) = ((i as f64 + 0.5) * grid.dx, (j as f64 + 0.5) * grid.dy);
                let column = (0.45 - x).min(0.6 - 0.3 * x - y);
                let film = 0.4 * grid.dy - y;
                phi.set(i, j, column.max(film) + 0.3 * grid.dx * e);
            }
        }
        phi
    }

    /// The fast sweeping on the interface mask with the branch-free selection of the Godunov
    /// update gives the distances of the point-by-point, branching sweep bit for bit: on the
    /// column (film, corner, noise) and on a circle, with dx ≠ dy; and the distances are not
    /// trivially equal (most cells are reached, some by the two-axis update).
    #[test]
    fn fast_sweeping_on_the_mask_is_the_branching_sweep_bit_for_bit() {
        for (nx, ny, lx, ly) in [(90, 37, 1.5, 0.6), (64, 64, 1.0, 1.0), (33, 42, 1.0, 0.9), (17, 5, 1.0, 0.3)] {
            let grid = Grid::new(nx, ny, lx, ly).unwrap();
            let circle = {
                let mut f = Field::zeros(&grid, Location::Centre);
                for j in 0..ny {
                    for i in 0..nx {
                        let (x, y) = ((i as f64 + 0.5) * grid.dx, (j as f64 + 0.5) * grid.dy);
                        f.set(i, j, 0.2 * ly - ((x - 0.4 * lx).powi(2) + (y - 0.5 * ly).powi(2)).sqrt());
                    }
                }
                f
            };
            for (name, mut phi) in [("column", column_phi(&grid)), ("circle", circle)] {
                let mut rd = Redistancer::new(&grid, RedistanceSettings::default()).unwrap();
                phi.extrapolate_ghosts_linear();
                rd.phi0.assign(&phi);
                rd.find_interface(&grid, Exec::SERIAL);
                let (mut got, mut want) = (Field::zeros(&grid, Location::Centre), Field::zeros(&grid, Location::Centre));
                assert!(sweep_distance(&phi, &rd.sub, &grid, &mut got, &mut rd.interface, Exec::SERIAL));
                assert!(sweep_distance_reference(&phi, &rd.sub, &grid, &mut want));
                let (mut reached, mut differ) = (0, 0);
                for j in 0..ny as isize {
                    for i in 0..nx as isize {
                        let (a, b) = (got.at(i, j), want.at(i, j));
                        assert_eq!(a.to_bits(), b.to_bits(), "{name} {nx}x{ny}: cell ({i}, {j}): {a} != {b}");
                        reached += a.is_finite() as usize;
                        differ += (a != phi.at(i, j).abs()) as usize;
                    }
                }
                assert_eq!(reached, nx * ny, "{name} {nx}x{ny}: every cell reached");
                assert!(differ > nx * ny / 2, "{name} {nx}x{ny}: the sweeps set most cells ({differ})");
            }
        }
    }

    /// The sweeps pipelined over strips of columns give the serial sweep's distances bit for
    /// bit, whatever the number of strips and of threads (strips more than threads included,
    /// and strips of one column), and `sweep_distance` on a pool uses strips on a wide grid.
    #[test]
    fn the_sweeps_in_strips_are_the_serial_sweeps_bit_for_bit() {
        for (nx, ny, lx, ly) in [(300, 37, 1.5, 0.6), (61, 24, 1.0, 0.5), (7, 9, 1.0, 0.9)] {
            let grid = Grid::new(nx, ny, lx, ly).unwrap();
            let mut phi = column_phi(&grid);
            phi.extrapolate_ghosts_linear();
            let mut rd = Redistancer::new(&grid, RedistanceSettings::default()).unwrap();
            rd.phi0.assign(&phi);
            rd.find_interface(&grid, Exec::SERIAL);
            let mut want = Field::zeros(&grid, Location::Centre);
            assert!(sweep_distance(&phi, &rd.sub, &grid, &mut want, &mut rd.interface, Exec::SERIAL));
            // the sweeps carry distances across the strips' borders (a strip that read stale
            // values there would differ): cells of the column on the border of two strips are
            // set by them
            let st = want.stride();
            let set = (0..ny).filter(|&j| {
                let c = (HALO + j) * st + HALO + nx / 2;
                want.slice()[c].is_finite() && want.slice()[c] != phi.slice()[c].abs()
            });
            assert!(set.count() > 0, "{nx}x{ny}: the sweeps set cells on the strips' border");
            for threads in [1, 2, 4] {
                let pool = crate::exec::build_pool(threads).unwrap();
                for strips in [1, 2, 3, 5, nx] {
                    let mut got = Field::zeros(&grid, Location::Centre);
                    let exec = Exec::with_threads(threads);
                    assert!(pool.install(|| sweep_distance_in_strips(&phi, &rd.sub, &grid, &mut got, &mut rd.interface, exec, strips)));
                    for k in 0..got.slice().len() {
                        let (a, b) = (got.slice()[k], want.slice()[k]);
                        assert_eq!(a.to_bits(), b.to_bits(), "{nx}x{ny}, {threads} threads, {strips} strips: storage cell {k}: {a} != {b}");
                    }
                }
                let mut got = Field::zeros(&grid, Location::Centre);
                assert!(pool.install(|| sweep_distance(&phi, &rd.sub, &grid, &mut got, &mut rd.interface, Exec::with_threads(threads))));
                assert!(got.slice().iter().zip(want.slice()).all(|(a, b)| a.to_bits() == b.to_bits()), "{nx}x{ny}, {threads} threads");
            }
        }
    }

    #[test]
    fn the_row_kernel_is_the_cell_by_cell_stage_bit_for_bit() {
        let grid = Grid::new(61, 37, 1.0, 0.6).unwrap();
        let settings = RedistanceSettings { band: Some(9.0), ..RedistanceSettings::default() };
        let mut rd = Redistancer::new(&grid, settings).unwrap();
        let mut phi = column_phi(&grid);
        phi.extrapolate_ghosts_linear();
        rd.phi0.assign(&phi);
        rd.find_interface(&grid, Exec::SERIAL);
        rd.freeze_interface(&grid, Exec::SERIAL);
        let fz = rd.frozen.slice().to_vec();
        phi.slice_mut().iter_mut().zip(&fz).for_each(|(p, &f)| {
            if f.is_finite() {
                *p = f
            }
        });
        assert!(sweep_distance(&phi, &rd.sub, &grid, &mut rd.dist, &mut rd.interface, Exec::SERIAL));
        // a reach that leaves cells out, and a source that is not Φ⁰ (a stage in the middle of
        // the iterations)
        let reach = 6.0 * grid.h();
        let mut src = phi.clone();
        src.slice_mut().iter_mut().enumerate().for_each(|(k, p)| *p += 1e-3 * ((k % 7) as f64 - 3.0));
        src.extrapolate_ghosts_linear();
        let other = column_phi(&grid);
        let ctx = Ctx { phi0: &rd.phi0, sub: &rd.sub, frozen: &rd.frozen, dist: &rd.dist, reach, grid: &grid, cfl: 0.5, band: 9.0 * grid.h() };
        let counts = {
            let (p0, d) = (rd.phi0.slice(), rd.dist.slice());
            let iterated = (0..p0.len()).filter(|&k| p0[k] != 0.0 && p0[k].abs() <= ctx.band && d[k] <= reach && !fz[k].is_finite()).count();
            (iterated, fz.iter().filter(|f| f.is_finite()).count(), rd.sub[0].slice().iter().filter(|s| s.is_finite()).count())
        };
        assert!(counts.0 > 100 && counts.1 > 20 && counts.2 > 20, "{counts:?}");
        for (name, base, a, b) in
            [("none", Base::None, 0.0, 1.0), ("other", Base::Other(&other), 0.75, 0.25), ("in place", Base::InPlace, 1.0 / 3.0, 2.0 / 3.0)]
        {
            let mut expected = other.clone();
            ctx.stage_reference(&mut expected, base, a, b, &src);
            for exec in [Exec::SERIAL, Exec { parallel: true }] {
                let mut got = other.clone();
                ctx.stage(&mut got, base, a, b, &src, exec);
                let same = expected.slice().iter().zip(got.slice()).all(|(e, g)| e.to_bits() == g.to_bits());
                assert!(same, "{name}, parallel = {}", exec.parallel);
            }
        }
    }

    #[test]
    fn the_avx2_copy_of_the_row_kernel_is_the_baseline_copy_bit_for_bit() {
        let n = 40;
        let mut rnd = crate::operators::random_rows(17);
        let rows: Vec<Vec<f64>> = (0..17).map(|_| rnd(n + 6)).collect();
        let mut sub: [Vec<f64>; 4] = std::array::from_fn(|d| rows[13 + d][..n].iter().map(|v| 0.2 + v.abs()).collect());
        // sub-cell sides on some cells only (∞ elsewhere), frozen cells, zeros of Φ⁰
        for (d, s) in sub.iter_mut().enumerate() {
            for (i, v) in s.iter_mut().enumerate() {
                if (i + d) % 3 != 0 {
                    *v = f64::INFINITY;
                }
            }
        }
        let frozen: Vec<f64> = (0..n).map(|i| if i % 11 == 5 { 0.3 } else { f64::NAN }).collect();
        let mut p0 = rows[8][..n].to_vec();
        p0[7] = 0.0;
        let dist: Vec<f64> = (0..n).map(|i| if i % 9 == 4 { 50.0 } else { 1.0 }).collect();
        let r = RedistanceRow {
            x: &rows[0][..n + 6],
            y: std::array::from_fn(|m| &rows[1 + m][..n]),
            p0: &p0,
            frozen: &frozen,
            dist: &dist,
            sub: std::array::from_fn(|d| &sub[d][..]),
        };
        let c = StageCoef { a: 0.75, b: 0.25, inv_dx: 7.0, inv_dy: 5.0, inv_dx2: 49.0, inv_dy2: 25.0, dtau_far: 0.05, cfl: 0.5, band: 10.0, reach: 20.0 };
        let base = &rows[12][..n];
        for rb in [RowBase::None, RowBase::InPlace, RowBase::Other(base)] {
            let (mut a, mut b) = (rows[9][..n].to_vec(), rows[9][..n].to_vec());
            redistance_row(&r, c, rb, &mut a);
            redistance_row_base(&r, c, rb, &mut b);
            assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
        }
    }
}
