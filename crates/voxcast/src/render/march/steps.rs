//! Marchers with a step per block: `uniform` and `jitter` (one step
//! everywhere), `adaptive` (the step from the block's bound on the change
//! of the classified signal, with grouped reuse capped by it), S0's
//! `adaptive-s0` (the step from the derivative at the block's midpoint) and
//! `adaptive-max` (from the block's largest derivative).
//!
//! The block walk is an interval iterator in the manner of Open VKL's
//! `vklIterateInterval`: consecutive blocks that are sampled with the same
//! step merge into one interval, so the per-sample loop runs over a whole
//! interval — for `uniform` without skipping, the whole ray — and the cost
//! of a block boundary (the stretch of the last sample, corrected with an
//! `exp`) is paid only where the step changes or a skip begins. Sample
//! positions are `t₀ + n·s`, whatever merged, so the picture is that of the
//! block-by-block march.

use super::BlockWalker;
use crate::render::ray::{Composite, Counters, Frame, Marcher, Sampler, Segment};
use crate::transfer::LUT_SIZE;
use crate::volume::Voxel;
use glam::Vec3;

/// S0's largest group of samples that share one value (grouped reuse):
/// the cap where a rule sets none.
const MAX_GROUP: u32 = 3;

/// How the step level of a block is chosen: `j` in `step·2^j`, and the
/// largest group of samples grouped reuse may share one value in (S0's
/// groups of 1–3 are capped by it; [`MAX_GROUP`] where the rule sets no
/// cap). Asked only for blocks that are not empty: those take the longest
/// step (a `FIXED` rule's one step) and the cap `u32::MAX`, which no block
/// that shows has, so that a grouped run never spans an empty block and a
/// visible one.
pub(in crate::render) trait Level: Sync {
    /// One level everywhere (no per-block choice).
    const FIXED: bool = false;
    fn level<T: Voxel>(
        &self,
        steps: &Steps<Self>,
        f: &Frame<'_, T>,
        seg: &Segment,
        block: (usize, f32, f32),
        n: &mut Counters,
    ) -> (i32, u32)
    where
        Self: Sized;

    /// The rule for the packets' vector walk.
    fn vector(&self) -> VRule<'_> {
        VRule::Scalar
    }
}

/// A [`Level`] rule as the packets' vector walk reads it: `k` per block
/// from a table, or nothing to read (the lanes walk in scalar code).
#[derive(Clone, Copy)]
pub(in crate::render) enum VRule<'a> {
    /// `adaptive-s0`'s gradient at each block's midpoint: a scalar walk.
    Scalar,
    /// [`Fixed`].
    Fixed,
    /// [`BlockMax`]'s table.
    Max(&'a [f32]),
    /// [`Classified`]'s table.
    Classified(&'a [f32]),
}

/// One step everywhere (`uniform`, `jitter`).
pub(in crate::render) struct Fixed;

impl Level for Fixed {
    const FIXED: bool = true;
    fn vector(&self) -> VRule<'_> {
        VRule::Fixed
    }
    #[inline(always)]
    fn level<T: Voxel>(
        &self,
        _: &Steps<Self>,
        _: &Frame<'_, T>,
        _: &Segment,
        _: (usize, f32, f32),
        _: &mut Counters,
    ) -> (i32, u32) {
        (0, MAX_GROUP)
    }
}

/// `adaptive-s0`, S0 eqs. 1–6: `k` the largest partial derivative at the
/// block's midpoint.
pub(in crate::render) struct Midpoint;

impl Level for Midpoint {
    #[inline(always)]
    fn level<T: Voxel>(
        &self,
        st: &Steps<Self>,
        f: &Frame<'_, T>,
        seg: &Segment,
        (_, ta, tb): (usize, f32, f32),
        n: &mut Counters,
    ) -> (i32, u32) {
        let tm = 0.5 * (ta + tb);
        let g = f.grid.gradient(seg.o + seg.d * tm);
        n.interpolations += 6;
        let k = g.x.abs().max(g.y.abs()).max(g.z.abs());
        (st.level_of(k, seg.t_out, tm), MAX_GROUP)
    }
}

/// `adaptive-max`: `k` the block's largest derivative (precomputed).
pub(in crate::render) struct BlockMax<'a>(pub &'a [f32]);

impl Level for BlockMax<'_> {
    fn vector(&self) -> VRule<'_> {
        VRule::Max(self.0)
    }
    #[inline(always)]
    fn level<T: Voxel>(
        &self,
        st: &Steps<Self>,
        _: &Frame<'_, T>,
        seg: &Segment,
        (b, ta, tb): (usize, f32, f32),
        _: &mut Counters,
    ) -> (i32, u32) {
        (
            st.level_of(self.0[b], seg.t_out, 0.5 * (ta + tb)),
            MAX_GROUP,
        )
    }
}

