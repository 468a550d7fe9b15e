//! `voxcast convert` and chunked stores from the command line: a pyramid
//! written and rendered in core and out of core to the same picture, the
//! level chosen by zoom, and every refusal with its reason.

mod common;
use common::{psnr, stderr, voxcast};
use std::path::Path;

fn ok(args: &[&str], cwd: &Path) -> String {
    let o = voxcast(args, cwd);
    assert!(o.status.success(), "voxcast {args:?}: {}", stderr(&o));
    stderr(&o)
}

fn fails(args: &[&str], cwd: &Path) -> String {
    let o = voxcast(args, cwd);
    assert!(!o.status.success(), "voxcast {args:?} should fail");
    let e = stderr(&o);
    assert!(!e.contains("panicked"), "{e}");
    e
}

#[test]
fn a_level_read_whole_looks_as_it_does_out_of_core() {
    // Levels 1 and 2 read whole (they fit the budget) give the out-of-core
    // renderer's pixels exactly: level 0's opacity unit and camera box
    // (35.4 dB apart before), steps of the level's own voxels (they were
    // level 0's: twice the samples, on other positions) and the automatic
    // transfer function and window of the same stand-in level and value
    // range (they followed the level's own histogram): 51 dB apart at
    // level 1 and 41 dB at level 2 before.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    ok(
        &[
            "convert",
            "builtin:demo",
            "-o",
            "demo.zarr",
            "--chunk",
            "32",
        ],
        d,
    );
    for level in ["1", "2"] {
        for shading in ["on", "off"] {
            let common = [
                "--size",
                "64x64",
                "--level",
                level,
                "--azimuth",
                "30",
                "--elevation",
                "20",
                "--shading",
                shading,
            ];
            let mut a = vec!["render", "demo.zarr", "-o", "a.png"];
            a.extend(common);
            let said = ok(&a, d);
            assert!(said.contains(&format!("level {level} of 0…2")), "{said}");
            assert!(said.contains("as out of core"), "{said}");
            let mut b = vec!["render", "demo.zarr", "-o", "b.png", "--out-of-core"];
            b.extend(common);
            let said = ok(&b, d);
            assert!(said.contains(&format!("level {level}")), "{said}");
            let db = psnr("a.png", "b.png", d).map_or(f64::INFINITY, |v| v);
            assert!(
                db.is_infinite(),
                "level {level}, shading {shading}: in core against out of core: {db:.1} dB"
            );
        }
    }
}

#[test]
fn a_converted_store_renders_out_of_core_as_in_core() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let said = ok(
        &[
            "convert",
            "builtin:demo",
            "-o",
            "demo.zarr",
            "--chunk",
            "32",
        ],
        d,
    );
    assert!(said.contains("3 levels"), "{said}");
    assert!(d.join("demo.zarr/zarr.json").is_file());
    // No temporary folder is left beside it.
    let names: Vec<String> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, vec!["demo.zarr".to_string()]);
    let common = ["--size", "96x96", "--azimuth", "30", "--elevation", "20"];
    let mut a = vec!["render", "builtin:demo", "-o", "a.png"];
    a.extend(common);
    ok(&a, d);
    let mut b = vec!["render", "demo.zarr", "-o", "b.png", "--level", "0"];
    b.extend(common);
    ok(&b, d);
    // Out of core under a budget of a few chunks: the same voxels, window
    // and samples.
    let mut c = vec![
        "render",
        "demo.zarr",
        "-o",
        "c.png",
        "--level",
        "0",
        "--out-of-core",
        "--memory-budget",
        "1MiB",
        "--stats-json",
        "c.json",
    ];
    c.extend(common);
    let said = ok(&c, d);
    assert!(said.contains("out of core"), "{said}");
    assert_eq!(psnr("a.png", "b.png", d), None, "in core: identical");
    let db = psnr("a.png", "c.png", d).map_or(f64::INFINITY, |v| v);
    assert!(db >= 60.0, "out of core {db} dB");
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("c.json")).unwrap()).unwrap();
    assert!(j["out_of_core"]["bytes_read"].as_u64().unwrap() > 0, "{j}");
    assert!(
        j["out_of_core"]["cache"]["peak_bytes"].as_u64().unwrap() <= 1 << 20,
        "{j}"
    );
    // A 96² view of 128³ needs level 1; zoomed in, level 0.
    let said = ok(
        &["render", "demo.zarr", "-o", "d.png", "--size", "96x96"],
        d,
    );
    assert!(said.contains("level 1 of 0…2"), "{said}");
    let said = ok(
        &[
            "render",
            "demo.zarr",
            "-o",
            "e.png",
            "--size",
            "96x96",
            "--zoom",
            "3",
        ],
        d,
    );
    assert!(said.contains("level 0 of 0…2"), "{said}");
    // A level that is not there is named.
    let e = fails(&["render", "demo.zarr", "-o", "f.png", "--level", "7"], d);
    assert!(e.contains("--level 7") && e.contains("0…2"), "{e}");
    // info lists the levels.
    let o = voxcast(&["info", "demo.zarr"], d);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("OME-Zarr 0.5") && text.contains("level 2 [2]: 32×32×32"),
        "{text}"
    );
}

