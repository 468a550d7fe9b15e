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
    /// Pipelines specialised for a render's [`Spec`], built on first use.
    pub(crate) pipelines: HashMap<Spec, wgpu::ComputePipeline>,
}

/// What a specialised pipeline is built for: the method's code, the flag
/// bits, the optical model and whether there are opaque shapes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) struct Spec {
    pub(crate) method: u32,
    pub(crate) flags: u32,
    pub(crate) optical: u32,
    pub(crate) shapes: bool,
}

/// The shader module and what every pipeline of it shares.
pub(crate) struct Shader {
    module: wgpu::ShaderModule,
    layout: wgpu::PipelineLayout,
    bricked: bool,
    hw_filter: bool,
    /// Invocations per workgroup in x and y (`VOXCAST_GPU_WORKGROUP`,
    /// default 8×8).
    pub(crate) workgroup: [u32; 2],
}

impl Shader {
    /// The pipeline for `spec`, or the generic one for `None`.
    pub(crate) fn pipeline(
        &self,
        device: &wgpu::Device,
        spec: Option<Spec>,
    ) -> wgpu::ComputePipeline {
        let b = |v: bool| if v { 1.0 } else { 0.0 };
        let mut constants = vec![
            ("BRICKED", b(self.bricked)),
            ("HW_FILTER", b(self.hw_filter)),
            ("WG_X", self.workgroup[0] as f64),
            ("WG_Y", self.workgroup[1] as f64),
        ];
        if let Some(s) = spec {
            constants.extend([
                ("SPEC", 1.0),
                ("SPEC_METHOD", s.method as f64),
                ("SPEC_FLAGS", s.flags as f64),
                ("SPEC_OPTICAL", s.optical as f64),
                ("SPEC_SHAPES", b(s.shapes)),
            ]);
        }
        device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(if spec.is_some() {
                "raycast (specialised)"
            } else {
                "raycast"
            }),
            layout: Some(&self.layout),
            module: &self.module,
            entry_point: Some("main"),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants: &constants,
                ..Default::default()
            },
            cache: None,
        })
    }
}

/// The workgroup size from `VOXCAST_GPU_WORKGROUP` (`16x8`: x and y, each
/// 1…32, at most 256 invocations), else 8×8.
pub(crate) fn env_workgroup() -> [u32; 2] {
    match std::env::var(WORKGROUP_ENV) {
        Ok(v) => parse_workgroup(&v).unwrap_or_else(|| {
            eprintln!("warning: {WORKGROUP_ENV}={v:?} is not XxY with x, y in 1…32 and 8…256 invocations; using 8x8");
            [8, 8]
        }),
        Err(_) => [8, 8],
    }
}

/// `"16x8"` → `[16, 8]`: each side 1…32, 8…256 invocations (the shader's
/// statistics need six).
pub fn parse_workgroup(v: &str) -> Option<[u32; 2]> {
    let (x, y) = v.trim().split_once(['x', 'X'])?;
    let (x, y) = (x.trim().parse::<u32>().ok()?, y.trim().parse::<u32>().ok()?);
    ((1..=32).contains(&x) && (1..=32).contains(&y) && (8..=256).contains(&(x * y)))
        .then_some([x, y])
}

/// The environment variable that sets the workgroup size (for tuning).
pub const WORKGROUP_ENV: &str = "VOXCAST_GPU_WORKGROUP";

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
    /// The generic pipeline (method, flags and optical model read from the
    /// uniforms at run time).
    pub(crate) pipeline: wgpu::ComputePipeline,
    pub(crate) shader: Shader,
    /// Whether renders use specialised pipelines ([`GpuOptions::specialise`]).
    pub(crate) specialise: bool,
    pub(crate) layout: wgpu::BindGroupLayout,
    pub(crate) uniform: wgpu::Buffer,
    /// Stored → normalised: `texel·scale + offset`.
    pub(crate) scale: f32,
    pub(crate) offset: f32,
    pub(crate) format: wgpu::TextureFormat,
    pub(crate) state: Mutex<State>,
    /// See [`GpuRenderer::setup_seconds`].
    pub(crate) setup_seconds: f64,
    /// Binding 16: linear under [`Filter::Hardware`], else unused.
    pub(crate) sampler: wgpu::Sampler,
    pub(crate) filter: Filter,
}

/// How a sample is reconstructed from the 3D texture.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Filter {
    /// [`Filter::Hardware`] on a hardware GPU, [`Filter::Exact`] on a
    /// software rasteriser (where the texture unit is emulated and the CPU's
    /// arithmetic is what the parity tests check).
    #[default]
    Auto,
    /// Eight texel loads and the CPU's trilinear arithmetic in `f32`: the
    /// CPU's picture (the parity tests hold it to ≥ 40 dB).
    Exact,
    /// One fetch filtered by the texture unit: fewer instructions and
    /// fetches per sample, with the hardware's weight precision (8
    /// fractional bits on NVIDIA and AMD). Only for a volume in one brick
    /// and a filterable format (u8, u16/i16 that `f16` holds exactly, and
    /// `f32` where the device has `FLOAT32_FILTERABLE`); otherwise
    /// [`Filter::Exact`] is used ([`GpuRenderer::filter`] says which).
    Hardware,
}

