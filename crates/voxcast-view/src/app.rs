//! The viewer window: the volume view (orbit, zoom, pan), the control panel
//! (transfer-function editor, rendering options, lights, time, saving) and
//! the stats bar. Rendering happens on the worker thread; this file only
//! turns input into requests and shows what comes back.

use crate::backend::Backend;
use crate::camera_ctl::OrbitController;
use crate::image_paint::{self, PaintImage};
use crate::progressive::{frame_params, Quality, Scheduler};
use crate::screenshot::{crop_rgba, Rgb8};
use crate::tf_model::{LogHistogram, TfModel};
use crate::tf_widget::{self, TfWidgetState};
use crate::worker::{Reply, Request, Source, Worker};
use crate::{ScriptStats, ViewOptions};
use eframe::egui::{self, Color32, ColorImage, Pos2, Rect, Sense, TextureHandle, Vec2};
use std::collections::VecDeque;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use voxcast::render::light::Light;
use voxcast::render::{Method, OpticalModel, RenderParams};
use voxcast::scene::Scene;
use voxcast::transfer::{TransferFunction, PRESETS};
use voxcast::volume::Series;
use voxcast::Volume;

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
    stats: ScriptStats,
}

pub struct ViewerApp {
    scene: Scene,
    backend: Backend,
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
            options,
            outcome,
        } = setup;
        let (mut lo, mut hi) = volume.world_bounds();
        if let Some((glo, ghi)) = geometry.as_ref().and_then(|g| g.bounds()) {
            (lo, hi) = (lo.min(glo), hi.max(ghi));
        }
        let cam = OrbitController::new(&scene.camera, (lo, hi));
        let (source, frame) = match &series {
            Some((s, f)) => (
                Source::Series(Box::new(s.clone()), scene.input.options.clone()),
                *f,
            ),
            None => (Source::Single, 0),
        };
        let worker = Worker::spawn(
            options.backend.clone(),
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
            stats: ScriptStats::default(),
        });
        let preset = if scene.transfer.map.is_some() {
            "(scene)".to_string()
        } else {
            scene.transfer.tf.clone()
        };
        ViewerApp {
            params: scene.render.clone(),
            backend: options.backend.clone(),
            tf: TfModel::new(&tf),
            tf_state: TfWidgetState::default(),
            preset,
            window,
            data_range,
            volume,
            cam,
            time,
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

    fn frame_index(&self) -> usize {
        self.time.as_ref().map_or(0, |t| t.frame)
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
                } => {
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
                        painted_at: u64::MAX,
                    });
                    self.last_stats = Some((stats, quality));
                    self.message.clear();
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

    /// Sends the request the current state needs, if any.
    fn schedule(&mut self, ctx: &egui::Context) {
        if self.params.width == 0 || self.params.height == 0 {
            return;
        }
        let since = self.last_change.elapsed();
        let moving = since < self.scheduler.settle;
        let full_shown = self
            .shown
            .as_ref()
            .is_some_and(|s| s.generation == self.version && s.quality == Quality::Full);
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

    /// The scripted orbit and exit.
    fn run_script(&mut self, ctx: &egui::Context) {
        let Some(s) = &mut self.script else { return };
        ctx.request_repaint();
        // The orbit starts from a still, refined view (as a user looks,
        // then drags), so that no full frame is in flight when it starts.
        let have_image = s.orbit_start.is_some()
            || self
                .shown
                .as_ref()
                .is_some_and(|sh| sh.generation == self.version && sh.quality == Quality::Full);
        let mut turn = 0.0;
        if let (Some(len), true) = (s.orbit, have_image) {
            let now = Instant::now();
            let start = *s.orbit_start.get_or_insert(now);
            if s.orbit_end.is_none() {
                if now.duration_since(start) >= len {
                    s.orbit_end = Some(now);
                    s.stats.orbit_seconds = now.duration_since(start).as_secs_f64();
                } else {
                    s.stats.ui_frames_while_moving += 1;
                    turn = ORBIT_SPEED * ctx.input(|i| i.stable_dt).min(0.1);
                }
            }
        }
        let orbit_done = s.orbit.is_none() || s.orbit_end.is_some();
        if turn > 0.0 {
            self.cam.azimuth += turn;
            self.touch();
            return;
        }
        let Some(s) = &mut self.script else { return };
        let refined = self.shown.as_ref().is_some_and(|sh| {
            sh.generation == self.version
                && sh.quality == Quality::Full
                && sh.painted_at < self.ui_frame
        });
        if !(orbit_done && refined && self.ui_frame >= s.exit_after) {
            return;
        }
        if let Some(path) = self.options.screenshot.clone() {
            if !s.requested {
                s.requested = true;
                self.request_screenshot(ctx, path);
            }
            // Wait for the screenshot to be written.
            return;
        }
        if !s.requested {
            s.requested = true;
            self.finish(ctx, Ok(()));
        }
    }

    /// Ends the scripted run: saves the scene if asked, reports, closes.
    fn finish(&mut self, ctx: &egui::Context, result: Result<(), String>) {
        let mut result = result;
        if result.is_ok() {
            if let Some(p) = &self.options.save_scene {
                if let Err(e) = self.current_scene().save(p) {
                    result = Err(e.to_string());
                }
            }
        }
        let stats = self.script.as_ref().map(|s| {
            let mut st = s.stats.clone();
            st.ui_frames = self.ui_frame;
            st.view = [self.params.width, self.params.height];
            st.backend = self.backend.name().to_string();
            st
        });
        let mut o = self.outcome.lock().unwrap_or_else(|e| e.into_inner());
        if o.is_none() {
            *o = Some(result.map(|()| stats.unwrap_or_default()));
        }
        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
    }

    fn request_screenshot(&mut self, ctx: &egui::Context, path: PathBuf) {
        self.shot_target = Some(path);
        let slot = self.shot.clone();
        let c = ctx.clone();
        ctx.send_viewport_cmd(egui::ViewportCommand::Screenshot(
            egui::ScreenshotCallback::new(move |img| {
                *slot.lock().unwrap_or_else(|e| e.into_inner()) = Some(img);
                c.request_repaint();
            }),
        ));
    }

    /// Writes a screenshot that has arrived.
    fn take_screenshot(&mut self, ctx: &egui::Context) {
        let Some(img) = self.shot.lock().unwrap_or_else(|e| e.into_inner()).take() else {
            return;
        };
        let Some(path) = self.shot_target.take() else {
            return;
        };
        let [w, h] = img.size;
        let rgba: Vec<u8> = img.pixels.iter().flat_map(|c| c.to_array()).collect();
        let crop: Rgb8 = crop_rgba(&rgba, w as u32, h as u32, self.view_px);
        let res = crop.write_png(&path).map_err(|e| e.to_string());
        match &res {
            Ok(()) => {
                self.message = format!("saved {} ({}×{})", path.display(), crop.width, crop.height)
            }
            Err(e) => self.message = format!("screenshot failed: {e}"),
        }
        if self.script.as_ref().is_some_and(|s| s.requested) {
            self.finish(ctx, res);
        }
    }

    /// Counts an image painted for the first time: the fps of the stats
    /// bar and the scripted measurement count images that reached the
    /// screen, not images that arrived (two arriving between UI frames show
    /// only the second).
    fn on_new_image(&mut self, quality: Quality, generation: u64) {
        let now = Instant::now();
        self.shown_times.push_back(now);
        while self.shown_times.len() > 120 {
            self.shown_times.pop_front();
        }
        let version = self.version;
        let Some(s) = &mut self.script else { return };
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

    fn view(&mut self, ui: &mut egui::Ui) {
        let ppp = ui.ctx().pixels_per_point();
        let avail = ui.available_rect_before_wrap();
        // Snap to whole pixels so that a full frame maps 1:1 to the screen.
        let x0 = (avail.min.x * ppp).round();
        let y0 = (avail.min.y * ppp).round();
        let x1 = (avail.max.x * ppp).round();
        let y1 = (avail.max.y * ppp).round();
        let (pw, ph) = ((x1 - x0).max(1.0) as u32, (y1 - y0).max(1.0) as u32);
        self.view_px = (x0 as u32, y0 as u32, x0 as u32 + pw, y0 as u32 + ph);
        let rect = Rect::from_min_max(
            Pos2::new(x0 / ppp, y0 / ppp),
            Pos2::new((x0 + pw as f32) / ppp, (y0 + ph as f32) / ppp),
        );
        if (pw, ph) != (self.params.width, self.params.height) {
            self.params.width = pw;
            self.params.height = ph;
            self.touch();
        }
        let resp = ui.allocate_rect(rect, Sense::click_and_drag());
        let painter = ui.painter_at(rect);
        let bg = self
            .params
            .background
            .map(|c| (c.clamp(0.0, 1.0) * 255.0 + 0.5) as u8);
        let mut newly_painted = None;
        match &mut self.shown {
            // The image is opaque and covers the view: no background under
            // it (on a software rasteriser every covered pixel costs).
            Some(s) => {
                match &s.pixels {
                    Pixels::Paint(img) => {
                        painter.add(image_paint::shape(rect, img.clone()));
                    }
                    Pixels::Texture(t) => {
                        painter.image(
                            t.id(),
                            rect,
                            Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0)),
                            Color32::WHITE,
                        );
                    }
                }
                if s.painted_at == u64::MAX {
                    s.painted_at = self.ui_frame;
                    newly_painted = Some((s.quality, s.generation));
                }
            }
            None => {
                painter.rect_filled(rect, 0.0, Color32::from_rgb(bg[0], bg[1], bg[2]));
            }
        }
        if let Some((quality, generation)) = newly_painted {
            self.on_new_image(quality, generation);
        }
        if resp.dragged() {
            let d = resp.drag_delta() * ppp;
            let pan = ui.input(|i| i.modifiers.shift || i.modifiers.command)
                || resp.dragged_by(egui::PointerButton::Secondary)
                || resp.dragged_by(egui::PointerButton::Middle);
            if d != Vec2::ZERO {
                if pan {
                    self.cam.pan_by(d.x, d.y, pw, ph);
                } else {
                    self.cam.orbit(d.x, d.y);
                }
                self.touch();
            }
        }
        if resp.hovered() {
            let s = ui.input(|i| i.smooth_scroll_delta().y);
            if s != 0.0 {
                self.cam.scroll(s);
                self.touch();
            }
        }
        if resp.double_clicked() {
            self.cam.reset();
            self.touch();
        }
    }

    fn stats_bar(&self, ui: &mut egui::Ui) {
        ui.horizontal_centered(|ui| {
            let now = Instant::now();
            let recent = self
                .shown_times
                .iter()
                .filter(|t| now.duration_since(**t) < Duration::from_secs(1))
                .count();
            let mut text = format!("{} · ", self.backend.name());
            if let Some((st, q)) = &self.last_stats {
                let what = match q {
                    Quality::Full => "refined".to_string(),
                    Quality::Preview { divisor } => format!("preview 1/{divisor}"),
                };
                let spr = if st.rays > 0 {
                    st.samples as f64 / st.rays as f64
                } else {
                    0.0
                };
                text += &format!(
                    "{what} · {:.0} ms/frame · {recent} fps · {spr:.1} samples/ray · ",
                    st.seconds * 1e3
                );
            } else {
                text += "rendering… · ";
            }
            text += &format!("{}×{}", self.params.width, self.params.height);
            if let Some(t) = &self.time {
                text += &format!(" · frame {}/{} {}", t.frame + 1, t.times.len(), t.label());
            }
            ui.monospace(text);
            if !self.message.is_empty() {
                ui.colored_label(Color32::from_rgb(255, 200, 120), &self.message);
            }
        });
    }

    fn controls(&mut self, ui: &mut egui::Ui) {
        let mut changed = false;
        ui.heading("voxcast view");
        let d = self.volume.dims();
        ui.label(format!(
            "{} · {}×{}×{} {}",
            short(&self.scene.input.path),
            d[0],
            d[1],
            d[2],
            self.volume.scalar_type()
        ));
        ui.separator();

        // Transfer function.
        ui.strong("Transfer function");
        ui.horizontal(|ui| {
            let mut pick = None;
            egui::ComboBox::from_id_salt("preset")
                .selected_text(self.preset.clone())
                .show_ui(ui, |ui| {
                    for name in std::iter::once("auto").chain(PRESETS.iter().map(|p| p.0)) {
                        if ui.selectable_label(self.preset == name, name).clicked() {
                            pick = Some(name.to_string());
                        }
                    }
                });
            if let Some(name) = pick {
                let tf = if name == "auto" {
                    TransferFunction::auto(&self.volume)
                } else {
                    TransferFunction::preset(&name).expect("listed preset")
                };
                self.tf = TfModel::new(&tf);
                self.window = tf.window_for(&self.volume, self.scene.transfer.window);
                self.preset = name;
                changed = true;
            }
            ui.label("preset");
        });
        let width = ui.available_width().min(PANEL_WIDTH - 20.0);
        if tf_widget::show(
            ui,
            &mut self.tf,
            self.histogram.as_ref(),
            &mut self.tf_state,
            width,
        ) {
            changed = true;
        }
        ui.horizontal(|ui| {
            let [lo, hi] = self.data_range;
            let span = (hi - lo).abs().max(1e-6);
            let speed = span / 500.0;
            let mut w = self.window;
            ui.label("window");
            let a = ui.add(egui::DragValue::new(&mut w[0]).speed(speed));
            let b = ui.add(egui::DragValue::new(&mut w[1]).speed(speed));
            if (a.changed() || b.changed()) && w[0] < w[1] && w[0].is_finite() && w[1].is_finite() {
                self.window = w;
                changed = true;
            }
            if ui.button("data range").clicked() && lo < hi {
                self.window = [lo, hi];
                changed = true;
            }
        });
        ui.separator();

        // Time.
        if let Some(t) = &mut self.time {
            ui.strong("Time");
            let n = t.times.len();
            ui.horizontal(|ui| {
                // Plain words: the default fonts have no media-control glyphs.
                let label = if t.playing { "pause" } else { "play" };
                if ui.button(label).clicked() {
                    t.playing = !t.playing;
                    t.last_step = Instant::now();
                }
                let mut f = t.frame;
                if ui
                    .add(egui::Slider::new(&mut f, 0..=n - 1).text("frame"))
                    .changed()
                {
                    t.frame = f;
                    changed = true;
                }
            });
            ui.horizontal(|ui| {
                ui.label(t.label());
                ui.add(
                    egui::DragValue::new(&mut t.fps)
                        .range(0.2..=60.0)
                        .speed(0.1)
                        .suffix(" frames/s"),
                );
            });
            ui.separator();
        }

        // Rendering.
        ui.strong("Rendering");
        let p = &mut self.params;
        egui::ComboBox::from_label("method")
            .selected_text(p.method.name())
            .show_ui(ui, |ui| {
                for m in Method::ALL {
                    if ui.selectable_value(&mut p.method, m, m.name()).changed() {
                        changed = true;
                    }
                }
            });
        if !p.method.is_physical() {
            egui::ComboBox::from_label("optical model")
                .selected_text(p.optical.name())
                .show_ui(ui, |ui| {
                    for o in OpticalModel::ALL {
                        if ui.selectable_value(&mut p.optical, o, o.name()).changed() {
                            changed = true;
                        }
                    }
                });
        }
        changed |= ui
            .add(
                egui::Slider::new(&mut p.step, 0.05..=4.0)
                    .logarithmic(true)
                    .text("step (voxels)"),
            )
            .changed();
        changed |= ui
            .add(egui::Slider::new(&mut p.ert, 0.5..=1.0).text("early termination"))
            .changed();
        ui.horizontal(|ui| {
            changed |= ui.checkbox(&mut p.jitter, "jitter").changed();
            changed |= ui.checkbox(&mut p.shading, "shading").changed();
            changed |= ui.checkbox(&mut p.skip_empty, "skip empty").changed();
        });
        ui.horizontal(|ui| {
            changed |= ui.checkbox(&mut p.grouped, "grouped (S0)").changed();
            if p.method.is_stochastic() || p.jitter {
                changed |= ui
                    .add(
                        egui::DragValue::new(&mut p.spp)
                            .range(1..=4096)
                            .prefix("spp "),
                    )
                    .changed();
            }
        });
        ui.horizontal(|ui| {
            let mut c = p.background;
            if egui::color_picker::color_edit_button_rgb(ui, &mut c).changed() {
                p.background = c.map(|x| x.clamp(0.0, 1.0));
                changed = true;
            }
            ui.label("background");
        });
        if p.method.is_physical() {
            ui.separator();
            ui.strong("Medium and lights");
            changed |= ui
                .add(
                    egui::Slider::new(&mut p.medium.scale, 0.1..=200.0)
                        .logarithmic(true)
                        .text("extinction"),
                )
                .changed();
            if p.lights.is_empty() {
                ui.label("default sun and sky");
                if ui.button("edit lights").clicked() {
                    p.lights = Light::default_sun_and_sky();
                    changed = true;
                }
            }
            let mut remove = None;
            for (i, l) in p.lights.iter_mut().enumerate() {
                ui.push_id(i, |ui| {
                    ui.horizontal(|ui| {
                        changed |= light_editor(ui, l);
                        if ui.small_button("remove").clicked() {
                            remove = Some(i);
                        }
                    });
                });
            }
            if let Some(i) = remove {
                p.lights.remove(i);
                changed = true;
            }
        }
        ui.separator();

        // Camera.
        ui.strong("Camera");
        ui.horizontal(|ui| {
            let c = &mut self.cam;
            changed |= ui
                .add(
                    egui::DragValue::new(&mut c.azimuth)
                        .speed(0.5)
                        .prefix("az "),
                )
                .changed();
            changed |= ui
                .add(
                    egui::DragValue::new(&mut c.elevation)
                        .range(-89.0..=89.0)
                        .speed(0.5)
                        .prefix("el "),
                )
                .changed();
            changed |= ui
                .add(
                    egui::DragValue::new(&mut c.zoom)
                        .range(0.05..=200.0)
                        .speed(0.01)
                        .prefix("zoom "),
                )
                .changed();
        });
        ui.horizontal(|ui| {
            let c = &mut self.cam;
            let mut ortho = c.projection == voxcast::camera::Projection::Orthographic;
            if ui.checkbox(&mut ortho, "orthographic").changed() {
                c.projection = if ortho {
                    c.pan = [0.0, 0.0];
                    voxcast::camera::Projection::Orthographic
                } else {
                    voxcast::camera::Projection::Perspective
                };
                changed = true;
            }
            changed |= ui
                .add(
                    egui::DragValue::new(&mut c.fov)
                        .range(5.0..=120.0)
                        .speed(0.2)
                        .prefix("fov "),
                )
                .changed();
            if ui.button("reset").clicked() {
                c.reset();
                changed = true;
            }
        });
        ui.weak("drag: orbit · wheel: zoom · shift/right-drag: pan · double-click: reset");
        ui.separator();

        // Saving.
        ui.strong("Save");
        let ctx = ui.ctx().clone();
        ui.horizontal(|ui| {
            ui.add(egui::TextEdit::singleline(&mut self.screenshot_path).desired_width(190.0));
            if ui.button("screenshot").clicked() {
                let p = PathBuf::from(&self.screenshot_path);
                self.request_screenshot(&ctx, p);
            }
        });
        ui.horizontal(|ui| {
            ui.add(egui::TextEdit::singleline(&mut self.scene_path).desired_width(190.0));
            if ui.button("scene").clicked() {
                let p = PathBuf::from(&self.scene_path);
                self.message = match self.current_scene().save(&p) {
                    Ok(()) => format!(
                        "saved {}: `voxcast render --scene {}` reproduces the view",
                        p.display(),
                        p.display()
                    ),
                    Err(e) => format!("cannot save the scene: {e}"),
                };
            }
        });
        if changed {
            self.touch();
        }
    }
}

