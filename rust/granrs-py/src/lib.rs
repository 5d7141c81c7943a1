use pyo3::prelude::*;
#[pymodule]
fn _granrs(_m: &Bound<'_, PyModule>) -> PyResult<()> { Ok(()) }
