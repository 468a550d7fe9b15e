//! Locating the shared real-data folder for tests and benchmarks.
//!
//! The data lives outside the repository, in `../shared/data` beside the
//! project's root, or wherever `VOXCAST_DATA` points. Where it is missing a
//! test skips (and says so) — except under CI (`CI=true`), where missing data
//! is a failure, so CI never passes by testing nothing.

use std::path::PathBuf;

/// The data folder, if it exists.
pub fn data_dir() -> Option<PathBuf> {
    if let Some(d) = std::env::var_os("VOXCAST_DATA") {
        let d = PathBuf::from(d);
        return d.is_dir().then_some(d);
    }
    let d = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    d.canonicalize().ok().filter(|d| d.is_dir())
}

/// The path of `rel` inside the data folder, or `None` (with a note on
/// stderr) when it is missing. Under `CI=true` a missing file panics.
pub fn data_path(rel: &str) -> Option<PathBuf> {
    let p = data_dir().map(|d| d.join(rel));
    match p {
        Some(p) if p.exists() => Some(p),
        _ => {
            if std::env::var("CI")
                .map(|v| v == "true" || v == "1")
                .unwrap_or(false)
            {
                panic!("test data {rel} is missing (set VOXCAST_DATA or put ../shared/data beside the project)");
            }
            eprintln!("skipping: test data {rel} not found");
            None
        }
    }
}
