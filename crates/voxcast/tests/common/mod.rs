//! Helpers shared by the integration tests.

use voxcast::render::Simd;
use voxcast::Image;

/// A progress callback that ignores progress.
#[allow(dead_code)] // used by some of the test crates that include this file
pub fn no_progress(_: usize, _: usize) {}

/// The largest difference of any channel of any pixel.
pub fn max_diff(a: &Image, b: &Image) -> f32 {
    a.pixels
        .iter()
        .zip(&b.pixels)
        .flat_map(|(p, q)| (0..4).map(move |c| (p[c] - q[c]).abs()))
        .fold(0.0, f32::max)
}

/// The packet levels this CPU runs (`Simd::Auto` picks the best; `Avx2`
/// holds it to AVX2 with gathers, `Avx2Loads` with scalar loads, and
/// `Avx512`/`Avx512Loads` the same at AVX-512), each named once; none
/// without AVX2.
#[allow(dead_code)] // used by some of the test crates that include this file
pub fn simd_levels() -> Vec<(Simd, &'static str)> {
    let mut out: Vec<(Simd, &'static str)> = Vec::new();
    for simd in [
        Simd::Auto,
        Simd::Avx2,
        Simd::Avx2Loads,
        Simd::Avx512,
        Simd::Avx512Loads,
    ] {
        if let Some(l) = voxcast::render::simd_level(simd) {
            if out.iter().all(|(_, n)| *n != l.name()) {
                out.push((simd, l.name()));
            }
        }
    }
    out
}
