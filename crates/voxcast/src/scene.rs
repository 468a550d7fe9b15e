//! The scene: everything a render depends on, as plain data that reads from
//! and writes to TOML, so every image can be reproduced with
//! `voxcast render --scene scene.toml`.
//!
//! ```toml
//! [input]
//! path = "../shared/data/teapot_ct/slices"   # or builtin:demo; relative to this file
//!
//! [transfer]
//! tf = "auto"              # a preset name, "auto", or a TF TOML file
//! # window = [-1000, 2000] # data values mapped to 0…1
//! # [transfer.map]        # an inline map (wins over `tf`), as written by --save-scene
//!
//! [camera]
//! projection = "perspective"
//! azimuth = 30.0
//! elevation = 20.0
//! zoom = 1.0
//! fov = 30.0
//!
//! [render]
//! width = 512
//! height = 512
//! method = "uniform"
//! step = 0.5
//! ert = 0.99
//! order = "front-to-back"
//! optical = "emission-absorption"
//! shading = true
//! background = [0.0, 0.0, 0.0]
//! seed = 0
//!
//! [geometry]               # opaque geometry (see geometry::file); left out: auto
//! file = "room.toml"
//! shadows = true
//! ```

use crate::camera::CameraParams;
use crate::error::{Error, FieldError, Result};
use crate::files::write_file;
use crate::geometry::{Geometry, GeometrySpec};
use crate::image::Image;
use crate::io::OpenOptions;
use crate::render::{RenderParams, RenderStats};
use crate::transfer::TransferFunction;
use crate::volume::Volume;
use serde::{Deserialize, Serialize};
use std::path::{Component, Path, PathBuf};

/// Prefix of built-in volume names (defined with them, in [`crate::builtin`]).
pub use crate::builtin::PREFIX as BUILTIN_PREFIX;

/// What to load.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(from = "InputFields")]
pub struct InputSpec {
    /// A file, folder or glob; or `builtin:NAME`.
    pub path: String,
    #[serde(flatten)]
    pub options: OpenOptions,
}

/// `[input]` as it is read: serde cannot refuse unknown keys next to a
/// flattened struct, so the options' keys are spelled out here.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct InputFields {
    path: String,
    #[serde(default)]
    raw: Option<crate::io::RawLayout>,
    #[serde(default)]
    spacing: Option<[f32; 3]>,
    #[serde(default)]
    variable: Option<String>,
    #[serde(default)]
    time: Option<f64>,
    #[serde(default)]
    level: Option<usize>,
    #[serde(default)]
    lod_scale: Option<f32>,
}

impl From<InputFields> for InputSpec {
    fn from(f: InputFields) -> InputSpec {
        InputSpec {
            path: f.path,
            options: OpenOptions {
                raw: f.raw,
                spacing: f.spacing,
                variable: f.variable,
                time: f.time,
                level: f.level,
                lod_scale: f.lod_scale,
            },
        }
    }
}

impl Default for InputSpec {
    fn default() -> Self {
        InputSpec {
            path: format!("{BUILTIN_PREFIX}demo"),
            options: OpenOptions::default(),
        }
    }
}

/// Which transfer function, over which window.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[serde(default)]
pub struct TransferSpec {
    /// A preset name, `auto` (chosen from the histogram), or a TOML file.
    pub tf: String,
    /// Data values mapped to 0 and 1 (default: the map's own window on CT
    /// data in HU, else the data range).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub window: Option<[f32; 2]>,
    /// An inline map; wins over `tf`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub map: Option<TransferFunction>,
}

impl Default for TransferSpec {
    fn default() -> Self {
        TransferSpec {
            tf: "auto".into(),
            window: None,
            map: None,
        }
    }
}

/// Everything a render depends on.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    #[serde(default)]
    pub input: InputSpec,
    #[serde(default)]
    pub transfer: TransferSpec,
    #[serde(default)]
    pub camera: CameraParams,
    #[serde(default)]
    pub render: RenderParams,
    /// Opaque geometry: a file, inline shapes, or what comes with the input.
    #[serde(default, skip_serializing_if = "GeometrySpec::is_default")]
    pub geometry: GeometrySpec,
}

/// A scene with its volume loaded and its transfer function resolved.
pub struct Prepared {
    pub volume: Volume,
    pub tf: TransferFunction,
    pub window: [f32; 2],
    /// Opaque geometry, if the scene has any.
    pub geometry: Option<std::sync::Arc<Geometry>>,
}

