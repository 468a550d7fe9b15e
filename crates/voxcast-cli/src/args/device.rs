//! `--device`, shared by render, bench and view.

/// `--device`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum DeviceArg {
    Cpu,
    Gpu,
    Auto,
}

impl From<DeviceArg> for voxcast_gpu::DeviceRequest {
    fn from(d: DeviceArg) -> Self {
        match d {
            DeviceArg::Cpu => voxcast_gpu::DeviceRequest::Cpu,
            DeviceArg::Gpu => voxcast_gpu::DeviceRequest::Gpu,
            DeviceArg::Auto => voxcast_gpu::DeviceRequest::Auto,
        }
    }
}

/// `--gpu-filter`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum GpuFilterArg {
    /// hardware on a hardware GPU, exact on a software rasteriser (lavapipe).
    #[default]
    Auto,
    /// Eight texel loads and the CPU's trilinear arithmetic: the CPU's picture.
    Exact,
    /// The texture unit's trilinear filter: one fetch per sample, with the
    /// hardware's weight precision (u8 and u16 volumes in one brick; others
    /// fall back to exact).
    Hardware,
}

impl From<GpuFilterArg> for voxcast_gpu::Filter {
    fn from(f: GpuFilterArg) -> Self {
        match f {
            GpuFilterArg::Auto => voxcast_gpu::Filter::Auto,
            GpuFilterArg::Exact => voxcast_gpu::Filter::Exact,
            GpuFilterArg::Hardware => voxcast_gpu::Filter::Hardware,
        }
    }
}

/// `--device`'s long help, after `intro`: the GPU's methods come from the
/// one table (`voxcast::render::Backend`), so the help cannot drift from
/// what the GPU renders.
pub fn device_help(intro: &str) -> String {
    use voxcast::render::Backend;
    format!(
        "{intro}cpu: the multi-threaded CPU ray caster. gpu: the wgpu compute-shader ray caster on any Vulkan adapter, software ones such as lavapipe included (WGPU_BACKEND is honoured); with no adapter this is an error naming what was tried, never a silent fallback. auto: a hardware GPU if there is one and it renders the scene, else the CPU (a software rasteriser is slower than the CPU renderer); the choice is printed.\n\nThe GPU renders {}; opaque boxes and planes (not OBJ meshes); volumes beyond its 3D texture limit in up to eight bricks; and gives the CPU's picture (PSNR ≥ 40 dB). The CPU renders every method.",
        Backend::Gpu.method_list()
    )
}
