//! The step-per-block lanes' block walks in vector registers: where a
//! rule's level is a table lookup (`uniform` grouped, `adaptive`,
//! `adaptive-max`), every lane that needs its next run walks its blocks in
//! lock-step with the others — the 3D DDA, the block's emptiness and level,
//! the run's first and last sample, the merging of blocks that share a
//! level — one block per lane per iteration, instead of one lane at a time
//! in scalar code ([`super::walk::walk_runs`], which `adaptive-s0` keeps:
//! its level needs a gradient per block).
//!
//! It is [`RunWalk::next`] operation for operation — the same crossings
//! from the same planes, the same divisions and roundings — so the lanes
//! get the scalar walk's runs. Only the compositing of a run's last
//! sample over its stretch (an `exp` per run, not per block) stays scalar.
//!
//! The 3D DDA itself ([`VBlocks`]) is shared with `importance`'s walks
//! ([`super::importance::VImp`]).
//!
//! [`RunWalk::next`]: crate::render::march::RunWalk::next

use super::simd::Simd;
use super::walk::RunRegs;
use super::{Packets, Runs, State, VParams, WalkStart, LANES};
use crate::render::march::{exp2i, VRule};
use crate::volume::Voxel;

/// The lanes' 3D DDA over the block grid in vector registers
/// ([`BlockWalker::next`] operation for operation, in its `staying`
/// mode): each lane's block (per axis), where it leaves it on each axis,
/// where it stands and where its walk ends; and what the walks share: the
/// rays (voxel coordinates), each axis's direction (−1, 0, 1; 1 as a float
/// where it goes up), the block grid.
///
/// [`BlockWalker::next`]: crate::render::march::BlockWalker
pub(super) struct VBlocks<S: Simd> {
    blk: [S::I; 3],
    tmax: [S::F; 3],
    pub t: S::F,
    pub t_out: S::F,
    o: [S::F; 3],
    inv_d: [S::F; 3],
    sgn: [S::I; 3],
    up: [S::F; 3],
    size: S::F,
    last: [S::I; 3],
    ncx: S::I,
    ncy: S::I,
}

/// One lane's walk, as [`VBlocks::new`] takes it: its block and where it
/// leaves it on each axis ([`BlockWalker::state`]), where it stands and
/// where the walk ends.
///
/// [`BlockWalker::state`]: crate::render::march::BlockWalker::state
pub(super) type LaneWalk = ([i64; 3], [f32; 3], f32, f32);

impl<S: Simd> VBlocks<S> {
    /// The walks of the lanes (`None`: a lane with no walk, which must
    /// never step) on the rays `o + d·t` (`inv_d = 1/d`, as the scalar
    /// walks divide; the grids' start unused), over `counts` blocks of
    /// `size` voxels.
    ///
    /// # Safety
    /// The width's instructions.
    #[inline(always)]
    pub unsafe fn new(
        lanes: &[Option<LaneWalk>],
        counts: [usize; 3],
        size: usize,
        &Rays { o, d, inv_d, .. }: &Rays<S>,
    ) -> Self {
        let mut a = [S::Af::default(); 5];
        let mut bi = [S::Ai::default(); 3];
        for (i, w) in lanes.iter().enumerate().take(S::N) {
            let Some((b, tm, t, t_out)) = *w else {
                continue;
            };
            for c in 0..3 {
                bi[c][i] = b[c] as i32;
                a[c][i] = tm[c];
            }
            a[3][i] = t;
            a[4][i] = t_out;
        }
        // (No closures: they would not inherit the loop's target features,
        // and each intrinsic would become a call.)
        let sgn = [sign::<S>(d[0]), sign::<S>(d[1]), sign::<S>(d[2])];
        let up = [ups::<S>(d[0]), ups::<S>(d[1]), ups::<S>(d[2])];
        VBlocks {
            blk: [S::load_i(bi[0]), S::load_i(bi[1]), S::load_i(bi[2])],
            tmax: [S::load(a[0]), S::load(a[1]), S::load(a[2])],
            t: S::load(a[3]),
            t_out: S::load(a[4]),
            o,
            inv_d,
            sgn,
            up,
            size: S::splat(size as f32),
            last: last_blocks::<S>(counts),
            ncx: S::splat_i(counts[0] as i32),
            ncy: S::splat_i(counts[1] as i32),
        }
    }

