//! The packets' vector code, written once over [`Simd`] and compiled at
//! two widths (see the parent module): deferred shading's queue and the
//! marching loop, over the grid's fetches and block exits of
//! [`super::fetch`].

use super::fetch::{Skips, Vol};
use super::importance::{ImpState, VImp};
use super::shade::{Batch, Deferred, Light, Slots};
use super::simd::Simd;
#[cfg(target_arch = "aarch64")]
use super::simd::W4;
#[cfg(target_arch = "x86_64")]
use super::simd::{W16, W8};
use super::tail::{composite, drain_deferred, over_stretch, store_lanes};
use super::vwalk::{Rays, VWalk};
use super::walk::{walk_runs, RunRegs};
use super::{Lane, Packets, Runs, State, LANES};
use crate::volume::Voxel;

/// Shades a batch of samples from `dq` (`view`: the lanes' view
/// directions) and adds them to their lanes.
///
/// # Safety
/// The width's instructions; `b` is the last batch `dq` gave.
#[inline(always)]
pub(super) unsafe fn shade_batch<S: Simd, T: Voxel>(
    dq: &mut Deferred<S>,
    b: Batch<S>,
    vol: &Vol<S>,
    light: &Light<S>,
    view: [S::F; 3],
) {
    let gr = vol.gradient_cells::<T>(b.p, b.m);
    let v = [
        S::permute(view[0], b.lane),
        S::permute(view[1], b.lane),
        S::permute(view[2], b.lane),
    ];
    let e = light.shade(gr, b.q, b.al, v);
    dq.add(&b, e);
}

/// Queues the slots of lanes `m` ([`Slots`]), shading a vector when one
/// is full.
///
/// # Safety
/// The width's instructions.
#[inline(always)]
pub(super) unsafe fn queue_slots<S: Simd, T: Voxel>(
    dq: &mut Deferred<S>,
    sl: &Slots<S>,
    m: S::M,
    vol: &Vol<S>,
    light: &Light<S>,
    view: [S::F; 3],
) {
    if let Some(b) = dq.push(m, sl.p, sl.w, sl.al, sl.q) {
        shade_batch::<S, T>(dq, b, vol, light, view);
    }
}

