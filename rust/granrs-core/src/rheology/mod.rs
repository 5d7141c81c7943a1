//! Viscoplastic rheologies of the granular (dense) phase (Aravena et al. §2.2, eq. 3–7; §2.4).
//!
//! The deviatoric stress splits into a viscous and a plastic part (eq. 5–7):
//!
//!   T = 2 η(|D|, p) D(u) + τ Σ,   Σ = P(Σ + r D(u))   (r > 0),
//!
//! with the tensor norm |λ| = √(½ Σᵢⱼ λᵢⱼ²) (simple shear u(y): |D| = |u'|/2, so the shear
//! stress is η u' + τ sign(u')), P the orthogonal projection on the unit ball of symmetric
//! traceless tensors, and, in the two-phase model, τ(Φ) = τ H_ε(Φ + s ε) (only the dense phase
//! yields), with the shift s of [`InterfaceYield`]: 0 is the paper's τ(Φ) = tan(α) p H_ε(Φ)
//! (§2.4, the default), 1 puts the whole smoothed jump on the air side, so that every cell the
//! density counts as granular (Φ > 0) has its full Coulomb ratio τ/p = tan α, and 2 gives it to
//! the whole band that carries granular weight (Φ > −ε).
//!
//! | law | yield stress τ | viscosity η of the dense phase |
//! |---|---|---|
//! | [`RheologyLaw::Newtonian`] | 0 | `dense.viscosity` |
//! | [`RheologyLaw::Bingham`] | `yield_stress` τ_y | `dense.viscosity` |
//! | [`RheologyLaw::DruckerPrager`] (the paper's D-P model) | tan(α) p⁺ | `dense.viscosity` (η_s constant) |
//! | [`RheologyLaw::MuI`] (eq. 3–5, Jop, Forterre & Pouliquen 2006) | μ_s p⁺ | `dense.viscosity` + (μ₂ − μ_s) p⁺ / (2|D| + (I₀/d)√(p⁺/ρ_s)) |
//!
//! p is the model pressure p^n (the solid pressure of the granular phase; a pore pressure will be
//! subtracted by the pore-pressure room). Its gauge must be fixed (an outflow side, p = 0, as the
//! paper's open top) for p⁺ to mean anything. In the μ(I) law `dense.viscosity` is a small
//! background viscosity that keeps the viscous operator definite where p → 0 (free surface);
//! the variable viscosity is lagged (evaluated with u^n).
//!
//! How the yield stress is imposed ([`YieldTreatment`]):
//! - `Projection`: the bi-projection scheme (Chupin & Dubois 2016, *Comput. Math. Appl.* 72;
//!   Chalayer, Chupin & Dubois 2018, *SIAM J. Numer. Anal.* 56), implemented in [`plastic`];
//! - `Papanastasiou { m }`: regularised viscosity η + τ (1 − e^{−m|D|})/(2|D|) (Papanastasiou
//!   1987, *J. Rheol.* 31), lagged, implicit viscous solve;
//! - `BiViscous { yield_viscosity }`: η + min(τ/(2|D|), η_y − η) (a bi-viscous law: viscosity η_y
//!   below the yield point), lagged, implicit viscous solve.
//!
//! Coulomb friction walls (paper eq. 8–9) are in [`crate::walls`].

pub mod anderson;
pub mod plastic;
pub mod rest;
pub(crate) mod stage;

use crate::error::{check_positive, check_range, Error, Result};

pub use crate::plasticity::InterfaceYield;
pub use plastic::{PicardInfo, PlasticState};
pub use rest::RestStress;

/// A constitutive law of the dense phase.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RheologyLaw {
    /// T = 2η D(u).
    Newtonian,
    /// T = 2η D(u) + τ_y Σ, constant yield stress [Pa].
    Bingham { yield_stress: f64 },
    /// T = 2η_s D(u) + tan(α) p⁺ Σ; `friction_angle` α in degrees (paper: 27°).
    DruckerPrager { friction_angle: f64 },
    /// μ(I) rheology (paper eq. 3–5): T = 2η_s(|D|, p) D(u) + μ_s p⁺ Σ.
    MuI {
        /// Static friction coefficient μ_s = tan(α).
        mu_s: f64,
        /// Limiting friction coefficient μ₂ (the paper's μ_∞), μ₂ > μ_s.
        mu_2: f64,
        /// I₀ of μ(I) = μ_s + (μ₂ − μ_s)/(I₀/I + 1).
        i0: f64,
        /// Grain diameter d [m].
        grain_diameter: f64,
        /// Grain density ρ_s [kg m⁻³] in I = 2|D| d √(ρ_s/p).
        grain_density: f64,
    },
}

