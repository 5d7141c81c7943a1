//! # granrs-core
//!
//! Pure-Rust core of granrs: a 2D MAC-grid solver for dense granular flows fluidised by pore gas
//! pressure, after Aravena, Chupin, Dubois & Roche, *Fluidisation by pore pressure of dense
//! granular flows: numerical simulations versus experiments*. No Python here: `cargo test` and
//! `cargo bench` run on their own; the `granrs-py` crate binds this to Python.
//!
//! ## Where each equation is discretised
//!
//! The paper's equations (Aravena et al. §2.4 and §3.1) and the file and function that
//! discretise each; every such file opens with its equation.
//!
//! | equation | what | file | function |
//! |---|---|---|---|
//! | (10a) | ∂_t Φ + u·∇Φ = 0 (step 1, WENO5 + TVD-RK3) | `levelset/stage.rs`, `levelset/transport.rs` | [`levelset::Interface::advance`], [`levelset::LevelSetTransport::advect`] |
//! | (10b) | momentum: ρ(∂_t u + u·∇u) + ∇(p + p_f) = ρg + div(2ηD) + div(τΣ) | `models/step.rs`, `time_stepping/momentum.rs` | `TwoPhaseModel::predictor`, [`time_stepping::MomentumSolver::solve_implicit`] |
//! | (10c) | div u = 0 | `projection/stage.rs`, `projection/mod.rs` | [`projection::PressureStage::project`], [`projection::PressureProjection::project`] |
//! | (10d) | Σ = P(Σ + r D(u)), the plastic projection | `rheology/plastic.rs` | [`rheology::PlasticState::update`] |
//! | (10e) | σ_t = τ_b s, s = P_b(s − r_b u_t), the Coulomb walls | `walls/mod.rs` | [`walls::CoulombWalls::update`] |
//! | (10f) | ∂_t p_f + div(u p_f) = div(κ(Φ)∇p_f) (step 3) | `pore_pressure/mod.rs` | [`pore_pressure::PorePressure::advance`] |
//! | (10a), mass | the optional global mass correction Φ ← Φ + δ, \|{Φ > 0}\| = A_ref (after step 1); with `mass_correction_film` = a, Φ ← Φ + δ w sparing films thinner than a cells | `levelset/stage.rs`, `levelset/film.rs` | [`levelset::Interface::correct_mass`], [`levelset::FilmWeight`] |
//! | (10a), volume | with `interface_transport = "clsvof"`: ∂_t F + ∇·(uF) − c∇·u = 0, c = H(Fⁿ − ½), the dense volume fraction by split PLIC fluxes (conservative), then Φ rebuilt as the distance to F's interface (after step 1's transport) | `levelset/vof.rs`, `levelset/stage.rs` | [`levelset::VolumeFraction::transport`], [`levelset::VolumeFraction::rebuild_level_set`] |
//! | (10a), pieces | the optional removal of the regions of {Φ > 0} of at most N cells other than the largest (after the mass correction; not in the paper) | `levelset/pieces.rs` | [`levelset::Interface::remove_pieces`] |
//! | step 2 | ρ(Φ), η(Φ) from Φ^{n+1} | `properties/mod.rs` | [`properties::MaterialProperties::update`] ([`properties::PropertyLaws`]) |
//! | step 2 | τ(Φ), τ_b, r, r_b, the lagged viscosity of μ(I) | `rheology/stage.rs` | [`rheology::stage::RheologyState::prepare`] |
//! | (11) | the predictor ũ^{n+1} with Σ^{n+1}, s^{n+1} (step 4, BDF2) | `models/step.rs`, `models/rheology_stage.rs` | `TwoPhaseModel::predictor`, `TwoPhaseModel::momentum_solve` |
//! | (12) | the Picard iteration of the bi-projection (pseudo-relaxation θ) | `rheology/stage.rs` | [`rheology::stage::RheologyState::bi_projection`] |
//! | step 5 | the pressure projection: a₀ρ(u^{n+1} − ũ)/δt + ∇δp = 0, div u^{n+1} = 0 | `projection/stage.rs` (two-phase: `projection/mod.rs`, granular-only: `projection/free_surface.rs`) | [`projection::PressureStage::project`] ([`projection::PressureProjection::project`], [`projection::free_surface::FreeSurfaceProjection::project`]) |
//!
//! The order of the stages of a step (steps 1–5 of the paper) is stated once, in `models/step.rs`.
//!
//! ## Rooms and floors
//!
//! One folder per concept, the paper's names. A room imports only rooms on a lower floor, or
//! rooms of its own floor without a cycle, and the files inside a room import each other without
//! a cycle (mod.rs, the room's front, is only ever imported); `scripts/check_layers.py` checks
//! both in CI. Each physics room owns its state and its stage of a step (a method with explicit
//! inputs and outputs); the model holds the rooms and the shared fields, and `models/step.rs`
//! alone calls the stages. Checkpoints and the active window reach a room's state through
//! [`grid::StateArrays`] and [`grid::WindowState`], never through its fields:
//!
//! 5. [`models`]: the two-phase model (its configuration, the shared fields and the rooms'
//!    states, `step.rs`: the one ordered list of the stages of a step and the rejected-step
//!    rule, the inputs of the rheology's stages, checkpoints, the active window, the energy
//!    budget, the memory estimate) and the depth-averaged model;
//! 4. [`time_stepping`]: clock (δt, BDF2 coefficients, the step's floor), the momentum
//!    predictor's viscous solver, what a step did (with the wall time of each stage);
//! 3. physics rooms: [`levelset`] (the interface stage: transport, redistancing, the mass
//!    correction, the conserved volume fraction; smoothed Heaviside and material laws), [`properties`] (ρ on the faces, η at
//!    centres and nodes: their state and step 2's stage), [`pore_pressure`], [`projection`] (the
//!    pressure projections and their stage), [`rheology`] (laws, the plastic projection, the
//!    room's state with its preparation and the bi-projection of eq. 12), [`walls`] (Coulomb and side-wall friction),
//!    [`plasticity`] (what rheology and walls share: the unit-ball projection, the increment of
//!    a projected field, the interface blending of yield and friction), [`diagnostics`] (the
//!    energy budget's terms);
//! 2. [`operators`] (staggered differences, interpolations, WENO5, strain rate, viscous
//!    operator) and [`solvers`] (multigrid-preconditioned CG, sparse Cholesky);
//! 1. [`grid`]: the grid, MAC locations, fields with halos, boundary conditions, the rooms' state
//!    interfaces (`StateArrays`, `WindowState`);
//! 0. [`error`], [`exec`] (the execution policy: serial or the model's rayon pool) and
//!    [`options`] (the options schema: each option's spec, its validation, key → value maps).

pub mod diagnostics;
pub mod error;
pub mod exec;
pub mod grid;
pub mod levelset;
pub mod models;
pub mod operators;
pub mod options;
pub mod plasticity;
pub mod pore_pressure;
pub mod projection;
pub mod properties;
pub mod rheology;
pub mod solvers;
pub mod time_stepping;
pub mod walls;

pub use error::{Error, Result};
pub use exec::Exec;
pub use grid::{BoundaryConditions, Field, Grid, Location, PressureBc, Side, VelocityBc, HALO};

/// The crate version (the Python package reports the same).
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
