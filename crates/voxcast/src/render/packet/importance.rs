//! `importance` in the packets: each lane walks its blocks in scalar code
//! (once per block, for the block's pdf level and the transmittance
//! estimate), as [`crate::render::stochastic::systematic`] does, and hands
//! the vector loop the stretch, spacing and table of its level.

use super::{Lane, Packets, Setup};
use crate::render::march::BlockWalker;
use crate::render::stats::RenderStats;
use crate::render::stochastic::{PdfBlock, BETA, MAX_LEVEL, NO_MASS};
use crate::volume::Voxel;
use glam::Vec3;

/// `importance` in packets: each lane walks its blocks (scalar, once per
/// block) for the stretch, level and spacing of its pdf, as
/// [`super::stochastic::systematic`] does, and marches the stretch in the
/// vector loop with its level's step.
pub(in crate::render) struct Imp<'a> {
    pub pdf: &'a [PdfBlock],
    /// Per level, the spacing (world units).
    pub steps: &'a [f32],
    /// The levels' premultiplied tables, one after the other
    /// (`LUT_SIZE` rows each).
    pub tables: &'a [[f32; 4]],
}

/// One `importance` lane's walk: its blocks, the optical depth of the
/// blocks' mean extinction so far, and its pdf offset for the first stretch.
pub(super) struct ImpLane {
    pub(super) walker: BlockWalker,
    pub(super) tau: f32,
    /// The CDF offset ξ before the first stretch; NaN once the walk started.
    pub(super) xi: f32,
}

impl Imp<'_> {
    /// Moves lane `l` on from position `t` (spacing `s`, its stretch
    /// ending at `tb`) to its next sample past the stretch, as
    /// `systematic` carries the CDF from piece to piece: `(t, s, tb,
    /// level)`, or `None` when the walk has ended.
    pub(super) fn next(
        &self,
        l: &mut ImpLane,
        t: f32,
        s: f32,
        tb: f32,
    ) -> Option<(f32, f32, f32, usize)> {
        let beta = BETA * std::f32::consts::LOG2_E;
        let mut ahead = if l.xi.is_nan() { (t - tb) / s } else { l.xi };
        l.xi = f32::NAN;
        for (ta, tb, b) in l.walker.by_ref() {
            let blk = self.pdf[b];
            let j = if blk.level < 0.0 {
                NO_MASS
            } else {
                (blk.level + beta * l.tau).min(MAX_LEVEL as f32) as u8
            };
            l.tau += blk.sigma_mean * (tb - ta);
            if j == NO_MASS {
                continue;
            }
            let s = self.steps[j as usize];
            let t = ta + ahead * s;
            if t < tb {
                return Some((t, s, tb, j as usize));
            }
            ahead = (t - tb) / s;
        }
        None
    }
}

impl<T: Voxel, R: super::Runs<T>> Packets<'_, T, R> {
    /// Sets up an `importance` ray as [`super::trace::trace`] and
    /// `Importance::march` do: the lane (no fixed-step samples) and its
    /// block walk.
    pub(super) fn imp_lane(
        &self,
        ray: (Vec3, Vec3),
        limit: f32,
        pixel: (u32, u32),
        pass: u32,
        stats: &mut RenderStats,
    ) -> Option<(Lane, ImpLane)> {
        let f = self.f;
        let Setup {
            o,
            d,
            t_in,
            t_out,
            walk,
        } = self.setup(ray, limit, stats)?;
        let walker = BlockWalker::new(o, d, walk.0, walk.1, f.block_size, f.block_counts).staying();
        let xi = crate::render::rng::pixel_sequence(f.seed, pixel.0, pixel.1, pass);
        // No jitter offset: the stretches end at the exit.
        let lane = Lane::walking(o, d, -ray.1, t_in, t_out);
        Some((
            lane,
            ImpLane {
                walker,
                tau: 0.0,
                xi,
            },
        ))
    }
}
