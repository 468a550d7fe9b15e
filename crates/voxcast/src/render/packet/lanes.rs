//! A fixed-step packet's lanes set up in vector registers: the sixteen
//! rays' voxel-space origin and direction, their entry and exit of the
//! volume's box and of the occupied box, and their first and last sample
//! — what [`Packets::lane`](super::Packets) computes ray by ray — as a few
//! vector operations for all of them. The divisions (three per ray for the
//! box, three for the sample indices), the box tests' chains of `min` and
//! `max` and the `ceil`s (a library call in the scalar build) were about a
//! tenth of an unshaded teapot frame.
//!
//! The arithmetic is the scalar set-up's, operation for operation, so the
//! lanes are the same bits, down to how each `min` and `max` treats a NaN
//! (a ray parallel to a box face, starting on its plane: `0 · ∞`) and
//! which zero of two it keeps: glam's `Vec3::min` is the instruction's
//! rule, `f32::min` another ([`fmin`]).

use super::simd::Simd;
#[cfg(target_arch = "aarch64")]
use super::simd::W4;
#[cfg(target_arch = "x86_64")]
use super::simd::{W16, W8};
use super::{Lane, WalkStart, LANES};
use crate::camera::{Camera, Projection};
use glam::Vec3;

/// What the set-up reads of a render (the fields of its `Frame` and the
/// packets' step).
#[derive(Clone, Copy)]
pub(super) struct Geometry {
    pub origin_w: Vec3,
    pub inv_spacing: Vec3,
    pub box_lo: Vec3,
    pub box_hi: Vec3,
    pub occupied: Option<(Vec3, Vec3)>,
    /// The step in voxel-space ray units.
    pub st: f32,
    /// The block grid the step-per-block marches walk.
    pub block_size: usize,
    pub block_counts: [usize; 3],
}

/// `f32::min` as x86-64 builds it: where `a` is NaN, `b`; else the
/// instruction's `b < a ? b : a` (which gives `a` where `b` is NaN, and
/// picks the same zero of two).
#[inline(always)]
unsafe fn fmin<S: Simd>(a: S::F, b: S::F) -> S::F {
    S::blend(S::eq(a, a), b, S::min(b, a))
}

/// `f32::max` as x86-64 builds it (see [`fmin`]).
#[inline(always)]
unsafe fn fmax<S: Simd>(a: S::F, b: S::F) -> S::F {
    S::blend(S::eq(a, a), b, S::max(b, a))
}

/// One axis of the box test: the nearer and the farther crossing of the
/// planes `lo` and `hi`, by glam's `Vec3::min`/`max` (`t0 < t1 ? t0 :
/// t1`, the instructions' own rule: NaN where `t1` is, on the `hi`
/// plane); the chains after it take `f32`'s, which drop a NaN.
#[inline(always)]
unsafe fn slab<S: Simd>(o: S::F, inv_d: S::F, lo: f32, hi: f32) -> (S::F, S::F) {
    let t0 = (S::splat(lo) - o) * inv_d;
    let t1 = (S::splat(hi) - o) * inv_d;
    (S::min(t0, t1), S::max(t0, t1))
}

/// [`crate::render::march::intersect_box`] for the lanes: entry, exit,
/// and the lanes that meet the box (`exit > entry`).
#[inline(always)]
unsafe fn intersect<S: Simd>(
    o: [S::F; 3],
    inv_d: [S::F; 3],
    lo: Vec3,
    hi: Vec3,
) -> (S::F, S::F, S::M) {
    let (x0, x1) = slab::<S>(o[0], inv_d[0], lo.x, hi.x);
    let (y0, y1) = slab::<S>(o[1], inv_d[1], lo.y, hi.y);
    let (z0, z1) = slab::<S>(o[2], inv_d[2], lo.z, hi.z);
    let enter = fmax::<S>(fmax::<S>(fmax::<S>(x0, y0), z0), S::splat(0.0));
    let exit = fmin::<S>(fmin::<S>(x1, y1), z1);
    (enter, exit, S::gt(exit, enter))
}

