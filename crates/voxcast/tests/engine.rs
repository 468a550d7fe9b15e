//! The ray loop's three choices are independent types (render/ray.rs): every
//! marcher, with either reconstruction and shading, must composite the same
//! way in both orders, and the optical models must differ only in the terms
//! they keep — checked for every ray-casting method, since each combination
//! is its own monomorphised loop.

mod common;
use common::{max_diff, no_progress, simd_levels};

use voxcast::camera::CameraParams;
use voxcast::render::{Method, OpticalModel, Order, RenderParams, Renderer, Simd};
use voxcast::transfer::TransferFunction;
use voxcast::Image;

/// The ray-casting methods (the physically based ones have their own
/// integrator and tests).
fn methods() -> impl Iterator<Item = Method> {
    Method::ALL.into_iter().filter(|m| !m.is_physical())
}

fn scene() -> (voxcast::Volume, TransferFunction) {
    let vol = voxcast::builtin::open("demo").unwrap();
    let tf = TransferFunction {
        color: vec![[0.0, 1.0, 0.6, 0.3], [1.0, 0.4, 0.7, 1.0]],
        opacity: vec![[0.0, 0.0], [0.3, 0.0], [0.6, 0.25], [1.0, 0.7]],
        window: None,
    };
    (vol, tf)
}

fn camera() -> CameraParams {
    CameraParams {
        azimuth: 30.0,
        elevation: 20.0,
        zoom: 1.4,
        ..Default::default()
    }
}

fn draw(r: &Renderer<'_>, tf: &TransferFunction, p: &RenderParams) -> Image {
    r.render(tf, &camera(), p, &no_progress).unwrap().0
}

/// In the scalar loop, which composites back to front by S4's
/// recurrence over the buffered samples (the packets sum front to back
/// with termination off; `back_to_front_packets_give_the_scalar_pixels`
/// holds them to this loop).
#[test]
fn every_method_composites_the_same_in_both_orders() {
    let (vol, tf) = scene();
    let s = vol.stats();
    let r = Renderer::new(&vol, [s.min, s.max]).unwrap();
    for method in methods() {
        for grouped in [false, true] {
            for shading in [false, true] {
                let mut p = RenderParams {
                    width: 48,
                    height: 40,
                    method,
                    grouped,
                    shading,
                    // Without early termination both orders add up every
                    // sample: the same sum in another order.
                    ert: 1.0,
                    background: [0.1, 0.2, 0.3],
                    seed: 7,
                    simd: Simd::Scalar,
                    ..Default::default()
                };
                if method == Method::Lod {
                    // S3 spaces the samples by the opacity in front of
                    // them, which a back-to-front pass cannot know (it uses
                    // the leaves' own amounts): one spacing everywhere makes
                    // the two passes take the same samples.
                    p.lod.high = 3;
                    p.lod.low = 3;
                    p.lod.sparse = 3;
                }
                let front = draw(&r, &tf, &p);
                p.order = Order::BackToFront;
                let back = draw(&r, &tf, &p);
                let d = max_diff(&front, &back);
                assert!(
                    d < 2e-5,
                    "{} grouped {grouped} shading {shading}: orders differ by {d}",
                    method.name()
                );
                // And the picture is not empty (the test would pass on nothing).
                let lit = front.pixels.iter().filter(|px| px[3] > 0.05).count();
                assert!(lit > 100, "{}: only {lit} pixels drawn", method.name());
            }
        }
    }
}

