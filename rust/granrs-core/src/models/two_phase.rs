//! The two-phase model: configuration, state, and the work arrays of a step.
//!
//! State at t_n: u^n, v^n (MAC faces), u^{n−1}, v^{n−1} and (u·∇u)^{n−1} for BDF2, p^n (cell
//! centres), Φ^n (cell centres). The stages of a step are listed in `models/step.rs`.

use crate::diagnostics::EnergyLedger;
use crate::error::{check_finite, check_positive, Error, Result};
use crate::exec::{build_pool, Exec};
use crate::grid::{BoundaryConditions, Field, Grid, Location};
use crate::levelset::{dense_area, init_signed_distance, Interface, InterfaceTransport, PlicNormal, RedistanceSettings, Shape, VolumeFraction};
use crate::options::{self, Configurable, OptionMap, OptionSpec, Value};
use crate::pore_pressure::{PorePressure, PorePressureConfig};
use crate::projection::PressureStage;
use crate::properties::{MaterialProperties, PropertyLaws};
use crate::rheology::stage::RheologyState;
use crate::rheology::{RheologyConfig, RheologyLaw};
use crate::solvers::{SolveInfo, SolverSettings};
use crate::time_stepping::{MomentumSolver, StepInfo, TimeConfig, ViscousScheme};

/// A Newtonian material (or the Newtonian part of a granular one).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Density ρ [kg m⁻³] (for the granular mixture: φ ρ_s).
    pub density: f64,
    /// Dynamic viscosity η [Pa s].
    pub viscosity: f64,
}

impl Material {
    /// Checks both values are finite and positive, naming them `{prefix}.density` etc.
    pub fn validate(&self, prefix: &str) -> Result<()> {
        check_positive(&format!("{prefix}.density"), self.density)?;
        check_positive(&format!("{prefix}.viscosity"), self.viscosity)
    }
}

/// Discretisation of (u·∇)u.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConvectionScheme {
    /// Centred second order (non-dissipative; the validated single-phase default).
    Centred,
    /// Upwind WENO5 per derivative (dissipative at the grid scale; for high density ratios and
    /// under-resolved shear layers of the light phase).
    Weno5,
}

/// How the constant of the pressure is fixed when no side prescribes it (no `Outflow` side: the
/// pressure problem has a null space and the projection returns a zero-mean increment).
///
/// Only ∇p enters the momentum balance, but a pressure-dependent yield stress tan(α) p⁺ and the
/// Coulomb walls' τ_b = tan(α_b) p⁺ use p itself: its level must mean "atmospheric = 0", as with
/// the paper's open top (p = 0 there). With a zero-mean gauge the air sits at −⟨p⟩ (about
/// −145 Pa at the start of the paper's column, rising as it collapses), which leaves every layer
/// thinner than ⟨p⟩/(ρ g) ≈ 1 cm without friction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PressureGauge {
    /// `Top` when the rheology's yield stress or the walls' friction depend on p (Drucker–Prager,
    /// μ(I), Coulomb sides), `Mean` otherwise.
    Auto,
    /// ∫ p = 0 over the domain (the projection's own gauge).
    Mean,
    /// The mean of p over the top row of cells is 0 (a closed lid standing in for an open top).
    Top,
}

