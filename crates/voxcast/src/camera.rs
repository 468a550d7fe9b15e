//! The camera: perspective or orthographic, orbiting the volume's centre.
//!
//! Axis convention (world = the volume's physical coordinates, right-handed):
//! at azimuth 0 and elevation 0 the camera looks along **+y**, with **+x to
//! the right** of the image and **+z up**. Positive azimuth orbits the camera
//! counter-clockwise seen from +z (from −y towards +x), so the volume appears
//! to turn clockwise; positive elevation raises the camera towards +z and
//! looks down. Image row 0 is the top.

use glam::Vec3;
use serde::{Deserialize, Serialize};

/// Projection type.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Projection {
    #[default]
    Perspective,
    Orthographic,
}

/// How the user places the camera (plain data, part of the scene).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[serde(default)]
pub struct CameraParams {
    pub projection: Projection,
    /// Degrees about +z, counter-clockwise seen from above.
    pub azimuth: f32,
    /// Degrees above the xy plane.
    pub elevation: f32,
    /// Magnification relative to the auto-fit (2 = twice as large).
    pub zoom: f32,
    /// Vertical field of view in degrees (perspective).
    pub fov: f32,
    /// Place the camera explicitly, as pbrt's and Mitsuba's `LookAt`
    /// (world coordinates); orbit and zoom are then ignored.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub look_at: Option<LookAt>,
}

/// A camera by eye position, target point and up vector (world units),
/// with the vertical field of view of [`CameraParams::fov`]:
/// `look_at = { origin = [0, -4, 1], target = [0, 0, 0], up = [0, 0, 1] }`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LookAt {
    pub origin: [f32; 3],
    pub target: [f32; 3],
    #[serde(default = "LookAt::z_up")]
    pub up: [f32; 3],
}

impl LookAt {
    fn z_up() -> [f32; 3] {
        [0.0, 0.0, 1.0]
    }

    /// Checks that the eye is not the target and `up` is not along the view.
    pub fn validate(&self) -> Result<(), crate::FieldError> {
        let f = Vec3::from(self.target) - Vec3::from(self.origin);
        let up = Vec3::from(self.up);
        if !(f.is_finite() && up.is_finite())
            || f.length() < 1e-9
            || f.cross(up).length() < 1e-9 * f.length() * up.length().max(1e-30)
        {
            return Err(crate::FieldError::new(
                "camera.look_at",
                format!("{self:?}: origin and target must differ and up must not be parallel to the view"),
            ));
        }
        Ok(())
    }
}

impl CameraParams {
    /// Checks every camera value a user may set (flags, a scene file or the
    /// API alike): finite angles, a positive zoom, a field of view of 1…170
    /// degrees, a proper `look_at`. Both renderers refuse what fails it, so
    /// nothing is clamped or reset quietly.
    pub fn validate(&self) -> Result<(), crate::FieldError> {
        let bad = |field: &str, m: String| Err(crate::FieldError::new(field, m));
        for (field, v) in [
            ("camera.azimuth", self.azimuth),
            ("camera.elevation", self.elevation),
        ] {
            if !v.is_finite() {
                return bad(field, format!("{v}: expected a finite angle in degrees"));
            }
        }
        if !(self.zoom.is_finite() && self.zoom > 0.0) {
            return bad(
                "camera.zoom",
                format!("{}: must be a positive number", self.zoom),
            );
        }
        if !(1.0..=170.0).contains(&self.fov) {
            return bad(
                "camera.fov",
                format!("{}: must be between 1 and 170 degrees", self.fov),
            );
        }
        match &self.look_at {
            Some(l) => l.validate(),
            None => Ok(()),
        }
    }
}

impl Default for CameraParams {
    fn default() -> Self {
        CameraParams {
            projection: Projection::Perspective,
            azimuth: 0.0,
            elevation: 0.0,
            zoom: 1.0,
            fov: 30.0,
            look_at: None,
        }
    }
}

/// A camera fitted to a box and an image size; gives one ray per pixel.
#[derive(Clone, Copy, Debug)]
pub struct Camera {
    pub eye: Vec3,
    pub forward: Vec3,
    pub right: Vec3,
    pub up: Vec3,
    pub(crate) projection: Projection,
    /// Half height of the image plane at distance 1 (perspective) or in
    /// world units (orthographic).
    pub(crate) half_height: f32,
    pub(crate) aspect: f32,
    pub(crate) width: u32,
    pub(crate) height: u32,
}

