//! Renders, benches and image files: the long work runs with the GIL
//! released on a worker thread while the calling thread watches for Ctrl-C
//! and feeds a Python progress callback.

use crate::err;
use crate::scene::Scene;
use crate::volume::Volume;
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Duration;
use voxcast::files::Outputs;
use voxcast::image::Image;
use voxcast::scene::Prepared;
use voxcast_gpu::{Device, DeviceRequest};

/// How often the waiting thread looks for Ctrl-C and reports progress.
const POLL: Duration = Duration::from_millis(50);

/// Runs `work` on a worker thread with the GIL released. Meanwhile this
/// thread, every [`POLL`], takes the GIL back briefly to check for signals
/// (Ctrl-C raises `cancel`, which the renderer reads once per tile) and to
/// call `progress(done, total)` when the work reported new figures. A
/// callback that raises cancels too; its exception is what Python sees.
fn detached<T: Send>(
    py: Python<'_>,
    progress: Option<&Bound<'_, PyAny>>,
    work: impl FnOnce(&(dyn Fn(usize, usize) + Sync), &AtomicBool) -> voxcast::Result<T> + Send,
) -> PyResult<T> {
    let callback = progress.map(|p| p.clone().unbind());
    let cancel = AtomicBool::new(false);
    let (done, total) = (AtomicUsize::new(0), AtomicUsize::new(0));
    let report = |d: usize, t: usize| {
        done.store(d, Ordering::Relaxed);
        total.store(t, Ordering::Relaxed);
    };
    let (joined, raised) = py.detach(|| {
        std::thread::scope(|s| {
            // The worker wakes this thread when it ends, so no render waits
            // out the rest of a poll interval.
            let waiter = std::thread::current();
            let (report, stop) = (&report, &cancel);
            let worker = s.spawn(move || {
                let r = work(report, stop);
                waiter.unpark();
                r
            });
            let mut raised: Option<PyErr> = None;
            let mut last = (0, 0);
            while !worker.is_finished() {
                std::thread::park_timeout(POLL);
                if raised.is_some() {
                    continue;
                }
                Python::attach(|py| {
                    if let Err(e) = py.check_signals() {
                        raised = Some(e);
                    } else if let Some(cb) = &callback {
                        let now = (done.load(Ordering::Relaxed), total.load(Ordering::Relaxed));
                        if now != last && now.1 > 0 {
                            last = now;
                            if let Err(e) = cb.call1(py, now) {
                                raised = Some(e);
                            }
                        }
                    }
                });
                if raised.is_some() {
                    cancel.store(true, Ordering::Relaxed);
                }
            }
            (worker.join(), raised)
        })
    });
    if let Some(e) = raised {
        return Err(e);
    }
    match joined {
        Ok(r) => r.map_err(err),
        Err(panic) => {
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_default();
            Err(err(format!(
                "internal error (please report it): the render stopped: {what}"
            )))
        }
    }
}

/// The scene with its volume: the given one (shared, not copied), or the
/// scene's input read now.
fn prepare(py: Python<'_>, scene: &voxcast::Scene, volume: Option<&Volume>) -> PyResult<Prepared> {
    let volume = volume.map(|v| v.volume());
    py.detach(|| match volume {
        Some(v) => scene.prepare_with(v),
        None => scene.prepare(),
    })
    .map_err(err)
}

/// An (H, W, 4) float32 array of the image's linear RGBA pixels.
fn pixels<'py>(py: Python<'py>, image: &Image) -> PyResult<Bound<'py, PyAny>> {
    let flat = PyArray1::from_slice(py, image.pixels.as_flattened());
    Ok(flat
        .reshape([image.height as usize, image.width as usize, 4])?
        .into_any())
}

