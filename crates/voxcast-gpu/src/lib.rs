//! The GPU back end of voxcast: the CPU ray caster of
//! [`voxcast::render`] as a wgpu compute shader (WGSL), one invocation per
//! pixel, computing the same picture.
//!
//! The volume lives in a 3D texture (`r8unorm` for 8-bit data, `r16float`
//! for 16-bit data whose values f16 holds exactly, `r32float` otherwise),
//! the transfer function in a 1D texture (the CPU's 4096-entry table:
//! linear colour and extinction per unit length), the block grid's
//! emptiness flags in a storage buffer. The shader reconstructs values with
//! eight texel loads and the CPU's clamping, walks the same block grid with
//! the same 3D DDA, uses the same opacity correction, adaptive levels,
//! grouped reuse and early ray termination, and the same seeded random
//! sequences (SplitMix64 and PCG32 emulated with pairs of `u32`), so a GPU
//! render matches the CPU render to float rounding (PSNR well above 40 dB;
//! `tests/parity.rs`).
//!
//! # API
//!
//! ```no_run
//! use voxcast_gpu::{DeviceChoice, GpuContext, GpuRenderer};
//! # fn main() -> Result<(), voxcast_gpu::GpuError> {
//! # let scene = voxcast::scene::Scene::default();
//! # let prepared = scene.prepare()?;
//! // Once: pick an adapter (errors name the backends and adapters tried).
//! let ctx = GpuContext::new(DeviceChoice::Gpu)?;
//! eprintln!("{}", ctx.info());
//! // Once per volume: uploads the 3D texture and builds the block grid.
//! let renderer = GpuRenderer::new(ctx, &prepared.volume, prepared.window)?;
//! // Per frame: the transfer function and the camera are cheap to change
//! // (a 64 KiB table and the block flags are re-uploaded only when the
//! // transfer function changes).
//! let (image, stats) = renderer.render(&prepared.tf, &scene.camera, &scene.render)?;
//! # let _ = (image, stats); Ok(()) }
//! ```
//!
//! * [`GpuContext::new`] / [`GpuContext::probe`]: adapter selection.
//!   [`DeviceChoice::Gpu`] takes any adapter of the enabled backends
//!   (Vulkan; `WGPU_BACKEND` is honoured), software ones such as lavapipe
//!   included; [`DeviceChoice::Auto`] takes only hardware adapters and
//!   returns [`GpuError::NoAdapter`] otherwise, so the caller can fall back
//!   to the CPU renderer knowingly. Neither ever falls back silently.
//! * [`GpuRenderer::render`] returns the core's [`Image`] (linear RGBA,
//!   composited over the background) and [`RenderStats`], like
//!   [`voxcast::render::Renderer::render`].
//!
//! # Supported
//!
//! Methods `uniform`, `adaptive`, `adaptive-max`, `threshold` (each with
//! `+grouped` and `+noskip`), `jitter`, `stratified`, `mc` (progressive over
//! `spp`, in dispatches of at most eight passes), the
//! three optical models, shading, both compositing orders (back to front is
//! computed front to back without early termination, which is the same
//! sum); `single-scatter` (optical model 4: delta tracking, ratio-tracked
//! shadow rays to directional and point lights, one phase-sampled shadow ray
//! to environment and sky lights; isotropic, HG, Schlick, Rayleigh and Mie
//! phase functions; grid or global majorant — the CPU's random numbers, so
//! the same image); opaque axis-aligned boxes and planes (bounded or
//! infinite) with Blinn–Phong lighting and smoke shadows
//! ([`GpuRenderer::with_geometry`]); volumes larger than the device's 3D
//! texture limit, split into up to eight bricks ([`Bricking`]).
//!
//! Not yet: `importance`, `lod`, `path`, triangle meshes (OBJ),
//! volumes that need more than eight bricks; each is refused with an error
//! naming it.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use voxcast::camera::{Camera, CameraParams, Projection};
use voxcast::render::blocks::{BuildBlocks, BuildMaxGradient, DEFAULT_BLOCK};
use voxcast::render::{BlockGrid, Method, OpticalModel, Order, RenderParams, RenderStats};
use voxcast::transfer::{srgb_to_linear, Lut, TransferFunction, LUT_SIZE};
use voxcast::volume::{Volume, VoxelData};
use voxcast::Image;
use wgpu::util::DeviceExt;

/// What went wrong on the GPU side.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No adapter fit the request; the message lists what was tried.
    #[error("no GPU adapter: {0}")]
    NoAdapter(String),
    /// The adapter would not give a device, or the device failed.
    #[error("GPU device: {0}")]
    Device(String),
    /// A feature of the scene the GPU renderer does not have.
    #[error("not supported on the GPU back end: {0}")]
    Unsupported(String),
    /// An error of the core library (bad parameters, I/O).
    #[error(transparent)]
    Core(#[from] voxcast::Error),
}

/// Which device to render on, as given by `--device`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DeviceChoice {
    /// Any adapter of the enabled backends, software ones included.
    Gpu,
    /// A hardware adapter only (discrete, integrated or virtual GPU).
    Auto,
}

/// Names of the backends this build can use, e.g. `"vulkan"`.
pub fn compiled_backends() -> &'static str {
    "vulkan"
}

fn backend_names(b: wgpu::Backends) -> String {
    let mut v = Vec::new();
    for (flag, name) in [
        (wgpu::Backends::VULKAN, "vulkan"),
        (wgpu::Backends::METAL, "metal"),
        (wgpu::Backends::DX12, "dx12"),
        (wgpu::Backends::GL, "gl"),
        (wgpu::Backends::BROWSER_WEBGPU, "webgpu"),
    ] {
        if b.contains(flag) {
            v.push(name);
        }
    }
    if v.is_empty() {
        "none".into()
    } else {
        v.join(", ")
    }
}

/// An adapter and its device and queue, shared by the renderers.
pub struct GpuContext {
    adapter: wgpu::Adapter,
    device: wgpu::Device,
    queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
}

/// One adapter found by [`GpuContext::probe`].
#[derive(Clone, Debug)]
pub struct AdapterSummary {
    pub name: String,
    pub backend: String,
    pub device_type: String,
    pub driver: String,
}

impl std::fmt::Display for AdapterSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} ({}, {}{})",
            self.name,
            self.backend,
            self.device_type,
            if self.driver.is_empty() {
                String::new()
            } else {
                format!(", {}", self.driver)
            }
        )
    }
}

