//! Pore gas pressure p_f (Aravena et al. eq. 2 third line and eq. 10f; boundary and initial
//! conditions §2.3; time discretisation §3.1 step 3):
//!
//!   ∂_t p_f + div(u p_f) = div(κ(Φ) ∇p_f)            (10f, with ∇ restored: docs/reference-data.md, "The paper")
//!
//! Two time schemes ([`PoreTimeScheme`]):
//!
//! - `Implicit` (default): BDF2 with extrapolated advection and implicit diffusion (so that δt is
//!   not bounded by h²/κ), second order in time:
//!
//!   (a₀ p^{n+1} − a₁ p^n + a₂ p^{n−1})/δt + (1+ω) div(uⁿ pⁿ) − ω div(uⁿ⁻¹ pⁿ⁻¹) − div(κ ∇p^{n+1}) = 0;
//!
//!   the system (a₀/δt − div κ∇) p = R is solved with the project's multigrid-preconditioned CG
//!   (a Poisson operator with a diagonal shift).
//! - `Explicit`: forward Euler, first order in time, the same advection and diffusion fluxes:
//!
//!   (p^{n+1} − p^n)/δt + div(uⁿ pⁿ) − div(κ ∇pⁿ) = 0,
//!
//!   with only the sub-cell Dirichlet term of the interface (below) taken at n+1 (it is diagonal:
//!   a division, no solve). Then p^{n+1} is a convex combination of pⁿ at the cell and its
//!   neighbours plus δt × the sources iff δt κ Σ_faces 1/h² ≤ 1, i.e. (von Neumann and the
//!   discrete maximum principle agree for the 5-point Laplacian, whose largest eigenvalue is
//!   4κ(1/dx² + 1/dy²); e.g. Morton & Mayers, *Numerical Solution of PDEs*, 2005, §2.6, §3.3)
//!
//!   δt ≤ δt_exp = 1/(2κ(1/dx² + 1/dy²))  = h²/(4κ) on square cells.
//!
//!   Beyond it the checkerboard mode grows by |1 − 2δt/δt_exp| per step. Each explicit step
//!   checks the maximum principle |p^{n+1}| ≤ max|pⁿ| + δt |sources| (which holds exactly below
//!   the limit) and stops with [`Error::Simulation`] naming the cell when it fails or p_f is not
//!   finite. The check is the monotonicity of the scheme: in a bounded box the largest eigenvalue
//!   is slightly below 4κ(1/dx² + 1/dy²) (by 0.4 % on 32 × 32 cells, 8 % on 4 columns), so just
//!   above δt_exp a grid-scale extremum is reported while its L2 growth is still below 1; on an
//!   unbounded grid both limits coincide. Only with the granular-only formulation: κ∞ = 1e16 in
//!   the air would make δt_exp ≈ 0.
//!
//! Second-order finite volumes in space: advective flux u_f (p_L + p_R)/2 on each face, diffusive
//! flux κ (p_R − p_L)/h.
//!
//! Two formulations of what happens outside the granular phase:
//! - [`PoreFormulation::GranularOnly`] (default): the equation is solved only where Φ > 0, with
//!   p_f = 0 on the air interface imposed at its sub-cell position (ghost-fluid Dirichlet
//!   condition of Gibou, Fedkiw, Cheng & Kang 2002, *J. Comput. Phys.* 176: a face crossing the
//!   interface at the fraction θ = Φ_in/(Φ_in − Φ_out) contributes κ/(θh²) to the diagonal);
//!   p_f = 0 in the air.
//! - [`PoreFormulation::KappaInfinity`]: the paper's κ(Φ) = κ_f H_ε(Φ) + κ_∞ (1 − H_ε(Φ)) on the whole
//!   domain (κ_∞ = 1e16 in the paper), with p_f = 0 on the open top of the domain so that the
//!   extension into the air is zero.
//!
//! Boundary conditions: ∂p_f/∂y = `basal_flux.gradient` on the base for x in [x_min, x_max]
//! (the paper's air supply under the reservoir, gradient −β φ ρ_s g, which keeps the initial
//! profile β φ ρ_s g (H_c − y) stationary at rest); homogeneous Neumann elsewhere.

