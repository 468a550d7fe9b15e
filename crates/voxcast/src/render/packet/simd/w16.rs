//! [`W16`]: sixteen lanes in AVX-512 registers, lane masks in mask
//! registers (`__mmask16`), fetching by the gather instructions or, as
//! `W16<true>`, lane by lane with scalar loads.

use super::{Simd, W16};
use std::arch::x86_64::*;

/// Sixteen floats.
#[derive(Clone, Copy)]
pub(in crate::render::packet) struct F16(pub __m512);

/// Sixteen 32-bit integers.
#[derive(Clone, Copy)]
pub(in crate::render::packet) struct I16(pub __m512i);

// SAFETY (every `unsafe` block of this file): these values exist only
// inside functions compiled for AVX-512 F (see the parent module).
op!(F16, Add, add, _mm512_add_ps);
op!(F16, Sub, sub, _mm512_sub_ps);
op!(F16, Mul, mul, _mm512_mul_ps);
op!(F16, Div, div, _mm512_div_ps);
op!(I16, Add, add, _mm512_add_epi32);
op!(I16, Sub, sub, _mm512_sub_epi32);

/// `_MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC`, and towards +∞.
const FLOOR: i32 = 0x09;
const CEIL: i32 = 0x0A;

/// The 64-bit elements at byte offsets `ix[a..a + 8] · scale` from `p`.
#[inline(always)]
unsafe fn pairs(p: *const i64, ix: &[i32; 16], a: usize, scale: i32) -> __m512i {
    let b = p as *const u8;
    let at = |k: usize| {
        (b.wrapping_offset(ix[a + k] as isize * scale as isize) as *const i64).read_unaligned()
    };
    _mm512_setr_epi64(at(0), at(1), at(2), at(3), at(4), at(5), at(6), at(7))
}

/// Rows `ix[a]`, `ix[a + 4]`, `ix[a + 8]`, `ix[a + 12]` of `table` (float
/// offsets), one per 128-bit lane.
#[inline(always)]
unsafe fn quad(table: *const f32, ix: &[i32; 16], a: usize) -> __m512 {
    let v = _mm512_castps128_ps512(_mm_loadu_ps(table.wrapping_add(ix[a] as u32 as usize)));
    let v = _mm512_insertf32x4::<1>(
        v,
        _mm_loadu_ps(table.wrapping_add(ix[a + 4] as u32 as usize)),
    );
    let v = _mm512_insertf32x4::<2>(
        v,
        _mm_loadu_ps(table.wrapping_add(ix[a + 8] as u32 as usize)),
    );
    _mm512_insertf32x4::<3>(
        v,
        _mm_loadu_ps(table.wrapping_add(ix[a + 12] as u32 as usize)),
    )
}

/// The lanes `i` of the 32 floats of `a` then `b`. (A function, not a
/// closure: a closure would not inherit the caller's AVX-512.)
#[inline(always)]
unsafe fn pick(a: __m512i, i: __m512i, b: __m512i) -> __m512 {
    _mm512_permutex2var_ps(_mm512_castsi512_ps(a), i, _mm512_castsi512_ps(b))
}

impl<const LOADS: bool> Simd for W16<LOADS> {
    const N: usize = 16;
    type F = F16;
    type I = I16;
    type M = __mmask16;
    type Af = [f32; 16];
    type Ai = [i32; 16];

