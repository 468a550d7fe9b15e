//! The per-brick ray loop of the out-of-core renderer. Every pixel keeps
//! its ray's state between bricks — composited colour and opacity, and the
//! index of its next sample on the grid `t₀ + k·step` — so bricks taken in
//! visibility order march each ray's samples in order, each exactly once,
//! at the positions the in-core `uniform` march takes them. The rays are
//! in the base level's voxel coordinates (the finest level the frame
//! reads); a brick of a coarser level takes every `stride`-th sample of the
//! base grid, in its own voxel coordinates (see the `plan` module).

use super::plan::LevelGeo;
use crate::render::march::intersect_box;
use crate::render::optics::over_front;
use crate::render::packet::Lane;
use crate::render::shading::BlinnPhong;
use crate::transfer::{Lut, LUT_SIZE};
use crate::volume::{Grid, Voxel};
use glam::{Vec3, Vec4};

/// One pixel's ray between bricks.
#[derive(Clone, Copy, Debug)]
pub(super) struct Px {
    /// Premultiplied colour and opacity so far.
    pub c: Vec3,
    pub a: f32,
    /// The ray in the base level's voxel coordinates (`t` in world units).
    pub o: Vec3,
    pub d: Vec3,
    /// `1 / d`, for the bricks' slab tests.
    pub inv_d: Vec3,
    /// Towards the eye (world), for shading.
    pub view: Vec3,
    /// Start of the sample grid and end of the last sample's stretch.
    pub t0: f32,
    pub t_end: f32,
    /// The next sample to take and the ray's last one.
    pub next: u32,
    pub last: u32,
    /// Still marching (met the volume, not terminated).
    pub live: bool,
    pub terminated: bool,
}

impl Px {
    /// The pixel's ray clipped to the base level's sample box `[lo, hi]`;
    /// `jitter` the start offset in steps (0 without jitter).
    pub fn start(o: Vec3, d: Vec3, view: Vec3, (lo, hi): (Vec3, Vec3), st: f32, jitter: f32) -> Px {
        let mut p = Px {
            c: Vec3::ZERO,
            a: 0.0,
            o,
            d,
            inv_d: Vec3::ONE / d,
            view,
            t0: 0.0,
            t_end: 0.0,
            next: 0,
            last: 0,
            live: false,
            terminated: false,
        };
        if let Some((t_in, t_out)) = intersect_box(o, p.inv_d, lo, hi) {
            let t0 = t_in + jitter * st;
            let n = ((t_out - t0) / st).ceil();
            if n >= 1.0 {
                p.t0 = t0;
                p.t_end = t_out + (t0 - t_in);
                p.last = n as u32 - 1;
                p.live = true;
            }
        }
        p
    }

    /// The colour of the finished ray.
    pub fn finish(&self) -> Vec4 {
        self.c.extend(self.a)
    }
}

/// What one brick's march shares.
pub(super) struct BrickFrame<'a, T> {
    pub grid: Grid<'a, T>,
    /// The brick's level, in terms of the base.
    pub geo: &'a LevelGeo<'a>,
    /// The brick's data box starts at this voxel (level coordinates).
    pub data_lo: Vec3,
    /// The samples the brick owns lie in `[own_lo, own_hi]` (base
    /// coordinates).
    pub own_lo: Vec3,
    pub own_hi: Vec3,
    pub lut: &'a Lut,
    /// The premultiplied table of one of the level's steps.
    pub q: &'a [[f32; 4]; LUT_SIZE],
    /// The base step (world units).
    pub st: f32,
    pub unit: f32,
    pub inv_spacing: Vec3,
    pub emission: f32,
    pub absorption: f32,
    /// Opacity at which a ray stops (∞: never).
    pub stop: f32,
    pub shading: Option<BlinnPhong>,
}

/// Counts of one row's work.
#[derive(Default, Clone, Copy)]
pub(super) struct RowCount {
    pub samples: u64,
    pub shaded: u64,
    pub terminated: u64,
}

/// Where the ray of `px` crosses the brick's own box (`None`: it does
/// not, or the ray is done); [`lane`] and [`march`] start from it.
#[inline]
pub(super) fn span<T: Voxel>(f: &BrickFrame<'_, T>, px: &Px) -> Option<(f32, f32)> {
    if !px.live {
        return None;
    }
    intersect_box(px.o, px.inv_d, f.own_lo, f.own_hi)
}

