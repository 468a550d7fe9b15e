//! End to end from the command line: a Mitsuba `.vol` medium, path traced
//! into a linear EXR, checked against Beer–Lambert.

use std::process::Command;

#[test]
fn path_traced_absorbing_vol_slab_matches_beer_lambert() {
    let dir = tempfile::tempdir().unwrap();
    // A homogeneous unit cube of density 1 (4³ samples spanning [0, 1]³).
    let bytes = voxcast::io::mitsuba_vol::encode([4, 4, 4], [0.0; 3], [1.0; 3], &[1.0; 64]);
    std::fs::write(dir.path().join("cube.vol"), bytes).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_voxcast"))
        .args([
            "render",
            "cube.vol",
            "--method",
            "path",
            "--spp",
            "256",
            "--albedo",
            "0",
            "--extinction",
            "1",
            "--env",
            "1",
            "--window",
            "0,1",
            "--ortho",
            "--size",
            "16x16",
            "-o",
            "out.exr",
            "--stats-json",
            "stats.json",
            "-q",
        ])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let img = voxcast::Image::read(&dir.path().join("out.exr")).unwrap();
    // Outside the cube the camera sees the environment, exactly 1.
    assert_eq!(img.get(0, 0)[0], 1.0);
    // Through the cube (depth 1 along +y, σ = 1, nothing scattered): the
    // fraction of paths that escape is exp(−1).
    let exact = (-1.0f64).exp();
    let mut sum = 0.0;
    for y in 6..10 {
        for x in 6..10 {
            sum += img.get(x, y)[1] as f64;
        }
    }
    let mean = sum / 16.0;
    let se = (exact * (1.0 - exact) / (16.0 * 256.0)).sqrt();
    assert!((mean - exact).abs() < 3.0 * se, "{mean} vs {exact} ± {se}");
    // Camera rays (256 per pixel) are counted, and those that met the
    // medium's box: some, not all (the corner pixel sees only the sky).
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("stats.json")).unwrap())
            .unwrap();
    let rays = stats["rays"].as_u64().unwrap();
    let hit = stats["rays_hit"].as_u64().unwrap();
    assert_eq!(rays, 16 * 16 * 256, "{stats}");
    assert!(hit >= 16 * 256 && hit < rays, "{stats}");
}

#[test]
fn bad_medium_flags_are_named() {
    let dir = tempfile::tempdir().unwrap();
    for (flag, value, word) in [
        ("--phase", "hg", "--phase"),
        ("--albedo", "2", "albedo"),
        ("--majorant", "octree", "--majorant"),
        ("--spp", "0", "spp"),
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_voxcast"))
            .args(["render", "--method", "path", flag, value, "-q"])
            .current_dir(dir.path())
            .output()
            .unwrap();
        assert!(!o.status.success());
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains(word), "{flag} {value}: {e}");
    }
}
