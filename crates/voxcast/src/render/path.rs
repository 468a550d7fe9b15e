//! The physically based integrators: optical model 4, single scattering
//! with shadows (`single-scatter`), and optical model 5, volumetric path
//! tracing (`path`) — S4's last two optical models, computed as pbrt-v4's
//! `VolPathIntegrator` does for a medium without emission:
//!
//! * free paths by **delta tracking** (Woodcock): tentative collisions at
//!   the majorant rate, accepted as real with probability `σ_t/σ_maj`;
//! * absorption as a weight: each real collision multiplies the throughput
//!   by the albedo `σ_s/σ_t`;
//! * **next-event estimation** to every delta light (directional, point):
//!   `albedo × phase × light × T`, the transmittance `T` to the light by
//!   **ratio tracking** (Cramer 1978; Novák et al. 2014), an unbiased
//!   estimate that never returns 0 early except by Russian roulette;
//! * infinite lights (environment, sky) are reached by the phase-sampled
//!   continuation leaving the medium (sampling is exact, so the weight
//!   `p/pdf` is 1); `single-scatter` follows that direction with one
//!   ratio-tracked shadow ray instead of continuing the path;
//! * **Russian roulette** on the throughput after 3 bounces;
//! * both trackers draw their tentative collisions from a [`Majorant`]:
//!   per-block maxima walked by DDA, or one global maximum.
//!
//! Camera rays that leave the medium see the infinite lights (the
//! environment is the background). Output is linear radiance.

use super::light::{environment, Light};
use super::majorant::Majorant;
use super::march::intersect_box;
use super::medium::MediumParams;
use super::phase::{Phase, PhaseVisitor};
use super::rng::Rng;
use super::stats::RenderStats;
use super::{BlockGrid, RenderParams};
use crate::camera::Camera;
use crate::image::Image;
use crate::volume::{Grid, GridVisitor, Volume, Voxel};
use glam::Vec3;

/// The medium as the trackers see it: world ↔ voxel mapping, density grid,
/// majorant. Shared by both integrators and by the tests.
pub(super) struct MediumCtx<'a, T> {
    pub grid: &'a Grid<'a, T>,
    pub majorant: &'a Majorant,
    /// Voxel coordinates of world point p: `(p − offset) · scale_v`.
    pub offset: Vec3,
    pub scale_v: Vec3,
    /// The grid's box in voxel coordinates.
    pub box_lo: Vec3,
    pub box_hi: Vec3,
    /// Extinction at density 1 (world units⁻¹).
    pub sigma_scale: f32,
}

// Manual impls: only references to T are held.
impl<T> Clone for MediumCtx<'_, T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T> Copy for MediumCtx<'_, T> {}

/// Tentative collisions one path may take in all, its camera ray, bounces
/// and shadow rays together. A path that needs more (an extinction far
/// past [`super::medium::MAX_OPTICAL_DEPTH`]'s spirit, in a thin part of a
/// block with a dense corner) ends there, as if absorbed, and is counted
/// in [`RenderStats::capped_paths`]: a bound on time, not a hang.
pub const MAX_PATH_COLLISIONS: u64 = 1 << 20;

/// Per-tile work counts, and the current path's budget.
pub(super) struct Work {
    /// Tentative collisions (majorant events).
    pub tentative: u64,
    /// Density lookups (trilinear interpolations).
    pub lookups: u64,
    /// Tentative collisions the current path may still take.
    pub budget: u64,
    /// Paths ended by the budget.
    pub capped: u64,
}

impl Default for Work {
    fn default() -> Work {
        Work {
            tentative: 0,
            lookups: 0,
            budget: MAX_PATH_COLLISIONS,
            capped: 0,
        }
    }
}

impl Work {
    /// Charges `n` collisions to the path; true when its budget is spent.
    #[inline(always)]
    fn charge(&mut self, n: u64) -> bool {
        self.tentative += n;
        self.budget = self.budget.saturating_sub(n);
        self.budget == 0
    }
}