/// Everything that defines a model (grid, boundary conditions, materials, numerics).
#[derive(Clone, Debug)]
pub struct ModelConfig {
    pub grid: Grid,
    pub bc: BoundaryConditions,
    /// Gravity vector (g_x, g_y) [m s⁻²].
    pub gravity: [f64; 2],
    /// The phase where Φ > 0 (granular mixture, heavy fluid, or the only fluid).
    pub dense: Material,
    /// The phase where Φ < 0 (air); `None` for a single-phase flow.
    pub light: Option<Material>,
    /// Half-width ε of the smoothed interface, in units of h = min(dx, dy).
    pub interface_width: f64,
    /// Whether the level set is transported (false: a frozen interface).
    pub transport_interface: bool,
    /// Redistance the level set every this many steps (0: never).
    pub redistance_every: usize,
    /// Settings of the redistancing.
    pub redistance: RedistanceSettings,
    /// Global mass correction of the level set (off by default): after each interface update Φ is
    /// shifted by a constant so that the dense-phase area keeps its initial value.
    pub mass_correction: bool,
    /// How the interface is transported: the level set alone, or with the conservative volume
    /// fraction F from which Φ is rebuilt each step (`levelset/vof.rs`).
    pub interface_transport: InterfaceTransport,
    /// The PLIC normals' source with [`InterfaceTransport::Clsvof`].
    pub plic_normal: PlicNormal,
    pub viscous: ViscousScheme,
    pub pressure_solver: SolverSettings,
    pub time: TimeConfig,
    /// Number of threads of the model's rayon pool.
    pub threads: usize,
    /// The pore-pressure equation (None: not fluidised, the solve is skipped entirely).
    pub pore: Option<PorePressureConfig>,
    /// Rheology of the dense phase (yield stress, its treatment) and Coulomb wall friction.
    pub rheology: RheologyConfig,
    /// Whether the convective term ρ(u·∇)u is included (false: unsteady Stokes equations).
    pub convection: bool,
    /// Discretisation of the convective term (see `operators::kernels`).
    pub convection_scheme: ConvectionScheme,
    /// Relative residual of the implicit viscous solve (tightened inside the Picard loop).
    pub viscous_rtol: f64,
    /// Iteration cap of the implicit viscous CG (reaching it is an error; default 2000).
    pub viscous_max_iterations: usize,
    /// How the pressure's constant is fixed when no side is an outflow (see [`PressureGauge`]).
    pub pressure_gauge: PressureGauge,
    /// The pressure update of the projection: `false` (default) the standard incremental form
    /// p^{n+1} = p^n + δp, `true` the rotational form p^{n+1} = p^n + δp − η div ũ
    /// (Timmermans, Minev & Van De Vosse 1996; Guermond, Minev & Shen 2006 §3.4), see
    /// `projection/mod.rs`. Two-phase projection only.
    pub rotational_pressure: bool,
    /// p is the pressure in excess of the light phase's hydrostatic pressure ρ_f g·x (the
    /// ambient air at rest): the body force becomes (ρ(Φ) − ρ_f) g. Needed where the light
    /// phase cannot be in hydrostatic balance in the box, as between the open sides of an
    /// x-invariant layer on a slope (tilted gravity), where the air would otherwise free-fall
    /// along the slope; the grains' effective pressure then also excludes the ambient one.
    /// Off by default (two-phase models only).
    pub ambient_hydrostatic: bool,
    /// Run each step on a window around the dense phase ([`super::active_region`]); None: on the
    /// whole domain.
    pub active_region: Option<super::active_region::ActiveRegion>,
    /// Value of the mean pressure over the top row of cells under the `Top` gauge (0: the lid's
    /// air at p = 0). An active window sets it to the air's hydrostatic pressure at its top row.
    pub pressure_top_value: f64,
    /// The `Top` gauge averages the top row over the cells i ≥ this (0: the whole row).
    pub pressure_top_from: usize,
    /// The granular-only model: the light phase is not resolved; the dense phase has a free
    /// surface at p = 0 (ghost-fluid Dirichlet), its velocity is extended into the light phase
    /// to transport Φ (`projection/free_surface.rs`). False: the two-phase model (default).
    pub free_surface: bool,
}

