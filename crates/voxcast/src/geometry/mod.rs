//! Opaque scene geometry — room walls, furniture, FDS obstructions — that
//! the smoke is composited over (S0 Fig. 9–13): axis-aligned boxes, planes
//! (infinite or rectangles) and OBJ triangle meshes, lit with Blinn–Phong.
//!
//! A ray stops at the first opaque hit: the renderer clamps the ray's exit
//! from the volume to the hit and composites the smoke in front over the lit
//! surface ([`crate::render`]). Bounded shapes sit in one [`bvh::Bvh`], so a
//! mesh of many triangles costs O(log n) per ray; infinite planes are tested
//! one by one.
//!
//! Where geometry comes from ([`Geometry::for_scene`]): a geometry file
//! ([`mod@file`]), the scene's `[geometry]` table, or, automatically, the
//! `geometry.toml` beside a simulated volume or the OBST boxes of an FDS
//! case.

pub mod bvh;
pub mod file;
pub mod light;
pub mod obj;
pub mod packet;
pub mod shapes;

pub use file::{BoxDef, GeometryDef, GeometrySpec, MeshDef, PlaneDef};
pub use light::SurfaceLight;
pub use shapes::{plane_axes, Aabb, Plane, Triangle};

use crate::error::{Error, Result};
use crate::transfer::srgb_to_linear;
use bvh::Bvh;
use glam::Vec3;
use std::path::{Path, PathBuf};

/// The file the simulator writes beside its frames.
pub const GEOMETRY_FILE: &str = "geometry.toml";

/// A bounded shape.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Shape {
    Box(Aabb),
    Rect(Plane),
    Tri(Triangle),
}

impl Shape {
    fn bounds(&self) -> Aabb {
        match self {
            Shape::Box(b) => *b,
            // A rectangle always has bounds (only those go in the BVH).
            Shape::Rect(p) => p.bounds().unwrap_or(Aabb::EMPTY),
            Shape::Tri(t) => t.bounds(),
        }
    }

    #[inline(always)]
    fn hit(&self, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> Option<(f32, Vec3)> {
        match self {
            Shape::Box(b) => b.hit(o, d, t_min, t_max),
            Shape::Rect(p) => p.hit(o, d, t_min, t_max),
            Shape::Tri(t) => t.hit(o, d, t_min, t_max),
        }
    }
}

/// One shape of a [`Geometry`], as [`Geometry::primitives`] lists them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Primitive {
    Box(Aabb),
    /// A bounded plane (a rectangle).
    Rect(Plane),
    Triangle(Triangle),
    /// A plane without bounds.
    InfinitePlane(Plane),
}

/// The first opaque surface on a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter (world units for a unit direction).
    pub t: f32,
    /// Unit geometric normal (either side).
    pub normal: Vec3,
    /// Linear albedo.
    pub albedo: Vec3,
}

/// Opaque geometry ready for ray queries, with how it is lit.
#[derive(Clone, Debug, Default)]
pub struct Geometry {
    shapes: Vec<Shape>,
    /// Linear albedo per shape.
    albedo: Vec<Vec3>,
    infinite: Vec<(Plane, Vec3)>,
    bvh: Bvh,
    /// Shadow rays through smoke and shapes towards the key light.
    pub shadows: bool,
    /// Direction towards the key light (world); `None`: camera-relative.
    pub light: Option<[f32; 3]>,
    /// Where the shapes came from, for messages.
    pub sources: Vec<String>,
    counts: [usize; 4],
    /// Per shape: vertex normals of a smooth triangle (Phong-interpolated
    /// shading normal), else `None`.
    vertex_normals: Vec<Option<[Vec3; 3]>>,
}

/// Collects shapes before the BVH is built.
#[derive(Default)]
struct Parts {
    shapes: Vec<Shape>,
    albedo: Vec<Vec3>,
    infinite: Vec<(Plane, Vec3)>,
    sources: Vec<String>,
    /// Boxes, planes, meshes, triangles.
    counts: [usize; 4],
    /// Vertex normals of smooth triangles, by shape index.
    smooth: Vec<(usize, [Vec3; 3])>,
}

fn linear(c: [f32; 3]) -> Vec3 {
    Vec3::from(c.map(srgb_to_linear))
}

