//! Robustness of the renderer: random valid scenes render without NaN,
//! panic or hang; every random method gives the same bytes for the same
//! seed whatever the thread count; an absurd extinction is refused at once.

use glam::Vec3;
use proptest::prelude::*;
use std::time::{Duration, Instant};
use voxcast::camera::Projection;
use voxcast::geometry::{BoxDef, PlaneDef};
use voxcast::render::{Method, OpticalModel, Order};
use voxcast::{Scene, Volume};

/// A small lumpy volume: a blob with a hole and a hard edge.
fn tiny(dims: [usize; 3]) -> Volume {
    Volume::from_fn(dims, Vec3::new(1.0, 1.2, 0.8), |i, j, k| {
        let c = |n: usize, x: usize| x as f32 / (n.max(2) - 1) as f32 - 0.5;
        let (x, y, z) = (c(dims[0], i), c(dims[1], j), c(dims[2], k));
        let r = (x * x + y * y + z * z).sqrt();
        let blob = (1.0 - 2.0 * r).max(0.0);
        let edge = if x > 0.2 { 0.7 } else { 0.0 };
        blob + edge * (1.0 - blob) + 0.1 * ((i * 7 + j * 3 + k) % 5) as f32
    })
    .unwrap()
}

fn render(scene: &Scene, volume: Volume) -> voxcast::Result<voxcast::Image> {
    let prepared = scene.prepare_with(volume)?;
    Ok(scene.render(&prepared, &|_, _| {})?.0)
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
}

#[test]
fn every_random_method_gives_the_same_bytes_on_1_2_and_3_threads() {
    let random: Vec<Method> = Method::ALL
        .into_iter()
        .filter(|m| m.is_stochastic() || m.is_physical())
        .collect();
    assert!(random.len() >= 6, "{random:?}");
    for method in random {
        let mut scene = Scene::default();
        scene.transfer.tf = "cloud".into();
        scene.render.method = method;
        scene.render.width = 40;
        scene.render.height = 28;
        scene.render.spp = 3;
        scene.render.seed = 11;
        scene.camera.azimuth = 25.0;
        scene.camera.elevation = 15.0;
        let images: Vec<Vec<[f32; 4]>> = [1, 2, 3]
            .iter()
            .map(|&n| pool(n).install(|| render(&scene, tiny([19, 17, 13])).unwrap().pixels))
            .collect();
        for (n, img) in [2, 3].iter().zip(&images[1..]) {
            let same = img
                .iter()
                .zip(&images[0])
                .all(|(a, b)| a.map(f32::to_bits) == b.map(f32::to_bits));
            assert!(same, "{method:?}: {n} threads give other bytes than 1");
        }
        // And the seed matters (the images are not trivially equal).
        scene.render.seed = 12;
        let other = pool(2).install(|| render(&scene, tiny([19, 17, 13])).unwrap().pixels);
        assert_ne!(other, images[0], "{method:?}: the seed changes nothing");
    }
}

#[test]
fn an_absurd_extinction_is_refused_at_once_and_a_huge_one_ends() {
    for method in [Method::Path, Method::SingleScatter] {
        let mut scene = Scene::default();
        scene.render.method = method;
        scene.render.width = 64;
        scene.render.height = 64;
        scene.render.medium.scale = 1e30;
        let t = Instant::now();
        let e = render(&scene, tiny([9, 9, 9])).unwrap_err().to_string();
        assert!(
            e.contains("medium.scale") && e.contains("optical depth"),
            "{e}"
        );
        assert!(t.elapsed() < Duration::from_secs(2), "{:?}", t.elapsed());
        // Just under the limit: dense, slow per path, but it ends.
        let (lo, hi) = tiny([9, 9, 9]).world_bounds();
        scene.render.medium.scale =
            0.9 * voxcast::render::medium::MAX_OPTICAL_DEPTH / (hi - lo).length();
        scene.render.width = 8;
        scene.render.height = 8;
        let img = render(&scene, tiny([9, 9, 9])).unwrap();
        assert!(img.pixels.iter().flatten().all(|c| c.is_finite()));
    }
}

fn method() -> impl Strategy<Value = Method> {
    proptest::sample::select(Method::ALL.to_vec())
}

fn optical() -> impl Strategy<Value = OpticalModel> {
    proptest::sample::select(vec![
        OpticalModel::AbsorptionOnly,
        OpticalModel::EmissionOnly,
        OpticalModel::EmissionAbsorption,
    ])
}

/// Opaque geometry: none, a box through the volume, a floor, or both.
fn geometry() -> impl Strategy<Value = (bool, bool)> {
    (any::<bool>(), any::<bool>())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn random_valid_scenes_render_without_nan_panic_or_hang(
        method in method(),
        optical in optical(),
        back_to_front in any::<bool>(),
        width in 1u32..24,
        height in 1u32..24,
        step in 0.05f32..6.0,
        spp in 1u32..4,
        seed in any::<u64>(),
        ert in 0.5f32..=1.0,
        shading in any::<bool>(),
        skip_empty in any::<bool>(),
        jitter in any::<bool>(),
        azimuth in -720f32..720.0,
        elevation in -90f32..90.0,
        zoom in 0.05f32..20.0,
        fov in 1f32..=170.0,
        ortho in any::<bool>(),
        dims in (1usize..12, 1usize..12, 1usize..12),
        (with_box, with_plane) in geometry(),
        scale in 0.0f32..200.0,
    ) {
        let mut scene = Scene::default();
        scene.transfer.tf = "grayscale".into();
        let r = &mut scene.render;
        r.method = method;
        r.optical = optical;
        r.order = if back_to_front { Order::BackToFront } else { Order::FrontToBack };
        r.width = width;
        r.height = height;
        r.step = step;
        r.spp = spp;
        r.seed = seed;
        r.ert = ert;
        r.shading = shading;
        r.skip_empty = skip_empty;
        r.jitter = jitter;
        r.medium.scale = scale;
        let c = &mut scene.camera;
        c.azimuth = azimuth;
        c.elevation = elevation;
        c.zoom = zoom;
        c.fov = fov;
        c.projection = if ortho { Projection::Orthographic } else { Projection::Perspective };
        let g = &mut scene.geometry;
        if with_box {
            g.boxes.push(BoxDef { min: [2.0, 1.0, 1.0], max: [4.0, 9.0, 3.0], color: [0.6, 0.5, 0.4], name: None });
        }
        if with_plane {
            g.planes.push(PlaneDef { point: [0.0, 0.0, -0.5], normal: [0.0, 0.0, 1.0], color: [0.5; 3], half_extent: None, name: None });
        }
        prop_assume!(scene.validate().is_ok());
        let volume = tiny([dims.0, dims.1, dims.2]);
        let t = Instant::now();
        match render(&scene, volume) {
            Ok(img) => {
                prop_assert_eq!(img.pixels.len(), (width * height) as usize);
                prop_assert!(
                    img.pixels.iter().flatten().all(|c| c.is_finite()),
                    "{:?}: a pixel is not finite", method
                );
            }
            // The one combination refused today, by name.
            Err(e) => prop_assert!(
                method.is_physical() && (with_box || with_plane)
                    && e.to_string().contains("opaque geometry is not supported"),
                "{:?}: {}", method, e
            ),
        }
        prop_assert!(t.elapsed() < Duration::from_secs(30), "{:?} took {:?}", method, t.elapsed());
    }
}