fn summary(info: &wgpu::AdapterInfo) -> AdapterSummary {
    AdapterSummary {
        name: info.name.clone(),
        backend: format!("{:?}", info.backend).to_lowercase(),
        device_type: match info.device_type {
            wgpu::DeviceType::DiscreteGpu => "discrete GPU",
            wgpu::DeviceType::IntegratedGpu => "integrated GPU",
            wgpu::DeviceType::VirtualGpu => "virtual GPU",
            wgpu::DeviceType::Cpu => "software (CPU)",
            wgpu::DeviceType::Other => "other",
        }
        .into(),
        driver: [info.driver.as_str(), info.driver_info.as_str()]
            .iter()
            .filter(|s| !s.is_empty())
            .copied()
            .collect::<Vec<_>>()
            .join(" "),
    }
}

fn is_hardware(t: wgpu::DeviceType) -> bool {
    matches!(
        t,
        wgpu::DeviceType::DiscreteGpu
            | wgpu::DeviceType::IntegratedGpu
            | wgpu::DeviceType::VirtualGpu
    )
}

fn rank(t: wgpu::DeviceType) -> u32 {
    match t {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    }
}

impl GpuContext {
    /// The backends to try: those compiled in, narrowed by `WGPU_BACKEND`.
    fn instance() -> (wgpu::Instance, wgpu::Backends) {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
        if std::env::var_os("WGPU_BACKEND").is_none() {
            desc.backends = wgpu::Backends::VULKAN;
        }
        let backends = desc.backends;
        (wgpu::Instance::new(desc), backends)
    }

    /// All adapters the enabled backends offer, and the backends tried.
    pub fn probe() -> (Vec<AdapterSummary>, String) {
        let (instance, backends) = Self::instance();
        let adapters = pollster::block_on(instance.enumerate_adapters(backends));
        (
            adapters.iter().map(|a| summary(&a.get_info())).collect(),
            backend_names(backends),
        )
    }

    /// Opens a device on the best adapter allowed by `choice` (discrete
    /// first, software last). Never falls back to another backend: with no
    /// fitting adapter the error says which backends and adapters were
    /// tried.
    pub fn new(choice: DeviceChoice) -> Result<Arc<GpuContext>, GpuError> {
        let (instance, backends) = Self::instance();
        let adapters = pollster::block_on(instance.enumerate_adapters(backends));
        let found: Vec<String> = adapters
            .iter()
            .map(|a| summary(&a.get_info()).to_string())
            .collect();
        let tried = format!(
            "tried backends [{}] (compiled in: {}; WGPU_BACKEND={}); adapters found: {}",
            backend_names(backends),
            compiled_backends(),
            std::env::var("WGPU_BACKEND").unwrap_or_else(|_| "unset".into()),
            if found.is_empty() {
                "none".to_string()
            } else {
                found.join("; ")
            }
        );
        let adapter = adapters
            .into_iter()
            .filter(|a| choice == DeviceChoice::Gpu || is_hardware(a.get_info().device_type))
            .min_by_key(|a| rank(a.get_info().device_type))
            .ok_or_else(|| {
                let hint = match choice {
                    DeviceChoice::Auto => "no hardware adapter",
                    DeviceChoice::Gpu => {
                        "no adapter at all (install a Vulkan driver: your GPU's, or Mesa's lavapipe from the `mesa-vulkan-drivers` package)"
                    }
                };
                GpuError::NoAdapter(format!("{hint}; {tried}"))
            })?;
        let info = adapter.get_info();
        let alimits = adapter.limits();
        let limits = wgpu::Limits {
            max_texture_dimension_3d: alimits.max_texture_dimension_3d,
            max_texture_dimension_1d: alimits.max_texture_dimension_1d.max(LUT_SIZE as u32),
            max_storage_buffer_binding_size: alimits.max_storage_buffer_binding_size,
            max_buffer_size: alimits.max_buffer_size,
            ..wgpu::Limits::default()
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("voxcast"),
            required_features: wgpu::Features::empty(),
            required_limits: limits,
            ..Default::default()
        }))
        .map_err(|e| GpuError::Device(format!("{} refused a device: {e}", info.name)))?;
        Ok(Arc::new(GpuContext {
            adapter,
            device,
            queue,
            info,
        }))
    }

    /// The adapter in use, in words (name, backend, type, driver).
    pub fn info(&self) -> String {
        summary(&self.info).to_string()
    }

    /// Whether the adapter is a software rasteriser (lavapipe, SwiftShader).
    pub fn is_software(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// The adapter's limits.
    pub fn limits(&self) -> wgpu::Limits {
        self.adapter.limits()
    }
}

/// Describes the adapter [`GpuContext::new`] would pick for `choice`,
/// without keeping it, or the error naming what was tried.
pub fn adapter_info(choice: DeviceChoice) -> Result<String, GpuError> {
    GpuContext::new(choice).map(|c| c.info())
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    eye: [f32; 4],
    forward: [f32; 4],
    right: [f32; 4],
    up: [f32; 4],
    origin_w: [f32; 4],
    inv_spacing: [f32; 4],
    box_lo: [f32; 4],
    box_hi: [f32; 4],
    grid_max: [f32; 4],
    background: [f32; 4],
    dims: [u32; 4],
    counts: [u32; 4],
    size: [u32; 4],
    seed: [u32; 4],
    levels: [i32; 4],
    /// Geometry and lights: shape records, shadows, light records, phase kind.
    geo: [u32; 4],
    /// Surface key light: direction towards it; w unused.
    surf_dir: [f32; 4],
    /// Surface Blinn–Phong: ambient, diffuse, specular, shininess.
    surf_k: [f32; 4],
    /// Medium: world → voxel offset, w: σ_t at density 1.
    med_offset: [f32; 4],
    /// Medium: world → voxel scale, w: phase parameter (g or k).
    med_scale: [f32; 4],
    /// Medium: the box's far corner (voxels), w: global majorant.
    med_hi: [f32; 4],
    /// Medium: albedo, w: 1 for the global majorant, 0 for the grid.
    med_albedo: [f32; 4],
    /// Medium: has infinite lights, unused ×3.
    med_flags: [u32; 4],
    /// Bricks per axis, w: their product.
    bricks: [u32; 4],
    /// Cells per brick along each axis.
    brick_cells: [u32; 4],
    /// The passes of one dispatch: first, end (exclusive).
    chunk: [u32; 4],
    /// Threshold: range bounds, steps of ranges 0 and 1 (voxels).
    thresh: [f32; 4],
    /// Threshold: step of range 2 (voxels).
    thresh2: [f32; 4],
}