/// The options of [`ModelConfig`]'s own fields (the interface, the viscous and convective
/// terms, the pressure's gauge, the threads, the model of the air).
pub const MODEL_OPTIONS: &[OptionSpec] = &[
    options::float("interface", "interface_width", 1.5, 0.0, 10.0, "cells", "half-width ε/h of the smoothed interface (h = min(dx, dy))"),
    options::boolean("interface", "transport_interface", true, "whether the level set is transported (false: a frozen interface)"),
    options::int("interface", "redistance_every", 10, 0, 1_000_000, "steps", "redistance the level set every this many steps (0: never); with interface_transport = clsvof the level set is rebuilt from the volume fraction at every step instead and this is not read"),
    options::boolean(
        "interface",
        "mass_correction",
        false,
        "shift Φ by a constant after each interface update so that the dense-phase area keeps its initial value",
    ),
    options::choice(
        "interface",
        "interface_transport",
        "level-set",
        &["level-set", "clsvof"],
        "the interface's transport: the level set alone, or with the dense volume fraction F moved by conservative split PLIC fluxes (Weymouth & Yue 2010) and Φ rebuilt as the distance to F's interface each step (Sussman & Puckett 2000); clsvof conserves the dense volume without mass_correction",
    ),
    options::choice(
        "interface",
        "plic_normal",
        "level-set",
        &["level-set", "youngs"],
        "with interface_transport = clsvof: the normal of F's PLIC lines, −∇Φ (central differences) or Youngs's −∇F",
    )
    .variant(),
    options::choice(
        "model",
        "viscous",
        "implicit",
        &["implicit", "explicit"],
        "the viscous term: implicit (CG solve) or explicit (stable for δt below the viscous limit)",
    ),
    options::int(
        "model",
        "threads",
        1,
        1,
        1024,
        "threads",
        "size of the Rust thread pool, at most the free cores: its threads wait actively for work during a step (results are identical for any value)",
    ),
    options::boolean("model", "convection", true, "whether ρ(u·∇)u is included (false: unsteady Stokes equations)"),
    options::choice(
        "model",
        "convection_scheme",
        "centred",
        &["centred", "weno5"],
        "convective term: centred second order, or upwind WENO5 per derivative (damps an under-resolved shear layer)",
    ),
    options::float("model", "viscous_rtol", 1e-10, 1e-14, 1e-2, "1", "relative residual of the implicit viscous solve"),
    options::int("model", "viscous_max_iterations", 2000, 1, 100_000_000, "1", "iteration cap of the implicit viscous CG (reaching it is an error)"),
    options::choice(
        "model",
        "pressure_update",
        "standard",
        &["standard", "rotational"],
        "the projection's pressure update: p + δp, or the rotational p + δp − η div ũ (two-phase only)",
    ),
    options::boolean("model", "ambient_hydrostatic", false, "p is the pressure in excess of the light phase's hydrostatic one; body force (ρ − ρ_f) g"),
    options::choice(
        "model",
        "air",
        "resolved",
        &["resolved", "free-surface"],
        "the light phase: resolved (the two-phase model) or a free surface at p = 0 (the granular-only model)",
    ),
    options::choice(
        "model",
        "pressure_gauge",
        "auto",
        &["auto", "mean", "top"],
        "the pressure's constant without an outflow side: top when τ or the walls depend on p, else mean",
    )
    .variant(),
];

impl ConvectionScheme {
    /// Name used in Python and the docs.
    pub fn name(&self) -> &'static str {
        match self {
            ConvectionScheme::Centred => "centred",
            ConvectionScheme::Weno5 => "weno5",
        }
    }
}

impl PressureGauge {
    /// Name used in Python and the docs.
    pub fn name(&self) -> &'static str {
        match self {
            PressureGauge::Auto => "auto",
            PressureGauge::Mean => "mean",
            PressureGauge::Top => "top",
        }
    }
}

impl Configurable for ModelConfig {
    fn options() -> &'static [OptionSpec] {
        MODEL_OPTIONS
    }

    fn get(&self, key: &str) -> Value {
        let int = |n: usize| Value::Int(n.min(i64::MAX as usize) as i64);
        match key {
            "interface_width" => Value::Float(self.interface_width),
            "transport_interface" => Value::Bool(self.transport_interface),
            "redistance_every" => int(self.redistance_every),
            "mass_correction" => Value::Bool(self.mass_correction),
            "interface_transport" => Value::str(self.interface_transport.name()),
            "plic_normal" => Value::str(self.plic_normal.name()),
            "viscous" => Value::str(if self.viscous == ViscousScheme::Explicit { "explicit" } else { "implicit" }),
            "threads" => int(self.threads),
            "convection" => Value::Bool(self.convection),
            "convection_scheme" => Value::str(self.convection_scheme.name()),
            "viscous_rtol" => Value::Float(self.viscous_rtol),
            "viscous_max_iterations" => int(self.viscous_max_iterations),
            "pressure_update" => Value::str(if self.rotational_pressure { "rotational" } else { "standard" }),
            "ambient_hydrostatic" => Value::Bool(self.ambient_hydrostatic),
            "air" => Value::str(if self.free_surface { "free-surface" } else { "resolved" }),
            "pressure_gauge" => Value::str(self.pressure_gauge.name()),
            _ => Value::None,
        }
    }

    fn set(&mut self, key: &str, v: &Value) -> Result<()> {
        let name = options::as_name(v);
        match key {
            "interface_width" => self.interface_width = v.as_f64().unwrap_or(self.interface_width),
            "transport_interface" => self.transport_interface = options::as_bool(v),
            "redistance_every" => self.redistance_every = options::as_usize(v),
            "mass_correction" => self.mass_correction = options::as_bool(v),
            "interface_transport" => self.interface_transport = InterfaceTransport::from_name(name),
            "plic_normal" => self.plic_normal = PlicNormal::from_name(name),
            "viscous" => self.viscous = if name == "explicit" { ViscousScheme::Explicit } else { ViscousScheme::Implicit },
            "threads" => self.threads = options::as_usize(v),
            "convection" => self.convection = options::as_bool(v),
            "convection_scheme" => self.convection_scheme = if name == "weno5" { ConvectionScheme::Weno5 } else { ConvectionScheme::Centred },
            "viscous_rtol" => self.viscous_rtol = v.as_f64().unwrap_or(self.viscous_rtol),
            "viscous_max_iterations" => self.viscous_max_iterations = options::as_usize(v),
            "pressure_update" => self.rotational_pressure = name == "rotational",
            "ambient_hydrostatic" => self.ambient_hydrostatic = options::as_bool(v),
            "air" => self.free_surface = name == "free-surface",
            "pressure_gauge" => {
                self.pressure_gauge = match name {
                    "mean" => PressureGauge::Mean,
                    "top" => PressureGauge::Top,
                    _ => PressureGauge::Auto,
                }
            }
            _ => {}
        }
        Ok(())
    }
}

