//! Built-in volumes, generated on the fly: the demo scene rendered when no
//! file is given, and classic test signals. Named `builtin:NAME` wherever a
//! file path is accepted.

use crate::error::{Error, Result};
use crate::volume::{Volume, VoxelData};
use glam::Vec3;

/// The built-in volumes: name and description.
pub const BUILTINS: &[(&str, &str)] = &[
    (
        "demo",
        "128³ u8: a lattice-cut spherical shell around a glowing core, ringed by a torus",
    ),
    (
        "marschner-lobb",
        "41³ f32: the Marschner–Lobb test signal (fM = 6, α = 0.25)",
    ),
    ("sphere", "64³ u8: a soft ball, densest at the centre"),
];

/// Generates the built-in volume `name`.
pub fn open(name: &str) -> Result<Volume> {
    let mut v = match name {
        "demo" => demo(128)?,
        "marschner-lobb" => marschner_lobb(41)?,
        "sphere" => sphere(64)?,
        _ => {
            let names: Vec<&str> = BUILTINS.iter().map(|b| b.0).collect();
            return Err(Error::invalid(format!(
                "builtin:{name}: no such built-in volume (known: {})",
                names.join(", ")
            )));
        }
    };
    v.name = Some(format!("builtin:{name}"));
    Ok(v)
}

fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Maps voxel (i, j, k) of an n³ grid to [−1, 1]³.
fn unit(n: usize, i: usize) -> f32 {
    i as f32 / (n - 1) as f32 * 2.0 - 1.0
}

fn to_u8(n: usize, f: impl Fn(Vec3) -> f32 + Sync) -> Result<Volume> {
    use rayon::prelude::*;
    let data: Vec<u8> = (0..n * n * n)
        .into_par_iter()
        .map(|idx| {
            let (i, j, k) = (idx % n, idx / n % n, idx / (n * n));
            let p = Vec3::new(unit(n, i), unit(n, j), unit(n, k));
            (f(p).clamp(0.0, 1.0) * 255.0 + 0.5) as u8
        })
        .collect();
    Volume::new([n, n, n], Vec3::ONE, Vec3::ZERO, VoxelData::U8(data))
}

fn demo(n: usize) -> Result<Volume> {
    to_u8(n, |p| {
        let r = p.length();
        // Core: a soft glowing ball.
        let core = 1.0 - smoothstep(0.0, 0.32, r);
        // Shell of radius 0.62 cut by a gyroid lattice into a cage.
        let shell = 1.0 - smoothstep(0.02, 0.06, (r - 0.62).abs());
        let q = p * 9.0;
        let gyroid = q.x.sin() * q.y.cos() + q.y.sin() * q.z.cos() + q.z.sin() * q.x.cos();
        let cage = shell * smoothstep(-0.1, 0.25, gyroid);
        // Torus tilted 25° about x, major radius 0.8, minor 0.09.
        let (s, c) = 25f32.to_radians().sin_cos();
        let t = Vec3::new(p.x, c * p.y - s * p.z, s * p.y + c * p.z);
        let ring_d = ((t.x * t.x + t.y * t.y).sqrt() - 0.8).hypot(t.z);
        let ring = 1.0 - smoothstep(0.06, 0.1, ring_d);
        (0.45 * ring).max(0.7 * cage).max(core)
    })
}

fn sphere(n: usize) -> Result<Volume> {
    to_u8(n, |p| 1.0 - smoothstep(0.0, 0.8, p.length()))
}

fn marschner_lobb(n: usize) -> Result<Volume> {
    const FM: f32 = 6.0;
    const ALPHA: f32 = 0.25;
    use std::f32::consts::PI;
    Volume::from_fn([n, n, n], Vec3::ONE, |i, j, k| {
        let (x, y, z) = (unit(n, i), unit(n, j), unit(n, k));
        let r = (x * x + y * y).sqrt();
        let rho_r = (2.0 * PI * FM * (PI * r / 2.0).cos()).cos();
        (1.0 - (PI * z / 2.0).sin() + ALPHA * (1.0 + rho_r)) / (2.0 * (1.0 + ALPHA))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtins_generate() {
        for (name, _) in BUILTINS {
            let v = open(name).unwrap();
            assert!(v.stats().max > v.stats().min, "{name}");
        }
        assert!(open("nope").is_err());
        let ml = open("marschner-lobb").unwrap();
        assert!(ml.stats().min >= 0.0 && ml.stats().max <= 1.0);
    }
}