    #[inline(always)]
    unsafe fn splat(x: f32) -> F16 {
        F16(_mm512_set1_ps(x))
    }
    #[inline(always)]
    unsafe fn load(a: [f32; 16]) -> F16 {
        F16(_mm512_loadu_ps(a.as_ptr()))
    }
    #[inline(always)]
    unsafe fn store(v: F16) -> [f32; 16] {
        let mut a = [0f32; 16];
        _mm512_storeu_ps(a.as_mut_ptr(), v.0);
        a
    }
    #[inline(always)]
    unsafe fn min(a: F16, b: F16) -> F16 {
        F16(_mm512_min_ps(a.0, b.0))
    }
    #[inline(always)]
    unsafe fn max(a: F16, b: F16) -> F16 {
        F16(_mm512_max_ps(a.0, b.0))
    }
    #[inline(always)]
    unsafe fn floor(a: F16) -> F16 {
        F16(_mm512_roundscale_ps::<FLOOR>(a.0))
    }
    #[inline(always)]
    unsafe fn ceil(a: F16) -> F16 {
        F16(_mm512_roundscale_ps::<CEIL>(a.0))
    }
    #[inline(always)]
    unsafe fn sqrt(a: F16) -> F16 {
        F16(_mm512_sqrt_ps(a.0))
    }
    #[inline(always)]
    unsafe fn rsqrt(a: F16) -> F16 {
        // A 14-bit estimate, then y·(3 − a·y²)/2.
        let y = _mm512_rsqrt14_ps(a.0);
        let ay2 = _mm512_mul_ps(_mm512_mul_ps(a.0, y), y);
        let h = _mm512_mul_ps(y, _mm512_set1_ps(0.5));
        F16(_mm512_mul_ps(h, _mm512_sub_ps(_mm512_set1_ps(3.0), ay2)))
    }
    #[inline(always)]
    unsafe fn abs(a: F16) -> F16 {
        F16(_mm512_abs_ps(a.0))
    }
    #[inline(always)]
    unsafe fn to_i(a: F16) -> I16 {
        I16(_mm512_cvttps_epi32(a.0))
    }
    #[inline(always)]
    unsafe fn lt(a: F16, b: F16) -> __mmask16 {
        _mm512_cmp_ps_mask::<_CMP_LT_OQ>(a.0, b.0)
    }
    #[inline(always)]
    unsafe fn gt(a: F16, b: F16) -> __mmask16 {
        _mm512_cmp_ps_mask::<_CMP_GT_OQ>(a.0, b.0)
    }
    #[inline(always)]
    unsafe fn ge(a: F16, b: F16) -> __mmask16 {
        _mm512_cmp_ps_mask::<_CMP_GE_OQ>(a.0, b.0)
    }
    #[inline(always)]
    unsafe fn eq(a: F16, b: F16) -> __mmask16 {
        _mm512_cmp_ps_mask::<_CMP_EQ_OQ>(a.0, b.0)
    }
    #[inline(always)]
    unsafe fn blend(m: __mmask16, f: F16, t: F16) -> F16 {
        F16(_mm512_mask_blend_ps(m, f.0, t.0))
    }
    #[inline(always)]
    unsafe fn keep(m: __mmask16, v: F16) -> F16 {
        F16(_mm512_maskz_mov_ps(m, v.0))
    }
    #[inline(always)]
    unsafe fn zero(m: __mmask16, v: F16) -> F16 {
        F16(_mm512_maskz_mov_ps(!m, v.0))
    }

