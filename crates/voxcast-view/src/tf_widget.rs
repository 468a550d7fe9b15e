//! The transfer-function editor widget: the log histogram of the data over
//! the window, the opacity curve with its control points above it, and the
//! colour bar with its colour points below.
//!
//! * opacity area: click on empty space adds a point; drag moves one;
//!   right-click (or select and press Delete) removes it;
//! * colour bar: click adds a point with the colour already there (then pick
//!   its colour below the editor); drag moves it; right-click removes it.
//!
//! The histogram and the colour bar are drawn as two textures, remade only
//! when the histogram, the size or the colours change: as hundreds of
//! anti-aliased rectangles they were re-tessellated every frame and cost a
//! software rasteriser (lavapipe) about as much as the rest of the window.

use crate::tf_model::{pick, Curve, LogHistogram, TfModel};
use eframe::egui::{self, Color32, ColorImage, Pos2, Rect, Sense, Stroke, TextureHandle, Vec2};

/// Radius (points) within which a click picks a control point.
const PICK_RADIUS: f32 = 7.0;
/// Height of the colour bar.
const BAR_HEIGHT: f32 = 18.0;

/// Steps of the colour bar.
const BAR_STEPS: usize = 64;
/// Grey of the histogram's background and bars.
const HIST_BG: u8 = 24;
const HIST_BAR: u8 = 70;

/// What the widget keeps between frames.
#[derive(Default)]
pub struct TfWidgetState {
    /// The selected point (its colour is edited below the editor).
    pub selected: Option<(Curve, usize)>,
    /// The point being dragged.
    dragging: Option<(Curve, usize)>,
    /// The histogram texture and what it was made from (heights, size).
    histogram: Option<(Vec<f32>, [usize; 2], TextureHandle)>,
    /// The colour bar texture and the colour points it was made from.
    bar: Option<(Vec<[f32; 4]>, TextureHandle)>,
}

/// The histogram as `w`×`h` pixels: a bar per bin, `heights` (0…1) of the
/// height, bins spread evenly over the width.
pub fn histogram_pixels(heights: &[f32], w: usize, h: usize) -> ColorImage {
    let n = heights.len().max(1);
    let mut img = ColorImage::new([w, h], vec![Color32::from_gray(HIST_BG); w * h]);
    for x in 0..w {
        let bin = (x * n / w.max(1)).min(n - 1);
        let v = heights.get(bin).copied().unwrap_or(0.0).clamp(0.0, 1.0);
        // Rows from the bottom that the bar covers (rounded to whole pixels).
        let rows = (v * h as f32).round() as usize;
        for y in h - rows.min(h)..h {
            img.pixels[y * w + x] = Color32::from_gray(HIST_BAR);
        }
    }
    img
}

fn srgb(c: [f32; 3]) -> Color32 {
    let b = c.map(|x| (x.clamp(0.0, 1.0) * 255.0 + 0.5) as u8);
    Color32::from_rgb(b[0], b[1], b[2])
}

