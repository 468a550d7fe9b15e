//! Scripted runs (`--orbit`, `--screenshot`, `--script-stats`): the
//! script's steps, its end, and screenshots of the window.

use crate::progressive::Quality;
use crate::screenshot::{crop_rgba, Rgb8};
use eframe::egui::{self};
use std::path::PathBuf;
use std::time::Instant;

use super::{ViewerApp, ORBIT_SPEED};

impl ViewerApp {
    /// The scripted orbit and exit.
    pub(super) fn run_script(&mut self, ctx: &egui::Context) {
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
        // The refined image: full quality, and of the finest level a store
        // is read down to.
        let refined = self.shown.as_ref().is_some_and(|sh| {
            sh.generation == self.version
                && sh.quality == Quality::Full
                && sh.painted_at < self.ui_frame
        }) && !self.levels.as_ref().is_some_and(|l| l.refining())
            && !self.store.as_ref().is_some_and(|st| st.refining());
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
    pub(super) fn finish(&mut self, ctx: &egui::Context, result: Result<(), String>) {
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
            st.backend = crate::backend::label(&self.device).to_string();
            st
        });
        let mut o = self.outcome.lock().unwrap_or_else(|e| e.into_inner());
        if o.is_none() {
            *o = Some(result.map(|()| stats.unwrap_or_default()));
        }
        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
    }

    pub(super) fn request_screenshot(&mut self, ctx: &egui::Context, path: PathBuf) {
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
    pub(super) fn take_screenshot(&mut self, ctx: &egui::Context) {
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
}
