//! Image error metrics: PSNR and SSIM, computed on display-encoded (sRGB)
//! values in 0…1, as the eye and most tools see an image.

use crate::error::{Error, Result};
use crate::image::Image;
use crate::transfer::linear_to_srgb;

fn check_sizes(a: &Image, b: &Image) -> Result<()> {
    if (a.width, a.height) != (b.width, b.height) {
        return Err(Error::invalid(format!(
            "images differ in size: {}×{} vs {}×{}",
            a.width, a.height, b.width, b.height
        )));
    }
    Ok(())
}

/// Mean squared error over the RGB channels (sRGB-encoded, 0…1).
pub fn mse(a: &Image, b: &Image) -> Result<f64> {
    check_sizes(a, b)?;
    let mut sum = 0.0f64;
    for (p, q) in a.pixels.iter().zip(&b.pixels) {
        for c in 0..3 {
            let d = (linear_to_srgb(p[c]) - linear_to_srgb(q[c])) as f64;
            sum += d * d;
        }
    }
    Ok(sum / (a.pixels.len() * 3).max(1) as f64)
}

/// Peak signal-to-noise ratio in dB (peak 1); `inf` for identical images.
pub fn psnr(a: &Image, b: &Image) -> Result<f64> {
    let m = mse(a, b)?;
    Ok(if m == 0.0 {
        f64::INFINITY
    } else {
        -10.0 * m.log10()
    })
}

/// Structural similarity (Wang et al. 2004) of the luma (Rec. 709 weights of
/// the sRGB-encoded channels), 11×11 Gaussian window with σ = 1.5,
/// K₁ = 0.01, K₂ = 0.03; the mean of the SSIM map (borders clamped).
pub fn ssim(a: &Image, b: &Image) -> Result<f64> {
    check_sizes(a, b)?;
    let (w, h) = (a.width as usize, a.height as usize);
    let luma = |img: &Image| -> Vec<f64> {
        img.pixels
            .iter()
            .map(|p| {
                0.2126 * linear_to_srgb(p[0]) as f64
                    + 0.7152 * linear_to_srgb(p[1]) as f64
                    + 0.0722 * linear_to_srgb(p[2]) as f64
            })
            .collect()
    };
    let x = luma(a);
    let y = luma(b);
    let xx: Vec<f64> = x.iter().map(|v| v * v).collect();
    let yy: Vec<f64> = y.iter().map(|v| v * v).collect();
    let xy: Vec<f64> = x.iter().zip(&y).map(|(a, b)| a * b).collect();
    let [mx, my, sxx, syy, sxy] = [&x, &y, &xx, &yy, &xy].map(|v| blur(v, w, h));
    let (c1, c2) = (0.01f64.powi(2), 0.03f64.powi(2));
    let mut total = 0.0;
    for i in 0..w * h {
        let (ux, uy) = (mx[i], my[i]);
        let vx = sxx[i] - ux * ux;
        let vy = syy[i] - uy * uy;
        let cxy = sxy[i] - ux * uy;
        total +=
            ((2.0 * ux * uy + c1) * (2.0 * cxy + c2)) / ((ux * ux + uy * uy + c1) * (vx + vy + c2));
    }
    Ok(total / (w * h).max(1) as f64)
}

/// Separable Gaussian blur (σ = 1.5, radius 5) with clamped borders.
fn blur(v: &[f64], w: usize, h: usize) -> Vec<f64> {
    const R: isize = 5;
    let mut k = [0.0f64; 11];
    for (i, kv) in k.iter_mut().enumerate() {
        let d = i as f64 - R as f64;
        *kv = (-d * d / (2.0 * 1.5 * 1.5)).exp();
    }
    let s: f64 = k.iter().sum();
    k.iter_mut().for_each(|kv| *kv /= s);
    let mut tmp = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut acc = 0.0;
            for (i, kv) in k.iter().enumerate() {
                let xx = (x as isize + i as isize - R).clamp(0, w as isize - 1) as usize;
                acc += kv * v[y * w + xx];
            }
            tmp[y * w + x] = acc;
        }
    }
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut acc = 0.0;
            for (i, kv) in k.iter().enumerate() {
                let yy = (y as isize + i as isize - R).clamp(0, h as isize - 1) as usize;
                acc += kv * tmp[yy * w + x];
            }
            out[y * w + x] = acc;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise_image(seed: u32, w: u32, h: u32) -> Image {
        let mut img = Image::new(w, h);
        let mut s = seed;
        for p in img.pixels.iter_mut() {
            s = s.wrapping_mul(1664525).wrapping_add(1013904223);
            let v = (s >> 8) as f32 / (1u32 << 24) as f32;
            *p = [v, v * 0.5, 1.0 - v, 1.0];
        }
        img
    }

    #[test]
    fn identical_images() {
        let a = noise_image(1, 32, 24);
        assert_eq!(psnr(&a, &a).unwrap(), f64::INFINITY);
        assert!((ssim(&a, &a).unwrap() - 1.0).abs() < 1e-9);
    }

    #[test]
    fn known_psnr() {
        // Black vs a uniform sRGB value of 0.1 in every channel: MSE 0.01 → 20 dB.
        let a = Image::new(8, 8);
        let mut b = Image::new(8, 8);
        let lin = crate::transfer::srgb_to_linear(0.1);
        b.pixels.iter_mut().for_each(|p| *p = [lin, lin, lin, 1.0]);
        assert!((psnr(&a, &b).unwrap() - 20.0).abs() < 1e-3);
    }

    #[test]
    fn ssim_drops_with_noise_and_rejects_size_mismatch() {
        let a = noise_image(1, 32, 32);
        let b = noise_image(2, 32, 32);
        let s = ssim(&a, &b).unwrap();
        assert!(s < 0.2, "{s}");
        assert!(psnr(&a, &Image::new(4, 4)).is_err());
    }
}