#[test]
fn convert_refuses_to_lose_data() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    ok(&["convert", "builtin:sphere", "-o", "s.zarr", "-q"], d);
    // An existing store needs --overwrite; a folder that is not a store is
    // never replaced.
    let e = fails(&["convert", "builtin:sphere", "-o", "s.zarr"], d);
    assert!(e.contains("--overwrite"), "{e}");
    std::fs::create_dir(d.join("photos")).unwrap();
    std::fs::write(d.join("photos/keep.txt"), "mine").unwrap();
    let e = fails(
        &["convert", "builtin:sphere", "-o", "photos", "--overwrite"],
        d,
    );
    assert!(e.contains("not a Zarr store"), "{e}");
    assert!(d.join("photos/keep.txt").is_file());
    // A store is not written over itself, nor over the folder holding it.
    let e = fails(&["convert", "s.zarr", "-o", "s.zarr", "--overwrite"], d);
    assert!(e.contains("input"), "{e}");
    // With --overwrite the new store replaces the old one whole.
    ok(
        &[
            "convert",
            "builtin:demo",
            "-o",
            "s.zarr",
            "--overwrite",
            "-q",
        ],
        d,
    );
    let o = voxcast(&["info", "s.zarr", "--json"], d);
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["dims"], serde_json::json!([128, 128, 128]));
    // info's JSON lists the levels for scripts.
    let z = &j["zarr"];
    assert_eq!(z["ome_version"], "0.5");
    assert_eq!(z["levels"][1]["dims"], serde_json::json!([64, 64, 64]));
    assert_eq!(
        z["levels"][1]["spacing"],
        serde_json::json!([2.0, 2.0, 2.0])
    );
    assert_eq!(z["levels"][0]["chunk"], serde_json::json!([64, 64, 64]));
    assert_eq!(z["levels"][0]["chunk_ranges"], true);
    // Bad flags, each named.
    for (args, want) in [
        (vec!["--chunk", "0"], "--chunk"),
        (vec!["--zarr-version", "4"], "--zarr-version"),
        (vec!["--compression", "lzma"], "--compression"),
        (vec!["--levels", "0"], "--levels"),
        (vec!["--dims", "8,8"], "--dims"),
    ] {
        let mut a = vec!["convert", "builtin:sphere", "-o", "x.zarr"];
        a.extend(args);
        let e = fails(&a, d);
        assert!(e.contains(want), "{want}: {e}");
        assert!(!d.join("x.zarr").exists());
    }
    let e = fails(
        &[
            "convert",
            "builtin:plume",
            "--dims",
            "8,8,8",
            "-o",
            "x.zarr",
        ],
        d,
    );
    assert!(e.contains("not generated at other sizes"), "{e}");
    // A failed read leaves nothing behind.
    let e = fails(&["convert", "missing.nrrd", "-o", "x.zarr"], d);
    assert!(e.contains("missing.nrrd"), "{e}");
    let left: Vec<_> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("x.zarr"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

#[test]
fn a_damaged_store_is_a_clear_error_or_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    ok(
        &[
            "convert",
            "builtin:demo",
            "-o",
            "s.zarr",
            "--chunk",
            "32",
            "--levels",
            "1",
            "-q",
        ],
        d,
    );
    let args = [
        "render",
        "s.zarr",
        "-o",
        "o.png",
        "--size",
        "64x64",
        "--out-of-core",
        "--memory-budget",
        "1MiB",
    ];
    // A budget below one brick is refused with what it needs.
    let e = fails(
        &[
            "render",
            "s.zarr",
            "-o",
            "o.png",
            "--out-of-core",
            "--memory-budget",
            "10KiB",
        ],
        d,
    );
    assert!(e.contains("below one brick"), "{e}");
    let e = fails(
        &["render", "s.zarr", "-o", "o.png", "--memory-budget", "lots"],
        d,
    );
    assert!(e.contains("--memory-budget"), "{e}");
    // A chunk that held values is missing: rendered as the fill value,
    // with one warning.
    std::fs::remove_file(d.join("s.zarr/0/c/1/1/1")).unwrap();
    std::fs::remove_file(d.join("s.zarr/0/c/2/1/1")).unwrap();
    let said = ok(&args, d);
    assert_eq!(
        said.matches("is missing from the store").count(),
        1,
        "{said}"
    );
    // Corrupt bytes: an error naming the chunk; the image of the run
    // before is left as it was.
    let before = std::fs::read(d.join("o.png")).unwrap();
    std::fs::write(d.join("s.zarr/0/c/1/2/1"), b"garbage").unwrap();
    let e = fails(&args, d);
    assert!(e.contains("c/1/2/1") && e.contains("s.zarr"), "{e}");
    assert_eq!(std::fs::read(d.join("o.png")).unwrap(), before);
    // Metadata that is not JSON names the file.
    std::fs::write(d.join("s.zarr/zarr.json"), b"{").unwrap();
    let e = fails(&["info", "s.zarr"], d);
    assert!(e.contains("zarr.json") && e.contains("JSON"), "{e}");
}

