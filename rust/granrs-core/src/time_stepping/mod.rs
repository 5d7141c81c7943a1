//! Time stepping: the clock (δt, BDF2 coefficients, the step's floor) and the momentum
//! predictor's solver. The ordered list of the stages of a step is `models/step.rs`.

pub mod clock;
pub mod momentum;
mod step_info;

pub use clock::{bdf_coefficients, stable_dt, TimeConfig, DT_CEILING_RECOVERY, LIGHT_CFL_BAND, SPEED_BOUND};
pub use momentum::{MomentumSolver, ViscousScheme};
pub use step_info::{StageSeconds, StepInfo};