impl RheologyLaw {
    /// Name used in Python and the docs.
    pub fn name(&self) -> &'static str {
        match self {
            RheologyLaw::Newtonian => "newtonian",
            RheologyLaw::Bingham { .. } => "bingham",
            RheologyLaw::DruckerPrager { .. } => "drucker-prager",
            RheologyLaw::MuI { .. } => "mu-i",
        }
    }

    /// Whether the law has a yield stress.
    pub fn has_yield_stress(&self) -> bool {
        !matches!(self, RheologyLaw::Newtonian)
    }

    /// Whether the yield stress depends on the pressure.
    pub fn pressure_dependent(&self) -> bool {
        matches!(self, RheologyLaw::DruckerPrager { .. } | RheologyLaw::MuI { .. })
    }

    /// Yield stress of the pure dense phase at pressure `p` (before the H_ε(Φ) factor).
    #[inline]
    pub fn yield_stress(&self, p: f64) -> f64 {
        match *self {
            RheologyLaw::Newtonian => 0.0,
            RheologyLaw::Bingham { yield_stress } => yield_stress,
            RheologyLaw::DruckerPrager { friction_angle } => friction_angle.to_radians().tan() * p.max(0.0),
            RheologyLaw::MuI { mu_s, .. } => mu_s * p.max(0.0),
        }
    }

    /// Rate-dependent part of the viscosity of the dense phase at strain-rate norm `d_norm` and
    /// pressure `p` (0 except for μ(I): (μ₂ − μ_s) p⁺ / (2|D| + (I₀/d)√(p⁺/ρ_s))).
    #[inline]
    pub fn extra_viscosity(&self, d_norm: f64, p: f64) -> f64 {
        match *self {
            RheologyLaw::MuI { mu_s, mu_2, i0, grain_diameter, grain_density } => {
                let p = p.max(0.0);
                let den = 2.0 * d_norm + (i0 / grain_diameter) * (p / grain_density).sqrt();
                if den > 0.0 {
                    (mu_2 - mu_s) * p / den
                } else {
                    0.0
                }
            }
            _ => 0.0,
        }
    }

    /// Checks the parameters, naming the offending one.
    pub fn validate(&self) -> Result<()> {
        match *self {
            RheologyLaw::Newtonian => Ok(()),
            RheologyLaw::Bingham { yield_stress } => crate::error::check_non_negative("yield_stress", yield_stress),
            RheologyLaw::DruckerPrager { friction_angle } => {
                if friction_angle.is_finite() && friction_angle > 0.0 && friction_angle < 90.0 {
                    Ok(())
                } else {
                    Err(Error::param("friction_angle", friction_angle, "an angle in degrees in (0, 90)"))
                }
            }
            RheologyLaw::MuI { mu_s, mu_2, i0, grain_diameter, grain_density } => {
                crate::error::check_non_negative("mu_s", mu_s)?;
                if !(mu_2.is_finite() && mu_2 > mu_s) {
                    return Err(Error::param("mu_2", mu_2, &format!("a finite number > mu_s = {mu_s}")));
                }
                check_positive("i0", i0)?;
                check_positive("grain_diameter", grain_diameter)?;
                check_positive("grain_density", grain_density)
            }
        }
    }
}

/// The normal stress −σ_n that the Coulomb walls' τ_b = tan(α_b)(−σ_n)⁺ H_ε(Φ) uses (eq. 8).
///
/// The paper writes −σ_n for the normal component of the granular phase's total stress
/// σ = T − p I, T = 2ηD(u) + τΣ: −σ_n = p − T_nn. On a wall T_nn = ±T_xx (2D, T traceless: T_yy =
/// −T_xx on the base and the lid, T_xx on the side walls).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum WallNormalStress {
    /// −σ_n = p: the pressure alone (T_nn neglected; exact for a layer at rest or in simple
    /// shear along the wall, where D_nn = 0 and Σ_nn = 0).
    #[default]
    Pressure,
    /// −σ_n = p − T_nn with T_nn = 2η D_nn(u^n) + τ Σ^n_nn, lagged by one step like p^n: a
    /// spreading layer (D_xx > 0, Σ_yy = −Σ_xx < 0 on the base) presses harder on the base.
    Total,
}