#[test]
fn optical_models_keep_only_their_terms() {
    let (vol, tf) = scene();
    let s = vol.stats();
    let r = Renderer::new(&vol, [s.min, s.max]).unwrap();
    for method in methods() {
        let mut p = RenderParams {
            width: 40,
            height: 32,
            method,
            shading: false,
            ert: 1.0,
            seed: 3,
            ..Default::default()
        };
        let both = draw(&r, &tf, &p);
        p.optical = OpticalModel::AbsorptionOnly;
        let absorb = draw(&r, &tf, &p);
        p.optical = OpticalModel::EmissionOnly;
        let emit = draw(&r, &tf, &p);
        let name = method.name();
        let mut brighter = 0;
        for ((b, a), e) in both.pixels.iter().zip(&absorb.pixels).zip(&emit.pixels) {
            // Absorption only: the same opacity, no light of its own (the
            // background is black).
            assert!((a[3] - b[3]).abs() < 1e-5, "{name}: absorption changed α");
            assert!(
                a[0].max(a[1]).max(a[2]) < 1e-6,
                "{name}: absorption emitted"
            );
            // Emission only: nothing absorbed, so at least as much light.
            assert!(e[3].abs() < 1e-6, "{name}: emission absorbed");
            for c in 0..3 {
                assert!(e[c] >= b[c] - 1e-5, "{name}: emission-only darker");
            }
            brighter += (e[0] > b[0] + 1e-3) as usize;
        }
        assert!(brighter > 20, "{name}: emission-only never brighter");
    }
}

/// A 37×29×23 field of every stored type, with empty space around a few
/// blobs (so rays leave, skip and terminate at different samples within
/// one packet) and an odd x size (partial packets at tile edges).
fn typed_volumes() -> Vec<voxcast::Volume> {
    use voxcast::volume::VoxelData;
    let dims = [37usize, 29, 23];
    let field = |i: usize, j: usize, k: usize| {
        let p = glam::Vec3::new(i as f32, j as f32, k as f32);
        let blobs = [
            (glam::Vec3::new(12.0, 10.0, 8.0), 6.0),
            (glam::Vec3::new(25.0, 18.0, 14.0), 5.0),
            (glam::Vec3::new(18.0, 14.0, 11.0), 3.0),
        ];
        blobs
            .iter()
            .map(|(c, r)| (-(p - *c).length_squared() / (r * r)).exp())
            .sum::<f32>()
            .min(1.0)
    };
    let mut f = Vec::new();
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                f.push(field(i, j, k));
            }
        }
    }
    let s = glam::Vec3::new(1.0, 1.2, 0.9);
    let make = |d| voxcast::Volume::new(dims, s, glam::Vec3::ZERO, d).unwrap();
    vec![
        make(VoxelData::U8(f.iter().map(|v| (v * 255.0) as u8).collect())),
        make(VoxelData::U16(
            f.iter().map(|v| (v * 60000.0) as u16).collect(),
        )),
        make(VoxelData::I16(
            f.iter().map(|v| (v * 30000.0 - 1000.0) as i16).collect(),
        )),
        make(VoxelData::F32(f.clone().into())),
    ]
}

