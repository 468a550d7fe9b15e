//! The CPU renderer: the image is cut into tiles, rayon renders the tiles in
//! parallel, each pixel runs one ray loop. The loop is generic over the voxel
//! type and the optical model, so the per-sample path has no dynamic
//! dispatch, no allocation and no locks.

pub mod blocks;
mod composite;
mod job;
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
use crate::transfer::{Lut, TransferFunction};
use crate::volume::Volume;
use job::Job;
pub use march::{AdaptiveParams, ThresholdParams};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Instant;

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
