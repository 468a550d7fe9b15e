//! The sampling methods: empty-space skipping, S0's adaptive steps and
//! grouped interpolation, the threshold baseline, jitter — each checked by
//! numbers.

mod common;
use common::{max_diff, no_progress};

use glam::Vec3;
use voxcast::camera::{CameraParams, Projection};
use voxcast::render::{
    AdaptiveParams, Method, MethodSpec, RenderParams, RenderStats, Renderer, Simd,
};
use voxcast::transfer::TransferFunction;
use voxcast::{metrics, Image, Volume, VoxelData};

fn draw(
    vol: &Volume,
    tf: &TransferFunction,
    cam: &CameraParams,
    p: &RenderParams,
) -> (Image, RenderStats) {
    let s = vol.stats();
    let r = Renderer::new(vol, [s.min, s.max]).unwrap();
    r.render(tf, cam, p, &no_progress).unwrap()
}

fn view() -> CameraParams {
    CameraParams {
        azimuth: 35.0,
        elevation: 25.0,
        zoom: 1.4,
        ..Default::default()
    }
}

/// The demo with a transfer function that leaves most blocks empty.
fn sparse_scene() -> (Volume, TransferFunction) {
    let vol = voxcast::builtin::open("demo").unwrap();
    let tf = TransferFunction {
        color: vec![[0.0, 1.0, 0.6, 0.3], [1.0, 1.0, 1.0, 0.9]],
        opacity: vec![[0.0, 0.0], [0.3, 0.0], [0.6, 0.2], [1.0, 0.6]],
        window: None,
    };
    (vol, tf)
}

#[test]
fn empty_space_skipping_changes_cost_not_pixels() {
    let (vol, tf) = sparse_scene();
    for spec in [
        "uniform",
        "adaptive",
        "adaptive-max",
        "uniform+grouped",
        "adaptive+grouped",
    ] {
        for jitter in [false, true] {
            let mut p = RenderParams {
                width: 96,
                height: 80,
                jitter,
                ..Default::default()
            };
            MethodSpec::parse(spec).unwrap().apply(&mut p);
            p.skip_empty = false;
            let (full, s_full) = draw(&vol, &tf, &view(), &p);
            p.skip_empty = true;
            let (skip, s_skip) = draw(&vol, &tf, &view(), &p);
            let d = max_diff(&full, &skip);
            assert!(
                d <= 1e-6,
                "{spec} jitter {jitter}: skipping moved a pixel by {d}"
            );
            assert!(
                s_skip.samples * 2 < s_full.samples,
                "{spec}: {} samples with skipping vs {} without",
                s_skip.samples,
                s_full.samples
            );
        }
    }
}

#[test]
fn uniform_steps_agree_after_opacity_correction() {
    // A smooth volume: the soft sphere.
    let vol = voxcast::builtin::open("sphere").unwrap();
    let tf = TransferFunction::preset("viridis").unwrap();
    let mut p = RenderParams {
        width: 96,
        height: 96,
        ert: 1.0,
        ..Default::default()
    };
    let mut images = Vec::new();
    for step in [0.25, 0.5, 1.0] {
        p.step = step;
        images.push(draw(&vol, &tf, &view(), &p).0);
    }
    for (i, j) in [(0, 1), (0, 2), (1, 2)] {
        let psnr = metrics::psnr(&images[i], &images[j]).unwrap();
        assert!(psnr >= 45.0, "steps {i} vs {j}: {psnr:.1} dB");
    }
}

#[test]
fn adaptive_with_a_forced_constant_step_is_uniform() {
    let (vol, tf) = sparse_scene();
    let mut p = RenderParams {
        width: 80,
        height: 64,
        // The blocks adaptive steps with (unset, `uniform` may take finer
        // ones on sparse data: the same picture, fewer samples).
        block_size: Some(8),
        // The scalar march, which adaptive's shares bit for bit (the SIMD
        // packets are held to it in tests/engine.rs).
        simd: Simd::Scalar,
        ..Default::default()
    };
    let (uniform, su) = draw(&vol, &tf, &view(), &p);
    for method in [Method::Adaptive, Method::AdaptiveMax] {
        p.method = method;
        p.adaptive = AdaptiveParams {
            min_step: Some(p.step),
            max_step: Some(p.step),
            ..Default::default()
        };
        let (adaptive, sa) = draw(&vol, &tf, &view(), &p);
        assert_eq!(uniform.pixels, adaptive.pixels, "{method:?}");
        assert_eq!(su.samples, sa.samples);
    }
}

#[test]
fn adaptive_takes_fewer_samples_at_close_quality() {
    let vol = voxcast::builtin::open("demo").unwrap();
    let tf = TransferFunction::auto(&vol);
    let mut p = RenderParams {
        width: 96,
        height: 96,
        // Against `uniform` on the same blocks.
        block_size: Some(8),
        ..Default::default()
    };
    let (reference, su) = draw(&vol, &tf, &view(), &p);
    for method in [Method::Adaptive, Method::AdaptiveMax] {
        p.method = method;
        let (img, sa) = draw(&vol, &tf, &view(), &p);
        assert!(
            sa.samples < su.samples,
            "{method:?}: {} vs {}",
            sa.samples,
            su.samples
        );
        let psnr = metrics::psnr(&reference, &img).unwrap();
        assert!(psnr > 30.0, "{method:?}: {psnr:.1} dB vs uniform");
    }
}

