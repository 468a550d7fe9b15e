//! Draws the volume's image straight into egui's render pass with a
//! pipeline of its own (an egui wgpu paint callback) instead of as an egui
//! textured mesh.
//!
//! Why: on a software rasteriser (lavapipe) the window's frame time is
//! nearly all per-pixel shading, and the view is most of the window's
//! pixels. egui's fragment shader serves every kind of mesh: it blends,
//! multiplies by the vertex colour, and carries branches for dithering and
//! for software filtering that a SIMD software rasteriser pays for even when
//! they are off. This pipeline's fragment shader is one texture sample,
//! written without blending. A preview is uploaded at its own small size and
//! magnified by a linear sampler; a full frame maps 1:1 to the view's pixels
//! and is read with a nearest sampler.

use eframe::egui;
use eframe::egui_wgpu::{self, wgpu};
use std::sync::Arc;

/// An image to show: 8-bit sRGB RGBA, `width`×`height`, opaque (alpha 255:
/// the shader copies alpha too).
pub struct PaintImage {
    /// Changes whenever the pixels change (the upload is skipped otherwise).
    pub id: u64,
    pub width: u32,
    pub height: u32,
    pub rgba: Vec<u8>,
    /// Magnify with a linear filter (previews); nearest otherwise.
    pub linear: bool,
}

const SHADER: &str = r"
struct VOut {
    @builtin(position) pos: vec4<f32>,
    @location(0) uv: vec2<f32>,
};

// A quad (triangle strip) exactly covering the viewport, which egui sets to
// the callback's rectangle: an axis-aligned rectangle with a plain texture
// copy is what a software rasteriser's fast paths recognise.
@vertex
fn vs(@builtin(vertex_index) i: u32) -> VOut {
    let uv = vec2<f32>(f32(i & 1u), f32(i >> 1u));
    var o: VOut;
    o.pos = vec4<f32>(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0, 0.0, 1.0);
    o.uv = uv;
    return o;
}

@group(0) @binding(0) var image: texture_2d<f32>;
@group(0) @binding(1) var image_sampler: sampler;

// The texture is opaque (alpha 255): a straight copy.
@fragment
fn fs(v: VOut) -> @location(0) vec4<f32> {
    return textureSample(image, image_sampler, v.uv);
}
";

/// The pipeline and the uploaded image, kept in egui's callback resources.
struct Resources {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    linear: wgpu::Sampler,
    nearest: wgpu::Sampler,
    /// The texture's format: sRGB-decoding when the target encodes sRGB, so
    /// the bytes come out as they went in.
    format: wgpu::TextureFormat,
    uploaded: Option<Uploaded>,
}

struct Uploaded {
    id: u64,
    size: [u32; 2],
    texture: wgpu::Texture,
    bind_group: wgpu::BindGroup,
}

/// Makes the pipeline for the window's render target. Call once, at start.
pub fn install(rs: &egui_wgpu::RenderState) {
    let device = &rs.device;
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("voxcast-view image"),
        source: wgpu::ShaderSource::Wgsl(SHADER.into()),
    });
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("voxcast-view image"),
        entries: &[
            wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: true },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            },
            wgpu::BindGroupLayoutEntry {
                binding: 1,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                count: None,
            },
        ],
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("voxcast-view image"),
        bind_group_layouts: &[Some(&layout)],
        immediate_size: 0,
    });
    let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("voxcast-view image"),
        layout: Some(&pipeline_layout),
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("fs"),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::ColorTargetState {
                format: rs.target_format,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        primitive: wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::TriangleStrip,
            ..Default::default()
        },
        depth_stencil: None,
        multisample: wgpu::MultisampleState::default(),
        multiview_mask: None,
        cache: None,
    });
    let sampler = |filter| {
        device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("voxcast-view image"),
            mag_filter: filter,
            min_filter: filter,
            ..Default::default()
        })
    };
    let format = if rs.target_format.is_srgb() {
        wgpu::TextureFormat::Rgba8UnormSrgb
    } else {
        wgpu::TextureFormat::Rgba8Unorm
    };
    let res = Resources {
        pipeline,
        layout,
        linear: sampler(wgpu::FilterMode::Linear),
        nearest: sampler(wgpu::FilterMode::Nearest),
        format,
        uploaded: None,
    };
    rs.renderer.write().callback_resources.insert(res);
}

/// The paint callback drawing `image` over `rect`.
pub fn shape(rect: egui::Rect, image: Arc<PaintImage>) -> egui::Shape {
    egui::Shape::Callback(egui_wgpu::Callback::new_paint_callback(
        rect,
        ImageCallback { image },
    ))
}

struct ImageCallback {
    image: Arc<PaintImage>,
}

impl egui_wgpu::CallbackTrait for ImageCallback {
    fn prepare(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        _screen: &egui_wgpu::ScreenDescriptor,
        _encoder: &mut wgpu::CommandEncoder,
        resources: &mut egui_wgpu::CallbackResources,
    ) -> Vec<wgpu::CommandBuffer> {
        let Some(res) = resources.get_mut::<Resources>() else {
            return Vec::new();
        };
        let img = &self.image;
        if img.width == 0
            || img.height == 0
            || img.rgba.len() != (img.width * img.height * 4) as usize
        {
            return Vec::new();
        }
        let size = [img.width, img.height];
        let sampler = if img.linear {
            &res.linear
        } else {
            &res.nearest
        };
        if res.uploaded.as_ref().is_some_and(|u| u.id == img.id) {
            return Vec::new();
        }
        // A texture of the same size is rewritten; another size replaces it.
        let texture = match res.uploaded.take() {
            Some(u) if u.size == size => u.texture,
            _ => device.create_texture(&wgpu::TextureDescriptor {
                label: Some("voxcast-view image"),
                size: wgpu::Extent3d {
                    width: img.width,
                    height: img.height,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: res.format,
                usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            }),
        };
        queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &texture,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            &img.rgba,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(img.width * 4),
                rows_per_image: Some(img.height),
            },
            texture.size(),
        );
        let view = texture.create_view(&Default::default());
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("voxcast-view image"),
            layout: &res.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(&view),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::Sampler(sampler),
                },
            ],
        });
        res.uploaded = Some(Uploaded {
            id: img.id,
            size,
            texture,
            bind_group,
        });
        Vec::new()
    }

    fn paint(
        &self,
        _info: egui::PaintCallbackInfo,
        pass: &mut wgpu::RenderPass<'static>,
        resources: &egui_wgpu::CallbackResources,
    ) {
        let Some(res) = resources.get::<Resources>() else {
            return;
        };
        let Some(u) = &res.uploaded else { return };
        pass.set_pipeline(&res.pipeline);
        pass.set_bind_group(0, &u.bind_group, &[]);
        pass.draw(0..4, 0..1);
    }
}
