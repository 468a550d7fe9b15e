//! Built-in volumes, generated on the fly: the demo scene rendered when no
//! file is given, and classic test signals. Named `builtin:NAME` wherever a
//! file path is accepted.

use crate::error::{Error, Result};
use crate::volume::{ScalarType, Volume, VoxelData};
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
    (
        "fractal",
        "256³ u8: a Menger sponge, holes at every scale down to the voxel, brighter towards the centre (any size with `convert --dims`)",
    ),
];

/// The built-in volumes that are a function of position and so can be
/// generated at any size and type, slab by slab (`convert builtin:NAME
/// --dims X,Y,Z --type T`).
pub const SIZED: &[&str] = &["demo", "sphere", "marschner-lobb", "fractal"];

/// Generates the built-in volume `name`.
pub fn open(name: &str) -> Result<Volume> {
    let mut v = match name {
        "demo" => demo(128)?,
        "marschner-lobb" => marschner_lobb(41)?,
        "sphere" => sphere(64)?,
        "plume" => plume([128, 128, 160])?,
        "fractal" => sized("fractal", [256; 3], ScalarType::U8)?,
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

/// Built-in `name` (one of [`SIZED`]) at `dims` voxels of `ty`, spanning
/// the same shape whatever the size (values 0…1 scaled to the type's range:
/// 255, 65535, 32767, or 1 for f32).
pub fn sized(name: &str, dims: [usize; 3], ty: ScalarType) -> Result<Volume> {
    let d = dims.map(|v| v as u64);
    crate::volume::checked_voxel_count(d).map_err(Error::invalid)?;
    let data = slab(name, d, ty, 0, d[2])?;
    let mut v = Volume::new(dims, Vec3::ONE, Vec3::ZERO, data)?;
    v.name = Some(format!("{PREFIX}{name}"));
    Ok(v)
}

/// Slices `z0..z1` of built-in `name` (one of [`SIZED`]) at `dims` voxels
/// of `ty`, x fastest: for writing volumes larger than memory.
pub fn slab(name: &str, dims: [u64; 3], ty: ScalarType, z0: u64, z1: u64) -> Result<VoxelData> {
    use rayon::prelude::*;
    let f: fn([u64; 3], [u64; 3]) -> f32 = match name {
        "demo" => |d, i| demo_at(unit3(d, i)),
        "sphere" => |d, i| sphere_at(unit3(d, i)),
        "marschner-lobb" => |d, i| marschner_lobb_at(unit3(d, i)),
        "fractal" => fractal_at,
        _ => {
            return Err(Error::invalid(format!(
                "{PREFIX}{name}: not generated at other sizes (these are: {})",
                SIZED.join(", ")
            )))
        }
    };
    if dims.contains(&0) || z0 > z1 || z1 > dims[2] {
        return Err(Error::invalid(format!(
            "{PREFIX}{name}: slices {z0}…{z1} of {}×{}×{}",
            dims[0], dims[1], dims[2]
        )));
    }
    let area = (dims[0] * dims[1]) as usize;
    let n = area * (z1 - z0) as usize;
    let at = move |idx: usize| {
        let i = [
            (idx % dims[0] as usize) as u64,
            (idx / dims[0] as usize % dims[1] as usize) as u64,
            z0 + (idx / area) as u64,
        ];
        f(dims, i).clamp(0.0, 1.0)
    };
    macro_rules! go {
        ($var:ident, $scale:expr) => {
            VoxelData::$var(
                (0..n)
                    .into_par_iter()
                    .map(|i| (at(i) * $scale + 0.5) as _)
                    .collect::<Vec<_>>()
                    .into(),
            )
        };
    }
    Ok(match ty {
        ScalarType::U8 => go!(U8, 255.0),
        ScalarType::U16 => go!(U16, 65535.0),
        ScalarType::I16 => go!(I16, 32767.0),
        ScalarType::F32 => {
            VoxelData::F32((0..n).into_par_iter().map(at).collect::<Vec<_>>().into())
        }
    })
}

/// Voxel `i` of a grid of `d` in [−1, 1]³ (an axis of one voxel at 0).
fn unit3(d: [u64; 3], i: [u64; 3]) -> Vec3 {
    let u = |a: usize| {
        if d[a] > 1 {
            i[a] as f32 / (d[a] - 1) as f32 * 2.0 - 1.0
        } else {
            0.0
        }
    };
    Vec3::new(u(0), u(1), u(2))
}

/// A Menger sponge: at each level (down to the voxel) the cube is cut in
/// 3×3×3 and the centre and face-centre cells removed; what stays is
/// brighter towards the centre. Integer arithmetic on the voxel index.
fn fractal_at(d: [u64; 3], i: [u64; 3]) -> f32 {
    let n = d.iter().copied().max().unwrap_or(1);
    // Levels until a cell is smaller than a voxel.
    let mut levels = 0;
    let mut p = 1u64;
    while p < n && levels < 12 {
        p *= 3;
        levels += 1;
    }
    let mut scale = 1u64;
    for _ in 0..levels {
        scale *= 3;
        let ones = (0..3)
            .filter(|&a| (i[a] * scale / d[a].max(1)) % 3 == 1)
            .count();
        if ones >= 2 {
            return 0.0;
        }
    }
    let c = unit3(d, i);
    0.3 + 0.7 * (1.0 - c.length() / 3f32.sqrt())
}

fn demo_at(p: Vec3) -> f32 {
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
}

fn sphere_at(p: Vec3) -> f32 {
    1.0 - smoothstep(0.0, 0.8, p.length())
}

fn marschner_lobb_at(p: Vec3) -> f32 {
    const FM: f32 = 6.0;
    const ALPHA: f32 = 0.25;
    use std::f32::consts::PI;
    let r = (p.x * p.x + p.y * p.y).sqrt();
    let rho_r = (2.0 * PI * FM * (PI * r / 2.0).cos()).cos();
    (1.0 - (PI * p.z / 2.0).sin() + ALPHA * (1.0 + rho_r)) / (2.0 * (1.0 + ALPHA))
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
    to_u8(n, demo_at)
}

fn sphere(n: usize) -> Result<Volume> {
    to_u8(n, sphere_at)
}

fn marschner_lobb(n: usize) -> Result<Volume> {
    Volume::from_fn([n, n, n], Vec3::ONE, |i, j, k| {
        marschner_lobb_at(Vec3::new(unit(n, i), unit(n, j), unit(n, k)))
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

    #[test]
    fn sized_builtins_match_the_fixed_ones_and_slabs_tile_the_volume() {
        // The same function at the same size and type: the same voxels.
        let demo = sized("demo", [128; 3], ScalarType::U8).unwrap();
        assert_eq!(demo.data(), open("demo").unwrap().data());
        // Slabs concatenate to the whole volume.
        let d = [27u64, 20, 13];
        let whole = slab("fractal", d, ScalarType::U16, 0, 13).unwrap();
        let mut parts = Vec::new();
        for (a, b) in [(0, 5), (5, 6), (6, 13)] {
            let s = slab("fractal", d, ScalarType::U16, a, b).unwrap();
            parts.extend((0..s.len()).map(|i| s.get(i)));
        }
        assert_eq!(
            parts,
            (0..whole.len()).map(|i| whole.get(i)).collect::<Vec<_>>()
        );
        // The sponge: the centre cell of a 27³ cube is a hole, a corner solid.
        let f = sized("fractal", [27; 3], ScalarType::F32).unwrap();
        assert_eq!(f.value(13, 13, 13), 0.0);
        assert!(f.value(0, 0, 0) > 0.2);
        // 20 of 27 cells stay at each of the 3 levels.
        let solid = (0..f.data().len())
            .filter(|&i| f.data().get(i) > 0.0)
            .count();
        assert_eq!(solid, 20 * 20 * 20);
        assert!(slab("plume", d, ScalarType::U8, 0, 1).is_err());
    }
}
