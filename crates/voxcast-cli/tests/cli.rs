//! End-to-end tests of the `voxcast` binary: exit codes, files written (and
//! not written), JSON keys, reproducibility through saved scenes.

use std::path::{Path, PathBuf};

mod common;
use common::{stderr, voxcast};

fn data(rel: &str) -> Option<String> {
    voxcast::testdata::data_path(rel).map(|p| p.to_string_lossy().into_owned())
}

#[test]
fn render_without_input_renders_the_demo() {
    let dir = tempfile::tempdir().unwrap();
    let o = voxcast(
        &["render", "--size", "96x64", "--stats-json", "s.json"],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let img = voxcast::Image::read(&dir.path().join("render.png")).unwrap();
    assert_eq!((img.width, img.height), (96, 64));
    assert!(img.pixels.iter().any(|p| p[0] > 0.2), "the demo is black");
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("s.json")).unwrap()).unwrap();
    for key in ["rays", "samples", "interpolations", "seconds"] {
        assert!(stats.get(key).is_some(), "stats lack `{key}`: {stats}");
    }
    assert_eq!(stats["rays"], 96 * 64);
    assert!(stats["samples"].as_u64().unwrap() > 10_000);
}

#[test]
fn saved_scene_reproduces_the_image_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let args = [
        "render",
        "builtin:sphere",
        "-o",
        "a.png",
        "--size",
        "64x48",
        "--azimuth",
        "40",
        "--elevation",
        "-15",
        "--tf",
        "fire",
        "--step",
        "0.7",
        "--background",
        "#203040",
        "--save-scene",
        "scene.toml",
    ];
    let o = voxcast(&args, dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    let o = voxcast(
        &["render", "--scene", "scene.toml", "-o", "b.png"],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let a = std::fs::read(dir.path().join("a.png")).unwrap();
    let b = std::fs::read(dir.path().join("b.png")).unwrap();
    assert_eq!(a, b);
    let o = voxcast(&["compare", "a.png", "b.png", "--json"], dir.path());
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["identical"], true);
    assert!(j.get("psnr_db").is_some() && (j["ssim"].as_f64().unwrap() - 1.0).abs() < 1e-9);
}

