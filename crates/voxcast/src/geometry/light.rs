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
        let (ndl, x) = self.cosines(n, dir);
        if ndl <= 0.0 {
            return albedo * self.ambient;
        }
        let spec = match self.whole_power() {
            Some(k) => powi(x, k),
            None => x.powf(self.shininess),
        };
        self.combine(albedo, ndl, spec, light)
    }

    /// [`SurfaceLight::shade`] for a packet of lanes (`n`, `dir`, `albedo`:
    /// x, y and z lane by lane), in loops the compiler turns into vector
    /// instructions: the same colours, bit for bit.
    pub fn shade_packet<const P: usize>(
        &self,
        albedo: &[[f32; P]; 3],
        n: &[[f32; P]; 3],
        dir: &[[f32; P]; 3],
        light: &[f32; P],
    ) -> [[f32; P]; 3] {
        let at = |v: &[[f32; P]; 3], l: usize| Vec3::new(v[0][l], v[1][l], v[2][l]);
        let (mut ndl, mut x) = ([0.0; P], [0.0; P]);
        for l in 0..P {
            (ndl[l], x[l]) = self.cosines(at(n, l), at(dir, l));
        }
        // The specular power, by the same multiplications as `powi`.
        let spec = match self.whole_power() {
            Some(mut k) => {
                let mut r = [1.0f32; P];
                loop {
                    if k & 1 == 1 {
                        for l in 0..P {
                            r[l] *= x[l];
                        }
                    }
                    k >>= 1;
                    if k == 0 {
                        break r;
                    }
                    for v in &mut x {
                        *v *= *v;
                    }
                }
            }
            None => x.map(|x| x.powf(self.shininess)),
        };
        let mut out = [[0.0; P]; 3];
        for l in 0..P {
            let a = at(albedo, l);
            let c = if ndl[l] <= 0.0 {
                a * self.ambient
            } else {
                self.combine(a, ndl[l], spec[l], light[l])
            };
            (out[0][l], out[1][l], out[2][l]) = (c.x, c.y, c.z);
        }
        out
    }

    /// The normal's cosines, turned towards the viewer: to the light (≤ 0:
    /// the light is behind the surface) and to the half vector (≥ 0).
    #[inline(always)]
    fn cosines(&self, n: Vec3, dir: Vec3) -> (f32, f32) {
        let n = if n.dot(dir) > 0.0 { -n } else { n };
        let h = (self.to_light - dir).normalize_or_zero();
        (n.dot(self.to_light), n.dot(h).max(0.0))
    }

    /// A whole exponent (the default 32), taken by multiplications: `powf`
    /// was 6 % of a frame of the office scene, one call per surface pixel.
    #[inline(always)]
    fn whole_power(&self) -> Option<u32> {
        (self.shininess.fract() == 0.0 && (0.0..=64.0).contains(&self.shininess))
            .then_some(self.shininess as u32)
    }

    /// Ambient, diffuse and specular, lit by the fraction `light`.
    #[inline(always)]
    fn combine(&self, albedo: Vec3, ndl: f32, spec: f32, light: f32) -> Vec3 {
        (albedo * (self.ambient + self.diffuse * ndl * light)
            + Vec3::splat(self.specular * spec * light))
        .min(Vec3::ONE)
    }
}

/// `x` to the whole power `k` by squaring, as `f32::powi` computes it
/// (compiler-rt's `__powisf2`), inline and without its call.
#[inline(always)]
fn powi(mut x: f32, mut k: u32) -> f32 {
    let mut r = 1.0;
    loop {
        if k & 1 == 1 {
            r *= x;
        }
        k >>= 1;
        if k == 0 {
            return r;
        }
        x *= x;
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

    /// A packet's colours are [`SurfaceLight::shade`]'s, bit for bit: lit
    /// and unlit sides, seen from either side, whole and fractional
    /// exponents, in and out of shadow.
    #[test]
    fn packet_shading_is_the_scalar_shading() {
        let mut rng = crate::render::rng::Rng::new(0x243f_6a88_85a3_08d3, 0);
        let mut rnd = move || rng.uniform();
        let (mut lit, mut dark) = (0, 0);
        for shininess in [32.0, 7.0, 7.5, 0.0] {
            let l = SurfaceLight {
                shininess,
                ..light(Vec3::new(0.3, -0.2, 1.0))
            };
            for _ in 0..40 {
                let (mut a, mut n, mut d) = ([[0.0; 16]; 3], [[0.0; 16]; 3], [[0.0; 16]; 3]);
                let mut k = [0.0; 16];
                for i in 0..16 {
                    let nv = (Vec3::new(rnd(), rnd(), rnd()) - 0.5).normalize();
                    let dv = (Vec3::new(rnd(), rnd(), rnd()) - 0.5).normalize();
                    for c in 0..3 {
                        (a[c][i], n[c][i], d[c][i]) = (rnd(), nv[c], dv[c]);
                    }
                    k[i] = if i % 3 == 0 { 1.0 } else { rnd() };
                }
                let got = l.shade_packet(&a, &n, &d, &k);
                for i in 0..16 {
                    let at = |v: &[[f32; 16]; 3]| Vec3::new(v[0][i], v[1][i], v[2][i]);
                    let want = l.shade(at(&a), at(&n), at(&d), k[i]);
                    assert_eq!(
                        at(&got).to_array().map(f32::to_bits),
                        want.to_array().map(f32::to_bits)
                    );
                    let (ndl, _) = l.cosines(at(&n), at(&d));
                    (lit, dark) = if ndl > 0.0 {
                        (lit + 1, dark)
                    } else {
                        (lit, dark + 1)
                    };
                }
            }
        }
        assert!(lit > 500 && dark > 500, "{lit} lit, {dark} unlit");
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