    /// The index of the block each lane of `m` stands in, the one its
    /// next [`VBlocks::step`] returns (always inside the grid: a walk
    /// past it stays in the edge block); 0 in the other lanes.
    ///
    /// # Safety
    /// The width's instructions.
    #[inline(always)]
    pub unsafe fn current(&self, m: S::M) -> S::I {
        let [bx, by, bz] = self.blk;
        S::keep_i(m, bx + S::mullo(self.ncx, by + S::mullo(self.ncy, bz)))
    }

    /// One block for each lane of `m` (lanes whose walk is not over, `t <
    /// t_out`): where the lane enters and leaves it, its index and its
    /// place on each axis; the lanes move on to their next block.
    ///
    /// # Safety
    /// The width's instructions.
    #[inline(always)]
    pub unsafe fn step(&mut self, m: S::M) -> (S::F, S::F, S::I, [S::I; 3]) {
        let [t0m, t1m, t2m] = self.tmax;
        let ax0 = S::and(S::ge(t1m, t0m), S::ge(t2m, t0m));
        let ax1 = S::but(S::ge(t2m, t1m), ax0);
        let ax = [ax0, ax1, S::but(S::but(m, ax0), ax1)];
        let tsel = S::blend(ax0, S::blend(ax1, t2m, t1m), t0m);
        let ta = self.t;
        let tb = S::max(S::min(tsel, self.t_out), ta);
        let [bx, by, bz] = self.blk;
        let b = self.current(m);
        self.t = S::blend(m, self.t, tb);
        // Each lane moves on one axis: that axis's block, direction,
        // bounds and plane, picked lane by lane, and one crossing.
        let pick = |v: [S::F; 3]| S::blend(ax0, S::blend(ax1, v[2], v[1]), v[0]);
        let pick_i = |v: [S::I; 3]| S::blend_i(ax0, S::blend_i(ax1, v[2], v[1]), v[0]);
        let bc = pick_i(self.blk);
        let sg = pick_i(self.sgn);
        let nb = bc + sg;
        let outside = S::or(
            S::positive(S::splat_i(0) - nb),
            S::positive(nb - pick_i(self.last)),
        );
        // Past the grid on this axis: the walk stays in the edge block,
        // with no more crossings on it.
        let nb = S::blend_i(outside, nb, bc);
        let plane = (S::to_f(nb) + pick(self.up)) * self.size;
        // `BlockWalker`'s `crossing`: the far plane's `(plane − o)·(1/d)`;
        // ∞ where the ray does not move on that axis.
        let tc = (plane - pick(self.o)) * pick(self.inv_d);
        let moving = S::or(S::positive(sg), S::positive(S::splat_i(0) - sg));
        let tc = S::blend(S::but(moving, outside), S::splat(f32::INFINITY), tc);
        for (c, axc) in ax.into_iter().enumerate() {
            let mc = S::and(m, axc);
            self.blk[c] = S::blend_i(mc, self.blk[c], nb);
            self.tmax[c] = S::blend(mc, self.tmax[c], tc);
        }
        (ta, tb, b, [bx, by, bz])
    }
}

/// The last block on each axis of a grid of `counts` blocks, in every
/// lane.
///
/// # Safety
/// The width's instructions.
#[inline(always)]
pub(super) unsafe fn last_blocks<S: Simd>(counts: [usize; 3]) -> [S::I; 3] {
    [
        S::splat_i(counts[0] as i32 - 1),
        S::splat_i(counts[1] as i32 - 1),
        S::splat_i(counts[2] as i32 - 1),
    ]
}

