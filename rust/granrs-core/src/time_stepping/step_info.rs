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
    /// Times the step was rejected (Picard non-convergence) and retaken with δt halved.
    pub retries: usize,
}
