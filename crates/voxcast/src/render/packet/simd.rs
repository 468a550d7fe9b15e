//! The vector operations the packets' loop is written in, at three
//! widths: on x86-64 eight lanes in AVX2 registers (`W8`, lane masks as
//! vectors) and sixteen in AVX-512 registers (`W16`, lane masks in mask
//! registers); on AArch64 four in NEON registers (`W4`). The loop
//! (`vector.rs`) is generic over [`Simd`], so every width runs the same
//! code, operation for operation.
//!
//! Every function is `unsafe` and `#[inline(always)]`: it is only ever
//! inlined into a function compiled for its instructions (`march_avx2`,
//! `march_avx512`, `march_neon`), and a value of these types exists only
//! there.

use std::ops::{Add, Div, Index, IndexMut, Mul, Sub};

/// One width of lanes: floats `F`, 32-bit integers `I`, lane masks `M`,
/// and their arrays (`Af`, `Ai`) for the scalar code around the loop.
pub(super) trait Simd: Copy {
    /// Lanes.
    const N: usize;
    type F: Copy
        + Add<Output = Self::F>
        + Sub<Output = Self::F>
        + Mul<Output = Self::F>
        + Div<Output = Self::F>;
    type I: Copy + Add<Output = Self::I> + Sub<Output = Self::I>;
    type M: Copy;
    type Af: Copy + Default + Index<usize, Output = f32> + IndexMut<usize>;
    type Ai: Copy + Default + Index<usize, Output = i32> + IndexMut<usize>;

    unsafe fn splat(x: f32) -> Self::F;
    unsafe fn load(a: Self::Af) -> Self::F;
    unsafe fn store(v: Self::F) -> Self::Af;
    unsafe fn min(a: Self::F, b: Self::F) -> Self::F;
    unsafe fn max(a: Self::F, b: Self::F) -> Self::F;
    unsafe fn floor(a: Self::F) -> Self::F;
    unsafe fn ceil(a: Self::F) -> Self::F;
    unsafe fn sqrt(a: Self::F) -> Self::F;
    /// `1/√a` for `a > 0`, to within a few ulps: the hardware estimate
    /// refined by one Newton step, instead of a square root and a
    /// division; ∞ or NaN at 0.
    unsafe fn rsqrt(a: Self::F) -> Self::F;
    unsafe fn abs(a: Self::F) -> Self::F;
    /// Truncated towards zero.
    unsafe fn to_i(a: Self::F) -> Self::I;
    unsafe fn lt(a: Self::F, b: Self::F) -> Self::M;
    unsafe fn gt(a: Self::F, b: Self::F) -> Self::M;
    unsafe fn ge(a: Self::F, b: Self::F) -> Self::M;
    unsafe fn eq(a: Self::F, b: Self::F) -> Self::M;
    /// `t` in the lanes of `m`, `f` elsewhere.
    unsafe fn blend(m: Self::M, f: Self::F, t: Self::F) -> Self::F;
    /// `v` in the lanes of `m`, zero elsewhere.
    unsafe fn keep(m: Self::M, v: Self::F) -> Self::F;
    /// Zero in the lanes of `m`, `v` elsewhere.
    unsafe fn zero(m: Self::M, v: Self::F) -> Self::F;

    unsafe fn splat_i(x: i32) -> Self::I;
    unsafe fn load_i(a: Self::Ai) -> Self::I;
    unsafe fn store_i(v: Self::I) -> Self::Ai;
    unsafe fn to_f(a: Self::I) -> Self::F;
    /// The float's bits, reinterpreted.
    unsafe fn as_bits(a: Self::F) -> Self::I;
    /// The float of these bits.
    unsafe fn of_bits(a: Self::I) -> Self::F;
    unsafe fn mullo(a: Self::I, b: Self::I) -> Self::I;
    unsafe fn min_i(a: Self::I, b: Self::I) -> Self::I;
    unsafe fn max_i(a: Self::I, b: Self::I) -> Self::I;
    unsafe fn and_i(a: Self::I, b: Self::I) -> Self::I;
    /// Shifts by `k` (a constant at every call, so an immediate).
    unsafe fn srl(a: Self::I, k: i32) -> Self::I;
    unsafe fn sll(a: Self::I, k: i32) -> Self::I;
    unsafe fn sra(a: Self::I, k: i32) -> Self::I;
    unsafe fn blend_i(m: Self::M, f: Self::I, t: Self::I) -> Self::I;
    unsafe fn keep_i(m: Self::M, v: Self::I) -> Self::I;
    /// `a + 1` in the lanes of `m`.
    unsafe fn count(a: Self::I, m: Self::M) -> Self::I;
    /// The lanes of `a` above zero.
    unsafe fn positive(a: Self::I) -> Self::M;
    /// 32-bit loads at byte offsets `idx · SCALE` from `p` (which need not
    /// point into the data itself: only the loads' addresses must).
    unsafe fn gather<const SCALE: i32>(p: *const i32, idx: Self::I) -> Self::I;
    unsafe fn gather_f<const SCALE: i32>(p: *const f32, idx: Self::I) -> Self::F;
    /// 64-bit loads at byte offsets `idx · SCALE` from `p` (as for
    /// [`Simd::gather`]): their low and their high 32 bits.
    unsafe fn gather_pair<const SCALE: i32>(p: *const i64, idx: Self::I) -> (Self::I, Self::I);
    /// The four channels of rows `i4 / 4` of a table of `[f32; 4]` rows
    /// (`i4`: float offsets, none negative), one 128-bit load per lane and a
    /// transpose.
    unsafe fn rows(table: *const f32, i4: Self::I) -> [Self::F; 4];

