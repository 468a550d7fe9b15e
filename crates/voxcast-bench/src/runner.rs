//! The bench run: the reference rendered (or read from the cache), then the
//! methods' warm-up and timed renders interleaved round by round, each
//! compared with the reference, gathered into a [`BenchReport`].

use crate::quality::{self, QualityChoice};
use crate::reference::{
    cache_paths, load_cached, reference_key, reference_params, store_cached, CacheMeta,
    REFERENCE_FORMAT,
};
use crate::report::{
    input_label, BenchReport, CacheStatus, Machine, Measured, MethodResult, ReferenceInfo, RunInfo,
    SceneInfo,
};
use crate::{median, method_params, BenchConfig, Progress};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;
use voxcast::error::{Error, Result};
use voxcast::image::Image;
use voxcast::metrics;
use voxcast::render::{Method, MethodSpec, RenderParams, RenderStats, Renderer};
use voxcast::scene::{Prepared, Scene};

struct Slot {
    spec: MethodSpec,
    added: bool,
    params: RenderParams,
    /// The setting `--quality` chose.
    quality: Option<QualityChoice>,
    times: Vec<f64>,
    /// The device's own milliseconds per timed render (GPU timestamps).
    device_times: Vec<f64>,
    stats: Option<RenderStats>,
    /// PSNR and SSIM of the first image against the reference (each image
    /// is compared as soon as it exists, so none is kept).
    error_metrics: Option<(f64, f64)>,
    error: Option<String>,
}

