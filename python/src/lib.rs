use pyo3::prelude::*;

#[pymodule]
fn _furfit(_m: &Bound<'_, PyModule>) -> PyResult<()> {
    Ok(())
}
