//! `importance` in the packets: the lanes walk their blocks in lock-step
//! in vector registers ([`VImp`]: the DDA of [`VBlocks`], the block's pdf
//! level and the transmittance estimate, once per block), as
//! [`crate::render::stochastic::systematic`] does ray by ray, and hand
//! the vector loop each stretch's spacing, end and level table.

#[cfg(packets)]
use super::simd::Simd;
#[cfg(packets)]
use super::vwalk::{LaneWalk, Rays, VBlocks};
use super::{Lane, Packets, Setup, State, LANES};
use crate::render::march::BlockWalker;
use crate::render::stats::RenderStats;
use crate::render::stochastic::{PdfBlock, BETA, MAX_LEVEL};
use crate::transfer::LUT_SIZE;
use crate::volume::Voxel;
use glam::Vec3;

/// `importance` in packets: the pdf per block and its levels' spacings
/// and tables, which [`VImp`] walks.
pub(in crate::render) struct Imp<'a> {
    pub pdf: &'a [PdfBlock],
    /// Per level, the spacing (world units).
    pub steps: &'a [f32],
    /// The levels' premultiplied tables, one after the other
    /// (`LUT_SIZE` rows each).
    pub tables: &'a [[f32; 4]],
}

/// One `importance` lane's walk as set up: its blocks and its pdf offset
/// ξ for the first stretch.
pub(super) struct ImpLane {
    pub(super) walker: BlockWalker,
    pub(super) xi: f32,
}

/// `importance`'s lanes in the vector loop: where each samples next,
/// its spacing, the end of its stretch and the row offset of its level's
/// table (in floats).
#[cfg(packets)]
pub(super) struct ImpState<S: Simd> {
    pub t: S::F,
    pub s: S::F,
    pub tb: S::F,
    pub off: S::I,
}

#[cfg(packets)]
impl<S: Simd> ImpState<S> {
    /// No lane walking (a loop without `importance`).
    #[inline(always)]
    pub unsafe fn idle() -> Self {
        ImpState {
            t: S::splat(0.0),
            s: S::splat(1.0),
            tb: S::splat(0.0),
            off: S::splat_i(0),
        }
    }
}

/// The `importance` lanes' walks in vector registers: their blocks, and
/// the optical depth of the blocks' mean extinction so far.
#[cfg(packets)]
pub(super) struct VImp<'a, S: Simd> {
    ip: &'a Imp<'a>,
    w: VBlocks<S>,
    tau: S::F,
}

#[cfg(packets)]
impl<'a, S: Simd> VImp<'a, S> {
    /// The walks of `st.imp`'s lanes on the rays `o + d·t` (`inv_d =
    /// 1/d`; `rays.t0` unused), and the lanes' state before their first
    /// stretch: `(t − tb)/s` is each lane's ξ, the CDF offset
    /// [`VImp::next`] carries.
    ///
    /// # Safety
    /// The width's instructions.
    #[inline(always)]
    pub unsafe fn new(
        ip: &'a Imp<'a>,
        st: &State<'_>,
        counts: [usize; 3],
        size: usize,
        rays: &Rays<S>,
    ) -> (Self, ImpState<S>) {
        let mut lanes: [Option<LaneWalk>; LANES] = [None; LANES];
        let mut xi = S::Af::default();
        for (i, l) in st.imp.iter().enumerate().take(S::N) {
            if let Some(l) = l {
                lanes[i] = Some(l.walker.state());
                xi[i] = l.xi;
            }
        }
        let w = VBlocks::new(&lanes, counts, size, rays);
        let is = ImpState {
            t: S::load(xi),
            ..ImpState::idle()
        };
        let tau = S::splat(0.0);
        (VImp { ip, w, tau }, is)
    }

    /// The lanes of `need`, past their stretch (each at `t` with spacing
    /// `s`, the stretch ending at `tb`), walk on to their next sample, as
    /// `systematic` carries the CDF from piece to piece: block by block,
    /// each block's level `min(level + β·log₂e·τ, MAX_LEVEL)` (none where
    /// it has no mass), `τ` growing by its mean extinction times the
    /// length crossed, until the CDF offset falls inside a block. Returns
    /// the lanes whose walk ended.
    ///
    /// # Safety
    /// The width's instructions; `need` only lanes with a walk.
    #[inline(always)]
    pub unsafe fn next(&mut self, need: S::M, is: &mut ImpState<S>) -> S::M {
        let zero = S::splat(0.0);
        let beta = S::splat(BETA * std::f32::consts::LOG2_E);
        let top = S::splat(MAX_LEVEL as f32);
        let pdf = self.ip.pdf.as_ptr() as *const f32;
        // The CDF offset: how many spacings past the stretch's end.
        let mut ahead = (is.t - is.tb) / is.s;
        let mut m = need;
        let mut ended = S::from_bits(0);
        let mut j = S::splat_i(0);
        loop {
            let over = S::and(m, S::ge(self.w.t, self.w.t_out));
            ended = S::or(ended, over);
            m = S::but(m, over);
            if S::bits(m) == 0 {
                break;
            }
            let (ta, tb, b, _) = self.w.step(m);
            // `PdfBlock` is two floats: level, mean extinction.
            let b2 = b + b;
            let level = S::gather_f::<4>(pdf, b2);
            let sigma = S::gather_f::<4>(pdf.add(1), b2);
            // `.min(MAX_LEVEL) as u8`: capped as a float (a large value
            // would not convert; `min` gives `top` for a NaN), then at 0
            // (the lanes without mass, whose level is negative, still
            // gather a step).
            let x = S::min(level + beta * self.tau, top);
            let jb = S::max_i(S::to_i(x), S::splat_i(0));
            self.tau = S::blend(m, self.tau, self.tau + sigma * (tb - ta));
            let mass = S::but(m, S::lt(level, zero));
            if S::bits(mass) == 0 {
                continue;
            }
            let s = S::gather_f::<4>(self.ip.steps.as_ptr(), jb);
            let t = ta + ahead * s;
            let hit = S::and(mass, S::lt(t, tb));
            is.t = S::blend(hit, is.t, t);
            is.s = S::blend(hit, is.s, s);
            is.tb = S::blend(hit, is.tb, tb);
            j = S::blend_i(hit, j, jb);
            ahead = S::blend(S::but(mass, hit), ahead, (t - tb) / s);
            m = S::but(m, hit);
        }
        let found = S::but(need, ended);
        let off = S::mullo(j, S::splat_i((LUT_SIZE * 4) as i32));
        is.off = S::blend_i(found, is.off, off);
        ended
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
        Some((lane, ImpLane { walker, xi }))
    }
}
