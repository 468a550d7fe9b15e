//! [`W4`]: four lanes in AArch64's NEON registers, lane masks as
//! integer vectors (all ones or all zeros per lane). NEON has no gather:
//! every fetch is one scalar load per lane, as `W8<true>` does. Where a
//! NEON instruction rounds or treats NaN differently from the x86 one the
//! packets were written against (`min`, `max`, float-to-integer), the
//! x86 result is built, so every width gives the same values.

use super::{Simd, W4};
use std::arch::aarch64::*;

/// Four floats.
#[derive(Clone, Copy)]
pub(in crate::render::packet) struct F4(pub float32x4_t);

/// Four 32-bit integers.
#[derive(Clone, Copy)]
pub(in crate::render::packet) struct I4(pub int32x4_t);

// SAFETY (every `unsafe` block of this file): NEON is part of AArch64
// (every AArch64 target has it enabled).
op!(F4, Add, add, vaddq_f32);
op!(F4, Sub, sub, vsubq_f32);
op!(F4, Mul, mul, vmulq_f32);
op!(F4, Div, div, vdivq_f32);
op!(I4, Add, add, vaddq_s32);
op!(I4, Sub, sub, vsubq_s32);

/// For each 4-lane mask: with `expand` false the lanes it holds in order
/// (the rest zero), with `expand` true each of its lanes' rank among them
/// (zero for the others).
const fn order_table(expand: bool) -> [[i32; 4]; 16] {
    let mut t = [[0i32; 4]; 16];
    let mut m = 0;
    while m < 16 {
        let (mut k, mut i) = (0, 0);
        while i < 4 {
            if (m >> i) & 1 == 1 {
                if expand {
                    t[m][i] = k as i32;
                } else {
                    t[m][k] = i as i32;
                }
                k += 1;
            }
            i += 1;
        }
        m += 1;
    }
    t
}

/// [`Simd::set_lanes`]' permutes.
static COMPRESS: [[i32; 4]; 16] = order_table(false);

/// [`Simd::expand_order`]'s ranks.
static EXPAND: [[i32; 4]; 16] = order_table(true);

/// Lane `i`'s bit.
const LANE_BITS: [u32; 4] = [1, 2, 4, 8];

impl Simd for W4 {
    const N: usize = 4;
    type F = F4;
    type I = I4;
    type M = uint32x4_t;
    type Af = [f32; 4];
    type Ai = [i32; 4];

    #[inline(always)]
    unsafe fn splat(x: f32) -> F4 {
        F4(vdupq_n_f32(x))
    }
    #[inline(always)]
    unsafe fn load(a: [f32; 4]) -> F4 {
        F4(vld1q_f32(a.as_ptr()))
    }
    #[inline(always)]
    unsafe fn store(v: F4) -> [f32; 4] {
        let mut a = [0f32; 4];
        vst1q_f32(a.as_mut_ptr(), v.0);
        a
    }
    #[inline(always)]
    unsafe fn min(a: F4, b: F4) -> F4 {
        // x86's `minps`: `a < b ? a : b` (b where either is NaN).
        F4(vbslq_f32(vcltq_f32(a.0, b.0), a.0, b.0))
    }
    #[inline(always)]
    unsafe fn max(a: F4, b: F4) -> F4 {
        F4(vbslq_f32(vcgtq_f32(a.0, b.0), a.0, b.0))
    }
    #[inline(always)]
    unsafe fn floor(a: F4) -> F4 {
        F4(vrndmq_f32(a.0))
    }
    #[inline(always)]
    unsafe fn ceil(a: F4) -> F4 {
        F4(vrndpq_f32(a.0))
    }
    #[inline(always)]
    unsafe fn sqrt(a: F4) -> F4 {
        F4(vsqrtq_f32(a.0))
    }
    #[inline(always)]
    unsafe fn rsqrt(a: F4) -> F4 {
        // An 8-bit estimate, then two Newton steps y·(3 − a·y²)/2
        // (`vrsqrtsq_f32` is the bracket over two).
        let y = vrsqrteq_f32(a.0);
        let y = vmulq_f32(y, vrsqrtsq_f32(vmulq_f32(a.0, y), y));
        F4(vmulq_f32(y, vrsqrtsq_f32(vmulq_f32(a.0, y), y)))
    }
    #[inline(always)]
    unsafe fn abs(a: F4) -> F4 {
        F4(vabsq_f32(a.0))
    }
    #[inline(always)]
    unsafe fn to_i(a: F4) -> I4 {
        // x86's `cvttps2dq`: i32::MIN for NaN and out of range (NEON
        // saturates, and gives 0 for NaN).
        let inside = vcltq_f32(vabsq_f32(a.0), vdupq_n_f32(2147483648.0));
        I4(vbslq_s32(inside, vcvtq_s32_f32(a.0), vdupq_n_s32(i32::MIN)))
    }
    #[inline(always)]
    unsafe fn lt(a: F4, b: F4) -> uint32x4_t {
        vcltq_f32(a.0, b.0)
    }
    #[inline(always)]
    unsafe fn gt(a: F4, b: F4) -> uint32x4_t {
        vcgtq_f32(a.0, b.0)
    }
    #[inline(always)]
    unsafe fn ge(a: F4, b: F4) -> uint32x4_t {
        vcgeq_f32(a.0, b.0)
    }
    #[inline(always)]
    unsafe fn eq(a: F4, b: F4) -> uint32x4_t {
        vceqq_f32(a.0, b.0)
    }
    #[inline(always)]
    unsafe fn blend(m: uint32x4_t, f: F4, t: F4) -> F4 {
        F4(vbslq_f32(m, t.0, f.0))
    }
    #[inline(always)]
    unsafe fn keep(m: uint32x4_t, v: F4) -> F4 {
        F4(vreinterpretq_f32_u32(vandq_u32(
            vreinterpretq_u32_f32(v.0),
            m,
        )))
    }
    #[inline(always)]
    unsafe fn zero(m: uint32x4_t, v: F4) -> F4 {
        F4(vreinterpretq_f32_u32(vbicq_u32(
            vreinterpretq_u32_f32(v.0),
            m,
        )))
    }

