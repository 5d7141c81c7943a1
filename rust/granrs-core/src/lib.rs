//! # granrs-core
//!
//! Pure-Rust core of granrs: a 2D MAC-grid solver for dense granular flows fluidised by pore gas
//! pressure, after Aravena, Chupin, Dubois & Roche, *Fluidisation by pore pressure of dense
//! granular flows: numerical simulations versus experiments*. No Python here: `cargo test` and
//! `cargo bench` run on their own; the `granrs-py` crate binds this to Python.
//!
//! Rooms (one folder per concept, the paper's names):
//! - [`grid`]: the grid, MAC locations, fields with halos, boundary conditions;
//! - [`operators`]: staggered differences, interpolations, divergence/gradient, strain rate, viscous operator;
//! - [`solvers`]: multigrid-preconditioned CG and faer sparse Cholesky for the pressure equation;
//! - [`levelset`]: WENO5 + TVD-RK3 transport, redistancing, smoothed Heaviside and material laws;
//! - [`pore_pressure`]: advection–diffusion of the pore gas pressure p_f and its boundary conditions;
//! - [`projection`]: the variable-density pressure projection;
//! - [`rheology`]: Newtonian, Bingham, Drucker–Prager and μ(I) laws; `plastic.rs`, the plastic
//!   projection Σ = P(Σ + r D(u)) and its Picard iteration (the bi-projection scheme);
//! - [`walls`]: Coulomb friction walls (the friction projection s = P_b(s − r_b u_t));
//! - [`time_stepping`]: clock, CFL, and `step.rs`, the one ordered list of the stages of a step;
//! - [`models`]: the two-phase model that owns the state and takes one step;
//! - [`diagnostics`]: what is measured on the state, not a stage of the step (the energy budget).

pub mod diagnostics;
pub mod error;
pub mod exec;
pub mod grid;
pub mod levelset;
pub mod models;
pub mod operators;
pub mod pore_pressure;
pub mod projection;
pub mod rheology;
pub mod solvers;
pub mod time_stepping;
pub mod walls;

pub use error::{Error, Result};
pub use exec::Exec;
pub use grid::{BoundaryConditions, Field, Grid, Location, PressureBc, Side, VelocityBc, HALO};

/// The crate version (the Python package reports the same).
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