/// Where the plastic tensor Σ lives on the MAC grid (`rheology/plastic.rs`, "Storage").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum SigmaLocation {
    /// Σ_xx at cell centres with D_xx, D_yy, Σ_xy at nodes with D_xy: each component is projected
    /// where its strain rate is exact, and div(τΣ) has the compact stencil of the viscous term.
    #[default]
    Staggered,
    /// Σ_xx and Σ_xy both at cell centres, as in the paper's Figure 3 ("the discrete unknowns
    /// associated with Σ and p_f are also placed at the centre of the mesh cell"): D_xy is
    /// averaged from the four corner nodes to the centre, the pair is projected there, and the
    /// force takes τΣ_xy at a node as the average of its four cells (the adjoint of that average,
    /// so that the discrete plastic power is Σ_cells τ Σ:D).
    Centres,
}

impl SigmaLocation {
    /// Every location, in the order of the names.
    pub const ALL: [SigmaLocation; 2] = [SigmaLocation::Staggered, SigmaLocation::Centres];

    /// Name used in Python and the docs.
    pub fn name(&self) -> &'static str {
        match self {
            SigmaLocation::Staggered => "staggered",
            SigmaLocation::Centres => "centres",
        }
    }

    /// The location called `name`, if any.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|l| l.name() == name)
    }
}

/// Which pressure the yield stress τ = τ(p) and the walls' −σ_n = p use (two-phase models only).
///
/// In the level-set formulation (eq. 10b) one pressure p serves the air and the granular phase,
/// and it is continuous across the smoothed interface: the granular pressure at the surface is
/// the air's pressure there, not zero. Its value depends on the gauge (the whole domain fixes
/// the mean of its top row; an active window fixes its own top row, docs/models.md) and on the
/// air's dynamic pressure (suction over the collapsing column, −5 Pa against +0.6 Pa far away at
/// ny = 32). Under a 1 cm tongue the yield stress is tan(α) × 140 Pa, so a few pascals of gauge
/// are a few per cent of it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum YieldPressure {
    /// p itself (the paper's τ(Φ) = tan(α) p H_ε(Φ)).
    #[default]
    Absolute,
    /// p − p_s, with p_s the mean pressure of the air on the granular surface: the air cells
    /// −ε − h ≤ Φ < −ε just outside the smoothed band (h = max(dx, dy)), one per surface
    /// column, averaged with equal weights at each step from pⁿ. The granular pressure then
    /// starts from zero at the surface whatever the gauge: a uniform shift of p changes nothing.
    /// Local variations of the air's pressure along the surface still enter.
    SurfaceAir,
}

impl YieldPressure {
    /// Name used in Python and the docs.
    pub fn name(&self) -> &'static str {
        match self {
            YieldPressure::Absolute => "absolute",
            YieldPressure::SurfaceAir => "surface-air",
        }
    }
}

/// How the yield stress is imposed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum YieldTreatment {
    /// Bi-projection: Σ = P(Σ + r D(u)) by the Picard iteration of eq. (12).
    Projection,
    /// Papanastasiou regularisation with exponent `m` [s].
    Papanastasiou { m: f64 },
    /// Bi-viscous regularisation: viscosity `yield_viscosity` η_y [Pa s] below the yield point.
    BiViscous { yield_viscosity: f64 },
}

impl YieldTreatment {
    /// Name used in Python and the docs.
    pub fn name(&self) -> &'static str {
        match self {
            YieldTreatment::Projection => "projection",
            YieldTreatment::Papanastasiou { .. } => "papanastasiou",
            YieldTreatment::BiViscous { .. } => "bi-viscous",
        }
    }

    /// Regularised viscosity increment for yield stress `tau` at strain-rate norm `d_norm`, for
    /// a plastic viscosity `eta` (0 for the projection).
    #[inline]
    pub fn regularised_viscosity(&self, tau: f64, d_norm: f64, eta: f64) -> f64 {
        match *self {
            YieldTreatment::Projection => 0.0,
            YieldTreatment::Papanastasiou { m } => {
                let x = m * d_norm;
                // (1 − e^{−x})/x → 1 as x → 0: τ m / 2
                let f = if x > 1e-8 { -(-x).exp_m1() / x } else { 1.0 - 0.5 * x };
                0.5 * tau * m * f
            }
            YieldTreatment::BiViscous { yield_viscosity } => {
                let cap = (yield_viscosity - eta).max(0.0);
                if d_norm > 0.0 {
                    (0.5 * tau / d_norm).min(cap)
                } else {
                    cap
                }
            }
        }
    }
}