    #[inline(always)]
    unsafe fn splat_i(x: i32) -> I4 {
        I4(vdupq_n_s32(x))
    }
    #[inline(always)]
    unsafe fn load_i(a: [i32; 4]) -> I4 {
        I4(vld1q_s32(a.as_ptr()))
    }
    #[inline(always)]
    unsafe fn store_i(v: I4) -> [i32; 4] {
        let mut a = [0i32; 4];
        vst1q_s32(a.as_mut_ptr(), v.0);
        a
    }
    #[inline(always)]
    unsafe fn of_bits(a: I4) -> F4 {
        F4(vreinterpretq_f32_s32(a.0))
    }
    #[inline(always)]
    unsafe fn as_bits(a: F4) -> I4 {
        I4(vreinterpretq_s32_f32(a.0))
    }
    #[inline(always)]
    unsafe fn to_f(a: I4) -> F4 {
        F4(vcvtq_f32_s32(a.0))
    }
    #[inline(always)]
    unsafe fn mullo(a: I4, b: I4) -> I4 {
        I4(vmulq_s32(a.0, b.0))
    }
    #[inline(always)]
    unsafe fn min_i(a: I4, b: I4) -> I4 {
        I4(vminq_s32(a.0, b.0))
    }
    #[inline(always)]
    unsafe fn max_i(a: I4, b: I4) -> I4 {
        I4(vmaxq_s32(a.0, b.0))
    }
    #[inline(always)]
    unsafe fn and_i(a: I4, b: I4) -> I4 {
        I4(vandq_s32(a.0, b.0))
    }
    #[inline(always)]
    unsafe fn srl(a: I4, k: i32) -> I4 {
        // A shift left by −k is a right shift (logical on unsigned lanes).
        let u = vshlq_u32(vreinterpretq_u32_s32(a.0), vdupq_n_s32(-k));
        I4(vreinterpretq_s32_u32(u))
    }
    #[inline(always)]
    unsafe fn sll(a: I4, k: i32) -> I4 {
        I4(vshlq_s32(a.0, vdupq_n_s32(k)))
    }
    #[inline(always)]
    unsafe fn sra(a: I4, k: i32) -> I4 {
        I4(vshlq_s32(a.0, vdupq_n_s32(-k)))
    }
    #[inline(always)]
    unsafe fn blend_i(m: uint32x4_t, f: I4, t: I4) -> I4 {
        I4(vbslq_s32(m, t.0, f.0))
    }
    #[inline(always)]
    unsafe fn keep_i(m: uint32x4_t, v: I4) -> I4 {
        I4(vandq_s32(v.0, vreinterpretq_s32_u32(m)))
    }
    #[inline(always)]
    unsafe fn count(a: I4, m: uint32x4_t) -> I4 {
        // A mask lane is −1.
        I4(vsubq_s32(a.0, vreinterpretq_s32_u32(m)))
    }
    #[inline(always)]
    unsafe fn positive(a: I4) -> uint32x4_t {
        vcgtq_s32(a.0, vdupq_n_s32(0))
    }
    #[inline(always)]
    unsafe fn gather<const SCALE: i32>(p: *const i32, idx: I4) -> I4 {
        let ix = Self::store_i(idx);
        let b = p as *const u8;
        let at = |k: usize| {
            let q = b.wrapping_offset(ix[k] as isize * SCALE as isize) as *const i32;
            q.read_unaligned()
        };
        Self::load_i([at(0), at(1), at(2), at(3)])
    }
    #[inline(always)]
    unsafe fn gather_f<const SCALE: i32>(p: *const f32, idx: I4) -> F4 {
        Self::of_bits(Self::gather::<SCALE>(p as *const i32, idx))
    }
    #[inline(always)]
    unsafe fn gather_pair<const SCALE: i32>(p: *const i64, idx: I4) -> (I4, I4) {
        let ix = Self::store_i(idx);
        let b = p as *const u8;
        let at = |k: usize| {
            let q = b.wrapping_offset(ix[k] as isize * SCALE as isize) as *const i64;
            q.read_unaligned()
        };
        let v = [at(0), at(1), at(2), at(3)];
        (
            Self::load_i(v.map(|x| x as i32)),
            Self::load_i(v.map(|x| (x >> 32) as i32)),
        )
    }
    #[inline(always)]
    unsafe fn rows(table: *const f32, i4: I4) -> [F4; 4] {
        // Each lane's row in one 16-byte load, then transposed: 32-bit
        // pairs, then 64-bit ones.
        let ix = Self::store_i(i4);
        let r = ix.map(|i| vld1q_f32(table.wrapping_add(i as u32 as usize)));
        let t0 = vtrn1q_f32(r[0], r[1]);
        let t1 = vtrn2q_f32(r[0], r[1]);
        let t2 = vtrn1q_f32(r[2], r[3]);
        let t3 = vtrn2q_f32(r[2], r[3]);
        let (d0, d1) = (vreinterpretq_f64_f32(t0), vreinterpretq_f64_f32(t1));
        let (d2, d3) = (vreinterpretq_f64_f32(t2), vreinterpretq_f64_f32(t3));
        [
            F4(vreinterpretq_f32_f64(vtrn1q_f64(d0, d2))),
            F4(vreinterpretq_f32_f64(vtrn1q_f64(d1, d3))),
            F4(vreinterpretq_f32_f64(vtrn2q_f64(d0, d2))),
            F4(vreinterpretq_f32_f64(vtrn2q_f64(d1, d3))),
        ]
    }

