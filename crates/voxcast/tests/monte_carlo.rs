//! The Monte-Carlo marchers (S1): seeded, progressive, converging to the
//! converged reference at the rate Monte Carlo promises.

mod common;
use common::{max_diff, no_progress};

use voxcast::camera::CameraParams;
use voxcast::render::{Method, RenderParams, Renderer};
use voxcast::transfer::TransferFunction;
use voxcast::{metrics, Image, Volume};

fn scene() -> (Volume, TransferFunction) {
    let vol = voxcast::builtin::open("marschner-lobb").unwrap();
    let tf = TransferFunction {
        color: vec![[0.0, 0.2, 0.5, 1.0], [1.0, 1.0, 0.8, 0.3]],
        opacity: vec![[0.0, 0.0], [0.4, 0.05], [1.0, 0.4]],
        window: None,
    };
    (vol, tf)
}

fn cam() -> CameraParams {
    CameraParams {
        azimuth: 30.0,
        elevation: 25.0,
        ..Default::default()
    }
}

fn draw(r: &Renderer, tf: &TransferFunction, p: &RenderParams) -> Image {
    r.render(tf, &cam(), p, &no_progress).unwrap().0
}

fn params(method: Method, spp: u32, seed: u64) -> RenderParams {
    RenderParams {
        width: 48,
        height: 48,
        method,
        spp,
        seed,
        step: 1.0,
        ert: 1.0,
        shading: false,
        ..Default::default()
    }
}

#[test]
fn same_seed_same_image_other_seed_other_image() {
    let (vol, tf) = scene();
    let s = vol.stats();
    let r = Renderer::new(&vol, [s.min, s.max]).unwrap();
    for m in [
        Method::Jitter,
        Method::Stratified,
        Method::Mc,
        Method::Importance,
    ] {
        let a = draw(&r, &tf, &params(m, 2, 5));
        let b = draw(&r, &tf, &params(m, 2, 5));
        assert_eq!(max_diff(&a, &b), 0.0, "{m:?}");
        let c = draw(&r, &tf, &params(m, 2, 6));
        assert!(max_diff(&a, &c) > 1e-3, "{m:?}: the seed changes nothing");
    }
}

#[test]
fn progressive_mc_converges_at_the_monte_carlo_rate() {
    let (vol, tf) = scene();
    let s = vol.stats();
    let r = Renderer::new(&vol, [s.min, s.max]).unwrap();
    let mut reference = params(Method::Uniform, 1, 0);
    reference.step = 1.0 / 16.0;
    let reference = draw(&r, &tf, &reference);
    for m in [Method::Mc, Method::Stratified, Method::Importance] {
        let psnr: Vec<f64> = [1, 4, 16]
            .iter()
            .map(|&spp| metrics::psnr(&draw(&r, &tf, &params(m, spp, 1)), &reference).unwrap())
            .collect();
        // Variance ∝ 1/spp: +6 dB per ×4 in spp while the noise dominates.
        eprintln!("{m:?}: PSNR at 1/4/16 spp {psnr:?}");
        assert!(psnr[1] - psnr[0] > 4.5, "{m:?}: {psnr:?}");
        assert!(psnr[2] - psnr[1] > 4.0, "{m:?}: {psnr:?}");
    }
}

#[test]
fn spp_is_checked() {
    let mut p = params(Method::Mc, 0, 0);
    assert!(p.validate().unwrap_err().to_string().contains("spp"));
    p.spp = 3;
    assert!(p.validate().is_ok());
}
