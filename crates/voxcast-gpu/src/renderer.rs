//! [`GpuRenderer`]: a volume uploaded to the device with its pipeline, and
//! the per-render state (block grids, the transfer-function texture, output
//! buffers); building it and its accessors. The render itself is in
//! `dispatch.rs`.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use voxcast::camera::CameraParams;
use voxcast::render::blocks::{BuildBlocks, BuildMaxGradient, DEFAULT_BLOCK};
use voxcast::render::{Backend, BlockGrid, Method, RenderParams, RenderStats};
use voxcast::transfer::{TransferFunction, LUT_SIZE};
use voxcast::volume::Volume;
use voxcast::Image;
use wgpu::util::DeviceExt;

use crate::context::{scoped, GpuContext, GpuError};
use crate::params::Params;
use crate::upload::{env_texture_limit, texels, Bricking, MAX_BRICKS};

/// The shader files of `shader/`, concatenated in this order (WGSL has no
/// imports; each file names the Rust it mirrors).
const SHADER_FILES: &str = concat!(
    include_str!("shader/params.wgsl"),
    include_str!("shader/random.wgsl"),
    include_str!("shader/volume.wgsl"),
    include_str!("shader/march.wgsl"),
    include_str!("shader/geometry.wgsl"),
    include_str!("shader/scatter.wgsl"),
    include_str!("shader/main.wgsl"),
);

/// The ray caster's WGSL: the generated prelude (`Params` and the
/// constants, [`crate::params::prelude`]) and the files of `shader/`.
pub(crate) fn shader_source() -> String {
    crate::params::prelude() + SHADER_FILES
}

/// Passes per dispatch of the progressive methods: a render of many passes
/// is split into dispatches of at most this many, each adding to the sums
/// the one before left, so no single dispatch runs long enough to trip a
/// GPU watchdog (about 2 s on desktop drivers).
pub(crate) const PASSES_PER_DISPATCH: u32 = 8;

/// The method's code for the shader, or the refusal of a method the GPU
/// lacks (the table is [`Backend::renders`]).
pub(crate) fn method_code(m: Method) -> Result<u32, GpuError> {
    if Backend::Gpu.renders(m) {
        Ok(m.code())
    } else {
        Err(GpuError::Unsupported(format!(
            "method `{}` (the GPU renders {}; use --device cpu for `{}`)",
            m.name(),
            Backend::Gpu.method_list(),
            m.name()
        )))
    }
}

/// The block grid of one block size, with its GPU buffers.
pub(crate) struct Blocks {
    pub(crate) grid: BlockGrid,
    /// Emptiness flags under the transfer function last uploaded.
    pub(crate) empty: wgpu::Buffer,
    /// The adaptive methods' `k` per block: the largest gradient component
    /// (`adaptive-max`) or the change of the classified signal (`adaptive`,
    /// for the transfer function in `k_tf`).
    pub(crate) max_grad: wgpu::Buffer,
    /// Largest gradient component per block, on the CPU (what `max_grad`
    /// holds for `adaptive-max`, and the classified change's input).
    pub(crate) max_gradient: Vec<f32>,
    /// Emptiness flags under `tf`, on the CPU (the classified change's
    /// input).
    pub(crate) empty_flags: Vec<bool>,
    /// The transfer function the flags were computed for.
    pub(crate) tf: Option<TransferFunction>,
    /// What `max_grad` holds: `None` the largest gradients, `Some((tf,
    /// shading))` the classified change under `tf`, shaded or not.
    pub(crate) k_tf: Option<(TransferFunction, bool)>,
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
            source: wgpu::ShaderSource::Wgsl(shader_source().into()),
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
        if !Backend::Gpu.renders_geometry(Some(g)) {
            return Err(GpuError::Unsupported(format!(
                "triangle meshes (OBJ: {} meshes, {} triangles) are rendered on the CPU only; use --device cpu (boxes and planes are fine on the GPU)",
                g.counts()[2],
                g.counts()[3]
            )));
        }
        self.geometry = Some(g.clone());
        Ok(self)
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
                label: Some("block k"),
                contents: bytemuck::cast_slice(&maxg),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            });
            Blocks {
                grid,
                empty,
                max_grad,
                max_gradient: maxg,
                empty_flags: Vec::new(),
                tf: None,
                k_tf: None,
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