#[cfg(target_arch = "x86_64")]
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
#[cfg(target_arch = "x86_64")]
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
#[cfg(target_arch = "x86_64")]
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
#[cfg(target_arch = "x86_64")]
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
#[cfg(target_arch = "aarch64")]
entry!(
    /// [`march_avx2`] in four lanes of NEON registers (AArch64), the
    /// sixteen lanes as four packets, fetching by scalar loads.
    ///
    /// # Safety
    /// The grid `fits`; the shading `shades`; `pk.z_pairs` is the grid's
    /// z-paired copy (`ZPairs::of`).
    pub(super) march_neon,
    "neon",
    W4,
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
    // The fixed step's last samples (`Lane::last`) and their stretches' ends.
    let (mut klast, mut tend) = (S::Af::default(), S::Af::default());
    let mut last_bits = 0u32;
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
            if let Some(kl) = l.last {
                (klast[i], tend[i]) = (kl as f32, l.t_end);
                last_bits |= 1 << i;
            }
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
    // Shading: deferred where the colour is only summed (see `shade`):
    // the fixed step's samples go to the queue as they are composited; a
    // step-per-block march's wait in their lane's slot (a sample's colour
    // is composited at several steps: reuses, the run's end) when the
    // walk is a vector one (whose run ends add to the slot).
    let defer = SHADE && !R::ON;
    let defer_runs = SHADE && R::ON && vw.is_some();
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
    let mut dq = Deferred::<S>::new();
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
                let (ended, dead) = match vw.as_mut() {
                    Some(vw) => vw.next(pk, need, live, &mut rr, &mut kv, &mut col),
                    None => walk_runs::<S, T, R>(pk, st, bits, &mut rr, &mut kv, &mut col),
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
        // stretch; grouped reuse evaluates only where a group starts, and
        // the samples that follow in the group take its value, so this
        // iteration composites them too (up to two copies) and the lane
        // steps past them.
        let none = S::from_bits(0);
        let (is_last, eval, copies) = if R::ON {
            let is_last = S::and(act, S::eq(kv, rr.kend - one));
            if GROUPED {
                let (heads, c) = rr.groups(t, t0, kv, act);
                next = next + S::keep(c[0], one) + S::keep(c[1], one);
                (is_last, heads, c)
            } else {
                (is_last, act, [none; 2])
            }
        } else {
            (none, samp, [none; 2])
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
                    if let Some(b) = dq.push(valid, p, w, al, [qr, qg, qb]) {
                        shade_batch::<S, T>(&mut dq, b, &vol, &light, view);
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
        // Front to back (`over_front` with the optical model's weights;
        // `al` is zero outside `valid`).
        if defer_runs {
            // The slot's colour is composited here: it gains the weight.
            let w = &mut rr.slot.w;
            *w = *w + S::keep(valid, we * (one - col[3]));
        }
        composite::<S>(&mut col, &mut live, valid, e, al, [we, wa], stop);
        if R::ON && GROUPED && S::bits(copies[0]) != 0 {
            // The copies, one after the other as their own iterations
            // would composite them (a copy after the lane terminated is
            // not a sample).
            for c in copies {
                let m = S::and(c, live);
                if S::bits(m) == 0 {
                    break;
                }
                cnt = S::count(cnt, m);
                let mv = S::and(m, valid);
                if defer_runs {
                    let w = &mut rr.slot.w;
                    *w = *w + S::keep(mv, we * (one - col[3]));
                }
                let ev = [S::keep(mv, e[0]), S::keep(mv, e[1]), S::keep(mv, e[2])];
                composite::<S>(&mut col, &mut live, mv, ev, al, [we, wa], stop);
            }
        }
    }
    if !R::ON && !IMP && last_bits != 0 {
        // Each lane's last sample, over its stretch to the exit: the lanes
        // still alive composite it after their fixed steps, as the scalar
        // march's `flush` does (not sampled, and not counted, in an empty
        // block).
        let m = S::and(live, S::from_bits(last_bits));
        let t = t0 + S::load(klast) * stv;
        let p = [o[0] + d[0] * t, o[1] + d[1] * t, o[2] + d[2] * t];
        let m = match pk.empty {
            Some(_) => S::but(m, skips.empty_at(p, m)),
            None => m,
        };
        if S::bits(m) != 0 {
            cnt = S::count(cnt, m);
            let v = vol.sample::<T>(p);
            let valid = S::and(m, S::ge(v, zero));
            let idx = S::keep_i(valid, S::to_i(S::min(v, one) * top + half));
            let mut qv = S::rows(q, S::sll(idx, 2));
            // Transparent at the step: nothing, as the scalar `flush`.
            let vis = S::and(valid, S::gt(qv[3], zero));
            let len = S::max(S::load(tend), t) - t;
            let sigma = f.lut.sigmas().as_ptr();
            over_stretch::<S>(&mut qv, vis, sigma, idx, len, S::splat(1.0 / f.unit));
            let [qr, qg, qb, al] = qv;
            let show = S::and(vis, S::gt(al, zero));
            let mut e = [zero; 3];
            if SHADE {
                cnt_shaded = S::count(cnt_shaded, vis);
                let w = we * (one - col[3]);
                if let Some(b) = dq.push(show, p, w, al, [qr, qg, qb]) {
                    shade_batch::<S, T>(&mut dq, b, &vol, &light, view);
                }
            } else {
                e = [S::keep(show, qr), S::keep(show, qg), S::keep(show, qb)];
            }
            composite::<S>(&mut col, &mut live, show, e, al, [we, wa], stop);
        }
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
