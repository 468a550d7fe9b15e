//! `Volume`: a voxcast volume held for Python, read from a file by any of
//! the library's readers, or wrapping a NumPy array's memory in place.

use crate::err;
use glam::Vec3;
use numpy::ndarray::ArrayView1;
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use std::any::Any;
use std::path::Path;
use std::sync::Arc;
use voxcast::io::{OpenOptions, RawLayout};
use voxcast::volume::Voxels;
use voxcast::{ScalarType, VoxelData};

/// A 3-D scalar field: dims, spacing, origin and the voxels (u8, u16, i16
/// or f32, x varying fastest). Cloning it on the Rust side shares the voxels.
#[pyclass(frozen, module = "voxcast._voxcast", name = "_Volume")]
pub struct Volume {
    pub(crate) inner: voxcast::Volume,
    /// The file or folder it was read from (outputs may not land on it).
    #[pyo3(get)]
    pub(crate) source: Option<String>,
}

impl Volume {
    pub(crate) fn volume(&self) -> voxcast::Volume {
        // Cheap: the voxels are shared (`into_shared` when made).
        self.inner.clone()
    }
}

/// Voxels read in place from a contiguous 1-D NumPy array, which they keep
/// alive.
fn shared<T: numpy::Element + Send + Sync + Copy>(
    a: PyReadonlyArray1<'_, T>,
) -> PyResult<Voxels<T>> {
    let slice = a
        .as_slice()
        .map_err(|_| err("internal: the array handed to the native module is not contiguous"))?;
    let (ptr, len) = (slice.as_ptr(), slice.len());
    let owner: Arc<dyn Any + Send + Sync> = Arc::new(a.as_any().clone().unbind());
    // SAFETY: the array object is kept alive by `owner`; NumPy never moves
    // an array's data while a reference to it is held. The Python side
    // documents that the array must not be written while voxcast holds it.
    Ok(unsafe { Voxels::shared(ptr, len, owner) })
}

fn vec3(v: [f64; 3], what: &str) -> PyResult<Vec3> {
    if v.iter().any(|x| !x.is_finite()) {
        return Err(err(format!("{what} {v:?}: each value must be finite")));
    }
    Ok(Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32))
}

/// A volume over a 1-D contiguous array of u8, u16, i16 or f32 holding
/// `dims` (x, y, z) voxels, x fastest; spacing and origin in x, y, z. The
/// voxels are read in place (no copy).
#[pyfunction]
#[pyo3(signature = (data, dims, spacing, origin, name=None, units=None))]
pub fn from_array(
    data: &Bound<'_, PyAny>,
    dims: [usize; 3],
    spacing: [f64; 3],
    origin: [f64; 3],
    name: Option<String>,
    units: Option<String>,
) -> PyResult<Volume> {
    let voxels = if let Ok(a) = data.extract::<PyReadonlyArray1<u8>>() {
        VoxelData::U8(shared(a)?)
    } else if let Ok(a) = data.extract::<PyReadonlyArray1<u16>>() {
        VoxelData::U16(shared(a)?)
    } else if let Ok(a) = data.extract::<PyReadonlyArray1<i16>>() {
        VoxelData::I16(shared(a)?)
    } else if let Ok(a) = data.extract::<PyReadonlyArray1<f32>>() {
        VoxelData::F32(shared(a)?)
    } else {
        let ty = data
            .getattr("dtype")
            .map(|d| d.to_string())
            .unwrap_or_else(|_| data.get_type().to_string());
        return Err(err(format!(
            "array of {ty}: expected a 1-D array of uint8, uint16, int16 or float32"
        )));
    };
    let mut v = voxcast::Volume::new(
        dims,
        vec3(spacing, "spacing")?,
        vec3(origin, "origin")?,
        voxels,
    )
    .map_err(err)?;
    v.name = name;
    v.units = units;
    Ok(Volume {
        inner: v,
        source: None,
    })
}

