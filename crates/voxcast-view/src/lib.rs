//! The interactive viewer of voxcast (`voxcast view`): a window showing a
//! volume that turns with the mouse, with a transfer-function editor over
//! the data's histogram, the renderer's options, a time slider for series,
//! and screenshot/scene saving such that `voxcast render --scene` draws
//! exactly what is on screen.
//!
//! The window is egui on wgpu (eframe); the frames come from a
//! [`backend::FrameRenderer`] on a worker thread ([`worker`]), refined
//! progressively ([`progressive`]). The parts with logic of their own —
//! the transfer-function model ([`tf_model`]), the camera controller
//! ([`camera_ctl`]), the scheduler, the screenshot crop — need no window and
//! are tested without one. A multi-resolution store opens at its coarsest
//! level and refines as finer levels are read ([`levels`]).

mod app;
pub mod backend;
pub mod camera_ctl;
mod image_paint;
pub mod levels;
pub mod progressive;
pub mod screenshot;
pub mod stream;
pub mod tf_model;
mod tf_widget;
pub mod worker;

pub use voxcast_gpu::Device;

use levels::Pyramid;
use serde::Serialize;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use voxcast::io::Series;
use voxcast::scene::{Scene, BUILTIN_PREFIX};

/// Errors of the viewer.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    /// Loading or preparing the scene failed.
    #[error(transparent)]
    Scene(#[from] voxcast::Error),
    /// The window could not be opened.
    #[error("cannot open the viewer window: {0}")]
    Window(String),
    /// A scripted run (`--screenshot`, `--exit-after-frames`) failed.
    #[error("{0}")]
    Script(String),
}

/// How to run the viewer.
#[derive(Clone, Debug, Default)]
pub struct ViewOptions {
    /// Where the frames are drawn (`voxcast_gpu::choose`).
    pub device: Device,
    /// Scripted: write the view's pixels here, then exit.
    pub screenshot: Option<PathBuf>,
    /// Scripted: exit after at least this many UI frames, once the refined
    /// image is on screen (and the screenshot written).
    pub exit_after_frames: Option<u64>,
    /// Write the scene of what is on screen here on a scripted exit.
    pub save_scene: Option<PathBuf>,
    /// Scripted measurement: orbit the camera for this many seconds first.
    pub orbit: Option<f32>,
    /// For a store: the most decoded voxels held at once (default: half
    /// the memory available).
    pub memory_budget: Option<u64>,
}

/// What a scripted run measured.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ScriptStats {
    pub backend: String,
    /// Full-quality view size in pixels.
    pub view: [u32; 2],
    /// UI frames drawn.
    pub ui_frames: u64,
    /// Length of the scripted orbit (s).
    pub orbit_seconds: f64,
    /// Distinct new images painted during the orbit (an image replaced
    /// before a UI frame painted it does not count).
    pub frames_while_moving: u64,
    /// UI frames drawn during the orbit.
    pub ui_frames_while_moving: u64,
    /// Render time of each preview (ms).
    pub preview_render_ms: Vec<f64>,
    /// The last preview's divisor and size.
    pub preview_divisor: u32,
    pub preview_size: [u32; 2],
    /// Render time of each full-quality frame (ms).
    pub full_render_ms: Vec<f64>,
    /// From the end of the orbit to the UI frame that first painted the
    /// refined image (ms).
    pub refined_after_stop_ms: Option<f64>,
    /// Full-quality frames abandoned for a newer request.
    pub full_cancelled: u64,
    /// The window's present mode.
    pub present_mode: String,
    /// A store shown coarse first: the level of each new image painted,
    /// repeats left out (the coarsest first, the finest read last); empty
    /// for other inputs. A store drawn out of core: the finest level of
    /// each new image painted.
    pub levels: Vec<usize>,
    /// From the window's set-up to the first image painted, and to the
    /// last (ms).
    pub first_image_ms: Option<f64>,
    pub last_image_ms: f64,
}

impl ScriptStats {
    /// Images shown per second during the orbit.
    pub fn fps_while_moving(&self) -> f64 {
        if self.orbit_seconds > 0.0 {
            self.frames_while_moving as f64 / self.orbit_seconds
        } else {
            0.0
        }
    }

    /// UI frames per second during the orbit.
    pub fn ui_fps_while_moving(&self) -> f64 {
        if self.orbit_seconds > 0.0 {
            self.ui_frames_while_moving as f64 / self.orbit_seconds
        } else {
            0.0
        }
    }
}

