//! Opaque geometry in the renderer (S0 Fig. 9–13), checked by numbers: a
//! box in front of the smoke hides it exactly; smoke in front of a box
//! attenuates the box's colour by Beer–Lambert; smoke shadows dim the key
//! light by Beer–Lambert; every marcher and both compositing orders agree;
//! geometry files, scene tables and FDS obstructions load.

mod common;
use common::{max_diff, no_progress, simd_levels};

use glam::Vec3;
use std::path::Path;
use std::sync::Arc;
use voxcast::camera::{Camera, CameraParams, Projection};
use voxcast::geometry::{BoxDef, Geometry, GeometryDef, PlaneDef, SurfaceLight};
use voxcast::render::{MethodSpec, OpticalModel, Order, RenderParams, Renderer, Simd};
use voxcast::scene::Scene;
use voxcast::transfer::{srgb_to_linear, TransferFunction};
use voxcast::{Image, Volume, VoxelData};

/// An 8³ homogeneous slab, unit spacing, world box [0, 7]³.
fn slab() -> Volume {
    Volume::new(
        [8, 8, 8],
        Vec3::ONE,
        Vec3::ZERO,
        VoxelData::F32(vec![0.7; 512].into()),
    )
    .unwrap()
}

/// Grey smoke of step opacity `alpha` per unit length: σ = −ln(1 − α).
fn smoke(alpha: f32) -> TransferFunction {
    TransferFunction {
        color: vec![[0.0, 0.5, 0.5, 0.5]],
        opacity: vec![[0.0, alpha]],
        window: None,
    }
}

fn ortho() -> CameraParams {
    CameraParams {
        projection: Projection::Orthographic,
        ..Default::default()
    }
}

fn params() -> RenderParams {
    RenderParams {
        width: 33,
        height: 33,
        shading: false,
        ert: 1.0,
        ..Default::default()
    }
}

/// The key light of the tests: towards −y (the camera's side) and up.
const LIGHT: [f32; 3] = [0.3, -1.0, 0.6];

fn geometry(boxes: Vec<BoxDef>, planes: Vec<PlaneDef>) -> Arc<Geometry> {
    let def = GeometryDef {
        boxes,
        planes,
        meshes: vec![],
    };
    let mut g = Geometry::from_def(&def, Path::new("."), Path::new("test")).unwrap();
    g.light = Some(LIGHT);
    Arc::new(g)
}

fn bx(min: [f32; 3], max: [f32; 3], color: [f32; 3]) -> BoxDef {
    BoxDef {
        min,
        max,
        color,
        name: None,
    }
}

fn draw(
    vol: &Volume,
    tf: &TransferFunction,
    cam: &CameraParams,
    p: &RenderParams,
    g: Option<Arc<Geometry>>,
) -> Image {
    let s = vol.stats();
    let window = if s.max > s.min {
        [s.min, s.max]
    } else {
        [s.min - 0.5, s.min + 0.5]
    };
    Renderer::new(vol, window)
        .unwrap()
        .with_geometry(g)
        .render(tf, cam, p, &no_progress)
        .unwrap()
        .0
}

/// The lit colour of a face with normal `n` seen along +y.
fn lit(color: [f32; 3], n: Vec3, light: f32) -> Vec3 {
    let cam = Camera::fit(&ortho(), Vec3::ZERO, Vec3::ONE, 8, 8);
    let l = SurfaceLight::new(Some(LIGHT), &cam);
    l.shade(Vec3::from(color.map(srgb_to_linear)), n, Vec3::Y, light)
}

const METHODS: [&str; 6] = [
    "uniform",
    "adaptive",
    "adaptive-max",
    "threshold",
    "uniform+grouped",
    "uniform+noskip",
];

