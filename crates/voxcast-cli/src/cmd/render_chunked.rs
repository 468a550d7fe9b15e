//! `voxcast render STORE.zarr`: a chunked store is read whole when the
//! level to render fits the memory budget (then any method and device
//! work), and rendered out of core otherwise ([`voxcast::render::outofcore`]).

use crate::args::RenderArgs;
use anyhow::{bail, Result};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::time::Instant;
use voxcast::camera::Camera;
use voxcast::io::zarr::ZarrStore;
use voxcast::render::outofcore::{self, human_bytes, OutOfCoreParams};
use voxcast::scene::Scene;
use voxcast::volume::ChunkedSource;

/// Bytes an in-core render holds per byte of the level it reads (measured:
/// a 256 MiB level peaks at 527 MiB resident).
const IN_CORE_FACTOR: u64 = 2;

/// The largest level read whole to build the transfer function from.
const PROXY_BYTES: u64 = 64 << 20;

/// What to do with a chunked input.
pub enum Plan {
    /// Read this level whole and render as usual (the store, opened, for
    /// [`match_out_of_core`]).
    InCore(usize, Box<ZarrStore>),
    /// Render out of core.
    OutOfCore(Box<ZarrStore>, OutOfCoreParams),
}

/// For a chunked store as input: the level the camera needs, and whether
/// it fits the budget. `None` for any other input.
pub fn plan(a: &RenderArgs, scene: &Scene) -> Result<Option<Plan>> {
    let path = Path::new(&scene.input.path);
    if scene.input.path.starts_with(voxcast::builtin::PREFIX) || !voxcast::io::zarr::is_zarr(path) {
        return Ok(None);
    }
    let store = ZarrStore::open_with(path, &scene.input.options)?;
    let levels = store.levels();
    let budget = a.memory_budget.unwrap_or_else(outofcore::default_budget);
    let cam = camera_over(scene, levels);
    let lod_scale = lod_scale(scene)?;
    let level = match scene.input.options.level {
        Some(l) if l >= levels.len() => bail!(
            "--level {l}: {} has levels 0…{}",
            path.display(),
            levels.len() - 1
        ),
        Some(l) => l,
        None => outofcore::choose_level(levels, &cam, lod_scale),
    };
    let bytes = levels[level].bytes(store.scalar_type());
    // In core the renderer keeps a second copy of the voxels laid out for
    // its ray packets: twice the level must fit.
    if !a.out_of_core && bytes.saturating_mul(IN_CORE_FACTOR) <= budget {
        if !a.quiet && levels.len() > 1 {
            let d = levels[level].dims;
            eprintln!(
                "{}: level {level} of 0…{} ({}×{}×{}, {}) {}; twice it fits the memory budget ({}): reading it whole",
                path.display(),
                levels.len() - 1,
                d[0],
                d[1],
                d[2],
                human_bytes(bytes),
                if scene.input.options.level.is_some() {
                    "as asked"
                } else {
                    "has voxels no larger than a pixel"
                },
                human_bytes(budget)
            );
        }
        return Ok(Some(Plan::InCore(level, Box::new(store))));
    }
    // The level is asked for, or chosen per region: `level` near the eye,
    // coarser where the voxels of a coarser level are still no larger than
    // a pixel.
    let ooc = OutOfCoreParams {
        budget,
        level: scene.input.options.level,
        lod_scale,
        ..Default::default()
    };
    Ok(Some(Plan::OutOfCore(Box::new(store), ooc)))
}

/// The scene's `lod_scale` (`--lod-scale`; 1 when not given), checked: a
/// scene file may hold any number.
pub fn lod_scale(scene: &Scene) -> Result<f32> {
    Ok(scene.input.options.lod_scale()?)
}

