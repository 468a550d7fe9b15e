//! Counts of the work a render did, summed per tile without locks.

use serde::{Deserialize, Serialize};

/// What a render cost. `interpolations` counts trilinear reconstructions of
/// the value (what S0 counts); gradient lookups are counted apart.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RenderStats {
    /// Rays cast (one per pixel).
    pub rays: u64,
    /// Rays that met the volume's box.
    pub rays_hit: u64,
    /// Sample positions visited along rays.
    pub samples: u64,
    /// Trilinear interpolations of the value.
    pub interpolations: u64,
    /// Trilinear interpolations made for gradients (shading).
    pub gradient_interpolations: u64,
    /// Rays stopped by early ray termination.
    pub early_terminated: u64,
    /// Paths of the physically based methods ended by their collision
    /// budget (`render::path::MAX_PATH_COLLISIONS`); 0 in any sane scene.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub capped_paths: u64,
    /// Wall-clock seconds of the render.
    pub seconds: f64,
    /// Seconds the GPU spent in the render's compute passes, read from
    /// timestamp queries (upload, read-back and the driver's overhead
    /// excluded); `None` on the CPU or where the adapter has no timestamps.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub device_seconds: Option<f64>,
    /// The SIMD level the CPU ray loop ran at (`avx2`, `avx512`); `None`
    /// where the scalar loop ran (the method or the CPU has no packets,
    /// `--simd scalar`) and on the GPU.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub simd: Option<super::packet::Level>,
    /// Where empty-space skipping was asked for but left out because the
    /// transfer function hides too few blocks for it to pay
    /// ([`SKIP_PAYS`](super::SKIP_PAYS)): the share of blocks it hides.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub skipping_left_out: Option<f32>,
    /// The edge, in cells, of the blocks the CPU marchers skipped with
    /// ([`Renderer::block_size_for`](super::Renderer::block_size_for));
    /// 0 where none were (the GPU, out of core, `single-scatter` and `path`).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub block_size: u32,
}

/// Whether `n` is its type's default (a serde `skip_serializing_if`
/// helper, shared with the bench's report).
pub fn is_zero<T: Default + PartialEq>(n: &T) -> bool {
    *n == T::default()
}

impl RenderStats {
    /// Adds the counts of `o` (not the time).
    pub fn add(&mut self, o: &RenderStats) {
        self.rays += o.rays;
        self.rays_hit += o.rays_hit;
        self.samples += o.samples;
        self.interpolations += o.interpolations;
        self.gradient_interpolations += o.gradient_interpolations;
        self.early_terminated += o.early_terminated;
        self.capped_paths += o.capped_paths;
        self.simd = self.simd.or(o.simd);
        self.skipping_left_out = self.skipping_left_out.or(o.skipping_left_out);
        self.block_size = self.block_size.max(o.block_size);
    }

    /// Samples per second of wall time.
    pub fn samples_per_second(&self) -> f64 {
        if self.seconds > 0.0 {
            self.samples as f64 / self.seconds
        } else {
            0.0
        }
    }
}
