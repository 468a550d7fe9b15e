//! `voxcast view` end to end in a virtual display (Xvfb) with software
//! Vulkan (lavapipe): the screenshot of the window (the view's pixels as
//! the user sees them) must match `voxcast render` of the scene the viewer
//! saved. Each viewer gets an X server of its own (`Xvfb -displayfd`).
//! Without Xvfb the tests skip with a note — except under CI
//! (`CI=true`), where a missing display server or Vulkan driver fails them.

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

mod common;
use common::{in_ci as ci, voxcast};

/// True when `Xvfb` can be found; otherwise skips (fails under CI).
fn have_xvfb() -> bool {
    let found = Command::new("sh")
        .args(["-c", "command -v Xvfb"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !found {
        if ci() {
            panic!("Xvfb is missing (apt-get install xvfb xauth mesa-vulkan-drivers)");
        }
        eprintln!("skipping: Xvfb not found (apt-get install xvfb xauth mesa-vulkan-drivers)");
    }
    found
}

/// Runs `cmd` with a time limit; kills it past the limit.
fn run_with_limit(mut cmd: Command, limit: Duration) -> Output {
    let mut child = cmd
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start the command");
    let start = Instant::now();
    loop {
        if child.try_wait().expect("wait").is_some() {
            return child.wait_with_output().expect("output");
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let o = child.wait_with_output().expect("output");
            panic!(
                "timed out after {limit:?}: {}",
                String::from_utf8_lossy(&o.stderr)
            );
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// A virtual X server of its own, stopped on drop. `Xvfb -displayfd` picks
/// a free display number itself and writes it only once it accepts
/// connections, so a viewer started then always finds its server.
/// (`xvfb-run -a` guesses a free number from lock files and waits on a
/// signal; twice, once in the project's CI, a viewer it started found no X
/// server.)
struct VirtualDisplay {
    server: std::process::Child,
    /// `:N`, for `DISPLAY`.
    display: String,
}

impl VirtualDisplay {
    fn start(dir: &Path) -> VirtualDisplay {
        use std::io::BufRead;
        let log = std::fs::File::create(dir.join("xvfb.log")).unwrap();
        let mut server = Command::new("Xvfb")
            .args(["-displayfd", "1", "-screen", "0", "1600x1200x24"])
            .args(["-nolisten", "tcp"])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(log)
            .spawn()
            .expect("start Xvfb");
        let out = server.stdout.take().unwrap();
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut line = String::new();
            let _ = std::io::BufReader::new(out).read_line(&mut line);
            let _ = tx.send(line);
        });
        let line = rx.recv_timeout(Duration::from_secs(60)).unwrap_or_default();
        let number = line.trim();
        if number.is_empty() || !number.bytes().all(|b| b.is_ascii_digit()) {
            let _ = server.kill();
            let _ = server.wait();
            panic!(
                "Xvfb did not say its display within 60 s ({line:?}): {}",
                std::fs::read_to_string(dir.join("xvfb.log")).unwrap_or_default()
            );
        }
        VirtualDisplay {
            server,
            display: format!(":{number}"),
        }
    }
}

impl Drop for VirtualDisplay {
    /// SIGTERM first, so that the server removes its lock file and socket;
    /// SIGKILL if it has not gone within 10 s.
    fn drop(&mut self) {
        let _ = Command::new("kill")
            .args(["-TERM", &self.server.id().to_string()])
            .status();
        let start = Instant::now();
        while start.elapsed() < Duration::from_secs(10) {
            if let Ok(Some(_)) = self.server.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.server.kill();
        let _ = self.server.wait();
    }
}

/// `voxcast view ARGS` in `dir` on a virtual display of its own, on Vulkan
/// only.
fn view(args: &[&str], dir: &Path) -> Output {
    let runtime = dir.join("xdg");
    std::fs::create_dir_all(&runtime).unwrap();
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&runtime, std::fs::Permissions::from_mode(0o700)).unwrap();
    }
    let screen = VirtualDisplay::start(dir);
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_voxcast"));
    cmd.arg("view")
        .args(args)
        .current_dir(dir)
        .env("DISPLAY", &screen.display)
        .env_remove("WAYLAND_DISPLAY")
        .env_remove("XAUTHORITY")
        // A missing Vulkan driver must fail, not fall back to OpenGL.
        .env("WGPU_BACKEND", "vulkan")
        .env("XDG_RUNTIME_DIR", &runtime);
    run_with_limit(cmd, Duration::from_secs(400))
}

/// The screenshot against `voxcast render --scene` of the saved scene.
fn check_matches_render(dir: &Path) -> f64 {
    check_matches_render_with(dir, &[])
}

/// As [`check_matches_render`], with more flags for `voxcast render`.
fn check_matches_render_with(dir: &Path, more: &[&str]) -> f64 {
    let mut args = vec!["render", "--scene", "s.toml", "-o", "render.png", "-q"];
    args.extend_from_slice(more);
    let o = voxcast(&args, dir);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let shot = voxcast::Image::read(&dir.join("out.png")).unwrap();
    let render = voxcast::Image::read(&dir.join("render.png")).unwrap();
    assert_eq!(
        (shot.width, shot.height),
        (render.width, render.height),
        "the saved scene has the view's size"
    );
    // Not an empty picture: the volume covers a good part of the view.
    let lit = shot
        .pixels
        .iter()
        .filter(|p| p[0] + p[1] + p[2] > 0.05)
        .count();
    assert!(
        lit > shot.pixels.len() / 50,
        "the screenshot is nearly empty ({lit} lit pixels)"
    );
    voxcast::metrics::psnr(&shot, &render).unwrap()
}

/// `voxcast view DATA ARGS --screenshot out.png --exit-after-frames FRAMES
/// --save-scene s.toml` in a new temporary folder; `None` (a skip) where the
/// data or Xvfb is missing.
fn scripted_view(data: &str, args: &[&str], frames: &str) -> Option<(tempfile::TempDir, Output)> {
    let data = voxcast::testdata::data_path(data)?;
    if !have_xvfb() {
        return None;
    }
    let dir = tempfile::tempdir().unwrap();
    let data = data.to_string_lossy().into_owned();
    let mut all = vec![data.as_str()];
    all.extend_from_slice(args);
    all.extend_from_slice(&[
        "--screenshot",
        "out.png",
        "--exit-after-frames",
        frames,
        "--save-scene",
        "s.toml",
    ]);
    let o = view(&all, dir.path());
    Some((dir, o))
}

fn assert_ran(o: &Output) {
    assert!(
        o.status.success(),
        "voxcast view failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// The screenshot matches `voxcast render` of the saved scene at ≥ 35 dB.
fn assert_matches_render(dir: &Path, what: &str) {
    let psnr = check_matches_render(dir);
    eprintln!("{what}: PSNR {psnr:.2} dB");
    assert!(psnr >= 35.0, "PSNR {psnr:.2} dB < 35 dB");
}

#[test]
fn screenshot_matches_render_of_the_saved_scene() {
    let args = ["--size", "400x300", "--azimuth", "35", "--elevation", "25"];
    let Some((dir, o)) = scripted_view("teapot_ct/slices", &args, "30") else {
        return;
    };
    assert_ran(&o);
    let scene = voxcast::scene::Scene::load(&dir.path().join("s.toml")).unwrap();
    assert_eq!((scene.render.width, scene.render.height), (400, 300));
    assert_eq!((scene.camera.azimuth, scene.camera.elevation), (35.0, 25.0));
    assert!(
        scene.transfer.map.is_some(),
        "the edited map is written inline"
    );
    assert_matches_render(dir.path(), "view vs render");
}

/// The GPU back end (lavapipe here) draws the view, and the screenshot still
/// matches the CPU's `voxcast render` of the saved scene.
#[test]
fn gpu_backend_screenshot_matches_the_cpu_render() {
    let args = [
        "--device",
        "gpu",
        "--size",
        "200x150",
        "--azimuth",
        "20",
        "--elevation",
        "-30",
        "--stats-json",
        "st.json",
    ];
    let Some((dir, o)) = scripted_view("teapot_ct/slices", &args, "10") else {
        return;
    };
    let stderr = String::from_utf8_lossy(&o.stderr);
    if !o.status.success() && stderr.contains("no GPU adapter") && !ci() {
        eprintln!("skipping: no GPU adapter ({stderr})");
        return;
    }
    assert_ran(&o);
    assert!(
        stderr.contains("rendering on"),
        "names the adapter: {stderr}"
    );
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("st.json")).unwrap())
            .unwrap();
    assert_eq!(stats["backend"], "GPU", "{stats}");
    assert_matches_render(dir.path(), "GPU view vs CPU render");
}

#[test]
fn series_frame_and_time_are_saved_and_reproduced() {
    let args = [
        "--time",
        "30",
        "--size",
        "320x240",
        "--azimuth",
        "-30",
        "--elevation",
        "30",
    ];
    let Some((dir, o)) = scripted_view("fds_room/room_smoke.smv", &args, "5") else {
        return;
    };
    assert_ran(&o);
    let scene = voxcast::scene::Scene::load(&dir.path().join("s.toml")).unwrap();
    let t = scene.input.options.time.expect("the frame's time is saved");
    assert!((t - 30.0).abs() < 0.5, "time {t}");
    assert_matches_render(dir.path(), "series view vs render");
}

/// `builtin:demo` (128³) converted to `demo.zarr` in `dir` in chunks of
/// `chunk`; its path.
fn demo_store(dir: &Path, chunk: &str) -> String {
    let store = dir.join("demo.zarr");
    let store = store.to_str().unwrap().to_string();
    let o = voxcast(
        &["convert", "builtin:demo", "-o", &store, "--chunk", chunk],
        dir,
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    store
}

/// The levels a scripted view's `--stats-json st.json` says it showed.
fn shown_levels(dir: &Path) -> Vec<u64> {
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("st.json")).unwrap()).unwrap();
    stats["levels"]
        .as_array()
        .unwrap_or_else(|| panic!("no levels: {stats}"))
        .iter()
        .map(|l| l.as_u64().unwrap())
        .collect()
}

/// An OME-Zarr store opens at once at its coarsest level and refines, level
/// by level as they are read, down to level 0 (the images painted say which
/// level each showed); the scripted run waits for level 0, and the saved
/// scene renders the same picture.
#[test]
fn a_store_opens_at_the_coarsest_level_and_refines_to_level_0() {
    if !have_xvfb() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let store = demo_store(dir.path(), "32");
    let store = store.as_str();
    let args = [
        store,
        "--size",
        "240x180",
        "--azimuth",
        "30",
        "--screenshot",
        "out.png",
        "--exit-after-frames",
        "5",
        "--save-scene",
        "s.toml",
        "--stats-json",
        "st.json",
    ];
    let o = view(&args, dir.path());
    assert_ran(&o);
    let levels = shown_levels(dir.path());
    // Levels 128³, 64³, 32³: the first image is of level 2, the last of 0,
    // finer and finer in between.
    assert_eq!(levels.first(), Some(&2), "{levels:?}");
    assert_eq!(levels.last(), Some(&0), "{levels:?}");
    assert!(levels.windows(2).all(|w| w[0] > w[1]), "{levels:?}");
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("levels shown: 2"), "{e}");
    let scene = voxcast::scene::Scene::load(&dir.path().join("s.toml")).unwrap();
    assert_eq!(scene.input.options.level, None, "level 0: no --level");
    assert_matches_render(dir.path(), "store view vs render");
    // --level N: that level only, no refinement.
    let mut one = args.to_vec();
    one.extend_from_slice(&["--level", "1"]);
    let o = view(&one, dir.path());
    assert_ran(&o);
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("st.json")).unwrap())
            .unwrap();
    assert_eq!(stats["levels"], serde_json::json!([]), "{stats}");
    let scene = voxcast::scene::Scene::load(&dir.path().join("s.toml")).unwrap();
    assert_eq!(scene.input.options.level, Some(1));
    assert_matches_render(dir.path(), "store level 1 view vs render");
}

