//! The level-set room: the interface between the granular (dense) phase and the air
//! (paper §2.4; steps 1–2 of the time scheme, §3.1).
//!
//! Φ > 0 in the dense phase, Φ < 0 in the air, Φ = signed distance at t = 0.
//!
//! | file | equation | reference |
//! |------|----------|-----------|
//! | [`weno5`] | one-sided WENO5 derivatives Φ_x^± | Jiang & Shu 1996; Jiang & Peng 2000 |
//! | [`transport`] | ∂Φ/∂t + u·∇Φ = 0 (10a), TVD-RK3 + upwind WENO5 | Shu & Osher 1988 |
//! | [`redistance`] | ∂Φ/∂τ + S(Φ⁰)(\|∇Φ\| − 1) = 0 with a frozen subcell band | Sussman, Smereka & Osher 1994; Russo & Smereka 2000; Chopp 2001; Min 2010 |
//! | [`extension`] | ∇u_ext·∇Φ = 0 below Φ = d h: the transport velocity extended from the dense phase (option) | Adalsteinsson & Sethian 1999 |
//! | [`pieces`] | regions of {Φ > 0} of at most N cells, other than the largest, turned to air after the transport (option) | — (granrs's own; docs/validation.md, "Arrest of the deposit") |
//! | [`film`] | Φ ← Φ + δ w, w = min(1, max(0, M/h − a)): the global mass correction that leaves films thinner than a cells alone (option) | — (granrs's own; docs/validation.md, "Arrest of the deposit") |
//! | [`vof`] | ∂F/∂t + ∇·(uF) − c∇·u = 0, c = H(Fⁿ − ½): the dense volume fraction by direction-split geometric (PLIC) fluxes, conservative to round-off; Φ rebuilt as the distance to F's interface (`interface_transport = "clsvof"`) | Weymouth & Yue 2010; Scardovelli & Zaleski 2000; Sussman & Puckett 2000 |
//! | [`shapes`] | exact signed distances of the initial shapes | — |
//! | [`stage`] | the room's stage of a step: transport, redistancing and the optional mass correction (step 1) | paper §3.1 |
//! | [`heaviside`](mod@heaviside) | H_ε, δ_ε, ρ(Φ), η(Φ) (harmonic), blends for κ, τ, τ_b | paper §2.4 |
//! | [`diagnostics`] | dense-phase area, symmetric difference, eikonal error | — |
//! | [`validation`] | Zalesak disk, Rider–Kothe vortex | docs/reference-data.md, "Level-set transport" |
//!
//! Typical use inside a time step (the order lives in `models/step.rs`):
//!
//! ```
//! use granrs_core::{Exec, Field, Grid, Location};
//! use granrs_core::levelset::{init_signed_distance, LevelSetTransport, Redistancer,
//!     RedistanceSettings, Shape, stable_dt, dense_area};
//! let grid = Grid::new(64, 32, 2.0, 1.0).unwrap();
//! let mut phi = Field::zeros(&grid, Location::Centre);
//! init_signed_distance(&Shape::Rectangle { x0: -1.0, x1: 0.4, y0: -1.0, y1: 0.8 }, &grid, &mut phi).unwrap();
//! let u = Field::from_fn(&grid, Location::XFace, |_, _| 1.0);
//! let v = Field::zeros(&grid, Location::YFace);
//! let mut transport = LevelSetTransport::new(&grid);
//! let mut redistancer = Redistancer::new(&grid, RedistanceSettings::default()).unwrap();
//! let dt = stable_dt(&u, &v, &grid, 0.5, Exec::SERIAL).unwrap();
//! for step in 1..=20 {
//!     transport.advect(&mut phi, &u, &v, &grid, dt, Exec::SERIAL).unwrap();
//!     if step % 10 == 0 {
//!         redistancer.redistance(&mut phi, &grid, Exec::SERIAL).unwrap();
//!     }
//! }
//! let area = dense_area(&phi, &grid, Exec::SERIAL);
//! assert!((area - (0.4 + 20.0 * dt) * 0.8).abs() < 5e-3);
//! ```

mod closest_point;
pub mod diagnostics;
pub mod extension;
pub mod film;
pub mod heaviside;
pub mod pieces;
pub mod redistance;
pub mod shapes;
pub mod stage;
pub mod subcell;
pub mod transport;
pub mod validation;
pub mod vof;
pub use crate::operators::weno5;

pub use diagnostics::{dense_area, dense_area_refined, eikonal_error, interface_points, symmetric_difference_area, EikonalError};
pub use extension::VelocityExtension;
pub use film::FilmWeight;
pub use heaviside::{blend, blend_harmonic, default_eps, dirac, heaviside, map_centre_field, TwoPhaseProperties, DEFAULT_EPS_CELLS};
pub use pieces::DetachedPieces;
pub use redistance::{InterfaceTreatment, RedistanceInfo, RedistanceSettings, Redistancer, KINK_RATIO};
pub use shapes::{init_signed_distance, Shape};
pub use stage::{Interface, TransportVelocity};
pub use subcell::{interface_diagonal, interface_faces, interface_fraction, THETA_MIN};
pub use transport::{cfl_number, max_transport_rate, stable_dt, LevelSetTransport, DEFAULT_CFL};
pub use validation::{single_vortex, single_vortex_with, zalesak, zalesak_with, CaseOptions, LevelSetMetrics};
pub use vof::{
    fraction_volume, heaviside_inverse, plic_alpha, plic_area, swept_volume, InterfaceTransport, PlicNormal, VolumeBudget, VolumeFraction, THIN_ZONE_CELLS,
};
pub use weno5::WenoWeights;
