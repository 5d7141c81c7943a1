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
pub(crate) mod augmented;
pub(crate) mod cone;
pub mod exact;
pub mod interior_point;
pub mod plastic;
pub mod rest;
pub(crate) mod stage;

use crate::error::{Error, Result};
use crate::options::{self, OptionMap, OptionSpec, Value};

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

/// A law's yield stress against the pressure: `constant` (Bingham), or `slope` · p⁺ (the
/// friction coefficient tan α of Drucker–Prager, μ_s of μ(I)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct YieldStress {
    constant: f64,
    slope: Option<f64>,
}

impl YieldStress {
    /// The yield stress at pressure `p` [Pa].
    #[inline]
    pub fn at(&self, p: f64) -> f64 {
        match self.slope {
            Some(s) => s * p.max(0.0),
            None => self.constant,
        }
    }
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
        self.yield_stress_fn().at(p)
    }

    /// The law's yield stress as a function of the pressure with its constant (tan α of
    /// Drucker–Prager) evaluated once, for loops over cells: the values of
    /// [`RheologyLaw::yield_stress`] bit for bit.
    #[inline]
    pub fn yield_stress_fn(&self) -> YieldStress {
        match *self {
            RheologyLaw::Newtonian => YieldStress { constant: 0.0, slope: None },
            RheologyLaw::Bingham { yield_stress } => YieldStress { constant: yield_stress, slope: None },
            RheologyLaw::DruckerPrager { friction_angle } => YieldStress { constant: 0.0, slope: Some(friction_angle.to_radians().tan()) },
            RheologyLaw::MuI { mu_s, .. } => YieldStress { constant: 0.0, slope: Some(mu_s) },
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

    /// The options of the law's parameters (its room is the law's name).
    pub fn options(&self) -> &'static [OptionSpec] {
        match self {
            RheologyLaw::Newtonian => &[],
            RheologyLaw::Bingham { .. } => BINGHAM_OPTIONS,
            RheologyLaw::DruckerPrager { .. } => DRUCKER_PRAGER_OPTIONS,
            RheologyLaw::MuI { .. } => MU_I_OPTIONS,
        }
    }

    /// The law called `kind` with the parameters of `map` (checked against the law's options;
    /// a parameter with a default may be left out, a required one may not).
    pub fn from_options(kind: &str, map: &OptionMap) -> Result<Self> {
        let table: &[OptionSpec] = match kind {
            "newtonian" => &[],
            "bingham" => BINGHAM_OPTIONS,
            "drucker-prager" => DRUCKER_PRAGER_OPTIONS,
            "mu-i" => MU_I_OPTIONS,
            other => return Err(Error::param("rheology", other, "one of 'newtonian', 'bingham', 'drucker-prager', 'mu-i'")),
        };
        for k in map.keys() {
            if !table.iter().any(|s| s.key == k) {
                let names: Vec<&str> = table.iter().map(|s| s.key).collect();
                return Err(Error::param(
                    k,
                    "given",
                    &format!("a parameter of the '{kind}' rheology ({})", if names.is_empty() { "none".to_string() } else { names.join(", ") }),
                ));
            }
        }
        let get = |k: &str| -> Result<f64> {
            let s = options::spec(table, k);
            match map.get(k).unwrap_or(&s.default) {
                Value::None => Err(Error::param(k, "missing", &format!("{} (required by the '{kind}' rheology)", s.allowed()))),
                v => Ok(s.check(v)?.as_f64().unwrap_or(f64::NAN)),
            }
        };
        let law = match kind {
            "bingham" => RheologyLaw::Bingham { yield_stress: get("yield_stress")? },
            "drucker-prager" => RheologyLaw::DruckerPrager { friction_angle: get("friction_angle")? },
            "mu-i" => RheologyLaw::MuI {
                mu_s: get("mu_s")?,
                mu_2: get("mu_2")?,
                i0: get("i0")?,
                grain_diameter: get("grain_diameter")?,
                grain_density: get("grain_density")?,
            },
            _ => RheologyLaw::Newtonian,
        };
        law.validate()?;
        Ok(law)
    }

    /// The law's parameters by key (the inverse of [`RheologyLaw::from_options`]).
    pub fn to_options(&self) -> OptionMap {
        let pairs: Vec<(&str, f64)> = match *self {
            RheologyLaw::Newtonian => vec![],
            RheologyLaw::Bingham { yield_stress } => vec![("yield_stress", yield_stress)],
            RheologyLaw::DruckerPrager { friction_angle } => vec![("friction_angle", friction_angle)],
            RheologyLaw::MuI { mu_s, mu_2, i0, grain_diameter, grain_density } => {
                vec![("mu_s", mu_s), ("mu_2", mu_2), ("i0", i0), ("grain_diameter", grain_diameter), ("grain_density", grain_density)]
            }
        };
        pairs.into_iter().map(|(k, v)| (k.to_string(), Value::Float(v))).collect()
    }

    /// Checks the parameters against the law's options, naming the offending one.
    pub fn validate(&self) -> Result<()> {
        let table = self.options();
        for (k, v) in self.to_options() {
            options::spec(table, &k).check(&v)?;
        }
        if let RheologyLaw::MuI { mu_s, mu_2, .. } = *self {
            if !(mu_2.is_finite() && mu_2 > mu_s) {
                return Err(Error::param("mu_2", mu_2, &format!("a finite number > mu_s = {mu_s}")));
            }
        }
        Ok(())
    }
}

