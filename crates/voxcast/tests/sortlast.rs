//! Sort-last rendering (`render::sortlast`): the decomposition, the
//! compositing rounds, and over threads the one-process picture.

mod common;
use common::max_diff;

use glam::Vec3;
use std::sync::atomic::AtomicBool;
use voxcast::camera::{CameraParams, Projection};
use voxcast::metrics::psnr;
use voxcast::render::outofcore::{OutOfCore, OutOfCoreParams};
use voxcast::render::sortlast::*;
use voxcast::render::{Method, Order, RenderParams};
use voxcast::transfer::TransferFunction;
use voxcast::volume::{MemorySource, Volume, VoxelData};

#[test]
fn rounds_are_the_prime_factors_smallest_first() {
    assert_eq!(rounds(1), Vec::<usize>::new());
    assert_eq!(rounds(2), vec![2]);
    assert_eq!(rounds(3), vec![3]);
    assert_eq!(rounds(4), vec![2, 2]);
    assert_eq!(rounds(6), vec![2, 3]);
    assert_eq!(rounds(9), vec![3, 3]);
    assert_eq!(rounds(12), vec![2, 2, 3]);
    assert_eq!(rounds(7), vec![7]);
    assert_eq!(rounds(50), vec![2, 5, 5]);
}

/// Every chunk belongs to exactly one part.
fn assert_tiles(d: &Decomposition, counts: [u64; 3]) {
    let mut owner = vec![usize::MAX; counts.iter().product::<u64>() as usize];
    for r in 0..d.leaves.len() {
        let (lo, hi) = d.part(r);
        for z in lo[2]..hi[2] {
            for y in lo[1]..hi[1] {
                for x in lo[0]..hi[0] {
                    let i = (x + counts[0] * (y + counts[1] * z)) as usize;
                    assert_eq!(owner[i], usize::MAX, "chunk {x},{y},{z} in two parts");
                    owner[i] = r;
                }
            }
        }
    }
    assert!(owner.iter().all(|&o| o != usize::MAX), "a chunk in no part");
}

#[test]
fn parts_tile_the_chunks_and_balance_their_weight() {
    let counts = [8, 6, 5];
    for n in 1..=12 {
        let d = Decomposition::new(counts, n, &|_| 1);
        assert_tiles(&d, counts);
        assert_eq!(d.weights.iter().sum::<u64>(), 240, "{n} parts");
        let (min, max) = (
            *d.weights.iter().min().unwrap(),
            *d.weights.iter().max().unwrap(),
        );
        // A round of k cuts one axis into k: a prime k above the longest
        // axis's 8 chunks (11) leaves some parts empty.
        if n <= 8 || n == 12 {
            assert!(min > 0, "{n} parts: an empty part {:?}", d.weights);
            // Whole slices are cut, so a part may be off by about one
            // slice per cut.
            assert!(max <= 2 * min + 30, "{n} parts: {:?}", d.weights);
        }
    }
    // Only the chunks with z < 2 may show: both parts get half of them,
    // not half of the box.
    let d = Decomposition::new([8, 8, 8], 2, &|c| u64::from(c[2] < 2));
    assert_tiles(&d, [8, 8, 8]);
    assert_eq!(d.weights, vec![64, 64]);
    // Fewer chunks than processes: some parts are empty, none overlap.
    let d = Decomposition::new([2, 1, 1], 4, &|_| 1);
    assert_tiles(&d, [2, 1, 1]);
    assert_eq!(d.weights.iter().sum::<u64>(), 2);
}

#[test]
fn children_are_ordered_nearest_first_from_either_side_of_every_cut() {
    let d = Decomposition::new([6, 1, 1], 3, &|_| 1);
    let root = &d.nodes[0];
    assert_eq!((root.axis, root.cuts.clone()), (0, vec![0, 2, 4, 6]));
    let eye = |x: f32| View::Eye(Vec3::new(x, 0.5, 0.5));
    assert_eq!(d.order(0, &eye(-1.0)), vec![0, 1, 2]);
    assert_eq!(d.order(0, &eye(7.0)), vec![2, 1, 0]);
    assert_eq!(d.order(0, &eye(3.0))[0], 1);
    assert_eq!(d.order(0, &eye(5.0)), vec![2, 1, 0]);
    assert_eq!(d.order(0, &eye(1.0)), vec![0, 1, 2]);
    let dir = |x: f32| View::Direction(Vec3::new(x, 0.2, 0.1));
    assert_eq!(d.order(0, &dir(1.0)), vec![0, 1, 2]);
    assert_eq!(d.order(0, &dir(-1.0)), vec![2, 1, 0]);
}

