//! Lighting of the opaque surfaces: Blinn–Phong with one directional key
//! light and an ambient term, the surface counterpart of the volume's
//! headlight in `render::shading`. Lighting is two-sided: the normal is
//! turned towards the viewer, so a plane or an open mesh seen from behind
//! is lit like its front.

use crate::camera::Camera;
use glam::Vec3;

/// The key light and the Blinn–Phong weights.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceLight {
    /// Unit direction from a surface point towards the light.
    pub to_light: Vec3,
    pub ambient: f32,
    pub diffuse: f32,
    pub specular: f32,
    pub shininess: f32,
}

impl SurfaceLight {
    /// A key light towards `dir` (world, any length), or, with `None`, from
    /// above-left-behind the camera so the faces the camera sees are lit
    /// from every orbit angle.
    pub fn new(dir: Option<[f32; 3]>, cam: &Camera) -> SurfaceLight {
        let to_light = dir
            .map(Vec3::from)
            .filter(|d| d.length_squared() > 0.0 && d.is_finite())
            .unwrap_or(-cam.forward + 0.9 * cam.up - 0.5 * cam.right)
            .normalize();
        SurfaceLight {
            to_light,
            ambient: 0.3,
            diffuse: 0.7,
            specular: 0.15,
            shininess: 32.0,
        }
    }

    /// Linear colour of a surface of linear albedo `albedo` with geometric
    /// normal `n`, seen along `dir` (from the eye), receiving the fraction
    /// `light` of the key light (1 unshadowed, the smoke's transmittance in
    /// its shadow). Never brighter than white, like the volume's shading.
    #[inline(always)]
    pub fn shade(&self, albedo: Vec3, n: Vec3, dir: Vec3, light: f32) -> Vec3 {
        let n = if n.dot(dir) > 0.0 { -n } else { n };
        let ndl = n.dot(self.to_light);
        if ndl <= 0.0 {
            return albedo * self.ambient;
        }
        let h = (self.to_light - dir).normalize_or_zero();
        let x = n.dot(h).max(0.0);
        // A whole exponent (the default 32) by multiplications: `powf` was
        // 6 % of a frame of the office scene, one call per surface pixel.
        let spec = if self.shininess.fract() == 0.0 && (0.0..=64.0).contains(&self.shininess) {
            x.powi(self.shininess as i32)
        } else {
            x.powf(self.shininess)
        };
        (albedo * (self.ambient + self.diffuse * ndl * light)
            + Vec3::splat(self.specular * spec * light))
        .min(Vec3::ONE)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn light(d: Vec3) -> SurfaceLight {
        SurfaceLight {
            to_light: d.normalize(),
            ..SurfaceLight::new(Some([0.0, 0.0, 1.0]), &test_cam())
        }
    }

    fn test_cam() -> Camera {
        Camera::fit(
            &crate::camera::CameraParams::default(),
            Vec3::ZERO,
            Vec3::ONE,
            8,
            8,
        )
    }

    #[test]
    fn lambert_ambient_and_two_sided() {
        let l = light(Vec3::Z);
        let a = Vec3::new(0.5, 0.25, 1.0);
        // Seen from straight above, lit from straight above: full diffuse
        // plus the specular peak.
        let c = l.shade(a, Vec3::Z, -Vec3::Z, 1.0);
        let want = (a * (l.ambient + l.diffuse) + Vec3::splat(l.specular)).min(Vec3::ONE);
        assert!((c - want).abs().max_element() < 1e-6, "{c} {want}");
        // The same face with its normal pointing away: two-sided, same.
        assert_eq!(l.shade(a, -Vec3::Z, -Vec3::Z, 1.0), c);
        // Fully shadowed: ambient only, no highlight.
        assert!((l.shade(a, Vec3::Z, -Vec3::Z, 0.0) - a * l.ambient).length() < 1e-6);
        // Half the light: diffuse and specular halve.
        let half = l.shade(a * 0.5, Vec3::Z, -Vec3::Z, 0.5);
        let want = a * 0.5 * (l.ambient + 0.5 * l.diffuse) + Vec3::splat(0.5 * l.specular);
        assert!((half - want).abs().max_element() < 1e-6);
        // Light at 60° from the normal: cos = 0.5 (Lambert).
        let l60 = SurfaceLight {
            specular: 0.0,
            ..light(Vec3::new(3f32.sqrt(), 0.0, 1.0))
        };
        let c = l60.shade(a, Vec3::Z, Vec3::new(-1.0, 0.0, -1.0).normalize(), 1.0);
        let want = a * (l60.ambient + 0.5 * l60.diffuse);
        assert!((c - want).length() < 1e-6, "{c} {want}");
        // A face turned away from the light gets ambient only.
        let c = l.shade(a, Vec3::X, -Vec3::X, 1.0);
        assert!((c - a * l.ambient).length() < 1e-6);
    }

    #[test]
    fn highlight_follows_the_exponent_whole_or_not() {
        let a = Vec3::new(0.2, 0.3, 0.1);
        let dir = Vec3::new(-0.3, 0.1, -1.0).normalize();
        for shininess in [32.0, 7.5, 1.0] {
            let l = SurfaceLight {
                shininess,
                ..light(Vec3::new(0.2, -0.1, 1.0))
            };
            let ndl = Vec3::Z.dot(l.to_light);
            let nh = Vec3::Z.dot((l.to_light - dir).normalize());
            let want =
                a * (l.ambient + l.diffuse * ndl) + Vec3::splat(l.specular * nh.powf(shininess));
            let c = l.shade(a, Vec3::Z, dir, 1.0);
            assert!(
                (c - want).abs().max_element() < 1e-6,
                "{shininess}: {c} {want}"
            );
            assert!(nh.powf(shininess) > 0.05, "the highlight shows");
        }
    }

    #[test]
    fn default_light_comes_from_behind_the_camera_and_above() {
        let cam = test_cam();
        let l = SurfaceLight::new(None, &cam);
        assert!(l.to_light.dot(cam.forward) < -0.5);
        assert!(l.to_light.dot(cam.up) > 0.3);
        assert!((l.to_light.length() - 1.0).abs() < 1e-6);
        // A zero vector falls back to the default too.
        assert_eq!(SurfaceLight::new(Some([0.0; 3]), &cam), l);
    }
}
