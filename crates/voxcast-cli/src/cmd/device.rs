//! `--device`: the CPU renderer or a GPU one, for render and bench.

use crate::args::DeviceArg;
use anyhow::{bail, Context, Result};
use voxcast::scene::Scene;

/// The renderer `--device` chose.
pub enum Device {
    Cpu,
    Gpu(std::sync::Arc<voxcast_gpu::GpuContext>),
}

impl Device {
    pub fn describe(&self) -> String {
        match self {
            Device::Cpu => format!(
                "cpu ({} threads)",
                std::thread::available_parallelism().map_or(1, |n| n.get())
            ),
            Device::Gpu(ctx) => format!("gpu: {}", ctx.info()),
        }
    }
}

/// Resolves `--device` for `scene`: `gpu` must find an adapter (the error
/// names the backends and adapters tried); `auto` takes a hardware GPU when
/// there is one and it renders the scene's method, else the CPU, and says
/// which. Triangle meshes in `geometry` are CPU-only (boxes and planes are
/// fine on the GPU).
pub fn pick_device(
    arg: DeviceArg,
    scene: &Scene,
    geometry: Option<&voxcast::geometry::Geometry>,
    quiet: bool,
) -> Result<Device> {
    use voxcast_gpu::{DeviceChoice, GpuContext, GpuError, GpuRenderer};
    match arg {
        DeviceArg::Cpu => Ok(Device::Cpu),
        DeviceArg::Gpu => {
            if !voxcast_gpu::supports(scene.render.method) {
                bail!(
                    "--device gpu: method `{}` is not implemented on the GPU (it renders uniform, adaptive, adaptive-max, threshold, jitter, stratified, mc and single-scatter); use --device cpu or auto",
                    scene.render.method.name()
                );
            }
            let ctx = GpuContext::new(DeviceChoice::Gpu).context("--device gpu")?;
            if !quiet {
                eprintln!("rendering on {}", ctx.info());
            }
            Ok(Device::Gpu(ctx))
        }
        DeviceArg::Auto => {
            if !voxcast_gpu::supports(scene.render.method) {
                if !quiet {
                    eprintln!(
                        "--device auto: method `{}` has no GPU version; rendering on the CPU",
                        scene.render.method.name()
                    );
                }
                return Ok(Device::Cpu);
            }
            if !GpuRenderer::supports_geometry(geometry) {
                if !quiet {
                    eprintln!(
                        "--device auto: triangle meshes have no GPU version; rendering on the CPU"
                    );
                }
                return Ok(Device::Cpu);
            }
            match GpuContext::new(DeviceChoice::Auto) {
                Ok(ctx) => {
                    if !quiet {
                        eprintln!("--device auto: rendering on {}", ctx.info());
                    }
                    Ok(Device::Gpu(ctx))
                }
                Err(GpuError::NoAdapter(why)) => {
                    if !quiet {
                        eprintln!("--device auto: {why}; rendering on the CPU");
                    }
                    Ok(Device::Cpu)
                }
                Err(e) => Err(e).context("--device auto"),
            }
        }
    }
}

/// Uploads the prepared volume to the GPU.
pub fn gpu_renderer(
    ctx: &std::sync::Arc<voxcast_gpu::GpuContext>,
    prepared: &voxcast::scene::Prepared,
) -> Result<voxcast_gpu::GpuRenderer> {
    let r = voxcast_gpu::GpuRenderer::new(ctx.clone(), &prepared.volume, prepared.window)
        .context("uploading the volume to the GPU")?
        .with_geometry(prepared.geometry.as_deref())?;
    Ok(r)
}
