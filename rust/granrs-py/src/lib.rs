//! Thin Python binding of granrs-core: converts and validates arguments, maps core errors to
//! Python exceptions, releases the GIL around Rust work, and exposes the model's fields as
//! zero-copy NumPy arrays (the Python layer marks them read-only and strips the halos).

use granrs_core::exec::Exec;
use granrs_core::grid::{BoundaryConditions, Field, Grid, Side, VelocityBc};
use granrs_core::levelset::{self, Shape};
use granrs_core::models::{Material, ModelConfig, TwoPhaseModel};
use granrs_core::options::{self, Kind, OptionMap, OptionSpec, Value};
use granrs_core::pore_pressure::PorePressureConfig;
use granrs_core::rheology::{RheologyLaw, COULOMB_OPTIONS, SIDE_WALL_OPTIONS};
use granrs_core::solvers::SolveInfo;
use granrs_core::time_stepping::{StepInfo, TimeConfig};
use granrs_core::walls::side::SideWalls;
use granrs_core::Error;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArray2};
use pyo3::create_exception;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyInt, PyTuple};

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
        Error::Simulation { step, time, location, .. } | Error::CflExceeded { step, time, location, .. } => {
            with_place(SimulationError::new_err(e.to_string()), *step, *time, *location)
        }
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
    pic.set_item("restarts", s.picard_restarts)?;
    d.set_item("picard", pic)?;
    d.set_item("retries", s.retries)?;
    d.set_item("pieces_removed", s.pieces_removed)?;
    d.set_item("mass_shift", s.mass_shift)?;
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
            "volume_fraction" => match self.inner.volume_fraction() {
                Some(f) => f,
                None => return Err(param_err("name", "volume_fraction", "a field of a two-phase model with interface_transport = 'clsvof'")),
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
                return Err(param_err(
                    "name",
                    other,
                    "one of 'u', 'v', 'p', 'phi', 'pf', 'volume_fraction', 'viscosity', 'sigma_xx', 'sigma_xy', 'trial_norm', 'yield_stress'",
                ))
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

/// A Python value as an option value (bool before int: a Python bool is an int).
fn to_value(v: &Bound<'_, PyAny>, name: &str) -> PyResult<Value> {
    if v.is_none() {
        Ok(Value::None)
    } else if let Ok(b) = v.cast::<PyBool>() {
        Ok(Value::Bool(b.is_true()))
    } else if v.cast::<PyInt>().is_ok() {
        v.extract::<i64>().map(Value::Int).map_err(|_| param_err(name, v, "an integer in the range of i64"))
    } else if let Ok(x) = v.extract::<f64>() {
        Ok(Value::Float(x))
    } else if let Ok(s) = v.extract::<String>() {
        Ok(Value::str(&s))
    } else {
        Err(param_err(name, v, "a number, a bool, a string or None"))
    }
}

/// An option value as a Python object.
fn from_value<'py>(py: Python<'py>, v: &Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match v {
        Value::None => py.None().into_bound(py),
        Value::Bool(b) => PyBool::new(py, *b).to_owned().into_any(),
        Value::Int(i) => i.into_pyobject(py)?.into_any(),
        Value::Float(x) => x.into_pyobject(py)?.into_any(),
        Value::Str(s) => s.as_ref().into_pyobject(py)?.into_any(),
    })
}

/// A dict of option values (None: an empty map).
fn option_map(d: Option<&Bound<'_, PyAny>>, what: &str) -> PyResult<OptionMap> {
    let mut map = OptionMap::new();
    let Some(d) = d.filter(|d| !d.is_none()) else { return Ok(map) };
    let d = d.cast::<PyDict>().map_err(|_| param_err(what, d, "a dict of options"))?;
    for (k, v) in d.iter() {
        let key: String = k.extract().map_err(|_| param_err(what, &k, "string keys"))?;
        let value = to_value(&v, &key)?;
        map.insert(key, value);
    }
    Ok(map)
}

