//! The grid as the packets' lanes read it, written once over [`Simd`]:
//! the trilinear fetches (from the volume's z-paired copy), the
//! central-difference gradients, and the block exits of empty-space
//! skipping ([`Skips`]).

use super::simd::Simd;
use super::vwalk::Rays;
use super::{Packets, Runs};
use crate::volume::{Voxel, VoxelKind};

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
        // (No closure: it would not inherit the loop's target features,
        // and each intrinsic would become a call.)
        let [x, y, z] = [self.cell(p, 0), self.cell(p, 1), self.cell(p, 2)];
        let b = x + S::mullo(self.ncx, y + S::mullo(self.ncy, z));
        S::and(act, S::positive(S::gather::<4>(self.empty, b)))
    }

    /// The block `⌊p/B⌋` on axis `a`, clamped into the grid.
    ///
    /// # Safety
    /// The width's instructions.
    #[inline(always)]
    unsafe fn cell(&self, p: [S::F; 3], a: usize) -> S::I {
        let b = S::to_i(S::floor(S::max(p[a], S::splat(0.0)) / self.bs));
        S::min_i(b, self.top[a])
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
    /// The grid's z-paired copy (`super::ZPairs`).
    zp: *const u8,
    max: [S::F; 3],
    last: [S::I; 3],
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
        let (_, step, last, max) = f.grid.layout();
        let (scale, offset) = f.grid.scale_offset();
        let dims = f.grid.dims();
        Vol {
            zp: pk.z_pairs.ptr(T::KIND),
            max: [S::splat(max.x), S::splat(max.y), S::splat(max.z)],
            last: [
                S::splat_i(last[0] as i32),
                S::splat_i(last[1] as i32),
                S::splat_i(last[2] as i32),
            ],
            zp_step: {
                // The bytes of a pair.
                let e = match T::KIND {
                    VoxelKind::U8 => 2,
                    VoxelKind::U16 | VoxelKind::I16 => 4,
                    VoxelKind::F32 => 8,
                };
                [e, e * step[1] as isize, e * step[2] as isize]
            },
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
        // Rows y and y + 1 of the z-paired copy, one load (or gather) a
        // lane each: 4 bytes (u8), 8 (u16, i16) or 16 (f32).
        let dy = self.zp_step[1];
        cell_of::<S>(
            self.paired_quad::<T>(base, 0),
            self.paired_quad::<T>(base, dy),
        )
    }

    /// f32 grids: voxels `(x, z)`, `(x, z + 1)`, `(x + 1, z)`, `(x + 1,
    /// z + 1)` at element `i` of the z-paired copy, `off` bytes on: 16
    /// contiguous bytes, fetched as a table's rows are (one 128-bit load a
    /// lane and a transpose, or 64-bit gathers; the grid is below 1 GiB,
    /// so `2i` fits).
    #[inline(always)]
    unsafe fn f32_row(&self, i: S::I, off: isize) -> [S::F; 4] {
        S::rows(self.zp.wrapping_offset(off) as *const f32, i + i)
    }

    /// Voxels x, x + 1 of the row at element `i`, `off` bytes on, both z
    /// of the pair ([`Vol::quad`], [`Vol::f32_row`], [`Vol::h16_row`]).
    #[inline(always)]
    unsafe fn paired_quad<T: Voxel>(&self, i: S::I, off: isize) -> [S::F; 4] {
        match T::KIND {
            VoxelKind::U8 => self.quad(i, off),
            VoxelKind::F32 => self.f32_row(i, off),
            VoxelKind::U16 | VoxelKind::I16 => self.h16_row::<T>(i, off),
        }
    }

    /// u16 and i16 grids: voxels `(x, z)`, `(x, z + 1)`, `(x + 1, z)`,
    /// `(x + 1, z + 1)` at element `i` of the z-paired copy, `off` bytes
    /// on: 8 contiguous bytes, one 64-bit load (or gather) a lane.
    #[inline(always)]
    unsafe fn h16_row<T: Voxel>(&self, i: S::I, off: isize) -> [S::F; 4] {
        let p = self.zp.wrapping_offset(off) as *const i64;
        let (lo, hi) = S::gather_pair::<4>(p, i);
        let [a, b] = halves::<S, T>(lo);
        let [c, d] = halves::<S, T>(hi);
        [a, b, c, d]
    }

    /// Columns x − 1, x and x + 1, x + 2 of the row at element `i`, `off`
    /// bytes on (u8: one 64-bit load, [`Vol::row`]; others two of
    /// [`Vol::paired_quad`]).
    #[inline(always)]
    unsafe fn paired_row<T: Voxel>(&self, i: S::I, off: isize) -> ([S::F; 4], [S::F; 4]) {
        if T::KIND == VoxelKind::U8 {
            self.row(i, off)
        } else {
            let dx = self.zp_step[0];
            (
                self.paired_quad::<T>(i, off - dx),
                self.paired_quad::<T>(i, off + dx),
            )
        }
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
    pub(super) unsafe fn gradient<T: Voxel>(&self, p: [S::F; 3]) -> [S::F; 3] {
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
    pub(super) unsafe fn gradient_cells<T: Voxel>(&self, p: [S::F; 3], m: S::M) -> [S::F; 3] {
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
        self.gradient_paired::<T>(base, f)
    }

    /// [`Vol::gradient_cells`]'s differences from the z-paired copy, the
    /// same values in fewer loads: rows y and y + 1 at x − 1 … x + 2 hold
    /// both cells x ± 1 and the cell's own middle, which the y differences
    /// reuse (u8: one 64-bit load a row, eight loads a lane where the six
    /// cells take twelve; u16, i16 and f32: two loads a row, ten).
    #[inline(always)]
    unsafe fn gradient_paired<T: Voxel>(&self, base: S::I, f: [S::F; 3]) -> [S::F; 3] {
        let [_, sy, sz] = self.zp_step;
        // Columns x − 1, x (`l`) and x + 1, x + 2 (`h`) of rows y, y + 1.
        let (l0, h0) = self.paired_row::<T>(base, 0);
        let (l1, h1) = self.paired_row::<T>(base, sy);
        let (m0, m1) = (mid::<S>(l0, h0), mid::<S>(l1, h1));
        let gx = diff::<S>(cell_of::<S>(h0, h1), cell_of::<S>(l0, l1), f);
        let gy = diff::<S>(
            cell_of::<S>(m1, self.paired_quad::<T>(base, 2 * sy)),
            cell_of::<S>(self.paired_quad::<T>(base, -sy), m0),
            f,
        );
        let gz = diff::<S>(
            cell_of::<S>(
                self.paired_quad::<T>(base, sz),
                self.paired_quad::<T>(base, sz + sy),
            ),
            cell_of::<S>(
                self.paired_quad::<T>(base, -sz),
                self.paired_quad::<T>(base, sy - sz),
            ),
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

/// The two 16-bit halves of each lane of `g`, low first, as floats:
/// unsigned for u16 grids, signed for i16.
#[inline(always)]
unsafe fn halves<S: Simd, T: Voxel>(g: S::I) -> [S::F; 2] {
    if T::KIND == VoxelKind::I16 {
        [S::to_f(S::sra(S::sll(g, 16), 16)), S::to_f(S::sra(g, 16))]
    } else {
        [
            S::to_f(S::and_i(g, S::splat_i(0xffff))),
            S::to_f(S::srl(g, 16)),
        ]
    }
}

/// The middle two columns of [`Vol::row`]'s four.
#[inline(always)]
fn mid<S: Simd>(l: [S::F; 4], h: [S::F; 4]) -> [S::F; 4] {
    [l[2], l[3], h[0], h[1]]
}

/// The trilinear value at `f` of the corners' differences `a − b`.
#[inline(always)]
unsafe fn diff<S: Simd>(a: [S::F; 8], b: [S::F; 8], f: [S::F; 3]) -> S::F {
    // (Written out: a closure would not inherit the loop's target
    // features.)
    let c = [
        a[0] - b[0],
        a[1] - b[1],
        a[2] - b[2],
        a[3] - b[3],
        a[4] - b[4],
        a[5] - b[5],
        a[6] - b[6],
        a[7] - b[7],
    ];
    trilinear::<S>(c, f)
}

/// A cell's corners `c[x + 2y + 4z]` from its rows y and y + 1, each
/// `[(x, z), (x, z + 1), (x + 1, z), (x + 1, z + 1)]`.
#[inline(always)]
fn cell_of<S: Simd>(r0: [S::F; 4], r1: [S::F; 4]) -> [S::F; 8] {
    [r0[0], r0[2], r1[0], r1[2], r0[1], r0[3], r1[1], r1[3]]
}