impl Parts {
    /// Adds the shapes of `def`; mesh paths are relative to `base`, errors
    /// name `file` (the TOML the shapes were read from) and the field.
    fn add_def(&mut self, def: &GeometryDef, base: &Path, file: &Path, prefix: &str) -> Result<()> {
        let bad = |field: String, msg: &str| Error::format(file, format!("{prefix}{field}"), msg);
        let color_ok = |c: &[f32; 3]| c.iter().all(|x| (0.0..=1.0).contains(x));
        for (i, b) in def.boxes.iter().enumerate() {
            let (lo, hi) = (Vec3::from(b.min), Vec3::from(b.max));
            if !(lo.is_finite() && hi.is_finite()) || lo.cmpgt(hi).any() {
                return Err(bad(
                    format!("box[{i}]"),
                    "min and max must be finite with min ≤ max on every axis",
                ));
            }
            if !color_ok(&b.color) {
                return Err(bad(
                    format!("box[{i}].color"),
                    "expected sRGB values in 0..1",
                ));
            }
            self.push(Shape::Box(Aabb { min: lo, max: hi }), b.color);
            self.counts[0] += 1;
        }
        for (i, p) in def.planes.iter().enumerate() {
            let (pt, n) = (Vec3::from(p.point), Vec3::from(p.normal));
            if !pt.is_finite() || !n.is_finite() || n.length_squared() == 0.0 {
                return Err(bad(
                    format!("plane[{i}]"),
                    "point must be finite and normal a non-zero vector",
                ));
            }
            if p.half_extent
                .is_some_and(|h| h.iter().any(|x| !(x.is_finite() && *x > 0.0)))
            {
                return Err(bad(
                    format!("plane[{i}].half_extent"),
                    "expected two positive half widths along the plane's u and v axes",
                ));
            }
            if !color_ok(&p.color) {
                return Err(bad(
                    format!("plane[{i}].color"),
                    "expected sRGB values in 0..1",
                ));
            }
            let plane = Plane::new(pt, n, p.half_extent);
            if p.half_extent.is_some() {
                self.push(Shape::Rect(plane), p.color);
            } else {
                self.infinite.push((plane, linear(p.color)));
            }
            self.counts[1] += 1;
        }
        for (i, m) in def.meshes.iter().enumerate() {
            if !color_ok(&m.color) {
                return Err(bad(
                    format!("mesh[{i}].color"),
                    "expected sRGB values in 0..1",
                ));
            }
            let path = base.join(&m.path);
            let mesh =
                obj::load_obj(&path, m.scale, Vec3::from(m.translate)).map_err(|e| match e {
                    Error::Invalid(msg) => bad(format!("mesh[{i}]"), &msg),
                    e => e,
                })?;
            self.counts[3] += mesh.triangles.len();
            for (k, t) in mesh.triangles.into_iter().enumerate() {
                self.push(Shape::Tri(t), m.color);
                if let Some(n) = mesh.normals.get(k) {
                    self.smooth.push((self.shapes.len() - 1, *n));
                }
            }
            self.counts[2] += 1;
        }
        Ok(())
    }

    fn push(&mut self, s: Shape, color: [f32; 3]) {
        self.shapes.push(s);
        self.albedo.push(linear(color));
    }

    fn build(self) -> Geometry {
        let bounds: Vec<Aabb> = self.shapes.iter().map(Shape::bounds).collect();
        let mut vertex_normals = Vec::new();
        if !self.smooth.is_empty() {
            vertex_normals = vec![None; self.shapes.len()];
            for (i, n) in self.smooth {
                vertex_normals[i] = Some(n);
            }
        }
        Geometry {
            vertex_normals,
            bvh: Bvh::build(&bounds),
            shapes: self.shapes,
            albedo: self.albedo,
            infinite: self.infinite,
            shadows: false,
            light: None,
            sources: self.sources,
            counts: self.counts,
        }
    }
}

/// Reads and parses a geometry TOML file.
fn read_def(path: &Path) -> Result<GeometryDef> {
    crate::files::read_toml(path)
}

impl Geometry {
    /// Reads a geometry file (format in [`mod@file`]); mesh paths are relative
    /// to it.
    pub fn load(path: &Path) -> Result<Geometry> {
        let mut parts = Parts::default();
        parts.add_file(path)?;
        Ok(parts.build())
    }

