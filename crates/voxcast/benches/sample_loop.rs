//! The per-sample loop — trilinear reconstruction, transfer-function lookup,
//! front-to-back compositing — measured alone, per scalar type, and inside a
//! whole render.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use glam::Vec3;
use std::hint::black_box;
use voxcast::camera::CameraParams;
use voxcast::render::optics::over_front;
use voxcast::render::{render, RenderParams};
use voxcast::transfer::{Lut, TransferFunction};
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

criterion_group!(benches, per_sample, whole_render);
criterion_main!(benches);
