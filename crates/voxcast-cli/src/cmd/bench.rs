//! `voxcast bench`: the methods table (CPU or GPU), or time to quality
//! with `--target-psnr`.

use super::device::{gpu_renderer, pick_device};
use super::render::prepare;
use crate::args::{BenchArgs, DeviceArg};
use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::{IsTerminal, Write};
use std::sync::atomic::{AtomicUsize, Ordering};
use voxcast::files::Outputs;
use voxcast::scene::Scene;
use voxcast::Image;
use voxcast_gpu::Device;

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

pub fn run(a: BenchArgs) -> Result<()> {
    use voxcast_bench as bench;
    let methods = bench::parse_methods(&a.methods)?;
    if a.repeat == 0 {
        bail!("--repeat 0: at least one timed render per method is needed");
    }
    let scene = a.scene.scene()?;
    let mut outputs = Outputs::new([&scene.input.path]);
    outputs.plan_optional("--json", a.json.as_deref(), &[])?;
    outputs.plan_optional("--chart", a.chart.as_deref(), &["png"])?;
    let quiet = a.quiet;
    let prepared = prepare(&scene, &mut outputs, quiet)?;
    if !a.target_psnr.is_empty() {
        if a.device != DeviceArg::Cpu {
            bail!(
                "--target-psnr measures the CPU renderer only; drop --device or use --device cpu"
            );
        }
        if a.chart.is_some() {
            bail!("--chart draws the methods table; with --target-psnr, use --json");
        }
        return time_to_quality(&a, &scene, &prepared, methods, outputs);
    }
    // `auto` picks the CPU when any method has no GPU version; under `gpu`
    // such a method is reported as failed in the table (the baseline
    // `uniform` always renders), so none is passed.
    let needs: Vec<_> = match a.device {
        DeviceArg::Auto => methods.iter().map(|m| m.method).collect(),
        _ => Vec::new(),
    };
    let device = pick_device(a.device, &needs, prepared.geometry.as_deref(), quiet)?;
    let gpu = match &device {
        Device::Cpu => None,
        Device::Gpu(ctx) => Some(GpuMethods {
            renderer: gpu_renderer(ctx, &prepared, a.gpu_filter.into(), quiet)?,
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
        quality: a.quality,
    };
    if let (Some(q), false) = (a.quality, quiet) {
        eprintln!(
            "--quality {q} dB: a pilot per method picks its setting before the timed renders"
        );
    }
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
    let mut report = bench::run_on(
        &scene,
        &prepared,
        &config,
        &progress,
        gpu.as_ref().map(|g| g as &dyn bench::MethodRenderer),
    )?;
    bar.finish_and_clear();
    if let Some(g) = &gpu {
        let r = &g.renderer;
        let [wx, wy] = r.workgroup();
        report.notes.push(format!(
            "GPU: {} texture, {} filter, {} pipeline, workgroup {wx}×{wy}; set-up once, not timed above (volume converted and uploaded, pipeline built, block grid): {:.1} ms",
            r.texture_format(),
            match r.filter() {
                voxcast_gpu::Filter::Hardware => "hardware (texture unit)",
                _ => "exact",
            },
            if r.specialises() {
                "specialised per method"
            } else {
                "generic"
            },
            r.setup_seconds() * 1e3
        ));
    }
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
        for m in &report.methods {
            if let Some(q) = &m.quality {
                eprintln!("{}: {}", m.name, q.describe());
            }
        }
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
    mut outputs: Outputs,
) -> Result<()> {
    let mut methods = methods;
    if !methods.iter().any(|m| m.to_string() == "uniform")
        && !methods.iter().any(|m| m.method.is_physical())
    {
        methods.insert(0, voxcast::render::MethodSpec::parse("uniform")?);
    }
    let targets = &a.target_psnr;
    let config = voxcast_bench::ttq::TtqConfig {
        methods,
        target_psnr: targets[0],
        repeat: a.repeat,
        reference_spp: a.reference_spp,
        time_budget: a.time_budget,
    };
    let bar = ProgressBar::new_spinner();
    if !std::io::stderr().is_terminal() || a.quiet {
        bar.set_draw_target(ProgressDrawTarget::hidden());
    }
    let reports =
        voxcast_bench::ttq::run_targets(scene, prepared, &config, targets, &|m: &str| {
            bar.set_message(m.to_string());
            bar.tick();
        })?;
    bar.finish_and_clear();
    for (i, report) in reports.iter().enumerate() {
        if i > 0 {
            println!();
        }
        print!("{}", voxcast_bench::ttq::markdown(report));
    }
    if let Some(f) = &a.json {
        // One target: its report, as before; several: an array of them.
        let json = match reports.as_slice() {
            [one] => serde_json::to_string_pretty(one)?,
            all => serde_json::to_string_pretty(all)?,
        };
        outputs.write(f, |w| writeln!(w, "{json}"))?;
    }
    outputs.commit()?;
    Ok(())
}
