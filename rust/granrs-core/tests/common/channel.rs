//! The Bingham channel of the step tests: plane Poiseuille flow started from rest by the body
//! force G = 1 (channel 0 < y < 2 on 4 × 16 cells, ρ = 1, μ = 0.01, τ_y = 0.2, outflow sides),
//! θ = 0.5, a constant r = 0.5 and a Picard cap of `cap` iterations at tolerance 1e-8.

use granrs_core::grid::{BoundaryConditions, Grid, Side, VelocityBc};
use granrs_core::models::{Material, ModelConfig};
use granrs_core::rheology::{RheologyConfig, RheologyLaw};

pub fn bingham_channel(cap: usize, retries: usize, fixed_dt: Option<f64>) -> ModelConfig {
    let n = 16;
    let dy = 2.0 / n as f64;
    let grid = Grid::new(4, n, 4.0 * dy, 2.0).unwrap();
    let bc = BoundaryConditions::uniform(VelocityBc::NoSlip).with(Side::Left, VelocityBc::Outflow).with(Side::Right, VelocityBc::Outflow);
    let mut cfg = ModelConfig::single_phase(grid, bc, Material { density: 1.0, viscosity: 0.01 });
    cfg.gravity = [1.0, 0.0];
    cfg.time.fixed_dt = fixed_dt;
    cfg.time.cfl_abort = 100.0;
    cfg.time.step_retries = retries;
    cfg.rheology = RheologyConfig::new(RheologyLaw::Bingham { yield_stress: 0.2 });
    cfg.rheology.theta = 0.5;
    cfg.rheology.picard_tol = 1e-8;
    cfg.rheology.picard_max_iterations = cap;
    cfg.rheology.r = Some(0.5);
    cfg
}