/// `adaptive`: `k` the block's bound on the change of the classified
/// signal per voxel ([`crate::render::blocks::BlockGrid::classified_change`],
/// recomputed per transfer function), with `k_ref` the tolerance per base
/// step. The block's allowed step is `x = k_ref / F` base steps; the level
/// is `round(log₂ x)` clamped, and grouped reuse may share one value over
/// `⌊x / 2^j⌋` samples of that level (1–3): as far as the allowed step
/// reaches, so grouping never reconstructs more coarsely than the
/// tolerance allows.
pub(in crate::render) struct Classified<'a>(pub &'a [f32]);

impl Level for Classified<'_> {
    fn vector(&self) -> VRule<'_> {
        VRule::Classified(self.0)
    }
    #[inline(always)]
    fn level<T: Voxel>(
        &self,
        st: &Steps<Self>,
        _: &Frame<'_, T>,
        seg: &Segment,
        (b, ta, tb): (usize, f32, f32),
        _: &mut Counters,
    ) -> (i32, u32) {
        classified_level(
            self.0[b],
            st.k_ref,
            seg.t_out / (0.5 * (ta + tb)).max(1e-6),
            (st.level_lo, st.level_hi),
        )
    }
}

/// [`Classified`]'s rule for a block with classified change `k` per voxel,
/// S0's distance factor `|MN|/|MS|` and tolerance per base step `k_ref`:
/// the level `j` and the group cap.
#[inline(always)]
pub(in crate::render) fn classified_level(
    k: f32,
    k_ref: f32,
    distance: f32,
    (lo, hi): (i32, i32),
) -> (i32, u32) {
    if k <= 0.0 {
        return (hi, MAX_GROUP);
    }
    // The allowed step, in base steps.
    let x = k_ref / (k * distance);
    let j = round_log2(x).clamp(lo, hi);
    // The largest group that keeps reuse within the allowed step and two
    // of the coarsest level's: ⌊min(x, 2^(hi+1))/2^j⌋ samples of level j,
    // at least 1 and at most S0's 3.
    (j, group_cap(x, j, hi))
}

/// `⌊min(x, 2^(hi+1)) / 2^j⌋` clamped to 1…3: how many samples of level
/// `j` a group may span where the allowed step is `x` base steps. Below
/// the coarsest level `x/2^j` rounds to 1 (the level is `x`'s); only where
/// `x` reaches past the coarsest step do groups form, up to twice that
/// step: a held value is a step as long as its group, and beyond that the
/// classified bound no longer holds up (the shaded teapot at tolerance 0.3
/// falls from 48 dB to 38 with groups of three coarsest steps, and stays
/// at 44 with two).
#[inline(always)]
fn group_cap(x: f32, j: i32, hi: i32) -> u32 {
    (x.min(exp2i(hi + 1)) / exp2i(j))
        .floor()
        .clamp(1.0, MAX_GROUP as f32) as u32
}

/// `round(log₂ x)` for `x > 0`, exactly, from its bits: the exponent, plus
/// one where the mantissa exceeds √2. (`log2f` then `roundf` are two
/// library calls per block and ray in the block walk, and round the wrong
/// way within a few ulps of the √2 boundaries, where `log2f` returns an
/// exact half.) Zero and subnormals give −127, ∞ and NaN 128: callers
/// clamp to their levels.
#[inline(always)]
pub(in crate::render) fn round_log2(x: f32) -> i32 {
    let b = x.to_bits() & 0x7fff_ffff;
    let e = (b >> 23) as i32 - 127;
    // The mantissa bits of the first f32 above √2 (1.41421366); the one
    // below, 1.41421354, is under √2.
    e + ((b & 0x7f_ffff) >= 0x35_04f4) as i32
}

/// `2^j` for a level `j` (−126…127), exactly.
#[inline(always)]
pub(in crate::render) fn exp2i(j: i32) -> f32 {
    f32::from_bits(((j + 127) as u32) << 23)
}

/// A step-per-block marcher: the level rule and the step tables.
pub(in crate::render) struct Steps<'a, L> {
    pub rule: L,
    /// Allowed power-of-two levels, and `k_ref`.
    pub level_lo: i32,
    pub level_hi: i32,
    pub k_ref: f32,
    /// Per level (index `j − level_lo`): the step in world units and the
    /// premultiplied table of that step ([`crate::transfer::Lut::premultiplied`]),
    /// the tables one after the other.
    pub level_steps: &'a [f32],
    pub level_tables: &'a [[f32; 4]],
}

