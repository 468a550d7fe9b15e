//! One ray, generic over the three choices of the ray loop: clip it to the
//! volume (and to the first opaque surface), hand the segment to the
//! marcher, composite over the surface. Monomorphised per voxel type,
//! marcher, sampler and compositor.

use super::composite::{Order, Weights};
use super::march::intersect_box;
use super::ray::{Composite, Counters, Frame, Marcher, Sampler, Segment};
use super::stats::RenderStats;
use super::surface::{self, SurfaceCtx};
use crate::volume::Voxel;
use glam::{Vec3, Vec4};

/// What [`trace`] needs besides the frame: the choices' values.
pub(super) struct Tracer<'a, M, S> {
    pub marcher: &'a M,
    /// The sampler every ray starts from.
    pub sampler: S,
    pub weights: Weights,
    pub ert: f32,
    /// Seed of the per-pixel jitter of the start (`jitter`, or `--jitter`).
    pub jitter: Option<u64>,
    /// Opaque geometry the ray may stop at (S0 Fig. 9–13).
    pub surface: Option<SurfaceCtx<'a>>,
}

/// Casts one ray from world `origin` along unit `dir` (pixel `pixel`,
/// pass `pass`); returns
/// premultiplied linear colour and opacity (before the background).
#[inline]
pub(super) fn trace<T: Voxel, M: Marcher<T>, S: Sampler<T>, O: Order>(
    f: &Frame<'_, T>,
    tr: &Tracer<'_, M, S>,
    (origin, dir): (Vec3, Vec3),
    pixel: (u32, u32),
    pass: u32,
    stats: &mut RenderStats,
    scratch: &mut Vec<(Vec3, f32)>,
) -> Vec4 {
    stats.rays += 1;
    // The ray in voxel coordinates; t stays in world units.
    let o = (origin - f.origin_w) * f.inv_spacing;
    let d = dir * f.inv_spacing;
    // The first opaque surface ends the ray (S0 Fig. 9–13).
    let hit = surface::first_hit(
        f,
        tr.surface.as_ref(),
        origin,
        dir,
        &mut stats.interpolations,
    );
    let behind = hit.map(|(_, rgb)| rgb);
    let opaque = || behind.map_or(Vec4::ZERO, |c| c.extend(1.0));
    let inv_d = Vec3::ONE / d;
    let Some((t_in, mut t_out)) = intersect_box(o, inv_d, f.box_lo, f.box_hi) else {
        return opaque();
    };
    if let Some((t, _)) = hit {
        if t <= t_in {
            return opaque();
        }
        t_out = t_out.min(t);
    }
    stats.rays_hit += 1;
    let t0 = match tr.jitter {
        // Pass 0 of the sequence is the plain per-pixel random offset.
        Some(seed) => t_in + super::rng::pixel_sequence(seed, pixel.0, pixel.1, pass) * f.step,
        None => t_in,
    };
    let mut c = O::start(tr.weights, tr.ert, scratch);
    // The stretch of the ray that meets blocks that are not empty: the block
    // walk starts and ends there (sample positions still follow from `t_in`,
    // so the picture does not change, only the empty blocks walked).
    let walk = match f.occupied {
        Some((lo, hi)) => intersect_box(o, inv_d, lo, hi)
            .map(|(a, b)| (a.max(t_in), b.min(t_out)))
            .filter(|(a, b)| a < b),
        None => Some((t_in, t_out)),
    };
    let mut n = Counters::default();
    let terminated = match walk {
        Some(walk) => {
            let seg = Segment {
                o,
                d,
                view: -dir,
                t_in,
                t_out,
                t0,
                walk,
                pixel,
                pass,
            };
            let mut s = tr.sampler;
            s.begin(t_out);
            tr.marcher.march(f, &seg, &mut s, &mut c, &mut n)
        }
        // Every block on the ray is empty (and skipped).
        None => false,
    };
    stats.samples += n.samples;
    stats.interpolations += n.interpolations;
    stats.gradient_interpolations += 6 * n.shaded;
    stats.early_terminated += terminated as u64;
    c.finish(behind)
}