    /// Geometry from shapes; mesh paths relative to `base`, errors naming
    /// `origin`.
    pub fn from_def(def: &GeometryDef, base: &Path, origin: &Path) -> Result<Geometry> {
        let mut parts = Parts::default();
        parts.add_def(def, base, origin, "")?;
        Ok(parts.build())
    }

    /// The obstructions of an FDS case as boxes, in metres (the FDS
    /// volume's world units), with their Smokeview colours. The reader has
    /// already dropped zero-volume OBSTs (FORMAT.md: a door HOLE leaves one).
    pub fn from_fds(smv: &crate::io::fds::Smv, path: &Path) -> Geometry {
        let mut parts = Parts::default();
        for o in &smv.obstructions {
            let c = o
                .color
                .map(|c| [c[0], c[1], c[2]])
                .filter(|c| c.iter().all(|x| (0.0..=1.0).contains(x)))
                .unwrap_or(file::DEFAULT_COLOR);
            parts.push(
                Shape::Box(Aabb {
                    min: o.min,
                    max: o.max,
                }),
                c,
            );
            parts.counts[0] += 1;
        }
        parts.sources.push(format!(
            "{}: {} OBST boxes",
            path.display(),
            smv.obstructions.len()
        ));
        parts.build()
    }

    /// The geometry of a scene whose volume comes from `input` (a path or
    /// `builtin:NAME`): the spec's file, else (with `auto`) the geometry
    /// that comes with the input, plus the inline shapes, whose mesh paths
    /// are relative to `scene_dir`. `None` when there is none.
    pub fn for_scene(
        spec: &GeometrySpec,
        input: &str,
        scene_dir: &Path,
    ) -> Result<Option<Geometry>> {
        let mut parts = Parts::default();
        if let Some(f) = &spec.file {
            parts.add_file(Path::new(f))?;
        } else if spec.auto && !input.starts_with(crate::builtin::PREFIX) {
            let p = Path::new(input);
            let is_smv = p.extension().is_some_and(|e| e.eq_ignore_ascii_case("smv"));
            if is_smv && p.is_file() {
                let smv = crate::io::fds::parse_smv(p)?;
                let g = Geometry::from_fds(&smv, p);
                parts.shapes.extend(g.shapes);
                parts.albedo.extend(g.albedo);
                parts.counts[0] += g.counts[0];
                parts.sources.extend(g.sources);
            } else if let Some(f) = auto_file(p) {
                parts.add_file(&f)?;
            }
        }
        let inline = spec.shapes();
        if !inline.is_empty() {
            parts.add_def(&inline, scene_dir, Path::new("scene"), "geometry.")?;
            parts.sources.push("the scene's [geometry] table".into());
        }
        if parts.shapes.is_empty() && parts.infinite.is_empty() {
            return Ok(None);
        }
        let mut g = parts.build();
        g.shadows = spec.shadows;
        g.light = spec.light;
        Ok(Some(g))
    }

    /// True when there is nothing to hit.
    pub fn is_empty(&self) -> bool {
        self.shapes.is_empty() && self.infinite.is_empty()
    }

    /// Numbers of boxes, planes, meshes and mesh triangles.
    pub fn counts(&self) -> [usize; 4] {
        self.counts
    }

    /// One line for messages: what was loaded from where.
    pub fn describe(&self) -> String {
        let [b, p, m, t] = self.counts;
        let mut parts = Vec::new();
        if b > 0 {
            parts.push(format!("{b} boxes"));
        }
        if p > 0 {
            parts.push(format!("{p} planes"));
        }
        if m > 0 {
            parts.push(format!("{m} meshes ({t} triangles)"));
        }
        format!(
            "geometry: {} from {}{}",
            parts.join(", "),
            self.sources.join(", "),
            if self.shadows { "; shadows on" } else { "" }
        )
    }

    /// Every shape with its linear albedo, for other back ends (the GPU
    /// ray caster): the bounded shapes in the order [`Geometry::hit`]'s BVH
    /// holds them, then the infinite planes in the order they are tested.
    pub fn primitives(&self) -> Vec<(Primitive, Vec3)> {
        let bounded = self.shapes.iter().zip(&self.albedo).map(|(s, &c)| {
            let p = match *s {
                Shape::Box(b) => Primitive::Box(b),
                Shape::Rect(p) => Primitive::Rect(p),
                Shape::Tri(t) => Primitive::Triangle(t),
            };
            (p, c)
        });
        let infinite = self
            .infinite
            .iter()
            .map(|&(p, c)| (Primitive::InfinitePlane(p), c));
        bounded.chain(infinite).collect()
    }

