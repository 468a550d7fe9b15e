//! What a render needs besides the volume: the shapes, lights and medium
//! of the scene packed for the shader, and the majorant grid.

use voxcast::camera::Camera;
use voxcast::render::{BlockGrid, RenderParams};
use voxcast::volume::Volume;

use crate::params::{Params, LIGHT_WORDS, SHAPE_WORDS};

/// What a render needs besides the volume: the shapes and lights in one
/// buffer of `vec4` records, and the majorant grid.
pub(crate) struct SceneData {
    pub(crate) records: Vec<[f32; 4]>,
    pub(crate) majorant: Vec<f32>,
}

impl SceneData {
    /// Packs the scene's shapes, lights and medium: the records and the
    /// majorant grid returned, their counts and parameters written to `p`.
    pub(crate) fn new(
        p: &mut Params,
        geometry: Option<&voxcast::geometry::Geometry>,
        cam: &Camera,
        params: &RenderParams,
        volume: &Volume,
        blocks: &BlockGrid,
    ) -> SceneData {
        use voxcast::geometry::Primitive;
        use voxcast::render::light::Light;
        use voxcast::render::phase::PhaseFunction;
        let v4 = |v: glam::Vec3, w: f32| [v.x, v.y, v.z, w];
        let mut records = Vec::new();
        let mut shapes = 0;
        let mut surf_dir = [0.0; 3];
        let mut surf_k = [0.0; 4];
        let mut shadows = 0;
        if let Some(g) = geometry {
            // Per shape: kind (0 box, 1 rectangle, 2 infinite plane) and
            // half extents; min | point; max | normal; u; v; albedo.
            for (p, albedo) in g.primitives() {
                let rec = match p {
                    Primitive::Box(b) => {
                        [[0.0; 4], v4(b.min, 0.0), v4(b.max, 0.0), [0.0; 4], [0.0; 4]]
                    }
                    Primitive::Rect(p) | Primitive::InfinitePlane(p) => {
                        let [a, b] = p.half_extent.unwrap_or([0.0; 2]);
                        let kind = if p.half_extent.is_some() { 1.0 } else { 2.0 };
                        [
                            [kind, a, b, 0.0],
                            v4(p.point, 0.0),
                            v4(p.normal, 0.0),
                            v4(p.u, 0.0),
                            v4(p.v, 0.0),
                        ]
                    }
                    // Refused by `with_geometry`.
                    Primitive::Triangle(_) => continue,
                };
                records.extend_from_slice(&rec);
                records.push(v4(albedo, 0.0));
                shapes += 1;
            }
            let light = voxcast::geometry::SurfaceLight::new(g.light, cam);
            surf_dir = light.to_light.to_array();
            surf_k = [
                light.ambient,
                light.diffuse,
                light.specular,
                light.shininess,
            ];
            shadows = g.shadows as u32;
        }
        debug_assert_eq!(records.len(), shapes * SHAPE_WORDS);
        // Lights (single-scatter): kind (0 directional, 1 point,
        // 2 environment, 3 sky); then its vectors.
        let lights = params.lights_or_default();
        let v = |a: [f32; 3]| [a[0], a[1], a[2], 0.0];
        for l in lights.iter() {
            let rec = match *l {
                Light::Directional {
                    direction,
                    irradiance,
                } => [
                    [0.0; 4],
                    v4(glam::Vec3::from(direction).normalize(), 0.0),
                    v(irradiance),
                    [0.0; 4],
                ],
                Light::Point {
                    position,
                    intensity,
                } => [[1.0, 0.0, 0.0, 0.0], v(position), v(intensity), [0.0; 4]],
                Light::Environment { radiance } => {
                    [[2.0, 0.0, 0.0, 0.0], v(radiance), [0.0; 4], [0.0; 4]]
                }
                Light::Sky {
                    zenith,
                    horizon,
                    ground,
                } => [[3.0, 0.0, 0.0, 0.0], v(zenith), v(horizon), v(ground)],
            };
            records.extend_from_slice(&rec);
        }
        debug_assert_eq!(
            records.len(),
            shapes * SHAPE_WORDS + lights.len() * LIGHT_WORDS
        );
        if records.is_empty() {
            records.push([0.0; 4]);
        }
        let medium = &params.medium;
        let (phase_kind, phase_arg) = match medium.phase {
            PhaseFunction::Isotropic => (0, 0.0),
            PhaseFunction::Hg { g } => (1, g),
            PhaseFunction::Schlick { k } => (2, k),
            PhaseFunction::Rayleigh => (3, 0.0),
            PhaseFunction::Mie { g } => (4, g),
        };
        // path.rs: the medium box in voxel coordinates.
        let dims = volume.dims();
        let hi = glam::Vec3::new(
            dims[0].saturating_sub(1).max(1) as f32,
            dims[1].saturating_sub(1).max(1) as f32,
            dims[2].saturating_sub(1).max(1) as f32,
        );
        let (offset, scale_v) = match medium.r#box {
            Some([lo, bhi]) => (
                glam::Vec3::from(lo),
                hi / (glam::Vec3::from(bhi) - glam::Vec3::from(lo)),
            ),
            None => (volume.origin(), glam::Vec3::ONE / volume.spacing()),
        };
        let (majorant, global) = if params.method.is_physical() {
            let m = voxcast::render::majorant::Majorant::new(blocks, medium.scale, medium.majorant);
            (m.sigma, m.global)
        } else {
            (vec![0.0], 0.0)
        };
        p.shapes = shapes as u32;
        p.shadows = shadows;
        p.lights = lights.len() as u32;
        p.phase = phase_kind;
        p.phase_g = phase_arg;
        p.surf_dir = surf_dir;
        p.surf_k = surf_k;
        p.med_offset = offset.to_array();
        p.sigma_t = medium.scale;
        p.med_scale = scale_v.to_array();
        p.med_hi = hi.to_array();
        p.majorant = global;
        p.med_albedo = medium.albedo;
        p.global_majorant =
            (medium.majorant == voxcast::render::medium::MajorantKind::Global) as u32;
        p.infinite_lights = lights.iter().any(|l| !l.is_delta()) as u32;
        SceneData {
            records,
            majorant: if majorant.is_empty() {
                vec![0.0]
            } else {
                majorant
            },
        }
    }
}