#[test]
fn raw_files_and_stores_convert_slab_by_slab_to_the_same_voxels() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A raw u16 file, big-endian after a 7-byte header, 70×50×90 (several
    // slabs of 64 MiB would need a larger file; the path is the same).
    let (x, y, z) = (70u32, 50u32, 90u32);
    let mut bytes = vec![1u8; 7];
    for k in 0..z {
        for j in 0..y {
            for i in 0..x {
                let v = ((i * 7 + j * 13 + k * 29) % 4000) as u16 * ((i / 20 + k / 30) % 2) as u16;
                bytes.extend_from_slice(&v.to_be_bytes());
            }
        }
    }
    std::fs::write(d.join("v.raw"), &bytes).unwrap();
    let raw = [
        "--raw-dims",
        "70,50,90",
        "--raw-type",
        "u16",
        "--raw-endian",
        "big",
        "--raw-header-bytes",
        "7",
    ];
    let mut a = vec!["convert", "v.raw", "-o", "r.zarr", "--chunk", "16,32,8"];
    a.extend(raw);
    let said = ok(&a, d);
    assert!(said.contains("streaming"), "{said}");
    // The same voxels as the in-core reader gives.
    let mut b = vec![
        "render", "v.raw", "-o", "a.png", "--size", "64x64", "--tf", "fire",
    ];
    b.extend(raw);
    ok(&b, d);
    let args = |input: &'static str, out: &'static str| {
        vec![
            "render", input, "-o", out, "--size", "64x64", "--tf", "fire", "--level", "0",
        ]
    };
    ok(&args("r.zarr", "b.png"), d);
    assert_eq!(psnr("a.png", "b.png", d), None);
    // A store rechunked and recompressed into v2, from level 0, slab by slab.
    let said = ok(
        &[
            "convert",
            "r.zarr",
            "-o",
            "s.zarr",
            "--chunk",
            "32",
            "--zarr-version",
            "2",
            "--compression",
            "blosc",
        ],
        d,
    );
    assert!(said.contains("streaming"), "{said}");
    assert!(d.join("s.zarr/.zattrs").is_file());
    ok(&args("s.zarr", "c.png"), d);
    assert_eq!(psnr("a.png", "c.png", d), None);
    // A raw file shorter than its layout is refused before anything is
    // written.
    std::fs::write(d.join("short.raw"), &bytes[..1000]).unwrap();
    let mut a = vec!["convert", "short.raw", "-o", "t.zarr"];
    a.extend(raw);
    let e = fails(&a, d);
    assert!(e.contains("short.raw") && e.contains("truncated"), "{e}");
    assert!(!d.join("t.zarr").exists());
}

