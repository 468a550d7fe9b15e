//! `--device cpu|gpu|auto` end to end: with no Vulkan driver `gpu` is a clear
//! error and a non-zero exit (never a panic, never a silent fallback),
//! `auto` says it falls back to the CPU; with an adapter the GPU's PNG and
//! stats match the CPU's. Without an adapter the GPU render test skips
//! with a note, except under CI (`CI=true`), where it fails.

use std::path::Path;
use std::process::{Command, Output};

mod common;
use common::{in_ci, stderr, voxcast_with};

fn voxcast(args: &[&str], cwd: &Path, no_driver: bool) -> Output {
    // The Vulkan loader reads only the driver manifests named here.
    let none = [
        ("VK_ICD_FILENAMES", "/nonexistent/no-driver.json"),
        ("VK_DRIVER_FILES", "/nonexistent/no-driver.json"),
        ("WGPU_BACKEND", "vulkan"),
    ];
    voxcast_with(args, cwd, if no_driver { &none } else { &[] })
}

#[test]
fn gpu_without_a_driver_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let o = voxcast(
        &[
            "render", "--device", "gpu", "--size", "32x32", "-o", "g.png",
        ],
        dir.path(),
        true,
    );
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("no GPU adapter"), "{err}");
    assert!(err.contains("tried backends [vulkan]"), "{err}");
    assert!(err.contains("adapters found: none"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(!dir.path().join("g.png").exists(), "an image was written");
}

#[test]
fn auto_without_a_driver_renders_on_the_cpu_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let o = voxcast(
        &[
            "render",
            "--device",
            "auto",
            "--size",
            "32x32",
            "-o",
            "a.png",
            "--stats-json",
            "s.json",
        ],
        dir.path(),
        true,
    );
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("rendering on the CPU"), "{err}");
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("s.json")).unwrap()).unwrap();
    assert!(
        stats["device"].as_str().unwrap().starts_with("cpu"),
        "{stats}"
    );
}

#[test]
fn gpu_refuses_a_method_it_lacks_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let o = voxcast(
        &[
            "render",
            "--device",
            "gpu",
            "--method",
            "importance",
            "--size",
            "32x32",
        ],
        dir.path(),
        false,
    );
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("method `importance`"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn gpu_render_matches_the_cpu_render() {
    let dir = tempfile::tempdir().unwrap();
    let common = ["--size", "96x80", "--azimuth", "30", "--elevation", "25"];
    let run = |device: &str, out: &str| {
        let mut args = vec![
            "render",
            "--device",
            device,
            "-o",
            out,
            "--float-out",
            "",
            "--stats-json",
        ];
        let json = format!("{out}.json");
        let exr = format!("{out}.exr");
        args[6] = &exr;
        args.push(&json);
        args.extend(common);
        let o = voxcast(&args, dir.path(), false);
        (o, json, exr)
    };
    let (o, _, cpu_exr) = run("cpu", "cpu.png");
    assert!(o.status.success(), "{}", stderr(&o));
    let (o, json, gpu_exr) = run("gpu", "gpu.png");
    let err = stderr(&o);
    if !o.status.success() && err.contains("no GPU adapter") && !in_ci() {
        eprintln!("skipping: {err}");
        return;
    }
    assert!(o.status.success(), "{err}");
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join(&json)).unwrap()).unwrap();
    assert!(
        stats["device"].as_str().unwrap().starts_with("gpu: "),
        "{stats}"
    );
    assert_eq!(stats["rays"], 96 * 80);
    let a = voxcast::Image::read(&dir.path().join(cpu_exr)).unwrap();
    let b = voxcast::Image::read(&dir.path().join(gpu_exr)).unwrap();
    let psnr = voxcast::metrics::psnr(&a, &b).unwrap();
    assert!(psnr >= 40.0, "GPU vs CPU PSNR {psnr:.2} dB");
    assert!(dir.path().join("gpu.png").exists());
}

