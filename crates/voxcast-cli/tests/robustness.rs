//! The `voxcast` binary under hostile input (issue 20): no input is ever
//! written over, a failed command writes none of its outputs, values are
//! checked the same way from flags and from files, and messages that quote
//! a file cannot drive the terminal.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

mod common;
use common::{stderr, voxcast};

/// The files of `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// A detached NRRD: `v.nhdr` pointing at `v_data.raw` (8³ u8).
fn detached(dir: &Path) -> Vec<u8> {
    let data: Vec<u8> = (0..512u32).map(|i| (i * 7 % 256) as u8).collect();
    std::fs::write(dir.join("v_data.raw"), &data).unwrap();
    std::fs::write(
        dir.join("v.nhdr"),
        "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 8 8 8\nencoding: raw\ndata file: v_data.raw\n",
    )
    .unwrap();
    data
}

#[test]
fn no_output_flag_can_write_over_an_input_file() {
    let dir = tempfile::tempdir().unwrap();
    let data = detached(dir.path());
    let header = std::fs::read(dir.path().join("v.nhdr")).unwrap();
    for (flag, target) in [
        ("--stats-json", "v_data.raw"),
        ("--stats-json", "v.nhdr"),
        ("--save-scene", "v.nhdr"),
        ("--float-out", "v_data.raw"),
        ("-o", "v.nhdr"),
    ] {
        let mut args = vec!["render", "v.nhdr", "--size", "16x16", flag, target];
        if flag != "-o" {
            args.extend(["-o", "out.png"]);
        }
        let o = voxcast(&args, dir.path());
        assert!(!o.status.success(), "{flag} {target}: exit 0");
        let e = stderr(&o);
        assert!(e.contains(flag) && e.contains(target), "{flag}: {e}");
        assert_eq!(std::fs::read(dir.path().join("v_data.raw")).unwrap(), data);
        assert_eq!(std::fs::read(dir.path().join("v.nhdr")).unwrap(), header);
        assert_eq!(
            names(dir.path()),
            ["v.nhdr", "v_data.raw"],
            "{flag} {target}"
        );
    }
    // Scene and transfer-function files read by the command are inputs too.
    let o = voxcast(
        &[
            "render",
            "v.nhdr",
            "--size",
            "16x16",
            "--save-scene",
            "s.toml",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let scene = std::fs::read(dir.path().join("s.toml")).unwrap();
    let o = voxcast(
        &[
            "render",
            "--scene",
            "s.toml",
            "-o",
            "b.png",
            "--stats-json",
            "s.toml",
        ],
        dir.path(),
    );
    assert!(
        !o.status.success() && stderr(&o).contains("reads as input"),
        "{}",
        stderr(&o)
    );
    assert_eq!(std::fs::read(dir.path().join("s.toml")).unwrap(), scene);
}

#[test]
fn a_failing_output_means_no_output_at_all() {
    let dir = tempfile::tempdir().unwrap();
    detached(dir.path());
    for extra in [
        ["--stats-json", "missing/s.json"],
        ["--save-scene", "missing/s.toml"],
        ["--float-out", "missing/f.exr"],
    ] {
        let mut args = vec!["render", "v.nhdr", "-o", "out.png", "--size", "16x16"];
        args.extend(extra);
        let o = voxcast(&args, dir.path());
        assert!(!o.status.success());
        assert!(stderr(&o).contains("does not exist"), "{}", stderr(&o));
        assert_eq!(names(dir.path()), ["v.nhdr", "v_data.raw"], "{extra:?}");
    }
    // One file named by two outputs.
    let o = voxcast(
        &["render", "v.nhdr", "-o", "x.exr", "--float-out", "x.exr"],
        dir.path(),
    );
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("-o writes that file already"),
        "{}",
        stderr(&o)
    );
    assert_eq!(names(dir.path()), ["v.nhdr", "v_data.raw"]);
}

#[test]
fn flags_and_scene_files_are_held_to_the_same_rules() {
    let dir = tempfile::tempdir().unwrap();
    detached(dir.path());
    let render = |extra: &[&str]| {
        let mut args = vec!["render", "v.nhdr", "-o", "out.png", "--size", "16x16"];
        args.extend(extra);
        voxcast(&args, dir.path())
    };
    for (flag, value, says) in [
        ("--azimuth", "nan", "--azimuth"),
        ("--elevation", "NaN", "--elevation"),
        ("--fov", "0", "--fov"),
        ("--fov", "180", "--fov"),
        ("--zoom", "0", "--zoom"),
        ("--window", "5,5", "--window"),
    ] {
        let o = render(&[flag, value]);
        assert!(!o.status.success(), "{flag} {value}: exit 0");
        assert!(stderr(&o).contains(says), "{flag} {value}: {}", stderr(&o));
    }
    for (table, value, field) in [
        ("camera", "fov = 0.0", "camera.fov"),
        ("camera", "fov = 180.0", "camera.fov"),
        ("camera", "fov = nan", "camera.fov"),
        ("camera", "zoom = 0.0", "camera.zoom"),
        ("camera", "zoom = nan", "camera.zoom"),
        ("camera", "azimuth = nan", "camera.azimuth"),
        ("transfer", "window = [5.0, 5.0]", "transfer.window"),
        ("render", "step = 0.0", "render"),
    ] {
        std::fs::write(dir.path().join("s.toml"), format!("[{table}]\n{value}\n")).unwrap();
        let o = render(&["--scene", "s.toml"]);
        assert!(!o.status.success(), "{value}: exit 0");
        let e = stderr(&o);
        assert!(e.contains("s.toml") && e.contains(field), "{value}: {e}");
    }
    assert_eq!(names(dir.path()), ["s.toml", "v.nhdr", "v_data.raw"]);
}

#[test]
fn unknown_keys_are_refused_with_the_nearest_known_one() {
    let dir = tempfile::tempdir().unwrap();
    detached(dir.path());
    for (file, text, hint) in [
        ("s.toml", "[camera]\nazimth = 30.0\n", "`azimuth`"),
        ("s.toml", "[render]\nstpe = 0.5\n", "`step`"),
        (
            "s.toml",
            "[input]\npath = \"v.nhdr\"\nspacin = [1, 1, 1]\n",
            "`spacing`",
        ),
        ("s.toml", "[redner]\nstep = 0.5\n", "`render`"),
    ] {
        std::fs::write(dir.path().join(file), text).unwrap();
        let o = voxcast(
            &["render", "v.nhdr", "--scene", file, "-o", "o.png"],
            dir.path(),
        );
        assert!(!o.status.success(), "{text}: exit 0");
        let e = stderr(&o);
        assert!(
            e.contains("did you mean") && e.contains(hint),
            "{text}: {e}"
        );
    }
    std::fs::write(
        dir.path().join("tf.toml"),
        "color = [[0.0, 0, 0, 0], [1.0, 1, 1, 1]]\nopacity = [[0.0, 0.0], [1.0, 0.5]]\nwindw = [0.0, 1.0]\n",
    )
    .unwrap();
    let o = voxcast(
        &["render", "v.nhdr", "--tf", "tf.toml", "-o", "o.png"],
        dir.path(),
    );
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(e.contains("tf.toml") && e.contains("`window`"), "{e}");
}

#[test]
fn devices_as_inputs_are_refused_not_read_forever() {
    let dir = tempfile::tempdir().unwrap();
    detached(dir.path());
    std::fs::write(
        dir.path().join("g.toml"),
        "[[mesh]]\npath = \"/dev/zero\"\n",
    )
    .unwrap();
    for args in [
        vec!["render", "v.nhdr", "--geometry", "g.toml", "-o", "o.png"],
        vec!["render", "v.nhdr", "--tf", "/dev/zero", "-o", "o.png"],
        vec!["info", "/dev/zero"],
        vec!["render", "--scene", "/dev/zero", "-o", "o.png"],
    ] {
        let t = Instant::now();
        let o = voxcast(&args, dir.path());
        assert!(!o.status.success(), "{args:?}");
        assert!(stderr(&o).contains("/dev/zero"), "{args:?}: {}", stderr(&o));
        assert_eq!(o.status.code(), Some(1), "{args:?}: killed by a signal?");
        assert!(t.elapsed() < Duration::from_secs(20), "{args:?}");
    }
}

#[test]
fn absurd_extinction_is_an_error_not_a_hang() {
    let dir = tempfile::tempdir().unwrap();
    for method in ["path", "single-scatter"] {
        let t = Instant::now();
        let o = voxcast(
            &[
                "render",
                "--method",
                method,
                "--extinction",
                "1e30",
                "--size",
                "64x64",
                "-o",
                "p.png",
            ],
            dir.path(),
        );
        assert!(!o.status.success(), "{method}");
        let e = stderr(&o);
        assert!(
            e.contains("medium.scale") && e.contains("optical depth"),
            "{e}"
        );
        assert!(
            t.elapsed() < Duration::from_secs(20),
            "{method}: {:?}",
            t.elapsed()
        );
    }
    assert!(names(dir.path()).is_empty());
}

#[test]
fn messages_quoting_a_file_are_escaped_and_cut() {
    let dir = tempfile::tempdir().unwrap();
    let mut header = b"NRRD0004\ntype: \x1b]0;owned\x07\x1b[2J".to_vec();
    header.extend(std::iter::repeat_n(b'A', 5000));
    header.extend(b"\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n");
    header.extend([0u8; 8]);
    std::fs::write(dir.path().join("evil.nrrd"), &header).unwrap();
    let o = voxcast(&["info", "evil.nrrd"], dir.path());
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        !e.chars().any(|c| c.is_control() && c != '\n'),
        "control characters reach the terminal: {e:?}"
    );
    assert!(e.contains("\\x1b"), "{e}");
    assert!(e.len() < 1500, "{} bytes of message", e.len());
    // An OS error is said once.
    let o = voxcast(&["info", "no-such-file.nrrd"], dir.path());
    let e = stderr(&o);
    assert_eq!(e.matches("os error 2").count(), 1, "{e}");
}