/// Opens `scene`'s input (a series when it has more than one frame) and
/// shows it in a window until the window is closed (or, scripted, until the
/// screenshot is written). Returns what a scripted run measured.
pub fn run(scene: Scene, options: ViewOptions) -> Result<ScriptStats, ViewError> {
    let (series, pyramid, volume) = open_input(&scene, &options)?;
    let prepared = scene.prepare_with(volume)?;
    let (w, h) = (scene.render.width, scene.render.height);
    let outcome = Arc::new(Mutex::new(None));
    let setup = app::Setup {
        tf: prepared.tf,
        window: prepared.window,
        volume: Arc::new(prepared.volume),
        geometry: prepared.geometry,
        series,
        pyramid,
        options: options.clone(),
        outcome: outcome.clone(),
        scene,
    };
    let present = present_mode()?;
    let mut wgpu_options = eframe::egui_wgpu::WgpuConfiguration::default();
    wgpu_options.surface.present_mode = present;
    let native = eframe::NativeOptions {
        viewport: eframe::egui::ViewportBuilder::default()
            .with_title("voxcast view")
            .with_inner_size([w as f32 + app::PANEL_WIDTH, h as f32 + app::BAR_HEIGHT]),
        renderer: eframe::Renderer::Wgpu,
        wgpu_options,
        // Dithering adds noise to every pixel, the volume's too (screenshots
        // would no longer match `voxcast render`), and costs per pixel on a
        // software rasteriser.
        dithering: std::env::var_os("VOXCAST_VIEW_DITHER").is_some_and(|v| v == "1"),
        ..Default::default()
    };
    eframe::run_native(
        "voxcast view",
        native,
        Box::new(move |cc| Ok(Box::new(app::ViewerApp::new(cc, setup)))),
    )
    .map_err(|e| {
        ViewError::Window(format!(
            "{e} (a display is needed: on a machine without one run `xvfb-run -a voxcast view …`)"
        ))
    })?;
    let scripted = options.screenshot.is_some()
        || options.exit_after_frames.is_some()
        || options.orbit.is_some();
    let result = outcome.lock().unwrap_or_else(|e| e.into_inner()).take();
    match result {
        Some(Ok(mut stats)) => {
            stats.present_mode = format!("{present:?}");
            Ok(stats)
        }
        Some(Err(e)) => Err(ViewError::Script(e)),
        None if scripted => Err(ViewError::Script(
            "the window was closed before the scripted run finished".into(),
        )),
        None => Ok(ScriptStats::default()),
    }
}

/// The window's present mode: `VOXCAST_VIEW_PRESENT` (`fifo`, `mailbox`,
/// `immediate`, `auto-vsync`, `auto-novsync`), else `auto-novsync`. The
/// images come at the renderer's pace, not the display's, so waiting for a
/// vertical blank only adds latency; where no tearing-free mode without
/// waiting exists, wgpu falls back to FIFO.
fn present_mode() -> Result<eframe::wgpu::PresentMode, ViewError> {
    use eframe::wgpu::PresentMode;
    let Some(v) = std::env::var_os("VOXCAST_VIEW_PRESENT") else {
        return Ok(PresentMode::AutoNoVsync);
    };
    Ok(match v.to_string_lossy().as_ref() {
        "fifo" => PresentMode::Fifo,
        "mailbox" => PresentMode::Mailbox,
        "immediate" => PresentMode::Immediate,
        "auto-vsync" => PresentMode::AutoVsync,
        "auto-novsync" => PresentMode::AutoNoVsync,
        other => {
            return Err(ViewError::Window(format!(
                "VOXCAST_VIEW_PRESENT={other}: expected fifo, mailbox, immediate, auto-vsync or auto-novsync"
            )))
        }
    })
}

/// What the viewer shows: a series of more than one frame (with the frame
/// to show first: the one nearest `--time`, else the first) and that
/// frame's volume; a store of several levels (without `--level`) and its
/// coarsest level, to be refined; or a single volume.
type Input = (Option<(Series, usize)>, Option<Pyramid>, voxcast::Volume);

fn open_input(scene: &Scene, options: &ViewOptions) -> Result<Input, ViewError> {
    let path = &scene.input.path;
    if !path.starts_with(BUILTIN_PREFIX) {
        let opts = &scene.input.options;
        let budget = options
            .memory_budget
            .unwrap_or_else(voxcast::render::outofcore::default_budget);
        if let Some(mut p) = Pyramid::open(std::path::Path::new(path), opts, budget)? {
            let v = p.read(p.coarsest)?;
            if p.finest > 0 {
                use voxcast::render::outofcore::human_bytes;
                // The CPU draws the store out of core, chunk by chunk; the
                // GPU needs a level whole.
                p.out_of_core = matches!(options.device, Device::Cpu);
                let how = if p.out_of_core {
                    "it draws the store out of core, reading the chunks the view needs, each region at the level it needs".to_string()
                } else {
                    format!(
                        "the GPU refines down to level {} ({}); `--device cpu` draws level 0 out of core",
                        p.finest,
                        human_bytes(p.bytes(p.finest))
                    )
                };
                eprintln!(
                    "note: {path}: level 0 is {} decoded, and the viewer would hold about two copies within the memory budget ({}): {how}",
                    human_bytes(p.bytes(0)),
                    human_bytes(budget),
                );
            }
            return Ok((None, Some(p), v));
        }
        let series = Series::open(std::path::Path::new(path), opts)?;
        if series.len() > 1 {
            let frame = opts.time.map_or(0, |t| series.nearest(t));
            let v = series.load(frame, opts)?;
            return Ok((Some((series, frame)), None, v));
        }
    }
    Ok((None, None, scene.load_volume()?))
}