/// Edits one light's numbers; true when changed.
fn light_editor(ui: &mut egui::Ui, l: &mut Light) -> bool {
    let mut changed = false;
    let mut vec3 = |ui: &mut egui::Ui, v: &mut [f32; 3], speed: f32| {
        for x in v.iter_mut() {
            changed |= ui
                .add(egui::DragValue::new(x).speed(speed).max_decimals(2))
                .changed();
        }
    };
    match l {
        Light::Directional {
            direction,
            irradiance,
        } => {
            ui.label("sun dir");
            vec3(ui, direction, 0.02);
            ui.label("E");
            let mut s = irradiance[0];
            let r = ui.add(egui::DragValue::new(&mut s).range(0.0..=100.0).speed(0.05));
            if r.changed() && irradiance[0] > 0.0 {
                let k = s / irradiance[0];
                *irradiance = irradiance.map(|c| c * k);
                changed = true;
            }
        }
        Light::Point {
            position,
            intensity,
        } => {
            ui.label("point");
            vec3(ui, position, 0.05);
            ui.label("I");
            vec3(ui, intensity, 0.05);
        }
        Light::Environment { radiance } => {
            ui.label("environment");
            vec3(ui, radiance, 0.02);
        }
        Light::Sky { zenith, .. } => {
            ui.label("sky zenith");
            vec3(ui, zenith, 0.02);
        }
    }
    // Keep lights valid: no zero direction, no negative power.
    if let Light::Directional { direction, .. } = l {
        if direction.iter().all(|c| *c == 0.0) {
            direction[2] = 1.0;
        }
    }
    changed
}

/// The last two components of a path, for the panel's title line.
fn short(p: &str) -> String {
    let parts: Vec<&str> = p.trim_end_matches('/').rsplit('/').take(2).collect();
    parts.into_iter().rev().collect::<Vec<_>>().join("/")
}

impl eframe::App for ViewerApp {
    fn clear_color(&self, visuals: &egui::Visuals) -> [f32; 4] {
        visuals.panel_fill.to_normalized_gamma_f32()
    }

    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        self.ui_frame += 1;
        self.poll_replies(&ctx);
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