/// Passes per dispatch of the progressive methods: a render of many passes
/// is split into dispatches of at most this many, each adding to the sums
/// the one before left, so no single dispatch runs long enough to trip a
/// GPU watchdog (about 2 s on desktop drivers).
const PASSES_PER_DISPATCH: u32 = 8;

/// Texture slots for bricks (bindings 1 and 9…15).
const MAX_BRICKS: usize = 8;
/// `vec4` records per shape and per light in the scene buffer.
const SHAPE_WORDS: usize = 6;
const LIGHT_WORDS: usize = 4;

const F_SHADING: u32 = 1;
const F_GROUPED: u32 = 2;
const F_JITTER: u32 = 4;
const F_SKIP: u32 = 8;

/// The shader's method numbers.
fn method_code(m: Method) -> Result<u32, GpuError> {
    Ok(match m {
        Method::Uniform => 0,
        Method::Adaptive => 1,
        Method::AdaptiveMax => 2,
        Method::Jitter => 3,
        Method::Mc => 4,
        Method::Stratified => 5,
        Method::SingleScatter => 6,
        Method::Threshold => 7,
        other => {
            return Err(GpuError::Unsupported(format!(
                "method `{}` (the GPU renders uniform, adaptive, adaptive-max, threshold, jitter, stratified, mc and single-scatter; use --device cpu for `{}`)",
                other.name(),
                other.name()
            )))
        }
    })
}

/// Whether the GPU back end renders `method`: `uniform`, `adaptive`,
/// `adaptive-max`, `threshold`, `jitter`, `stratified`, `mc` and
/// `single-scatter` (not `importance`, `lod`, `path`). Opaque geometry is a separate
/// question, [`GpuRenderer::supports_geometry`]: boxes and planes yes,
/// triangle meshes no (`single-scatter` takes no geometry on either back
/// end).
pub fn supports(method: Method) -> bool {
    method_code(method).is_ok()
}

/// The block grid of one block size, with its GPU buffers.
struct Blocks {
    grid: BlockGrid,
    /// Emptiness flags under the transfer function last uploaded.
    empty: wgpu::Buffer,
    /// Largest gradient component per block (for `adaptive-max`).
    max_grad: wgpu::Buffer,
    /// The transfer function the flags were computed for.
    tf: Option<TransferFunction>,
}

/// What changes between renders, kept behind a lock so [`GpuRenderer::render`]
/// can take `&self`.
struct State {
    blocks: HashMap<usize, Blocks>,
    lut_tf: Option<TransferFunction>,
    out: Option<(u64, wgpu::Buffer, wgpu::Buffer, wgpu::Buffer, wgpu::Buffer)>,
}

/// A volume uploaded to the GPU, ready to render with any transfer function,
/// camera and parameters (see the crate documentation).
pub struct GpuRenderer {
    ctx: Arc<GpuContext>,
    volume: Volume,
    window: [f32; 2],
    /// One view per texture slot (bricks, then repeats of the first).
    texture_views: Vec<wgpu::TextureView>,
    /// Bricks per axis and cells per brick (see [`Bricking`]).
    bricking: Bricking,
    /// Opaque boxes and planes (see [`GpuRenderer::with_geometry`]).
    geometry: Option<voxcast::geometry::Geometry>,
    lut_texture: wgpu::Texture,
    lut_view: wgpu::TextureView,
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    uniform: wgpu::Buffer,
    /// Stored → normalised: `texel·scale + offset`.
    scale: f32,
    offset: f32,
    format: wgpu::TextureFormat,
    state: Mutex<State>,
}

/// The texels to upload for `volume`, their format, and the map from texel
/// to normalised value.
fn texels(volume: &Volume, window: [f32; 2]) -> (Vec<u8>, wgpu::TextureFormat, f32, f32) {
    let (lo, hi) = (window[0], window[1]);
    let width = if hi > lo { hi - lo } else { 1.0 };
    let (scale, offset) = (1.0 / width, -lo / width);
    let f16_exact = |v: f32| v.abs() <= 2048.0;
    match volume.data() {
        // r8unorm stores v/255.
        VoxelData::U8(d) => (
            d.clone(),
            wgpu::TextureFormat::R8Unorm,
            scale * 255.0,
            offset,
        ),
        VoxelData::U16(d) if d.iter().all(|&v| f16_exact(v as f32)) => (
            d.iter()
                .flat_map(|&v| f16_bits(v as f32).to_le_bytes())
                .collect(),
            wgpu::TextureFormat::R16Float,
            scale,
            offset,
        ),
        VoxelData::I16(d) if d.iter().all(|&v| f16_exact(v as f32)) => (
            d.iter()
                .flat_map(|&v| f16_bits(v as f32).to_le_bytes())
                .collect(),
            wgpu::TextureFormat::R16Float,
            scale,
            offset,
        ),
        data => {
            // NaN/Inf render as empty, as on the CPU: a value normalising to −1.
            let empty = lo - width;
            let bytes = (0..data.len())
                .flat_map(|i| {
                    let v = data.get(i);
                    (if v.is_finite() { v } else { empty }).to_le_bytes()
                })
                .collect();
            (bytes, wgpu::TextureFormat::R32Float, scale, offset)
        }
    }
}

/// IEEE half bits of an integer-valued `v` with |v| ≤ 2048 (exact).
fn f16_bits(v: f32) -> u16 {
    if v == 0.0 {
        return 0;
    }
    let sign = if v < 0.0 { 0x8000u16 } else { 0 };
    let a = v.abs();
    let e = a.log2().floor() as i32;
    // Integers up to 2048 are normal halves: exponent e, 10 mantissa bits.
    let m = ((a / 2f32.powi(e) - 1.0) * 1024.0).round() as u16;
    sign | (((e + 15) as u16) << 10) | m
}

/// The environment variable that lowers the 3D texture limit (voxels per
/// side) below the device's, to exercise bricking on volumes that would fit.
pub const TEXTURE_LIMIT_ENV: &str = "VOXCAST_GPU_MAX_TEXTURE_3D";

fn env_texture_limit() -> Option<u32> {
    std::env::var(TEXTURE_LIMIT_ENV).ok()?.trim().parse().ok()
}

