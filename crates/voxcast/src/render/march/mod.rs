//! Where samples go along a ray (the marcher; DESIGN.md axis 1).
//!
//! Every marcher walks the ray through the block grid with a 3D DDA
//! ([`BlockWalker`]), which plays the role of Open VKL's interval iterator:
//! it yields the stretch of ray inside each block, so empty-space skipping
//! and per-block step selection live in one place.
//!
//! Sample positions lie on global grids `t₀ + n·s` (`t₀` the ray's entry plus
//! the jitter offset, `s` the block's step), so a sample's position depends
//! only on the block it lies in — never on which blocks before it were
//! skipped. Skipping empty blocks therefore changes the cost, not the
//! picture; and a marcher whose step is forced constant reproduces `uniform`
//! exactly.

mod steps;
mod threshold;

#[cfg(test)]
pub(super) use steps::{classified_level, round_log2};
#[cfg_attr(not(packets), allow(unused_imports))]
pub(super) use steps::{
    exp2i, BlockMax, Classified, Fixed, Level, Midpoint, Next, Pending, RunWalk, Steps, VRule,
};
pub(super) use threshold::{Pick, Threshold};

use glam::Vec3;
use serde::{Deserialize, Serialize};

/// Entry and exit parameters of a ray with an axis-aligned box, or `None`
/// when it misses. `inv_dir` is `1 / dir` per component (±∞ for 0).
#[inline]
pub fn intersect_box(origin: Vec3, inv_dir: Vec3, lo: Vec3, hi: Vec3) -> Option<(f32, f32)> {
    let t0 = (lo - origin) * inv_dir;
    let t1 = (hi - origin) * inv_dir;
    // `min`/`max` ignore a NaN (0·∞ on a slab plane), which keeps that axis
    // from deciding the interval.
    let tmin = t0.min(t1);
    let tmax = t0.max(t1);
    let enter = tmin.x.max(tmin.y).max(tmin.z).max(0.0);
    let exit = tmax.x.min(tmax.y).min(tmax.z);
    (exit > enter).then_some((enter, exit))
}

/// A 3D DDA (Amanatides & Woo 1987) over blocks of `size` cells: yields
/// `(t_enter, t_exit, block_index)` for every block the ray crosses between
/// `t_in` and `t_out`, front to back, with consecutive stretches sharing
/// their boundary value exactly.
///
/// Every crossing is computed from its plane, `(plane − o)·(1/d)` — the
/// form [`intersect_box`] uses — instead of accumulating `t_delta`, so a
/// boundary has the same bits whichever block the walk started in, and the
/// same as the occupied box's face: a walk from the ray's entry and one from
/// the occupied box put every sample in the same block (skipping changes no
/// pixel, even for a sample that lands on a boundary).
pub struct BlockWalker {
    t: f32,
    t_out: f32,
    block: [i64; 3],
    counts: [i64; 3],
    step: [i64; 3],
    t_max: [f32; 3],
    o: [f32; 3],
    inv_d: [f32; 3],
    size: f32,
    /// Stay in the edge block past the grid (see `next`).
    stay: bool,
}

impl BlockWalker {
    /// The ray casters' walk over frame `f`'s blocks of segment `seg`,
    /// from the start of its walk to `end` ([`BlockWalker::staying`]).
    pub(in crate::render) fn of_segment<T>(
        f: &crate::render::ray::Frame<'_, T>,
        seg: &crate::render::ray::Segment,
        end: f32,
    ) -> BlockWalker {
        BlockWalker::new(seg.o, seg.d, seg.walk.0, end, f.block_size, f.block_counts).staying()
    }

    /// A walk that runs on to `t_out` in the edge block when the ray
    /// leaves the block range on one axis but not the sample box (a
    /// one-voxel axis): the ray casters' walks.
    pub fn staying(mut self) -> BlockWalker {
        self.stay = true;
        self
    }

