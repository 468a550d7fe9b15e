//! `mpirun -np N voxcast render` (cargo feature `mpi`): the composited
//! picture against one process, on a real volume, in core and from a
//! chunked store, with the camera on either side of the cuts; and a
//! failure on one process ends all of them, never a hang.
#![cfg(feature = "mpi")]

mod common;
use common::{read_json, stderr, voxcast};
use std::path::Path;
use std::process::{Command, Output};

const TEAPOT: &str = "../../../shared/data/teapot_ct/slices";

/// `mpirun -np N voxcast ARGS` in `cwd`, killed after two minutes (a hang
/// fails the test instead of stalling it).
fn mpirun(n: usize, args: &[&str], cwd: &Path) -> Output {
    Command::new("timeout")
        .args([
            "120",
            "mpirun",
            "--allow-run-as-root",
            "--oversubscribe",
            "-np",
        ])
        .arg(n.to_string())
        .arg(env!("CARGO_BIN_EXE_voxcast"))
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("run mpirun (Debian: openmpi-bin)")
}

/// The PSNR of B against A; identical images count as infinite.
fn psnr(a: &str, b: &str, cwd: &Path) -> f64 {
    common::psnr(a, b, cwd).unwrap_or(f64::INFINITY)
}

fn teapot() -> Option<String> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join(TEAPOT);
    if p.is_dir() {
        Some(p.to_string_lossy().into_owned())
    } else {
        assert!(!common::in_ci(), "{} is missing", p.display());
        eprintln!("skipped: {} is missing", p.display());
        None
    }
}

/// The FDS room case (`None`, and skipped, where the data is missing
/// outside CI).
fn fds_room() -> Option<String> {
    let p =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/fds_room/room_smoke.smv");
    if p.is_file() {
        Some(p.to_string_lossy().into_owned())
    } else {
        assert!(!common::in_ci(), "{} is missing", p.display());
        eprintln!("skipped: {} is missing", p.display());
        None
    }
}

#[test]
fn three_processes_give_the_one_process_picture_from_either_side() {
    let Some(teapot) = teapot() else { return };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // In core (each process reads the slices) and from a chunked store
    // (each reads its part's chunks and the ghost layer), shaded or not,
    // from in front of and behind every cut.
    let o = voxcast(&["convert", &teapot, "-o", "t.zarr", "--chunk", "32"], d);
    assert!(o.status.success(), "{}", stderr(&o));
    for (input, az, el, shaded) in [
        (teapot.as_str(), "30", "20", false),
        (teapot.as_str(), "210", "-40", true),
        ("t.zarr", "120", "60", true),
        ("t.zarr", "300", "-15", false),
    ] {
        let mut args = vec![
            "render",
            input,
            "--size",
            "160x128",
            "--azimuth",
            az,
            "--elevation",
            el,
        ];
        if shaded {
            args.extend(["--shading", "on"]);
        }
        let mut one = args.clone();
        one.extend(["-o", "one.png", "--ert", "1", "--quiet"]);
        // A store is rendered by one process the way each part is: out
        // of core, its transfer function from the same stand-in level.
        if input.ends_with(".zarr") {
            one.push("--out-of-core");
        }
        let o = voxcast(&one, d);
        assert!(o.status.success(), "{}", stderr(&o));
        for n in [1, 3] {
            let mut many = args.clone();
            many.extend(["-o", "many.png", "--stats-json", "many.json"]);
            let o = mpirun(n, &many, d);
            let said = stderr(&o);
            assert!(o.status.success(), "{n} processes, {args:?}: {said}");
            assert!(said.contains("early ray termination is off"), "{said}");
            let db = psnr("one.png", "many.png", d);
            assert!(db >= 60.0, "{n} processes, {args:?}: {db:.1} dB");
            let j = read_json(&d.join("many.json"));
            assert_eq!(j["mpi"]["processes"], n);
            assert_eq!(j["mpi"]["per_process"].as_array().unwrap().len(), n);
            let bpp = j["mpi"]["bytes_per_pixel"].as_f64().unwrap();
            // Direct send among three: each sends at most 2/3 of its image
            // (16 bytes a pixel; less where a piece is transparent at its
            // ends) and its third to process 0.
            if n == 1 {
                assert_eq!(bpp, 0.0);
            } else {
                let most = 16.0 * (2.0 + 2.0 / 3.0);
                let least = 16.0 * 2.0 / 3.0;
                assert!(
                    bpp > least && bpp < most + 0.5,
                    "{n}: {bpp} bytes per pixel"
                );
            }
        }
    }
}

