//! The GPU's speed options give the generic pipeline's picture: pipelines
//! specialised per method (pipeline constants) against the generic one, the
//! texture unit's filter against the exact trilinear, and the render's
//! device time from timestamp queries. Without an adapter the tests skip
//! with a note; under CI (`CI=true`) a missing adapter is a failure.

use std::sync::Arc;
use voxcast::render::{MethodSpec, OpticalModel, RenderParams};
use voxcast::scene::{Prepared, Scene};
use voxcast_gpu::{parse_workgroup, Filter, GpuContext, GpuOptions, GpuRenderer};

mod common;
use common::{context, scene};

fn prepared(rel: &str) -> Option<(Scene, Prepared)> {
    let s = scene(rel)?;
    let prepared = s.prepare().unwrap();
    Some((s, prepared))
}

/// The adapter and the teapot, or `None` (the test skips) without either.
fn teapot() -> Option<(Arc<GpuContext>, Scene, Prepared)> {
    let ctx = context()?;
    let (scene, p) = prepared("teapot_ct/slices")?;
    Some((ctx, scene, p))
}

fn renderer(ctx: &Arc<GpuContext>, p: &Prepared, filter: Filter, specialise: bool) -> GpuRenderer {
    let options = GpuOptions {
        filter,
        specialise: Some(specialise),
        ..Default::default()
    };
    GpuRenderer::with_options(ctx.clone(), &p.volume, p.window, options).unwrap()
}

#[test]
fn specialised_pipelines_match_the_generic_one() {
    let Some((ctx, scene, p)) = teapot() else {
        return;
    };
    let generic = renderer(&ctx, &p, Filter::Exact, false);
    let special = renderer(&ctx, &p, Filter::Exact, true);
    assert!(!generic.specialises() && special.specialises());
    let cases: [(&str, u32, bool, OpticalModel); 8] = [
        ("uniform", 1, true, OpticalModel::EmissionAbsorption),
        ("uniform+noskip", 1, false, OpticalModel::EmissionAbsorption),
        (
            "adaptive+grouped",
            1,
            true,
            OpticalModel::EmissionAbsorption,
        ),
        (
            "threshold+grouped",
            1,
            false,
            OpticalModel::EmissionAbsorption,
        ),
        ("jitter", 2, true, OpticalModel::EmissionAbsorption),
        ("mc", 2, false, OpticalModel::EmissionAbsorption),
        ("uniform", 1, false, OpticalModel::EmissionOnly),
        ("uniform", 1, true, OpticalModel::AbsorptionOnly),
    ];
    for (spec, spp, shading, optical) in cases {
        let mut params = RenderParams {
            width: 64,
            height: 64,
            seed: 3,
            spp,
            shading,
            optical,
            ..RenderParams::default()
        };
        MethodSpec::parse(spec).unwrap().apply(&mut params);
        let (a, sa) = generic.render(&p.tf, &scene.camera, &params).unwrap();
        let (b, sb) = special.render(&p.tf, &scene.camera, &params).unwrap();
        let psnr = voxcast::metrics::psnr(&a, &b).unwrap();
        eprintln!("{spec} shading {shading} {optical:?}: PSNR {psnr:.1} dB");
        assert!(psnr >= 80.0, "{spec}: specialised PSNR {psnr:.2} dB < 80");
        assert_eq!(sa.samples, sb.samples, "{spec}: sample counts differ");
        assert_eq!(sa.interpolations, sb.interpolations, "{spec}");
        let bg = a.pixels[0];
        let lit = a
            .pixels
            .iter()
            .filter(|px| (0..4).any(|c| (px[c] - bg[c]).abs() > 0.05));
        assert!(
            lit.count() > 64 * 64 / 50,
            "{spec} {optical:?}: empty image"
        );
    }
}

#[test]
fn hardware_filter_is_close_to_exact() {
    let Some((ctx, scene, p)) = teapot() else {
        return;
    };
    let exact = renderer(&ctx, &p, Filter::Exact, false);
    let hw = renderer(&ctx, &p, Filter::Hardware, false);
    assert_eq!(hw.filter(), Filter::Hardware);
    for shading in [false, true] {
        let params = RenderParams {
            width: 96,
            height: 96,
            shading,
            jitter: false,
            ..RenderParams::default()
        };
        let (a, sa) = exact.render(&p.tf, &scene.camera, &params).unwrap();
        let (b, sb) = hw.render(&p.tf, &scene.camera, &params).unwrap();
        let psnr = voxcast::metrics::psnr(&a, &b).unwrap();
        eprintln!("hardware filter, shading {shading}: PSNR {psnr:.1} dB against exact");
        assert!(psnr >= 40.0, "hardware filter: PSNR {psnr:.2} dB < 40");
        let (x, y) = (sa.samples as f64, sb.samples as f64);
        assert!((x - y).abs() <= 0.01 * x, "samples {x} vs {y}");
    }
    // An f32 texture is filtered only where the device offers it; else the
    // exact path is used.
    if let Some((scene, cloud)) = prepared("cloud_vdb/cloud.vdb") {
        let r = renderer(&ctx, &cloud, Filter::Hardware, false);
        assert_eq!(r.texture_format(), "r32float");
        if !ctx.filters_f32() {
            assert_eq!(r.filter(), Filter::Exact);
            return;
        }
        assert_eq!(r.filter(), Filter::Hardware);
        let exact = renderer(&ctx, &cloud, Filter::Exact, false);
        let params = RenderParams {
            width: 96,
            height: 96,
            jitter: false,
            ..RenderParams::default()
        };
        let (a, _) = exact.render(&cloud.tf, &scene.camera, &params).unwrap();
        let (b, _) = r.render(&cloud.tf, &scene.camera, &params).unwrap();
        let psnr = voxcast::metrics::psnr(&a, &b).unwrap();
        eprintln!("hardware filter on f32: PSNR {psnr:.1} dB against exact");
        assert!(psnr >= 40.0, "f32 hardware filter: PSNR {psnr:.2} dB < 40");
    }
}

#[test]
fn timestamps_time_the_passes_alone() {
    let Some((ctx, scene, p)) = teapot() else {
        return;
    };
    let r = renderer(&ctx, &p, Filter::Exact, false);
    assert!(r.setup_seconds() > 0.0);
    let params = RenderParams {
        width: 64,
        height: 64,
        ..RenderParams::default()
    };
    let (_, st) = r.render(&p.tf, &scene.camera, &params).unwrap();
    match st.device_seconds {
        Some(d) => {
            assert!(ctx.has_timestamps());
            assert!(
                d > 0.0 && d <= st.seconds,
                "device {d} s, wall {} s",
                st.seconds
            );
        }
        None => eprintln!("no timestamp queries on {}", ctx.info()),
    }
}

#[test]
fn workgroup_sizes_parse() {
    assert_eq!(parse_workgroup("16x8"), Some([16, 8]));
    assert_eq!(parse_workgroup(" 8X8 "), Some([8, 8]));
    assert_eq!(parse_workgroup("16x16"), Some([16, 16]));
    assert_eq!(parse_workgroup("2x2"), None, "fewer than 8 invocations");
    assert_eq!(parse_workgroup("32x16"), None, "more than 256");
    assert_eq!(parse_workgroup("64x1"), None);
    assert_eq!(parse_workgroup("8"), None);
    assert_eq!(parse_workgroup("ax8"), None);
}