    #[inline(always)]
    unsafe fn load_at(p: *const f32) -> F4 {
        F4(vld1q_f32(p))
    }
    #[inline(always)]
    unsafe fn store_at(p: *mut f32, v: F4) {
        vst1q_f32(p, v.0)
    }
    #[inline(always)]
    unsafe fn permute(v: F4, idx: I4) -> F4 {
        Self::of_bits(Self::permute_i(Self::as_bits(v), idx))
    }
    #[inline(always)]
    unsafe fn permute_i(v: I4, idx: I4) -> I4 {
        // A byte table lookup: lane `j` is bytes 4j … 4j + 3.
        let j = vandq_u32(vreinterpretq_u32_s32(idx.0), vdupq_n_u32(3));
        let bytes = vaddq_u32(
            vmulq_u32(j, vdupq_n_u32(0x0404_0404)),
            vdupq_n_u32(0x0302_0100),
        );
        let t = vqtbl1q_u8(vreinterpretq_u8_s32(v.0), vreinterpretq_u8_u32(bytes));
        I4(vreinterpretq_s32_u8(t))
    }
    #[inline(always)]
    unsafe fn set_lanes(m: uint32x4_t) -> I4 {
        I4(vld1q_s32(COMPRESS[Self::bits(m) as usize].as_ptr()))
    }
    #[inline(always)]
    unsafe fn iota() -> I4 {
        Self::load_i([0, 1, 2, 3])
    }
    #[inline(always)]
    unsafe fn expand_order(dest: u32, pos: i32) -> I4 {
        let rank = vld1q_s32(EXPAND[dest as usize & 0xf].as_ptr());
        I4(vaddq_s32(rank, vdupq_n_s32(pos)))
    }

    #[inline(always)]
    unsafe fn bits(m: uint32x4_t) -> u32 {
        vaddvq_u32(vandq_u32(m, vld1q_u32(LANE_BITS.as_ptr())))
    }
    #[inline(always)]
    unsafe fn from_bits(b: u32) -> uint32x4_t {
        vtstq_u32(vdupq_n_u32(b), vld1q_u32(LANE_BITS.as_ptr()))
    }
    #[inline(always)]
    unsafe fn and(a: uint32x4_t, b: uint32x4_t) -> uint32x4_t {
        vandq_u32(a, b)
    }
    #[inline(always)]
    unsafe fn or(a: uint32x4_t, b: uint32x4_t) -> uint32x4_t {
        vorrq_u32(a, b)
    }
    #[inline(always)]
    unsafe fn but(a: uint32x4_t, b: uint32x4_t) -> uint32x4_t {
        vbicq_u32(a, b)
    }
}
