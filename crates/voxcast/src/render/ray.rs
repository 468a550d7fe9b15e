//! One ray: the marcher's sample positions, reconstruction (with S0's
//! grouped reuse), the transfer function, shading and compositing. Generic
//! over the voxel type and the optical model; no allocation, no dynamic
//! dispatch, no locks.

use super::march::{group_size, BlockWalker, ThresholdParams};
use super::optics::{over_back, over_front, Optics};
use super::shading::BlinnPhong;
use super::stats::RenderStats;
use super::Method;
use crate::transfer::{Lut, LUT_SIZE};
use crate::volume::{Grid, Voxel};
use glam::{Vec3, Vec4};

/// Everything a ray needs that is the same for all rays of a render (and
/// pass: progressive methods copy it with the pass number changed).
pub(super) struct RayCtx<'a, T> {
    pub grid: &'a Grid<'a, T>,
    pub lut: &'a Lut,
    /// Box through the voxel centres, in voxel coordinates.
    pub box_lo: Vec3,
    pub box_hi: Vec3,
    pub origin_w: Vec3,
    pub inv_spacing: Vec3,
    /// Base step in world units.
    pub step: f32,
    /// Unit length (the smallest spacing) in world units.
    pub unit: f32,
    pub ert: f32,
    pub back_to_front: bool,
    pub shading: Option<BlinnPhong>,
    pub method: Method,
    pub grouped: bool,
    pub jitter: Option<u64>,
    pub skip_empty: bool,
    /// Block grid: edge in cells, counts, emptiness under the TF, and the
    /// largest gradient component per block.
    pub block_size: usize,
    pub block_counts: [usize; 3],
    pub empty: &'a [bool],
    /// With empty-space skipping: the box (voxel coordinates) around the
    /// blocks that are not empty, outside which a ray has nothing to march;
    /// `None` without skipping.
    pub occupied: Option<(Vec3, Vec3)>,
    pub max_gradient: &'a [f32],
    /// Adaptive: allowed power-of-two levels, `k_ref`, and per level
    /// (index `j − level_lo`) the step in world units and the step opacity
    /// of every table entry.
    pub level_lo: i32,
    pub level_hi: i32,
    pub k_ref: f32,
    pub level_steps: &'a [f32],
    pub level_alphas: &'a [Box<[f32; LUT_SIZE]>],
    /// Threshold marcher: ranges and, per range, the step (world units) and
    /// the step opacities.
    pub threshold: ThresholdParams,
    pub threshold_steps: [f32; 3],
    pub threshold_alphas: &'a [Box<[f32; LUT_SIZE]>],
    /// Opaque geometry the ray may stop at (S0 Fig. 9–13).
    pub surface: Option<super::surface::SurfaceCtx<'a>>,
    /// Seed and pass of the stochastic marchers (Monte-Carlo passes).
    pub seed: u64,
    pub pass: u32,
    /// `importance`: its pdf per block (see `stochastic.rs`), and per level
    /// `j` the spacing `step·2^j` (world units) and the step opacity of
    /// every table entry.
    pub pdf: &'a [super::stochastic::PdfBlock],
    pub importance_steps: &'a [f32],
    pub importance_alphas: &'a [Box<[f32; LUT_SIZE]>],
    /// S3 octree + LOD: the octree and the spacing tables (`lod` only).
    pub lod: Option<&'a super::lod::LodRay<'a>>,
}

// Manual impls: a derive would demand `T: Copy`, but only references to T
// are held.
impl<T> Clone for RayCtx<'_, T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T> Copy for RayCtx<'_, T> {}

/// A sample evaluated but not yet composited (its stretch of ray is known
/// only when the next sample's position is).
#[derive(Clone, Copy)]
pub(super) struct Pending {
    pub t: f32,
    pub entry: usize,
    pub rgb: Vec3,
}

/// Accumulated colour and opacity, in either order.
pub(super) struct Acc<'s> {
    c: Vec3,
    pub a: f32,
    ert: f32,
    back: Option<&'s mut Vec<(Vec3, f32)>>,
}

