//! The end of a packet's march, the same for every vector loop: the
//! deferred shading's last samples, and each lane's colour and counts
//! handed back; and the end of a step in the loops whose lanes keep their
//! own positions (`threshold`, `stratified`): a ray's last sample over
//! its stretch, and front-to-back compositing.

use super::shade::{Deferred, Light};
use super::simd::Simd;
use super::vector::{shade_deferred, Vol};
use super::vwalk::exp;
use super::{Lane, State};
use crate::volume::Voxel;
use glam::Vec4;

/// Shades every sample still waiting in `dq` and adds the queue's colour
/// to the lanes' `col`: the end of a packet's march.
///
/// # Safety
/// The width's instructions.
#[inline(always)]
pub(super) unsafe fn drain_deferred<S: Simd, T: Voxel>(
    dq: &mut Deferred,
    col: &mut [S::F; 4],
    vol: &Vol<S>,
    light: &Light<S>,
    view: [S::F; 3],
) {
    while dq.waiting() > 0 {
        shade_deferred::<S, T>(dq, vol, light, view);
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
