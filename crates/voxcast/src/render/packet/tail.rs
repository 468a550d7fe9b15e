//! The end of a packet's march, the same for every vector loop: the
//! deferred shading's last samples, and each lane's colour and counts
//! handed back; and the end of a step in the loops whose lanes keep their
//! own positions (`threshold`, `stratified`, `mc`): a sample over its own
//! stretch, and front-to-back compositing.

use super::fetch::Vol;
use super::shade::{Deferred, Light};
use super::simd::Simd;
use super::vector::shade_batch;
use super::vwalk::exp;
use super::{Lane, Packets, Runs, State};
use crate::transfer::LUT_SIZE;
use crate::volume::Voxel;
use glam::Vec4;

/// Shades every sample still waiting in `dq` and adds the queue's colour
/// to the lanes' `col`: the end of a packet's march.
///
/// # Safety
/// The width's instructions.
#[inline(always)]
pub(super) unsafe fn drain_deferred<S: Simd, T: Voxel>(
    dq: &mut Deferred<S>,
    col: &mut [S::F; 4],
    vol: &Vol<S>,
    light: &Light<S>,
    view: [S::F; 3],
) {
    if let Some(b) = dq.rest() {
        shade_batch::<S, T>(dq, b, vol, light, view);
    }
    for (c, acc) in dq.acc.iter().enumerate() {
        col[c] = col[c] + S::load_at(acc.as_ptr());
    }
}

/// Hands each lane's colour, counts (samples, shaded, interpolations) and
/// whether it is still marching (`live`, a lane of `lanes`) back to `st`.
///
/// # Safety
/// The width's instructions.
#[inline(always)]
pub(super) unsafe fn store_lanes<S: Simd>(
    st: &mut State<'_>,
    lanes: &[Option<Lane>],
    col: [S::F; 4],
    counts: [S::I; 3],
    live: S::M,
) {
    let col = [
        S::store(col[0]),
        S::store(col[1]),
        S::store(col[2]),
        S::store(col[3]),
    ];
    let (c, cs, ci) = (
        S::store_i(counts[0]),
        S::store_i(counts[1]),
        S::store_i(counts[2]),
    );
    let l = S::bits(live);
    for i in 0..S::N {
        st.acc[i] = Vec4::new(col[0][i], col[1][i], col[2][i], col[3][i]);
        st.count[i] = [c[i] as u32, cs[i] as u32, ci[i] as u32];
        st.alive[i] = lanes[i].is_some() && (l >> i) & 1 == 1;
    }
}

/// The lanes of `last` stand for a stretch of length `len` (a ray's last
/// sample, `Segment::t_end`): their opacity `q[3]` becomes `1 −
/// exp(−σ·len/unit)`, σ the extinction of their table entry `idx`, and
/// their premultiplied colour follows it.
///
/// # Safety
/// The width's instructions; `sigma` has every entry of `idx`.
#[inline(always)]
pub(super) unsafe fn over_stretch<S: Simd>(
    q: &mut [S::F; 4],
    last: S::M,
    sigma: *const f32,
    idx: S::I,
    len: S::F,
    inv_unit: S::F,
) {
    if S::bits(last) == 0 {
        return;
    }
    let (zero, one) = (S::splat(0.0), S::splat(1.0));
    let sg = S::gather_f::<4>(sigma, idx);
    let ax = one - exp::<S>(zero - sg * len * inv_unit);
    let k = S::blend(S::gt(q[3], zero), zero, ax / q[3]);
    let k = S::blend(last, one, k);
    (q[0], q[1], q[2]) = (q[0] * k, q[1] * k, q[2] * k);
    q[3] = S::blend(last, q[3], ax);
}

/// Composites a step front to back: the lanes of `valid` add emission
/// `e` (zero where shading is deferred) and opacity `al`, weighted by the
/// optical model (`we`, `wa`); a lane whose opacity reaches `stop` ends.
///
/// # Safety
/// The width's instructions.
#[inline(always)]
pub(super) unsafe fn composite<S: Simd>(
    col: &mut [S::F; 4],
    live: &mut S::M,
    valid: S::M,
    e: [S::F; 3],
    al: S::F,
    [we, wa]: [S::F; 2],
    stop: S::F,
) {
    let al = S::keep(valid, al);
    let tr = S::splat(1.0) - col[3];
    col[0] = col[0] + e[0] * we * tr;
    col[1] = col[1] + e[1] * we * tr;
    col[2] = col[2] + e[2] * we * tr;
    col[3] = col[3] + al * wa * tr;
    *live = S::but(*live, S::and(valid, S::ge(col[3], stop)));
}