use crate::error::{Error, Result};
use crate::exec::Exec;
use crate::grid::{Field, Grid, Location, PressureBc, HALO};
use crate::levelset::{heaviside, interface_diagonal};
use crate::operators::for_each_interior_row;
use crate::options::{self, OptionSpec, Value};
use crate::solvers::{ShiftedSystem, SolveInfo, SolverSettings};

/// What p_f does outside the granular phase.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PoreFormulation {
    /// Solve only where Φ > 0, p_f = 0 on the interface (sub-cell) and in the air.
    GranularOnly,
    /// The paper's whole-domain formulation with diffusivity `kappa_air` in the air. `smoothed`:
    /// κ(Φ) = κ_f H_ε(Φ) + κ_∞(1 − H_ε(Φ)) literally (the paper); its p_f = 0 boundary then sits
    /// where H_ε reaches 1, about ε inside the grains. Sharp: a face crossed by the interface at
    /// the fraction θ gets the series value 1/(θ/κ_f + (1 − θ)/κ_∞), which puts the boundary at
    /// Φ = 0 (and tends to the granular-only solve as κ_∞ → ∞).
    KappaInfinity { kappa_air: f64, smoothed: bool },
}

impl PoreFormulation {
    /// Name used in Python and the docs.
    pub fn name(&self) -> &'static str {
        match self {
            PoreFormulation::GranularOnly => "granular-only",
            PoreFormulation::KappaInfinity { smoothed: false, .. } => "kappa-infinity",
            PoreFormulation::KappaInfinity { smoothed: true, .. } => "kappa-infinity-smoothed",
        }
    }
}

/// Time discretisation of the pore-pressure equation (see the module header).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PoreTimeScheme {
    /// BDF2, implicit diffusion (unconditionally stable for the diffusion; default).
    Implicit,
    /// Forward Euler, explicit diffusion: stable for δt ≤ h²/(4κ).
    Explicit,
}

impl PoreTimeScheme {
    /// Name used in Python and the docs.
    pub fn name(&self) -> &'static str {
        match self {
            PoreTimeScheme::Implicit => "implicit",
            PoreTimeScheme::Explicit => "explicit",
        }
    }
}

/// Prescribed ∂p_f/∂y on part of the base.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BasalFlux {
    /// ∂p_f/∂y on the base [Pa/m] (negative: air injected upwards).
    pub gradient: f64,
    /// Extent of the supply along the base [m].
    pub x_min: f64,
    pub x_max: f64,
}

/// Parameters of the pore-pressure equation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PorePressureConfig {
    /// Diffusion coefficient κ_f [m² s⁻¹] in the granular phase.
    pub diffusivity: f64,
    pub formulation: PoreFormulation,
    pub basal_flux: Option<BasalFlux>,
    /// Implicit (BDF2) or explicit (forward Euler) diffusion.
    pub time_scheme: PoreTimeScheme,
}

/// The options of [`PorePressureConfig`] (the pore-pressure equation, eq. 10f).
pub const PORE_PRESSURE_OPTIONS: &[OptionSpec] = &[
    options::float("pore_pressure", "diffusivity", 0.035, 1e-12, 1e6, "m2 s-1", "κ_f, diffusion coefficient of the pore pressure in the granular phase (the paper: 0.035)").required(),
    options::float("pore_pressure", "basal_gradient", 0.0, -1e12, 1e12, "Pa m-1", "∂p_f/∂y on the base between basal_x_min and basal_x_max (negative: air injected upwards; None: no supply)").off_by_default(),
    options::float("pore_pressure", "basal_x_min", 0.0, f64::NEG_INFINITY, f64::INFINITY, "m", "start of the basal supply along the base (None: the left end)").off_by_default(),
    options::float("pore_pressure", "basal_x_max", 0.0, f64::NEG_INFINITY, f64::INFINITY, "m", "end of the basal supply along the base (None: the right end)").off_by_default(),
    options::choice("pore_pressure", "time_scheme", "implicit", &["implicit", "explicit"], "BDF2 with implicit diffusion, or forward Euler (stable for δt ≤ h²/(4κ); granular-only only)"),
    options::choice("pore_pressure", "formulation", "granular-only", &["granular-only", "kappa-infinity", "kappa-infinity-smoothed"], "p_f outside the grains: p_f = 0 on the interface (granular-only), κ_∞ in the air with a sharp interface, or the paper's smoothed κ(Φ) = κ_f H_ε + κ_∞(1 − H_ε)").variant(),
    options::float("pore_pressure", "kappa_air", 1e16, 1.0, 1e16, "m2 s-1", "κ_∞, diffusivity in the air of the kappa-infinity formulations (the paper: 1e16)").variant(),
];

