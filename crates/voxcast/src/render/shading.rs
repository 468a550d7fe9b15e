//! Gradient Blinn–Phong shading with a headlight (S1: Phong for
//! surface-like features). The normal is the normalised gradient of the
//! field in world units; lighting is two-sided, so surfaces seen from inside
//! are lit too.

use glam::Vec3;

/// Ambient, diffuse and specular weights and the specular exponent.
#[derive(Clone, Copy, Debug)]
pub struct BlinnPhong {
    pub ambient: f32,
    pub diffuse: f32,
    pub specular: f32,
    pub shininess: f32,
    /// Gradient magnitude (normalised value per voxel) below which a sample
    /// is treated as flat and left unshaded: its normal is noise.
    pub min_gradient: f32,
}

impl Default for BlinnPhong {
    fn default() -> Self {
        BlinnPhong {
            ambient: 0.25,
            diffuse: 0.75,
            specular: 0.25,
            shininess: 24.0,
            min_gradient: 1e-3,
        }
    }
}

impl BlinnPhong {
    /// Shades `rgb` for gradient `g` (per voxel, in voxel axes; `inv_spacing`
    /// converts it to world units) seen along `view_dir` (from the eye), lit
    /// by a light at the eye.
    #[inline(always)]
    pub fn shade(&self, rgb: Vec3, g: Vec3, inv_spacing: Vec3, view_dir: Vec3) -> Vec3 {
        if g.length_squared() < self.min_gradient * self.min_gradient {
            return rgb;
        }
        let n = (g * inv_spacing).normalize();
        // Headlight: light, view and half vectors coincide.
        let ndl = n.dot(view_dir).abs();
        let spec = ndl.powf(self.shininess);
        // Clamped so a sample never emits more than a white one: keeps the
        // early-termination error bound `1 − threshold`.
        (rgb * (self.ambient + self.diffuse * ndl) + Vec3::splat(self.specular * spec))
            .min(Vec3::ONE)
    }
}