impl Acc<'_> {
    /// Adds a sample; true when the ray may stop (early ray termination).
    #[inline(always)]
    pub(super) fn add<O: Optics>(&mut self, rgb: Vec3, alpha: f32) -> bool {
        let (em, ab) = O::contribution(rgb, alpha);
        match &mut self.back {
            Some(buf) => {
                buf.push((em, ab));
                false
            }
            None => {
                over_front(&mut self.c, &mut self.a, em, ab);
                self.a >= self.ert && self.ert < 1.0
            }
        }
    }

    /// The composite, over the opaque surface colour `behind` if the ray
    /// ended on one.
    fn finish(mut self, behind: Option<Vec3>) -> Vec4 {
        if let Some(s) = behind {
            if self.back.is_some() {
                // Back to front starts from the opaque surface.
                self.c = s;
                self.a = 1.0;
            } else {
                over_front(&mut self.c, &mut self.a, s, 1.0);
            }
        }
        if let Some(buf) = self.back.take() {
            for &(em, ab) in buf.iter().rev() {
                over_back(&mut self.c, &mut self.a, em, ab);
            }
        }
        self.c.extend(self.a)
    }
}

/// Reconstructs, classifies and shades the sample at voxel position `p`;
/// `None` when the transfer function makes it transparent.
#[inline(always)]
pub(super) fn evaluate<T: Voxel>(
    ctx: &RayCtx<'_, T>,
    p: Vec3,
    view: Vec3,
    n: &mut Counters,
) -> Option<(usize, Vec3)> {
    let v = ctx.grid.sample(p);
    n.interpolations += 1;
    let i = Lut::index(v)?;
    shade_entry(ctx, i, p, view, n).map(|rgb| (i, rgb))
}

/// Per-ray counters, kept in registers and added to the tile's stats once.
#[derive(Default)]
pub(super) struct Counters {
    pub samples: u64,
    pub interpolations: u64,
    pub shaded: u64,
}

/// Casts one ray; returns premultiplied linear colour and opacity (before
/// the background).
#[inline]
pub(super) fn trace<T: Voxel, O: Optics>(
    ctx: &RayCtx<'_, T>,
    origin: Vec3,
    dir: Vec3,
    pixel: (u32, u32),
    stats: &mut RenderStats,
    scratch: &mut Vec<(Vec3, f32)>,
) -> Vec4 {
    stats.rays += 1;
    // The ray in voxel coordinates; t stays in world units.
    let o = (origin - ctx.origin_w) * ctx.inv_spacing;
    let d = dir * ctx.inv_spacing;
    // The first opaque surface ends the ray (S0 Fig. 9–13).
    let hit = ctx.surface.and_then(|s| {
        s.geometry
            .hit(origin, dir, 0.0, f32::INFINITY)
            .map(|h| (s, h))
    });
    let surface_rgb = |stats: &mut RenderStats| {
        hit.map(|(s, h)| super::surface::shade(ctx, &s, origin, dir, &h, &mut stats.interpolations))
    };
    let inv_d = Vec3::ONE / d;
    let Some((t_in, mut t_out)) = super::march::intersect_box(o, inv_d, ctx.box_lo, ctx.box_hi)
    else {
        return surface_rgb(stats).map_or(Vec4::ZERO, |c| c.extend(1.0));
    };
    if let Some((_, h)) = &hit {
        if h.t <= t_in {
            return surface_rgb(stats).map_or(Vec4::ZERO, |c| c.extend(1.0));
        }
        t_out = t_out.min(h.t);
    }
    stats.rays_hit += 1;
    let t0 = match ctx.jitter {
        // Pass 0 of the sequence is the plain per-pixel random offset.
        Some(seed) => {
            t_in + super::rng::pixel_sequence(seed, pixel.0, pixel.1, ctx.pass) * ctx.step
        }
        None => t_in,
    };
    scratch.clear();
    let mut acc = Acc {
        c: Vec3::ZERO,
        a: 0.0,
        ert: ctx.ert,
        back: ctx.back_to_front.then_some(scratch),
    };
    let mut n = Counters::default();
    // The stretch of the ray that meets blocks that are not empty: the block
    // walk starts and ends there (sample positions still follow from `t_in`,
    // so the picture does not change, only the empty blocks walked).
    let walk = match ctx.occupied {
        Some((lo, hi)) => super::march::intersect_box(o, inv_d, lo, hi)
            .map(|(a, b)| (a.max(t_in), b.min(t_out)))
            .filter(|(a, b)| a < b),
        None => Some((t_in, t_out)),
    };
    let terminated = if let (Method::Lod, Some(lod)) = (ctx.method, ctx.lod) {
        super::lod::march_lod::<T, O>(ctx, lod, o, d, -dir, t0, t_in, t_out, &mut acc, &mut n)
    } else if let Some(walk) = walk {
        let walker = BlockWalker::new(o, d, walk.0, t_out, ctx.block_size, ctx.block_counts);
        if ctx.method == Method::Threshold {
            march_threshold::<T, O>(ctx, o, d, -dir, t0, t_out, walk.1, walker, &mut acc, &mut n)
        } else if ctx.method.is_monte_carlo() {
            super::stochastic::march::<T, O>(
                ctx, o, d, -dir, t_in, t_out, walk, pixel, &mut acc, &mut n,
            )
        } else {
            march_blocks::<T, O>(ctx, o, d, -dir, t0, t_out, walk.1, walker, &mut acc, &mut n)
        }
    } else {
        // Every block on the ray is empty (and skipped).
        false
    };
    stats.samples += n.samples;
    stats.interpolations += n.interpolations;
    stats.gradient_interpolations += 6 * n.shaded;
    stats.early_terminated += terminated as u64;
    let behind = surface_rgb(stats);
    acc.finish(behind)
}

