//! The camera controller: mouse gestures to the scene's camera, without a
//! window (so that it can be tested).
//!
//! * drag: orbit — the volume turns with the mouse (drag right: the front
//!   moves right, so the camera's azimuth falls; drag down: the camera rises);
//! * wheel: zoom, by a factor per notch, so zooming in and out again returns
//!   to the same view;
//! * modifier-drag (or right/middle drag): pan — the point under the mouse
//!   follows it (perspective only: the scene's orthographic `look_at` camera
//!   has no zoom, so a panned orthographic view could not keep its zoom).
//!
//! The scene format has no pan of its own: a panned view is written as the
//! equivalent explicit `look_at` camera (eye and target both shifted), which
//! the renderer draws identically. An orbit view without pan stays in
//! azimuth/elevation/zoom form.

use glam::Vec3;
use voxcast::camera::{Camera, CameraParams, LookAt, Projection};

/// Degrees of orbit per pixel of drag.
pub const DEG_PER_PIXEL: f32 = 0.4;
/// Zoom factor per wheel point (egui gives about 50 points per notch).
pub const ZOOM_PER_POINT: f32 = 1.0025;
/// Elevation stays inside ±this (the orbit camera's up is +z).
pub const MAX_ELEVATION: f32 = 89.0;

/// Orbit angles, zoom and pan of the viewer's camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrbitController {
    pub projection: Projection,
    pub azimuth: f32,
    pub elevation: f32,
    pub zoom: f32,
    pub fov: f32,
    /// Shift of the orbit centre in the camera's right/up directions, as a
    /// fraction of the bounding sphere's radius.
    pub pan: [f32; 2],
    /// The framed box (the volume and any geometry), world units.
    pub bounds: (Vec3, Vec3),
}

impl OrbitController {
    /// Starts from the scene's camera. An explicit `look_at` camera is
    /// turned into the orbit view nearest to it (its direction; its distance
    /// as zoom; its target as pan).
    pub fn new(params: &CameraParams, bounds: (Vec3, Vec3)) -> OrbitController {
        let mut c = OrbitController {
            projection: params.projection,
            azimuth: params.azimuth,
            elevation: params.elevation.clamp(-MAX_ELEVATION, MAX_ELEVATION),
            zoom: if params.zoom > 0.0 { params.zoom } else { 1.0 },
            fov: params.fov,
            pan: [0.0, 0.0],
            bounds,
        };
        if let Some(l) = params.look_at.filter(|l| l.validate().is_ok()) {
            let (o, t) = (Vec3::from(l.origin), Vec3::from(l.target));
            let to_eye = (o - t).normalize();
            c.elevation = to_eye
                .z
                .asin()
                .to_degrees()
                .clamp(-MAX_ELEVATION, MAX_ELEVATION);
            c.azimuth = to_eye.x.atan2(-to_eye.y).to_degrees();
            // The fitted distance at zoom 1, to turn |o − t| into a zoom.
            let fit = Camera::fit(
                &CameraParams {
                    look_at: None,
                    zoom: 1.0,
                    ..c.params_unpanned()
                },
                bounds.0,
                bounds.1,
                1,
                1,
            );
            let d1 = (fit.eye - c.center()).length();
            let d = (o - t).length();
            if params.projection == Projection::Perspective && d > 0.0 {
                c.zoom = d1 / d;
            }
            let off = t - c.center();
            let cam = c.fitted(1, 1);
            let r = c.radius();
            c.pan = [off.dot(cam.right) / r, off.dot(cam.up) / r];
        }
        c
    }

    fn center(&self) -> Vec3 {
        (self.bounds.0 + self.bounds.1) * 0.5
    }

    fn radius(&self) -> f32 {
        ((self.bounds.1 - self.bounds.0).length() * 0.5).max(1e-6)
    }

    fn params_unpanned(&self) -> CameraParams {
        CameraParams {
            projection: self.projection,
            azimuth: self.azimuth,
            elevation: self.elevation,
            zoom: self.zoom,
            fov: self.fov,
            look_at: None,
        }
    }

    fn fitted(&self, width: u32, height: u32) -> Camera {
        Camera::fit(
            &self.params_unpanned(),
            self.bounds.0,
            self.bounds.1,
            width,
            height,
        )
    }