/// `max(ceil(x), 0)`: a sample index as `Packets::lane` takes it (`ceil`,
/// then `max(0.0)`, then a cast to `u32` that the callers undo exactly).
#[inline(always)]
unsafe fn index<S: Simd>(x: S::F) -> S::F {
    S::max(S::ceil(x), S::splat(0.0))
}

/// A packet's rays in registers, as the set-ups take them: voxel-space
/// origins and directions, the directions' reciprocals, the lanes' grid
/// offsets; their entry into and exit from the volume's box, the lanes
/// that meet it; and the stretch that meets the occupied box and the lanes
/// that meet that (the whole ray, without one).
struct Rays<S: Simd> {
    o: [S::F; 3],
    d: [S::F; 3],
    inv_d: [S::F; 3],
    jit: S::F,
    t_in: S::F,
    t_out: S::F,
    hit: S::M,
    walk: (S::F, S::F),
    ok: S::M,
}

/// `rays[base..base + n]` (`n ≤ S::N`) with their offsets `jit`, each
/// ending at its `limit` (its first opaque surface, or ∞), as
/// `Packets::setup` computes them ray by ray.
///
/// # Safety
/// The width's instructions.
#[inline(always)]
unsafe fn rays_at<S: Simd>(
    g: &Geometry,
    rays: &[(Vec3, Vec3)],
    jit: &[f32; LANES],
    limit: &[f32; LANES],
    base: usize,
    n: usize,
) -> Rays<S> {
    let mut a = [S::Af::default(); 8];
    for (i, (o, d)) in rays[base..base + n].iter().enumerate() {
        a[0][i] = o.x;
        a[1][i] = o.y;
        a[2][i] = o.z;
        a[3][i] = d.x;
        a[4][i] = d.y;
        a[5][i] = d.z;
        a[6][i] = jit[base + i];
        a[7][i] = limit[base + i];
    }
    // Voxel space: `(origin − origin_w) · inv_spacing`, `dir · inv_spacing`.
    let (ow, is) = (g.origin_w, g.inv_spacing);
    let o = [
        (S::load(a[0]) - S::splat(ow.x)) * S::splat(is.x),
        (S::load(a[1]) - S::splat(ow.y)) * S::splat(is.y),
        (S::load(a[2]) - S::splat(ow.z)) * S::splat(is.z),
    ];
    let d = [
        S::load(a[3]) * S::splat(is.x),
        S::load(a[4]) * S::splat(is.y),
        S::load(a[5]) * S::splat(is.z),
    ];
    let one = S::splat(1.0);
    let inv_d = [one / d[0], one / d[1], one / d[2]];
    let (t_in, t_out, hit) = intersect::<S>(o, inv_d, g.box_lo, g.box_hi);
    let hit = S::and(hit, S::from_bits((1u32 << n) - 1));
    // A ray whose surface comes before the volume samples nothing; the
    // others stop at theirs (`t_out.min(limit)`).
    let limit = S::load(a[7]);
    let hit = S::and(hit, S::lt(t_in, limit));
    let t_out = fmin::<S>(t_out, limit);
    let (w0, w1, ok) = match g.occupied {
        Some((lo, hi)) => {
            let (a0, b0, m) = intersect::<S>(o, inv_d, lo, hi);
            let (a0, b0) = (fmax::<S>(a0, t_in), fmin::<S>(b0, t_out));
            (a0, b0, S::and(hit, S::and(m, S::lt(a0, b0))))
        }
        None => (t_in, t_out, hit),
    };
    Rays {
        o,
        d,
        inv_d,
        jit: S::load(a[6]),
        t_in,
        t_out,
        hit,
        walk: (w0, w1),
        ok,
    }
}

