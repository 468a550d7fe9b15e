//! Out-of-core rendering of a chunked multi-resolution volume
//! ([`ChunkedSource`]: OME-Zarr, or a volume in memory) under a memory
//! budget.
//!
//! 1. **Levels**: near the eye the coarsest level whose voxel is no larger
//!    than a pixel where the volume comes nearest the eye (a full-screen
//!    view of 2048³ at 1024² reads level 1; zooming in reads level 0), and
//!    further off, per chunk, the coarsest level fine enough there (the
//!    `plan` module); or the one level asked.
//! 2. **Bricks**: the chunks so chosen. A brick whose chunks (and the
//!    border its interpolation reads) are all transparent under the transfer
//!    function — known from the store's chunk ranges, or because a chunk is
//!    not stored — is skipped without reading it; so is one outside the
//!    image.
//! 3. **Visibility order**: bricks sorted by the sum over axes of their
//!    index distance from the eye's brick, among siblings, depth first (a
//!    ray's distance on each axis never shrinks, so every ray meets its
//!    bricks in this order; for an orthographic camera, by position along
//!    the view direction).
//! 4. **March**: each brick, with a border of one voxel (two with shading)
//!    copied from its neighbours, marches the samples of every pixel whose
//!    ray crosses it, in parallel by rows; each pixel keeps its colour,
//!    opacity and next sample index between bricks (the `march` module), so the
//!    picture is the in-core `uniform` march's, and a brick is read once
//!    per frame whatever the budget.
//! 5. **Cache and prefetch**: decoded chunks live in an LRU cache within
//!    the budget; a prefetch thread reads the chunks of the bricks ahead
//!    while the render marches.
//!
//! Only `uniform` (and `jitter`) march here: the methods that choose steps
//! per block or sample stochastically need the whole volume in memory.

mod brick;
mod cache;
mod cells;
mod march;
mod plan;

pub use cache::{human_bytes, parse_bytes, CacheStats};

use crate::camera::{Camera, CameraParams};
use crate::error::{Error, Result};
use crate::image::Image;
use crate::render::shading::BlinnPhong;
use crate::render::{Method, Order, RenderParams, RenderStats};
use crate::transfer::{srgb_to_linear, Lut, TransferFunction, LUT_SIZE};
use crate::volume::{ChunkRange, ChunkedSource, Level};
use brick::{BrickBuf, FrameArgs};
use cache::ChunkCache;
use cells::CellStore;
use glam::Vec3;
use march::{Px, RowCount};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Instant;

/// How the out-of-core renderer reads.
#[derive(Clone, Debug, PartialEq)]
pub struct OutOfCoreParams {
    /// Bytes of decoded voxels held at once (the chunk cache and the brick
    /// being marched).
    pub budget: u64,
    /// Render this level (0 the finest) instead of choosing by the screen.
    pub level: Option<usize>,
    /// Scales the pixel size the level is chosen by: 2 reads a level
    /// coarser, 0.5 a level finer.
    pub lod_scale: f32,
    /// Read ahead on a second thread while the render marches.
    pub prefetch: bool,
    /// Never wait for a read (a viewer): each region is drawn at the finest
    /// level it needs whose chunks are in memory — the coarsest level's
    /// are read if they are not — and the chunks that finer regions would
    /// read are listed in [`OutOfCoreStats::wanted`], for a loader to read
    /// with [`OutOfCore::fetch`] before the next frame.
    pub resident_only: bool,
}

impl Default for OutOfCoreParams {
    fn default() -> Self {
        OutOfCoreParams {
            budget: default_budget(),
            level: None,
            lod_scale: 1.0,
            prefetch: true,
            resident_only: false,
        }
    }
}

/// Half the machine's available memory (`MemAvailable`), at least 256 MiB;
/// 2 GiB where it cannot be read.
pub fn default_budget() -> u64 {
    let avail = std::fs::read_to_string("/proc/meminfo").ok().and_then(|s| {
        s.lines()
            .find(|l| l.starts_with("MemAvailable:"))
            .and_then(|l| l.split_whitespace().nth(1)?.parse::<u64>().ok())
            .map(|kib| kib * 1024)
    });
    avail.map_or(2 << 30, |a| (a / 2).max(256 << 20))
}

