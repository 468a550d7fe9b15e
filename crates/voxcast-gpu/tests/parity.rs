//! GPU vs CPU parity: the same scene, seed and parameters rendered by the
//! CPU renderer and by the wgpu compute shader must agree at PSNR ≥ 40 dB,
//! for every method the GPU supports, on three real volumes of different
//! voxel types (8-bit CT slices → r8unorm, 16-bit DICOM CT → r16float,
//! float cloud and 16-bit CT head → r32float).
//!
//! Also single scattering on three volumes (every phase function, all four
//! kinds of light, both majorants), opaque boxes and planes (the FDS room
//! with its obstructions and smoke shadows, a plume over a floor plane), and
//! bricked volumes against unbricked ones.
//!
//! Without an adapter the tests skip with a note; under CI (`CI=true`) a
//! missing adapter is a failure, so CI never passes by testing nothing.

use std::sync::Arc;
use voxcast::render::{MethodSpec, RenderParams};
use voxcast::scene::Scene;
use voxcast_gpu::{GpuContext, GpuRenderer};

mod common;
use common::{context, scene};

/// The methods compared, with the spp that makes the stochastic ones
/// progressive.
const METHODS: [(&str, u32); 9] = [
    ("uniform", 1),
    ("uniform+noskip", 1),
    ("adaptive+grouped", 1),
    ("adaptive-max", 1),
    ("threshold", 1),
    ("threshold+grouped", 1),
    ("jitter", 4),
    ("stratified", 4),
    ("mc", 4),
];

fn check_volume(rel: &str, format: &str) {
    let Some(ctx) = context() else { return };
    let Some(scene) = scene(rel) else { return };
    let prepared = scene.prepare().unwrap();
    let gpu = GpuRenderer::new(ctx, &prepared.volume, prepared.window).unwrap();
    assert_eq!(gpu.texture_format(), format, "{rel}");
    let cpu = voxcast::render::Renderer::new(&prepared.volume, prepared.window).unwrap();
    for (spec, spp) in METHODS {
        let mut params = RenderParams {
            width: 96,
            height: 96,
            seed: 7,
            spp,
            ..RenderParams::default()
        };
        MethodSpec::parse(spec).unwrap().apply(&mut params);
        let (a, sa) = cpu
            .render(&prepared.tf, &scene.camera, &params, &|_, _| {})
            .unwrap();
        let (b, sb) = gpu
            .render(&prepared.tf, &scene.camera, &on_cpu_blocks(&params, &sa))
            .unwrap();
        let psnr = voxcast::metrics::psnr(&a, &b).unwrap();
        let lit = a.pixels.iter().filter(|p| p[3] > 0.05).count();
        eprintln!(
            "{rel} {spec}: PSNR {psnr:.1} dB, samples cpu {} gpu {}, lit {lit}",
            sa.samples, sb.samples
        );
        assert!(lit > 96 * 96 / 50, "{rel} {spec}: the CPU image is empty");
        assert!(psnr >= 40.0, "{rel} {spec}: PSNR {psnr:.2} dB < 40");
        assert_eq!(sa.rays, sb.rays, "{rel} {spec}: ray counts differ");
        // Sample counts agree up to rays that round differently at a
        // block or box boundary.
        let (x, y) = (sa.samples as f64, sb.samples as f64);
        assert!(
            (x - y).abs() <= 0.01 * x.max(y) + 10.0,
            "{rel} {spec}: samples cpu {x} gpu {y}"
        );
    }
}

#[test]
fn teapot_ct_slices_8bit() {
    check_volume("teapot_ct/slices", "r8unorm");
}

#[test]
fn dicom_ct_lung_16bit() {
    check_volume("dicom_ct_lung", "r16float");
}

#[test]
fn cloud_vdb_float() {
    check_volume("cloud_vdb/cloud.vdb", "r32float");
}

/// Unsigned 16-bit CT (values up to 3926, beyond f16's exact integers).
#[test]
fn ct_head_u16() {
    check_volume("ct_head_headsq/headsq.nhdr", "r32float");
}

