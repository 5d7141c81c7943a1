//! Thin Python binding of granrs-core: converts and validates arguments, maps core errors to
//! Python exceptions, releases the GIL around Rust work, and exposes the model's fields as
//! zero-copy NumPy arrays (the Python layer marks them read-only and strips the halos).

use granrs_core::exec::Exec;
use granrs_core::grid::{BoundaryConditions, Field, Grid, Side, VelocityBc};
use granrs_core::levelset::{self, Shape};
use granrs_core::models::{ActiveRegion, ConvectionScheme, Material, ModelConfig, PressureGauge, TwoPhaseModel, WindowSides};
use granrs_core::pore_pressure::{BasalFlux, PoreFormulation, PorePressureConfig, PoreTimeScheme};
use granrs_core::rheology::{InterfaceYield, RheologyConfig, RheologyLaw, SigmaLocation, WallNormalStress, YieldPressure, YieldTreatment};
use granrs_core::solvers::{PressureSolverKind, SolveInfo};
use granrs_core::time_stepping::{StepInfo, ViscousScheme};
use granrs_core::walls::side::SideWalls;
use granrs_core::Error;
use numpy::{PyArray2, PyReadonlyArray2};
use pyo3::create_exception;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

mod depth_averaged;

create_exception!(_granrs, ParameterError, PyValueError, "A parameter is outside its allowed range, or an array has the wrong shape.");
create_exception!(_granrs, SimulationError, PyRuntimeError, "A simulation stopped: what failed, where and when.");
create_exception!(
    _granrs,
    SolverError,
    SimulationError,
    "A linear solver failed or did not converge (during a step: a SimulationError with its step and time)."
);

/// Sets the `step`, `time` and `location` attributes of a raised error.
fn with_place(err: PyErr, step: u64, time: f64, location: Option<(usize, usize)>) -> PyErr {
    Python::attach(|py| {
        let v = err.value(py);
        let _ = v.setattr("step", step);
        let _ = v.setattr("time", time);
        let _ = v.setattr("location", location);
    });
    err
}

/// Maps the core's one error type to the Python exception classes.
fn to_py(e: Error) -> PyErr {
    match &e {
        Error::InvalidParameter { .. } | Error::Shape { .. } => ParameterError::new_err(e.to_string()),
        Error::NotConverged { .. } | Error::SolverFailure { .. } => SolverError::new_err(e.to_string()),
        Error::SolverInStep { step, time, .. } => with_place(SolverError::new_err(e.to_string()), *step, *time, None),
        Error::Simulation { step, time, location, .. } => with_place(SimulationError::new_err(e.to_string()), *step, *time, *location),
        Error::PicardNotConverged { step, time, .. } => with_place(SimulationError::new_err(e.to_string()), *step, *time, None),
    }
}

/// Clears the WRITEABLE flag of a view of the model's storage: the model is its only writer.
pub(crate) fn read_only(arr: &Bound<'_, PyAny>) -> PyResult<()> {
    arr.getattr("flags")?.setattr("writeable", false)
}

fn param_err(name: &str, value: impl std::fmt::Display, allowed: &str) -> PyErr {
    to_py(Error::param(name, value, allowed))
}

/// Parses one side's condition from ("kind", {params}).
fn parse_bc(side: &str, kind: &str, params: Option<&Bound<'_, PyDict>>) -> PyResult<VelocityBc> {
    let get = |key: &str| -> PyResult<f64> {
        match params.and_then(|p| p.get_item(key).ok().flatten()) {
            Some(v) => v.extract::<f64>().map_err(|_| param_err(&format!("bc.{side}.{key}"), v, "a number")),
            None => Ok(0.0),
        }
    };
    Ok(match kind {
        "no-slip" => VelocityBc::NoSlip,
        "free-slip" => VelocityBc::FreeSlip,
        "velocity" => VelocityBc::Velocity { normal: get("normal")?, tangential: get("tangential")? },
        "navier" => VelocityBc::NavierSlip { slip_length: get("slip_length")? },
        "outflow" => VelocityBc::Outflow,
        "coulomb" => VelocityBc::Coulomb,
        "fully-developed" => VelocityBc::FullyDeveloped,
        other => {
            return Err(param_err(&format!("bc.{side}"), other, "one of 'no-slip', 'free-slip', 'velocity', 'navier', 'outflow', 'coulomb', 'fully-developed'"))
        }
    })
}

/// Parses the rheology ("kind", {params}) of the dense phase.
fn parse_rheology(kind: &str, params: Option<&Bound<'_, PyDict>>) -> PyResult<RheologyLaw> {
    let get = |key: &str| -> PyResult<f64> {
        match params.and_then(|p| p.get_item(key).ok().flatten()) {
            Some(v) => v.extract::<f64>().map_err(|_| param_err(key, v, "a number")),
            None => Err(param_err(key, "missing", &format!("a number (required by the '{kind}' rheology)"))),
        }
    };
    Ok(match kind {
        "newtonian" => RheologyLaw::Newtonian,
        "bingham" => RheologyLaw::Bingham { yield_stress: get("yield_stress")? },
        "drucker-prager" => RheologyLaw::DruckerPrager { friction_angle: get("friction_angle")? },
        "mu-i" => RheologyLaw::MuI {
            mu_s: get("mu_s")?,
            mu_2: get("mu_2")?,
            i0: get("i0")?,
            grain_diameter: get("grain_diameter")?,
            grain_density: get("grain_density")?,
        },
        other => return Err(param_err("rheology", other, "one of 'newtonian', 'bingham', 'drucker-prager', 'mu-i'")),
    })
}

