//! Models: the state and configuration of a simulation, and what one step of it does.
//!
//! [`TwoPhaseModel`] is the paper's unified model (eq. 10): one velocity and pressure on the
//! whole domain, a level set Φ separating the dense phase (Φ > 0) from the light one (Φ < 0).
//! A single-phase flow is the same model with no light phase (the level set is not transported).
//!
//! [`DepthAveragedModel`] is the cheap rung of the ladder: a Savage–Hutter shallow layer along the
//! channel with a depth-averaged pore pressure (`depth_averaged.rs`, docs/models.md).

pub mod active_region;
mod checkpoint;
pub mod depth_averaged;
mod energy;
pub mod memory;
mod rest;
mod rheology_stage;
mod step;
mod two_phase;
mod window;

pub use crate::grid::StateEntry;
pub use active_region::{ActiveRegion, WindowSides};
pub use depth_averaged::{DepthAveragedConfig, DepthAveragedModel, DepthAveragedPore, EarthPressure, PoreTransport};
pub use memory::available_memory;
pub use two_phase::{ConvectionScheme, Material, ModelConfig, PressureGauge, TwoPhaseModel};
