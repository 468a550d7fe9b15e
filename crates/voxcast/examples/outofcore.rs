//! Out-of-core against in-core on one volume, warm: the same frame rendered
//! by the in-core `uniform` ray caster and by the out-of-core renderer
//! (chunks of 64³ in memory, the cache warm after a first frame), with the
//! time ratio and the PSNR between the two images.
//!
//! cargo run --release --example outofcore -- ../shared/data/teapot_ct/slices [512] [budget] [tf]

use std::sync::atomic::AtomicBool;
use std::time::Instant;
use voxcast::camera::CameraParams;
use voxcast::render::outofcore::{parse_bytes, OutOfCore, OutOfCoreParams};
use voxcast::render::{RenderParams, Renderer};
use voxcast::transfer::TransferFunction;
use voxcast::volume::MemorySource;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args.first().map(String::as_str).unwrap_or("builtin:demo");
    let size: u32 = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(512);
    let budget = args
        .get(2)
        .map(|s| parse_bytes(s))
        .transpose()?
        .unwrap_or(1 << 30);
    let vol = match path.strip_prefix("builtin:") {
        Some(n) => voxcast::builtin::open(n)?,
        None => voxcast::io::open(path.as_ref(), &Default::default())?,
    };
    let tf = match args.get(3) {
        Some(name) => TransferFunction::resolve(name, &vol)?,
        None => TransferFunction::auto(&vol),
    };
    let window = tf.window_for(&vol, None);
    let cam = CameraParams {
        azimuth: 30.0,
        elevation: 20.0,
        ..Default::default()
    };
    let p = RenderParams {
        width: size,
        height: size,
        ..Default::default()
    };
    let renderer = Renderer::new(&vol, window)?;
    let src = MemorySource::new(vol.clone(), 0, [64; 3])?;
    let ooc = OutOfCore::new(
        &src,
        OutOfCoreParams {
            budget,
            level: Some(0),
            ..Default::default()
        },
    );
    let no = AtomicBool::new(false);
    let (a, _) = renderer.render(&tf, &cam, &p, &|_, _| {})?;
    let (b, _, first) = ooc.render(&tf, window, &cam, &p, &|_, _| {}, &no)?;
    let reps = 5;
    let scalar = RenderParams {
        simd: voxcast::render::Simd::Scalar,
        ..p.clone()
    };
    let noskip = RenderParams {
        skip_empty: false,
        ..scalar.clone()
    };
    let (mut t_in, mut t_out, mut t_sc, mut t_ns) =
        (f64::INFINITY, f64::INFINITY, f64::INFINITY, f64::INFINITY);
    for _ in 0..reps {
        let t = Instant::now();
        renderer.render(&tf, &cam, &scalar, &|_, _| {})?;
        t_sc = t_sc.min(t.elapsed().as_secs_f64());
        let t = Instant::now();
        renderer.render(&tf, &cam, &noskip, &|_, _| {})?;
        t_ns = t_ns.min(t.elapsed().as_secs_f64());
        let t = Instant::now();
        renderer.render(&tf, &cam, &p, &|_, _| {})?;
        t_in = t_in.min(t.elapsed().as_secs_f64());
        let t = Instant::now();
        ooc.render(&tf, window, &cam, &p, &|_, _| {}, &no)?;
        t_out = t_out.min(t.elapsed().as_secs_f64());
    }
    let d = vol.dims();
    println!(
        "{path} {}×{}×{} {}, {size}², uniform step 0.5, chunks 64³",
        d[0],
        d[1],
        d[2],
        vol.scalar_type()
    );
    println!(
        "first out-of-core frame: {} of {} bricks marched, {} empty; cache {} misses",
        first.marched, first.bricks, first.empty, first.cache.misses
    );
    println!(
        "best of {reps}: in-core {:.1} ms, out-of-core (warm) {:.1} ms: {:.2}×; PSNR {:.1} dB",
        t_in * 1e3,
        t_out * 1e3,
        t_out / t_in,
        voxcast::metrics::psnr(&a, &b)?
    );
    println!(
        "in-core scalar loop {:.1} ms, scalar without empty-space skipping {:.1} ms",
        t_sc * 1e3,
        t_ns * 1e3
    );
    Ok(())
}