/// An image from an (H, W, 4) (or (H, W, 3), opaque) float32 array.
fn image_of(a: &PyReadonlyArray3<'_, f32>) -> PyResult<Image> {
    let s = a.shape();
    let (h, w, c) = (s[0], s[1], s[2]);
    if c != 3 && c != 4 {
        return Err(err(format!(
            "image of shape {s:?}: expected (height, width, 4) or (height, width, 3)"
        )));
    }
    if h == 0 || w == 0 || h > u32::MAX as usize || w > u32::MAX as usize {
        return Err(err(format!("image of shape {s:?}: empty or too large")));
    }
    let v = a.as_array();
    let mut img = Image::new(w as u32, h as u32);
    for ((y, x), p) in (0..h)
        .flat_map(|y| (0..w).map(move |x| (y, x)))
        .zip(img.pixels.iter_mut())
    {
        for (ch, out) in p.iter_mut().enumerate() {
            *out = if ch < c { v[[y, x, ch]] } else { 1.0 };
        }
    }
    Ok(img)
}

/// Renders `scene` (with `volume` in place of its input when given) on
/// `device` (`cpu`, `gpu` or `auto`). Returns the (H, W, 4) float32 linear
/// RGBA pixels, the statistics as JSON, the device in words and the note of
/// the device choice.
#[pyfunction]
#[pyo3(signature = (scene, volume=None, device="cpu", progress=None))]
pub fn render<'py>(
    py: Python<'py>,
    scene: &Scene,
    volume: Option<&Volume>,
    device: &str,
    progress: Option<&Bound<'py, PyAny>>,
) -> PyResult<(Bound<'py, PyAny>, String, String, Option<String>)> {
    let scene = &scene.inner;
    let request = DeviceRequest::parse(device).ok_or_else(|| {
        err(format!(
            "device {device:?}: expected \"cpu\", \"gpu\" or \"auto\""
        ))
    })?;
    let prepared = prepare(py, scene, volume)?;
    let choice = py
        .detach(|| {
            voxcast_gpu::choose(
                request,
                &[scene.render.method],
                prepared.geometry.as_deref(),
            )
        })
        .map_err(|e| err(format!("device {device:?}: {e}")))?;
    let (image, stats) = match &choice.device {
        Device::Cpu => detached(py, progress, |report, cancel| {
            voxcast::render::Renderer::new(&prepared.volume, prepared.window)?
                .with_geometry(prepared.geometry.clone())
                .render_cancellable(&prepared.tf, &scene.camera, &scene.render, report, cancel)
        })?,
        Device::Gpu(ctx) => py
            .detach(|| {
                voxcast_gpu::GpuRenderer::new(ctx.clone(), &prepared.volume, prepared.window)?
                    .with_geometry(prepared.geometry.as_deref())?
                    .render(&prepared.tf, &scene.camera, &scene.render)
            })
            .map_err(|e| err(format!("rendering on the GPU: {e}")))?,
    };
    let mut stats_json = serde_json::to_value(stats).map_err(err)?;
    if let serde_json::Value::Object(m) = &mut stats_json {
        m.insert("device".into(), choice.device.describe().into());
    }
    Ok((
        pixels(py, &image)?,
        stats_json.to_string(),
        choice.device.describe(),
        choice.note,
    ))
}

/// Times `methods` (a comma-separated list as `voxcast bench --methods`
/// takes it; the default list when `None`) on the CPU against a converged
/// reference. Returns the report as JSON and the table as text. Ctrl-C
/// stops it within a tile, as a render.
#[pyfunction]
#[pyo3(signature = (scene, volume=None, methods=None, repeat=5, warmup=1, quality=None, cache=true, progress=None))]
#[allow(clippy::too_many_arguments)]
pub fn bench<'py>(
    py: Python<'py>,
    scene: &Scene,
    volume: Option<&Volume>,
    methods: Option<&str>,
    repeat: usize,
    warmup: usize,
    quality: Option<f64>,
    cache: bool,
    progress: Option<&Bound<'py, PyAny>>,
) -> PyResult<(String, String)> {
    let scene = &scene.inner;
    let config = voxcast_bench::BenchConfig {
        methods: match methods {
            Some(m) => voxcast_bench::parse_methods(m).map_err(err)?,
            None => voxcast_bench::default_methods(),
        },
        repeat,
        warmup,
        cache_dir: cache.then(voxcast_bench::default_cache_dir),
        refresh_reference: false,
        quality,
    };
    let prepared = prepare(py, scene, volume)?;
    let report = detached(py, progress, |report, cancel| {
        // Progress in thousandths of a render, over all renders of the run.
        let each = |p: &voxcast_bench::Progress<'_>| {
            report(
                p.render * 1000 + p.done * 1000 / p.total.max(1),
                p.renders.max(1) * 1000,
            )
        };
        voxcast_bench::run_cancellable(scene, &prepared, &config, &each, None, cancel)
    })?;
    let json = serde_json::to_string(&report).map_err(err)?;
    Ok((json, voxcast_bench::text_table(&report)))
}

