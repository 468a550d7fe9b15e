//! [`GpuRenderer::render`]'s body: the uniforms, bind groups and dispatches
//! of one render, the read-back, and the statistics.

use std::time::Instant;

use voxcast::camera::{Camera, CameraParams, Projection};
use voxcast::render::{Method, Order, RenderParams, RenderStats};
use voxcast::transfer::{srgb_to_linear, Lut, TransferFunction, LUT_SIZE};
use voxcast::Image;
use wgpu::util::DeviceExt;

use crate::context::{map_read, read_back, GpuError};
use crate::params::{optical_code, Params, GROUPED, JITTER, SHADING, SKIP};
use crate::renderer::{method_code, GpuRenderer, Spec, PASSES_PER_DISPATCH};
use crate::scene::SceneData;
use rayon::prelude::*;

impl GpuRenderer {
    pub(crate) fn render_inner(
        &self,
        tf: &TransferFunction,
        camera: &CameraParams,
        params: &RenderParams,
    ) -> Result<(Image, RenderStats), GpuError> {
        params.validate_for(&self.volume)?;
        camera.validate().map_err(voxcast::Error::from)?;
        let params = &*params.in_opacity_units(&self.volume);
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
        let blocks = self.blocks(&mut st, params.block_size_or_default() as usize);
        if blocks.tf.as_ref() != Some(tf) {
            blocks.empty_flags = blocks.grid.empty_flags(tf);
            let flags: Vec<u32> = blocks.empty_flags.iter().map(|&e| u32::from(e)).collect();
            queue.write_buffer(&blocks.empty, 0, bytemuck::cast_slice(&flags));
            blocks.tf = Some(tf.clone());
        }
        // The adaptive methods' `k` per block, as the CPU's `Job` has it.
        let k_tf = (params.method == Method::Adaptive).then(|| (tf.clone(), params.shading));
        if matches!(params.method, Method::Adaptive | Method::AdaptiveMax) && blocks.k_tf != k_tf {
            if k_tf.is_some() {
                let k = blocks.grid.classified_change(
                    &Lut::new(tf, params.step),
                    &blocks.max_gradient,
                    &blocks.empty_flags,
                    params.shade_weight(),
                );
                queue.write_buffer(&blocks.max_grad, 0, bytemuck::cast_slice(&k));
            } else {
                queue.write_buffer(
                    &blocks.max_grad,
                    0,
                    bytemuck::cast_slice(&blocks.max_gradient),
                );
            }
            blocks.k_tf = k_tf;
        }
        let counts = blocks.grid.counts;
        let block_size = blocks.grid.size;

        // The camera, as the CPU frames it (the volume and the shapes).
        let (mut lo, mut hi) = self.volume.frame_bounds();
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
        let unit = self.volume.opacity_unit();
        let inv = glam::Vec3::ONE / self.volume.spacing();
        let origin = self.volume.origin();
        let (level_lo, level_hi) = if params.has_levels() {
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
            flags |= SHADING;
        }
        if params.grouped {
            flags |= GROUPED;
        }
        if jitter {
            flags |= JITTER;
        }
        if params.skip_empty {
            flags |= SKIP;
        }
        let seed = params.seed;
        let sm = voxcast::render::rng::splitmix(seed);
        let bg = params.background.map(srgb_to_linear);
        let mut p = Params {
            eye: cam.eye.to_array(),
            orthographic: (projection == Projection::Orthographic) as u32,
            forward: cam.forward.to_array(),
            half_width: sx,
            right: cam.right.to_array(),
            half_height: sy,
            up: cam.up.to_array(),
            step: params.step,
            origin: origin.to_array(),
            unit,
            inv_spacing: inv.to_array(),
            value_scale: self.scale,
            grid_max: [
                (dims[0] - 1) as f32,
                (dims[1] - 1) as f32,
                (dims[2] - 1) as f32,
            ],
            value_offset: self.offset,
            box_lo: box_lo.to_array(),
            ert,
            box_hi: box_hi.to_array(),
            k_ref: params.adaptive_k_ref(),
            dims: dims.map(|d| d as u32),
            block_size: block_size as u32,
            block_counts: counts.map(|c| c as u32),
            method,
            bricks: self.bricking.counts.map(|c| c as u32),
            brick_count: self.bricking.len() as u32,
            brick_cells: self.bricking.cells.map(|c| c as u32),
            flags,
            width: w,
            height: h,
            passes,
            first_pass: 0,
            seed: [seed as u32, (seed >> 32) as u32],
            seed_mixed: [sm as u32, (sm >> 32) as u32],
            end_pass: passes,
            level_lo,
            level_hi,
            optical: optical_code(params.optical),
            thresh_lo: params.threshold.bounds[0],
            thresh_hi: params.threshold.bounds[1],
            thresh_step0: params.threshold.steps[0],
            thresh_step1: params.threshold.steps[1],
            thresh_step2: params.threshold.steps[2],
            ..bytemuck::Zeroable::zeroed()
        };
        let scene = SceneData::new(&mut p, geometry, &cam, params, &self.volume, &blocks.grid);
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

        let [wg_x, wg_y] = self.shader.workgroup;
        let (gx, gy) = (w.div_ceil(wg_x), h.div_ceil(wg_y));
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
        // The pipeline: specialised for this render's method, flags and
        // optical model (built once per combination), or the generic one.
        let pipeline = if self.specialise {
            let spec = Spec {
                method: p.method,
                flags: p.flags,
                optical: p.optical,
                shapes: p.shapes > 0,
            };
            st.pipelines
                .entry(spec)
                .or_insert_with(|| self.shader.pipeline(device, Some(spec)))
                .clone()
        } else {
            self.pipeline.clone()
        };
        let blocks = &st.blocks[&(params.block_size_or_default() as usize)];
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
                wgpu::BindGroupEntry {
                    binding: 16,
                    resource: wgpu::BindingResource::Sampler(&self.sampler),
                },
            ],
        });
        // One submit per chunk of passes (queue order keeps each chunk's
        // parameters with its dispatch); the last one copies the sums out.
        let chunks = passes.div_ceil(PASSES_PER_DISPATCH);
        let timer = Timestamps::new(self, chunks);
        let mut first = 0;
        let mut chunk = 0;
        while first < passes {
            let end = (first + PASSES_PER_DISPATCH).min(passes);
            (p.first_pass, p.end_pass) = (first, end);
            queue.write_buffer(&self.uniform, 0, bytemuck::bytes_of(&p));
            let mut enc = device.create_command_encoder(&Default::default());
            {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("ray cast"),
                    timestamp_writes: timer.as_ref().map(|t| t.writes(chunk)),
                });
                pass.set_pipeline(&pipeline);
                pass.set_bind_group(0, &bind, &[]);
                pass.dispatch_workgroups(gx, gy, 1);
            }
            if end == passes {
                enc.copy_buffer_to_buffer(out_px, 0, read_px, 0, out_bytes);
                enc.copy_buffer_to_buffer(out_stats, 0, read_stats, 0, stats_bytes);
                if let Some(t) = &timer {
                    t.resolve(&mut enc);
                }
            }
            queue.submit([enc.finish()]);
            first = end;
            chunk += 1;
        }
        // The sums over the passes → the average, over the background (the
        // CPU's arithmetic: linear radiance, opaque, for single-scatter),
        // converted in parallel straight from the mapped buffer: at 1024²
        // a copy first, then a serial pass, cost more than the render on a
        // fast GPU.
        let n = passes as f32;
        let bg_v = glam::Vec3::from(bg);
        let convert = |b: &[u8]| -> [f32; 4] {
            let s = glam::Vec4::from(bytemuck::pod_read_unaligned::<[f32; 4]>(b));
            if physical {
                let c = s.truncate() / n;
                [c.x, c.y, c.z, 1.0]
            } else {
                let c = s / n;
                let rgb = c.truncate() + bg_v * (1.0 - c.w);
                [rgb.x, rgb.y, rgb.z, c.w]
            }
        };
        let pixels_f: Vec<[f32; 4]> = map_read(device, read_px, |bytes| {
            bytes.par_chunks_exact(16).map(convert).collect()
        })?;
        let sv = read_back(device, read_stats)?;
        let device_seconds = match &timer {
            Some(t) => t.seconds(self)?,
            None => None,
        };
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
            device_seconds,
            simd: None,
            skipping_left_out: None,
            block_size: 0,
        };
        Ok((image, stats))
    }
}