#[test]
fn out_of_core_reads_far_regions_at_a_coarser_level() {
    // The demo in chunks of 16: at 96² zoomed 1.2×, the front needs level
    // 0 and the back only level 1. The render reads each region at its
    // level, and comes nearer level 0's picture than level 1 alone.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    ok(
        &[
            "convert",
            "builtin:demo",
            "-o",
            "d.zarr",
            "--chunk",
            "16",
            "-q",
        ],
        d,
    );
    let view = ["--size", "96x96", "--zoom", "1.2", "--out-of-core"];
    let render = |out: &str, extra: &[&str]| {
        let mut a = vec!["render", "d.zarr", "-o", out];
        a.extend(view);
        a.extend(extra);
        ok(&a, d)
    };
    let said = render("mixed.png", &["--stats-json", "m.json"]);
    assert!(said.contains("levels 0…1"), "{said}");
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("m.json")).unwrap()).unwrap();
    let per = &j["out_of_core"]["per_level"];
    assert!(
        per[0].as_u64().unwrap() > 0 && per[1].as_u64().unwrap() > 0,
        "{j}"
    );
    render("l0.png", &["--level", "0"]);
    render("l1.png", &["--level", "1"]);
    let mixed = psnr("l0.png", "mixed.png", d).unwrap();
    let coarse = psnr("l0.png", "l1.png", d).unwrap();
    // Measured: 45.9 dB against 29.3.
    assert!(mixed >= 40.0 && mixed > coarse + 5.0, "{mixed} {coarse}");
    // --lod-scale 2: the front a level coarser (level 1), and the saved
    // scene keeps it; 0 is refused.
    render(
        "coarser.png",
        &[
            "--lod-scale",
            "2",
            "--save-scene",
            "c.toml",
            "--stats-json",
            "c.json",
        ],
    );
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("c.json")).unwrap()).unwrap();
    assert_eq!(j["out_of_core"]["level"], 1, "{j}");
    let scene = voxcast::scene::Scene::load(&d.join("c.toml")).unwrap();
    assert_eq!(scene.input.options.lod_scale, Some(2.0));
    let o = voxcast(&["render", "--scene", "c.toml", "-o", "again.png", "-q"], d);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // (In core this time: level 1 fits; 92.5 dB, 8-bit roundings.)
    let db = psnr("coarser.png", "again.png", d).unwrap_or(f64::INFINITY);
    assert!(db >= 60.0, "the scene renders level 1 again: {db} dB");
    let o = voxcast(&["render", "d.zarr", "--lod-scale", "0", "-o", "x.png"], d);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("--lod-scale 0"), "{e}");
}
