//! The Monte-Carlo marchers of S1: sample positions drawn at random instead
//! of on a regular grid, which trades the Riemann sum's aliasing (wood
//! grain) for noise that progressive accumulation over `spp` passes removes.
//!
//! Each estimates the optical depth `∫ σ(t) dt` of every stretch without
//! bias: a sample at `tᵢ` drawn with density `p` stands for a stretch of
//! length `Δᵢ = 1/(n·p(tᵢ))` (S1 eq. 7; eq. 6 for the uniform pdf
//! `p = 1/(b − a)`), and is composited with opacity `1 − exp(−σ(tᵢ)·Δᵢ)`.
//!
//! * `stratified`: one uniform position in each interval `[t_in + k·s,
//!   t_in + (k+1)·s)`; `Δ = s`.
//! * `mc`: `n = ⌈L/s⌉` independent uniform positions on the ray's whole
//!   `[t_in, t_out]` (S1 eqs. 5–6); `Δ = L/n`.
//! * `importance`: `n` positions from a pdf proportional, block by block, to
//!   the largest extinction the transfer function gives the block's values
//!   (zero in empty blocks, which are thus skipped); `Δᵢ = W/(n·wᵢ)` with
//!   `W = Σ w_b·len_b` (S1 eq. 7).
//!
//! `mc` and `importance` need their positions in order along the ray for
//! front-to-back compositing; they are drawn already sorted, as descending
//! order statistics `U₍ₙ₎ = V^{1/n}`, `U₍ₖ₎ = U₍ₖ₊₁₎·V^{1/k}` (Devroye 1986,
//! V.3), so there is no buffer and no sort.

use super::march::BlockWalker;
use super::optics::Optics;
use super::ray::{evaluate, Acc, Counters, RayCtx};
use super::rng::{splitmix, Rng};
use super::Method;
use crate::volume::Voxel;
use glam::Vec3;

/// `n` uniform numbers in [0, 1), produced in ascending order.
struct SortedUniforms {
    rng: Rng,
    left: u32,
    cur: f32,
}

impl SortedUniforms {
    fn new(rng: Rng, n: u32) -> SortedUniforms {
        SortedUniforms {
            rng,
            left: n,
            cur: 1.0,
        }
    }
}

impl Iterator for SortedUniforms {
    type Item = f32;
    #[inline(always)]
    fn next(&mut self) -> Option<f32> {
        if self.left == 0 {
            return None;
        }
        self.cur *= self.rng.uniform_open0().powf(1.0 / self.left as f32);
        self.left -= 1;
        Some((1.0 - self.cur).clamp(0.0, 1.0 - f32::EPSILON))
    }
}

/// A uniform number for interval `k` of a ray (counter-based, so a stretch
/// can ask for any interval's position in any order).
#[inline(always)]
fn interval_random(key: u64, k: u64) -> f32 {
    (splitmix(key ^ k.wrapping_mul(0xD6E8_FEB8_6659_FD93)) >> 40) as f32 / (1u64 << 24) as f32
}

/// Whether voxel-space point `p` lies in a block that is empty under the TF.
#[inline(always)]
fn in_empty_block<T>(ctx: &RayCtx<'_, T>, p: Vec3) -> bool {
    let b = ctx.block_size as f32;
    let c = ctx.block_counts;
    let ix = ((p.x / b) as usize).min(c[0] - 1);
    let iy = ((p.y / b) as usize).min(c[1] - 1);
    let iz = ((p.z / b) as usize).min(c[2] - 1);
    ctx.empty[ix + c[0] * (iy + c[1] * iz)]
}

/// Runs the stochastic marcher of `ctx.method` on `[t_in, t_out]`; true when
/// the ray was terminated early.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) fn march<T: Voxel, O: Optics>(
    ctx: &RayCtx<'_, T>,
    o: Vec3,
    d: Vec3,
    view: Vec3,
    t_in: f32,
    t_out: f32,
    pixel: (u32, u32),
    acc: &mut Acc<'_>,
    n: &mut Counters,
) -> bool {
    let rng = Rng::for_pixel(ctx.seed, pixel.0, pixel.1, ctx.pass);
    match ctx.method {
        Method::Stratified => stratified::<T, O>(ctx, o, d, view, t_in, t_out, rng, acc, n),
        Method::Mc => uniform_mc::<T, O>(ctx, o, d, view, t_in, t_out, rng, acc, n),
        _ => importance::<T, O>(ctx, o, d, view, t_in, t_out, rng, acc, n),
    }
}

/// Composites the sample at `t` standing for a stretch of `len` (world).
#[inline(always)]
fn sample<T: Voxel, O: Optics>(
    ctx: &RayCtx<'_, T>,
    p: Vec3,
    view: Vec3,
    len: f32,
    acc: &mut Acc<'_>,
    n: &mut Counters,
) -> bool {
    n.samples += 1;
    let Some((i, rgb)) = evaluate(ctx, p, view, n) else {
        return false;
    };
    let alpha = 1.0 - (-ctx.lut.sigma(i) * len / ctx.unit).exp();
    alpha > 0.0 && acc.add::<O>(rgb, alpha)
}

