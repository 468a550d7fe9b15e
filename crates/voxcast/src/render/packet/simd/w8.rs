//! [`W8`]: eight lanes in AVX2 registers, lane masks as float vectors
//! (all ones or all zeros per lane); its fetches by the AVX2 gathers, or
//! lane by lane with scalar loads (`W8<true>`).

use super::{Simd, W8};
use std::arch::x86_64::*;

/// Eight floats.
#[derive(Clone, Copy)]
pub(in crate::render::packet) struct F8(pub __m256);

/// Eight 32-bit integers.
#[derive(Clone, Copy)]
pub(in crate::render::packet) struct I8(pub __m256i);

// SAFETY (every `unsafe` block of this file): these values exist only
// inside functions compiled for AVX2 (see the parent module).
op!(F8, Add, add, _mm256_add_ps);
op!(F8, Sub, sub, _mm256_sub_ps);
op!(F8, Mul, mul, _mm256_mul_ps);
op!(F8, Div, div, _mm256_div_ps);
op!(I8, Add, add, _mm256_add_epi32);
op!(I8, Sub, sub, _mm256_sub_epi32);

/// Floats 0, 2, 4, 6 of `a` then of `b`: shuffled within the 128-bit
/// halves (a0 a2 b0 b2 | a4 a6 b4 b6), then the 64-bit pairs reordered.
#[inline(always)]
unsafe fn evens(a: __m256, b: __m256) -> __m256 {
    let s = _mm256_shuffle_ps::<0x88>(a, b);
    _mm256_castpd_ps(_mm256_permute4x64_pd::<0xD8>(_mm256_castps_pd(s)))
}

/// Floats 1, 3, 5, 7 of `a` then of `b`.
#[inline(always)]
unsafe fn odds(a: __m256, b: __m256) -> __m256 {
    let s = _mm256_shuffle_ps::<0xDD>(a, b);
    _mm256_castpd_ps(_mm256_permute4x64_pd::<0xD8>(_mm256_castps_pd(s)))
}

/// For each 8-lane mask, a permute as eight nibbles: with `expand`
/// false the lanes it holds in order (the rest zero), with `expand` true
/// each of its lanes' rank among them (zero for the others).
const fn nibble_table(expand: bool) -> [u32; 256] {
    let mut t = [0u32; 256];
    let mut m = 0;
    while m < 256 {
        let (mut packed, mut k, mut i) = (0u32, 0, 0);
        while i < 8 {
            if (m >> i) & 1 == 1 {
                packed |= if expand {
                    (k as u32) << (4 * i)
                } else {
                    (i as u32) << (4 * k)
                };
                k += 1;
            }
            i += 1;
        }
        t[m] = packed;
        m += 1;
    }
    t
}

/// AVX2 has no compress: a permute by this order.
static COMPRESS: [u32; 256] = nibble_table(false);

/// Nor an expand: [`Simd::expand_order`] permutes by these ranks.
static EXPAND: [u32; 256] = nibble_table(true);

/// The nibbles of `packed` as eight lanes.
#[inline(always)]
unsafe fn nibbles(packed: u32) -> __m256i {
    let sh = _mm256_srlv_epi32(
        _mm256_set1_epi32(packed as i32),
        _mm256_setr_epi32(0, 4, 8, 12, 16, 20, 24, 28),
    );
    _mm256_and_si256(sh, _mm256_set1_epi32(7))
}

/// The permute that moves the lanes of `m` to the front, in order.
#[inline(always)]
unsafe fn compress_order(m: __m256) -> __m256i {
    nibbles(COMPRESS[_mm256_movemask_ps(m) as usize & 0xff])
}

impl<const LOADS: bool> Simd for W8<LOADS> {
    const N: usize = 8;
    type F = F8;
    type I = I8;
    type M = __m256;
    type Af = [f32; 8];
    type Ai = [i32; 8];

