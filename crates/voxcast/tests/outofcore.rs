//! Out-of-core rendering (`render::outofcore`): bricks in visibility order,
//! the budget, the levels, the packets against the scalar loop.

mod common;
use common::max_diff;

use glam::Vec3;
use std::sync::atomic::AtomicBool;
use voxcast::camera::{Camera, CameraParams, Projection};
use voxcast::metrics::psnr;
use voxcast::render::outofcore::*;
use voxcast::render::{Method, RenderParams, Simd};
use voxcast::transfer::TransferFunction;
use voxcast::volume::{ChunkedSource, Level, MemorySource, Volume, VoxelData};
use voxcast::Image;

fn params(size: u32, shading: bool) -> RenderParams {
    RenderParams {
        width: size,
        height: size,
        shading,
        ..Default::default()
    }
}

fn camera(zoom: f32, projection: Projection) -> CameraParams {
    CameraParams {
        azimuth: 30.0,
        elevation: 20.0,
        zoom,
        projection,
        ..Default::default()
    }
}

fn in_core(vol: &Volume, tf: &TransferFunction, cam: &CameraParams, p: &RenderParams) -> Image {
    let window = tf.window_for(vol, None);
    voxcast::render::render(vol, tf, window, cam, p, &|_, _| {})
        .unwrap()
        .0
}

fn out_of_core(
    src: &MemorySource,
    tf: &TransferFunction,
    cam: &CameraParams,
    p: &RenderParams,
    ooc: &OutOfCoreParams,
) -> (Image, OutOfCoreStats) {
    let window = tf.window_for(src.volume(0), None);
    out_of_core_in(src, window, tf, cam, p, ooc)
}

/// [`out_of_core`] of any chunked source, over the data window `window`.
fn out_of_core_in(
    src: &dyn ChunkedSource,
    window: [f32; 2],
    tf: &TransferFunction,
    cam: &CameraParams,
    p: &RenderParams,
    ooc: &OutOfCoreParams,
) -> (Image, OutOfCoreStats) {
    let (img, _, st) = render_chunked(
        src,
        tf,
        window,
        cam,
        p,
        ooc,
        &|_, _| {},
        &AtomicBool::new(false),
    )
    .unwrap();
    (img, st)
}

fn level0(budget: u64) -> OutOfCoreParams {
    OutOfCoreParams {
        budget,
        level: Some(0),
        lod_scale: 1.0,
        prefetch: true,
        resident_only: false,
    }
}

#[test]
fn bricks_in_visibility_order_give_the_in_core_picture() {
    let vol = voxcast::builtin::open("demo").unwrap();
    let tf = TransferFunction::auto(&vol);
    // Chunks of uneven shape, so brick faces fall everywhere.
    let src = MemorySource::new(vol.clone(), 0, [20, 16, 24]).unwrap();
    for (shading, projection) in [
        (false, Projection::Perspective),
        (true, Projection::Perspective),
        (false, Projection::Orthographic),
    ] {
        for az in [30.0, 210.0] {
            let mut cam = camera(1.0, projection);
            cam.azimuth = az;
            cam.elevation = if az > 100.0 { -35.0 } else { 20.0 };
            let p = params(96, shading);
            let a = in_core(&vol, &tf, &cam, &p);
            let (b, st) = out_of_core(&src, &tf, &cam, &p, &level0(64 << 20));
            let db = psnr(&a, &b).unwrap();
            assert!(
                db >= 60.0,
                "shading {shading} {projection:?} az {az}: {db:.1} dB"
            );
            assert!(st.marched > 0 && st.marched < st.bricks, "{st:?}");
        }
    }
}

#[test]
fn a_budget_of_a_few_chunks_evicts_and_gives_the_same_image() {
    let vol = voxcast::builtin::open("demo").unwrap();
    let tf = TransferFunction::auto(&vol);
    let src = MemorySource::new(vol, 0, [16, 16, 16]).unwrap();
    let cam = camera(1.0, Projection::Perspective);
    let p = params(64, false);
    let (big, s_big) = out_of_core(&src, &tf, &cam, &p, &level0(256 << 20));
    // One 17³ brick and 8 chunks of 4 KiB, and little more.
    let tiny = 17 * 17 * 17 + 10 * 4096;
    let (small, s_small) = out_of_core(&src, &tf, &cam, &p, &level0(tiny));
    assert_eq!(big.pixels, small.pixels);
    // The big cache reads each chunk once; the tiny one reads some again.
    assert!(
        s_small.cache.misses > s_big.cache.misses,
        "{s_small:?} {s_big:?}"
    );
    assert!(s_small.cache.peak_bytes <= tiny, "{s_small:?}");
    let e = render_chunked(
        &src,
        &tf,
        [0.0, 255.0],
        &cam,
        &p,
        &level0(4096),
        &|_, _| {},
        &AtomicBool::new(false),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("--memory-budget") && e.contains("below one brick"),
        "{e}"
    );
}