/// How a volume larger than the device's 3D texture limit is split.
///
/// Design: each axis whose voxel count exceeds the limit `L` is cut into
/// `n = ⌈(dims − 1)/(L − 1)⌉` equal runs of `C = ⌈(dims − 1)/n⌉` cells; a
/// brick holds the `C + 1` voxels of its cells (the last one fewer), so
/// neighbouring bricks share one plane of voxels. Every brick is its own 3D
/// texture (no side above `L`), bound in one of [`MAX_BRICKS`] fixed texture
/// slots (bindings 1 and 9…15: no binding-array feature needed). The shader
/// reconstructs a sample from the eight voxels of its cell, and with the
/// shared plane all eight lie in the brick that owns the cell's lower corner
/// (`⌊cell / C⌋` per axis — the page table is this division), so a bricked
/// render reads exactly the values of an unbricked one: the picture is the
/// same, seams included. Eight slots cover volumes up to about twice the
/// limit on every side (8192³ voxels at lavapipe's 4096, 4096³ at the 2048
/// of many GPUs), or eight times it along one axis; larger volumes are
/// refused with an error naming the sizes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Bricking {
    /// Bricks per axis.
    pub counts: [usize; 3],
    /// Cells per brick along each axis (the last brick may have fewer).
    pub cells: [usize; 3],
}

impl Bricking {
    /// The split of a volume of `dims` voxels for a limit of `limit` (≥ 2)
    /// voxels per texture side.
    pub fn new(dims: [usize; 3], limit: usize) -> Result<Bricking, GpuError> {
        let mut counts = [1; 3];
        let mut cells = [1; 3];
        for a in 0..3 {
            let n_cells = dims[a].saturating_sub(1).max(1);
            counts[a] = n_cells.div_ceil(limit - 1);
            cells[a] = n_cells.div_ceil(counts[a]);
        }
        let total: usize = counts.iter().product();
        if total > MAX_BRICKS {
            return Err(GpuError::Unsupported(format!(
                "volume of {}×{}×{} voxels: larger than this device's 3D texture limit of {limit} per side (max_texture_dimension_3d{}) even in {MAX_BRICKS} bricks (it would need {}×{}×{}); use --device cpu or downsample the volume",
                dims[0],
                dims[1],
                dims[2],
                if env_texture_limit().is_some() {
                    format!(", or {TEXTURE_LIMIT_ENV}")
                } else {
                    String::new()
                },
                counts[0],
                counts[1],
                counts[2]
            )));
        }
        Ok(Bricking { counts, cells })
    }

    /// Number of bricks.
    pub fn len(&self) -> usize {
        self.counts.iter().product()
    }

    /// Always false: a volume is at least one brick.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Brick coordinates in slot order (x fastest).
    fn all(&self) -> impl Iterator<Item = [usize; 3]> + '_ {
        let [nx, ny, nz] = self.counts;
        (0..nz).flat_map(move |k| (0..ny).flat_map(move |j| (0..nx).map(move |i| [i, j, k])))
    }

    /// First voxel and voxel counts of brick `b` of a volume of `dims`.
    fn extent(&self, b: [usize; 3], dims: [usize; 3]) -> ([usize; 3], [usize; 3]) {
        let mut lo = [0; 3];
        let mut size = [0; 3];
        for a in 0..3 {
            lo[a] = b[a] * self.cells[a];
            let hi = (lo[a] + self.cells[a]).min(dims[a] - 1);
            size[a] = hi - lo[a] + 1;
        }
        (lo, size)
    }
}

impl GpuRenderer {
    /// Uploads `volume` (values `window[0]…window[1]` map to 0…1, as on the
    /// CPU) and builds the default block grid.
    pub fn new(
        ctx: Arc<GpuContext>,
        volume: &Volume,
        window: [f32; 2],
    ) -> Result<GpuRenderer, GpuError> {
        Self::with_texture_limit(ctx, volume, window, None)
    }

    /// [`GpuRenderer::new`] with the 3D texture limit lowered to `max_side`
    /// voxels per side (`None`: the device's `max_texture_dimension_3d`, or
    /// `VOXCAST_GPU_MAX_TEXTURE_3D` when set and smaller), so bricking can
    /// be tried on volumes that would fit whole.
    pub fn with_texture_limit(
        ctx: Arc<GpuContext>,
        volume: &Volume,
        window: [f32; 2],
        max_side: Option<u32>,
    ) -> Result<GpuRenderer, GpuError> {
        // The CPU renderer's window checks and widening.
        let mut window = window;
        if window[0].is_finite() && window[0] == window[1] {
            window = [window[0] - 0.5, window[0] + 0.5];
        }
        if !(window[0].is_finite() && window[1].is_finite() && window[0] < window[1]) {
            return Err(voxcast::Error::invalid(format!(
                "window [{}, {}] must have lo < hi",
                window[0], window[1]
            ))
            .into());
        }
        let device_limit = ctx.limits().max_texture_dimension_3d;
        let limit = max_side
            .into_iter()
            .chain(env_texture_limit())
            .fold(device_limit, u32::min)
            .max(2) as usize;
        let bricking = Bricking::new(volume.dims(), limit)?;
        let (bytes, format, scale, offset) = texels(volume, window);
        scoped(
            &ctx.device,
            "uploading the volume and building the shader",
            || {
                Self::build(
                    ctx.clone(),
                    volume,
                    window,
                    bricking,
                    bytes,
                    format,
                    scale,
                    offset,
                )
            },
        )
    }