/// What an out-of-core render read and skipped.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct OutOfCoreStats {
    /// The finest level rendered (the one near the eye).
    pub level: usize,
    /// The coarsest level rendered (regions far from the eye).
    pub coarsest: usize,
    /// Bricks marched at each level (index: the level).
    pub per_level: Vec<usize>,
    /// Bricks considered: chunks of the levels rendered, where each region
    /// is read at one level.
    pub bricks: usize,
    /// Bricks marched.
    pub marched: usize,
    /// Skipped as transparent (from chunk ranges, before or after reading).
    pub empty: usize,
    /// Outside the image.
    pub culled: usize,
    /// Skipped because every ray through them had already terminated.
    pub occluded: usize,
    /// Bytes the store read (compressed), where it counts them.
    pub bytes_read: u64,
    pub cache: CacheStats,
    /// Seconds spent waiting for chunks on the render thread.
    pub wait_seconds: f64,
    /// With [`OutOfCoreParams::resident_only`]: the chunks to read for a
    /// finer picture, coarser levels first, as many as fit the budget
    /// beside those the frame used.
    #[serde(skip)]
    pub wanted: Vec<ChunkKey>,
    /// Some chunks a finer picture needs were left out of `wanted`: the
    /// budget cannot hold them beside those the frame reads.
    #[serde(skip)]
    pub over_budget: bool,
}

/// A chunk of a store: its level and index (x, y, z).
pub type ChunkKey = (usize, [u64; 3]);

impl OutOfCoreStats {
    /// Share of chunk requests answered from memory.
    pub fn hit_rate(&self) -> f64 {
        let n = self.cache.hits + self.cache.misses;
        if n == 0 {
            0.0
        } else {
            self.cache.hits as f64 / n as f64
        }
    }
}

/// The world box through level 0's voxel centres (what the camera frames).
pub fn world_bounds(levels: &[Level]) -> (Vec3, Vec3) {
    let l = &levels[0];
    let ext = Vec3::from(l.dims.map(|d| (d.max(1) - 1) as f32)) * l.spacing;
    (l.origin, l.origin + ext)
}

/// The level the renderer reads for `cam`: the coarsest whose smallest
/// spacing is at most the size of a pixel (times `lod_scale`) where the
/// volume comes nearest the eye.
pub fn choose_level(levels: &[Level], cam: &Camera, lod_scale: f32) -> usize {
    let (lo, hi) = world_bounds(levels);
    let nearest = cam.eye.clamp(lo, hi);
    let z = (nearest - cam.eye).dot(cam.forward).max(0.0);
    let pixel = cam.pixel_size_at(z) * lod_scale.max(1e-6);
    let mut best = 0;
    for (i, l) in levels.iter().enumerate() {
        if l.spacing.min_element() <= pixel * (1.0 + 1e-4) {
            best = i;
        }
    }
    best
}

/// Checks that the out-of-core renderer can run `params`; the error names
/// the setting.
fn check_params(params: &RenderParams) -> Result<()> {
    params.validate()?;
    check_uniform(
        params,
        "out of core, voxcast",
        "render a level that fits in memory with --level N, or raise --memory-budget until the volume fits",
    )
}

/// Checks that `params` march uniform steps front to back in one pass, as
/// bricks taken one after another can (`who` says who does, `way_out` what
/// the user can do instead); the error names the setting.
pub(crate) fn check_uniform(params: &RenderParams, who: &str, way_out: &str) -> Result<()> {
    if !matches!(params.method, Method::Uniform | Method::Jitter) {
        return Err(Error::invalid(format!(
            "method {}: {who} marches uniform steps only (uniform, jitter); {way_out}",
            params.method.name()
        )));
    }
    if params.order != Order::FrontToBack {
        return Err(Error::invalid(format!(
            "render.order back-to-front: {who} composites front to back only"
        )));
    }
    if params.grouped {
        return Err(Error::invalid(format!(
            "render.grouped: {who} has no grouped interpolation"
        )));
    }
    if params.spp > 1 && (params.jitter || params.method == Method::Jitter) {
        return Err(Error::invalid(format!(
            "render.spp: {who} takes one jittered pass (spp = 1)"
        )));
    }
    Ok(())
}