    /// A drag of `(dx, dy)` pixels (y down): orbit.
    pub fn orbit(&mut self, dx: f32, dy: f32) {
        self.azimuth = wrap_degrees(self.azimuth - dx * DEG_PER_PIXEL);
        self.elevation = (self.elevation + dy * DEG_PER_PIXEL).clamp(-MAX_ELEVATION, MAX_ELEVATION);
    }

    /// A wheel scroll of `dy` points (positive: away from the user, zoom in).
    pub fn scroll(&mut self, dy: f32) {
        self.zoom = (self.zoom * ZOOM_PER_POINT.powf(dy)).clamp(0.05, 200.0);
    }

    /// A pan drag of `(dx, dy)` pixels in a view `height` pixels high: the
    /// point at the orbit centre's depth moves with the mouse.
    /// Orthographic views do not pan (see the module comment).
    pub fn pan_by(&mut self, dx: f32, dy: f32, width: u32, height: u32) {
        if self.projection != Projection::Perspective {
            return;
        }
        let cam = self.fitted(width.max(1), height.max(1));
        // World units per pixel at the centre's depth.
        let (_, d0) = cam.ray_at(0.0, height as f32 * 0.5);
        let (_, d1) = cam.ray_at(width as f32, height as f32 * 0.5);
        let depth = (self.center() - cam.eye).dot(cam.forward);
        let span = (d1 / d1.dot(cam.forward) - d0 / d0.dot(cam.forward)).length() * depth;
        let per_px = span / width.max(1) as f32;
        let r = self.radius();
        self.pan[0] -= dx * per_px / r;
        self.pan[1] += dy * per_px / r;
    }

    /// Back to the scene's framing: no pan, zoom 1.
    pub fn reset(&mut self) {
        self.pan = [0.0, 0.0];
        self.zoom = 1.0;
    }

    /// The camera for a scene rendered at `width`×`height`: orbit form when
    /// not panned, else the equivalent `look_at`.
    pub fn params(&self, width: u32, height: u32) -> CameraParams {
        let base = self.params_unpanned();
        if self.pan == [0.0, 0.0] || self.projection != Projection::Perspective {
            return base;
        }
        let cam = self.fitted(width.max(1), height.max(1));
        let r = self.radius();
        let shift = cam.right * (self.pan[0] * r) + cam.up * (self.pan[1] * r);
        let target = self.center() + shift;
        CameraParams {
            look_at: Some(LookAt {
                origin: (cam.eye + shift).to_array(),
                target: target.to_array(),
                up: cam.up.to_array(),
            }),
            ..base
        }
    }
}