#[test]
fn the_level_follows_the_size_of_a_pixel() {
    // 256³ voxels of spacing 1 and four levels; a 128² image of the whole
    // volume has pixels of about 3 voxels: level 1 (2 voxels) fits, level 2
    // (4) does not.
    let levels: Vec<Level> = (0..4)
        .map(|l| Level {
            dims: [256 >> l; 3],
            spacing: Vec3::splat((1 << l) as f32),
            origin: Vec3::splat(((1 << l) as f32 - 1.0) * 0.5),
            chunk: [64; 3],
        })
        .collect();
    let (lo, hi) = world_bounds(&levels);
    let at = |zoom: f32, size: u32| {
        let cam = Camera::fit(&camera(zoom, Projection::Perspective), lo, hi, size, size);
        choose_level(&levels, &cam, 1.0)
    };
    assert_eq!(at(1.0, 128), 1);
    assert_eq!(at(1.0, 64), 2);
    assert_eq!(at(1.0, 1024), 0);
    // Zooming in four times reads a finer level.
    assert_eq!(at(4.0, 128), 0);
}

#[test]
fn other_methods_are_refused_by_name() {
    let vol = voxcast::builtin::open("sphere").unwrap();
    let tf = TransferFunction::auto(&vol);
    let src = MemorySource::new(vol, 0, [32; 3]).unwrap();
    let mut p = params(32, false);
    p.method = Method::Adaptive;
    let e = render_chunked(
        &src,
        &tf,
        [0.0, 255.0],
        &camera(1.0, Projection::Perspective),
        &p,
        &level0(64 << 20),
        &|_, _| {},
        &AtomicBool::new(false),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("adaptive") && e.contains("uniform"), "{e}");
}

#[test]
fn a_coarser_level_reads_fewer_bytes_and_looks_alike() {
    let vol = voxcast::builtin::open("demo").unwrap();
    let tf = TransferFunction::auto(&vol);
    let src = MemorySource::new(vol.clone(), 2, [32; 3]).unwrap();
    let cam = camera(1.0, Projection::Perspective);
    let p = params(64, false);
    let (fine, s0) = out_of_core(&src, &tf, &cam, &p, &level0(64 << 20));
    let mut one = level0(64 << 20);
    one.level = Some(1);
    let (coarse, s1) = out_of_core(&src, &tf, &cam, &p, &one);
    assert!(
        s1.cache.decoded_bytes * 4 < s0.cache.decoded_bytes,
        "{s0:?} {s1:?}"
    );
    let db = psnr(&fine, &coarse).unwrap();
    assert!(db > 20.0, "{db}");
}

#[test]
fn packets_and_the_scalar_loop_march_bricks_to_the_same_pixels() {
    // The demo (u8: the packets' z-paired fetch) and a u16 and an f32 copy,
    // shaded and flat, jittered, with early termination: every lane that
    // leaves a brick, ends, or terminates inside a packet must give the
    // pixel the scalar loop gives.
    let demo = voxcast::builtin::open("demo").unwrap();
    let d = demo.dims();
    let u16v = Volume::new(
        d,
        demo.spacing(),
        demo.origin(),
        VoxelData::U16(
            (0..demo.len())
                .map(|i| demo.data().get(i) as u16 * 200)
                .collect::<Vec<_>>()
                .into(),
        ),
    )
    .unwrap();
    let f32v = Volume::new(
        d,
        demo.spacing(),
        demo.origin(),
        VoxelData::F32(
            (0..demo.len())
                .map(|i| demo.data().get(i) / 255.0)
                .collect::<Vec<_>>()
                .into(),
        ),
    )
    .unwrap();
    for vol in [demo.clone(), u16v, f32v] {
        let tf = TransferFunction::auto(&vol);
        let src = MemorySource::new(vol.clone(), 0, [24, 20, 32]).unwrap();
        for shading in [false, true] {
            let mut p = params(80, shading);
            p.jitter = true;
            let cam = camera(1.0, Projection::Perspective);
            let (simd, s1) = out_of_core(&src, &tf, &cam, &p, &level0(64 << 20));
            p.simd = Simd::Scalar;
            let (scalar, s2) = out_of_core(&src, &tf, &cam, &p, &level0(64 << 20));
            let worst = max_diff(&simd, &scalar);
            assert!(
                worst < 1e-4,
                "{:?} shading {shading}: {worst}",
                vol.scalar_type()
            );
            assert_eq!(s1.marched, s2.marched);
        }
    }
}

