//! `stratified` (S1) in the packets: each lane takes one uniform position
//! in each interval `[t_in + k·s, t_in + (k+1)·s)` of its ray, as
//! `stochastic::Stratified` does ray by ray: the same counter-based
//! random per interval (`interval_random`, drawn lane by lane in scalar
//! code: a 64-bit hash), the same last interval cut at the exit, the same
//! samples dropped where their position lies in an empty block or outside
//! the walk. An empty block's lanes jump its empty cube: to the first
//! interval whose position may lie past it.
//!
//! The same loop samples `mc`'s positions ([`super::mc`]): a flag picks
//! where the positions come from, so both share one copy of the sampling,
//! shading and compositing per stored type and level.

#[cfg(all(packets, target_arch = "aarch64"))]
pub(super) use vector::strat_neon;
#[cfg(all(packets, target_arch = "x86_64"))]
pub(super) use vector::{strat_avx2, strat_avx2_loads, strat_avx512, strat_avx512_loads};

use super::super::stochastic::stratified_key;
use super::{Lane, Packets, Runs, Setup};
use crate::render::stats::RenderStats;
use crate::transfer::LUT_SIZE;
use crate::volume::Voxel;
use glam::Vec3;

/// `stratified` or `mc` (S1's uniform marchers) in packets: the
/// extinction of every table entry, for the opacity of a stretch that is
/// not the step (`stratified`'s last interval, each of `mc`'s samples;
/// the others take the step's table, `pk.q`).
pub(in crate::render) struct Strat<'a> {
    pub sigma: &'a [f32; LUT_SIZE],
    /// `mc`'s positions (sorted uniforms over the whole ray, [`super::mc`])
    /// rather than one per interval.
    pub mc: bool,
}

impl<T: Voxel, R: Runs<T>> Packets<'_, T, R> {
    /// Sets up a `stratified` ray as [`crate::render::trace::trace`] and
    /// `Stratified::march` do: the lane (`t0` its entry `t_in`, `t_end`
    /// its exit, `k0` the interval the walk starts in), the walk's ends,
    /// and the ray's random key.
    pub(super) fn strat_lane(
        &self,
        ray: (Vec3, Vec3),
        limit: f32,
        pixel: (u32, u32),
        pass: u32,
        stats: &mut RenderStats,
    ) -> Option<(Lane, [f32; 2], u64)> {
        let Setup {
            o,
            d,
            t_in,
            t_out,
            walk,
        } = self.setup(ray, limit, stats)?;
        let s = self.f.step;
        let k0 = ((walk.0 - t_in) / s).floor().max(0.0) as u32;
        if t_in + k0 as f32 * s >= walk.1 {
            return None;
        }
        let lane = Lane {
            k0,
            ..Lane::walking(o, d, -ray.1, t_in, t_out)
        };
        let key = stratified_key(self.f.seed, pixel, pass);
        Some((lane, [walk.0, walk.1], key))
    }
}

/// The vector loop (where the packets are compiled: x86-64, AArch64).
#[cfg(packets)]
mod vector {
    use super::super::super::stochastic::interval_random;
    use super::super::fetch::Skips;
    use super::super::mc::Draws;
    use super::super::simd::Simd;
    #[cfg(target_arch = "aarch64")]
    use super::super::simd::W4;
    #[cfg(target_arch = "x86_64")]
    use super::super::simd::{W16, W8};
    use super::super::tail::Taker;
    use super::super::vwalk::Rays;
    use super::super::{Lane, Packets, Runs, State, LANES};
    use crate::volume::Voxel;

    #[cfg(target_arch = "x86_64")]
    entry!(
        /// The `stratified` lanes' loop at AVX2: two packets of eight,
        /// fetching by the gather instructions.
        ///
        /// # Safety
        /// AVX2 and FMA present; the grid `fits`; the shading `shades`;
        /// `pk.z_pairs` is the grid's z-paired copy; `pk.strat` is set.
        pub(in crate::render::packet) strat_avx2,
        "avx2,fma",
        W8<false>,
        march<>
    );
    #[cfg(target_arch = "x86_64")]
    entry!(
        /// [`strat_avx2`] fetching by scalar loads.
        ///
        /// # Safety
        /// As [`strat_avx2`].
        pub(in crate::render::packet) strat_avx2_loads,
        "avx2,fma",
        W8<true>,
        march<>
    );
    #[cfg(target_arch = "x86_64")]
    entry!(
        /// [`strat_avx2`] in sixteen lanes of AVX-512 registers.
        ///
        /// # Safety
        /// As [`strat_avx2`], and AVX-512 F present.
        pub(in crate::render::packet) strat_avx512,
        "avx2,fma,avx512f",
        W16<false>,
        march<>
    );
    #[cfg(target_arch = "x86_64")]
    entry!(
        /// [`strat_avx512`] fetching by scalar loads.
        ///
        /// # Safety
        /// As [`strat_avx512`].
        pub(in crate::render::packet) strat_avx512_loads,
        "avx2,fma,avx512f",
        W16<true>,
        march<>
    );
    #[cfg(target_arch = "aarch64")]
    entry!(
        /// [`strat_avx2`] in four lanes of NEON registers (AArch64).
        ///
        /// # Safety
        /// The grid `fits`; the shading `shades`; `pk.z_pairs` is the
        /// grid's z-paired copy; `pk.strat` is set.
        pub(in crate::render::packet) strat_neon,
        "neon",
        W4,
        march<>
    );

