//! What one step did (returned by `TwoPhaseModel::step`, models/step.rs).

use crate::solvers::SolveInfo;

/// What one step did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepInfo {
    /// δt of the step.
    pub dt: f64,
    /// Time after the step.
    pub time: f64,
    /// Pressure solve (iterations, residual).
    pub pressure: SolveInfo,
    /// Viscous solve of the predictor (0 iterations when explicit).
    pub viscous: SolveInfo,
    /// Pore-pressure solve (0 iterations when not fluidised).
    pub pore: SolveInfo,
    /// max |u|, max |v| after the step.
    pub max_speed: f64,
    /// Advective CFL number δt (max|u|/dx + max|v|/dy) after the step.
    pub cfl: f64,
    /// max |div u| after the projection.
    pub divergence: f64,
    /// Picard iterations of the bi-projection (0 without plastic stress or wall friction).
    pub picard_iterations: usize,
    /// Final increment max |Σ^{k+1} − Σ^k|, max |s^{k+1} − s^k| of the Picard iteration.
    pub picard_increment: f64,
    /// Times the Picard stall safeguard halved r and r_b in the step.
    pub picard_r_halvings: usize,
    /// Proximal restarts of the Picard iteration in the step (`proximal_restarts` is their cap:
    /// a step that reaches it stops on the relaxed fixed point of its last anchor).
    pub picard_restarts: usize,
    /// Times the step was rejected (Picard non-convergence) and retaken with δt halved.
    pub retries: usize,
    /// Cells of the small detached pieces of {Φ > 0} turned to air in the step
    /// (`piece_removal_cells`; 0 without the option).
    pub pieces_removed: usize,
    /// The global mass correction's shift δ of Φ in the step (m; Φ ← Φ + δ moves the interface
    /// by δ along its normal; 0 without the correction).
    pub mass_shift: f64,
    /// Wall time of each stage of the accepted attempt (`std::time::Instant`; a measurement of
    /// this machine, never part of the results).
    pub stage_seconds: StageSeconds,
}

/// Wall time [s] of each stage of one step (`models/step.rs` lists them in order).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StageSeconds {
    /// δt from the CFL rule and the BDF2 coefficients.
    pub choose_dt: f64,
    /// Level-set transport, redistancing and mass correction (paper step 1).
    pub interface: f64,
    /// ρ on faces and η at centres and nodes from Φ (paper step 2).
    pub properties: f64,
    /// The pore-pressure step (paper step 3).
    pub pore_pressure: f64,
    /// Yield stress, wall friction, lagged viscosity and the projections' parameters r, r_b.
    pub rheology: f64,
    /// The predictor's right-hand side (convection, pressure force, BDF2 history).
    pub predictor_setup: f64,
    /// The viscous solves of the predictor (every Picard iteration's).
    pub predictor_solves: f64,
    /// The plastic, Coulomb-wall and side-wall projections of the Picard loop (their forces,
    /// the strain rate they read and their updates).
    pub projections: f64,
    /// The pressure projection and the gauge (paper step 5).
    pub pressure_projection: f64,
    /// The checks after the predictor and the step, and the energy budget's accounting.
    pub diagnostics: f64,
}

impl StageSeconds {
    /// The sum of the stages.
    pub fn total(&self) -> f64 {
        self.choose_dt
            + self.interface
            + self.properties
            + self.pore_pressure
            + self.rheology
            + self.predictor_setup
            + self.predictor_solves
            + self.projections
            + self.pressure_projection
            + self.diagnostics
    }
}