/// Timestamp queries around each compute pass of a render: a begin and an
/// end per chunk of passes, resolved after the last and summed, so the
/// device's own time leaves out the uploads, the read-back and the gaps
/// between submits.
struct Timestamps {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    read: wgpu::Buffer,
    count: u32,
}

impl Timestamps {
    /// `None` where the device has no timestamp queries, or for more
    /// chunks than a query set holds (`wgpu::QUERY_SET_MAX_QUERIES`).
    fn new(r: &GpuRenderer, chunks: u32) -> Option<Timestamps> {
        let count = chunks.checked_mul(2)?;
        if !r.ctx.has_timestamps() || count > wgpu::QUERY_SET_MAX_QUERIES {
            return None;
        }
        let device = &r.ctx.device;
        let bytes = count as u64 * 8;
        let buf = |label, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage,
                mapped_at_creation: false,
            })
        };
        Some(Timestamps {
            set: device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("pass timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count,
            }),
            resolve: buf(
                "timestamps",
                wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            ),
            read: buf(
                "timestamps read",
                wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            ),
            count,
        })
    }

    fn writes(&self, chunk: u32) -> wgpu::ComputePassTimestampWrites<'_> {
        wgpu::ComputePassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(2 * chunk),
            end_of_pass_write_index: Some(2 * chunk + 1),
        }
    }

    fn resolve(&self, enc: &mut wgpu::CommandEncoder) {
        enc.resolve_query_set(&self.set, 0..self.count, &self.resolve, 0);
        enc.copy_buffer_to_buffer(&self.resolve, 0, &self.read, 0, self.count as u64 * 8);
    }

    /// The summed pass time; `None` when a pair is out of order (a driver
    /// that does not keep its timestamps monotonic across a pass).
    fn seconds(&self, r: &GpuRenderer) -> Result<Option<f64>, GpuError> {
        // Collected, not cast: the mapped bytes need not be 8-aligned.
        let ticks: Vec<u64> = map_read(&r.ctx.device, &self.read, bytemuck::pod_collect_to_vec)?;
        let mut sum = 0u64;
        for pair in ticks.chunks_exact(2) {
            match pair[1].checked_sub(pair[0]) {
                Some(d) => sum += d,
                None => return Ok(None),
            }
        }
        let period_ns = r.ctx.queue.get_timestamp_period() as f64;
        Ok((period_ns > 0.0).then_some(sum as f64 * period_ns * 1e-9))
    }
}