fn info_dict<'py>(py: Python<'py>, s: &SolveInfo) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("iterations", s.iterations)?;
    d.set_item("residual", s.residual)?;
    d.set_item("initial_residual", s.initial_residual)?;
    Ok(d)
}

fn step_dict<'py>(py: Python<'py>, s: &StepInfo) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("dt", s.dt)?;
    d.set_item("time", s.time)?;
    d.set_item("max_speed", s.max_speed)?;
    d.set_item("cfl", s.cfl)?;
    d.set_item("divergence", s.divergence)?;
    d.set_item("pressure", info_dict(py, &s.pressure)?)?;
    d.set_item("viscous", info_dict(py, &s.viscous)?)?;
    d.set_item("pore", info_dict(py, &s.pore)?)?;
    let pic = PyDict::new(py);
    pic.set_item("iterations", s.picard_iterations)?;
    pic.set_item("increment", s.picard_increment)?;
    pic.set_item("r_halvings", s.picard_r_halvings)?;
    d.set_item("picard", pic)?;
    d.set_item("retries", s.retries)?;
    let t = &s.stage_seconds;
    let secs = PyDict::new(py);
    for (name, x) in [
        ("choose_dt", t.choose_dt),
        ("interface", t.interface),
        ("properties", t.properties),
        ("pore_pressure", t.pore_pressure),
        ("rheology", t.rheology),
        ("predictor_setup", t.predictor_setup),
        ("predictor_solves", t.predictor_solves),
        ("projections", t.projections),
        ("pressure_projection", t.pressure_projection),
        ("diagnostics", t.diagnostics),
    ] {
        secs.set_item(name, x)?;
    }
    d.set_item("stage_seconds", secs)?;
    Ok(d)
}

/// The Rust model (granrs.Model wraps it).
#[pyclass(name = "RustModel", module = "granrs._granrs")]
struct PyModel {
    inner: TwoPhaseModel,
}

impl PyModel {
    fn field_ref(&self, name: &str) -> PyResult<&Field> {
        Ok(match name {
            "u" => &self.inner.u,
            "v" => &self.inner.v,
            "p" => &self.inner.p,
            "phi" => &self.inner.phi,
            "pf" => match &self.inner.pore {
                Some(p) => &p.pf,
                None => return Err(param_err("name", "pf", "a field of this model: it has no pore pressure (not fluidised)")),
            },
            "viscosity" => self.inner.viscosity().0,
            "sigma_xx" | "sigma_xy" | "trial_norm" | "yield_stress" => {
                let missing = || param_err("name", name, "a field of a model with a yield stress or friction walls (this rheology has none)");
                match name {
                    "sigma_xx" => self.inner.plastic_tensor().ok_or_else(missing)?.0,
                    "sigma_xy" => self.inner.plastic_tensor().ok_or_else(missing)?.1,
                    "trial_norm" => self.inner.plastic_trial_norm().ok_or_else(missing)?,
                    _ => self.inner.yield_stress().ok_or_else(missing)?,
                }
            }
            other => {
                return Err(param_err("name", other, "one of 'u', 'v', 'p', 'phi', 'pf', 'viscosity', 'sigma_xx', 'sigma_xy', 'trial_norm', 'yield_stress'"))
            }
        })
    }
}

/// Parses a shape spec: (kind, [numbers]) or ("union"/"difference", [specs]).
fn parse_shape(spec: &Bound<'_, PyAny>) -> PyResult<Shape> {
    let (kind, args): (String, Bound<'_, PyAny>) = spec.extract().map_err(|_| param_err("shape", spec, "a (kind, parameters) tuple"))?;
    let nums = |n: usize| -> PyResult<Vec<f64>> {
        let v: Vec<f64> = args.extract().map_err(|_| param_err(&format!("shape.{kind}"), &args, &format!("{n} numbers")))?;
        if v.len() != n {
            return Err(param_err(&format!("shape.{kind}"), format!("{v:?}"), &format!("{n} numbers")));
        }
        Ok(v)
    };
    let shape = match kind.as_str() {
        "rectangle" => {
            let v = nums(4)?;
            Shape::Rectangle { x0: v[0], x1: v[1], y0: v[2], y1: v[3] }
        }
        "circle" => {
            let v = nums(3)?;
            Shape::Circle { xc: v[0], yc: v[1], radius: v[2] }
        }
        "slotted-disk" => {
            let v = nums(5)?;
            Shape::SlottedDisk { xc: v[0], yc: v[1], radius: v[2], slot_width: v[3], slot_top: v[4] }
        }
        "half-plane" => {
            let v = nums(4)?;
            Shape::HalfPlane { px: v[0], py: v[1], nx: v[2], ny: v[3] }
        }
        "union" => {
            let parts: Vec<Bound<'_, PyAny>> = args.extract()?;
            Shape::Union(parts.iter().map(parse_shape).collect::<PyResult<Vec<_>>>()?)
        }
        "difference" => {
            let parts: Vec<Bound<'_, PyAny>> = args.extract()?;
            if parts.len() != 2 {
                return Err(param_err("shape.difference", parts.len(), "exactly 2 shapes"));
            }
            Shape::Difference(Box::new(parse_shape(&parts[0])?), Box::new(parse_shape(&parts[1])?))
        }
        other => return Err(param_err("shape", other, "one of 'rectangle', 'circle', 'slotted-disk', 'half-plane', 'union', 'difference'")),
    };
    shape.validate().map_err(to_py)?;
    Ok(shape)
}

/// Runs a level-set benchmark ('zalesak' or 'single-vortex') in Rust; returns its metrics.
#[pyfunction]
#[pyo3(signature = (case, n, period, redistance_every, cfl, threads=1))]
fn levelset_validation<'py>(
    py: Python<'py>,
    case: &str,
    n: usize,
    period: f64,
    redistance_every: usize,
    cfl: f64,
    threads: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let pool = granrs_core::exec::build_pool(threads).map_err(to_py)?;
    let exec = Exec::with_threads(threads);
    let every = if redistance_every == 0 { None } else { Some(redistance_every) };
    let case_owned = case.to_string();
    let m = py
        .detach(|| {
            pool.install(|| match case_owned.as_str() {
                "zalesak" => levelset::zalesak(n, every, cfl, exec),
                "single-vortex" => levelset::single_vortex(n, period, every, cfl, exec),
                other => Err(Error::param("case", other, "'zalesak' or 'single-vortex'")),
            })
        })
        .map_err(to_py)?;
    let d = PyDict::new(py);
    d.set_item("n", m.n)?;
    d.set_item("steps", m.steps)?;
    d.set_item("dt", m.dt)?;
    d.set_item("final_time", m.final_time)?;
    d.set_item("redistance_calls", m.redistance_calls)?;
    d.set_item("area_exact", m.area_exact)?;
    d.set_item("area_initial", m.area_initial)?;
    d.set_item("area_final", m.area_final)?;
    d.set_item("area_rel_error", m.area_rel_error)?;
    d.set_item("area_rel_change", m.area_rel_change)?;
    d.set_item("symdiff_rel", m.symdiff_rel)?;
    Ok(d)
}

