//! `--device`: the one choice of `voxcast_gpu::choose`, for render, bench and
//! view, and the GPU renderer of a prepared scene.

use crate::args::DeviceArg;
use anyhow::{Context, Result};
use voxcast_gpu::Device;

/// Resolves `--device` with `voxcast_gpu::choose` for a scene rendered with
/// `methods` and `geometry`, and prints the reason for the choice unless
/// `quiet`. `gpu` must find an adapter (the error names the backends and
/// adapters tried) and render every method; `auto` takes a hardware GPU when
/// there is one and it renders the scene, else the CPU, and says which.
pub fn pick_device(
    arg: DeviceArg,
    methods: &[voxcast::render::Method],
    geometry: Option<&voxcast::geometry::Geometry>,
    quiet: bool,
) -> Result<Device> {
    let request = voxcast_gpu::DeviceRequest::from(arg);
    let choice = voxcast_gpu::choose(request, methods, geometry)
        .with_context(|| format!("--device {}", request.name()))?;
    if let (Some(note), false) = (&choice.note, quiet) {
        eprintln!("{note}");
    }
    Ok(choice.device)
}

/// Uploads the prepared volume to the GPU.
pub fn gpu_renderer(
    ctx: &std::sync::Arc<voxcast_gpu::GpuContext>,
    prepared: &voxcast::scene::Prepared,
    filter: voxcast_gpu::Filter,
    quiet: bool,
) -> Result<voxcast_gpu::GpuRenderer> {
    let options = voxcast_gpu::GpuOptions {
        filter,
        ..Default::default()
    };
    let r = voxcast_gpu::GpuRenderer::with_options(
        ctx.clone(),
        &prepared.volume,
        prepared.window,
        options,
    )
    .context("uploading the volume to the GPU")?
    .with_geometry(prepared.geometry.as_deref())?;
    if filter == voxcast_gpu::Filter::Hardware && r.filter() != filter && !quiet {
        eprintln!(
            "--gpu-filter hardware: this volume is {} in {} brick(s); the texture unit filters one brick of u8 or f16 (f32 where the device offers FLOAT32_FILTERABLE), so the exact filter is used",
            r.texture_format(),
            r.bricking().len()
        );
    }
    Ok(r)
}
