//! The CPU renderer: the image is cut into tiles, rayon renders the tiles in
//! parallel, each pixel runs one ray loop. The loop is generic over the voxel
//! type and the optical model, so the per-sample path has no dynamic
//! dispatch, no allocation and no locks.

pub mod blocks;
mod composite;
pub mod light;
pub mod lod;
pub mod majorant;
pub mod march;
pub mod medium;
pub mod octree;
pub mod optics;
pub mod outofcore;
mod packet;
mod params;
mod path;
pub mod phase;
mod ray;
pub mod rng;
mod sample;
pub mod shading;
pub mod sortlast;
pub mod stats;
mod stochastic;
mod surface;
mod tf_tables;
mod tiles;
mod trace;

pub use blocks::BlockGrid;
pub use optics::OpticalModel;
pub use packet::{level as simd_level, Level as SimdLevel};
pub use params::{Backend, Method, MethodSpec, Order, RenderParams, Simd};
pub use stats::RenderStats;

use crate::camera::{Camera, CameraParams};
use crate::error::{Error, Result};
use crate::image::Image;
use crate::transfer::{srgb_to_linear, Lut, TransferFunction};
use crate::volume::{Grid, GridVisitor, Volume, Voxel};
use composite::{BackToFront, FrontToBack, Weights};
use glam::Vec3;
pub use march::{AdaptiveParams, ThresholdParams};
use march::{BlockMax, Classified, Fixed, Level, Midpoint, Steps, Threshold};
use ray::{Frame, Marcher, Sampler};
use sample::{Flat, Grouped, Phong, Shade, Trilinear};
use shading::BlinnPhong;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Instant;
use trace::Tracer;

/// Renders `volume` with `tf` over the data window `window`, seen by
/// `camera`. `progress(done, total)` is called after each tile. For repeated
/// renders of one volume, make a [`Renderer`] once instead.
pub fn render(
    volume: &Volume,
    tf: &TransferFunction,
    window: [f32; 2],
    camera: &CameraParams,
    params: &RenderParams,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<(Image, RenderStats)> {
    Renderer::new(volume, window)?.render(tf, camera, params, progress)
}

/// A volume ready for rendering over one data window: the derived
/// structures (the block grid) are built once and reused by every render.
pub struct Renderer<'v> {
    volume: &'v Volume,
    window: [f32; 2],
    /// Derived structures per block size, built on first use.
    derived: std::sync::Mutex<Vec<(usize, Arc<Derived>)>>,
    /// Opaque geometry rays stop at.
    geometry: Option<Arc<crate::geometry::Geometry>>,
    /// The SIMD packets' z-paired copy of the volume
    /// ([`packet::ZPairs`]), built on the first render that uses it.
    z_pairs: std::sync::OnceLock<packet::ZPairs>,
}

/// What a block size derives from the volume: the block grid, and the
/// per-block maximum derivative for `adaptive-max` (built on first use).
struct Derived {
    blocks: BlockGrid,
    max_gradient: std::sync::OnceLock<Vec<f32>>,
    /// The S3 octree over the blocks (for `lod`, built on first use).
    octree: std::sync::OnceLock<octree::Octree>,
    /// The `importance` pdf of the last transfer function it was asked for.
    pdf: std::sync::Mutex<Option<(TransferFunction, Arc<Vec<stochastic::PdfBlock>>)>>,
    /// The packets' skip distances ([`packet::skip_distances`]) of the
    /// last emptiness they were asked for.
    skip: std::sync::Mutex<Option<SkipCache>>,
    /// The tables of the last transfer functions and steps rendered
    /// ([`tf_tables::TfTables`]).
    tf_tables: std::sync::Mutex<Vec<Arc<tf_tables::TfTables>>>,
}

/// Block emptiness and the skip distances it gives.
type SkipCache = (Vec<bool>, Arc<Vec<i32>>);

impl Derived {
    /// The skip distances of the blocks under `empty` (built once per
    /// emptiness, so once per transfer function).
    fn skip_distances(&self, empty: &[bool]) -> Arc<Vec<i32>> {
        let mut cache = self.skip.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((e, d)) = cache.as_ref() {
            if e == empty {
                return d.clone();
            }
        }
        let d = Arc::new(packet::skip_distances(|i| empty[i], self.blocks.counts));
        *cache = Some((empty.to_vec(), d.clone()));
        d
    }

