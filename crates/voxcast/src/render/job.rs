//! One render's job: the ray loop's three choices — compositor, shading,
//! marcher and reconstruction — picked once per render by a `match`, each
//! path instantiating one monomorphised loop (the SIMD packets where the
//! CPU has them, else the scalar tiles).

use super::composite::{self, BackToFront, FrontToBack, Weights};
use super::march::{self, BlockMax, Classified, Fixed, Level, Midpoint, Steps, Threshold};
use super::ray::{self, Frame, Marcher, Sampler};
use super::sample::{Flat, Grouped, Phong, Shade, Trilinear};
use super::shading::BlinnPhong;
use super::trace::{self, Tracer};
use super::{
    lod, octree, packet, stochastic, surface, tf_tables, tiles, Derived, Method, Order,
    RenderParams, RenderStats,
};
use crate::camera::Camera;
use crate::image::Image;
use crate::transfer::srgb_to_linear;
use crate::volume::{Grid, GridVisitor, Volume, Voxel};
use glam::Vec3;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

/// Premultiplied linear `c` over background `bg`: the pixel.
#[inline]
fn over_background(c: glam::Vec4, bg: Vec3) -> [f32; 4] {
    let rgb = c.truncate() + bg * (1.0 - c.w);
    [rgb.x, rgb.y, rgb.z, c.w]
}

/// What one render hands its ray loop: the volume's derived structures
/// for the render's block size, the transfer function's tables, the camera
/// and the parameters.
pub(super) struct Job<'a> {
    /// The renderer's z-paired copy for the packets, built by the first
    /// render that runs them.
    pub(super) z_pairs: &'a std::sync::OnceLock<packet::ZPairs>,
    pub(super) pdf: &'a [stochastic::PdfBlock],
    pub(super) volume: &'a Volume,
    pub(super) derived: &'a Derived,
    /// What the transfer function and step give (kept across renders):
    /// the table, the blocks' emptiness, the levels' tables.
    pub(super) tft: &'a tf_tables::TfTables,
    /// The adaptive methods' `k` per block: the largest derivative
    /// (`adaptive-max`) or the change of the classified signal
    /// (`adaptive`); empty for the others.
    pub(super) block_k: &'a [f32],
    pub(super) tree: Option<&'a octree::Octree>,
    pub(super) cam: Camera,
    pub(super) params: &'a RenderParams,
    pub(super) unit: f32,
    pub(super) progress: &'a (dyn Fn(usize, usize) + Sync),
    pub(super) cancel: &'a AtomicBool,
    pub(super) surface: Option<surface::SurfaceCtx<'a>>,
}

impl GridVisitor for Job<'_> {
    type Output = Option<(Image, RenderStats)>;
    fn visit<T: Voxel>(self, grid: &Grid<'_, T>) -> Self::Output {
        self.run(grid)
    }
}

/// The tables a render derives from the transfer function for its marcher.
struct Tables {
    /// Adaptive levels `level_lo..=level_hi`: step (world), and the
    /// premultiplied tables of their steps one after the other.
    level_lo: i32,
    level_hi: i32,
    level_steps: Vec<f32>,
    level_tables: Arc<Vec<[f32; 4]>>,
}

impl Tables {
    /// A step-per-block marcher with level rule `rule` over these tables.
    fn steps<L>(&self, rule: L, k_ref: f32) -> Steps<'_, L> {
        Steps {
            rule,
            level_lo: self.level_lo,
            level_hi: self.level_hi,
            k_ref,
            level_steps: &self.level_steps,
            level_tables: &self.level_tables,
        }
    }
}