/// Renders every method of `config` on `scene` (already loaded as
/// `prepared`), the reference (or reads it from the cache), and compares.
/// `progress` is called after every tile of every render, from the render's
/// threads.
///
/// Invalid parameters fail before anything renders. A method whose render
/// fails is reported with its error and the others still run; the baseline
/// `uniform` failing fails the run.
pub fn run(
    scene: &Scene,
    prepared: &Prepared,
    config: &BenchConfig,
    progress: &(dyn Fn(&Progress<'_>) + Sync),
) -> Result<BenchReport> {
    run_on(scene, prepared, config, progress, None)
}

/// A back end that renders the methods under test in place of the CPU
/// [`Renderer`] (the GPU renderer of `voxcast-gpu`); the reference is always
/// the CPU's, so the PSNR column also measures the back end's parity.
pub trait MethodRenderer: Sync {
    /// Renders the prepared scene's volume with `params` (and the scene's
    /// transfer function and camera).
    fn render(&self, params: &RenderParams) -> Result<(Image, RenderStats)>;
    /// The device in words, for the report.
    fn device(&self) -> String;
}

/// [`run`] with the methods rendered by `methods_on` (`None`: the CPU).
pub fn run_on(
    scene: &Scene,
    prepared: &Prepared,
    config: &BenchConfig,
    progress: &(dyn Fn(&Progress<'_>) + Sync),
    methods_on: Option<&dyn MethodRenderer>,
) -> Result<BenchReport> {
    run_cancellable(
        scene,
        prepared,
        config,
        progress,
        methods_on,
        &AtomicBool::new(false),
    )
}

/// [`run_on`] that stops with [`Error::Cancelled`] once `cancel` is raised
/// (from another thread): a CPU render stops within a tile, a GPU render
/// at its end.
pub fn run_cancellable(
    scene: &Scene,
    prepared: &Prepared,
    config: &BenchConfig,
    progress: &(dyn Fn(&Progress<'_>) + Sync),
    methods_on: Option<&dyn MethodRenderer>,
    cancel: &AtomicBool,
) -> Result<BenchReport> {
    if config.repeat == 0 {
        return Err(Error::invalid("repeat must be at least 1"));
    }
    if config.methods.is_empty() {
        return Err(Error::invalid("no method to measure"));
    }
    let mut notes = Vec::new();
    let baseline = MethodSpec {
        method: Method::Uniform,
        grouped: false,
        no_skip: false,
    };
    let mut specs: Vec<(MethodSpec, bool)> = Vec::new();
    for s in &config.methods {
        if specs.iter().any(|(t, _)| t == s) {
            notes.push(format!("`{s}` was named twice; it is measured once"));
        } else {
            specs.push((*s, false));
        }
    }
    if !specs.iter().any(|(s, _)| *s == baseline) {
        specs.insert(0, (baseline, true));
        notes.push("`uniform` was added: it is the baseline of the speed-ups".into());
    }
    let mut slots = Vec::with_capacity(specs.len());
    for (spec, added) in specs {
        let params = method_params(&scene.render, &spec);
        params
            .validate()
            .map_err(|e| Error::invalid(format!("method `{spec}`: {e}")))?;
        slots.push(Slot {
            spec,
            added,
            params,
            quality: None,
            times: Vec::new(),
            device_times: Vec::new(),
            stats: None,
            error_metrics: None,
            error: None,
        });
    }
    let ref_params = reference_params(&scene.render);
    ref_params.validate()?;

    let t = Instant::now();
    let renderer =
        Renderer::new(&prepared.volume, prepared.window)?.with_geometry(prepared.geometry.clone());
    let setup_ms = t.elapsed().as_secs_f64() * 1e3;

    // `--quality`: each method's setting from its pilot (on the CPU, which
    // the GPU matches), before anything is timed.
    if let Some(target) = config.quality {
        let pilot = |p: &RenderParams| {
            renderer.render_cancellable(&prepared.tf, &scene.camera, p, &|_, _| {}, cancel)
        };
        for slot in slots.iter_mut() {
            let spec = slot.spec.to_string();
            let choice =
                quality::choose(&slot.params, target, quality::PILOT_PIXELS, &pilot, &|_| {});
            if cancel.load(Ordering::Relaxed) {
                return Err(Error::Cancelled);
            }
            let choice = choice.map_err(|e| Error::invalid(format!("method `{spec}`: {e}")))?;
            slot.params = choice.params.clone();
            slot.quality = Some(choice);
        }
    }

    let key = reference_key(scene, prepared);
    let cached = match &config.cache_dir {
        Some(dir) if !config.refresh_reference => {
            load_cached(dir, key, ref_params.width, ref_params.height)
        }
        _ => None,
    };
    let renders = usize::from(cached.is_none()) + slots.len() * (config.warmup + config.repeat);
    let render_one = |index: usize, task: &str, params: &RenderParams| {
        let tick = |done: usize, total: usize| {
            progress(&Progress {
                task,
                render: index,
                renders,
                done,
                total,
            })
        };
        let t = Instant::now();
        let r = renderer.render_cancellable(&prepared.tf, &scene.camera, params, &tick, cancel);
        let ms = t.elapsed().as_secs_f64() * 1e3;
        r.map(|(img, stats)| (img, stats, ms))
    };
    let render_method = |index: usize, task: &str, params: &RenderParams| match methods_on {
        None => render_one(index, task, params),
        Some(m) => {
            let t = Instant::now();
            let r = m.render(params);
            let ms = t.elapsed().as_secs_f64() * 1e3;
            progress(&Progress {
                task,
                render: index,
                renders,
                done: 1,
                total: 1,
            });
            r.map(|(img, stats)| (img, stats, ms))
        }
    };
    if let Some(m) = methods_on {
        notes.push(format!(
            "methods rendered on {}; the reference on the CPU",
            m.device()
        ));
    }
    let mut index = 0usize;

    // The reference.
    let (ref_image, ref_ms, ref_stats, cache, cache_file) = match cached {
        Some((img, meta)) => (
            img,
            meta.ms,
            meta.stats,
            CacheStatus::Hit,
            config.cache_dir.as_ref().map(|d| cache_paths(d, key).0),
        ),
        None => {
            let r = render_one(index, "reference", &ref_params);
            if cancel.load(Ordering::Relaxed) {
                return Err(Error::Cancelled);
            }
            let (img, stats, ms) =
                r.map_err(|e| Error::invalid(format!("reference render: {e}")))?;
            index += 1;
            let (cache, file) = match &config.cache_dir {
                Some(dir) => {
                    let mut s = scene.resolved(prepared);
                    s.render = ref_params.clone();
                    let meta = CacheMeta {
                        key: format!("{key:016x}"),
                        format: REFERENCE_FORMAT.into(),
                        ms,
                        stats,
                        scene: toml::to_string(&s).unwrap_or_default(),
                    };
                    match store_cached(dir, key, &img, &meta) {
                        Ok(f) if config.refresh_reference => (CacheStatus::Refreshed, Some(f)),
                        Ok(f) => (CacheStatus::Miss, Some(f)),
                        Err(e) => {
                            notes.push(format!("the reference could not be cached: {e}"));
                            (CacheStatus::Off, None)
                        }
                    }
                }
                None => (CacheStatus::Off, None),
            };
            (img, ms, stats, cache, file)
        }
    };

    // Warm-up, then the timed rounds, methods interleaved.
    let rounds = (0..config.warmup)
        .map(|_| None)
        .chain((0..config.repeat).map(Some));
    for round in rounds {
        for slot in slots.iter_mut() {
            if slot.error.is_some() {
                index += 1;
                continue;
            }
            let task = match round {
                None => format!("{} (warm-up)", slot.spec),
                Some(r) => format!("{} {}/{}", slot.spec, r + 1, config.repeat),
            };
            let result = render_method(index, &task, &slot.params);
            index += 1;
            if cancel.load(Ordering::Relaxed) {
                return Err(Error::Cancelled);
            }
            match result {
                Ok((img, stats, ms)) => {
                    if round.is_some() {
                        slot.times.push(ms);
                        if let Some(d) = stats.device_seconds {
                            slot.device_times.push(d * 1e3);
                        }
                    }
                    if slot.error_metrics.is_none() {
                        let psnr = metrics::psnr(&img, &ref_image)?;
                        let ssim = metrics::ssim(&img, &ref_image)?;
                        slot.error_metrics = Some((psnr, ssim));
                        slot.stats = Some(stats);
                    }
                }
                Err(e) => {
                    if slot.spec == baseline {
                        return Err(Error::invalid(format!("method `uniform`: {e}")));
                    }
                    slot.error = Some(e.to_string());
                    slot.error_metrics = None;
                    slot.stats = None;
                }
            }
        }
    }

    let base = slots
        .iter()
        .find(|s| s.spec == baseline)
        .expect("the baseline is in the list");
    let base_ms = median(&base.times);
    let base_stats = base.stats.expect("the baseline rendered");
    let ratio = |a: u64, b: u64| if b > 0 { a as f64 / b as f64 } else { f64::NAN };
    let mut methods = Vec::with_capacity(slots.len());
    for slot in &slots {
        let measured = match (slot.error_metrics, &slot.stats, &slot.error) {
            (Some((psnr, ssim)), Some(st), None) => {
                let ms_median = median(&slot.times);
                Some(Measured {
                    samples: st.samples,
                    interpolations: st.interpolations,
                    gradient_interpolations: st.gradient_interpolations,
                    rays: st.rays,
                    rays_hit: st.rays_hit,
                    early_terminated: st.early_terminated,
                    ms_median,
                    ms_min: slot.times.iter().copied().fold(f64::INFINITY, f64::min),
                    ms_max: slot.times.iter().copied().fold(0.0, f64::max),
                    ms_per_repeat: slot.times.clone(),
                    device_ms_median: (!slot.device_times.is_empty()
                        && slot.device_times.len() == slot.times.len())
                    .then(|| median(&slot.device_times)),
                    device_ms_per_repeat: slot.device_times.clone(),
                    speedup_vs_uniform: base_ms / ms_median,
                    samples_vs_uniform: ratio(st.samples, base_stats.samples),
                    interpolations_vs_uniform: ratio(st.interpolations, base_stats.interpolations),
                    psnr_db: psnr,
                    identical: psnr.is_infinite(),
                    ssim,
                    simd: st.simd.map(|l| l.name()),
                    skipping_left_out: st.skipping_left_out,
                    block_size: st.block_size,
                })
            }
            _ => None,
        };
        methods.push(MethodResult {
            name: slot.spec.to_string(),
            method: slot.spec.method.name().to_string(),
            grouped: slot.spec.grouped,
            added_as_baseline: slot.added,
            quality: slot.quality.clone(),
            measured,
            error: slot.error.clone(),
        });
    }

    let v = &prepared.volume;
    let r = &scene.render;
    Ok(BenchReport {
        scene: SceneInfo {
            input: scene.input.path.clone(),
            label: input_label(&scene.input.path),
            dims: v.dims(),
            scalar_type: v.scalar_type().name().to_string(),
            width: r.width,
            height: r.height,
            tf: if scene.transfer.map.is_some() {
                "inline".into()
            } else {
                scene.transfer.tf.clone()
            },
            window: prepared.window,
            step: r.step,
            ert: r.ert,
            shading: r.shading,
            skip_empty: r.skip_empty,
            jitter: r.jitter,
            azimuth: scene.camera.azimuth,
            elevation: scene.camera.elevation,
            zoom: scene.camera.zoom,
        },
        machine: Machine::this(),
        run: RunInfo {
            repeat: config.repeat,
            warmup: config.warmup,
            setup_ms,
            timer: if methods_on.is_some() {
                "wall-clock ms around the back end's render (upload of the camera and transfer function, compute, read-back), renderer built once"
            } else {
                "wall-clock ms around Renderer::render, renderer built once"
            },
            device: methods_on.map_or_else(|| "cpu".to_string(), |m| m.device()),
            simd: scene.render.simd,
            voxcast_version: env!("CARGO_PKG_VERSION"),
        },
        reference: ReferenceInfo {
            method: ref_params.method.name().into(),
            step: ref_params.step,
            ert: ref_params.ert,
            skip_empty: ref_params.skip_empty,
            jitter: ref_params.jitter,
            grouped: ref_params.grouped,
            ms: ref_ms,
            samples: ref_stats.samples,
            interpolations: ref_stats.interpolations,
            rays: ref_stats.rays,
            cache,
            cache_file,
            key: format!("{key:016x}"),
        },
        methods,
        notes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{markdown, parse_methods, text_table};

    #[test]
    fn run_measures_every_method_and_caches_the_reference() {
        let dir = tempfile::tempdir().unwrap();
        let mut scene = Scene::default();
        scene.input.path = "builtin:sphere".into();
        scene.render.width = 24;
        scene.render.height = 16;
        let prepared = scene.prepare().unwrap();
        let config = BenchConfig {
            methods: parse_methods("adaptive,uniform+grouped").unwrap(),
            repeat: 2,
            warmup: 0,
            cache_dir: Some(dir.path().to_path_buf()),
            refresh_reference: false,
            quality: None,
        };
        let calls = std::sync::atomic::AtomicUsize::new(0);
        let last = std::sync::Mutex::new((0, 0));
        let progress = |p: &Progress<'_>| {
            calls.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            assert!(p.render < p.renders && p.done <= p.total);
            *last.lock().unwrap() = (p.render, p.renders);
        };
        let r = run(&scene, &prepared, &config, &progress).unwrap();
        // uniform added first as the baseline, then the two named.
        let names: Vec<&str> = r.methods.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names[0], "uniform");
        assert!(r.methods[0].added_as_baseline);
        assert_eq!(names.len(), 3);
        assert!(!r.notes.is_empty());
        assert_eq!(r.reference.cache, CacheStatus::Miss);
        assert!(calls.into_inner() > 0);
        // 1 reference + 3 methods × 2 timed renders; the last is the last.
        assert_eq!(*last.lock().unwrap(), (6, 7));
        let u = r.methods[0].measured.as_ref().unwrap();
        assert_eq!(u.speedup_vs_uniform, 1.0);
        assert_eq!(u.ms_per_repeat.len(), 2);
        assert!(u.ms_min <= u.ms_median && u.ms_median <= u.ms_max);
        assert!(u.samples > 0 && u.psnr_db > 20.0 && u.ssim > 0.5);
        // The second run reads the reference back, bit for bit.
        let again = run(&scene, &prepared, &config, &|_| {}).unwrap();
        assert_eq!(again.reference.cache, CacheStatus::Hit);
        assert_eq!(again.reference.samples, r.reference.samples);
        let u2 = again.methods[0].measured.as_ref().unwrap();
        assert_eq!(u2.psnr_db, u.psnr_db);
        let md = markdown(&again);
        assert!(md.contains("| method | samples |"), "{md}");
        assert!(text_table(&again).contains("speed-up"));
        let json = serde_json::to_value(&again).unwrap();
        assert!(json["methods"][0]["psnr_db"].is_number());
    }
}
