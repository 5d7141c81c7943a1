//! Diagnostics computed from the model's state that are not stages of the step: the mechanical
//! energy budget ([`energy`]).

pub mod energy;

pub use energy::{EnergyBudget, EnergyLedger, EnergyRates};