/// 16-bit data that f16 holds exactly (|v| ≤ 2048) goes up as r16float and
/// still matches the CPU.
#[test]
fn i16_within_half_range_uses_r16float() {
    let Some(ctx) = context() else { return };
    let dims = [40usize, 36, 30];
    let mut data = Vec::with_capacity(dims[0] * dims[1] * dims[2]);
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let r = ((i as f32 - 20.0).powi(2)
                    + (j as f32 - 18.0).powi(2)
                    + (k as f32 - 15.0).powi(2))
                .sqrt();
                data.push((2000.0 - 200.0 * r).clamp(-1000.0, 2000.0) as i16);
            }
        }
    }
    let vol = voxcast::volume::Volume::new(
        dims,
        glam::Vec3::new(1.0, 1.0, 1.5),
        glam::Vec3::ZERO,
        voxcast::VoxelData::I16(data.into()),
    )
    .unwrap();
    let tf = voxcast::transfer::TransferFunction::preset("fire").unwrap();
    let window = [-1000.0, 2000.0];
    let gpu = GpuRenderer::new(ctx, &vol, window).unwrap();
    assert_eq!(gpu.texture_format(), "r16float");
    let cpu = voxcast::render::Renderer::new(&vol, window).unwrap();
    let params = RenderParams {
        width: 64,
        height: 64,
        ..RenderParams::default()
    };
    let camera = Default::default();
    let (a, _) = cpu.render(&tf, &camera, &params, &|_, _| {}).unwrap();
    let (b, _) = gpu.render(&tf, &camera, &params).unwrap();
    let psnr = voxcast::metrics::psnr(&a, &b).unwrap();
    let lit = a.pixels.iter().filter(|p| p[3] > 0.05).count();
    assert!(lit > 64 * 64 / 50, "the CPU image is empty");
    assert!(psnr >= 40.0, "PSNR {psnr:.2} dB < 40");
}

/// Parameters shared by the methods: optical models, orthographic camera,
/// back-to-front order, no shading, a background colour.
#[test]
fn options_match_the_cpu() {
    let Some(ctx) = context() else { return };
    let Some(mut scene) = scene("teapot_ct/slices") else {
        return;
    };
    let prepared = scene.prepare().unwrap();
    let gpu = GpuRenderer::new(ctx, &prepared.volume, prepared.window).unwrap();
    let cpu = voxcast::render::Renderer::new(&prepared.volume, prepared.window).unwrap();
    scene.camera.projection = voxcast::camera::Projection::Orthographic;
    for (name, edit) in [
        (
            "absorption-only over white",
            (|p: &mut RenderParams| {
                p.optical = voxcast::render::OpticalModel::AbsorptionOnly;
                p.background = [1.0, 1.0, 1.0];
            }) as fn(&mut RenderParams),
        ),
        ("emission-only", |p| {
            p.optical = voxcast::render::OpticalModel::EmissionOnly
        }),
        ("back-to-front", |p| {
            p.order = voxcast::render::Order::BackToFront
        }),
        ("no shading, background", |p| {
            p.shading = false;
            p.background = [0.2, 0.3, 0.5];
        }),
        ("block size 16, step 1", |p| {
            p.block_size = Some(16);
            p.step = 1.0;
        }),
    ] {
        let mut params = RenderParams {
            width: 80,
            height: 64,
            ..RenderParams::default()
        };
        edit(&mut params);
        let (a, _) = cpu
            .render(&prepared.tf, &scene.camera, &params, &|_, _| {})
            .unwrap();
        let (b, _) = gpu.render(&prepared.tf, &scene.camera, &params).unwrap();
        let psnr = voxcast::metrics::psnr(&a, &b).unwrap();
        // Pixels that differ from the background (emission-only has no
        // coverage, so alpha cannot tell).
        let bg = a.pixels[0];
        let lit = a
            .pixels
            .iter()
            .filter(|p| (0..3).any(|c| (p[c] - bg[c]).abs() > 0.02))
            .count();
        eprintln!("{name}: PSNR {psnr:.1} dB");
        assert!(lit > 80 * 64 / 50, "{name}: the CPU image is empty");
        assert!(
            a.pixels.iter().any(|p| p[0] > 0.05 && p[0] < 0.95),
            "{name}: the CPU image is flat"
        );
        assert!(psnr >= 40.0, "{name}: PSNR {psnr:.2} dB < 40");
    }
}