#[test]
fn packets_skip_the_empty_cells_of_a_brick_and_a_warm_renderer_keeps_their_ranges() {
    // The demo's bricks hold transparent cells: with skipping the packets
    // take fewer samples and give the same pixels; a second frame of the
    // same renderer reuses the cell ranges and gives the same image.
    let vol = voxcast::builtin::open("demo").unwrap();
    let tf = TransferFunction::auto(&vol);
    let window = tf.window_for(&vol, None);
    let src = MemorySource::new(vol.clone(), 0, [24, 20, 32]).unwrap();
    let ooc = OutOfCore::new(&src, level0(64 << 20));
    let cam = camera(1.0, Projection::Perspective);
    let no = AtomicBool::new(false);
    let mut p = params(96, false);
    p.jitter = false;
    let (skip, s_skip, _) = ooc.render(&tf, window, &cam, &p, &|_, _| {}, &no).unwrap();
    let (again, s_again, _) = ooc.render(&tf, window, &cam, &p, &|_, _| {}, &no).unwrap();
    p.skip_empty = false;
    let (all, s_all, _) = ooc.render(&tf, window, &cam, &p, &|_, _| {}, &no).unwrap();
    let worst = max_diff(&skip, &all);
    assert!(worst < 1e-4, "skipping changed a pixel by {worst}");
    assert_eq!(skip.pixels, again.pixels, "the warm frame differs");
    assert_eq!(s_skip.samples, s_again.samples);
    if voxcast::render::simd_level(Simd::Auto).is_some() {
        assert!(
            s_skip.samples < s_all.samples,
            "skipping took {} samples, not fewer than {}",
            s_skip.samples,
            s_all.samples
        );
    }
}

#[test]
fn a_warm_renderer_keeps_its_skip_maps_only_while_the_transfer_function_stays() {
    // A warm renderer keeps each brick's skip map for the transfer function
    // of the frame before. Shifting the window down shows cells the first
    // one hid: a map kept across the change would skip them. Each frame
    // must be a fresh renderer's, pixel for pixel and sample for sample.
    let vol = voxcast::builtin::open("demo").unwrap();
    let tf = TransferFunction::auto(&vol);
    let [w0, w1] = tf.window_for(&vol, None);
    let shifted = [w0 - 0.5 * (w1 - w0), w1 - 0.5 * (w1 - w0)];
    let src = MemorySource::new(vol.clone(), 0, [24, 20, 32]).unwrap();
    let warm = OutOfCore::new(&src, level0(64 << 20));
    let cam = camera(1.0, Projection::Perspective);
    let no = AtomicBool::new(false);
    let mut p = params(96, false);
    p.jitter = false;
    let fresh = |window: [f32; 2]| {
        let ooc = OutOfCore::new(&src, level0(64 << 20));
        ooc.render(&tf, window, &cam, &p, &|_, _| {}, &no).unwrap()
    };
    let mut samples = Vec::new();
    for window in [[w0, w1], shifted, [w0, w1], shifted] {
        let (img, stats, _) = warm.render(&tf, window, &cam, &p, &|_, _| {}, &no).unwrap();
        let (want, want_stats, _) = fresh(window);
        assert_eq!(
            img.pixels, want.pixels,
            "window {window:?}: the warm frame differs"
        );
        assert_eq!(stats.samples, want_stats.samples, "window {window:?}");
        samples.push(stats.samples);
    }
    // The shift changes what is visible, so the test can tell.
    assert_ne!(
        samples[0], samples[1],
        "the two windows march the same samples"
    );
}