impl Scene {
    /// Reads a scene file; relative paths in it are taken from its folder.
    pub fn load(path: &Path) -> Result<Scene> {
        let mut scene: Scene = crate::files::read_toml(path)?;
        let base = path.parent().unwrap_or(Path::new("."));
        if !scene.input.path.starts_with(BUILTIN_PREFIX) {
            scene.input.path = join(base, &scene.input.path);
        }
        if TransferFunction::preset(&scene.transfer.tf).is_none() && scene.transfer.tf != "auto" {
            scene.transfer.tf = join(base, &scene.transfer.tf);
        }
        if let Some(f) = &mut scene.geometry.file {
            *f = join(base, f);
        }
        for m in &mut scene.geometry.meshes {
            m.path = join(base, &m.path);
        }
        if let Some(e) = scene.problem() {
            return Err(Error::format(path, e.field, e.message));
        }
        Ok(scene)
    }

    /// Checks every value a user can set, from flags or a file alike: the
    /// error names the field (`camera.fov`, `transfer.window`, …).
    pub fn validate(&self) -> Result<()> {
        match self.problem() {
            Some(e) => Err(e.into()),
            None => Ok(()),
        }
    }

    /// The first invalid value, naming its field; `None` when the scene is
    /// valid. The one set of rules for scene files, the command line (which
    /// names the flag that set the field) and the API: each part checks its
    /// own values ([`CameraParams::validate`](crate::camera::CameraParams::validate),
    /// [`RenderParams::validate`](crate::render::RenderParams::validate), …).
    pub fn problem(&self) -> Option<FieldError> {
        let bad = |field: &str, message: String| Some(FieldError::new(field, message));
        if let Err(e) = self.camera.validate() {
            return Some(e);
        }
        if let Some([lo, hi]) = self.transfer.window {
            if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                return bad(
                    "transfer.window",
                    format!("[{lo}, {hi}]: expected [LO, HI] with finite LO < HI"),
                );
            }
        }
        if let Some(m) = &self.transfer.map {
            if let Err(e) = m.validate() {
                return Some(e.within("transfer.map"));
            }
        }
        if let Some(s) = self.input.options.spacing {
            if s.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
                return bad(
                    "input.spacing",
                    format!("{s:?}: each spacing must be a positive number"),
                );
            }
        }
        if let Some(l) = self.geometry.light {
            if !l.iter().all(|x| x.is_finite()) || l == [0.0; 3] {
                return bad(
                    "geometry.light",
                    format!("{l:?}: expected a non-zero direction [x, y, z]"),
                );
            }
        }
        self.render.validate().err()
    }

    /// Writes the scene to `path` (atomically), with file paths relative to
    /// the scene file's folder.
    pub fn save(&self, path: &Path) -> Result<()> {
        let text = self.to_toml(path)?;
        write_file(path, |f| {
            use std::io::Write;
            f.write_all(text.as_bytes())
        })
    }

    /// The scene as the TOML text of a file at `path` (file paths in it made
    /// relative to that file's folder).
    pub fn to_toml(&self, path: &Path) -> Result<String> {
        let mut s = self.clone();
        let base = path.parent().unwrap_or(Path::new("."));
        if !s.input.path.starts_with(BUILTIN_PREFIX) {
            s.input.path = relative_to(Path::new(&s.input.path), base);
        }
        if s.map_is_file() {
            s.transfer.tf = relative_to(Path::new(&s.transfer.tf), base);
        }
        if let Some(f) = &mut s.geometry.file {
            *f = relative_to(Path::new(f), base);
        }
        for m in &mut s.geometry.meshes {
            m.path = relative_to(Path::new(&m.path), base);
        }
        let text = toml::to_string(&s)
            .map_err(|e| Error::invalid(format!("cannot write the scene: {e}")))?;
        Ok(format!(
            "# voxcast scene: render it with `voxcast render --scene THIS_FILE`\n{text}"
        ))
    }

    fn map_is_file(&self) -> bool {
        self.transfer.tf != "auto" && TransferFunction::preset(&self.transfer.tf).is_none()
    }

    /// Loads the volume named by the input.
    pub fn load_volume(&self) -> Result<Volume> {
        let p = &self.input.path;
        let mut v = if let Some(name) = p.strip_prefix(BUILTIN_PREFIX) {
            crate::builtin::open(name)?
        } else {
            crate::io::open(Path::new(p), &self.input.options)?
        };
        if p.starts_with(BUILTIN_PREFIX) {
            if let Some(s) = self.input.options.spacing {
                v.set_spacing(s.into())?;
            }
        }
        Ok(v)
    }

    /// Loads the volume and resolves the transfer function and window.
    pub fn prepare(&self) -> Result<Prepared> {
        let volume = self.load_volume()?;
        self.prepare_with(volume)
    }

    /// Resolves the transfer function and window for an already loaded volume.
    pub fn prepare_with(&self, volume: Volume) -> Result<Prepared> {
        self.validate()?;
        let tf = match &self.transfer.map {
            Some(m) => m.clone(),
            None => TransferFunction::resolve(&self.transfer.tf, &volume)?,
        };
        let window = tf.window_for(&volume, self.transfer.window);
        let geometry = self.load_geometry()?.map(std::sync::Arc::new);
        Ok(Prepared {
            volume,
            tf,
            window,
            geometry,
        })
    }

    /// The scene's opaque geometry (`None` when it has none).
    pub fn load_geometry(&self) -> Result<Option<Geometry>> {
        Geometry::for_scene(&self.geometry, &self.input.path, Path::new(""))
    }

    /// The same scene with the transfer function written out inline and the
    /// window fixed, so that it reproduces the image even if presets or the
    /// automatic choice change.
    pub fn resolved(&self, prepared: &Prepared) -> Scene {
        let mut s = self.clone();
        s.transfer.map = Some(prepared.tf.clone());
        s.transfer.window = Some(prepared.window);
        s
    }

    /// Renders a prepared scene.
    pub fn render(
        &self,
        prepared: &Prepared,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<(Image, RenderStats)> {
        crate::render::Renderer::new(&prepared.volume, prepared.window)?
            .with_geometry(prepared.geometry.clone())
            .render(&prepared.tf, &self.camera, &self.render, progress)
    }
}