/// Methods the GPU lacks are refused by name, not rendered wrongly.
#[test]
fn unsupported_methods_are_named() {
    let Some(ctx) = context() else { return };
    let vol =
        voxcast::volume::Volume::from_fn([8, 8, 8], glam::Vec3::ONE, |i, j, k| (i + j + k) as f32)
            .unwrap();
    let gpu = GpuRenderer::new(ctx, &vol, [0.0, 21.0]).unwrap();
    let tf = voxcast::transfer::TransferFunction::preset("fire").unwrap();
    for m in ["importance", "lod", "path"] {
        let mut params = RenderParams {
            width: 8,
            height: 8,
            ..RenderParams::default()
        };
        MethodSpec::parse(m).unwrap().apply(&mut params);
        let e = gpu
            .render(&tf, &Default::default(), &params)
            .err()
            .unwrap_or_else(|| panic!("{m} rendered"));
        assert!(e.to_string().contains(m), "{m}: {e}");
    }
}

/// `p` with the blocks the CPU's render skipped with, so that the GPU
/// takes the same samples: unset, the CPU may take finer blocks on sparse
/// data for the marchers that only skip with them (the same picture) and
/// for `adaptive+grouped` (finer levels), and
/// the GPU keeps its default.
fn on_cpu_blocks(p: &RenderParams, cpu: &voxcast::render::RenderStats) -> RenderParams {
    RenderParams {
        block_size: (cpu.block_size > 0)
            .then_some(cpu.block_size)
            .or(p.block_size),
        ..p.clone()
    }
}

/// PSNR of the GPU render against the CPU render of `scene` (its own
/// prepared volume and geometry), and the number of lit CPU pixels.
fn compare(
    ctx: &Arc<GpuContext>,
    scene: &Scene,
    prepared: &voxcast::scene::Prepared,
    gpu: &GpuRenderer,
) -> (
    f64,
    usize,
    voxcast::render::RenderStats,
    voxcast::render::RenderStats,
) {
    let cpu = voxcast::render::Renderer::new(&prepared.volume, prepared.window)
        .unwrap()
        .with_geometry(prepared.geometry.clone());
    let _ = ctx;
    let (a, sa) = cpu
        .render(&prepared.tf, &scene.camera, &scene.render, &|_, _| {})
        .unwrap();
    let (b, sb) = gpu
        .render(
            &prepared.tf,
            &scene.camera,
            &on_cpu_blocks(&scene.render, &sa),
        )
        .unwrap();
    let psnr = voxcast::metrics::psnr(&a, &b).unwrap();
    let bg = a.pixels[0];
    let lit = a
        .pixels
        .iter()
        .filter(|p| (0..3).any(|c| (p[c] - bg[c]).abs() > 0.02))
        .count();
    (psnr, lit, sa, sb)
}