/// The parameter of the Bingham law.
pub const BINGHAM_OPTIONS: &[OptionSpec] =
    &[options::float("bingham", "yield_stress", 0.0, 0.0, f64::INFINITY, "Pa", "τ_y, the constant yield stress").open(false, true).required()];

/// The parameter of the Drucker–Prager law (the paper's D-P model).
pub const DRUCKER_PRAGER_OPTIONS: &[OptionSpec] = &[options::float(
    "drucker-prager",
    "friction_angle",
    27.0,
    0.0,
    90.0,
    "degree",
    "α, internal friction angle: yield stress tan(α) p⁺ (the paper's glass beads: 27)",
)
.open(true, true)];

/// The parameters of the μ(I) law (paper eq. 3–5).
pub const MU_I_OPTIONS: &[OptionSpec] = &[
    options::float("mu-i", "mu_s", 0.0, 0.0, f64::INFINITY, "1", "μ_s = tan(α), static friction coefficient").open(false, true).required(),
    options::float("mu-i", "mu_2", 0.0, 0.0, f64::INFINITY, "1", "μ₂ (the paper's μ_∞), limiting friction coefficient, > μ_s").open(false, true).required(),
    options::float("mu-i", "i0", 0.0, 0.0, f64::INFINITY, "1", "I₀ of μ(I) = μ_s + (μ₂ − μ_s)/(I₀/I + 1)").open(true, true).required(),
    options::float("mu-i", "grain_diameter", 0.0, 0.0, f64::INFINITY, "m", "d, grain diameter in I = 2|D| d √(ρ_s/p)").open(true, true).required(),
    options::float("mu-i", "grain_density", 0.0, 0.0, f64::INFINITY, "kg m-3", "ρ_s, grain density in I").open(true, true).required(),
];

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
    /// How the default r_b is chosen: one for every face, or each face's own
    /// (`walls/mod.rs`, "Choice of r_b"); a user's `r_wall` is used as a constant.
    pub wall_r: crate::walls::WallR,
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
    /// How the step of eq. (11) is solved: the Picard iteration of eq. (12), or the exact step
    /// ([`exact`]).
    pub solver: BiProjectionSolver,
    /// The exact step stops when both residuals of eq. (11) are below this (`exact.rs`, the
    /// stopping test).
    pub newton_tol: f64,
    /// Iteration cap of the exact step: sparse factorisations, the interior point's and the method
    /// of multipliers' included
    /// (reaching it rejects the step, or stops the run).
    pub newton_max_iterations: usize,
}

/// How the bi-projection's step (eq. 11) is solved.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BiProjectionSolver {
    /// The Picard iteration with pseudo-relaxation θ of eq. (12) (`rheology/stage.rs`).
    #[default]
    Picard,
    /// Eq. (11) itself on the two-location plastic functional, to the residual `newton_tol`: a
    /// semismooth Newton loop from the previous step, an interior-point stage where it does not
    /// converge, and the semismooth loop from that point ([`exact`]).
    Newton,
}

