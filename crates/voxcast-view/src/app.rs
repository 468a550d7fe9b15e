//! The viewer window: the volume view (orbit, zoom, pan), the control panel
//! (transfer-function editor, rendering options, lights, time, saving) and
//! the stats bar. Rendering happens on the worker thread; this module only
//! turns input into requests and shows what comes back. Here: the app's
//! state, the worker's replies and the render schedule; `panels` draws the
//! view, the stats bar and the control panel; `script` runs `--orbit`,
//! `--screenshot` and `--script-stats`. A store shown coarse first swaps in
//! each finer level as the loader hands it over ([`crate::levels`]); one too
//! large for memory is drawn out of core and drawn again as chunks arrive
//! ([`crate::stream`]).

use crate::camera_ctl::OrbitController;
use crate::image_paint::{self, PaintImage};
use crate::levels::{LevelSlots, Loaded, Pyramid};
use crate::progressive::{frame_params, Quality, Scheduler};
use crate::stream::StoreFrame;
use crate::tf_model::{LogHistogram, TfModel};
use crate::tf_widget::TfWidgetState;
use crate::worker::{Reply, Request, Source, Worker};
use crate::{ScriptStats, ViewOptions};
use eframe::egui::{self, Color32, ColorImage, TextureHandle};
use std::collections::VecDeque;
use std::path::PathBuf;
use std::sync::mpsc::{Receiver, TryRecvError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use voxcast::io::Series;
use voxcast::render::RenderParams;
use voxcast::scene::Scene;
use voxcast::transfer::TransferFunction;
use voxcast::Volume;
use voxcast_gpu::Device;

mod panels;
mod script;

/// Width of the control panel (points).
pub const PANEL_WIDTH: f32 = 340.0;
/// Height of the stats bar (points).
pub const BAR_HEIGHT: f32 = 26.0;
/// Degrees per second of the scripted orbit (`--orbit`).
const ORBIT_SPEED: f32 = 30.0;

/// What the app needs from `run`.
pub struct Setup {
    pub scene: Scene,
    pub tf: TransferFunction,
    pub window: [f32; 2],
    pub volume: Arc<Volume>,
    pub geometry: Option<Arc<voxcast::geometry::Geometry>>,
    pub series: Option<(Series, usize)>,
    /// A store shown coarse first (`volume` is its coarsest level).
    pub pyramid: Option<Pyramid>,
    pub options: ViewOptions,
    /// Where the scripted run reports its result.
    pub outcome: Arc<Mutex<Option<Result<ScriptStats, String>>>>,
}

/// The series being shown.
struct TimeState {
    series: Series,
    times: Vec<f64>,
    frame: usize,
    playing: bool,
    fps: f32,
    last_step: Instant,
}

/// A store shown coarse first, refined level by level.
struct LevelState {
    coarsest: usize,
    /// The finest level to be read.
    finest: usize,
    /// The level in use: requests name it as their frame.
    level: usize,
    /// The store, until the loader starts (once the first image is on
    /// screen, so that the first image does not wait for a read).
    pyramid: Option<Pyramid>,
    slots: Arc<LevelSlots>,
    loaded: Option<Receiver<Loaded>>,
    /// Why no finer level comes.
    failed: Option<String>,
    ctx: egui::Context,
}

/// A store too large for memory, drawn out of core.
struct StoreState {
    coarsest: usize,
    /// What the last full-quality frame of the current view showed.
    shown: Option<StoreFrame>,
    /// Chunks arrived since the last frame was asked for: the view is to
    /// be drawn again once the full frame in progress is on screen.
    arrived: bool,
}

impl StoreState {
    /// True while the view is to be drawn again with chunks read since.
    fn refining(&self) -> bool {
        self.arrived || self.shown.is_none_or(|f| f.wanted > 0)
    }
}

impl LevelState {
    /// True while a finer level is still to come.
    fn refining(&self) -> bool {
        self.level > self.finest && self.failed.is_none()
    }
}

/// How the image on screen is drawn.
enum Pixels {
    /// With a pipeline of its own (the default on wgpu).
    Paint(Arc<PaintImage>),
    /// As an egui texture (`VOXCAST_VIEW_EGUI_IMAGE=1`, or no wgpu).
    Texture(TextureHandle),
}

impl TimeState {
    /// The current frame's time: the file's name for it (WRF's `Times`)
    /// where there is one, else the number and its unit.
    fn label(&self) -> String {
        match self.series.label(self.frame) {
            Some(l) => format!("t = {l}"),
            None => format!(
                "t = {:.3} {}",
                self.times[self.frame],
                self.series.time_units.as_deref().unwrap_or("")
            )
            .trim_end()
            .to_string(),
        }
    }
}

/// The image on screen.
struct Shown {
    pixels: Pixels,
    generation: u64,
    quality: Quality,
    frame: usize,
    /// A store drawn out of core: what it showed.
    store: Option<StoreFrame>,
    /// UI frame in which it was first painted.
    painted_at: u64,
}

/// The scripted run (`--screenshot`, `--exit-after-frames`, `--orbit`).
struct Script {
    exit_after: u64,
    orbit: Option<Duration>,
    orbit_start: Option<Instant>,
    orbit_end: Option<Instant>,
    requested: bool,
    /// When the window was set up.
    started: Instant,
    stats: ScriptStats,
}

pub struct ViewerApp {
    scene: Scene,
    device: Device,
    tf: TfModel,
    tf_state: TfWidgetState,
    preset: String,
    window: [f32; 2],
    data_range: [f32; 2],
    volume: Arc<Volume>,
    cam: OrbitController,
    /// Full-quality parameters (the view's size).
    params: RenderParams,
    time: Option<TimeState>,
    levels: Option<LevelState>,
    store: Option<StoreState>,
    worker: Worker,
    scheduler: Scheduler,
    /// The view state's version: bumped by every change.
    version: u64,
    last_change: Instant,
    /// The last request sent: (version, full quality?).
    requested: Option<(u64, bool)>,
    shown: Option<Shown>,
    /// Draw the image with `image_paint` (else as an egui texture).
    paint_images: bool,
    /// Images received (their ids for `image_paint`).
    images: u64,
    histogram: Option<LogHistogram>,
    /// Times at which new images were shown (for fps).
    shown_times: VecDeque<Instant>,
    last_stats: Option<(voxcast::RenderStats, Quality)>,
    ui_frame: u64,
    message: String,
    screenshot_path: String,
    scene_path: String,
    /// The view's rectangle in pixels of the last frame.
    view_px: (u32, u32, u32, u32),
    shot: Arc<Mutex<Option<Arc<ColorImage>>>>,
    /// Where the pending screenshot goes.
    shot_target: Option<PathBuf>,
    options: ViewOptions,
    script: Option<Script>,
    outcome: Arc<Mutex<Option<Result<ScriptStats, String>>>>,
}

impl ViewerApp {
    pub fn new(cc: &eframe::CreationContext<'_>, setup: Setup) -> ViewerApp {
        let ctx = cc.egui_ctx.clone();
        let egui_image = std::env::var_os("VOXCAST_VIEW_EGUI_IMAGE").is_some_and(|v| v == "1");
        let paint_images = match &cc.wgpu_render_state {
            Some(rs) if !egui_image => {
                image_paint::install(rs);
                true
            }
            _ => false,
        };
        let Setup {
            scene,
            tf,
            window,
            volume,
            geometry,
            series,
            pyramid,
            options,
            outcome,
        } = setup;
        let (mut lo, mut hi) = volume.frame_bounds();
        if let Some((glo, ghi)) = geometry.as_ref().and_then(|g| g.bounds()) {
            (lo, hi) = (lo.min(glo), hi.max(ghi));
        }
        let cam = OrbitController::new(&scene.camera, (lo, hi));
        let (pyramid, streamed) = match pyramid {
            Some(p) if p.out_of_core => (None, Some(p)),
            p => (p, None),
        };
        let store = streamed.as_ref().map(|p| StoreState {
            coarsest: p.coarsest,
            shown: None,
            arrived: false,
        });
        let levels = pyramid.map(|p| LevelState {
            coarsest: p.coarsest,
            finest: p.finest,
            level: p.coarsest,
            pyramid: Some(p),
            slots: Arc::default(),
            loaded: None,
            failed: None,
            ctx: ctx.clone(),
        });
        let (source, frame) = match (&series, &levels, streamed) {
            (Some((s, f)), _, _) => (
                Source::Series(Box::new(s.clone()), scene.input.options.clone()),
                *f,
            ),
            (None, Some(l), _) => (Source::Levels(l.slots.clone()), l.level),
            (None, None, Some(p)) => {
                let ooc = crate::stream::params(p.budget, p.lod_scale);
                (Source::Store(Arc::new(p.into_store()), ooc), 0)
            }
            (None, None, None) => (Source::Single, 0),
        };
        let worker = Worker::spawn(
            options.device.clone(),
            source,
            frame,
            volume.clone(),
            geometry,
            move || ctx.request_repaint(),
        );
        let time = series.map(|(series, frame)| TimeState {
            times: series.times(),
            series,
            frame,
            playing: false,
            fps: 5.0,
            last_step: Instant::now(),
        });
        let stats = volume.stats();
        let data_range = [stats.min, stats.max];
        let script = (options.screenshot.is_some()
            || options.exit_after_frames.is_some()
            || options.orbit.is_some())
        .then(|| Script {
            exit_after: options.exit_after_frames.unwrap_or(0),
            orbit: options.orbit.map(Duration::from_secs_f32),
            orbit_start: None,
            orbit_end: None,
            requested: false,
            started: Instant::now(),
            stats: ScriptStats::default(),
        });
        let preset = if scene.transfer.map.is_some() {
            "(scene)".to_string()
        } else {
            scene.transfer.tf.clone()
        };
        ViewerApp {
            params: scene.render.clone(),
            device: options.device.clone(),
            tf: TfModel::new(&tf),
            tf_state: TfWidgetState::default(),
            preset,
            window,
            data_range,
            volume,
            cam,
            time,
            levels,
            store,
            worker,
            scheduler: Scheduler::default(),
            version: 1,
            last_change: Instant::now(),
            requested: None,
            shown: None,
            paint_images,
            images: 0,
            histogram: None,
            shown_times: VecDeque::new(),
            last_stats: None,
            ui_frame: 0,
            message: String::new(),
            screenshot_path: "voxcast-view.png".into(),
            scene_path: "voxcast-view.toml".into(),
            view_px: (0, 0, 0, 0),
            shot: Arc::new(Mutex::new(None)),
            shot_target: None,
            options,
            script,
            outcome,
            scene,
        }
    }

    /// Marks the view as changed: previews until it is still again.
    fn touch(&mut self) {
        self.version += 1;
        self.last_change = Instant::now();
    }

    /// The frame of the series, or the level of the store, in use.
    fn frame_index(&self) -> usize {
        match (&self.time, &self.levels) {
            (Some(t), _) => t.frame,
            (None, Some(l)) => l.level,
            (None, None) => 0,
        }
    }

    /// The scene that reproduces what is on screen.
    pub fn current_scene(&self) -> Scene {
        let mut s = self.scene.clone();
        if let Some(t) = &self.time {
            let i = t.frame;
            match t.series.frame_path(i) {
                Some(p) if p != t.series.source.as_path() => {
                    s.input.path = p.to_string_lossy().into_owned();
                    s.input.options.time = None;
                }
                _ => s.input.options.time = Some(t.times[i]),
            }
        }
        if let Some(l) = &self.levels {
            // Level 0 is what `voxcast render` reads (or renders out of
            // core) by itself.
            s.input.options.level = (l.level > 0).then_some(l.level);
        }
        s.transfer.tf = "auto".into();
        s.transfer.map = Some(self.tf.tf().clone());
        s.transfer.window = Some(self.window);
        s.camera = self.cam.params(self.params.width, self.params.height);
        s.render = self.params.clone();
        s
    }

    fn poll_replies(&mut self, ctx: &egui::Context) {
        while let Some(r) = self.worker.try_recv() {
            match r {
                Reply::Volume {
                    frame,
                    window,
                    histogram,
                    ..
                } => {
                    if frame == self.frame_index() && window == self.window {
                        self.histogram = Some(histogram);
                    }
                }
                Reply::Frame {
                    generation,
                    frame,
                    quality,
                    image,
                    srgba,
                    stats,
                    store,
                } => {
                    if let (Some(st), Some(f), Quality::Full) = (&mut self.store, store, quality) {
                        if generation == self.version {
                            st.shown = Some(f);
                        }
                    }
                    if let Quality::Preview { .. } = quality {
                        self.scheduler.record(stats.rays, stats.seconds);
                    }
                    if let Some(s) = &mut self.script {
                        let t = stats.seconds;
                        match quality {
                            Quality::Preview { divisor } => {
                                s.stats.preview_render_ms.push(t * 1e3);
                                s.stats.preview_divisor = divisor;
                                s.stats.preview_size = [image.width, image.height];
                            }
                            Quality::Full => s.stats.full_render_ms.push(t * 1e3),
                        }
                    }
                    // A preview is uploaded at its own size and scaled by the
                    // sampler; a full frame maps 1:1 to the view's pixels.
                    let preview = matches!(quality, Quality::Preview { .. });
                    self.images += 1;
                    let pixels = if self.paint_images {
                        Pixels::Paint(Arc::new(PaintImage {
                            id: self.images,
                            width: image.width,
                            height: image.height,
                            rgba: srgba,
                            linear: preview,
                        }))
                    } else {
                        let ci = ColorImage::from_rgba_unmultiplied(
                            [image.width as usize, image.height as usize],
                            &srgba,
                        );
                        let filter = if preview {
                            egui::TextureOptions::LINEAR
                        } else {
                            egui::TextureOptions::NEAREST
                        };
                        match self.shown.take().map(|s| s.pixels) {
                            Some(Pixels::Texture(mut t)) => {
                                t.set(ci, filter);
                                Pixels::Texture(t)
                            }
                            _ => Pixels::Texture(ctx.load_texture("volume", ci, filter)),
                        }
                    };
                    self.shown = Some(Shown {
                        pixels,
                        generation,
                        quality,
                        frame,
                        store,
                        painted_at: u64::MAX,
                    });
                    self.last_stats = Some((stats, quality));
                    self.message.clear();
                }
                Reply::Arrived { .. } => {
                    if let Some(st) = &mut self.store {
                        st.arrived = true;
                    }
                }
                Reply::Cancelled { .. } => {
                    if let Some(s) = &mut self.script {
                        s.stats.full_cancelled += 1;
                    }
                }
                Reply::Error {
                    generation,
                    message,
                } => {
                    self.message = format!("render failed: {message}");
                    if generation == self.version {
                        // Do not ask again for the same failing state.
                        self.requested = Some((generation, true));
                    }
                    if self.script.is_some() {
                        self.finish(ctx, Err(message));
                    }
                }
            }
        }
    }

    /// Starts reading the finer levels of a store, once the first image is
    /// on screen (so that it does not wait for a read).
    fn start_loader(&mut self) {
        let Some(l) = &mut self.levels else { return };
        if let Some(p) = l.pyramid.take() {
            if l.refining() {
                let c = l.ctx.clone();
                l.loaded = Some(p.load_finer(l.slots.clone(), move || c.request_repaint()));
            }
        }
    }

    /// Swaps in the finest level of the store read so far: same camera,
    /// transfer function and window; its full-quality frame follows.
    fn poll_levels(&mut self, ctx: &egui::Context) {
        let Some(l) = &mut self.levels else { return };
        let Some(rx) = &l.loaded else { return };
        let mut newest = None;
        let mut failed = None;
        loop {
            match rx.try_recv() {
                Ok(Ok((level, volume))) => {
                    l.level = level;
                    newest = Some(volume);
                }
                Ok(Err(message)) => failed = Some(message),
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => {
                    if l.refining() && failed.is_none() {
                        failed = Some("the level loader stopped".into());
                    }
                    l.loaded = None;
                    break;
                }
            }
        }
        if let Some(volume) = newest {
            let stats = volume.stats();
            self.data_range = [stats.min, stats.max];
            self.volume = volume;
            // Not a move: the image on screen stays until the new level's
            // full-quality frame replaces it.
            self.version += 1;
        }
        if let Some(message) = failed {
            self.message = format!("reading a finer level failed: {message}");
            if let Some(l) = &mut self.levels {
                l.failed = Some(message);
            }
            if self.script.is_some() {
                self.finish(ctx, Err(self.message.clone()));
            }
        }
    }

    /// Sends the request the current state needs, if any.
    fn schedule(&mut self, ctx: &egui::Context) {
        if self.params.width == 0 || self.params.height == 0 {
            return;
        }
        let since = self.last_change.elapsed();
        let moving = since < self.scheduler.settle;
        let mut full_shown = self
            .shown
            .as_ref()
            .is_some_and(|s| s.generation == self.version && s.quality == Quality::Full);
        // A store drawn out of core: chunks arrived since the full frame on
        // screen was asked for. Not a move: that frame stays until the
        // next one, drawn with them, replaces it.
        if let Some(st) = &mut self.store {
            if st.arrived && full_shown && !moving {
                st.arrived = false;
                st.shown = None;
                self.version += 1;
                full_shown = false;
            }
        }
        let quality = if moving {
            if self.requested.is_some_and(|r| r.0 == self.version) {
                None
            } else {
                Some(Quality::Preview {
                    divisor: self
                        .scheduler
                        .preview_divisor(self.params.width, self.params.height),
                })
            }
        } else if !full_shown && self.requested != Some((self.version, true)) {
            Some(Quality::Full)
        } else {
            None
        };
        if let Some(q) = quality {
            let mut params = frame_params(&self.params, q);
            // A preview keeps the full frame's aspect, so the camera framing
            // is the same.
            params.seed = self.params.seed;
            self.worker.submit(Request {
                generation: self.version,
                frame: self.frame_index(),
                window: self.window,
                tf: self.tf.tf().clone(),
                camera: self.cam.params(self.params.width, self.params.height),
                params,
                quality: q,
            });
            self.requested = Some((self.version, q == Quality::Full));
        }
        if moving {
            ctx.request_repaint_after(self.scheduler.settle.saturating_sub(since));
        }
    }

    fn advance_playback(&mut self) {
        let shown_frame = self.shown.as_ref().map(|s| s.frame);
        let Some(t) = &mut self.time else { return };
        if !t.playing {
            return;
        }
        let due = t.last_step.elapsed().as_secs_f32() >= 1.0 / t.fps.max(0.1);
        // Wait for the current frame to be on screen before moving on.
        if due && shown_frame == Some(t.frame) {
            t.frame = (t.frame + 1) % t.times.len();
            t.last_step = Instant::now();
            self.touch();
        }
    }

    /// Counts an image painted for the first time: the fps of the stats
    /// bar and the scripted measurement count images that reached the
    /// screen, not images that arrived (two arriving between UI frames show
    /// only the second).
    fn on_new_image(&mut self, quality: Quality, generation: u64) {
        self.start_loader();
        let now = Instant::now();
        self.shown_times.push_back(now);
        while self.shown_times.len() > 120 {
            self.shown_times.pop_front();
        }
        let version = self.version;
        let shown_level = match (&self.levels, &self.shown) {
            (Some(_), Some(sh)) => Some(sh.frame),
            (None, Some(sh)) => sh.store.map(|f| f.finest),
            _ => None,
        };
        let Some(s) = &mut self.script else { return };
        let since = now.duration_since(s.started).as_secs_f64() * 1e3;
        s.stats.first_image_ms.get_or_insert(since);
        s.stats.last_image_ms = since;
        if let Some(l) = shown_level {
            if s.stats.levels.last() != Some(&l) {
                s.stats.levels.push(l);
            }
        }
        if s.orbit_start.is_some() && s.orbit_end.is_none() {
            s.stats.frames_while_moving += 1;
        }
        if quality == Quality::Full && generation == version {
            if let Some(end) = s.orbit_end {
                if s.stats.refined_after_stop_ms.is_none() {
                    s.stats.refined_after_stop_ms =
                        Some(now.duration_since(end).as_secs_f64() * 1e3);
                }
            }
        }
    }
}

impl eframe::App for ViewerApp {
    fn clear_color(&self, visuals: &egui::Visuals) -> [f32; 4] {
        visuals.panel_fill.to_normalized_gamma_f32()
    }

    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        self.ui_frame += 1;
        self.poll_replies(&ctx);
        self.poll_levels(&ctx);
        self.take_screenshot(&ctx);
        self.advance_playback();
        self.run_script(&ctx);
        // The panels are not filled: the clear colour (the panel colour, see
        // `clear_color`) shows through for free, where a fill is one more
        // layer of blended pixels for a software rasteriser every frame.
        let panel_frame = egui::Frame::side_top_panel(ui.style()).fill(Color32::TRANSPARENT);
        egui::Panel::right("controls")
            .exact_size(PANEL_WIDTH)
            .resizable(false)
            .frame(panel_frame)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| self.controls(ui));
            });
        egui::Panel::bottom("stats")
            .exact_size(BAR_HEIGHT)
            .resizable(false)
            .frame(panel_frame)
            .show(ui, |ui| self.stats_bar(ui));
        egui::CentralPanel::no_frame().show(ui, |ui| self.view(ui));
        self.schedule(&ctx);
        if self.worker.busy() || self.time.as_ref().is_some_and(|t| t.playing) {
            ctx.request_repaint_after(Duration::from_millis(30));
        }
    }
}