impl ModelConfig {
    /// Every option of the model's flat map, room by room: the model's own, the clock's, the
    /// pressure solve's, the redistancing's, the bi-projection's, the active region's and the
    /// variants. Their keys are unique. (The rheology law's parameters, the pore pressure, the
    /// Coulomb walls' angle and the side walls are objects of their own: see
    /// [`ModelConfig::object_schema`].)
    pub fn schema() -> Vec<&'static OptionSpec> {
        use crate::levelset::redistance::REDISTANCE_OPTIONS;
        use crate::models::active_region::ACTIVE_REGION_OPTIONS;
        use crate::rheology::{BI_PROJECTION_OPTIONS, RHEOLOGY_VARIANT_OPTIONS};
        use crate::solvers::PRESSURE_SOLVER_OPTIONS;
        use crate::time_stepping::clock::TIME_OPTIONS;
        [MODEL_OPTIONS, TIME_OPTIONS, PRESSURE_SOLVER_OPTIONS, REDISTANCE_OPTIONS, BI_PROJECTION_OPTIONS, ACTIVE_REGION_OPTIONS, RHEOLOGY_VARIANT_OPTIONS]
            .into_iter()
            .flatten()
            .collect()
    }

    /// The options of the objects a model is built from besides its flat options: the rheology
    /// laws' parameters, the pore pressure, the Coulomb walls and the side walls.
    pub fn object_schema() -> Vec<&'static OptionSpec> {
        use crate::pore_pressure::PORE_PRESSURE_OPTIONS;
        use crate::rheology::{BINGHAM_OPTIONS, COULOMB_OPTIONS, DRUCKER_PRAGER_OPTIONS, MU_I_OPTIONS, SIDE_WALL_OPTIONS};
        [BINGHAM_OPTIONS, DRUCKER_PRAGER_OPTIONS, MU_I_OPTIONS, PORE_PRESSURE_OPTIONS, COULOMB_OPTIONS, SIDE_WALL_OPTIONS].into_iter().flatten().collect()
    }

    /// Sets the options of `map` (keys of [`ModelConfig::schema`], each checked against its
    /// spec: the error names the key and its allowed values); an unknown key is refused.
    pub fn apply_options(&mut self, map: &OptionMap) -> Result<()> {
        let schema = Self::schema();
        if let Some(k) = map.keys().find(|k| !schema.iter().any(|s| s.key == k.as_str())) {
            return Err(options::unknown_key(k, &schema));
        }
        options::apply(self, map)?;
        options::apply(&mut self.time, map)?;
        options::apply(&mut self.pressure_solver, map)?;
        options::apply(&mut self.redistance, map)?;
        self.rheology.apply_options(map)?;
        if crate::models::active_region::ACTIVE_REGION_OPTIONS.iter().any(|s| map.contains_key(s.key)) {
            let mut full = self.active_region_options();
            full.extend(map.iter().filter(|(k, _)| k.starts_with("active_region")).map(|(k, v)| (k.clone(), v.clone())));
            self.active_region = super::active_region::ActiveRegion::from_options(&full)?;
        }
        Ok(())
    }

    fn active_region_options(&self) -> OptionMap {
        super::active_region::ACTIVE_REGION_OPTIONS
            .iter()
            .map(|s| (s.key.to_string(), super::active_region::ActiveRegion::get_option(&self.active_region, s.key)))
            .collect()
    }

    /// Every option of [`ModelConfig::schema`] with its value in this configuration.
    pub fn to_options(&self) -> OptionMap {
        let mut m = options::to_map(self);
        m.extend(options::to_map(&self.time));
        m.extend(options::to_map(&self.pressure_solver));
        m.extend(options::to_map(&self.redistance));
        for s in crate::rheology::BI_PROJECTION_OPTIONS.iter().chain(crate::rheology::RHEOLOGY_VARIANT_OPTIONS) {
            m.insert(s.key.to_string(), self.rheology.get_option(s.key));
        }
        m.extend(self.active_region_options());
        m
    }

    /// A single-phase configuration with the options of `map` (the others at their defaults).
    pub fn from_options(grid: Grid, bc: BoundaryConditions, fluid: Material, map: &OptionMap) -> Result<Self> {
        let mut cfg = Self::single_phase(grid, bc, fluid);
        cfg.apply_options(map)?;
        Ok(cfg)
    }

    /// A single-phase configuration with the default options.
    pub fn single_phase(grid: Grid, bc: BoundaryConditions, fluid: Material) -> Self {
        let o = |k| options::spec(MODEL_OPTIONS, k);
        let mut cfg = ModelConfig {
            grid,
            bc,
            gravity: [0.0, 0.0],
            dense: fluid,
            light: None,
            interface_width: o("interface_width").float(),
            transport_interface: o("transport_interface").bool(),
            redistance_every: o("redistance_every").usize(),
            redistance: RedistanceSettings::default(),
            mass_correction: o("mass_correction").bool(),
            interface_transport: InterfaceTransport::LevelSet,
            plic_normal: PlicNormal::LevelSet,
            viscous: ViscousScheme::Implicit,
            pressure_solver: SolverSettings::default(),
            time: TimeConfig::default(),
            threads: o("threads").usize(),
            pore: None,
            rheology: RheologyConfig::default(),
            convection: o("convection").bool(),
            convection_scheme: ConvectionScheme::Centred,
            viscous_rtol: o("viscous_rtol").float(),
            viscous_max_iterations: o("viscous_max_iterations").usize(),
            pressure_gauge: PressureGauge::Auto,
            rotational_pressure: false,
            ambient_hydrostatic: o("ambient_hydrostatic").bool(),
            active_region: None,
            pressure_top_value: 0.0,
            pressure_top_from: 0,
            free_surface: false,
        };
        for key in ["viscous", "convection_scheme", "pressure_gauge", "pressure_update", "air", "interface_transport", "plic_normal"] {
            let d = o(key).default.clone();
            cfg.set(key, &d).expect("a default choice");
        }
        cfg
    }

    /// The laws of step 2 (the properties room's [`PropertyLaws`]): the phases' densities and
    /// viscosities, ε = `interface_width` h, the granular-only model's face density.
    #[inline]
    pub(crate) fn property_laws(&self) -> PropertyLaws {
        let light = self.light.unwrap_or(self.dense);
        PropertyLaws {
            dense_density: self.dense.density,
            dense_viscosity: self.dense.viscosity,
            light_density: light.density,
            light_viscosity: light.viscosity,
            eps: self.interface_width * self.grid.h(),
            free_surface: self.free_surface,
        }
    }

    /// Density of a face between cells whose level set is `a` and `b` (step 2 of the paper,
    /// [`PropertyLaws::face_density`]).
    #[inline]
    pub(crate) fn face_density(&self, a: f64, b: f64) -> f64 {
        self.property_laws().face_density(a, b)
    }

    /// Whether the momentum of a face between cells `a` and `b` is solved for
    /// ([`PropertyLaws::face_is_solved`]).
    #[inline]
    pub(crate) fn face_is_solved(&self, a: f64, b: f64) -> bool {
        self.property_laws().face_is_solved(a, b)
    }

    /// The reference density of the body force: ρ_f with `ambient_hydrostatic`, else 0.
    pub fn reference_density(&self) -> f64 {
        match self.light {
            Some(l) if self.ambient_hydrostatic => l.density,
            _ => 0.0,
        }
    }

    /// The gauge in force: `None` when a side fixes p (an outflow), else `Mean` or `Top` with
    /// `Auto` resolved (see [`PressureGauge::Auto`]).
    pub fn resolved_pressure_gauge(&self) -> Option<PressureGauge> {
        use crate::grid::{PressureBc, Side};
        if self.free_surface || [Side::Left, Side::Right, Side::Bottom, Side::Top].iter().any(|&s| self.bc.pressure(s) == PressureBc::Dirichlet) {
            return None;
        }
        Some(match self.pressure_gauge {
            PressureGauge::Auto => {
                let pressure_law = matches!(self.rheology.law, RheologyLaw::DruckerPrager { .. } | RheologyLaw::MuI { .. });
                let coulomb = self.rheology.wall_friction_angle.is_some()
                    && [Side::Left, Side::Right, Side::Bottom, Side::Top].iter().any(|&s| self.bc.get(s) == crate::grid::VelocityBc::Coulomb);
                if pressure_law || coulomb {
                    PressureGauge::Top
                } else {
                    PressureGauge::Mean
                }
            }
            g => g,
        })
    }

    /// Checks every parameter, naming the first offending one and its allowed range.
    pub fn validate(&self) -> Result<()> {
        self.bc.validate(self.grid.lx, self.grid.ly)?;
        check_finite("gravity.x", self.gravity[0])?;
        check_finite("gravity.y", self.gravity[1])?;
        self.dense.validate("dense")?;
        if let Some(l) = &self.light {
            l.validate("light")?;
        }
        options::validate_all(self)?;
        self.redistance.validate()?;
        self.pressure_solver.validate()?;
        self.time.validate()?;
        if let Some(pc) = &self.pore {
            pc.validate()?;
        }
        self.rheology.validate()?;
        if self.rheology.solver == crate::rheology::BiProjectionSolver::Newton && self.viscous == ViscousScheme::Explicit {
            return Err(Error::param("solver", "'newton'", "'picard' with viscous = 'explicit' (the exact step solves the implicit predictor)"));
        }
        if self.free_surface && self.light.is_none() {
            return Err(Error::param("free_surface", "true", "false for a single-phase model (the free surface is the interface Φ = 0 with a light phase)"));
        }
        if self.interface_transport == InterfaceTransport::Clsvof && self.light.is_some() {
            // F is the conserved volume and Φ is rebuilt from it: a shift of Φ or a removal of
            // its pieces would be undone by the next rebuild and break Φ's agreement with F
            if self.mass_correction {
                return Err(Error::param(
                    "mass_correction",
                    "true",
                    "false with interface_transport = 'clsvof' (the volume fraction conserves the dense volume itself)",
                ));
            }
            if self.redistance.piece_removal_cells > 0 {
                return Err(Error::param("piece_removal_cells", self.redistance.piece_removal_cells, "0 with interface_transport = 'clsvof'"));
            }
        }
        if self.free_surface && self.rotational_pressure {
            return Err(Error::param(
                "pressure_update",
                "rotational",
                "'standard' with the granular-only model (its free-surface projection has the standard update only)",
            ));
        }
        TwoPhaseModel::validate_active_region(self)?;
        check_finite("pressure_top_value", self.pressure_top_value)?;
        Ok(())
    }
}

