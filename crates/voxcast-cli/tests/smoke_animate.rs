//! End to end: `voxcast simulate smoke` on a small scene file, then
//! `animate` (GIF, PNG folder, MP4 without ffmpeg) and `bench-frames` over
//! its frame folder.

use std::process::{Command, Output};

mod common;
use common::voxcast;

fn ok(o: &Output) {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn simulate_then_animate_and_bench_frames() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // The room preset written out, then shrunk to a tiny grid.
    ok(&voxcast(
        &[
            "simulate",
            "smoke",
            "--scene",
            "room",
            "--save-scene",
            "s.toml",
        ],
        d,
    ));
    let text = std::fs::read_to_string(d.join("s.toml")).unwrap();
    assert!(text.contains("[source]") && text.contains("[[obstacle]]"));
    ok(&voxcast(
        &[
            "simulate", "smoke", "--scene", "s.toml", "--grid", "16,16,12", "--frames", "4", "-o",
            "run", "-q",
        ],
        d,
    ));
    let run = d.join("run");
    for f in [
        "series.toml",
        "geometry.toml",
        "scene.toml",
        "simulation.json",
    ] {
        assert!(run.join(f).is_file(), "{f}");
    }
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("simulation.json")).unwrap())
            .unwrap();
    let last = &stats.as_array().unwrap()[3];
    let (m, i) = (
        last["mass"].as_f64().unwrap(),
        last["injected"].as_f64().unwrap(),
    );
    assert!(
        m > 0.0 && (m - i).abs() < 1e-3 * i,
        "closed room: mass {m} = injected {i}"
    );

    // GIF: one frame per selected frame.
    ok(&voxcast(
        &[
            "animate", "run", "-o", "a.gif", "--size", "48x32", "--tf", "smoke", "-q",
        ],
        d,
    ));
    let mut dec = gif::DecodeOptions::new();
    dec.set_color_output(gif::ColorOutput::RGBA);
    let mut r = dec
        .read_info(std::fs::File::open(d.join("a.gif")).unwrap())
        .unwrap();
    assert_eq!((r.width(), r.height()), (48, 32));
    let mut n = 0;
    while r.read_next_frame().unwrap().is_some() {
        n += 1;
    }
    assert_eq!(n, 4);

    // PNG folder with a selection and per-frame stats.
    ok(&voxcast(
        &[
            "animate",
            "run",
            "-o",
            "pngs/",
            "--size",
            "32x32",
            "--frames",
            "1..",
            "--every",
            "2",
            "--stats-json",
            "st.json",
            "-q",
        ],
        d,
    ));
    assert!(d.join("pngs/frame_00000.png").is_file() && d.join("pngs/frame_00001.png").is_file());
    assert!(!d.join("pngs/frame_00002.png").exists());
    let st: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("st.json")).unwrap()).unwrap();
    let frames: Vec<u64> = st
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["frame"].as_u64().unwrap())
        .collect();
    assert_eq!(frames, vec![1, 3]);

    // MP4 without ffmpeg on PATH: a clear error, nothing written.
    let o = Command::new(env!("CARGO_BIN_EXE_voxcast"))
        .args(["animate", "run", "-o", "a.mp4"])
        .current_dir(d)
        .env("PATH", "")
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("ffmpeg"));
    assert!(!d.join("a.mp4").exists());

    // Never into the input folder.
    let o = voxcast(&["animate", "run", "-o", "run/x.gif"], d);
    assert!(!o.status.success());

    // bench-frames: a row per frame, uniform's speed-up exactly 1.
    ok(&voxcast(
        &[
            "bench-frames",
            "run",
            "--size",
            "32x32",
            "--repeat",
            "1",
            "--every",
            "2",
            "--json",
            "bf.json",
            "--chart",
            "bf.png",
            "-q",
        ],
        d,
    ));
    let bf: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("bf.json")).unwrap()).unwrap();
    assert_eq!(bf["frames"].as_array().unwrap().len(), 2);
    assert_eq!(bf["summary"][0]["name"], "uniform");
    assert_eq!(bf["summary"][0]["mean_speedup"].as_f64().unwrap(), 1.0);
    assert_eq!(bf["methods"].as_array().unwrap().len(), 3);
    assert!(std::fs::read(d.join("bf.png"))
        .unwrap()
        .starts_with(b"\x89PNG"));
}
