//! `voxcast._voxcast`: the native half of the Python package. The Python
//! half (`python/voxcast/__init__.py`) shapes it to NumPy, xarray and
//! Jupyter habits; this half holds the volume, runs renders and benches with
//! the GIL released, and turns every library error into `VoxcastError`.
//!
//! Nothing here panics on user input: arrays of the wrong type or shape,
//! missing files and bad scenes come back as Python exceptions.
//!
//! Built only with the `python` feature (maturin sets it), so that the
//! workspace builds and tests without a Python interpreter.
#![cfg(feature = "python")]

mod run;
mod scene;
mod volume;

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;

create_exception!(
    voxcast,
    VoxcastError,
    PyException,
    "An error from voxcast: a file that cannot be read (named with the field at fault), a scene \
     value out of range, a render that failed."
);

/// A library error as a Python exception carrying its message.
pub(crate) fn err(e: impl std::fmt::Display) -> PyErr {
    VoxcastError::new_err(e.to_string())
}

#[pymodule]
fn _voxcast(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("VoxcastError", m.py().get_type::<VoxcastError>())?;
    m.add_class::<volume::Volume>()?;
    m.add_class::<scene::Scene>()?;
    m.add_function(wrap_pyfunction!(volume::open, m)?)?;
    m.add_function(wrap_pyfunction!(volume::from_array, m)?)?;
    m.add_function(wrap_pyfunction!(run::render, m)?)?;
    m.add_function(wrap_pyfunction!(run::bench, m)?)?;
    m.add_function(wrap_pyfunction!(run::write_image, m)?)?;
    m.add_function(wrap_pyfunction!(run::png_bytes, m)?)?;
    m.add_function(wrap_pyfunction!(run::write_gif, m)?)?;
    m.add_function(wrap_pyfunction!(run::srgb8, m)?)?;
    m.add_function(wrap_pyfunction!(scene::presets, m)?)?;
    m.add_function(wrap_pyfunction!(scene::methods, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
