//! The step-per-block marchers in the packets — `adaptive`, `adaptive-s0`,
//! `adaptive-max`, and any of them or `uniform` with S0's grouped reuse:
//! each lane walks its blocks as a [`RunWalk`] does (once per run of blocks
//! sharing a step, not per sample) — in vector registers together with the
//! other lanes where the rule's level is a table lookup
//! ([`super::vwalk`]), in scalar code with its `RunWalk` for
//! `adaptive-s0` — and the vector loop marches the run's samples with the
//! lane's step and its level's table.
//! The last sample of a run waits, as in [`Steps::march`], until the walk
//! knows where its stretch ends; the walk composites it.

use super::{Lane, Packets, Setup};
use crate::render::composite::Front;
use crate::render::march::{Level, Next, RunWalk, Steps, VRule};
use crate::render::ray::{Counters, Frame, Segment};
use crate::render::stats::RenderStats;
use crate::volume::Voxel;
use glam::Vec3;

/// What the vector walk reads of a step-per-block march.
#[derive(Clone, Copy)]
pub(in crate::render) struct VParams<'a> {
    pub rule: VRule<'a>,
    /// The levels `lo..=hi` and their steps (world units).
    pub lo: i32,
    pub hi: i32,
    pub steps: &'a [f32],
    pub k_ref: f32,
    /// Per block, the rule's `k` (0 for [`VRule::Fixed`]), or −1 where
    /// the block is empty under the transfer function: one gather per
    /// block.
    pub k: &'a [f32],
    /// Skipping empty blocks.
    pub skip_empty: bool,
    /// Runs keep S0's groups (grouped reuse): blocks merge only where
    /// they share their group cap ([`Sampler::GROUPS`]).
    ///
    /// [`Sampler::GROUPS`]: crate::render::ray::Sampler::GROUPS
    pub groups: bool,
}

/// Where the packets' lanes get their runs from: a step-per-block march
/// ([`Adapt`]), or none (`()`: a fixed step, or `importance`).
pub(in crate::render) trait Runs<T: Voxel>: Sync {
    /// Whether the lanes march runs.
    const ON: bool;
    /// The levels' premultiplied tables, one after the other (`LUT_SIZE`
    /// rows each).
    fn tables(&self) -> &[[f32; 4]];
    /// The step of level index `li` (world units).
    fn step(&self, li: usize) -> f32;
    /// Grouped reuse (runs merge only blocks of one cap, groups restart
    /// with each run).
    fn grouped(&self) -> bool;
    /// The lane's next run (see [`RunWalk::next`]), compositing its
    /// pending sample into `c`.
    fn next(&self, f: &Frame<'_, T>, w: &mut RunWalk, c: &mut Front, n: &mut Counters) -> Next;
    /// What the lanes' vector walk reads, where the rule's level is a
    /// table lookup; `None`: the lanes walk in scalar code (`next`).
    fn vector(&self) -> Option<VParams<'_>>;
}

impl<T: Voxel> Runs<T> for () {
    const ON: bool = false;
    fn tables(&self) -> &[[f32; 4]] {
        &[]
    }
    fn step(&self, _: usize) -> f32 {
        0.0
    }
    fn grouped(&self) -> bool {
        false
    }
    fn next(&self, _: &Frame<'_, T>, _: &mut RunWalk, _: &mut Front, _: &mut Counters) -> Next {
        Next::Ended
    }
    fn vector(&self) -> Option<VParams<'_>> {
        None
    }
}

/// The walk of a lane's runs (see [`RunWalk::next`]) of one marcher.
pub(in crate::render) type WalkFn<'a, T> =
    dyn Fn(&Frame<'_, T>, &mut RunWalk, &mut Front, &mut Counters) -> Next + Sync + 'a;

/// A step-per-block march for the packets: its levels' steps and tables
/// end to end, whether samples are grouped, and the lanes' walk of their
/// runs. The marcher's level rule sits behind `walk`, a `dyn` call once
/// per run (the scalar walk of `adaptive-s0` only; the vector walk reads
/// `vector`), so the packets' loop is compiled once for every rule, not
/// once per rule (80 copies of the march instead of 176).
pub(in crate::render) struct Adapt<'a, T> {
    pub level_steps: &'a [f32],
    pub tables: &'a [[f32; 4]],
    pub grouped: bool,
    pub walk: &'a WalkFn<'a, T>,
    /// What the lanes' vector walk reads ([`vector_params`]), or `None`
    /// where they walk in scalar code.
    pub vector: Option<VParams<'a>>,
}