    #[allow(clippy::too_many_arguments)]
    fn build(
        ctx: Arc<GpuContext>,
        volume: &Volume,
        window: [f32; 2],
        bricking: Bricking,
        bytes: Vec<u8>,
        format: wgpu::TextureFormat,
        scale: f32,
        offset: f32,
    ) -> GpuRenderer {
        let dims = volume.dims();
        let device = &ctx.device;
        let bpp = format.block_copy_size(None).unwrap_or(4) as usize;
        let mut texture_views = Vec::with_capacity(MAX_BRICKS);
        for b in bricking.all() {
            let (lo, size) = bricking.extent(b, dims);
            // The brick's voxels, row by row.
            let mut data = Vec::with_capacity(size[0] * size[1] * size[2] * bpp);
            for k in lo[2]..lo[2] + size[2] {
                for j in lo[1]..lo[1] + size[1] {
                    let row = (lo[0] + dims[0] * (j + dims[1] * k)) * bpp;
                    data.extend_from_slice(&bytes[row..row + size[0] * bpp]);
                }
            }
            let extent = wgpu::Extent3d {
                width: size[0] as u32,
                height: size[1] as u32,
                depth_or_array_layers: size[2] as u32,
            };
            let texture = device.create_texture(&wgpu::TextureDescriptor {
                label: Some("volume brick"),
                size: extent,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D3,
                format,
                usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            });
            ctx.queue.write_texture(
                wgpu::TexelCopyTextureInfo {
                    texture: &texture,
                    mip_level: 0,
                    origin: wgpu::Origin3d::ZERO,
                    aspect: wgpu::TextureAspect::All,
                },
                &data,
                wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some((size[0] * bpp) as u32),
                    rows_per_image: Some(size[1] as u32),
                },
                extent,
            );
            texture_views.push(texture.create_view(&Default::default()));
        }
        drop(bytes);
        // Unused slots repeat the first brick (never read).
        while texture_views.len() < MAX_BRICKS {
            texture_views.push(texture_views[0].clone());
        }
        let lut_texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("transfer function"),
            size: wgpu::Extent3d {
                width: LUT_SIZE as u32,
                height: 1,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D1,
            format: wgpu::TextureFormat::Rgba32Float,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        let lut_view = lut_texture.create_view(&Default::default());
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("raycast.wgsl"),
            source: wgpu::ShaderSource::Wgsl(include_str!("raycast.wgsl").into()),
        });
        let storage = |binding: u32, read_only: bool| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let texture_entry =
            |binding: u32, dim: wgpu::TextureViewDimension| wgpu::BindGroupLayoutEntry {
                binding,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: false },
                    view_dimension: dim,
                    multisampled: false,
                },
                count: None,
            };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("raycast"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                texture_entry(1, wgpu::TextureViewDimension::D3),
                texture_entry(2, wgpu::TextureViewDimension::D1),
                storage(3, true),
                storage(4, true),
                storage(5, false),
                storage(6, false),
                storage(7, true),
                storage(8, true),
                texture_entry(9, wgpu::TextureViewDimension::D3),
                texture_entry(10, wgpu::TextureViewDimension::D3),
                texture_entry(11, wgpu::TextureViewDimension::D3),
                texture_entry(12, wgpu::TextureViewDimension::D3),
                texture_entry(13, wgpu::TextureViewDimension::D3),
                texture_entry(14, wgpu::TextureViewDimension::D3),
                texture_entry(15, wgpu::TextureViewDimension::D3),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("raycast"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("raycast"),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some("main"),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants: &[("BRICKED", if bricking.len() > 1 { 1.0 } else { 0.0 })],
                ..Default::default()
            },
            cache: None,
        });
        let uniform = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("params"),
            size: std::mem::size_of::<Params>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let r = GpuRenderer {
            ctx,
            volume: volume.clone(),
            window,
            texture_views,
            bricking,
            geometry: None,
            lut_texture,
            lut_view,
            pipeline,
            layout,
            uniform,
            scale,
            offset,
            format,
            state: Mutex::new(State {
                blocks: HashMap::new(),
                lut_tf: None,
                out: None,
            }),
        };
        {
            let mut st = r.state.lock().unwrap_or_else(|e| e.into_inner());
            r.blocks(&mut st, DEFAULT_BLOCK);
        }
        r
    }

    /// Adds opaque geometry: axis-aligned boxes and planes (bounded or
    /// infinite) are rendered on the GPU as on the CPU — the first hit ends
    /// the ray, the smoke in front is composited over the Blinn–Phong lit
    /// surface, with the optional smoke shadows. Triangle meshes (OBJ) are
    /// CPU-only and refused by name. `None` or an empty geometry: none.
    pub fn with_geometry(
        mut self,
        geometry: Option<&voxcast::geometry::Geometry>,
    ) -> Result<GpuRenderer, GpuError> {
        self.geometry = None;
        let Some(g) = geometry.filter(|g| !g.is_empty()) else {
            return Ok(self);
        };
        if g.counts()[2] > 0 {
            return Err(GpuError::Unsupported(format!(
                "triangle meshes (OBJ: {} meshes, {} triangles) are rendered on the CPU only; use --device cpu (boxes and planes are fine on the GPU)",
                g.counts()[2],
                g.counts()[3]
            )));
        }
        self.geometry = Some(g.clone());
        Ok(self)
    }

    /// Whether the GPU renders `geometry` (boxes and planes; not meshes).
    pub fn supports_geometry(geometry: Option<&voxcast::geometry::Geometry>) -> bool {
        geometry.is_none_or(|g| g.counts()[2] == 0)
    }

    /// How the volume was split into bricks (one brick when it fits).
    pub fn bricking(&self) -> Bricking {
        self.bricking
    }

    /// The data window in use.
    pub fn window(&self) -> [f32; 2] {
        self.window
    }

    /// The texture format the volume was uploaded in.
    pub fn texture_format(&self) -> &'static str {
        match self.format {
            wgpu::TextureFormat::R8Unorm => "r8unorm",
            wgpu::TextureFormat::R16Float => "r16float",
            _ => "r32float",
        }
    }

    /// The GPU context.
    pub fn context(&self) -> &Arc<GpuContext> {
        &self.ctx
    }

    fn blocks<'s>(&self, st: &'s mut State, size: usize) -> &'s mut Blocks {
        st.blocks.entry(size).or_insert_with(|| {
            let (lo, hi) = (self.window[0], self.window[1]);
            let grid = self.volume.visit(lo, hi, BuildBlocks { size });
            let maxg = self.volume.visit(lo, hi, BuildMaxGradient { size });
            let n = grid.range.len();
            let device = &self.ctx.device;
            let empty = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("empty blocks"),
                size: (n.max(1) * 4) as u64,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let max_grad = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("max gradient"),
                contents: bytemuck::cast_slice(&maxg),
                usage: wgpu::BufferUsages::STORAGE,
            });
            Blocks {
                grid,
                empty,
                max_grad,
                tf: None,
            }
        })
    }

    /// Renders with `tf`, seen by `camera` (progress is not reported: one
    /// dispatch renders the whole image).
    pub fn render(
        &self,
        tf: &TransferFunction,
        camera: &CameraParams,
        params: &RenderParams,
    ) -> Result<(Image, RenderStats), GpuError> {
        scoped(&self.ctx.device, "rendering", || {
            self.render_inner(tf, camera, params)
        })?
    }

    fn render_inner(
        &self,
        tf: &TransferFunction,
        camera: &CameraParams,
        params: &RenderParams,
    ) -> Result<(Image, RenderStats), GpuError> {
        params.validate_for(&self.volume)?;
        if let Some(l) = &camera.look_at {
            l.validate().map_err(voxcast::Error::invalid)?;
        }
        let method = method_code(params.method)?;
        let physical = params.method.is_physical();
        let geometry = self.geometry.as_ref().filter(|g| !g.is_empty());
        if physical && geometry.is_some() {
            // As the CPU renderer refuses it.
            return Err(voxcast::Error::invalid(format!(
                "method {}: opaque geometry is not supported by the physically based integrators yet; render without it (--geometry none) or use a ray-casting method",
                params.method.name()
            ))
            .into());
        }
        let start = Instant::now();
        let (w, h) = (params.width, params.height);
        let pixels = w as u64 * h as u64;
        let out_bytes = pixels * 16;
        let limits = self.ctx.limits();
        if out_bytes > limits.max_storage_buffer_binding_size {
            return Err(GpuError::Unsupported(format!(
                "image {w}×{h}: needs {} MiB of output buffer, more than this device's max_storage_buffer_binding_size of {} MiB",
                out_bytes >> 20,
                limits.max_storage_buffer_binding_size >> 20
            )));
        }
        let device = &self.ctx.device;
        let queue = &self.ctx.queue;
        let mut st = self.state.lock().unwrap_or_else(|e| e.into_inner());
        if st.lut_tf.as_ref() != Some(tf) {
            let lut = Lut::new(tf, 1.0);
            let mut data = Vec::with_capacity(LUT_SIZE * 4);
            for i in 0..LUT_SIZE {
                let e = lut.entry(i);
                data.extend_from_slice(&[e[0], e[1], e[2], lut.sigma(i)]);
            }
            queue.write_texture(
                wgpu::TexelCopyTextureInfo {
                    texture: &self.lut_texture,
                    mip_level: 0,
                    origin: wgpu::Origin3d::ZERO,
                    aspect: wgpu::TextureAspect::All,
                },
                bytemuck::cast_slice(&data),
                wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(LUT_SIZE as u32 * 16),
                    rows_per_image: None,
                },
                wgpu::Extent3d {
                    width: LUT_SIZE as u32,
                    height: 1,
                    depth_or_array_layers: 1,
                },
            );
            st.lut_tf = Some(tf.clone());
        }
        let blocks = self.blocks(&mut st, params.block_size as usize);
        if blocks.tf.as_ref() != Some(tf) {
            let flags: Vec<u32> = blocks
                .grid
                .empty_flags(tf)
                .into_iter()
                .map(u32::from)
                .collect();
            queue.write_buffer(&blocks.empty, 0, bytemuck::cast_slice(&flags));
            blocks.tf = Some(tf.clone());
        }
        let counts = blocks.grid.counts;
        let block_size = blocks.grid.size;

        // The camera, as the CPU frames it (the volume and the shapes).
        let (mut lo, mut hi) = self.volume.world_bounds();
        if let Some((glo, ghi)) = geometry.and_then(|g| g.bounds()) {
            (lo, hi) = (lo.min(glo), hi.max(ghi));
        }
        let cam = Camera::fit(camera, lo, hi, w, h);
        let projection = camera.projection;
        // Half extents of the image plane, recovered from the corner ray.
        let (o, d) = cam.ray_at(w as f32, 0.0);
        let (sx, sy) = match projection {
            Projection::Perspective => (
                d.dot(cam.right) / d.dot(cam.forward),
                d.dot(cam.up) / d.dot(cam.forward),
            ),
            Projection::Orthographic => ((o - cam.eye).dot(cam.right), (o - cam.eye).dot(cam.up)),
        };
        let dims = self.volume.dims();
        let (box_lo, box_hi) = self.volume.sample_box();
        let unit = self.volume.spacing().min_element();
        let inv = glam::Vec3::ONE / self.volume.spacing();
        let origin = self.volume.origin();
        let (level_lo, level_hi) =
            if matches!(params.method, Method::Adaptive | Method::AdaptiveMax) {
                params.adaptive.levels(params.step)
            } else {
                (0, 0)
            };
        let jitter = params.jitter || params.method == Method::Jitter;
        let passes = if params.method.is_stochastic() || params.jitter {
            params.spp
        } else {
            1
        };
        let ert = if params.order == Order::BackToFront {
            1.0
        } else {
            params.ert
        };
        let mut flags = 0;
        if params.shading {
            flags |= F_SHADING;
        }
        if params.grouped {
            flags |= F_GROUPED;
        }
        if jitter {
            flags |= F_JITTER;
        }
        if params.skip_empty {
            flags |= F_SKIP;
        }
        let seed = params.seed;
        let sm = voxcast::render::rng::splitmix(seed);
        let scene = SceneData::new(geometry, &cam, params, &self.volume, &blocks.grid);
        let bg = params.background.map(srgb_to_linear);
        let mut p = Params {
            eye: [
                cam.eye.x,
                cam.eye.y,
                cam.eye.z,
                (projection == Projection::Orthographic) as u32 as f32,
            ],
            forward: [cam.forward.x, cam.forward.y, cam.forward.z, sx],
            right: [cam.right.x, cam.right.y, cam.right.z, sy],
            up: [cam.up.x, cam.up.y, cam.up.z, 0.0],
            origin_w: [origin.x, origin.y, origin.z, unit],
            inv_spacing: [inv.x, inv.y, inv.z, params.step],
            box_lo: [box_lo.x, box_lo.y, box_lo.z, ert],
            box_hi: [box_hi.x, box_hi.y, box_hi.z, params.adaptive.k_ref],
            grid_max: [
                (dims[0] - 1) as f32,
                (dims[1] - 1) as f32,
                (dims[2] - 1) as f32,
                self.scale,
            ],
            background: [bg[0], bg[1], bg[2], self.offset],
            dims: [
                dims[0] as u32,
                dims[1] as u32,
                dims[2] as u32,
                block_size as u32,
            ],
            counts: [counts[0] as u32, counts[1] as u32, counts[2] as u32, method],
            size: [w, h, passes, flags],
            seed: [
                seed as u32,
                (seed >> 32) as u32,
                sm as u32,
                (sm >> 32) as u32,
            ],
            levels: [
                level_lo,
                level_hi,
                match params.optical {
                    OpticalModel::AbsorptionOnly => 0,
                    OpticalModel::EmissionOnly => 1,
                    OpticalModel::EmissionAbsorption => 2,
                },
                0,
            ],
            geo: scene.geo,
            surf_dir: scene.surf_dir,
            surf_k: scene.surf_k,
            med_offset: scene.med_offset,
            med_scale: scene.med_scale,
            med_hi: scene.med_hi,
            med_albedo: scene.med_albedo,
            med_flags: scene.med_flags,
            bricks: [
                self.bricking.counts[0] as u32,
                self.bricking.counts[1] as u32,
                self.bricking.counts[2] as u32,
                self.bricking.len() as u32,
            ],
            brick_cells: [
                self.bricking.cells[0] as u32,
                self.bricking.cells[1] as u32,
                self.bricking.cells[2] as u32,
                0,
            ],
            chunk: [0, passes, 0, 0],
            thresh: [
                params.threshold.bounds[0],
                params.threshold.bounds[1],
                params.threshold.steps[0],
                params.threshold.steps[1],
            ],
            thresh2: [params.threshold.steps[2], 0.0, 0.0, 0.0],
        };
        let records = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("shapes and lights"),
            contents: bytemuck::cast_slice(&scene.records),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let majorant = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("majorant"),
            contents: bytemuck::cast_slice(&scene.majorant),
            usage: wgpu::BufferUsages::STORAGE,
        });

        let (gx, gy) = (w.div_ceil(8), h.div_ceil(8));
        let stats_bytes = gx as u64 * gy as u64 * 6 * 4;
        if st.out.as_ref().map(|o| o.0) != Some(pixels) {
            let buf = |label: &str, size: u64, usage: wgpu::BufferUsages| {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size,
                    usage,
                    mapped_at_creation: false,
                })
            };
            let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
            let read = wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST;
            st.out = Some((
                pixels,
                buf("pixels", out_bytes, storage),
                buf("stats", stats_bytes, storage),
                buf("pixels read", out_bytes, read),
                buf("stats read", stats_bytes, read),
            ));
        }
        let blocks = &st.blocks[&(params.block_size as usize)];
        let (_, out_px, out_stats, read_px, read_stats) = st.out.as_ref().expect("made above");
        let tex = |binding: u32, slot: usize| wgpu::BindGroupEntry {
            binding,
            resource: wgpu::BindingResource::TextureView(&self.texture_views[slot]),
        };
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("raycast"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: self.uniform.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(&self.texture_views[0]),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::TextureView(&self.lut_view),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: blocks.empty.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: blocks.max_grad.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 5,
                    resource: out_px.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 6,
                    resource: out_stats.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 7,
                    resource: records.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 8,
                    resource: majorant.as_entire_binding(),
                },
                tex(9, 1),
                tex(10, 2),
                tex(11, 3),
                tex(12, 4),
                tex(13, 5),
                tex(14, 6),
                tex(15, 7),
            ],
        });
        // One submit per chunk of passes (queue order keeps each chunk's
        // parameters with its dispatch); the last one copies the sums out.
        let mut first = 0;
        while first < passes {
            let end = (first + PASSES_PER_DISPATCH).min(passes);
            p.chunk = [first, end, 0, 0];
            queue.write_buffer(&self.uniform, 0, bytemuck::bytes_of(&p));
            let mut enc = device.create_command_encoder(&Default::default());
            {
                let mut pass = enc.begin_compute_pass(&Default::default());
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, &bind, &[]);
                pass.dispatch_workgroups(gx, gy, 1);
            }
            if end == passes {
                enc.copy_buffer_to_buffer(out_px, 0, read_px, 0, out_bytes);
                enc.copy_buffer_to_buffer(out_stats, 0, read_stats, 0, stats_bytes);
            }
            queue.submit([enc.finish()]);
            first = end;
        }
        let px = read_back(device, read_px)?;
        let sv = read_back(device, read_stats)?;
        // The sums over the passes → the average, over the background (the
        // CPU's arithmetic: linear radiance, opaque, for single-scatter).
        let sums: &[[f32; 4]] = bytemuck::cast_slice(&px);
        let n = passes as f32;
        let bg_v = glam::Vec3::from(bg);
        let pixels_f = sums
            .iter()
            .map(|&s| {
                let s = glam::Vec4::from(s);
                if physical {
                    let c = s.truncate() / n;
                    [c.x, c.y, c.z, 1.0]
                } else {
                    let c = s / n;
                    let rgb = c.truncate() + bg_v * (1.0 - c.w);
                    [rgb.x, rgb.y, rgb.z, c.w]
                }
            })
            .collect();
        let image = Image {
            width: w,
            height: h,
            pixels: pixels_f,
        };
        let words: &[u32] = bytemuck::cast_slice(&sv);
        let mut sum = [0u64; 6];
        for chunk in words.chunks_exact(6) {
            for (s, &v) in sum.iter_mut().zip(chunk) {
                *s += v as u64;
            }
        }
        let stats = RenderStats {
            rays: sum[0],
            rays_hit: sum[1],
            samples: sum[2],
            interpolations: sum[3],
            gradient_interpolations: 6 * sum[4],
            early_terminated: sum[5],
            capped_paths: 0,
            seconds: start.elapsed().as_secs_f64(),
        };
        Ok((image, stats))
    }
}

