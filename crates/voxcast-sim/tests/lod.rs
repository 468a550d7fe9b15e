//! S3's octree + LOD marcher on a particle-system cloud: with every spacing
//! 1 it is `uniform`; skipping empty subtrees changes no pixel; decimation
//! takes fewer samples and stays close to the reference.

// The core's integration-test helpers (no_progress, max_diff), shared
// rather than copied.
#[path = "../../voxcast/tests/common/mod.rs"]
mod common;
use common::{max_diff, no_progress};

use voxcast::camera::CameraParams;
use voxcast::render::lod::LodParams;
use voxcast::render::{Method, Order, RenderParams, RenderStats, Renderer};
use voxcast::transfer::TransferFunction;
use voxcast::{metrics, Image, Volume};
use voxcast_sim::cloud::{CloudOptions, CloudSim, CloudType};

fn cloud() -> Volume {
    let mut s = CloudSim::new(CloudOptions {
        kind: CloudType::Cumulus,
        grid: [120, 120, 30],
        seed: 5,
        frames: 1,
    })
    .unwrap();
    for _ in 0..s.schedule().0 {
        s.step();
    }
    s.density().unwrap()
}

fn draw(r: &Renderer<'_>, p: &RenderParams) -> (Image, RenderStats) {
    let tf = TransferFunction::preset("cloud").unwrap();
    let cam = CameraParams {
        azimuth: 30.0,
        elevation: 35.0,
        zoom: 1.3,
        ..Default::default()
    };
    r.render(&tf, &cam, p, &no_progress).unwrap()
}

fn params(method: Method) -> RenderParams {
    RenderParams {
        width: 96,
        height: 80,
        method,
        ..Default::default()
    }
}

#[test]
fn lod_with_every_spacing_one_is_uniform() {
    let vol = cloud();
    let r = Renderer::new(&vol, [0.0, 1.0]).unwrap();
    for (order, jitter) in [
        (Order::FrontToBack, false),
        (Order::FrontToBack, true),
        (Order::BackToFront, false),
    ] {
        let mut u = params(Method::Uniform);
        u.order = order;
        u.jitter = jitter;
        // `lod`'s leaves are the blocks: `uniform` on the same ones (unset,
        // it may take finer ones on sparse data, with fewer samples).
        u.block_size = Some(8);
        let mut l = u.clone();
        l.method = Method::Lod;
        l.lod = LodParams {
            high: 1,
            low: 1,
            sparse: 1,
            ..Default::default()
        };
        let (a, sa) = draw(&r, &u);
        let (b, sb) = draw(&r, &l);
        assert!(sa.rays_hit > 0 && a.pixels.iter().any(|p| p[3] > 0.5));
        let psnr = metrics::psnr(&a, &b).unwrap();
        assert!(
            psnr >= 60.0,
            "{order:?} jitter {jitter}: {psnr} dB, max diff {}",
            max_diff(&a, &b)
        );
        assert_eq!(sa.samples, sb.samples, "the same samples are taken");
    }
}

/// Skipping the transparent leaves saves samples at nearly the same
/// quality: past a skipped stretch the march starts again on the base
/// grid, where without skipping the sparse spacing strides through it, so
/// the samples after it lie elsewhere (the two pictures are about 33 dB
/// apart on this small cloud at 96×80, the size of `lod`'s own error
/// here), and against the reference skipping measured 0.6–1.0 dB lower
/// (35.0 against 35.6–36.1 dB).
#[test]
fn skipping_empty_leaves_saves_samples_at_nearly_the_same_quality() {
    let vol = cloud();
    let r = Renderer::new(&vol, [0.0, 1.0]).unwrap();
    let mut reference = params(Method::Uniform);
    reference.step = 1.0 / 16.0;
    reference.ert = 1.0;
    reference.skip_empty = false;
    let (ref_img, _) = draw(&r, &reference);
    for jitter in [false, true] {
        let mut skip = params(Method::Lod);
        skip.jitter = jitter;
        let mut noskip = skip.clone();
        noskip.skip_empty = false;
        let (a, sa) = draw(&r, &skip);
        let (b, sb) = draw(&r, &noskip);
        let (pa, pb) = (
            metrics::psnr(&ref_img, &a).unwrap(),
            metrics::psnr(&ref_img, &b).unwrap(),
        );
        assert!(
            pa >= pb - 1.5,
            "jitter {jitter}: skipping {pa} dB, not {pb} dB"
        );
        assert!(
            sa.samples * 2 < sb.samples,
            "skipping should save samples: {} vs {}",
            sa.samples,
            sb.samples
        );
    }
}

#[test]
fn decimation_takes_fewer_samples_and_stays_close() {
    let vol = cloud();
    let r = Renderer::new(&vol, [0.0, 1.0]).unwrap();
    // The bench's reference: uniform, a sixteenth of a voxel, no ERT.
    let mut reference = params(Method::Uniform);
    reference.step = 1.0 / 16.0;
    reference.ert = 1.0;
    reference.skip_empty = false;
    let (ref_img, _) = draw(&r, &reference);
    let (u, su) = draw(&r, &params(Method::Uniform));
    let pu = metrics::psnr(&ref_img, &u).unwrap();
    // Gentle spacings (1, 2, 4): fewer samples at ≥ 38 dB.
    let mut gentle = params(Method::Lod);
    gentle.lod = LodParams {
        high: 1,
        low: 2,
        sparse: 4,
        ..Default::default()
    };
    let (g, sg) = draw(&r, &gentle);
    let pg = metrics::psnr(&ref_img, &g).unwrap();
    assert!(
        sg.samples * 10 < su.samples * 8,
        "lod 1,2,4: {} samples vs uniform {}",
        sg.samples,
        su.samples
    );
    assert!(pg >= 38.0, "lod 1,2,4: {pg} dB (uniform {pu} dB)");
    // The defaults (3, 4, 8) decimate harder: under half the samples; on
    // this small cloud seen at 96×80 the error is larger than at 512² on
    // the 400×400×60 one (≥ 41 dB there, docs/clouds.md).
    let (l, sl) = draw(&r, &params(Method::Lod));
    let pl = metrics::psnr(&ref_img, &l).unwrap();
    assert!(
        sl.samples * 2 < su.samples,
        "{} vs {}",
        sl.samples,
        su.samples
    );
    assert!(
        pl >= 32.0 && pl < pg,
        "lod defaults: {pl} dB, gentle {pg} dB"
    );
}

#[test]
fn bad_lod_parameters_are_refused() {
    let mut p = params(Method::Lod);
    p.lod.low = 0;
    assert!(p.validate().unwrap_err().to_string().contains("lod.low"));
    p.lod.low = 2;
    p.lod.threshold = 1.5;
    assert!(p
        .validate()
        .unwrap_err()
        .to_string()
        .contains("lod.threshold"));
}
