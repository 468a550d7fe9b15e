//! SIMD ray packets: eight neighbouring rays of a tile row marched in
//! lock-step, one per lane of an AVX2 register, for the commonest render —
//! a fixed step (`uniform`, `jitter`), trilinear, unshaded, front to back.
//!
//! Each lane keeps its own ray: its sample grid `t₀ + k·s`, its first and
//! last sample, and its accumulated colour and opacity; a lane mask drops
//! the rays that have left the volume or terminated, and the packet ends
//! when no lane is left. Per iteration the eight corner pairs of the
//! trilinear fetch are four gathers (the +x neighbour comes in the same
//! 32-bit load), the transfer-function lookup is four gathers from the
//! premultiplied table, and compositing is plain vector arithmetic. With
//! empty-space skipping a lane whose sample falls in an empty block jumps
//! to its first sample past that block (one gather of the block flags per
//! iteration), so long empty stretches cost a lane one step per block.
//!
//! The arithmetic is the scalar path's, operation for operation (no fused
//! multiply-adds where the scalar path has none), so a packet gives the
//! scalar pixels to within the rounding of a few skipped-block boundaries.
//! The last sample of a ray (its stretch ends at the volume's exit, not a
//! full step) is composited by the scalar code, lane by lane.
//!
//! Dispatch is at run time ([`available`]): x86-64 with AVX2 and FMA; any
//! other machine, or `RenderParams::simd = scalar`, takes the scalar loop,
//! which stays the reference.

use super::composite::Weights;
use super::march::intersect_box;
use super::optics::over_front;
use super::ray::{Counters, Frame};
use super::sample::{evaluate_premul, Flat};
use super::stats::RenderStats;
use crate::transfer::LUT_SIZE;
use crate::volume::Voxel;
use glam::{Vec3, Vec4};

/// Lanes of a packet.
pub(super) const LANES: usize = 8;

/// Whether this CPU runs the packets (x86-64 with AVX2 and FMA).
pub(super) fn available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Whether the packets can fetch from grid `g`: 32-bit gather offsets, and
/// a +x neighbour in every row (the pair fetch).
pub(super) fn fits<T: Voxel>(g: &crate::volume::Grid<'_, T>) -> bool {
    let (data, step, _, _) = g.layout();
    let bytes = std::mem::size_of_val(data);
    step[0] == 1 && bytes >= 4 && bytes < (i32::MAX as usize) / 2
}

/// What every packet of a render shares.
pub(super) struct Packets<'a, T> {
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
    /// Block emptiness as 32-bit flags (−1 empty), with skipping on.
    pub empty: Option<&'a [i32]>,
}

/// One lane's ray, set up by the scalar code as [`super::trace::trace`]
/// does.
#[derive(Clone, Copy, Default)]
struct Lane {
    o: Vec3,
    d: Vec3,
    t0: f32,
    t_out: f32,
    /// Samples `k0..k_end` go through the vector loop.
    k0: u32,
    k_end: u32,
    /// The last sample, composited with its stretch to `t_out`.
    last: Option<u32>,
}