/// The last sample of an interval, waiting for its stretch: position,
/// entry, and emitted colour and opacity for a full step.
#[derive(Clone, Copy)]
pub(in crate::render) struct Pending {
    pub t: f32,
    pub entry: usize,
    pub e: Vec3,
    pub a: f32,
}

/// Composites `p` over the stretch up to `t_next` (opacity corrected for
/// the stretch's length, colour scaled with it); true when the ray may stop.
#[inline(always)]
pub(in crate::render) fn flush<T, C: Composite>(
    f: &Frame<'_, T>,
    p: Pending,
    t_next: f32,
    c: &mut C,
) -> bool {
    let alpha = stretch_alpha(f, &p, t_next);
    alpha > 0.0 && c.add_premul(p.e * (alpha / p.a), alpha)
}

/// The opacity of `p` over the stretch up to `t_next` ([`flush`]); 0
/// where its sample is transparent.
#[inline(always)]
pub(in crate::render) fn stretch_alpha<T>(f: &Frame<'_, T>, p: &Pending, t_next: f32) -> f32 {
    if p.a <= 0.0 {
        return 0.0;
    }
    let ds = t_next - p.t;
    1.0 - (-f.lut.sigma(p.entry) * ds / f.unit).exp()
}

impl<L> Steps<'_, L> {
    /// The level of a block with largest derivative `k` whose midpoint is
    /// at `tm` on a ray leaving at `t_out`: `F = k·|MN|/|MS|`.
    #[inline(always)]
    fn level_of(&self, k: f32, t_out: f32, tm: f32) -> i32 {
        let f = k * t_out / tm.max(1e-6);
        if f > 0.0 {
            round_log2(self.k_ref / f).clamp(self.level_lo, self.level_hi)
        } else {
            self.level_hi
        }
    }
}

/// A run of samples `n0..n1` (indices on the grid `t₀ + n·s`) at level
/// index `li`.
#[derive(Clone, Copy)]
pub(in crate::render) struct Run {
    pub n0: u32,
    pub n1: u32,
    pub li: usize,
    /// The group cap of grouped reuse ([`Level`]).
    pub cap: u32,
}

impl<T: Voxel, L: Level> Marcher<T> for Steps<'_, L> {
    #[inline(always)]
    fn march<S: Sampler<T>, C: Composite>(
        &self,
        f: &Frame<'_, T>,
        seg: &Segment,
        s: &mut S,
        c: &mut C,
        n: &mut Counters,
    ) -> bool {
        let mut pending: Option<Pending> = None;
        if L::FIXED && !f.skip_empty && !S::GROUPS {
            // Nothing to choose per block: the whole ray is one interval.
            let st = self.level_steps[0];
            let n0 = ((seg.walk.0 - seg.t0) / st).ceil().max(0.0);
            let n1 = ((seg.t_out - seg.t0) / st).ceil().max(0.0);
            if n1 > n0 {
                let r = Run {
                    n0: n0 as u32,
                    n1: n1 as u32,
                    li: 0,
                    cap: u32::MAX,
                };
                if self.sample_run(f, seg, r, &mut pending, s, c, n) {
                    return true;
                }
            }
            return match pending {
                Some(p) => flush(f, p, seg.t_end().max(p.t), c),
                None => false,
            };
        }
        let mut w = RunWalk::new(f, *seg);
        loop {
            match w.next(self, f, S::GROUPS, c, n) {
                Next::Run(r) => {
                    if self.sample_run(f, seg, r, &mut w.pending, s, c, n) {
                        return true;
                    }
                }
                Next::Ended => return false,
                Next::Terminated => return true,
            }
        }
    }
}

impl<L> Steps<'_, L> {
    /// Samples a run: every sample but the last is composited with the
    /// run's step opacity; the last waits in `pending` for its stretch.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn sample_run<T: Voxel, S: Sampler<T>, C: Composite>(
        &self,
        f: &Frame<'_, T>,
        seg: &Segment,
        r: Run,
        pending: &mut Option<Pending>,
        s: &mut S,
        c: &mut C,
        n: &mut Counters,
    ) -> bool {
        let st = self.level_steps[r.li];
        let q: &[[f32; 4]; LUT_SIZE] = self.level_tables[r.li * LUT_SIZE..]
            .first_chunk()
            .expect("a table per level");
        let last = r.n1 - 1;
        s.restart();
        s.limit(r.cap);
        for k in r.n0..last {
            let t = seg.t0 + k as f32 * st;
            // No `alpha > 0` test: a zero composites as nothing, and the
            // branch would mispredict on dense data.
            if let Some((e, a, _)) = s.at_premul(f, q, seg.o + seg.d * t, (t, k, seg.view), n) {
                if c.add_premul(e, a) {
                    n.samples += (k + 1 - r.n0) as u64;
                    return true;
                }
            }
        }
        n.samples += (r.n1 - r.n0) as u64;
        let t = seg.t0 + last as f32 * st;
        if let Some((e, a, entry)) = s.at_premul(f, q, seg.o + seg.d * t, (t, last, seg.view), n) {
            *pending = Some(Pending { t, entry, e, a });
        }
        false
    }
}

