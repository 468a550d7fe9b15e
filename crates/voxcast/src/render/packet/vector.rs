//! The packets' vector code, written once over [`Simd`] and compiled at
//! two widths (see the parent module): the trilinear gathers, the block
//! exits of empty-space skipping, shading and the marching loop.

use super::importance::{ImpState, VImp};
use super::lod::VLod;
use super::shade::{Deferred, Light, Slots};
use super::simd::{Simd, W16, W8};
use super::tail::{drain_deferred, store_lanes};
use super::vwalk::{Rays, VWalk};
use super::walk::{group_heads, walk_runs, RunRegs};
use super::{Lane, Packets, Runs, State, LANES};
use crate::volume::{Voxel, VoxelKind};

/// The values at `idx` and `idx + 1` (element indices) of `data`, as
/// floats: one 32-bit gather for both where the type allows.
///
/// # Safety
/// The width's instructions; every `idx + 1` < `len` (elements), and
/// `len` bytes ≥ 4.
#[inline(always)]
unsafe fn pair<S: Simd, T: Voxel>(data: *const u8, len_bytes: i32, idx: S::I) -> (S::F, S::F) {
    match T::KIND {
        VoxelKind::U8 => {
            // Read 4 bytes at `idx`, moved back near the end of the
            // data so the read stays inside; shift the pair down.
            let addr = S::min_i(idx, S::splat_i(len_bytes - 4));
            let sh = S::sll(idx - addr, 3);
            let g = S::gather::<1>(data as *const i32, addr);
            let m = S::splat_i(0xff);
            let lo = S::and_i(S::srlv(g, sh), m);
            let hi = S::and_i(S::srlv(g, sh + S::splat_i(8)), m);
            (S::to_f(lo), S::to_f(hi))
        }
        VoxelKind::U16 => {
            let g = S::gather::<2>(data as *const i32, idx);
            let lo = S::and_i(g, S::splat_i(0xffff));
            let hi = S::srl(g, 16);
            (S::to_f(lo), S::to_f(hi))
        }
        VoxelKind::I16 => {
            let g = S::gather::<2>(data as *const i32, idx);
            let lo = S::sra(S::sll(g, 16), 16);
            let hi = S::sra(g, 16);
            (S::to_f(lo), S::to_f(hi))
        }
        VoxelKind::F32 => {
            let p = data as *const f32;
            let lo = S::gather_f::<4>(p, idx);
            let hi = S::gather_f::<4>(p, idx + S::splat_i(1));
            (lo, hi)
        }
    }
}

/// `a + (b − a)·t` without fusing, as the scalar path computes it.
#[inline(always)]
unsafe fn lerp<S: Simd>(a: S::F, b: S::F, t: S::F) -> S::F {
    a + (b - a) * t
}

/// Trilinear interpolation of corners `c[x + 2y + 4z]` at fractions `f`
/// (x first, then y, then z, as `Grid::sample`).
#[inline(always)]
unsafe fn trilinear<S: Simd>(c: [S::F; 8], [fx, fy, fz]: [S::F; 3]) -> S::F {
    let c00 = lerp::<S>(c[0], c[1], fx);
    let c10 = lerp::<S>(c[2], c[3], fx);
    let c01 = lerp::<S>(c[4], c[5], fx);
    let c11 = lerp::<S>(c[6], c[7], fx);
    let c0 = lerp::<S>(c00, c10, fy);
    let c1 = lerp::<S>(c01, c11, fy);
    lerp::<S>(c0, c1, fz)
}

/// Where the ray `o + d·t` (one axis; `inv_d` = 1/d) leaves the cube of
/// blocks within `r − 1` of block `b` (blocks of edge `bs`): its far face,
/// `b + r` going up, `b − r + 1` going down (∞ where the ray runs parallel
/// to the axis). By the reciprocal, not a division: off by an ulp or so,
/// which the caller's margin covers.
#[inline(always)]
unsafe fn exit<S: Simd>(o: S::F, d: S::F, inv_d: S::F, b: S::I, r: S::F, bs: S::F) -> S::F {
    let zero = S::splat(0.0);
    let up = S::gt(d, zero);
    let face = (S::to_f(b) + S::blend(up, S::splat(1.0) - r, r)) * bs;
    let te = (face - o) * inv_d;
    S::blend(S::eq(d, zero), te, S::splat(f32::INFINITY))
}

/// The block of coordinate `c` (≥ 0) on one axis for a ray of
/// direction `d`: `⌊c/B⌋`, or `⌈c/B⌉ − 1` going down (so a sample on a
/// face belongs to the block the ray is leaving, as in `BlockWalker`),
/// clamped to `0..=top`.
#[inline(always)]
unsafe fn block<S: Simd>(c: S::F, d: S::F, inv_bs: S::F, top: S::I) -> S::I {
    let q = c * inv_bs;
    let down = S::lt(d, S::splat(0.0));
    let b = S::blend(down, S::floor(q), S::ceil(q) - S::splat(1.0));
    S::min_i(S::max_i(S::to_i(b), S::splat_i(0)), top)
}