/// Parses the pore-pressure settings dict.
fn parse_pore(d: &Bound<'_, PyDict>) -> PyResult<PorePressureConfig> {
    let f = |key: &str| -> PyResult<Option<f64>> {
        match d.get_item(key)? {
            Some(v) if !v.is_none() => Ok(Some(v.extract::<f64>().map_err(|_| param_err(&format!("pore_pressure.{key}"), &v, "a number"))?)),
            _ => Ok(None),
        }
    };
    let diffusivity = f("diffusivity")?.ok_or_else(|| param_err("pore_pressure.diffusivity", "missing", "a number > 0 (m²/s)"))?;
    let formulation: String = d.get_item("formulation")?.map(|v| v.extract()).transpose()?.unwrap_or_else(|| "granular-only".into());
    let formulation = match formulation.as_str() {
        "granular-only" => PoreFormulation::GranularOnly,
        "kappa-infinity" => PoreFormulation::KappaInfinity { kappa_air: f("kappa_air")?.unwrap_or(1e16), smoothed: false },
        "kappa-infinity-smoothed" => PoreFormulation::KappaInfinity { kappa_air: f("kappa_air")?.unwrap_or(1e16), smoothed: true },
        other => return Err(param_err("pore_pressure.formulation", other, "'granular-only', 'kappa-infinity' or 'kappa-infinity-smoothed'")),
    };
    let basal_flux = match f("basal_gradient")? {
        Some(g) => Some(BasalFlux { gradient: g, x_min: f("basal_x_min")?.unwrap_or(f64::NEG_INFINITY), x_max: f("basal_x_max")?.unwrap_or(f64::INFINITY) }),
        None => None,
    };
    let time_scheme: String = d.get_item("time_scheme")?.filter(|v| !v.is_none()).map(|v| v.extract()).transpose()?.unwrap_or_else(|| "implicit".into());
    let time_scheme = match time_scheme.as_str() {
        "implicit" => PoreTimeScheme::Implicit,
        "explicit" => PoreTimeScheme::Explicit,
        other => return Err(param_err("pore_pressure.time_scheme", other, "'implicit' or 'explicit'")),
    };
    let cfg = PorePressureConfig { diffusivity, formulation, basal_flux, time_scheme };
    cfg.validate().map_err(to_py)?;
    Ok(cfg)
}

