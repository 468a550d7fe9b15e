//! [`GpuRenderer`]: a volume uploaded to the device with its pipeline, and
//! the per-render state (block grids, the transfer-function texture, output
//! buffers); building it and its accessors. The render itself is in
//! `dispatch.rs`.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use voxcast::camera::CameraParams;
use voxcast::render::blocks::{BuildBlocks, BuildMaxGradient, DEFAULT_BLOCK};
use voxcast::render::{BlockGrid, Method, RenderParams, RenderStats};
use voxcast::transfer::{TransferFunction, LUT_SIZE};
use voxcast::volume::Volume;
use voxcast::Image;
use wgpu::util::DeviceExt;

use crate::context::{scoped, GpuContext, GpuError};
use crate::upload::{env_texture_limit, texels, Bricking};

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct Params {
    pub(crate) eye: [f32; 4],
    pub(crate) forward: [f32; 4],
    pub(crate) right: [f32; 4],
    pub(crate) up: [f32; 4],
    pub(crate) origin_w: [f32; 4],
    pub(crate) inv_spacing: [f32; 4],
    pub(crate) box_lo: [f32; 4],
    pub(crate) box_hi: [f32; 4],
    pub(crate) grid_max: [f32; 4],
    pub(crate) background: [f32; 4],
    pub(crate) dims: [u32; 4],
    pub(crate) counts: [u32; 4],
    pub(crate) size: [u32; 4],
    pub(crate) seed: [u32; 4],
    pub(crate) levels: [i32; 4],
    /// Geometry and lights: shape records, shadows, light records, phase kind.
    pub(crate) geo: [u32; 4],
    /// Surface key light: direction towards it; w unused.
    pub(crate) surf_dir: [f32; 4],
    /// Surface Blinn–Phong: ambient, diffuse, specular, shininess.
    pub(crate) surf_k: [f32; 4],
    /// Medium: world → voxel offset, w: σ_t at density 1.
    pub(crate) med_offset: [f32; 4],
    /// Medium: world → voxel scale, w: phase parameter (g or k).
    pub(crate) med_scale: [f32; 4],
    /// Medium: the box's far corner (voxels), w: global majorant.
    pub(crate) med_hi: [f32; 4],
    /// Medium: albedo, w: 1 for the global majorant, 0 for the grid.
    pub(crate) med_albedo: [f32; 4],
    /// Medium: has infinite lights, unused ×3.
    pub(crate) med_flags: [u32; 4],
    /// Bricks per axis, w: their product.
    pub(crate) bricks: [u32; 4],
    /// Cells per brick along each axis.
    pub(crate) brick_cells: [u32; 4],
    /// The passes of one dispatch: first, end (exclusive).
    pub(crate) chunk: [u32; 4],
    /// Threshold: range bounds, steps of ranges 0 and 1 (voxels).
    pub(crate) thresh: [f32; 4],
    /// Threshold: step of range 2 (voxels).
    pub(crate) thresh2: [f32; 4],
}

/// Passes per dispatch of the progressive methods: a render of many passes
/// is split into dispatches of at most this many, each adding to the sums
/// the one before left, so no single dispatch runs long enough to trip a
/// GPU watchdog (about 2 s on desktop drivers).
/// The ray caster's WGSL: the files of `shader/`, concatenated (WGSL has
/// no imports; each file names the Rust it mirrors).
const SHADER: &str = concat!(
    include_str!("shader/params.wgsl"),
    include_str!("shader/random.wgsl"),
    include_str!("shader/volume.wgsl"),
    include_str!("shader/march.wgsl"),
    include_str!("shader/geometry.wgsl"),
    include_str!("shader/scatter.wgsl"),
    include_str!("shader/main.wgsl"),
);

pub(crate) const PASSES_PER_DISPATCH: u32 = 8;

/// Texture slots for bricks (bindings 1 and 9…15).
pub(crate) const MAX_BRICKS: usize = 8;
/// `vec4` records per shape and per light in the scene buffer.
pub(crate) const SHAPE_WORDS: usize = 6;
pub(crate) const LIGHT_WORDS: usize = 4;

pub(crate) const F_SHADING: u32 = 1;
pub(crate) const F_GROUPED: u32 = 2;
pub(crate) const F_JITTER: u32 = 4;
pub(crate) const F_SKIP: u32 = 8;

/// The shader's method numbers.
pub(crate) fn method_code(m: Method) -> Result<u32, GpuError> {
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
pub(crate) struct Blocks {
    pub(crate) grid: BlockGrid,
    /// Emptiness flags under the transfer function last uploaded.
    pub(crate) empty: wgpu::Buffer,
    /// Largest gradient component per block (for `adaptive-max`).
    pub(crate) max_grad: wgpu::Buffer,
    /// The transfer function the flags were computed for.
    pub(crate) tf: Option<TransferFunction>,
}

/// What changes between renders, kept behind a lock so [`GpuRenderer::render`]
/// can take `&self`.
pub(crate) struct State {
    pub(crate) blocks: HashMap<usize, Blocks>,
    pub(crate) lut_tf: Option<TransferFunction>,
    pub(crate) out: Option<(u64, wgpu::Buffer, wgpu::Buffer, wgpu::Buffer, wgpu::Buffer)>,
}

/// A volume uploaded to the GPU, ready to render with any transfer function,
/// camera and parameters (see the crate documentation).
pub struct GpuRenderer {
    pub(crate) ctx: Arc<GpuContext>,
    pub(crate) volume: Volume,
    pub(crate) window: [f32; 2],
    /// One view per texture slot (bricks, then repeats of the first).
    pub(crate) texture_views: Vec<wgpu::TextureView>,
    /// Bricks per axis and cells per brick (see [`Bricking`]).
    pub(crate) bricking: Bricking,
    /// Opaque boxes and planes (see [`GpuRenderer::with_geometry`]).
    pub(crate) geometry: Option<voxcast::geometry::Geometry>,
    pub(crate) lut_texture: wgpu::Texture,
    pub(crate) lut_view: wgpu::TextureView,
    pub(crate) pipeline: wgpu::ComputePipeline,
    pub(crate) layout: wgpu::BindGroupLayout,
    pub(crate) uniform: wgpu::Buffer,
    /// Stored → normalised: `texel·scale + offset`.
    pub(crate) scale: f32,
    pub(crate) offset: f32,
    pub(crate) format: wgpu::TextureFormat,
    pub(crate) state: Mutex<State>,
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
            label: Some("voxcast ray caster (shader/*.wgsl)"),
            source: wgpu::ShaderSource::Wgsl(SHADER.into()),
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

    pub(crate) fn blocks<'s>(&self, st: &'s mut State, size: usize) -> &'s mut Blocks {
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
}