/// Degrees into (−180, 180].
fn wrap_degrees(a: f32) -> f32 {
    let mut a = a % 360.0;
    if a <= -180.0 {
        a += 360.0;
    } else if a > 180.0 {
        a -= 360.0;
    }
    a
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_box() -> (Vec3, Vec3) {
        (Vec3::ZERO, Vec3::new(2.0, 2.0, 2.0))
    }

    #[test]
    fn drag_right_turns_the_front_right_and_drag_down_raises_the_camera() {
        let mut c = OrbitController::new(&CameraParams::default(), unit_box());
        c.orbit(50.0, 0.0);
        assert!(
            (c.azimuth + 50.0 * DEG_PER_PIXEL).abs() < 1e-5,
            "{}",
            c.azimuth
        );
        // Seen from the new camera, the point that faced the old camera
        // (the −y face) has moved right in the image.
        let cam = Camera::fit(&c.params(100, 100), unit_box().0, unit_box().1, 100, 100);
        let front = Vec3::new(1.0, 0.0, 1.0);
        assert!((front - cam.eye).dot(cam.right) > 0.0);
        c.orbit(0.0, 25.0);
        assert!((c.elevation - 10.0).abs() < 1e-5);
        let cam = Camera::fit(&c.params(100, 100), unit_box().0, unit_box().1, 100, 100);
        assert!(cam.eye.z > 1.0, "the camera rose: {}", cam.eye);
    }

    #[test]
    fn elevation_is_clamped_and_azimuth_wraps() {
        let mut c = OrbitController::new(&CameraParams::default(), unit_box());
        c.orbit(0.0, 10_000.0);
        assert_eq!(c.elevation, MAX_ELEVATION);
        c.orbit(0.0, -20_000.0);
        assert_eq!(c.elevation, -MAX_ELEVATION);
        c.orbit(-1000.0, 0.0); // +400°
        assert!((c.azimuth - 40.0).abs() < 1e-3, "{}", c.azimuth);
    }

    #[test]
    fn wheel_zooms_and_undoes() {
        let mut c = OrbitController::new(&CameraParams::default(), unit_box());
        c.scroll(100.0);
        assert!(c.zoom > 1.2);
        let cam_in = Camera::fit(&c.params(64, 64), unit_box().0, unit_box().1, 64, 64);
        c.scroll(-100.0);
        assert!((c.zoom - 1.0).abs() < 1e-5);
        let cam = Camera::fit(&c.params(64, 64), unit_box().0, unit_box().1, 64, 64);
        assert!(
            (cam_in.eye - Vec3::ONE).length() < (cam.eye - Vec3::ONE).length(),
            "zooming in brings the eye closer"
        );
    }

    #[test]
    fn pan_moves_the_centre_with_the_mouse() {
        let (lo, hi) = unit_box();
        {
            let proj = Projection::Perspective;
            let mut c = OrbitController::new(
                &CameraParams {
                    projection: proj,
                    azimuth: 30.0,
                    elevation: 20.0,
                    ..Default::default()
                },
                (lo, hi),
            );
            let (w, h) = (200, 100);
            let before = Camera::fit(&c.params(w, h), lo, hi, w, h);
            let centre = Vec3::ONE;
            let px_before = project(&before, centre);
            c.pan_by(30.0, -10.0, w, h);
            let p = c.params(w, h);
            assert!(p.look_at.is_some());
            let after = Camera::fit(&p, lo, hi, w, h);
            let px_after = project(&after, centre);
            // The volume's centre moved by the drag (30 right, 10 up).
            assert!(
                (px_after.0 - px_before.0 - 30.0).abs() < 0.5
                    && (px_after.1 - px_before.1 + 10.0).abs() < 0.5,
                "{proj:?}: {px_before:?} → {px_after:?}"
            );
            // The view direction did not change.
            assert!((after.forward - before.forward).length() < 1e-5);
        }
        let mut c = OrbitController::new(
            &CameraParams {
                projection: Projection::Orthographic,
                ..Default::default()
            },
            (lo, hi),
        );
        c.pan_by(30.0, -10.0, 200, 100);
        assert_eq!(c.pan, [0.0, 0.0], "orthographic views do not pan");
        assert!(c.params(200, 100).look_at.is_none());
    }

    #[test]
    fn unpanned_view_stays_in_orbit_form_and_look_at_round_trips() {
        let mut c = OrbitController::new(
            &CameraParams {
                azimuth: -70.0,
                elevation: 35.0,
                zoom: 1.7,
                ..Default::default()
            },
            unit_box(),
        );
        assert!(c.params(80, 60).look_at.is_none());
        c.pan_by(12.0, 7.0, 80, 60);
        let p = c.params(80, 60);
        let back = OrbitController::new(&p, unit_box());
        assert!((back.azimuth - c.azimuth).abs() < 1e-3, "{back:?}");
        assert!((back.elevation - c.elevation).abs() < 1e-3);
        assert!((back.zoom - c.zoom).abs() < 1e-3);
        assert!((back.pan[0] - c.pan[0]).abs() < 1e-4 && (back.pan[1] - c.pan[1]).abs() < 1e-4);
    }

    /// Pixel position of world point `p` for a pinhole camera: `ray_at`
    /// inverted on the plane at distance 1.
    fn project(cam: &Camera, p: Vec3) -> (f32, f32) {
        // Two rays a pixel apart give the image-plane axes.
        let (_, d) = cam.ray_at(0.0, 0.0);
        let (_, dx) = cam.ray_at(1.0, 0.0);
        let (_, dy) = cam.ray_at(0.0, 1.0);
        let f = cam.forward;
        let plane = |d: Vec3| d / d.dot(f);
        let (a, ax, ay) = (plane(d), plane(dx), plane(dy));
        let q = plane(p - cam.eye);
        let (ux, uy) = (ax - a, ay - a);
        let v = q - a;
        (
            v.dot(ux) / ux.length_squared(),
            v.dot(uy) / uy.length_squared(),
        )
    }
}