/// A step-per-block march handed out run by run, for the SIMD packets
/// (`render/packet/`): each lane walks its blocks with one of these in
/// scalar code — once per run, not per sample — and marches the run's
/// samples in the vector loop. The walk is [`Steps::march`]'s, step for
/// step: the same blocks, levels, merged runs and group caps; the caller
/// marches samples `n0..n1` of each run and leaves the last in
/// [`RunWalk::pending`], which the walk composites over its stretch (up to
/// the next run's first sample, a skipped block's, or the exit) before it
/// hands out the next run.
pub(in crate::render) struct RunWalk {
    pub seg: Segment,
    pub walker: BlockWalker,
    /// The current run, still growing.
    cur: Option<Run>,
    /// The block that ended the run handed out last, not yet taken.
    held: Option<(Run, bool)>,
    /// The last sample of the run handed out last (set by the caller).
    pub pending: Option<Pending>,
    /// Whether the walk has handed out its last run.
    ended: bool,
}

/// What a lane does next: march a run, or stop.
pub(in crate::render) enum Next {
    /// March this run (it starts a new group of grouped reuse).
    Run(Run),
    /// The walk is over; the ray was not terminated.
    Ended,
    /// Early termination at a pending sample.
    Terminated,
}

impl RunWalk {
    /// The walk of segment `seg` over frame `f`'s blocks.
    pub fn new<T>(f: &Frame<'_, T>, seg: Segment) -> RunWalk {
        let walker = BlockWalker::of_segment(f, &seg, seg.t_out);
        RunWalk {
            seg,
            walker,
            cur: None,
            held: None,
            pending: None,
            ended: false,
        }
    }

    /// The next run, after compositing the pending sample of the last one
    /// into `c`; `groups`: runs keep S0's groups (grouped reuse), so only
    /// blocks with the same cap merge (see [`Sampler::GROUPS`]). Inlined into
    /// the packets' loop, so it is compiled with their instruction set
    /// (`ceil` one instruction, not a library call).
    #[inline(always)]
    pub fn next<T: Voxel, L: Level, C: Composite>(
        &mut self,
        st: &Steps<'_, L>,
        f: &Frame<'_, T>,
        groups: bool,
        c: &mut C,
        n: &mut Counters,
    ) -> Next {
        let seg = self.seg;
        if let Some((b, skip)) = self.held.take() {
            // The pending sample's stretch ends at this block's first
            // sample, whether or not the block is skipped.
            if let Some(p) = self.pending.take() {
                if flush(f, p, seg.t0 + b.n0 as f32 * st.level_steps[b.li], c) {
                    return Next::Terminated;
                }
            }
            if !skip {
                self.cur = Some(b);
            }
        }
        if !self.ended {
            let t_stop = seg.walk.1;
            for (ta, tb, b) in self.walker.by_ref() {
                if ta >= t_stop && self.cur.is_none() {
                    break;
                }
                // A skipped block with no run before it changes nothing.
                let skip = f.skip_empty && f.empty[b];
                if skip && self.cur.is_none() {
                    continue;
                }
                let (j, cap) = if f.empty[b] {
                    let j = if L::FIXED { st.level_lo } else { st.level_hi };
                    (j, u32::MAX)
                } else {
                    st.rule.level(st, f, &seg, (b, ta, tb), n)
                };
                let li = (j - st.level_lo) as usize;
                let s = st.level_steps[li];
                let n0 = ((ta - seg.t0) / s).ceil().max(0.0);
                let n1 = ((tb - seg.t0) / s).ceil().max(0.0);
                if n1 <= n0 {
                    continue;
                }
                let blk = Run {
                    n0: n0 as u32,
                    n1: n1 as u32,
                    li,
                    cap,
                };
                if let Some(r) = &mut self.cur {
                    let same = r.li == li && r.n1 == blk.n0 && (!groups || r.cap == cap);
                    if same && !skip {
                        r.n1 = blk.n1;
                        continue;
                    }
                }
                if let Some(r) = self.cur.take() {
                    self.held = Some((blk, skip));
                    return Next::Run(r);
                }
                if !skip {
                    self.cur = Some(blk);
                }
            }
            self.ended = true;
            if let Some(r) = self.cur.take() {
                return Next::Run(r);
            }
        }
        match self.pending.take() {
            Some(p) if flush(f, p, seg.t_end().max(p.t), c) => Next::Terminated,
            _ => Next::Ended,
        }
    }
}