/// The level's sample box in voxel coordinates (as [`crate::volume::Volume::sample_box`]).
fn sample_box(dims: [u64; 3]) -> (Vec3, Vec3) {
    let ax = |d: u64| {
        if d > 1 {
            (0.0, (d - 1) as f32)
        } else {
            (-0.5, 0.5)
        }
    };
    let [x, y, z] = dims.map(ax);
    (Vec3::new(x.0, y.0, z.0), Vec3::new(x.1, y.1, z.1))
}

/// Renders `source` with `tf` over the data window `window`, reading no more
/// than `ooc.budget` bytes of decoded voxels at once. `progress(done,
/// total)` counts bricks; `cancel` is read before each brick. For several
/// renders of one store, make an [`OutOfCore`] once: its cache stays warm.
#[allow(clippy::too_many_arguments)]
pub fn render_chunked(
    source: &dyn ChunkedSource,
    tf: &TransferFunction,
    window: [f32; 2],
    camera: &CameraParams,
    params: &RenderParams,
    ooc: &OutOfCoreParams,
    progress: &(dyn Fn(usize, usize) + Sync),
    cancel: &AtomicBool,
) -> Result<(Image, RenderStats, OutOfCoreStats)> {
    OutOfCore::new(source, ooc.clone()).render(tf, window, camera, params, progress, cancel)
}

/// A chunked store and its chunk cache, for renders one after another (a
/// viewer, an orbit, a benchmark): chunks read by one render serve the next.
pub struct OutOfCore<'s> {
    source: &'s dyn ChunkedSource,
    ooc: OutOfCoreParams,
    cache: ChunkCache<'s>,
    /// Bricks' cell ranges, kept from frame to frame within a sixteenth of
    /// the budget: a warm frame flags a brick's empty cells without reading
    /// its voxels again; and, while the transfer function's visible ranges
    /// stay, the flags themselves.
    cells: std::sync::Mutex<CellStore>,
    /// What the store knows of each chunk, per level, asked once: a store
    /// answers with a file-system call per chunk.
    ranges: std::sync::Mutex<std::collections::HashMap<usize, std::sync::Arc<Vec<ChunkRange>>>>,
}

impl<'s> OutOfCore<'s> {
    /// Prepares `source` for rendering within `ooc.budget`.
    pub fn new(source: &'s dyn ChunkedSource, ooc: OutOfCoreParams) -> OutOfCore<'s> {
        // The brick being marched is held beside the cache: the largest a
        // brick of any level can be: a shaded one, with its border of 3, or
        // 4 for a coarser level's region, which sits a fraction of a voxel
        // off its chunk.
        let ty = source.scalar_type();
        let brick_max = source
            .levels()
            .iter()
            .map(|l| l.chunk.iter().map(|&c| c as u64 + 4).product::<u64>() * ty.size() as u64)
            .max()
            .unwrap_or(0);
        let cache = ChunkCache::new(source, ooc.budget.saturating_sub(brick_max));
        OutOfCore {
            source,
            ooc,
            cache,
            cells: Default::default(),
            ranges: Default::default(),
        }
    }

    /// The store rendered.
    pub fn source(&self) -> &'s dyn ChunkedSource {
        self.source
    }

    /// The level a render through `cam` reads: the one asked for, else
    /// [`choose_level`]'s.
    pub fn level_for(&self, cam: &Camera) -> Result<usize> {
        let levels = self.source.levels();
        match self.ooc.level {
            Some(l) if l >= levels.len() => Err(Error::invalid(format!(
                "--level {l}: {} has levels 0…{}",
                self.source.name(),
                levels.len().saturating_sub(1)
            ))),
            Some(l) => Ok(l),
            None => Ok(choose_level(levels, cam, self.ooc.lod_scale)),
        }
    }