/// The SIMD packets, at every level this CPU has, against the scalar loop:
/// every stored type, both fixed-step methods, `importance`, `threshold`
/// and `threshold+grouped` (the same interpolations, and some reused),
/// `stratified` (a random position per interval, a key per ray and pass),
/// `mc` (sorted uniforms over the whole ray from the pixel's stream),
/// skipping on and off, early termination on and off, flat and Phong,
/// every optical model, several passes of jitter.
/// On a CPU without AVX2 there is no level and the test checks nothing (the
/// packets' own dispatch, which must then pick the scalar loop, is what the
/// other tests see).
#[test]
fn packets_give_the_scalar_pixels() {
    let tf = TransferFunction {
        color: vec![[0.0, 1.0, 0.5, 0.2], [1.0, 0.3, 0.6, 1.0]],
        opacity: vec![[0.0, 0.0], [0.2, 0.0], [0.5, 0.6], [1.0, 1.0]],
        window: None,
    };
    for vol in typed_volumes() {
        let s = vol.stats();
        let r = Renderer::new(&vol, [s.min, s.max]).unwrap();
        let (mut terminated, mut reused) = (0, 0);
        for (method, grouped) in [
            (Method::Uniform, false),
            (Method::Jitter, false),
            (Method::Importance, false),
            (Method::Threshold, false),
            (Method::Threshold, true),
            (Method::Stratified, false),
            (Method::Mc, false),
        ] {
            for skip_empty in [true, false] {
                for (ert, shading) in [(0.9, false), (1.0, false), (0.9, true), (1.0, true)] {
                    for optical in [
                        OpticalModel::EmissionAbsorption,
                        OpticalModel::AbsorptionOnly,
                        OpticalModel::EmissionOnly,
                    ] {
                        let mut p = RenderParams {
                            width: 45,
                            height: 21,
                            method,
                            grouped,
                            shading,
                            skip_empty,
                            ert,
                            optical,
                            spp: 3,
                            seed: 5,
                            step: 0.37,
                            background: [0.2, 0.1, 0.3],
                            ..Default::default()
                        };
                        p.simd = Simd::Scalar;
                        let (scalar, sc) = r.render(&tf, &camera(), &p, &no_progress).unwrap();
                        for (level, name) in simd_levels() {
                            p.simd = level;
                            let (simd, ss) = r.render(&tf, &camera(), &p, &no_progress).unwrap();
                            let d = max_diff(&simd, &scalar);
                            let what = format!(
                            "{name}: {}{} {:?} skip {skip_empty} ert {ert} shading {shading} {optical:?}",
                            method.name(),
                            if grouped { "+grouped" } else { "" },
                            vol.scalar_type()
                        );
                            assert!(d < 1e-4, "{what}: packets differ from scalar by {d}");
                            assert_eq!(ss.rays, sc.rays, "{what}");
                            assert_eq!(ss.rays_hit, sc.rays_hit, "{what}");
                            assert!(sc.rays_hit < sc.rays, "{what}: every ray hits");
                            assert_eq!(ss.early_terminated, sc.early_terminated, "{what}");
                            let (a, b) = (
                                ss.gradient_interpolations as f64,
                                sc.gradient_interpolations as f64,
                            );
                            assert!((a - b).abs() <= 1e-3 * b, "{what}: gradients {a} vs {b}");
                            assert_eq!(b > 0.0, shading, "{what}: gradients {b}");
                            // Samples keep their meaning: the same samples
                            // (lanes skip sample by sample where the scalar
                            // march skips block by block, by the same rule on
                            // faces; a rounding at a face may differ).
                            let (a, b) = (ss.samples as f64, sc.samples as f64);
                            assert!((a - b).abs() <= 1e-3 * b, "{what}: samples {a} vs {b}");
                            let (a, b) = (ss.interpolations as f64, sc.interpolations as f64);
                            assert!(
                                (a - b).abs() <= 1e-3 * b,
                                "{what}: interpolations {a} vs {b}"
                            );
                            assert_eq!(ss.simd.map(|l| l.name()), Some(name), "{what}");
                            assert_eq!(sc.simd, None, "{what}");
                        }
                        terminated += sc.early_terminated;
                        if grouped && sc.interpolations < sc.samples {
                            reused += 1;
                        }
                    }
                }
            }
        }
        assert!(
            terminated > 0,
            "no ray terminated early: the test lost its teeth"
        );
        assert!(
            reused > 0,
            "no grouped sample was reused: the test lost its teeth"
        );
    }
}