/// Writes an (H, W, 4) float32 linear image as PNG (8-bit sRGB, the CLI's
/// encoder) or EXR (linear float) by the extension, atomically; refuses to
/// write onto `source` (the volume's file).
#[pyfunction]
#[pyo3(signature = (pixels, path, source=None))]
pub fn write_image(
    py: Python<'_>,
    pixels: PyReadonlyArray3<'_, f32>,
    path: PathBuf,
    source: Option<String>,
) -> PyResult<()> {
    let image = image_of(&pixels)?;
    let mut outputs = Outputs::new(source.iter());
    outputs.plan("path", &path, &["png", "exr"]).map_err(err)?;
    py.detach(|| {
        image.write_into(&mut outputs, &path)?;
        outputs.commit()
    })
    .map_err(err)
}

/// The bytes of the PNG `write_image` would write.
#[pyfunction]
pub fn png_bytes<'py>(
    py: Python<'py>,
    pixels: PyReadonlyArray3<'_, f32>,
) -> PyResult<Bound<'py, PyBytes>> {
    let bytes = image_of(&pixels)?.png_bytes().map_err(err)?;
    Ok(PyBytes::new(py, &bytes))
}

/// The image's RGB as 8-bit sRGB bytes, row by row (what the PNG holds).
#[pyfunction]
pub fn srgb8<'py>(
    py: Python<'py>,
    pixels: PyReadonlyArray3<'_, f32>,
) -> PyResult<Bound<'py, PyBytes>> {
    Ok(PyBytes::new(py, &image_of(&pixels)?.to_srgb8()))
}

/// Writes frames ((H, W, 4) float32 linear images of one size) as a
/// looping GIF at `fps`, as `voxcast animate` does, atomically.
#[pyfunction]
#[pyo3(signature = (frames, path, fps=12.0, source=None))]
pub fn write_gif(
    py: Python<'_>,
    frames: Vec<PyReadonlyArray3<'_, f32>>,
    path: PathBuf,
    fps: f64,
    source: Option<String>,
) -> PyResult<()> {
    if !(fps.is_finite() && fps > 0.0) {
        return Err(err(format!("fps {fps}: expected a positive number")));
    }
    let images = frames.iter().map(image_of).collect::<PyResult<Vec<_>>>()?;
    let Some(first) = images.first() else {
        return Err(err("no frames to write"));
    };
    let (w, h) = (first.width, first.height);
    if images.iter().any(|i| (i.width, i.height) != (w, h)) {
        return Err(err(
            "frames of different sizes: a GIF's frames share one size",
        ));
    }
    if w > u16::MAX as u32 || h > u16::MAX as u32 {
        return Err(err("GIF frames are at most 65535 pixels wide and high"));
    }
    let mut outputs = Outputs::new(source.iter());
    outputs.plan("path", &path, &["gif"]).map_err(err)?;
    let delay = (100.0 / fps).round().max(2.0) as u16;
    py.detach(|| {
        outputs.write(&path, |out| {
            let mut enc =
                gif::Encoder::new(out, w as u16, h as u16, &[]).map_err(std::io::Error::other)?;
            enc.set_repeat(gif::Repeat::Infinite)
                .map_err(std::io::Error::other)?;
            for img in &images {
                // NeuQuant palette per frame (speed 10), as `voxcast animate`.
                let mut f = gif::Frame::from_rgb_speed(w as u16, h as u16, &img.to_srgb8(), 10);
                f.delay = delay;
                enc.write_frame(&f).map_err(std::io::Error::other)?;
            }
            Ok(())
        })?;
        outputs.commit()
    })
    .map_err(err)
}