/// The core's configuration from the arguments of `Model(...)` (see its signature).
#[allow(clippy::too_many_arguments)]
fn build_config(
    nx: i64,
    ny: i64,
    lx: f64,
    ly: f64,
    bc: &Bound<'_, PyDict>,
    dense: (f64, f64),
    light: Option<(f64, f64)>,
    gravity: (f64, f64),
    interface_width: f64,
    transport_interface: bool,
    redistance_every: i64,
    viscous: &str,
    cfl: f64,
    dt: Option<f64>,
    max_dt: f64,
    max_growth: f64,
    cfl_abort: f64,
    pressure_solver: &str,
    pressure_rtol: f64,
    pressure_max_iterations: i64,
    threads: i64,
    rheology: Option<(String, Option<Bound<'_, PyDict>>)>,
    plastic: &str,
    regularisation: Option<f64>,
    r: Option<f64>,
    r_wall: Option<f64>,
    theta: f64,
    picard_tol: f64,
    picard_max_iterations: i64,
    convection: bool,
    viscous_rtol: f64,
    pore_pressure: Option<&Bound<'_, PyDict>>,
    mass_correction: bool,
    convection_scheme: &str,
    pressure_gauge: &str,
    viscous_max_iterations: i64,
    interface_yield: &str,
    ambient_hydrostatic: bool,
    proximal_restarts: i64,
    wall_normal_stress: &str,
    active_region: Option<(i64, i64, String)>,
    step_retries: i64,
    air: &str,
    anderson_depth: i64,
    pressure_update: &str,
    picard_solve_max_iterations: i64,
    yield_pressure: &str,
    r_neighbourhood: i64,
    sigma_location: &str,
    side_walls: Option<(f64, f64)>,
) -> PyResult<ModelConfig> {
    let pos = |name: &str, v: i64| -> PyResult<usize> {
        if v < 0 {
            Err(param_err(name, v, "a non-negative integer"))
        } else {
            Ok(v as usize)
        }
    };
    let grid = Grid::new(pos("nx", nx)?, pos("ny", ny)?, lx, ly).map_err(to_py)?;
    let mut conds = BoundaryConditions::uniform(VelocityBc::NoSlip);
    let mut wall_friction_angle: Option<f64> = None;
    for key in bc.keys() {
        let k: String = key.extract()?;
        if !["left", "right", "bottom", "top"].contains(&k.as_str()) {
            return Err(param_err("bc", &k, "keys 'left', 'right', 'bottom', 'top'"));
        }
    }
    for side in Side::ALL {
        if let Some(item) = bc.get_item(side.name())? {
            let t = item.cast::<PyTuple>().map_err(|_| param_err(&format!("bc.{}", side.name()), &item, "a (kind, params) tuple"))?;
            let kind: String = t.get_item(0)?.extract()?;
            let params = t.get_item(1)?;
            let params = params.cast::<PyDict>().ok();
            conds = conds.with(side, parse_bc(side.name(), &kind, params)?);
            if kind == "coulomb" {
                if let Some(a) = params.as_ref().and_then(|p| p.get_item("friction_angle").ok().flatten()) {
                    let name = format!("bc.{}.friction_angle", side.name());
                    let a: f64 = a.extract().map_err(|_| param_err(&name, &a, "an angle in degrees"))?;
                    match wall_friction_angle {
                        Some(b) if b != a => return Err(param_err(&name, a, &format!("the same angle on every Coulomb side ({b} elsewhere)"))),
                        _ => wall_friction_angle = Some(a),
                    }
                }
            }
        }
    }
    let viscous = match viscous {
        "implicit" => ViscousScheme::Implicit,
        "explicit" => ViscousScheme::Explicit,
        other => return Err(param_err("viscous", other, "'implicit' or 'explicit'")),
    };
    let mut cfg = ModelConfig::single_phase(grid, conds, Material { density: dense.0, viscosity: dense.1 });
    cfg.light = light.map(|(r, e)| Material { density: r, viscosity: e });
    cfg.gravity = [gravity.0, gravity.1];
    cfg.interface_width = interface_width;
    cfg.transport_interface = transport_interface;
    cfg.redistance_every = pos("redistance_every", redistance_every)?;
    cfg.viscous = viscous;
    cfg.time.cfl = cfl;
    cfg.time.fixed_dt = dt;
    cfg.time.max_dt = max_dt;
    cfg.time.max_growth = max_growth;
    cfg.time.cfl_abort = cfl_abort;
    cfg.time.step_retries = pos("step_retries", step_retries)?;
    cfg.pressure_solver.kind = match pressure_solver {
        "multigrid-cg" => PressureSolverKind::MultigridCg,
        "direct" => PressureSolverKind::Direct,
        other => return Err(param_err("pressure_solver", other, "'multigrid-cg' or 'direct'")),
    };
    cfg.pressure_solver.rtol = pressure_rtol;
    cfg.pressure_solver.max_iterations = pos("pressure_max_iterations", pressure_max_iterations)?;
    cfg.threads = pos("threads", threads)?;
    cfg.pore = pore_pressure.map(parse_pore).transpose()?;
    cfg.mass_correction = mass_correction;
    cfg.convection = convection;
    cfg.convection_scheme = match convection_scheme {
        "centred" => ConvectionScheme::Centred,
        "weno5" => ConvectionScheme::Weno5,
        other => return Err(param_err("convection_scheme", other, "'centred' or 'weno5'")),
    };
    cfg.rotational_pressure = match pressure_update {
        "standard" => false,
        "rotational" => true,
        other => return Err(param_err("pressure_update", other, "'standard' or 'rotational'")),
    };
    cfg.pressure_gauge = match pressure_gauge {
        "auto" => PressureGauge::Auto,
        "mean" => PressureGauge::Mean,
        "top" => PressureGauge::Top,
        other => return Err(param_err("pressure_gauge", other, "'auto', 'mean' or 'top'")),
    };
    cfg.viscous_rtol = viscous_rtol;
    cfg.ambient_hydrostatic = ambient_hydrostatic;
    cfg.viscous_max_iterations = pos("viscous_max_iterations", viscous_max_iterations)?;
    let law = match &rheology {
        Some((kind, params)) => parse_rheology(kind, params.as_ref())?,
        None => RheologyLaw::Newtonian,
    };
    let need_reg = |what: &str| -> PyResult<f64> {
        regularisation.ok_or_else(|| param_err("regularisation", "None", &format!("a number ({what}) for plastic = '{plastic}'")))
    };
    let treatment = match plastic {
        "projection" => YieldTreatment::Projection,
        "papanastasiou" => YieldTreatment::Papanastasiou { m: need_reg("the exponent m in s")? },
        "bi-viscous" => YieldTreatment::BiViscous { yield_viscosity: need_reg("the viscosity below yield in Pa s")? },
        other => return Err(param_err("plastic", other, "'projection', 'papanastasiou' or 'bi-viscous'")),
    };
    cfg.rheology = RheologyConfig {
        law,
        treatment,
        wall_friction_angle,
        r,
        r_wall,
        theta,
        picard_tol,
        picard_max_iterations: pos("picard_max_iterations", picard_max_iterations)?,
        picard_solve_max_iterations: pos("picard_solve_max_iterations", picard_solve_max_iterations)?,
        interface_yield: match interface_yield {
            "paper" => InterfaceYield::Paper,
            "granular-side" => InterfaceYield::GranularSide,
            "density-support" => InterfaceYield::DensitySupport,
            other => return Err(param_err("interface_yield", other, "'paper', 'granular-side' or 'density-support'")),
        },
        proximal_restarts: match proximal_restarts {
            0..=1_000_000 => proximal_restarts as usize,
            other => return Err(param_err("proximal_restarts", other, "an integer in [0, 1000000]")),
        },
        anderson_depth: pos("anderson_depth", anderson_depth)?,
        r_neighbourhood: pos("r_neighbourhood", r_neighbourhood)?,
        wall_normal_stress: match wall_normal_stress {
            "pressure" => WallNormalStress::Pressure,
            "total" => WallNormalStress::Total,
            other => return Err(param_err("wall_normal_stress", other, "'pressure' or 'total'")),
        },
        yield_pressure: match yield_pressure {
            "absolute" => YieldPressure::Absolute,
            "surface-air" => YieldPressure::SurfaceAir,
            other => return Err(param_err("yield_pressure", other, "'absolute' or 'surface-air'")),
        },
        sigma_location: SigmaLocation::from_name(sigma_location).ok_or_else(|| {
            let names: Vec<String> = SigmaLocation::ALL.iter().map(|l| format!("'{}'", l.name())).collect();
            param_err("sigma_location", sigma_location, &names.join(" or "))
        })?,
        side_walls: side_walls.map(|(width, friction_angle)| SideWalls { width, friction_angle }),
    };
    cfg.active_region = match active_region {
        None => None,
        Some((band, align, sides)) => {
            let sides = WindowSides::from_name(&sides).ok_or_else(|| {
                let names: Vec<String> = WindowSides::ALL.iter().map(|s| format!("'{}'", s.name())).collect();
                let (last, rest) = names.split_last().expect("WindowSides has values");
                param_err("active_region_sides", &sides, &format!("{} or {last}", rest.join(", ")))
            })?;
            Some(ActiveRegion { band: pos("active_region.band", band)?, align: pos("active_region.align", align)?, sides })
        }
    };
    cfg.free_surface = match air {
        "resolved" => false,
        "free-surface" => true,
        other => return Err(param_err("air", other, "'resolved' (the two-phase model) or 'free-surface' (the granular-only model)")),
    };
    Ok(cfg)
}

#[pymethods]
impl PyModel {
    /// Builds a model. `bc` maps 'left', 'right', 'bottom', 'top' to (kind, params) tuples.
    #[new]
    #[pyo3(signature = (nx, ny, lx, ly, bc, dense, light=None, gravity=(0.0, 0.0), interface_width=1.5,
        transport_interface=true, redistance_every=10, viscous="implicit", cfl=0.5, dt=None,
        max_dt=f64::INFINITY, max_growth=1.2, cfl_abort=1.0, pressure_solver="multigrid-cg",
        pressure_rtol=1e-8, pressure_max_iterations=200, threads=1, rheology=None, plastic="projection",
        regularisation=None, r=None, r_wall=None, theta=0.5, picard_tol=1e-9, picard_max_iterations=1000,
        convection=true, viscous_rtol=1e-10, pore_pressure=None, mass_correction=false, convection_scheme="centred", pressure_gauge="auto", viscous_max_iterations=2000, interface_yield="paper", ambient_hydrostatic=false, proximal_restarts=0, wall_normal_stress="pressure", active_region=None, step_retries=3, air="resolved", anderson_depth=0, pressure_update="standard", picard_solve_max_iterations=500, yield_pressure="absolute", r_neighbourhood=0, sigma_location="staggered", side_walls=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        nx: i64,
        ny: i64,
        lx: f64,
        ly: f64,
        bc: &Bound<'_, PyDict>,
        dense: (f64, f64),
        light: Option<(f64, f64)>,
        gravity: (f64, f64),
        interface_width: f64,
        transport_interface: bool,
        redistance_every: i64,
        viscous: &str,
        cfl: f64,
        dt: Option<f64>,
        max_dt: f64,
        max_growth: f64,
        cfl_abort: f64,
        pressure_solver: &str,
        pressure_rtol: f64,
        pressure_max_iterations: i64,
        threads: i64,
        rheology: Option<(String, Option<Bound<'_, PyDict>>)>,
        plastic: &str,
        regularisation: Option<f64>,
        r: Option<f64>,
        r_wall: Option<f64>,
        theta: f64,
        picard_tol: f64,
        picard_max_iterations: i64,
        convection: bool,
        viscous_rtol: f64,
        pore_pressure: Option<&Bound<'_, PyDict>>,
        mass_correction: bool,
        convection_scheme: &str,
        pressure_gauge: &str,
        viscous_max_iterations: i64,
        interface_yield: &str,
        ambient_hydrostatic: bool,
        proximal_restarts: i64,
        wall_normal_stress: &str,
        active_region: Option<(i64, i64, String)>,
        step_retries: i64,
        air: &str,
        anderson_depth: i64,
        pressure_update: &str,
        picard_solve_max_iterations: i64,
        yield_pressure: &str,
        r_neighbourhood: i64,
        sigma_location: &str,
        side_walls: Option<(f64, f64)>,
    ) -> PyResult<Self> {
        let cfg = build_config(
            nx,
            ny,
            lx,
            ly,
            bc,
            dense,
            light,
            gravity,
            interface_width,
            transport_interface,
            redistance_every,
            viscous,
            cfl,
            dt,
            max_dt,
            max_growth,
            cfl_abort,
            pressure_solver,
            pressure_rtol,
            pressure_max_iterations,
            threads,
            rheology,
            plastic,
            regularisation,
            r,
            r_wall,
            theta,
            picard_tol,
            picard_max_iterations,
            convection,
            viscous_rtol,
            pore_pressure,
            mass_correction,
            convection_scheme,
            pressure_gauge,
            viscous_max_iterations,
            interface_yield,
            ambient_hydrostatic,
            proximal_restarts,
            wall_normal_stress,
            active_region,
            step_retries,
            air,
            anderson_depth,
            pressure_update,
            picard_solve_max_iterations,
            yield_pressure,
            r_neighbourhood,
            sigma_location,
            side_walls,
        )?;
        let inner = TwoPhaseModel::new(cfg).map_err(to_py)?;
        Ok(PyModel { inner })
    }

    /// The bytes a model built with these arguments would hold (models/memory.rs: its arrays,
    /// as counted from the grid and the options) and the memory available (MemAvailable of
    /// /proc/meminfo; None where it cannot be read), as (estimate, available). Nothing is
    /// allocated; invalid arguments raise ParameterError as the constructor does. The
    /// constructor refuses a model whose estimate exceeds the memory available.
    #[staticmethod]
    #[pyo3(signature = (nx, ny, lx, ly, bc, dense, light=None, gravity=(0.0, 0.0), interface_width=1.5,
        transport_interface=true, redistance_every=10, viscous="implicit", cfl=0.5, dt=None,
        max_dt=f64::INFINITY, max_growth=1.2, cfl_abort=1.0, pressure_solver="multigrid-cg",
        pressure_rtol=1e-8, pressure_max_iterations=200, threads=1, rheology=None, plastic="projection",
        regularisation=None, r=None, r_wall=None, theta=0.5, picard_tol=1e-9, picard_max_iterations=1000,
        convection=true, viscous_rtol=1e-10, pore_pressure=None, mass_correction=false, convection_scheme="centred", pressure_gauge="auto", viscous_max_iterations=2000, interface_yield="paper", ambient_hydrostatic=false, proximal_restarts=0, wall_normal_stress="pressure", active_region=None, step_retries=3, air="resolved", anderson_depth=0, pressure_update="standard", picard_solve_max_iterations=500, yield_pressure="absolute", r_neighbourhood=0, sigma_location="staggered", side_walls=None))]
    #[allow(clippy::too_many_arguments)]
    fn estimate_memory(
        nx: i64,
        ny: i64,
        lx: f64,
        ly: f64,
        bc: &Bound<'_, PyDict>,
        dense: (f64, f64),
        light: Option<(f64, f64)>,
        gravity: (f64, f64),
        interface_width: f64,
        transport_interface: bool,
        redistance_every: i64,
        viscous: &str,
        cfl: f64,
        dt: Option<f64>,
        max_dt: f64,
        max_growth: f64,
        cfl_abort: f64,
        pressure_solver: &str,
        pressure_rtol: f64,
        pressure_max_iterations: i64,
        threads: i64,
        rheology: Option<(String, Option<Bound<'_, PyDict>>)>,
        plastic: &str,
        regularisation: Option<f64>,
        r: Option<f64>,
        r_wall: Option<f64>,
        theta: f64,
        picard_tol: f64,
        picard_max_iterations: i64,
        convection: bool,
        viscous_rtol: f64,
        pore_pressure: Option<&Bound<'_, PyDict>>,
        mass_correction: bool,
        convection_scheme: &str,
        pressure_gauge: &str,
        viscous_max_iterations: i64,
        interface_yield: &str,
        ambient_hydrostatic: bool,
        proximal_restarts: i64,
        wall_normal_stress: &str,
        active_region: Option<(i64, i64, String)>,
        step_retries: i64,
        air: &str,
        anderson_depth: i64,
        pressure_update: &str,
        picard_solve_max_iterations: i64,
        yield_pressure: &str,
        r_neighbourhood: i64,
        sigma_location: &str,
        side_walls: Option<(f64, f64)>,
    ) -> PyResult<(u64, Option<u64>)> {
        let cfg = build_config(
            nx,
            ny,
            lx,
            ly,
            bc,
            dense,
            light,
            gravity,
            interface_width,
            transport_interface,
            redistance_every,
            viscous,
            cfl,
            dt,
            max_dt,
            max_growth,
            cfl_abort,
            pressure_solver,
            pressure_rtol,
            pressure_max_iterations,
            threads,
            rheology,
            plastic,
            regularisation,
            r,
            r_wall,
            theta,
            picard_tol,
            picard_max_iterations,
            convection,
            viscous_rtol,
            pore_pressure,
            mass_correction,
            convection_scheme,
            pressure_gauge,
            viscous_max_iterations,
            interface_yield,
            ambient_hydrostatic,
            proximal_restarts,
            wall_normal_stress,
            active_region,
            step_retries,
            air,
            anderson_depth,
            pressure_update,
            picard_solve_max_iterations,
            yield_pressure,
            r_neighbourhood,
            sigma_location,
            side_walls,
        )?;
        cfg.validate().map_err(to_py)?;
        Ok((cfg.memory_estimate(), granrs_core::models::available_memory()))
    }

    /// Full storage (halos included) of a field as a zero-copy, read-only NumPy array; the array
    /// keeps the model alive. The buffers are never reallocated, so the view stays valid and
    /// live. Only the model writes them (`set_field` copies into them); a view read from another
    /// thread while a step runs (the step releases the GIL) races the step's writes and may see
    /// a half-updated field.
    fn field_storage<'py>(slf: Bound<'py, Self>, name: &str) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let borrowed = slf.borrow();
        let field = borrowed.field_ref(name)?;
        let container = slf.clone().into_any();
        // SAFETY: the array lives inside the model object, which `container` keeps alive; field
        // buffers are allocated once and never reallocated or moved for the model's lifetime.
        let arr = unsafe { PyArray2::borrow_from_array(&field.data, container) };
        read_only(arr.as_any())?;
        Ok(arr)
    }

    /// Copies `values` (interior shape) into a field, then tells the model fields changed.
    fn set_field(&mut self, name: &str, values: PyReadonlyArray2<'_, f64>) -> PyResult<()> {
        let a = values.as_array();
        let field = match name {
            "u" => &mut self.inner.u,
            "v" => &mut self.inner.v,
            "p" => &mut self.inner.p,
            "phi" => &mut self.inner.phi,
            "pf" => match &mut self.inner.pore {
                Some(p) => &mut p.pf,
                None => return Err(param_err("name", "pf", "a field of this model: it has no pore pressure (not fluidised)")),
            },
            other => return Err(param_err("name", other, "one of 'u', 'v', 'p', 'phi', 'pf'")),
        };
        let expected = (field.ny, field.nx);
        if a.dim() != expected {
            return Err(to_py(Error::Shape { name: name.into(), got: a.shape().to_vec(), expected: vec![expected.0, expected.1] }));
        }
        if let Some(bad) = a.iter().position(|x| !x.is_finite()) {
            return Err(param_err(name, format!("non-finite value at flat index {bad}"), "finite values"));
        }
        field.interior_mut().assign(&a);
        if name == "pf" {
            if let Some(p) = &mut self.inner.pore {
                p.restart_history();
            }
        }
        if name == "u" || name == "v" {
            self.inner.u_prev.assign(&self.inner.u);
            self.inner.v_prev.assign(&self.inner.v);
        }
        self.inner.fields_changed();
        Ok(())
    }

    /// Initialises Φ as the exact signed distance to a shape spec.
    fn set_shape(&mut self, spec: &Bound<'_, PyAny>) -> PyResult<()> {
        let shape = parse_shape(spec)?;
        self.inner.set_shape(&shape).map_err(to_py)
    }

    /// Area of the dense phase {Φ > 0}, sub-cell accurate.
    fn dense_area(&self) -> f64 {
        self.inner.dense_area()
    }

    /// The mechanical energy budget since the state was last set (diagnostics/energy.rs), in
    /// J per metre of width: energies now and initially, the time integrals of the powers, the
    /// residual (what the discretisation added, > 0, or removed, < 0), and the last rates [W/m].
    fn energy_budget<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let b = self.inner.energy_budget();
        let d = PyDict::new(py);
        d.set_item("kinetic", b.kinetic)?;
        d.set_item("kinetic_initial", b.kinetic_initial)?;
        d.set_item("potential", b.potential)?;
        d.set_item("potential_initial", b.potential_initial)?;
        d.set_item("gravity_work", b.gravity_work)?;
        d.set_item("plastic_work", b.plastic_work)?;
        d.set_item("plastic_negative_work", b.plastic_negative_work)?;
        d.set_item("viscous_work", b.viscous_work)?;
        let sides = ["left", "right", "bottom", "top"];
        let walls = PyDict::new(py);
        let rates_walls = PyDict::new(py);
        for (k, side) in sides.iter().enumerate() {
            walls.set_item(side, b.wall_work[k])?;
            rates_walls.set_item(side, b.rates.wall[k])?;
        }
        d.set_item("wall_work", walls)?;
        d.set_item("side_wall_work", b.side_wall_work)?;
        d.set_item("residual", b.residual)?;
        let r = PyDict::new(py);
        r.set_item("gravity", b.rates.gravity)?;
        r.set_item("plastic", b.rates.plastic)?;
        r.set_item("plastic_negative", b.rates.plastic_negative)?;
        r.set_item("viscous", b.rates.viscous)?;
        r.set_item("wall", rates_walls)?;
        r.set_item("side_walls", b.rates.side_walls)?;
        d.set_item("rates", r)?;
        Ok(d)
    }

    /// Sets p so that the body force is balanced at rest (one pressure solve).
    fn initialise_pressure<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let inner = &mut self.inner;
        let info = py.detach(|| inner.initialise_pressure()).map_err(to_py)?;
        info_dict(py, &info)
    }

    /// Sets the plastic tensor Σ that holds the current state at rest, column by column
    /// (`rheology/rest.rs`); returns max_ratio (≤ 1: admissible), node, clamped, x_residual.
    fn balance_plastic_stress<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let inner = &mut self.inner;
        let r = py.detach(|| inner.balance_plastic_stress()).map_err(to_py)?;
        let d = PyDict::new(py);
        d.set_item("max_ratio", r.max_ratio)?;
        d.set_item("node", r.node)?;
        d.set_item("clamped", r.clamped)?;
        d.set_item("x_residual", r.x_residual)?;
        Ok(d)
    }

    /// Takes one step; returns its diagnostics.
    fn step<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let inner = &mut self.inner;
        let info = py.detach(|| inner.step()).map_err(to_py)?;
        step_dict(py, &info)
    }

    /// Takes steps until `t_end` (the last step is shortened to land on it) or `max_steps`
    /// steps, with the GIL released. Returns per-step arrays: time, dt, max_speed, cfl,
    /// pressure_iterations, viscous_iterations, divergence, picard_iterations, picard_increment,
    /// picard_r_halvings, step_retries.
    #[pyo3(signature = (t_end=None, max_steps=None))]
    fn advance<'py>(&mut self, py: Python<'py>, t_end: Option<f64>, max_steps: Option<u64>) -> PyResult<Bound<'py, PyDict>> {
        if t_end.is_none() && max_steps.is_none() {
            return Err(param_err("t_end/max_steps", "None", "at least one of them"));
        }
        if let Some(t) = t_end {
            if !t.is_finite() {
                return Err(param_err("t_end", t, "a finite time"));
            }
        }
        let inner = &mut self.inner;
        let (log, err) = py.detach(|| {
            let mut log: Vec<StepInfo> = Vec::new();
            let limit = max_steps.unwrap_or(u64::MAX);
            let mut n = 0;
            while n < limit {
                if let Some(t) = t_end {
                    let remaining = t - inner.time;
                    if remaining <= 1e-12 * t.abs().max(1e-300) {
                        break;
                    }
                    // land on t_end: a fixed step is shortened; the adaptive one is capped
                    inner.set_time_to_land(Some(remaining));
                }
                match inner.step() {
                    Ok(s) => log.push(s),
                    Err(e) => return (log, Some(e)),
                }
                n += 1;
            }
            inner.set_time_to_land(None);
            (log, None)
        });
        let d = PyDict::new(py);
        d.set_item("time", log.iter().map(|s| s.time).collect::<Vec<_>>())?;
        d.set_item("dt", log.iter().map(|s| s.dt).collect::<Vec<_>>())?;
        d.set_item("max_speed", log.iter().map(|s| s.max_speed).collect::<Vec<_>>())?;
        d.set_item("cfl", log.iter().map(|s| s.cfl).collect::<Vec<_>>())?;
        d.set_item("divergence", log.iter().map(|s| s.divergence).collect::<Vec<_>>())?;
        d.set_item("pressure_iterations", log.iter().map(|s| s.pressure.iterations).collect::<Vec<_>>())?;
        d.set_item("viscous_iterations", log.iter().map(|s| s.viscous.iterations).collect::<Vec<_>>())?;
        d.set_item("pore_iterations", log.iter().map(|s| s.pore.iterations).collect::<Vec<_>>())?;
        d.set_item("picard_iterations", log.iter().map(|s| s.picard_iterations).collect::<Vec<_>>())?;
        d.set_item("picard_increment", log.iter().map(|s| s.picard_increment).collect::<Vec<_>>())?;
        d.set_item("picard_r_halvings", log.iter().map(|s| s.picard_r_halvings as f64).collect::<Vec<_>>())?;
        d.set_item("step_retries", log.iter().map(|s| s.retries as f64).collect::<Vec<_>>())?;
        if let Some(e) = err {
            // the steps taken before the failure travel with the exception
            let pyerr = to_py(e);
            pyerr.value(py).setattr("history", d)?;
            return Err(pyerr);
        }
        Ok(d)
    }

    /// Simulated time.
    #[getter]
    fn time(&self) -> f64 {
        self.inner.time
    }

    /// Steps taken.
    #[getter]
    fn step_count(&self) -> u64 {
        self.inner.step_count
    }

    /// Diagnostics of the last step.
    fn last_step<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        step_dict(py, &self.inner.last)
    }

    /// (nx, ny, lx, ly, dx, dy).
    #[getter]
    fn grid(&self) -> (usize, usize, f64, f64, f64, f64) {
        let g = self.inner.grid();
        (g.nx, g.ny, g.lx, g.ly, g.dx, g.dy)
    }

    /// Coulomb friction on `side`: (s, τ_b) along the side's tangential faces, or None.
    fn wall_friction(&self, side: &str) -> PyResult<Option<(Vec<f64>, Vec<f64>)>> {
        let s = match side {
            "left" => Side::Left,
            "right" => Side::Right,
            "bottom" => Side::Bottom,
            "top" => Side::Top,
            other => return Err(param_err("side", other, "'left', 'right', 'bottom' or 'top'")),
        };
        Ok(self.inner.wall_friction(s).map(|(a, b)| (a.to_vec(), b.to_vec())))
    }

    /// The whole state a step reads (fields with their ghost layers, BDF2 history, Σ, wall
    /// directions, clock), as 1-D float64 arrays by name: `restore_state` of a model built with
    /// the same configuration continues bit for bit.
    fn checkpoint_state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (name, data) in self.inner.checkpoint() {
            d.set_item(name, numpy::PyArray1::from_vec(py, data))?;
        }
        Ok(d)
    }

    /// Restores a state from `checkpoint_state` (same configuration; every entry, right lengths).
    fn restore_state(&mut self, state: &Bound<'_, PyDict>) -> PyResult<()> {
        let mut entries = Vec::with_capacity(state.len());
        for (k, v) in state.iter() {
            let name: String = k.extract()?;
            let data: Vec<f64> = match v.extract::<numpy::PyReadonlyArray1<f64>>() {
                Ok(a) => a.as_slice()?.to_vec(),
                Err(_) => vec![v.extract::<f64>().map_err(|_| to_py(Error::param("state", &name, "1-D float64 arrays or numbers")))?],
            };
            entries.push((name, data));
        }
        self.inner.restore(&entries).map_err(to_py)
    }

    /// Increments of the Picard iterations of the last step.
    fn picard_history(&self) -> Vec<f64> {
        self.inner.picard_history().to_vec()
    }

    /// (nx, ny) of the active window the last step ran on, or None (whole domain).
    fn active_window(&self) -> Option<(usize, usize)> {
        self.inner.active_window()
    }

    /// Number of threads of the model's pool.
    #[getter]
    fn threads(&self) -> usize {
        self.inner.config().threads
    }
}

/// Build information: version and profile (benchmarks refuse a debug build).
#[pyfunction]
fn build_info<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("version", granrs_core::VERSION)?;
    d.set_item("profile", if cfg!(debug_assertions) { "debug" } else { "release" })?;
    d.set_item("halo", granrs_core::HALO)?;
    Ok(d)
}

#[pymodule]
fn _granrs(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyModel>()?;
    m.add_class::<depth_averaged::PyDepthAveraged>()?;
    m.add_function(wrap_pyfunction!(build_info, m)?)?;
    m.add_function(wrap_pyfunction!(levelset_validation, m)?)?;
    m.add("__version__", granrs_core::VERSION)?;
    m.add("ParameterError", m.py().get_type::<ParameterError>())?;
    m.add("SolverError", m.py().get_type::<SolverError>())?;
    m.add("SimulationError", m.py().get_type::<SimulationError>())?;
    Ok(())
}
