//! `voxcast render`.

use super::device::{gpu_renderer, pick_device};
use crate::args::RenderArgs;
use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};
use voxcast::files::Outputs;
use voxcast::scene::Scene;
use voxcast_gpu::Device;

pub fn run(a: RenderArgs) -> Result<()> {
    #[cfg(feature = "mpi")]
    if a.show_parts {
        anyhow::bail!(
            "--show-parts: the volume is split only under mpirun (mpirun -np N voxcast render …)"
        );
    }
    let mut scene = a.scene()?;
    // A chunked store: the level the camera needs, read whole if it fits
    // the memory budget, else rendered out of core.
    let mut level_read_whole = None;
    match super::render_chunked::plan(&a, &scene)? {
        Some(super::render_chunked::Plan::OutOfCore(store, ooc)) => {
            return super::render_chunked::run(&a, &scene, &store, &ooc)
        }
        Some(super::render_chunked::Plan::InCore(level, store)) => {
            scene.input.options.level = Some(level);
            level_read_whole = Some((level, store));
        }
        None => {}
    }
    // Every output is checked before any work, and written only when all
    // of them can be.
    let (mut outputs, out) = plan_outputs(&a, &scene)?;
    let quiet = a.quiet;
    let mut prepared = prepare(&scene, &mut outputs, quiet)?;
    if let Some((level, store)) = level_read_whole {
        let said = super::render_chunked::match_out_of_core(&scene, &store, level, &mut prepared)?;
        if let (Some(said), false) = (said, quiet) {
            eprintln!("{said}");
        }
    }
    if let Some(target) = a.quality {
        // The pilot renders on the CPU, which the GPU matches.
        let renderer = voxcast::render::Renderer::new(&prepared.volume, prepared.window)?
            .with_geometry(prepared.geometry.clone());
        let render = |p: &voxcast::render::RenderParams| {
            renderer.render(&prepared.tf, &scene.camera, p, &|_, _| {})
        };
        let tell = |what: &str| {
            if !quiet && std::io::stderr().is_terminal() {
                eprint!("\rquality pilot: {what:<40}");
            }
        };
        let choice = voxcast_bench::quality::choose(
            &scene.render,
            target,
            voxcast_bench::quality::PILOT_PIXELS,
            &render,
            &tell,
        )?;
        if !quiet {
            if std::io::stderr().is_terminal() {
                eprint!("\r{:60}\r", "");
            }
            eprintln!("{}", choice.describe());
        }
        scene.render = choice.params;
    }
    let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::hidden());
    bar.set_style(
        ProgressStyle::with_template("rendering {bar:40.cyan/blue} {percent:>3}% {elapsed}<{eta}")
            .expect("valid template"),
    );
    let shown = AtomicBool::new(false);
    let start = Instant::now();
    let tty = std::io::stderr().is_terminal() && !quiet;
    let progress = |done: usize, total: usize| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
        // Only renders longer than about a second get a bar.
        if tty && start.elapsed() > Duration::from_secs(1) && !shown.swap(true, Ordering::Relaxed) {
            bar.set_draw_target(ProgressDrawTarget::stderr());
        }
    };
    let device = pick_device(
        a.device,
        &[scene.render.method],
        prepared.geometry.as_deref(),
        quiet,
    )?;
    let (image, stats) = match &device {
        Device::Cpu => scene.render(&prepared, &progress)?,
        Device::Gpu(ctx) => gpu_renderer(ctx, &prepared, a.gpu_filter.into(), quiet)?
            .render(&prepared.tf, &scene.camera, &scene.render)
            .context("rendering on the GPU")?,
    };
    bar.finish_and_clear();
    let mut extra = serde_json::Map::new();
    extra.insert("device".into(), device.describe().into());
    write_outputs(
        &a,
        &mut outputs,
        &out,
        &image,
        &stats,
        extra,
        &scene,
        &prepared,
    )?;
    outputs.commit()?;
    if !quiet {
        // Where the CPU ray loop ran: the SIMD packets, or the scalar loop.
        let mut simd = match (&device, stats.simd) {
            (Device::Cpu, Some(l)) => format!(", SIMD {}", l.name()),
            (Device::Cpu, None) => ", scalar loop".to_string(),
            (Device::Gpu(_), _) => String::new(),
        };
        if stats.block_size > 0 {
            simd.push_str(&format!(", blocks {}³", stats.block_size));
        }
        eprintln!(
            "wrote {} ({}×{}) in {:.3} s on {}{simd}: {} rays, {} samples ({:.1} M/s), {} early-terminated",
            out.display(),
            image.width,
            image.height,
            stats.seconds,
            device.describe(),
            stats.rays,
            stats.samples,
            stats.samples_per_second() / 1e6,
            stats.early_terminated
        );
        if let Some(share) = stats.skipping_left_out {
            eprintln!(
                "empty-space skipping left out: the transfer function hides {:.1} % of the blocks, too few for it to pay",
                share * 100.0
            );
        }
        if let Some(d) = stats.device_seconds {
            eprintln!(
                "GPU time (timestamp queries, compute passes alone): {:.3} ms, {:.1} M samples/s",
                d * 1e3,
                stats.samples as f64 / d * 1e-6
            );
        }
    }
    Ok(())
}

