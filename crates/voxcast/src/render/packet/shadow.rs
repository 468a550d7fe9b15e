//! The shadow rays of a packet's surfaces (`--shadows on`) in vector
//! registers: every lane's ray goes towards the same light, so the lanes
//! march together, each from its own surface point with its own spacing,
//! and sum the extinction at their samples as [`march_tau`] does lane by
//! lane — the same positions, the grid's trilinear value by the packets'
//! fetch, the same table.
//!
//! [`march_tau`]: crate::render::surface::march_tau

use super::fetch::Vol;
use super::simd::Simd;
#[cfg(target_arch = "aarch64")]
use super::simd::W4;
#[cfg(target_arch = "x86_64")]
use super::simd::{W16, W8};
use super::{Packets, Runs, LANES};
use crate::render::surface::ShadowMarch;
use crate::transfer::LUT_SIZE;
use crate::volume::Voxel;

/// Each lane's sum of the extinction at its shadow ray's samples into
/// `tau` (lanes without a march: 0).
///
/// # Safety
/// The width's instructions; `pk`'s grid fits the packets
/// ([`super::fits`]).
#[inline(always)]
unsafe fn taus<S: Simd, T: Voxel, R: Runs<T>>(
    pk: &Packets<'_, T, R>,
    marches: &[Option<ShadowMarch>; LANES],
    tau: &mut [f32; LANES],
) {
    let vol = Vol::<S>::of(pk);
    let sigma = pk.f.lut.sigmas().as_ptr();
    let (zero, half, one) = (S::splat(0.0), S::splat(0.5), S::splat(1.0));
    let top = S::splat((LUT_SIZE - 1) as f32);
    for base in (0..LANES).step_by(S::N) {
        // Origin, start, spacing, first and end sample, per lane; the
        // direction (the light's, in voxel space) is every lane's.
        let mut a = [S::Af::default(); 7];
        let mut d = None;
        for (i, m) in marches[base..base + S::N].iter().enumerate() {
            if let Some(m) = m {
                for (k, v) in [m.o.x, m.o.y, m.o.z, m.t0, m.ds].into_iter().enumerate() {
                    a[k][i] = v;
                }
                (a[5][i], a[6][i]) = (m.k0 as f32, m.k1 as f32);
                d = Some(m.d);
            }
        }
        let Some(d) = d else { continue };
        let o = [S::load(a[0]), S::load(a[1]), S::load(a[2])];
        let d = [S::splat(d.x), S::splat(d.y), S::splat(d.z)];
        let (t0, ds, k1) = (S::load(a[3]), S::load(a[4]), S::load(a[6]));
        let mut k = S::load(a[5]);
        let mut acc = zero;
        loop {
            let live = S::lt(k, k1);
            if S::bits(live) == 0 {
                break;
            }
            let s = t0 + (k + half) * ds;
            let v = vol.sample::<T>([o[0] + d[0] * s, o[1] + d[1] * s, o[2] + d[2] * s]);
            // `Lut::index`: values below 0 (and NaN) add nothing.
            let ok = S::and(live, S::ge(v, zero));
            let i = S::to_i(S::keep(ok, S::min(v, one) * top + half));
            acc = acc + S::keep(ok, S::gather_f::<4>(sigma, i));
            k = k + S::keep(live, one);
        }
        let acc = S::store(acc);
        for (i, t) in tau[base..base + S::N].iter_mut().enumerate() {
            *t = acc[i];
        }
    }
}

macro_rules! shadow_entry {
    ($(#[$doc:meta])* $name:ident, $features:literal, $w:ty) => {
        $(#[$doc])*
        ///
        /// # Safety
        /// The CPU has the width's instructions; `pk`'s grid fits the
        /// packets.
        #[target_feature(enable = $features)]
        pub(super) unsafe fn $name<T: Voxel, R: Runs<T>>(
            pk: &Packets<'_, T, R>,
            marches: &[Option<ShadowMarch>; LANES],
            tau: &mut [f32; LANES],
        ) {
            taus::<$w, T, R>(pk, marches, tau)
        }
    };
}

#[cfg(target_arch = "x86_64")]
shadow_entry!(
    /// [`taus`] in AVX2 registers, eight lanes at a time.
    taus_avx2,
    "avx2,fma",
    W8<false>
);
#[cfg(target_arch = "x86_64")]
shadow_entry!(
    /// [`taus_avx2`] fetching by scalar loads.
    taus_avx2_loads,
    "avx2,fma",
    W8<true>
);
#[cfg(target_arch = "x86_64")]
shadow_entry!(
    /// [`taus`] in AVX-512 registers, sixteen lanes at once.
    taus_avx512,
    "avx2,fma,avx512f",
    W16<false>
);
#[cfg(target_arch = "x86_64")]
shadow_entry!(
    /// [`taus_avx512`] fetching by scalar loads.
    taus_avx512_loads,
    "avx2,fma,avx512f",
    W16<true>
);
#[cfg(target_arch = "aarch64")]
shadow_entry!(
    /// [`taus`] in NEON registers (AArch64), four lanes at a time.
    taus_neon,
    "neon",
    W4
);