    /// What the store knows of every chunk of level `lidx` (x fastest):
    /// asked of the store on the first render of the level, kept after.
    pub(crate) fn ranges(&self, lidx: usize) -> std::sync::Arc<Vec<ChunkRange>> {
        let kept = self.ranges.lock().ok().and_then(|m| m.get(&lidx).cloned());
        kept.unwrap_or_else(|| {
            let r = std::sync::Arc::new(chunk_ranges(self.source, lidx));
            if let Ok(mut m) = self.ranges.lock() {
                m.insert(lidx, r.clone());
            }
            r
        })
    }

    /// What the cache has done since it was made.
    pub fn cache_stats(&self) -> CacheStats {
        self.cache.stats()
    }

    /// Reads chunk `k` into the cache unless it is there (for a loader
    /// beside resident-only renders); true when it read.
    pub fn fetch(&self, k: ChunkKey) -> Result<bool> {
        if self.cache.has(k) {
            return Ok(false);
        }
        self.cache.get(k).map(|_| true)
    }

    /// Renders one image; see [`render_chunked`].
    pub fn render(
        &self,
        tf: &TransferFunction,
        window: [f32; 2],
        camera: &CameraParams,
        params: &RenderParams,
        progress: &(dyn Fn(usize, usize) + Sync),
        cancel: &AtomicBool,
    ) -> Result<(Image, RenderStats, OutOfCoreStats)> {
        let (part, rs, stats) =
            self.render_part(tf, window, camera, params, None, progress, cancel)?;
        Ok((
            with_background(part, params.width, params.height, params.background),
            rs,
            stats,
        ))
    }