/// `bench --device gpu` times the methods on the GPU against the CPU's
/// reference; a method the GPU lacks is reported failed by name while the
/// others still run.
#[test]
fn bench_on_the_gpu_reports_the_device_and_unsupported_methods() {
    let dir = tempfile::tempdir().unwrap();
    let o = voxcast(
        &[
            "bench",
            "--device",
            "gpu",
            "--methods",
            "uniform,adaptive+grouped,importance",
            "--size",
            "32x32",
            "--repeat",
            "1",
            "--warmup",
            "0",
            "--json",
            "b.json",
            "-q",
        ],
        dir.path(),
        false,
    );
    let err = stderr(&o);
    if err.contains("no GPU adapter") && !in_ci() {
        eprintln!("skipping: {err}");
        return;
    }
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains("importance") && out.contains("not supported on the GPU back end"),
        "{out}\n{err}"
    );
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("b.json")).unwrap()).unwrap();
    assert!(
        j["run"]["device"].as_str().unwrap().starts_with("gpu: "),
        "{j}"
    );
    let methods = j["methods"].as_array().unwrap();
    for m in &methods[..2] {
        let psnr = m["psnr_db"].as_f64().unwrap();
        assert!(psnr > 30.0, "{m}");
    }
    assert!(methods[2]["error"].as_str().unwrap().contains("importance"));
}

/// Renders `args` with `--device cpu` and `--device gpu` (plus `env` for
/// the GPU run) and returns the PSNR of the two EXRs, or `None` when there
/// is no adapter outside CI.
fn cpu_vs_gpu(args: &[&str], env: &[(&str, &str)]) -> Option<f64> {
    let dir = tempfile::tempdir().unwrap();
    let run = |device: &str, env: &[(&str, &str)]| {
        let png = format!("{device}.png");
        let exr = format!("{device}.exr");
        let json = format!("{device}.json");
        let mut a = vec![
            "render",
            "--device",
            device,
            "-o",
            &png,
            "--float-out",
            &exr,
            "--stats-json",
            &json,
        ];
        a.extend(args);
        let mut c = Command::new(env!("CARGO_BIN_EXE_voxcast"));
        c.args(&a).current_dir(dir.path());
        for (k, v) in env {
            c.env(k, v);
        }
        c.output().expect("run voxcast")
    };
    let o = run("cpu", &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = run("gpu", env);
    let err = stderr(&o);
    if !o.status.success() && err.contains("no GPU adapter") && !in_ci() {
        eprintln!("skipping: {err}");
        return None;
    }
    assert!(o.status.success(), "{err}");
    assert!(dir.path().join("gpu.png").exists());
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("gpu.json")).unwrap())
            .unwrap();
    assert!(
        stats["device"].as_str().unwrap().starts_with("gpu: "),
        "{stats}"
    );
    let a = voxcast::Image::read(&dir.path().join("cpu.exr")).unwrap();
    let b = voxcast::Image::read(&dir.path().join("gpu.exr")).unwrap();
    Some(voxcast::metrics::psnr(&a, &b).unwrap())
}

/// The FDS room with its OBST boxes (loaded automatically from the .smv)
/// renders on the GPU, also split into bricks by a lowered texture limit.
#[test]
fn fds_room_with_obstructions_on_the_gpu() {
    let Some(smv) = voxcast::testdata::data_path("fds_room/room_smoke.smv") else {
        return;
    };
    let smv = smv.to_string_lossy().into_owned();
    let args = [
        smv.as_str(),
        "--time",
        "30",
        "--tf",
        "smoke",
        "--size",
        "96x72",
    ];
    let Some(psnr) = cpu_vs_gpu(&args, &[]) else {
        return;
    };
    assert!(psnr >= 40.0, "FDS room GPU vs CPU PSNR {psnr:.2} dB");
    let psnr = cpu_vs_gpu(&args, &[("VOXCAST_GPU_MAX_TEXTURE_3D", "32")]).unwrap();
    assert!(
        psnr >= 40.0,
        "bricked FDS room GPU vs CPU PSNR {psnr:.2} dB"
    );
}

/// `--method single-scatter` on the GPU: the same radiance as the CPU.
#[test]
fn single_scatter_on_the_gpu() {
    let Some(vdb) = voxcast::testdata::data_path("cloud_vdb/cloud.vdb") else {
        return;
    };
    let vdb = vdb.to_string_lossy().into_owned();
    let args = [
        vdb.as_str(),
        "--method",
        "single-scatter",
        "--window",
        "0,1",
        "--extinction",
        "40",
        "--phase",
        "hg:0.8",
        "--spp",
        "4",
        "--size",
        "64x64",
    ];
    let Some(psnr) = cpu_vs_gpu(&args, &[]) else {
        return;
    };
    assert!(psnr >= 40.0, "single-scatter GPU vs CPU PSNR {psnr:.2} dB");
}