/// Empty-space skipping as the lanes read it: each block's skip distance
/// (`Packets::empty`) and the block grid.
pub(super) struct Skips<S: Simd> {
    empty: *const i32,
    inv_bs: S::F,
    bs: S::F,
    top: [S::I; 3],
    ncx: S::I,
    ncy: S::I,
}

impl<S: Simd> Skips<S> {
    /// # Safety
    /// The width's instructions.
    #[inline(always)]
    pub(super) unsafe fn of<T: Voxel, R: Runs<T>>(pk: &Packets<'_, T, R>) -> Self {
        let f = pk.f;
        let [cx, cy, cz] = [0, 1, 2].map(|a| f.block_counts[a] as i32);
        Skips {
            empty: pk.empty.map_or(std::ptr::null(), |e| e.as_ptr()),
            inv_bs: S::splat(1.0 / f.block_size as f32),
            bs: S::splat(f.block_size as f32),
            top: [S::splat_i(cx - 1), S::splat_i(cy - 1), S::splat_i(cz - 1)],
            ncx: S::splat_i(cx),
            ncy: S::splat_i(cy),
        }
    }

    /// The lanes of `act` whose samples `p` (inside the grid's sample
    /// box) lie in an empty block by [`Frame::in_empty_block`]'s rule:
    /// block `⌊p/B⌋`, whichever way the ray goes (`mc`, whose positions
    /// are not on a walk).
    ///
    /// # Safety
    /// The width's instructions; `pk.empty` was set.
    ///
    /// [`Frame::in_empty_block`]: crate::render::ray::Frame::in_empty_block
    #[inline(always)]
    pub(super) unsafe fn empty_at(&self, p: [S::F; 3], act: S::M) -> S::M {
        let zero = S::splat(0.0);
        let b3: [S::I; 3] = std::array::from_fn(|a| {
            let b = S::to_i(S::floor(S::max(p[a], zero) / self.bs));
            S::min_i(b, self.top[a])
        });
        let b = b3[0] + S::mullo(self.ncx, b3[1] + S::mullo(self.ncy, b3[2]));
        S::and(act, S::positive(S::gather::<4>(self.empty, b)))
    }

    /// The lanes of `act` whose samples `p` lie in an empty block (the
    /// block walk's rule: on a face, a ray going down belongs to the
    /// block below), and each lane's exit from the cube around its block:
    /// the empty cube's nearest far face for those lanes, for the others
    /// the far face of the cube of blocks that can show around theirs
    /// ([`super::skip_distances`]; at least their own block, as for a map
    /// that gives the visible blocks 0).
    ///
    /// # Safety
    /// The width's instructions; `pk.empty` was set.
    #[inline(always)]
    pub(super) unsafe fn exit(
        &self,
        vol: &Vol<S>,
        p: [S::F; 3],
        r: &Rays<S>,
        act: S::M,
    ) -> (S::M, S::F) {
        let c = vol.clamp(p);
        let d = r.d;
        let b3 = [
            block::<S>(c[0], d[0], self.inv_bs, self.top[0]),
            block::<S>(c[1], d[1], self.inv_bs, self.top[1]),
            block::<S>(c[2], d[2], self.inv_bs, self.top[2]),
        ];
        let b = b3[0] + S::mullo(self.ncx, b3[1] + S::mullo(self.ncy, b3[2]));
        let e = S::gather::<4>(self.empty, b);
        let skip = S::and(act, S::positive(e));
        let (o, inv_d, bs) = (r.o, r.inv_d, self.bs);
        let ef = S::to_f(e);
        let re = S::max(S::abs(ef), S::splat(1.0));
        let te = S::min(
            S::min(
                exit::<S>(o[0], d[0], inv_d[0], b3[0], re, bs),
                exit::<S>(o[1], d[1], inv_d[1], b3[1], re, bs),
            ),
            exit::<S>(o[2], d[2], inv_d[2], b3[2], re, bs),
        );
        (skip, te)
    }
}

/// The grid as the lanes read it (see `Grid::sample`).
pub(super) struct Vol<S: Simd> {
    data: *const u8,
    /// u8 and f32 grids: the z-paired copy (`super::ZPairs`; null for
    /// other types).
    zp: *const u8,
    len_bytes: i32,
    max: [S::F; 3],
    last: [S::I; 3],
    sy: S::I,
    sz: S::I,
    /// The z-paired copy's bytes from one column, row and slice to the
    /// next (`[dx, dy, dz]`): the fetches of one cell or one gradient
    /// offset the copy's pointer, not the lanes' indices, so the loads'
    /// width takes each lane's index out of its vector once.
    zp_step: [isize; 3],
    dimx: S::I,
    dimy: S::I,
    /// The element index of voxel (1, 1, 1).
    inner: S::I,
    /// `last` as floats.
    lastf: [S::F; 3],
    scale: S::F,
    /// `scale / 2`, for central differences in stored units.
    half_scale: S::F,
    offset: S::F,
}

