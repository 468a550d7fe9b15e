//! The CPU renderer: the image is cut into tiles, rayon renders the tiles in
//! parallel, each pixel runs one ray loop. The loop is generic over the voxel
//! type and the optical model, so the per-sample path has no dynamic
//! dispatch, no allocation and no locks.

pub mod blocks;
pub mod march;
pub mod optics;
pub mod shading;
pub mod stats;

pub use blocks::BlockGrid;
pub use optics::OpticalModel;
pub use stats::RenderStats;

use crate::camera::{Camera, CameraParams};
use crate::error::{Error, Result};
use crate::image::Image;
use crate::transfer::{srgb_to_linear, Lut, TransferFunction};
use crate::volume::{Grid, GridVisitor, Volume, Voxel};
use glam::{Vec3, Vec4};
use march::{intersect_box, Marcher, Uniform};
use optics::{over_back, over_front, AbsorptionOnly, EmissionAbsorption, EmissionOnly, Optics};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use shading::BlinnPhong;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

/// Where samples go along the ray (DESIGN.md axis 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Equal steps of `step` voxels (S4).
    #[default]
    Uniform,
    /// S0: a step per block from the frequency `F = k·|MN|/|MS|`, with `k`
    /// the largest partial derivative at the block's midpoint.
    Adaptive,
    /// S0's frequency with `k` the block's largest gradient magnitude instead
    /// of the midpoint's (the midpoint can miss a thin feature).
    AdaptiveMax,
    /// Zeng et al. 2018: the step depends on the value range the current
    /// sample falls into.
    Threshold,
}

impl Method {
    pub const ALL: [Method; 4] = [
        Method::Uniform,
        Method::Adaptive,
        Method::AdaptiveMax,
        Method::Threshold,
    ];

    /// The name used on the command line and in scene files.
    pub fn name(self) -> &'static str {
        match self {
            Method::Uniform => "uniform",
            Method::Adaptive => "adaptive",
            Method::AdaptiveMax => "adaptive-max",
            Method::Threshold => "threshold",
        }
    }

    /// Parses a method name.
    pub fn parse(s: &str) -> Option<Method> {
        Method::ALL.into_iter().find(|m| m.name() == s)
    }
}

/// A method as written on the command line: a marcher name optionally
/// followed by `+grouped` (S0's grouped interpolation), e.g.
/// `adaptive+grouped`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MethodSpec {
    pub method: Method,
    pub grouped: bool,
}

impl MethodSpec {
    /// Parses `NAME[+grouped]`.
    pub fn parse(s: &str) -> Result<MethodSpec> {
        let mut parts = s.trim().split('+');
        let name = parts.next().unwrap_or("");
        let method = Method::parse(name).ok_or_else(|| {
            let names: Vec<&str> = Method::ALL.iter().map(|m| m.name()).collect();
            Error::invalid(format!(
                "method `{s}`: unknown sampling method `{name}` (known: {}; add +grouped for grouped interpolation)",
                names.join(", ")
            ))
        })?;
        let mut grouped = false;
        for p in parts {
            match p {
                "grouped" => grouped = true,
                _ => {
                    return Err(Error::invalid(format!(
                        "method `{s}`: unknown modifier `+{p}` (known: +grouped)"
                    )))
                }
            }
        }
        Ok(MethodSpec { method, grouped })
    }

    /// Sets the method and modifiers of `params`.
    pub fn apply(&self, params: &mut RenderParams) {
        params.method = self.method;
        params.grouped = self.grouped;
    }

    /// Reads the spec back from `params`.
    pub fn of(params: &RenderParams) -> MethodSpec {
        MethodSpec {
            method: params.method,
            grouped: params.grouped,
        }
    }
}

impl std::fmt::Display for MethodSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.method.name())?;
        if self.grouped {
            f.write_str("+grouped")?;
        }
        Ok(())
    }
}

/// Compositing order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Order {
    /// Front to back, with early ray termination.
    #[default]
    FrontToBack,
    /// Back to front (no early termination possible).
    BackToFront,
}

/// Everything about a render that is not the volume, the transfer function
/// or the camera.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct RenderParams {
    pub width: u32,
    pub height: u32,
    pub method: Method,
    /// Step length in voxels (of the smallest spacing).
    pub step: f32,
    /// Early ray termination: stop when accumulated opacity reaches this
    /// (1 disables).
    pub ert: f32,
    pub order: Order,
    pub optical: OpticalModel,
    /// Gradient Blinn–Phong shading.
    pub shading: bool,
    /// Background colour, sRGB 0…1.
    pub background: [f32; 3],
    /// Seed for the stochastic methods and jitter (the same scene and seed
    /// give the same image).
    pub seed: u64,
    /// S0 grouped interpolation: farther samples reuse the value of the
    /// first sample of their group of 2 or 3.
    pub grouped: bool,
    /// Empty-space skipping over blocks whose values are all transparent.
    pub skip_empty: bool,
    /// A random start offset in [0, Δ) per pixel, against wood-grain artefacts.
    pub jitter: bool,
}