/// What a render needs besides the volume: the shapes and lights in one
/// buffer of `vec4` records, the medium and the majorant.
struct SceneData {
    geo: [u32; 4],
    surf_dir: [f32; 4],
    surf_k: [f32; 4],
    med_offset: [f32; 4],
    med_scale: [f32; 4],
    med_hi: [f32; 4],
    med_albedo: [f32; 4],
    med_flags: [u32; 4],
    records: Vec<[f32; 4]>,
    majorant: Vec<f32>,
}

impl SceneData {
    fn new(
        geometry: Option<&voxcast::geometry::Geometry>,
        cam: &Camera,
        params: &RenderParams,
        volume: &Volume,
        blocks: &BlockGrid,
    ) -> SceneData {
        use voxcast::geometry::Primitive;
        use voxcast::render::light::Light;
        use voxcast::render::phase::PhaseFunction;
        let v4 = |v: glam::Vec3, w: f32| [v.x, v.y, v.z, w];
        let mut records = Vec::new();
        let mut shapes = 0;
        let mut surf_dir = [0.0; 4];
        let mut surf_k = [0.0; 4];
        let mut shadows = 0;
        if let Some(g) = geometry {
            // Per shape: kind (0 box, 1 rectangle, 2 infinite plane) and
            // half extents; min | point; max | normal; u; v; albedo.
            for (p, albedo) in g.primitives() {
                let rec = match p {
                    Primitive::Box(b) => {
                        [[0.0; 4], v4(b.min, 0.0), v4(b.max, 0.0), [0.0; 4], [0.0; 4]]
                    }
                    Primitive::Rect(p) | Primitive::InfinitePlane(p) => {
                        let [a, b] = p.half_extent.unwrap_or([0.0; 2]);
                        let kind = if p.half_extent.is_some() { 1.0 } else { 2.0 };
                        [
                            [kind, a, b, 0.0],
                            v4(p.point, 0.0),
                            v4(p.normal, 0.0),
                            v4(p.u, 0.0),
                            v4(p.v, 0.0),
                        ]
                    }
                    // Refused by `with_geometry`.
                    Primitive::Triangle(_) => continue,
                };
                records.extend_from_slice(&rec);
                records.push(v4(albedo, 0.0));
                shapes += 1;
            }
            let light = voxcast::geometry::SurfaceLight::new(g.light, cam);
            surf_dir = v4(light.to_light, 0.0);
            surf_k = [
                light.ambient,
                light.diffuse,
                light.specular,
                light.shininess,
            ];
            shadows = g.shadows as u32;
        }
        debug_assert_eq!(records.len(), shapes * SHAPE_WORDS);
        // Lights (single-scatter): kind (0 directional, 1 point,
        // 2 environment, 3 sky); then its vectors.
        let lights = params.lights_or_default();
        let v = |a: [f32; 3]| [a[0], a[1], a[2], 0.0];
        for l in lights.iter() {
            let rec = match *l {
                Light::Directional {
                    direction,
                    irradiance,
                } => [
                    [0.0; 4],
                    v4(glam::Vec3::from(direction).normalize(), 0.0),
                    v(irradiance),
                    [0.0; 4],
                ],
                Light::Point {
                    position,
                    intensity,
                } => [[1.0, 0.0, 0.0, 0.0], v(position), v(intensity), [0.0; 4]],
                Light::Environment { radiance } => {
                    [[2.0, 0.0, 0.0, 0.0], v(radiance), [0.0; 4], [0.0; 4]]
                }
                Light::Sky {
                    zenith,
                    horizon,
                    ground,
                } => [[3.0, 0.0, 0.0, 0.0], v(zenith), v(horizon), v(ground)],
            };
            records.extend_from_slice(&rec);
        }
        debug_assert_eq!(
            records.len(),
            shapes * SHAPE_WORDS + lights.len() * LIGHT_WORDS
        );
        if records.is_empty() {
            records.push([0.0; 4]);
        }
        let medium = &params.medium;
        let (phase_kind, phase_arg) = match medium.phase {
            PhaseFunction::Isotropic => (0, 0.0),
            PhaseFunction::Hg { g } => (1, g),
            PhaseFunction::Schlick { k } => (2, k),
            PhaseFunction::Rayleigh => (3, 0.0),
            PhaseFunction::Mie { g } => (4, g),
        };
        // path.rs: the medium box in voxel coordinates.
        let dims = volume.dims();
        let hi = glam::Vec3::new(
            dims[0].saturating_sub(1).max(1) as f32,
            dims[1].saturating_sub(1).max(1) as f32,
            dims[2].saturating_sub(1).max(1) as f32,
        );
        let (offset, scale_v) = match medium.r#box {
            Some([lo, bhi]) => (
                glam::Vec3::from(lo),
                hi / (glam::Vec3::from(bhi) - glam::Vec3::from(lo)),
            ),
            None => (volume.origin(), glam::Vec3::ONE / volume.spacing()),
        };
        let (majorant, global) = if params.method.is_physical() {
            let m = voxcast::render::majorant::Majorant::new(blocks, medium.scale, medium.majorant);
            (m.sigma, m.global)
        } else {
            (vec![0.0], 0.0)
        };
        SceneData {
            geo: [shapes as u32, shadows, lights.len() as u32, phase_kind],
            surf_dir,
            surf_k,
            med_offset: v4(offset, medium.scale),
            med_scale: v4(scale_v, phase_arg),
            med_hi: v4(hi, global),
            med_albedo: [
                medium.albedo[0],
                medium.albedo[1],
                medium.albedo[2],
                (medium.majorant == voxcast::render::medium::MajorantKind::Global) as u32 as f32,
            ],
            med_flags: [lights.iter().any(|l| !l.is_delta()) as u32, 0, 0, 0],
            records,
            majorant: if majorant.is_empty() {
                vec![0.0]
            } else {
                majorant
            },
        }
    }
}

