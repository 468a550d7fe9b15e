//! `lod` (S3's decimation, [`crate::render::lod`]) in the packets: the
//! lanes walk their octree leaves (the block grid's blocks) together in
//! vector registers ([`VLod`], the DDA of [`VBlocks`]) and hand the
//! vector loop one run per leaf — every `k`-th point of the uniform grid,
//! `k` the leaf's spacing — as the step-per-block marches' runs go
//! ([`super::vwalk`]). Unlike `adaptive`'s levels, a leaf's spacing
//! depends on the opacity the ray has gathered in front of it, so a leaf
//! is classed only when the lane reaches it, after the samples before it
//! are composited; its first sample then closes the stretch of the
//! pending last sample of the leaf before, as `LodRay::march` does.

use super::simd::Simd;
use super::vwalk::{flush_lanes, run_walks, Rays, VBlocks};
use super::walk::RunRegs;
use super::{Packets, Runs, State};
use crate::volume::Voxel;

/// What the lanes' `lod` walk reads.
#[derive(Clone, Copy)]
pub(in crate::render) struct VLodParams<'a> {
    /// Per leaf, the opacity of its mean density across it (its amount
    /// of cloud, `LodRay::amount`), or where the transfer function makes
    /// it transparent minus its skip distance (≤ −1,
    /// [`super::skip_distances`]; −1 without skipping): one gather per
    /// leaf.
    pub amount: &'a [f32],
    /// The contribution at or above which a leaf is `high`.
    pub threshold: f32,
    /// The spacing classes' steps (world units): high, low, sparse.
    pub steps: [f32; 3],
    /// Skipping the transparent leaves (their samples are not taken).
    pub skip_empty: bool,
    /// Front to back: a leaf is classed by the opacity gathered in front
    /// of it. Back to front has none (`Back::opacity` is 0), and classes
    /// a leaf by its amount alone, as the scalar loop's back-to-front pass
    /// does.
    pub front: bool,
}

/// The `lod` lanes' leaf walks: their blocks ([`VBlocks`]); where their
/// sample grids start, where their pending sample's last stretch ends at
/// the ray's end, where the walk may stop once nothing is pending (past
/// the last leaf that is not transparent), and whether it is over.
pub(super) struct VLod<'a, S: Simd> {
    p: VLodParams<'a>,
    w: VBlocks<S>,
    t0: S::F,
    t_end: S::F,
    t_stop: S::F,
    ended: S::M,
}

impl<'a, S: Simd> VLod<'a, S> {
    /// The walks of the lanes of `st.runs` (each where its `RunWalk` was
    /// set up) on the rays `rays`, over `counts` leaves of `size` cells.
    ///
    /// # Safety
    /// The width's instructions.
    #[inline(always)]
    pub unsafe fn new(
        p: VLodParams<'a>,
        st: &State<'_>,
        counts: [usize; 3],
        size: usize,
        rays: Rays<S>,
    ) -> Self {
        let (w, t_stop, t_end) = run_walks(st, counts, size, &rays);
        VLod {
            p,
            w,
            t0: rays.t0,
            t_stop,
            t_end,
            ended: S::from_bits(0),
        }
    }

    /// The lanes of `need`, past their run, walk on leaf by leaf (`LodRay::
    /// march` operation for operation): each leaf's class from its amount
    /// and the lane's opacity `col[3]` (0 back to front), its first and
    /// end sample on the class's grid; where it has a sample, the pending sample is
    /// composited over its stretch up to it, and the leaf becomes the
    /// lane's run unless skipped. `rr` and `kv` then hold the runs.
    /// Returns the lanes whose walk ended and those that terminated.
    ///
    /// # Safety
    /// The width's instructions; `need` only lanes with a walk.
    #[inline(always)]
    pub unsafe fn next<T: Voxel, R: Runs<T>>(
        &mut self,
        pk: &Packets<'_, T, R>,
        need: S::M,
        rr: &mut RunRegs<S>,
        kv: &mut S::F,
        col: &mut [S::F; 4],
    ) -> (S::M, S::M) {
        let zero = S::splat(0.0);
        let one = S::splat(1.0);
        let none = S::from_bits(0);
        let th = S::splat(self.p.threshold);
        let quarter = S::splat(0.25 * self.p.threshold);
        let [s0, s1, s2] = self.p.steps.map(|s| S::splat(s));
        let amount = self.p.amount.as_ptr();
        let mut m = need;
        let (mut found, mut fin, mut dead) = (none, none, none);
        let (mut n0, mut n1, mut sk, mut c) = (zero, zero, one, zero);
        loop {
            // Walks that are over, or past the last leaf that shows with
            // nothing pending, finish.
            let over = S::and(m, S::or(self.ended, S::ge(self.w.t, self.w.t_out)));
            let idle = S::but(S::and(m, S::ge(self.w.t, self.t_stop)), rr.pend_ok);
            let over = S::or(over, idle);
            if S::bits(over) != 0 {
                self.ended = S::or(self.ended, over);
                fin = S::or(fin, over);
                m = S::but(m, over);
            }
            if S::bits(m) == 0 {
                break;
            }
            let (ta, tb, b, b3) = self.w.step(m);
            let am = S::gather_f::<4>(amount, b);
            let e = S::lt(am, zero);
            // The class: high, low or sparse by the contribution
            // `(1 − A)·amount` (sparse where transparent).
            let wgt = (one - if self.p.front { col[3] } else { zero }) * am;
            let cls = S::blend(S::ge(wgt, quarter), S::splat(2.0), one);
            let cls = S::blend(S::ge(wgt, th), cls, zero);
            let cls = S::blend(e, cls, S::splat(2.0));
            let s = S::blend(S::eq(cls, zero), S::blend(S::eq(cls, one), s2, s1), s0);
            // Samples at t₀ + n·s, n from ⌈(ta − t₀)/s⌉ up to ⌈(tb − t₀)/s⌉.
            let a0 = S::max(S::ceil((ta - self.t0) / s), zero);
            let a1 = S::max(S::ceil((tb - self.t0) / s), zero);
            let has = S::and(m, S::gt(a1, a0));
            if self.p.skip_empty {
                // A transparent leaf with nothing pending, at the centre of
                // a larger empty cube (`amount` is minus its radius): the
                // lane goes past the cube in one move; the leaves it
                // crosses would take no sample and flush nothing.
                let far = S::but(S::and(m, S::lt(am, S::splat(-1.5))), rr.pend_ok);
                if S::bits(far) != 0 {
                    self.w.jump(far, b3, S::to_i(zero - am));
                }
            }
            if S::bits(has) == 0 {
                continue;
            }
            // The pending sample's stretch ends at the leaf's first sample,
            // whether or not the leaf is skipped.
            let d = flush_lanes(pk, has, self.t0 + a0 * s, false, rr, col);
            dead = S::or(dead, d);
            m = S::but(m, d);
            let skip = if self.p.skip_empty { e } else { none };
            let run = S::but(S::but(has, d), skip);
            n0 = S::blend(run, n0, a0);
            n1 = S::blend(run, n1, a1);
            sk = S::blend(run, sk, s);
            c = S::blend(run, c, cls);
            found = S::or(found, run);
            m = S::but(m, run);
        }
        // Finished walks: the pending sample's stretch runs to the exit.
        let mut ended = none;
        if S::bits(fin) != 0 {
            let d = flush_lanes(pk, fin, self.t_end, true, rr, col);
            dead = S::or(dead, d);
            ended = S::but(fin, d);
        }
        rr.pend_ok = S::but(rr.pend_ok, need);
        rr.take(found, kv, n0, n1, sk, c);
        (ended, dead)
    }
}