#[test]
fn opaque_box_in_front_of_smoke_hides_it() {
    let vol = slab();
    let color = [0.8, 0.4, 0.2];
    // Between the camera (on −y) and the slab, much wider than the slab.
    let g = geometry(
        vec![bx([-8.0, -4.0, -8.0], [15.0, -1.0, 15.0], color)],
        vec![],
    );
    let want = lit(color, -Vec3::Y, 1.0);
    for spec in METHODS {
        for order in [Order::FrontToBack, Order::BackToFront] {
            for jitter in [false, true] {
                let mut p = params();
                MethodSpec::parse(spec).unwrap().apply(&mut p);
                p.order = order;
                p.jitter = jitter;
                p.ert = 0.99;
                let img = draw(&vol, &smoke(0.2), &ortho(), &p, Some(g.clone()));
                // The centre, and two pixels whose rays miss the slab.
                for (x, y) in [(16, 16), (8, 10), (24, 22)] {
                    let px = img.get(x, y);
                    assert_eq!(px[3], 1.0, "{spec} {order:?}");
                    let d = (Vec3::new(px[0], px[1], px[2]) - want).abs().max_element();
                    assert!(d < 1e-6, "{spec} {order:?} ({x},{y}): {px:?} vs {want}");
                }
            }
        }
    }
    // Without the box the smoke is what one sees: the test can fail.
    let img = draw(&vol, &smoke(0.2), &ortho(), &params(), None);
    let px = img.get(16, 16);
    assert!((Vec3::new(px[0], px[1], px[2]) - want).abs().max_element() > 0.05);
}

#[test]
fn smoke_in_front_of_a_box_attenuates_it_by_beer_lambert() {
    let vol = slab();
    let color = [0.3, 0.7, 0.9];
    // Inside the slab from y = 4: a ray along +y crosses 4 units of smoke.
    let g = geometry(vec![bx([-2.0, 4.0, -2.0], [9.0, 6.0, 9.0], color)], vec![]);
    let surface = lit(color, -Vec3::Y, 1.0).as_dvec3();
    let alpha = 0.05f32;
    let sigma = -(1.0 - alpha as f64).ln();
    let t = (-sigma * 4.0).exp();
    let gray = srgb_to_linear(0.5) as f64;
    for spec in METHODS {
        for order in [Order::FrontToBack, Order::BackToFront] {
            for step in [0.25, 0.3, 0.5, 1.0] {
                for model in [
                    OpticalModel::AbsorptionOnly,
                    OpticalModel::EmissionAbsorption,
                ] {
                    let mut p = params();
                    MethodSpec::parse(spec).unwrap().apply(&mut p);
                    p.order = order;
                    p.step = step;
                    p.optical = model;
                    let img = draw(&vol, &smoke(alpha), &ortho(), &p, Some(g.clone()));
                    let px = img.get(16, 16);
                    // C = e·(1 − T) + T·S (emission–absorption), T·S (absorption only).
                    let emitted = match model {
                        OpticalModel::EmissionAbsorption => gray * (1.0 - t),
                        _ => 0.0,
                    };
                    for c in 0..3 {
                        let want = emitted + t * surface[c];
                        assert!(
                            (px[c] as f64 - want).abs() < 1e-3,
                            "{spec} {order:?} step {step} {model:?}: channel {c} {} vs {want}",
                            px[c]
                        );
                    }
                    assert!((px[3] - 1.0).abs() < 1e-6);
                }
            }
        }
    }
}

