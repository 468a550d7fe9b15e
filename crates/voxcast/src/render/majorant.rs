//! Majorants for free-flight sampling: the per-block maximum extinction
//! (pbrt-v4's `MajorantGrid`, walked by a 3D DDA as its `SampleT_maj` does),
//! or one global maximum. Delta tracking and ratio tracking draw tentative
//! collisions at the rate `σ_maj` of the segment they are in; a tight
//! majorant wastes fewer of them where the medium is thin.
//!
//! The walk knows nothing of what the integrator does with a collision: it
//! calls back at each tentative collision with its `t` and `σ_maj`, and
//! stops when the callback says so.

use super::march::BlockWalker;
use super::medium::MajorantKind;
use super::rng::Rng;
use super::BlockGrid;
use glam::Vec3;

/// Majorant extinction per block (world units⁻¹), or one for all.
pub struct Majorant {
    pub kind: MajorantKind,
    pub size: usize,
    pub counts: [usize; 3],
    pub sigma: Vec<f32>,
    pub global: f32,
}

impl Majorant {
    /// From the block grid's value ranges: density is the normalised value
    /// clamped to 0…1, so `σ_maj = scale · clamp(max)` bounds every
    /// trilinear sample in the block (blocks.rs includes the far faces).
    pub fn new(blocks: &BlockGrid, scale: f32, kind: MajorantKind) -> Majorant {
        let sigma: Vec<f32> = blocks
            .range
            .iter()
            .map(|&[_, hi]| scale * hi.clamp(0.0, 1.0))
            .collect();
        let global = sigma.iter().copied().fold(0.0, f32::max);
        Majorant {
            kind,
            size: blocks.size,
            counts: blocks.counts,
            sigma,
            global,
        }
    }

    /// Calls `f(t, σ_maj)` at tentative collisions on `o + d·t` (voxel
    /// coordinates, t in world units) between `t_in` and `t_out`, front to
    /// back, until `f` returns true; returns whether it did (false: the
    /// ray left the medium). Exponential steps restart at each segment's
    /// start with the segment's rate — exact, by memorylessness. `stats`
    /// counts the collisions; the walk stops (returning true) when it
    /// reaches `budget`, so no walk is unbounded.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn walk(
        &self,
        o: Vec3,
        d: Vec3,
        t_in: f32,
        t_out: f32,
        rng: &mut Rng,
        stats: &mut u64,
        budget: u64,
        mut f: impl FnMut(f32, f32, &mut Rng) -> bool,
    ) -> bool {
        let mut segment = |ta: f32, tb: f32, s: f32, rng: &mut Rng| -> bool {
            if s <= 0.0 {
                return false;
            }
            let mut t = ta;
            loop {
                t -= rng.uniform_open0().ln() / s;
                if t >= tb {
                    return false;
                }
                if *stats >= budget {
                    return true;
                }
                *stats += 1;
                if f(t, s, rng) {
                    return true;
                }
            }
        };
        match self.kind {
            MajorantKind::Global => segment(t_in, t_out, self.global, rng),
            MajorantKind::Grid => {
                for (ta, tb, b) in BlockWalker::new(o, d, t_in, t_out, self.size, self.counts) {
                    if segment(ta, tb, self.sigma[b], rng) {
                        return true;
                    }
                }
                false
            }
        }
    }
}
