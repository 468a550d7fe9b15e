//! The end of a packet's march, the same for every vector loop: the
//! deferred shading's last samples, and each lane's colour and counts
//! handed back.

use super::shade::{Deferred, Light};
use super::simd::Simd;
use super::vector::{shade_deferred, Vol};
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