    #[inline(always)]
    unsafe fn splat(x: f32) -> F8 {
        F8(_mm256_set1_ps(x))
    }
    #[inline(always)]
    unsafe fn load(a: [f32; 8]) -> F8 {
        F8(_mm256_loadu_ps(a.as_ptr()))
    }
    #[inline(always)]
    unsafe fn store(v: F8) -> [f32; 8] {
        let mut a = [0f32; 8];
        _mm256_storeu_ps(a.as_mut_ptr(), v.0);
        a
    }
    #[inline(always)]
    unsafe fn min(a: F8, b: F8) -> F8 {
        F8(_mm256_min_ps(a.0, b.0))
    }
    #[inline(always)]
    unsafe fn max(a: F8, b: F8) -> F8 {
        F8(_mm256_max_ps(a.0, b.0))
    }
    #[inline(always)]
    unsafe fn floor(a: F8) -> F8 {
        F8(_mm256_floor_ps(a.0))
    }
    #[inline(always)]
    unsafe fn ceil(a: F8) -> F8 {
        F8(_mm256_ceil_ps(a.0))
    }
    #[inline(always)]
    unsafe fn sqrt(a: F8) -> F8 {
        F8(_mm256_sqrt_ps(a.0))
    }
    #[inline(always)]
    unsafe fn rsqrt(a: F8) -> F8 {
        // A 12-bit estimate, then y·(3 − a·y²)/2.
        let y = _mm256_rsqrt_ps(a.0);
        let ay2 = _mm256_mul_ps(_mm256_mul_ps(a.0, y), y);
        let h = _mm256_mul_ps(y, _mm256_set1_ps(0.5));
        F8(_mm256_mul_ps(h, _mm256_sub_ps(_mm256_set1_ps(3.0), ay2)))
    }
    #[inline(always)]
    unsafe fn abs(a: F8) -> F8 {
        F8(_mm256_and_ps(
            a.0,
            _mm256_castsi256_ps(_mm256_set1_epi32(i32::MAX)),
        ))
    }
    #[inline(always)]
    unsafe fn to_i(a: F8) -> I8 {
        I8(_mm256_cvttps_epi32(a.0))
    }
    #[inline(always)]
    unsafe fn lt(a: F8, b: F8) -> __m256 {
        _mm256_cmp_ps::<_CMP_LT_OQ>(a.0, b.0)
    }
    #[inline(always)]
    unsafe fn gt(a: F8, b: F8) -> __m256 {
        _mm256_cmp_ps::<_CMP_GT_OQ>(a.0, b.0)
    }
    #[inline(always)]
    unsafe fn ge(a: F8, b: F8) -> __m256 {
        _mm256_cmp_ps::<_CMP_GE_OQ>(a.0, b.0)
    }
    #[inline(always)]
    unsafe fn eq(a: F8, b: F8) -> __m256 {
        _mm256_cmp_ps::<_CMP_EQ_OQ>(a.0, b.0)
    }
    #[inline(always)]
    unsafe fn blend(m: __m256, f: F8, t: F8) -> F8 {
        F8(_mm256_blendv_ps(f.0, t.0, m))
    }
    #[inline(always)]
    unsafe fn keep(m: __m256, v: F8) -> F8 {
        F8(_mm256_and_ps(v.0, m))
    }
    #[inline(always)]
    unsafe fn zero(m: __m256, v: F8) -> F8 {
        F8(_mm256_andnot_ps(m, v.0))
    }