    /// The premultiplied colour and opacity (linear RGBA, no background) of
    /// the samples the bricks of `part` own — a box `[lo, hi)` of the
    /// rendered level's chunk indices; `None`: all of them. Parts that tile
    /// the level, composited with `over` in visibility order, give the
    /// whole render (the sort-last renderer, [`crate::render::sortlast`]);
    /// for that, early ray termination must be off (`params.ert = 1`), as
    /// a part does not see the opacity in front of it.
    #[allow(clippy::too_many_arguments)]
    pub fn render_part(
        &self,
        tf: &TransferFunction,
        window: [f32; 2],
        camera: &CameraParams,
        params: &RenderParams,
        part: Option<ChunkBox>,
        progress: &(dyn Fn(usize, usize) + Sync),
        cancel: &AtomicBool,
    ) -> Result<(Vec<[f32; 4]>, RenderStats, OutOfCoreStats)> {
        let (source, ooc) = (self.source, &self.ooc);
        let before = self.cache.stats();
        let read_before = source.bytes_read();
        check_params(params)?;
        camera.validate()?;
        let start = Instant::now();
        let levels = source.levels();
        if levels.is_empty() {
            return Err(Error::invalid(format!(
                "{}: the store has no levels",
                source.name()
            )));
        }
        let (w, h) = (params.width, params.height);
        let (lo, hi) = world_bounds(levels);
        let cam = Camera::fit(camera, lo, hi, w, h);
        let fine = self.level_for(&cam)?;
        // Coarser levels where they nest and no level or part was asked.
        let coarse = if self.ooc.level.is_some() || part.is_some() {
            fine
        } else {
            let f = plan::factors(levels);
            (fine + 1..levels.len())
                .take_while(|&l| f[l].is_some())
                .last()
                .unwrap_or(fine)
        };
        let ty = source.scalar_type();
        let shading = params.shading.then(BlinnPhong::default);
        // Eight rays per SIMD packet where the CPU and the shading allow
        // (the in-core rule), else the scalar loop.
        let packets = crate::render::packet::level(params.simd)
            .filter(|_| shading.is_none_or(|bp| crate::render::packet::shades(&bp)));
        let window = widen(window);
        let transparent = |lo: f32, hi: f32| range_transparent(tf, window, lo, hi);
        let known_empty = |r: &ChunkRange| known_empty(tf, window, r);

        // The plan: the bricks to march, in visibility order.
        let planner = plan::Planner {
            levels,
            cam: &cam,
            size: (w, h),
            fine,
            coarse,
            lod_scale: ooc.lod_scale,
            shaded: shading.is_some(),
            part,
            resident: None,
        };
        // Resident only: the chunks the plan finds in memory are held
        // (the cache cannot evict them) until the frame is drawn, and each
        // is asked once: the loader adds chunks meanwhile, and the plan may
        // walk the tree twice (its base must not change in between).
        let held = std::cell::RefCell::new(std::collections::HashMap::new());
        let resident = |l: usize, k: [u64; 3]| {
            let mut held = held.borrow_mut();
            held.entry((l, k))
                .or_insert_with(|| self.cache.peek((l, k)))
                .is_some()
        };
        let planner = plan::Planner {
            resident: ooc.resident_only.then_some(&resident as _),
            ..planner
        };
        let mut plan = planner.plan(&|l| self.ranges(l), &known_empty);
        let base = plan.base;
        let geos: Vec<plan::LevelGeo> = (0..levels.len())
            .map(|l| plan::LevelGeo::new(levels, base, l, shading.is_some()))
            .collect();
        // Wanted: as many as fit beside the chunks this frame reads.
        let mut wanted = std::mem::take(&mut plan.wanted);
        let asked = wanted.len();
        if !wanted.is_empty() {
            let mut used: std::collections::HashSet<ChunkKey> = held
                .borrow()
                .iter()
                .filter_map(|(k, c)| c.as_ref().map(|_| *k))
                .collect();
            used.extend(
                plan.bricks
                    .iter()
                    .flat_map(|b| b.chunks.iter().map(|&k| (b.lidx, k))),
            );
            let mut bytes: u64 = used.iter().map(|k| levels[k.0].chunk_bytes(ty)).sum();
            let room = self.cache.budget();
            wanted.retain(|k| {
                bytes += levels[k.0].chunk_bytes(ty);
                bytes <= room
            });
        }
        let mut stats = OutOfCoreStats {
            over_budget: wanted.len() < asked,
            wanted,
            level: base,
            coarsest: base,
            bricks: plan.considered,
            culled: plan.culled,
            empty: plan.empty,
            ..Default::default()
        };
        // The budget must hold one brick and the chunks it reads.
        let brick_need = |b: &plan::Brick| {
            let vox: u64 = (0..3).map(|a| b.dbox.1[a] - b.dbox.0[a]).product();
            vox * ty.size() as u64 + b.chunks.len() as u64 * levels[b.lidx].chunk_bytes(ty)
        };
        if let Some(b) = plan.bricks.iter().max_by_key(|b| brick_need(b)) {
            let need = brick_need(b);
            if ooc.budget < need {
                let c = levels[b.lidx].chunk;
                return Err(cache::too_small(
                    ooc.budget,
                    need,
                    &format!(
                        "chunks of {}×{}×{} {ty} at level {}: one brick with its border and the {} chunks it reads",
                        c[0], c[1], c[2], b.lidx, b.chunks.len()
                    ),
                ));
            }
        }
        let ranges: Vec<std::sync::Arc<Vec<ChunkRange>>> = (0..levels.len())
            .map(|l| {
                if plan.bricks.iter().any(|b| b.lidx == l) {
                    self.ranges(l)
                } else {
                    Default::default()
                }
            })
            .collect();
        let plan = plan.bricks;

        // Every pixel's ray, in the base level's voxel coordinates.
        let blevel = &levels[base];
        let inv_spacing = Vec3::ONE / blevel.spacing;
        let unit = levels[0].spacing.min_element();
        let st = params.step * blevel.spacing.min_element();
        let jitter = (params.jitter || params.method == Method::Jitter).then_some(params.seed);
        let sbox = sample_box(blevel.dims);
        let mut px: Vec<Px> = (0..w * h)
            .into_par_iter()
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let (o, d) = cam.ray(x, y);
                let u = jitter.map_or(0.0, |s| crate::render::rng::pixel_sequence(s, x, y, 0));
                Px::start(
                    (o - blevel.origin) * inv_spacing,
                    d * inv_spacing,
                    -d,
                    sbox,
                    st,
                    u,
                )
            })
            .collect();
        let hit = px.iter().filter(|p| p.live).count() as u64;

        let lut = Lut::new(tf, params.step);
        // Each level's premultiplied table, for its step (`stride` base
        // steps).
        let mut tables: Vec<Option<Box<[[f32; 4]; LUT_SIZE]>>> = vec![None; levels.len()];
        for b in &plan {
            tables[b.lidx]
                .get_or_insert_with(|| lut.premultiplied(st * geos[b.lidx].stride as f32 / unit));
        }
        // Whether a sample interpolated from values in `[lo, hi]` may show:
        // its table entry (the nearest, `Lut::index`) lies between those of
        // `lo` and `hi`, and the march skips the entries of zero opacity.
        // `shown[i]` is the first entry from `i` on that has opacity. (A
        // margin of a whole entry, as before, made every cell of zeros
        // "visible" under a map whose opacity rises from 0, such as the
        // cloud's: nothing was skipped.) Opacity is zero at one step exactly
        // where it is at any.
        let q0 = lut.premultiplied(st / unit);
        let mut shown = vec![LUT_SIZE; LUT_SIZE + 1];
        for i in (0..LUT_SIZE).rev() {
            shown[i] = if q0[i][3] > 0.0 { i } else { shown[i + 1] };
        }
        let generation = CellStore::begin(&self.cells, window, &shown);
        let visible = |lo: f32, hi: f32| {
            // A hair of margin for the interpolation's rounding.
            const EPS: f32 = 1e-5;
            let s = window[1] - window[0];
            let (a, b) = ((lo - window[0]) / s, (hi - window[0]) / s);
            let (Some(ia), Some(ib)) = (Lut::index((a - EPS).max(0.0)), Lut::index(b + EPS)) else {
                return false;
            };
            shown[ia] <= ib
        };
        let (emission, absorption) = match params.optical {
            crate::render::OpticalModel::AbsorptionOnly => (0.0, 1.0),
            crate::render::OpticalModel::EmissionOnly => (1.0, 0.0),
            crate::render::OpticalModel::EmissionAbsorption => (1.0, 1.0),
        };
        let stop = if params.ert < 1.0 {
            params.ert
        } else {
            f32::INFINITY
        };
        let cache = &self.cache;
        let cursor = AtomicUsize::new(0);
        let done = AtomicBool::new(false);
        let mut counts_total = RowCount::default();
        let mut error: Option<Error> = None;
        let chunk_bytes = plan
            .iter()
            .map(|b| levels[b.lidx].chunk_bytes(ty))
            .max()
            .unwrap_or(0)
            .max(1);
        let biggest = plan.iter().map(brick_need).max().unwrap_or(0);
        let lookahead = (ooc.budget.saturating_sub(biggest) / (16 * chunk_bytes)).min(64) as usize;
        std::thread::scope(|scope| {
            if ooc.prefetch && !ooc.resident_only && lookahead > 0 {
                let (plan, cursor, done, ranges) = (&plan, &cursor, &done, &ranges);
                scope.spawn(move || {
                    for (j, b) in plan.iter().enumerate() {
                        while j > cursor.load(Ordering::Acquire) + lookahead {
                            if done.load(Ordering::Acquire) {
                                return;
                            }
                            std::thread::sleep(std::time::Duration::from_micros(200));
                        }
                        let level = &levels[b.lidx];
                        for &k in &b.chunks {
                            if done.load(Ordering::Acquire) {
                                return;
                            }
                            if matches!(ranges[b.lidx][level.chunk_index(k)], ChunkRange::Fill(_))
                                || cache.has((b.lidx, k))
                            {
                                continue;
                            }
                            // An error is the render thread's to report.
                            let _ = cache.get((b.lidx, k));
                        }
                    }
                });
            }
            let mut buf = BrickBuf::new(ty);
            for (j, b) in plan.iter().enumerate() {
                cursor.store(j, Ordering::Release);
                if cancel.load(Ordering::Relaxed) {
                    error = Some(Error::Cancelled);
                    break;
                }
                let [x0, x1, y0, y1] = b.rect;
                let any_live = (y0..y1).any(|y| {
                    let r = (y * w) as usize;
                    px[r + x0 as usize..r + x1 as usize].iter().any(|p| p.live)
                });
                if !any_live {
                    stats.occluded += 1;
                    progress(j + 1, plan.len());
                    continue;
                }
                let geo = &geos[b.lidx];
                let t = Instant::now();
                let dbox = b.dbox;
                match buf.assemble(geo, dbox, &b.chunks, &ranges[b.lidx], cache) {
                    Ok(Some((lo, hi))) if transparent(lo, hi) => {
                        stats.wait_seconds += t.elapsed().as_secs_f64();
                        stats.empty += 1;
                        progress(j + 1, plan.len());
                        continue;
                    }
                    Ok(None) => {
                        stats.empty += 1;
                        progress(j + 1, plan.len());
                        continue;
                    }
                    Ok(_) => {}
                    Err(e) => {
                        error = Some(e);
                        break;
                    }
                }
                stats.wait_seconds += t.elapsed().as_secs_f64();
                let (olo, ohi) = b.own;
                let dims = std::array::from_fn(|a| (dbox.1[a] - dbox.0[a]) as usize);
                let data_lo = Vec3::from(dbox.0.map(|v| v as f32));
                // Samples outside the box around the brick's visible cells are
                // transparent: the march skips them, and the packets skip
                // the empty cells inside it.
                let (cell_counts, flags) = CellStore::brick(
                    &self.cells,
                    (b.lidx, dbox),
                    generation,
                    ooc.budget / 16,
                    &buf,
                    dims,
                    &visible,
                );
                let Some((vlo, vhi)) = flags.shown else {
                    stats.empty += 1;
                    progress(j + 1, plan.len());
                    continue;
                };
                // (A face on the level's edge stays open: a coarser
                // level's region reaches past its last voxel centres, and
                // the samples there read the edge's cells, clamped.)
                let d = Vec3::from(geo.level.dims.map(|v| v as f32 - 1.0));
                let (vlo, vhi) = (vlo + data_lo, vhi + data_lo);
                let vlo = Vec3::select(vlo.cmple(Vec3::ZERO), Vec3::NEG_INFINITY, vlo);
                let vhi = Vec3::select(vhi.cmpge(d), Vec3::INFINITY, vhi);
                let (olo, ohi) = (olo.max(geo.to_base(vlo)), ohi.min(geo.to_base(vhi)));
                if (0..3).any(|a| olo[a] > ohi[a]) {
                    stats.empty += 1;
                    progress(j + 1, plan.len());
                    continue;
                }
                stats.marched += 1;
                if stats.per_level.len() <= b.lidx {
                    stats.per_level.resize(b.lidx + 1, 0);
                }
                stats.per_level[b.lidx] += 1;
                stats.coarsest = stats.coarsest.max(b.lidx);
                let frame = FrameArgs {
                    geo,
                    data_lo,
                    own_lo: olo,
                    own_hi: ohi,
                    lut: &lut,
                    q: tables[b.lidx].as_deref().unwrap_or(&q0),
                    st,
                    unit,
                    inv_spacing: Vec3::ONE / geo.level.spacing,
                    emission,
                    absorption,
                    stop,
                    shading,
                    window,
                    packets,
                    cells: params.skip_empty.then_some((&flags.skip[..], cell_counts)),
                };
                let c = buf.march(&frame, dims, &mut px, w, b.rect);
                counts_total.samples += c.samples;
                counts_total.shaded += c.shaded;
                counts_total.terminated += c.terminated;
                progress(j + 1, plan.len());
            }
            done.store(true, Ordering::Release);
        });
        if let Some(e) = error {
            return Err(e);
        }
        let pixels = px.par_iter().map(|p| p.finish().to_array()).collect();
        stats.cache = cache.stats().since(&before);
        stats.bytes_read = source.bytes_read() - read_before;
        let rs = RenderStats {
            rays: (w * h) as u64,
            rays_hit: hit,
            samples: counts_total.samples,
            interpolations: counts_total.samples,
            gradient_interpolations: 6 * counts_total.shaded,
            early_terminated: counts_total.terminated,
            capped_paths: 0,
            seconds: start.elapsed().as_secs_f64(),
            device_seconds: None,
            simd: packets,
            skipping_left_out: None,
            block_size: 0,
        };
        Ok((pixels, rs, stats))
    }
}