/// Back to front in the packets (summed front to back with early
/// termination off) against the scalar loop's back-to-front recurrence,
/// at every level this CPU has: every marcher the packets run, flat and
/// Phong, skipping on and off, a u8 and an f32 grid; no ray terminates
/// early. `lod`'s samples are classed with no opacity in front of them, as
/// the scalar back-to-front pass does.
#[test]
fn back_to_front_packets_give_the_scalar_pixels() {
    let tf = TransferFunction {
        color: vec![[0.0, 1.0, 0.5, 0.2], [1.0, 0.3, 0.6, 1.0]],
        opacity: vec![[0.0, 0.0], [0.2, 0.0], [0.5, 0.6], [1.0, 1.0]],
        window: None,
    };
    let vols = typed_volumes();
    let mut checked = 0;
    for vol in [&vols[0], &vols[3]] {
        let s = vol.stats();
        let r = Renderer::new(vol, [s.min, s.max]).unwrap();
        for (method, grouped) in [
            (Method::Uniform, false),
            (Method::Jitter, false),
            (Method::Uniform, true),
            (Method::Adaptive, false),
            (Method::Adaptive, true),
            (Method::AdaptiveMax, false),
            (Method::Importance, false),
            (Method::Threshold, false),
            (Method::Threshold, true),
            (Method::Stratified, false),
            (Method::Mc, false),
            (Method::Lod, false),
        ] {
            for (skip_empty, shading) in [(true, false), (false, false), (true, true)] {
                let mut p = RenderParams {
                    width: 45,
                    height: 21,
                    method,
                    grouped,
                    shading,
                    skip_empty,
                    order: Order::BackToFront,
                    // Ignored back to front.
                    ert: 0.5,
                    spp: 2,
                    seed: 5,
                    step: 0.37,
                    background: [0.2, 0.1, 0.3],
                    simd: Simd::Scalar,
                    ..Default::default()
                };
                let (scalar, sc) = r.render(&tf, &camera(), &p, &no_progress).unwrap();
                for (level, name) in simd_levels() {
                    p.simd = level;
                    let (simd, ss) = r.render(&tf, &camera(), &p, &no_progress).unwrap();
                    let what = format!(
                        "{name}: {}{} {:?} skip {skip_empty} shading {shading}",
                        method.name(),
                        if grouped { "+grouped" } else { "" },
                        vol.scalar_type()
                    );
                    let d = max_diff(&simd, &scalar);
                    assert!(d < 1e-4, "{what}: packets differ from scalar by {d}");
                    let (a, b) = (ss.samples as f64, sc.samples as f64);
                    assert!(b > 0.0, "{what}: nothing sampled");
                    assert!((a - b).abs() <= 1e-3 * b, "{what}: samples {a} vs {b}");
                    assert_eq!(ss.early_terminated, 0, "{what}");
                    assert_eq!(sc.early_terminated, 0, "{what}");
                    assert_eq!(ss.simd.map(|l| l.name()), Some(name), "{what}");
                    checked += 1;
                }
            }
        }
    }
    assert!(checked > 0 || simd_levels().is_empty(), "nothing compared");
}