    #[inline(always)]
    unsafe fn splat_i(x: i32) -> I8 {
        I8(_mm256_set1_epi32(x))
    }
    #[inline(always)]
    unsafe fn load_i(a: [i32; 8]) -> I8 {
        I8(_mm256_loadu_si256(a.as_ptr() as *const __m256i))
    }
    #[inline(always)]
    unsafe fn store_i(v: I8) -> [i32; 8] {
        let mut a = [0i32; 8];
        _mm256_storeu_si256(a.as_mut_ptr() as *mut __m256i, v.0);
        a
    }
    #[inline(always)]
    unsafe fn of_bits(a: I8) -> F8 {
        F8(_mm256_castsi256_ps(a.0))
    }
    #[inline(always)]
    unsafe fn as_bits(a: F8) -> I8 {
        I8(_mm256_castps_si256(a.0))
    }
    #[inline(always)]
    unsafe fn to_f(a: I8) -> F8 {
        F8(_mm256_cvtepi32_ps(a.0))
    }
    #[inline(always)]
    unsafe fn mullo(a: I8, b: I8) -> I8 {
        I8(_mm256_mullo_epi32(a.0, b.0))
    }
    #[inline(always)]
    unsafe fn min_i(a: I8, b: I8) -> I8 {
        I8(_mm256_min_epi32(a.0, b.0))
    }
    #[inline(always)]
    unsafe fn max_i(a: I8, b: I8) -> I8 {
        I8(_mm256_max_epi32(a.0, b.0))
    }
    #[inline(always)]
    unsafe fn and_i(a: I8, b: I8) -> I8 {
        I8(_mm256_and_si256(a.0, b.0))
    }
    #[inline(always)]
    unsafe fn srl(a: I8, k: i32) -> I8 {
        I8(_mm256_srl_epi32(a.0, _mm_cvtsi32_si128(k)))
    }
    #[inline(always)]
    unsafe fn sll(a: I8, k: i32) -> I8 {
        I8(_mm256_sll_epi32(a.0, _mm_cvtsi32_si128(k)))
    }
    #[inline(always)]
    unsafe fn sra(a: I8, k: i32) -> I8 {
        I8(_mm256_sra_epi32(a.0, _mm_cvtsi32_si128(k)))
    }
    #[inline(always)]
    unsafe fn blend_i(m: __m256, f: I8, t: I8) -> I8 {
        I8(_mm256_castps_si256(_mm256_blendv_ps(
            _mm256_castsi256_ps(f.0),
            _mm256_castsi256_ps(t.0),
            m,
        )))
    }
    #[inline(always)]
    unsafe fn keep_i(m: __m256, v: I8) -> I8 {
        I8(_mm256_and_si256(v.0, _mm256_castps_si256(m)))
    }
    #[inline(always)]
    unsafe fn count(a: I8, m: __m256) -> I8 {
        // A mask lane is −1.
        I8(_mm256_sub_epi32(a.0, _mm256_castps_si256(m)))
    }
    #[inline(always)]
    unsafe fn positive(a: I8) -> __m256 {
        _mm256_castsi256_ps(_mm256_cmpgt_epi32(a.0, _mm256_setzero_si256()))
    }
    #[inline(always)]
    unsafe fn gather<const SCALE: i32>(p: *const i32, idx: I8) -> I8 {
        if LOADS {
            let ix = Self::store_i(idx);
            let b = p as *const u8;
            let at = |k: usize| b.wrapping_offset(ix[k] as isize * SCALE as isize) as *const i32;
            return I8(_mm256_setr_epi32(
                at(0).read_unaligned(),
                at(1).read_unaligned(),
                at(2).read_unaligned(),
                at(3).read_unaligned(),
                at(4).read_unaligned(),
                at(5).read_unaligned(),
                at(6).read_unaligned(),
                at(7).read_unaligned(),
            ));
        }
        I8(_mm256_i32gather_epi32::<SCALE>(p, idx.0))
    }
    #[inline(always)]
    unsafe fn gather_f<const SCALE: i32>(p: *const f32, idx: I8) -> F8 {
        if LOADS {
            return F8(_mm256_castsi256_ps(
                Self::gather::<SCALE>(p as *const i32, idx).0,
            ));
        }
        F8(_mm256_i32gather_ps::<SCALE>(p, idx.0))
    }
    #[inline(always)]
    unsafe fn gather_pair<const SCALE: i32>(p: *const i64, idx: I8) -> (I8, I8) {
        let (lo, hi) = (
            _mm256_castsi256_si128(idx.0),
            _mm256_extracti128_si256::<1>(idx.0),
        );
        let a = _mm256_castsi256_ps(_mm256_i32gather_epi64::<SCALE>(p, lo));
        let b = _mm256_castsi256_ps(_mm256_i32gather_epi64::<SCALE>(p, hi));
        (
            I8(_mm256_castps_si256(evens(a, b))),
            I8(_mm256_castps_si256(odds(a, b))),
        )
    }
    #[inline(always)]
    unsafe fn rows(table: *const f32, i4: I8) -> [F8; 4] {
        if LOADS {
            // Each lane's row in one 16-byte load, then transposed.
            let ix = Self::store_i(i4);
            let r: [__m128; 8] = [
                _mm_loadu_ps(table.wrapping_add(ix[0] as u32 as usize)),
                _mm_loadu_ps(table.wrapping_add(ix[1] as u32 as usize)),
                _mm_loadu_ps(table.wrapping_add(ix[2] as u32 as usize)),
                _mm_loadu_ps(table.wrapping_add(ix[3] as u32 as usize)),
                _mm_loadu_ps(table.wrapping_add(ix[4] as u32 as usize)),
                _mm_loadu_ps(table.wrapping_add(ix[5] as u32 as usize)),
                _mm_loadu_ps(table.wrapping_add(ix[6] as u32 as usize)),
                _mm_loadu_ps(table.wrapping_add(ix[7] as u32 as usize)),
            ];
            let a0 = _mm256_set_m128(r[4], r[0]);
            let a1 = _mm256_set_m128(r[5], r[1]);
            let a2 = _mm256_set_m128(r[6], r[2]);
            let a3 = _mm256_set_m128(r[7], r[3]);
            let t0 = _mm256_unpacklo_ps(a0, a1);
            let t1 = _mm256_unpacklo_ps(a2, a3);
            let t2 = _mm256_unpackhi_ps(a0, a1);
            let t3 = _mm256_unpackhi_ps(a2, a3);
            return [
                F8(_mm256_shuffle_ps::<0x44>(t0, t1)),
                F8(_mm256_shuffle_ps::<0xEE>(t0, t1)),
                F8(_mm256_shuffle_ps::<0x44>(t2, t3)),
                F8(_mm256_shuffle_ps::<0xEE>(t2, t3)),
            ];
        }
        // A row is two 64-bit halves, (r, g) and (b, a): four gathers of
        // four 64-bit elements (16 loads), then per channel a shuffle of
        // the evens or odds of both and a cross-lane reorder.
        let h = _mm256_srli_epi32::<1>(i4.0);
        let (lo, hi) = (_mm256_castsi256_si128(h), _mm256_extracti128_si256::<1>(h));
        let base = table as *const i64;
        let rg_lo = _mm256_castsi256_ps(_mm256_i32gather_epi64::<8>(base, lo));
        let rg_hi = _mm256_castsi256_ps(_mm256_i32gather_epi64::<8>(base, hi));
        let ba_lo = _mm256_castsi256_ps(_mm256_i32gather_epi64::<8>(base.add(1), lo));
        let ba_hi = _mm256_castsi256_ps(_mm256_i32gather_epi64::<8>(base.add(1), hi));
        [
            F8(evens(rg_lo, rg_hi)),
            F8(odds(rg_lo, rg_hi)),
            F8(evens(ba_lo, ba_hi)),
            F8(odds(ba_lo, ba_hi)),
        ]
    }