/// A store whose level 0 does not fit the memory budget is drawn out of
/// core on the CPU: the first image shows the coarsest level, each later
/// one finer regions as their chunks are read, and the scripted run waits
/// until nothing more is wanted; the picture is then `voxcast render`'s out
/// of core within the same budget.
#[test]
fn a_store_too_large_for_memory_is_drawn_out_of_core_and_refines_by_region() {
    if !have_xvfb() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let store = demo_store(dir.path(), "16");
    let store = store.as_str();
    // Level 0 is 2 MiB: twice it does not fit in 3 MiB, its chunks do.
    let args = [
        store,
        "--size",
        "240x180",
        "--azimuth",
        "30",
        "--device",
        "cpu",
        "--memory-budget",
        "3MiB",
        "--screenshot",
        "out.png",
        "--exit-after-frames",
        "5",
        "--save-scene",
        "s.toml",
        "--stats-json",
        "st.json",
    ];
    let o = view(&args, dir.path());
    assert_ran(&o);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("out of core"), "{e}");
    let levels = shown_levels(dir.path());
    // The finest level of each new image: 3 (16³, all of it) first, then
    // finer, down to level 0 near the eye.
    assert_eq!(levels.first(), Some(&3), "{levels:?}");
    assert_eq!(levels.last(), Some(&0), "{levels:?}");
    assert!(levels.windows(2).all(|w| w[0] > w[1]), "{levels:?}");
    let psnr = check_matches_render_with(dir.path(), &["--out-of-core", "--memory-budget", "3MiB"]);
    eprintln!("streamed store view vs render: PSNR {psnr:.2} dB");
    assert!(psnr >= 40.0, "PSNR {psnr:.2} dB < 40 dB");
}

#[test]
fn view_without_a_display_or_with_bad_flags_fails_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    // Scripted-only flags without a scripted run.
    let o = voxcast(&["view", "--save-scene", "s.toml"], dir.path());
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("--save-scene") && e.contains("scripted"), "{e}");
    // A screenshot must be a PNG.
    let o = voxcast(&["view", "--screenshot", "s.jpg"], dir.path());
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains(".png"));
    // No display: a clear error, not a panic.
    let o = Command::new(env!("CARGO_BIN_EXE_voxcast"))
        .args(["view", "--exit-after-frames", "1"])
        .current_dir(dir.path())
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .unwrap();
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("error:") && !e.contains("panicked"), "{e}");
}