/// Per lane, the sign of `d` (1, 0 or −1) as an integer.
///
/// # Safety
/// The width's instructions.
#[inline(always)]
unsafe fn sign<S: Simd>(d: S::F) -> S::I {
    let zero = S::splat(0.0);
    let (up, down) = (S::gt(d, zero), S::lt(d, zero));
    S::blend_i(down, S::keep_i(up, S::splat_i(1)), S::splat_i(-1))
}

/// Per lane, 1 where `d` is positive, else 0.
///
/// # Safety
/// The width's instructions.
#[inline(always)]
unsafe fn ups<S: Simd>(d: S::F) -> S::F {
    S::keep(S::gt(d, S::splat(0.0)), S::splat(1.0))
}

/// The lanes' run walks: their blocks ([`VBlocks`]); the run each is
/// merging (`cur`: first sample, end, level index, group cap) and the
/// block that ended the run it was handed last (`held`, and whether that
/// block is skipped); whether its walk is over. And what every walk
/// shares.
pub(super) struct VWalk<'a, S: Simd> {
    p: VParams<'a>,
    w: VBlocks<S>,
    /// `(t − t₀)/s₀`, `s₀` the finest level's step: a sample index on
    /// that level's grid, for the blocks' first and end samples.
    q: S::F,
    t_stop: S::F,
    t_end: S::F,
    cur: [S::F; 4],
    cur_ok: S::M,
    held: [S::F; 4],
    held_ok: S::M,
    held_skip: S::M,
    ended: S::M,
    /// Each lane's next run, found ahead (`rdy_ok`), or the end of its
    /// walk (`rdy_fin`); where the pending sample's stretch ends (`rt`)
    /// when a held block ended it (`rfl`).
    rdy: Run<S>,
    rdy_ok: S::M,
    rdy_fin: S::M,
    rt: S::F,
    rfl: S::M,
    // The rays' sample grids' start, and the finest level's step.
    t0: S::F,
    s0: S::F,
}

/// Level index, first and end sample and group cap of a block or run.
type Run<S> = [<S as Simd>::F; 4];

/// The lanes' rays: origin, direction and its reciprocal (voxel
/// coordinates), and where their sample grids start.
#[derive(Clone, Copy)]
pub(super) struct Rays<S: Simd> {
    pub o: [S::F; 3],
    pub d: [S::F; 3],
    pub inv_d: [S::F; 3],
    pub t0: S::F,
}

/// The block walks of the lanes of `st.runs` or `st.starts`, each where
/// its `RunWalk` was set up (or as `lanes::set_up_runs` set it up), on
/// the rays `rays` over `counts` blocks of `size` cells; and per lane
/// where its walk's stretch with samples ends (`walk.1`) and its ray's
/// samples end (`Segment::t_end`).
///
/// # Safety
/// The width's instructions.
#[inline(always)]
pub(super) unsafe fn run_walks<S: Simd>(
    st: &State<'_>,
    counts: [usize; 3],
    size: usize,
    rays: &Rays<S>,
) -> (VBlocks<S>, S::F, S::F) {
    let mut a = [S::Af::default(); 2];
    let mut lanes: [Option<LaneWalk>; LANES] = [None; LANES];
    for (i, (w, s)) in st.runs.iter().zip(st.starts).enumerate().take(S::N) {
        let Some(s) = w.as_ref().map(WalkStart::of).or(*s) else {
            continue;
        };
        lanes[i] = Some((s.block, s.t_max, s.t, s.t_out));
        a[0][i] = s.t_stop;
        a[1][i] = s.t_end;
    }
    (
        VBlocks::new(&lanes, counts, size, rays),
        S::load(a[0]),
        S::load(a[1]),
    )
}