/// Default of `RheologyConfig::r_neighbourhood`.
pub const DEFAULT_R_NEIGHBOURHOOD: usize = 0;

/// Rheology of the dense phase and the numerics of its yield stress and of Coulomb walls.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RheologyConfig {
    pub law: RheologyLaw,
    pub treatment: YieldTreatment,
    /// Basal friction angle α_b [degrees] of the `Coulomb` sides (paper: 15°); `None`: those
    /// sides are frictionless (free slip).
    pub wall_friction_angle: Option<f64>,
    /// r of Σ = P(Σ + r D(u)) [s]; `None`: the contraction bound of [`plastic::default_r`].
    pub r: Option<f64>,
    /// r_b of s = P_b(s − r_b u_t) [s m⁻¹]; `None`: the bound of [`crate::walls::default_r_wall`].
    pub r_wall: Option<f64>,
    /// Pseudo-relaxation θ ∈ [0, 1) of eq. (12) (0: plain Uzawa iteration).
    pub theta: f64,
    /// The Picard iteration stops when max |τ(Σ^{k+1} − Σ^k)|/τ_max and max |τ_b(s^{k+1} − s^k)|/max τ_b are below this.
    pub picard_tol: f64,
    /// Reaching this many iterations without convergence is an error.
    pub picard_max_iterations: usize,
    /// Iteration cap of each viscous solve inside the Picard loop (default
    /// [`stage::PICARD_SOLVE_MAX_ITERATIONS`]; the overall `viscous_max_iterations` still
    /// applies). Fine creeping grids need more from a cold start (the Bingham cavity at
    /// n = 128: over 500 at its first step).
    pub picard_solve_max_iterations: usize,
    /// Where the smoothed jump of τ(Φ) and τ_b(Φ) sits (two-phase models only).
    pub interface_yield: InterfaceYield,
    /// Proximal restarts of the anchor of eq. (12) per step (0: the paper's iteration). Eq. (12)
    /// converges to Σ = P(Σ + rD + θ(Σ^n − Σ)), not to eq. (11): a rigid zone deforms at
    /// D = θ(Σ − Σ^n)/r, an elastic body of shear modulus τr/(θδt). After each converged
    /// relaxed iteration whose Σ still differs from its anchor by more than `picard_tol`, the
    /// anchor is set to it (Σ^n ← Σ, s^n ← s) and the iteration goes on: a proximal-point
    /// iteration whose fixed point is eq. (11) itself. Iterations count against
    /// `picard_max_iterations`.
    pub proximal_restarts: usize,
    /// Depth m of the Anderson acceleration of the Picard iteration (0: the plain iteration of
    /// eq. 12; [`anderson`]). Same fixed point, fewer predictor solves where the plain
    /// iteration crawls (θ → 0, fine grids, proximal restarts).
    pub anderson_depth: usize,
    /// The normal stress of the Coulomb walls' friction (eq. 8).
    pub wall_normal_stress: WallNormalStress,
    /// Half-width w (cells) of the neighbourhood over which the default local r takes the
    /// largest velocity response k (0: the cell's own faces; at most
    /// [`plastic::MAX_R_NEIGHBOURHOOD`]). It sets how soft the relaxed fixed point of eq. (12)
    /// is near the interface (`rheology/plastic.rs`, "Choice of r").
    pub r_neighbourhood: usize,
    /// The pressure of the yield stress and of the walls' normal stress (two-phase models only).
    pub yield_pressure: YieldPressure,
    /// Where Σ lives: staggered (default) or at cell centres (the paper's Figure 3).
    pub sigma_location: SigmaLocation,
    /// Friction of a channel's side walls on the 2D flow (`walls/side.rs`); `None` (default,
    /// the paper's 2D model): no side walls.
    pub side_walls: Option<crate::walls::side::SideWalls>,
}

