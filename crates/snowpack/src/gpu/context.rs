//! Adapter and device selection with overrides, fallbacks and actionable errors.
//!
//! * `SNOWPACK_BACKEND` (or wgpu's `WGPU_BACKEND`): a comma list of
//!   `vulkan`, `gl`, `metal`, `dx12`, `webgpu`.
//! * `SNOWPACK_ADAPTER`: a case-insensitive substring of the adapter's name.
//!
//! Without overrides the best adapter wins: discrete, integrated, virtual, then
//! software; Vulkan before other backends on a tie.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use crate::error::SnowError;

/// How long a blocking wait for the GPU may take before it is an error, not a hang.
pub const WAIT_TIMEOUT: Duration = Duration::from_secs(60);

/// What a person needs to know about the chosen adapter.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AdapterSummary {
    /// The adapter's name, e.g. `NVIDIA H100` or `llvmpipe (LLVM 15.0.6, 256 bits)`.
    pub name: String,
    /// The backend, lower case: `vulkan`, `gl`, `metal`, `dx12`, `webgpu`.
    pub backend: String,
    /// `discrete`, `integrated`, `virtual`, `cpu` or `other`.
    pub device_type: String,
    /// Driver name and version, where the backend reports them.
    pub driver: String,
}

impl AdapterSummary {
    fn from_info(info: &wgpu::AdapterInfo) -> Self {
        let device_type = match info.device_type {
            wgpu::DeviceType::DiscreteGpu => "discrete",
            wgpu::DeviceType::IntegratedGpu => "integrated",
            wgpu::DeviceType::VirtualGpu => "virtual",
            wgpu::DeviceType::Cpu => "cpu",
            wgpu::DeviceType::Other => "other",
        };
        Self {
            name: info.name.clone(),
            backend: info.backend.to_str().to_owned(),
            device_type: device_type.to_owned(),
            driver: format!("{} {}", info.driver, info.driver_info).trim().to_owned(),
        }
    }

    /// True for software rasterisers (llvmpipe, lavapipe, WARP, SwiftShader):
    /// their timings are for ratios only.
    #[must_use]
    pub fn is_software(&self) -> bool {
        self.device_type == "cpu" || self.name.to_ascii_lowercase().contains("llvmpipe")
    }
}

/// Errors wgpu reported outside error scopes, and the device-lost reason.
#[derive(Default)]
struct ErrorSink {
    errors: Mutex<Vec<String>>,
    lost: Mutex<Option<String>>,
}

/// A wgpu device and queue chosen for snowpack, with error tracking.
pub struct GpuContext {
    /// The instance the adapter came from.
    pub instance: wgpu::Instance,
    /// The chosen adapter.
    pub adapter: wgpu::Adapter,
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// The adapter, in words.
    pub summary: AdapterSummary,
    sink: Arc<ErrorSink>,
}

fn parse_backends(list: &str) -> Result<wgpu::Backends, SnowError> {
    let mut backends = wgpu::Backends::empty();
    for name in list.split(',').map(|s| s.trim().to_ascii_lowercase()).filter(|s| !s.is_empty()) {
        backends |= match name.as_str() {
            "vulkan" | "vk" => wgpu::Backends::VULKAN,
            "gl" | "gles" | "opengl" => wgpu::Backends::GL,
            "metal" | "mtl" => wgpu::Backends::METAL,
            "dx12" | "d3d12" => wgpu::Backends::DX12,
            "webgpu" | "browser" => wgpu::Backends::BROWSER_WEBGPU,
            _ => return Err(SnowError::UnknownBackend(list.to_owned())),
        };
    }
    if backends.is_empty() {
        return Err(SnowError::UnknownBackend(list.to_owned()));
    }
    Ok(backends)
}

fn type_rank(t: wgpu::DeviceType) -> u32 {
    match t {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Cpu => 3,
        wgpu::DeviceType::Other => 4,
    }
}

const NO_ADAPTER_HINT: &str = "install a driver: on Debian/Ubuntu without a GPU, \
`apt-get install mesa-vulkan-drivers` (lavapipe, Vulkan) or `apt-get install libegl1 libgl1-mesa-dri` \
(llvmpipe, GL); check SNOWPACK_BACKEND / SNOWPACK_ADAPTER if set";

impl GpuContext {
    /// Picks an adapter (honouring `SNOWPACK_BACKEND` and `SNOWPACK_ADAPTER`) and
    /// creates a device without a surface, for headless runs, tests and the bench.
    pub fn new_headless() -> Result<Self, SnowError> {
        Self::new_headless_with(None, None)
    }

    /// Like [`Self::new_headless`], with explicit backend list and adapter-name
    /// filter taking precedence over the environment (for `--backend`).
    pub fn new_headless_with(backend: Option<&str>, adapter: Option<&str>) -> Result<Self, SnowError> {
        let desc = Self::instance_descriptor(wgpu::InstanceDescriptor::new_without_display_handle_from_env(), backend)?;
        let instance = wgpu::Instance::new(desc);
        Self::choose(instance, None, backend, adapter)
    }

    /// `desc` with its backends narrowed by `backend` or `SNOWPACK_BACKEND`
    /// (for a windowed instance, start from
    /// `wgpu::InstanceDescriptor::new_with_display_handle_from_env`).
    pub fn instance_descriptor(mut desc: wgpu::InstanceDescriptor, backend: Option<&str>) -> Result<wgpu::InstanceDescriptor, SnowError> {
        let env = |key: &str| std::env::var(key).ok().filter(|s| !s.trim().is_empty());
        if let Some(list) = backend.map(str::to_owned).or_else(|| env("SNOWPACK_BACKEND")) {
            desc.backends = parse_backends(&list)?;
        }
        Ok(desc)
    }