/// How [`GpuRenderer::with_options`] builds the renderer.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GpuOptions {
    /// The 3D texture limit lowered to this many voxels per side (`None`:
    /// the device's `max_texture_dimension_3d`, or
    /// `VOXCAST_GPU_MAX_TEXTURE_3D` when set and smaller), so bricking can
    /// be tried on volumes that would fit whole.
    pub max_texture_side: Option<u32>,
    /// How a sample is reconstructed.
    pub filter: Filter,
    /// Whether each render uses a pipeline specialised for its method, flags
    /// and optical model (pipeline constants: the driver compiles out every
    /// other path, so the shader needs fewer registers and runs more rays at
    /// once). `None`: on a hardware GPU yes; on a software rasteriser no (it
    /// compiles each variant slowly and gains little).
    pub specialise: Option<bool>,
}

impl GpuRenderer {
    /// Uploads `volume` (values `window[0]…window[1]` map to 0…1, as on the
    /// CPU) and builds the default block grid.
    pub fn new(
        ctx: Arc<GpuContext>,
        volume: &Volume,
        window: [f32; 2],
    ) -> Result<GpuRenderer, GpuError> {
        Self::with_options(ctx, volume, window, GpuOptions::default())
    }

    /// [`GpuRenderer::new`] with the 3D texture limit lowered to `max_side`
    /// voxels per side (see [`GpuOptions::max_texture_side`]).
    pub fn with_texture_limit(
        ctx: Arc<GpuContext>,
        volume: &Volume,
        window: [f32; 2],
        max_side: Option<u32>,
    ) -> Result<GpuRenderer, GpuError> {
        let options = GpuOptions {
            max_texture_side: max_side,
            ..GpuOptions::default()
        };
        Self::with_options(ctx, volume, window, options)
    }

    /// [`GpuRenderer::new`] with `options`.
    pub fn with_options(
        ctx: Arc<GpuContext>,
        volume: &Volume,
        window: [f32; 2],
        options: GpuOptions,
    ) -> Result<GpuRenderer, GpuError> {
        let max_side = options.max_texture_side;
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
        let start = std::time::Instant::now();
        let (bytes, format, scale, offset) = texels(volume, window);
        let wanted = match options.filter {
            Filter::Auto if ctx.is_software() => Filter::Exact,
            Filter::Auto => Filter::Hardware,
            f => f,
        };
        let filter = match wanted {
            Filter::Hardware
                if bricking.len() == 1
                    && (format != wgpu::TextureFormat::R32Float || ctx.filters_f32()) =>
            {
                Filter::Hardware
            }
            _ => Filter::Exact,
        };
        let mut r = scoped(
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
                    filter,
                )
            },
        )?;
        r.specialise = options.specialise.unwrap_or(!r.ctx.is_software());
        // The uploads are queued; wait for them so the time is true.
        r.ctx.queue.submit([]);
        r.ctx
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| GpuError::Device(format!("uploading the volume: {e}")))?;
        r.setup_seconds = start.elapsed().as_secs_f64();
        Ok(r)
    }

    /// Wall-clock seconds [`GpuRenderer::new`] took: converting and
    /// uploading the volume, building the pipeline and the block grid.
    pub fn setup_seconds(&self) -> f64 {
        self.setup_seconds
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
        filter: Filter,
    ) -> GpuRenderer {
        let hw = filter == Filter::Hardware;
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
                    sample_type: wgpu::TextureSampleType::Float {
                        filterable: hw && binding == 1,
                    },
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
                wgpu::BindGroupLayoutEntry {
                    binding: 16,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Sampler(if hw {
                        wgpu::SamplerBindingType::Filtering
                    } else {
                        wgpu::SamplerBindingType::NonFiltering
                    }),
                    count: None,
                },
            ],
        });
        let linear = if hw {
            wgpu::FilterMode::Linear
        } else {
            wgpu::FilterMode::Nearest
        };
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("volume"),
            mag_filter: linear,
            min_filter: linear,
            ..Default::default()
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("raycast"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let shader = Shader {
            module,
            layout: pipeline_layout,
            bricked: bricking.len() > 1,
            hw_filter: hw,
            workgroup: env_workgroup(),
        };
        let pipeline = shader.pipeline(device, None);
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
            shader,
            specialise: false,
            layout,
            uniform,
            scale,
            offset,
            format,
            state: Mutex::new(State {
                blocks: HashMap::new(),
                lut_tf: None,
                out: None,
                pipelines: HashMap::new(),
            }),
            setup_seconds: 0.0,
            sampler,
            filter,
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

    /// The reconstruction in use, `Exact` or `Hardware` ([`Filter::Auto`]
    /// resolved; [`Filter::Hardware`] falls back to [`Filter::Exact`] for a
    /// bricked volume, or an `f32` texture the device cannot filter).
    pub fn filter(&self) -> Filter {
        self.filter
    }

    /// Whether renders use pipelines specialised per method
    /// ([`GpuOptions::specialise`]).
    pub fn specialises(&self) -> bool {
        self.specialise
    }

    /// Invocations per workgroup, x and y.
    pub fn workgroup(&self) -> [u32; 2] {
        self.shader.workgroup
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