impl PorePressureConfig {
    /// The configuration of the options in `map` (checked against [`PORE_PRESSURE_OPTIONS`];
    /// `diffusivity` is required, the others take their defaults). Unknown keys are refused.
    pub fn from_options(map: &options::OptionMap) -> Result<Self> {
        for k in map.keys() {
            if !PORE_PRESSURE_OPTIONS.iter().any(|s| s.key == k) {
                return Err(Error::param(
                    "pore_pressure",
                    k,
                    &format!("a key of the pore pressure, one of {}", PORE_PRESSURE_OPTIONS.iter().map(|s| s.key).collect::<Vec<_>>().join(", ")),
                ));
            }
        }
        let get = |k: &str| -> Result<Value> {
            let s = options::spec(PORE_PRESSURE_OPTIONS, k);
            s.check_named(&format!("pore_pressure.{k}"), map.get(k).unwrap_or(&s.default))
        };
        let kappa_air = get("kappa_air")?.as_f64().unwrap_or(f64::INFINITY);
        let formulation = match options::as_name(&get("formulation")?) {
            "kappa-infinity" => PoreFormulation::KappaInfinity { kappa_air, smoothed: false },
            "kappa-infinity-smoothed" => PoreFormulation::KappaInfinity { kappa_air, smoothed: true },
            _ => PoreFormulation::GranularOnly,
        };
        let basal_flux = get("basal_gradient")?.as_f64().map(|g| -> Result<BasalFlux> {
            Ok(BasalFlux {
                gradient: g,
                x_min: get("basal_x_min")?.as_f64().unwrap_or(f64::NEG_INFINITY),
                x_max: get("basal_x_max")?.as_f64().unwrap_or(f64::INFINITY),
            })
        });
        let time_scheme = if options::as_name(&get("time_scheme")?) == "explicit" { PoreTimeScheme::Explicit } else { PoreTimeScheme::Implicit };
        let cfg =
            PorePressureConfig { diffusivity: get("diffusivity")?.as_f64().unwrap_or(0.0), formulation, basal_flux: basal_flux.transpose()?, time_scheme };
        cfg.validate()?;
        Ok(cfg)
    }