impl<'a, S: Simd> VWalk<'a, S> {
    /// The walks of the lanes of `st.runs` (each where its [`RunWalk`]
    /// was set up), on the rays `o + d·t` (`inv_d = 1/d`), sample grids
    /// from `t0`.
    ///
    /// # Safety
    /// The width's instructions.
    ///
    /// [`RunWalk`]: crate::render::march::RunWalk
    #[inline(always)]
    pub unsafe fn new(
        p: VParams<'a>,
        st: &State<'_>,
        counts: [usize; 3],
        size: usize,
        rays: Rays<S>,
    ) -> Self {
        let (w, t_stop, t_end) = run_walks(st, counts, size, &rays);
        let t0 = rays.t0;
        let s0 = S::splat(p.steps[0]);
        let z = [S::splat(0.0); 4];
        VWalk {
            p,
            q: (w.t - t0) / s0,
            w,
            t_stop,
            t_end,
            cur: z,
            cur_ok: S::from_bits(0),
            held: z,
            held_ok: S::from_bits(0),
            held_skip: S::from_bits(0),
            ended: S::from_bits(0),
            rdy: z,
            rdy_ok: S::from_bits(0),
            rdy_fin: S::from_bits(0),
            rt: S::splat(0.0),
            rfl: S::from_bits(0),
            t0,
            s0,
        }
    }

    /// `round(log₂ x)` ([`crate::render::march`]'s `round_log2`), clamped
    /// to the levels, as a float.
    #[inline(always)]
    unsafe fn level(&self, x: S::F) -> S::F {
        let b = S::and_i(S::as_bits(x), S::splat_i(0x7fff_ffff));
        let e = S::srl(b, 23) - S::splat_i(127);
        let round_up = S::positive(S::and_i(b, S::splat_i(0x7f_ffff)) - S::splat_i(0x35_04f3));
        let j = S::count(e, round_up);
        S::to_f(S::max_i(
            S::min_i(j, S::splat_i(self.p.hi)),
            S::splat_i(self.p.lo),
        ))
    }

    /// The level `j` (a float) and group cap (1–3; 4 for the empty
    /// blocks, as the scalar walk's `u32::MAX`) of the lanes' blocks with
    /// `k` (see [`VParams::k`]) crossed over `ta..tb`, `e` the empty ones:
    /// [`crate::render::march::Level::level`] of the rule.
    #[inline(always)]
    unsafe fn rule(&self, k: S::F, ta: S::F, tb: S::F, e: S::M) -> (S::F, S::F) {
        let (hi, three) = (S::splat(self.p.hi as f32), S::splat(3.0));
        let four = S::splat(4.0);
        let tm = S::max(S::splat(0.5) * (ta + tb), S::splat(1e-6));
        let k_ref = S::splat(self.p.k_ref);
        let zero = S::splat(0.0);
        let (j, cap) = match self.p.rule {
            VRule::Fixed => return (zero, S::blend(e, three, four)),
            VRule::Max(_) => {
                let f = k * self.w.t_out / tm;
                (S::blend(S::gt(f, zero), hi, self.level(k_ref / f)), three)
            }
            VRule::Classified(_) => {
                let x = k_ref / (k * (self.w.t_out / tm));
                let j = self.level(x);
                // `group_cap`: `min(x, 2^(hi+1)) / 2^j`, exactly.
                let reach = S::min(x, S::splat(exp2i(self.p.hi + 1)));
                let cap = S::min(
                    S::max(S::floor(reach * pow2::<S>(zero - j)), S::splat(1.0)),
                    three,
                );
                let none = S::ge(zero, k);
                (S::blend(none, j, hi), S::blend(none, cap, three))
            }
            // `new`'s callers check.
            VRule::Scalar => unreachable!(),
        };
        (S::blend(e, j, hi), S::blend(e, cap, four))
    }

    /// The step (world units) of level indices `li`: the finest's times
    /// `2^li`, exactly the level's ([`super::vector_params`] walks only
    /// steps that double), with no gather.
    #[inline(always)]
    unsafe fn step(&self, li: S::F) -> S::F {
        self.s0 * pow2::<S>(li)
    }

