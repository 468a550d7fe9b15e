//! Where the vector loop hands lanes to their scalar walks: a
//! step-per-block march's runs ([`walk_runs`]), with the lane state it
//! keeps in registers (`adaptive-s0`'s; the other rules walk in vector
//! registers, `super::vwalk`).

use super::shade::Slots;
use super::simd::Simd;
use super::{Packets, Runs, State};
use crate::render::composite::Front;
use crate::render::march::{Next, Pending};
use crate::transfer::LUT_SIZE;
use crate::volume::Voxel;
use glam::Vec4;

/// A step-per-block march's lane state in the vector loop: each lane's
/// run (`k` up to `kend`, step, table offset, group cap), its grouped
/// reuse (`fresh`: the next sample starts a group; the last evaluated
/// sample), and the pending last sample of its run.
pub(super) struct RunRegs<S: Simd> {
    pub stv: S::F,
    pub kend: S::F,
    pub offv: S::I,
    pub capv: S::F,
    pub fresh: S::M,
    /// `group_size`'s thresholds: a third and two thirds of the exit.
    pub th1: S::F,
    pub th2: S::F,
    /// The last evaluated sample: colour, opacity, entry, validity.
    pub last: [S::F; 4],
    pub last_idx: S::I,
    pub last_ok: S::M,
    /// The run's last sample: colour, opacity, position, entry, validity.
    pub pend: [S::F; 5],
    pub pend_idx: S::I,
    pub pend_ok: S::M,
    /// Shading deferred ([`super::shade`]): each lane's last evaluated
    /// sample waits in its slot, its weight gathered at every step it is
    /// composited at, reuses and the run's end included.
    pub defer: bool,
    pub slot: Slots<S>,
}

/// S0's grouped reuse, the lanes whose sample heads a group: of the
/// lanes `act`, those that start afresh (`fresh`, cleared for them here)
/// or whose count `k` is a multiple of `group_size(t, t_out)` — 1, 2 or 3
/// by the thirds `th1`, `th2` of the exit, at most `cap`. The step-per-
/// block runs and `threshold` both group with it, as the scalar
/// `Grouped` does.
#[inline(always)]
pub(super) unsafe fn group_heads<S: Simd>(
    t: S::F,
    k: S::F,
    th1: S::F,
    th2: S::F,
    cap: S::F,
    act: S::M,
    fresh: &mut S::M,
) -> S::M {
    let heads = S::and(act, S::or(*fresh, divides::<S>(t, k, th1, th2, cap)));
    *fresh = S::but(*fresh, act);
    heads
}

/// The lanes whose count `k` (at `t`) is a multiple of its group size
/// ([`group_heads`] without the fresh starts).
#[inline(always)]
unsafe fn divides<S: Simd>(t: S::F, k: S::F, th1: S::F, th2: S::F, cap: S::F) -> S::M {
    let one = S::splat(1.0);
    let g = one + S::keep(S::gt(t, th1), one) + S::keep(S::gt(t, th2), one);
    let g = S::min(g, cap);
    S::eq(S::floor(k / g) * g, k)
}

/// Of the lanes `act` at sample `k` of their run (`t0 + k·step` on their
/// rays), those whose next sample continues the group (not a head, and
/// not the run's last, which waits for its stretch), and of those, the
/// ones whose next but one does too: the copies of this sample's value
/// that the same iteration composites ([`RunRegs`]' `stv`, `kend`,
/// thresholds and cap). A group spans at most four samples (where its
/// size grows from 2 to 3), so a third copy is left to the next
/// iteration, which reuses the value as a continuation does.
#[inline(always)]
unsafe fn group_copies<S: Simd>(rr: &RunRegs<S>, t0: S::F, k: S::F, act: S::M) -> (S::M, S::M) {
    let one = S::splat(1.0);
    let last = rr.kend - one;
    let (k1, k2) = (k + one, k + one + one);
    let (t1, t2) = (t0 + k1 * rr.stv, t0 + k2 * rr.stv);
    let c1 = S::but(
        S::and(act, S::lt(k1, last)),
        divides::<S>(t1, k1, rr.th1, rr.th2, rr.capv),
    );
    let c2 = S::but(
        S::and(c1, S::lt(k2, last)),
        divides::<S>(t2, k2, rr.th1, rr.th2, rr.capv),
    );
    (c1, c2)
}

