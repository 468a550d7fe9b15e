//! The Monte-Carlo marchers (S1): seeded, progressive, converging to the
//! converged reference at the rate Monte Carlo promises.

mod common;
use common::{max_diff, no_progress};

use voxcast::camera::CameraParams;
use voxcast::render::{Method, RenderParams, Renderer};
use voxcast::transfer::TransferFunction;
use voxcast::{metrics, Image, Volume};

fn scene() -> (Volume, TransferFunction) {
    let vol = voxcast::builtin::open("marschner-lobb").unwrap();
    let tf = TransferFunction {
        color: vec![[0.0, 0.2, 0.5, 1.0], [1.0, 1.0, 0.8, 0.3]],
        opacity: vec![[0.0, 0.0], [0.4, 0.05], [1.0, 0.4]],
        window: None,
    };
    (vol, tf)
}

fn cam() -> CameraParams {
    CameraParams {
        azimuth: 30.0,
        elevation: 25.0,
        ..Default::default()
    }
}

fn draw(r: &Renderer, tf: &TransferFunction, p: &RenderParams) -> Image {
    r.render(tf, &cam(), p, &no_progress).unwrap().0
}

fn params(method: Method, spp: u32, seed: u64) -> RenderParams {
    RenderParams {
        width: 48,
        height: 48,
        method,
        spp,
        seed,
        step: 1.0,
        ert: 1.0,
        shading: false,
        ..Default::default()
    }
}

#[test]
fn same_seed_same_image_other_seed_other_image() {
    let (vol, tf) = scene();
    let s = vol.stats();
    let r = Renderer::new(&vol, [s.min, s.max]).unwrap();
    for m in [
        Method::Jitter,
        Method::Stratified,
        Method::Mc,
        Method::Importance,
    ] {
        let a = draw(&r, &tf, &params(m, 2, 5));
        let b = draw(&r, &tf, &params(m, 2, 5));
        assert_eq!(max_diff(&a, &b), 0.0, "{m:?}");
        let c = draw(&r, &tf, &params(m, 2, 6));
        assert!(max_diff(&a, &c) > 1e-3, "{m:?}: the seed changes nothing");
    }
}

#[test]
fn progressive_mc_converges_at_the_monte_carlo_rate() {
    let (vol, tf) = scene();
    let s = vol.stats();
    let r = Renderer::new(&vol, [s.min, s.max]).unwrap();
    let mut reference = params(Method::Uniform, 1, 0);
    reference.step = 1.0 / 16.0;
    let reference = draw(&r, &tf, &reference);
    for m in [Method::Mc, Method::Stratified, Method::Importance] {
        let psnr: Vec<f64> = [1, 4, 16]
            .iter()
            .map(|&spp| metrics::psnr(&draw(&r, &tf, &params(m, spp, 1)), &reference).unwrap())
            .collect();
        // Variance ∝ 1/spp: +6 dB per ×4 in spp while the noise dominates.
        eprintln!("{m:?}: PSNR at 1/4/16 spp {psnr:?}");
        assert!(psnr[1] - psnr[0] > 4.5, "{m:?}: {psnr:?}");
        assert!(psnr[2] - psnr[1] > 4.0, "{m:?}: {psnr:?}");
    }
}

#[test]
fn spp_is_checked() {
    let mut p = params(Method::Mc, 0, 0);
    assert!(p.validate().unwrap_err().to_string().contains("spp"));
    p.spp = 3;
    assert!(p.validate().is_ok());
}

/// White furnace: a medium that scatters everything (albedo 1) inside an
/// environment of radiance 1 is invisible, whatever its phase function: every
/// pixel's mean is 1 within 3 standard errors (a lost or doubled path
/// weight shows at once).
#[test]
fn white_furnace_for_every_phase_function() {
    use voxcast::render::light::Light;
    use voxcast::render::medium::MajorantKind;
    use voxcast::render::phase::PhaseFunction;
    let vol = voxcast::builtin::open("sphere").unwrap();
    let s = vol.stats();
    let r = Renderer::new(&vol, [s.min, s.max]).unwrap();
    let tf = TransferFunction::preset("grayscale").unwrap_or_else(|| scene().1);
    for (i, phase) in [
        PhaseFunction::Isotropic,
        PhaseFunction::Hg { g: 0.8 },
        PhaseFunction::Hg { g: -0.5 },
        PhaseFunction::Schlick { k: 0.6 },
        PhaseFunction::Rayleigh,
        PhaseFunction::Mie { g: 0.85 },
    ]
    .into_iter()
    .enumerate()
    {
        let mut p = params(Method::Path, 2, i as u64);
        p.width = 24;
        p.height = 24;
        p.lights = vec![Light::Environment {
            radiance: [1.0, 1.0, 1.0],
        }];
        p.medium.albedo = [1.0; 3];
        p.medium.scale = 1.0;
        // No truncation bias: the estimator itself must conserve energy.
        p.medium.max_depth = 100_000;
        p.medium.phase = phase;
        p.medium.majorant = if i % 2 == 0 {
            MajorantKind::Grid
        } else {
            MajorantKind::Global
        };
        let (img, stats) = r.render(&tf, &cam(), &p, &no_progress).unwrap();
        assert!(stats.samples > 1000, "the medium was crossed: {stats:?}");
        let v: Vec<f64> = img
            .pixels
            .iter()
            .flat_map(|q| q[..3].iter().map(|&c| c as f64))
            .collect();
        let n = v.len() as f64;
        let mean = v.iter().sum::<f64>() / n;
        let se = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt();
        assert!(
            (mean - 1.0).abs() <= 3.0 * se + 1e-5,
            "{phase:?}: mean {mean} ± {se}"
        );
    }
}

