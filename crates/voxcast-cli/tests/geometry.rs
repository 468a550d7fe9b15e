//! End-to-end: opaque geometry from the command line (`--geometry`,
//! `--shadows`, `--light`), the FDS room with its obstructions, saved
//! scenes that reproduce geometry renders, clean errors.

use std::process::Output;

mod common;
use common::{stderr, voxcast};

/// Exit code 1 (a clean error, not a panic's 101) with `needles` in the message.
fn fails_with(o: &Output, needles: &[&str]) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    for n in needles {
        assert!(e.contains(n), "`{n}` not in: {e}");
    }
}

#[test]
fn fds_room_renders_with_its_obstructions_and_the_scene_reproduces_it() {
    let Some(smv) = voxcast::testdata::data_path("fds_room/room_smoke.smv") else {
        return;
    };
    let smv = smv.to_string_lossy().into_owned();
    let dir = tempfile::tempdir().unwrap();
    let common = [
        "--time",
        "30",
        "--size",
        "96x64",
        "--elevation",
        "20",
        "--azimuth",
        "30",
    ];
    let run = |extra: &[&str]| {
        let mut a = vec!["render", smv.as_str()];
        a.extend(common);
        a.extend(extra);
        voxcast(&a, dir.path())
    };
    let o = run(&["-o", "a.png", "--shadows", "on", "--save-scene", "s.toml"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("22 boxes"), "{}", stderr(&o));
    let scene = std::fs::read_to_string(dir.path().join("s.toml")).unwrap();
    assert!(
        scene.contains("[geometry]") && scene.contains("shadows = true"),
        "{scene}"
    );
    let o = voxcast(&["render", "--scene", "s.toml", "-o", "b.png"], dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    let (a, b) = (
        std::fs::read(dir.path().join("a.png")).unwrap(),
        std::fs::read(dir.path().join("b.png")).unwrap(),
    );
    assert!(a == b, "the saved scene renders a different image");
    let o = run(&["-o", "c.png", "--geometry", "none"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("boxes"));
    let ia = voxcast::Image::read(&dir.path().join("a.png")).unwrap();
    let ic = voxcast::Image::read(&dir.path().join("c.png")).unwrap();
    // The obstructions change a good part of the picture.
    let changed = ia
        .pixels
        .iter()
        .zip(&ic.pixels)
        .filter(|(p, q)| (0..3).any(|c| (p[c] - q[c]).abs() > 0.05))
        .count();
    assert!(changed > 300, "{changed} of 6144 pixels changed");
}

#[test]
fn geometry_file_beside_the_input_is_found_and_flags_are_checked() {
    let dir = tempfile::tempdir().unwrap();
    let mut nrrd = b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 8 8 8\nencoding: raw\n\n".to_vec();
    nrrd.extend((0..512u32).map(|i| (i % 7 * 30) as u8));
    std::fs::write(dir.path().join("vol.nrrd"), nrrd).unwrap();
    std::fs::write(
        dir.path().join("geometry.toml"),
        "[[box]]\nmin = [2, 2, 2]\nmax = [5, 5, 5]\ncolor = [0.9, 0.2, 0.1]\n[[plane]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\n",
    )
    .unwrap();
    let o = voxcast(
        &["render", "vol.nrrd", "--size", "32x32", "-o", "a.png"],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("1 boxes, 1 planes"), "{}", stderr(&o));
    // An explicit file, with shadows and a light.
    std::fs::write(
        dir.path().join("m.obj"),
        "v 0 0 0\nv 7 0 0\nv 0 7 0\nf 1 2 3\n",
    )
    .unwrap();
    std::fs::write(dir.path().join("g.toml"), "[[mesh]]\npath = \"m.obj\"\n").unwrap();
    let o = voxcast(
        &[
            "render",
            "vol.nrrd",
            "--size",
            "32x32",
            "-o",
            "b.png",
            "--geometry",
            "g.toml",
            "--shadows",
            "on",
            "--light",
            "0,0,1",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("1 meshes (1 triangles)"),
        "{}",
        stderr(&o)
    );
    // Clean errors.
    let bad = |extra: &[&str]| {
        let mut a = vec!["render", "vol.nrrd", "--size", "16x16", "-o", "x.png"];
        a.extend(extra);
        voxcast(&a, dir.path())
    };
    fails_with(
        &bad(&["--geometry", "nope.toml"]),
        &["nope.toml", "--geometry"],
    );
    fails_with(&bad(&["--shadows", "maybe"]), &["--shadows", "on or off"]);
    fails_with(&bad(&["--light", "0,0,0"]), &["--light"]);
    fails_with(&bad(&["--light", "1,2"]), &["--light"]);
    std::fs::write(
        dir.path().join("m.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n",
    )
    .unwrap();
    fails_with(&bad(&["--geometry", "g.toml"]), &["m.obj", "`f`"]);
    std::fs::write(dir.path().join("g.toml"), "[[box]]\nmin = [0, 0]\n").unwrap();
    fails_with(&bad(&["--geometry", "g.toml"]), &["g.toml", "line 2"]);
    assert!(!dir.path().join("x.png").exists());
}

#[test]
fn truncated_s3d_is_a_clean_error_from_the_cli() {
    let Some(smv) = voxcast::testdata::data_path("fds_room/room_smoke.smv") else {
        return;
    };
    let src = smv.parent().unwrap();
    let dir = tempfile::tempdir().unwrap();
    for f in ["room_smoke.smv", "room_smoke_1.xyz"] {
        std::fs::copy(src.join(f), dir.path().join(f)).unwrap();
    }
    let s3d = std::fs::read(src.join("room_smoke_1_1.s3d")).unwrap();
    std::fs::write(
        dir.path().join("room_smoke_1_1.s3d"),
        &s3d[..s3d.len() * 2 / 3],
    )
    .unwrap();
    let o = voxcast(
        &[
            "render",
            "room_smoke.smv",
            "--time",
            "59",
            "--size",
            "16x16",
            "-o",
            "x.png",
        ],
        dir.path(),
    );
    fails_with(&o, &["room_smoke_1_1.s3d", "truncated"]);
    assert!(!dir.path().join("x.png").exists());
}

#[test]
fn info_lists_the_fds_case_with_its_obstructions() {
    let Some(smv) = voxcast::testdata::data_path("fds_room/room_smoke.smv") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let o = voxcast(&["info", &smv.to_string_lossy()], dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    for needle in [
        "mesh MESH_0000001: 50×30×25 cells",
        "121 frames, 0 .. 60 s (room_smoke_1_1.s3d)",
        "times 10, 20.01, 30.01, 40, 50, 60 s",
        "obstructions: 22 (1 zero-volume skipped)",
        "Table top: 2..3.2 × 1..1.8 × 0.7..0.8 m",
    ] {
        assert!(out.contains(needle), "`{needle}` not in:\n{out}");
    }
}
