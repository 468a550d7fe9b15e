//! The bench's table says which inner loop ran: the methods the SIMD
//! packets do not cover yet (since `mc` moved into them, only the
//! physically based integrators), or every method where `--simd scalar`
//! asked for the scalar loop.

use voxcast::render::{simd_level, Simd};
use voxcast::scene::Scene;
use voxcast_bench::{parse_methods, run, text_table, BenchConfig};

fn table(simd: Simd) -> String {
    let mut scene = Scene::default();
    scene.input.path = "builtin:demo".into();
    scene.render.width = 32;
    scene.render.height = 32;
    scene.render.simd = simd;
    let prepared = scene.prepare().unwrap();
    let config = BenchConfig {
        methods: parse_methods("uniform,single-scatter").unwrap(),
        repeat: 1,
        warmup: 0,
        cache_dir: None,
        ..Default::default()
    };
    text_table(&run(&scene, &prepared, &config, &|_| {}).unwrap())
}

#[test]
fn the_table_says_which_loop_ran() {
    let forced = table(Simd::Scalar);
    let auto = table(Simd::Auto);
    if simd_level(Simd::Auto).is_some() {
        assert!(
            forced.contains("Scalar loop for every method, as asked (--simd scalar)."),
            "{forced}"
        );
        assert!(!forced.contains("yet"), "{forced}");
        assert!(
            auto.contains(
                "Scalar loop (these methods do not run in the SIMD packets yet): single-scatter."
            ),
            "{auto}"
        );
    } else {
        // No packets on this CPU: nothing to say.
        assert!(!forced.contains("Scalar loop") && !auto.contains("Scalar loop"));
    }
}