impl Camera {
    /// Frames the box `[lo, hi]` so that its bounding sphere fits the image,
    /// then applies orbit and zoom.
    pub fn fit(params: &CameraParams, lo: Vec3, hi: Vec3, width: u32, height: u32) -> Camera {
        if let Some(l) = params.look_at.filter(|l| l.validate().is_ok()) {
            return Camera::look_at(&l, params.fov, params.projection, lo, hi, width, height);
        }
        let center = (lo + hi) * 0.5;
        let radius = ((hi - lo).length() * 0.5).max(1e-6);
        let az = params.azimuth.to_radians();
        let el = params.elevation.clamp(-89.9, 89.9).to_radians();
        // Unit vector from the centre to the eye.
        let to_eye = Vec3::new(az.sin() * el.cos(), -az.cos() * el.cos(), el.sin());
        let forward = -to_eye;
        let right = forward.cross(Vec3::Z).normalize();
        let up = right.cross(forward);
        let aspect = width as f32 / height.max(1) as f32;
        let zoom = if params.zoom > 0.0 { params.zoom } else { 1.0 };
        match params.projection {
            Projection::Perspective => {
                let fov = params.fov.clamp(1.0, 170.0).to_radians();
                let tan_v = (fov * 0.5).tan();
                // The sphere must fit the narrower of the two fields of view.
                let tan_min = tan_v * aspect.min(1.0);
                let half_min = tan_min.atan();
                let dist = radius / half_min.sin() / zoom;
                Camera {
                    eye: center + to_eye * dist,
                    forward,
                    right,
                    up,
                    projection: Projection::Perspective,
                    half_height: tan_v,
                    aspect,
                    width,
                    height,
                }
            }
            Projection::Orthographic => {
                let half = radius / zoom / aspect.min(1.0);
                Camera {
                    eye: center + to_eye * (radius * 3.0),
                    forward,
                    right,
                    up,
                    projection: Projection::Orthographic,
                    half_height: half,
                    aspect,
                    width,
                    height,
                }
            }
        }
    }

    /// A camera at `l.origin` looking at `l.target` with vertical field of
    /// view `fov` degrees (orthographic: the image height spans the box's
    /// bounding sphere at the target).
    pub fn look_at(
        l: &LookAt,
        fov: f32,
        projection: Projection,
        lo: Vec3,
        hi: Vec3,
        width: u32,
        height: u32,
    ) -> Camera {
        let eye = Vec3::from(l.origin);
        let forward = (Vec3::from(l.target) - eye).normalize();
        let right = forward.cross(Vec3::from(l.up)).normalize();
        let up = right.cross(forward);
        let aspect = width as f32 / height.max(1) as f32;
        let half_height = match projection {
            Projection::Perspective => (fov.clamp(1.0, 170.0).to_radians() * 0.5).tan(),
            Projection::Orthographic => ((hi - lo).length() * 0.5).max(1e-6),
        };
        Camera {
            eye,
            forward,
            right,
            up,
            projection,
            half_height,
            aspect,
            width,
            height,
        }
    }

    /// The ray through the centre of pixel `(x, y)` (row 0 at the top):
    /// origin and unit direction.
    #[inline]
    pub fn ray(&self, x: u32, y: u32) -> (Vec3, Vec3) {
        self.ray_at(x as f32 + 0.5, y as f32 + 0.5)
    }

    /// Where world point `p` falls on the image, in pixels (the inverse of
    /// [`Camera::ray_at`]); `None` for a perspective camera when `p` is not
    /// in front of the eye.
    pub fn project(&self, p: Vec3) -> Option<(f32, f32)> {
        let d = p - self.eye;
        let (sx, sy) = match self.projection {
            Projection::Perspective => {
                let z = d.dot(self.forward);
                if z <= 1e-6 {
                    return None;
                }
                (d.dot(self.right) / z, d.dot(self.up) / z)
            }
            Projection::Orthographic => (d.dot(self.right), d.dot(self.up)),
        };
        let px = (sx / (self.half_height * self.aspect) + 1.0) * 0.5 * self.width as f32;
        let py = (1.0 - sy / self.half_height) * 0.5 * self.height as f32;
        Some((px, py))
    }

    /// Whether the camera is orthographic.
    pub fn is_orthographic(&self) -> bool {
        self.projection == Projection::Orthographic
    }

    /// The size of one pixel in world units at distance `z` along the view
    /// direction (the same at every distance for an orthographic camera).
    pub fn pixel_size_at(&self, z: f32) -> f32 {
        match self.projection {
            Projection::Perspective => 2.0 * self.half_height * z.max(0.0) / self.height as f32,
            Projection::Orthographic => 2.0 * self.half_height / self.height as f32,
        }
    }