    /// Every option with its value (the inverse of [`PorePressureConfig::from_options`]).
    pub fn to_options(&self) -> options::OptionMap {
        let kappa = match self.formulation {
            PoreFormulation::KappaInfinity { kappa_air, .. } => kappa_air,
            PoreFormulation::GranularOnly => options::spec(PORE_PRESSURE_OPTIONS, "kappa_air").float(),
        };
        let b = self.basal_flux;
        let finite = |x: f64| if x.is_finite() { Value::Float(x) } else { Value::None };
        [
            ("diffusivity", Value::Float(self.diffusivity)),
            ("basal_gradient", Value::opt_f64(b.map(|b| b.gradient))),
            ("basal_x_min", b.map_or(Value::None, |b| finite(b.x_min))),
            ("basal_x_max", b.map_or(Value::None, |b| finite(b.x_max))),
            ("time_scheme", Value::str(self.time_scheme.name())),
            ("formulation", Value::str(self.formulation.name())),
            ("kappa_air", Value::Float(kappa)),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect()
    }

    /// Checks the parameters against [`PORE_PRESSURE_OPTIONS`], naming the offending one.
    pub fn validate(&self) -> Result<()> {
        let o = |k| options::spec(PORE_PRESSURE_OPTIONS, k);
        o("diffusivity").check_f64(self.diffusivity)?;
        if let PoreFormulation::KappaInfinity { kappa_air, .. } = self.formulation {
            o("kappa_air").check_f64(kappa_air)?;
            if self.time_scheme == PoreTimeScheme::Explicit {
                return Err(Error::param(
                    "time_scheme",
                    "explicit",
                    &format!("'implicit' with formulation '{}' (κ = kappa_air = {kappa_air:e} m²/s in the air makes the explicit limit h²/(4κ) vanish); 'explicit' only with 'granular-only'", self.formulation.name()),
                ));
            }
        }
        if let Some(b) = self.basal_flux {
            o("basal_gradient").check_named("basal_flux.gradient", &Value::Float(b.gradient))?;
            if b.x_min.is_nan() || b.x_max.is_nan() || b.x_max < b.x_min {
                return Err(Error::param("basal_flux.x_max", b.x_max, &format!("a position >= basal_flux.x_min = {}", b.x_min)));
            }
        }
        Ok(())
    }
}

/// State and solver of the pore-pressure equation.
pub struct PorePressure {
    pub config: PorePressureConfig,
    /// p_f^n at cell centres.
    pub pf: Field,
    /// p_f^{n−1}.
    pub pf_prev: Field,
    /// div(u p_f) at t_{n−1}.
    pub(crate) adv_prev: Field,
    adv: Field,
    /// The shifted system of the implicit step (face coefficients also used by the explicit one).
    sys: ShiftedSystem,
    /// The last solve.
    pub last: SolveInfo,
}

impl PorePressure {
    /// A pore-pressure solver on `grid` (p_f = 0 initially).
    pub fn new(grid: &Grid, config: PorePressureConfig, settings: SolverSettings) -> Result<Self> {
        config.validate()?;
        let bc = match config.formulation {
            PoreFormulation::GranularOnly => [PressureBc::Neumann; 4],
            PoreFormulation::KappaInfinity { .. } => [PressureBc::Neumann, PressureBc::Neumann, PressureBc::Neumann, PressureBc::Dirichlet],
        };
        Ok(PorePressure {
            config,
            pf: Field::zeros(grid, Location::Centre),
            pf_prev: Field::zeros(grid, Location::Centre),
            adv_prev: Field::zeros(grid, Location::Centre),
            adv: Field::zeros(grid, Location::Centre),
            sys: ShiftedSystem::new(grid.nx, grid.ny, grid.dx, grid.dy, bc, settings)?,
            last: SolveInfo::default(),
        })
    }

