//! The per-sample loop — trilinear reconstruction, transfer-function lookup,
//! front-to-back compositing — measured alone, per scalar type, and inside a
//! whole render; and the **ceiling**: the same camera rays through a dense
//! 256³ volume marched by a bare loop (uniform steps, trilinear, table
//! lookup, front-to-back, nothing else) beside the real renderer doing the
//! same work (`uniform`, no skipping, no early termination, unshaded), both
//! reported in samples per second. `cargo bench -p voxcast --bench
//! sample_loop -- ceiling` prints the two rates; their ratio is how far the
//! renderer is from the scalar ceiling.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use glam::Vec3;
use rayon::prelude::*;
use std::hint::black_box;
use voxcast::camera::{Camera, CameraParams};
use voxcast::render::march::intersect_box;
use voxcast::render::optics::over_front;
use voxcast::render::{render, RenderParams, Renderer};
use voxcast::transfer::{Lut, TransferFunction, LUT_SIZE};
use voxcast::volume::{Grid, GridVisitor, Voxel};
use voxcast::{Volume, VoxelData};

const N: usize = 4096;

/// Marches `N` samples along a diagonal ray through the grid.
struct Loop<'a> {
    lut: &'a Lut,
}

impl GridVisitor for Loop<'_> {
    type Output = f32;
    fn visit<T: Voxel>(self, grid: &Grid<'_, T>) -> f32 {
        let d = grid.dims();
        let dir = Vec3::new(d[0] as f32 - 1.0, d[1] as f32 - 1.0, d[2] as f32 - 1.0) / N as f32;
        let mut c = Vec3::ZERO;
        let mut a = 0.0f32;
        for n in 0..N {
            let p = Vec3::new(0.3, 0.7, 0.1) + dir * n as f32;
            let v = grid.sample(black_box(p));
            if let Some(i) = Lut::index(v) {
                let e = self.lut.entry(i);
                over_front(
                    &mut c,
                    &mut a,
                    Vec3::new(e[0], e[1], e[2]) * e[3],
                    e[3] * 0.01,
                );
            }
        }
        c.x + a
    }
}

fn volume(kind: &str) -> Volume {
    let n = 128;
    let f = |i: usize, j: usize, k: usize| ((i * 7 + j * 13 + k * 29) % 256) as f32;
    let v = Volume::from_fn([n, n, n], Vec3::ONE, f).unwrap();
    let data = match kind {
        "u8" => VoxelData::U8((0..v.len()).map(|i| v.data().get(i) as u8).collect()),
        "u16" => VoxelData::U16((0..v.len()).map(|i| v.data().get(i) as u16).collect()),
        _ => return v,
    };
    Volume::new([n, n, n], Vec3::ONE, Vec3::ZERO, data).unwrap()
}

fn per_sample(c: &mut Criterion) {
    let tf = TransferFunction::preset("viridis").unwrap();
    let lut = Lut::new(&tf, 0.5);
    let mut g = c.benchmark_group("sample_loop");
    g.throughput(Throughput::Elements(N as u64));
    for kind in ["u8", "u16", "f32"] {
        let vol = volume(kind);
        g.bench_with_input(BenchmarkId::from_parameter(kind), &vol, |b, vol| {
            b.iter(|| vol.visit(0.0, 255.0, Loop { lut: &lut }))
        });
    }
    g.finish();
}

fn whole_render(c: &mut Criterion) {
    let vol = voxcast::builtin::open("demo").unwrap();
    let tf = TransferFunction::auto(&vol);
    let mut g = c.benchmark_group("render_demo_128x128");
    g.sample_size(20);
    for shading in [false, true] {
        let p = RenderParams {
            width: 128,
            height: 128,
            shading,
            ..Default::default()
        };
        let name = if shading { "shaded" } else { "unshaded" };
        g.bench_function(name, |b| {
            b.iter(|| {
                render(
                    &vol,
                    &tf,
                    [0.0, 255.0],
                    &CameraParams::default(),
                    &p,
                    &|_, _| {},
                )
                .unwrap()
            })
        });
    }
    g.finish();
}

/// Marschner–Lobb (fM = 6, α = 0.25) on an n³ grid of u8: dense, every
/// sample classified.
fn marschner_lobb_u8(n: usize) -> Volume {
    use std::f32::consts::PI;
    let unit = |i: usize| i as f32 / (n - 1) as f32 * 2.0 - 1.0;
    let mut data = vec![0u8; n * n * n];
    data.par_chunks_mut(n * n)
        .enumerate()
        .for_each(|(k, slab)| {
            for j in 0..n {
                for i in 0..n {
                    let (x, y, z) = (unit(i), unit(j), unit(k));
                    let r = (x * x + y * y).sqrt();
                    let rho = (2.0 * PI * 6.0 * (PI * r / 2.0).cos()).cos();
                    let v = (1.0 - (PI * z / 2.0).sin() + 0.25 * (1.0 + rho)) / 2.5;
                    slab[i + n * j] = (v.clamp(0.0, 1.0) * 255.0).round() as u8;
                }
            }
        });
    Volume::new([n; 3], Vec3::ONE, Vec3::ZERO, VoxelData::U8(data.into())).unwrap()
}

