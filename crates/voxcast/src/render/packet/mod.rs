//! SIMD ray packets: sixteen rays (a 4×4 square of a tile) marched in lock-step —
//! in one AVX-512 register, or as two packets of eight in AVX2 registers —
//! for the commonest render — a fixed step (`uniform`, `jitter`),
//! trilinear, flat or Blinn–Phong shaded, front to back — for
//! `importance`, whose march is a fixed step per block (the lanes walk
//! their blocks in vector registers, once per block, for the block's pdf
//! level; the loop samples with each lane's spacing and reads its level's
//! table), for the step-per-block marches (`adaptive` and its
//! rules, S0's grouped reuse; [`runs`]), `lod`, `threshold`, and
//! `stratified` and `mc`, whose lanes draw their own random positions.
//! Back to front is summed front to back with early termination off (the
//! same sum; `Job::packets`).
//!
//! Each lane keeps its own ray: its sample grid `t₀ + k·s`, its first and
//! last sample, and its accumulated colour and opacity; a lane mask drops
//! the rays that have left the volume or terminated, and the packet ends
//! when no lane is left. Per iteration the corners of the trilinear fetch
//! are two to four gathers (the +x neighbour comes in the same 32-bit
//! load; u8 grids are read from a z-paired copy), the transfer-function
//! rows are loaded whole and transposed, and compositing is plain vector
//! arithmetic. Shading needs the gradient's six trilinear fetches; where
//! the colour is only summed, the visible samples wait in a queue and are
//! shaded sixteen at a time ([`shade`]), otherwise in the loop, skipped
//! when no lane's sample is visible. With empty-space skipping a
//! lane whose sample falls in an empty block jumps to its first sample
//! past the empty cube around that block ([`skip_distances`]: one gather
//! of the blocks' distances), so a long empty stretch costs a lane a step
//! or two, not a step per block; a lane in a visible block asks the map
//! again only once past the cube of visible blocks around it.
//!
//! The vector code is written once over the [`simd::Simd`] operations and
//! compiled at each width. Its arithmetic is the scalar path's, operation
//! for operation (no fused multiply-adds where the scalar path has none),
//! so a packet gives the scalar pixels to within the rounding of a few
//! skipped-block boundaries. The last sample of a ray (its stretch ends at
//! the volume's exit, not a full step) is composited by the vector loop
//! too, after the lane's fixed steps, with the stretch's own opacity.
//!
//! Dispatch is at run time ([`level`]): x86-64 with AVX-512 F runs the
//! sixteen lanes in 512-bit registers with mask registers; with AVX2 and
//! FMA, two packets of eight; AArch64 runs four packets of four in NEON
//! registers; any other machine, or `RenderParams::simd = scalar`, takes
//! the scalar loop, which stays the reference. The packets are compiled
//! where `cfg(packets)` is set (`build.rs`: x86-64 and AArch64); elsewhere
//! this module keeps only what the scalar path shares, and the rest of it
//! is unused.

// Built without the packets, the lanes' set-up and state are unused.
#![cfg_attr(not(packets), allow(dead_code, unused_imports))]

