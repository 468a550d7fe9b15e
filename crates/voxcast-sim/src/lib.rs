//! voxcast-sim — the simulators that make the volumes voxcast renders.
//!
//! Two of the seed papers (SPEC.md) render data that a simulation
//! produced; this crate makes that data, so the renderer can be measured on
//! the scenes the papers describe:
//!
//! * [`smoke`]: incompressible smoke with fire, heat, obstacles and openings
//!   (Fedkiw, Stam & Jensen 2001 on a MAC grid; [`advect`] the transport,
//!   [`pressure`] the MGPCG pressure solve), the input of **S0** (Liu, Lu &
//!   Chang 2021, block-adaptive sampling for indoor smoke). [`scenes`] holds
//!   S0's fixed room, office and corridor as presets; [`simulate_smoke`]
//!   writes a run frame by frame as a [`voxcast::io::Series`] folder with
//!   the scene's solids beside it (`geometry.toml`, read by the renderer).
//! * [`cloud`]: **S3**'s particle-system cloud (Xie, Li & Kou): puffs filled
//!   frame by frame that grow, change slowly and dissipate from the edge, the
//!   particles splatted into a density grid — the volume S3's octree + LOD
//!   marcher (`voxcast::render::lod`, in the core) renders.
//!
//! The renderer does not depend on this crate: it depends on the core
//! (`voxcast`) for [`Volume`](voxcast::Volume), series folders and errors,
//! and the CLI (`voxcast simulate smoke`, `voxcast cloud`) drives it.

pub mod advect;
pub mod cloud;
pub mod pressure;
pub mod scenes;
pub mod smoke;

pub use scenes::SmokeScene;
pub use smoke::{Smoke, StepStats};

use serde::Serialize;
use std::path::Path;
use std::time::Instant;
use voxcast::error::{Error, Result};
use voxcast::files::write_file;
use voxcast::io::SeriesWriter;

/// The solids file a smoke folder carries beside `series.toml`.
pub const GEOMETRY: &str = "geometry.toml";
/// The scene a smoke folder was simulated from.
pub const SCENE: &str = "scene.toml";
/// Per-frame statistics of a run.
pub const STATS: &str = "simulation.json";

/// What one written frame cost and what the room holds.
#[derive(Clone, Debug, Default, Serialize)]
pub struct FrameStats {
    pub frame: usize,
    /// Simulated time at the frame (s).
    pub time: f64,
    /// Wall time of the frame's steps, without writing (ms).
    pub step_ms: f64,
    /// Wall time spent writing the frame (ms).
    pub write_ms: f64,
    /// CG iterations over the frame's steps.
    pub cg_iterations: usize,
    /// Worst relative residual of the frame's pressure solves.
    pub relative_residual: f64,
    /// Smoke mass in the room, injected so far, out through the openings.
    pub mass: f64,
    pub injected: f64,
    pub outflow: f64,
    /// Density advection sub-steps of the fastest rows over the frame's
    /// steps (what every row took before local sub-stepping).
    pub substeps: usize,
    /// Density sub-steps computed per grid row, averaged over the rows,
    /// over the frame's steps ([`StepStats::row_substeps`]).
    pub row_substeps: f64,
    /// Wall time per phase over the frame's steps (ms): density, temperature,
    /// velocity advection, forces, pressure projection.
    pub phase_ms: [f64; 5],
}

/// Runs `scene` for `frames` frames into the frame folder `dir` (frame 0 is
/// the state after the first frame's steps), with `geometry.toml`,
/// `scene.toml` and `simulation.json` beside the frames. `on_frame` sees
/// every frame's stats as it is written.
pub fn simulate_smoke(
    scene: &SmokeScene,
    frames: usize,
    dir: &Path,
    mut on_frame: impl FnMut(&FrameStats),
) -> Result<Vec<FrameStats>> {
    if frames == 0 {
        return Err(Error::invalid("--frames 0: at least one frame is needed"));
    }
    let mut smoke = Smoke::new(scene)?;
    let title = if scene.title.is_empty() {
        "smoke".to_string()
    } else {
        scene.title.clone()
    };
    let mut writer = SeriesWriter::create(dir, Some(title), Some("s".into()))?;
    let text = scene.geometry_toml();
    write_file(&dir.join(GEOMETRY), |f| {
        use std::io::Write;
        f.write_all(text.as_bytes())
    })?;
    let text = scene.to_toml();
    write_file(&dir.join(SCENE), |f| {
        use std::io::Write;
        f.write_all(
            b"# voxcast smoke scene: run again with `voxcast simulate smoke --scene THIS_FILE`\n",
        )?;
        f.write_all(text.as_bytes())
    })?;
    let mut all = Vec::with_capacity(frames);
    for frame in 0..frames {
        let t0 = Instant::now();
        let mut st = FrameStats {
            frame,
            ..Default::default()
        };
        for _ in 0..scene.steps_per_frame {
            let s = smoke.step();
            st.cg_iterations += s.solve.iterations;
            st.relative_residual = st.relative_residual.max(s.solve.relative_residual);
            st.substeps += s.substeps;
            st.row_substeps += s.row_substeps;
            for (a, b) in st.phase_ms.iter_mut().zip(s.phase_ms) {
                *a += b;
            }
        }
        st.step_ms = t0.elapsed().as_secs_f64() * 1e3;
        let t1 = Instant::now();
        writer.push(&smoke.to_volume()?, smoke.time())?;
        st.write_ms = t1.elapsed().as_secs_f64() * 1e3;
        st.time = smoke.time();
        st.mass = smoke.mass();
        st.injected = smoke.injected();
        st.outflow = smoke.outflow();
        on_frame(&st);
        all.push(st);
        if frame + 1 == frames || frame % 25 == 0 {
            let json = serde_json::to_string_pretty(&all)
                .map_err(|e| Error::invalid(format!("cannot write {STATS}: {e}")))?;
            write_file(&dir.join(STATS), |f| {
                use std::io::Write;
                f.write_all(json.as_bytes())
            })?;
        }
    }
    Ok(all)
}