impl<T: Voxel> MediumCtx<'_, T> {
    /// The ray in voxel coordinates and its `[t_in, t_out]` in the box.
    #[inline(always)]
    fn enter(&self, o: Vec3, d: Vec3, t_max: f32) -> Option<(Vec3, Vec3, f32, f32)> {
        let ov = (o - self.offset) * self.scale_v;
        let dv = d * self.scale_v;
        let (a, b) = intersect_box(ov, Vec3::ONE / dv, self.box_lo, self.box_hi)?;
        let b = b.min(t_max);
        (b > a).then_some((ov, dv, a, b))
    }

    /// `σ_t` at voxel position `p`.
    #[inline(always)]
    fn sigma_t(&self, p: Vec3, w: &mut Work) -> f32 {
        w.lookups += 1;
        self.sigma_scale * self.grid.sample(p).clamp(0.0, 1.0)
    }

    /// Delta tracking: the distance to the next real collision on the world
    /// ray `o + d·t`, or `None` when the ray leaves the medium.
    #[inline(always)]
    pub fn delta_track(&self, o: Vec3, d: Vec3, rng: &mut Rng, w: &mut Work) -> Option<f32> {
        let (ov, dv, a, b) = self.enter(o, d, f32::INFINITY)?;
        let mut hit = None;
        let mut tentative = 0;
        let budget = w.budget;
        self.majorant.walk(
            ov,
            dv,
            a,
            b,
            rng,
            &mut tentative,
            budget,
            |t, s_maj, rng| {
                let s = self.sigma_t(ov + dv * t, w);
                if rng.uniform() * s_maj < s {
                    hit = Some(t);
                    true
                } else {
                    false
                }
            },
        );
        w.charge(tentative);
        hit
    }

    /// Ratio tracking: an unbiased estimate of the transmittance along
    /// `o + d·t` for `t` in `[0, t_max]`. The product `Π (1 − σ_t/σ_maj)`
    /// over tentative collisions; once it falls below 0.1 it is continued
    /// with probability 1/2 (Russian roulette, doubling it) or set to 0.
    #[inline(always)]
    pub fn ratio_track(&self, o: Vec3, d: Vec3, t_max: f32, rng: &mut Rng, w: &mut Work) -> f32 {
        let Some((ov, dv, a, b)) = self.enter(o, d, t_max) else {
            return 1.0;
        };
        let mut tr = 1.0f32;
        let mut tentative = 0;
        let budget = w.budget;
        self.majorant.walk(
            ov,
            dv,
            a,
            b,
            rng,
            &mut tentative,
            budget,
            |t, s_maj, rng| {
                let s = self.sigma_t(ov + dv * t, w);
                tr *= 1.0 - s / s_maj;
                if tr < 0.1 {
                    if rng.uniform() < 0.5 {
                        tr = 0.0;
                        return true;
                    }
                    tr *= 2.0;
                }
                false
            },
        );
        if w.charge(tentative) {
            // Out of budget: the rest of the segment is taken as opaque.
            return 0.0;
        }
        tr
    }
}

/// Everything an integrator needs besides the medium.
struct Integrator<'a, P> {
    phase: P,
    albedo: Vec3,
    lights: &'a [Light],
    has_infinite: bool,
    max_depth: u32,
    single: bool,
}

impl<P: Phase> Integrator<'_, P> {
    /// Radiance arriving at the camera along `d` from `o`.
    #[inline]
    fn li<T: Voxel>(
        &self,
        m: &MediumCtx<'_, T>,
        mut o: Vec3,
        mut d: Vec3,
        rng: &mut Rng,
        w: &mut Work,
    ) -> Vec3 {
        let mut l = Vec3::ZERO;
        let mut beta = Vec3::ONE;
        w.budget = MAX_PATH_COLLISIONS;
        for depth in 0..self.max_depth {
            let track = m.delta_track(o, d, rng, w);
            if w.budget == 0 {
                w.capped += 1;
                return l;
            }
            let Some(t) = track else {
                // Left the medium: what the infinite lights send along d.
                return l + beta * environment(self.lights, d);
            };
            let p = o + d * t;
            beta *= self.albedo;
            // Next-event estimation to each delta light.
            for light in self.lights {
                if let Some(inc) = light.incident(p) {
                    let ph = self.phase.eval(d.dot(inc.dir));
                    if ph > 0.0 && inc.li.max_element() > 0.0 {
                        let tr = m.ratio_track(p, inc.dir, inc.dist, rng, w);
                        l += beta * inc.li * (ph * tr);
                    }
                }
            }
            let (nd, pdf) = self.phase.sample(d, rng);
            let weight = if pdf > 0.0 {
                self.phase.eval(d.dot(nd)) / pdf
            } else {
                0.0
            };
            if self.single {
                // Model 4: the infinite lights by one phase-sampled shadow ray.
                if self.has_infinite {
                    let tr = m.ratio_track(p, nd, f32::INFINITY, rng, w);
                    l += beta * environment(self.lights, nd) * (weight * tr);
                }
                return l;
            }
            beta *= weight;
            o = p;
            d = nd;
            if depth >= 3 {
                let q = beta.max_element().min(1.0);
                if q < 1.0 {
                    if rng.uniform() >= q {
                        return l;
                    }
                    beta /= q;
                }
            }
        }
        l
    }
}

