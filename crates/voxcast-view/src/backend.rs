//! Frame back ends: what turns (transfer function, camera, parameters) into
//! an image for the viewer. One is made per volume and data window (its
//! derived structures are built once) and then asked for frame after frame.
//!
//! Today there is the CPU ray caster. A GPU back end plugs in as one more
//! [`Backend`] variant and one more arm in [`create`]: an adapter type that
//! holds the GPU renderer made once per volume and implements
//! [`FrameRenderer::render`] by updating the transfer function and camera
//! and rendering.

use std::sync::Arc;
use voxcast::camera::CameraParams;
use voxcast::geometry::Geometry;
use voxcast::render::{RenderParams, Renderer};
use voxcast::transfer::TransferFunction;
use voxcast::{Image, RenderStats, Volume};

/// Which renderer draws the frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Backend {
    /// The CPU ray caster (`voxcast::render`), the same as `voxcast render`.
    #[default]
    Cpu,
}

impl Backend {
    /// The name shown in the stats bar.
    pub fn name(self) -> &'static str {
        match self {
            Backend::Cpu => "CPU",
        }
    }
}

/// A renderer bound to one volume and data window.
pub trait FrameRenderer {
    /// Renders one frame.
    fn render(
        &mut self,
        tf: &TransferFunction,
        camera: &CameraParams,
        params: &RenderParams,
    ) -> voxcast::Result<(Image, RenderStats)>;
}

/// Makes the frame renderer of `backend` for `volume` over `window`, with
/// the scene's opaque geometry.
pub fn create<'v>(
    backend: Backend,
    volume: &'v Volume,
    window: [f32; 2],
    geometry: Option<Arc<Geometry>>,
) -> voxcast::Result<Box<dyn FrameRenderer + 'v>> {
    match backend {
        Backend::Cpu => Ok(Box::new(CpuFrames {
            renderer: Renderer::new(volume, window)?.with_geometry(geometry),
        })),
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
    ) -> voxcast::Result<(Image, RenderStats)> {
        self.renderer.render(tf, camera, params, &|_, _| {})
    }
}