    /// The lanes of `need`, past their run: each composites its run's
    /// last sample over its stretch and goes on to its next run, which
    /// `rr` and `kv` then hold. Returns the masks of the lanes whose walk
    /// ended and of those that terminated.
    ///
    /// A lane's next run is found ahead: when some lane of `need` has
    /// none ready, every lane of `live` without one walks to its next
    /// run in the same lock-step iterations ([`VWalk::advance`]), so the
    /// lanes still sampling do the work their next call would do while
    /// the walk runs anyway, and fewer calls walk. Each lane's walk and
    /// compositing are the same operations in the same order as walking
    /// when it needs the run: the same runs and pixels.
    ///
    /// # Safety
    /// The width's instructions; `need` only lanes with a walk, within
    /// `live`.
    #[inline(always)]
    pub unsafe fn next<T: Voxel, R: Runs<T>>(
        &mut self,
        pk: &Packets<'_, T, R>,
        need: S::M,
        live: S::M,
        rr: &mut RunRegs<S>,
        kv: &mut S::F,
        col: &mut [S::F; 4],
    ) -> (S::M, S::M) {
        let none = S::from_bits(0);
        let ready = S::or(self.rdy_ok, self.rdy_fin);
        if S::bits(S::but(need, ready)) != 0 {
            self.advance(S::but(S::or(need, live), ready));
        }
        // The pending sample's stretch ends where a held block started
        // the next run, or at the exit where the walk is over.
        let mut dead = none;
        let h = S::and(need, self.rfl);
        if S::bits(h) != 0 {
            dead = flush_lanes(pk, h, self.rt, false, rr, col);
        }
        self.rfl = S::but(self.rfl, need);
        let found = S::but(S::and(need, self.rdy_ok), dead);
        let fin = S::but(S::and(need, self.rdy_fin), dead);
        self.rdy_ok = S::but(self.rdy_ok, need);
        self.rdy_fin = S::but(self.rdy_fin, need);
        let mut ended = none;
        if S::bits(fin) != 0 {
            let d = flush_lanes(pk, fin, self.t_end, true, rr, col);
            dead = S::or(dead, d);
            ended = S::but(fin, d);
        }
        // Each pending sample is now composited.
        rr.pend_ok = S::but(rr.pend_ok, need);
        // The runs handed out.
        let [li, n0, n1, cap] = self.rdy;
        rr.take(found, kv, n0, n1, self.step(S::keep(found, li)), li);
        rr.capv = S::blend(found, rr.capv, cap);
        (ended, dead)
    }