impl BiProjectionSolver {
    /// Every value, in the order of the names.
    pub const ALL: [BiProjectionSolver; 2] = [BiProjectionSolver::Picard, BiProjectionSolver::Newton];

    /// Name used in Python and the docs.
    pub fn name(&self) -> &'static str {
        match self {
            BiProjectionSolver::Picard => "picard",
            BiProjectionSolver::Newton => "newton",
        }
    }
}

/// The options of the bi-projection (the Picard iteration of eq. 12) and of how the yield
/// stress is imposed: `RheologyConfig`'s numerics of the common case.
pub const BI_PROJECTION_OPTIONS: &[OptionSpec] = &[
    options::choice(
        "bi_projection",
        "plastic",
        "projection",
        &["projection", "papanastasiou", "bi-viscous"],
        "how the yield stress is imposed: the bi-projection, or a regularised viscosity (with regularisation)",
    ),
    options::float(
        "bi_projection",
        "regularisation",
        1.0,
        0.0,
        f64::INFINITY,
        "",
        "the Papanastasiou exponent m [s] or the bi-viscous viscosity below yield [Pa s] (required by those treatments)",
    )
    .open(true, true)
    .off_by_default(),
    options::choice(
        "bi_projection",
        "solver",
        "picard",
        &["picard", "newton"],
        "how eq. (11) is solved: the Picard iteration of eq. (12), or the exact step (semismooth Newton with an interior-point stage, finished by the method of multipliers; rheology/exact.rs)",
    ),
    options::float(
        "bi_projection",
        "newton_tol",
        1e-9,
        1e-14,
        1e-2,
        "1",
        "the exact step stops when the momentum residual (maximum norm, relative) and the projection residual of eq. (11) (one r for every location: h/U, U the step's largest uncoupled face velocity) are below this",
    ),
    options::int(
        "bi_projection",
        "newton_max_iterations",
        100,
        1,
        100_000,
        "1",
        "iteration cap of the exact step (sparse factorisations, the interior point's and the method of multipliers' included)",
    ),
    options::float("bi_projection", "r", 1.0, 0.0, f64::INFINITY, "s", "r of Σ = P(Σ + r D(u)) (None: the local contraction bound of rheology/plastic.rs)")
        .open(true, true)
        .off_by_default(),
    options::float("bi_projection", "r_wall", 1.0, 0.0, f64::INFINITY, "s m-1", "r_b of s = P_b(s − r_b u_t) (None: the bound of walls/mod.rs)")
        .open(true, true)
        .off_by_default(),
    options::float("bi_projection", "theta", 0.5, 0.0, 1.0, "1", "θ, pseudo-relaxation of the Picard iteration (geometric ratio about 1 − θ; 0: plain Uzawa)")
        .open(false, true),
    options::float(
        "bi_projection",
        "picard_tol",
        1e-9,
        1e-15,
        0.5,
        "1",
        "the Picard iteration stops when max |τ ΔΣ|/τ_max and max |τ_b Δs|/max τ_b are below this",
    ),
    options::int(
        "bi_projection",
        "picard_max_iterations",
        1000,
        1,
        1_000_000,
        "1",
        "iteration cap of the Picard loop (reaching it rejects the step, or stops the run)",
    ),
    options::int(
        "bi_projection",
        "picard_solve_max_iterations",
        stage::PICARD_SOLVE_MAX_ITERATIONS as i64,
        1,
        100_000_000,
        "1",
        "iteration cap of each viscous solve inside the Picard loop",
    ),
    options::int(
        "bi_projection",
        "anderson_depth",
        0,
        0,
        anderson::MAX_ANDERSON_DEPTH as i64,
        "1",
        "depth of the Anderson acceleration of the Picard iteration (0: the plain iteration; same fixed point)",
    ),
];