#[test]
fn grouped_interpolation_count_follows_the_group_formula() {
    // One block (8³ voxels), an orthographic ray along +y through its middle:
    // every sample position is known, so the count of interpolations is too.
    let vol = Volume::new(
        [8, 8, 8],
        Vec3::ONE,
        Vec3::ZERO,
        VoxelData::F32(vec![0.5; 512].into()),
    )
    .unwrap();
    let tf = TransferFunction {
        color: vec![[0.0, 1.0, 1.0, 1.0]],
        opacity: vec![[0.0, 0.01]],
        window: None,
    };
    let cam = CameraParams {
        projection: Projection::Orthographic,
        ..Default::default()
    };
    let mut p = RenderParams {
        width: 1,
        height: 1,
        shading: false,
        ert: 1.0,
        step: 0.25,
        ..Default::default()
    };
    let (plain, s_plain) = draw(&vol, &tf, &cam, &p);
    p.grouped = true;
    let (grouped, s_grouped) = draw(&vol, &tf, &cam, &p);
    assert_eq!(s_plain.rays_hit, 1);
    // The ray enters the box (y from 0 to 7) at t_in and leaves at t_out; the
    // camera sits 3 bounding radii from the centre.
    let radius = (Vec3::splat(7.0).length()) * 0.5;
    let t_in = 3.0 * radius - 3.5;
    let t_out = t_in + 7.0;
    let n = (7.0f32 / 0.25).ceil() as u32; // 28 samples
    assert_eq!(s_plain.samples, n as u64);
    assert_eq!(s_plain.interpolations, n as u64);
    let expected: u64 = (0..n)
        .filter(|&k| {
            let t = t_in + k as f32 * 0.25;
            let g = if t <= t_out / 3.0 {
                1
            } else if t <= t_out * 2.0 / 3.0 {
                2
            } else {
                3
            };
            k == 0 || k % g == 0
        })
        .count() as u64;
    assert_eq!(s_grouped.samples, n as u64);
    assert_eq!(s_grouped.interpolations, expected);
    assert!(expected < n as u64);
    // On a constant volume reuse changes nothing.
    assert!(max_diff(&plain, &grouped) < 1e-6);
}

#[test]
fn threshold_steps_by_value_range() {
    let (vol, tf) = sparse_scene();
    let mut p = RenderParams {
        width: 96,
        height: 80,
        skip_empty: false,
        ..Default::default()
    };
    let (uniform, su) = draw(&vol, &tf, &view(), &p);
    p.method = Method::Threshold;
    let (thr, st) = draw(&vol, &tf, &view(), &p);
    // Long steps (2 voxels) through the empty low values: far fewer samples.
    assert!(
        st.samples * 2 < su.samples,
        "{} vs {}",
        st.samples,
        su.samples
    );
    let psnr = metrics::psnr(&uniform, &thr).unwrap();
    assert!(psnr > 25.0, "threshold vs uniform: {psnr:.1} dB");
    // With every range at the base step it is uniform again (same grid).
    p.threshold.steps = [p.step; 3];
    let (same, ss) = draw(&vol, &tf, &view(), &p);
    assert_eq!(ss.samples, su.samples);
    assert!(max_diff(&uniform, &same) < 1e-4);
}

#[test]
fn jitter_is_seeded_and_unbiased() {
    let (vol, tf) = sparse_scene();
    let mut p = RenderParams {
        width: 64,
        height: 64,
        jitter: true,
        seed: 3,
        ..Default::default()
    };
    let (a, _) = draw(&vol, &tf, &view(), &p);
    let (b, _) = draw(&vol, &tf, &view(), &p);
    assert_eq!(a.pixels, b.pixels, "same seed, same image");
    p.seed = 4;
    let (c, _) = draw(&vol, &tf, &view(), &p);
    assert_ne!(a.pixels, c.pixels, "another seed, another image");
    p.jitter = false;
    let (plain, _) = draw(&vol, &tf, &view(), &p);
    let mean =
        |i: &Image| i.pixels.iter().map(|p| p[3] as f64).sum::<f64>() / i.pixels.len() as f64;
    assert!(
        (mean(&a) / mean(&plain) - 1.0).abs() < 0.01,
        "jitter changed the mean opacity"
    );
}