    /// `N` floats from `p` (unaligned).
    unsafe fn load_at(p: *const f32) -> Self::F;
    /// `N` floats to `p` (unaligned).
    unsafe fn store_at(p: *mut f32, v: Self::F);
    /// Lane `idx[i]` of `v` in lane `i` (`idx` taken modulo `N`).
    unsafe fn permute(v: Self::F, idx: Self::I) -> Self::F;
    /// Lane `idx[i]` of `v` in lane `i` (`idx` taken modulo `N`).
    unsafe fn permute_i(v: Self::I, idx: Self::I) -> Self::I;
    /// The indices of `m`'s lanes, in increasing order, in the low lanes
    /// (the rest unspecified): the permute that compresses by `m`.
    unsafe fn set_lanes(m: Self::M) -> Self::I;
    /// `0, 1, …, N − 1`.
    unsafe fn iota() -> Self::I;
    /// The permute (for [`Simd::permute`]) that puts lanes `pos`,
    /// `pos + 1`, … of a vector into the lanes of `dest` (bits), in
    /// order: an expand after a shift. Lanes not in `dest` unspecified;
    /// `pos + dest.count_ones()` ≤ `N`.
    unsafe fn expand_order(dest: u32, pos: i32) -> Self::I;

    /// Lane `i` of `m` is bit `i`.
    unsafe fn bits(m: Self::M) -> u32;
    unsafe fn from_bits(b: u32) -> Self::M;
    unsafe fn and(a: Self::M, b: Self::M) -> Self::M;
    unsafe fn or(a: Self::M, b: Self::M) -> Self::M;
    /// The lanes of `a` not in `b`.
    unsafe fn but(a: Self::M, b: Self::M) -> Self::M;
}

/// Eight lanes in AVX2 registers. `LOADS`: gathers and table rows fetched
/// by one scalar load per lane instead of the AVX2 gather instructions,
/// which AMD's cores and Intel's from Skylake to Ice Lake run slower than
/// the loads (see [`super::dispatch::loads_beat_gathers`]); the same values either
/// way.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub(super) struct W8<const LOADS: bool>;

/// Sixteen lanes in AVX-512 registers. `LOADS`: every gather (voxels,
/// 64-bit pairs, the walks' floats) and the table rows fetched by one
/// scalar load per lane (sixteen 128-bit row loads and a transpose for the
/// rows), which AMD's Zen 5 and Intel's Skylake-SP to Ice Lake run faster
/// than their AVX-512 gathers (see [`super::dispatch::loads_beat_gathers`]); the same values either way.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub(super) struct W16<const LOADS: bool>;

/// Four lanes in AArch64's NEON registers (every AArch64 CPU has them),
/// fetching by one scalar load per lane: NEON has no gather.
#[cfg(target_arch = "aarch64")]
#[derive(Clone, Copy)]
pub(super) struct W4;

/// `impl $tr for $t` (an operator of a width's vector newtype) by the
/// intrinsic `$i`, for the width files below; each says why its
/// intrinsics are safe to call there.
macro_rules! op {
    ($t:ident, $tr:ident, $f:ident, $i:ident) => {
        impl std::ops::$tr for $t {
            type Output = $t;
            #[inline(always)]
            fn $f(self, o: $t) -> $t {
                unsafe { $t($i(self.0, o.0)) }
            }
        }
    };
}

#[cfg(target_arch = "x86_64")]
mod w16;
#[cfg(target_arch = "aarch64")]
mod w4;
#[cfg(target_arch = "x86_64")]
mod w8;

/// Runs the generic test body `f::<S>()` at each width this CPU has (a
/// test helper: each width in a function compiled for its instructions).
#[cfg(all(test, target_arch = "x86_64"))]
macro_rules! at_each_width {
    ($f:ident) => {{
        #[target_feature(enable = "avx2,fma")]
        unsafe fn on_w8() {
            $f::<$crate::render::packet::simd::W8<false>>();
        }
        #[target_feature(enable = "avx2,fma,avx512f")]
        unsafe fn on_w16() {
            $f::<$crate::render::packet::simd::W16<false>>();
        }
        if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
            // SAFETY: the CPU has the instructions (checked above).
            unsafe { on_w8() };
        }
        if std::is_x86_feature_detected!("avx512f") {
            // SAFETY: as above.
            unsafe { on_w16() };
        }
    }};
}
/// Runs the generic test body `f::<S>()` at NEON's width.
#[cfg(all(test, target_arch = "aarch64"))]
macro_rules! at_each_width {
    ($f:ident) => {{
        // SAFETY: every AArch64 CPU has NEON.
        unsafe { $f::<$crate::render::packet::simd::W4>() };
    }};
}
#[cfg(test)]
pub(super) use at_each_width;

#[cfg(test)]
mod tests {
    use super::*;

    /// Every mask `dest` and start `pos` that fit: lane `l` of `dest`
    /// gets element `pos` + (the lanes of `dest` below `l`).
    ///
    /// # Safety
    /// The width's instructions.
    #[inline(always)]
    unsafe fn expand_order_puts_runs_on_their_lanes<S: Simd>() {
        let mut src = S::Af::default();
        for i in 0..S::N {
            src[i] = i as f32;
        }
        let src = S::load(src);
        for dest in 0u32..(1 << S::N) {
            let c = dest.count_ones() as usize;
            for pos in 0..=S::N - c {
                let got = S::store(S::permute(src, S::expand_order(dest, pos as i32)));
                let mut rank = 0;
                for l in 0..S::N {
                    if dest >> l & 1 == 1 {
                        assert_eq!(got[l], (pos + rank) as f32, "dest {dest:b} pos {pos}");
                        rank += 1;
                    }
                }
            }
        }
    }

    #[test]
    fn expand_order_at_each_width_the_cpu_has() {
        at_each_width!(expand_order_puts_runs_on_their_lanes);
    }
}