impl Default for RheologyConfig {
    fn default() -> Self {
        RheologyConfig {
            law: RheologyLaw::Newtonian,
            treatment: YieldTreatment::Projection,
            wall_friction_angle: None,
            r: None,
            r_wall: None,
            theta: 0.5,
            picard_tol: 1e-9,
            picard_max_iterations: 1000,
            picard_solve_max_iterations: stage::PICARD_SOLVE_MAX_ITERATIONS,
            interface_yield: InterfaceYield::default(),
            proximal_restarts: 0,
            anderson_depth: 0,
            wall_normal_stress: WallNormalStress::default(),
            r_neighbourhood: DEFAULT_R_NEIGHBOURHOOD,
            yield_pressure: YieldPressure::default(),
            sigma_location: SigmaLocation::default(),
            side_walls: None,
        }
    }
}

impl RheologyConfig {
    /// A configuration with `law` and the default numerics.
    pub fn new(law: RheologyLaw) -> Self {
        RheologyConfig { law, ..Default::default() }
    }

    /// Whether the bi-projection (Picard loop) runs: a yield stress with the projection
    /// treatment, or Coulomb friction walls.
    pub fn needs_picard(&self, has_coulomb_walls: bool) -> bool {
        (self.law.has_yield_stress() && self.treatment == YieldTreatment::Projection)
            || (has_coulomb_walls && self.wall_friction_angle.is_some())
            || self.side_walls.is_some()
    }

    /// Whether the viscosity of the dense phase changes from step to step.
    pub fn variable_viscosity(&self) -> bool {
        matches!(self.law, RheologyLaw::MuI { .. }) || (self.law.has_yield_stress() && self.treatment != YieldTreatment::Projection)
    }

    /// Checks every parameter, naming the first offending one.
    pub fn validate(&self) -> Result<()> {
        self.law.validate()?;
        match self.treatment {
            YieldTreatment::Projection => {}
            YieldTreatment::Papanastasiou { m } => check_positive("regularisation", m)?,
            YieldTreatment::BiViscous { yield_viscosity } => check_positive("regularisation", yield_viscosity)?,
        }
        if let Some(a) = self.wall_friction_angle {
            if !(a.is_finite() && (0.0..90.0).contains(&a)) {
                return Err(Error::param("wall_friction_angle", a, "an angle in degrees in [0, 90)"));
            }
        }
        if let Some(r) = self.r {
            check_positive("r", r)?;
        }
        if let Some(r) = self.r_wall {
            check_positive("r_wall", r)?;
        }
        if !(self.theta.is_finite() && (0.0..1.0).contains(&self.theta)) {
            return Err(Error::param("theta", self.theta, "a number in [0, 1)"));
        }
        check_range("picard_tol", self.picard_tol, 1e-15, 0.5)?;
        if self.picard_max_iterations == 0 || self.picard_max_iterations > 1_000_000 {
            return Err(Error::param("picard_max_iterations", self.picard_max_iterations, "an integer in [1, 1e6]"));
        }
        if self.picard_solve_max_iterations == 0 || self.picard_solve_max_iterations > 100_000_000 {
            return Err(Error::param("picard_solve_max_iterations", self.picard_solve_max_iterations, "an integer in [1, 1e8]"));
        }
        if self.r_neighbourhood > plastic::MAX_R_NEIGHBOURHOOD {
            return Err(Error::param("r_neighbourhood", self.r_neighbourhood, &format!("an integer in [0, {}]", plastic::MAX_R_NEIGHBOURHOOD)));
        }
        if self.anderson_depth > anderson::MAX_ANDERSON_DEPTH {
            return Err(Error::param("anderson_depth", self.anderson_depth, &format!("an integer in [0, {}]", anderson::MAX_ANDERSON_DEPTH)));
        }
        if let Some(w) = self.side_walls {
            if !(w.width.is_finite() && w.width > 0.0 && w.width <= crate::walls::side::MAX_CHANNEL_WIDTH) {
                return Err(Error::param("side_walls.width", w.width, &format!("a channel width in (0, {}] (m)", crate::walls::side::MAX_CHANNEL_WIDTH)));
            }
            if !(w.friction_angle.is_finite() && (0.0..90.0).contains(&w.friction_angle)) {
                return Err(Error::param("side_walls.friction_angle", w.friction_angle, "an angle in degrees in [0, 90)"));
            }
        }
        if self.anderson_depth > 0 && self.sigma_location == SigmaLocation::Centres {
            return Err(Error::param("anderson_depth", self.anderson_depth, "0 with sigma_location = 'centres' (Anderson mixing acts on the staggered Σ)"));
        }
        Ok(())
    }
}
