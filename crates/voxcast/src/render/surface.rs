//! The opaque surface at the end of a ray (S0 Fig. 9–13): the ray's exit
//! from the volume is clamped to the first geometry hit, the smoke in front
//! is composited over the surface's lit colour. Optional shadows: the key
//! light reaching the surface is attenuated by the smoke along a shadow ray
//! (Beer–Lambert, `T = exp(−∫σ ds)`) and blocked by other shapes.

use super::ray::Frame;
use crate::geometry::packet::PACKET;
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
/// colours. `taus(marches, tau)` sums each shadow ray's extinction
/// ([`march_tau`] for each lane of `marches` that has one; the packets do
/// it in vector registers).
pub(super) fn first_hits<T: Voxel>(
    ctx: &Frame<'_, T>,
    s: &SurfaceCtx<'_>,
    rays: &[(Vec3, Vec3)],
    out: &mut [Option<(f32, Vec3)>],
    interpolations: &mut u64,
    taus: impl FnOnce(&[Option<ShadowMarch>; PACKET], &mut [f32; PACKET]),
) {
    const P: usize = PACKET;
    let mut hits = [None; P];
    let hits = &mut hits[..rays.len()];
    s.geometry.hit_packet(rays, hits);
    // Lane by lane: albedo, normal, direction (x, y, z) and the light.
    let (mut a, mut n, mut d) = ([[0.0; P]; 3], [[0.0; P]; 3], [[0.0; P]; 3]);
    let mut light = [1.0; P];
    let mut marches = [None; P];
    for (l, (&(o, dir), hit)) in rays.iter().zip(&*hits).enumerate() {
        let Some(h) = hit else { continue };
        for k in 0..3 {
            (a[k][l], n[k][l], d[k][l]) = (h.albedo[k], h.normal[k], dir[k]);
        }
        if s.shadows {
            match shadow_start(ctx, s, o, dir, h) {
                Err(lit) => light[l] = lit,
                Ok(p) => {
                    marches[l] = shadow_march(ctx, p, s.light.to_light);
                    *interpolations += marches[l].map_or(0, |m| m.lookups());
                }
            }
        }
    }
    if marches.iter().any(Option::is_some) {
        let mut tau = [0.0; P];
        taus(&marches, &mut tau);
        for ((m, tau), light) in marches.iter().zip(tau).zip(&mut light) {
            if let Some(m) = m {
                *light = m.light(tau, ctx.unit);
            }
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
    match shadow_start(ctx, s, origin, dir, hit) {
        Err(lit) => lit,
        Ok(p) => transmittance(ctx, p, s.light.to_light, interpolations),
    }
}

/// Where `hit`'s shadow ray starts (world), or, where it needs none, the
/// light the hit gets: 1 on a face turned from the light, 0 behind
/// another shape.
#[inline]
fn shadow_start<T: Voxel>(
    ctx: &Frame<'_, T>,
    s: &SurfaceCtx<'_>,
    origin: Vec3,
    dir: Vec3,
    hit: &Hit,
) -> Result<Vec3, f32> {
    let facing = if hit.normal.dot(dir) > 0.0 {
        -hit.normal
    } else {
        hit.normal
    };
    if facing.dot(s.light.to_light) <= 0.0 {
        return Err(1.0);
    }
    // Off the surface by a fraction of a voxel, so the shadow ray does not
    // find the surface it starts on.
    let p = origin + dir * hit.t + facing * (1e-3 * ctx.unit);
    if s.geometry.occluded(p, s.light.to_light, 0.0, f32::INFINITY) {
        Err(0.0)
    } else {
        Ok(p)
    }
}

/// The samples of a shadow ray through the volume: positions
/// `o + d·(t0 + (k + ½)·ds)` (voxel space) for `k0 ≤ k < k1`.
#[derive(Clone, Copy, Debug)]
pub(super) struct ShadowMarch {
    pub o: Vec3,
    pub d: Vec3,
    pub t0: f32,
    pub ds: f32,
    pub k0: u32,
    pub k1: u32,
}

impl ShadowMarch {
    /// The grid lookups it takes.
    pub fn lookups(&self) -> u64 {
        self.k1.saturating_sub(self.k0) as u64
    }

    /// The light it lets through, Beer–Lambert, from the sum `tau` of the
    /// extinction at its samples ([`march_tau`]; `unit`: the frame's unit
    /// length in voxels).
    pub fn light(&self, tau: f32, unit: f32) -> f32 {
        (-tau * self.ds / unit).exp()
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
    let Some(m) = shadow_march(ctx, p, l) else {
        return 1.0;
    };
    *interpolations += m.lookups();
    m.light(march_tau(ctx, &m), ctx.unit)
}

/// Where [`transmittance`] samples the ray from world point `p` along
/// unit `l`; `None` where it meets no block that is not empty.
#[inline]
pub(super) fn shadow_march<T: Voxel>(ctx: &Frame<'_, T>, p: Vec3, l: Vec3) -> Option<ShadowMarch> {
    let o = (p - ctx.origin_w) * ctx.inv_spacing;
    let d = l * ctx.inv_spacing;
    let inv_d = Vec3::ONE / d;
    let (t0, t1) = super::march::intersect_box(o, inv_d, ctx.box_lo, ctx.box_hi)?;
    let n = ((t1 - t0) / ctx.step).ceil().max(1.0);
    let ds = (t1 - t0) / n;
    // The samples `k0..k1` are those that can lie in the occupied box, with
    // a sample of margin each side (one taken in an empty block adds 0).
    let (k0, k1) = match ctx.occupied {
        Some((lo, hi)) => {
            let (ta, tb) = super::march::intersect_box(o, inv_d, lo, hi)?;
            let k0 = ((ta - t0) / ds - 1.5).floor().max(0.0);
            let k1 = ((tb - t0) / ds + 1.0).ceil().min(n);
            (k0 as u32, k1 as u32)
        }
        None => (0, n as u32),
    };
    Some(ShadowMarch {
        o,
        d,
        t0,
        ds,
        k0,
        k1,
    })
}

/// The sum of the extinction at a shadow ray's samples.
#[inline]
pub(super) fn march_tau<T: Voxel>(ctx: &Frame<'_, T>, m: &ShadowMarch) -> f32 {
    let mut tau = 0.0f32;
    for k in m.k0..m.k1 {
        let v = ctx
            .grid
            .sample(m.o + m.d * (m.t0 + (k as f32 + 0.5) * m.ds));
        if let Some(i) = Lut::index(v) {
            tau += ctx.lut.sigma(i);
        }
    }
    tau
}