#[test]
fn an_interrupted_render_leaves_no_output_and_no_temporary_file() {
    let dir = tempfile::tempdir().unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_voxcast"))
        .args([
            "render",
            "--method",
            "path",
            "--spp",
            "64",
            "--size",
            "2048x2048",
            "-o",
            "out.png",
            "--stats-json",
            "s.json",
            "--save-scene",
            "s.toml",
            "-q",
        ])
        .current_dir(dir.path())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    assert!(
        child.try_wait().unwrap().is_none(),
        "the render ended before it could be interrupted"
    );
    let killed = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    // A shell that starts jobs in the background without job control
    // ignores SIGINT for them, and an ignored signal stays ignored across
    // exec: then the render would run on for many minutes. Fail instead.
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if start.elapsed() > Duration::from_secs(30) {
            child.kill().unwrap();
            child.wait().unwrap();
            panic!("SIGINT did not stop the render: is SIGINT ignored by the shell that runs the tests?");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(!status.success());
    assert!(names(dir.path()).is_empty(), "{:?}", names(dir.path()));
}

/// A command that only prints ends quietly when its reader goes away
/// (`voxcast info scan.nhdr | head -1`): the closed pipe is not a panic.
#[test]
fn printing_into_a_closed_pipe_is_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    detached(dir.path());
    let nhdr = dir.path().join("v.nhdr");
    let info = ["info", nhdr.to_str().unwrap()];
    for args in [&info[..], &["presets"]] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_voxcast"))
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // The reader is gone before the command prints.
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}