    #[inline(always)]
    unsafe fn splat_i(x: i32) -> I16 {
        I16(_mm512_set1_epi32(x))
    }
    #[inline(always)]
    unsafe fn load_i(a: [i32; 16]) -> I16 {
        I16(_mm512_loadu_si512(a.as_ptr() as *const _))
    }
    #[inline(always)]
    unsafe fn store_i(v: I16) -> [i32; 16] {
        let mut a = [0i32; 16];
        _mm512_storeu_si512(a.as_mut_ptr() as *mut _, v.0);
        a
    }
    #[inline(always)]
    unsafe fn of_bits(a: I16) -> F16 {
        F16(_mm512_castsi512_ps(a.0))
    }
    #[inline(always)]
    unsafe fn as_bits(a: F16) -> I16 {
        I16(_mm512_castps_si512(a.0))
    }
    #[inline(always)]
    unsafe fn to_f(a: I16) -> F16 {
        F16(_mm512_cvtepi32_ps(a.0))
    }
    #[inline(always)]
    unsafe fn mullo(a: I16, b: I16) -> I16 {
        I16(_mm512_mullo_epi32(a.0, b.0))
    }
    #[inline(always)]
    unsafe fn min_i(a: I16, b: I16) -> I16 {
        I16(_mm512_min_epi32(a.0, b.0))
    }
    #[inline(always)]
    unsafe fn max_i(a: I16, b: I16) -> I16 {
        I16(_mm512_max_epi32(a.0, b.0))
    }
    #[inline(always)]
    unsafe fn and_i(a: I16, b: I16) -> I16 {
        I16(_mm512_and_si512(a.0, b.0))
    }
    #[inline(always)]
    unsafe fn srl(a: I16, k: i32) -> I16 {
        I16(_mm512_srl_epi32(a.0, _mm_cvtsi32_si128(k)))
    }
    #[inline(always)]
    unsafe fn sll(a: I16, k: i32) -> I16 {
        I16(_mm512_sll_epi32(a.0, _mm_cvtsi32_si128(k)))
    }
    #[inline(always)]
    unsafe fn sra(a: I16, k: i32) -> I16 {
        I16(_mm512_sra_epi32(a.0, _mm_cvtsi32_si128(k)))
    }
    #[inline(always)]
    unsafe fn blend_i(m: __mmask16, f: I16, t: I16) -> I16 {
        I16(_mm512_mask_blend_epi32(m, f.0, t.0))
    }
    #[inline(always)]
    unsafe fn keep_i(m: __mmask16, v: I16) -> I16 {
        I16(_mm512_maskz_mov_epi32(m, v.0))
    }
    #[inline(always)]
    unsafe fn count(a: I16, m: __mmask16) -> I16 {
        I16(_mm512_mask_add_epi32(a.0, m, a.0, _mm512_set1_epi32(1)))
    }
    #[inline(always)]
    unsafe fn positive(a: I16) -> __mmask16 {
        _mm512_cmpgt_epi32_mask(a.0, _mm512_setzero_si512())
    }
    #[inline(always)]
    unsafe fn gather<const SCALE: i32>(p: *const i32, idx: I16) -> I16 {
        if LOADS {
            let ix = Self::store_i(idx);
            let b = p as *const u8;
            let at = |k: usize| {
                (b.wrapping_offset(ix[k] as isize * SCALE as isize) as *const i32).read_unaligned()
            };
            return I16(_mm512_setr_epi32(
                at(0),
                at(1),
                at(2),
                at(3),
                at(4),
                at(5),
                at(6),
                at(7),
                at(8),
                at(9),
                at(10),
                at(11),
                at(12),
                at(13),
                at(14),
                at(15),
            ));
        }
        I16(_mm512_i32gather_epi32::<SCALE>(idx.0, p))
    }
    #[inline(always)]
    unsafe fn gather_f<const SCALE: i32>(p: *const f32, idx: I16) -> F16 {
        if LOADS {
            return F16(_mm512_castsi512_ps(
                Self::gather::<SCALE>(p as *const i32, idx).0,
            ));
        }
        F16(_mm512_i32gather_ps::<SCALE>(idx.0, p))
    }
    #[inline(always)]
    unsafe fn gather_pair<const SCALE: i32>(p: *const i64, idx: I16) -> (I16, I16) {
        let (a, b) = if LOADS {
            let ix = Self::store_i(idx);
            (pairs(p, &ix, 0, SCALE), pairs(p, &ix, 8, SCALE))
        } else {
            let (lo, hi) = (
                _mm512_castsi512_si256(idx.0),
                _mm512_extracti64x4_epi64::<1>(idx.0),
            );
            (
                _mm512_i32gather_epi64::<SCALE>(lo, p),
                _mm512_i32gather_epi64::<SCALE>(hi, p),
            )
        };
        let even = _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30);
        let odd = _mm512_add_epi32(even, _mm512_set1_epi32(1));
        (
            I16(_mm512_castps_si512(pick(a, even, b))),
            I16(_mm512_castps_si512(pick(a, odd, b))),
        )
    }
    #[inline(always)]
    unsafe fn rows(table: *const f32, i4: I16) -> [F16; 4] {
        if LOADS {
            // Each lane's row in one 16-byte load, four to a register
            // (lanes a, a + 4, a + 8, a + 12 in its 128-bit quarters), then
            // a 4×4 transpose in each quarter: lane order comes out whole.
            let ix = Self::store_i(i4);
            let (a0, a1, a2, a3) = (
                quad(table, &ix, 0),
                quad(table, &ix, 1),
                quad(table, &ix, 2),
                quad(table, &ix, 3),
            );
            let t0 = _mm512_unpacklo_ps(a0, a1);
            let t1 = _mm512_unpacklo_ps(a2, a3);
            let t2 = _mm512_unpackhi_ps(a0, a1);
            let t3 = _mm512_unpackhi_ps(a2, a3);
            return [
                F16(_mm512_shuffle_ps::<0x44>(t0, t1)),
                F16(_mm512_shuffle_ps::<0xEE>(t0, t1)),
                F16(_mm512_shuffle_ps::<0x44>(t2, t3)),
                F16(_mm512_shuffle_ps::<0xEE>(t2, t3)),
            ];
        }
        // A row is two 64-bit halves, (r, g) and (b, a): four gathers of
        // eight 64-bit elements (32 loads, where four 16-wide gathers of
        // floats are 64 and sixteen row loads need a transpose), then one
        // two-register permute per channel picks the evens or the odds.
        let h = _mm512_srli_epi32::<1>(i4.0);
        let (lo, hi) = (_mm512_castsi512_si256(h), _mm512_extracti64x4_epi64::<1>(h));
        let base = table as *const i64;
        let rg_lo = _mm512_i32gather_epi64::<8>(lo, base);
        let rg_hi = _mm512_i32gather_epi64::<8>(hi, base);
        let ba_lo = _mm512_i32gather_epi64::<8>(lo, base.add(1));
        let ba_hi = _mm512_i32gather_epi64::<8>(hi, base.add(1));
        let even = _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30);
        let odd = _mm512_add_epi32(even, _mm512_set1_epi32(1));
        [
            F16(pick(rg_lo, even, rg_hi)),
            F16(pick(rg_lo, odd, rg_hi)),
            F16(pick(ba_lo, even, ba_hi)),
            F16(pick(ba_lo, odd, ba_hi)),
        ]
    }

    #[inline(always)]
    unsafe fn load_at(p: *const f32) -> F16 {
        F16(_mm512_loadu_ps(p))
    }
    #[inline(always)]
    unsafe fn store_at(p: *mut f32, v: F16) {
        _mm512_storeu_ps(p, v.0)
    }
    #[inline(always)]
    unsafe fn permute(v: F16, idx: I16) -> F16 {
        F16(_mm512_permutexvar_ps(idx.0, v.0))
    }
    #[inline(always)]
    unsafe fn permute_i(v: I16, idx: I16) -> I16 {
        I16(_mm512_permutexvar_epi32(idx.0, v.0))
    }
    #[inline(always)]
    unsafe fn set_lanes(m: __mmask16) -> I16 {
        I16(_mm512_maskz_compress_epi32(m, Self::iota().0))
    }
    #[inline(always)]
    unsafe fn iota() -> I16 {
        I16(_mm512_setr_epi32(
            0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15,
        ))
    }

    #[inline(always)]
    unsafe fn expand_order(dest: u32, pos: i32) -> I16 {
        let from = _mm512_add_epi32(Self::iota().0, _mm512_set1_epi32(pos));
        I16(_mm512_maskz_expand_epi32(dest as __mmask16, from))
    }

    #[inline(always)]
    unsafe fn bits(m: __mmask16) -> u32 {
        m as u32
    }
    #[inline(always)]
    unsafe fn from_bits(b: u32) -> __mmask16 {
        b as __mmask16
    }
    #[inline(always)]
    unsafe fn and(a: __mmask16, b: __mmask16) -> __mmask16 {
        a & b
    }
    #[inline(always)]
    unsafe fn or(a: __mmask16, b: __mmask16) -> __mmask16 {
        a | b
    }
    #[inline(always)]
    unsafe fn but(a: __mmask16, b: __mmask16) -> __mmask16 {
        a & !b
    }
}