#[test]
fn compare_reports_psnr_and_ssim() {
    let dir = tempfile::tempdir().unwrap();
    for (name, az) in [("a.png", "0"), ("b.png", "5")] {
        let o = voxcast(
            &[
                "render",
                "builtin:demo",
                "-o",
                name,
                "--size",
                "64x64",
                "--azimuth",
                az,
            ],
            dir.path(),
        );
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let o = voxcast(&["compare", "a.png", "b.png", "--json"], dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let psnr = j["psnr_db"].as_f64().unwrap();
    let ssim = j["ssim"].as_f64().unwrap();
    assert!(psnr > 10.0 && psnr < 60.0, "{psnr}");
    assert!(ssim > 0.3 && ssim < 1.0, "{ssim}");
}

#[test]
fn bad_input_fails_cleanly_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("tiny.raw"), [0u8; 1024]).unwrap();
    std::fs::write(d.join("junk.xyz"), b"hello").unwrap();
    std::fs::write(d.join("bad.toml"), "[render]\nwidth = -3\n").unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec![
                "render",
                "tiny.raw",
                "--raw-dims",
                "1000,1000,1000",
                "--raw-type",
                "u8",
                "-o",
                "o.png",
            ],
            "tiny.raw",
        ),
        (vec!["render", "tiny.raw", "-o", "o.png"], "--raw-dims"),
        (
            vec!["render", "missing.nrrd", "-o", "o.png"],
            "missing.nrrd",
        ),
        (vec!["render", "junk.xyz", "-o", "o.png"], "junk.xyz"),
        (vec!["render", "builtin:nope", "-o", "o.png"], "nope"),
        (
            vec![
                "render",
                "builtin:demo",
                "--tf",
                "no-such-tf",
                "-o",
                "o.png",
            ],
            "no-such-tf",
        ),
        (
            vec!["render", "builtin:demo", "--step", "0", "-o", "o.png"],
            "step",
        ),
        (
            vec!["render", "builtin:demo", "--size", "12", "-o", "o.png"],
            "--size",
        ),
        (vec!["render", "builtin:demo", "-o", "o.jpg"], "o.jpg"),
        (
            vec!["render", "--scene", "bad.toml", "-o", "o.png"],
            "bad.toml",
        ),
        (
            vec![
                "render",
                "tiny.raw",
                "--raw-dims",
                "4,4,4",
                "--raw-type",
                "u8",
                "-o",
                "tiny.raw",
            ],
            "tiny.raw",
        ),
        (
            vec![
                "info",
                "tiny.raw",
                "--raw-dims",
                "0,4,4",
                "--raw-type",
                "u8",
            ],
            "at least 1",
        ),
        (vec!["compare", "nothere.png", "tiny.raw"], "nothere.png"),
    ];
    for (args, needle) in cases {
        let o = voxcast(&args, d);
        let err = stderr(&o);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: `{needle}` not in: {err}");
        assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    }
    // A slice stack's folder or glob is an input too.
    std::fs::create_dir(d.join("stack")).unwrap();
    let o = voxcast(&["render", "builtin:sphere", "-o", "stack/s.png"], d);
    assert!(o.status.success(), "{}", stderr(&o));
    for (input, out) in [("stack", "stack/new.png"), ("stack/*.png", "stack/z.png")] {
        let o = voxcast(&["render", input, "-o", out], d);
        assert_eq!(o.status.code(), Some(1), "{input} → {out}");
        assert!(stderr(&o).contains("refusing"), "{}", stderr(&o));
    }
    std::fs::remove_dir_all(d.join("stack")).unwrap();
    // Nothing was written, the input is untouched, no temporary files remain.
    let mut names: Vec<String> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["bad.toml", "junk.xyz", "tiny.raw"]);
    assert_eq!(std::fs::read(d.join("tiny.raw")).unwrap(), vec![0u8; 1024]);
}

#[test]
fn info_json_on_a_real_volume() {
    let Some(p) = data("neghip/neghip.nhdr") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let o = voxcast(&["info", &p, "--json"], dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["dims"], serde_json::json!([64, 64, 64]));
    assert_eq!(j["scalar_type"], "u8");
    assert_eq!(j["nan"], 0);
    let counts = j["histogram"]["counts"].as_array().unwrap();
    let total: u64 = counts.iter().map(|c| c.as_u64().unwrap()).sum();
    assert_eq!(total, 64 * 64 * 64);
    let o = voxcast(&["info", &p], dir.path());
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("64 × 64 × 64") && text.contains("percentiles"),
        "{text}"
    );
}

/// Every real volume of a supported format loads and renders to a picture
/// with something in it.
#[test]
fn renders_every_shared_volume() {
    let inputs = [
        "neghip/neghip.nhdr",
        "ct_head_headsq/headsq.nhdr",
        "mr_head/HeadMRVolume.mhd",
        "iron_protein/ironProt.vtk",
        "carotid_mra/carotid.vtk",
        "teapot_ct/slices",
        "dicom_ct_lung",
        "dicom_mri_brain",
        "smoke_vdb/smoke.vdb",
        "cloud_vdb/cloud.vdb",
        "fds_room/room_smoke.smv",
    ];
    let dir = tempfile::tempdir().unwrap();
    for rel in inputs {
        let Some(p) = data(rel) else { continue };
        let out: PathBuf = dir.path().join("o.png");
        let o = voxcast(
            &["render", &p, "-o", "o.png", "--size", "64x64", "-q"],
            dir.path(),
        );
        assert!(o.status.success(), "{rel}: {}", stderr(&o));
        let img = voxcast::Image::read(&out).unwrap();
        let lit = img.pixels.iter().filter(|p| p[3] > 0.05).count();
        assert!(lit > 64 * 64 / 50, "{rel}: only {lit} pixels show anything");
    }
}