/// A box `[lo, hi)` of chunk indices of one level.
pub type ChunkBox = ([u64; 3], [u64; 3]);

/// The image of premultiplied `pixels` (linear RGBA, as
/// [`OutOfCore::render_part`] gives them) over the sRGB `background`.
pub fn with_background(
    pixels: Vec<[f32; 4]>,
    width: u32,
    height: u32,
    background: [f32; 3],
) -> Image {
    let bg = Vec3::from(background.map(srgb_to_linear));
    let pixels = pixels
        .into_par_iter()
        .map(|[r, g, b, a]| {
            let rgb = Vec3::new(r, g, b) + bg * (1.0 - a);
            [rgb.x, rgb.y, rgb.z, a]
        })
        .collect();
    Image {
        width,
        height,
        pixels,
    }
}

/// A window of one value widened to one unit around it (as the renderer
/// classifies).
pub(crate) fn widen(window: [f32; 2]) -> [f32; 2] {
    if window[0] == window[1] {
        [window[0] - 0.5, window[0] + 0.5]
    } else {
        window
    }
}

/// What the store knows of every chunk of level `lidx` (x fastest), in
/// parallel.
fn chunk_ranges(source: &dyn ChunkedSource, lidx: usize) -> Vec<ChunkRange> {
    let level = &source.levels()[lidx];
    let n = level.chunk_counts().iter().product::<u64>();
    (0..n)
        .into_par_iter()
        .map(|i| source.chunk_range(lidx, level.chunk_at(i)))
        .collect()
}