impl<S: Simd> RunRegs<S> {
    /// S0's grouped reuse for the lanes `act` at sample `k` of their run
    /// (`t0 + k·step` on their rays): the lanes whose sample heads a group
    /// ([`group_heads`]) and the copies of its value that the same
    /// iteration composites ([`group_copies`]). The group tests run only
    /// where some lane can group — a cap above 1, and past `group_size`'s
    /// lower threshold by its third sample from here (a step to spare for
    /// the roundings); elsewhere every lane heads its own group with no
    /// copies, as the tests would find.
    #[inline(always)]
    pub unsafe fn groups(&mut self, t: S::F, t0: S::F, k: S::F, act: S::M) -> (S::M, [S::M; 2]) {
        let one = S::splat(1.0);
        let reach = S::gt(t + S::splat(3.0) * self.stv, S::min(self.th1, self.th2));
        if S::bits(S::and(S::and(act, S::gt(self.capv, one)), reach)) == 0 {
            self.fresh = S::but(self.fresh, act);
            return (act, [S::from_bits(0); 2]);
        }
        let (th1, th2, cap) = (self.th1, self.th2, self.capv);
        let heads = group_heads::<S>(t, k, th1, th2, cap, act, &mut self.fresh);
        let (c1, c2) = group_copies::<S>(self, t0, k, act);
        (heads, [c1, c2])
    }

    /// The lanes of `found` take their next run: samples `n0..n1` (`n0`
    /// into `kv`) at step `step` on the tables' level `level` (a whole
    /// number as a float); it starts its groups afresh.
    #[inline(always)]
    pub unsafe fn take(
        &mut self,
        found: S::M,
        kv: &mut S::F,
        n0: S::F,
        n1: S::F,
        step: S::F,
        level: S::F,
    ) {
        *kv = S::blend(found, *kv, n0);
        self.kend = S::blend(found, self.kend, n1);
        self.stv = S::blend(found, self.stv, step);
        let off = S::mullo(S::to_i(level), S::splat_i((LUT_SIZE * 4) as i32));
        self.offv = S::blend_i(found, self.offv, off);
        self.fresh = S::or(self.fresh, found);
    }

    /// Lanes that have no run yet (each fetches its first), with the
    /// group thresholds `th1`, `th2`.
    #[inline(always)]
    pub unsafe fn new(kend: S::F, th1: S::F, th2: S::F, defer: bool) -> Self {
        let zero = S::splat(0.0);
        RunRegs {
            stv: S::splat(1.0),
            kend,
            offv: S::splat_i(0),
            capv: S::splat(3.0),
            fresh: S::from_bits(0),
            th1,
            th2,
            last: [zero; 4],
            last_idx: S::splat_i(0),
            last_ok: S::from_bits(0),
            pend: [zero; 5],
            pend_idx: S::splat_i(0),
            pend_ok: S::from_bits(0),
            defer,
            slot: Slots::new(),
        }
    }

    /// The lanes of `m` keep their evaluated sample `e` (colour,
    /// opacity), its entry and validity, for their group's reuse.
    #[inline(always)]
    pub unsafe fn keep(&mut self, m: S::M, e: [S::F; 4], idx: S::I, ok: S::M) {
        take::<S, 4>(
            &mut self.last,
            &mut self.last_idx,
            &mut self.last_ok,
            m,
            e,
            idx,
            ok,
        );
    }

    /// The lanes of `m` hold their run's last sample `e` (colour,
    /// opacity, position), entry and validity until their walk takes it.
    #[inline(always)]
    pub unsafe fn hold(&mut self, m: S::M, e: [S::F; 5], idx: S::I, ok: S::M) {
        take::<S, 5>(
            &mut self.pend,
            &mut self.pend_idx,
            &mut self.pend_ok,
            m,
            e,
            idx,
            ok,
        );
    }
}