    /// Bounds of the bounded shapes (infinite planes have none).
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        self.bvh.bounds().map(|b| (b.min, b.max))
    }

    /// The nearest surface on `o + d·t`, `t_min < t < t_max`.
    #[inline]
    pub fn hit(&self, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> Option<Hit> {
        let mut best = self
            .bvh
            .traverse(o, d, t_min, t_max, false, |i, tm| {
                self.shapes[i]
                    .hit(o, d, t_min, tm)
                    .map(|(t, n)| (t, (n, i)))
            })
            .map(|(t, (n, i))| Hit {
                t,
                normal: self.shading_normal(i, o + d * t, n),
                albedo: self.albedo[i],
            });
        for (p, c) in &self.infinite {
            let tm = best.map_or(t_max, |h| h.t);
            if let Some((t, n)) = p.hit(o, d, t_min, tm) {
                best = Some(Hit {
                    t,
                    normal: n,
                    albedo: *c,
                });
            }
        }
        best
    }

    /// The normal to shade shape `i` with at `p`: its vertex normals
    /// interpolated by the barycentric coordinates of `p` (Phong 1975), or
    /// the geometric normal `n`.
    #[inline]
    fn shading_normal(&self, i: usize, p: Vec3, n: Vec3) -> Vec3 {
        let (Some(Some(vn)), Shape::Tri(t)) = (self.vertex_normals.get(i), &self.shapes[i]) else {
            return n;
        };
        let (e1, e2, q) = (t.b - t.a, t.c - t.a, p - t.a);
        // Barycentrics from the sub-triangle areas.
        let c = e1.cross(e2);
        let inv = 1.0 / c.length_squared();
        let u = q.cross(e2).dot(c) * inv;
        let v = e1.cross(q).dot(c) * inv;
        let s = vn[0] * (1.0 - u - v) + vn[1] * u + vn[2] * v;
        if s.length_squared() > 0.0 {
            s.normalize()
        } else {
            n
        }
    }

    /// Whether anything lies on `o + d·t`, `t_min < t < t_max` (shadow rays).
    #[inline]
    pub fn occluded(&self, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> bool {
        self.infinite
            .iter()
            .any(|(p, _)| p.hit(o, d, t_min, t_max).is_some())
            || self
                .bvh
                .traverse(o, d, t_min, t_max, true, |i, tm| {
                    self.shapes[i].hit(o, d, t_min, tm).map(|(t, _)| (t, ()))
                })
                .is_some()
    }

    /// A hash of the shapes and lighting, for cache keys.
    pub fn fingerprint(&self) -> u64 {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        let mut eat = |x: f32| {
            for b in x.to_bits().to_le_bytes() {
                h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
            }
        };
        for (s, c) in self.shapes.iter().zip(&self.albedo) {
            let v: [Vec3; 3] = match s {
                Shape::Box(b) => [b.min, b.max, Vec3::ZERO],
                Shape::Rect(p) => {
                    let [a, b] = p.half_extent.unwrap_or([0.0; 2]);
                    [p.point, p.normal, Vec3::new(a, b, 1.0)]
                }
                Shape::Tri(t) => [t.a, t.b, t.c],
            };
            for x in v.iter().chain([c]).flat_map(|v| v.to_array()) {
                eat(x);
            }
        }
        for (p, c) in &self.infinite {
            for x in [p.point, p.normal, *c].iter().flat_map(|v| v.to_array()) {
                eat(x);
            }
        }
        eat(self.shadows as u8 as f32);
        for x in self.light.unwrap_or([0.0; 3]) {
            eat(x);
        }
        h
    }
}

impl Parts {
    fn add_file(&mut self, path: &Path) -> Result<()> {
        let def = read_def(path)?;
        let base = path.parent().unwrap_or(Path::new("."));
        self.add_def(&def, base, path, "")?;
        self.sources.push(path.display().to_string());
        Ok(())
    }
}

/// `geometry.toml` in the folder `p`, or beside the file `p`.
fn auto_file(p: &Path) -> Option<PathBuf> {
    let dir = if p.is_dir() { p } else { p.parent()? };
    let f = dir.join(GEOMETRY_FILE);
    f.is_file().then_some(f)
}