/// The packets' lane for the samples of `px` in the brick but the ray's
/// last (which the scalar [`march`] composites with its stretch): the
/// brick's own box clipped as [`march`] clips it, in the brick's voxel
/// coordinates, stepping the level's step from the ray's next sample; and
/// the ray's next sample once the lane is marched. `None` when there is no
/// such sample. `(ta, tb)`: the ray's [`span`] in the brick.
pub(super) fn lane<T: Voxel>(
    f: &BrickFrame<'_, T>,
    px: &Px,
    (ta, tb): (f32, f32),
) -> Option<(Lane, u32)> {
    let first = ((ta - px.t0) / f.st).ceil().max(0.0);
    let k0 = px.next.max(first.min(u32::MAX as f32) as u32);
    // The first sample at or past the brick's exit, by the scalar loop's
    // own test `t >= tb`.
    let mut kb = ((tb - px.t0) / f.st).ceil().max(0.0).min(u32::MAX as f32) as u32;
    while kb > 0 && px.t0 + (kb - 1) as f32 * f.st >= tb {
        kb -= 1;
    }
    while kb < u32::MAX && px.t0 + kb as f32 * f.st < tb {
        kb += 1;
    }
    // The brick takes samples k0, k0 + m, …: in the lane's terms, samples
    // j of the grid t0 + phase·st + j·(m·st) (for m = 1, the ray's own).
    let m = f.geo.stride;
    let phase = k0 % m;
    if px.last < phase {
        return None;
    }
    let j_exit = (kb.saturating_sub(phase)).div_ceil(m);
    let j_last = (px.last - phase) / m;
    let (j0, j_end) = (k0 / m, j_exit.min(j_last));
    (j0 < j_end).then(|| {
        (
            Lane {
                o: f.geo.to_level(px.o) - f.data_lo,
                d: f.geo.dir_to_level(px.d),
                view: px.view,
                t0: px.t0 + phase as f32 * f.st,
                t_end: px.t_end,
                k0: j0,
                k_end: j_end,
                last: None,
            },
            phase + j_end * m,
        )
    })
}

/// Marches the samples of `px` that fall in the brick, whose [`span`] is
/// `(ta, tb)` (the packets may have ended the ray since).
#[inline]
pub(super) fn march<T: Voxel>(
    f: &BrickFrame<'_, T>,
    px: &mut Px,
    (ta, tb): (f32, f32),
    n: &mut RowCount,
) {
    if !px.live {
        return;
    }
    let first = ((ta - px.t0) / f.st).ceil().max(0.0);
    let mut k = px.next.max(first.min(u32::MAX as f32) as u32);
    let (o, d) = (f.geo.to_level(px.o), f.geo.dir_to_level(px.d));
    let m = f.geo.stride;
    while k <= px.last {
        let t = px.t0 + k as f32 * f.st;
        if t >= tb {
            break;
        }
        // The in-core march's position, then an exact shift by whole voxels
        // (p ≥ data_lo, so the difference is representable): the same
        // trilinear weights and voxels as the in-core render (at the base
        // level, where `o` and `d` are the ray's own).
        let p = o + d * t;
        let value = f.grid.sample(p - f.data_lo);
        n.samples += 1;
        k = k.saturating_add(m);
        let Some(i) = Lut::index(value) else {
            continue;
        };
        let q = f.q[i];
        if q[3] <= 0.0 {
            continue;
        }
        let (mut e, mut alpha) = (Vec3::new(q[0], q[1], q[2]), q[3]);
        if let Some(bp) = &f.shading {
            let c = f.lut.entry(i);
            let g = f.grid.gradient(p - f.data_lo);
            n.shaded += 1;
            e = bp.shade(Vec3::new(c[0], c[1], c[2]), g, f.inv_spacing, px.view) * alpha;
        }
        if k > px.last {
            // The last sample stands for the stretch up to the ray's end.
            let ds = (px.t_end - t).max(0.0);
            let a2 = 1.0 - (-f.lut.sigma(i) * ds / f.unit).exp();
            e *= a2 / alpha;
            alpha = a2;
        }
        over_front(&mut px.c, &mut px.a, e * f.emission, alpha * f.absorption);
        if px.a >= f.stop {
            px.live = false;
            px.terminated = true;
            n.terminated += 1;
            break;
        }
    }
    px.next = k;
    if k > px.last {
        px.live = false;
    }
}