/// Skipping by distance: a lane in an empty block jumps over the whole
/// empty cube around it (`packet::skip_distances`), not one block at a
/// time. Two small blobs in opposite corners of a larger volume leave
/// empty blocks up to four blocks from anything visible between them,
/// and the rays cross those stretches at every angle; at every level this
/// CPU has, the packets give the scalar pixels with the same samples
/// (a jump passes only samples the scalar march skips too);
/// `importance`'s vector walks, through the same long empty stretches,
/// give the scalar walk's samples; `lod`'s lanes (in `threshold`'s loop),
/// which jump the same cubes and start again on the base grid, give the
/// scalar march's pixels and samples; `threshold`'s lanes, which jump them and start
/// again on the base grid, sample where the scalar march restarts;
/// `stratified`'s, which go on at the first interval past the cube,
/// take the scalar march's random positions; and `mc`'s, which cannot
/// jump, drop the same positions in the empty blocks.
#[test]
fn packets_jump_the_empty_space_and_keep_the_samples() {
    use voxcast::volume::VoxelData;
    let dims = [83usize, 71, 64];
    let blobs = [
        (glam::Vec3::new(9.0, 8.0, 7.0), 5.0),
        (glam::Vec3::new(72.0, 61.0, 55.0), 6.0),
    ];
    let mut f = Vec::with_capacity(dims.iter().product());
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let p = glam::Vec3::new(i as f32, j as f32, k as f32);
                let v: f32 = blobs
                    .iter()
                    .map(|(c, r)| (-(p - *c).length_squared() / (r * r)).exp())
                    .sum();
                f.push((v.min(1.0) * 255.0) as u8);
            }
        }
    }
    let vol = voxcast::Volume::new(
        dims,
        glam::Vec3::ONE,
        glam::Vec3::ZERO,
        VoxelData::U8(f.into()),
    )
    .unwrap();
    let tf = TransferFunction {
        color: vec![[0.0, 1.0, 0.5, 0.2], [1.0, 0.3, 0.6, 1.0]],
        opacity: vec![[0.0, 0.0], [0.3, 0.0], [0.6, 0.5], [1.0, 0.9]],
        window: None,
    };
    let r = Renderer::new(&vol, [0.0, 255.0]).unwrap();
    let mut samples = 0;
    for (azimuth, elevation) in [(30.0, 20.0), (-135.0, -40.0), (90.0, 0.0), (47.0, 71.0)] {
        let cam = CameraParams {
            azimuth,
            elevation,
            ..Default::default()
        };
        for (method, shading, grouped) in [
            (Method::Uniform, false, false),
            (Method::Uniform, true, false),
            (Method::Importance, false, false),
            (Method::Importance, true, false),
            (Method::Lod, false, false),
            (Method::Lod, true, false),
            (Method::Threshold, false, false),
            (Method::Threshold, true, false),
            // Grouped `threshold` starts a group past each jump.
            (Method::Threshold, false, true),
            (Method::Threshold, true, true),
            // `stratified` jumps to the first interval past the cube.
            (Method::Stratified, false, false),
            (Method::Stratified, true, false),
            // `mc` drops its positions in empty blocks, by the scalar
            // march's rule.
            (Method::Mc, false, false),
            (Method::Mc, true, false),
            // The step-per-block walks jump the empty cubes too.
            (Method::Adaptive, false, false),
            (Method::Adaptive, true, true),
            (Method::AdaptiveMax, false, true),
            (Method::Uniform, true, true),
        ] {
            let mut p = RenderParams {
                width: 64,
                height: 48,
                method,
                shading,
                grouped,
                step: 0.41,
                spp: 2,
                seed: 3,
                ..Default::default()
            };
            p.simd = Simd::Scalar;
            let (scalar, sc) = r.render(&tf, &cam, &p, &no_progress).unwrap();
            for (level, name) in simd_levels() {
                p.simd = level;
                let (simd, ss) = r.render(&tf, &cam, &p, &no_progress).unwrap();
                let what = format!(
                    "{name}: {} grouped {grouped} azimuth {azimuth} elevation {elevation} shading {shading}",
                    method.name()
                );
                let d = max_diff(&simd, &scalar);
                assert!(d < 1e-4, "{what}: packets differ from scalar by {d}");
                assert_eq!(ss.samples, sc.samples, "{what}");
                assert_eq!(ss.interpolations, sc.interpolations, "{what}");
                assert_eq!(ss.early_terminated, sc.early_terminated, "{what}");
                assert_eq!(ss.simd.map(|l| l.name()), Some(name), "{what}");
            }
            samples += sc.samples;
        }
    }
    assert!(
        samples > 0,
        "the blobs were not seen: the test lost its teeth"
    );
}