/// The vector walk's parameters of march `steps` with `k` per block
/// (the rule's, −1 where empty: [`VParams::k`]), or `None` where the
/// lanes must walk in scalar code: a rule that is not a table lookup
/// (`adaptive-s0`), or steps that are not the finest times powers of
/// two (the walk finds a level's sample indices from the finest's, as
/// `Tables` makes them).
pub(in crate::render) fn vector_params<'a, L: Level>(
    steps: &'a Steps<'a, L>,
    k: &'a [f32],
    skip_empty: bool,
    grouped: bool,
) -> Option<VParams<'a>> {
    let rule = steps.rule.vector();
    let doubling = steps
        .level_steps
        .iter()
        .enumerate()
        .all(|(li, &s)| li < 16 && s == steps.level_steps[0] * (1u32 << li) as f32);
    (doubling && !matches!(rule, VRule::Scalar)).then_some(VParams {
        rule,
        lo: steps.level_lo,
        hi: steps.level_hi,
        steps: steps.level_steps,
        k_ref: steps.k_ref,
        k,
        skip_empty,
        groups: grouped,
    })
}

impl<T: Voxel> Runs<T> for Adapt<'_, T> {
    const ON: bool = true;
    fn tables(&self) -> &[[f32; 4]] {
        self.tables
    }
    fn step(&self, li: usize) -> f32 {
        self.level_steps[li]
    }
    fn grouped(&self) -> bool {
        self.grouped
    }
    fn next(&self, f: &Frame<'_, T>, w: &mut RunWalk, c: &mut Front, n: &mut Counters) -> Next {
        (self.walk)(f, w, c, n)
    }
    fn vector(&self) -> Option<VParams<'_>> {
        self.vector
    }
}

impl<T: Voxel, R: Runs<T>> Packets<'_, T, R> {
    /// Sets up a ray of a step-per-block march as [`super::trace::trace`]
    /// does: the lane (its sample grid's start; no fixed-step samples)
    /// and its walk.
    pub(super) fn run_lane(
        &self,
        ray: (Vec3, Vec3),
        limit: f32,
        pixel: (u32, u32),
        pass: u32,
        stats: &mut RenderStats,
    ) -> Option<(Lane, RunWalk)> {
        let f = self.f;
        let Setup {
            o,
            d,
            t_in,
            t_out,
            walk,
        } = self.setup(ray, limit, stats)?;
        let t0 = self.grid_start(t_in, pixel, pass);
        let seg = Segment {
            o,
            d,
            view: -ray.1,
            t_in,
            t_out,
            t0,
            walk,
            pixel,
            pass,
        };
        let lane = Lane::walking(o, d, seg.view, t0, seg.t_end());
        Some((lane, RunWalk::new(f, seg)))
    }
}

/// Where a step-per-block lane's walk starts, where its lanes were set
/// up in vector registers (`lanes::set_up_runs`) instead of with a
/// [`RunWalk`] each: what the vector walks read of one
/// ([`WalkStart::of`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct WalkStart {
    /// The block it starts in (per axis) and where it leaves it on each
    /// axis (`BlockWalker::state`).
    pub block: [i64; 3],
    pub t_max: [f32; 3],
    /// Where the walk starts and ends (`Segment::walk.0`, `t_out`).
    pub t: f32,
    pub t_out: f32,
    /// Where its stretch with samples ends (`Segment::walk.1`), and its
    /// ray's samples (`Segment::t_end`).
    pub t_stop: f32,
    pub t_end: f32,
}

impl WalkStart {
    /// The start of `w`'s walk.
    #[cfg(packets)]
    pub(super) fn of(w: &RunWalk) -> WalkStart {
        let (block, t_max, t, t_out) = w.walker.state();
        WalkStart {
            block,
            t_max,
            t,
            t_out,
            t_stop: w.seg.walk.1,
            t_end: w.seg.t_end(),
        }
    }
}