impl Default for RenderParams {
    fn default() -> Self {
        RenderParams {
            width: 512,
            height: 512,
            method: Method::Uniform,
            step: 0.5,
            ert: 0.99,
            order: Order::FrontToBack,
            optical: OpticalModel::EmissionAbsorption,
            shading: true,
            background: [0.0, 0.0, 0.0],
            seed: 0,
            grouped: false,
            skip_empty: true,
            jitter: false,
        }
    }
}

impl RenderParams {
    /// Checks the numbers a user may get wrong.
    pub fn validate(&self) -> Result<()> {
        if self.width == 0 || self.height == 0 || self.width > 16384 || self.height > 16384 {
            return Err(Error::invalid(format!(
                "image size {}×{}: each side must be 1…16384 pixels",
                self.width, self.height
            )));
        }
        if !(self.step.is_finite() && self.step >= 1e-3 && self.step <= 64.0) {
            return Err(Error::invalid(format!(
                "step {}: must be between 0.001 and 64 voxels",
                self.step
            )));
        }
        if !(self.ert > 0.0 && self.ert <= 1.0) {
            return Err(Error::invalid(format!(
                "ert {}: the termination threshold must be in (0, 1] (1 disables it)",
                self.ert
            )));
        }
        if self.background.iter().any(|c| !(0.0..=1.0).contains(c)) {
            return Err(Error::invalid("background: each component must be in 0…1"));
        }
        Ok(())
    }
}

/// Side of a square tile in pixels.
const TILE: u32 = 16;

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
    blocks: BlockGrid,
}

impl<'v> Renderer<'v> {
    /// Prepares `volume` for rendering with data values `window[0]…window[1]`
    /// mapped to 0…1. A window of zero width (a constant volume) is widened
    /// by ±0.5 so it still normalises.
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
        let blocks = volume.visit(
            window[0],
            window[1],
            blocks::BuildBlocks {
                size: blocks::DEFAULT_BLOCK,
            },
        );
        Ok(Renderer {
            volume,
            window,
            blocks,
        })
    }

    /// The volume.
    pub fn volume(&self) -> &Volume {
        self.volume
    }

    /// The data window in use.
    pub fn window(&self) -> [f32; 2] {
        self.window
    }

    /// The block grid.
    pub fn blocks(&self) -> &BlockGrid {
        &self.blocks
    }

    /// Renders with `tf`, seen by `camera`.
    pub fn render(
        &self,
        tf: &TransferFunction,
        camera: &CameraParams,
        params: &RenderParams,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<(Image, RenderStats)> {
        params.validate()?;
        let start = Instant::now();
        let volume = self.volume;
        let (lo, hi) = volume.world_bounds();
        let cam = Camera::fit(camera, lo, hi, params.width, params.height);
        let unit = volume.spacing().min_element();
        let job = Job {
            volume,
            lut: Lut::new(tf, params.step),
            cam,
            params,
            unit,
            progress,
        };
        let (image, mut stats) = volume.visit(self.window[0], self.window[1], job);
        stats.seconds = start.elapsed().as_secs_f64();
        Ok((image, stats))
    }
}

struct Job<'a> {
    volume: &'a Volume,
    lut: Lut,
    cam: Camera,
    params: &'a RenderParams,
    unit: f32,
    progress: &'a (dyn Fn(usize, usize) + Sync),
}

impl GridVisitor for Job<'_> {
    type Output = (Image, RenderStats);
    fn visit<T: Voxel>(self, grid: &Grid<'_, T>) -> Self::Output {
        match self.params.optical {
            OpticalModel::AbsorptionOnly => self.run::<T, AbsorptionOnly>(grid),
            OpticalModel::EmissionOnly => self.run::<T, EmissionOnly>(grid),
            OpticalModel::EmissionAbsorption => self.run::<T, EmissionAbsorption>(grid),
        }
    }
}

/// Per-ray constants.
struct RayCtx<'g, 'l, T> {
    grid: &'g Grid<'g, T>,
    lut: &'l Lut,
    /// Box through the voxel centres, in voxel coordinates.
    box_lo: Vec3,
    box_hi: Vec3,
    origin_w: Vec3,
    inv_spacing: Vec3,
    step: f32,
    unit: f32,
    ert: f32,
    back_to_front: bool,
    shading: Option<BlinnPhong>,
}