/// The scene prepared from a stand-in for the store's volume, and the
/// stand-in's level: the finest level of at most 64 MiB stands in where the
/// transfer function and the window need the values (auto, histograms) —
/// level 0 itself for a volume of that size, so the picture is the in-core
/// one. Only the transfer function, the window and the geometry are kept;
/// the stand-in is freed before the render starts, so the budget holds.
pub fn prepare_from_proxy(
    scene: &Scene,
    store: &ZarrStore,
) -> Result<(voxcast::scene::Prepared, usize)> {
    let levels = store.levels();
    let coarsest = store.finest_within(PROXY_BYTES).unwrap_or(levels.len() - 1);
    let proxy = store.read_level(coarsest)?;
    let mut prepared = scene.prepare_with(proxy)?;
    window_over_level0(scene, store, &mut prepared);
    prepared.volume = voxcast::Volume::new(
        [1, 1, 1],
        glam::Vec3::ONE,
        glam::Vec3::ZERO,
        voxcast::VoxelData::U8(vec![0u8].into()),
    )?;
    Ok((prepared, coarsest))
}

/// For a level of a chunked store read whole (`prepared`, its volume that
/// level): the transfer function and window the out-of-core renderer takes
/// ([`prepare_from_proxy`]: the automatic choices from the same stand-in
/// level, the window over level 0's value range), so that a level looks
/// the same read whole as out of core. Before, an automatic transfer
/// function followed the level's own histogram and the window its own
/// range (a coarse level's means are narrower): level 1 of the demo store
/// was 51 dB from out of core, level 2 41 dB.
/// Returns what changed, to tell the user (`None`: nothing).
pub fn match_out_of_core(
    scene: &Scene,
    store: &ZarrStore,
    level: usize,
    prepared: &mut voxcast::scene::Prepared,
) -> Result<Option<String>> {
    let coarsest = store
        .finest_within(PROXY_BYTES)
        .unwrap_or(store.levels().len() - 1);
    let (tf, window) = (prepared.tf.clone(), prepared.window);
    if coarsest != level {
        let from = scene.prepare_with(store.read_level(coarsest)?)?;
        prepared.tf = from.tf;
        prepared.window = from.window;
    }
    window_over_level0(scene, store, prepared);
    let said = (prepared.tf != tf || prepared.window != window).then(|| {
        format!(
            "transfer function from level {coarsest} and window [{}, {}] from level 0's value range, as out of core",
            prepared.window[0], prepared.window[1]
        )
    });
    Ok(said)
}

/// The window over the data range, where neither the scene nor the
/// transfer function sets one: level 0's, where the store keeps its chunks'
/// ranges (a coarser level's means are narrower).
fn window_over_level0(scene: &Scene, store: &ZarrStore, prepared: &mut voxcast::scene::Prepared) {
    if scene.transfer.window.is_none() && prepared.tf.window.is_none() {
        if let Some(r) = store.value_range() {
            prepared.window = r;
        }
    }
}

