//! `Scene`: the scene TOML of `voxcast render --scene`, held for Python. The
//! Python side reads and sets its fields by dotted key through a JSON image
//! of it, so every field the file has is reachable without a binding of its
//! own, and the library's validation judges every change.

use crate::err;
use pyo3::prelude::*;
use std::path::PathBuf;
use voxcast::render::{Method, MethodSpec};

/// Everything a render depends on: input, transfer function, camera,
/// ray casting (the same fields, names and rules as a scene file).
#[pyclass(module = "voxcast._voxcast", name = "_Scene")]
#[derive(Clone)]
pub struct Scene {
    pub(crate) inner: voxcast::Scene,
}

/// A problem with a scene as an error naming the field.
fn check(s: &voxcast::Scene) -> PyResult<()> {
    match s.problem() {
        Some(e) => Err(err(e)),
        None => Ok(()),
    }
}

#[pymethods]
impl Scene {
    /// The default scene (the built-in demo volume, `auto` transfer
    /// function, default camera and sampling).
    #[new]
    fn new() -> Scene {
        Scene {
            inner: voxcast::Scene::default(),
        }
    }

    /// Reads a scene file; relative paths in it are taken from its folder.
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Scene> {
        Ok(Scene {
            inner: voxcast::Scene::load(&path).map_err(err)?,
        })
    }

    /// Parses scene TOML text; relative paths are taken from the working
    /// folder.
    #[staticmethod]
    fn parse(text: &str) -> PyResult<Scene> {
        let inner: voxcast::Scene =
            voxcast::files::input::parse_toml(std::path::Path::new("<scene text>"), text)
                .map_err(err)?;
        check(&inner)?;
        Ok(Scene { inner })
    }

    /// The scene as TOML text; with `path`, the text of a file there (file
    /// paths relative to its folder).
    #[pyo3(signature = (path=None))]
    fn to_toml(&self, path: Option<PathBuf>) -> PyResult<String> {
        let base = path.unwrap_or_else(|| PathBuf::from("scene.toml"));
        self.inner.to_toml(&base).map_err(err)
    }

    /// Writes the scene file, atomically.
    fn save(&self, path: PathBuf) -> PyResult<()> {
        let mut outputs = voxcast::files::Outputs::new([&self.inner.input.path]);
        outputs.plan("path", &path, &["toml"]).map_err(err)?;
        self.inner.save(&path).map_err(err)
    }

    /// The scene as JSON (every field, defaults included).
    fn to_json(&self) -> PyResult<String> {
        serde_json::to_string(&self.inner).map_err(err)
    }

    /// Replaces the scene by one read from JSON; refused (the scene
    /// unchanged) when a field is unknown, mistyped or out of range.
    fn set_json(&mut self, json: &str) -> PyResult<()> {
        let s: voxcast::Scene = serde_json::from_str(json).map_err(err)?;
        check(&s)?;
        self.inner = s;
        Ok(())
    }

    /// Sets `render.method` and its options from a method name as the CLI
    /// takes it (`adaptive+grouped`, `uniform+noskip`).
    fn set_method(&mut self, method: &str) -> PyResult<()> {
        MethodSpec::parse(method)
            .map_err(|e| err(format!("method {method:?}: {e}")))?
            .apply(&mut self.inner.render);
        Ok(())
    }

    /// The method name with its options (`adaptive+grouped`).
    fn method_name(&self) -> String {
        MethodSpec::of(&self.inner.render).to_string()
    }

    fn __eq__(&self, other: &Scene) -> bool {
        self.inner == other.inner
    }
}

/// The transfer-function presets: (name, description).
#[pyfunction]
pub fn presets() -> Vec<(&'static str, &'static str)> {
    voxcast::transfer::PRESETS.to_vec()
}

/// The sampling methods' names.
#[pyfunction]
pub fn methods() -> Vec<&'static str> {
    Method::ALL.iter().map(|m| m.name()).collect()
}
