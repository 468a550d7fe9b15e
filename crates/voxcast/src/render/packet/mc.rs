//! `mc` (S1 eqs. 5–6) in the packets: each lane draws the `n = ⌈L/s⌉`
//! sorted uniform positions of its whole ray from its pixel's random
//! stream, as `stochastic::UniformMc` does ray by ray — the same
//! generator ([`SortedUniforms`], drawn lane by lane in scalar code: an
//! `ln` a position), the same positions, the same samples dropped where
//! their position lies in an empty block — and `stratified`'s vector loop
//! (`super::stratified`) samples them, each over the stretch `L/n` it
//! stands for. The positions come one after the other from the
//! generator, so a lane cannot jump an empty stretch; it draws and drops
//! its positions there, as the scalar march does.

use super::super::rng::Rng;
use super::super::stochastic::SortedUniforms;
use super::{Lane, Packets, Runs, Setup, LANES};
use crate::render::stats::RenderStats;
use crate::volume::Voxel;
use glam::Vec3;
use std::ops::IndexMut;

impl<T: Voxel, R: Runs<T>> Packets<'_, T, R> {
    /// Sets up an `mc` ray as [`crate::render::trace::trace`] does: the
    /// lane (`t0` its entry, `t_end` its exit) and its pixel's random
    /// stream for pass `pass`.
    pub(super) fn mc_lane(
        &self,
        ray: (Vec3, Vec3),
        limit: f32,
        pixel: (u32, u32),
        pass: u32,
        stats: &mut RenderStats,
    ) -> Option<(Lane, u64)> {
        let Setup {
            o, d, t_in, t_out, ..
        } = self.setup(ray, limit, stats)?;
        let lane = Lane::walking(o, d, -ray.1, t_in, t_out);
        Some((lane, Rng::pixel_stream(pixel.0, pixel.1, pass)))
    }
}

/// The lanes' `mc` positions: each lane's generator, and which lanes have
/// positions left.
pub(super) struct Draws {
    draws: [Option<SortedUniforms>; LANES],
    /// Lanes with positions left (bits).
    going: u32,
}

impl Draws {
    /// The generators of the first `width` lanes of `lanes`, seeded with
    /// `seed` on their pixels' streams `keys`, `n = ⌈L/step⌉` positions
    /// each; and per lane the stretch `L/n` each position stands for
    /// (`UniformMc::march`, S1 eq. 6: n positions of pdf 1/L weigh L/n).
    pub fn new(
        lanes: &[Option<Lane>],
        width: usize,
        keys: &[u64],
        seed: u64,
        step: f32,
    ) -> (Draws, [f32; LANES]) {
        let mut out = Draws {
            draws: std::array::from_fn(|_| None),
            going: 0,
        };
        let mut w = [0.0f32; LANES];
        for (i, l) in lanes.iter().enumerate().take(width) {
            let Some(l) = l else { continue };
            let len = l.t_end - l.t0;
            let count = (len / step).ceil().max(1.0) as u32;
            w[i] = len / count as f32;
            out.draws[i] = Some(SortedUniforms::new(Rng::new(seed, keys[i]), count));
            out.going |= 1 << i;
        }
        (out, w)
    }

    /// The next position (in `[0, 1)` of the ray) of each lane of `live`
    /// (bits, within the first `width`) that has one, into `u`; the lanes
    /// whose positions are all drawn, or that are not live, drop out.
    /// Returns the lanes that drew one.
    #[inline(always)]
    pub fn next<U: IndexMut<usize, Output = f32>>(
        &mut self,
        live: u32,
        u: &mut U,
        width: usize,
    ) -> u32 {
        self.going &= live;
        for (i, g) in self.draws.iter_mut().enumerate().take(width) {
            if self.going & (1 << i) == 0 {
                continue;
            }
            match g.as_mut().and_then(Iterator::next) {
                Some(x) => u[i] = x,
                None => self.going &= !(1 << i),
            }
        }
        self.going
    }
}
