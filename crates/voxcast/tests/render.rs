//! Renderer tests that assert numbers: analytic slabs, compositing orders,
//! early termination bounds, the axis convention, determinism.

mod common;
use common::{max_diff, no_progress};

use glam::Vec3;
use voxcast::camera::{CameraParams, Projection};
use voxcast::render::{render, OpticalModel, Order, RenderParams, Simd};
use voxcast::transfer::{srgb_to_linear, TransferFunction};
use voxcast::{Image, Volume, VoxelData};

fn constant_tf(gray: f32, alpha: f32) -> TransferFunction {
    TransferFunction {
        color: vec![[0.0, gray, gray, gray]],
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

fn params(w: u32, h: u32) -> RenderParams {
    RenderParams {
        width: w,
        height: h,
        shading: false,
        ert: 1.0,
        ..Default::default()
    }
}

fn draw(vol: &Volume, tf: &TransferFunction, cam: &CameraParams, p: &RenderParams) -> Image {
    let s = vol.stats();
    let window = if s.max > s.min {
        [s.min, s.max]
    } else {
        [s.min - 0.5, s.min + 0.5]
    };
    render(vol, tf, window, cam, p, &no_progress).unwrap().0
}

#[test]
fn homogeneous_slab_matches_beer_lambert() {
    // 9 × 38 × 9 voxels, anisotropic spacing: the smallest (0.8, along y) is
    // the unit length, and an orthographic ray along +y crosses 37 units.
    let dims = [9, 38, 9];
    let vol = Volume::new(
        dims,
        Vec3::new(1.0, 0.8, 1.2),
        Vec3::new(3.0, -2.0, 5.0),
        VoxelData::F32(vec![0.7; 9 * 38 * 9].into()),
    )
    .unwrap();
    let (gray, alpha) = (0.5f32, 0.05f32);
    let tf = constant_tf(gray, alpha);
    let sigma = -(1.0 - alpha as f64).ln();
    let length = 37.0;
    let expect = 1.0 - (-sigma * length).exp();
    let c = srgb_to_linear(gray) as f64;
    for step in [0.25, 0.3, 0.5, 1.0] {
        for model in [
            OpticalModel::EmissionAbsorption,
            OpticalModel::AbsorptionOnly,
        ] {
            let mut p = params(33, 33);
            p.step = step;
            p.optical = model;
            p.background = [1.0, 1.0, 1.0];
            let img = draw(&vol, &tf, &ortho(), &p);
            let px = img.get(16, 16);
            let want_rgb = match model {
                // Emission–absorption: C = c·(1 − e^(−σL)) over a white background.
                OpticalModel::EmissionAbsorption => c * expect + (1.0 - expect),
                // Absorption only: the background seen through the slab.
                _ => 1.0 - expect,
            };
            assert!(
                (px[3] as f64 - expect).abs() < 1e-3,
                "step {step}: α {} vs {expect}",
                px[3]
            );
            for c in &px[..3] {
                assert!(
                    (*c as f64 - want_rgb).abs() < 1e-3,
                    "step {step} {model:?}: {c} vs {want_rgb}"
                );
            }
        }
    }
    // Emission only: no absorption, the emitted light adds up along the ray.
    let mut p = params(33, 33);
    p.optical = OpticalModel::EmissionOnly;
    let img = draw(&vol, &tf, &ortho(), &p);
    let a_step = 1.0 - (-sigma * 0.5).exp();
    let want = c * a_step * (length / 0.5);
    assert!((img.get(16, 16)[0] as f64 - want.min(f64::MAX)).abs() < 1e-3);
}

#[test]
fn front_to_back_equals_back_to_front_and_ert_is_bounded() {
    let vol = voxcast::builtin::open("demo").unwrap();
    let tf = TransferFunction::auto(&vol);
    let cam = CameraParams {
        azimuth: 30.0,
        elevation: 20.0,
        zoom: 1.5,
        ..Default::default()
    };
    for shading in [false, true] {
        let mut p = params(96, 80);
        p.shading = shading;
        p.background = [0.2, 0.3, 0.4];
        let ftb = draw(&vol, &tf, &cam, &p);
        // S4's back-to-front recurrence is the scalar loop's (the packets
        // sum front to back without termination).
        p.order = Order::BackToFront;
        p.simd = Simd::Scalar;
        let btf = draw(&vol, &tf, &cam, &p);
        let d = max_diff(&ftb, &btf);
        assert!(d < 1e-5, "front-to-back vs back-to-front differ by {d}");
        p.order = Order::FrontToBack;
        p.simd = Simd::Auto;
        for threshold in [0.9f32, 0.99] {
            p.ert = threshold;
            let ert = draw(&vol, &tf, &cam, &p);
            let d = max_diff(&ftb, &ert);
            assert!(
                d <= 1.0 - threshold + 1e-6,
                "ERT {threshold}: a pixel moved by {d}"
            );
        }
    }
    // And ERT really did terminate rays on this scene.
    let mut p = params(96, 80);
    p.ert = 0.9;
    let s = vol.stats();
    let (_, stats) = render(&vol, &tf, [s.min, s.max], &cam, &p, &no_progress).unwrap();
    assert!(stats.early_terminated > 100, "{stats:?}");
}

/// A 33³ volume, empty but for a bright blob around voxel `at`.
fn marker(at: [f32; 3]) -> Volume {
    Volume::from_fn([33, 33, 33], Vec3::ONE, |i, j, k| {
        let d = Vec3::new(i as f32, j as f32, k as f32) - Vec3::from(at);
        (1.0 - d.length() / 4.0).max(0.0)
    })
    .unwrap()
}

/// Centroid (x, y) in pixels of the image's brightness.
fn centroid(img: &Image) -> (f32, f32) {
    let (mut sx, mut sy, mut s) = (0.0, 0.0, 0.0);
    for y in 0..img.height {
        for x in 0..img.width {
            let v = img.get(x, y)[0];
            sx += v * x as f32;
            sy += v * y as f32;
            s += v;
        }
    }
    assert!(s > 0.0, "the marker is not visible");
    (sx / s, sy / s)
}

#[test]
fn axis_convention_matches_the_readme() {
    let tf = constant_tf(1.0, 0.0);
    let tf = TransferFunction {
        opacity: vec![[0.0, 0.0], [0.2, 0.0], [1.0, 0.8]],
        ..tf
    };
    let p = params(64, 64);
    let mid = 31.5;
    let look = |at: [f32; 3], cam: &CameraParams| centroid(&draw(&marker(at), &tf, cam, &p));
    // Default view: looking along +y, +x to the right, +z up.
    let (x, _) = look([28.0, 16.0, 16.0], &CameraParams::default());
    assert!(x > mid + 8.0, "+x marker at column {x}");
    let (x, _) = look([4.0, 16.0, 16.0], &CameraParams::default());
    assert!(x < mid - 8.0, "−x marker at column {x}");
    let (_, y) = look([16.0, 16.0, 28.0], &CameraParams::default());
    assert!(y < mid - 8.0, "+z marker at row {y}");
    // Azimuth 90: the camera sits on +x looking along −x, so +y is right.
    let az90 = CameraParams {
        azimuth: 90.0,
        ..Default::default()
    };
    let (x, _) = look([16.0, 28.0, 16.0], &az90);
    assert!(x > mid + 8.0, "az 90: +y marker at column {x}");
    // Elevation 90 (clamped to 89.9): looking down −z, +x still right, +y up.
    let top = CameraParams {
        elevation: 90.0,
        ..Default::default()
    };
    let (x, y) = look([28.0, 28.0, 16.0], &top);
    assert!(
        x > mid + 8.0 && y < mid - 8.0,
        "top view: (+x,+y) marker at {x},{y}"
    );
}

#[test]
fn same_scene_same_bytes() {
    let vol = voxcast::builtin::open("demo").unwrap();
    let tf = TransferFunction::auto(&vol);
    let mut p = params(64, 48);
    p.shading = true;
    p.ert = 0.99;
    let a = draw(&vol, &tf, &CameraParams::default(), &p).to_srgb8();
    let b = draw(&vol, &tf, &CameraParams::default(), &p).to_srgb8();
    assert_eq!(a, b);
}

#[test]
fn step_size_changes_cost_not_picture() {
    let vol = voxcast::builtin::open("sphere").unwrap();
    let tf = TransferFunction::preset("viridis").unwrap();
    let mut p = params(64, 64);
    p.step = 0.125;
    let fine = draw(&vol, &tf, &CameraParams::default(), &p);
    p.step = 1.0;
    let coarse = draw(&vol, &tf, &CameraParams::default(), &p);
    let psnr = voxcast::metrics::psnr(&fine, &coarse).unwrap();
    assert!(psnr > 40.0, "step 1 vs 1/8: {psnr} dB");
    // Without opacity correction a step 8× longer would be far darker; the
    // mean opacity must agree within 1 %.
    let mean =
        |i: &Image| i.pixels.iter().map(|p| p[3] as f64).sum::<f64>() / i.pixels.len() as f64;
    assert!((mean(&fine) / mean(&coarse) - 1.0).abs() < 0.01);
}

#[test]
fn nan_voxels_are_empty() {
    let mut v = vec![0.5f32; 8 * 8 * 8];
    v[0] = f32::NAN;
    v[5] = f32::INFINITY;
    let nan_vol = Volume::new([8, 8, 8], Vec3::ONE, Vec3::ZERO, VoxelData::F32(v.into())).unwrap();
    assert_eq!(nan_vol.stats().nan, 1);
    assert_eq!(nan_vol.stats().inf, 1);
    let all_nan = Volume::new(
        [4, 4, 4],
        Vec3::ONE,
        Vec3::ZERO,
        VoxelData::F32(vec![f32::NAN; 64].into()),
    )
    .unwrap();
    let tf = constant_tf(1.0, 0.9);
    let img = draw(&all_nan, &tf, &CameraParams::default(), &params(16, 16));
    assert!(img.pixels.iter().all(|p| p[3] == 0.0));
    let img = draw(&nan_vol, &tf, &CameraParams::default(), &params(16, 16));
    assert!(img.pixels.iter().any(|p| p[3] > 0.5));
}

/// A raised cancel flag ends a render within a few tiles with
/// `Error::Cancelled`; an unraised one changes nothing.
#[test]
fn cancelled_render_stops_early() {
    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
    use voxcast::render::Renderer;
    let v = voxcast::builtin::open("sphere").unwrap();
    let tf = voxcast::transfer::TransferFunction::preset("grayscale").unwrap();
    let cam = voxcast::camera::CameraParams::default();
    let r = Renderer::new(&v, [0.0, 255.0]).unwrap();
    for method in ["uniform", "path"] {
        let params = RenderParams {
            width: 320,
            height: 320,
            method: voxcast::render::Method::parse(method).unwrap(),
            ..Default::default()
        };
        // 20×20 tiles; the flag goes up when the first one is done.
        let flag = AtomicBool::new(false);
        let done = AtomicUsize::new(0);
        let progress = |n: usize, _total: usize| {
            done.fetch_max(n, Ordering::Relaxed);
            flag.store(true, Ordering::Relaxed);
        };
        let res = r.render_cancellable(&tf, &cam, &params, &progress, &flag);
        assert!(
            matches!(res, Err(voxcast::Error::Cancelled)),
            "{method}: {:?}",
            res.map(|_| ())
        );
        let threads = rayon::current_num_threads();
        assert!(
            done.load(Ordering::Relaxed) <= threads,
            "{method}: {} tiles finished after the flag went up ({threads} threads)",
            done.load(Ordering::Relaxed)
        );
        // Not raised: the same image as `render`.
        let never = AtomicBool::new(false);
        let (a, _) = r
            .render_cancellable(&tf, &cam, &params, &|_, _| {}, &never)
            .unwrap();
        let (b, _) = r.render(&tf, &cam, &params, &|_, _| {}).unwrap();
        assert_eq!(a.pixels, b.pixels, "{method}");
    }
}

/// Steps are in the volume's voxels even where its opacity unit is a
/// finer length (a pyramid level read whole): the same samples as the
/// volume without it, and a more opaque picture (each step is two
/// opacity units long).
#[test]
fn steps_are_voxels_of_the_volume_not_its_opacity_unit() {
    let mut v =
        voxcast::builtin::sized("demo", [24, 20, 16], voxcast::volume::ScalarType::U8).unwrap();
    v.set_spacing(glam::Vec3::splat(2.0)).unwrap();
    let mut p = RenderParams {
        width: 24,
        height: 24,
        method: voxcast::render::Method::Adaptive,
        ..RenderParams::default()
    };
    p.adaptive.max_step = Some(2.0);
    p.threshold.steps = [0.5, 1.0, 2.0];
    assert!(matches!(
        p.in_opacity_units(&v),
        std::borrow::Cow::Borrowed(_)
    ));
    let mut fine = v.clone();
    fine.opacity_unit = Some(1.0);
    let q = p.in_opacity_units(&fine);
    assert_eq!(q.step, 1.0);
    assert_eq!(
        (q.adaptive.min_step, q.adaptive.max_step),
        (None, Some(4.0))
    );
    assert_eq!(q.threshold.steps, [1.0, 2.0, 4.0]);
    let tf = voxcast::transfer::TransferFunction::preset("grayscale").unwrap();
    let cam = voxcast::camera::CameraParams::default();
    p.method = voxcast::render::Method::Uniform;
    let render_it = |v: &Volume| {
        let w = [0.0, 255.0];
        render(v, &tf, w, &cam, &p, &|_, _| {}).unwrap()
    };
    let (a, sa) = render_it(&v);
    let (b, sb) = render_it(&fine);
    assert_eq!(sa.samples, sb.samples);
    assert!(a.to_srgb8() != b.to_srgb8());
}