#[test]
fn rays_that_miss_the_volume_still_see_geometry_and_its_smoke_shadow() {
    let vol = slab();
    let color = [0.9, 0.9, 0.9];
    // A wall facing the camera, left of the slab and behind it: camera rays
    // (along +y) reach it without crossing the slab; a shadow ray towards
    // the light (1, −1, 0) crosses the slab from x = 0 to y = 0.
    let wall = PlaneDef {
        point: [-10.0, 12.0, 3.5],
        normal: [0.0, -1.0, 0.0],
        color,
        half_extent: Some([6.0, 3.5]),
        name: None,
    };
    let def = GeometryDef {
        boxes: vec![],
        planes: vec![wall],
        meshes: vec![],
    };
    let mut g = Geometry::from_def(&def, Path::new("."), Path::new("test")).unwrap();
    let light = [1.0, -1.0, 0.0];
    g.light = Some(light);
    let (lo, hi) = vol.world_bounds();
    let (glo, ghi) = g.bounds().unwrap();
    let p = params();
    let cam = Camera::fit(&ortho(), lo.min(glo), hi.max(ghi), p.width, p.height);
    let key = SurfaceLight::new(Some(light), &cam);
    let albedo = Vec3::from(color.map(srgb_to_linear));
    let alpha = 0.1f32;
    let sigma = -(1.0 - alpha as f64).ln();
    let mut checked = 0;
    let mut darkest = 1f64;
    for shadows in [false, true] {
        g.shadows = shadows;
        let img = draw(&vol, &smoke(alpha), &ortho(), &p, Some(Arc::new(g.clone())));
        for y in 0..p.height {
            for x in 0..p.width {
                let (o, _) = cam.ray(x, y);
                // Wall points whose shadow ray crosses the slab's x = 0 face
                // (x ∈ (−12, −5), z ∈ (0, 7)); path (12 + x)·√2.
                if !(o.x > -11.5 && o.x < -5.5 && o.z > 0.5 && o.z < 6.5) {
                    continue;
                }
                let path = (12.0 + o.x as f64) * 2f64.sqrt();
                let t = if shadows { (-sigma * path).exp() } else { 1.0 };
                let want = key.shade(albedo, -Vec3::Y, Vec3::Y, t as f32);
                let px = img.get(x, y);
                let d = (Vec3::new(px[0], px[1], px[2]) - want).abs().max_element();
                assert!(d < 1e-3, "shadows {shadows} at x {}: {px:?} vs {want}", o.x);
                assert_eq!(px[3], 1.0);
                darkest = darkest.min(t);
                checked += 1;
            }
        }
    }
    assert!(checked > 20, "{checked} pixels checked");
    assert!(darkest < 0.5, "the shadow is real: T down to {darkest}");
}

/// Shadow rays skip what empty-space skipping skips: smoke in one corner
/// of a larger, otherwise empty volume over a floor. With skipping the
/// shadow rays leave out the samples outside the box around the smoke's
/// blocks (far fewer lookups), and every pixel, shadow included, is the
/// same as without skipping.
#[test]
fn shadow_rays_skip_the_empty_space_and_keep_the_pixels() {
    let n = 32;
    let mut v = vec![0f32; n * n * n];
    for z in 0..8 {
        for y in 0..8 {
            for x in 0..8 {
                v[x + n * (y + n * z)] = 0.7;
            }
        }
    }
    let vol = Volume::new([n; 3], Vec3::ONE, Vec3::ZERO, VoxelData::F32(v.into())).unwrap();
    let tf = TransferFunction {
        color: vec![[0.0, 0.5, 0.5, 0.5]],
        opacity: vec![[0.0, 0.0], [0.1, 0.0], [1.0, 0.4]],
        window: Some([0.0, 1.0]),
    };
    // A floor under the volume, lit from above and to the side, so that
    // most shadow rays cross only empty blocks and some cross the smoke.
    let floor = PlaneDef {
        point: [15.5, 15.5, -2.0],
        normal: [0.0, 0.0, 1.0],
        color: [0.8, 0.8, 0.8],
        half_extent: Some([30.0, 30.0]),
        name: None,
    };
    let def = GeometryDef {
        boxes: vec![],
        planes: vec![floor],
        meshes: vec![],
    };
    let mut g = Geometry::from_def(&def, Path::new("."), Path::new("test")).unwrap();
    g.light = Some([-0.3, -0.2, 1.0]);
    let cam = CameraParams {
        azimuth: 20.0,
        elevation: 50.0,
        ..Default::default()
    };
    let render = |shadows: bool, skip: bool| {
        let mut g = g.clone();
        g.shadows = shadows;
        let p = RenderParams {
            width: 48,
            height: 48,
            skip_empty: skip,
            ..Default::default()
        };
        let (img, st) = Renderer::new(&vol, [0.0, 1.0])
            .unwrap()
            .with_geometry(Some(Arc::new(g)))
            .render(&tf, &cam, &p, &no_progress)
            .unwrap();
        (img, st.interpolations - st.samples)
    };
    let (full, full_lookups) = render(true, false);
    let (skip, skip_lookups) = render(true, true);
    let d = max_diff(&full, &skip);
    assert!(d <= 1e-6, "skipping moved a pixel by {d}");
    assert!(
        skip_lookups > 0 && skip_lookups * 4 < full_lookups,
        "shadow lookups: {skip_lookups} with skipping, {full_lookups} without"
    );
    // The smoke's shadow is in the picture.
    let (lit, _) = render(false, true);
    assert!(max_diff(&lit, &skip) > 0.05, "no shadow");
}