impl<T: Voxel> Packets<'_, T> {
    /// Sets up the ray of pixel `pixel` (`ray`: world origin and unit
    /// direction), or `None` when it meets nothing to sample.
    fn lane(
        &self,
        (origin, dir): (Vec3, Vec3),
        pixel: (u32, u32),
        pass: u32,
        stats: &mut RenderStats,
    ) -> Option<Lane> {
        let f = self.f;
        stats.rays += 1;
        let o = (origin - f.origin_w) * f.inv_spacing;
        let d = dir * f.inv_spacing;
        let inv_d = Vec3::ONE / d;
        let (t_in, t_out) = intersect_box(o, inv_d, f.box_lo, f.box_hi)?;
        stats.rays_hit += 1;
        let t0 = match self.jitter {
            Some(seed) => t_in + super::rng::pixel_sequence(seed, pixel.0, pixel.1, pass) * f.step,
            None => t_in,
        };
        let walk = match f.occupied {
            Some((lo, hi)) => intersect_box(o, inv_d, lo, hi)
                .map(|(a, b)| (a.max(t_in), b.min(t_out)))
                .filter(|(a, b)| a < b)?,
            None => (t_in, t_out),
        };
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
            t0,
            t_out,
            k0,
            k_end,
            last,
        })
    }

    /// Renders pixels `x0..x0 + out.len()` (at most [`LANES`]) of row `y`
    /// for pass `pass`, adding premultiplied colour and opacity to `out`.
    pub fn row(
        &self,
        rays: &[(Vec3, Vec3)],
        (x0, y): (u32, u32),
        pass: u32,
        out: &mut [Vec4],
        stats: &mut RenderStats,
    ) {
        debug_assert!(rays.len() <= LANES && out.len() == rays.len());
        let mut lanes = [None; LANES];
        for (i, &r) in rays.iter().enumerate() {
            lanes[i] = self.lane(r, (x0 + i as u32, y), pass, stats);
        }
        if lanes.iter().all(Option::is_none) {
            return;
        }
        let mut acc = [Vec4::ZERO; LANES];
        let mut count = [0u32; LANES];
        let mut alive = [false; LANES];
        // SAFETY: `available()` was checked before any packet was made
        // (the only caller, `Job::packets`, does), and `fits` for the grid.
        #[cfg(target_arch = "x86_64")]
        unsafe {
            avx2::march(self, &lanes, &mut acc, &mut count, &mut alive)
        };
        let mut n = Counters::default();
        for i in 0..rays.len() {
            let Some(l) = lanes[i] else { continue };
            let (mut c, mut a) = (acc[i].truncate(), acc[i].w);
            let mut terminated = !alive[i];
            if let (Some(k), false) = (l.last, terminated) {
                terminated = self.last(&l, k, &mut c, &mut a, &mut n);
            }
            n.samples += count[i] as u64;
            n.interpolations += count[i] as u64;
            stats.early_terminated += terminated as u64;
            out[i] += c.extend(a);
        }
        stats.samples += n.samples;
        stats.interpolations += n.interpolations;
    }

    /// The last sample of lane `l` (index `k`), composited over its
    /// stretch to the exit as the scalar march does; true when it ends
    /// the ray.
    fn last(&self, l: &Lane, k: u32, c: &mut Vec3, a: &mut f32, n: &mut Counters) -> bool {
        let f = self.f;
        let t = l.t0 + k as f32 * self.st;
        n.samples += 1;
        let Some((e, pa, entry)) = evaluate_premul(f, &Flat, self.q, l.o + l.d * t, Vec3::ZERO, n)
        else {
            return false;
        };
        if pa <= 0.0 {
            return false;
        }
        let ds = l.t_out.max(t) - t;
        let alpha = 1.0 - (-f.lut.sigma(entry) * ds / f.unit).exp();
        if alpha <= 0.0 {
            return false;
        }
        let e = e * (alpha / pa);
        over_front(
            c,
            a,
            e * self.weights.emission,
            alpha * self.weights.absorption,
        );
        *a >= self.stop
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{Lane, Packets, LANES};
    use crate::volume::{Voxel, VoxelKind};
    use glam::Vec4;
    use std::arch::x86_64::*;

    /// The values at `idx` and `idx + 1` (element indices) of `data`, as
    /// floats: one 32-bit gather for both where the type allows.
    ///
    /// # Safety
    /// AVX2; every `idx + 1` < `len` (elements), and `len` bytes ≥ 4.
    #[inline(always)]
    unsafe fn pair<T: Voxel>(data: *const u8, len_bytes: i32, idx: __m256i) -> (__m256, __m256) {
        match T::KIND {
            VoxelKind::U8 => {
                // Read 4 bytes at `idx`, moved back near the end of the
                // data so the read stays inside; shift the pair down.
                let addr = _mm256_min_epi32(idx, _mm256_set1_epi32(len_bytes - 4));
                let sh = _mm256_slli_epi32::<3>(_mm256_sub_epi32(idx, addr));
                let g = _mm256_i32gather_epi32::<1>(data as *const i32, addr);
                let m = _mm256_set1_epi32(0xff);
                let lo = _mm256_and_si256(_mm256_srlv_epi32(g, sh), m);
                let hi = _mm256_and_si256(
                    _mm256_srlv_epi32(g, _mm256_add_epi32(sh, _mm256_set1_epi32(8))),
                    m,
                );
                (_mm256_cvtepi32_ps(lo), _mm256_cvtepi32_ps(hi))
            }
            VoxelKind::U16 => {
                let g = _mm256_i32gather_epi32::<2>(data as *const i32, idx);
                let lo = _mm256_and_si256(g, _mm256_set1_epi32(0xffff));
                let hi = _mm256_srli_epi32::<16>(g);
                (_mm256_cvtepi32_ps(lo), _mm256_cvtepi32_ps(hi))
            }
            VoxelKind::I16 => {
                let g = _mm256_i32gather_epi32::<2>(data as *const i32, idx);
                let lo = _mm256_srai_epi32::<16>(_mm256_slli_epi32::<16>(g));
                let hi = _mm256_srai_epi32::<16>(g);
                (_mm256_cvtepi32_ps(lo), _mm256_cvtepi32_ps(hi))
            }
            VoxelKind::F32 => {
                let p = data as *const f32;
                let lo = _mm256_i32gather_ps::<4>(p, idx);
                let hi = _mm256_i32gather_ps::<4>(p, _mm256_add_epi32(idx, _mm256_set1_epi32(1)));
                (lo, hi)
            }
        }
    }

    /// Where the ray `o + d·t` (one axis) leaves block `b` of edge `bs`:
    /// its far face (∞ where the ray runs parallel to the axis).
    #[inline(always)]
    unsafe fn exit(o: __m256, d: __m256, b: __m256i, bs: __m256) -> __m256 {
        let zero = _mm256_setzero_ps();
        let up = _mm256_cmp_ps::<_CMP_GT_OQ>(d, zero);
        let face = _mm256_mul_ps(
            _mm256_add_ps(
                _mm256_cvtepi32_ps(b),
                _mm256_and_ps(up, _mm256_set1_ps(1.0)),
            ),
            bs,
        );
        let te = _mm256_div_ps(_mm256_sub_ps(face, o), d);
        let flat = _mm256_cmp_ps::<_CMP_EQ_OQ>(d, zero);
        _mm256_blendv_ps(te, _mm256_set1_ps(f32::INFINITY), flat)
    }

    #[inline(always)]
    unsafe fn lerp(a: __m256, b: __m256, t: __m256) -> __m256 {
        // `a + (b − a)·t` without fusing, as the scalar path computes it.
        _mm256_add_ps(a, _mm256_mul_ps(_mm256_sub_ps(b, a), t))
    }

    #[inline(always)]
    unsafe fn load(v: [f32; LANES]) -> __m256 {
        _mm256_loadu_ps(v.as_ptr())
    }

    /// Marches the lanes' vector stretches `k0..k_end`: adds each lane's
    /// colour and opacity to `acc`, its samples to `count`, and leaves
    /// `alive` false for lanes that terminated early.
    ///
    /// # Safety
    /// AVX2 and FMA present; the grid `fits`.
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn march<T: Voxel>(
        pk: &Packets<'_, T>,
        lanes: &[Option<Lane>; LANES],
        acc: &mut [Vec4; LANES],
        count: &mut [u32; LANES],
        alive: &mut [bool; LANES],
    ) {
        let f = pk.f;
        let (data, step, last, max) = f.grid.layout();
        let (scale, offset) = f.grid.scale_offset();
        let len_bytes = std::mem::size_of_val(data) as i32;
        let data = data.as_ptr() as *const u8;
        let mut a = [[0f32; LANES]; 8];
        let (mut k, mut kend) = ([0f32; LANES], [0f32; LANES]);
        for (i, l) in lanes.iter().enumerate() {
            if let Some(l) = l {
                a[0][i] = l.o.x;
                a[1][i] = l.o.y;
                a[2][i] = l.o.z;
                a[3][i] = l.d.x;
                a[4][i] = l.d.y;
                a[5][i] = l.d.z;
                a[6][i] = l.t0;
                k[i] = l.k0 as f32;
                kend[i] = l.k_end as f32;
                alive[i] = true;
            }
        }
        let (ox, oy, oz) = (load(a[0]), load(a[1]), load(a[2]));
        let (dx, dy, dz) = (load(a[3]), load(a[4]), load(a[5]));
        let t0 = load(a[6]);
        let mut kv = load(k);
        let kend = load(kend);
        let st = _mm256_set1_ps(pk.st);
        let zero = _mm256_setzero_ps();
        let one = _mm256_set1_ps(1.0);
        let (mx, my, mz) = (
            _mm256_set1_ps(max.x),
            _mm256_set1_ps(max.y),
            _mm256_set1_ps(max.z),
        );
        let (lx, ly, lz) = (
            _mm256_set1_epi32(last[0] as i32),
            _mm256_set1_epi32(last[1] as i32),
            _mm256_set1_epi32(last[2] as i32),
        );
        let (sy, sz) = (
            _mm256_set1_epi32(step[1] as i32),
            _mm256_set1_epi32(step[2] as i32),
        );
        let dimx = _mm256_set1_epi32(f.grid.dims()[0] as i32);
        let dimy = _mm256_set1_epi32(f.grid.dims()[1] as i32);
        let (vs, vo) = (_mm256_set1_ps(scale), _mm256_set1_ps(offset));
        let top = _mm256_set1_ps((crate::transfer::LUT_SIZE - 1) as f32);
        let half = _mm256_set1_ps(0.5);
        let q = pk.q.as_ptr() as *const f32;
        let (we, wa) = (
            _mm256_set1_ps(pk.weights.emission),
            _mm256_set1_ps(pk.weights.absorption),
        );
        let stop = _mm256_set1_ps(pk.stop);
        // Blocks, for skipping.
        let bs = f.block_size as f32;
        let inv_bs = _mm256_set1_ps(1.0 / bs);
        let bsv = _mm256_set1_ps(bs);
        let [cx, cy, cz] = f.block_counts.map(|c| c as i32);
        let (bcx, bcy, bcz) = (
            _mm256_set1_epi32(cx - 1),
            _mm256_set1_epi32(cy - 1),
            _mm256_set1_epi32(cz - 1),
        );
        let (ncx, ncy) = (_mm256_set1_epi32(cx), _mm256_set1_epi32(cy));
        // Lane state.
        let mut live = _mm256_castsi256_ps(_mm256_set_epi32(
            -(alive[7] as i32),
            -(alive[6] as i32),
            -(alive[5] as i32),
            -(alive[4] as i32),
            -(alive[3] as i32),
            -(alive[2] as i32),
            -(alive[1] as i32),
            -(alive[0] as i32),
        ));
        let (mut cr, mut cg, mut cb, mut ca) = (zero, zero, zero, zero);
        let mut cnt = _mm256_setzero_si256();
        loop {
            let act = _mm256_and_ps(live, _mm256_cmp_ps::<_CMP_LT_OQ>(kv, kend));
            if _mm256_movemask_ps(act) == 0 {
                break;
            }
            let t = _mm256_add_ps(t0, _mm256_mul_ps(kv, st));
            // Positions, clamped as `Grid::sample` clamps (max first: a NaN
            // becomes 0).
            let px = _mm256_min_ps(
                _mm256_max_ps(_mm256_add_ps(ox, _mm256_mul_ps(dx, t)), zero),
                mx,
            );
            let py = _mm256_min_ps(
                _mm256_max_ps(_mm256_add_ps(oy, _mm256_mul_ps(dy, t)), zero),
                my,
            );
            let pz = _mm256_min_ps(
                _mm256_max_ps(_mm256_add_ps(oz, _mm256_mul_ps(dz, t)), zero),
                mz,
            );
            let mut samp = act;
            let mut next = _mm256_add_ps(kv, one);
            if let Some(empty) = pk.empty {
                let bx = _mm256_min_epi32(_mm256_cvttps_epi32(_mm256_mul_ps(px, inv_bs)), bcx);
                let by = _mm256_min_epi32(_mm256_cvttps_epi32(_mm256_mul_ps(py, inv_bs)), bcy);
                let bz = _mm256_min_epi32(_mm256_cvttps_epi32(_mm256_mul_ps(pz, inv_bs)), bcz);
                let b = _mm256_add_epi32(
                    bx,
                    _mm256_mullo_epi32(ncx, _mm256_add_epi32(by, _mm256_mullo_epi32(ncy, bz))),
                );
                let e = _mm256_i32gather_epi32::<4>(empty.as_ptr(), b);
                let skip = _mm256_and_ps(act, _mm256_castsi256_ps(e));
                if _mm256_movemask_ps(skip) != 0 {
                    // The lane's exit from its block: the nearest far face.
                    let te = _mm256_min_ps(
                        _mm256_min_ps(exit(ox, dx, bx, bsv), exit(oy, dy, by, bsv)),
                        exit(oz, dz, bz, bsv),
                    );
                    // First sample past the exit (a hair early: a sample
                    // still inside is tested again, never one skipped).
                    let kn = _mm256_ceil_ps(_mm256_sub_ps(
                        _mm256_div_ps(_mm256_sub_ps(te, t0), st),
                        _mm256_set1_ps(1e-3),
                    ));
                    next = _mm256_blendv_ps(next, _mm256_max_ps(next, kn), skip);
                    samp = _mm256_andnot_ps(skip, act);
                }
            }
            kv = _mm256_blendv_ps(kv, next, act);
            if _mm256_movemask_ps(samp) == 0 {
                continue;
            }
            let ix = _mm256_min_epi32(_mm256_cvttps_epi32(px), lx);
            let iy = _mm256_min_epi32(_mm256_cvttps_epi32(py), ly);
            let iz = _mm256_min_epi32(_mm256_cvttps_epi32(pz), lz);
            let fx = _mm256_sub_ps(px, _mm256_cvtepi32_ps(ix));
            let fy = _mm256_sub_ps(py, _mm256_cvtepi32_ps(iy));
            let fz = _mm256_sub_ps(pz, _mm256_cvtepi32_ps(iz));
            let base = _mm256_add_epi32(
                ix,
                _mm256_mullo_epi32(dimx, _mm256_add_epi32(iy, _mm256_mullo_epi32(dimy, iz))),
            );
            let (c000, c100) = pair::<T>(data, len_bytes, base);
            let (c010, c110) = pair::<T>(data, len_bytes, _mm256_add_epi32(base, sy));
            let (c001, c101) = pair::<T>(data, len_bytes, _mm256_add_epi32(base, sz));
            let (c011, c111) = pair::<T>(
                data,
                len_bytes,
                _mm256_add_epi32(base, _mm256_add_epi32(sy, sz)),
            );
            let c00 = lerp(c000, c100, fx);
            let c10 = lerp(c010, c110, fx);
            let c01 = lerp(c001, c101, fx);
            let c11 = lerp(c011, c111, fx);
            let c0 = lerp(c00, c10, fy);
            let c1 = lerp(c01, c11, fy);
            let v = _mm256_add_ps(_mm256_mul_ps(lerp(c0, c1, fz), vs), vo);
            // `Lut::index`: below 0 (or NaN) nothing; the lane's entry 0
            // is read and masked out.
            let valid = _mm256_and_ps(samp, _mm256_cmp_ps::<_CMP_GE_OQ>(v, zero));
            let x = _mm256_add_ps(_mm256_mul_ps(_mm256_min_ps(v, one), top), half);
            let idx = _mm256_and_si256(_mm256_cvttps_epi32(x), _mm256_castps_si256(valid));
            let i4 = _mm256_slli_epi32::<2>(idx);
            let er = _mm256_and_ps(_mm256_i32gather_ps::<4>(q, i4), valid);
            let eg = _mm256_and_ps(_mm256_i32gather_ps::<4>(q.add(1), i4), valid);
            let eb = _mm256_and_ps(_mm256_i32gather_ps::<4>(q.add(2), i4), valid);
            let al = _mm256_and_ps(_mm256_i32gather_ps::<4>(q.add(3), i4), valid);
            // Front to back (`over_front` with the optical model's weights).
            let tr = _mm256_sub_ps(one, ca);
            cr = _mm256_add_ps(cr, _mm256_mul_ps(_mm256_mul_ps(er, we), tr));
            cg = _mm256_add_ps(cg, _mm256_mul_ps(_mm256_mul_ps(eg, we), tr));
            cb = _mm256_add_ps(cb, _mm256_mul_ps(_mm256_mul_ps(eb, we), tr));
            ca = _mm256_add_ps(ca, _mm256_mul_ps(_mm256_mul_ps(al, wa), tr));
            cnt = _mm256_sub_epi32(cnt, _mm256_castps_si256(samp));
            let done = _mm256_and_ps(samp, _mm256_cmp_ps::<_CMP_GE_OQ>(ca, stop));
            live = _mm256_andnot_ps(done, live);
        }
        let mut out = [[0f32; LANES]; 4];
        _mm256_storeu_ps(out[0].as_mut_ptr(), cr);
        _mm256_storeu_ps(out[1].as_mut_ptr(), cg);
        _mm256_storeu_ps(out[2].as_mut_ptr(), cb);
        _mm256_storeu_ps(out[3].as_mut_ptr(), ca);
        let mut c = [0i32; LANES];
        _mm256_storeu_si256(c.as_mut_ptr() as *mut __m256i, cnt);
        let l = _mm256_movemask_ps(live);
        for i in 0..LANES {
            acc[i] = Vec4::new(out[0][i], out[1][i], out[2][i], out[3][i]);
            count[i] = c[i] as u32;
            alive[i] = lanes[i].is_some() && (l >> i) & 1 == 1;
        }
    }
}
