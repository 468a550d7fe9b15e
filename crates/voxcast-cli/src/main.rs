//! The `voxcast` command: parses arguments and wires the library together.
//! No rendering logic lives here.

mod animate;
mod args;
mod bench_frames;
mod cloud;
mod simulate;

use anyhow::{bail, Context, Result};
use args::{BenchArgs, Cli, Command, CompareArgs, InfoArgs, RenderArgs, ViewArgs};
use clap::Parser;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};
use voxcast::files::Outputs;
use voxcast::scene::Scene;
use voxcast::{metrics, Image};

fn main() {
    let cli = Cli::parse();
    // One command per process: no output may replace a file it read.
    voxcast::files::record_inputs();
    let result = match cli.command {
        Command::Render(a) => render(*a),
        Command::Bench(a) => bench(*a),
        Command::Info(a) => info(a),
        Command::Compare(a) => compare(a),
        Command::Cloud(a) => cloud::run(*a),
        Command::Presets => {
            presets();
            Ok(())
        }
        Command::Simulate(a) => simulate::run(a),
        Command::Animate(a) => animate::run(*a),
        Command::BenchFrames(a) => bench_frames::run(*a),
        Command::View(a) => view(*a),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

fn render(a: RenderArgs) -> Result<()> {
    let scene = a.scene()?;
    let out = a
        .output
        .clone()
        .unwrap_or_else(|| PathBuf::from("render.png"));
    // Every output is checked before any work, and written only when all
    // of them can be.
    let mut outputs = Outputs::new([&scene.input.path]);
    outputs.plan("-o", &out, &["png", "exr"])?;
    if let Some(f) = &a.float_out {
        outputs.plan("--float-out", f, &["exr"])?;
    }
    if let Some(f) = &a.stats_json {
        outputs.plan("--stats-json", f, &[])?;
    }
    if let Some(f) = &a.save_scene {
        outputs.plan("--save-scene", f, &["toml"])?;
    }
    let quiet = a.quiet;
    let t_load = Instant::now();
    let prepared = scene.prepare()?;
    // The files the readers opened (a detached header's data) are inputs too.
    outputs.check()?;
    if !quiet {
        eprintln!("{}", loaded(&scene, &prepared, t_load));
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
    let device = pick_device(a.device, &scene, prepared.geometry.as_deref(), quiet)?;
    let (image, stats) = match &device {
        Device::Cpu => scene.render(&prepared, &progress)?,
        Device::Gpu(ctx) => gpu_renderer(ctx, &prepared)?
            .render(&prepared.tf, &scene.camera, &scene.render)
            .context("rendering on the GPU")?,
    };
    bar.finish_and_clear();
    image.write_into(&mut outputs, &out)?;
    if let Some(f) = &a.float_out {
        image.write_exr_into(&mut outputs, f)?;
    }
    if let Some(f) = &a.stats_json {
        // The core's stats plus the device that rendered.
        let mut value = serde_json::to_value(stats)?;
        if let serde_json::Value::Object(m) = &mut value {
            m.insert("device".into(), device.describe().into());
        }
        let json = serde_json::to_string_pretty(&value)?;
        outputs.write(f, |w| writeln!(w, "{json}"))?;
    }
    if let Some(f) = &a.save_scene {
        let text = scene.resolved(&prepared).to_toml(f)?;
        outputs.write(f, |w| w.write_all(text.as_bytes()))?;
    }
    outputs.commit()?;
    if !quiet {
        eprintln!(
            "wrote {} ({}×{}) in {:.3} s on {}: {} rays, {} samples ({:.1} M/s), {} early-terminated",
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
    }
    Ok(())
}

/// The renderer `--device` chose.
enum Device {
    Cpu,
    Gpu(std::sync::Arc<voxcast_gpu::GpuContext>),
}

impl Device {
    fn describe(&self) -> String {
        match self {
            Device::Cpu => format!(
                "cpu ({} threads)",
                std::thread::available_parallelism().map_or(1, |n| n.get())
            ),
            Device::Gpu(ctx) => format!("gpu: {}", ctx.info()),
        }
    }
}

/// Resolves `--device` for `scene`: `gpu` must find an adapter (the error
/// names the backends and adapters tried); `auto` takes a hardware GPU when
/// there is one and it renders the scene's method, else the CPU, and says
/// which. Triangle meshes in `geometry` are CPU-only (boxes and planes are
/// fine on the GPU).
fn pick_device(
    arg: args::DeviceArg,
    scene: &Scene,
    geometry: Option<&voxcast::geometry::Geometry>,
    quiet: bool,
) -> Result<Device> {
    use voxcast_gpu::{DeviceChoice, GpuContext, GpuError, GpuRenderer};
    match arg {
        args::DeviceArg::Cpu => Ok(Device::Cpu),
        args::DeviceArg::Gpu => {
            if !voxcast_gpu::supports(scene.render.method) {
                bail!(
                    "--device gpu: method `{}` is not implemented on the GPU (it renders uniform, adaptive, adaptive-max, threshold, jitter, stratified, mc and single-scatter); use --device cpu or auto",
                    scene.render.method.name()
                );
            }
            let ctx = GpuContext::new(DeviceChoice::Gpu).context("--device gpu")?;
            if !quiet {
                eprintln!("rendering on {}", ctx.info());
            }
            Ok(Device::Gpu(ctx))
        }
        args::DeviceArg::Auto => {
            if !voxcast_gpu::supports(scene.render.method) {
                if !quiet {
                    eprintln!(
                        "--device auto: method `{}` has no GPU version; rendering on the CPU",
                        scene.render.method.name()
                    );
                }
                return Ok(Device::Cpu);
            }
            if !GpuRenderer::supports_geometry(geometry) {
                if !quiet {
                    eprintln!(
                        "--device auto: triangle meshes have no GPU version; rendering on the CPU"
                    );
                }
                return Ok(Device::Cpu);
            }
            match GpuContext::new(DeviceChoice::Auto) {
                Ok(ctx) => {
                    if !quiet {
                        eprintln!("--device auto: rendering on {}", ctx.info());
                    }
                    Ok(Device::Gpu(ctx))
                }
                Err(GpuError::NoAdapter(why)) => {
                    if !quiet {
                        eprintln!("--device auto: {why}; rendering on the CPU");
                    }
                    Ok(Device::Cpu)
                }
                Err(e) => Err(e).context("--device auto"),
            }
        }
    }
}

/// Uploads the prepared volume to the GPU.
fn gpu_renderer(
    ctx: &std::sync::Arc<voxcast_gpu::GpuContext>,
    prepared: &voxcast::scene::Prepared,
) -> Result<voxcast_gpu::GpuRenderer> {
    let r = voxcast_gpu::GpuRenderer::new(ctx.clone(), &prepared.volume, prepared.window)
        .context("uploading the volume to the GPU")?
        .with_geometry(prepared.geometry.as_deref())?;
    Ok(r)
}

/// `voxcast bench --device gpu`: the methods rendered by the GPU.
struct GpuMethods<'a> {
    renderer: voxcast_gpu::GpuRenderer,
    scene: &'a Scene,
    tf: &'a voxcast::transfer::TransferFunction,
}

impl voxcast_bench::MethodRenderer for GpuMethods<'_> {
    fn render(
        &self,
        params: &voxcast::render::RenderParams,
    ) -> voxcast::Result<(Image, voxcast::RenderStats)> {
        self.renderer
            .render(self.tf, &self.scene.camera, params)
            .map_err(|e| voxcast::Error::invalid(e.to_string()))
    }
    fn device(&self) -> String {
        format!("gpu: {}", self.renderer.context().info())
    }
}

fn view(a: ViewArgs) -> Result<()> {
    let scene = a.scene()?;
    let mut outputs = Outputs::new([&scene.input.path]);
    if let Some(f) = &a.screenshot {
        outputs.plan("--screenshot", f, &["png"])?;
    }
    if let Some(f) = &a.save_scene {
        outputs.plan("--save-scene", f, &["toml"])?;
    }
    if let Some(f) = &a.stats_json {
        outputs.plan("--stats-json", f, &[])?;
    }
    if let Some(s) = a.orbit {
        if !(s.is_finite() && s > 0.0 && s <= 600.0) {
            bail!("--orbit {s}: expected seconds in (0, 600]");
        }
    }
    let scripted = a.screenshot.is_some() || a.exit_after_frames.is_some() || a.orbit.is_some();
    if !scripted && (a.save_scene.is_some() || a.stats_json.is_some()) {
        bail!("--save-scene and --stats-json belong to a scripted run: add --screenshot FILE, --exit-after-frames N or --orbit S (in the window, use the Save buttons)");
    }
    let backend = match a.device {
        args::DeviceArg::Cpu => voxcast_view::Backend::Cpu,
        args::DeviceArg::Gpu => {
            let ctx = voxcast_gpu::GpuContext::new(voxcast_gpu::DeviceChoice::Gpu)
                .context("--device gpu")?;
            eprintln!("view: rendering on {}", ctx.info());
            voxcast_view::Backend::Gpu(ctx)
        }
        args::DeviceArg::Auto => {
            match voxcast_gpu::GpuContext::new(voxcast_gpu::DeviceChoice::Auto) {
                Ok(ctx) => {
                    eprintln!("view: --device auto: rendering on {}", ctx.info());
                    voxcast_view::Backend::Gpu(ctx)
                }
                Err(voxcast_gpu::GpuError::NoAdapter(why)) => {
                    eprintln!("view: --device auto: {why}; rendering on the CPU");
                    voxcast_view::Backend::Cpu
                }
                Err(e) => return Err(e).context("--device auto"),
            }
        }
    };
    let options = voxcast_view::ViewOptions {
        backend,
        screenshot: a.screenshot.clone(),
        exit_after_frames: a.exit_after_frames,
        save_scene: a.save_scene.clone(),
        orbit: a.orbit,
    };
    let stats = voxcast_view::run(scene, options)?;
    if let Some(f) = &a.screenshot {
        eprintln!("wrote {}", f.display());
    }
    if let Some(f) = &a.save_scene {
        eprintln!("wrote {}", f.display());
    }
    if a.orbit.is_some() {
        let mut p = stats.preview_render_ms.clone();
        p.sort_by(f64::total_cmp);
        let median = p.get(p.len() / 2).copied().unwrap_or(f64::NAN);
        eprintln!(
            "{} {}×{}: {:.1} frames/s while moving ({} new images painted in {:.2} s, {:.1} UI frames/s; previews 1/{} = {}×{}, median {:.0} ms); refined image {} ms after the camera stopped (full render {} ms)",
            stats.backend,
            stats.view[0],
            stats.view[1],
            stats.fps_while_moving(),
            stats.frames_while_moving,
            stats.orbit_seconds,
            stats.ui_fps_while_moving(),
            stats.preview_divisor,
            stats.preview_size[0],
            stats.preview_size[1],
            median,
            stats
                .refined_after_stop_ms
                .map_or("?".into(), |t| format!("{t:.0}")),
            stats
                .full_render_ms
                .last()
                .map_or("?".into(), |t| format!("{t:.0}")),
        );
    }
    if let Some(f) = &a.stats_json {
        let json = serde_json::to_string_pretty(&stats)?;
        outputs.write(f, |w| writeln!(w, "{json}"))?;
    }
    outputs.commit()?;
    Ok(())
}

fn bench(a: BenchArgs) -> Result<()> {
    use voxcast_bench as bench;
    let methods = bench::parse_methods(&a.methods)?;
    if a.repeat == 0 {
        bail!("--repeat 0: at least one timed render per method is needed");
    }
    let scene = a.scene.scene()?;
    let mut outputs = Outputs::new([&scene.input.path]);
    if let Some(f) = &a.json {
        outputs.plan("--json", f, &[])?;
    }
    if let Some(f) = &a.chart {
        outputs.plan("--chart", f, &["png"])?;
    }
    let quiet = a.quiet;
    let t_load = Instant::now();
    let prepared = scene.prepare()?;
    outputs.check()?;
    if !quiet {
        eprintln!("{}", loaded(&scene, &prepared, t_load));
    }
    if let Some(target) = a.target_psnr {
        if a.device != args::DeviceArg::Cpu {
            bail!(
                "--target-psnr measures the CPU renderer only; drop --device or use --device cpu"
            );
        }
        if a.chart.is_some() {
            bail!("--chart draws the methods table; with --target-psnr, use --json");
        }
        return time_to_quality(&a, &scene, &prepared, methods, target, outputs);
    }
    // `auto` picks the CPU when any method has no GPU version; under `gpu`
    // such a method is reported as failed in the table (the baseline
    // `uniform` always renders).
    let mut device_scene = scene.clone();
    device_scene.render.method = voxcast::render::Method::Uniform;
    if a.device == args::DeviceArg::Auto {
        if let Some(m) = methods.iter().find(|m| !voxcast_gpu::supports(m.method)) {
            m.apply(&mut device_scene.render);
        }
    }
    let device = pick_device(a.device, &device_scene, prepared.geometry.as_deref(), quiet)?;
    let gpu = match &device {
        Device::Cpu => None,
        Device::Gpu(ctx) => Some(GpuMethods {
            renderer: gpu_renderer(ctx, &prepared)?,
            scene: &scene,
            tf: &prepared.tf,
        }),
    };
    let config = bench::BenchConfig {
        methods,
        repeat: a.repeat,
        warmup: a.warmup,
        cache_dir: Some(bench::default_cache_dir()),
        refresh_reference: a.refresh_reference,
    };
    let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::hidden());
    bar.set_style(
        ProgressStyle::with_template("{msg:<26} {bar:40.cyan/blue} {percent:>3}% {elapsed}<{eta}")
            .expect("valid template"),
    );
    if std::io::stderr().is_terminal() && !quiet {
        bar.set_draw_target(ProgressDrawTarget::stderr());
    }
    // The render whose name the bar shows (+1; 0 before the first).
    let current = AtomicUsize::new(0);
    let progress = |p: &bench::Progress<'_>| {
        bar.set_length((p.renders * p.total) as u64);
        bar.set_position((p.render * p.total + p.done) as u64);
        if current.swap(p.render + 1, Ordering::Relaxed) != p.render + 1 {
            bar.set_message(p.task.to_string());
        }
    };
    let report = bench::run_on(
        &scene,
        &prepared,
        &config,
        &progress,
        gpu.as_ref().map(|g| g as &dyn bench::MethodRenderer),
    )?;
    bar.finish_and_clear();
    if !quiet {
        let r = &report.reference;
        let file = r
            .cache_file
            .as_ref()
            .map(|f| f.display().to_string())
            .unwrap_or_else(|| "not cached".into());
        let how = match r.cache {
            bench::CacheStatus::Hit => "read from the cache",
            bench::CacheStatus::Miss => "rendered and cached",
            bench::CacheStatus::Refreshed => "rendered again and cached",
            bench::CacheStatus::Off => "rendered",
        };
        eprintln!("reference {how}: {file}");
    }
    if a.markdown {
        print!("{}", bench::markdown(&report));
    } else {
        print!("{}", bench::text_table(&report));
    }
    if let Some(f) = &a.json {
        let json = serde_json::to_string_pretty(&report)?;
        outputs.write(f, |w| writeln!(w, "{json}"))?;
    }
    if let Some(f) = &a.chart {
        let png = bench::chart::bench_png(&report).context("drawing the chart")?;
        outputs.write(f, |w| w.write_all(&png))?;
    }
    outputs.commit()?;
    let failures = report.failures();
    if !failures.is_empty() {
        let list: Vec<String> = failures.iter().map(|(m, e)| format!("{m}: {e}")).collect();
        bail!(
            "{} of {} methods failed to render — {}",
            failures.len(),
            report.methods.len(),
            list.join("; ")
        );
    }
    Ok(())
}