/// The demo, sparse, with a box through it, a floor and a back wall, lit
/// with smoke shadows; its transfer function and a camera that sees all.
fn demo_with_geometry() -> (
    Volume,
    TransferFunction,
    Option<Arc<Geometry>>,
    CameraParams,
) {
    let vol = voxcast::builtin::open("demo").unwrap();
    let tf = TransferFunction {
        color: vec![[0.0, 1.0, 0.6, 0.3], [1.0, 1.0, 1.0, 0.9]],
        opacity: vec![[0.0, 0.0], [0.3, 0.0], [0.6, 0.2], [1.0, 0.6]],
        window: None,
    };
    let (lo, hi) = vol.world_bounds();
    let mid = (lo + hi) * 0.5;
    let ext = hi - lo;
    let def = GeometryDef {
        boxes: vec![bx(
            (mid - ext * Vec3::new(0.1, 0.4, 0.3)).into(),
            (mid + ext * Vec3::new(0.1, 0.1, 0.1)).into(),
            [0.2, 0.5, 0.8],
        )],
        planes: vec![
            PlaneDef {
                point: [mid.x, mid.y, lo.z + 0.2 * ext.z],
                normal: [0.0, 0.0, 1.0],
                color: [0.6, 0.6, 0.6],
                half_extent: Some([ext.x, ext.y]),
                name: None,
            },
            PlaneDef {
                // Facing the camera (planes are one-sided).
                point: [mid.x, hi.y, mid.z],
                normal: [0.0, -1.0, 0.0],
                color: [0.9, 0.8, 0.7],
                half_extent: None,
                name: None,
            },
        ],
        meshes: vec![],
    };
    let mut g = Geometry::from_def(&def, Path::new("."), Path::new("test")).unwrap();
    g.shadows = true;
    let cam = CameraParams {
        azimuth: 35.0,
        elevation: 25.0,
        zoom: 1.4,
        ..Default::default()
    };
    (vol, tf, Some(Arc::new(g)), cam)
}

#[test]
fn empty_space_skipping_and_order_do_not_change_pixels_with_geometry() {
    let (vol, tf, g, cam) = demo_with_geometry();
    for spec in ["uniform", "adaptive", "adaptive-max", "uniform+grouped"] {
        for jitter in [false, true] {
            let mut p = RenderParams {
                width: 64,
                height: 48,
                jitter,
                ..Default::default()
            };
            MethodSpec::parse(spec).unwrap().apply(&mut p);
            p.skip_empty = false;
            let full = draw(&vol, &tf, &cam, &p, g.clone());
            p.skip_empty = true;
            let skip = draw(&vol, &tf, &cam, &p, g.clone());
            let d = max_diff(&full, &skip);
            assert!(
                d <= 1e-6,
                "{spec} jitter {jitter}: skipping moved a pixel by {d}"
            );
            // S4's back-to-front recurrence (the scalar loop's) against
            // the packets' front to back.
            p.order = Order::BackToFront;
            p.ert = 1.0;
            p.simd = Simd::Scalar;
            let btf = draw(&vol, &tf, &cam, &p, g.clone());
            p.order = Order::FrontToBack;
            p.simd = Simd::Auto;
            let ftb = draw(&vol, &tf, &cam, &p, g.clone());
            let d = max_diff(&ftb, &btf);
            assert!(
                d < 1e-5,
                "{spec}: front-to-back vs back-to-front differ by {d}"
            );
        }
    }
    // The geometry is in the picture: without it pixels change.
    let p = RenderParams {
        width: 64,
        height: 48,
        ..Default::default()
    };
    let with = draw(&vol, &tf, &cam, &p, g.clone());
    let without = draw(&vol, &tf, &cam, &p, None);
    assert!(max_diff(&with, &without) > 0.2);
}