#[test]
fn radix_k_over_threads_composites_layers_in_order() {
    // Process p's layer is a flat colour of opacity 0.5 in every pixel;
    // the view looks down +x, so process order along x decides.
    for n in [2, 3, 4, 6, 8] {
        let d = Decomposition::new([n as u64, 1, 1], n, &|_| 1);
        let view = View::Direction(Vec3::X);
        let pixels = 37;
        let out = run_threads(n, |ex| {
            let r = ex.rank();
            let (lo, _) = d.part(r);
            let c = lo[0] as f32 / n as f32;
            composite(ex, &d, &view, vec![[0.5 * c, 0.0, 0.0, 0.5]; pixels]).unwrap()
        });
        let img = out[0].0.clone().expect("process 0 holds the image");
        assert!(out[1..].iter().all(|o| o.0.is_none()));
        // Front to back: sum over x-slices of 0.5 · (x/n) · 0.5^x.
        let want: f32 = (0..n)
            .map(|x| 0.5 * (x as f32 / n as f32) * 0.5f32.powi(x as i32))
            .sum();
        for p in &img {
            assert!((p[0] - want).abs() < 1e-6, "{n}: {} against {want}", p[0]);
            assert!((p[3] - (1.0 - 0.5f32.powi(n as i32))).abs() < 1e-6);
        }
        // Every process sends at most its image once over (1 − 1/k per
        // round, then its final piece), far less than all-to-one.
        for (r, o) in out.iter().enumerate() {
            assert!(
                o.1.bytes_sent <= 16 * pixels as u64 * 2,
                "{n}: {r} sent {}",
                o.1.bytes_sent
            );
        }
    }
}

fn run_threads<T: Send>(n: usize, f: impl Fn(&ThreadExchange) -> T + Sync) -> Vec<T> {
    let group = ThreadExchange::group(n);
    std::thread::scope(|s| {
        let handles: Vec<_> = group
            .into_iter()
            .map(|ex| {
                let f = &f;
                s.spawn(move || f(&ex))
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    })
}

/// A sphere of soft values with a hard-edged slab through its middle
/// (across the cuts): a seam in the reconstruction would show on it.
fn sharp_volume() -> Volume {
    let (nx, ny, nz) = (45usize, 38usize, 33usize);
    let mut v = vec![0u8; nx * ny * nz];
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let p = Vec3::new(x as f32 / 44.0, y as f32 / 37.0, z as f32 / 32.0) - 0.5;
                let mut val = (200.0 * (1.0 - 2.2 * p.length())).max(0.0);
                if (x / 3 + y / 5) % 3 == 0 && (10..30).contains(&z) {
                    val = 250.0;
                }
                v[x + nx * (y + ny * z)] = val as u8;
            }
        }
    }
    Volume::new(
        [nx, ny, nz],
        Vec3::new(1.0, 1.1, 0.9),
        Vec3::ZERO,
        VoxelData::U8(v.into()),
    )
    .unwrap()
}

#[test]
fn sort_last_over_threads_gives_the_one_process_picture() {
    let vol = sharp_volume();
    let tf = TransferFunction::auto(&vol);
    let window = tf.window_for(&vol, None);
    let src = MemorySource::new(vol, 0, [8, 7, 9]).unwrap().with_ranges();
    let ooc = OutOfCore::new(
        &src,
        OutOfCoreParams {
            budget: 64 << 20,
            level: Some(0),
            ..Default::default()
        },
    );
    let never = AtomicBool::new(false);
    // Cameras on either side of every cut plane, from inside the volume
    // too, and orthographic.
    let views = [
        (30.0, 20.0, 1.0, Projection::Perspective),
        (210.0, -35.0, 1.0, Projection::Perspective),
        (120.0, 60.0, 1.0, Projection::Orthographic),
        (300.0, -70.0, 1.0, Projection::Orthographic),
        (75.0, 10.0, 6.0, Projection::Perspective),
    ];
    for (i, &(az, el, zoom, projection)) in views.iter().enumerate() {
        let cam = CameraParams {
            azimuth: az,
            elevation: el,
            zoom,
            projection,
            ..Default::default()
        };
        let params = RenderParams {
            width: 40,
            height: 36,
            shading: i % 2 == 1,
            jitter: i == 2,
            ert: 1.0,
            ..Default::default()
        };
        let (one, ..) = ooc
            .render(&tf, window, &cam, &params, &|_, _| {}, &never)
            .unwrap();
        for n in [1, 2, 3, 4, 6] {
            let out = run_threads(n, |ex| {
                render(
                    ex,
                    &ooc,
                    &tf,
                    window,
                    &cam,
                    &params,
                    false,
                    &|_, _| {},
                    &never,
                )
                .unwrap()
            });
            let img = out[0].image.as_ref().expect("process 0 has the image");
            let worst = max_diff(img, &one);
            let db = psnr(img, &one).unwrap();
            assert!(
                worst < 2e-4 && db >= 60.0,
                "view {i}, {n} processes: worst {worst}, {db:.1} dB"
            );
            // The parts' samples add up to the one render's.
            let samples: u64 = out.iter().map(|o| o.stats.samples).sum();
            let (_, one_stats, _) = ooc
                .render_part(&tf, window, &cam, &params, None, &|_, _| {}, &never)
                .unwrap();
            let diff = samples.abs_diff(one_stats.samples);
            assert!(
                diff * 1000 <= one_stats.samples,
                "view {i}, {n}: {samples} samples against {}",
                one_stats.samples
            );
        }
    }
}

#[test]
fn methods_that_need_the_whole_ray_are_refused_by_name() {
    for (method, grouped, order, word) in [
        (Method::Adaptive, false, Order::FrontToBack, "adaptive"),
        (Method::Uniform, true, Order::FrontToBack, "grouped"),
        (Method::Uniform, false, Order::BackToFront, "back-to-front"),
    ] {
        let p = RenderParams {
            method,
            grouped,
            order,
            ..Default::default()
        };
        let e = check_params(&p).unwrap_err().to_string();
        assert!(e.contains(word) && e.contains("MPI"), "{e}");
    }
    assert!(check_params(&RenderParams::default()).is_ok());
}
