//! Binding of the depth-averaged (Savage–Hutter) model, `granrs.DepthAveragedModel` wraps it.
//! Equations and numerics: granrs-core `models/depth_averaged.rs`.

use granrs_core::models::depth_averaged::GHOSTS;
use granrs_core::models::{DepthAveragedConfig, DepthAveragedModel, DepthAveragedPore, EarthPressure, PoreTransport};
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::{param_err, to_py};

/// The Rust depth-averaged model.
#[pyclass(name = "RustDepthAveraged", module = "granrs._granrs")]
pub struct PyDepthAveraged {
    inner: DepthAveragedModel,
}

fn slice1<'a>(name: &str, a: &'a PyReadonlyArray1<'_, f64>) -> PyResult<&'a [f64]> {
    a.as_slice().map_err(|_| param_err(name, "a non-contiguous array", "a contiguous 1-D float64 array"))
}

/// The keys of the depth-averaged model's configuration object.
const KEYS: [&str; 10] =
    ["cells", "length", "gravity", "earth_pressure", "basal_friction_angle", "cfl", "dry_depth", "max_dt", "pore", "internal_friction_angle"];

/// The core's configuration from the one configuration object of `RustDepthAveraged(config)`: a
/// dict with `cells` and `length` (required) and any of `gravity`, `earth_pressure`,
/// `basal_friction_angle`, `cfl`, `dry_depth`, `max_dt` (absent: `DepthAveragedConfig::new`'s
/// defaults), `pore` (None: not fluidised, or {diffusivity, supply_ratio, supply_x_max, transport}
/// with transport 'depth-integrated' or 'basal-ratio') and `internal_friction_angle` (None: the
/// constant k = earth_pressure of the effective stress; φ in degrees: Savage–Hutter's active
/// coefficient of φ and the basal angle). Every value is checked in Rust
/// (`DepthAveragedConfig::validate`).
fn build_config(config: &Bound<'_, PyDict>) -> PyResult<DepthAveragedConfig> {
    for k in config.keys() {
        let k: String = k.extract()?;
        if !KEYS.contains(&k.as_str()) {
            return Err(param_err("config", &k, &format!("a key of the depth-averaged model's configuration, one of {}", KEYS.join(", "))));
        }
    }
    let item = |k: &str| -> PyResult<Option<Bound<'_, PyAny>>> { Ok(config.get_item(k)?.filter(|v| !v.is_none())) };
    let number = |k: &str, default: f64| -> PyResult<f64> {
        match item(k)? {
            None => Ok(default),
            Some(v) => v.extract::<f64>().map_err(|_| param_err(k, &v, "a number")),
        }
    };
    let cells: usize = match item("cells")? {
        None => return Err(param_err("cells", "missing", "an integer in [4, 10000000]")),
        Some(v) => v.extract().map_err(|_| param_err("cells", &v, "an integer in [4, 10000000]"))?,
    };
    let length = match item("length")? {
        None => return Err(param_err("length", "missing", "a finite number > 0 (m)")),
        Some(v) => v.extract::<f64>().map_err(|_| param_err("length", &v, "a finite number > 0 (m)"))?,
    };
    let mut cfg = DepthAveragedConfig::new(cells, length);
    cfg.gravity = number("gravity", cfg.gravity)?;
    cfg.basal_friction_angle = number("basal_friction_angle", cfg.basal_friction_angle)?;
    cfg.cfl = number("cfl", cfg.cfl)?;
    cfg.dry_depth = number("dry_depth", cfg.dry_depth)?;
    cfg.max_dt = number("max_dt", cfg.max_dt)?;
    let EarthPressure::Constant(k_default) = cfg.earth_pressure else { unreachable!("DepthAveragedConfig::new: a constant k") };
    cfg.earth_pressure = match item("internal_friction_angle")? {
        None => EarthPressure::Constant(number("earth_pressure", k_default)?),
        Some(v) => EarthPressure::SavageHutterActive {
            internal_friction_angle: v.extract::<f64>().map_err(|_| param_err("internal_friction_angle", &v, "None or a number"))?,
        },
    };
    cfg.pore = match item("pore")? {
        None => None,
        Some(p) => {
            let d = p.cast::<PyDict>().map_err(|_| param_err("pore", &p, "None or a dict {diffusivity, supply_ratio, supply_x_max, transport}"))?;
            let get = |key: &str| -> PyResult<f64> {
                match d.get_item(key)? {
                    Some(v) => v.extract::<f64>().map_err(|_| param_err(&format!("pore.{key}"), v, "a number")),
                    None => Err(param_err(&format!("pore.{key}"), "missing", "a number")),
                }
            };
            let transport = match d.get_item("transport")? {
                None => PoreTransport::DepthIntegrated,
                Some(v) => match v.extract::<String>().ok().as_deref() {
                    Some("depth-integrated") => PoreTransport::DepthIntegrated,
                    Some("basal-ratio") => PoreTransport::BasalRatio,
                    _ => return Err(param_err("pore.transport", v, "'depth-integrated' or 'basal-ratio'")),
                },
            };
            Some(DepthAveragedPore { diffusivity: get("diffusivity")?, supply_ratio: get("supply_ratio")?, supply_x_max: get("supply_x_max")?, transport })
        }
    };
    Ok(cfg)
}