/// The bare ray loop: per pixel, the camera ray clipped to the sample box,
/// samples at `t_in + n·step`, trilinear, table lookup, front to back.
/// Returns the image's summed alpha (so nothing is optimised away) and the
/// number of samples taken.
struct Bare<'a> {
    cam: &'a Camera,
    lut: &'a Lut,
    alphas: &'a [f32; LUT_SIZE],
    vol: &'a Volume,
    step: f32,
    size: u32,
}

impl GridVisitor for Bare<'_> {
    type Output = (f64, u64);
    fn visit<T: Voxel>(self, grid: &Grid<'_, T>) -> (f64, u64) {
        let (lo, hi) = self.vol.sample_box();
        let origin = self.vol.origin();
        let inv_sp = Vec3::ONE / self.vol.spacing();
        (0..self.size)
            .into_par_iter()
            .map(|y| {
                let mut sum = 0.0f64;
                let mut samples = 0u64;
                for x in 0..self.size {
                    let (o, d) = self.cam.ray(x, y);
                    let o = (o - origin) * inv_sp;
                    let d = d * inv_sp;
                    let Some((t_in, t_out)) = intersect_box(o, Vec3::ONE / d, lo, hi) else {
                        continue;
                    };
                    let mut c = Vec3::ZERO;
                    let mut a = 0.0f32;
                    let mut n = 0u32;
                    loop {
                        let t = t_in + n as f32 * self.step;
                        if t >= t_out {
                            break;
                        }
                        n += 1;
                        if let Some(i) = Lut::index(grid.sample(o + d * t)) {
                            let alpha = self.alphas[i];
                            let e = self.lut.entry(i);
                            over_front(&mut c, &mut a, Vec3::new(e[0], e[1], e[2]) * alpha, alpha);
                        }
                    }
                    samples += n as u64;
                    sum += (a + c.x) as f64;
                }
                (sum, samples)
            })
            .reduce(|| (0.0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
    }
}

/// The ceiling and the renderer on the same rays: 256³ u8 Marschner–Lobb,
/// 512², step 0.5 voxel, azimuth 30 / elevation 20.
fn ceiling(c: &mut Criterion) {
    let size = 512;
    let vol = marschner_lobb_u8(256);
    let tf = TransferFunction::preset("viridis").unwrap();
    let window = [0.0, 255.0];
    let camera = CameraParams {
        azimuth: 30.0,
        elevation: 20.0,
        ..Default::default()
    };
    let params = RenderParams {
        width: size,
        height: size,
        step: 0.5,
        ert: 1.0,
        skip_empty: false,
        shading: false,
        ..Default::default()
    };
    let renderer = Renderer::new(&vol, window).unwrap();
    let (_, stats) = renderer.render(&tf, &camera, &params, &|_, _| {}).unwrap();
    let (lo, hi) = vol.world_bounds();
    let cam = Camera::fit(&camera, lo, hi, size, size);
    let lut = Lut::new(&tf, params.step);
    let alphas = lut.alphas(params.step);
    let bare = || {
        vol.visit(
            window[0],
            window[1],
            Bare {
                cam: &cam,
                lut: &lut,
                alphas: &alphas,
                vol: &vol,
                step: params.step,
                size,
            },
        )
    };
    let (_, bare_samples) = bare();
    let mut g = c.benchmark_group("ceiling_ml256_u8_512");
    g.sample_size(10);
    g.throughput(Throughput::Elements(bare_samples));
    g.bench_function("bare_loop", |b| b.iter(|| black_box(bare())));
    g.throughput(Throughput::Elements(stats.samples));
    // The renderer's own choice (SIMD packets where the CPU has AVX2),
    // and its scalar loop.
    g.bench_function("renderer_uniform", |b| {
        b.iter(|| renderer.render(&tf, &camera, &params, &|_, _| {}).unwrap())
    });
    let scalar = RenderParams {
        simd: voxcast::render::Simd::Scalar,
        ..params.clone()
    };
    g.bench_function("renderer_uniform_scalar", |b| {
        b.iter(|| renderer.render(&tf, &camera, &scalar, &|_, _| {}).unwrap())
    });
    g.finish();
}

criterion_group!(benches, per_sample, whole_render, ceiling);
criterion_main!(benches);
