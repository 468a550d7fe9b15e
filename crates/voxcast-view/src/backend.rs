//! Frame back ends: what turns (transfer function, camera, parameters) into
//! an image for the viewer. One is made per volume and data window (its
//! derived structures are built once) and then asked for frame after frame.
//!
//! Two back ends: the CPU ray caster, and the wgpu compute ray caster of
//! `voxcast-gpu` (the volume uploaded once per volume and window; each frame
//! only rewrites the transfer-function table and the camera). Methods the GPU
//! does not have (and scenes with triangle meshes) are drawn by the CPU
//! renderer inside the GPU back end, frame by frame, so every control keeps
//! working; the stats bar says which device drew the frame.

use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use voxcast::camera::CameraParams;
use voxcast::geometry::Geometry;
use voxcast::render::{Backend, RenderParams, Renderer};
use voxcast::transfer::TransferFunction;
use voxcast::{Image, RenderStats, Volume};
use voxcast_gpu::{Device, GpuRenderer};

/// The name shown in the stats bar: `CPU` or `GPU`.
pub fn label(device: &Device) -> &'static str {
    match device.backend() {
        Backend::Cpu => "CPU",
        Backend::Gpu => "GPU",
    }
}

/// A renderer bound to one volume and data window.
pub trait FrameRenderer {
    /// Renders one frame; gives up with [`voxcast::Error::Cancelled`] once
    /// `cancel` is raised (the CPU renderer checks it per tile; a GPU frame
    /// is one short dispatch and runs to its end).
    fn render(
        &mut self,
        tf: &TransferFunction,
        camera: &CameraParams,
        params: &RenderParams,
        cancel: &AtomicBool,
    ) -> voxcast::Result<(Image, RenderStats)>;

    /// What the last frame showed of a store drawn out of core.
    fn store_frame(&self) -> Option<crate::stream::StoreFrame> {
        None
    }
}

/// Makes the frame renderer of `device` (chosen by `voxcast_gpu::choose`)
/// for `volume` over `window`, with the scene's opaque geometry.
pub fn create<'v>(
    device: Device,
    volume: &'v Volume,
    window: [f32; 2],
    geometry: Option<Arc<Geometry>>,
) -> voxcast::Result<Box<dyn FrameRenderer + 'v>> {
    match device {
        Device::Cpu => Ok(Box::new(CpuFrames {
            renderer: Renderer::new(volume, window)?.with_geometry(geometry),
        })),
        Device::Gpu(ctx) => {
            let gpu = GpuRenderer::new(ctx, volume, window)
                .map_err(|e| voxcast::Error::invalid(e.to_string()))?;
            // Boxes and planes are drawn on the GPU; meshes only on the CPU.
            let cpu_geometry = !Backend::Gpu.renders_geometry(geometry.as_deref());
            let gpu = if cpu_geometry {
                gpu
            } else {
                gpu.with_geometry(geometry.as_deref())
                    .map_err(|e| voxcast::Error::invalid(e.to_string()))?
            };
            Ok(Box::new(GpuFrames {
                gpu,
                cpu_geometry,
                volume,
                window,
                geometry,
                cpu: None,
            }))
        }
    }
}

/// The GPU ray caster, with the CPU renderer (made the first time it is
/// needed) for the methods and scenes the GPU does not draw.
struct GpuFrames<'v> {
    gpu: GpuRenderer,
    /// Geometry the GPU does not draw (triangle meshes).
    cpu_geometry: bool,
    volume: &'v Volume,
    window: [f32; 2],
    geometry: Option<Arc<Geometry>>,
    cpu: Option<Renderer<'v>>,
}

impl FrameRenderer for GpuFrames<'_> {
    fn render(
        &mut self,
        tf: &TransferFunction,
        camera: &CameraParams,
        params: &RenderParams,
        cancel: &AtomicBool,
    ) -> voxcast::Result<(Image, RenderStats)> {
        if Backend::Gpu.renders(params.method) && !self.cpu_geometry {
            return self
                .gpu
                .render(tf, camera, params)
                .map_err(|e| voxcast::Error::invalid(format!("GPU: {e}")));
        }
        if self.cpu.is_none() {
            self.cpu =
                Some(Renderer::new(self.volume, self.window)?.with_geometry(self.geometry.clone()));
        }
        let cpu = self.cpu.as_ref().expect("made just above");
        cpu.render_cancellable(tf, camera, params, &|_, _| {}, cancel)
    }
}

/// The CPU ray caster: exactly what `Scene::render` runs, so a saved scene
/// renders the same image from the command line.
struct CpuFrames<'v> {
    renderer: Renderer<'v>,
}

impl FrameRenderer for CpuFrames<'_> {
    fn render(
        &mut self,
        tf: &TransferFunction,
        camera: &CameraParams,
        params: &RenderParams,
        cancel: &AtomicBool,
    ) -> voxcast::Result<(Image, RenderStats)> {
        self.renderer
            .render_cancellable(tf, camera, params, &|_, _| {}, cancel)
    }
}