/// `voxcast bench --target-psnr`: time to quality per method.
fn time_to_quality(
    a: &BenchArgs,
    scene: &Scene,
    prepared: &voxcast::scene::Prepared,
    methods: Vec<voxcast::render::MethodSpec>,
    target: f64,
    mut outputs: Outputs,
) -> Result<()> {
    let mut methods = methods;
    if !methods.iter().any(|m| m.to_string() == "uniform")
        && !methods.iter().any(|m| m.method.is_physical())
    {
        methods.insert(0, voxcast::render::MethodSpec::parse("uniform")?);
    }
    let config = voxcast_bench::ttq::TtqConfig {
        methods,
        target_psnr: target,
        repeat: a.repeat,
        reference_spp: a.reference_spp,
        time_budget: a.time_budget,
    };
    let bar = ProgressBar::new_spinner();
    if !std::io::stderr().is_terminal() || a.quiet {
        bar.set_draw_target(ProgressDrawTarget::hidden());
    }
    let report = voxcast_bench::ttq::run(scene, prepared, &config, &|m: &str| {
        bar.set_message(m.to_string());
        bar.tick();
    })?;
    bar.finish_and_clear();
    print!("{}", voxcast_bench::ttq::markdown(&report));
    if let Some(f) = &a.json {
        let json = serde_json::to_string_pretty(&report)?;
        outputs.write(f, |w| writeln!(w, "{json}"))?;
    }
    outputs.commit()?;
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

fn info(a: InfoArgs) -> Result<()> {
    let mut scene = Scene::default();
    scene.input.path = a.input.clone();
    scene.input.options = a.open.options()?;
    let vol = scene.load_volume()?;
    // An FDS case: its meshes, quantities, times and obstructions.
    let fds = if a.input.to_ascii_lowercase().ends_with(".smv") {
        Some(voxcast::io::fds::parse_smv(Path::new(&a.input))?.summary())
    } else {
        None
    };
    // A WRF file: its 3D fields and times.
    let wrf = if voxcast::io::detect(Path::new(&a.input), &scene.input.options).ok()
        == Some(voxcast::io::Format::Wrf)
    {
        Some(voxcast::io::wrf::summary(Path::new(&a.input))?)
    } else {
        None
    };
    // A DICOM folder or file: the series found, their frames and transfer
    // syntaxes, and the files skipped.
    let dicom = if voxcast::io::detect(Path::new(&a.input), &scene.input.options).ok()
        == Some(voxcast::io::Format::Dicom)
    {
        Some(voxcast::io::dicom::summary(
            Path::new(&a.input),
            scene.input.options.variable.as_deref(),
        )?)
    } else {
        None
    };
    // NIfTI-1/2, Analyze, MGH, MINC: what the header says.
    let header = voxcast::io::header_summary(Path::new(&a.input), &scene.input.options)?;
    let s = *vol.stats();
    let hist = vol.histogram(256);
    let pct = [0.01, 0.05, 0.25, 0.5, 0.75, 0.95, 0.99].map(|q| (q, hist.quantile(q)));
    let d = vol.dims();
    let (lo, hi) = vol.world_bounds();
    if a.json {
        let coarse = vol.histogram(64);
        let j = serde_json::json!({
            "path": a.input,
            "name": vol.name,
            "dims": d,
            "scalar_type": vol.scalar_type().name(),
            "spacing": vol.spacing().to_array(),
            "origin": vol.origin().to_array(),
            "extent": [lo.to_array(), hi.to_array()],
            "units": vol.units,
            "min": s.min,
            "max": s.max,
            "mean": s.mean,
            "nan": s.nan,
            "inf": s.inf,
            "percentiles": pct.iter().map(|(q, v)| serde_json::json!({"q": q, "value": v})).collect::<Vec<_>>(),
            "histogram": {"lo": coarse.lo, "hi": coarse.hi, "counts": coarse.counts},
            "variables": vol.variables,
            "active_voxels": vol.active_voxels,
            "fds": fds,
            "wrf": wrf,
            "dicom": dicom,
            "header": header.as_ref().map(|(_, lines)| lines),
            "time": vol.time,
        });
        println!("{}", serde_json::to_string_pretty(&j)?);
        return Ok(());
    }
    println!("{}", a.input);
    if let Some(n) = &vol.name {
        println!("  name        {n}");
    }
    println!(
        "  dims        {} × {} × {}  ({} voxels, {:.1} MB)",
        d[0],
        d[1],
        d[2],
        vol.len(),
        (vol.len() * vol.scalar_type().size()) as f64 / 1e6
    );
    println!("  type        {}", vol.scalar_type());
    let sp = vol.spacing();
    let o = vol.origin();
    println!("  spacing     {} {} {}", sp.x, sp.y, sp.z);
    println!("  origin      {} {} {}", o.x, o.y, o.z);
    println!(
        "  extent      {:.4} … {:.4}, {:.4} … {:.4}, {:.4} … {:.4}",
        lo.x, hi.x, lo.y, hi.y, lo.z, hi.z
    );
    let units = vol
        .units
        .as_deref()
        .map(|u| format!(" {u}"))
        .unwrap_or_default();
    println!(
        "  range       {} … {}{units}  (mean {:.4})",
        s.min, s.max, s.mean
    );
    println!("  NaN / Inf   {} / {}", s.nan, s.inf);
    let p: Vec<String> = pct
        .iter()
        .map(|(q, v)| format!("p{}={}", (q * 100.0) as u32, v))
        .collect();
    println!("  percentiles {}", p.join("  "));
    println!(
        "  histogram   {}  (64 bins, log counts)",
        sparkline(&vol.histogram(64).counts)
    );
    if let Some(n) = vol.active_voxels {
        println!("  active      {n} voxels");
    }
    if let Some(lines) = &fds {
        println!("  FDS case");
        for l in lines {
            println!("    {l}");
        }
    }
    if let Some(lines) = &wrf {
        println!("  WRF output");
        for l in lines {
            println!("    {l}");
        }
    }
    if let Some((title, lines)) = &header {
        println!("  {title}");
        for l in lines {
            println!("    {l}");
        }
    }
    if let Some(lines) = &dicom {
        println!("  DICOM series");
        for l in lines {
            println!("    {l}");
        }
    }
    if let Some(t) = vol.time {
        println!("  time        {t}");
    }
    if !vol.variables.is_empty() {
        println!("  variables   {}", vol.variables.join(", "));
    }
    Ok(())
}

/// A one-line histogram of log counts.
fn sparkline(counts: &[u64]) -> String {
    const BARS: [char; 8] = ['▁', '▂', '▃', '▄', '▅', '▆', '▇', '█'];
    let max = counts.iter().copied().max().unwrap_or(0) as f64;
    counts
        .iter()
        .map(|&c| {
            if c == 0 {
                ' '
            } else {
                let f = (c as f64).ln_1p() / max.ln_1p().max(1e-9);
                BARS[((f * 7.0).round() as usize).min(7)]
            }
        })
        .collect()
}

fn compare(a: CompareArgs) -> Result<()> {
    // The library's errors name the file.
    let x = Image::read(&a.a)?;
    let y = Image::read(&a.b)?;
    let psnr = metrics::psnr(&x, &y)?;
    let ssim = metrics::ssim(&x, &y)?;
    if a.json {
        let j = serde_json::json!({
            "psnr_db": if psnr.is_finite() { Some(psnr) } else { None },
            "ssim": ssim,
            "identical": psnr.is_infinite(),
        });
        println!("{}", serde_json::to_string_pretty(&j)?);
    } else if psnr.is_infinite() {
        println!("PSNR inf dB (identical)  SSIM {ssim:.6}");
    } else {
        println!("PSNR {psnr:.3} dB  SSIM {ssim:.6}");
    }
    Ok(())
}

fn presets() {
    println!("Transfer-function presets (--tf NAME):");
    println!(
        "  {:<16} chosen from the data's histogram (the default)",
        "auto"
    );
    for (n, d) in voxcast::transfer::PRESETS {
        println!("  {n:<16} {d}");
    }
    println!("\nBuilt-in volumes (INPUT = builtin:NAME):");
    for (n, d) in voxcast::builtin::BUILTINS {
        println!("  {n:<16} {d}");
    }
}
