//! The device: picking an adapter ([`DeviceChoice`]), the wgpu context,
//! and the helpers that turn wgpu's errors into [`GpuError`]s and read a
//! buffer back.

use std::sync::Arc;

use voxcast::transfer::LUT_SIZE;

/// What went wrong on the GPU side.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No adapter fit the request; the message lists what was tried.
    #[error("no GPU adapter: {0}")]
    NoAdapter(String),
    /// The adapter would not give a device, or the device failed.
    #[error("GPU device: {0}")]
    Device(String),
    /// A feature of the scene the GPU renderer does not have.
    #[error("not supported on the GPU back end: {0}")]
    Unsupported(String),
    /// An error of the core library (bad parameters, I/O).
    #[error(transparent)]
    Core(#[from] voxcast::Error),
}

/// Which device to render on, as given by `--device`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DeviceChoice {
    /// Any adapter of the enabled backends, software ones included.
    Gpu,
    /// A hardware adapter only (discrete, integrated or virtual GPU).
    Auto,
}

/// Names of the backends this build can use, e.g. `"vulkan"`.
pub fn compiled_backends() -> &'static str {
    "vulkan"
}

fn backend_names(b: wgpu::Backends) -> String {
    let mut v = Vec::new();
    for (flag, name) in [
        (wgpu::Backends::VULKAN, "vulkan"),
        (wgpu::Backends::METAL, "metal"),
        (wgpu::Backends::DX12, "dx12"),
        (wgpu::Backends::GL, "gl"),
        (wgpu::Backends::BROWSER_WEBGPU, "webgpu"),
    ] {
        if b.contains(flag) {
            v.push(name);
        }
    }
    if v.is_empty() {
        "none".into()
    } else {
        v.join(", ")
    }
}

/// An adapter and its device and queue, shared by the renderers.
pub struct GpuContext {
    pub(crate) adapter: wgpu::Adapter,
    pub(crate) device: wgpu::Device,
    pub(crate) queue: wgpu::Queue,
    pub(crate) info: wgpu::AdapterInfo,
}

/// One adapter found by [`GpuContext::probe`].
#[derive(Clone, Debug)]
pub struct AdapterSummary {
    pub name: String,
    pub backend: String,
    pub device_type: String,
    pub driver: String,
}

impl std::fmt::Display for AdapterSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} ({}, {}{})",
            self.name,
            self.backend,
            self.device_type,
            if self.driver.is_empty() {
                String::new()
            } else {
                format!(", {}", self.driver)
            }
        )
    }
}

fn summary(info: &wgpu::AdapterInfo) -> AdapterSummary {
    AdapterSummary {
        name: info.name.clone(),
        backend: format!("{:?}", info.backend).to_lowercase(),
        device_type: match info.device_type {
            wgpu::DeviceType::DiscreteGpu => "discrete GPU",
            wgpu::DeviceType::IntegratedGpu => "integrated GPU",
            wgpu::DeviceType::VirtualGpu => "virtual GPU",
            wgpu::DeviceType::Cpu => "software (CPU)",
            wgpu::DeviceType::Other => "other",
        }
        .into(),
        driver: [info.driver.as_str(), info.driver_info.as_str()]
            .iter()
            .filter(|s| !s.is_empty())
            .copied()
            .collect::<Vec<_>>()
            .join(" "),
    }
}

fn is_hardware(t: wgpu::DeviceType) -> bool {
    matches!(
        t,
        wgpu::DeviceType::DiscreteGpu
            | wgpu::DeviceType::IntegratedGpu
            | wgpu::DeviceType::VirtualGpu
    )
}

fn rank(t: wgpu::DeviceType) -> u32 {
    match t {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    }
}

impl GpuContext {
    /// The backends to try: those compiled in, narrowed by `WGPU_BACKEND`.
    fn instance() -> (wgpu::Instance, wgpu::Backends) {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
        if std::env::var_os("WGPU_BACKEND").is_none() {
            desc.backends = wgpu::Backends::VULKAN;
        }
        let backends = desc.backends;
        (wgpu::Instance::new(desc), backends)
    }

    /// All adapters the enabled backends offer, and the backends tried.
    pub fn probe() -> (Vec<AdapterSummary>, String) {
        let (instance, backends) = Self::instance();
        let adapters = pollster::block_on(instance.enumerate_adapters(backends));
        (
            adapters.iter().map(|a| summary(&a.get_info())).collect(),
            backend_names(backends),
        )
    }