/// Loads the scene's volume (and geometry), checks the planned outputs
/// against every file the readers opened (a detached header's data is an
/// input too), and says what was loaded unless `quiet`.
pub fn prepare(
    scene: &Scene,
    outputs: &mut Outputs,
    quiet: bool,
) -> Result<voxcast::scene::Prepared> {
    let t_load = Instant::now();
    let prepared = scene.prepare()?;
    outputs.check()?;
    if !quiet {
        eprintln!("{}", loaded(scene, &prepared, t_load));
    }
    Ok(prepared)
}

/// The outputs `a` asks for, planned (checked against the input): the
/// image (`-o`, default `render.png`) and the optional ones.
pub(super) fn plan_outputs(a: &RenderArgs, scene: &Scene) -> Result<(Outputs, PathBuf)> {
    let out = a
        .output
        .clone()
        .unwrap_or_else(|| PathBuf::from("render.png"));
    let mut outputs = Outputs::new([&scene.input.path]);
    outputs.plan("-o", &out, &["png", "exr"])?;
    outputs.plan_optional("--float-out", a.float_out.as_deref(), &["exr"])?;
    outputs.plan_optional("--stats-json", a.stats_json.as_deref(), &[])?;
    outputs.plan_optional("--save-scene", a.save_scene.as_deref(), &["toml"])?;
    Ok((outputs, out))
}

/// Writes the image to `out` and the optional outputs `a` asks for:
/// `--float-out`, `--stats-json` (the core's stats with `extra`'s keys
/// added) and `--save-scene`. The caller commits.
#[allow(clippy::too_many_arguments)]
pub(super) fn write_outputs(
    a: &RenderArgs,
    outputs: &mut Outputs,
    out: &std::path::Path,
    image: &voxcast::Image,
    stats: &voxcast::RenderStats,
    extra: serde_json::Map<String, serde_json::Value>,
    scene: &Scene,
    prepared: &voxcast::scene::Prepared,
) -> Result<()> {
    image.write_into(outputs, out)?;
    if let Some(f) = &a.float_out {
        image.write_exr_into(outputs, f)?;
    }
    if let Some(f) = &a.stats_json {
        let mut value = serde_json::to_value(stats)?;
        if let serde_json::Value::Object(m) = &mut value {
            m.extend(extra);
        }
        let json = serde_json::to_string_pretty(&value)?;
        outputs.write(f, |w| writeln!(w, "{json}"))?;
    }
    if let Some(f) = &a.save_scene {
        let text = scene.resolved(prepared).to_toml(f)?;
        outputs.write(f, |w| w.write_all(text.as_bytes()))?;
    }
    Ok(())
}

/// The line saying what was loaded.
fn loaded(scene: &Scene, prepared: &voxcast::scene::Prepared, since: Instant) -> String {
    let v = &prepared.volume;
    let d = v.dims();
    format!(
        "loaded {} — {}×{}×{} {} in {:.2} s; window [{}, {}]",
        scene.input.path,
        d[0],
        d[1],
        d[2],
        v.scalar_type(),
        since.elapsed().as_secs_f64(),
        prepared.window[0],
        prepared.window[1]
    ) + &prepared
        .geometry
        .as_ref()
        .map(|g| format!("\n{}", g.describe()))
        .unwrap_or_default()
}