    /// The `importance` pdf per block for `tf` (built once per transfer
    /// function: it reads every voxel for the blocks' mean extinction).
    fn pdf(
        &self,
        volume: &Volume,
        window: [f32; 2],
        tf: &TransferFunction,
        unit: f32,
    ) -> Arc<Vec<stochastic::PdfBlock>> {
        let mut cache = self.pdf.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((t, p)) = cache.as_ref() {
            if t == tf {
                return p.clone();
            }
        }
        let lut = Lut::new(tf, 1.0);
        let mean = volume.visit(
            window[0],
            window[1],
            blocks::BuildMeanSigma {
                size: self.blocks.size,
                sigma: lut.sigmas(),
            },
        );
        let p = Arc::new(stochastic::pdf_blocks(
            &self.blocks.range,
            tf,
            1.0 / unit,
            &mean,
        ));
        *cache = Some((tf.clone(), p.clone()));
        p
    }
}

impl<'v> Renderer<'v> {
    /// Prepares `volume` for rendering with data values `window[0]…window[1]`
    /// mapped to 0…1. A window of zero width (a constant volume) is widened
    /// by ±0.5 so it still normalises. The block grid of the default size is
    /// built here, so that renders measure rendering, not set-up.
    pub fn new(volume: &'v Volume, window: [f32; 2]) -> Result<Renderer<'v>> {
        let mut window = window;
        if window[0].is_finite() && window[0] == window[1] {
            window = [window[0] - 0.5, window[0] + 0.5];
        }
        if !(window[0].is_finite() && window[1].is_finite() && window[0] < window[1]) {
            return Err(Error::invalid(format!(
                "window [{}, {}] must have lo < hi",
                window[0], window[1]
            )));
        }
        let r = Renderer {
            volume,
            window,
            derived: std::sync::Mutex::new(Vec::new()),
            z_pairs: std::sync::OnceLock::new(),
            geometry: None,
        };
        r.derived(blocks::DEFAULT_BLOCK);
        Ok(r)
    }

    /// Adds opaque geometry (world coordinates) that rays stop at; the
    /// camera then frames the volume and the geometry's bounds together.
    pub fn with_geometry(mut self, geometry: Option<Arc<crate::geometry::Geometry>>) -> Self {
        self.geometry = geometry.filter(|g| !g.is_empty());
        self
    }

    /// The volume.
    pub fn volume(&self) -> &Volume {
        self.volume
    }

    /// The data window in use.
    pub fn window(&self) -> [f32; 2] {
        self.window
    }

    /// The derived structures for blocks of `size` cells.
    fn derived(&self, size: usize) -> Arc<Derived> {
        // A poisoned lock only means another render panicked while building;
        // the list itself is always consistent.
        let mut list = self.derived.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, d)) = list.iter().find(|(s, _)| *s == size) {
            return d.clone();
        }
        let blocks =
            self.volume
                .visit(self.window[0], self.window[1], blocks::BuildBlocks { size });
        let d = Arc::new(Derived {
            blocks,
            max_gradient: std::sync::OnceLock::new(),
            octree: std::sync::OnceLock::new(),
            pdf: std::sync::Mutex::new(None),
            skip: std::sync::Mutex::new(None),
            tf_tables: std::sync::Mutex::new(Vec::new()),
        });
        list.push((size, d.clone()));
        d
    }

    /// The edge of the blocks a render with `tf` and `params` uses: the
    /// scene's ([`RenderParams::block_size`]), else
    /// [`DEFAULT_BLOCK`](blocks::DEFAULT_BLOCK) (8) — or, for the marchers
    /// that only skip with the blocks and for `adaptive+grouped`
    /// ([`RenderParams::block_size_follows_data`]),
    /// [`SPARSE_BLOCK`](blocks::SPARSE_BLOCK) (4) where `tf` leaves the
    /// blocks of 4³ showing at most [`FINER_BLOCKS_PAY`] of what the blocks
    /// of 8³ show. Finer blocks skip closer to what shows but cost more
    /// steps of the walk; on sparse data they pay, on dense data they do
    /// not (docs/engine.md, "Finer blocks where the data is sparse").
    /// Builds the grids it compares (kept for later renders); the 4³ one
    /// only where 8³ blocks hide enough for skipping to run at all
    /// ([`SKIP_PAYS`]).
    pub fn block_size_for(&self, tf: &TransferFunction, params: &RenderParams) -> usize {
        self.derived_for(tf, &params.in_opacity_units(self.volume))
            .blocks
            .size
    }

    /// What [`Renderer::block_size_for`]'s blocks derive, for `params`
    /// already in opacity units (as the render has them).
    fn derived_for(&self, tf: &TransferFunction, params: &RenderParams) -> Arc<Derived> {
        if let Some(b) = params.block_size {
            return self.derived(b as usize);
        }
        let coarse = self.derived(blocks::DEFAULT_BLOCK);
        if !params.block_size_follows_data() {
            return coarse;
        }
        let coarse_tft = coarse.tf_tables(tf, params.step);
        if !coarse_tft.skipping_pays() {
            return coarse;
        }
        let fine = self.derived(blocks::SPARSE_BLOCK);
        let shown = |t: &tf_tables::TfTables| 1.0 - t.empty_share;
        if shown(&fine.tf_tables(tf, params.step)) <= FINER_BLOCKS_PAY * shown(&coarse_tft) {
            fine
        } else {
            coarse
        }
    }

    /// Renders with `tf`, seen by `camera`.
    pub fn render(
        &self,
        tf: &TransferFunction,
        camera: &CameraParams,
        params: &RenderParams,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<(Image, RenderStats)> {
        self.render_cancellable(tf, camera, params, progress, &AtomicBool::new(false))
    }

    /// [`Renderer::render`] that stops early, with [`Error::Cancelled`],
    /// once `cancel` is raised (from another thread, or from `progress`).
    /// The flag is read once per 16×16 tile, so a raised flag ends the
    /// render within about one tile's time per thread, and the per-sample
    /// loop does not change. A render that finished all its tiles returns
    /// its image even if the flag was raised at the very end.
    pub fn render_cancellable(
        &self,
        tf: &TransferFunction,
        camera: &CameraParams,
        params: &RenderParams,
        progress: &(dyn Fn(usize, usize) + Sync),
        cancel: &AtomicBool,
    ) -> Result<(Image, RenderStats)> {
        params.validate_for(self.volume)?;
        camera.validate()?;
        let start = Instant::now();
        let params = &*params.in_opacity_units(self.volume);
        let volume = self.volume;
        let (mut lo, mut hi) = volume.frame_bounds();
        if let Some((glo, ghi)) = self.geometry.as_ref().and_then(|g| g.bounds()) {
            (lo, hi) = (lo.min(glo), hi.max(ghi));
        }
        let cam = Camera::fit(camera, lo, hi, params.width, params.height);
        let unit = volume.opacity_unit();
        let derived = self.derived_for(tf, params);
        let max_gradient: &[f32] =
            if matches!(params.method, Method::AdaptiveMax | Method::Adaptive) {
                derived.max_gradient.get_or_init(|| {
                    volume.visit(
                        self.window[0],
                        self.window[1],
                        blocks::BuildMaxGradient {
                            size: derived.blocks.size,
                        },
                    )
                })
            } else {
                &[]
            };
        let tft = derived.tf_tables(tf, params.step);
        // Each adaptive method's `k` per block.
        let change = (params.method == Method::Adaptive)
            .then(|| tft.change(&derived.blocks, max_gradient, params.shade_weight()));
        let block_k = change.as_deref().map_or(max_gradient, |k| k.as_slice());
        if params.method.is_physical() {
            // The path tracer's medium has no surfaces yet: refuse rather
            // than draw the smoke through walls the user asked for.
            if self.geometry.is_some() {
                return Err(Error::invalid(format!(
                    "method {}: opaque geometry is not supported by the physically based integrators yet; render without it (--geometry none) or use a ray-casting method",
                    params.method.name()
                )));
            }
            let (image, mut stats) = path::render(
                volume,
                self.window,
                &derived.blocks,
                cam,
                params,
                progress,
                cancel,
            )
            .ok_or(Error::Cancelled)?;
            stats.seconds = start.elapsed().as_secs_f64();
            return Ok((image, stats));
        }
        let pdf = if params.method == Method::Importance {
            derived.pdf(volume, self.window, tf, unit)
        } else {
            Arc::new(Vec::new())
        };
        let tree = (params.method == Method::Lod).then(|| {
            derived.octree.get_or_init(|| {
                volume.visit(
                    self.window[0],
                    self.window[1],
                    octree::BuildOctree {
                        leaf: derived.blocks.size,
                    },
                )
            })
        });
        let job = Job {
            z_pairs: &self.z_pairs,
            pdf: pdf.as_slice(),
            volume,
            tft: &tft,
            cam,
            params,
            unit,
            progress,
            cancel,
            blocks: &derived.blocks,
            derived: &derived,
            block_k,
            surface: self.geometry.as_deref().map(|g| surface::SurfaceCtx {
                geometry: g,
                light: crate::geometry::SurfaceLight::new(g.light, &cam),
                shadows: g.shadows,
            }),
            tree,
        };
        let (image, mut stats) = volume
            .visit(self.window[0], self.window[1], job)
            .ok_or(Error::Cancelled)?;
        stats.seconds = start.elapsed().as_secs_f64();
        Ok((image, stats))
    }
}