use super::composite::Weights;
use super::march::intersect_box;
use super::optics::over_front;
use super::ray::{Counters, Frame};
use super::shading::BlinnPhong;
use super::stats::RenderStats;
use super::surface::{self, SurfaceCtx};
/// One entry point of a packets' loop (`vector`'s, `threshold`'s): a
/// function compiled for `$features` with the loop `$march` of width `$w`
/// inlined into it, the sixteen lanes as packets of `$w`'s width (two of
/// eight at AVX2), for the type choices `$p` (bounded by `$pb`) and the
/// const choices `$c` it passes on.
#[cfg(packets)]
macro_rules! entry {
    ($(#[$doc:meta])* $vis:vis $name:ident, $features:literal, $w:ty, $march:ident<$($c:ident),*>) => {
        entry!($(#[$doc])* $vis $name, $features, $w, $march<[] $($c),*>);
    };
    ($(#[$doc:meta])* $vis:vis $name:ident, $features:literal, $w:ty,
     $march:ident<[$($p:ident: $pb:path),*] $($c:ident),*>) => {
        $(#[$doc])*
        #[target_feature(enable = $features)]
        $vis unsafe fn $name<T: Voxel, R: Runs<T>, $($p: $pb,)* $(const $c: bool),*>(
            pk: &Packets<'_, T, R>,
            lanes: &[Option<Lane>; LANES],
            st: &mut State<'_>,
        ) {
            let n = <$w as Simd>::N;
            for h in (0..LANES).step_by(n).map(|a| a..a + n) {
                if lanes[h.clone()].iter().any(Option::is_some) {
                    $march::<$w, T, R, $($p,)* $($c),*>(pk, &lanes[h.clone()], &mut st.part(h));
                }
            }
        }
    };
}

mod dispatch;
mod distance;
mod importance;
mod mc;
mod runs;
#[cfg(packets)]
mod shade;
mod stratified;
mod threshold;
mod zpairs;

use super::march::RunWalk;
use crate::transfer::LUT_SIZE;
use crate::volume::Voxel;
pub(in crate::render) use distance::skip_distances;
use glam::{Vec3, Vec4};
pub(in crate::render) use importance::Imp;
use importance::ImpLane;
use runs::VParams;
use runs::WalkStart;
pub(in crate::render) use runs::{vector_params, Adapt, Runs};
pub(in crate::render) use stratified::Strat;
pub(in crate::render) use threshold::{LodSelect, Select, Thr};
pub(in crate::render) use zpairs::ZPairs;

/// Lanes of a packet: a 4×4 square of a tile. AVX-512 marches them in one
/// register, AVX2 as two packets of eight.
pub(super) const LANES: usize = 16;

pub use dispatch::{level, Level};

/// Whether the packets can fetch from grid `g`: 32-bit gather offsets, and
/// a +x neighbour in every row (the pair fetch).
pub(super) fn fits<T: Voxel>(g: &crate::volume::Grid<'_, T>) -> bool {
    let (data, step, _, _) = g.layout();
    let bytes = std::mem::size_of_val(data);
    step[0] == 1 && bytes >= 4 && bytes < (i32::MAX as usize) / 2
}

/// What every packet of a render shares; `R`: where the lanes' runs come
/// from, for a step-per-block march ([`Runs`]).
pub(super) struct Packets<'a, T, R = ()> {
    pub f: &'a Frame<'a, T>,
    /// The premultiplied table of the step ([`crate::transfer::Lut::premultiplied`]).
    pub q: &'a [[f32; 4]; LUT_SIZE],
    /// The step in world units.
    pub st: f32,
    pub weights: Weights,
    /// Early-termination threshold (∞ when off).
    pub stop: f32,
    /// Seed of the per-pixel start jitter.
    pub jitter: Option<u64>,
    /// With skipping on, each block's skip distance: how far the empty
    /// space around an empty block reaches, and minus how far the visible
    /// blocks around a visible one reach ([`skip_distances`]; a map may
    /// also hold 0 for a visible block, whose lanes then ask again at their
    /// next sample).
    pub empty: Option<&'a [i32]>,
    /// Blinn–Phong shading (an integer exponent, 0…64; see [`shades`]), or
    /// flat colour.
    pub shading: Option<BlinnPhong>,
    /// The grid's z-paired copy ([`ZPairs`]), of the grid's voxel type.
    pub z_pairs: &'a ZPairs,
    /// The instruction set ([`level`]).
    pub level: Level,
    /// `importance`'s pdf and levels, when the packets march it.
    pub imp: Option<Imp<'a>>,
    /// A step-per-block march, when the packets march one.
    pub runs: Option<&'a R>,
    /// `threshold`'s ranges, steps and tables, when the packets march it.
    pub thr: Option<Thr<'a>>,
    /// `stratified`'s or `mc`'s extinctions, when the packets march it.
    pub strat: Option<Strat<'a>>,
    /// Opaque geometry the rays stop at (S0 Fig. 9–13): a lane's ray ends
    /// at its first hit, and the surface's lit colour is composited
    /// behind what it gathered, as [`super::trace::trace`] does.
    pub surface: Option<SurfaceCtx<'a>>,
}

/// Whether the packets can shade with `bp`: the specular power is taken by
/// repeated squaring, so the exponent must be a whole number (≤ 64).
pub(super) fn shades(bp: &BlinnPhong) -> bool {
    bp.shininess.fract() == 0.0 && (0.0..=64.0).contains(&bp.shininess)
}

/// The lanes' state the vector loop reads and writes besides their rays:
/// the walks (`importance`'s or a step-per-block march's), each lane's
/// colour and opacity, its counts (samples, shaded samples,
/// interpolations) and whether it is still going; `walk` gets what the
/// walks count (`adaptive-s0`'s gradients).
struct State<'s> {
    imp: &'s mut [Option<ImpLane>],
    runs: &'s mut [Option<RunWalk>],
    /// The step-per-block lanes' walks where set up in vector registers
    /// (`runs` then holds none).
    starts: &'s [Option<WalkStart>],
    acc: &'s mut [Vec4],
    count: &'s mut [[u32; 3]],
    alive: &'s mut [bool],
    walk: &'s mut Counters,
    /// `threshold`'s lanes: the end of the walk, and the exit;
    /// `stratified`'s: the walk's start and end.
    ends: &'s [[f32; 2]],
    /// `stratified`'s lanes: their rays' random keys; `mc`'s: their
    /// pixels' random streams.
    keys: &'s [u64],
}

impl State<'_> {
    /// The state of lanes `r` (for a narrower packet).
    #[cfg(packets)]
    fn part(&mut self, r: std::ops::Range<usize>) -> State<'_> {
        State {
            imp: &mut self.imp[r.clone()],
            runs: &mut self.runs[r.clone()],
            starts: &self.starts[r.clone()],
            acc: &mut self.acc[r.clone()],
            count: &mut self.count[r.clone()],
            alive: &mut self.alive[r.clone()],
            walk: self.walk,
            ends: &self.ends[r.clone()],
            keys: &self.keys[r],
        }
    }
}

/// One lane's ray, set up by the scalar code as [`super::trace::trace`]
/// does (or by the out-of-core renderer, from a pixel's state in a brick).
#[derive(Clone, Copy, Default, Debug, PartialEq)]
pub(super) struct Lane {
    /// Origin and direction in the grid's voxel coordinates.
    pub o: Vec3,
    pub d: Vec3,
    /// Towards the eye (world), for shading.
    pub view: Vec3,
    pub t0: f32,
    /// Where the last sample's stretch ends (`Segment::t_end`).
    pub t_end: f32,
    /// Samples `k0..k_end` go through the vector loop.
    pub k0: u32,
    pub k_end: u32,
    /// The last sample, composited with its stretch to `t_end` (by the
    /// vector loop, after the lane's fixed steps).
    pub last: Option<u32>,
}

impl Lane {
    /// A lane that walks its ray (`importance`, a step-per-block march):
    /// no fixed-step samples, its stretches handed out by its walk.
    fn walking(o: Vec3, d: Vec3, view: Vec3, t0: f32, t_end: f32) -> Lane {
        Lane {
            o,
            d,
            view,
            t0,
            t_end,
            k0: 0,
            k_end: 0,
            last: None,
        }
    }
}

/// A lane's ray as [`super::trace::trace`] sets it up: origin and direction
/// in voxel coordinates, entry and exit, and the stretch that meets blocks
/// that are not empty.
struct Setup {
    o: Vec3,
    d: Vec3,
    t_in: f32,
    t_out: f32,
    walk: (f32, f32),
}

impl<T: Voxel, R: Runs<T>> Packets<'_, T, R> {
    /// Sets up the ray `(origin, unit direction)` in world units, ending
    /// at `limit` (its first opaque surface, or ∞), counting it; `None`
    /// when it misses the volume, meets the surface first or meets only
    /// empty blocks.
    fn setup(
        &self,
        (origin, dir): (Vec3, Vec3),
        limit: f32,
        stats: &mut RenderStats,
    ) -> Option<Setup> {
        let f = self.f;
        stats.rays += 1;
        let o = (origin - f.origin_w) * f.inv_spacing;
        let d = dir * f.inv_spacing;
        let inv_d = Vec3::ONE / d;
        let (t_in, t_out) = intersect_box(o, inv_d, f.box_lo, f.box_hi)?;
        if limit <= t_in {
            return None;
        }
        let t_out = t_out.min(limit);
        stats.rays_hit += 1;
        let walk = match f.occupied {
            Some((lo, hi)) => intersect_box(o, inv_d, lo, hi)
                .map(|(a, b)| (a.max(t_in), b.min(t_out)))
                .filter(|(a, b)| a < b)?,
            None => (t_in, t_out),
        };
        Some(Setup {
            o,
            d,
            t_in,
            t_out,
            walk,
        })
    }

    /// The camera's rays through `pixels` (at most [`LANES`]) into
    /// `rays`: [`crate::camera::Camera::ray`]'s, to the bit, computed in
    /// vector registers ([`lanes::camera_rays_avx2`]).
    #[cfg(packets)]
    pub fn camera_rays(
        &self,
        cam: &crate::camera::Camera,
        pixels: &[(u32, u32)],
        rays: &mut [(Vec3, Vec3)],
    ) {
        // SAFETY: `level` checked the CPU before any packet was made.
        unsafe {
            match self.level {
                #[cfg(target_arch = "x86_64")]
                Level::Avx2 | Level::Avx2Loads => lanes::camera_rays_avx2(cam, pixels, rays),
                #[cfg(target_arch = "x86_64")]
                Level::Avx512 | Level::Avx512Loads => lanes::camera_rays_avx512(cam, pixels, rays),
                #[cfg(target_arch = "aarch64")]
                Level::Neon => lanes::camera_rays_neon(cam, pixels, rays),
            }
        }
    }

    /// What [`lanes`]' set-up reads of the render.
    #[cfg(packets)]
    fn geometry(&self) -> lanes::Geometry {
        let f = self.f;
        lanes::Geometry {
            origin_w: f.origin_w,
            inv_spacing: f.inv_spacing,
            box_lo: f.box_lo,
            box_hi: f.box_hi,
            occupied: f.occupied,
            st: self.st,
            block_size: f.block_size,
            block_counts: f.block_counts,
        }
    }

    /// Where pixel `pixel`'s sample grid starts on a ray entering at
    /// `t_in`: moved on by its jitter offset for pass `pass` where the
    /// render jitters (as [`super::trace::trace`]).
    fn grid_start(&self, t_in: f32, pixel: (u32, u32), pass: u32) -> f32 {
        match self.jitter {
            Some(seed) => {
                t_in + super::rng::pixel_sequence(seed, pixel.0, pixel.1, pass) * self.f.step
            }
            None => t_in,
        }
    }

    /// Sets up the ray of pixel `pixel` (`ray`: world origin and unit
    /// direction; ending at `limit`), or `None` when it meets nothing to
    /// sample.
    fn lane(
        &self,
        ray: (Vec3, Vec3),
        limit: f32,
        pixel: (u32, u32),
        pass: u32,
        stats: &mut RenderStats,
    ) -> Option<Lane> {
        let Setup {
            o,
            d,
            t_in,
            t_out,
            walk,
        } = self.setup(ray, limit, stats)?;
        let t0 = self.grid_start(t_in, pixel, pass);
        let st = self.st;
        let k0 = ((walk.0 - t0) / st).ceil().max(0.0) as u32;
        let n1 = ((t_out - t0) / st).ceil().max(0.0) as u32;
        // Past the walk's end every block is empty: nothing to sample.
        let n_end = (((walk.1 - t0) / st).ceil().max(0.0) as u32).min(n1);
        if n_end <= k0 {
            return None;
        }
        let (k_end, last) = if n_end == n1 {
            (n1 - 1, Some(n1 - 1))
        } else {
            (n_end, None)
        };
        Some(Lane {
            o,
            d,
            view: -ray.1,
            t0,
            t_end: t_out + (t0 - t_in),
            k0,
            k_end,
            last,
        })
    }

    /// Renders the pixels `pixels` (at most [`LANES`], `rays` their rays)
    /// for pass `pass`, adding premultiplied colour and opacity to `out`.
    pub fn render(
        &self,
        rays: &[(Vec3, Vec3)],
        pixels: &[(u32, u32)],
        pass: u32,
        out: &mut [Vec4],
        stats: &mut RenderStats,
    ) {
        debug_assert!(rays.len() <= LANES && out.len() == rays.len());
        let mut lanes = [None; LANES];
        let mut imp: [Option<ImpLane>; LANES] = std::array::from_fn(|_| None);
        let mut runs: [Option<RunWalk>; LANES] = std::array::from_fn(|_| None);
        // Each lane's first opaque surface, lit (its colour is composited
        // behind the lane's samples).
        let mut behind: [Option<Vec3>; LANES] = [None; LANES];
        let mut ends = [[0.0f32; 2]; LANES];
        let mut keys = [0u64; LANES];
        // Where each lane's first opaque surface stops its ray (∞: none).
        const _: () = assert!(LANES <= crate::geometry::packet::PACKET);
        let mut limit = [f32::INFINITY; LANES];
        if let Some(s) = self.surface.as_ref() {
            let mut hits = [None; LANES];
            surface::first_hits(
                self.f,
                s,
                rays,
                &mut hits[..rays.len()],
                &mut stats.interpolations,
                |marches, tau| self.shadow_taus(marches, tau),
            );
            for ((h, l), b) in hits.iter().zip(&mut limit).zip(&mut behind) {
                if let Some((t, rgb)) = *h {
                    (*l, *b) = (t, Some(rgb));
                }
            }
        }
        // A fixed step: the lanes set up in vector registers ([`lanes`]);
        // a step-per-block march whose walks run in vector registers: the
        // lanes and where their walks start (`starts`), likewise.
        #[cfg_attr(not(packets), allow(unused_mut))]
        let mut starts: [Option<WalkStart>; LANES] = [None; LANES];
        #[cfg(packets)]
        let vector_runs = R::ON && self.runs.is_some_and(|r| r.vector().is_some());
        #[cfg(packets)]
        let vector_set_up = vector_runs
            || (!R::ON && self.thr.is_none() && self.strat.is_none() && self.imp.is_none());
        #[cfg(not(packets))]
        let vector_set_up = false;
        #[cfg(packets)]
        if vector_set_up {
            let mut jit = [0.0f32; LANES];
            if let Some(seed) = self.jitter {
                for (j, &(x, y)) in jit.iter_mut().zip(pixels) {
                    *j = super::rng::pixel_sequence(seed, x, y, pass) * self.f.step;
                }
            }
            let g = self.geometry();
            stats.rays += rays.len() as u64;
            // SAFETY: `level` checked the CPU before any packet was made.
            stats.rays_hit += unsafe {
                match (self.level, vector_runs) {
                    #[cfg(target_arch = "x86_64")]
                    (Level::Avx2 | Level::Avx2Loads, false) => {
                        lanes::set_up_avx2(&g, rays, &jit, &limit, &mut lanes)
                    }
                    #[cfg(target_arch = "x86_64")]
                    (Level::Avx512 | Level::Avx512Loads, false) => {
                        lanes::set_up_avx512(&g, rays, &jit, &limit, &mut lanes)
                    }
                    #[cfg(target_arch = "x86_64")]
                    (Level::Avx2 | Level::Avx2Loads, true) => {
                        lanes::set_up_runs_avx2(&g, rays, &jit, &limit, &mut lanes, &mut starts)
                    }
                    #[cfg(target_arch = "x86_64")]
                    (Level::Avx512 | Level::Avx512Loads, true) => {
                        lanes::set_up_runs_avx512(&g, rays, &jit, &limit, &mut lanes, &mut starts)
                    }
                    #[cfg(target_arch = "aarch64")]
                    (Level::Neon, false) => lanes::set_up_neon(&g, rays, &jit, &limit, &mut lanes),
                    #[cfg(target_arch = "aarch64")]
                    (Level::Neon, true) => {
                        lanes::set_up_runs_neon(&g, rays, &jit, &limit, &mut lanes, &mut starts)
                    }
                }
            };
        }
        // Otherwise ray by ray.
        if !vector_set_up {
            for (i, (&r, &pixel)) in rays.iter().zip(pixels).enumerate() {
                let limit = limit[i];
                lanes[i] = if R::ON {
                    self.run_lane(r, limit, pixel, pass, stats).map(|(l, w)| {
                        runs[i] = Some(w);
                        l
                    })
                } else if self.thr.is_some() {
                    self.thr_lane(r, limit, pixel, pass, stats).map(|(l, e)| {
                        ends[i] = e;
                        l
                    })
                } else if self.strat.as_ref().is_some_and(|s| s.mc) {
                    self.mc_lane(r, limit, pixel, pass, stats).map(|(l, key)| {
                        keys[i] = key;
                        l
                    })
                } else if self.strat.is_some() {
                    self.strat_lane(r, limit, pixel, pass, stats)
                        .map(|(l, e, key)| {
                            (ends[i], keys[i]) = (e, key);
                            l
                        })
                } else if self.imp.is_some() {
                    self.imp_lane(r, limit, pixel, pass, stats).map(|(l, w)| {
                        imp[i] = Some(w);
                        l
                    })
                } else {
                    self.lane(r, limit, pixel, pass, stats)
                };
            }
        }
        // A ray with nothing to sample shows its surface alone.
        for ((lane, b), out) in lanes.iter().zip(&behind).zip(out.iter_mut()) {
            if let (None, Some(rgb)) = (lane, b) {
                *out += rgb.extend(1.0);
            }
        }
        if lanes.iter().all(Option::is_none) {
            return;
        }
        let mut acc = [Vec4::ZERO; LANES];
        let mut count = [[0u32; 3]; LANES];
        let mut alive = [false; LANES];
        let mut walk = Counters::default();
        let mut st = State {
            imp: &mut imp,
            runs: &mut runs,
            starts: &starts,
            acc: &mut acc,
            count: &mut count,
            alive: &mut alive,
            walk: &mut walk,
            ends: &ends,
            keys: &keys,
        };
        // SAFETY: `level` checked the CPU before any packet was made (the
        // only caller, `Job::packets`, takes it from there), `fits` for the
        // grid and `shades` for the shading.
        #[cfg(packets)]
        unsafe {
            self.dispatch(&lanes, &mut st)
        };
        #[cfg(not(packets))]
        let _ = &mut st;
        let mut n = Counters::default();
        for i in 0..rays.len() {
            if lanes[i].is_none() {
                continue;
            }
            let (mut c, mut a) = (acc[i].truncate(), acc[i].w);
            let terminated = !alive[i];
            n.samples += count[i][0] as u64;
            n.interpolations += count[i][2] as u64;
            n.shaded += count[i][1] as u64;
            stats.early_terminated += terminated as u64;
            if let Some(rgb) = behind[i] {
                over_front(&mut c, &mut a, rgb, 1.0);
            }
            out[i] += c.extend(a);
        }
        stats.samples += n.samples + walk.samples;
        stats.interpolations += n.interpolations + walk.interpolations;
        stats.gradient_interpolations += 6 * (n.shaded + walk.shaded);
    }

    /// Marches samples `k0..k_end` of each lane through the vector loop,
    /// from the colour and opacity `acc` holds (premultiplied), skipping
    /// the empty blocks of `empty` when given; `count` gets each lane's
    /// samples, shaded samples and interpolations, `alive` whether it is
    /// still going (not terminated early). A lane's `last` sample, where
    /// set, is composited too; the out-of-core renderer, whose rays cross
    /// brick after brick and which this is for, sets none and composites
    /// a ray's last sample itself.
    pub fn march_lanes(
        &self,
        lanes: &[Option<Lane>; LANES],
        acc: &mut [Vec4; LANES],
        count: &mut [[u32; 3]; LANES],
        alive: &mut [bool; LANES],
    ) {
        debug_assert!(self.imp.is_none() && self.thr.is_none() && self.strat.is_none() && !R::ON);
        debug_assert!(self
            .empty
            .is_none_or(|e| { e.len() == self.f.block_counts.iter().product::<usize>() }));
        let mut imp: [Option<ImpLane>; LANES] = std::array::from_fn(|_| None);
        let mut runs: [Option<RunWalk>; LANES] = std::array::from_fn(|_| None);
        let mut walk = Counters::default();
        let mut st = State {
            imp: &mut imp,
            runs: &mut runs,
            starts: &[None; LANES],
            acc,
            count,
            alive,
            walk: &mut walk,
            ends: &[[0.0; 2]; LANES],
            keys: &[0; LANES],
        };
        // SAFETY: as in `render`: the caller took `level` from [`level`],
        // checked [`fits`] for the grid and [`shades`] for the shading;
        // `empty`, when given, holds a flag per block of the frame's
        // `block_counts`.
        #[cfg(packets)]
        unsafe {
            self.dispatch(lanes, &mut st)
        }
        #[cfg(not(packets))]
        let _ = (lanes, &mut st);
    }

    /// Runs the vector loop compiled for this render's choices —
    /// skipping, shading, `importance`, grouped runs — at the packets'
    /// level.
    ///
    /// # Safety
    /// `self.level` from [`level`] on this CPU; the grid [`fits`], the
    /// shading [`shades`]; `empty`, when given, a flag per block.
    #[cfg(packets)]
    unsafe fn dispatch(&self, lanes: &[Option<Lane>; LANES], st: &mut State<'_>) {
        // Grouped reuse: in the step-per-block runs, or in `threshold`'s
        // own loop.
        let grouped =
            self.runs.is_some_and(|r| r.grouped()) || self.thr.as_ref().is_some_and(|t| t.grouped);
        let choice = (
            self.empty.is_some(),
            self.shading.is_some(),
            self.imp.is_some(),
            grouped,
        );
        // Only the combinations a render can ask for are instantiated:
        // `Job::packets` skips empty blocks only on the fixed step (no
        // runs) and groups only in runs (or in `threshold`'s loop, below);
        // `importance` has no runs. `R::ON` is known at compile time, so
        // the other branch is not built: 176 copies of the march where all
        // combinations made 320 (`cargo llvm-lines`), and the march was
        // most of the crate's build time.
        macro_rules! go {
            ($f:ident) => {
                if R::ON {
                    match choice {
                        (false, false, false, false) => {
                            vector::$f::<T, R, false, false, false, false>(self, lanes, st)
                        }
                        (false, true, false, false) => {
                            vector::$f::<T, R, false, true, false, false>(self, lanes, st)
                        }
                        (false, false, false, true) => {
                            vector::$f::<T, R, false, false, false, true>(self, lanes, st)
                        }
                        (false, true, false, true) => {
                            vector::$f::<T, R, false, true, false, true>(self, lanes, st)
                        }
                        _ => unreachable!("packets: skipping or importance with runs"),
                    }
                } else {
                    match choice {
                        (false, false, false, false) => {
                            vector::$f::<T, R, false, false, false, false>(self, lanes, st)
                        }
                        (true, false, false, false) => {
                            vector::$f::<T, R, true, false, false, false>(self, lanes, st)
                        }
                        (false, true, false, false) => {
                            vector::$f::<T, R, false, true, false, false>(self, lanes, st)
                        }
                        (true, true, false, false) => {
                            vector::$f::<T, R, true, true, false, false>(self, lanes, st)
                        }
                        (false, false, true, false) => {
                            vector::$f::<T, R, false, false, true, false>(self, lanes, st)
                        }
                        (false, true, true, false) => {
                            vector::$f::<T, R, false, true, true, false>(self, lanes, st)
                        }
                        _ => unreachable!("packets: grouping without runs"),
                    }
                }
            };
        }
        if !R::ON && self.thr.is_some() {
            // `threshold`: skipping, shading and grouped reuse (its own
            // loop).
            // `lod` (its own selection in the same loop) is never grouped.
            use threshold::{ByLeaf, ByRange};
            let lod = matches!(self.thr.as_ref().map(|t| &t.select), Some(Select::Lod(_)));
            macro_rules! thr {
                ($f:ident) => {
                    match (lod, choice.0, choice.1, choice.3) {
                        (false, false, false, false) => {
                            threshold::$f::<T, R, ByRange, false, false, false>(self, lanes, st)
                        }
                        (false, true, false, false) => {
                            threshold::$f::<T, R, ByRange, true, false, false>(self, lanes, st)
                        }
                        (false, false, true, false) => {
                            threshold::$f::<T, R, ByRange, false, true, false>(self, lanes, st)
                        }
                        (false, true, true, false) => {
                            threshold::$f::<T, R, ByRange, true, true, false>(self, lanes, st)
                        }
                        (false, false, false, true) => {
                            threshold::$f::<T, R, ByRange, false, false, true>(self, lanes, st)
                        }
                        (false, true, false, true) => {
                            threshold::$f::<T, R, ByRange, true, false, true>(self, lanes, st)
                        }
                        (false, false, true, true) => {
                            threshold::$f::<T, R, ByRange, false, true, true>(self, lanes, st)
                        }
                        (false, true, true, true) => {
                            threshold::$f::<T, R, ByRange, true, true, true>(self, lanes, st)
                        }
                        (true, false, false, _) => {
                            threshold::$f::<T, R, ByLeaf, false, false, false>(self, lanes, st)
                        }
                        (true, true, false, _) => {
                            threshold::$f::<T, R, ByLeaf, true, false, false>(self, lanes, st)
                        }
                        (true, false, true, _) => {
                            threshold::$f::<T, R, ByLeaf, false, true, false>(self, lanes, st)
                        }
                        (true, true, true, _) => {
                            threshold::$f::<T, R, ByLeaf, true, true, false>(self, lanes, st)
                        }
                    }
                };
            }
            return match self.level {
                #[cfg(target_arch = "x86_64")]
                Level::Avx2 => thr!(thr_avx2),
                #[cfg(target_arch = "x86_64")]
                Level::Avx2Loads => thr!(thr_avx2_loads),
                #[cfg(target_arch = "x86_64")]
                Level::Avx512 => thr!(thr_avx512),
                #[cfg(target_arch = "x86_64")]
                Level::Avx512Loads => thr!(thr_avx512_loads),
                #[cfg(target_arch = "aarch64")]
                Level::Neon => thr!(thr_neon),
            };
        }
        if !R::ON && self.strat.is_some() {
            // `stratified` and `mc`: their own loop, which reads skipping,
            // shading and which of the two as flags.
            return match self.level {
                #[cfg(target_arch = "x86_64")]
                Level::Avx2 => stratified::strat_avx2::<T, R>(self, lanes, st),
                #[cfg(target_arch = "x86_64")]
                Level::Avx2Loads => stratified::strat_avx2_loads::<T, R>(self, lanes, st),
                #[cfg(target_arch = "x86_64")]
                Level::Avx512 => stratified::strat_avx512::<T, R>(self, lanes, st),
                #[cfg(target_arch = "x86_64")]
                Level::Avx512Loads => stratified::strat_avx512_loads::<T, R>(self, lanes, st),
                #[cfg(target_arch = "aarch64")]
                Level::Neon => stratified::strat_neon::<T, R>(self, lanes, st),
            };
        }
        match self.level {
            #[cfg(target_arch = "x86_64")]
            Level::Avx2 => go!(march_avx2),
            #[cfg(target_arch = "x86_64")]
            Level::Avx2Loads => go!(march_avx2_loads),
            #[cfg(target_arch = "x86_64")]
            Level::Avx512 => go!(march_avx512),
            #[cfg(target_arch = "x86_64")]
            Level::Avx512Loads => go!(march_avx512_loads),
            #[cfg(target_arch = "aarch64")]
            Level::Neon => go!(march_neon),
        }
    }

    /// Each lane's sum of the extinction at its shadow ray's samples
    /// ([`surface::march_tau`]), all lanes at once in vector registers.
    fn shadow_taus(&self, marches: &[Option<surface::ShadowMarch>; LANES], tau: &mut [f32; LANES]) {
        // SAFETY: `level` checked the CPU before any packet was made (the
        // only caller, `Job::packets`, takes it from there), `fits` for the
        // grid.
        #[cfg(packets)]
        unsafe {
            match self.level {
                #[cfg(target_arch = "x86_64")]
                Level::Avx2 => shadow::taus_avx2(self, marches, tau),
                #[cfg(target_arch = "x86_64")]
                Level::Avx2Loads => shadow::taus_avx2_loads(self, marches, tau),
                #[cfg(target_arch = "x86_64")]
                Level::Avx512 => shadow::taus_avx512(self, marches, tau),
                #[cfg(target_arch = "x86_64")]
                Level::Avx512Loads => shadow::taus_avx512_loads(self, marches, tau),
                #[cfg(target_arch = "aarch64")]
                Level::Neon => shadow::taus_neon(self, marches, tau),
            }
        }
        #[cfg(not(packets))]
        for (m, t) in marches.iter().zip(tau) {
            if let Some(m) = m {
                *t = surface::march_tau(self.f, m);
            }
        }
    }
}

#[cfg(packets)]
mod fetch;
#[cfg(packets)]
mod lanes;
#[cfg(packets)]
mod shadow;
#[cfg(packets)]
mod simd;
#[cfg(packets)]
mod tail;
#[cfg(packets)]
mod vector;
#[cfg(packets)]
mod vwalk;
#[cfg(packets)]
mod walk;