    /// Starts at `t_in` on the ray `o + d·t` (voxel coordinates).
    pub fn new(
        o: Vec3,
        d: Vec3,
        t_in: f32,
        t_out: f32,
        size: usize,
        counts: [usize; 3],
    ) -> BlockWalker {
        let b = size as f32;
        let p = o + d * t_in;
        let mut block = [0i64; 3];
        let mut step = [0i64; 3];
        let mut t_max = [f32::INFINITY; 3];
        let inv_d = [1.0 / d.x, 1.0 / d.y, 1.0 / d.z];
        for a in 0..3 {
            let n = counts[a] as i64;
            let q = p[a] / b;
            // On a boundary, a ray going down belongs to the block below.
            let mut c = if d[a] < 0.0 {
                q.ceil() as i64 - 1
            } else {
                q.floor() as i64
            };
            c = c.clamp(0, n - 1);
            block[a] = c;
            if d[a] > 0.0 {
                step[a] = 1;
            } else if d[a] < 0.0 {
                step[a] = -1;
            }
            t_max[a] = crossing(c, step[a], b, o[a], inv_d[a]);
        }
        BlockWalker {
            t: t_in,
            t_out,
            block,
            counts: counts.map(|c| c as i64),
            step,
            t_max,
            o: o.to_array(),
            inv_d,
            size: b,
            stay: false,
        }
    }
}

impl BlockWalker {
    /// The walk's state: the block it is in (per axis), where it leaves
    /// that block on each axis (∞: never), where it stands, and where it
    /// ends.
    pub fn state(&self) -> ([i64; 3], [f32; 3], f32, f32) {
        (self.block, self.t_max, self.t, self.t_out)
    }
}

/// Where a ray leaves block `c` along one axis going `step` (±1; 0: never):
/// the far plane's `(plane − o)·(1/d)`.
#[inline(always)]
fn crossing(c: i64, step: i64, b: f32, o: f32, inv_d: f32) -> f32 {
    match step {
        1 => ((c + 1) as f32 * b - o) * inv_d,
        -1 => (c as f32 * b - o) * inv_d,
        _ => f32::INFINITY,
    }
}

impl Iterator for BlockWalker {
    type Item = (f32, f32, usize);

    #[inline]
    fn next(&mut self) -> Option<(f32, f32, usize)> {
        if self.t >= self.t_out {
            return None;
        }
        let a = if self.t_max[0] <= self.t_max[1] && self.t_max[0] <= self.t_max[2] {
            0
        } else if self.t_max[1] <= self.t_max[2] {
            1
        } else {
            2
        };
        let t_exit = self.t_max[a].min(self.t_out).max(self.t);
        let [bx, by, bz] = self.block;
        let index = (bx + self.counts[0] * (by + self.counts[1] * bz)) as usize;
        let enter = self.t;
        self.t = t_exit;
        self.block[a] += self.step[a];
        self.t_max[a] = crossing(
            self.block[a],
            self.step[a],
            self.size,
            self.o[a],
            self.inv_d[a],
        );
        if self.block[a] < 0 || self.block[a] >= self.counts[a] {
            // Past the grid's last block on this axis. The ray may still be
            // inside the sample box — a one-voxel axis has a box half a
            // voxel thick on either side of its only slice, beyond the block
            // range — and samples there are clamped into this edge block.
            // The ray casters' walks (`staying`) stay in it, with no more
            // crossings on this axis (ending the walk here lost the far half
            // of a single slice); the others end (the majorant walks of the
            // physically based methods, which the GPU mirrors).
            if self.stay {
                self.block[a] -= self.step[a];
                self.t_max[a] = f32::INFINITY;
            } else {
                self.t = self.t_out;
            }
        }
        Some((enter, t_exit, index))
    }
}

/// Parameters of the S0 adaptive marchers.
///
/// Per block crossed, the frequency is `F = k·|MN|/|MS|` (S0 eqs. 1–6), `M`
/// the eye, `N` the ray's exit, `S` the block's midpoint. For `adaptive-s0`
/// `k` is the largest partial derivative of the normalised field per voxel
/// at `S`, for `adaptive-max` the block's largest, and the step is
/// `step · k_ref / F`. For `adaptive` `k` bounds the change of the
/// classified signal per voxel in the block (see
/// [`crate::render::blocks::BlockGrid::classified_change`]) and the step is
/// `tolerance / F` voxels. Steps are rounded to a power-of-two multiple of
/// `step` and clamped to `[min_step, max_step]` (voxels; rounded to powers
/// of two times `step` too). Blocks that the transfer function makes
/// transparent take `max_step`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[serde(default)]
pub struct AdaptiveParams {
    /// The `k·|MN|/|MS|` at which the base step is used (`adaptive-s0`,
    /// `adaptive-max`).
    pub k_ref: f32,
    /// `adaptive`: the largest change of the classified signal (opacity of
    /// one voxel's length, and colour premultiplied by it) allowed from one
    /// sample to the next; smaller is finer and slower.
    pub tolerance: f32,
    /// Finest step in voxels (default: the base step).
    pub min_step: Option<f32>,
    /// Coarsest step in voxels (default: 4 × the base step).
    pub max_step: Option<f32>,
}