/// The SIMD ray packets stop at the geometry as the scalar loop does: at
/// every level this CPU has, the same pixels (within 1e-4) and counts for
/// the fixed step, `importance` and the step-per-block marches, flat and
/// shaded, u8 and f32, with smoke shadows on the surfaces. Without AVX2
/// the test checks nothing (there is no packet level).
#[test]
fn packets_stop_at_the_geometry_as_the_scalar_loop_does() {
    use voxcast::render::Simd;
    let (vol, tf, g, cam) = demo_with_geometry();
    let f32_vol = Volume::new(
        vol.dims(),
        vol.spacing(),
        vol.origin(),
        VoxelData::F32(
            (0..vol.len())
                .map(|i| vol.data().get(i))
                .collect::<Vec<f32>>()
                .into(),
        ),
    )
    .unwrap();
    for vol in [vol, f32_vol] {
        let s = vol.stats();
        let r = Renderer::new(&vol, [s.min, s.max])
            .unwrap()
            .with_geometry(g.clone());
        let bare = Renderer::new(&vol, [s.min, s.max]).unwrap();
        for spec in [
            "uniform",
            "jitter",
            "importance",
            "adaptive",
            "adaptive+grouped",
            "adaptive-max",
        ] {
            for shading in [false, true] {
                let mut p = RenderParams {
                    width: 48,
                    height: 40,
                    shading,
                    spp: 2,
                    ..Default::default()
                };
                MethodSpec::parse(spec).unwrap().apply(&mut p);
                p.simd = Simd::Scalar;
                let (scalar, sc) = r.render(&tf, &cam, &p, &no_progress).unwrap();
                // The geometry is in the picture.
                let (without, _) = bare.render(&tf, &cam, &p, &no_progress).unwrap();
                assert!(
                    max_diff(&scalar, &without) > 0.2,
                    "{spec}: no geometry seen"
                );
                for (level, _) in simd_levels() {
                    p.simd = level;
                    let (simd, ss) = r.render(&tf, &cam, &p, &no_progress).unwrap();
                    let what =
                        format!("{spec} {:?} {level:?} shading {shading}", vol.scalar_type());
                    assert!(ss.simd.is_some(), "{what}: the packets did not run");
                    let d = max_diff(&simd, &scalar);
                    assert!(d < 1e-4, "{what}: packets differ from scalar by {d}");
                    assert_eq!(ss.rays, sc.rays, "{what}");
                    assert_eq!(ss.rays_hit, sc.rays_hit, "{what}");
                    assert_eq!(ss.early_terminated, sc.early_terminated, "{what}");
                    let (a, b) = (ss.samples as f64, sc.samples as f64);
                    assert!((a - b).abs() <= 1e-3 * b, "{what}: samples {a} vs {b}");
                    // Shadow rays count their interpolations in both.
                    let (a, b) = (ss.interpolations as f64, sc.interpolations as f64);
                    assert!(
                        (a - b).abs() <= 1e-3 * b,
                        "{what}: interpolations {a} vs {b}"
                    );
                }
            }
        }
    }
}

