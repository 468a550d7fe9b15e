//! What the command-line tests share: running the `voxcast` binary and
//! reading what it said. Each test file takes what it needs (`mod common;`).
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

/// Runs `voxcast ARGS` in `cwd` and waits for it.
pub fn voxcast(args: &[&str], cwd: &Path) -> Output {
    voxcast_with(args, cwd, &[])
}

/// [`voxcast`] with extra environment variables.
pub fn voxcast_with(args: &[&str], cwd: &Path, env: &[(&str, &str)]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_voxcast"))
        .args(args)
        .current_dir(cwd)
        .envs(env.iter().copied())
        .output()
        .expect("run voxcast")
}

/// The run's standard error as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Under CI (`CI=true` or `1`) a missing GPU driver or display server fails
/// the tests that need one instead of skipping them.
pub fn in_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true" || v == "1")
}

/// A JSON file the command wrote.
pub fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// `voxcast compare A B`'s PSNR in dB; `None` for identical images.
pub fn psnr(a: &str, b: &str, cwd: &Path) -> Option<f64> {
    let o = voxcast(&["compare", a, b, "--json"], cwd);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    j["psnr_db"].as_f64()
}