/// Whether every value in `[lo, hi]` is transparent under `tf` over the
/// (widened) `window`.
pub(crate) fn range_transparent(tf: &TransferFunction, window: [f32; 2], lo: f32, hi: f32) -> bool {
    let (a, b) = (
        (lo - window[0]) / (window[1] - window[0]),
        (hi - window[0]) / (window[1] - window[0]),
    );
    b < 0.0 || tf.max_opacity_in(a.max(0.0), b.min(1.0)) <= 0.0
}

/// Whether a chunk is known to be transparent without reading it.
pub(crate) fn known_empty(tf: &TransferFunction, window: [f32; 2], r: &ChunkRange) -> bool {
    match *r {
        ChunkRange::Fill(v) => v.is_nan() || range_transparent(tf, window, v, v),
        ChunkRange::Range(a, b) => range_transparent(tf, window, a, b),
        ChunkRange::Unknown => false,
    }
}

/// The pixel rectangle `[x0, x1, y0, y1]` the box `[lo, hi]` (world) may
/// cover; `None` when it is off the image.
fn screen_rect(cam: &Camera, lo: Vec3, hi: Vec3, w: u32, h: u32) -> Option<[u32; 4]> {
    let (mut x0, mut x1, mut y0, mut y1) = (
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::INFINITY,
        f32::NEG_INFINITY,
    );
    for i in 0..8 {
        let p = Vec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        );
        match cam.project(p) {
            Some((x, y)) => {
                x0 = x0.min(x);
                x1 = x1.max(x);
                y0 = y0.min(y);
                y1 = y1.max(y);
            }
            // A corner behind the eye: the box may cover any pixel.
            None => return Some([0, w, 0, h]),
        }
    }
    // One pixel of margin for rounding.
    let cx = |v: f32| (v.max(-1.0).min(w as f32 + 1.0)) as i64;
    let cy = |v: f32| (v.max(-1.0).min(h as f32 + 1.0)) as i64;
    let r = [
        (cx(x0.floor()) - 1).max(0) as u32,
        (cx(x1.ceil()) + 1).min(w as i64) as u32,
        (cy(y0.floor()) - 1).max(0) as u32,
        (cy(y1.ceil()) + 1).min(h as i64) as u32,
    ];
    (r[0] < r[1] && r[2] < r[3]).then_some(r)
}

// Its tests render, so they are integration tests (tests/outofcore.rs): a
// unit test that renders makes the library's test build compile every SIMD
// ray loop a second time.