/// The bi-projection's numerical variants of the rheology and the walls (room "bi_projection"): readings
/// of the paper kept for study, each default the measured choice (docs/models.md, "Variants").
pub const RHEOLOGY_VARIANT_OPTIONS: &[OptionSpec] = &[
    options::choice(
        "bi_projection",
        "interface_yield",
        "paper",
        &["paper", "granular-side", "density-support"],
        "where the smoothed jump of τ(Φ) and τ_b(Φ) sits: the paper's H_ε(Φ), H_ε(Φ + ε) or H_ε(Φ + 2ε)",
    )
    .variant(),
    options::choice(
        "bi_projection",
        "wall_normal_stress",
        "pressure",
        &["pressure", "total"],
        "normal stress of the Coulomb walls: the pressure p, or the total stress p − T_nn",
    )
    .variant(),
    options::choice(
        "bi_projection",
        "yield_pressure",
        "absolute",
        &["absolute", "surface-air"],
        "pressure of the yield stress and the walls: p, or p minus the mean air pressure on the surface",
    )
    .variant(),
    options::choice(
        "bi_projection",
        "sigma_location",
        "staggered",
        &["staggered", "centres"],
        "where Σ lives: Σ_xx at centres and Σ_xy at nodes, or both at centres (the paper's Figure 3)",
    )
    .variant(),
    options::int(
        "bi_projection",
        "r_neighbourhood",
        crate::rheology::DEFAULT_R_NEIGHBOURHOOD as i64,
        0,
        plastic::MAX_R_NEIGHBOURHOOD as i64,
        "cells",
        "half-width of the neighbourhood over which the local r takes the largest velocity response",
    )
    .variant(),
    options::int(
        "bi_projection",
        "proximal_restarts",
        0,
        0,
        1_000_000,
        "1",
        "proximal restarts of the anchor Σⁿ of eq. (12) per step (0: the paper's iteration)",
    )
    .variant(),
    options::choice(
        "bi_projection",
        "wall_r",
        "single",
        &["single", "local"],
        "default r_b of the Coulomb walls: one from the stiffest face, or each face's own bound (1 − θ)h c/τ_b",
    )
    .variant(),
];

/// The friction angle of the Coulomb walls (paper eq. 8–9; `RheologyConfig::wall_friction_angle`).
pub const COULOMB_OPTIONS: &[OptionSpec] = &[options::float(
    "coulomb",
    "friction_angle",
    15.0,
    0.0,
    90.0,
    "degree",
    "α_b, friction angle of the granular phase on the wall (the paper: 15; None: frictionless)",
)
.open(false, true)
.off_by_default()];

/// The channel's side walls (`RheologyConfig::side_walls`, `walls/side.rs`).
pub const SIDE_WALL_OPTIONS: &[OptionSpec] = &[
    options::float("side_walls", "width", 0.1, 0.0, crate::walls::side::MAX_CHANNEL_WIDTH, "m", "W, width of the channel (the paper's experiment: 0.10)")
        .open(true, false)
        .required(),
    options::float("side_walls", "friction_angle", 15.0, 0.0, 90.0, "degree", "α_w, friction angle of the granular phase on the side walls")
        .open(false, true)
        .required(),
];

impl Default for RheologyConfig {
    fn default() -> Self {
        let b = |k| options::spec(BI_PROJECTION_OPTIONS, k);
        let v = |k| options::spec(RHEOLOGY_VARIANT_OPTIONS, k);
        RheologyConfig {
            law: RheologyLaw::Newtonian,
            treatment: YieldTreatment::Projection,
            wall_friction_angle: None,
            r: None,
            r_wall: None,
            wall_r: crate::walls::WallR::default(),
            theta: b("theta").float(),
            picard_tol: b("picard_tol").float(),
            picard_max_iterations: b("picard_max_iterations").usize(),
            picard_solve_max_iterations: b("picard_solve_max_iterations").usize(),
            interface_yield: InterfaceYield::default(),
            proximal_restarts: v("proximal_restarts").usize(),
            anderson_depth: b("anderson_depth").usize(),
            wall_normal_stress: WallNormalStress::default(),
            r_neighbourhood: v("r_neighbourhood").usize(),
            yield_pressure: YieldPressure::default(),
            sigma_location: SigmaLocation::default(),
            side_walls: None,
            solver: BiProjectionSolver::default(),
            newton_tol: b("newton_tol").float(),
            newton_max_iterations: b("newton_max_iterations").usize(),
        }
    }
}

impl InterfaceYield {
    /// Every value, in the order of the names.
    pub const ALL: [InterfaceYield; 3] = [InterfaceYield::Paper, InterfaceYield::GranularSide, InterfaceYield::DensitySupport];

    /// Name used in Python and the docs.
    pub fn name(&self) -> &'static str {
        match self {
            InterfaceYield::Paper => "paper",
            InterfaceYield::GranularSide => "granular-side",
            InterfaceYield::DensitySupport => "density-support",
        }
    }
}