impl<S: Simd> Vol<S> {
    /// The grid of the packets' frame (and, for u8, its z-paired copy).
    ///
    /// # Safety
    /// The width's instructions.
    #[inline(always)]
    pub(super) unsafe fn of<T: Voxel, R: Runs<T>>(pk: &Packets<'_, T, R>) -> Self {
        let f = pk.f;
        let (data, step, last, max) = f.grid.layout();
        let (scale, offset) = f.grid.scale_offset();
        let dims = f.grid.dims();
        Vol {
            data: data.as_ptr() as *const u8,
            zp: pk.z_pairs.ptr(T::KIND),
            len_bytes: std::mem::size_of_val(data) as i32,
            max: [S::splat(max.x), S::splat(max.y), S::splat(max.z)],
            last: [
                S::splat_i(last[0] as i32),
                S::splat_i(last[1] as i32),
                S::splat_i(last[2] as i32),
            ],
            sy: S::splat_i(step[1] as i32),
            zp_step: {
                let e = if T::KIND == VoxelKind::F32 { 8 } else { 2 };
                [e, e * step[1] as isize, e * step[2] as isize]
            },
            sz: S::splat_i(step[2] as i32),
            dimx: S::splat_i(dims[0] as i32),
            dimy: S::splat_i(dims[1] as i32),
            inner: S::splat_i((1 + dims[0] + dims[0] * dims[1]) as i32),
            lastf: [
                S::splat(last[0] as f32),
                S::splat(last[1] as f32),
                S::splat(last[2] as f32),
            ],
            scale: S::splat(scale),
            half_scale: S::splat(0.5 * scale),
            offset: S::splat(offset),
        }
    }

    /// Positions clamped into the grid as `Grid::sample` clamps them
    /// (max first: a NaN becomes 0).
    #[inline(always)]
    pub(super) unsafe fn clamp(&self, p: [S::F; 3]) -> [S::F; 3] {
        let z = S::splat(0.0);
        [
            S::min(S::max(p[0], z), self.max[0]),
            S::min(S::max(p[1], z), self.max[1]),
            S::min(S::max(p[2], z), self.max[2]),
        ]
    }

    /// The cell of `p` (clamped into the grid): the element index of its
    /// lower corner and the fractions within it.
    #[inline(always)]
    unsafe fn locate(&self, p: [S::F; 3]) -> (S::I, [S::F; 3]) {
        let [px, py, pz] = self.clamp(p);
        let ix = S::min_i(S::to_i(px), self.last[0]);
        let iy = S::min_i(S::to_i(py), self.last[1]);
        let iz = S::min_i(S::to_i(pz), self.last[2]);
        let f = [px - S::to_f(ix), py - S::to_f(iy), pz - S::to_f(iz)];
        (ix + S::mullo(self.dimx, iy + S::mullo(self.dimy, iz)), f)
    }

    /// The trilinear value, in stored units, of the cell whose lower
    /// corner is element `base`, at fractions `f`.
    #[inline(always)]
    unsafe fn cell<T: Voxel>(&self, base: S::I, f: [S::F; 3]) -> S::F {
        trilinear::<S>(self.corners::<T>(base), f)
    }

    /// The eight corners, in stored units, of the cell whose lower corner
    /// is element `base`: `c[x + 2y + 4z]`.
    #[inline(always)]
    unsafe fn corners<T: Voxel>(&self, base: S::I) -> [S::F; 8] {
        if T::KIND == VoxelKind::U8 {
            // Two gathers: rows y and y + 1 of the z-paired copy.
            let dy = self.zp_step[1];
            cell_of::<S>(self.quad(base, 0), self.quad(base, dy))
        } else if T::KIND == VoxelKind::F32 {
            // Rows y and y + 1 of the z-paired copy: a 64-bit gather at
            // x and one at x + 1 each.
            let [dx, dy, _] = self.zp_step;
            let (c000, c001) = self.z_pair(base, 0);
            let (c100, c101) = self.z_pair(base, dx);
            let (c010, c011) = self.z_pair(base, dy);
            let (c110, c111) = self.z_pair(base, dy + dx);
            [c000, c100, c010, c110, c001, c101, c011, c111]
        } else {
            let (d, n) = (self.data, self.len_bytes);
            let (c000, c100) = pair::<S, T>(d, n, base);
            let (c010, c110) = pair::<S, T>(d, n, base + self.sy);
            let (c001, c101) = pair::<S, T>(d, n, base + self.sz);
            let (c011, c111) = pair::<S, T>(d, n, base + self.sy + self.sz);
            [c000, c100, c010, c110, c001, c101, c011, c111]
        }
    }

    /// f32 grids: voxels `(x, z)` and `(x, z + 1)` at element `i` of the
    /// z-paired copy, `off` bytes on, in one 64-bit gather.
    #[inline(always)]
    unsafe fn z_pair(&self, i: S::I, off: isize) -> (S::F, S::F) {
        let p = self.zp.wrapping_offset(off) as *const i64;
        let (lo, hi) = S::gather_pair::<8>(p, i);
        (S::of_bits(lo), S::of_bits(hi))
    }

