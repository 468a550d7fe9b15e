//! The opaque surface at the end of a ray (S0 Fig. 9–13): the ray's exit
//! from the volume is clamped to the first geometry hit, the smoke in front
//! is composited over the surface's lit colour. Optional shadows: the key
//! light reaching the surface is attenuated by the smoke along a shadow ray
//! (Beer–Lambert, `T = exp(−∫σ ds)`) and blocked by other shapes.

use super::ray::Frame;
use crate::geometry::{Geometry, Hit, SurfaceLight};
use crate::transfer::Lut;
use crate::volume::Voxel;
use glam::Vec3;

/// What a ray needs to know about the geometry.
#[derive(Clone, Copy)]
pub(super) struct SurfaceCtx<'a> {
    pub geometry: &'a Geometry,
    pub light: SurfaceLight,
    pub shadows: bool,
}

/// The first opaque surface on the ray `origin + dir·t` (world), if any:
/// where the ray ends (`t`) and the surface's lit colour ([`shade`],
/// counting the shadow ray's lookups in `interpolations`) — what
/// `trace` and the packets composite behind the ray's samples.
pub(super) fn first_hit<T: Voxel>(
    ctx: &Frame<'_, T>,
    s: Option<&SurfaceCtx<'_>>,
    origin: Vec3,
    dir: Vec3,
    interpolations: &mut u64,
) -> Option<(f32, Vec3)> {
    let s = s?;
    let hit = s.geometry.hit(origin, dir, 0.0, f32::INFINITY)?;
    Some((hit.t, shade(ctx, s, origin, dir, &hit, interpolations)))
}

/// [`first_hit`] for each of `rays` (at most a packet's) into `out` (as
/// many), the BVH walked once for all of them
/// ([`crate::geometry::Geometry::hit_packet`]) and the hits lit together
/// ([`crate::geometry::SurfaceLight::shade_packet`]): the same hits and
/// colours.
pub(super) fn first_hits<T: Voxel>(
    ctx: &Frame<'_, T>,
    s: &SurfaceCtx<'_>,
    rays: &[(Vec3, Vec3)],
    out: &mut [Option<(f32, Vec3)>],
    interpolations: &mut u64,
) {
    const P: usize = crate::geometry::packet::PACKET;
    let mut hits = [None; P];
    let hits = &mut hits[..rays.len()];
    s.geometry.hit_packet(rays, hits);
    // Lane by lane: albedo, normal, direction (x, y, z) and the light.
    let (mut a, mut n, mut d) = ([[0.0; P]; 3], [[0.0; P]; 3], [[0.0; P]; 3]);
    let mut light = [1.0; P];
    for (l, (&(o, dir), hit)) in rays.iter().zip(&*hits).enumerate() {
        let Some(h) = hit else { continue };
        for k in 0..3 {
            (a[k][l], n[k][l], d[k][l]) = (h.albedo[k], h.normal[k], dir[k]);
        }
        if s.shadows {
            light[l] = light_at(ctx, s, o, dir, h, interpolations);
        }
    }
    let rgb = s.light.shade_packet(&a, &n, &d, &light);
    for (l, (hit, out)) in hits.iter().zip(out).enumerate() {
        *out = hit.map(|h| (h.t, Vec3::new(rgb[0][l], rgb[1][l], rgb[2][l])));
    }
}

/// The lit linear colour of `hit` on the ray `origin + dir·t` (world).
#[inline]
pub(super) fn shade<T: Voxel>(
    ctx: &Frame<'_, T>,
    s: &SurfaceCtx<'_>,
    origin: Vec3,
    dir: Vec3,
    hit: &Hit,
    interpolations: &mut u64,
) -> Vec3 {
    let light = light_at(ctx, s, origin, dir, hit, interpolations);
    s.light.shade(hit.albedo, hit.normal, dir, light)
}

/// The fraction of the key light that reaches `hit`: 1 without shadows,
/// else what the shapes and the smoke between it and the light let through.
#[inline]
fn light_at<T: Voxel>(
    ctx: &Frame<'_, T>,
    s: &SurfaceCtx<'_>,
    origin: Vec3,
    dir: Vec3,
    hit: &Hit,
    interpolations: &mut u64,
) -> f32 {
    if !s.shadows {
        return 1.0;
    }
    let facing = if hit.normal.dot(dir) > 0.0 {
        -hit.normal
    } else {
        hit.normal
    };
    if facing.dot(s.light.to_light) <= 0.0 {
        return 1.0;
    }
    // Off the surface by a fraction of a voxel, so the shadow ray does not
    // find the surface it starts on.
    let p = origin + dir * hit.t + facing * (1e-3 * ctx.unit);
    if s.geometry.occluded(p, s.light.to_light, 0.0, f32::INFINITY) {
        0.0
    } else {
        transmittance(ctx, p, s.light.to_light, interpolations)
    }
}

/// Transmittance of the volume from world point `p` along unit `l` to the
/// volume's edge: midpoint sums of the extinction at the render's base step.
///
/// With empty-space skipping, the samples outside the occupied box (the box
/// around the blocks the transfer function does not make transparent) are
/// not taken, nor counted in `interpolations`: each lies in an empty block
/// and adds exactly 0 to the sum, so the sum, and the picture, are the same
/// bits as without skipping. In a room with little smoke most of a shadow
/// ray is outside that box (office frame 50, `--shadows on`: −9 % time).
/// Testing each sample's block inside the box as well saved more lookups
/// but no time (measured; the test costs about what a lookup does).
#[inline]
pub(super) fn transmittance<T: Voxel>(
    ctx: &Frame<'_, T>,
    p: Vec3,
    l: Vec3,
    interpolations: &mut u64,
) -> f32 {
    let o = (p - ctx.origin_w) * ctx.inv_spacing;
    let d = l * ctx.inv_spacing;
    let inv_d = Vec3::ONE / d;
    let Some((t0, t1)) = super::march::intersect_box(o, inv_d, ctx.box_lo, ctx.box_hi) else {
        return 1.0;
    };
    let n = ((t1 - t0) / ctx.step).ceil().max(1.0);
    let ds = (t1 - t0) / n;
    // The samples `k0..k1` are those that can lie in the occupied box, with
    // a sample of margin each side (one taken in an empty block adds 0).
    let (k0, k1) = match ctx.occupied {
        Some((lo, hi)) => {
            let Some((ta, tb)) = super::march::intersect_box(o, inv_d, lo, hi) else {
                return 1.0;
            };
            let k0 = ((ta - t0) / ds - 1.5).floor().max(0.0);
            let k1 = ((tb - t0) / ds + 1.0).ceil().min(n);
            (k0 as u32, k1 as u32)
        }
        None => (0, n as u32),
    };
    let mut tau = 0.0f32;
    for k in k0..k1 {
        let v = ctx.grid.sample(o + d * (t0 + (k as f32 + 0.5) * ds));
        if let Some(i) = Lut::index(v) {
            tau += ctx.lut.sigma(i);
        }
    }
    *interpolations += k1.saturating_sub(k0) as u64;
    (-tau * ds / ctx.unit).exp()
}