#[test]
fn cells_of_zeros_are_skipped_under_a_map_whose_opacity_rises_from_zero() {
    // A blob in a box of exact zeros, under the cloud map (opacity
    // proportional to density from 0): the zeros' cells are transparent.
    // A margin of a whole table entry once counted them as visible, and
    // the out-of-core march took every sample of every brick.
    let n = 64usize;
    let data: Vec<f32> = (0..n * n * n)
        .map(|i| {
            let p = Vec3::new((i % n) as f32, (i / n % n) as f32, (i / (n * n)) as f32);
            let r = (p - Vec3::splat(20.0)).length();
            if r < 10.0 {
                1.0 - r / 10.0
            } else {
                0.0
            }
        })
        .collect();
    let vol = Volume::new([n; 3], Vec3::ONE, Vec3::ZERO, VoxelData::F32(data.into())).unwrap();
    let tf = TransferFunction::preset("cloud").unwrap();
    let window = [0.0, 1.0];
    let src = MemorySource::new(vol.clone(), 0, [32; 3])
        .unwrap()
        .with_ranges();
    let ooc = OutOfCore::new(&src, level0(64 << 20));
    let cam = camera(1.0, Projection::Perspective);
    let no = AtomicBool::new(false);
    let mut p = params(96, false);
    p.jitter = false;
    p.ert = 1.0;
    let (skip, s_skip, _) = ooc.render(&tf, window, &cam, &p, &|_, _| {}, &no).unwrap();
    let (_, s_in) = voxcast::render::render(&vol, &tf, window, &cam, &p, &|_, _| {}).unwrap();
    p.skip_empty = false;
    let (all, s_all, _) = ooc.render(&tf, window, &cam, &p, &|_, _| {}, &no).unwrap();
    let worst = max_diff(&skip, &all);
    assert!(worst < 1e-4, "skipping changed a pixel by {worst}");
    // As few samples as the in-core march with its blocks (measured: 14906
    // out of core against 20145 in core, and 48376 with the old margin);
    // the packets skip cells inside the box of the visible ones.
    let packets = voxcast::render::simd_level(Simd::Auto).is_some();
    assert!(
        s_skip.samples * 5 <= s_in.samples * 6 && (!packets || s_skip.samples < s_all.samples),
        "out of core {} samples ({} without skipping), in core {}",
        s_skip.samples,
        s_all.samples,
        s_in.samples
    );
}

/// An f32 volume of `dims` voxels whose value at voxel `(x, y, z)` is
/// `f(x, y, z)`.
fn field(dims: [usize; 3], f: impl Fn(f32, f32, f32) -> f32) -> Volume {
    let data: Vec<f32> = (0..dims[0] * dims[1] * dims[2])
        .map(|i| {
            let (x, y, z) = (i % dims[0], i / dims[0] % dims[1], i / (dims[0] * dims[1]));
            f(x as f32, y as f32, z as f32)
        })
        .collect();
    Volume::new(dims, Vec3::ONE, Vec3::ZERO, VoxelData::F32(data.into())).unwrap()
}

/// A close perspective view, at an image size where the far half of the
/// volume needs only the coarser levels.
fn close_view() -> (CameraParams, RenderParams) {
    let mut cam = camera(1.0, Projection::Perspective);
    cam.azimuth = 40.0;
    cam.elevation = 25.0;
    (cam, params(64, false))
}

fn per_region(budget: u64) -> OutOfCoreParams {
    OutOfCoreParams {
        level: None,
        ..level0(budget)
    }
}

#[test]
fn levels_chosen_by_region_cover_each_stretch_of_a_ray_once() {
    // A constant field looks the same at every level (its means are the
    // value itself, and a coarser level's sample stands for as many base
    // steps as it skips): a region read at another level must leave no
    // gap and take no sample twice where it meets its neighbours.
    let vol = field([96, 80, 64], |_, _, _| 0.5);
    let tf = TransferFunction::preset("grayscale").unwrap();
    let src = MemorySource::new(vol, 2, [16; 3]).unwrap();
    let (cam, mut p) = close_view();
    p.ert = 1.0;
    for shading in [false, true] {
        p.shading = shading;
        for simd in [Simd::Auto, Simd::Scalar] {
            p.simd = simd;
            let (mixed, s) = out_of_core(&src, &tf, &cam, &p, &per_region(64 << 20));
            let (fine, s0) = out_of_core(&src, &tf, &cam, &p, &level0(64 << 20));
            let levels = s.per_level.iter().filter(|&&n| n > 0).count();
            assert!(
                s.level == 0 && s.coarsest > 0 && levels >= 2,
                "one level only: {s:?}"
            );
            assert!(
                s.cache.decoded_bytes < s0.cache.decoded_bytes,
                "{s:?} {s0:?}"
            );
            let worst = max_diff(&mixed, &fine);
            assert!(worst < 1e-4, "shading {shading} {simd:?}: {worst}");
        }
    }
}