#[test]
fn geometry_file_loads_boxes_planes_and_meshes_relative_to_itself() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("furniture")).unwrap();
    std::fs::write(
        dir.path().join("furniture/tri.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 4 3\n",
    )
    .unwrap();
    let file = dir.path().join("geometry.toml");
    std::fs::write(
        &file,
        r#"# world coordinates
[[box]]
min = [0.0, 0.0, 0.0]
max = [1.0, 0.5, 0.8]
color = [0.7, 0.6, 0.5]
name = "desk"
[[plane]]
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
color = [0.5, 0.5, 0.5]
[[plane]]
point = [0.0, 3.0, 1.0]
normal = [0.0, -1.0, 0.0]
half_extent = [2.0, 1.0]
[[mesh]]
path = "furniture/tri.obj"
color = [0.6, 0.4, 0.3]
translate = [5.0, 0.0, 2.0]
scale = 2.0
"#,
    )
    .unwrap();
    let g = Geometry::load(&file).unwrap();
    assert_eq!(g.counts(), [1, 2, 1, 2]);
    // The mesh: a 2×2 square at z = 2, x 5..7.
    let h = g
        .hit(Vec3::new(6.0, 1.0, 9.0), -Vec3::Z, 0.0, f32::INFINITY)
        .unwrap();
    assert!((h.t - 7.0).abs() < 1e-5);
    let want = Vec3::from([0.6f32, 0.4, 0.3].map(srgb_to_linear));
    assert!((h.albedo - want).length() < 1e-6);
    // Beside the square the infinite floor (z = 0) is hit instead.
    let h = g
        .hit(Vec3::new(8.0, 1.0, 9.0), -Vec3::Z, 0.0, f32::INFINITY)
        .unwrap();
    assert!((h.t - 9.0).abs() < 1e-5);
    // The desk's top.
    let h = g
        .hit(Vec3::new(0.5, 0.25, 9.0), -Vec3::Z, 0.0, f32::INFINITY)
        .unwrap();
    assert!((h.t - 8.2).abs() < 1e-5 && h.normal == Vec3::Z);
    // The bounded wall (facing −y: u = +x, v = +z): hit inside its
    // rectangle only.
    let h = g.hit(Vec3::new(1.5, 0.6, 1.5), Vec3::Y, 0.0, 1e9).unwrap();
    assert!((h.t - 2.4).abs() < 1e-5);
    assert!(g.hit(Vec3::new(2.5, 0.6, 1.5), Vec3::Y, 0.0, 1e9).is_none());
    assert!(g.hit(Vec3::new(1.5, 0.6, 2.1), Vec3::Y, 0.0, 1e9).is_none());
    let (lo, hi) = g.bounds().unwrap();
    assert_eq!(
        (lo, hi),
        (Vec3::new(-2.0, 0.0, 0.0), Vec3::new(7.0, 3.0, 2.0))
    );
}