/// In the lanes of `m`, `(e, idx, ok)` replace `(v, v_idx, v_ok)`.
#[inline(always)]
unsafe fn take<S: Simd, const N: usize>(
    v: &mut [S::F; N],
    v_idx: &mut S::I,
    v_ok: &mut S::M,
    m: S::M,
    e: [S::F; N],
    idx: S::I,
    ok: S::M,
) {
    for (v, e) in v.iter_mut().zip(e) {
        *v = S::blend(m, *v, e);
    }
    *v_idx = S::blend_i(m, *v_idx, idx);
    *v_ok = S::or(S::and(m, ok), S::but(*v_ok, m));
}

/// The step-per-block lanes of `bits`, past their run: each hands its
/// run's last sample to its walk, which composites it into the lane's
/// colour `col` and finds the next run (scalar). Returns the masks of the
/// lanes whose walk ended and of those that terminated.
///
/// # Safety
/// The width's instructions; `st.runs` holds a walk for every lane of
/// `bits`.
#[inline(always)]
pub(super) unsafe fn walk_runs<S: Simd, T: Voxel, R: Runs<T>>(
    pk: &Packets<'_, T, R>,
    st: &mut State<'_>,
    bits: u32,
    rr: &mut RunRegs<S>,
    kv: &mut S::F,
    col: &mut [S::F; 4],
) -> (S::M, S::M) {
    let runs = pk.runs.unwrap_unchecked();
    let mut c4 = [
        S::store(col[0]),
        S::store(col[1]),
        S::store(col[2]),
        S::store(col[3]),
    ];
    let pend = [
        S::store(rr.pend[0]),
        S::store(rr.pend[1]),
        S::store(rr.pend[2]),
        S::store(rr.pend[3]),
        S::store(rr.pend[4]),
    ];
    let pend_idx = S::store_i(rr.pend_idx);
    let pend_ok = S::bits(rr.pend_ok);
    let (mut k, mut kend, mut s, mut cap) = (
        S::store(*kv),
        S::store(rr.kend),
        S::store(rr.stv),
        S::store(rr.capv),
    );
    let mut fresh = S::bits(rr.fresh);
    let mut off = S::store_i(rr.offv);
    let (mut ended, mut dead) = (0u32, 0u32);
    for (i, w) in st.runs.iter_mut().enumerate() {
        if (bits >> i) & 1 == 0 {
            continue;
        }
        let w = w.as_mut().unwrap_unchecked();
        // The run's last sample (none before the first run).
        if (pend_ok >> i) & 1 == 1 {
            w.pending = Some(Pending {
                t: pend[4][i],
                entry: pend_idx[i] as usize,
                e: glam::Vec3::new(pend[0][i], pend[1][i], pend[2][i]),
                a: pend[3][i],
            });
        }
        let acc = Vec4::new(c4[0][i], c4[1][i], c4[2][i], c4[3][i]);
        let mut c = Front::resume(acc, pk.weights, pk.stop);
        match runs.next(pk.f, w, &mut c, st.walk) {
            Next::Run(r) => {
                k[i] = r.n0 as f32;
                kend[i] = r.n1 as f32;
                s[i] = runs.step(r.li);
                off[i] = (r.li * LUT_SIZE * 4) as i32;
                cap[i] = r.cap.min(3) as f32;
                fresh |= 1 << i;
            }
            Next::Ended => ended |= 1 << i,
            Next::Terminated => dead |= 1 << i,
        }
        let acc = c.acc();
        c4[0][i] = acc.x;
        c4[1][i] = acc.y;
        c4[2][i] = acc.z;
        c4[3][i] = acc.w;
    }
    *kv = S::load(k);
    rr.kend = S::load(kend);
    rr.stv = S::load(s);
    rr.capv = S::load(cap);
    rr.fresh = S::from_bits(fresh);
    rr.offv = S::load_i(off);
    // Each pending sample is now with its walk.
    rr.pend_ok = S::but(rr.pend_ok, S::from_bits(bits));
    for (r, v) in col.iter_mut().zip(c4) {
        *r = S::load(v);
    }
    (S::from_bits(ended), S::from_bits(dead))
}
