//! The one error type of the granrs core. The binding crate maps each variant to a Python
//! exception class (`granrs.ParameterError`, `granrs.SolverError`, `granrs.SimulationError`).

use thiserror::Error;

/// Everything the core can fail with.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum Error {
    /// A parameter is outside its allowed range. `name` is the public name of the parameter
    /// (the same in Rust, Python and the docs), `allowed` says which values are accepted.
    #[error("invalid parameter `{name}` = {value}: allowed {allowed}")]
    InvalidParameter { name: String, value: String, allowed: String },

    /// An array has the wrong shape.
    #[error("array `{name}` has shape {got:?}, expected {expected:?}")]
    Shape { name: String, got: Vec<usize>, expected: Vec<usize> },

    /// An iterative solver did not reach its tolerance.
    #[error("{solver} did not converge: relative residual {residual:.3e} after {iterations} iterations (tolerance {tolerance:.1e})")]
    NotConverged { solver: String, iterations: usize, residual: f64, tolerance: f64 },

    /// A linear solver failed for another reason (singular matrix, factorisation failure).
    #[error("{solver} failed: {message}")]
    SolverFailure { solver: String, message: String },

    /// A simulation blew up or left its domain of validity: says what, where and when.
    #[error("simulation stopped at step {step}, t = {time:.6e} s: {what}{}", location.map(|(i, j)| format!(" at cell (i={i}, j={j})")).unwrap_or_default())]
    Simulation { what: String, step: u64, time: f64, location: Option<(usize, usize)> },

    /// The Picard iteration of the bi-projection (eq. 12) did not reach its tolerance within its
    /// cap. A step with retries (`TimeConfig::step_retries`) is retaken with δt halved on this
    /// error; the step that fails for good reports it as [`Error::Simulation`] with the same
    /// message ([`Error::into_reported`]).
    #[error("simulation stopped at step {step}, t = {time:.6e} s: {what}")]
    PicardNotConverged { what: String, step: u64, time: f64 },

    /// The advective CFL number after a step exceeded `TimeConfig::cfl_abort`: the flow
    /// accelerated through a δt chosen from the speeds before the step. A step with retries is
    /// retaken with δt halved on this error, as on [`Error::PicardNotConverged`]; the step that
    /// fails for good reports it as [`Error::Simulation`] ([`Error::into_reported`]).
    #[error("simulation stopped at step {step}, t = {time:.6e} s: {what}{}", location.map(|(i, j)| format!(" at cell (i={i}, j={j})")).unwrap_or_default())]
    CflExceeded { what: String, step: u64, time: f64, location: Option<(usize, usize)> },

    /// A linear solver failed during a step: the solver's own error ([`Error::NotConverged`] or
    /// [`Error::SolverFailure`]) with the step and time (Python: `granrs.SolverError`).
    #[error("simulation stopped at step {step}, t = {time:.6e} s: {source}")]
    SolverInStep { step: u64, time: f64, source: Box<Error> },
}

/// Result alias used throughout the core.
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// Shorthand for [`Error::InvalidParameter`].
    pub fn param(name: &str, value: impl std::fmt::Display, allowed: &str) -> Self {
        Error::InvalidParameter { name: name.to_string(), value: value.to_string(), allowed: allowed.to_string() }
    }

    /// A solver's error raised during step `step` at time `time`: [`Error::SolverInStep`] for
    /// [`Error::NotConverged`] and [`Error::SolverFailure`], any other error unchanged.
    pub fn in_step(self, step: u64, time: f64) -> Self {
        match self {
            Error::NotConverged { .. } | Error::SolverFailure { .. } => Error::SolverInStep { step, time, source: Box::new(self) },
            other => other,
        }
    }

    /// The error as a step reports it: a Picard non-convergence or a CFL number above the limit
    /// becomes [`Error::Simulation`] (the same message), every other error is unchanged.
    pub fn into_reported(self) -> Self {
        match self {
            Error::PicardNotConverged { what, step, time } => Error::Simulation { what, step, time, location: None },
            Error::CflExceeded { what, step, time, location } => Error::Simulation { what, step, time, location },
            other => other,
        }
    }

    /// Whether a step that failed with this error is retaken with δt halved (with the adaptive
    /// rule and retries left, `TimeConfig::step_retries`): a Picard non-convergence or a CFL
    /// number above `cfl_abort`.
    pub fn retakes_step(&self) -> bool {
        matches!(self, Error::PicardNotConverged { .. } | Error::CflExceeded { .. })
    }
}

/// Checks that `value` is finite and strictly positive.
pub fn check_positive(name: &str, value: f64) -> Result<()> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(Error::param(name, value, "a finite number > 0"))
    }
}

/// Checks that `value` is finite and non-negative.
pub fn check_non_negative(name: &str, value: f64) -> Result<()> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(Error::param(name, value, "a finite number >= 0"))
    }
}

/// Checks that `value` is finite and in the closed interval `[lo, hi]`.
pub fn check_range(name: &str, value: f64, lo: f64, hi: f64) -> Result<()> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(())
    } else {
        Err(Error::param(name, value, &format!("a finite number in [{lo}, {hi}]")))
    }
}

/// Checks that `value` is finite.
pub fn check_finite(name: &str, value: f64) -> Result<()> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(Error::param(name, value, "a finite number"))
    }
}