impl WallNormalStress {
    /// Name used in Python and the docs.
    pub fn name(&self) -> &'static str {
        match self {
            WallNormalStress::Pressure => "pressure",
            WallNormalStress::Total => "total",
        }
    }
}

impl RheologyConfig {
    /// A configuration with `law` and the default numerics.
    pub fn new(law: RheologyLaw) -> Self {
        RheologyConfig { law, ..Default::default() }
    }

    /// The value of option `key` of [`BI_PROJECTION_OPTIONS`] or [`RHEOLOGY_VARIANT_OPTIONS`].
    pub fn get_option(&self, key: &str) -> Value {
        match key {
            "plastic" => Value::str(self.treatment.name()),
            "regularisation" => match self.treatment {
                YieldTreatment::Projection => Value::None,
                YieldTreatment::Papanastasiou { m } => Value::Float(m),
                YieldTreatment::BiViscous { yield_viscosity } => Value::Float(yield_viscosity),
            },
            "r" => Value::opt_f64(self.r),
            "r_wall" => Value::opt_f64(self.r_wall),
            "theta" => Value::Float(self.theta),
            "picard_tol" => Value::Float(self.picard_tol),
            "picard_max_iterations" => Value::Int(self.picard_max_iterations.min(i64::MAX as usize) as i64),
            "picard_solve_max_iterations" => Value::Int(self.picard_solve_max_iterations.min(i64::MAX as usize) as i64),
            "anderson_depth" => Value::Int(self.anderson_depth.min(i64::MAX as usize) as i64),
            "interface_yield" => Value::str(self.interface_yield.name()),
            "wall_normal_stress" => Value::str(self.wall_normal_stress.name()),
            "yield_pressure" => Value::str(self.yield_pressure.name()),
            "sigma_location" => Value::str(self.sigma_location.name()),
            "r_neighbourhood" => Value::Int(self.r_neighbourhood.min(i64::MAX as usize) as i64),
            "proximal_restarts" => Value::Int(self.proximal_restarts.min(i64::MAX as usize) as i64),
            "wall_r" => Value::str(self.wall_r.name()),
            "solver" => Value::str(self.solver.name()),
            "newton_tol" => Value::Float(self.newton_tol),
            "newton_max_iterations" => Value::Int(self.newton_max_iterations.min(i64::MAX as usize) as i64),
            _ => Value::None,
        }
    }