#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn stratified<T: Voxel, O: Optics>(
    ctx: &RayCtx<'_, T>,
    o: Vec3,
    d: Vec3,
    view: Vec3,
    t_in: f32,
    t_out: f32,
    mut rng: Rng,
    acc: &mut Acc<'_>,
    n: &mut Counters,
) -> bool {
    let s = ctx.step;
    let key = rng.next_u32() as u64 | (rng.next_u32() as u64) << 32;
    let last = ((t_out - t_in) / s).ceil().max(1.0) as u64 - 1;
    // Interval k's sample position and the length it stands for (the last
    // interval is cut at t_out).
    let pos = |k: u64| {
        let a = t_in + k as f32 * s;
        let len = if k == last { t_out - a } else { s };
        (a + interval_random(key, k) * len, len)
    };
    let full_alphas = &ctx.level_alphas[(-ctx.level_lo) as usize];
    // A sample belongs to the stretch its position lies in, so skipping an
    // empty stretch drops exactly the samples that contribute nothing.
    for (ta, tb, b) in BlockWalker::new(o, d, t_in, t_out, ctx.block_size, ctx.block_counts) {
        if ctx.skip_empty && ctx.empty[b] {
            continue;
        }
        let k0 = ((ta - t_in) / s).floor().max(0.0) as u64;
        let k1 = (((tb - t_in) / s).floor() as u64).min(last);
        for k in k0..=k1 {
            let (t, len) = pos(k);
            if t < ta || t >= tb {
                continue;
            }
            n.samples += 1;
            let Some((i, rgb)) = evaluate(ctx, o + d * t, view, n) else {
                continue;
            };
            let alpha = if k == last {
                1.0 - (-ctx.lut.sigma(i) * len / ctx.unit).exp()
            } else {
                full_alphas[i]
            };
            if alpha > 0.0 && acc.add::<O>(rgb, alpha) {
                return true;
            }
        }
    }
    false
}

#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn uniform_mc<T: Voxel, O: Optics>(
    ctx: &RayCtx<'_, T>,
    o: Vec3,
    d: Vec3,
    view: Vec3,
    t_in: f32,
    t_out: f32,
    rng: Rng,
    acc: &mut Acc<'_>,
    n: &mut Counters,
) -> bool {
    let len = t_out - t_in;
    let count = (len / ctx.step).ceil().max(1.0) as u32;
    // S1 eq. 6: each of n samples of pdf 1/L weighs L/n.
    let w = len / count as f32;
    for u in SortedUniforms::new(rng, count) {
        let p = o + d * (t_in + u * len);
        if ctx.skip_empty && in_empty_block(ctx, p) {
            continue;
        }
        if sample::<T, O>(ctx, p, view, w, acc, n) {
            return true;
        }
    }
    false
}

#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn importance<T: Voxel, O: Optics>(
    ctx: &RayCtx<'_, T>,
    o: Vec3,
    d: Vec3,
    view: Vec3,
    t_in: f32,
    t_out: f32,
    rng: Rng,
    acc: &mut Acc<'_>,
    n: &mut Counters,
) -> bool {
    let walker = || BlockWalker::new(o, d, t_in, t_out, ctx.block_size, ctx.block_counts);
    // First walk: the pdf's normalisation W = Σ w_b·len_b and the length
    // that is not empty (which sets the sample count, as uniform's would).
    let (mut total, mut busy) = (0.0f32, 0.0f32);
    for (ta, tb, b) in walker() {
        let w = ctx.block_sigma[b];
        total += w * (tb - ta);
        busy += if w > 0.0 { tb - ta } else { 0.0 };
    }
    if total <= 0.0 {
        return false;
    }
    let count = (busy / ctx.step).ceil().max(1.0) as u32;
    // Second walk: inverse CDF of the sorted uniforms, stretch by stretch.
    let mut cdf = 0.0f32;
    let mut stretches = walker().filter(|&(_, _, b)| ctx.block_sigma[b] > 0.0);
    let Some(mut cur) = stretches.next() else {
        return false;
    };
    let mut cur_mass = ctx.block_sigma[cur.2] * (cur.1 - cur.0);
    for u in SortedUniforms::new(rng, count) {
        let target = u * total;
        while cdf + cur_mass <= target {
            cdf += cur_mass;
            match stretches.next() {
                Some(s) => {
                    cur = s;
                    cur_mass = ctx.block_sigma[cur.2] * (cur.1 - cur.0);
                }
                // Rounding at the very end: the sample is in the last stretch.
                None => {
                    cdf -= cur_mass;
                    break;
                }
            }
        }
        let w_b = ctx.block_sigma[cur.2];
        let t = (cur.0 + (target - cdf) / w_b).clamp(cur.0, cur.1);
        // S1 eq. 7: Δ = 1/(n·p(t)), p(t) = w_b / W.
        let len = total / (count as f32 * w_b);
        if sample::<T, O>(ctx, o + d * t, view, len, acc, n) {
            return true;
        }
    }
    false
}