    /// The lanes of `m` (none with a run or end ready) walk to their next
    /// run (`rdy`, `rdy_ok`) or to the end of their walk (`rdy_fin`),
    /// `RunWalk::next` operation for operation; a lane whose held block
    /// starts it notes where the pending sample's stretch ends (`rt`,
    /// `rfl`).
    ///
    /// # Safety
    /// The width's instructions; `m` only lanes with a walk.
    #[inline(always)]
    unsafe fn advance(&mut self, mut m: S::M) {
        let zero = S::splat(0.0);
        let none = S::from_bits(0);
        // A held block: the pending sample's stretch ends at its first
        // sample, whether or not it is skipped; then it is the current run
        // unless skipped.
        let h = S::and(m, self.held_ok);
        if S::bits(h) != 0 {
            let t_next = self.t0 + self.held[1] * self.step(self.held[0]);
            self.rt = S::blend(h, self.rt, t_next);
            self.rfl = S::or(self.rfl, h);
            let take = S::but(h, self.held_skip);
            for (c, v) in self.cur.iter_mut().zip(self.held) {
                *c = S::blend(take, *c, v);
            }
            self.cur_ok = S::or(self.cur_ok, take);
            self.held_ok = S::but(self.held_ok, h);
        }
        let (mut found, mut fin) = (none, none);
        let mut out: Run<S> = self.rdy;
        // Each lane's `k` is gathered a block ahead: the next block's
        // gather starts as soon as the lanes have stepped, so its latency
        // overlaps this block's rule instead of lengthening the chain from
        // block to block (a lane of `m` now was in `m` then, and has not
        // moved since).
        let mut k_next = S::gather_f::<4>(self.p.k.as_ptr(), self.w.current(m));
        loop {
            // Walks that are over hand out their current run, or finish.
            let over = S::and(m, S::or(self.ended, S::ge(self.w.t, self.w.t_out)));
            if S::bits(over) != 0 {
                self.ended = S::or(self.ended, over);
                let hand = S::and(over, self.cur_ok);
                for (o, c) in out.iter_mut().zip(self.cur) {
                    *o = S::blend(hand, *o, c);
                }
                found = S::or(found, hand);
                fin = S::or(fin, S::but(over, self.cur_ok));
                self.cur_ok = S::but(self.cur_ok, over);
                m = S::but(m, over);
            }
            if S::bits(m) == 0 {
                break;
            }
            // One block per lane (`BlockWalker::next`).
            let (ta, tb, _, _) = self.w.step(m);
            let k = k_next;
            k_next = S::gather_f::<4>(self.p.k.as_ptr(), self.w.current(m));
            let (qa, qb) = (self.q, (tb - self.t0) / self.s0);
            self.q = S::blend(m, self.q, qb);
            // Past the walk's end with no run: over.
            let stop = S::but(S::and(m, S::ge(ta, self.t_stop)), self.cur_ok);
            self.ended = S::or(self.ended, stop);
            fin = S::or(fin, stop);
            m = S::but(m, stop);
            let e = S::lt(k, zero);
            let skip = if self.p.skip_empty { e } else { none };
            // A skipped block with no run before it changes nothing.
            let mut go = S::but(m, S::but(skip, self.cur_ok));
            if S::bits(go) == 0 {
                continue;
            }
            let (j, cap) = self.rule(k, ta, tb, e);
            let li = j - S::splat(self.p.lo as f32);
            // `⌈(t − t₀)/s⌉` at the block's ends, `s = s₀·2^li`: the
            // same roundings as dividing by `s` (a power of two scales
            // exactly), one division per block, not two.
            let r = pow2::<S>(zero - li);
            let n0 = S::max(S::ceil(qa * r), zero);
            let n1 = S::max(S::ceil(qb * r), zero);
            go = S::and(go, S::gt(n1, n0));
            let blk: Run<S> = [li, n0, n1, cap];
            // The block extends the current run (with groups, one of its
            // cap).
            let mut same = S::and(S::eq(self.cur[0], li), S::eq(self.cur[2], n0));
            if self.p.groups {
                same = S::and(same, S::eq(self.cur[3], cap));
            }
            let merge = S::and(S::but(S::and(go, self.cur_ok), skip), same);
            self.cur[2] = S::blend(merge, self.cur[2], n1);
            go = S::but(go, merge);
            // Or ends it: the run is handed out, the block held.
            let hand = S::and(go, self.cur_ok);
            for (c, b) in blk.into_iter().enumerate() {
                out[c] = S::blend(hand, out[c], self.cur[c]);
                self.held[c] = S::blend(hand, self.held[c], b);
            }
            self.held_ok = S::or(self.held_ok, hand);
            self.held_skip = S::or(S::and(hand, skip), S::but(self.held_skip, hand));
            found = S::or(found, hand);
            m = S::but(m, hand);
            // Or starts one.
            let start = S::but(S::but(go, self.cur_ok), skip);
            for (c, b) in self.cur.iter_mut().zip(blk) {
                *c = S::blend(start, *c, b);
            }
            self.cur_ok = S::or(S::but(self.cur_ok, hand), start);
        }
        self.rdy = out;
        self.rdy_ok = S::or(self.rdy_ok, found);
        self.rdy_fin = S::or(self.rdy_fin, fin);
    }
}