impl Job<'_> {
    /// Picks the ray loop's three choices once per render — compositor,
    /// shading, marcher, reconstruction, in that order — and runs the one
    /// monomorphised loop they make.
    fn run<T: Voxel>(&self, grid: &Grid<'_, T>) -> Option<(Image, RenderStats)> {
        let p = self.params;
        let (box_lo, box_hi) = self.volume.sample_box();
        let skip_empty = p.skip_empty && self.tft.skipping_pays();
        let frame = Frame {
            grid,
            lut: &self.tft.lut,
            box_lo,
            box_hi,
            origin_w: self.volume.origin(),
            inv_spacing: Vec3::ONE / self.volume.spacing(),
            step: p.step * self.unit,
            unit: self.unit,
            skip_empty,
            block_size: self.derived.blocks.size,
            block_counts: self.derived.blocks.counts,
            empty: &self.tft.empty,
            occupied: skip_empty.then(|| self.tft.occupied(&self.derived.blocks, box_lo, box_hi)),
            seed: p.seed,
        };
        let out = match p.order {
            Order::FrontToBack => self.shaded::<T, FrontToBack>(&frame),
            Order::BackToFront => self.shaded::<T, BackToFront>(&frame),
        };
        let left_out = (p.skip_empty && !skip_empty).then_some(self.tft.empty_share);
        out.map(|(image, stats)| {
            let stats = RenderStats {
                skipping_left_out: left_out,
                block_size: self.derived.blocks.size as u32,
                ..stats
            };
            (image, stats)
        })
    }

    fn shaded<T: Voxel, C: composite::Order>(
        &self,
        f: &Frame<'_, T>,
    ) -> Option<(Image, RenderStats)> {
        if self.params.shading {
            self.marched::<T, C, Phong>(f, Phong(BlinnPhong::default()))
        } else {
            self.marched::<T, C, Flat>(f, Flat)
        }
    }

    fn marched<T: Voxel, C: composite::Order, Sh: Shade>(
        &self,
        f: &Frame<'_, T>,
        sh: Sh,
    ) -> Option<(Image, RenderStats)> {
        let p = self.params;
        let (level_lo, level_hi) = if p.has_levels() {
            p.adaptive.levels(p.step)
        } else {
            (0, 0)
        };
        let levels: Vec<f32> = (level_lo..=level_hi)
            .map(|j| p.step * 2f32.powi(j))
            .collect();
        let t = Tables {
            level_lo,
            level_hi,
            level_steps: levels.iter().map(|s| s * self.unit).collect(),
            level_tables: self.tft.levels(&levels),
        };
        let k = p.adaptive_k_ref();
        match p.method {
            Method::Uniform | Method::Jitter if !p.grouped => {
                match self.packets::<T, ()>(f, &t, None, None, None, None) {
                    Some(out) => out,
                    None => self.grouped::<T, C, Sh, _>(f, sh, &t.steps(Fixed, k)),
                }
            }
            Method::Uniform | Method::Jitter => {
                self.stepped::<T, C, Sh, _>(f, sh, &t, &t.steps(Fixed, k))
            }
            Method::Adaptive => {
                self.stepped::<T, C, Sh, _>(f, sh, &t, &t.steps(Classified(self.block_k), k))
            }
            Method::AdaptiveS0 => self.stepped::<T, C, Sh, _>(f, sh, &t, &t.steps(Midpoint, k)),
            Method::AdaptiveMax => {
                self.stepped::<T, C, Sh, _>(f, sh, &t, &t.steps(BlockMax(self.block_k), k))
            }
            Method::Threshold => {
                // In SIMD packets where the CPU and the render allow: the
                // ranges' premultiplied tables, one after the other.
                let tables = self.tft.levels(&p.threshold.steps);
                let thr = packet::Thr {
                    select: packet::Select::Range(p.threshold),
                    steps: p.threshold.steps.map(|s| s * self.unit),
                    tables: &tables,
                    sigma: self.tft.lut.sigmas(),
                    grouped: p.grouped,
                };
                if let Some(out) = self.packets::<T, ()>(f, &t, None, None, Some(thr), None) {
                    return out;
                }
                let alphas: Vec<_> = p
                    .threshold
                    .steps
                    .iter()
                    .map(|&r| self.tft.lut.alphas(r))
                    .collect();
                let m = Threshold {
                    params: p.threshold,
                    steps: p.threshold.steps.map(|s| s * self.unit),
                    alphas: &alphas,
                };
                self.grouped::<T, C, Sh, _>(f, sh, &m)
            }
            Method::Stratified | Method::Mc => {
                // In SIMD packets where the CPU and the render allow (one
                // loop for both).
                let mc = p.method == Method::Mc;
                let strat = packet::Strat {
                    sigma: self.tft.lut.sigmas(),
                    mc,
                };
                if let Some(out) = self.packets::<T, ()>(f, &t, None, None, None, Some(strat)) {
                    return out;
                }
                if mc {
                    return self.tiles::<T, C, _, _>(f, &stochastic::UniformMc, Trilinear(sh));
                }
                let full_alphas = self.tft.lut.alphas(p.step);
                let m = stochastic::Stratified {
                    full_alphas: &full_alphas,
                };
                self.tiles::<T, C, _, _>(f, &m, Trilinear(sh))
            }
            Method::Importance => {
                // The spacing and step opacities of its pdf's levels.
                let (steps, alphas): (Vec<f32>, Vec<_>) = (0..=stochastic::MAX_LEVEL)
                    .map(|j| {
                        let r = p.step * (1u32 << j) as f32;
                        (r * self.unit, self.tft.lut.alphas(r))
                    })
                    .unzip();
                // In SIMD packets where the CPU and the render allow: the
                // levels' premultiplied tables, one after the other.
                let ratios: Vec<f32> = (0..=stochastic::MAX_LEVEL)
                    .map(|j| p.step * (1u32 << j) as f32)
                    .collect();
                let tables = self.tft.levels(&ratios);
                let imp = packet::Imp {
                    pdf: self.pdf,
                    steps: &steps,
                    tables: &tables,
                };
                if let Some(out) = self.packets::<T, ()>(f, &t, Some(imp), None, None, None) {
                    return out;
                }
                let m = stochastic::Importance {
                    pdf: self.pdf,
                    steps: &steps,
                    alphas: &alphas,
                };
                self.tiles::<T, C, _, _>(f, &m, Trilinear(sh))
            }
            Method::Lod => {
                let tree = self.tree.expect("the octree is built for lod");
                let m = self.tft.lod(tree, &p.lod, self.unit);
                if let Some(out) = self.lod_packets(f, &t, &m) {
                    return out;
                }
                self.tiles::<T, C, _, _>(f, &*m, Trilinear(sh))
            }
            // Rendered by `path::render` before a Job is made.
            Method::SingleScatter | Method::Path => None,
        }
    }

    /// The seed of the per-pixel start jitter (`jitter`, or `--jitter`).
    fn jitter_seed(&self) -> Option<u64> {
        let p = self.params;
        (p.jitter || p.method == Method::Jitter).then_some(p.seed)
    }

    /// Passes per pixel: deterministic methods give the same image every
    /// pass.
    fn passes(&self) -> u32 {
        let p = self.params;
        if p.method.is_stochastic() || p.jitter {
            p.spp
        } else {
            1
        }
    }

    /// The background, linear.
    fn background(&self) -> Vec3 {
        Vec3::from(self.params.background.map(srgb_to_linear))
    }

    /// A step-per-block march (`uniform` grouped, the `adaptive` family):
    /// in the SIMD packets where the CPU and the render allow, else the
    /// scalar loop.
    fn stepped<T: Voxel, C: composite::Order, Sh: Shade, L: Level>(
        &self,
        f: &Frame<'_, T>,
        sh: Sh,
        t: &Tables,
        m: &Steps<'_, L>,
    ) -> Option<(Image, RenderStats)> {
        if packet::level(self.params.simd).is_some() {
            // Per block the rule's `k`, −1 where empty (the vector walk's
            // one gather per block); none for a rule it cannot walk.
            let k: Vec<f32> = match m.rule.vector() {
                march::VRule::Scalar => Vec::new(),
                rule => {
                    let k = match rule {
                        march::VRule::Max(k) | march::VRule::Classified(k) => k,
                        _ => &[],
                    };
                    let k_of = |(b, &e): (usize, &bool)| match e {
                        true => -1.0,
                        false => k.get(b).copied().unwrap_or(0.0),
                    };
                    f.empty.iter().enumerate().map(k_of).collect()
                }
            };
            let grouped = self.params.grouped;
            let walk =
                |f: &Frame<'_, T>,
                 w: &mut march::RunWalk,
                 c: &mut composite::Front,
                 n: &mut ray::Counters| { w.next(m, f, grouped, c, n) };
            let runs = packet::Adapt {
                level_steps: m.level_steps,
                tables: &t.level_tables,
                grouped,
                walk: &walk,
                vector: packet::vector_params(m, &k, f.skip_empty, grouped),
            };
            if let Some(out) = self.packets(f, t, None, Some(&runs), None, None) {
                return out;
            }
        }
        self.grouped::<T, C, Sh, _>(f, sh, m)
    }

    /// `lod` in the SIMD packets (`threshold`'s loop, the step picked by
    /// the sample's class) where the CPU and the render allow.
    fn lod_packets<T: Voxel>(
        &self,
        f: &Frame<'_, T>,
        t: &Tables,
        m: &lod::LodRay,
    ) -> Option<Option<(Image, RenderStats)>> {
        packet::level(self.params.simd)?;
        let tables = self.tft.levels(&m.ratios);
        let thr = packet::Thr {
            select: packet::Select::Lod(packet::LodSelect {
                amount: &m.amount,
                counts: m.counts,
                inv_leaf: m.inv_leaf,
                threshold: m.threshold,
                front: self.params.order == Order::FrontToBack,
            }),
            steps: m.steps,
            tables: &tables,
            sigma: self.tft.lut.sigmas(),
            grouped: false,
        };
        self.packets::<T, ()>(f, t, None, None, Some(thr), None)
    }

    /// A render through the SIMD ray packets (packet/) — a fixed step,
    /// `importance` (`imp`), a step-per-block march (`runs`), `threshold`
    /// (`thr`) or `stratified` (`strat`) — where the CPU and the render
    /// allow; `None` where the scalar loop must run.
    fn packets<T: Voxel, R: packet::Runs<T>>(
        &self,
        f: &Frame<'_, T>,
        t: &Tables,
        imp: Option<packet::Imp<'_>>,
        runs: Option<&R>,
        thr: Option<packet::Thr<'_>>,
        strat: Option<packet::Strat<'_>>,
    ) -> Option<Option<(Image, RenderStats)>> {
        let p = self.params;
        // The shading `shaded` picks.
        let shading = p.shading.then(BlinnPhong::default);
        let level = packet::level(p.simd)?;
        // Back to front is summed front to back with early termination
        // off: the same samples and, the over operator being associative,
        // the same sum to a float rounding (as on the GPU); the scalar loop
        // keeps S4's recurrence over the buffered samples. (`lod` then
        // classes its samples with no opacity in front, as that loop does:
        // `LodSelect::front`.)
        let back = p.order == Order::BackToFront;
        if (p.grouped && runs.is_none() && thr.is_none())
            || shading.is_some_and(|bp| !packet::shades(&bp))
            || !packet::fits(f.grid)
        {
            return None;
        }
        let z_pairs = self
            .z_pairs
            .get_or_init(|| packet::ZPairs::of(self.volume.data(), self.volume.dims()));
        // `importance` skips nothing (its pdf has no mass in empty blocks);
        // a step-per-block march skips in its walk.
        let empty = (f.skip_empty && imp.is_none() && runs.is_none())
            .then(|| self.derived.skip_distances(f.empty));
        let pk = packet::Packets {
            f,
            q: t.level_tables.first_chunk().expect("a table per level"),
            st: t.level_steps[0],
            weights: Weights::of(p.optical),
            stop: composite::ert_stop(if back { 1.0 } else { p.ert }),
            jitter: self.jitter_seed(),
            empty: empty.as_ref().map(|e| e.as_slice()),
            shading,
            z_pairs,
            level,
            imp,
            runs,
            thr,
            strat,
            surface: self.surface,
        };
        let (passes, bg) = (self.passes(), self.background());
        // A packet is a square of 4×4 pixels (of a 16×16 tile): its rays
        // stay closer together than a row's, so their lengths and the
        // voxels they fetch differ less.
        const SIDE: u32 = 4;
        const _: () = assert!((SIDE * SIDE) as usize == packet::LANES);
        let out = tiles::render_whole_tiles(
            p.width,
            p.height,
            self.progress,
            self.cancel,
            || (),
            |_, stats, (tx, ty, tw), px| {
                let th = px.len() as u32 / tw;
                for by in (0..th).step_by(SIDE as usize) {
                    for bx in (0..tw).step_by(SIDE as usize) {
                        let mut pixels = [(0u32, 0u32); packet::LANES];
                        let mut n = 0;
                        for y in by..(by + SIDE).min(th) {
                            for x in bx..(bx + SIDE).min(tw) {
                                pixels[n] = (tx + x, ty + y);
                                n += 1;
                            }
                        }
                        let mut rays = [(Vec3::ZERO, Vec3::ZERO); packet::LANES];
                        #[cfg(packets)]
                        pk.camera_rays(&self.cam, &pixels[..n], &mut rays[..n]);
                        #[cfg(not(packets))]
                        for (r, &(x, y)) in rays[..n].iter_mut().zip(&pixels[..n]) {
                            *r = self.cam.ray(x, y);
                        }
                        let mut acc = [glam::Vec4::ZERO; packet::LANES];
                        for pass in 0..passes {
                            pk.render(&rays[..n], &pixels[..n], pass, &mut acc[..n], stats);
                        }
                        for (&(x, y), c) in pixels[..n].iter().zip(acc) {
                            let i = ((y - ty) * tw + (x - tx)) as usize;
                            px[i] = over_background(c / passes as f32, bg);
                        }
                    }
                }
            },
            |_, _| {},
        );
        // The stats say the packets ran, and at which level.
        Some(out.map(|(img, st)| {
            (
                img,
                RenderStats {
                    simd: Some(level),
                    ..st
                },
            )
        }))
    }

    /// S0's grouped interpolation, for the marchers it applies to.
    fn grouped<T: Voxel, C: composite::Order, Sh: Shade, M: Marcher<T>>(
        &self,
        f: &Frame<'_, T>,
        sh: Sh,
        m: &M,
    ) -> Option<(Image, RenderStats)> {
        if self.params.grouped {
            self.tiles::<T, C, _, _>(f, m, Grouped::new(sh))
        } else {
            self.tiles::<T, C, _, _>(f, m, Trilinear(sh))
        }
    }

    /// Renders the tiles with one monomorphised ray loop.
    fn tiles<T: Voxel, C: composite::Order, M: Marcher<T>, S: Sampler<T>>(
        &self,
        f: &Frame<'_, T>,
        m: &M,
        sampler: S,
    ) -> Option<(Image, RenderStats)> {
        let p = self.params;
        let tr = Tracer {
            marcher: m,
            sampler,
            weights: Weights::of(p.optical),
            ert: p.ert,
            jitter: self.jitter_seed(),
            surface: self.surface,
        };
        let (passes, bg) = (self.passes(), self.background());
        tiles::render_tiles(
            p.width,
            p.height,
            self.progress,
            self.cancel,
            Vec::<(Vec3, f32)>::new,
            |scratch, stats, x, y| {
                let (o, d) = self.cam.ray(x, y);
                let mut c = glam::Vec4::ZERO;
                for pass in 0..passes {
                    c += trace::trace::<T, M, S, C>(f, &tr, (o, d), (x, y), pass, stats, scratch);
                }
                // Progressive average of premultiplied colour (linear).
                over_background(c / passes as f32, bg)
            },
            |_, _| {},
        )
    }
}