    /// The loop of both widths: lane by lane `Stratified::march` (or
    /// `UniformMc::march`) with front-to-back compositing, from the colour
    /// and opacity in `st.acc`.
    ///
    /// # Safety
    /// As [`strat_avx2`], with the width's instructions.
    #[inline(always)]
    unsafe fn march<S: Simd, T: Voxel, R: Runs<T>>(
        pk: &Packets<'_, T, R>,
        lanes: &[Option<Lane>],
        st: &mut State<'_>,
    ) {
        debug_assert!(lanes.len() == S::N && st.acc.len() == S::N);
        let f = pk.f;
        let strat = pk.strat.as_ref().unwrap_unchecked();
        let s = f.step;
        // Skipping, shading and `mc` are flags read each step, not const
        // parameters: one loop per type and level (16) where the const
        // choices made 64, which cost six minutes of CI's dev build; a
        // predictable branch a step costs no measurable time.
        let skipping = pk.empty.is_some();
        // `mc`: the lanes' generators, and the stretch a position stands
        // for.
        let (mut draws, mc_w) = if strat.mc {
            let (d, w) = Draws::new(lanes, S::N, st.keys, f.seed, s);
            (Some(d), w)
        } else {
            (None, [0.0; LANES])
        };
        // Per lane: origin, direction, entry, view, first interval, the
        // walk's ends, exit, last interval, colour and opacity, `mc`'s
        // stretch.
        let mut a = [S::Af::default(); 20];
        let mut keys = [0u64; LANES];
        let mut live_bits = 0u32;
        for (i, l) in lanes.iter().enumerate() {
            let Some(l) = l else { continue };
            let c = st.acc[i];
            let [w0, w1] = st.ends[i];
            let last = ((l.t_end - l.t0) / s).ceil().max(1.0) as u64 - 1;
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
                l.k0 as f32,
                w0,
                w1,
                l.t_end,
                last as f32,
                c.x,
                c.y,
                c.z,
                c.w,
                mc_w[i],
            ];
            for (k, x) in v.into_iter().enumerate() {
                a[k][i] = x;
            }
            keys[i] = st.keys[i];
            live_bits |= 1 << i;
        }
        let o = [S::load(a[0]), S::load(a[1]), S::load(a[2])];
        let d = [S::load(a[3]), S::load(a[4]), S::load(a[5])];
        let t_in = S::load(a[6]);
        let view = [S::load(a[7]), S::load(a[8]), S::load(a[9])];
        let mut kv = S::load(a[10]);
        let (w0, w1, t_out, lastk) = (
            S::load(a[11]),
            S::load(a[12]),
            S::load(a[13]),
            S::load(a[14]),
        );
        let col = [
            S::load(a[15]),
            S::load(a[16]),
            S::load(a[17]),
            S::load(a[18]),
        ];
        let (mc_len, mc_w) = (t_out - t_in, S::load(a[19]));
        let one = S::splat(1.0);
        let sv = S::splat(s);
        let inv_s = S::splat(1.0 / s);
        let mut tk = Taker::<S>::new(pk, strat.sigma, view, col, S::from_bits(live_bits));
        let inv_d = [one / d[0], one / d[1], one / d[2]];
        let skips = Skips::<S>::of(pk);
        let rays = Rays {
            o,
            d,
            inv_d,
            t0: t_in,
        };
        loop {
            if let Some(dr) = draws.as_mut() {
                // `mc`: the lanes still going draw their next position;
                // every sample stands for the stretch `L/n`; one in an
                // empty block is dropped (not counted).
                let mut u = S::Af::default();
                let bits = dr.next(S::bits(tk.live), &mut u, S::N);
                if bits == 0 {
                    break;
                }
                let mut samp = S::from_bits(bits);
                let t = t_in + S::load(u) * mc_len;
                let p = [o[0] + d[0] * t, o[1] + d[1] * t, o[2] + d[2] * t];
                if skipping {
                    samp = S::but(samp, skips.empty_at(p, samp));
                }
                if S::bits(samp) != 0 {
                    tk.take::<T>(samp, p, samp, mc_w);
                }
                continue;
            }
            // Interval k starts at `a`; the walk ends every lane whose
            // interval starts at or past its end.
            let a0 = t_in + kv * sv;
            let act = S::and(tk.live, S::and(S::ge(lastk, kv), S::lt(a0, w1)));
            let bits = S::bits(act);
            if bits == 0 {
                break;
            }
            // The interval's random, lane by lane (`interval_random`).
            let ks = S::store(kv);
            let mut u = S::Af::default();
            for (i, &key) in keys.iter().enumerate().take(S::N) {
                if bits & (1 << i) != 0 {
                    u[i] = interval_random(key, ks[i] as u64);
                }
            }
            let is_last = S::eq(kv, lastk);
            let len = S::blend(is_last, sv, t_out - a0);
            let t = a0 + S::load(u) * len;
            let p = [o[0] + d[0] * t, o[1] + d[1] * t, o[2] + d[2] * t];
            // A sample belongs to the walk's stretch its position lies in.
            let mut samp = S::and(act, S::and(S::ge(t, w0), S::lt(t, w1)));
            let mut jumped = S::from_bits(0);
            if skipping && S::bits(samp) != 0 {
                let (skip, te) = skips.exit(&tk.vol, p, &rays, samp);
                if S::bits(skip) != 0 {
                    // Past the empty cube: the first interval whose
                    // position may lie beyond it (its position, if still
                    // inside, is tested again), and at least the next.
                    let kn = S::floor((te - t_in) * inv_s);
                    kv = S::blend(skip, kv, S::max(kn, kv + one));
                    samp = S::but(samp, skip);
                    jumped = skip;
                }
            }
            // The last interval stands for its own length.
            if S::bits(samp) != 0 {
                tk.take::<T>(samp, p, is_last, len);
            }
            // Every active lane that did not jump takes its next interval.
            kv = S::blend(S::but(act, jumped), kv, kv + one);
        }
        tk.finish::<T>(st, lanes);
    }
}