#[test]
fn a_region_read_at_a_coarser_level_samples_the_same_places() {
    // A linear field: each level's means are its values at the coarser
    // voxels' centres and trilinear interpolation is exact, so every level
    // holds the same field. A brick mapping the base's coordinates to its
    // level's wrongly (half a voxel off) shows at once; what is left is
    // the clamping at the volume's faces, where a coarser level's last
    // voxel centre lies inside.
    let vol = field([96, 80, 64], |x, y, z| (x + 0.7 * y + 0.4 * z) / 180.0);
    let tf = TransferFunction::preset("viridis").unwrap();
    let src = MemorySource::new(vol, 2, [16; 3]).unwrap();
    let (cam, p) = close_view();
    // A narrow window: the colour changes by 3 % a voxel.
    let render = |ooc: &OutOfCoreParams| {
        let no = AtomicBool::new(false);
        let (img, _, st) =
            render_chunked(&src, &tf, [0.4, 0.6], &cam, &p, ooc, &|_, _| {}, &no).unwrap();
        (img, st)
    };
    let (mixed, s) = render(&per_region(64 << 20));
    let (fine, _) = render(&level0(64 << 20));
    assert!(s.coarsest > 0, "{s:?}");
    let db = psnr(&fine, &mixed).unwrap();
    assert!(db >= 60.0, "{db:.1} dB");
}

#[test]
fn the_levels_follow_the_distance() {
    // Near the eye the finest level, further off coarser ones: the
    // bricks marched per level, for a close view and a far one.
    let vol = field([96, 80, 64], |x, _, _| x / 96.0);
    let tf = TransferFunction::preset("grayscale").unwrap();
    let src = MemorySource::new(vol, 2, [16; 3]).unwrap();
    let (cam, p) = close_view();
    let (_, near) = out_of_core(&src, &tf, &cam, &p, &per_region(64 << 20));
    assert_eq!((near.level, near.coarsest), (0, 1), "{near:?}");
    // The same view at half the pixels each way: a level coarser.
    let small = params(32, false);
    let (_, far) = out_of_core(&src, &tf, &cam, &small, &per_region(64 << 20));
    assert_eq!((far.level, far.coarsest), (1, 2), "{far:?}");
    // An asked level is the only one read.
    let (_, one) = out_of_core(&src, &tf, &cam, &p, &level0(64 << 20));
    assert_eq!((one.level, one.coarsest), (0, 0), "{one:?}");
}

#[test]
fn resident_only_frames_never_read_and_refine_to_the_full_picture() {
    // A viewer's frames: the first reads the coarsest level's chunks and
    // draws everything at that level; each later frame reads nothing and
    // draws each region at the finest level in memory, listing what it
    // lacks. Read what is wanted, frame after frame: the picture becomes
    // the one a render that reads as it goes draws.
    let vol = field([96, 80, 64], |x, y, z| {
        0.5 + 0.25 * (x * 0.31).sin() * (y * 0.23).cos() + 0.2 * (z / 64.0)
    });
    let tf = TransferFunction::preset("viridis").unwrap();
    let src = MemorySource::new(vol, 2, [16; 3]).unwrap();
    let window = tf.window_for(src.volume(0), None);
    let (cam, p) = close_view();
    let no = AtomicBool::new(false);
    let streaming = OutOfCoreParams {
        resident_only: true,
        ..per_region(64 << 20)
    };
    let full = |ooc: &OutOfCoreParams| {
        render_chunked(&src, &tf, window, &cam, &p, ooc, &|_, _| {}, &no).unwrap()
    };
    let (want, _, want_st) = full(&per_region(64 << 20));
    let (coarse, _, _) = full(&OutOfCoreParams {
        level: Some(2),
        ..per_region(64 << 20)
    });
    assert_eq!((want_st.level, want_st.coarsest), (0, 1), "{want_st:?}");

    let ooc = OutOfCore::new(&src, streaming);
    let mut bases = Vec::new();
    let mut last = None;
    for frame in 0..10 {
        let (img, _, st) = ooc.render(&tf, window, &cam, &p, &|_, _| {}, &no).unwrap();
        if frame == 0 {
            assert_eq!(st.level, 2, "{st:?}");
            assert!(max_diff(&img, &coarse) < 1e-6, "the coarsest level");
            assert!(!st.wanted.is_empty());
        } else {
            assert_eq!(st.cache.misses, 0, "frame {frame} read: {st:?}");
        }
        bases.push(st.level);
        let done = st.wanted.is_empty();
        for &k in &st.wanted {
            assert!(ooc.fetch(k).unwrap(), "{k:?} was wanted but in memory");
        }
        last = Some(img);
        if done {
            break;
        }
    }
    assert_eq!(bases.first(), Some(&2), "{bases:?}");
    assert_eq!(bases.last(), Some(&0), "{bases:?}");
    assert!(bases.windows(2).all(|w| w[0] >= w[1]), "{bases:?}");
    let worst = max_diff(&last.unwrap(), &want);
    assert!(worst < 1e-5, "refined picture differs by {worst}");
}