/// Uniform and adaptive marching: per block a step `s = step·2^j` (j = 0 for
/// uniform), samples at `t₀ + n·s` inside the block. Past `t_stop` every
/// block is empty: the walk ends there once no sample waits for its stretch.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn march_blocks<T: Voxel, O: Optics>(
    ctx: &RayCtx<'_, T>,
    o: Vec3,
    d: Vec3,
    view: Vec3,
    t0: f32,
    t_out: f32,
    t_stop: f32,
    walker: BlockWalker,
    acc: &mut Acc<'_>,
    n: &mut Counters,
) -> bool {
    let mut pending: Option<Pending> = None;
    // Composites the pending sample over the stretch up to `t_next`.
    let flush = |p: Pending, t_next: f32, acc: &mut Acc<'_>| -> bool {
        let ds = t_next - p.t;
        let alpha = 1.0 - (-ctx.lut.sigma(p.entry) * ds / ctx.unit).exp();
        alpha > 0.0 && acc.add::<O>(p.rgb, alpha)
    };
    for (ta, tb, b) in walker {
        if ta >= t_stop && pending.is_none() {
            break;
        }
        let empty = ctx.empty[b];
        let j = match ctx.method {
            Method::Adaptive | Method::AdaptiveMax if empty => ctx.level_hi,
            Method::Adaptive => {
                // S0 eqs. 1–6 at the block's midpoint S.
                let tm = 0.5 * (ta + tb);
                let g = ctx.grid.gradient(o + d * tm);
                n.interpolations += 6;
                let k = g.x.abs().max(g.y.abs()).max(g.z.abs());
                level(ctx, k, t_out, tm)
            }
            Method::AdaptiveMax => level(ctx, ctx.max_gradient[b], t_out, 0.5 * (ta + tb)),
            // Uniform steps: uniform, threshold's base grid, jitter.
            _ => 0,
        };
        let li = (j - ctx.level_lo) as usize;
        let s = ctx.level_steps[li];
        let n0 = ((ta - t0) / s).ceil().max(0.0);
        let n1 = ((tb - t0) / s).ceil().max(0.0);
        if n1 <= n0 {
            continue;
        }
        let (n0, n1) = (n0 as u32, n1 as u32);
        let t_first = t0 + n0 as f32 * s;
        if let Some(p) = pending.take() {
            if flush(p, t_first, acc) {
                return true;
            }
        }
        if empty && ctx.skip_empty {
            continue;
        }
        let alphas = &ctx.level_alphas[li];
        let mut last: Option<(usize, Vec3)> = None;
        for k in n0..n1 {
            let t = t0 + k as f32 * s;
            n.samples += 1;
            let head = !ctx.grouped || k == n0 || k.is_multiple_of(group_size(t, t_out));
            let here = if head {
                let e = evaluate(ctx, o + d * t, view, n);
                last = e;
                e
            } else {
                last
            };
            let Some((i, rgb)) = here else { continue };
            if k + 1 < n1 {
                // The next sample is in this block: a full step.
                let alpha = alphas[i];
                if alpha > 0.0 && acc.add::<O>(rgb, alpha) {
                    return true;
                }
            } else {
                pending = Some(Pending { t, entry: i, rgb });
            }
        }
    }
    if let Some(p) = pending {
        return flush(p, t_out.max(p.t), acc);
    }
    false
}

