//! Shared configurations of the integration tests.

use granrs_core::grid::{BoundaryConditions, Grid, Side, VelocityBc};
use granrs_core::levelset::Shape;
use granrs_core::models::{Material, ModelConfig, TwoPhaseModel};
use granrs_core::rheology::{RheologyConfig, RheologyLaw};

pub const AIR: Material = Material { density: 1.2, viscosity: 1.8e-5 };
pub const BEADS: Material = Material { density: 1450.0, viscosity: 0.1 };

/// The column case in miniature: D-P beads (φρ_s = 1450, α = 27°, η_s = 0.1) under air in a
/// channel of nx × ny cells and height 0.45 m, with Coulomb base and back wall (α_b = 15°),
/// free-slip right side and lid, adaptive δt.
pub fn column_config(nx: usize, ny: usize) -> ModelConfig {
    let (lx, ly) = (nx as f64 * 0.45 / ny as f64, 0.45);
    let grid = Grid::new(nx, ny, lx, ly).unwrap();
    let bc = BoundaryConditions::uniform(VelocityBc::FreeSlip).with(Side::Left, VelocityBc::Coulomb).with(Side::Bottom, VelocityBc::Coulomb);
    let mut cfg = ModelConfig::single_phase(grid, bc, BEADS);
    cfg.light = Some(AIR);
    cfg.gravity = [0.0, -9.81];
    cfg.rheology = RheologyConfig::new(RheologyLaw::DruckerPrager { friction_angle: 27.0 });
    cfg.rheology.wall_friction_angle = Some(15.0);
    cfg.rheology.picard_tol = 1e-3;
    cfg.rheology.theta = 0.8;
    cfg
}

/// A model of `cfg` with the 0.1 m × 0.2 m column released at rest, pressure balanced.
pub fn released_column(cfg: ModelConfig) -> TwoPhaseModel {
    let mut m = TwoPhaseModel::new(cfg).unwrap();
    m.set_shape(&Shape::Rectangle { x0: -1.0, x1: 0.1, y0: -1.0, y1: 0.2 }).unwrap();
    m.initialise_pressure().unwrap();
    m
}