#[test]
fn a_failure_on_one_process_ends_all_of_them() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Only process 0 writes: its output folder is missing, while the
    // others render and wait for it.
    let o = mpirun(
        3,
        &[
            "render",
            "builtin:demo",
            "--size",
            "64x64",
            "-o",
            "no/such/folder/x.png",
        ],
        d,
    );
    let said = stderr(&o);
    assert_ne!(o.status.code(), Some(124), "mpirun hung: {said}");
    assert!(!o.status.success(), "{said}");
    assert!(
        said.contains("process 0 of 3") && said.contains("x.png"),
        "{said}"
    );
    assert!(!said.contains("panicked"), "{said}");
    // A method that needs the whole ray is refused by name.
    let o = mpirun(2, &["render", "--method", "adaptive", "-o", "a.png"], d);
    let said = stderr(&o);
    assert!(
        !o.status.success() && said.contains("method adaptive"),
        "{said}"
    );
    assert!(!d.join("a.png").exists());
}

#[test]
fn animate_spreads_the_frames_and_writes_the_one_process_frames() {
    let Some(smv) = fds_room() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let args = ["animate", &smv, "--size", "64x48", "--frames", "0..7"];
    let mut one = args.to_vec();
    one.extend(["-o", "one/", "-q"]);
    let o = voxcast(&one, d);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut many = args.to_vec();
    // Any method: each process renders whole frames.
    many.extend(["-o", "many/", "--stats-json", "s.json"]);
    let o = mpirun(3, &many, d);
    let said = stderr(&o);
    assert!(o.status.success(), "{said}");
    assert!(said.contains("frames spread over the processes"), "{said}");
    let j = read_json(&d.join("s.json"));
    let frames: Vec<u64> = j
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["frame"].as_u64().unwrap())
        .collect();
    assert_eq!(frames, (0..7).collect::<Vec<u64>>(), "in order");
    for k in 0..7 {
        let name = format!("frame_{k:05}.png");
        let (a, b) = (
            std::fs::read(d.join("one").join(&name)).unwrap(),
            std::fs::read(d.join("many").join(&name)).unwrap(),
        );
        assert!(a == b, "{name} differs");
    }
}