    /// Sets the options of `map` that are the bi-projection's or the variants' (checked
    /// against their specs); returns how many keys it used.
    pub fn apply_options(&mut self, map: &OptionMap) -> Result<usize> {
        let mut used = 0;
        let mut checked = |k: &str| -> Result<Option<Value>> {
            let s = BI_PROJECTION_OPTIONS.iter().chain(RHEOLOGY_VARIANT_OPTIONS).find(|s| s.key == k).expect("a rheology option");
            match map.get(k) {
                Some(v) => {
                    used += 1;
                    Ok(Some(s.check(v)?))
                }
                None => Ok(None),
            }
        };
        let plastic = checked("plastic")?;
        let reg = checked("regularisation")?;
        if plastic.is_some() || reg.is_some() {
            let name = plastic.as_ref().map_or(self.treatment.name().to_string(), |v| options::as_name(v).to_string());
            let reg = match reg {
                Some(v) => v.as_f64(),
                None => self.get_option("regularisation").as_f64(),
            };
            let need = |what: &str| reg.ok_or_else(|| Error::param("regularisation", "None", &format!("a number ({what}) for plastic = '{name}'")));
            self.treatment = match name.as_str() {
                "papanastasiou" => YieldTreatment::Papanastasiou { m: need("the exponent m in s")? },
                "bi-viscous" => YieldTreatment::BiViscous { yield_viscosity: need("the viscosity below yield in Pa s")? },
                _ => YieldTreatment::Projection,
            };
        }
        if let Some(v) = checked("r")? {
            self.r = v.as_f64();
        }
        if let Some(v) = checked("r_wall")? {
            self.r_wall = v.as_f64();
        }
        if let Some(v) = checked("theta")? {
            self.theta = v.as_f64().unwrap_or(self.theta);
        }
        if let Some(v) = checked("picard_tol")? {
            self.picard_tol = v.as_f64().unwrap_or(self.picard_tol);
        }
        if let Some(v) = checked("picard_max_iterations")? {
            self.picard_max_iterations = options::as_usize(&v);
        }
        if let Some(v) = checked("picard_solve_max_iterations")? {
            self.picard_solve_max_iterations = options::as_usize(&v);
        }
        if let Some(v) = checked("anderson_depth")? {
            self.anderson_depth = options::as_usize(&v);
        }
        if let Some(v) = checked("interface_yield")? {
            self.interface_yield = InterfaceYield::ALL.into_iter().find(|x| x.name() == options::as_name(&v)).unwrap_or_default();
        }
        if let Some(v) = checked("wall_normal_stress")? {
            self.wall_normal_stress = if options::as_name(&v) == "total" { WallNormalStress::Total } else { WallNormalStress::Pressure };
        }
        if let Some(v) = checked("yield_pressure")? {
            self.yield_pressure = if options::as_name(&v) == "surface-air" { YieldPressure::SurfaceAir } else { YieldPressure::Absolute };
        }
        if let Some(v) = checked("sigma_location")? {
            self.sigma_location = SigmaLocation::from_name(options::as_name(&v)).unwrap_or_default();
        }
        if let Some(v) = checked("r_neighbourhood")? {
            self.r_neighbourhood = options::as_usize(&v);
        }
        if let Some(v) = checked("proximal_restarts")? {
            self.proximal_restarts = options::as_usize(&v);
        }
        if let Some(v) = checked("solver")? {
            self.solver = BiProjectionSolver::ALL.into_iter().find(|x| x.name() == options::as_name(&v)).unwrap_or_default();
        }
        if let Some(v) = checked("newton_tol")? {
            self.newton_tol = v.as_f64().unwrap_or(self.newton_tol);
        }
        if let Some(v) = checked("newton_max_iterations")? {
            self.newton_max_iterations = options::as_usize(&v);
        }
        if let Some(v) = checked("wall_r")? {
            self.wall_r = crate::walls::WallR::ALL.into_iter().find(|x| x.name() == options::as_name(&v)).unwrap_or_default();
        }
        Ok(used)
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

    /// Checks every parameter against its spec, naming the first offending one.
    pub fn validate(&self) -> Result<()> {
        self.law.validate()?;
        for s in BI_PROJECTION_OPTIONS.iter().chain(RHEOLOGY_VARIANT_OPTIONS) {
            if s.key != "regularisation" {
                s.check(&self.get_option(s.key))?;
            }
        }
        match self.treatment {
            YieldTreatment::Projection => {}
            YieldTreatment::Papanastasiou { m } => options::spec(BI_PROJECTION_OPTIONS, "regularisation").check_f64(m)?,
            YieldTreatment::BiViscous { yield_viscosity } => options::spec(BI_PROJECTION_OPTIONS, "regularisation").check_f64(yield_viscosity)?,
        }
        options::spec(COULOMB_OPTIONS, "friction_angle").check_named("wall_friction_angle", &Value::opt_f64(self.wall_friction_angle))?;
        if let Some(w) = self.side_walls {
            options::spec(SIDE_WALL_OPTIONS, "width").check_named("side_walls.width", &Value::Float(w.width))?;
            options::spec(SIDE_WALL_OPTIONS, "friction_angle").check_named("side_walls.friction_angle", &Value::Float(w.friction_angle))?;
        }
        if self.solver == BiProjectionSolver::Newton && self.side_walls.is_some() {
            return Err(Error::param("solver", "'newton'", "'picard' with side walls (the exact step has no side-wall friction term)"));
        }
        if self.solver == BiProjectionSolver::Newton && self.treatment != YieldTreatment::Projection {
            return Err(Error::param(
                "solver",
                "'newton'",
                "'picard' with a regularised yield stress (plastic = 'papanastasiou' or 'bi-viscous': no bi-projection to solve)",
            ));
        }
        if self.anderson_depth > 0 && self.sigma_location == SigmaLocation::Centres {
            return Err(Error::param("anderson_depth", self.anderson_depth, "0 with sigma_location = 'centres' (Anderson mixing acts on the staggered Σ)"));
        }
        Ok(())
    }
}