/// Work arrays of a step (allocated once).
pub(crate) struct Work {
    pub conv_u: Field,
    pub conv_v: Field,
    pub rhs_u: Field,
    pub rhs_v: Field,
    pub gx: Field,
    pub gy: Field,
    pub c_u: Field,
    pub c_v: Field,
    /// p + p_f, whose gradient drives the predictor.
    pub ptot: Field,
}

/// The paper's unified two-phase model (eq. 10), or a single-phase Navier–Stokes model: the
/// shared fields (u, p, Φ and the BDF2 history), the rooms' states (the interface, the pore
/// pressure, the rheology, the pressure projection, the momentum solver) and the clock. The
/// stages are called, in order, by `models/step.rs` alone.
pub struct TwoPhaseModel {
    pub(crate) config: ModelConfig,
    pub(crate) pool: std::sync::Arc<rayon::ThreadPool>,
    /// x-velocity u^n on XFace.
    pub u: Field,
    /// y-velocity v^n on YFace.
    pub v: Field,
    /// u^{n−1}, v^{n−1}.
    pub u_prev: Field,
    pub v_prev: Field,
    /// (u·∇)u at t_{n−1}.
    pub(crate) conv_prev_u: Field,
    pub(crate) conv_prev_v: Field,
    /// Pressure p^n (cell centres).
    pub p: Field,
    /// Level set Φ^n (cell centres; > 0 in the dense phase).
    pub phi: Field,
    pub(crate) work: Work,
    /// The properties room: ρ on the faces, η at centres and nodes (step 2).
    pub(crate) properties: MaterialProperties,
    /// The interface room: level-set transport and redistancing.
    pub(crate) levelset: Interface,
    /// Pore gas pressure (None when not fluidised).
    pub pore: Option<PorePressure>,
    /// The pressure projection room (the free-surface projection with
    /// `ModelConfig::free_surface`).
    pub(crate) pressure: PressureStage,
    pub(crate) momentum: MomentumSolver,
    /// Plastic tensor, wall friction and their work arrays (None: Newtonian without friction).
    pub(crate) rheology: Option<RheologyState>,
    /// Simulated time t_n.
    pub time: f64,
    /// Steps taken.
    pub step_count: u64,
    /// δt_{n−1} (None before the first step).
    pub dt_prev: Option<f64>,
    /// What the last step did.
    pub last: StepInfo,
    /// Time left to a target time the next step must not overshoot.
    pub(crate) time_to_land: Option<f64>,
    /// Dense-phase area the mass correction restores (set when Φ is set).
    pub reference_area: f64,
    /// The active window's model (with [`ModelConfig::active_region`]; None until the first step
    /// and after the state was changed from outside, when it is rebuilt from this model's state).
    pub(crate) window: Option<Box<TwoPhaseModel>>,
    /// Whether this model's fields lag the window's state: a window's step copies back only
    /// the clock, and the fields follow when the call returns (within
    /// [`TwoPhaseModel::advance`], once at its end).
    pub(crate) window_ahead: bool,
    /// The window size a restored checkpoint held (its next step rebuilds the window at it,
    /// as the uninterrupted run keeps its window; `models/window.rs`).
    pub(crate) restored_window: Option<(usize, usize)>,
    /// Ceiling on δt lowered by a rejected step (`TimeConfig::step_retries`), recovering by
    /// [`crate::time_stepping::DT_CEILING_RECOVERY`] per accepted step (∞: none).
    pub dt_ceiling: f64,
    /// δt of the step in progress (the one a rejection halves).
    pub(crate) dt_attempt: f64,
    /// The state before the step in progress (reused buffers; only with step retries).
    pub(crate) step_snapshot: Vec<crate::grid::StateEntry>,
    /// Time integrals of the mechanical energy budget (`diagnostics/energy.rs`).
    pub(crate) energy: EnergyLedger,
}