#[test]
fn geometry_errors_name_the_file_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("room.toml");
    let load = |text: &str| {
        std::fs::write(&file, text).unwrap();
        Geometry::load(&file).unwrap_err().to_string()
    };
    let e = load("[[box]]\nmin = [0, 0, 0]\nmax = [1, 1]\n");
    assert!(e.contains("room.toml") && e.contains("line 3"), "{e}");
    let e = load("[[box]]\nmin = [0, 0, 0]\nmax = [1, 1, 1]\ncolour = [1, 0, 0]\n");
    assert!(e.contains("room.toml") && e.contains("colour"), "{e}");
    let e = load("[[box]]\nmin = [0, 2, 0]\nmax = [1, 1, 1]\n");
    assert!(e.contains("room.toml") && e.contains("box[0]"), "{e}");
    let e = load("[[box]]\nmin = [0, 0, 0]\nmax = [1, 1, 1]\ncolor = [255, 0, 0]\n");
    assert!(e.contains("box[0].color") && e.contains("0..1"), "{e}");
    let e = load("[[plane]]\npoint = [0, 0, 0]\nnormal = [0, 0, 0]\n");
    assert!(e.contains("plane[0]") && e.contains("normal"), "{e}");
    let e = load("[[plane]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nhalf_extent = [1, -1]\n");
    assert!(e.contains("plane[0].half_extent"), "{e}");
    // A missing mesh names the mesh file; a bad face index names it too.
    let e = load("[[mesh]]\npath = \"chair.obj\"\n");
    assert!(e.contains("chair.obj"), "{e}");
    std::fs::write(
        dir.path().join("chair.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n",
    )
    .unwrap();
    let e = load("[[mesh]]\npath = \"chair.obj\"\n");
    assert!(e.contains("chair.obj") && e.contains("`f`"), "{e}");
    let e = load("[[mesh]]\npath = \"chair.obj\"\nscale = 0\n");
    assert!(e.contains("mesh[0]") && e.contains("scale"), "{e}");
    let e = Geometry::load(&dir.path().join("nope.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("nope.toml"), "{e}");
}

/// A 4³ uint8 NRRD volume in `dir`.
fn write_nrrd(dir: &Path) -> std::path::PathBuf {
    let p = dir.join("vol.nrrd");
    let mut bytes =
        b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nencoding: raw\n\n".to_vec();
    bytes.extend((0..64u8).map(|i| i * 3));
    std::fs::write(&p, bytes).unwrap();
    p
}

#[test]
fn scene_loads_geometry_beside_the_input_and_saves_it_reproducibly() {
    let dir = tempfile::tempdir().unwrap();
    let vol = write_nrrd(dir.path());
    std::fs::write(
        dir.path().join("geometry.toml"),
        "[[box]]\nmin = [1, 1, 1]\nmax = [2, 2, 2]\n",
    )
    .unwrap();
    let mut scene = Scene::default();
    scene.input.path = vol.to_string_lossy().into_owned();
    let g = scene.load_geometry().unwrap().unwrap();
    assert_eq!(g.counts(), [1, 0, 0, 0]);
    // The folder itself as input finds it too; auto off finds nothing.
    assert!(Geometry::for_scene(
        &scene.geometry,
        &dir.path().to_string_lossy(),
        Path::new("")
    )
    .unwrap()
    .is_some());
    scene.geometry.auto = false;
    assert!(scene.load_geometry().unwrap().is_none());
    // A scene with a geometry file, an inline mesh and shadows round-trips
    // with paths relative to the scene file.
    std::fs::write(
        dir.path().join("m.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    scene.geometry.file = Some(
        dir.path()
            .join("geometry.toml")
            .to_string_lossy()
            .into_owned(),
    );
    scene.geometry.shadows = true;
    scene.geometry.light = Some([0.0, 0.0, 1.0]);
    scene.geometry.meshes.push(voxcast::geometry::MeshDef {
        path: dir.path().join("m.obj").to_string_lossy().into_owned(),
        color: [0.5, 0.5, 0.5],
        translate: [0.0; 3],
        scale: 1.0,
        name: None,
    });
    let sub = dir.path().join("scenes");
    std::fs::create_dir(&sub).unwrap();
    let saved = sub.join("s.toml");
    scene.save(&saved).unwrap();
    let text = std::fs::read_to_string(&saved).unwrap();
    assert!(text.contains("file = \"../geometry.toml\""), "{text}");
    assert!(text.contains("path = \"../m.obj\""), "{text}");
    let back = Scene::load(&saved).unwrap();
    let g = back.load_geometry().unwrap().unwrap();
    assert_eq!(g.counts(), [1, 0, 1, 1]);
    assert!(g.shadows && g.light == Some([0.0, 0.0, 1.0]));
    // The same picture from the saved scene.
    let a = scene.prepare().unwrap();
    let b = back.prepare().unwrap();
    let (ia, _) = scene.render(&a, &no_progress).unwrap();
    let (ib, _) = back.render(&b, &no_progress).unwrap();
    assert_eq!(max_diff(&ia, &ib), 0.0);
    // A default scene writes no [geometry] table.
    let mut plain = Scene::default();
    plain.input.path = scene.input.path.clone();
    plain.save(&saved).unwrap();
    assert!(!std::fs::read_to_string(&saved)
        .unwrap()
        .contains("geometry"));
}

#[test]
fn fds_case_brings_its_obstructions() {
    let Some(smv) = voxcast::testdata::data_path("fds_room/room_smoke.smv") else {
        return;
    };
    let mut scene = Scene::default();
    scene.input.path = smv.to_string_lossy().into_owned();
    scene.input.options.time = Some(30.0);
    let prepared = scene.prepare().unwrap();
    let g = prepared.geometry.as_ref().unwrap();
    // 23 OBST lines, the zero-thickness door piece skipped.
    assert_eq!(g.counts(), [22, 0, 0, 0]);
    let (lo, hi) = g.bounds().unwrap();
    assert!((lo - Vec3::ZERO).length() < 1e-5, "{lo}");
    assert!((hi - Vec3::new(4.1, 3.0, 2.5)).length() < 1e-5, "{hi}");
    // Straight down onto the table top (z = 0.8) at its centre.
    let h = g.hit(Vec3::new(2.6, 1.4, 5.0), -Vec3::Z, 0.0, 1e9).unwrap();
    assert!((h.t - 4.2).abs() < 1e-5, "{}", h.t);
    let red = Vec3::from([0.64706f32, 0.16471, 0.16471].map(srgb_to_linear));
    assert!((h.albedo - red).length() < 1e-4);
    // The render shows them: looking down, the table top pixel differs from
    // the same render without geometry, and is opaque.
    scene.camera.elevation = 89.0;
    scene.render.width = 48;
    scene.render.height = 48;
    let (with, _) = scene.render(&prepared, &no_progress).unwrap();
    scene.geometry.auto = false;
    let bare = scene.prepare().unwrap();
    assert!(bare.geometry.is_none());
    let (without, _) = scene.render(&bare, &no_progress).unwrap();
    assert!(max_diff(&with, &without) > 0.1);
    let opaque = with.pixels.iter().filter(|p| p[3] == 1.0).count();
    let opaque0 = without.pixels.iter().filter(|p| p[3] == 1.0).count();
    assert!(opaque > opaque0 + 100, "{opaque} vs {opaque0}");
}

#[test]
fn vertex_normals_shade_smoothly_by_barycentric_interpolation() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("t.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 1 0 1\nvn 0 1 1\nf 1//1 2//2 3//3\n",
    )
    .unwrap();
    let file = dir.path().join("g.toml");
    std::fs::write(&file, "[[mesh]]\npath = \"t.obj\"\n").unwrap();
    let g = Geometry::load(&file).unwrap();
    let n = |x: f32, y: f32| {
        g.hit(Vec3::new(x, y, 1.0), -Vec3::Z, 0.0, 9.0)
            .unwrap()
            .normal
    };
    let (na, nb, nc) = (
        Vec3::Z,
        Vec3::new(1.0, 0.0, 1.0).normalize(),
        Vec3::new(0.0, 1.0, 1.0).normalize(),
    );
    // At (x, y) the barycentrics are (1 − x − y, x, y).
    for (x, y) in [(0.25, 0.25), (0.6, 0.1), (0.1, 0.7), (0.01, 0.01)] {
        let want = (na * (1.0 - x - y) + nb * x + nc * y).normalize();
        assert!(
            (n(x, y) - want).length() < 1e-5,
            "({x},{y}): {} vs {want}",
            n(x, y)
        );
    }
    // Without `vn` the face is flat.
    std::fs::write(
        dir.path().join("t.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    let g = Geometry::load(&file).unwrap();
    let h = g.hit(Vec3::new(0.6, 0.1, 1.0), -Vec3::Z, 0.0, 9.0).unwrap();
    assert_eq!(h.normal, Vec3::Z);
}