/// The step-per-block marches in the packets (each lane walks its blocks
/// with the scalar march's own walk, run by run, and the vector loop
/// samples the runs), at every level this CPU has, against the scalar
/// loop: the three `adaptive` rules with and without S0's grouped reuse,
/// `uniform` grouped, every stored type, skipping on and off, early
/// termination on and off, flat and Phong, jitter on and off. The walk is
/// the same code, so the counts are equal, not close.
#[test]
fn step_per_block_packets_give_the_scalar_pixels() {
    let tf = TransferFunction {
        color: vec![[0.0, 1.0, 0.5, 0.2], [1.0, 0.3, 0.6, 1.0]],
        opacity: vec![[0.0, 0.0], [0.2, 0.0], [0.5, 0.6], [1.0, 1.0]],
        window: None,
    };
    // And a hard-edged box: runs end in full opacity at a face with empty
    // blocks behind it.
    let dims = [40usize, 24, 20];
    let edged = (0..dims.iter().product::<usize>())
        .map(|i| {
            let (x, y, z) = (i % 40, i / 40 % 24, i / (40 * 24));
            200 * ((9..21).contains(&x) && (5..15).contains(&y) && (3..13).contains(&z)) as u8
        })
        .collect();
    let edged = voxcast::Volume::new(
        dims,
        glam::Vec3::ONE,
        glam::Vec3::ZERO,
        voxcast::volume::VoxelData::U8(edged),
    )
    .unwrap();
    for vol in typed_volumes().into_iter().chain([edged]) {
        let s = vol.stats();
        let r = Renderer::new(&vol, [s.min, s.max]).unwrap();
        let (mut terminated, mut grouped_reuse) = (0, 0);
        for (method, grouped) in [
            (Method::Adaptive, false),
            (Method::Adaptive, true),
            (Method::AdaptiveS0, true),
            (Method::AdaptiveMax, false),
            (Method::Uniform, true),
            (Method::Lod, false),
        ] {
            // Blocks of 4 leave empty blocks between the blobs and behind
            // them, where runs end and walks finish.
            for (skip_empty, jitter, block_size) in
                [(true, true, 8), (false, false, 8), (true, false, 4)]
            {
                for (ert, shading) in [(0.9, false), (1.0, false), (0.9, true), (1.0, true)] {
                    let mut p = RenderParams {
                        width: 45,
                        height: 21,
                        method,
                        grouped,
                        shading,
                        skip_empty,
                        block_size: Some(block_size),
                        ert,
                        jitter,
                        seed: 5,
                        step: 0.37,
                        background: [0.2, 0.1, 0.3],
                        ..Default::default()
                    };
                    p.simd = Simd::Scalar;
                    let (scalar, sc) = r.render(&tf, &camera(), &p, &no_progress).unwrap();
                    for (level, name) in simd_levels() {
                        p.simd = level;
                        let (simd, ss) = r.render(&tf, &camera(), &p, &no_progress).unwrap();
                        let d = max_diff(&simd, &scalar);
                        let what = format!(
                            "{name}: {}{} {:?} skip {skip_empty} jitter {jitter} block {block_size} ert {ert} shading {shading}",
                            method.name(),
                            if grouped { "+grouped" } else { "" },
                            vol.scalar_type()
                        );
                        assert!(d < 1e-4, "{what}: packets differ from scalar by {d}");
                        assert_eq!(ss.rays_hit, sc.rays_hit, "{what}");
                        assert_eq!(ss.samples, sc.samples, "{what}");
                        assert_eq!(ss.interpolations, sc.interpolations, "{what}");
                        assert_eq!(
                            ss.gradient_interpolations, sc.gradient_interpolations,
                            "{what}"
                        );
                        assert_eq!(ss.early_terminated, sc.early_terminated, "{what}");
                        assert!(sc.samples > 0, "{what}: nothing sampled");
                        // The stats say which loop ran.
                        assert_eq!(ss.simd.map(|l| l.name()), Some(name), "{what}");
                        assert_eq!(sc.simd, None, "{what}");
                    }
                    terminated += sc.early_terminated;
                    if grouped && sc.interpolations < sc.samples {
                        grouped_reuse += 1;
                    }
                }
            }
        }
        assert!(
            terminated > 0,
            "no ray terminated early: the test lost its teeth"
        );
        assert!(
            grouped_reuse > 0,
            "grouping reused nothing: the test lost its teeth"
        );
    }
}