/// `2^j` for whole `j` (−126…127), exactly, from its bits.
#[inline(always)]
unsafe fn pow2<S: Simd>(j: S::F) -> S::F {
    S::of_bits(S::sll(S::to_i(j) + S::splat_i(127), 23))
}

/// The lanes of `m` composite their pending sample (`rr`'s, which they no
/// longer hold) into `col` over its stretch up to `t_next` (past the
/// sample where `to_exit`); returns those that terminated. In registers,
/// `march::flush` lane by lane: the opacity `1 − exp(−σ·Δt/unit)` of the
/// stretch (by [`exp`]), the colour scaled with it — or, with shading
/// deferred, the weight it gains in the lane's slot, the opacity
/// composited now.
#[inline(always)]
pub(super) unsafe fn flush_lanes<S: Simd, T: Voxel, R: Runs<T>>(
    pk: &Packets<'_, T, R>,
    m: S::M,
    t_next: S::F,
    to_exit: bool,
    rr: &mut RunRegs<S>,
    col: &mut [S::F; 4],
) -> S::M {
    let m2 = S::and(m, rr.pend_ok);
    rr.pend_ok = S::but(rr.pend_ok, m);
    if S::bits(m2) == 0 {
        return S::from_bits(0);
    }
    let zero = S::splat(0.0);
    let one = S::splat(1.0);
    let t = if to_exit {
        S::max(t_next, rr.pend[4])
    } else {
        t_next
    };
    // `stretch_alpha`: 0 where the sample is transparent.
    let sigma = S::gather_f::<4>(pk.f.lut.sigmas().as_ptr(), rr.pend_idx);
    let x = zero - sigma * (t - rr.pend[4]) / S::splat(pk.f.unit);
    let a = rr.pend[3];
    let alpha = S::keep(S::gt(a, zero), one - exp::<S>(x));
    let show = S::and(m2, S::gt(alpha, zero));
    if S::bits(show) == 0 {
        return S::from_bits(0);
    }
    let (we, wa) = (
        S::splat(pk.weights.emission),
        S::splat(pk.weights.absorption),
    );
    let tr = one - col[3];
    let r = alpha / a;
    if rr.defer {
        let w = &mut rr.slot.w;
        *w = S::blend(show, *w, *w + we * tr * r);
    } else {
        for (c, p) in col.iter_mut().zip(&rr.pend[..3]) {
            *c = S::blend(show, *c, *c + *p * r * we * tr);
        }
    }
    col[3] = S::blend(show, col[3], col[3] + alpha * wa * tr);
    S::and(show, S::ge(col[3], S::splat(pk.stop)))
}

/// `eˣ` for `x ≤ 0`, to a few float roundings: `2ⁿ·e^r`, `n` the nearest
/// whole number to `x·log₂e`, `r = x − n·ln 2` (in two parts, Cody–Waite)
/// so `|r| ≤ ln 2 / 2`, and `e^r` by its Taylor polynomial of degree 6
/// (error below `r⁷/7!` ≈ 1.2·10⁻⁷ relative); `x` below −87 gives
/// `e⁻⁸⁷` (≈ 0 to an opacity).
#[inline(always)]
pub(super) unsafe fn exp<S: Simd>(x: S::F) -> S::F {
    let x = S::max(x, S::splat(-87.0));
    let n = S::floor(x * S::splat(std::f32::consts::LOG2_E) + S::splat(0.5));
    let r = x - n * S::splat(0.693_145_75) - n * S::splat(1.428_606_8e-6);
    let mut p = S::splat(1.0 / 720.0);
    for c in [1.0 / 120.0, 1.0 / 24.0, 1.0 / 6.0, 0.5, 1.0, 1.0] {
        p = p * r + S::splat(c);
    }
    p * pow2::<S>(n)
}