#[test]
fn animate_chooses_whole_or_split_frames_for_a_partial_last_round_and_both_match() {
    let Some(smv) = fds_room() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Without the room's obstructions a frame can be split; early ray
    // termination off, as a split frame has it, so that whole and split
    // frames both match the one-process frames.
    let args = [
        "animate",
        &smv,
        "--size",
        "64x48",
        "--frames",
        "0..7",
        "--geometry",
        "none",
        "--ert",
        "1",
    ];
    let mut one = args.to_vec();
    one.extend(["-o", "one/", "-q"]);
    let o = voxcast(&one, d);
    assert!(o.status.success(), "{}", stderr(&o));
    // 7 frames on 3 processes: 2 rounds of whole frames, then frame 6
    // whole or over all 3, as a pilot on it finds faster.
    let mut many = args.to_vec();
    many.extend(["-o", "many/"]);
    let o = mpirun(3, &many, d);
    let said = stderr(&o);
    assert!(o.status.success(), "{said}");
    assert!(
        said.contains("pilot on frame 6")
            && (said.contains("6 whole frames spread over the processes (2 rounds), then 1 frame split over 3 processes each")
                || said.contains("7 whole frames spread over the processes (3 rounds)")),
        "{said}"
    );
    // The last round split, forced: 2 rounds of 3 whole frames, then
    // frame 6 over all 3 processes.
    let mut split = args.to_vec();
    split.extend(["-o", "split/", "--mpi-frames", "split"]);
    let o = mpirun(3, &split, d);
    let said = stderr(&o);
    assert!(o.status.success(), "{said}");
    assert!(
        said.contains("6 whole frames spread over the processes (2 rounds), then 1 frame split over 3 processes each")
            && !said.contains("pilot"),
        "{said}"
    );
    // 6 frames on 4 processes: one round whole, then two groups of two at
    // once, one of them led by process 2, which sends its frame to 0.
    let mut groups = args.to_vec();
    groups[5] = "1..7";
    groups.extend(["-o", "groups/", "--mpi-frames", "split"]);
    let o = mpirun(4, &groups, d);
    let said = stderr(&o);
    assert!(o.status.success(), "{said}");
    assert!(
        said.contains("4 whole frames spread over the processes (1 round), then 2 frames split over 2 processes each"),
        "{said}"
    );
    for k in 0..6 {
        let (a, b) = (
            format!("one/frame_{:05}.png", k + 1),
            format!("groups/frame_{k:05}.png"),
        );
        let p = psnr(&a, &b, d);
        assert!(p >= 60.0, "{b}: {p:.1} dB against {a}");
    }
    for k in 0..7 {
        let name = format!("frame_{k:05}.png");
        for other in ["many", "split"] {
            let p = psnr(&format!("one/{name}"), &format!("{other}/{name}"), d);
            assert!(p >= 60.0, "{other}/{name}: {p:.1} dB against one process");
        }
    }
    // A method that needs the whole ray is never split, and asking for it
    // names the reason.
    let mut adaptive = args.to_vec();
    adaptive.extend(["-o", "a/", "--method", "adaptive", "--mpi-frames", "split"]);
    let o = mpirun(2, &adaptive, d);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("adaptive"), "{}", stderr(&o));
    // Outside mpirun the flag is refused.
    let mut alone = args.to_vec();
    alone.extend(["-o", "b/", "--mpi-frames", "spread"]);
    let o = voxcast(&alone, d);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("only under mpirun"), "{}", stderr(&o));
}

#[test]
fn bench_under_mpi_reports_each_process_and_skips_whole_ray_methods() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = mpirun(
        2,
        &[
            "bench",
            "builtin:demo",
            "--size",
            "64x48",
            "--methods",
            "uniform,adaptive,jitter",
            "--repeat",
            "2",
            "--warmup",
            "0",
            "--json",
            "b.json",
        ],
        d,
    );
    let said = stderr(&o);
    assert!(o.status.success(), "{said}");
    assert!(said.contains("skipped adaptive"), "{said}");
    let table = String::from_utf8_lossy(&o.stdout);
    assert!(
        table.contains("| uniform |") && table.contains("| jitter |"),
        "{table}"
    );
    let j = read_json(&d.join("b.json"));
    assert_eq!(j["processes"], 2);
    let methods = j["methods"].as_array().unwrap();
    assert_eq!(methods.len(), 2);
    for m in methods {
        assert_eq!(m["render_seconds_per_process"].as_array().unwrap().len(), 2);
        // At most half the image each, and the gather's half.
        let bpp = m["bytes_per_pixel"].as_f64().unwrap();
        assert!(bpp > 8.0 && bpp < 24.5, "{m}");
        // Null: identical to one process.
        let db = m["psnr_db_vs_one_process"]
            .as_f64()
            .unwrap_or(f64::INFINITY);
        assert!(db >= 60.0, "{m}");
    }
}

#[test]
fn show_parts_tints_each_process_and_needs_mpirun() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let args = [
        "render",
        "builtin:demo",
        "--size",
        "64x64",
        "--ert",
        "1",
        "-q",
    ];
    let mut plain = args.to_vec();
    plain.extend(["-o", "plain.png"]);
    let o = mpirun(2, &plain, d);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut tinted = args.to_vec();
    tinted.extend(["-o", "tinted.png", "--show-parts"]);
    let o = mpirun(2, &tinted, d);
    assert!(o.status.success(), "{}", stderr(&o));
    let db = psnr("plain.png", "tinted.png", d);
    assert!(db < 30.0, "the tint shows: {db:.1} dB");
    // Without mpirun there are no parts to show.
    let o = voxcast(&["render", "--show-parts", "-o", "x.png"], d);
    assert!(!o.status.success() && stderr(&o).contains("--show-parts"));
    assert!(!d.join("x.png").exists());
}
