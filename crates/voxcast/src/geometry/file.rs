//! The geometry file (`geometry.toml`, written by `voxcast simulate` beside
//! its frames) and the scene's `[geometry]` table. World coordinates are the
//! volume's physical coordinates (`origin + index·spacing`, the units of
//! the spacing).
//!
//! ```toml
//! [[box]]
//! min = [0.0, 0.0, 0.0]
//! max = [1.0, 0.5, 0.8]
//! color = [0.7, 0.6, 0.5]   # sRGB 0..1; optional, default [0.75, 0.75, 0.75]
//! name = "desk"             # optional
//! [[plane]]
//! point = [0.0, 0.0, 0.0]
//! normal = [0.0, 0.0, 1.0]   # seen from this side only (from behind: transparent)
//! color = [0.5, 0.5, 0.5]
//! # half_extent = [2.0, 3.0]  optional: a rectangle; axes u, v of geometry::plane_axes
//! [[mesh]]
//! path = "chair.obj"        # relative to the TOML file
//! color = [0.6, 0.4, 0.3]
//! translate = [0.0, 0.0, 0.0]  # optional
//! scale = 1.0                  # optional
//! ```

use serde::{Deserialize, Serialize};

/// Default surface colour (sRGB).
pub const DEFAULT_COLOR: [f32; 3] = [0.75, 0.75, 0.75];

fn default_color() -> [f32; 3] {
    DEFAULT_COLOR
}
fn default_scale() -> f32 {
    1.0
}
fn is_default_color(c: &[f32; 3]) -> bool {
    *c == DEFAULT_COLOR
}
fn is_one(s: &f32) -> bool {
    *s == 1.0
}
fn is_zero3(v: &[f32; 3]) -> bool {
    *v == [0.0; 3]
}

/// An axis-aligned box.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxDef {
    pub min: [f32; 3],
    pub max: [f32; 3],
    #[serde(default = "default_color", skip_serializing_if = "is_default_color")]
    pub color: [f32; 3],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
}

/// A plane, infinite or a rectangle of `half_extent` along its in-plane
/// axes (see [`super::plane_axes`]); visible only from the side its normal
/// points to.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlaneDef {
    pub point: [f32; 3],
    pub normal: [f32; 3],
    #[serde(default = "default_color", skip_serializing_if = "is_default_color")]
    pub color: [f32; 3],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub half_extent: Option<[f32; 2]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
}

/// A Wavefront OBJ triangle mesh, placed by `p·scale + translate`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshDef {
    /// Relative to the file that names it.
    pub path: String,
    #[serde(default = "default_color", skip_serializing_if = "is_default_color")]
    pub color: [f32; 3],
    #[serde(default, skip_serializing_if = "is_zero3")]
    pub translate: [f32; 3],
    #[serde(default = "default_scale", skip_serializing_if = "is_one")]
    pub scale: f32,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
}

/// The shapes of a geometry file.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GeometryDef {
    #[serde(default, rename = "box", skip_serializing_if = "Vec::is_empty")]
    pub boxes: Vec<BoxDef>,
    #[serde(default, rename = "plane", skip_serializing_if = "Vec::is_empty")]
    pub planes: Vec<PlaneDef>,
    #[serde(default, rename = "mesh", skip_serializing_if = "Vec::is_empty")]
    pub meshes: Vec<MeshDef>,
}

impl GeometryDef {
    pub fn is_empty(&self) -> bool {
        self.boxes.is_empty() && self.planes.is_empty() && self.meshes.is_empty()
    }
}

fn yes() -> bool {
    true
}
fn is_true(b: &bool) -> bool {
    *b
}
fn is_false(b: &bool) -> bool {
    !*b
}

/// The scene's `[geometry]` table: where the opaque geometry comes from and
/// how it is lit.
///
/// ```toml
/// [geometry]
/// auto = true             # geometry.toml in the input's folder, or an FDS case's OBST boxes
/// file = "room.toml"      # a geometry file (relative to the scene file)
/// shadows = false         # smoke (and geometry) shadows on the surfaces
/// light = [-0.3, -0.5, 0.8]  # direction towards the key light (world); default: over the camera's left shoulder
/// [[geometry.box]]        # inline shapes, as in a geometry file
/// min = [0, 0, 0]
/// max = [1, 1, 1]
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GeometrySpec {
    /// Load the geometry that comes with the input: `geometry.toml` in the
    /// input folder (or beside the input file), or the OBST boxes of an FDS
    /// `.smv`.
    #[serde(default = "yes", skip_serializing_if = "is_true")]
    pub auto: bool,
    /// A geometry file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub file: Option<String>,
    /// Shadow rays from each surface point to the key light through the
    /// smoke (Beer–Lambert) and the other shapes.
    #[serde(default, skip_serializing_if = "is_false")]
    pub shadows: bool,
    /// Direction towards the key light in world coordinates (need not be
    /// unit length); default: from above-left-behind the camera.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub light: Option<[f32; 3]>,
    #[serde(default, rename = "box", skip_serializing_if = "Vec::is_empty")]
    pub boxes: Vec<BoxDef>,
    #[serde(default, rename = "plane", skip_serializing_if = "Vec::is_empty")]
    pub planes: Vec<PlaneDef>,
    #[serde(default, rename = "mesh", skip_serializing_if = "Vec::is_empty")]
    pub meshes: Vec<MeshDef>,
}

impl Default for GeometrySpec {
    fn default() -> Self {
        GeometrySpec {
            auto: true,
            file: None,
            shadows: false,
            light: None,
            boxes: Vec::new(),
            planes: Vec::new(),
            meshes: Vec::new(),
        }
    }
}

impl GeometrySpec {
    /// True when it is the default (left out of saved scenes).
    pub fn is_default(&self) -> bool {
        *self == GeometrySpec::default()
    }

    /// The inline shapes.
    pub fn shapes(&self) -> GeometryDef {
        GeometryDef {
            boxes: self.boxes.clone(),
            planes: self.planes.clone(),
            meshes: self.meshes.clone(),
        }
    }
}
