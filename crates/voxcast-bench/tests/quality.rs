//! `--quality DB`: the setting a low-resolution pilot picks reaches the
//! target on the full image.

use voxcast::metrics;
use voxcast::render::{MethodSpec, RenderParams, Renderer};
use voxcast::scene::Scene;
use voxcast_bench::quality::{choose, PILOT_PIXELS};
use voxcast_bench::reference_params;

#[test]
fn quality_reaches_its_target_within_1_db_on_two_volumes() {
    let neghip = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/data/neghip/neghip.nhdr"
    );
    for input in ["builtin:demo", neghip] {
        let mut scene = Scene::default();
        scene.input.path = input.into();
        scene.camera.azimuth = 30.0;
        scene.camera.elevation = 20.0;
        scene.render.width = 256;
        scene.render.height = 256;
        let prepared = scene.prepare().unwrap();
        let renderer = Renderer::new(&prepared.volume, prepared.window).unwrap();
        let render = |p: &RenderParams| renderer.render(&prepared.tf, &scene.camera, p, &|_, _| {});
        let (reference, _) = render(&reference_params(&scene.render)).unwrap();
        for spec in ["uniform", "adaptive+grouped"] {
            let mut p = scene.render.clone();
            MethodSpec::parse(spec).unwrap().apply(&mut p);
            let mut steps = Vec::new();
            for target in [40.0, 46.0] {
                // The default pilot: 128×128, a quarter of the pixels.
                let c = choose(&p, target, PILOT_PIXELS, &render, &|_| {}).unwrap();
                assert_eq!((c.pilot_width, c.pilot_height), (128, 128));
                assert!(c.reached, "{input} {spec} {target} dB: {c:?}");
                let (img, _) = render(&c.params).unwrap();
                let psnr = metrics::psnr(&img, &reference).unwrap();
                assert!(
                    (psnr - target).abs() <= 1.0,
                    "{input} {spec}: --quality {target} gives {psnr:.2} dB on the full image ({}; trials {:?})",
                    c.describe(),
                    c.trials
                );
                steps.push(c.step);
            }
            // A higher target samples more finely.
            assert!(steps[1] < steps[0], "{input} {spec}: steps {steps:?}");
        }
    }
}

#[test]
fn quality_refuses_what_it_cannot_measure() {
    let p = RenderParams {
        method: voxcast::render::Method::Path,
        ..Default::default()
    };
    let never = |_: &RenderParams| -> voxcast::Result<_> { unreachable!("nothing renders") };
    let e = choose(&p, 40.0, 1000, &never, &|_| {}).unwrap_err();
    assert!(e.to_string().contains("--spp"), "{e}");
    let e = choose(&RenderParams::default(), f64::NAN, 1000, &never, &|_| {}).unwrap_err();
    assert!(e.to_string().contains("--quality NaN"), "{e}");
}