    /// u8 grids: the z-paired copy's 64 bits at element `i − 1`, `off`
    /// bytes on, as two [`Vol::quad`]s: columns x − 1, x and x + 1, x + 2.
    #[inline(always)]
    unsafe fn row(&self, i: S::I, off: isize) -> ([S::F; 4], [S::F; 4]) {
        let p = self.zp.wrapping_offset(off - 2) as *const i64;
        let (lo, hi) = S::gather_pair::<2>(p, i);
        (bytes::<S>(lo), bytes::<S>(hi))
    }

    /// u8 grids: the z-paired copy's 32 bits at element `i`, `off` bytes
    /// on, i.e. voxels `(x, z)`, `(x, z + 1)`, `(x + 1, z)`,
    /// `(x + 1, z + 1)` of its row.
    #[inline(always)]
    unsafe fn quad(&self, i: S::I, off: isize) -> [S::F; 4] {
        let p = self.zp.wrapping_offset(off) as *const i32;
        bytes::<S>(S::gather::<2>(p, i))
    }

    /// The difference of the trilinear values of the cells at elements
    /// `a` and `b`, at the same fractions `f`, as the trilinear value of
    /// the corners' differences: one interpolation instead of two (the
    /// same value to a rounding; the differences themselves are exact for
    /// integer voxels).
    #[inline(always)]
    unsafe fn cell_diff<T: Voxel>(&self, a: S::I, b: S::I, f: [S::F; 3]) -> S::F {
        diff::<S>(self.corners::<T>(a), self.corners::<T>(b), f)
    }

    /// The normalised trilinear value at `p` (voxel coordinates),
    /// lane by lane `Grid::sample`.
    #[inline(always)]
    pub(super) unsafe fn sample<T: Voxel>(&self, p: [S::F; 3]) -> S::F {
        let (base, f) = self.locate(p);
        self.cell::<T>(base, f) * self.scale + self.offset
    }

    /// Central-difference gradient at `p` by six clamped samples: lane by
    /// lane `Grid::gradient` near the grid's faces, and inside to a
    /// rounding (see [`Vol::gradient_cells`]).
    #[inline(always)]
    unsafe fn gradient<T: Voxel>(&self, p: [S::F; 3]) -> [S::F; 3] {
        let one = S::splat(1.0);
        let half = S::splat(0.5);
        let [x, y, z] = p;
        let gx = self.sample::<T>([x + one, y, z]) - self.sample::<T>([x - one, y, z]);
        let gy = self.sample::<T>([x, y + one, z]) - self.sample::<T>([x, y - one, z]);
        let gz = self.sample::<T>([x, y, z + one]) - self.sample::<T>([x, y, z - one]);
        [gx * half, gy * half, gz * half]
    }

    /// [`Vol::gradient`] for the lanes of `m` (others unspecified): where
    /// all of them are inside (a cell on each side of their own, on every
    /// axis), as `Grid::gradient` does, the neighbouring cells at the
    /// lanes' own fractions, located once. In the marching loop six
    /// samples measured faster (the compiler shares their work with the
    /// sample's), so only the deferred shading, which has no sample, uses
    /// this.
    #[inline(always)]
    unsafe fn gradient_cells<T: Voxel>(&self, p: [S::F; 3], m: S::M) -> [S::F; 3] {
        let one = S::splat(1.0);
        let [x, y, z] = p;
        // ⌊p⌋ ≥ 1 and ⌊p⌋ + 2 ≤ dims − 1 on every axis, i.e.
        // 1 ≤ p < last (a NaN fails).
        let lf = self.lastf;
        let ix = S::and(S::ge(x, one), S::lt(x, lf[0]));
        let iy = S::and(S::ge(y, one), S::lt(y, lf[1]));
        let iz = S::and(S::ge(z, one), S::lt(z, lf[2]));
        if S::bits(S::but(m, S::and(S::and(ix, iy), iz))) != 0 {
            return self.gradient::<T>(p);
        }
        // Lanes outside `m` read cell (1, 1, 1), inside as well.
        let (base, f) = self.locate(p);
        let base = S::blend_i(m, self.inner, base);
        let (dx, dy, dz) = (S::splat_i(1), self.sy, self.sz);
        if T::KIND == VoxelKind::U8 {
            return self.gradient_u8(base, f);
        }
        let gx = self.cell_diff::<T>(base + dx, base - dx, f);
        let gy = self.cell_diff::<T>(base + dy, base - dy, f);
        let gz = self.cell_diff::<T>(base + dz, base - dz, f);
        let hs = self.half_scale;
        [gx * hs, gy * hs, gz * hs]
    }