    #[inline(always)]
    unsafe fn load_at(p: *const f32) -> F8 {
        F8(_mm256_loadu_ps(p))
    }
    #[inline(always)]
    unsafe fn store_at(p: *mut f32, v: F8) {
        _mm256_storeu_ps(p, v.0)
    }
    #[inline(always)]
    unsafe fn permute(v: F8, idx: I8) -> F8 {
        F8(_mm256_permutevar8x32_ps(v.0, idx.0))
    }
    #[inline(always)]
    unsafe fn permute_i(v: I8, idx: I8) -> I8 {
        I8(_mm256_permutevar8x32_epi32(v.0, idx.0))
    }
    #[inline(always)]
    unsafe fn set_lanes(m: __m256) -> I8 {
        I8(compress_order(m))
    }
    #[inline(always)]
    unsafe fn iota() -> I8 {
        I8(_mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7))
    }
    #[inline(always)]
    unsafe fn expand_order(dest: u32, pos: i32) -> I8 {
        let rank = nibbles(EXPAND[dest as usize & 0xff]);
        I8(_mm256_add_epi32(rank, _mm256_set1_epi32(pos)))
    }

    #[inline(always)]
    unsafe fn bits(m: __m256) -> u32 {
        _mm256_movemask_ps(m) as u32
    }
    #[inline(always)]
    unsafe fn from_bits(b: u32) -> __m256 {
        let lane_bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        _mm256_castsi256_ps(_mm256_cmpeq_epi32(
            _mm256_and_si256(_mm256_set1_epi32(b as i32), lane_bits),
            lane_bits,
        ))
    }
    #[inline(always)]
    unsafe fn and(a: __m256, b: __m256) -> __m256 {
        _mm256_and_ps(a, b)
    }
    #[inline(always)]
    unsafe fn or(a: __m256, b: __m256) -> __m256 {
        _mm256_or_ps(a, b)
    }
    #[inline(always)]
    unsafe fn but(a: __m256, b: __m256) -> __m256 {
        _mm256_andnot_ps(b, a)
    }
}