/// The least share of blocks the transfer function must hide for the CPU
/// marchers to skip empty space (when asked to): skipping asks the skip
/// map as the lanes march, and where hardly a block is empty it saves less
/// than the asks cost. Marschner–Lobb 256³ under `bench/peers`' transfer
/// function hides 1.0 % of its blocks: skipping saved 1.7 % of the samples
/// and took about 4 % more time (AVX2, Zen 3). On an Emerald Rapids
/// (AVX-512), with slabs of it set to zero, skipping cost 5–8 % with 4.1 %
/// of the blocks hidden, 3 % with 7.3 %, broke even at 10.3 % and saved 4–5
/// % at 13.5 % (docs/engine.md): hence a tenth. The pictures are the same
/// either way (an empty block's samples add nothing); only the sample
/// counts differ, and the stats say when skipping was left out.
pub const SKIP_PAYS: f32 = 1.0 / 10.0;

/// How much less of the volume the blocks of 4³ must show than those of 8³
/// (the share of blocks not hidden, 4³ over 8³) for the marchers of
/// [`RenderParams::block_size_follows_data`] to take them by default
/// ([`Renderer::block_size_for`]). Measured on one pinned thread (Emerald
/// Rapids, `uniform`, 512²; docs/engine.md): the teapot CT and the Gaussian
/// blobs, whose 4³ blocks show 0.70 of what 8³ ones show, render
/// 1.16–1.20× faster with them; Marschner–Lobb with a quarter of it cut
/// away, at 0.956, 0.94× as fast. `adaptive+grouped` took 1–23 % less
/// time with 4³ on the eight CT and MR volumes that pass the test (its
/// defaults).
pub const FINER_BLOCKS_PAY: f32 = 0.85;