    /// Advances p_f to t_{n+1}. `phi` is Φ^{n+1} (ghosts filled), `u`, `v` are uⁿ (ghosts
    /// filled), (a₀, a₁, a₂, ω) the BDF2 coefficients, `first` true for the BDF1 start, `eps` the
    /// Heaviside half-width.
    #[allow(clippy::too_many_arguments)]
    pub fn advance(
        &mut self,
        phi: &Field,
        u: &Field,
        v: &Field,
        grid: &Grid,
        dt: f64,
        coeffs: (f64, f64, f64, f64),
        first: bool,
        eps: f64,
        exec: Exec,
    ) -> Result<SolveInfo> {
        let (a0, a1, a2, w) = coeffs;
        let nx = grid.nx;
        let (dx, dy) = (grid.dx, grid.dy);
        // advection A^n = div(uⁿ pⁿ), centred fluxes; boundary normal velocities are zero or prescribed
        self.pf.extrapolate_ghosts_constant();
        {
            let (ps, us, vs) = (self.pf.slice(), u.slice(), v.slice());
            let (sp, su, sv) = (self.pf.stride(), u.stride(), v.stride());
            for_each_interior_row(exec, &mut self.adv, |j, row| {
                let (bp, bpm, bpp) = ((j + HALO) * sp + HALO, (j + HALO - 1) * sp + HALO, (j + HALO + 1) * sp + HALO);
                let bu = (j + HALO) * su + HALO;
                let (bv0, bv1) = ((j + HALO) * sv + HALO, (j + HALO + 1) * sv + HALO);
                for i in 0..nx {
                    let fe = us[bu + i + 1] * 0.5 * (ps[bp + i] + ps[bp + i + 1]);
                    let fw = us[bu + i] * 0.5 * (ps[bp + i - 1] + ps[bp + i]);
                    let fn_ = vs[bv1 + i] * 0.5 * (ps[bp + i] + ps[bpp + i]);
                    let fs = vs[bv0 + i] * 0.5 * (ps[bpm + i] + ps[bp + i]);
                    row[HALO + i] = (fe - fw) / dx + (fn_ - fs) / dy;
                }
            });
        }
        let (we, wm) = if first { (1.0, 0.0) } else { (1.0 + w, w) };
        let kf = self.config.diffusivity;
        let inside = |k: f64| k > 0.0;
        // coefficients and right-hand side, row by row on the raw slices (elementwise: serial ==
        // parallel)
        let (ps, sp) = (phi.slice(), phi.stride());
        match self.config.formulation {
            PoreFormulation::GranularOnly => {
                exec.for_each_row(&mut self.sys.beta_x, nx + 1, |j, row| {
                    let b = (j + HALO) * sp + HALO;
                    for i in 0..=nx {
                        row[i] = if inside(ps[b + i - 1]) && inside(ps[b + i]) { kf } else { 0.0 };
                    }
                });
                exec.for_each_row(&mut self.sys.beta_y, nx, |j, row| {
                    let b = (j + HALO) * sp + HALO;
                    for i in 0..nx {
                        row[i] = if inside(ps[b - sp + i]) && inside(ps[b + i]) { kf } else { 0.0 };
                    }
                });
            }
            PoreFormulation::KappaInfinity { kappa_air, smoothed } => {
                let face = |a: f64, b: f64| -> f64 {
                    if smoothed {
                        let h = heaviside(0.5 * (a + b), eps);
                        kf * h + kappa_air * (1.0 - h)
                    } else if inside(a) == inside(b) {
                        if inside(a) {
                            kf
                        } else {
                            kappa_air
                        }
                    } else {
                        let (pin, pout) = if inside(a) { (a, b) } else { (b, a) };
                        let theta = pin / (pin - pout);
                        1.0 / (theta / kf + (1.0 - theta) / kappa_air)
                    }
                };
                exec.for_each_row(&mut self.sys.beta_x, nx + 1, |j, row| {
                    let b = (j + HALO) * sp + HALO;
                    for i in 0..=nx {
                        row[i] = face(ps[b + i - 1], ps[b + i]);
                    }
                });
                exec.for_each_row(&mut self.sys.beta_y, nx, |j, row| {
                    let b = (j + HALO) * sp + HALO;
                    for i in 0..nx {
                        row[i] = face(ps[b - sp + i], ps[b + i]);
                    }
                });
            }
        }
        let granular_only = self.config.formulation == PoreFormulation::GranularOnly;
        if self.config.time_scheme == PoreTimeScheme::Explicit {
            return self.advance_explicit(phi, grid, dt);
        }
        let basal = self.config.basal_flux;
        let (pfs, pps, ads, aps, st) = (self.pf.slice(), self.pf_prev.slice(), self.adv.slice(), self.adv_prev.slice(), self.pf.stride());
        debug_assert!(st == sp);
        let by = &self.sys.beta_y;
        exec.for_each_row(&mut self.sys.shift, nx, |j, row| {
            let b = (j + HALO) * sp + HALO;
            for i in 0..nx {
                if granular_only && !inside(ps[b + i]) {
                    row[i] = 1.0;
                    continue;
                }
                // granular-only: sub-cell Dirichlet p_f = 0 where a face crosses the interface
                row[i] = if granular_only { interface_diagonal(phi, i, j, dx, dy, kf, a0 / dt) } else { a0 / dt };
            }
        });
        exec.for_each_row(&mut self.sys.rhs, nx, |j, row| {
            let b = (j + HALO) * st + HALO;
            for i in 0..nx {
                let pc = ps[b + i];
                if granular_only && !inside(pc) {
                    row[i] = 0.0;
                    continue;
                }
                let mut r = (a1 * pfs[b + i] - a2 * pps[b + i]) / dt - (we * ads[b + i] - wm * aps[b + i]);
                if let Some(bf) = basal {
                    let xc = grid.xc(i as isize);
                    if j == 0 && xc >= bf.x_min && xc <= bf.x_max && (!granular_only || inside(pc)) {
                        let kb = if granular_only { kf } else { by[i] };
                        r -= kb * bf.gradient / dy;
                    }
                }
                // (L − σ) p = −R
                row[i] = -r;
            }
        });
        exec.for_each_row(&mut self.sys.x, nx, |j, row| {
            let b = (j + HALO) * st + HALO;
            for i in 0..nx {
                row[i] = if granular_only && !inside(ps[b + i]) { 0.0 } else { pfs[b + i] };
            }
        });
        let info = self.sys.solve(exec)?;
        if let Some(k) = (!crate::solvers::all_finite(&self.sys.x)).then(|| self.sys.x.iter().position(|v| !v.is_finite())).flatten() {
            return Err(Error::Simulation {
                what: format!("pore pressure p_f is not finite ({}) after the implicit (BDF2) solve", self.sys.x[k]),
                step: 0,
                time: 0.0,
                location: Some((k % nx, k / nx)),
            });
        }
        self.commit(exec);
        self.last = info;
        Ok(info)
    }

