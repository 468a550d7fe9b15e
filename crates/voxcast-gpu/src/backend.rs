//! The one choice of device, shared by `voxcast render`, `bench`, `view`
//! and the viewer: `cpu`, `gpu` or `auto` → the CPU ray caster or a GPU
//! context, with the reason said in one line.
//!
//! What each back end renders is the core's table
//! ([`voxcast::render::Backend::renders`]); this module adds what the core
//! cannot know without a GPU library: whether an adapter is there. It lives
//! in this crate, the lowest one that knows both back ends, so the core
//! stays free of GPU dependencies.

use std::sync::Arc;

use voxcast::geometry::Geometry;
use voxcast::render::{Backend, Method};

use crate::context::{DeviceChoice, GpuContext, GpuError};

/// Where the user asked to render.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DeviceRequest {
    /// The multi-threaded CPU ray caster.
    Cpu,
    /// The GPU ray caster on any adapter of the enabled backends, software
    /// ones (lavapipe) included; an error when there is none or when the
    /// scene's method has no GPU version.
    Gpu,
    /// A hardware GPU when there is one and it renders the scene, else the
    /// CPU (a software rasteriser is slower than the CPU renderer).
    #[default]
    Auto,
}

impl DeviceRequest {
    pub const ALL: [DeviceRequest; 3] =
        [DeviceRequest::Cpu, DeviceRequest::Gpu, DeviceRequest::Auto];

    /// `cpu`, `gpu` or `auto`.
    pub fn name(self) -> &'static str {
        match self {
            DeviceRequest::Cpu => "cpu",
            DeviceRequest::Gpu => "gpu",
            DeviceRequest::Auto => "auto",
        }
    }

    /// Parses `cpu`, `gpu` or `auto`.
    pub fn parse(s: &str) -> Option<DeviceRequest> {
        DeviceRequest::ALL.into_iter().find(|d| d.name() == s)
    }
}

/// The renderer chosen.
#[derive(Clone, Default)]
pub enum Device {
    /// The CPU ray caster (`voxcast::render::Renderer`).
    #[default]
    Cpu,
    /// The GPU ray caster on this adapter.
    Gpu(Arc<GpuContext>),
}

impl std::fmt::Debug for Device {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Device::Cpu => f.write_str("Cpu"),
            Device::Gpu(ctx) => write!(f, "Gpu({})", ctx.info()),
        }
    }
}

impl Device {
    /// Which back end this is.
    pub fn backend(&self) -> Backend {
        match self {
            Device::Cpu => Backend::Cpu,
            Device::Gpu(_) => Backend::Gpu,
        }
    }

    /// For messages and stats: `cpu (N threads)` or `gpu: ADAPTER (…)`.
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

/// A device and why it was taken.
#[derive(Debug)]
pub struct Choice {
    pub device: Device,
    /// One line for the user, e.g. `--device auto: method `lod` has no GPU
    /// version; rendering on the CPU`; `None` for an explicit `cpu`.
    pub note: Option<String>,
}

/// Resolves `request` for a scene that will be rendered with `methods` and
/// `geometry`: `cpu` is the CPU; `gpu` must find an adapter and render every
/// method (the error names the adapters tried, or the method and what the
/// GPU renders); `auto` takes a hardware GPU when there is one and the GPU
/// renders every method and the geometry, else the CPU, and says which.
///
/// A caller that falls back to the CPU frame by frame (the viewer) or
/// reports unsupported methods one by one (the bench under `gpu`) passes
/// no methods.
pub fn choose(
    request: DeviceRequest,
    methods: &[Method],
    geometry: Option<&Geometry>,
) -> Result<Choice, GpuError> {
    let lacking = methods.iter().find(|&&m| !Backend::Gpu.renders(m));
    match request {
        DeviceRequest::Cpu => Ok(Choice {
            device: Device::Cpu,
            note: None,
        }),
        DeviceRequest::Gpu => {
            if let Some(m) = lacking {
                return Err(GpuError::Unsupported(format!(
                    "method `{}` (the GPU renders {}); use --device cpu or auto",
                    m.name(),
                    Backend::Gpu.method_list()
                )));
            }
            let ctx = GpuContext::new(DeviceChoice::Gpu)?;
            Ok(Choice {
                note: Some(format!("rendering on {}", ctx.info())),
                device: Device::Gpu(ctx),
            })
        }
        DeviceRequest::Auto => {
            let cpu = |why: String| {
                Ok(Choice {
                    device: Device::Cpu,
                    note: Some(format!("--device auto: {why}; rendering on the CPU")),
                })
            };
            if let Some(m) = lacking {
                return cpu(format!("method `{}` has no GPU version", m.name()));
            }
            if !Backend::Gpu.renders_geometry(geometry) {
                return cpu("triangle meshes have no GPU version".into());
            }
            match GpuContext::new(DeviceChoice::Auto) {
                Ok(ctx) => Ok(Choice {
                    note: Some(format!("--device auto: rendering on {}", ctx.info())),
                    device: Device::Gpu(ctx),
                }),
                Err(GpuError::NoAdapter(why)) => cpu(why),
                Err(e) => Err(e),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_parse_by_name() {
        for d in DeviceRequest::ALL {
            assert_eq!(DeviceRequest::parse(d.name()), Some(d));
        }
        assert_eq!(DeviceRequest::parse("tpu"), None);
    }

    /// `cpu` never probes; `auto` with a method the GPU lacks takes the CPU
    /// and says why, without probing either (no adapter needed here).
    #[test]
    fn cpu_and_auto_fallbacks_need_no_adapter() {
        let c = choose(DeviceRequest::Cpu, &[Method::Lod], None).unwrap();
        assert!(matches!(c.device, Device::Cpu) && c.note.is_none());
        let c = choose(DeviceRequest::Auto, &[Method::Uniform, Method::Lod], None).unwrap();
        assert!(matches!(c.device, Device::Cpu));
        let note = c.note.unwrap();
        assert!(note.contains("method `lod` has no GPU version"), "{note}");
    }

    /// `gpu` with a method the GPU lacks is an error naming it and the list
    /// of what the GPU renders, before any adapter is looked for.
    #[test]
    fn gpu_refuses_what_it_lacks_by_name() {
        let e = choose(DeviceRequest::Gpu, &[Method::Path], None).unwrap_err();
        let s = e.to_string();
        assert!(s.contains("method `path`"), "{s}");
        assert!(s.contains("uniform, adaptive"), "{s}");
        assert!(!s.contains("importance,"), "{s}");
    }
}