impl TwoPhaseModel {
    /// Builds a model at rest (u = 0, p = 0, Φ = +1 everywhere: only the dense phase).
    pub fn new(config: ModelConfig) -> Result<Self> {
        config.validate()?;
        // refused before anything is allocated when it would not fit (models/memory.rs)
        config.check_memory()?;
        let g = &config.grid;
        let pool = std::sync::Arc::new(build_pool(config.threads)?);
        let c = || Field::zeros(g, Location::Centre);
        let xf = || Field::zeros(g, Location::XFace);
        let yf = || Field::zeros(g, Location::YFace);
        let mut phi = c();
        phi.fill(1.0);
        let pressure = PressureStage::new(g, &config.bc, config.pressure_solver, config.free_surface)?;
        let mut momentum = MomentumSolver::new(g);
        momentum.rtol = config.viscous_rtol;
        momentum.max_iterations = config.viscous_max_iterations;
        let rheology = RheologyState::new(g, &config.bc, &config.rheology);
        let work = Work { conv_u: xf(), conv_v: yf(), rhs_u: xf(), rhs_v: yf(), gx: xf(), gy: yf(), c_u: xf(), c_v: yf(), ptot: c() };
        let pore = match &config.pore {
            Some(pc) => Some(PorePressure::new(g, *pc, config.pressure_solver)?),
            None => None,
        };
        let mut levelset = Interface::new(g, config.redistance)?;
        if config.interface_transport == InterfaceTransport::Clsvof && config.light.is_some() {
            let mut vof = VolumeFraction::new(g, config.plic_normal);
            vof.f.fill(1.0);
            levelset.vof = Some(vof);
        }
        let mut model = TwoPhaseModel {
            levelset,
            u: xf(),
            v: yf(),
            u_prev: xf(),
            v_prev: yf(),
            conv_prev_u: xf(),
            conv_prev_v: yf(),
            p: c(),
            phi,
            work,
            properties: MaterialProperties::new(g),
            pore,
            pressure,
            momentum,
            rheology,
            time: 0.0,
            step_count: 0,
            dt_prev: None,
            last: StepInfo::default(),
            time_to_land: None,
            reference_area: 0.0,
            window: None,
            window_ahead: false,
            restored_window: None,
            dt_ceiling: f64::INFINITY,
            dt_attempt: 0.0,
            step_snapshot: Vec::new(),
            energy: EnergyLedger::default(),
            pool,
            config,
        };
        model.start_energy_budget();
        Ok(model)
    }