/// One-voxel axes (a single slice, a single row) and a two-voxel x axis:
/// the packets' neighbour fetches (the u8 z-paired copy, the +x pair) must
/// read the same corners as the scalar loop there. (This found the scalar
/// block walk ending at a single slice's mid-plane when skipping: the far
/// half of the slab was never sampled.)
#[test]
fn packets_handle_thin_volumes() {
    use voxcast::volume::VoxelData;
    let tf = TransferFunction {
        color: vec![[0.0, 1.0, 0.5, 0.2], [1.0, 0.3, 0.6, 1.0]],
        opacity: vec![[0.0, 0.0], [1.0, 0.8]],
        window: None,
    };
    for dims in [[9usize, 7, 1], [9, 1, 5], [2, 6, 4], [11, 3, 2]] {
        let n = dims[0] * dims[1] * dims[2];
        let v: Vec<f32> = (0..n).map(|i| ((i * 37) % 23) as f32 / 22.0).collect();
        let s = glam::Vec3::ONE;
        for data in [
            VoxelData::U8(v.iter().map(|x| (x * 255.0) as u8).collect()),
            VoxelData::U16(v.iter().map(|x| (x * 4000.0) as u16).collect()),
            VoxelData::F32(v.clone().into()),
        ] {
            let vol = voxcast::Volume::new(dims, s, glam::Vec3::ZERO, data).unwrap();
            let st = vol.stats();
            let r = Renderer::new(&vol, [st.min, st.max]).unwrap();
            for (elevation, shading, skip_empty) in [
                (20.0, false, true),
                (20.0, false, false),
                (80.0, true, true),
                (-35.0, false, true),
            ] {
                let cam = CameraParams {
                    azimuth: 30.0,
                    elevation,
                    ..Default::default()
                };
                let mut p = RenderParams {
                    width: 33,
                    height: 17,
                    shading,
                    skip_empty,
                    ..Default::default()
                };
                p.simd = Simd::Scalar;
                let (b, sb) = r.render(&tf, &cam, &p, &no_progress).unwrap();
                for (level, name) in simd_levels() {
                    p.simd = level;
                    let (a, sa) = r.render(&tf, &cam, &p, &no_progress).unwrap();
                    let d = max_diff(&a, &b);
                    let what = format!(
                        "{name}: {dims:?} {:?} elevation {elevation} skip {skip_empty}",
                        vol.scalar_type()
                    );
                    assert!(d < 1e-4, "{what}: packets differ from scalar by {d}");
                    assert!(sb.samples > 0, "{what}: nothing sampled");
                    assert_eq!(sa.rays_hit, sb.rays_hit, "{what}");
                }
            }
        }
    }
}

/// A renderer keeps what it derived from the last transfer function and
/// step (the table, the blocks' emptiness, the levels' tables, `adaptive`'s
/// change per block) for the renders after it: a render with another
/// transfer function or step must not be served them. Each render of one
/// renderer, through changes of either and back, gives the bytes of a
/// fresh renderer's.
#[test]
fn a_kept_renderer_redraws_what_a_fresh_one_draws() {
    let (vol, tf) = scene();
    let s = vol.stats();
    let window = [s.min, s.max];
    // Another transfer function: opaque where the first is faint, and an
    // empty stretch where it is not, so emptiness and levels change too.
    let tf2 = TransferFunction {
        color: vec![[0.0, 0.9, 0.2, 0.1], [1.0, 0.2, 0.4, 0.9]],
        opacity: vec![[0.0, 0.0], [0.1, 0.6], [0.5, 0.0], [1.0, 0.0]],
        window: None,
    };
    let kept = Renderer::new(&vol, window).unwrap();
    let mut changed = 0;
    let mut last: Option<Image> = None;
    for method in [
        Method::Adaptive,
        Method::Uniform,
        Method::Threshold,
        Method::Lod,
    ] {
        for (tf, step) in [(&tf, 0.5), (&tf2, 0.5), (&tf2, 1.0), (&tf, 0.5)] {
            let p = RenderParams {
                width: 40,
                height: 32,
                method,
                step,
                grouped: method == Method::Adaptive,
                ..Default::default()
            };
            let a = draw(&kept, tf, &p);
            let b = draw(&Renderer::new(&vol, window).unwrap(), tf, &p);
            assert!(
                a.pixels == b.pixels,
                "{} step {step}: the kept renderer drew another picture",
                method.name()
            );
            // The changes change the picture (the test would pass on a
            // renderer that ignored them only if they did not).
            if last.as_ref().is_some_and(|l| l.pixels != a.pixels) {
                changed += 1;
            }
            last = Some(a);
        }
    }
    assert!(
        changed >= 12,
        "only {changed} of 15 changes changed the picture"
    );
}