/// Sets up `lanes[..rays.len()]` as `Packets::lane` does (`rays`: world
/// origin and unit direction; `jit[i]`: lane `i`'s grid offset, its jitter
/// times the step, 0 without jitter; `limit[i]`: where its first opaque
/// surface stops it, ∞ where none does).
/// Returns how many rays met the volume's box.
///
/// # Safety
/// The width's instructions.
#[inline(always)]
unsafe fn set_up<S: Simd>(
    g: &Geometry,
    rays: &[(Vec3, Vec3)],
    jit: &[f32; LANES],
    limit: &[f32; LANES],
    lanes: &mut [Option<Lane>; LANES],
) -> u64 {
    let mut hits = 0;
    for base in (0..rays.len()).step_by(S::N) {
        let n = (rays.len() - base).min(S::N);
        let Rays {
            o,
            d,
            jit,
            t_in,
            t_out,
            hit,
            walk: (w0, w1),
            ok,
            ..
        } = rays_at::<S>(g, rays, jit, limit, base, n);
        hits += S::bits(hit).count_ones() as u64;
        let t0 = t_in + jit;
        let st = S::splat(g.st);
        let k0 = index::<S>((w0 - t0) / st);
        let n1 = index::<S>((t_out - t0) / st);
        let n_end = S::min(index::<S>((w1 - t0) / st), n1);
        let ok = S::bits(S::and(ok, S::gt(n_end, k0)));
        let ends = S::bits(S::eq(n_end, n1));
        let t_end = t_out + (t0 - t_in);
        // (No `map` with a closure: it would not inherit the width.)
        let v = [
            S::store(o[0]),
            S::store(o[1]),
            S::store(o[2]),
            S::store(d[0]),
            S::store(d[1]),
            S::store(d[2]),
            S::store(t0),
            S::store(t_end),
            S::store(k0),
            S::store(n_end),
        ];
        for (i, (_, dir)) in rays[base..base + n].iter().enumerate() {
            lanes[base + i] = (ok >> i & 1 == 1).then(|| {
                let n_end = v[9][i] as u32;
                let (k_end, last) = if ends >> i & 1 == 1 {
                    (n_end - 1, Some(n_end - 1))
                } else {
                    (n_end, None)
                };
                Lane {
                    o: Vec3::new(v[0][i], v[1][i], v[2][i]),
                    d: Vec3::new(v[3][i], v[4][i], v[5][i]),
                    view: -*dir,
                    t0: v[6][i],
                    t_end: v[7][i],
                    k0: v[8][i] as u32,
                    k_end,
                    last,
                }
            });
        }
    }
    hits
}

/// `BlockWalker::new` on one axis for rays starting at `t`: the block
/// the walk starts in (a whole number as a float) and where the ray
/// leaves it (∞ where it does not move on the axis).
#[inline(always)]
unsafe fn first_block<S: Simd>(
    o: S::F,
    d: S::F,
    inv_d: S::F,
    t: S::F,
    size: f32,
    count: usize,
) -> (S::F, S::F) {
    let (zero, one, b) = (S::splat(0.0), S::splat(1.0), S::splat(size));
    let q = (o + d * t) / b;
    let (up, down) = (S::gt(d, zero), S::lt(d, zero));
    // On a boundary, a ray going down belongs to the block below.
    let c = S::blend(down, S::floor(q), S::ceil(q) - one);
    // The cast to a whole number takes NaN to 0; then the clamp.
    let c = S::blend(S::eq(c, c), zero, c);
    let c = S::min(S::max(c, zero), S::splat(count as f32 - 1.0));
    // `crossing`: the far plane's `(plane − o)·(1/d)`.
    let plane = S::blend(up, c, c + one);
    let tm = (plane * b - o) * inv_d;
    (c, S::blend(S::or(up, down), S::splat(f32::INFINITY), tm))
}