    /// History: p^{n−1} ← p^n, p^n ← the new values in `x`, A^{n−1} ← A^n.
    fn commit(&mut self, exec: Exec) {
        let nx = self.pf.nx;
        exec.copy(self.pf_prev.slice_mut(), self.pf.slice());
        std::mem::swap(&mut self.adv, &mut self.adv_prev);
        let xs = &self.sys.x;
        for_each_interior_row(exec, &mut self.pf, |j, row| {
            row[HALO..HALO + nx].copy_from_slice(&xs[j * nx..(j + 1) * nx]);
        });
    }

    /// The explicit (forward Euler) step of the module header, with A^n in `self.adv` and the face
    /// coefficients in `beta_x`, `beta_y` (granular-only: κ_f on faces between granular cells, 0
    /// elsewhere). Checks the discrete maximum principle; the `step` and `time` of a returned
    /// [`Error::Simulation`] are filled in by the caller.
    fn advance_explicit(&mut self, phi: &Field, grid: &Grid, dt: f64) -> Result<SolveInfo> {
        let (nx, ny) = (grid.nx, grid.ny);
        let (idx2, idy2) = (1.0 / (grid.dx * grid.dx), 1.0 / (grid.dy * grid.dy));
        let kf = self.config.diffusivity;
        let inside = |k: f64| k > 0.0;
        let basal = self.config.basal_flux;
        let pf = &self.pf;
        // max |pⁿ| over the granular cells (p_f = 0 in the air)
        let mut pmax: f64 = 0.0;
        for j in 0..ny {
            for i in 0..nx {
                if inside(phi.at(i as isize, j as isize)) {
                    pmax = pmax.max(pf.at(i as isize, j as isize).abs());
                }
            }
        }
        // the worst violation of |p^{n+1}| ≤ max|pⁿ| + δt |S| (ratio, value, bound, cell)
        let mut worst: Option<(f64, f64, f64, (usize, usize))> = None;
        let mut non_finite: Option<(f64, (usize, usize))> = None;
        for j in 0..ny {
            for i in 0..nx {
                let (ii, jj) = (i as isize, j as isize);
                let k = j * nx + i;
                let pc = phi.at(ii, jj);
                if !inside(pc) {
                    self.sys.x[k] = 0.0;
                    continue;
                }
                let p = pf.at(ii, jj);
                // div(κ∇pⁿ) through the faces between granular cells (domain sides: no flux, the
                // basal supply is a source below)
                let mut lap = 0.0;
                if i > 0 {
                    lap += self.sys.beta_x[j * (nx + 1) + i] * (pf.at(ii - 1, jj) - p) * idx2;
                }
                if i + 1 < nx {
                    lap += self.sys.beta_x[j * (nx + 1) + i + 1] * (pf.at(ii + 1, jj) - p) * idx2;
                }
                if j > 0 {
                    lap += self.sys.beta_y[j * nx + i] * (pf.at(ii, jj - 1) - p) * idy2;
                }
                if j + 1 < ny {
                    lap += self.sys.beta_y[(j + 1) * nx + i] * (pf.at(ii, jj + 1) - p) * idy2;
                }
                // sub-cell Dirichlet p_f = 0 on the interface, taken at n+1 (diagonal)
                let dd = interface_diagonal(phi, i, j, grid.dx, grid.dy, kf, 0.0);
                let mut src = -self.adv.at(ii, jj);
                if let Some(b) = basal {
                    let xc = grid.xc(ii);
                    if j == 0 && xc >= b.x_min && xc <= b.x_max {
                        src -= kf * b.gradient / grid.dy;
                    }
                }
                let new = (p + dt * (lap + src)) / (1.0 + dt * dd);
                self.sys.x[k] = new;
                if !new.is_finite() {
                    non_finite.get_or_insert((new, (i, j)));
                    continue;
                }
                // exact below the limit; 1e-10 relative covers the rounding of the update
                let bound = pmax + dt * src.abs();
                let excess = new.abs() - bound * (1.0 + 1e-10);
                if excess > 0.0 {
                    let ratio = new.abs() / bound.max(f64::MIN_POSITIVE);
                    if worst.is_none_or(|w| ratio > w.0) {
                        worst = Some((ratio, new, bound, (i, j)));
                    }
                }
            }
        }
        let limit = self.explicit_limit(grid);
        let tail = format!(
            "δt = {dt:.3e} s against the explicit diffusion limit h²/(4κ) = 1/(2κ(1/dx² + 1/dy²)) = {limit:.3e} s \
             (δt/limit = {:.3}, κ = {kf} m²/s); use time_scheme = 'implicit' or δt below the limit",
            dt / limit
        );
        if let Some((v, loc)) = non_finite {
            return Err(Error::Simulation {
                what: format!("pore pressure p_f is not finite ({v}) with the explicit scheme: {tail}"),
                step: 0,
                time: 0.0,
                location: Some(loc),
            });
        }
        if let Some((_, v, bound, loc)) = worst {
            return Err(Error::Simulation {
                what: format!(
                    "pore pressure p_f grows past the discrete maximum principle with the explicit scheme (unstable \
                     diffusion): |p_f| = {:.6e} Pa > max|p_f^n| + δt|sources| = {bound:.6e} Pa; {tail}",
                    v.abs()
                ),
                step: 0,
                time: 0.0,
                location: Some(loc),
            });
        }
        self.commit(Exec::SERIAL);
        self.last = SolveInfo::default();
        Ok(self.last)
    }