/// Reads a volume with the library's readers (every format `voxcast render`
/// reads, or `builtin:NAME`).
#[pyfunction]
#[pyo3(signature = (path, *, raw_dims=None, raw_type=None, raw_big_endian=false, raw_header_bytes=0, spacing=None, variable=None, time=None, level=None))]
#[allow(clippy::too_many_arguments)]
pub fn open(
    py: Python<'_>,
    path: std::path::PathBuf,
    raw_dims: Option<[u64; 3]>,
    raw_type: Option<String>,
    raw_big_endian: bool,
    raw_header_bytes: u64,
    spacing: Option<[f32; 3]>,
    variable: Option<String>,
    time: Option<f64>,
    level: Option<usize>,
) -> PyResult<Volume> {
    let raw = match (raw_dims, raw_type) {
        (None, None) => None,
        (Some(dims), Some(t)) => Some(RawLayout {
            dims,
            scalar_type: ScalarType::parse(&t)
                .ok_or_else(|| err(format!("raw_type {t:?}: expected u8, u16, i16 or f32")))?,
            big_endian: raw_big_endian,
            header_bytes: raw_header_bytes,
        }),
        (Some(_), None) => return Err(err("raw_dims needs raw_type (u8, u16, i16 or f32)")),
        (None, Some(_)) => return Err(err("raw_type needs raw_dims=(x, y, z)")),
    };
    if let Some(s) = spacing {
        if s.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
            return Err(err(format!(
                "spacing {s:?}: each value must be a positive number"
            )));
        }
    }
    let mut scene = voxcast::Scene::default();
    scene.input.path = path.to_string_lossy().into_owned();
    scene.input.options = OpenOptions {
        raw,
        spacing,
        variable,
        time,
        level,
        lod_scale: None,
    };
    let is_builtin = scene.input.path.starts_with(voxcast::scene::BUILTIN_PREFIX);
    let glob = scene.input.path.contains(['*', '?', '[']);
    if !is_builtin && !glob && !Path::new(&scene.input.path).exists() {
        return Err(err(format!("{}: no such file or folder", path.display())));
    }
    let v = py.detach(|| scene.load_volume()).map_err(err)?;
    Ok(Volume {
        inner: v.into_shared(),
        source: Some(scene.input.path),
    })
}

#[pymethods]
impl Volume {
    /// Grid size (x, y, z).
    #[getter]
    fn dims(&self) -> (usize, usize, usize) {
        let d = self.inner.dims();
        (d[0], d[1], d[2])
    }

    /// Distance between voxel centres along x, y, z.
    #[getter]
    fn spacing(&self) -> (f32, f32, f32) {
        self.inner.spacing().into()
    }

    /// World position of voxel (0, 0, 0).
    #[getter]
    fn origin(&self) -> (f32, f32, f32) {
        self.inner.origin().into()
    }

    /// `u8`, `u16`, `i16` or `f32`.
    #[getter]
    fn dtype(&self) -> &'static str {
        self.inner.scalar_type().name()
    }

    /// The volume's facts as JSON (the Python side makes the dict).
    fn info_json(&self) -> String {
        let v = &self.inner;
        let s = v.stats();
        serde_json::json!({
            "dims": v.dims(),
            "spacing": v.spacing().to_array(),
            "origin": v.origin().to_array(),
            "dtype": v.scalar_type().name(),
            "min": finite(s.min as f64),
            "max": finite(s.max as f64),
            "non_finite": s.non_finite(),
            "units": v.units,
            "name": v.name,
            "variables": v.variables,
            "time": v.time,
            "active_voxels": v.active_voxels,
            "bytes": v.len() * v.scalar_type().size(),
        })
        .to_string()
    }

    /// The voxels as a 1-D array in memory order (x fastest), a view of the
    /// volume's own memory (no copy); the Python side reshapes it.
    fn flat_view<'py>(slf: &Bound<'py, Self>) -> Bound<'py, PyAny> {
        let container = slf.clone().into_any();
        macro_rules! view {
            ($v:expr) => {
                // SAFETY: the view borrows the volume's voxels, which live
                // (never written) as long as `container`, the volume.
                unsafe { PyArray1::borrow_from_array(&ArrayView1::from(&$v[..]), container) }
                    .into_any()
            };
        }
        match slf.get().inner.data() {
            VoxelData::U8(v) => view!(v),
            VoxelData::U16(v) => view!(v),
            VoxelData::I16(v) => view!(v),
            VoxelData::F32(v) => view!(v),
        }
    }

    /// Writes the volume as NRRD (raw, or gzip when `gzip`), atomically;
    /// refuses to replace the file the volume was read from.
    fn save_nrrd(&self, py: Python<'_>, path: std::path::PathBuf, gzip: bool) -> PyResult<()> {
        let mut outputs = voxcast::files::Outputs::new(self.source.iter());
        outputs.plan("path", &path, &["nrrd"]).map_err(err)?;
        let encoding = if gzip {
            voxcast::io::nrrd_write::Encoding::Gzip
        } else {
            voxcast::io::nrrd_write::Encoding::Raw
        };
        py.detach(|| voxcast::io::nrrd_write::write(&path, &self.inner, encoding))
            .map_err(err)
    }
}

fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}