/// Sets up `lanes[..rays.len()]` and their block walks `starts` as
/// `Packets::run_lane` and `RunWalk::new` do for the step-per-block
/// marches' rays (the arguments as [`set_up`]'s).
/// Returns how many rays met the volume's box.
///
/// # Safety
/// The width's instructions.
#[inline(always)]
unsafe fn set_up_runs<S: Simd>(
    g: &Geometry,
    rays: &[(Vec3, Vec3)],
    jit: &[f32; LANES],
    limit: &[f32; LANES],
    lanes: &mut [Option<Lane>; LANES],
    starts: &mut [Option<WalkStart>; LANES],
) -> u64 {
    let mut hits = 0;
    let (size, counts) = (g.block_size as f32, g.block_counts);
    for base in (0..rays.len()).step_by(S::N) {
        let n = (rays.len() - base).min(S::N);
        let Rays {
            o,
            d,
            inv_d,
            jit,
            t_in,
            t_out,
            hit,
            walk: (w0, w1),
            ok,
        } = rays_at::<S>(g, rays, jit, limit, base, n);
        hits += S::bits(hit).count_ones() as u64;
        let t0 = t_in + jit;
        let t_end = t_out + (t0 - t_in);
        let (bx, tx) = first_block::<S>(o[0], d[0], inv_d[0], w0, size, counts[0]);
        let (by, ty) = first_block::<S>(o[1], d[1], inv_d[1], w0, size, counts[1]);
        let (bz, tz) = first_block::<S>(o[2], d[2], inv_d[2], w0, size, counts[2]);
        let ok = S::bits(ok);
        let v = [
            S::store(o[0]),
            S::store(o[1]),
            S::store(o[2]),
            S::store(d[0]),
            S::store(d[1]),
            S::store(d[2]),
            S::store(t0),
            S::store(t_end),
            S::store(w0),
            S::store(w1),
            S::store(t_out),
            S::store(bx),
            S::store(by),
            S::store(bz),
            S::store(tx),
            S::store(ty),
            S::store(tz),
        ];
        for (i, (_, dir)) in rays[base..base + n].iter().enumerate() {
            if ok >> i & 1 == 0 {
                lanes[base + i] = None;
                starts[base + i] = None;
                continue;
            }
            lanes[base + i] = Some(Lane::walking(
                Vec3::new(v[0][i], v[1][i], v[2][i]),
                Vec3::new(v[3][i], v[4][i], v[5][i]),
                -*dir,
                v[6][i],
                v[7][i],
            ));
            starts[base + i] = Some(WalkStart {
                block: [v[11][i] as i64, v[12][i] as i64, v[13][i] as i64],
                t_max: [v[14][i], v[15][i], v[16][i]],
                t: v[8][i],
                t_out: v[10][i],
                t_stop: v[9][i],
                t_end: v[7][i],
            });
        }
    }
    hits
}