/// Renders `single-scatter` or `path` (see the module docs).
pub(super) fn render(
    volume: &Volume,
    window: [f32; 2],
    blocks: &BlockGrid,
    cam: Camera,
    params: &RenderParams,
    progress: &(dyn Fn(usize, usize) + Sync),
    cancel: &std::sync::atomic::AtomicBool,
) -> Option<(Image, RenderStats)> {
    let medium = &params.medium;
    let majorant = Majorant::new(blocks, medium.scale, medium.majorant);
    let lights = params.lights_or_default();
    let lights: &[Light] = &lights;
    let job = Job {
        volume,
        majorant: &majorant,
        medium,
        lights,
        cam,
        params,
        progress,
        cancel,
    };
    volume.visit(window[0], window[1], job)
}

struct Job<'a> {
    volume: &'a Volume,
    majorant: &'a Majorant,
    medium: &'a MediumParams,
    lights: &'a [Light],
    cam: Camera,
    params: &'a RenderParams,
    progress: &'a (dyn Fn(usize, usize) + Sync),
    cancel: &'a std::sync::atomic::AtomicBool,
}

impl GridVisitor for Job<'_> {
    type Output = Option<(Image, RenderStats)>;
    fn visit<T: Voxel>(self, grid: &Grid<'_, T>) -> Self::Output {
        let phase = self.medium.phase;
        phase.visit(WithGrid { job: self, grid })
    }
}

struct WithGrid<'a, 'g, T> {
    job: Job<'a>,
    grid: &'a Grid<'g, T>,
}