/// Single scattering (optical model 4) on three real volumes: delta
/// tracking, ratio-tracked shadow rays, each phase function and kind of
/// light, both majorants; the GPU draws the same random numbers as the CPU.
#[test]
fn single_scatter_matches_the_cpu() {
    use voxcast::render::light::Light;
    use voxcast::render::medium::MajorantKind;
    use voxcast::render::phase::PhaseFunction;
    let Some(ctx) = context() else { return };
    type Edit = fn(&mut Scene);
    let cases: [(&str, &str, Edit); 7] = [
        (
            "cloud_vdb/cloud.vdb",
            "hg:0.8, sun and sky, grid majorant",
            |s| {
                s.transfer.window = Some([0.0, 1.0]);
                s.render.medium.scale = 40.0;
                s.render.medium.phase = PhaseFunction::Hg { g: 0.8 };
            },
        ),
        (
            "cloud_vdb/cloud.vdb",
            "mie:0.85, point light + environment, global majorant",
            |s| {
                s.transfer.window = Some([0.0, 1.0]);
                s.render.medium.scale = 40.0;
                s.render.medium.phase = PhaseFunction::Mie { g: 0.85 };
                s.render.medium.majorant = MajorantKind::Global;
                s.render.lights = vec![
                    Light::Point {
                        position: [1.5, -1.5, 1.5],
                        intensity: [6.0, 5.0, 4.0],
                    },
                    Light::Environment {
                        radiance: [0.2, 0.25, 0.3],
                    },
                ];
            },
        ),
        ("teapot_ct/slices", "isotropic, sun and sky", |s| {
            s.render.medium.scale = 0.05;
            s.render.medium.phase = PhaseFunction::Isotropic;
        }),
        ("teapot_ct/slices", "schlick:0.6, directional only", |s| {
            s.render.medium.scale = 0.05;
            s.render.medium.albedo = [0.9, 0.7, 0.5];
            s.render.medium.phase = PhaseFunction::Schlick { k: 0.6 };
            s.render.lights = vec![Light::Directional {
                direction: [0.3, -0.5, 0.8],
                irradiance: [3.0, 3.0, 3.0],
            }];
        }),
        ("fds_room/room_smoke.smv", "rayleigh, sun and sky", |s| {
            s.render.medium.scale = 3.0;
            s.render.medium.phase = PhaseFunction::Rayleigh;
        }),
        (
            "fds_room/room_smoke.smv",
            "hg:-0.3, medium box, environment",
            |s| {
                s.render.medium.scale = 3.0;
                s.render.medium.phase = PhaseFunction::Hg { g: -0.3 };
                s.render.medium.r#box = Some([[0.0, 0.0, 0.0], [4.0, 3.0, 2.5]]);
                s.render.lights = vec![
                    Light::Environment {
                        radiance: [1.0, 1.0, 1.0],
                    },
                    Light::Directional {
                        direction: [-0.2, 0.4, 1.0],
                        irradiance: [2.0, 2.0, 2.0],
                    },
                ];
            },
        ),
        ("ct_head_headsq/headsq.nhdr", "hg:0.5, sun and sky", |s| {
            s.render.medium.scale = 0.1;
            s.render.medium.phase = PhaseFunction::Hg { g: 0.5 };
        }),
    ];
    for (rel, what, edit) in cases {
        let Some(mut scene) = scene(rel) else { return };
        if rel.ends_with(".smv") {
            scene.input.options.time = Some(30.0);
            scene.geometry.auto = false;
            scene.transfer.tf = "smoke".into();
        }
        scene.render.method = voxcast::render::Method::SingleScatter;
        scene.render.width = 64;
        scene.render.height = 64;
        scene.render.spp = 4;
        scene.render.seed = 11;
        edit(&mut scene);
        let prepared = scene.prepare().unwrap();
        let gpu = GpuRenderer::new(ctx.clone(), &prepared.volume, prepared.window).unwrap();
        let (psnr, lit, sa, sb) = compare(&ctx, &scene, &prepared, &gpu);
        eprintln!(
            "single-scatter {rel} ({what}): PSNR {psnr:.1} dB, lit {lit}, tentative collisions cpu {} gpu {}",
            sa.samples, sb.samples
        );
        assert!(lit > 64 * 64 / 50, "{rel} {what}: the CPU image is empty");
        assert!(psnr >= 40.0, "{rel} {what}: PSNR {psnr:.2} dB < 40");
        assert_eq!(sa.rays, sb.rays, "{rel} {what}");
        assert_eq!(sa.rays_hit, sb.rays_hit, "{rel} {what}");
        let (x, y) = (sa.samples as f64, sb.samples as f64);
        assert!(
            (x - y).abs() <= 0.01 * x.max(y) + 10.0,
            "{rel} {what}: tentative collisions cpu {x} gpu {y}"
        );
    }
}