/// [`Camera::ray`] for each pixel of `pixels` into `rays` (as many),
/// `S::N` at a time: its operations in its order — multiplications,
/// additions, divisions and the square root round the same in a lane as
/// in a scalar register — so the same bits.
///
/// # Safety
/// The width's instructions.
///
/// [`Camera::ray`]: crate::camera::Camera::ray
#[inline(always)]
unsafe fn camera_rays<S: Simd>(c: &Camera, pixels: &[(u32, u32)], rays: &mut [(Vec3, Vec3)]) {
    debug_assert!(rays.len() == pixels.len());
    for base in (0..pixels.len()).step_by(S::N) {
        let n = (pixels.len() - base).min(S::N);
        let (mut px, mut py) = (S::Af::default(), S::Af::default());
        for (i, &(x, y)) in pixels[base..base + n].iter().enumerate() {
            px[i] = x as f32 + 0.5;
            py[i] = y as f32 + 0.5;
        }
        let (one, two) = (S::splat(1.0), S::splat(2.0));
        let hh = S::splat(c.half_height);
        let sx = (two * S::load(px) / S::splat(c.width as f32) - one) * hh * S::splat(c.aspect);
        let sy = (one - two * S::load(py) / S::splat(c.height as f32)) * hh;
        // `b + right·sx + up·sy`: the direction's (perspective) or the
        // origin's (orthographic), component by component.
        let ortho = c.projection == Projection::Orthographic;
        let b = if ortho { c.eye } else { c.forward };
        let (r, u) = (c.right, c.up);
        let v = [
            S::splat(b.x) + S::splat(r.x) * sx + S::splat(u.x) * sy,
            S::splat(b.y) + S::splat(r.y) * sx + S::splat(u.y) * sy,
            S::splat(b.z) + S::splat(r.z) * sx + S::splat(u.z) * sy,
        ];
        if ortho {
            let o = [S::store(v[0]), S::store(v[1]), S::store(v[2])];
            for (i, ray) in rays[base..base + n].iter_mut().enumerate() {
                *ray = (Vec3::new(o[0][i], o[1][i], o[2][i]), c.forward);
            }
        } else {
            // glam's `normalize`: times the reciprocal of the length.
            let inv = one / S::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
            let d = [
                S::store(v[0] * inv),
                S::store(v[1] * inv),
                S::store(v[2] * inv),
            ];
            for (i, ray) in rays[base..base + n].iter_mut().enumerate() {
                *ray = (c.eye, Vec3::new(d[0][i], d[1][i], d[2][i]));
            }
        }
    }
}

/// [`set_up`], [`set_up_runs`] and [`camera_rays`] compiled for one
/// width's instructions, under the names `$set_up`, `$set_up_runs` and
/// `$camera_rays`.
macro_rules! at_width {
    ($arch:literal, $features:literal, $w:ty, $set_up:ident, $set_up_runs:ident, $camera_rays:ident) => {
        #[doc = concat!("[`set_up`] at `", stringify!($w), "`.")]
        ///
        /// # Safety
        /// The CPU has the width's instructions.
        #[cfg(target_arch = $arch)]
        #[target_feature(enable = $features)]
        pub(super) unsafe fn $set_up(
            g: &Geometry,
            rays: &[(Vec3, Vec3)],
            jit: &[f32; LANES],
            limit: &[f32; LANES],
            lanes: &mut [Option<Lane>; LANES],
        ) -> u64 {
            set_up::<$w>(g, rays, jit, limit, lanes)
        }

        #[doc = concat!("[`set_up_runs`] at `", stringify!($w), "`.")]
        ///
        /// # Safety
        /// The CPU has the width's instructions.
        #[cfg(target_arch = $arch)]
        #[target_feature(enable = $features)]
        pub(super) unsafe fn $set_up_runs(
            g: &Geometry,
            rays: &[(Vec3, Vec3)],
            jit: &[f32; LANES],
            limit: &[f32; LANES],
            lanes: &mut [Option<Lane>; LANES],
            starts: &mut [Option<WalkStart>; LANES],
        ) -> u64 {
            set_up_runs::<$w>(g, rays, jit, limit, lanes, starts)
        }

        #[doc = concat!("[`camera_rays`] at `", stringify!($w), "`.")]
        ///
        /// # Safety
        /// The CPU has the width's instructions.
        #[cfg(target_arch = $arch)]
        #[target_feature(enable = $features)]
        pub(super) unsafe fn $camera_rays(
            c: &Camera,
            pixels: &[(u32, u32)],
            rays: &mut [(Vec3, Vec3)],
        ) {
            camera_rays::<$w>(c, pixels, rays)
        }
    };
}