    /// The last pressure increment δp of whichever projection the model uses (row-major, the
    /// warm start of the next one), for checkpoints and the active window.
    pub(crate) fn pressure_increment(&self) -> &[f64] {
        self.pressure.increment()
    }

    pub(crate) fn pressure_increment_mut(&mut self) -> &mut [f64] {
        self.pressure.increment_mut()
    }

    /// Takes steps until the time `t_end` (the steps land on it: [`TwoPhaseModel::set_time_to_land`])
    /// or until `max_steps` steps (None: no limit; at least one of the two must be given).
    /// Returns the diagnostics of the steps taken and the error that stopped the run, if one did:
    /// the model is then at its last accepted state. With an active region the whole-domain
    /// fields are copied from the window once, when the call returns, not after every step.
    pub fn advance(&mut self, t_end: Option<f64>, max_steps: Option<u64>) -> (Vec<StepInfo>, Option<Error>) {
        let mut log = Vec::new();
        let limit = max_steps.unwrap_or(u64::MAX);
        let mut err = None;
        while (log.len() as u64) < limit {
            if let Some(t) = t_end {
                let remaining = t - self.time;
                if remaining <= 1e-12 * t.abs().max(1e-300) {
                    break;
                }
                // land on t_end: a fixed step is shortened; the adaptive one is capped
                self.set_time_to_land(Some(remaining));
            }
            match self.step_leaving_window() {
                Ok(s) => log.push(s),
                Err(e) => {
                    err = Some(e);
                    break;
                }
            }
        }
        self.sync_from_window();
        self.set_time_to_land(None);
        (log, err)
    }

