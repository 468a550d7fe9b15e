//! `voxcast compare`.

use crate::args::CompareArgs;
use anyhow::Result;
use voxcast::{metrics, Image};

pub fn run(a: CompareArgs) -> Result<()> {
    // The library's errors name the file.
    let x = Image::read(&a.a)?;
    let y = Image::read(&a.b)?;
    let psnr = metrics::psnr(&x, &y)?;
    let ssim = metrics::ssim(&x, &y)?;
    if a.json {
        let j = serde_json::json!({
            "psnr_db": if psnr.is_finite() { Some(psnr) } else { None },
            "ssim": ssim,
            "identical": psnr.is_infinite(),
        });
        println!("{}", serde_json::to_string_pretty(&j)?);
    } else if psnr.is_infinite() {
        println!("PSNR inf dB (identical)  SSIM {ssim:.6}");
    } else {
        println!("PSNR {psnr:.3} dB  SSIM {ssim:.6}");
    }
    Ok(())
}