// AVX2 (eight lanes at a time), AVX-512 (sixteen at once), NEON (four).
at_width!(
    "x86_64",
    "avx2,fma",
    W8<false>,
    set_up_avx2,
    set_up_runs_avx2,
    camera_rays_avx2
);
at_width!(
    "x86_64",
    "avx2,fma,avx512f",
    W16<false>,
    set_up_avx512,
    set_up_runs_avx512,
    camera_rays_avx512
);
at_width!(
    "aarch64",
    "neon",
    W4,
    set_up_neon,
    set_up_runs_neon,
    camera_rays_neon
);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::composite::Weights;
    use crate::render::packet::{Packets, ZPairs};
    use crate::render::ray::Frame;
    use crate::render::stats::RenderStats;
    use crate::transfer::{Lut, TransferFunction};
    use crate::volume::Grid;

    /// Rays at the box and past it from many directions, with the cases
    /// the NaN rule is for: rays parallel to a face's plane (a zero
    /// direction component, of either sign) starting on that plane, where
    /// the slab test meets `0 · ∞`; and rays along an axis, rays that miss.
    fn rays(lo: Vec3, hi: Vec3) -> Vec<(Vec3, Vec3)> {
        let mut out = Vec::new();
        let mut s = 0x2545_f491_u32;
        let mut rnd = || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s as f32 / u32::MAX as f32
        };
        let c = (lo + hi) * 0.5;
        for i in 0..900 {
            let mut dir = Vec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5);
            let target = c + (Vec3::new(rnd(), rnd(), rnd()) - 0.5) * (hi - lo) * 1.4;
            let a = (i / 2) % 3;
            if i % 2 == 0 {
                dir[a] = if (i / 6) % 2 == 0 { 0.0 } else { -0.0 };
            }
            if i % 10 == 1 {
                dir = Vec3::ZERO;
                dir[a] = if (i / 6) % 2 == 0 { 1.0 } else { -1.0 };
            }
            let dir = dir.normalize();
            let mut origin = target - dir * 40.0;
            if i % 2 == 0 {
                match (i / 12) % 3 {
                    0 => origin[a] = lo[a],
                    1 => origin[a] = hi[a],
                    _ => {}
                }
            }
            out.push((origin, dir));
        }
        out
    }

    /// A level the test's packets name (the set-ups do not read it).
    #[cfg(target_arch = "x86_64")]
    const ANY_LEVEL: super::super::Level = super::super::Level::Avx2;
    #[cfg(target_arch = "aarch64")]
    const ANY_LEVEL: super::super::Level = super::super::Level::Neon;

    type SetUp = unsafe fn(
        &Geometry,
        &[(Vec3, Vec3)],
        &[f32; LANES],
        &[f32; LANES],
        &mut [Option<Lane>; LANES],
    ) -> u64;
    type SetUpRuns = unsafe fn(
        &Geometry,
        &[(Vec3, Vec3)],
        &[f32; LANES],
        &[f32; LANES],
        &mut [Option<Lane>; LANES],
        &mut [Option<WalkStart>; LANES],
    ) -> u64;
    type CameraRays = unsafe fn(&Camera, &[(u32, u32)], &mut [(Vec3, Vec3)]);

    /// Each width this CPU runs: its set-ups and its camera rays.
    #[cfg(target_arch = "x86_64")]
    fn widths() -> Vec<(SetUp, SetUpRuns, CameraRays)> {
        let mut v = Vec::new();
        if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
            v.push((
                set_up_avx2 as SetUp,
                set_up_runs_avx2 as SetUpRuns,
                camera_rays_avx2 as CameraRays,
            ));
        }
        if std::is_x86_feature_detected!("avx512f") {
            v.push((set_up_avx512, set_up_runs_avx512, camera_rays_avx512));
        }
        v
    }

    /// Each width this CPU runs: NEON's.
    #[cfg(target_arch = "aarch64")]
    fn widths() -> Vec<(SetUp, SetUpRuns, CameraRays)> {
        vec![(
            set_up_neon as SetUp,
            set_up_runs_neon as SetUpRuns,
            camera_rays_neon as CameraRays,
        )]
    }

    #[test]
    fn vector_set_up_gives_the_scalar_lanes_bit_for_bit() {
        // (And the step-per-block marches' lanes with their walks'
        // starts: `Packets::run_lane` and `RunWalk::new`'s.)
        let widths = widths();
        if widths.is_empty() {
            return;
        }
        let dims = [9usize, 7, 5];
        let data = vec![0u8; dims.iter().product()];
        let grid = Grid::new(&data, dims, 0.0, 255.0);
        let tf = TransferFunction {
            color: vec![[0.0, 1.0, 1.0, 1.0], [1.0, 1.0, 1.0, 1.0]],
            opacity: vec![[0.0, 0.0], [1.0, 1.0]],
            window: None,
        };
        let lut = Lut::new(&tf, 1.0);
        let q = lut.premultiplied(1.0);
        let z = ZPairs::None;
        let (lo, hi) = (Vec3::ZERO, Vec3::new(8.0, 6.0, 4.0));
        // Spacing and origin that make voxel space differ from world space
        // (powers of two, so that a world point on a face's plane is on it
        // in voxel space too).
        let (spacing, origin_w) = (Vec3::new(0.5, 2.0, 0.25), Vec3::new(-1.5, 0.25, 3.0));
        let world = |p: Vec3| origin_w + p * spacing;
        let rays: Vec<_> = rays(world(lo), world(hi));
        for occupied in [
            None,
            Some((Vec3::new(1.5, 0.0, 1.0), Vec3::new(6.0, 5.5, 4.0))),
        ] {
            for jitter in [None, Some(11u64)] {
                let frame = Frame {
                    grid: &grid,
                    lut: &lut,
                    box_lo: lo,
                    box_hi: hi,
                    origin_w,
                    inv_spacing: Vec3::ONE / spacing,
                    step: 0.37,
                    unit: 0.7,
                    skip_empty: occupied.is_some(),
                    block_size: 4,
                    block_counts: [3, 2, 2],
                    empty: &[],
                    occupied,
                    seed: 0,
                };
                let pk: Packets<'_, u8> = Packets {
                    f: &frame,
                    q: &q,
                    st: 0.37 / 0.7,
                    weights: Weights {
                        emission: 1.0,
                        absorption: 1.0,
                    },
                    stop: f32::INFINITY,
                    jitter,
                    empty: None,
                    shading: None,
                    z_pairs: &z,
                    level: ANY_LEVEL,
                    imp: None,
                    runs: None,
                    thr: None,
                    strat: None,
                    surface: None,
                };
                let g = pk.geometry();
                let (mut met, mut walked) = (0, 0);
                // Packets of every size from 1 to 16.
                let mut at = 0;
                for (k, n) in (1..=LANES).cycle().enumerate() {
                    if at + n > rays.len() {
                        break;
                    }
                    let r = &rays[at..at + n];
                    let pixels: Vec<(u32, u32)> = (0..n as u32).map(|i| (i, k as u32)).collect();
                    let mut stats = RenderStats::default();
                    let mut want = [None; LANES];
                    let mut jit = [0.0; LANES];
                    // A third of the rays stop at a surface: before the
                    // volume, in it or past it (each ray aims at a point
                    // near the box, 40 along it).
                    let mut limit = [f32::INFINITY; LANES];
                    for (i, l) in limit.iter_mut().enumerate().take(n) {
                        if (at + i) % 3 == 1 {
                            *l = 25.0 + ((at + i) * 13 % 31) as f32;
                        }
                    }
                    for (i, (&ray, &px)) in r.iter().zip(&pixels).enumerate() {
                        want[i] = pk.lane(ray, limit[i], px, 2, &mut stats);
                        if let Some(seed) = jitter {
                            jit[i] = crate::render::rng::pixel_sequence(seed, px.0, px.1, 2)
                                * frame.step;
                        }
                    }
                    met += want.iter().flatten().count();
                    for &(set_up, _, _) in &widths {
                        let mut got = [None; LANES];
                        // SAFETY: the CPU has the instructions (checked above).
                        let hits = unsafe { set_up(&g, r, &jit, &limit, &mut got) };
                        // Compared as printed: `-0.0` and `0.0` differ there.
                        assert_eq!(
                            format!("{got:?}"),
                            format!("{want:?}"),
                            "rays {at}..{}",
                            at + n
                        );
                        assert_eq!(hits, stats.rays_hit, "rays {at}..{}", at + n);
                    }
                    // The step-per-block marches' lanes and walks.
                    let mut stats = RenderStats::default();
                    let mut want = [None; LANES];
                    for (i, (&ray, &px)) in r.iter().zip(&pixels).enumerate() {
                        want[i] = pk
                            .run_lane(ray, limit[i], px, 2, &mut stats)
                            .map(|(l, w)| (l, WalkStart::of(&w)));
                    }
                    walked += want.iter().flatten().count();
                    for &(_, set_up_runs, _) in &widths {
                        let (mut lanes, mut starts) = ([None; LANES], [None; LANES]);
                        // SAFETY: the CPU has the instructions (checked above).
                        let hits =
                            unsafe { set_up_runs(&g, r, &jit, &limit, &mut lanes, &mut starts) };
                        let got: Vec<_> =
                            lanes.iter().zip(&starts).map(|(l, s)| l.zip(*s)).collect();
                        assert_eq!(
                            format!("{got:?}"),
                            format!("{want:?}"),
                            "walks of rays {at}..{}",
                            at + n
                        );
                        assert_eq!(hits, stats.rays_hit, "rays {at}..{}", at + n);
                    }
                    at += n;
                }
                // The rays exercise both outcomes.
                assert!(met > 100 && met < rays.len() - 50, "{met} lanes set up");
                assert!(
                    walked >= met && walked < rays.len() - 50,
                    "{walked} walks set up"
                );
            }
        }
    }

    /// The cameras' rays in vector registers are `Camera::ray`'s, bit for
    /// bit: perspective and orthographic, from several sides, every pixel
    /// of an image whose rows split into packets of every length.
    #[test]
    fn vector_camera_rays_are_the_cameras_bit_for_bit() {
        use crate::camera::CameraParams;
        let widths = widths();
        if widths.is_empty() {
            return;
        }
        let (lo, hi) = (Vec3::new(-1.3, 0.2, -0.7), Vec3::new(2.9, 1.7, 3.1));
        let (w, h) = (37, 23);
        let mut checked = 0;
        for projection in [Projection::Perspective, Projection::Orthographic] {
            for (azimuth, elevation, zoom) in
                [(0.0, 0.0, 1.0), (30.0, 20.0, 1.7), (-117.0, -63.0, 0.6)]
            {
                let params = CameraParams {
                    projection,
                    azimuth,
                    elevation,
                    zoom,
                    ..CameraParams::default()
                };
                let cam = Camera::fit(&params, lo, hi, w, h);
                let pixels: Vec<(u32, u32)> =
                    (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).collect();
                for len in 1..=LANES {
                    for chunk in pixels.chunks(len) {
                        let want: Vec<_> = chunk.iter().map(|&(x, y)| cam.ray(x, y)).collect();
                        for &(_, _, rays_of) in &widths {
                            let mut got = vec![(Vec3::ZERO, Vec3::ZERO); chunk.len()];
                            // SAFETY: the CPU has the instructions (checked above).
                            unsafe { rays_of(&cam, chunk, &mut got) };
                            // Compared as printed: `-0.0` and `0.0` differ there.
                            assert_eq!(
                                format!("{got:?}"),
                                format!("{want:?}"),
                                "{projection:?} {chunk:?}"
                            );
                            checked += chunk.len();
                        }
                    }
                }
            }
        }
        assert!(checked >= 2 * 3 * 16 * (37 * 23) as usize);
    }
}