/// A 64³ u8 volume, dense (a ripple between 60 and 200 everywhere) but
/// for a cube of zeros `0..c` in one corner.
fn dense_but_a_corner(c: usize) -> voxcast::Volume {
    let n = 64usize;
    let mut f = Vec::with_capacity(n * n * n);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let v = if i < c && j < c && k < c {
                    0.0
                } else {
                    130.0
                        + 70.0
                            * ((i as f32 * 0.31).sin() * (j as f32 * 0.23 + k as f32 * 0.17).cos())
                };
                f.push(v as u8);
            }
        }
    }
    voxcast::Volume::new(
        [n; 3],
        glam::Vec3::ONE,
        glam::Vec3::ZERO,
        voxcast::volume::VoxelData::U8(f.into()),
    )
    .unwrap()
}

/// Where the transfer function hides under `SKIP_PAYS` of the blocks, the
/// CPU marchers leave skipping out (it would save less than its tests
/// cost): the same pixels and samples as without it, and the stats say
/// so; where it hides more, they skip.
#[test]
fn skipping_is_left_out_where_hardly_a_block_is_empty() {
    let tf = TransferFunction {
        color: vec![[0.0, 1.0, 0.5, 0.2], [1.0, 0.3, 0.6, 1.0]],
        opacity: vec![[0.0, 0.0], [0.1, 0.0], [0.5, 0.05], [1.0, 0.3]],
        window: None,
    };
    let cam = CameraParams {
        azimuth: 225.0,
        elevation: -35.0,
        ..Default::default()
    };
    // 8³ blocks: a corner of 24 zeros hides 2³ of the 8³ blocks (1.6 %),
    // one of 40 hides 4³ (12.5 %).
    for (c, dense) in [(24, true), (40, false)] {
        let vol = dense_but_a_corner(c);
        let r = Renderer::new(&vol, [0.0, 255.0]).unwrap();
        for method in [Method::Uniform, Method::Adaptive, Method::Lod] {
            for shading in [false, true] {
                let mut p = RenderParams {
                    width: 48,
                    height: 40,
                    method,
                    shading,
                    ..Default::default()
                };
                let what = format!("corner {c}, {} shading {shading}", method.name());
                p.skip_empty = false;
                let (full, s_full) = r.render(&tf, &cam, &p, &no_progress).unwrap();
                p.skip_empty = true;
                let (skip, s_skip) = r.render(&tf, &cam, &p, &no_progress).unwrap();
                if method == Method::Lod && !dense {
                    // `lod` starts again on the base grid past a skipped
                    // stretch, where without skipping its spacing strides
                    // through it: the samples after it move (52 dB).
                    let db = voxcast::metrics::psnr(&full, &skip).unwrap_or(f64::INFINITY);
                    assert!(db >= 45.0, "{what}: {db} dB apart");
                } else {
                    assert!(max_diff(&full, &skip) <= 1e-6, "{what}: a pixel moved");
                }
                assert_eq!(s_full.skipping_left_out, None, "{what}: not asked for");
                if dense {
                    let share = s_skip.skipping_left_out.unwrap_or(0.0);
                    assert!(
                        share > 0.0 && share < voxcast::render::SKIP_PAYS,
                        "{what}: left out at {share}"
                    );
                    assert_eq!(s_skip.samples, s_full.samples, "{what}");
                } else {
                    assert_eq!(s_skip.skipping_left_out, None, "{what}");
                    assert!(
                        s_skip.samples < s_full.samples,
                        "{what}: {} samples skipping, {} not",
                        s_skip.samples,
                        s_full.samples
                    );
                }
            }
        }
    }
}
