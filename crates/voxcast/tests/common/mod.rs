//! Helpers shared by the integration tests.

use voxcast::Image;

/// A progress callback that ignores progress.
pub fn no_progress(_: usize, _: usize) {}

/// The largest difference of any channel of any pixel.
pub fn max_diff(a: &Image, b: &Image) -> f32 {
    a.pixels
        .iter()
        .zip(&b.pixels)
        .flat_map(|(p, q)| (0..4).map(move |c| (p[c] - q[c]).abs()))
        .fold(0.0, f32::max)
}