/// The FDS room at t = 30 s with its 22 OBST boxes (loaded from the .smv),
/// the example scene's floor and walls, and smoke shadows on them.
#[test]
fn fds_room_geometry_matches_the_cpu() {
    let Some(ctx) = context() else { return };
    if voxcast::testdata::data_path("fds_room/room_smoke.smv").is_none() {
        return;
    }
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/fds-room.toml");
    let mut scene = Scene::load(&path).unwrap();
    scene.render.width = 96;
    scene.render.height = 72;
    let prepared = scene.prepare().unwrap();
    let g = prepared.geometry.clone().expect("the room has geometry");
    assert!(
        g.counts()[0] >= 20 && g.counts()[1] == 3 && g.shadows,
        "{}",
        g.describe()
    );
    let gpu = GpuRenderer::new(ctx.clone(), &prepared.volume, prepared.window)
        .unwrap()
        .with_geometry(Some(&g))
        .unwrap();
    for (spec, spp) in [("uniform", 1), ("adaptive+grouped", 1), ("mc", 2)] {
        MethodSpec::parse(spec).unwrap().apply(&mut scene.render);
        scene.render.spp = spp;
        let (psnr, lit, sa, sb) = compare(&ctx, &scene, &prepared, &gpu);
        eprintln!(
            "fds room {spec}: PSNR {psnr:.1} dB, lit {lit}, samples cpu {} gpu {}, interpolations cpu {} gpu {}",
            sa.samples, sb.samples, sa.interpolations, sb.interpolations
        );
        assert!(lit > 96 * 72 / 4, "{spec}: the CPU image shows no room");
        assert!(psnr >= 40.0, "fds room {spec}: PSNR {psnr:.2} dB < 40");
        // Rays that reach the smoke, up to rays that graze a shape's or the
        // volume's edge and round to the other side.
        let (x, y) = (sa.rays_hit as f64, sb.rays_hit as f64);
        assert!(
            (x - y).abs() <= 0.002 * x.max(y) + 2.0,
            "{spec}: rays that reach the smoke cpu {x} gpu {y}"
        );
    }
    // The physically based methods refuse geometry, as on the CPU.
    scene.render.method = voxcast::render::Method::SingleScatter;
    let Err(e) = gpu.render(&prepared.tf, &scene.camera, &scene.render) else {
        panic!("single-scatter with geometry is refused");
    };
    assert!(e.to_string().contains("geometry"), "{e}");
}

/// The simulated plume over an infinite floor plane, beside a box and a
/// rectangle, with shadows; the camera frames the shapes too.
#[test]
fn plume_over_a_plane_matches_the_cpu() {
    let Some(ctx) = context() else { return };
    let text = r#"
[input]
path = "builtin:plume"
[transfer]
tf = "smoke"
[camera]
azimuth = 30.0
elevation = 25.0
[render]
width = 80
height = 80
background = [0.1, 0.1, 0.12]
[geometry]
shadows = true
light = [0.5, -0.6, 1.0]
[[geometry.plane]]
point = [0.0, 0.0, -0.2]
normal = [0.0, 0.0, 1.0]
color = [0.6, 0.6, 0.55]
[[geometry.plane]]
point = [0.0, 1.2, 0.5]
normal = [0.0, -1.0, 0.0]
half_extent = [1.0, 0.7]
color = [0.8, 0.3, 0.2]
[[geometry.box]]
min = [0.7, -0.9, -0.2]
max = [1.1, -0.5, 0.3]
color = [0.2, 0.4, 0.8]
"#;
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("plume.toml");
    std::fs::write(&f, text).unwrap();
    let mut scene = Scene::load(&f).unwrap();
    let prepared = scene.prepare().unwrap();
    let g = prepared.geometry.clone().expect("geometry");
    assert_eq!(g.counts()[..2], [1, 2], "{}", g.describe());
    let gpu = GpuRenderer::new(ctx.clone(), &prepared.volume, prepared.window)
        .unwrap()
        .with_geometry(Some(&g))
        .unwrap();
    for spec in ["uniform", "jitter"] {
        MethodSpec::parse(spec).unwrap().apply(&mut scene.render);
        scene.render.spp = 2;
        let (psnr, lit, _, _) = compare(&ctx, &scene, &prepared, &gpu);
        eprintln!("plume + plane {spec}: PSNR {psnr:.1} dB, lit {lit}");
        assert!(lit > 80 * 80 / 6, "{spec}: the floor is missing");
        assert!(psnr >= 40.0, "plume + plane {spec}: PSNR {psnr:.2} dB < 40");
    }
}

/// OBJ meshes stay on the CPU, refused by name.
#[test]
fn meshes_are_refused_by_name() {
    let Some(ctx) = context() else { return };
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/plume-geometry.toml");
    let scene = Scene::load(&path).unwrap();
    let prepared = scene.prepare().unwrap();
    let g = prepared.geometry.clone().expect("geometry");
    assert!(g.counts()[2] > 0);
    assert!(!voxcast::render::Backend::Gpu.renders_geometry(Some(&g)));
    let e = GpuRenderer::new(ctx, &prepared.volume, prepared.window)
        .unwrap()
        .with_geometry(Some(&g))
        .err()
        .expect("meshes are refused");
    assert!(e.to_string().contains("triangle meshes"), "{e}");
}