fn join(base: &Path, p: &str) -> String {
    let path = Path::new(p);
    if path.is_absolute() || base.as_os_str().is_empty() {
        p.to_string()
    } else {
        base.join(path).to_string_lossy().into_owned()
    }
}

/// `path` relative to folder `base` when both can be made absolute; else
/// `path` as it is.
fn relative_to(path: &Path, base: &Path) -> String {
    let abs = |p: &Path| -> Option<PathBuf> {
        let p = if p.as_os_str().is_empty() {
            Path::new(".")
        } else {
            p
        };
        std::path::absolute(p).ok().map(|a| normalize(&a))
    };
    let (Some(p), Some(b)) = (abs(path), abs(base)) else {
        return path.to_string_lossy().into_owned();
    };
    let pc: Vec<Component> = p.components().collect();
    let bc: Vec<Component> = b.components().collect();
    let common = pc.iter().zip(&bc).take_while(|(a, b)| a == b).count();
    if common == 0 {
        return p.to_string_lossy().into_owned();
    }
    let mut out = PathBuf::new();
    for _ in common..bc.len() {
        out.push("..");
    }
    for c in &pc[common..] {
        out.push(c.as_os_str());
    }
    if out.as_os_str().is_empty() {
        ".".into()
    } else {
        out.to_string_lossy().into_owned()
    }
}

/// Removes `.` and folds `..` lexically.
fn normalize(p: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            c => out.push(c.as_os_str()),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scene_round_trips_through_toml_with_relative_paths() {
        let dir = tempfile::tempdir().unwrap();
        let data = dir.path().join("data");
        std::fs::create_dir(&data).unwrap();
        let mut s = Scene::default();
        s.input.path = data.join("vol.nrrd").to_string_lossy().into_owned();
        s.camera.azimuth = 42.0;
        s.render.width = 77;
        s.transfer.window = Some([1.0, 2.0]);
        let sub = dir.path().join("scenes");
        std::fs::create_dir(&sub).unwrap();
        let file = sub.join("a.toml");
        s.save(&file).unwrap();
        let text = std::fs::read_to_string(&file).unwrap();
        assert!(text.contains("path = \"../data/vol.nrrd\""), "{text}");
        let back = Scene::load(&file).unwrap();
        assert_eq!(back.camera, s.camera);
        assert_eq!(back.render, s.render);
        assert_eq!(back.transfer, s.transfer);
        assert_eq!(
            normalize(Path::new(&back.input.path)),
            normalize(Path::new(&s.input.path))
        );
    }

    #[test]
    fn bad_scene_names_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("bad.toml");
        std::fs::write(&file, "[render]\nstep = \"fast\"\n").unwrap();
        let e = Scene::load(&file).unwrap_err().to_string();
        assert!(e.contains("bad.toml") && e.contains("line 2"), "{e}");
        std::fs::write(&file, "[render]\nstep = 0.0\n").unwrap();
        let e = Scene::load(&file).unwrap_err().to_string();
        assert!(e.contains("step"), "{e}");
    }
}