/// Renders `store` out of core and writes the outputs `a` asks for.
pub fn run(a: &RenderArgs, scene: &Scene, store: &ZarrStore, ooc: &OutOfCoreParams) -> Result<()> {
    if a.quality.is_some() {
        bail!("--quality: not available out of core (the pilot renders the whole volume); give --step, or a --memory-budget the level fits in");
    }
    if !matches!(a.device, crate::args::DeviceArg::Cpu) {
        bail!("--device: out of core, voxcast renders on the CPU; leave --device at cpu, or give a --memory-budget the level fits in");
    }
    let (mut outputs, out) = super::render::plan_outputs(a, scene)?;
    let quiet = a.quiet;
    let t_load = Instant::now();
    let levels = store.levels();
    let (prepared, coarsest) = prepare_from_proxy(scene, store)?;
    outputs.check()?;
    if prepared.geometry.is_some() {
        bail!("--geometry: opaque geometry is not rendered out of core; render without it, or give a --memory-budget the level fits in");
    }
    let cam = camera_over(scene, levels);
    let level = ooc
        .level
        .unwrap_or_else(|| outofcore::choose_level(levels, &cam, ooc.lod_scale));
    let l = &levels[level];
    let how = if ooc.level.is_some() || level + 1 == levels.len() {
        "as asked".to_string()
    } else {
        "near the eye, coarser levels where their voxels are no larger than a pixel".to_string()
    };
    if !quiet {
        eprintln!(
            "opened {} — {} levels, level 0 {}×{}×{} {} ({}); rendering level {level} ({}×{}×{}, chunks {}×{}×{}) {how}, out of core within {}; window [{}, {}] from level {coarsest} ({:.2} s)",
            scene.input.path,
            levels.len(),
            levels[0].dims[0],
            levels[0].dims[1],
            levels[0].dims[2],
            store.scalar_type(),
            human_bytes(levels[0].bytes(store.scalar_type())),
            l.dims[0],
            l.dims[1],
            l.dims[2],
            l.chunk[0],
            l.chunk[1],
            l.chunk[2],
            human_bytes(ooc.budget),
            prepared.window[0],
            prepared.window[1],
            t_load.elapsed().as_secs_f64()
        );
    }
    let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::hidden());
    bar.set_style(
        ProgressStyle::with_template("bricks {bar:40.cyan/blue} {pos}/{len} {elapsed}<{eta}")
            .expect("valid template"),
    );
    if std::io::stderr().is_terminal() && !quiet {
        bar.set_draw_target(ProgressDrawTarget::stderr());
    }
    let progress = |done: usize, total: usize| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    };
    let (image, stats, oo) = outofcore::render_chunked(
        store,
        &prepared.tf,
        prepared.window,
        &scene.camera,
        &scene.render,
        ooc,
        &progress,
        &AtomicBool::new(false),
    )?;
    bar.finish_and_clear();
    let mut extra = serde_json::Map::new();
    extra.insert("device".into(), "cpu, out of core".into());
    extra.insert("out_of_core".into(), serde_json::to_value(&oo)?);
    extra.insert("budget_bytes".into(), ooc.budget.into());
    super::render::write_outputs(
        a,
        &mut outputs,
        &out,
        &image,
        &stats,
        extra,
        scene,
        &prepared,
    )?;
    outputs.commit()?;
    if !quiet {
        eprintln!(
            "wrote {} ({}×{}) in {:.3} s out of core: {}, {} of {} bricks marched ({} empty, {} off-image, {} hidden), read {} from the store ({} decoded), cache hits {:.0} %, peak {} of {}; {} samples ({:.1} M/s)",
            out.display(),
            image.width,
            image.height,
            stats.seconds,
            levels_marched(&oo),
            oo.marched,
            oo.bricks,
            oo.empty,
            oo.culled,
            oo.occluded,
            human_bytes(oo.bytes_read),
            human_bytes(oo.cache.decoded_bytes),
            100.0 * oo.hit_rate(),
            human_bytes(oo.cache.peak_bytes),
            human_bytes(ooc.budget),
            stats.samples,
            stats.samples_per_second() / 1e6,
        );
    }
    Ok(())
}

/// The levels an out-of-core render read, with the bricks marched at
/// each: "level 1" or "levels 1…3 (212, 96, 7 bricks)".
fn levels_marched(oo: &outofcore::OutOfCoreStats) -> String {
    if oo.coarsest == oo.level {
        return format!("level {}", oo.level);
    }
    let counts: Vec<String> = (oo.level..=oo.coarsest)
        .map(|l| oo.per_level.get(l).copied().unwrap_or(0).to_string())
        .collect();
    format!(
        "levels {}…{} ({} bricks)",
        oo.level,
        oo.coarsest,
        counts.join(", ")
    )
}

/// The scene's camera framing level 0's box, as the out-of-core renderer
/// frames it.
fn camera_over(scene: &Scene, levels: &[voxcast::volume::Level]) -> Camera {
    let (lo, hi) = outofcore::world_bounds(levels);
    Camera::fit(
        &scene.camera,
        lo,
        hi,
        scene.render.width,
        scene.render.height,
    )
}