/// Premultiplied linear `c` over background `bg`: the pixel.
#[inline]
fn over_background(c: glam::Vec4, bg: Vec3) -> [f32; 4] {
    let rgb = c.truncate() + bg * (1.0 - c.w);
    [rgb.x, rgb.y, rgb.z, c.w]
}

struct Job<'a> {
    /// The renderer's z-paired copy for the packets, built by the first
    /// render that runs them.
    z_pairs: &'a std::sync::OnceLock<packet::ZPairs>,
    pdf: &'a [stochastic::PdfBlock],
    volume: &'a Volume,
    blocks: &'a BlockGrid,
    derived: &'a Derived,
    /// What the transfer function and step give (kept across renders):
    /// the table, the blocks' emptiness, the levels' tables.
    tft: &'a tf_tables::TfTables,
    /// The adaptive methods' `k` per block: the largest derivative
    /// (`adaptive-max`) or the change of the classified signal
    /// (`adaptive`); empty for the others.
    block_k: &'a [f32],
    tree: Option<&'a octree::Octree>,
    cam: Camera,
    params: &'a RenderParams,
    unit: f32,
    progress: &'a (dyn Fn(usize, usize) + Sync),
    cancel: &'a AtomicBool,
    surface: Option<surface::SurfaceCtx<'a>>,
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
            block_size: self.blocks.size,
            block_counts: self.blocks.counts,
            empty: &self.tft.empty,
            occupied: skip_empty.then(|| self.tft.occupied(self.blocks, box_lo, box_hi)),
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
                block_size: self.blocks.size as u32,
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
                        #[cfg(target_arch = "x86_64")]
                        pk.camera_rays(&self.cam, &pixels[..n], &mut rays[..n]);
                        #[cfg(not(target_arch = "x86_64"))]
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