/// Runs `f` with wgpu's validation and out-of-memory errors captured, so
/// they come back as a [`GpuError`] naming `what` instead of wgpu's default
/// handler's panic.
fn scoped<T>(device: &wgpu::Device, what: &str, f: impl FnOnce() -> T) -> Result<T, GpuError> {
    let oom = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let r = f();
    let v = pollster::block_on(validation.pop());
    let o = pollster::block_on(oom.pop());
    match v.or(o) {
        Some(e) => Err(GpuError::Device(format!("{what}: {e}"))),
        None => Ok(r),
    }
}

/// Maps `buf`, copies its bytes out and unmaps it.
fn read_back(device: &wgpu::Device, buf: &wgpu::Buffer) -> Result<Vec<u8>, GpuError> {
    let (tx, rx) = std::sync::mpsc::channel();
    buf.map_async(wgpu::MapMode::Read, .., move |r| {
        let _ = tx.send(r);
    });
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| GpuError::Device(format!("waiting for the render: {e}")))?;
    rx.recv()
        .map_err(|_| GpuError::Device("the read-back was dropped".into()))?
        .map_err(|e| GpuError::Device(format!("reading the image back: {e}")))?;
    let bytes = buf
        .get_mapped_range(..)
        .map_err(|e| GpuError::Device(format!("reading the image back: {e}")))?
        .to_vec();
    buf.unmap();
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::f16_bits;

    #[test]
    fn half_bits_of_integers() {
        assert_eq!(f16_bits(0.0), 0);
        assert_eq!(f16_bits(1.0), 0x3C00);
        assert_eq!(f16_bits(3.0), 0x4200);
        assert_eq!(f16_bits(2047.0), 0x67FF);
        assert_eq!(f16_bits(2048.0), 0x6800);
        assert_eq!(f16_bits(-1024.0), 0xE400);
        assert_eq!(f16_bits(-1.0), 0xBC00);
    }
}