/// A physically based scene (lights, medium, look-at camera) survives a
/// TOML round trip, and the example scene parses.
#[test]
fn physical_scene_round_trips_through_toml() {
    use voxcast::camera::LookAt;
    use voxcast::render::light::Light;
    use voxcast::render::phase::PhaseFunction;
    use voxcast::Scene;
    let dir = tempfile::tempdir().unwrap();
    let mut s = Scene::default();
    s.render.method = Method::Path;
    s.render.spp = 32;
    s.render.medium.phase = PhaseFunction::Mie { g: 0.7 };
    s.render.medium.r#box = Some([[-1.0, -1.0, 0.0], [1.0, 1.0, 2.0]]);
    s.render.lights = vec![
        Light::Point {
            position: [0.0, 0.0, 3.0],
            intensity: [2.0, 2.0, 2.0],
        },
        Light::Environment {
            radiance: [0.1, 0.2, 0.3],
        },
    ];
    s.camera.look_at = Some(LookAt {
        origin: [0.0, -4.0, 1.0],
        target: [0.0, 0.0, 1.0],
        up: [0.0, 0.0, 1.0],
    });
    let f = dir.path().join("s.toml");
    s.save(&f).unwrap();
    let back = Scene::load(&f).unwrap();
    assert_eq!(back.render, s.render);
    assert_eq!(back.camera, s.camera);
    let ex =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/cloud-path.toml");
    let cloud = Scene::load(&ex).unwrap();
    assert_eq!(cloud.render.method, Method::Path);
    assert_eq!(cloud.render.lights.len(), 2);
    // A bad look-at is an error naming the field.
    std::fs::write(
        &f,
        "[camera]\nlook_at = { origin = [0, 0, 0], target = [0, 0, 0] }\n",
    )
    .unwrap();
    let e = Scene::load(&f).unwrap_err().to_string();
    assert!(e.contains("look_at"), "{e}");
}

/// Single scattering against its closed form: a homogeneous unit cube
/// (σ_t = 1, albedo 0.8, isotropic phase) seen orthographically face on,
/// lit by a directional light of irradiance E along the line of sight.
/// Along a camera ray through depth `t ∈ [0, 1]` the single-scatter
/// radiance is `∫ σ_s·E/(4π)·T_light(t)·T_cam(t) dt` with `T_cam = e^{−t}`:
/// * light behind the cube (shining at the camera): `T_light = e^{−(1−t)}`,
///   so `L = a·E·σ·e^{−σ}/(4π)`;
/// * light behind the camera: `T_light = e^{−t}`, so
///   `L = a·E·(1 − e^{−2σ})/(8π)`.
///
/// The mean of the pixels that look through the cube's face must be within
/// 3 standard errors of each.
#[test]
fn single_scatter_matches_the_closed_form_for_a_homogeneous_cube() {
    use voxcast::camera::{Camera, Projection};
    use voxcast::render::light::Light;
    use voxcast::render::phase::PhaseFunction;
    let vol = Volume::from_fn([5, 5, 5], glam::Vec3::splat(0.25), |_, _, _| 1.0).unwrap();
    let (lo, hi) = vol.world_bounds();
    assert_eq!((lo, hi), (glam::Vec3::ZERO, glam::Vec3::ONE));
    let r = Renderer::new(&vol, [0.0, 1.0]).unwrap();
    let tf = scene().1;
    let camera = CameraParams {
        projection: Projection::Orthographic,
        ..Default::default()
    };
    let (w, h) = (24u32, 24u32);
    let view = Camera::fit(&camera, lo, hi, w, h).ray(w / 2, h / 2).1;
    // The camera looks at a face of the cube.
    let axis = view.abs().max_element();
    assert!(axis > 0.999, "view {view}");
    let (sigma, albedo, e) = (1.0f64, 0.8f64, 2.0f32);
    let four_pi = 4.0 * std::f64::consts::PI;
    for (towards_light, exact) in [
        (view, albedo * e as f64 * sigma * (-sigma).exp() / four_pi),
        (
            -view,
            albedo * e as f64 * (1.0 - (-2.0 * sigma).exp()) / (2.0 * four_pi),
        ),
    ] {
        let mut p = params(Method::SingleScatter, 256, 3);
        p.width = w;
        p.height = h;
        p.lights = vec![Light::Directional {
            direction: towards_light.to_array(),
            irradiance: [e; 3],
        }];
        p.medium.albedo = [albedo as f32; 3];
        p.medium.scale = sigma as f32;
        p.medium.phase = PhaseFunction::Isotropic;
        let (img, _) = r.render(&tf, &camera, &p, &no_progress).unwrap();
        // Pixels whose rays cross the cube face on (away from its edges).
        let cam = Camera::fit(&camera, lo, hi, w, h);
        let mut v = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let (o, d) = cam.ray(x, y);
                // Where the ray meets the plane through the cube's centre
                // across the view: inside the face's middle 80 %?
                let t = (glam::Vec3::splat(0.5) - o).dot(view) / d.dot(view);
                let q = o + d * t - glam::Vec3::splat(0.5);
                if (q - view * q.dot(view)).abs().max_element() < 0.4 {
                    v.push(img.get(x, y)[1] as f64);
                }
            }
        }
        assert!(v.len() >= 100, "{} pixels through the cube", v.len());
        let n = v.len() as f64;
        let mean = v.iter().sum::<f64>() / n;
        let se = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt();
        assert!(se > 0.0 && se < 0.05 * exact, "se {se} vs {exact}");
        assert!(
            (mean - exact).abs() < 3.0 * se,
            "light towards {towards_light}: {mean} ± {se} vs {exact}"
        );
    }
}