impl Job<'_> {
    fn run<T: Voxel, O: Optics>(&self, grid: &Grid<'_, T>) -> (Image, RenderStats) {
        let (w, h) = (self.params.width, self.params.height);
        let dims = self.volume.dims();
        // A one-voxel axis gets a one-voxel-thick box so it can be seen.
        let axis = |d: usize| {
            if d > 1 {
                (0.0, (d - 1) as f32)
            } else {
                (-0.5, 0.5)
            }
        };
        let (ax, ay, az) = (axis(dims[0]), axis(dims[1]), axis(dims[2]));
        let ctx = RayCtx {
            grid,
            lut: &self.lut,
            box_lo: Vec3::new(ax.0, ay.0, az.0),
            box_hi: Vec3::new(ax.1, ay.1, az.1),
            origin_w: self.volume.origin(),
            inv_spacing: Vec3::ONE / self.volume.spacing(),
            step: self.params.step * self.unit,
            unit: self.unit,
            ert: self.params.ert,
            back_to_front: self.params.order == Order::BackToFront,
            shading: self.params.shading.then(BlinnPhong::default),
        };
        let tiles_x = w.div_ceil(TILE);
        let tiles_y = h.div_ceil(TILE);
        let total = (tiles_x * tiles_y) as usize;
        let done = AtomicUsize::new(0);
        let bg = Vec3::from(self.params.background.map(srgb_to_linear));
        let tiles: Vec<(u32, u32, Vec<[f32; 4]>, RenderStats)> = (0..tiles_x * tiles_y)
            .into_par_iter()
            .map(|ti| {
                let (tx, ty) = (ti % tiles_x * TILE, ti / tiles_x * TILE);
                let mut stats = RenderStats::default();
                let mut scratch: Vec<(Vec3, f32)> = Vec::new();
                let mut px = Vec::with_capacity((TILE * TILE) as usize);
                for y in ty..(ty + TILE).min(h) {
                    for x in tx..(tx + TILE).min(w) {
                        let (o, d) = self.cam.ray(x, y);
                        let c = trace::<T, O>(&ctx, o, d, &mut stats, &mut scratch);
                        let rgb = c.truncate() + bg * (1.0 - c.w);
                        px.push([rgb.x, rgb.y, rgb.z, c.w]);
                    }
                }
                let n = done.fetch_add(1, Ordering::Relaxed) + 1;
                (self.progress)(n, total);
                (tx, ty, px, stats)
            })
            .collect();
        let mut image = Image::new(w, h);
        let mut stats = RenderStats::default();
        for (tx, ty, px, s) in tiles {
            stats.add(&s);
            let tw = (tx + TILE).min(w) - tx;
            for (i, p) in px.into_iter().enumerate() {
                let (x, y) = (tx + i as u32 % tw, ty + i as u32 / tw);
                image.set(x, y, p);
            }
        }
        (image, stats)
    }
}

/// One ray: returns premultiplied linear colour and opacity (before the
/// background).
#[inline]
fn trace<T: Voxel, O: Optics>(
    ctx: &RayCtx<'_, '_, T>,
    origin: Vec3,
    dir: Vec3,
    stats: &mut RenderStats,
    scratch: &mut Vec<(Vec3, f32)>,
) -> Vec4 {
    stats.rays += 1;
    // Ray in voxel coordinates; t stays in world units.
    let o = (origin - ctx.origin_w) * ctx.inv_spacing;
    let d = dir * ctx.inv_spacing;
    let Some((t_in, t_out)) = intersect_box(o, Vec3::ONE / d, ctx.box_lo, ctx.box_hi) else {
        return Vec4::ZERO;
    };
    stats.rays_hit += 1;
    let mut marcher = Uniform::new(t_in, t_out, ctx.step);
    let mut acc_c = Vec3::ZERO;
    let mut acc_a = 0.0f32;
    // Counted in locals: the loop keeps them in registers.
    let (mut samples, mut shaded) = (0u64, 0u64);
    scratch.clear();
    let view = -dir;
    while let Some((t, ds)) = marcher.next_sample() {
        samples += 1;
        let p = o + d * t;
        let v = ctx.grid.sample(p);
        let Some(i) = Lut::index(v) else { continue };
        let e = ctx.lut.entry(i);
        let alpha = if ds == ctx.step {
            e[3]
        } else {
            // Opacity correction for a partial step (S4).
            1.0 - (-ctx.lut.sigma(i) * ds / ctx.unit).exp()
        };
        if alpha <= 0.0 {
            continue;
        }
        let mut rgb = Vec3::new(e[0], e[1], e[2]);
        if let Some(sh) = &ctx.shading {
            let g = ctx.grid.gradient(p);
            shaded += 1;
            rgb = sh.shade(rgb, g, ctx.inv_spacing, view);
        }
        let (em, ab) = O::contribution(rgb, alpha);
        if ctx.back_to_front {
            scratch.push((em, ab));
        } else {
            over_front(&mut acc_c, &mut acc_a, em, ab);
            if acc_a >= ctx.ert && ctx.ert < 1.0 {
                stats.early_terminated += 1;
                break;
            }
        }
    }
    stats.samples += samples;
    // Every sample reconstructs its value once (no reuse in this marcher).
    stats.interpolations += samples;
    stats.gradient_interpolations += 6 * shaded;
    if ctx.back_to_front {
        for &(em, ab) in scratch.iter().rev() {
            over_back(&mut acc_c, &mut acc_a, em, ab);
        }
    }
    acc_c.extend(acc_a)
}