impl Default for AdaptiveParams {
    fn default() -> Self {
        AdaptiveParams {
            k_ref: 0.1,
            tolerance: DEFAULT_TOLERANCE,
            min_step: None,
            max_step: None,
        }
    }
}

/// The default [`AdaptiveParams::tolerance`].
pub const DEFAULT_TOLERANCE: f32 = 0.3;

impl AdaptiveParams {
    /// The range of power-of-two levels `j` (step = base · 2^j) allowed.
    pub fn levels(&self, base: f32) -> (i32, i32) {
        let lvl = |s: f32| (s / base).log2().round().clamp(-6.0, 6.0) as i32;
        let lo = self.min_step.map(lvl).unwrap_or(0);
        let hi = self.max_step.map(lvl).unwrap_or(2);
        (lo.min(hi), hi.max(lo))
    }

    /// Level for frequency `f` within `[lo, hi]`.
    #[inline]
    pub fn level(&self, f: f32, lo: i32, hi: i32) -> i32 {
        if f > 0.0 {
            ((self.k_ref / f).log2().round() as i32).clamp(lo, hi)
        } else {
            hi
        }
    }
}

/// Parameters of the threshold-range marcher (Zeng et al. 2018, S0's
/// baseline): the value of the current sample (normalised, 0…1) falls into
/// one of three ranges split at `bounds`, and the step to the next sample is
/// that range's entry in `steps` (voxels).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[serde(default)]
pub struct ThresholdParams {
    /// Range boundaries `[a, b]`: `[0, a)`, `[a, b)`, `[b, 1]`.
    pub bounds: [f32; 2],
    /// Steps in voxels for the three ranges.
    pub steps: [f32; 3],
}

impl Default for ThresholdParams {
    fn default() -> Self {
        ThresholdParams {
            bounds: [0.1, 0.3],
            steps: [2.0, 1.0, 0.5],
        }
    }
}

impl ThresholdParams {
    /// Index of the range value `v` falls into.
    #[inline(always)]
    pub fn range(&self, v: f32) -> usize {
        if v < self.bounds[0] {
            0
        } else if v < self.bounds[1] {
            1
        } else {
            2
        }
    }
}

/// S0 grouped interpolation: the group size at distance `t` from the eye on
/// a ray leaving the volume at `t_exit` — 1 in the nearest third, 2 in the
/// middle third, 3 in the farthest.
#[inline(always)]
pub fn group_size(t: f32, t_exit: f32) -> u32 {
    if t <= t_exit / 3.0 {
        1
    } else if t <= t_exit * (2.0 / 3.0) {
        2
    } else {
        3
    }
}

