//! Binding of the depth-averaged (Savage–Hutter) model, `granrs.DepthAveragedModel` wraps it.
//! Equations and numerics: granrs-core `models/depth_averaged.rs`.

use granrs_core::models::depth_averaged::GHOSTS;
use granrs_core::models::{DepthAveragedConfig, DepthAveragedModel, DepthAveragedPore, EarthPressure};
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

#[pymethods]
impl PyDepthAveraged {
    /// pore: None (not fluidised) or {"diffusivity", "supply_ratio", "supply_x_max"};
    /// internal_friction_angle: None (constant k = earth_pressure) or φ in degrees (Savage–Hutter's
    /// active coefficient per cell, earth_pressure ignored).
    #[new]
    #[pyo3(signature = (cells, length, gravity=9.81, earth_pressure=1.0, basal_friction_angle=0.0, cfl=0.4,
                        dry_depth=1e-6, max_dt=1e-2, pore=None, internal_friction_angle=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        cells: usize,
        length: f64,
        gravity: f64,
        earth_pressure: f64,
        basal_friction_angle: f64,
        cfl: f64,
        dry_depth: f64,
        max_dt: f64,
        pore: Option<&Bound<'_, PyDict>>,
        internal_friction_angle: Option<f64>,
    ) -> PyResult<Self> {
        let pore = match pore {
            None => None,
            Some(d) => {
                let get = |key: &str| -> PyResult<f64> {
                    match d.get_item(key)? {
                        Some(v) => v.extract::<f64>().map_err(|_| param_err(&format!("pore.{key}"), v, "a number")),
                        None => Err(param_err(&format!("pore.{key}"), "missing", "a number")),
                    }
                };
                Some(DepthAveragedPore { diffusivity: get("diffusivity")?, supply_ratio: get("supply_ratio")?, supply_x_max: get("supply_x_max")? })
            }
        };
        let earth_pressure = match internal_friction_angle {
            None => EarthPressure::Constant(earth_pressure),
            Some(phi) => EarthPressure::SavageHutterActive { internal_friction_angle: phi },
        };
        let cfg = DepthAveragedConfig { cells, length, gravity, earth_pressure, basal_friction_angle, cfl, dry_depth, max_dt, pore };
        Ok(PyDepthAveraged { inner: DepthAveragedModel::new(cfg).map_err(to_py)? })
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

    /// Earth-pressure coefficient k per cell (a copy).
    fn earth_pressure<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_vec(py, self.inner.earth_pressure().collect())
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