/// Volumes split into bricks (a lowered texture limit) render the same
/// picture as unbricked ones, seams included.
#[test]
fn bricked_volumes_match_unbricked() {
    let Some(ctx) = context() else { return };
    for (rel, limit, bricks) in [
        ("iron_protein/ironProt.vtk", 64, [2, 2, 2]),
        ("teapot_ct/slices", 160, [2, 2, 2]),
        ("cloud_vdb/cloud.vdb", 100, [2, 2, 2]),
    ] {
        let Some(scene) = scene(rel) else { return };
        let prepared = scene.prepare().unwrap();
        let whole = GpuRenderer::new(ctx.clone(), &prepared.volume, prepared.window).unwrap();
        assert_eq!(whole.bricking().len(), 1);
        let split = GpuRenderer::with_texture_limit(
            ctx.clone(),
            &prepared.volume,
            prepared.window,
            Some(limit),
        )
        .unwrap();
        let b = split.bricking();
        assert_eq!(b.counts, bricks, "{rel}");
        assert!(b.len() > 1, "{rel}: not bricked");
        let dims = prepared.volume.dims();
        assert!(
            (0..3).all(|a| b.cells[a] < limit as usize && b.counts[a] * b.cells[a] + 1 >= dims[a]),
            "{rel}: {b:?} for {dims:?}"
        );
        for (spec, spp) in [("uniform", 1), ("adaptive+grouped", 1), ("mc", 2)] {
            let mut params = RenderParams {
                width: 96,
                height: 96,
                seed: 3,
                spp,
                ..RenderParams::default()
            };
            MethodSpec::parse(spec).unwrap().apply(&mut params);
            let (a, _) = whole.render(&prepared.tf, &scene.camera, &params).unwrap();
            let (c, _) = split.render(&prepared.tf, &scene.camera, &params).unwrap();
            let psnr = voxcast::metrics::psnr(&a, &c).unwrap();
            let lit = a.pixels.iter().filter(|p| p[3] > 0.05).count();
            eprintln!(
                "{rel} in {:?} bricks, {spec}: PSNR {psnr:.1} dB vs unbricked",
                b.counts
            );
            assert!(lit > 96 * 96 / 50, "{rel} {spec}: empty image");
            assert!(psnr >= 60.0, "{rel} {spec}: bricked PSNR {psnr:.2} dB < 60");
        }
    }
    // Too large for eight bricks: refused with the sizes.
    let vol = voxcast::volume::Volume::from_fn([40, 40, 40], glam::Vec3::ONE, |i, j, k| {
        (i + j + k) as f32
    })
    .unwrap();
    let e = GpuRenderer::with_texture_limit(ctx, &vol, [0.0, 117.0], Some(8))
        .err()
        .expect("refused");
    assert!(e.to_string().contains("40×40×40"), "{e}");
}

/// Many passes are split over several dispatches (8 passes each) that add
/// to the same sums: the image and the stats are those of one long loop.
#[test]
fn passes_split_over_dispatches_match_the_cpu() {
    let Some(ctx) = context() else { return };
    let Some(mut scene) = scene("teapot_ct/slices") else {
        return;
    };
    let prepared = scene.prepare().unwrap();
    let gpu = GpuRenderer::new(ctx.clone(), &prepared.volume, prepared.window).unwrap();
    scene.render.width = 48;
    scene.render.height = 48;
    scene.render.seed = 5;
    for (spec, spp) in [("mc", 20), ("jitter", 17), ("single-scatter", 12)] {
        MethodSpec::parse(spec).unwrap().apply(&mut scene.render);
        scene.render.spp = spp;
        scene.render.medium.scale = 0.05;
        let (psnr, lit, sa, sb) = compare(&ctx, &scene, &prepared, &gpu);
        eprintln!("{spec} spp {spp}: PSNR {psnr:.1} dB, lit {lit}");
        assert!(lit > 48 * 48 / 50, "{spec}: empty image");
        assert!(psnr >= 40.0, "{spec} spp {spp}: PSNR {psnr:.2} dB < 40");
        assert_eq!(sa.rays, sb.rays, "{spec}");
        assert_eq!(sa.rays_hit, sb.rays_hit, "{spec}");
        let (x, y) = (sa.samples as f64, sb.samples as f64);
        assert!(
            (x - y).abs() <= 0.01 * x.max(y) + 10.0,
            "{spec}: samples cpu {x} gpu {y}"
        );
    }
}