    /// The ray through image position `(px, py)` in pixels.
    #[inline]
    pub fn ray_at(&self, px: f32, py: f32) -> (Vec3, Vec3) {
        let sx = (2.0 * px / self.width as f32 - 1.0) * self.half_height * self.aspect;
        let sy = (1.0 - 2.0 * py / self.height as f32) * self.half_height;
        match self.projection {
            Projection::Perspective => {
                let d = (self.forward + self.right * sx + self.up * sy).normalize();
                (self.eye, d)
            }
            Projection::Orthographic => (self.eye + self.right * sx + self.up * sy, self.forward),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn project(cam: &Camera, p: Vec3) -> (f32, f32) {
        // Inverse of ray_at for a perspective camera.
        let d = p - cam.eye;
        let z = d.dot(cam.forward);
        let sx = d.dot(cam.right) / z;
        let sy = d.dot(cam.up) / z;
        let px = (sx / (cam.half_height * cam.aspect) + 1.0) * 0.5 * cam.width as f32;
        let py = (1.0 - sy / cam.half_height) * 0.5 * cam.height as f32;
        (px, py)
    }

    #[test]
    fn default_view_has_x_right_z_up() {
        let cam = Camera::fit(
            &CameraParams::default(),
            Vec3::ZERO,
            Vec3::splat(10.0),
            100,
            100,
        );
        assert!((cam.forward - Vec3::Y).length() < 1e-6);
        assert!((cam.right - Vec3::X).length() < 1e-6);
        assert!((cam.up - Vec3::Z).length() < 1e-6);
        let (px, _) = project(&cam, Vec3::new(10.0, 5.0, 5.0));
        assert!(px > 60.0);
        let (_, py) = project(&cam, Vec3::new(5.0, 5.0, 10.0));
        assert!(py < 40.0);
    }

    #[test]
    fn look_at_points_the_centre_ray_at_the_target() {
        let p = CameraParams {
            fov: 40.0,
            look_at: Some(LookAt {
                origin: [1.0, -5.0, 2.0],
                target: [0.0, 0.0, 0.5],
                up: [0.0, 0.0, 1.0],
            }),
            ..Default::default()
        };
        let cam = Camera::fit(&p, Vec3::ZERO, Vec3::ONE, 64, 48);
        let (o, d) = cam.ray_at(32.0, 24.0);
        let to = (Vec3::new(0.0, 0.0, 0.5) - o).normalize();
        assert!((d - to).length() < 1e-5);
        // The top edge is fov/2 above the centre.
        let (_, top) = cam.ray_at(32.0, 0.0);
        assert!((top.dot(d).acos().to_degrees() - 20.0).abs() < 1e-3);
        assert!(top.z > d.z);
        let bad = LookAt {
            origin: [0.0; 3],
            target: [0.0, 0.0, 1.0],
            up: [0.0, 0.0, 1.0],
        };
        assert!(bad.validate().is_err());
    }

    #[test]
    fn azimuth_90_looks_along_minus_x() {
        let p = CameraParams {
            azimuth: 90.0,
            ..Default::default()
        };
        let cam = Camera::fit(&p, Vec3::ZERO, Vec3::ONE, 64, 64);
        assert!((cam.forward + Vec3::X).length() < 1e-5);
        assert!((cam.eye.x - 0.5) > 0.0);
    }

    #[test]
    fn fit_keeps_the_box_inside_the_image() {
        for proj in [Projection::Perspective, Projection::Orthographic] {
            let p = CameraParams {
                projection: proj,
                azimuth: 33.0,
                elevation: 21.0,
                ..Default::default()
            };
            let (lo, hi) = (Vec3::new(-3.0, 0.0, 1.0), Vec3::new(5.0, 2.0, 9.0));
            let cam = Camera::fit(&p, lo, hi, 200, 100);
            // Corner rays: every corner of the box projects inside the image.
            for i in 0..8 {
                let c = Vec3::new(
                    if i & 1 == 0 { lo.x } else { hi.x },
                    if i & 2 == 0 { lo.y } else { hi.y },
                    if i & 4 == 0 { lo.z } else { hi.z },
                );
                let (px, py) = match proj {
                    Projection::Perspective => project(&cam, c),
                    Projection::Orthographic => {
                        let d = c - cam.eye;
                        let sx = d.dot(cam.right);
                        let sy = d.dot(cam.up);
                        (
                            (sx / (cam.half_height * cam.aspect) + 1.0) * 100.0,
                            (1.0 - sy / cam.half_height) * 50.0,
                        )
                    }
                };
                assert!(
                    (0.0..=200.0).contains(&px) && (0.0..=100.0).contains(&py),
                    "{proj:?} {c} → {px},{py}"
                );
            }
        }
    }
}