/// What the loops whose lanes draw their own positions (`stratified`,
/// `mc`) need to take a sample: the grid, the step's premultiplied table
/// and the extinctions (for a stretch of another length), the light, the
/// optical model's weights and the termination threshold; and what a
/// packet's samples gather: the lanes' colour and opacity, which are
/// still going, the shading queue and the counts.
pub(super) struct Taker<S: Simd> {
    pub vol: Vol<S>,
    q: *const f32,
    sigma: *const f32,
    shading: bool,
    light: Light<S>,
    view: [S::F; 3],
    weights: [S::F; 2],
    stop: S::F,
    inv_unit: S::F,
    col: [S::F; 4],
    pub live: S::M,
    dq: Deferred<S>,
    cnt: S::I,
    cnt_shaded: S::I,
}

impl<S: Simd> Taker<S> {
    /// For the packets `pk`, lanes `live` looking along `view`, from
    /// colour and opacity `col`; `sigma` every table entry's extinction.
    ///
    /// # Safety
    /// The width's instructions.
    #[inline(always)]
    pub unsafe fn new<T: Voxel, R: Runs<T>>(
        pk: &Packets<'_, T, R>,
        sigma: &[f32; LUT_SIZE],
        view: [S::F; 3],
        col: [S::F; 4],
        live: S::M,
    ) -> Self {
        Taker {
            vol: Vol::<S>::of(pk),
            q: pk.q.as_ptr() as *const f32,
            sigma: sigma.as_ptr(),
            shading: pk.shading.is_some(),
            light: Light::<S>::new(&pk.shading.unwrap_or_default(), pk.f.inv_spacing),
            view,
            weights: [
                S::splat(pk.weights.emission),
                S::splat(pk.weights.absorption),
            ],
            stop: S::splat(pk.stop),
            inv_unit: S::splat(1.0 / pk.f.unit),
            col,
            live,
            dq: Deferred::<S>::new(),
            cnt: S::splat_i(0),
            cnt_shaded: S::splat_i(0),
        }
    }

    /// The lanes of `samp` take a sample at `p` (counted), those of `own`
    /// over a stretch of length `len` (the others over the step), and
    /// composite it front to back (shaded, when the render shades, by the
    /// deferred queue).
    ///
    /// # Safety
    /// The width's instructions; `p` inside the grid's sample box.
    #[inline(always)]
    pub unsafe fn take<T: Voxel>(&mut self, samp: S::M, p: [S::F; 3], own: S::M, len: S::F) {
        let (zero, one, half) = (S::splat(0.0), S::splat(1.0), S::splat(0.5));
        let top = S::splat((LUT_SIZE - 1) as f32);
        self.cnt = S::count(self.cnt, samp);
        let v = self.vol.sample::<T>(p);
        // `Lut::index`: below 0 (or NaN) nothing.
        let mut valid = S::and(samp, S::ge(v, zero));
        let idx = S::keep_i(valid, S::to_i(S::min(v, one) * top + half));
        let mut qv = S::rows(self.q, S::sll(idx, 2));
        over_stretch::<S>(
            &mut qv,
            S::and(valid, own),
            self.sigma,
            idx,
            len,
            self.inv_unit,
        );
        let [qr, qg, qb, al] = qv;
        let mut e = [zero; 3];
        valid = S::and(valid, S::gt(al, zero));
        if self.shading {
            if S::bits(valid) != 0 {
                let w = self.weights[0] * (one - self.col[3]);
                if let Some(b) = self.dq.push(valid, p, w, al, [qr, qg, qb]) {
                    shade_batch::<S, T>(&mut self.dq, b, &self.vol, &self.light, self.view);
                }
                self.cnt_shaded = S::count(self.cnt_shaded, valid);
            }
        } else {
            e = [S::keep(valid, qr), S::keep(valid, qg), S::keep(valid, qb)];
        }
        composite::<S>(
            &mut self.col,
            &mut self.live,
            valid,
            e,
            al,
            self.weights,
            self.stop,
        );
    }

    /// The end of the march: the queue's last samples shaded, and each
    /// lane's colour, counts (every sample is interpolated once) and
    /// whether it is still going handed back to `st`.
    ///
    /// # Safety
    /// The width's instructions.
    #[inline(always)]
    pub unsafe fn finish<T: Voxel>(mut self, st: &mut State<'_>, lanes: &[Option<Lane>]) {
        if self.shading {
            drain_deferred::<S, T>(
                &mut self.dq,
                &mut self.col,
                &self.vol,
                &self.light,
                self.view,
            );
        }
        store_lanes::<S>(
            st,
            lanes,
            self.col,
            [self.cnt, self.cnt_shaded, self.cnt],
            self.live,
        );
    }
}
