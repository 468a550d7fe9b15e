//! The packets' vector code, compiled for AVX2 and for AVX-512 (see the
//! parent module): the trilinear gathers, the transfer-function rows, the
//! block exits of empty-space skipping, shading and the marching loop.

use super::{ImpState, Lane, Packets, Runs, State, LANES};
use crate::render::composite::Front;
use crate::render::march::{Next, Pending};
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

/// `a + (b − a)·t` without fusing, as the scalar path computes it.
#[inline(always)]
unsafe fn lerp(a: __m256, b: __m256, t: __m256) -> __m256 {
    _mm256_add_ps(a, _mm256_mul_ps(_mm256_sub_ps(b, a), t))
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

/// The block of coordinate `c` (≥ 0) on one axis for a ray of
/// direction `d`: `⌊c/B⌋`, or `⌈c/B⌉ − 1` going down (so a sample on a
/// face belongs to the block the ray is leaving, as in `BlockWalker`),
/// clamped to `0..=top`.
#[inline(always)]
unsafe fn block(c: __m256, d: __m256, inv_bs: __m256, top: __m256i) -> __m256i {
    let q = _mm256_mul_ps(c, inv_bs);
    let down = _mm256_cmp_ps::<_CMP_LT_OQ>(d, _mm256_setzero_ps());
    let b = _mm256_blendv_ps(
        _mm256_floor_ps(q),
        _mm256_sub_ps(_mm256_ceil_ps(q), _mm256_set1_ps(1.0)),
        down,
    );
    let b = _mm256_max_epi32(_mm256_cvttps_epi32(b), _mm256_setzero_si256());
    _mm256_min_epi32(b, top)
}

/// `[x, y, z]` of three registers.
type V3 = [__m256; 3];

/// The grid as the lanes read it (see `Grid::sample`).
struct Vol {
    data: *const u8,
    /// u8 grids: the z-paired copy (`super::z_pairs`).
    zp: *const u8,
    len_bytes: i32,
    max: V3,
    last: [__m256i; 3],
    sy: __m256i,
    sz: __m256i,
    dimx: __m256i,
    dimy: __m256i,
    scale: __m256,
    offset: __m256,
}

impl Vol {
    /// Positions clamped into the grid as `Grid::sample` clamps them
    /// (max first: a NaN becomes 0).
    #[inline(always)]
    unsafe fn clamp(&self, p: V3) -> V3 {
        let z = _mm256_setzero_ps();
        [
            _mm256_min_ps(_mm256_max_ps(p[0], z), self.max[0]),
            _mm256_min_ps(_mm256_max_ps(p[1], z), self.max[1]),
            _mm256_min_ps(_mm256_max_ps(p[2], z), self.max[2]),
        ]
    }

    /// The normalised trilinear value at `p` (voxel coordinates),
    /// lane by lane `Grid::sample`.
    #[inline(always)]
    unsafe fn sample<T: Voxel>(&self, p: V3) -> __m256 {
        let [px, py, pz] = self.clamp(p);
        let ix = _mm256_min_epi32(_mm256_cvttps_epi32(px), self.last[0]);
        let iy = _mm256_min_epi32(_mm256_cvttps_epi32(py), self.last[1]);
        let iz = _mm256_min_epi32(_mm256_cvttps_epi32(pz), self.last[2]);
        let fx = _mm256_sub_ps(px, _mm256_cvtepi32_ps(ix));
        let fy = _mm256_sub_ps(py, _mm256_cvtepi32_ps(iy));
        let fz = _mm256_sub_ps(pz, _mm256_cvtepi32_ps(iz));
        let base = _mm256_add_epi32(
            ix,
            _mm256_mullo_epi32(
                self.dimx,
                _mm256_add_epi32(iy, _mm256_mullo_epi32(self.dimy, iz)),
            ),
        );
        let (c000, c100, c010, c110, c001, c101, c011, c111);
        if T::KIND == VoxelKind::U8 {
            // Two gathers: rows y and y + 1 of the z-paired copy.
            let m = _mm256_set1_epi32(0xff);
            let g0 = _mm256_i32gather_epi32::<2>(self.zp as *const i32, base);
            let g1 =
                _mm256_i32gather_epi32::<2>(self.zp as *const i32, _mm256_add_epi32(base, self.sy));
            c000 = _mm256_cvtepi32_ps(_mm256_and_si256(g0, m));
            c001 = _mm256_cvtepi32_ps(_mm256_and_si256(_mm256_srli_epi32::<8>(g0), m));
            c100 = _mm256_cvtepi32_ps(_mm256_and_si256(_mm256_srli_epi32::<16>(g0), m));
            c101 = _mm256_cvtepi32_ps(_mm256_srli_epi32::<24>(g0));
            c010 = _mm256_cvtepi32_ps(_mm256_and_si256(g1, m));
            c011 = _mm256_cvtepi32_ps(_mm256_and_si256(_mm256_srli_epi32::<8>(g1), m));
            c110 = _mm256_cvtepi32_ps(_mm256_and_si256(_mm256_srli_epi32::<16>(g1), m));
            c111 = _mm256_cvtepi32_ps(_mm256_srli_epi32::<24>(g1));
        } else {
            let (d, n) = (self.data, self.len_bytes);
            (c000, c100) = pair::<T>(d, n, base);
            (c010, c110) = pair::<T>(d, n, _mm256_add_epi32(base, self.sy));
            (c001, c101) = pair::<T>(d, n, _mm256_add_epi32(base, self.sz));
            (c011, c111) = pair::<T>(
                d,
                n,
                _mm256_add_epi32(base, _mm256_add_epi32(self.sy, self.sz)),
            );
        }
        let c00 = lerp(c000, c100, fx);
        let c10 = lerp(c010, c110, fx);
        let c01 = lerp(c001, c101, fx);
        let c11 = lerp(c011, c111, fx);
        let c0 = lerp(c00, c10, fy);
        let c1 = lerp(c01, c11, fy);
        _mm256_add_ps(_mm256_mul_ps(lerp(c0, c1, fz), self.scale), self.offset)
    }

    /// Central-difference gradient at `p`, lane by lane `Grid::gradient`.
    #[inline(always)]
    unsafe fn gradient<T: Voxel>(&self, p: V3) -> V3 {
        let one = _mm256_set1_ps(1.0);
        let half = _mm256_set1_ps(0.5);
        let [x, y, z] = p;
        let (xp, xm) = (_mm256_add_ps(x, one), _mm256_sub_ps(x, one));
        let (yp, ym) = (_mm256_add_ps(y, one), _mm256_sub_ps(y, one));
        let (zp, zm) = (_mm256_add_ps(z, one), _mm256_sub_ps(z, one));
        let gx = _mm256_sub_ps(self.sample::<T>([xp, y, z]), self.sample::<T>([xm, y, z]));
        let gy = _mm256_sub_ps(self.sample::<T>([x, yp, z]), self.sample::<T>([x, ym, z]));
        let gz = _mm256_sub_ps(self.sample::<T>([x, y, zp]), self.sample::<T>([x, y, zm]));
        [
            _mm256_mul_ps(gx, half),
            _mm256_mul_ps(gy, half),
            _mm256_mul_ps(gz, half),
        ]
    }
}

/// `x^n` by repeated squaring (`n` ≤ 64).
#[inline(always)]
unsafe fn powi(x: __m256, n: u32) -> __m256 {
    let mut r = _mm256_set1_ps(1.0);
    let mut b = x;
    let mut n = n;
    while n > 0 {
        if n & 1 == 1 {
            r = _mm256_mul_ps(r, b);
        }
        n >>= 1;
        if n > 0 {
            b = _mm256_mul_ps(b, b);
        }
    }
    r
}

/// One channel of `BlinnPhong::shade` times the opacity: `min(c·k +
/// spec, 1)·α`, or `c·α` where the gradient is `flat`.
#[inline(always)]
unsafe fn phong(c: __m256, k: __m256, spec: __m256, flat: __m256, al: __m256) -> __m256 {
    let s = _mm256_min_ps(
        _mm256_add_ps(_mm256_mul_ps(c, k), spec),
        _mm256_set1_ps(1.0),
    );
    _mm256_mul_ps(_mm256_blendv_ps(s, c, flat), al)
}

/// The four channels of rows `i4 / 4` of a table of `[f32; 4]` rows
/// (`i4`: float offsets), one 128-bit load per lane and a transpose.
/// (No closures in these helpers: a closure does not inherit the
/// caller's AVX2, so its intrinsics would not inline.)
#[inline(always)]
unsafe fn rows(table: *const f32, i4: __m256i) -> [__m256; 4] {
    let mut ix = [0i32; LANES];
    _mm256_storeu_si256(ix.as_mut_ptr() as *mut __m256i, i4);
    let a0 = _mm256_set_m128(
        _mm_loadu_ps(table.add(ix[4] as usize)),
        _mm_loadu_ps(table.add(ix[0] as usize)),
    );
    let a1 = _mm256_set_m128(
        _mm_loadu_ps(table.add(ix[5] as usize)),
        _mm_loadu_ps(table.add(ix[1] as usize)),
    );
    let a2 = _mm256_set_m128(
        _mm_loadu_ps(table.add(ix[6] as usize)),
        _mm_loadu_ps(table.add(ix[2] as usize)),
    );
    let a3 = _mm256_set_m128(
        _mm_loadu_ps(table.add(ix[7] as usize)),
        _mm_loadu_ps(table.add(ix[3] as usize)),
    );
    let t0 = _mm256_unpacklo_ps(a0, a1);
    let t1 = _mm256_unpacklo_ps(a2, a3);
    let t2 = _mm256_unpackhi_ps(a0, a1);
    let t3 = _mm256_unpackhi_ps(a2, a3);
    [
        _mm256_shuffle_ps::<0x44>(t0, t1),
        _mm256_shuffle_ps::<0xEE>(t0, t1),
        _mm256_shuffle_ps::<0x44>(t2, t3),
        _mm256_shuffle_ps::<0xEE>(t2, t3),
    ]
}

#[inline(always)]
unsafe fn load(v: [f32; LANES]) -> __m256 {
    _mm256_loadu_ps(v.as_ptr())
}

#[inline(always)]
unsafe fn dot(a: V3, b: V3) -> __m256 {
    _mm256_add_ps(
        _mm256_add_ps(_mm256_mul_ps(a[0], b[0]), _mm256_mul_ps(a[1], b[1])),
        _mm256_mul_ps(a[2], b[2]),
    )
}

/// Marches the lanes' vector stretches `k0..k_end`: adds each lane's
/// colour and opacity to `st.acc`, its samples, shaded samples and
/// interpolations to `st.count`, and leaves `st.alive` false for lanes
/// that terminated early. `SKIP`: empty-space skipping (`pk.empty`);
/// `SHADE`: Blinn–Phong (`pk.shading`); `IMP`: `importance`'s walks
/// (`st.imp`); `R::ON`: a step-per-block march's runs (`st.runs`), with
/// S0's grouped reuse where `GROUPED`.
///
/// # Safety
/// The level's instructions present (AVX2 and FMA, and for
/// `march_avx512` AVX-512 F and VL); the grid `fits`; the shading
/// `shades`; for a u8 grid, `pk.z_pairs` is its z-paired copy.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn march_avx2<
    T: Voxel,
    R: Runs<T>,
    const SKIP: bool,
    const SHADE: bool,
    const IMP: bool,
    const GROUPED: bool,
>(
    pk: &Packets<'_, T, R>,
    lanes: &[Option<Lane>; LANES],
    st: &mut State<'_>,
) {
    march::<T, R, SKIP, SHADE, IMP, GROUPED>(pk, lanes, st)
}

/// [`march_avx2`], compiled with AVX-512 F and VL as well (same lanes,
/// same arithmetic, twice the registers).
///
/// # Safety
/// As [`march_avx2`].
#[target_feature(enable = "avx2,fma,avx512f,avx512vl")]
pub(super) unsafe fn march_avx512<
    T: Voxel,
    R: Runs<T>,
    const SKIP: bool,
    const SHADE: bool,
    const IMP: bool,
    const GROUPED: bool,
>(
    pk: &Packets<'_, T, R>,
    lanes: &[Option<Lane>; LANES],
    st: &mut State<'_>,
) {
    march::<T, R, SKIP, SHADE, IMP, GROUPED>(pk, lanes, st)
}

/// A lane mask from the low `LANES` bits of `bits`.
#[inline(always)]
unsafe fn mask(bits: i32) -> __m256 {
    let lane_bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
    _mm256_castsi256_ps(_mm256_cmpeq_epi32(
        _mm256_and_si256(_mm256_set1_epi32(bits), lane_bits),
        lane_bits,
    ))
}

#[inline(always)]
unsafe fn store(v: __m256) -> [f32; LANES] {
    let mut a = [0f32; LANES];
    _mm256_storeu_ps(a.as_mut_ptr(), v);
    a
}

#[inline(always)]
unsafe fn store_i(v: __m256i) -> [i32; LANES] {
    let mut a = [0i32; LANES];
    _mm256_storeu_si256(a.as_mut_ptr() as *mut __m256i, v);
    a
}

#[inline(always)]
unsafe fn load_i(v: [i32; LANES]) -> __m256i {
    _mm256_loadu_si256(v.as_ptr() as *const __m256i)
}

/// A step-per-block march's lane state in the vector loop: each lane's
/// run (`k` up to `kend`, step, table offset, group cap), its grouped
/// reuse (`fresh`: the next sample starts a group; the last evaluated
/// sample), and the pending last sample of its run.
struct RunRegs {
    stv: __m256,
    kend: __m256,
    offv: __m256i,
    capv: __m256,
    fresh: __m256,
    /// `group_size`'s thresholds: a third and two thirds of the exit.
    th1: __m256,
    th2: __m256,
    /// The last evaluated sample: colour, opacity, entry, validity.
    last: [__m256; 4],
    last_idx: __m256i,
    last_ok: __m256,
    /// The run's last sample: colour, opacity, position, entry, validity.
    pend: [__m256; 5],
    pend_idx: __m256i,
    pend_ok: __m256,
}

/// The loop of both levels, inlined into each.
///
/// # Safety
/// As [`march_avx2`].
#[inline(always)]
unsafe fn march<
    T: Voxel,
    R: Runs<T>,
    const SKIP: bool,
    const SHADE: bool,
    const IMP: bool,
    const GROUPED: bool,
>(
    pk: &Packets<'_, T, R>,
    lanes: &[Option<Lane>; LANES],
    st: &mut State<'_>,
) {
    let f = pk.f;
    let (data, step, last, max) = f.grid.layout();
    let (scale, offset) = f.grid.scale_offset();
    let dims = f.grid.dims();
    let vol = Vol {
        data: data.as_ptr() as *const u8,
        zp: pk.z_pairs.as_ptr() as *const u8,
        len_bytes: std::mem::size_of_val(data) as i32,
        max: [
            _mm256_set1_ps(max.x),
            _mm256_set1_ps(max.y),
            _mm256_set1_ps(max.z),
        ],
        last: [
            _mm256_set1_epi32(last[0] as i32),
            _mm256_set1_epi32(last[1] as i32),
            _mm256_set1_epi32(last[2] as i32),
        ],
        sy: _mm256_set1_epi32(step[1] as i32),
        sz: _mm256_set1_epi32(step[2] as i32),
        dimx: _mm256_set1_epi32(dims[0] as i32),
        dimy: _mm256_set1_epi32(dims[1] as i32),
        scale: _mm256_set1_ps(scale),
        offset: _mm256_set1_ps(offset),
    };
    let mut a = [[0f32; LANES]; 12];
    let (mut k, mut kend) = ([0f32; LANES], [0f32; LANES]);
    let mut live_bits = 0i32;
    for (i, l) in lanes.iter().enumerate() {
        if let Some(l) = l {
            // `group_size`'s thresholds of the lane's exit.
            let t_out = match &st.runs[i] {
                Some(w) if R::ON => w.seg.t_out,
                _ => 0.0,
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
    let o: V3 = [load(a[0]), load(a[1]), load(a[2])];
    let d: V3 = [load(a[3]), load(a[4]), load(a[5])];
    let t0 = load(a[6]);
    let view: V3 = [load(a[7]), load(a[8]), load(a[9])];
    let mut kv = load(k);
    let kend = load(kend);
    let zero = _mm256_setzero_ps();
    let one = _mm256_set1_ps(1.0);
    let mut rr = RunRegs {
        stv: one,
        kend,
        offv: _mm256_setzero_si256(),
        capv: _mm256_set1_ps(3.0),
        fresh: zero,
        th1: load(a[10]),
        th2: load(a[11]),
        last: [zero; 4],
        last_idx: _mm256_setzero_si256(),
        last_ok: zero,
        pend: [zero; 5],
        pend_idx: _mm256_setzero_si256(),
        pend_ok: zero,
    };
    let stv = _mm256_set1_ps(pk.st);
    let top = _mm256_set1_ps((crate::transfer::LUT_SIZE - 1) as f32);
    let half = _mm256_set1_ps(0.5);
    let q = match (IMP, &pk.imp, pk.runs) {
        (true, Some(ip), _) => ip.tables.as_ptr() as *const f32,
        (false, _, Some(r)) if R::ON => r.tables().as_ptr() as *const f32,
        _ => pk.q.as_ptr() as *const f32,
    };
    let rgb = f.lut.entries().as_ptr() as *const f32;
    let (we, wa) = (
        _mm256_set1_ps(pk.weights.emission),
        _mm256_set1_ps(pk.weights.absorption),
    );
    let stop = _mm256_set1_ps(pk.stop);
    // Shading constants.
    let bp = pk.shading.unwrap_or_default();
    let inv_sp = [
        _mm256_set1_ps(f.inv_spacing.x),
        _mm256_set1_ps(f.inv_spacing.y),
        _mm256_set1_ps(f.inv_spacing.z),
    ];
    let min_g2 = _mm256_set1_ps(bp.min_gradient * bp.min_gradient);
    let (amb, dif, spe) = (
        _mm256_set1_ps(bp.ambient),
        _mm256_set1_ps(bp.diffuse),
        _mm256_set1_ps(bp.specular),
    );
    let shin = bp.shininess as u32;
    let abs_mask = _mm256_castsi256_ps(_mm256_set1_epi32(i32::MAX));
    // Blocks, for skipping.
    let inv_bs = _mm256_set1_ps(1.0 / f.block_size as f32);
    let bsv = _mm256_set1_ps(f.block_size as f32);
    let [cx, cy, cz] = [0, 1, 2].map(|a| f.block_counts[a] as i32);
    let bmax = [
        _mm256_set1_epi32(cx - 1),
        _mm256_set1_epi32(cy - 1),
        _mm256_set1_epi32(cz - 1),
    ];
    let (ncx, ncy) = (_mm256_set1_epi32(cx), _mm256_set1_epi32(cy));
    let empty = pk.empty.map_or(std::ptr::null(), |e| e.as_ptr());
    // Lane state.
    let mut live = mask(live_bits);
    let mut walked = zero;
    // Each lane goes on from the colour and opacity it holds (zero for a
    // new ray; a brick's predecessors' for the out-of-core renderer).
    let mut start = [[0f32; LANES]; 4];
    for (i, c) in st.acc.iter().enumerate() {
        start[0][i] = c.x;
        start[1][i] = c.y;
        start[2][i] = c.z;
        start[3][i] = c.w;
    }
    let (mut cr, mut cg, mut cb, mut ca) = (
        load(start[0]),
        load(start[1]),
        load(start[2]),
        load(start[3]),
    );
    let mut cnt = _mm256_setzero_si256();
    let mut cnt_shaded = _mm256_setzero_si256();
    let mut cnt_interp = _mm256_setzero_si256();
    // `importance`: each lane's position, spacing, stretch end and
    // table offset; every lane starts by fetching its first stretch.
    let mut is = ImpState::default();
    let (mut tv, mut sv, mut tbv, mut offv) = (zero, one, zero, _mm256_setzero_si256());
    if IMP {
        is.tb = [f32::NEG_INFINITY; LANES];
        tbv = load(is.tb);
    }
    loop {
        if IMP {
            // Lanes past their stretch walk on to the next one (scalar).
            let need = _mm256_and_ps(live, _mm256_cmp_ps::<_CMP_GE_OQ>(tv, tbv));
            let bits = _mm256_movemask_ps(need);
            if bits != 0 {
                let ip = pk.imp.as_ref().unwrap_unchecked();
                _mm256_storeu_ps(is.t.as_mut_ptr(), tv);
                _mm256_storeu_ps(is.s.as_mut_ptr(), sv);
                _mm256_storeu_ps(is.tb.as_mut_ptr(), tbv);
                _mm256_storeu_si256(is.off.as_mut_ptr() as *mut __m256i, offv);
                let mut dead = 0i32;
                for (i, l) in st.imp.iter_mut().enumerate() {
                    if (bits >> i) & 1 == 0 {
                        continue;
                    }
                    let l = l.as_mut().unwrap_unchecked();
                    match ip.next(l, is.t[i], is.s[i], is.tb[i]) {
                        Some((t, s, tb, j)) => {
                            is.t[i] = t;
                            is.s[i] = s;
                            is.tb[i] = tb;
                            is.off[i] = (j * crate::transfer::LUT_SIZE * 4) as i32;
                        }
                        None => dead |= 1 << i,
                    }
                }
                tv = load(is.t);
                sv = load(is.s);
                tbv = load(is.tb);
                offv = _mm256_loadu_si256(is.off.as_ptr() as *const __m256i);
                // A lane whose walk ended is done, and not terminated.
                let ended = mask(dead);
                live = _mm256_andnot_ps(ended, live);
                walked = _mm256_or_ps(walked, ended);
            }
        }
        if R::ON {
            // Lanes past their run composite its last sample and walk on
            // to the next run (scalar).
            let need = _mm256_and_ps(live, _mm256_cmp_ps::<_CMP_GE_OQ>(kv, rr.kend));
            let bits = _mm256_movemask_ps(need);
            if bits != 0 {
                let (ended, dead) = walk_runs::<T, R>(
                    pk,
                    st,
                    bits,
                    &mut rr,
                    &mut kv,
                    [&mut cr, &mut cg, &mut cb, &mut ca],
                );
                live = _mm256_andnot_ps(_mm256_or_ps(ended, dead), live);
                walked = _mm256_or_ps(walked, ended);
            }
        }
        let act = if IMP {
            live
        } else {
            _mm256_and_ps(
                live,
                _mm256_cmp_ps::<_CMP_LT_OQ>(kv, if R::ON { rr.kend } else { kend }),
            )
        };
        if _mm256_movemask_ps(act) == 0 {
            break;
        }
        let t = if IMP {
            let t = tv;
            tv = _mm256_blendv_ps(tv, _mm256_add_ps(tv, sv), act);
            t
        } else if R::ON {
            _mm256_add_ps(t0, _mm256_mul_ps(kv, rr.stv))
        } else {
            _mm256_add_ps(t0, _mm256_mul_ps(kv, stv))
        };
        let p: V3 = [
            _mm256_add_ps(o[0], _mm256_mul_ps(d[0], t)),
            _mm256_add_ps(o[1], _mm256_mul_ps(d[1], t)),
            _mm256_add_ps(o[2], _mm256_mul_ps(d[2], t)),
        ];
        let mut samp = act;
        let mut next = _mm256_add_ps(kv, one);
        if SKIP {
            let c = vol.clamp(p);
            // The block walk's rule: on a face, a ray going down
            // belongs to the block below.
            let b3: [__m256i; 3] = [
                block(c[0], d[0], inv_bs, bmax[0]),
                block(c[1], d[1], inv_bs, bmax[1]),
                block(c[2], d[2], inv_bs, bmax[2]),
            ];
            let b = _mm256_add_epi32(
                b3[0],
                _mm256_mullo_epi32(ncx, _mm256_add_epi32(b3[1], _mm256_mullo_epi32(ncy, b3[2]))),
            );
            let e = _mm256_i32gather_epi32::<4>(empty, b);
            let skip = _mm256_and_ps(act, _mm256_castsi256_ps(e));
            if _mm256_movemask_ps(skip) != 0 {
                // The lane's exit from its block: the nearest far face.
                let te = _mm256_min_ps(
                    _mm256_min_ps(exit(o[0], d[0], b3[0], bsv), exit(o[1], d[1], b3[1], bsv)),
                    exit(o[2], d[2], b3[2], bsv),
                );
                // First sample past the exit (a hair early: a sample
                // still inside is tested again, never one skipped).
                let kn = _mm256_ceil_ps(_mm256_sub_ps(
                    _mm256_div_ps(_mm256_sub_ps(te, t0), stv),
                    _mm256_set1_ps(1e-3),
                ));
                next = _mm256_blendv_ps(next, _mm256_max_ps(next, kn), skip);
                samp = _mm256_andnot_ps(skip, act);
            }
        }
        // A step-per-block march: the run's last sample waits for its
        // stretch; grouped reuse evaluates only where a group starts.
        let (is_last, eval) = if R::ON {
            let is_last = _mm256_and_ps(
                act,
                _mm256_cmp_ps::<_CMP_EQ_OQ>(kv, _mm256_sub_ps(rr.kend, one)),
            );
            let eval = if GROUPED {
                // `group_size(t, t_out).min(cap)` divides k.
                let g = _mm256_add_ps(
                    _mm256_add_ps(
                        one,
                        _mm256_and_ps(_mm256_cmp_ps::<_CMP_GT_OQ>(t, rr.th1), one),
                    ),
                    _mm256_and_ps(_mm256_cmp_ps::<_CMP_GT_OQ>(t, rr.th2), one),
                );
                let g = _mm256_min_ps(g, rr.capv);
                let div = _mm256_cmp_ps::<_CMP_EQ_OQ>(
                    _mm256_mul_ps(_mm256_floor_ps(_mm256_div_ps(kv, g)), g),
                    kv,
                );
                let eval = _mm256_and_ps(act, _mm256_or_ps(rr.fresh, div));
                rr.fresh = _mm256_andnot_ps(act, rr.fresh);
                eval
            } else {
                act
            };
            (is_last, eval)
        } else {
            (zero, samp)
        };
        if !IMP {
            kv = _mm256_blendv_ps(kv, next, act);
        }
        if !R::ON && _mm256_movemask_ps(samp) == 0 {
            continue;
        }
        cnt = _mm256_sub_epi32(cnt, _mm256_castps_si256(samp));
        let (mut er, mut eg, mut eb, mut al, mut valid, mut idx) =
            (zero, zero, zero, zero, zero, _mm256_setzero_si256());
        if !GROUPED || _mm256_movemask_ps(eval) != 0 {
            cnt_interp = _mm256_sub_epi32(cnt_interp, _mm256_castps_si256(eval));
            let v = vol.sample::<T>(p);
            // `Lut::index`: below 0 (or NaN) nothing; the lane's entry 0
            // is read and masked out.
            valid = _mm256_and_ps(eval, _mm256_cmp_ps::<_CMP_GE_OQ>(v, zero));
            let x = _mm256_add_ps(_mm256_mul_ps(_mm256_min_ps(v, one), top), half);
            idx = _mm256_and_si256(_mm256_cvttps_epi32(x), _mm256_castps_si256(valid));
            let i4 = _mm256_slli_epi32::<2>(idx);
            // The eight table rows: loaded whole and transposed (cheaper
            // than four gathers); `importance` and the step-per-block
            // marches read their lane's level.
            let [qr, qg, qb, qa] = if IMP {
                rows(q, _mm256_add_epi32(i4, offv))
            } else if R::ON {
                rows(q, _mm256_add_epi32(i4, rr.offv))
            } else {
                rows(q, i4)
            };
            al = qa;
            if SHADE {
                // Transparent samples are culled before shading.
                valid = _mm256_and_ps(valid, _mm256_cmp_ps::<_CMP_GT_OQ>(al, zero));
                if _mm256_movemask_ps(valid) == 0 {
                    if !R::ON {
                        continue;
                    }
                } else {
                    let [r, g, b, _] = rows(rgb, i4);
                    let c = [r, g, b];
                    let g = vol.gradient::<T>(p);
                    let flat = _mm256_cmp_ps::<_CMP_LT_OQ>(dot(g, g), min_g2);
                    let gw: V3 = [
                        _mm256_mul_ps(g[0], inv_sp[0]),
                        _mm256_mul_ps(g[1], inv_sp[1]),
                        _mm256_mul_ps(g[2], inv_sp[2]),
                    ];
                    let inv_len = _mm256_div_ps(one, _mm256_sqrt_ps(dot(gw, gw)));
                    let n: V3 = [
                        _mm256_mul_ps(gw[0], inv_len),
                        _mm256_mul_ps(gw[1], inv_len),
                        _mm256_mul_ps(gw[2], inv_len),
                    ];
                    let ndl = _mm256_and_ps(dot(n, view), abs_mask);
                    let spec = _mm256_mul_ps(spe, powi(ndl, shin));
                    let k = _mm256_add_ps(amb, _mm256_mul_ps(dif, ndl));
                    er = _mm256_and_ps(phong(c[0], k, spec, flat, al), valid);
                    eg = _mm256_and_ps(phong(c[1], k, spec, flat, al), valid);
                    eb = _mm256_and_ps(phong(c[2], k, spec, flat, al), valid);
                    cnt_shaded = _mm256_sub_epi32(cnt_shaded, _mm256_castps_si256(valid));
                }
            } else {
                er = _mm256_and_ps(qr, valid);
                eg = _mm256_and_ps(qg, valid);
                eb = _mm256_and_ps(qb, valid);
            }
            al = _mm256_and_ps(al, valid);
            if GROUPED {
                // The lanes that evaluated keep their sample for reuse.
                for (l, e) in rr.last.iter_mut().zip([er, eg, eb, al]) {
                    *l = _mm256_blendv_ps(*l, e, eval);
                }
                rr.last_idx = _mm256_castps_si256(_mm256_blendv_ps(
                    _mm256_castsi256_ps(rr.last_idx),
                    _mm256_castsi256_ps(idx),
                    eval,
                ));
                rr.last_ok = _mm256_blendv_ps(rr.last_ok, valid, eval);
            }
        }
        if GROUPED {
            // Every sampling lane composites its group's value (lanes
            // that ended or terminated keep theirs, unused).
            [er, eg, eb, al] = rr.last.map(|v| _mm256_and_ps(v, act));
            idx = rr.last_idx;
            valid = _mm256_and_ps(rr.last_ok, act);
        }
        if R::ON {
            // The run's last sample waits for its stretch (the walk
            // composites it); the others composite with the run's step.
            let e = [er, eg, eb, al, t];
            for (pnd, e) in rr.pend.iter_mut().zip(e) {
                *pnd = _mm256_blendv_ps(*pnd, e, is_last);
            }
            rr.pend_idx = _mm256_castps_si256(_mm256_blendv_ps(
                _mm256_castsi256_ps(rr.pend_idx),
                _mm256_castsi256_ps(idx),
                is_last,
            ));
            rr.pend_ok = _mm256_blendv_ps(rr.pend_ok, valid, is_last);
            valid = _mm256_andnot_ps(is_last, valid);
            er = _mm256_andnot_ps(is_last, er);
            eg = _mm256_andnot_ps(is_last, eg);
            eb = _mm256_andnot_ps(is_last, eb);
            al = _mm256_andnot_ps(is_last, al);
        }
        // Front to back (`over_front` with the optical model's weights).
        let tr = _mm256_sub_ps(one, ca);
        cr = _mm256_add_ps(cr, _mm256_mul_ps(_mm256_mul_ps(er, we), tr));
        cg = _mm256_add_ps(cg, _mm256_mul_ps(_mm256_mul_ps(eg, we), tr));
        cb = _mm256_add_ps(cb, _mm256_mul_ps(_mm256_mul_ps(eb, we), tr));
        ca = _mm256_add_ps(ca, _mm256_mul_ps(_mm256_mul_ps(al, wa), tr));
        let done = _mm256_and_ps(valid, _mm256_cmp_ps::<_CMP_GE_OQ>(ca, stop));
        live = _mm256_andnot_ps(done, live);
    }
    if !R::ON {
        cnt_interp = cnt;
    }
    let [cr, cg, cb, ca] = [store(cr), store(cg), store(cb), store(ca)];
    let (c, cs, ci) = (store_i(cnt), store_i(cnt_shaded), store_i(cnt_interp));
    // Lanes whose walk ended count as alive (not terminated early).
    let l = _mm256_movemask_ps(_mm256_or_ps(live, walked));
    for i in 0..LANES {
        st.acc[i] = Vec4::new(cr[i], cg[i], cb[i], ca[i]);
        st.count[i] = [c[i] as u32, cs[i] as u32, ci[i] as u32];
        st.alive[i] = lanes[i].is_some() && (l >> i) & 1 == 1;
    }
}

/// The step-per-block lanes of `bits`, past their run: each hands its
/// run's last sample to its walk, which composites it and finds the next
/// run (scalar). Returns the masks of the lanes whose walk ended and of
/// those that terminated.
///
/// # Safety
/// As [`march_avx2`]; `st.runs` holds a walk for every lane of `bits`.
#[inline(always)]
unsafe fn walk_runs<T: Voxel, R: Runs<T>>(
    pk: &Packets<'_, T, R>,
    st: &mut State<'_>,
    bits: i32,
    rr: &mut RunRegs,
    kv: &mut __m256,
    c: [&mut __m256; 4],
) -> (__m256, __m256) {
    let runs = pk.runs.unwrap_unchecked();
    let mut col = [store(*c[0]), store(*c[1]), store(*c[2]), store(*c[3])];
    let pend = rr.pend.map(|p| store(p));
    let pend_idx = store_i(rr.pend_idx);
    let pend_ok = store_i(_mm256_castps_si256(rr.pend_ok));
    let (mut k, mut kend, mut s, mut cap, mut fresh) = (
        store(*kv),
        store(rr.kend),
        store(rr.stv),
        store(rr.capv),
        store_i(_mm256_castps_si256(rr.fresh)),
    );
    let mut off = store_i(rr.offv);
    let (mut ended, mut dead) = (0i32, 0i32);
    for (i, w) in st.runs.iter_mut().enumerate() {
        if (bits >> i) & 1 == 0 {
            continue;
        }
        let w = w.as_mut().unwrap_unchecked();
        // The run's last sample (none before the first run).
        if pend_ok[i] != 0 {
            w.pending = Some(Pending {
                t: pend[4][i],
                entry: pend_idx[i] as usize,
                e: glam::Vec3::new(pend[0][i], pend[1][i], pend[2][i]),
                a: pend[3][i],
            });
        }
        let acc = Vec4::new(col[0][i], col[1][i], col[2][i], col[3][i]);
        let mut c = Front::resume(acc, pk.weights, pk.stop);
        match runs.next(pk.f, w, &mut c, st.walk) {
            Next::Run(r) => {
                k[i] = r.n0 as f32;
                kend[i] = r.n1 as f32;
                s[i] = runs.step(r.li);
                off[i] = (r.li * crate::transfer::LUT_SIZE * 4) as i32;
                cap[i] = r.cap.min(3) as f32;
                fresh[i] = -1;
            }
            Next::Ended => ended |= 1 << i,
            Next::Terminated => dead |= 1 << i,
        }
        let acc = c.acc();
        for (ch, v) in col.iter_mut().zip(acc.to_array()) {
            ch[i] = v;
        }
    }
    *kv = load(k);
    rr.kend = load(kend);
    rr.stv = load(s);
    rr.capv = load(cap);
    rr.fresh = _mm256_castsi256_ps(load_i(fresh));
    rr.offv = load_i(off);
    // Each pending sample is now with its walk.
    rr.pend_ok = _mm256_andnot_ps(mask(bits), rr.pend_ok);
    for (r, v) in c.into_iter().zip(col) {
        *r = load(v);
    }
    (mask(ended), mask(dead))
}