/// The core's configuration from the one configuration object of `RustModel(config)`: a dict
/// with `grid` (nx, ny, lx, ly), `bc` (side → (kind, params)), `dense` and `light` ((density,
/// viscosity) or None), `gravity` (g_x, g_y), `rheology` ((law, params) or None), `pore_pressure`
/// (a dict of the pore pressure's options, or None), `side_walls` ({width, friction_angle} or
/// None) and `options` (the model's flat options, `schema()`); every value is checked in Rust.
fn build_config(config: &Bound<'_, PyDict>) -> PyResult<ModelConfig> {
    const KEYS: [&str; 8] = ["grid", "bc", "dense", "light", "gravity", "rheology", "pore_pressure", "options"];
    for k in config.keys() {
        let k: String = k.extract()?;
        if !KEYS.contains(&k.as_str()) && k != "side_walls" {
            return Err(param_err("config", &k, &format!("a key of the model's configuration, one of {}, side_walls", KEYS.join(", "))));
        }
    }
    let item = |k: &str| -> PyResult<Option<Bound<'_, PyAny>>> { Ok(config.get_item(k)?.filter(|v| !v.is_none())) };
    let required = |k: &str| -> PyResult<Bound<'_, PyAny>> { item(k)?.ok_or_else(|| param_err(&format!("config.{k}"), "missing", "a value")) };
    let (nx, ny, lx, ly): (i64, i64, f64, f64) = required("grid")?.extract().map_err(|_| param_err("grid", "?", "(nx, ny, lx, ly)"))?;
    let pos = |name: &str, v: i64| -> PyResult<usize> { usize::try_from(v).map_err(|_| param_err(name, v, "a non-negative integer")) };
    let grid = Grid::new(pos("nx", nx)?, pos("ny", ny)?, lx, ly).map_err(to_py)?;
    let bc_item = required("bc")?;
    let bc = bc_item.cast::<PyDict>().map_err(|_| param_err("bc", &bc_item, "a dict of side → (kind, params)"))?;
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
                    let a = options::spec(COULOMB_OPTIONS, "friction_angle").check_named(&name, &to_value(&a, &name)?).map_err(to_py)?;
                    if let Some(a) = a.as_f64() {
                        match wall_friction_angle {
                            Some(b) if b != a => return Err(param_err(&name, a, &format!("the same angle on every Coulomb side ({b} elsewhere)"))),
                            _ => wall_friction_angle = Some(a),
                        }
                    }
                }
            }
        }
    }
    let material = |k: &str| -> PyResult<Option<Material>> {
        match item(k)? {
            None => Ok(None),
            Some(v) => {
                let (density, viscosity): (f64, f64) = v.extract().map_err(|_| param_err(k, &v, "(density, viscosity)"))?;
                Ok(Some(Material { density, viscosity }))
            }
        }
    };
    let dense = material("dense")?.ok_or_else(|| param_err("config.dense", "missing", "(density, viscosity)"))?;
    let mut cfg = ModelConfig::single_phase(grid, conds, dense);
    cfg.light = material("light")?;
    if let Some(g) = item("gravity")? {
        let (gx, gy): (f64, f64) = g.extract().map_err(|_| param_err("gravity", &g, "(g_x, g_y)"))?;
        cfg.gravity = [gx, gy];
    }
    cfg.apply_options(&option_map(config.get_item("options")?.as_ref(), "options")?).map_err(to_py)?;
    cfg.rheology.law = match item("rheology")? {
        None => RheologyLaw::Newtonian,
        Some(r) => {
            let (kind, params): (String, Option<Bound<'_, PyAny>>) = r.extract().map_err(|_| param_err("rheology", &r, "a (law, params) tuple"))?;
            RheologyLaw::from_options(&kind, &option_map(params.as_ref(), "rheology")?).map_err(to_py)?
        }
    };
    cfg.rheology.wall_friction_angle = wall_friction_angle;
    cfg.rheology.side_walls = match item("side_walls")? {
        None => None,
        Some(w) => {
            let m = option_map(Some(&w), "side_walls")?;
            let get = |k: &str| -> PyResult<f64> {
                let s = options::spec(SIDE_WALL_OPTIONS, k);
                let v = s.check_named(&format!("side_walls.{k}"), m.get(k).unwrap_or(&Value::None)).map_err(to_py)?;
                Ok(v.as_f64().unwrap_or(f64::NAN))
            };
            Some(SideWalls { width: get("width")?, friction_angle: get("friction_angle")? })
        }
    };
    cfg.pore = match item("pore_pressure")? {
        None => None,
        Some(p) => Some(PorePressureConfig::from_options(&option_map(Some(&p), "pore_pressure")?).map_err(to_py)?),
    };
    Ok(cfg)
}