    /// The stability limit of the explicit scheme, δt_exp = 1/(2κ(1/dx² + 1/dy²)) (= h²/(4κ) on
    /// square cells).
    pub fn explicit_limit(&self, grid: &Grid) -> f64 {
        1.0 / (2.0 * self.config.diffusivity * (1.0 / (grid.dx * grid.dx) + 1.0 / (grid.dy * grid.dy)))
    }

    /// Makes the current p_f the whole history (after p_f was set from outside).
    pub fn restart_history(&mut self) {
        self.pf_prev.assign(&self.pf);
        self.adv_prev.fill(0.0);
    }

    /// Sets p_f (and its history) from a function of (x, y, Φ).
    pub fn set_initial(&mut self, grid: &Grid, phi: &Field, f: impl Fn(f64, f64, f64) -> f64) {
        for j in 0..grid.ny {
            for i in 0..grid.nx {
                let (x, y) = grid.coord(Location::Centre, i as isize, j as isize);
                self.pf.set(i, j, f(x, y, phi.at(i as isize, j as isize)));
            }
        }
        self.pf_prev.assign(&self.pf);
        self.adv_prev.fill(0.0);
    }
}

impl crate::grid::StateArrays for PorePressure {
    fn visit_state(&self, f: &mut dyn FnMut(&str, &[f64])) {
        f("pf", self.pf.slice());
        f("pf_prev", self.pf_prev.slice());
        f("pf_advection_prev", self.adv_prev.slice());
    }

    fn visit_state_mut(&mut self, f: &mut dyn FnMut(&str, &mut [f64])) {
        f("pf", self.pf.slice_mut());
        f("pf_prev", self.pf_prev.slice_mut());
        f("pf_advection_prev", self.adv_prev.slice_mut());
    }
}

impl crate::grid::WindowState for PorePressure {
    /// p_f, p_f^{n−1} and the advection at n − 1.
    fn state_fields(&self) -> Vec<&Field> {
        vec![&self.pf, &self.pf_prev, &self.adv_prev]
    }

    fn state_fields_mut(&mut self) -> Vec<&mut Field> {
        vec![&mut self.pf, &mut self.pf_prev, &mut self.adv_prev]
    }

    /// The last solve's info, after the window's step.
    fn copy_other_state(&mut self, src: &Self, back: bool) {
        if back {
            self.last = src.last;
        }
    }
}