#[test]
fn resident_only_wants_no_more_than_the_budget_holds() {
    // A budget of a few chunks: the frames refine as far as memory allows
    // and then stop asking (no chunk read only to evict another the view
    // uses), still reading nothing while they draw.
    let vol = field([96, 80, 64], |x, y, _| 0.3 + 0.4 * ((x + y) / 176.0));
    let tf = TransferFunction::preset("grayscale").unwrap();
    let src = MemorySource::new(vol, 2, [16; 3]).unwrap();
    let window = tf.window_for(src.volume(0), None);
    let (cam, p) = close_view();
    let no = AtomicBool::new(false);
    let chunk = 16 * 16 * 16 * 4;
    let budget = 40 * chunk;
    let ooc = OutOfCore::new(
        &src,
        OutOfCoreParams {
            resident_only: true,
            ..per_region(budget)
        },
    );
    let mut finished = false;
    for frame in 0..12 {
        let (_, _, st) = ooc.render(&tf, window, &cam, &p, &|_, _| {}, &no).unwrap();
        if frame > 0 {
            assert_eq!(st.cache.misses, 0, "frame {frame} read: {st:?}");
        }
        assert!(st.cache.peak_bytes <= budget, "{st:?}");
        if st.wanted.is_empty() {
            finished = true;
            assert!(st.level > 0, "level 0 cannot fit: {st:?}");
            assert!(st.over_budget, "{st:?}");
            break;
        }
        for &k in &st.wanted {
            ooc.fetch(k).unwrap();
        }
    }
    assert!(finished, "still wanting chunks after 12 frames");
}

/// A Zarr store written from the demo volume renders out of core as the
/// same volume held in memory, and its ranges skip the empty chunks.
#[test]
fn the_out_of_core_render_of_a_store_is_the_in_core_picture() {
    use voxcast::io::zarr::write::{write_volume, WriteOptions};
    use voxcast::io::zarr::ZarrStore;
    let vol = voxcast::builtin::open("demo").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("demo.zarr");
    let o = WriteOptions {
        chunk: [32, 32, 32],
        ..Default::default()
    };
    write_volume(&vol, &p, &o, &|_, _| {}).unwrap();
    let store = ZarrStore::open(&p).unwrap();
    let mem = MemorySource::new(vol.clone(), 0, [32, 32, 32]).unwrap();
    let tf = TransferFunction::auto(&vol);
    let window = tf.window_for(&vol, None);
    let cam = CameraParams {
        azimuth: 30.0,
        elevation: 20.0,
        ..Default::default()
    };
    let rp = RenderParams {
        width: 64,
        height: 64,
        ..Default::default()
    };
    let ooc = OutOfCoreParams {
        budget: 1 << 20,
        level: Some(0),
        ..Default::default()
    };
    let run = |src: &dyn ChunkedSource| out_of_core_in(src, window, &tf, &cam, &rp, &ooc);
    let (a, sa) = run(&store);
    let (b, sb) = run(&mem);
    assert_eq!(a.pixels, b.pixels);
    // The store's ranges skip the empty chunks without reading them.
    assert!(sa.empty > 0 && sa.bytes_read > 0, "{sa:?}");
    assert!(sa.cache.misses < sb.cache.misses, "{sa:?} {sb:?}");
}