/// The options schema (`granrs_core::options`): one dict per option.
#[pyfunction]
fn schema<'py>(py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
    let flat = ModelConfig::schema();
    let mut out = Vec::new();
    for (s, object) in flat.iter().map(|s| (*s, false)).chain(ModelConfig::object_schema().into_iter().map(|s| (s, true))) {
        let d = PyDict::new(py);
        d.set_item("key", s.key)?;
        d.set_item("room", s.room)?;
        d.set_item("object", object)?;
        d.set_item("group", s.group.name())?;
        d.set_item("default", from_value(py, &s.default)?)?;
        d.set_item("optional", s.optional)?;
        d.set_item("required", s.default == Value::None && !s.optional)?;
        d.set_item("unit", s.unit)?;
        d.set_item("doc", s.doc)?;
        d.set_item("allowed", s.allowed())?;
        let (kind, lo, hi, lo_open, hi_open, choices): (&str, Option<f64>, Option<f64>, bool, bool, Vec<&str>) = match s.kind {
            Kind::Float { lo, hi, lo_open, hi_open } => ("float", Some(lo), Some(hi), lo_open, hi_open, vec![]),
            Kind::Int { lo, hi } => ("int", Some(lo as f64), Some(hi as f64), false, false, vec![]),
            Kind::Bool => ("bool", None, None, false, false, vec![]),
            Kind::Choice(names) => ("choice", None, None, false, false, names.to_vec()),
        };
        d.set_item("kind", kind)?;
        if let Kind::Int { lo, hi } = s.kind {
            d.set_item("lo", lo)?;
            d.set_item("hi", hi)?;
        } else {
            d.set_item("lo", lo)?;
            d.set_item("hi", hi)?;
        }
        d.set_item("lo_open", lo_open)?;
        d.set_item("hi_open", hi_open)?;
        d.set_item("choices", PyTuple::new(py, choices)?)?;
        out.push(d);
    }
    Ok(out)
}

/// Checks one option value against its spec in Rust: returns the value converted to its kind
/// (an int for a float option becomes a float) or raises ParameterError naming `name` (default:
/// the key) and its allowed values. `room` picks an object's option (e.g. 'pore_pressure').
#[pyfunction]
#[pyo3(signature = (key, value, room=None, name=None))]
fn check_option<'py>(py: Python<'py>, key: &str, value: &Bound<'py, PyAny>, room: Option<&str>, name: Option<&str>) -> PyResult<Bound<'py, PyAny>> {
    let all: Vec<&OptionSpec> = ModelConfig::schema().into_iter().chain(ModelConfig::object_schema()).collect();
    let spec =
        all.iter().find(|s| s.key == key && room.is_none_or(|r| r == s.room)).ok_or_else(|| param_err("key", key, "a key of granrs._granrs.schema()"))?;
    let name = name.unwrap_or(key);
    let v = spec.check_named(name, &to_value(value, name)?).map_err(to_py)?;
    from_value(py, &v)
}

/// Checks the options of one room together, by the cross-field rules of its struct's
/// `validate` beyond each option's own range (the clock, "time": `cfl_light` at most
/// `cfl_abort`): ParameterError naming the offending key, or the room when it has no such rules.
#[pyfunction]
fn check_room(room: &str, values: &Bound<'_, PyAny>) -> PyResult<()> {
    let map = option_map(Some(values), room)?;
    match room {
        "time" => {
            let mut c = TimeConfig::default();
            options::apply(&mut c, &map).map_err(to_py)?;
            c.validate().map_err(to_py)
        }
        _ => Err(param_err("room", room, "'time' (the room whose options have rules across each other)")),
    }
}