    /// Makes the next steps land exactly on a target time `remaining` ahead: a step longer than
    /// what is left is shortened to it, and one between one and two steps short is halved (no
    /// tiny last step, which would hold back the step growth afterwards).
    pub fn set_time_to_land(&mut self, remaining: Option<f64>) {
        self.time_to_land = remaining;
    }

    /// Initialises Φ as the exact signed distance to `shape` (Φ > 0 inside).
    pub fn set_shape(&mut self, shape: &Shape) -> Result<()> {
        init_signed_distance(shape, &self.config.grid, &mut self.phi)?;
        self.fields_changed();
        Ok(())
    }

    /// Area of the dense phase {Φ > 0} (sub-cell accurate).
    pub fn dense_area(&self) -> f64 {
        dense_area(&self.phi, &self.config.grid, self.exec())
    }

    /// The dense volume fraction F (cell centres), with `interface_transport = "clsvof"`.
    pub fn volume_fraction(&self) -> Option<&Field> {
        self.levelset.vof.as_ref().map(|v| &v.f)
    }

    /// The conserved dense volume Σ F δx δy (m² per unit depth), with
    /// `interface_transport = "clsvof"`.
    pub fn dense_volume(&self) -> Option<f64> {
        self.levelset.vof.as_ref().map(|v| v.volume(&self.config.grid, self.exec()))
    }

    /// The dense volume's budget of the last step ([`crate::levelset::VolumeBudget`]), with
    /// `interface_transport = "clsvof"`.
    pub fn volume_budget(&self) -> Option<crate::levelset::VolumeBudget> {
        self.levelset.vof.as_ref().map(|v| v.budget)
    }

    /// The configuration.
    pub fn config(&self) -> &ModelConfig {
        &self.config
    }

    /// The grid.
    pub fn grid(&self) -> &Grid {
        &self.config.grid
    }

    /// Execution policy of the model's kernels.
    pub fn exec(&self) -> Exec {
        Exec::with_threads(self.config.threads)
    }

    /// Tells the model that fields were changed from outside (initial conditions): material
    /// properties are recomputed and the BDF2 history restarts with a first-order step.
    pub fn fields_changed(&mut self) {
        self.window = None;
        // F from the new Φ (the area of each cell on Φ's side of its closest interface line)
        if let Some(vof) = self.levelset.vof.as_mut() {
            vof.set_from_level_set(&mut self.phi, &self.config.grid);
        }
        self.properties.invalidate();
        self.dt_prev = None;
        self.reference_area = self.dense_area();
        self.start_energy_budget();
    }

    /// Density on u and v faces as last computed.
    pub fn face_density(&self) -> (&Field, &Field) {
        self.properties.density()
    }

    /// Viscosity at centres and nodes as last computed.
    pub fn viscosity(&self) -> (&Field, &Field) {
        self.properties.viscosity()
    }

    /// The last pressure solve.
    pub fn last_pressure_solve(&self) -> SolveInfo {
        self.last.pressure
    }
}