    /// Picks the best adapter of `instance` that can present to `surface`
    /// (when given), honouring `backend`/`SNOWPACK_BACKEND` and
    /// `adapter`/`SNOWPACK_ADAPTER`, and creates the device.
    pub fn choose(instance: wgpu::Instance, surface: Option<&wgpu::Surface<'_>>, backend: Option<&str>, adapter: Option<&str>) -> Result<Self, SnowError> {
        let env = |key: &str| std::env::var(key).ok().filter(|s| !s.trim().is_empty());
        let backend_env = backend.map(str::to_owned).or_else(|| env("SNOWPACK_BACKEND"));
        let adapter_env = adapter.map(str::to_owned).or_else(|| env("SNOWPACK_ADAPTER"));
        let backends = match &backend_env {
            Some(list) => parse_backends(list)?,
            None => wgpu::Backends::all(),
        };
        let mut adapters = pollster::block_on(instance.enumerate_adapters(backends));
        if let Some(surface) = surface {
            adapters.retain(|a| a.is_surface_supported(surface));
        }
        let mut filter = String::new();
        if let Some(list) = &backend_env {
            filter.push_str(&format!(" with SNOWPACK_BACKEND={list}"));
        }
        if surface.is_some() {
            filter.push_str(" that can present to the window");
        }
        if let Some(name) = &adapter_env {
            let needle = name.to_ascii_lowercase();
            adapters.retain(|a| a.get_info().name.to_ascii_lowercase().contains(&needle));
            filter.push_str(&format!(" with SNOWPACK_ADAPTER={name}"));
        }
        adapters.sort_by_key(|a| {
            let info = a.get_info();
            (type_rank(info.device_type), u32::from(info.backend != wgpu::Backend::Vulkan))
        });
        let adapter = adapters
            .into_iter()
            .next()
            .ok_or_else(|| SnowError::NoAdapter { filter, hint: NO_ADAPTER_HINT.to_owned() })?;
        Self::from_adapter(instance, adapter)
    }

    /// Creates the device on a given adapter, asking for the optional features
    /// snowpack can use (timestamps) only where the adapter has them.
    pub fn from_adapter(instance: wgpu::Instance, adapter: wgpu::Adapter) -> Result<Self, SnowError> {
        let summary = AdapterSummary::from_info(&adapter.get_info());
        let optional = wgpu::Features::TIMESTAMP_QUERY;
        let required_features = adapter.features() & optional;
        // Ask for what the adapter has: large windows need large storage buffers,
        // and the defaults are below what most adapters offer.
        let required_limits = adapter.limits();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("snowpack"),
            required_features,
            required_limits,
            ..Default::default()
        }))
        .map_err(|source| SnowError::RequestDevice { adapter: summary.name.clone(), source })?;

        let sink = Arc::new(ErrorSink::default());
        let errors = Arc::clone(&sink);
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            // The display of a validation error is only its kind; the description says what failed.
            let message = match &e {
                wgpu::Error::Validation { description, .. } | wgpu::Error::Internal { description, .. } => description.trim().to_owned(),
                other => other.to_string(),
            };
            tracing::error!("wgpu: {message}");
            if let Ok(mut list) = errors.errors.lock() {
                list.push(message);
            }
        }));
        let lost = Arc::clone(&sink);
        device.set_device_lost_callback(move |reason, message| {
            tracing::error!("GPU device lost ({reason:?}): {message}");
            if let Ok(mut slot) = lost.lost.lock() {
                *slot = Some(format!("{reason:?}: {message}"));
            }
        });
        tracing::info!(
            "GPU: {} ({}, {}), timestamps: {}",
            summary.name,
            summary.backend,
            summary.device_type,
            device.features().contains(wgpu::Features::TIMESTAMP_QUERY)
        );
        Ok(Self { instance, adapter, device, queue, summary, sink })
    }

    /// Whether per-pass GPU timestamps are available.
    #[must_use]
    pub fn has_timestamps(&self) -> bool {
        self.device.features().contains(wgpu::Features::TIMESTAMP_QUERY)
    }

    /// Returns the first GPU error reported since the last call (validation,
    /// out of memory) or the device-lost reason, so callers fail instead of
    /// rendering garbage or hanging.
    pub fn check(&self, context: &'static str) -> Result<(), SnowError> {
        if let Some(reason) = self.sink.lost.lock().ok().and_then(|s| s.clone()) {
            return Err(SnowError::DeviceLost(reason));
        }
        let mut errors = self.sink.errors.lock().map_err(|_| SnowError::Gpu {
            context,
            message: "error list poisoned".to_owned(),
        })?;
        if errors.is_empty() {
            return Ok(());
        }
        let message = errors.join("\n");
        errors.clear();
        Err(SnowError::Gpu { context, message })
    }

    /// Waits for all submitted work, with a timeout, then checks for errors.
    pub fn wait_idle(&self, context: &'static str) -> Result<(), SnowError> {
        self.device
            .poll(wgpu::PollType::Wait { submission_index: None, timeout: Some(WAIT_TIMEOUT) })
            .map_err(|e| SnowError::Gpu { context, message: format!("waiting for the GPU: {e}") })?;
        self.check(context)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn backend_lists_parse_and_reject_nonsense() {
        assert_eq!(parse_backends("vulkan").ok(), Some(wgpu::Backends::VULKAN));
        assert_eq!(
            parse_backends("GL, vulkan").ok(),
            Some(wgpu::Backends::GL | wgpu::Backends::VULKAN)
        );
        assert!(matches!(parse_backends("voodoo"), Err(SnowError::UnknownBackend(_))));
        assert!(matches!(parse_backends(" , "), Err(SnowError::UnknownBackend(_))));
    }
}