    /// [`Vol::gradient_cells`]'s differences for u8 grids, the same
    /// values in fewer loads: rows y and y + 1 of the z-paired copy at
    /// x − 1 … x + 2 are one 64-bit load each and hold both cells x ± 1
    /// and the cell's own middle, which the y differences reuse (eight
    /// loads a lane where the six cells take twelve).
    #[inline(always)]
    unsafe fn gradient_u8(&self, base: S::I, f: [S::F; 3]) -> [S::F; 3] {
        let [_, sy, sz] = self.zp_step;
        // Columns x − 1, x (`l`) and x + 1, x + 2 (`h`) of rows y, y + 1.
        let (l0, h0) = self.row(base, 0);
        let (l1, h1) = self.row(base, sy);
        let (m0, m1) = (mid::<S>(l0, h0), mid::<S>(l1, h1));
        let gx = diff::<S>(cell_of::<S>(h0, h1), cell_of::<S>(l0, l1), f);
        let gy = diff::<S>(
            cell_of::<S>(m1, self.quad(base, 2 * sy)),
            cell_of::<S>(self.quad(base, -sy), m0),
            f,
        );
        let gz = diff::<S>(
            cell_of::<S>(self.quad(base, sz), self.quad(base, sz + sy)),
            cell_of::<S>(self.quad(base, -sz), self.quad(base, sy - sz)),
            f,
        );
        let hs = self.half_scale;
        [gx * hs, gy * hs, gz * hs]
    }
}

/// The four bytes of `g`, low first, as floats.
#[inline(always)]
unsafe fn bytes<S: Simd>(g: S::I) -> [S::F; 4] {
    let m = S::splat_i(0xff);
    [
        S::to_f(S::and_i(g, m)),
        S::to_f(S::and_i(S::srl(g, 8), m)),
        S::to_f(S::and_i(S::srl(g, 16), m)),
        S::to_f(S::srl(g, 24)),
    ]
}

/// The middle two columns of [`Vol::row`]'s four.
#[inline(always)]
fn mid<S: Simd>(l: [S::F; 4], h: [S::F; 4]) -> [S::F; 4] {
    [l[2], l[3], h[0], h[1]]
}

/// The trilinear value at `f` of the corners' differences `a − b`.
#[inline(always)]
unsafe fn diff<S: Simd>(a: [S::F; 8], b: [S::F; 8], f: [S::F; 3]) -> S::F {
    trilinear::<S>(std::array::from_fn(|i| a[i] - b[i]), f)
}

/// A cell's corners `c[x + 2y + 4z]` from its rows y and y + 1, each
/// `[(x, z), (x, z + 1), (x + 1, z), (x + 1, z + 1)]`.
#[inline(always)]
fn cell_of<S: Simd>(r0: [S::F; 4], r1: [S::F; 4]) -> [S::F; 8] {
    [r0[0], r0[2], r1[0], r1[2], r0[1], r0[3], r1[1], r1[3]]
}

/// Shades a vector of the samples waiting in `dq` (`view`: the lanes'
/// view directions) and adds them to their lanes.
///
/// # Safety
/// The width's instructions.
#[inline(always)]
pub(super) unsafe fn shade_deferred<S: Simd, T: Voxel>(
    dq: &mut Deferred,
    vol: &Vol<S>,
    light: &Light<S>,
    view: [S::F; 3],
) {
    let b = dq.take::<S>();
    let gr = vol.gradient_cells::<T>(b.p, b.m);
    let v = [
        S::permute(view[0], b.lane),
        S::permute(view[1], b.lane),
        S::permute(view[2], b.lane),
    ];
    let e = light.shade(gr, b.q, b.al, v);
    dq.add::<S>(&b, e);
}

/// Queues the slots of lanes `m` ([`Slots`]), shading a vector when one
/// is full.
///
/// # Safety
/// The width's instructions; fewer than `S::N` samples waiting.
#[inline(always)]
pub(super) unsafe fn queue_slots<S: Simd, T: Voxel>(
    dq: &mut Deferred,
    sl: &Slots<S>,
    m: S::M,
    vol: &Vol<S>,
    light: &Light<S>,
    view: [S::F; 3],
) {
    if dq.push::<S>(m, sl.p, sl.w, sl.al, sl.q) {
        shade_deferred::<S, T>(dq, vol, light, view);
    }
}

entry!(
    /// Marches the lanes' vector stretches `k0..k_end`: adds each lane's
    /// colour and opacity to `st.acc`, its samples, shaded samples and
    /// interpolations to `st.count`, and leaves `st.alive` false for lanes
    /// that terminated early. `SKIP`: empty-space skipping (`pk.empty`);
    /// `SHADE`: Blinn–Phong (`pk.shading`); `IMP`: `importance`'s walks
    /// (`st.imp`); `R::ON`: a step-per-block march's runs (`st.runs`), with
    /// S0's grouped reuse where `GROUPED`. The sixteen lanes run as two
    /// packets of eight, one after the other, fetching by the gather
    /// instructions.
    ///
    /// # Safety
    /// AVX2 and FMA present; the grid `fits`; the shading `shades`;
    /// `pk.z_pairs` is the grid's z-paired copy (`ZPairs::of`).
    pub(super) march_avx2,
    "avx2,fma",
    W8<false>,
    march<SKIP, SHADE, IMP, GROUPED>
);
entry!(
    /// [`march_avx2`] fetching by scalar loads ([`W8`]`<true>`).
    ///
    /// # Safety
    /// As [`march_avx2`].
    pub(super) march_avx2_loads,
    "avx2,fma",
    W8<true>,
    march<SKIP, SHADE, IMP, GROUPED>
);
entry!(
    /// [`march_avx2`] in sixteen lanes of AVX-512 registers, lane masks in
    /// mask registers.
    ///
    /// # Safety
    /// As [`march_avx2`], and AVX-512 F present.
    pub(super) march_avx512,
    "avx2,fma,avx512f",
    W16<false>,
    march<SKIP, SHADE, IMP, GROUPED>
);
entry!(
    /// [`march_avx512`] fetching by scalar loads ([`W16`]`<true>`).
    ///
    /// # Safety
    /// As [`march_avx512`].
    pub(super) march_avx512_loads,
    "avx2,fma,avx512f",
    W16<true>,
    march<SKIP, SHADE, IMP, GROUPED>
);

