//! Time-step selection and BDF2 coefficients for variable steps.
//!
//! Adaptive δt (Kang, Fedkiw & Liu 2000, *J. Sci. Comput.* 15, eq. 31, without surface tension):
//!
//!   δt = 2 C_cfl / (C + √(C² + 4 F)),   C = max|u|/dx + max|v|/dy (+ 2ν_max(1/dx² + 1/dy²) if the
//!   viscous term is explicit),   F = |g| / min(dx, dy),
//!
//! capped by `max_dt` and by a growth factor per step (zero-stability of variable-step BDF2 needs
//! ω = δt_n/δt_{n−1} < 1 + √2; Grigorieff 1983). BDF2 with variable steps:
//!
//!   (a₀ u^{n+1} − a₁ u^n + a₂ u^{n−1})/δt_n,   a₀ = (1+2ω)/(1+ω), a₁ = 1+ω, a₂ = ω²/(1+ω),
//!
//! and the second-order extrapolation u* = (1+ω) u^n − ω u^{n−1}. ω = 1 gives the paper's 3/2, 2, 1/2.
//!
//! **A light phase with its own CFL number** (`cfl_light`, off by default). Once a collapse has
//! set the air going, the air far from the grains can move faster than anything near them (the
//! column at ny = 256 on its open window at t = 1.5 s: 2.7 m/s in the air 49 cells above the
//! reservoir, 0.94 m/s in the grains), and C sets the step from the air. With `cfl_light` the
//! rule takes the smaller of the step with C_cfl at the speeds of the faces next to a cell with
//! Φ > −[`LIGHT_CFL_BAND`]·h (the dense phase, its smoothed band and the WENO5 stencils across
//! it) and the step with `cfl_light` at the speeds everywhere: the grains and the interface keep
//! the CFL number C_cfl, the air beyond is advanced at up to `cfl_light`, a stability bound
//! rather than an accuracy one (WENO5 with TVD-RK3 for Φ, WENO5 with the extrapolated BDF2
//! convection for u; `cfl_abort` still guards every step). It changes the answer by the time
//! step's error, not by round-off (docs/benchmarks.md, "What options cost").
//!
//! **Rejected steps.** With the adaptive rule, a step whose Picard iteration (eq. 12) does not
//! converge, or whose advective CFL number after the step exceeds `cfl_abort` (the rule chose δt
//! from the speeds before the step, and the flow accelerated through it), is rejected: the state
//! before it is restored, a ceiling δt_max' = δt/2 is set and the step is taken again (at most
//! `step_retries` times). The ceiling then recovers by the factor
//! [`DT_CEILING_RECOVERY`] per accepted step, so a run settles near the largest step its
//! bi-projection handles instead of failing there (the column at ny = 256 failed at step 7 with
//! δt = 1.19 ms and ran with δt ≤ 0.5 ms).

use crate::error::{Error, Result};
use crate::options::{self, Configurable, OptionSpec, Value};

/// How the time step is chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeConfig {
    /// CFL number C_cfl for the adaptive step.
    pub cfl: f64,
    /// CFL number of the adaptive step for the light phase away from the dense one (None: C_cfl
    /// everywhere; see the module docs).
    pub cfl_light: Option<f64>,
    /// A fixed time step (the adaptive rule is then only used to detect CFL violations).
    pub fixed_dt: Option<f64>,
    /// Largest allowed step.
    pub max_dt: f64,
    /// Largest ratio δt_n/δt_{n−1}.
    pub max_growth: f64,
    /// A run stops with an error when the advective CFL number after a step exceeds this (with
    /// the adaptive rule, once the step's retries are spent).
    pub cfl_abort: f64,
    /// Rejections of one step (Picard non-convergence or CFL above `cfl_abort` → δt halved and
    /// the step retaken) before the run stops; 0: none. Only with the adaptive rule (a fixed δt
    /// is never changed).
    pub step_retries: usize,
}

/// The options of [`TimeConfig`] (the simulation's clock).
pub const TIME_OPTIONS: &[OptionSpec] = &[
    options::float("time", "cfl", 0.5, 1e-6, 2.0, "1", "CFL number C_cfl of the adaptive step"),
    options::float("time", "cfl_light", 0.9, 1e-6, 2.0, "1", "CFL number of the adaptive step for the light phase more than 6 cells from the dense phase, which keeps cfl (None: cfl everywhere)")
        .open(true, false)
        .off_by_default(),
    options::float("time", "dt", 1.0, 0.0, f64::INFINITY, "s", "a fixed time step instead of the adaptive one (None: adaptive)")
        .open(true, true)
        .off_by_default(),
    options::float("time", "max_dt", f64::INFINITY, 0.0, f64::INFINITY, "s", "largest step of the adaptive rule").open(true, false),
    options::float("time", "max_growth", 1.2, 1.0, 2.4, "1", "largest ratio δt_n/δt_{n−1} (variable-step BDF2 is zero-stable below 1 + √2)"),
    options::float("time", "cfl_abort", 1.0, 1e-6, 100.0, "1", "the run stops with an error when the advective CFL number after a step exceeds this (adaptive δt: once step_retries retakes with δt halved are spent)"),
    options::int(
        "time",
        "step_retries",
        3,
        0,
        20,
        "1",
        "rejections of a step whose Picard iteration does not converge or whose CFL number ends above cfl_abort (retaken with δt halved; adaptive δt only); 0: stop at once",
    ),
];