#[test]
fn every_block_size_skips_without_changing_pixels() {
    let (vol, tf) = sparse_scene();
    let s = vol.stats();
    // One renderer serves several block sizes (each built on first use).
    let r = Renderer::new(&vol, [s.min, s.max]).unwrap();
    let mut p = RenderParams {
        width: 64,
        height: 64,
        skip_empty: false,
        ..Default::default()
    };
    let (full, s_full) = r.render(&tf, &view(), &p, &no_progress).unwrap();
    p.skip_empty = true;
    let mut samples = Vec::new();
    for block in [2, 4, 8, 16] {
        p.block_size = Some(block);
        let (img, st) = r.render(&tf, &view(), &p, &no_progress).unwrap();
        let d = max_diff(&full, &img);
        assert!(d <= 1e-6, "block {block}: a pixel moved by {d}");
        samples.push(st.samples);
    }
    // Smaller blocks skip more tightly.
    assert!(samples.windows(2).all(|w| w[0] <= w[1]), "{samples:?}");
    assert!(samples[0] < s_full.samples);
    p.block_size = Some(1);
    assert!(r.render(&tf, &view(), &p, &no_progress).is_err());
}

/// Unset, the block size is 4 where the data is sparse for the marchers
/// that only skip with blocks (the picture is the one of 8³ blocks) and for
/// `adaptive+grouped` (finer levels, fewer samples), and 8
/// otherwise: for the methods that take their steps, groups, pdf or tree
/// from the blocks as measured at 8³, without skipping, and on dense data.
#[test]
fn the_block_size_follows_the_data_for_the_marchers_that_only_skip_and_adaptive_grouped() {
    let (vol, tf) = sparse_scene();
    let s = vol.stats();
    let r = Renderer::new(&vol, [s.min, s.max]).unwrap();
    let p = RenderParams {
        width: 48,
        height: 40,
        ..Default::default()
    };
    let size = |p: &RenderParams| r.render(&tf, &view(), p, &no_progress).unwrap();
    for method in [
        Method::Uniform,
        Method::Jitter,
        Method::Stratified,
        Method::Mc,
    ] {
        let p = RenderParams {
            method,
            ..p.clone()
        };
        let grouped = RenderParams {
            grouped: true,
            ..p.clone()
        };
        assert_eq!(r.block_size_for(&tf, &grouped), 8, "{method:?}+grouped");
        assert_eq!(r.block_size_for(&tf, &p), 4, "{method:?}");
        let (auto, st) = size(&p);
        assert_eq!(st.block_size, 4, "{method:?}");
        let (eight, st8) = size(&RenderParams {
            block_size: Some(8),
            ..p.clone()
        });
        assert_eq!(st8.block_size, 8);
        let d = max_diff(&auto, &eight);
        assert!(d <= 1e-6, "{method:?}: a pixel moved by {d}");
        assert!(st.samples < st8.samples, "{method:?}: {st:?} {st8:?}");
    }
    // `adaptive+grouped`: finer blocks, finer levels, fewer samples; a
    // picture of its own, whether it skips or not (skipping changes its
    // cost, not its pixels).
    let ag = RenderParams {
        method: Method::Adaptive,
        grouped: true,
        ..p.clone()
    };
    assert_eq!(r.block_size_for(&tf, &ag), 4);
    let noskip = RenderParams {
        skip_empty: false,
        ..ag.clone()
    };
    assert_eq!(r.block_size_for(&tf, &noskip), 4);
    let (_, st) = size(&ag);
    assert_eq!(st.block_size, 4);
    let st8 = size(&RenderParams {
        block_size: Some(8),
        ..ag.clone()
    })
    .1;
    assert!(st.samples < st8.samples, "{st:?} {st8:?}");
    for method in [
        Method::Adaptive,
        Method::AdaptiveS0,
        Method::AdaptiveMax,
        Method::Threshold,
        Method::Importance,
        Method::Lod,
    ] {
        let p = RenderParams {
            method,
            ..p.clone()
        };
        assert_eq!(r.block_size_for(&tf, &p), 8, "{method:?}");
        assert_eq!(size(&p).1.block_size, 8, "{method:?}");
    }
    let noskip = RenderParams {
        skip_empty: false,
        ..p.clone()
    };
    assert_eq!(r.block_size_for(&tf, &noskip), 8);
    let given = RenderParams {
        block_size: Some(16),
        ..p.clone()
    };
    assert_eq!(size(&given).1.block_size, 16);
    // A dense volume: every block shows, finer blocks save nothing.
    let dense = Volume::from_fn([40, 36, 30], Vec3::ONE, |i, j, k| {
        0.5 + 0.4 * ((i as f32 * 0.3).sin() * (j as f32 * 0.2).cos() + (k as f32 * 0.25).sin())
            / 2.0
    })
    .unwrap();
    let rd = Renderer::new(&dense, [0.0, 1.0]).unwrap();
    assert_eq!(rd.block_size_for(&tf, &p), 8);
    // Sparse, but with the finer blocks showing nearly as much: a slab of
    // zeros a quarter of the volume wide, the rest dense (8³ blocks hide
    // about a quarter, 4³ barely more).
    let cut = Volume::from_fn([40, 36, 30], Vec3::ONE, |i, j, k| {
        if i < 11 {
            0.0
        } else {
            0.7 + 0.2 * ((j as f32 * 0.2).cos() * (k as f32 * 0.25).sin())
        }
    })
    .unwrap();
    let rc = Renderer::new(&cut, [0.0, 1.0]).unwrap();
    assert_eq!(rc.block_size_for(&tf, &p), 8);
}
