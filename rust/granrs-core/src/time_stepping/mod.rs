//! Time stepping: the clock (δt, BDF2 coefficients), the momentum predictor, and `step.rs`,
//! the one ordered list of the stages of a time step.

pub mod clock;
pub mod momentum;
pub mod step;

pub use clock::{bdf_coefficients, stable_dt, TimeConfig, DT_CEILING_RECOVERY};
pub use momentum::{MomentumSolver, ViscousScheme};
pub use step::{StepInfo, SPEED_BOUND};