impl<T: Voxel> PhaseVisitor for WithGrid<'_, '_, T> {
    type Output = Option<(Image, RenderStats)>;
    fn visit<P: Phase>(self, phase: P) -> Self::Output {
        let job = &self.job;
        let dims = job.volume.dims();
        let hi = Vec3::new(
            dims[0].saturating_sub(1).max(1) as f32,
            dims[1].saturating_sub(1).max(1) as f32,
            dims[2].saturating_sub(1).max(1) as f32,
        );
        let (offset, scale_v) = match job.medium.r#box {
            Some([lo, bhi]) => (Vec3::from(lo), hi / (Vec3::from(bhi) - Vec3::from(lo))),
            None => (job.volume.origin(), Vec3::ONE / job.volume.spacing()),
        };
        let m = MediumCtx {
            grid: self.grid,
            majorant: job.majorant,
            offset,
            scale_v,
            box_lo: Vec3::ZERO,
            box_hi: hi,
            sigma_scale: job.medium.scale,
        };
        let integ = Integrator {
            phase,
            albedo: Vec3::from(job.medium.albedo),
            lights: job.lights,
            has_infinite: job.lights.iter().any(|l| !l.is_delta()),
            max_depth: job.medium.max_depth,
            single: job.params.method == super::Method::SingleScatter,
        };
        let p = job.params;
        super::tiles::render_tiles(
            p.width,
            p.height,
            job.progress,
            job.cancel,
            Work::default,
            |work, stats, x, y| {
                let mut sum = Vec3::ZERO;
                for pass in 0..p.spp {
                    let mut rng = Rng::for_pixel(p.seed, x, y, pass);
                    // A random position in the pixel (box filter).
                    let (o, d) = job
                        .cam
                        .ray_at(x as f32 + rng.uniform(), y as f32 + rng.uniform());
                    // Camera rays that meet the medium's box (as the ray
                    // caster counts its rays that meet the volume's).
                    stats.rays_hit += m.enter(o, d, f32::INFINITY).is_some() as u64;
                    sum += integ.li(&m, o, d, &mut rng, work);
                }
                stats.rays += p.spp as u64;
                let c = sum / p.spp as f32;
                [c.x, c.y, c.z, 1.0]
            },
            |work, stats| {
                stats.samples = work.tentative;
                stats.interpolations = work.lookups;
                stats.capped_paths = work.capped;
            },
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::blocks::BuildBlocks;
    use crate::render::medium::MajorantKind;

    /// A 33×5×5 medium whose density varies along x as `0.5 + 0.45·sin(0.7·i)`;
    /// along a ray through voxel centres, trilinear interpolation is linear
    /// between them, so the optical depth is the trapezoid sum exactly.
    fn medium_volume() -> (Volume, Vec<f32>) {
        let f = |i: usize| 0.5 + 0.45 * (0.7 * i as f32).sin();
        let vol = Volume::from_fn([33, 5, 5], Vec3::ONE, |i, _, _| f(i)).unwrap();
        (vol, (0..33).map(f).collect())
    }

    struct Estimate {
        kind: MajorantKind,
        delta: bool,
        n: usize,
    }
    impl GridVisitor for Estimate {
        type Output = (f64, f64);
        /// Mean and standard error of the transmittance estimates along x.
        fn visit<T: Voxel>(self, grid: &Grid<'_, T>) -> (f64, f64) {
            let blocks = BuildBlocks { size: 4 }.visit(grid);
            let majorant = Majorant::new(&blocks, 0.15, self.kind);
            let m = MediumCtx {
                grid,
                majorant: &majorant,
                offset: Vec3::ZERO,
                scale_v: Vec3::ONE,
                box_lo: Vec3::ZERO,
                box_hi: Vec3::new(32.0, 4.0, 4.0),
                sigma_scale: 0.15,
            };
            let mut rng = Rng::new(9, if self.delta { 1 } else { 2 });
            let mut w = Work::default();
            let o = Vec3::new(-3.0, 2.0, 2.0);
            let (mut s, mut s2) = (0.0f64, 0.0f64);
            for _ in 0..self.n {
                let x = if self.delta {
                    m.delta_track(o, Vec3::X, &mut rng, &mut w).is_none() as u8 as f64
                } else {
                    m.ratio_track(o, Vec3::X, f32::INFINITY, &mut rng, &mut w) as f64
                };
                s += x;
                s2 += x * x;
            }
            let n = self.n as f64;
            let mean = s / n;
            (mean, ((s2 / n - mean * mean) / n).sqrt())
        }
    }

    #[test]
    fn tracking_transmittance_matches_quadrature() {
        let (vol, f) = medium_volume();
        let depth: f64 = f
            .windows(2)
            .map(|w| 0.5 * (w[0] + w[1]) as f64)
            .sum::<f64>()
            * 0.15;
        let exact = (-depth).exp();
        assert!(
            exact > 0.05 && exact < 0.5,
            "a test that can tell: T = {exact}"
        );
        for kind in [MajorantKind::Grid, MajorantKind::Global] {
            for delta in [true, false] {
                let (mean, se) = vol.visit(
                    0.0,
                    1.0,
                    Estimate {
                        kind,
                        delta,
                        n: 40_000,
                    },
                );
                assert!(
                    (mean - exact).abs() < 3.0 * se,
                    "{kind:?} delta={delta}: {mean} ± {se} vs {exact}"
                );
                // Ratio tracking has less variance than the 0/1 of delta tracking.
                if !delta {
                    assert!(se < (exact * (1.0 - exact) / 40_000.0).sqrt());
                }
            }
        }
    }

    #[test]
    fn grid_majorant_bounds_the_density_and_is_tighter() {
        let (vol, _) = medium_volume();
        let blocks = vol.visit(0.0, 1.0, BuildBlocks { size: 4 });
        let m = Majorant::new(&blocks, 2.0, MajorantKind::Grid);
        assert!(m.sigma.iter().all(|&s| s <= m.global + 1e-6));
        assert!(m.sigma.iter().any(|&s| s < 0.9 * m.global));
    }
}