#[pymethods]
impl PyDepthAveraged {
    /// Builds a model from its configuration object (see `build_config`).
    #[new]
    fn new(config: &Bound<'_, PyDict>) -> PyResult<Self> {
        let cfg = build_config(config)?;
        Ok(PyDepthAveraged { inner: DepthAveragedModel::new(cfg).map_err(to_py)? })
    }

    /// The defaults of the optional keys of the configuration object (`DepthAveragedConfig::new`).
    #[staticmethod]
    fn defaults<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let cfg = DepthAveragedConfig::new(4, 1.0);
        let d = PyDict::new(py);
        d.set_item("gravity", cfg.gravity)?;
        if let EarthPressure::Constant(k) = cfg.earth_pressure {
            d.set_item("earth_pressure", k)?;
        }
        d.set_item("basal_friction_angle", cfg.basal_friction_angle)?;
        d.set_item("cfl", cfg.cfl)?;
        d.set_item("dry_depth", cfg.dry_depth)?;
        d.set_item("max_dt", cfg.max_dt)?;
        d.set_item("pore", py.None())?;
        d.set_item("internal_friction_angle", py.None())?;
        Ok(d)
    }

    /// Full storage (2 ghost cells at each end) of "h", "u" or "beta" as a zero-copy, read-only
    /// NumPy array that keeps the model alive; buffers are never reallocated, so the view stays
    /// live. A view read from another thread while a step runs (the GIL is released) races the
    /// step's writes.
    fn field_storage<'py>(slf: Bound<'py, Self>, name: &str) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let borrowed = slf.borrow();
        let field = match name {
            "h" => &borrowed.inner.h,
            "u" => &borrowed.inner.u,
            "beta" => &borrowed.inner.beta,
            "bed" => &borrowed.inner.bed,
            other => return Err(param_err("name", other, "one of 'h', 'u', 'beta', 'bed'")),
        };
        let container = slf.clone().into_any();
        // SAFETY: the array lives inside the model object, which `container` keeps alive; the
        // buffers are allocated once in DepthAveragedModel::new and never reallocated or moved.
        let arr = unsafe { PyArray1::borrow_from_array(field, container) };
        crate::read_only(arr.as_any())?;
        Ok(arr)
    }

    /// Sets h, u, β (interior values, n each).
    fn set_state(&mut self, h: PyReadonlyArray1<'_, f64>, u: PyReadonlyArray1<'_, f64>, beta: PyReadonlyArray1<'_, f64>) -> PyResult<()> {
        self.inner.set_state(slice1("h", &h)?, slice1("u", &u)?, slice1("beta", &beta)?).map_err(to_py)
    }

    /// Sets the bed elevation b (n values).
    fn set_bed(&mut self, bed: PyReadonlyArray1<'_, f64>) -> PyResult<()> {
        self.inner.set_bed(slice1("bed", &bed)?).map_err(to_py)
    }

    /// One step with the GIL released; returns Δt.
    fn step(&mut self, py: Python<'_>) -> PyResult<f64> {
        let inner = &mut self.inner;
        py.detach(|| inner.step()).map_err(to_py)
    }

    /// Steps until `t_end` (landing on it) or `max_steps`, with the GIL released; returns the
    /// number of steps taken.
    #[pyo3(signature = (t_end, max_steps=None))]
    fn advance(&mut self, py: Python<'_>, t_end: f64, max_steps: Option<u64>) -> PyResult<u64> {
        if !t_end.is_finite() {
            return Err(param_err("t_end", t_end, "a finite time"));
        }
        let inner = &mut self.inner;
        py.detach(|| inner.advance(t_end, max_steps.unwrap_or(u64::MAX))).map_err(to_py)
    }

    /// Σ h Δx [m²].
    fn mass(&self) -> f64 {
        self.inner.mass()
    }

    /// Lateral pressure coefficient K = k (1 − β̂) + β̂ per cell (a copy).
    fn earth_pressure<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_vec(py, self.inner.earth_pressure().collect())
    }

    /// The earth-pressure coefficient k of the effective stress.
    fn effective_earth_pressure(&self) -> f64 {
        self.inner.effective_earth_pressure()
    }

    /// Largest |u| [m/s].
    fn max_speed(&self) -> f64 {
        self.inner.max_speed()
    }

    /// x where h first falls to `threshold`, walking from the wall [m].
    fn front(&self, threshold: f64) -> f64 {
        self.inner.front(threshold)
    }

    #[getter]
    fn time(&self) -> f64 {
        self.inner.time
    }

    #[getter]
    fn step_count(&self) -> u64 {
        self.inner.step_count
    }

    #[getter]
    fn last_dt(&self) -> f64 {
        self.inner.last_dt
    }

    /// (cells, length, dx, ghosts).
    #[getter]
    fn grid(&self) -> (usize, f64, f64, usize) {
        (self.inner.cells(), self.inner.config().length, self.inner.dx(), GHOSTS)
    }
}