    /// Opens a device on the best adapter allowed by `choice` (discrete
    /// first, software last). Never falls back to another backend: with no
    /// fitting adapter the error says which backends and adapters were
    /// tried.
    pub fn new(choice: DeviceChoice) -> Result<Arc<GpuContext>, GpuError> {
        let (instance, backends) = Self::instance();
        let adapters = pollster::block_on(instance.enumerate_adapters(backends));
        let found: Vec<String> = adapters
            .iter()
            .map(|a| summary(&a.get_info()).to_string())
            .collect();
        let tried = format!(
            "tried backends [{}] (compiled in: {}; WGPU_BACKEND={}); adapters found: {}",
            backend_names(backends),
            compiled_backends(),
            std::env::var("WGPU_BACKEND").unwrap_or_else(|_| "unset".into()),
            if found.is_empty() {
                "none".to_string()
            } else {
                found.join("; ")
            }
        );
        let adapter = adapters
            .into_iter()
            .filter(|a| choice == DeviceChoice::Gpu || is_hardware(a.get_info().device_type))
            .min_by_key(|a| rank(a.get_info().device_type))
            .ok_or_else(|| {
                let hint = match choice {
                    DeviceChoice::Auto => "no hardware adapter",
                    DeviceChoice::Gpu => {
                        "no adapter at all (install a Vulkan driver: your GPU's, or Mesa's lavapipe from the `mesa-vulkan-drivers` package)"
                    }
                };
                GpuError::NoAdapter(format!("{hint}; {tried}"))
            })?;
        let info = adapter.get_info();
        let alimits = adapter.limits();
        let limits = wgpu::Limits {
            max_texture_dimension_3d: alimits.max_texture_dimension_3d,
            max_texture_dimension_1d: alimits.max_texture_dimension_1d.max(LUT_SIZE as u32),
            max_storage_buffer_binding_size: alimits.max_storage_buffer_binding_size,
            max_buffer_size: alimits.max_buffer_size,
            ..wgpu::Limits::default()
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("voxcast"),
            // Timestamps time the compute passes apart from upload and
            // read-back (`RenderStats::device_seconds`), where offered.
            // `r32float` volumes filtered by the texture unit
            // (`Filter::Hardware`), where offered.
            required_features: adapter.features()
                & (wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::FLOAT32_FILTERABLE),
            required_limits: limits,
            ..Default::default()
        }))
        .map_err(|e| GpuError::Device(format!("{} refused a device: {e}", info.name)))?;
        Ok(Arc::new(GpuContext {
            adapter,
            device,
            queue,
            info,
        }))
    }

    /// The adapter in use, in words (name, backend, type, driver).
    pub fn info(&self) -> String {
        summary(&self.info).to_string()
    }

    /// Whether the adapter is a software rasteriser (lavapipe, SwiftShader).
    pub fn is_software(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// The adapter's limits.
    pub fn limits(&self) -> wgpu::Limits {
        self.adapter.limits()
    }

    /// Whether `r32float` textures can be filtered by the texture unit.
    pub fn filters_f32(&self) -> bool {
        self.device
            .features()
            .contains(wgpu::Features::FLOAT32_FILTERABLE)
    }

    /// Whether renders are timed on the device by timestamp queries.
    pub fn has_timestamps(&self) -> bool {
        self.device
            .features()
            .contains(wgpu::Features::TIMESTAMP_QUERY)
    }
}

/// Describes the adapter [`GpuContext::new`] would pick for `choice`,
/// without keeping it, or the error naming what was tried.
pub fn adapter_info(choice: DeviceChoice) -> Result<String, GpuError> {
    GpuContext::new(choice).map(|c| c.info())
}

/// Runs `f` with wgpu's validation and out-of-memory errors captured, so
/// they come back as a [`GpuError`] naming `what` instead of wgpu's default
/// handler's panic.
pub(crate) fn scoped<T>(
    device: &wgpu::Device,
    what: &str,
    f: impl FnOnce() -> T,
) -> Result<T, GpuError> {
    let oom = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let r = f();
    let v = pollster::block_on(validation.pop());
    let o = pollster::block_on(oom.pop());
    match v.or(o) {
        Some(e) => Err(GpuError::Device(format!("{what}: {e}"))),
        None => Ok(r),
    }
}

/// Maps `buf`, copies its bytes out and unmaps it.
pub(crate) fn read_back(device: &wgpu::Device, buf: &wgpu::Buffer) -> Result<Vec<u8>, GpuError> {
    map_read(device, buf, |b| b.to_vec())
}

/// Waits for `buf`, maps it, hands its bytes to `f` and unmaps it: `f` reads
/// the mapped memory in place (an image is converted there, not copied
/// first).
pub(crate) fn map_read<T>(
    device: &wgpu::Device,
    buf: &wgpu::Buffer,
    f: impl FnOnce(&[u8]) -> T,
) -> Result<T, GpuError> {
    let (tx, rx) = std::sync::mpsc::channel();
    buf.map_async(wgpu::MapMode::Read, .., move |r| {
        let _ = tx.send(r);
    });
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| GpuError::Device(format!("waiting for the render: {e}")))?;
    rx.recv()
        .map_err(|_| GpuError::Device("the read-back was dropped".into()))?
        .map_err(|e| GpuError::Device(format!("reading the image back: {e}")))?;
    let out = f(&buf
        .get_mapped_range(..)
        .map_err(|e| GpuError::Device(format!("reading the image back: {e}")))?);
    buf.unmap();
    Ok(out)
}
