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
//! * [`GpuRenderer::render`] returns the core's [`voxcast::Image`] (linear
//!   RGBA, composited over the background) and [`voxcast::RenderStats`], like
//!   [`voxcast::render::Renderer::render`].
//!
//! # Supported
//!
//! Methods `uniform`, `adaptive`, `adaptive-s0`, `adaptive-max`, `threshold` (each with
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
//! naming it. The table of what each back end renders is the core's
//! [`voxcast::render::Backend`]; [`choose`] resolves `--device
//! cpu|gpu|auto` with it for every front end.
//!
//! # The contract with the shader
//!
//! The uniform block `Params` is a Rust struct (`params.rs`) from which the
//! WGSL `struct Params` and the shader's constants (method codes, optical
//! models, flag bits) are generated; a test checks its layout against
//! naga's. The shader itself is `shader/*.wgsl`, split by concern, each
//! function naming the Rust function it mirrors.

mod backend;
mod context;
mod dispatch;
mod params;
mod renderer;
mod scene;
mod upload;

pub use backend::{choose, Choice, Device, DeviceRequest};
pub use context::{
    adapter_info, compiled_backends, AdapterSummary, DeviceChoice, GpuContext, GpuError,
};
pub use renderer::{parse_workgroup, Filter, GpuOptions, GpuRenderer, WORKGROUP_ENV};
pub use upload::{Bricking, TEXTURE_LIMIT_ENV};
