//! Built-in volumes, generated on the fly: the demo scene rendered when no
//! file is given, and classic test signals. Named `builtin:NAME` wherever a
//! file path is accepted.

use crate::error::{Error, Result};
use crate::volume::{Volume, VoxelData};
use glam::Vec3;

/// Prefix of built-in volume names: `builtin:demo`.
pub const PREFIX: &str = "builtin:";

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
    (
        "plume",
        "128×128×160 f32: a synthetic smoke plume, rising and spreading, with turbulent detail",
    ),
];

/// Generates the built-in volume `name`.
pub fn open(name: &str) -> Result<Volume> {
    let mut v = match name {
        "demo" => demo(128)?,
        "marschner-lobb" => marschner_lobb(41)?,
        "sphere" => sphere(64)?,
        "plume" => plume([128, 128, 160])?,
        _ => {
            let names: Vec<&str> = BUILTINS.iter().map(|b| b.0).collect();
            return Err(Error::invalid(format!(
                "{PREFIX}{name}: no such built-in volume (known: {})",
                names.join(", ")
            )));
        }
    };
    v.name = Some(format!("{PREFIX}{name}"));
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
    Volume::new([n, n, n], Vec3::ONE, Vec3::ZERO, VoxelData::U8(data.into()))
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

/// Hash of an integer lattice point to [0, 1).
fn lattice(x: i32, y: i32, z: i32) -> f32 {
    let mut h = (x as u32).wrapping_mul(0x8da6_b343)
        ^ (y as u32).wrapping_mul(0xd816_3841)
        ^ (z as u32).wrapping_mul(0xcb1a_b31f);
    h = (h ^ (h >> 13)).wrapping_mul(0x5bd1_e995);
    h ^= h >> 15;
    (h & 0x00ff_ffff) as f32 / (1u32 << 24) as f32
}

/// Smooth value noise in [0, 1).
fn value_noise(p: Vec3) -> f32 {
    let f = p.floor();
    let t = p - f;
    let t = t * t * (Vec3::splat(3.0) - 2.0 * t);
    let (x, y, z) = (f.x as i32, f.y as i32, f.z as i32);
    let l = |dx, dy, dz| lattice(x + dx, y + dy, z + dz);
    let lerp = |a: f32, b: f32, u: f32| a + (b - a) * u;
    let x00 = lerp(l(0, 0, 0), l(1, 0, 0), t.x);
    let x10 = lerp(l(0, 1, 0), l(1, 1, 0), t.x);
    let x01 = lerp(l(0, 0, 1), l(1, 0, 1), t.x);
    let x11 = lerp(l(0, 1, 1), l(1, 1, 1), t.x);
    lerp(lerp(x00, x10, t.y), lerp(x01, x11, t.y), t.z)
}

/// Fractal sum of four octaves of value noise, in [0, 1).
fn fbm(p: Vec3) -> f32 {
    let (mut sum, mut amp, mut freq, mut norm) = (0.0, 0.5, 1.0, 0.0);
    for _ in 0..4 {
        sum += amp * value_noise(p * freq);
        norm += amp;
        amp *= 0.5;
        freq *= 2.03;
    }
    sum / norm
}

/// A smoke plume rising along +z from a source near the floor: a column
/// that widens with height, sways, and is broken up by turbulence; the top
/// mushrooms out under an invisible ceiling.
fn plume(dims: [usize; 3]) -> Result<Volume> {
    use rayon::prelude::*;
    let [nx, ny, nz] = dims;
    let data: Vec<f32> = (0..nx * ny * nz)
        .into_par_iter()
        .map(|idx| {
            let (i, j, k) = (idx % nx, idx / nx % ny, idx / (nx * ny));
            // Unit coordinates: x, y in [−1, 1], h in [0, 1] up the column.
            let x = unit(nx, i);
            let y = unit(ny, j);
            let h = k as f32 / (nz - 1) as f32;
            // Domain warp: large eddies push the smoke around.
            let q = Vec3::new(x * 2.0, y * 2.0, h * 3.0);
            let wx = fbm(q + Vec3::new(5.2, 1.3, 0.0)) - 0.5;
            let wy = fbm(q + Vec3::new(1.7, 9.2, 3.1)) - 0.5;
            let sway = 0.15 * (h * 5.0).sin() * h;
            let radius = 0.1 + 0.45 * h.powf(1.2);
            let (xw, yw) = (x - sway + 0.5 * h * wx, y + 0.5 * h * wy);
            let r = (xw * xw + yw * yw).sqrt();
            let turb = fbm(Vec3::new(xw * 5.0, yw * 5.0, h * 8.0));
            let column = (-(r / radius).powi(2) * 2.0).exp();
            // The cap: smoke pooled under the top, spreading sideways.
            let cap = smoothstep(0.72, 0.9, h) * (-(r / 0.85).powi(4)).exp();
            // Below a trace the air is clean: smoke fields are sparse.
            let d = (column.max(cap) * (1.8 * turb - 0.35) - 0.02).max(0.0);
            d * smoothstep(0.0, 0.05, h) * (1.0 - smoothstep(0.96, 1.0, h))
        })
        .collect();
    Volume::new(dims, Vec3::ONE, Vec3::ZERO, VoxelData::F32(data.into()))
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