/// `render` takes every method spec (`NAME[+grouped]`) and the scene flags it
/// shares with `bench` (`--skip-empty`, `--jitter`); a saved scene keeps them.
#[test]
fn render_takes_method_specs_and_the_shared_scene_flags() {
    let dir = tempfile::tempdir().unwrap();
    let o = voxcast(
        &[
            "render",
            "builtin:sphere",
            "-o",
            "m.png",
            "--size",
            "32x32",
            "--method",
            "adaptive+grouped",
            "--skip-empty",
            "off",
            "--jitter",
            "on",
            "--save-scene",
            "m.toml",
            "-q",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let scene = voxcast::Scene::load(&dir.path().join("m.toml")).unwrap();
    assert_eq!(scene.render.method, voxcast::render::Method::Adaptive);
    assert!(scene.render.grouped && scene.render.jitter && !scene.render.skip_empty);
    let o = voxcast(
        &[
            "render",
            "builtin:sphere",
            "--method",
            "warp",
            "-o",
            "w.png",
        ],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(1));
    let err = stderr(&o);
    assert!(err.contains("warp") && err.contains("threshold"), "{err}");
    assert!(!dir.path().join("w.png").exists());
}

#[test]
fn info_on_a_dicom_folder_with_strays_lists_series_and_skipped_files() {
    let Some(ct) = data("dicom_ct_lung") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for n in ["1-01.dcm", "1-02.dcm", "1-03.dcm"] {
        std::fs::copy(Path::new(&ct).join(n), d.join(n)).unwrap();
    }
    // A truncated slice and a compressed slice of another series.
    let b = std::fs::read(Path::new(&ct).join("1-04.dcm")).unwrap();
    std::fs::write(d.join("bad.dcm"), &b[..674]).unwrap();
    let rle =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../voxcast/tests/data/dicom_ts/mr_rle.dcm");
    std::fs::copy(rle, d.join("mr_rle.dcm")).unwrap();
    let o = voxcast(&["info", "."], d);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("512 × 512 × 3"), "{out}");
    assert!(
        out.contains("DICOM series")
            && out.contains("3 frame(s) in 3 file(s), Explicit VR Little Endian")
            && out.contains("RLE Lossless (1.2.840.10008.1.2.5)")
            && out.contains("skipped bad.dcm"),
        "{out}"
    );
    assert!(
        stderr(&o).contains("skipped 1 file(s): bad.dcm"),
        "{}",
        stderr(&o)
    );
    // --var 1 reads the RLE series.
    let o = voxcast(&["info", ".", "--var", "1", "--json"], d);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["dims"], serde_json::json!([48, 48, 1]));
    assert!(j["dicom"][1].as_str().unwrap().ends_with("(read)"), "{j}");
}

#[test]
fn info_warns_about_raw_nrrd_bytes_past_the_sizes_and_shows_new_format_headers() {
    let dir = tempfile::tempdir().unwrap();
    // 2×2×2 uint8 plus 5 stray bytes: read, with one warning naming them.
    let mut b = b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n".to_vec();
    b.extend_from_slice(&[1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 9, 9]);
    std::fs::write(dir.path().join("t.nrrd"), &b).unwrap();
    let out = voxcast(&["info", "t.nrrd"], dir.path());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("warning") && err.contains("t.nrrd") && err.contains("5 byte(s) after"),
        "{err}"
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("range       1 … 8"));
    // The added formats, end to end: `info` prints their header facts.
    let formats = Path::new(env!("CARGO_MANIFEST_DIR")).join("../voxcast/tests/data/formats");
    for (name, says) in [
        ("nifti2_le.nii", "NIfTI-2 (single file), little-endian"),
        (
            "analyze_le.img",
            "Analyze 7.5 (header + image file analyze_le.img)",
        ),
        ("brain.mgz", "FreeSurfer MGZ (gzip)"),
    ] {
        let out = voxcast(&["info", formats.join(name).to_str().unwrap()], dir.path());
        let s = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success() && s.contains(says), "{name}: {s}");
    }
}
