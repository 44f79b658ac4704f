//! `import skelight`: the renderer from Python. Scenes load into [`scene::Scene`], renders
//! come back as [`render::Render`] (a numpy array through `__array__`, with its variance,
//! sample count and, for a shard, its manifest), and errors raise [`SkelightError`] (loader
//! errors [`LoadError`], naming the file and line). The GIL is released while rendering.
//! Everything here is a thin layer over the library's [`skelight::job`],
//! [`skelight::shard`] and [`skelight::compare`], which the CLI runs too.

mod compare;
mod render;
mod scene;

use pyo3::create_exception;
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;

create_exception!(
    _skelight,
    SkelightError,
    PyRuntimeError,
    "An error of the renderer (bad parameters, a failed render)."
);
create_exception!(
    _skelight,
    LoadError,
    SkelightError,
    "A scene or image that cannot be read: the message names the file (and line)."
);

/// The Python exception for a library error.
pub(crate) fn error(e: impl std::fmt::Display) -> PyErr {
    SkelightError::new_err(e.to_string())
}

#[pymodule]
fn _skelight(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("SkelightError", m.py().get_type::<SkelightError>())?;
    m.add("LoadError", m.py().get_type::<LoadError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<scene::Scene>()?;
    m.add_class::<render::Render>()?;
    m.add_function(wrap_pyfunction!(scene::load_file, m)?)?;
    m.add_function(wrap_pyfunction!(scene::default_scene, m)?)?;
    m.add_function(wrap_pyfunction!(render::render, m)?)?;
    m.add_function(wrap_pyfunction!(render::merge, m)?)?;
    m.add_function(wrap_pyfunction!(render::render_key, m)?)?;
    m.add_function(wrap_pyfunction!(render::integrators, m)?)?;
    m.add_function(wrap_pyfunction!(render::load_image, m)?)?;
    m.add_function(wrap_pyfunction!(compare::compare, m)?)?;
    Ok(())
}