/// With `cfl_light`, the faces next to a cell with Φ > −LIGHT_CFL_BAND·h keep C_cfl: the dense
/// phase, the smoothed band 2ε = 3h of its properties and the three cells of the WENO5 stencils
/// that transport Φ and the momentum across it.
pub const LIGHT_CFL_BAND: f64 = 6.0;

/// Growth per accepted step of the δt ceiling a rejected step leaves (see the module docs): the
/// ceiling is back at the rejected δt after ln 2 / ln 1.01 ≈ 70 steps.
pub const DT_CEILING_RECOVERY: f64 = 1.01;

impl Default for TimeConfig {
    fn default() -> Self {
        let o = |k| options::spec(TIME_OPTIONS, k);
        TimeConfig {
            cfl: o("cfl").float(),
            cfl_light: None,
            fixed_dt: None,
            max_dt: o("max_dt").float(),
            max_growth: o("max_growth").float(),
            cfl_abort: o("cfl_abort").float(),
            step_retries: o("step_retries").usize(),
        }
    }
}

impl Configurable for TimeConfig {
    fn options() -> &'static [OptionSpec] {
        TIME_OPTIONS
    }

    fn get(&self, key: &str) -> Value {
        match key {
            "cfl" => Value::Float(self.cfl),
            "cfl_light" => Value::opt_f64(self.cfl_light),
            "dt" => Value::opt_f64(self.fixed_dt),
            "max_dt" => Value::Float(self.max_dt),
            "max_growth" => Value::Float(self.max_growth),
            "cfl_abort" => Value::Float(self.cfl_abort),
            "step_retries" => Value::Int(self.step_retries as i64),
            _ => Value::None,
        }
    }

    fn set(&mut self, key: &str, v: &Value) -> Result<()> {
        match key {
            "cfl" => self.cfl = v.as_f64().unwrap_or(self.cfl),
            "cfl_light" => self.cfl_light = v.as_f64(),
            "dt" => self.fixed_dt = v.as_f64(),
            "max_dt" => self.max_dt = v.as_f64().unwrap_or(self.max_dt),
            "max_growth" => self.max_growth = v.as_f64().unwrap_or(self.max_growth),
            "cfl_abort" => self.cfl_abort = v.as_f64().unwrap_or(self.cfl_abort),
            "step_retries" => self.step_retries = options::as_usize(v),
            _ => {}
        }
        Ok(())
    }
}

impl TimeConfig {
    /// Checks the parameters against [`TIME_OPTIONS`], naming the offending one.
    pub fn validate(&self) -> Result<()> {
        options::validate_all(self)?;
        match self.cfl_light {
            Some(c) if c > self.cfl_abort => {
                let range = options::spec(TIME_OPTIONS, "cfl_light").allowed();
                Err(Error::param(
                    "time.cfl_light",
                    c,
                    &format!("{range} and at most time.cfl_abort = {} (a step at cfl_light would be rejected)", self.cfl_abort),
                ))
            }
            _ => Ok(()),
        }
    }
}

/// A flow faster than this many times its reference speed (the free-fall speed over the domain,
/// √(2|g|(Lx + Ly)), or the largest prescribed boundary speed) is a blow-up: the adaptive step
/// collapses below the CFL step at that speed. The default column stays below the reference
/// speed itself (ny = 32: max|u| = 2.2 m/s dry and 2.4 m/s fluidised, against
/// √(2g(Lx + Ly)) = 8.9 m/s for its 3.6 m × 0.45 m box), some 400 times below the bound.
pub const SPEED_BOUND: f64 = 100.0;

/// Variable-step BDF2 coefficients (a₀, a₁, a₂) and the extrapolation weight ω for the step
/// `dt` following `dt_prev` (None: first step, BDF1).
pub fn bdf_coefficients(dt: f64, dt_prev: Option<f64>) -> (f64, f64, f64, f64) {
    match dt_prev {
        None => (1.0, 1.0, 0.0, 0.0),
        Some(prev) => {
            let w = dt / prev;
            ((1.0 + 2.0 * w) / (1.0 + w), 1.0 + w, w * w / (1.0 + w), w)
        }
    }
}

/// The stable step of the adaptive rule (before caps).
pub fn stable_dt(cfl: f64, umax: f64, vmax: f64, dx: f64, dy: f64, gravity: f64, nu_explicit: f64) -> f64 {
    let c = umax / dx + vmax / dy + 2.0 * nu_explicit * (1.0 / (dx * dx) + 1.0 / (dy * dy));
    let f = gravity.abs() / dx.min(dy);
    let denom = c + (c * c + 4.0 * f).sqrt();
    if denom > 0.0 {
        2.0 * cfl / denom
    } else {
        f64::INFINITY
    }
}