/// Draws the editor `width` points wide; returns true when the map changed.
pub fn show(
    ui: &mut egui::Ui,
    model: &mut TfModel,
    histogram: Option<&LogHistogram>,
    state: &mut TfWidgetState,
    width: f32,
) -> bool {
    let mut changed = false;
    let height = 130.0;
    let (resp, painter) = ui.allocate_painter(
        Vec2::new(width, height + BAR_HEIGHT + 4.0),
        Sense::click_and_drag(),
    );
    let full = resp.rect;
    let area = Rect::from_min_size(full.min, Vec2::new(width, height));
    let bar = Rect::from_min_size(
        Pos2::new(full.min.x, area.max.y + 4.0),
        Vec2::new(width, BAR_HEIGHT),
    );
    // Value/opacity ↔ screen.
    let to_x = |v: f32| area.min.x + v * area.width();
    let to_y = |a: f32| area.max.y - a * area.height();
    let from = |p: Pos2| {
        (
            ((p.x - area.min.x) / area.width()).clamp(0.0, 1.0),
            ((area.max.y - p.y) / area.height()).clamp(0.0, 1.0),
        )
    };

    let uv = Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0));
    match histogram {
        Some(h) => {
            // One texel per screen pixel.
            let ppp = ui.ctx().pixels_per_point();
            let size = [
                (area.width() * ppp).round().max(1.0) as usize,
                (area.height() * ppp).round().max(1.0) as usize,
            ];
            let fresh = state
                .histogram
                .as_ref()
                .is_some_and(|(hh, sz, _)| *sz == size && *hh == h.heights);
            if !fresh {
                let img = histogram_pixels(&h.heights, size[0], size[1]);
                let tex = ui
                    .ctx()
                    .load_texture("tf-histogram", img, egui::TextureOptions::NEAREST);
                state.histogram = Some((h.heights.clone(), size, tex));
            }
            if let Some((_, _, tex)) = &state.histogram {
                painter.image(tex.id(), area, uv, Color32::WHITE);
            }
        }
        None => {
            painter.rect_filled(area, 0.0, Color32::from_gray(HIST_BG));
        }
    }
    // The colour bar: the map's colour at each of `BAR_STEPS` values.
    let colors = model.color();
    if state.bar.as_ref().is_none_or(|(c, _)| c != colors) {
        let px: Vec<Color32> = (0..BAR_STEPS)
            .map(|i| srgb(model.tf().color_at((i as f32 + 0.5) / BAR_STEPS as f32)))
            .collect();
        let img = ColorImage::new([BAR_STEPS, 1], px);
        let tex = ui
            .ctx()
            .load_texture("tf-colour-bar", img, egui::TextureOptions::NEAREST);
        state.bar = Some((colors.to_vec(), tex));
    }
    if let Some((_, tex)) = &state.bar {
        painter.image(tex.id(), bar, uv, Color32::WHITE);
    }
    // The opacity curve, held flat beyond the end points.
    let op = model.opacity();
    let mut line = vec![Pos2::new(area.min.x, to_y(op[0][1]))];
    line.extend(op.iter().map(|p| Pos2::new(to_x(p[0]), to_y(p[1]))));
    line.push(Pos2::new(area.max.x, to_y(op[op.len() - 1][1])));
    painter.line(line, Stroke::new(1.5, Color32::from_rgb(240, 200, 80)));

    // Screen positions of the points, for picking.
    let op_pts: Vec<[f32; 2]> = model
        .opacity()
        .iter()
        .map(|p| [to_x(p[0]), to_y(p[1])])
        .collect();
    let col_pts: Vec<[f32; 2]> = model
        .color()
        .iter()
        .map(|p| [to_x(p[0]), bar.center().y])
        .collect();
    let hit = |p: Pos2| -> Option<(Curve, usize)> {
        if p.y >= bar.min.y - 2.0 {
            pick(&col_pts, [p.x, bar.center().y], PICK_RADIUS).map(|i| (Curve::Color, i))
        } else {
            pick(&op_pts, [p.x, p.y], PICK_RADIUS).map(|i| (Curve::Opacity, i))
        }
    };

    if resp.drag_started() {
        if let Some(p) = resp.interact_pointer_pos() {
            state.dragging = hit(p);
            if state.dragging.is_some() {
                state.selected = state.dragging;
            }
        }
    }
    if resp.dragged() {
        if let (Some((curve, i)), Some(p)) = (state.dragging, resp.interact_pointer_pos()) {
            let (v, a) = from(p);
            match curve {
                Curve::Opacity => model.move_opacity(i, v, a),
                Curve::Color => model.move_color(i, v),
            }
            changed = true;
        }
    }
    if resp.drag_stopped() {
        state.dragging = None;
    }
    if resp.clicked() {
        if let Some(p) = resp.interact_pointer_pos() {
            match hit(p) {
                Some(h) => state.selected = Some(h),
                None => {
                    let (v, a) = from(p);
                    let i = if p.y >= bar.min.y - 2.0 {
                        (Curve::Color, model.add_color(v))
                    } else {
                        (Curve::Opacity, model.add_opacity(v, a))
                    };
                    state.selected = Some(i);
                    changed = true;
                }
            }
        }
    }
    let delete_key = resp.hovered() && ui.input(|i| i.key_pressed(egui::Key::Delete));
    let remove = if resp.secondary_clicked() {
        resp.interact_pointer_pos().and_then(hit)
    } else if delete_key {
        state.selected
    } else {
        None
    };
    if let Some((curve, i)) = remove {
        if model.remove(curve, i) {
            state.selected = None;
            changed = true;
        }
    }
    // Selection can point past the end after edits elsewhere (presets).
    if let Some((c, i)) = state.selected {
        if i >= model.len(c) {
            state.selected = None;
        }
    }

    // Points on top.
    for (i, p) in model.opacity().iter().enumerate() {
        let sel = state.selected == Some((Curve::Opacity, i));
        let c = Pos2::new(to_x(p[0]), to_y(p[1]));
        painter.circle_filled(c, if sel { 5.5 } else { 4.0 }, Color32::WHITE);
        painter.circle_stroke(c, 4.0, Stroke::new(1.0, Color32::BLACK));
    }
    for (i, p) in model.color().iter().enumerate() {
        let sel = state.selected == Some((Curve::Color, i));
        let c = Pos2::new(to_x(p[0]), bar.center().y);
        let r = if sel { 7.0 } else { 5.0 };
        painter.rect_filled(
            Rect::from_center_size(c, Vec2::splat(r * 2.0)),
            1.0,
            srgb([p[1], p[2], p[3]]),
        );
        let ring = if sel { Color32::YELLOW } else { Color32::WHITE };
        painter.rect_stroke(
            Rect::from_center_size(c, Vec2::splat(r * 2.0)),
            1.0,
            Stroke::new(1.5, ring),
            egui::StrokeKind::Outside,
        );
    }

    // The selected point's numbers (and colour).
    ui.horizontal(|ui| match state.selected {
        Some((Curve::Opacity, i)) => {
            let p = model.opacity()[i];
            let (mut v, mut a) = (p[0], p[1]);
            let r1 = ui.add(
                egui::DragValue::new(&mut v)
                    .range(0.0..=1.0)
                    .speed(0.002)
                    .prefix("value "),
            );
            let r2 = ui.add(
                egui::DragValue::new(&mut a)
                    .range(0.0..=1.0)
                    .speed(0.002)
                    .prefix("opacity "),
            );
            if r1.changed() || r2.changed() {
                model.move_opacity(i, v, a);
                changed = true;
            }
        }
        Some((Curve::Color, i)) => {
            let p = model.color()[i];
            let mut rgb = [p[1], p[2], p[3]].map(|x| (x * 255.0 + 0.5) as u8);
            ui.label(format!("value {:.3}", p[0]));
            if egui::color_picker::color_edit_button_srgb(ui, &mut rgb).changed() {
                model.set_color(i, rgb.map(|x| x as f32 / 255.0));
                changed = true;
            }
        }
        None => {
            ui.weak("click: add a point · drag: move · right-click: remove");
        }
    });
    changed
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn histogram_pixels_draw_one_bar_per_bin() {
        // Two bins over 4×10 pixels: half height, then full height.
        let img = histogram_pixels(&[0.5, 1.0], 4, 10);
        let at = |x: usize, y: usize| img.pixels[y * 4 + x];
        let bg = Color32::from_gray(HIST_BG);
        let bar = Color32::from_gray(HIST_BAR);
        for x in 0..2 {
            assert_eq!(at(x, 4), bg, "above the first bar");
            assert_eq!(at(x, 5), bar, "top of the first bar");
            assert_eq!(at(x, 9), bar);
        }
        for x in 2..4 {
            assert_eq!(at(x, 0), bar, "the full bar");
        }
        // Empty and out-of-range heights.
        let img = histogram_pixels(&[0.0, 7.0, -1.0], 3, 2);
        assert_eq!(img.pixels, vec![bg, bar, bg, bg, bar, bg]);
    }
}