/// A uniform random number in [0, 1) from a seed and a pixel (SplitMix64).
#[inline]
pub fn pixel_random(seed: u64, x: u32, y: u32) -> f32 {
    let mut z = seed ^ ((x as u64) << 32 | y as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 40) as f32 / (1u64 << 24) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_hits_and_misses() {
        let inv = |d: Vec3| Vec3::ONE / d;
        let (lo, hi) = (Vec3::ZERO, Vec3::splat(10.0));
        let (a, b) = intersect_box(Vec3::new(5.0, -5.0, 5.0), inv(Vec3::Y), lo, hi).unwrap();
        assert!((a - 5.0).abs() < 1e-6 && (b - 15.0).abs() < 1e-6);
        assert!(intersect_box(Vec3::new(15.0, -5.0, 5.0), inv(Vec3::Y), lo, hi).is_none());
        let (a, _) = intersect_box(Vec3::splat(5.0), inv(Vec3::X), lo, hi).unwrap();
        assert_eq!(a, 0.0);
        assert!(intersect_box(Vec3::new(5.0, -5.0, 5.0), inv(-Vec3::Y), lo, hi).is_none());
    }

    #[test]
    fn walker_visits_the_blocks_in_order_and_covers_the_ray() {
        // 4×3×2 blocks of 8 cells; a diagonal ray through the whole grid.
        let counts = [4, 3, 2];
        let hi = Vec3::new(31.0, 23.0, 15.0);
        for (o, d) in [
            (Vec3::new(-1.0, -1.0, -1.0), Vec3::new(1.0, 0.7, 0.45)),
            (Vec3::new(40.0, 30.0, 20.0), Vec3::new(-1.0, -0.6, -0.5)),
            (Vec3::new(3.0, -5.0, 8.0), Vec3::new(0.0, 1.0, 0.0)),
        ] {
            let (t_in, t_out) = intersect_box(o, Vec3::ONE / d, Vec3::ZERO, hi).unwrap();
            let mut t = t_in;
            let mut n = 0;
            for (a, b, idx) in BlockWalker::new(o, d, t_in, t_out, 8, counts) {
                assert_eq!(a, t, "stretches must be contiguous");
                assert!(b >= a);
                t = b;
                n += 1;
                if b - a < 1e-3 {
                    // Corners crossed at once: a zero-length stretch.
                    continue;
                }
                // The midpoint lies in the block reported.
                let p = o + d * ((a + b) * 0.5);
                let c = [0, 1, 2]
                    .map(|k| ((p[k] / 8.0).floor() as i64).clamp(0, counts[k] as i64 - 1) as usize);
                assert_eq!(idx, c[0] + 4 * (c[1] + 3 * c[2]), "at {p}");
            }
            assert_eq!(t, t_out);
            assert!(n >= 2);
        }
    }

    #[test]
    fn groups_by_thirds() {
        assert_eq!(group_size(1.0, 9.0), 1);
        assert_eq!(group_size(3.0, 9.0), 1);
        assert_eq!(group_size(3.1, 9.0), 2);
        assert_eq!(group_size(6.5, 9.0), 3);
    }

    #[test]
    fn adaptive_levels() {
        let p = AdaptiveParams::default();
        let (lo, hi) = p.levels(0.5);
        assert_eq!((lo, hi), (0, 2));
        assert_eq!(p.level(0.0, lo, hi), 2);
        assert_eq!(p.level(10.0, lo, hi), 0);
        assert_eq!(p.level(0.05, lo, hi), 1);
        let fixed = AdaptiveParams {
            min_step: Some(0.5),
            max_step: Some(0.5),
            ..p
        };
        assert_eq!(fixed.levels(0.5), (0, 0));
    }

    #[test]
    fn jitter_is_uniform_and_deterministic() {
        let mut sum = 0.0;
        for i in 0..10_000 {
            let u = pixel_random(7, i % 100, i / 100);
            assert!((0.0..1.0).contains(&u));
            sum += u as f64;
        }
        assert!((sum / 10_000.0 - 0.5).abs() < 0.01);
        assert_eq!(pixel_random(1, 2, 3), pixel_random(1, 2, 3));
        assert_ne!(pixel_random(1, 2, 3), pixel_random(2, 2, 3));
    }

    /// The block walk's `round(log₂ x)` from the bits is exact (against
    /// f64) over twelve decades, powers of two and the √2 boundaries
    /// included, and agrees with `log2f` + `roundf` away from them.
    #[test]
    fn round_log2_is_log2_rounded() {
        let exact = |y: f32| (y as f64).log2().round() as i32;
        let mut x = 1e-6f32;
        let (mut n, mut same) = (0, 0);
        while x < 1e6 {
            for y in [
                x,
                f32::from_bits(x.to_bits() + 1),
                f32::from_bits(x.to_bits() - 1),
            ] {
                assert_eq!(round_log2(y), exact(y), "x = {y:e}");
                same += (round_log2(y) == y.log2().round() as i32) as usize;
                n += 1;
            }
            x *= 1.000_37;
        }
        for j in -20..20 {
            let p = 2f32.powi(j);
            let r = p * std::f32::consts::SQRT_2;
            for y in [
                p,
                r,
                f32::from_bits(r.to_bits() - 1),
                f32::from_bits(r.to_bits() + 1),
            ] {
                assert_eq!(round_log2(y), exact(y), "x = {y:e}");
            }
        }
        assert!(n > 100_000 && same > n - n / 1000, "{same} of {n}");
        assert!(round_log2(0.0) < -100 && round_log2(f32::INFINITY) > 100);
    }
}
