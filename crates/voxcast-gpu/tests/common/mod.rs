//! What the GPU test files share: the adapter (skipped with a note outside
//! CI, a failure under `CI=true`) and a scene of a shared-data volume.

use std::sync::Arc;
use voxcast::scene::Scene;
use voxcast_gpu::{DeviceChoice, GpuContext};

fn in_ci() -> bool {
    std::env::var("CI")
        .map(|v| v == "true" || v == "1")
        .unwrap_or(false)
}

/// The adapter, or `None` (with a note) where there is none outside CI.
pub fn context() -> Option<Arc<GpuContext>> {
    match GpuContext::new(DeviceChoice::Gpu) {
        Ok(c) => {
            eprintln!("GPU: {}", c.info());
            Some(c)
        }
        Err(e) if !in_ci() => {
            eprintln!("skipping: {e}");
            None
        }
        Err(e) => panic!("CI=true but {e}"),
    }
}

/// A scene of `rel` under the shared data folder, seen from azimuth 35°,
/// elevation 20°; `None` when the data is not there.
pub fn scene(rel: &str) -> Option<Scene> {
    let p = voxcast::testdata::data_path(rel)?;
    let mut s = Scene::default();
    s.input.path = p.to_string_lossy().into_owned();
    s.camera.azimuth = 35.0;
    s.camera.elevation = 20.0;
    Some(s)
}