/// The adaptive level of a block with largest derivative `k` whose
/// midpoint is at `tm` on a ray leaving at `t_out`: `F = k·|MN|/|MS|`.
#[inline(always)]
fn level<T>(ctx: &RayCtx<'_, T>, k: f32, t_out: f32, tm: f32) -> i32 {
    let f = k * t_out / tm.max(1e-6);
    if f > 0.0 {
        ((ctx.k_ref / f).log2().round() as i32).clamp(ctx.level_lo, ctx.level_hi)
    } else {
        ctx.level_hi
    }
}

/// Threshold-range marching (Zeng et al. 2018): from each sample the step
/// to the next depends on the range its value falls into. Positions follow
/// from the samples before them, so here skipping an empty block restarts
/// the march on the base grid `t₀ + n·step` at the next non-empty block
/// (there is none past `t_stop`).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn march_threshold<T: Voxel, O: Optics>(
    ctx: &RayCtx<'_, T>,
    o: Vec3,
    d: Vec3,
    view: Vec3,
    t0: f32,
    t_out: f32,
    t_stop: f32,
    walker: BlockWalker,
    acc: &mut Acc<'_>,
    n: &mut Counters,
) -> bool {
    let mut t = t0;
    // Grouped reuse: the head's value and shaded colour, and the count of
    // samples since the last skip (heads where it is a multiple of the group).
    let mut head_value = 0.0f32;
    let mut head_rgb: Option<Vec3> = None;
    let mut count = 0u32;
    for (ta, tb, b) in walker {
        if ta >= t_stop {
            break;
        }
        if ctx.skip_empty && ctx.empty[b] {
            continue;
        }
        if t < ta {
            t = t0 + ((ta - t0) / ctx.step).ceil() * ctx.step;
            count = 0;
        }
        while t < tb {
            n.samples += 1;
            let head = !ctx.grouped || count.is_multiple_of(group_size(t, t_out));
            count += 1;
            let p = o + d * t;
            if head {
                head_value = ctx.grid.sample(p);
                n.interpolations += 1;
                head_rgb = Lut::index(head_value).and_then(|i| shade_entry(ctx, i, p, view, n));
            }
            let r = ctx.threshold.range(head_value);
            let s = ctx.threshold_steps[r];
            if let (Some(rgb), Some(i)) = (head_rgb, Lut::index(head_value)) {
                let alpha = if t + s <= t_out {
                    ctx.threshold_alphas[r][i]
                } else {
                    1.0 - (-ctx.lut.sigma(i) * (t_out - t) / ctx.unit).exp()
                };
                if alpha > 0.0 && acc.add::<O>(rgb, alpha) {
                    return true;
                }
            }
            t += s;
        }
    }
    false
}

/// Colour of table entry `i` at `p`, shaded; `None` when transparent.
#[inline(always)]
fn shade_entry<T: Voxel>(
    ctx: &RayCtx<'_, T>,
    i: usize,
    p: Vec3,
    view: Vec3,
    n: &mut Counters,
) -> Option<Vec3> {
    if ctx.lut.sigma(i) <= 0.0 {
        return None;
    }
    let e = ctx.lut.entry(i);
    let mut rgb = Vec3::new(e[0], e[1], e[2]);
    if let Some(sh) = &ctx.shading {
        let g = ctx.grid.gradient(p);
        n.shaded += 1;
        rgb = sh.shade(rgb, g, ctx.inv_spacing, view);
    }
    Some(rgb)
}