#[pymethods]
impl PyModel {
    /// Builds a model from its configuration object (see `build_config`).
    #[new]
    fn new(config: &Bound<'_, PyDict>) -> PyResult<Self> {
        let cfg = build_config(config)?;
        let inner = TwoPhaseModel::new(cfg).map_err(to_py)?;
        Ok(PyModel { inner })
    }

    /// The bytes a model built from `config` would hold (models/memory.rs: its arrays, as
    /// counted from the grid and the options) and the memory available (MemAvailable of
    /// /proc/meminfo; None where it cannot be read), as (estimate, available). Nothing is
    /// allocated; an invalid configuration raises ParameterError as the constructor does. The
    /// constructor refuses a model whose estimate exceeds the memory available.
    #[staticmethod]
    fn estimate_memory(config: &Bound<'_, PyDict>) -> PyResult<(u64, Option<u64>)> {
        let cfg = build_config(config)?;
        cfg.validate().map_err(to_py)?;
        Ok((cfg.memory_estimate(), granrs_core::models::available_memory()))
    }

    /// Every option of the model with its value (keys of `schema()` that are not objects).
    fn options<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (k, v) in self.inner.config().to_options() {
            d.set_item(k, from_value(py, &v)?)?;
        }
        Ok(d)
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

    /// The conserved dense volume Σ F δx δy (interface_transport = 'clsvof'; None otherwise).
    fn dense_volume(&self) -> Option<f64> {
        self.inner.dense_volume()
    }

    /// The last step's dense-volume budget (boundary, divergence) in m² (interface_transport =
    /// 'clsvof'; None otherwise).
    fn volume_budget(&self) -> Option<(f64, f64)> {
        self.inner.volume_budget().map(|b| (b.boundary, b.divergence))
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
    /// picard_r_halvings, picard_restarts, step_retries, pieces_removed, mass_shift.
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
        let (log, err) = py.detach(|| inner.advance(t_end, max_steps));
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
        d.set_item("picard_restarts", log.iter().map(|s| s.picard_restarts as f64).collect::<Vec<_>>())?;
        d.set_item("step_retries", log.iter().map(|s| s.retries as f64).collect::<Vec<_>>())?;
        d.set_item("pieces_removed", log.iter().map(|s| s.pieces_removed as f64).collect::<Vec<_>>())?;
        d.set_item("mass_shift", log.iter().map(|s| s.mass_shift).collect::<Vec<_>>())?;
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

    /// The last exact step's discrete problem and solution (a dict of arrays), or None.
    fn exact_step_problem<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(pb) = self.inner.exact_problem() else { return Ok(None) };
        let d = PyDict::new(py);
        d.set_item("n", pb.n)?;
        for (k, v) in [("a_rows", &pb.a_rows), ("a_cols", &pb.a_cols), ("dim", &pb.dim), ("b_indptr", &pb.b_indptr), ("b_indices", &pb.b_indices)] {
            d.set_item(k, v.iter().map(|&i| i as i64).collect::<Vec<i64>>().into_pyarray(py))?;
        }
        for (k, v) in [("a_vals", &pb.a_vals), ("b", &pb.b), ("w", &pb.w), ("b_data", &pb.b_data), ("beta", &pb.beta), ("x", &pb.x), ("sigma", &pb.sigma)] {
            d.set_item(k, v.clone().into_pyarray(py))?;
        }
        Ok(Some(d))
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
    m.add_function(wrap_pyfunction!(schema, m)?)?;
    m.add_function(wrap_pyfunction!(check_option, m)?)?;
    m.add_function(wrap_pyfunction!(check_room, m)?)?;
    m.add("__version__", granrs_core::VERSION)?;
    m.add("VOLUME_FRACTION_MIN", granrs_core::levelset::vof::F_MIN)?;
    m.add("ParameterError", m.py().get_type::<ParameterError>())?;
    m.add("SolverError", m.py().get_type::<SolverError>())?;
    m.add("SimulationError", m.py().get_type::<SimulationError>())?;
    Ok(())
}