/// The loop of both widths, inlined into each; `lanes` and `st` hold
/// `S::N` lanes.
///
/// # Safety
/// As [`march_avx2`], with the width's instructions.
#[inline(always)]
unsafe fn march<
    S: Simd,
    T: Voxel,
    R: Runs<T>,
    const SKIP: bool,
    const SHADE: bool,
    const IMP: bool,
    const GROUPED: bool,
>(
    pk: &Packets<'_, T, R>,
    lanes: &[Option<Lane>],
    st: &mut State<'_>,
) {
    debug_assert!(lanes.len() == S::N && st.acc.len() == S::N);
    let f = pk.f;
    let vol = Vol::<S>::of(pk);
    let mut a = [S::Af::default(); 12];
    let (mut k, mut kend) = (S::Af::default(), S::Af::default());
    let mut live_bits = 0u32;
    for (i, l) in lanes.iter().enumerate() {
        if let Some(l) = l {
            // `group_size`'s thresholds of the lane's exit (grouped reuse).
            let t_out = match (&st.runs[i], &st.starts[i]) {
                _ if !(R::ON && GROUPED) => 0.0,
                (Some(w), _) => w.seg.t_out,
                (None, Some(s)) => s.t_out,
                (None, None) => 0.0,
            };
            let v = [
                l.o.x,
                l.o.y,
                l.o.z,
                l.d.x,
                l.d.y,
                l.d.z,
                l.t0,
                l.view.x,
                l.view.y,
                l.view.z,
                t_out / 3.0,
                t_out * (2.0 / 3.0),
            ];
            for (c, x) in v.into_iter().enumerate() {
                a[c][i] = x;
            }
            k[i] = l.k0 as f32;
            kend[i] = l.k_end as f32;
            live_bits |= 1 << i;
        }
    }
    let o = [S::load(a[0]), S::load(a[1]), S::load(a[2])];
    let d = [S::load(a[3]), S::load(a[4]), S::load(a[5])];
    let t0 = S::load(a[6]);
    let view = [S::load(a[7]), S::load(a[8]), S::load(a[9])];
    let mut kv = S::load(k);
    let kend = S::load(kend);
    let zero = S::splat(0.0);
    let one = S::splat(1.0);
    // For the skips' exits: no division in the loop.
    let inv_d = [one / d[0], one / d[1], one / d[2]];
    let rays = Rays { o, d, inv_d, t0 };
    let inv_st = S::splat(1.0 / pk.st);
    // The lanes' block walks in vector registers, where the rule allows.
    let mut vw = match pk.runs.and_then(|r| r.vector()) {
        Some(p) if R::ON => Some(VWalk::<S>::new(p, st, f.block_counts, f.block_size, rays)),
        _ => None,
    };
    // `lod`'s walk (its runs are the step-per-block ones).
    let mut vl = match pk.runs.and_then(|r| r.lod()) {
        Some(p) if R::ON => Some(VLod::<S>::new(p, st, f.block_counts, f.block_size, rays)),
        _ => None,
    };
    // Shading: deferred where the colour is only summed (see `shade`):
    // the fixed step's samples go to the queue as they are composited; a
    // step-per-block march's wait in their lane's slot (a sample's colour
    // is composited at several steps: reuses, the run's end) when the
    // walk is a vector one (whose run ends add to the slot).
    let defer = SHADE && !R::ON;
    let defer_runs = SHADE && R::ON && (vw.is_some() || vl.is_some());
    let mut rr = RunRegs::<S>::new(kend, S::load(a[10]), S::load(a[11]), defer_runs);
    let stv = S::splat(pk.st);
    let top = S::splat((crate::transfer::LUT_SIZE - 1) as f32);
    let half = S::splat(0.5);
    let q = match (IMP, &pk.imp, pk.runs) {
        (true, Some(ip), _) => ip.tables.as_ptr() as *const f32,
        (false, _, Some(r)) if R::ON => r.tables().as_ptr() as *const f32,
        _ => pk.q.as_ptr() as *const f32,
    };
    let (we, wa) = (
        S::splat(pk.weights.emission),
        S::splat(pk.weights.absorption),
    );
    let stop = S::splat(pk.stop);
    let light = Light::<S>::new(&pk.shading.unwrap_or_default(), f.inv_spacing);
    let mut dq = Deferred::new();
    // Blocks, for skipping.
    let skips = Skips::<S>::of(pk);
    // Lane state.
    let mut live = S::from_bits(live_bits);
    // The first sample each lane must test for emptiness (`SKIP`): past
    // the cube of visible blocks it was last found in.
    let mut kfull = S::splat(f32::NEG_INFINITY);
    let mut walked = S::from_bits(0);
    // Each lane goes on from the colour and opacity it holds (zero for a
    // new ray; a brick's predecessors' for the out-of-core renderer).
    let mut start = [S::Af::default(); 4];
    for (i, c) in st.acc.iter().enumerate() {
        start[0][i] = c.x;
        start[1][i] = c.y;
        start[2][i] = c.z;
        start[3][i] = c.w;
    }
    let mut col = [
        S::load(start[0]),
        S::load(start[1]),
        S::load(start[2]),
        S::load(start[3]),
    ];
    let mut cnt = S::splat_i(0);
    let mut cnt_shaded = S::splat_i(0);
    let mut cnt_interp = S::splat_i(0);
    // `importance`: the lanes' block walks, and each lane's position,
    // spacing, stretch end and table offset; every lane starts by
    // fetching its first stretch.
    let (mut vi, mut is) = match &pk.imp {
        Some(ip) if IMP => {
            let (v, is) = VImp::<S>::new(ip, st, f.block_counts, f.block_size, &rays);
            (Some(v), is)
        }
        _ => (None, ImpState::<S>::idle()),
    };
    loop {
        if IMP {
            // Lanes past their stretch walk on to the next one.
            let need = S::and(live, S::ge(is.t, is.tb));
            if S::bits(need) != 0 {
                let ended = vi.as_mut().unwrap_unchecked().next(need, &mut is);
                // A lane whose walk ended is done, and not terminated.
                live = S::but(live, ended);
                walked = S::or(walked, ended);
            }
        }
        if R::ON {
            // Lanes past their run composite its last sample and walk on
            // to the next run (scalar).
            let need = S::and(live, S::ge(kv, rr.kend));
            let bits = S::bits(need);
            if bits != 0 {
                let (ended, dead) = match (vl.as_mut(), vw.as_mut()) {
                    (Some(vl), _) => vl.next(pk, need, &mut rr, &mut kv, &mut col),
                    (None, Some(vw)) => vw.next(pk, need, live, &mut rr, &mut kv, &mut col),
                    (None, None) => walk_runs::<S, T, R>(pk, st, bits, &mut rr, &mut kv, &mut col),
                };
                live = S::but(live, S::or(ended, dead));
                walked = S::or(walked, ended);
            }
        }
        let act = if IMP {
            live
        } else {
            S::and(live, S::lt(kv, if R::ON { rr.kend } else { kend }))
        };
        if S::bits(act) == 0 {
            break;
        }
        let t = if IMP {
            let t = is.t;
            is.t = S::blend(act, is.t, is.t + is.s);
            t
        } else if R::ON {
            t0 + kv * rr.stv
        } else {
            t0 + kv * stv
        };
        let p = [o[0] + d[0] * t, o[1] + d[1] * t, o[2] + d[2] * t];
        let mut samp = act;
        let mut next = kv + one;
        // Only lanes past the cube of visible blocks they were last found
        // in ask the map again.
        if SKIP && S::bits(S::and(act, S::ge(kv, kfull))) != 0 {
            let (skip, te) = skips.exit(&vol, p, &rays, act);
            // The exit in steps from the lane's first sample.
            let ke = (te - t0) * inv_st;
            if S::bits(skip) != 0 {
                // First sample past the exit (a thousandth of a step
                // early, more than the reciprocals' rounding: a sample
                // still inside is tested again, never one skipped).
                let kn = S::ceil(ke - S::splat(1e-3));
                next = S::blend(skip, next, S::max(next, kn));
                samp = S::but(act, skip);
            }
            // The others sample without asking up to a hundredth of a
            // step before the far face of their visible cube.
            let kf = S::ceil(ke - S::splat(1e-2));
            kfull = S::blend(S::but(act, skip), kfull, kf);
        }
        // A step-per-block march: the run's last sample waits for its
        // stretch; grouped reuse evaluates only where a group starts.
        let (is_last, eval) = if R::ON {
            let is_last = S::and(act, S::eq(kv, rr.kend - one));
            let eval = if GROUPED {
                group_heads::<S>(t, kv, rr.th1, rr.th2, rr.capv, act, &mut rr.fresh)
            } else {
                act
            };
            (is_last, eval)
        } else {
            (S::from_bits(0), samp)
        };
        if !IMP {
            // Every lane steps on, the ones that ended or terminated too
            // (they are masked out): so the next position does not wait
            // for this sample's compositing, and the next gathers can
            // start before this one's have returned.
            kv = next;
        }
        if !R::ON && S::bits(samp) == 0 {
            continue;
        }
        cnt = S::count(cnt, samp);
        let (mut e, mut al, mut valid, mut idx) = ([zero; 3], zero, S::from_bits(0), S::splat_i(0));
        if !GROUPED || S::bits(eval) != 0 {
            cnt_interp = S::count(cnt_interp, eval);
            let v = vol.sample::<T>(p);
            // `Lut::index`: below 0 (or NaN) nothing; the lane's entry 0
            // is read and masked out.
            valid = S::and(eval, S::ge(v, zero));
            let x = S::min(v, one) * top + half;
            idx = S::keep_i(valid, S::to_i(x));
            let i4 = S::sll(idx, 2);
            // The lanes' table rows: loaded whole and transposed (cheaper
            // than four gathers); `importance` and the step-per-block
            // marches read their lane's level.
            let [qr, qg, qb, qa] = if IMP {
                S::rows(q, i4 + is.off)
            } else if R::ON {
                S::rows(q, i4 + rr.offv)
            } else {
                S::rows(q, i4)
            };
            al = qa;
            if SHADE {
                // Transparent samples are culled before shading.
                valid = S::and(valid, S::gt(al, zero));
                if S::bits(valid) == 0 {
                    if !R::ON {
                        continue;
                    }
                } else if defer {
                    // The colour waits in the queue, the opacity is
                    // composited now (with `e` zero).
                    let w = we * (one - col[3]);
                    if dq.push::<S>(valid, p, w, al, [qr, qg, qb]) {
                        shade_deferred::<S, T>(&mut dq, &vol, &light, view);
                    }
                    cnt_shaded = S::count(cnt_shaded, valid);
                } else if defer_runs {
                    // The colour waits in the slot (below), `e` zero.
                    cnt_shaded = S::count(cnt_shaded, valid);
                } else {
                    let gr = vol.gradient::<T>(p);
                    let c = light.shade(gr, [qr, qg, qb], al, view);
                    e = [
                        S::keep(valid, c[0]),
                        S::keep(valid, c[1]),
                        S::keep(valid, c[2]),
                    ];
                    cnt_shaded = S::count(cnt_shaded, valid);
                }
            } else {
                e = [S::keep(valid, qr), S::keep(valid, qg), S::keep(valid, qb)];
            }
            al = S::keep(valid, al);
            if defer_runs {
                // The evaluating lanes' old slots go to the queue, the
                // new samples take their place.
                let out = rr.slot.weighty(eval);
                if S::bits(out) != 0 {
                    queue_slots::<S, T>(&mut dq, &rr.slot, out, &vol, &light, view);
                }
                rr.slot.replace(eval, p, [qr, qg, qb], al, valid);
            }
            if GROUPED {
                // The lanes that evaluated keep their sample for reuse.
                rr.keep(eval, [e[0], e[1], e[2], al], idx, valid);
            }
        }
        if GROUPED {
            // Every sampling lane composites its group's value (lanes
            // that ended or terminated keep theirs, unused).
            let l = rr.last;
            e = [S::keep(act, l[0]), S::keep(act, l[1]), S::keep(act, l[2])];
            al = S::keep(act, l[3]);
            idx = rr.last_idx;
            valid = S::and(rr.last_ok, act);
        }
        if R::ON {
            // The run's last sample waits for its stretch (the walk
            // composites it); the others composite with the run's step.
            rr.hold(is_last, [e[0], e[1], e[2], al, t], idx, valid);
            valid = S::but(valid, is_last);
            e = [
                S::zero(is_last, e[0]),
                S::zero(is_last, e[1]),
                S::zero(is_last, e[2]),
            ];
            al = S::zero(is_last, al);
        }
        // Front to back (`over_front` with the optical model's weights).
        let tr = one - col[3];
        if defer_runs {
            // The slot's colour is composited here: it gains the weight.
            let w = &mut rr.slot.w;
            *w = *w + S::keep(valid, we * tr);
        }
        col[0] = col[0] + e[0] * we * tr;
        col[1] = col[1] + e[1] * we * tr;
        col[2] = col[2] + e[2] * we * tr;
        col[3] = col[3] + al * wa * tr;
        let done = S::and(valid, S::ge(col[3], stop));
        live = S::but(live, done);
    }
    if !R::ON {
        cnt_interp = cnt;
    }
    if defer_runs {
        // The samples still in their slots.
        let out = rr.slot.weighty(S::from_bits(u32::MAX >> (32 - S::N)));
        queue_slots::<S, T>(&mut dq, &rr.slot, out, &vol, &light, view);
    }
    if defer || defer_runs {
        drain_deferred::<S, T>(&mut dq, &mut col, &vol, &light, view);
    }
    // Lanes whose walk ended count as alive (not terminated early).
    store_lanes::<S>(
        st,
        lanes,
        col,
        [cnt, cnt_shaded, cnt_interp],
        S::or(live, walked),
    );
}
