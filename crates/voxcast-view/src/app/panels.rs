//! The window's parts drawn each frame: the volume view (the image, orbit,
//! zoom and pan), the stats bar, and the control panel (transfer-function
//! editor, rendering options, lights, time, saving).

use crate::image_paint::{self};
use crate::progressive::Quality;
use crate::tf_model::TfModel;
use crate::tf_widget::{self};
use eframe::egui::{self, Color32, Pos2, Rect, Sense, Vec2};
use std::path::PathBuf;
use std::time::{Duration, Instant};
use voxcast::render::light::Light;
use voxcast::render::{Method, OpticalModel};
use voxcast::transfer::{TransferFunction, PRESETS};

use super::{Pixels, ViewerApp, PANEL_WIDTH};

impl ViewerApp {
    pub(super) fn view(&mut self, ui: &mut egui::Ui) {
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

    pub(super) fn stats_bar(&self, ui: &mut egui::Ui) {
        ui.horizontal_centered(|ui| {
            let now = Instant::now();
            let recent = self
                .shown_times
                .iter()
                .filter(|t| now.duration_since(**t) < Duration::from_secs(1))
                .count();
            let mut text = format!("{} · ", crate::backend::label(&self.device));
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
            if let Some(l) = &self.levels {
                let shown = self.shown.as_ref().map_or(l.level, |s| s.frame);
                text += &format!(" · level {shown} of 0…{}", l.coarsest);
                if l.refining() || shown != l.level {
                    text += ", refining…";
                } else if l.failed.is_some() {
                    text += ", refining failed";
                } else if l.finest > 0 {
                    text += " (the finest that fits in memory)";
                }
            }
            if let Some(st) = &self.store {
                let f = self.shown.as_ref().and_then(|s| s.store);
                match f {
                    Some(f) if f.finest == f.coarsest => {
                        text += &format!(" · level {} of 0…{}", f.finest, st.coarsest)
                    }
                    Some(f) => {
                        text +=
                            &format!(" · levels {}…{} of 0…{}", f.finest, f.coarsest, st.coarsest)
                    }
                    None => text += &format!(" · levels of 0…{}", st.coarsest),
                }
                match f {
                    Some(f) if f.wanted > 0 => text += &format!(", reading {} chunks…", f.wanted),
                    Some(f) if f.over_budget => text += " (all the memory budget holds)",
                    _ => {}
                }
            }
            ui.monospace(text);
            if !self.message.is_empty() {
                ui.colored_label(Color32::from_rgb(255, 200, 120), &self.message);
            }
        });
    }

    pub(super) fn controls(&mut self, ui: &mut egui::Ui) {
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
