//! Adapter and device selection with overrides, fallbacks and actionable errors,
//! or a device the game already has ([`GpuContext::from_device`]).
//!
//! The library reads no environment variables. A program that wants
//! overrides asks for them: [`AdapterRequest::from_env`] reads
//! `SNOWPACK_BACKEND` (a comma list of `vulkan`, `gl`, `metal`, `dx12`,
//! `webgpu`) and `SNOWPACK_ADAPTER` (a case-insensitive substring of the
//! adapter's name), as the `snowpack` binary and the tests do.
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
    /// Set when a guarded call was interrupted by wgpu's GL context-lock
    /// panic ([`GpuContext::guarded`]); the context counts as lost from then on.
    gl_locked: Mutex<Option<String>>,
}

/// Which adapter snowpack's own selection ([`GpuContext::new_headless`],
/// `GpuContext::choose`) may pick. The default asks for nothing in
/// particular: the best adapter of any backend.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct AdapterRequest {
    /// A comma list of backends (`vulkan`, `gl`, `metal`, `dx12`, `webgpu`).
    pub backends: Option<String>,
    /// A case-insensitive substring of the adapter's name.
    pub adapter_name: Option<String>,
}

impl AdapterRequest {
    /// `SNOWPACK_BACKEND` (or wgpu's `WGPU_BACKEND`) and `SNOWPACK_ADAPTER` from the environment (empty
    /// values count as unset): what the `snowpack` binary and the tests honour.
    #[must_use]
    pub fn from_env() -> Self {
        let env = |key: &str| std::env::var(key).ok().filter(|s| !s.trim().is_empty());
        Self { backends: env("SNOWPACK_BACKEND").or_else(|| env("WGPU_BACKEND")), adapter_name: env("SNOWPACK_ADAPTER") }
    }
}

/// A wgpu device and queue for snowpack, with error tracking.
///
/// Made by snowpack's own adapter selection ([`Self::new_headless`],
/// `Self::choose`) for the demo, the runner and tools, or around a device
/// the game already has ([`Self::from_device`]). Its instance and adapter
/// are the tools' (`GpuContextExt::instance`, `GpuContextExt::adapter` in
/// `low_level`).
pub struct GpuContext {
    /// The instance the adapter came from (`None` for a game's device).
    pub(crate) instance: Option<wgpu::Instance>,
    /// The chosen adapter (`None` for a game's device).
    pub(crate) adapter: Option<wgpu::Adapter>,
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// The adapter, in words.
    pub summary: AdapterSummary,
    /// What the adapter can do below full WebGPU (all of it for a game's device,
    /// which is trusted to be able to run what it asks for).
    pub(crate) downlevel: wgpu::DownlevelFlags,
    /// Whether snowpack owns the device's error and device-lost handlers;
    /// a game's device keeps its own.
    owns_handlers: bool,
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

/// The display of a validation error is only its kind; the description says what failed.
fn error_message(e: &wgpu::Error) -> String {
    match e {
        wgpu::Error::Validation { description, .. } | wgpu::Error::Internal { description, .. } => description.trim().to_owned(),
        other => other.to_string(),
    }
}

/// Sends the device's uncaptured errors and its loss to `sink`.
fn install_handlers(device: &wgpu::Device, sink: &Arc<ErrorSink>) {
    let errors = Arc::clone(sink);
    device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
        let message = error_message(&e);
        tracing::error!("wgpu: {message}");
        if let Ok(mut list) = errors.errors.lock() {
            list.push(message);
        }
    }));
    let lost = Arc::clone(sink);
    device.set_device_lost_callback(move |reason, message| {
        tracing::error!("GPU device lost ({reason:?}): {message}");
        if let Ok(mut slot) = lost.lost.lock() {
            *slot = Some(format!("{reason:?}: {message}"));
        }
    });
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

/// What wgpu's GL backend panics with when it cannot lock the adapter's
/// context (`wgpu-hal`'s `AdapterContext::lock`, after 6 s).
pub const GL_CONTEXT_LOCK_PANIC: &str = "Could not lock adapter context";

/// The text of a panic's payload, when it is text.
#[must_use]
pub fn panic_text(payload: &(dyn std::any::Any + Send)) -> Option<&str> {
    payload.downcast_ref::<&str>().copied().or_else(|| payload.downcast_ref::<String>().map(String::as_str))
}

/// Runs `work` (an adapter or device request), turning wgpu's GL
/// context-lock panic into [`SnowError::GlContextLocked`]; other panics go on.
///
/// wgpu's GL backend has no fallible path here: when another thread holds
/// the EGL (or WGL) context for more than 6 s, `AdapterContext::lock`
/// panics ("Could not lock adapter context"). A program choosing an adapter
/// should get an error it can report and exit with, not a panic, so the
/// requests run under `catch_unwind`. The instance and adapter are
/// abandoned after such a panic (they are only dropped, never used again),
/// so state left half-changed by the unwinding cannot be observed.
fn gl_lock_panics_as_errors<T>(work: impl FnOnce() -> T) -> Result<T, SnowError> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(work)).or_else(|payload| match panic_text(&*payload) {
        Some(text) if text.contains(GL_CONTEXT_LOCK_PANIC) => Err(SnowError::GlContextLocked(text.to_owned())),
        _ => std::panic::resume_unwind(payload),
    })
}

impl GpuContext {
    /// Picks an adapter as `request` asks and creates a device without a
    /// surface, for headless runs, tests and the bench.
    pub fn new_headless(request: &AdapterRequest) -> Result<Self, crate::SnowError> {
        let desc = Self::instance_descriptor(wgpu::InstanceDescriptor::new_without_display_handle(), request)?;
        let instance = wgpu::Instance::new(desc);
        Self::choose(instance, None, request).map_err(Into::into)
    }

    /// Wraps a device the game already has (shared with its renderer).
    ///
    /// snowpack installs no handlers on it: uncaptured errors and device loss
    /// stay with the game's own handlers. snowpack's calls that report GPU
    /// errors (creating a window, [`crate::SnowDeformation::step_frame`]) catch
    /// their own errors in error scopes instead. Work snowpack records into
    /// the game's encoder is validated when the game finishes that encoder.
    ///
    /// ```
    /// fn adopt(device: &wgpu::Device, queue: &wgpu::Queue) -> snowpack::GpuContext {
    ///     let ctx = snowpack::GpuContext::from_device(device.clone(), queue.clone());
    ///     println!("snow on {}", ctx.summary.name);
    ///     ctx
    /// }
    /// ```
    #[must_use]
    pub fn from_device(device: wgpu::Device, queue: wgpu::Queue) -> Self {
        let summary = AdapterSummary::from_info(&device.adapter_info());
        Self {
            instance: None,
            adapter: None,
            device,
            queue,
            summary,
            downlevel: wgpu::DownlevelFlags::all(),
            owns_handlers: false,
            sink: Arc::new(ErrorSink::default()),
        }
    }

    /// Why the context counts as lost after wgpu's GL context-lock panic
    /// interrupted a guarded call, once it has.
    fn gl_lock_reason(&self) -> Option<String> {
        self.sink.gl_locked.lock().ok().and_then(|s| s.clone())
    }

    /// Runs a front-door call's GPU work, turning wgpu's GL context-lock
    /// panic into [`SnowError::DeviceLost`].
    ///
    /// wgpu's GL backend panics ("Could not lock adapter context") when a
    /// call waits more than 6 s for the context another thread holds; on a
    /// software rasteriser a submission runs in the submitting thread,
    /// context held, so one long frame of another thread is enough. The
    /// interrupted call leaves wgpu's state unknown, so the context counts
    /// as lost from then on: [`Self::check`] reports it, and every later
    /// guarded call fails at once with the same reason instead of waiting
    /// 6 s again. Other panics go on. (The panic's message is still printed
    /// by the panic hook, which is the program's, not the library's.)
    pub(crate) fn guarded<T, E: From<SnowError>>(&self, work: impl FnOnce() -> Result<T, E>) -> Result<T, E> {
        if let Some(reason) = self.gl_lock_reason() {
            return Err(SnowError::DeviceLost(reason).into());
        }
        // Unwind safety: after the lock panic nothing the work touched is
        // used again by snowpack's guarded calls, which fail at once above.
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(work)).unwrap_or_else(|payload| match panic_text(&*payload) {
            Some(text) if text.contains(GL_CONTEXT_LOCK_PANIC) => {
                let reason = format!(
                    "the OpenGL context could not be locked in the middle of a call ({text}): another thread held it for over 6 s; \
                     the call was cut short, so make a new context (or choose another backend, --backend vulkan)"
                );
                if let Ok(mut slot) = self.sink.gl_locked.lock() {
                    slot.get_or_insert(reason.clone());
                }
                Err(SnowError::DeviceLost(reason).into())
            }
            _ => std::panic::resume_unwind(payload),
        })
    }
}

/// What snowpack's own app, tools and tests do with a [`GpuContext`] beyond the front door: adapter choice, error capture and checks, waits.
/// A named item of `low_level` (an extension trait): [`GpuContext`] has one
/// shape with or without the feature.
#[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the app, the tools and the tests (`low_level`)"))]
pub trait GpuContextExt: Sized {
    /// `desc` with its backends narrowed to `request`'s (for a windowed
    /// instance, start from `wgpu::InstanceDescriptor::new_with_display_handle`).
    fn instance_descriptor(desc: wgpu::InstanceDescriptor, request: &AdapterRequest) -> Result<wgpu::InstanceDescriptor, SnowError>;

    /// Picks the best adapter of `instance` that can present to `surface`
    /// (when given) and matches `request`, and creates the device.
    fn choose(instance: wgpu::Instance, surface: Option<&wgpu::Surface<'_>>, request: &AdapterRequest) -> Result<Self, SnowError>;

    /// Creates the device on a given adapter, asking for the optional features
    /// snowpack can use (timestamps) only where the adapter has them.
    fn from_adapter(instance: wgpu::Instance, adapter: wgpu::Adapter) -> Result<Self, SnowError>;

    /// Wraps a device the program created for snowpack's use alone (the
    /// browser demo's, made by its window toolkit) and installs snowpack's
    /// uncaptured-error and device-lost handlers on it, as
    /// [`Self::from_adapter`] does: [`Self::check`] then reports every error
    /// and a lost device without error scopes.
    #[must_use]
    fn adopt_device(device: wgpu::Device, queue: wgpu::Queue) -> Self;

    /// Whether per-pass GPU timestamps are available.
    #[must_use]
    fn has_timestamps(&self) -> bool;

    /// The instance the adapter came from (`None` for a game's device).
    #[must_use]
    fn instance(&self) -> Option<&wgpu::Instance>;

    /// The chosen adapter (`None` for a game's device).
    #[must_use]
    fn adapter(&self) -> Option<&wgpu::Adapter>;

    /// Runs `work`, catching the GPU errors it causes (validation, out of
    /// memory) for [`Self::check`] to report. With snowpack's own device the
    /// uncaptured-error handler catches them already; with a game's device
    /// ([`GpuContext::from_device`]) this error scope is how snowpack sees its own
    /// errors without taking the game's.
    fn capturing<T>(&self, work: impl FnOnce() -> T) -> T;

    /// Why the device was lost, once it was (its device-lost callback ran);
    /// unlike [`Self::check`] this leaves any reported errors in place.
    #[must_use]
    fn lost_reason(&self) -> Option<String>;

    /// Returns the first GPU error reported since the last call (validation,
    /// out of memory) or the device-lost reason, so callers fail instead of
    /// rendering garbage or hanging.
    fn check(&self, context: &'static str) -> Result<(), crate::SnowError>;

    /// Waits for all submitted work, with a timeout, then checks for errors.
    fn wait_idle(&self, context: &'static str) -> Result<(), SnowError>;
}

impl GpuContextExt for GpuContext {
    fn instance(&self) -> Option<&wgpu::Instance> {
        self.instance.as_ref()
    }

    fn adapter(&self) -> Option<&wgpu::Adapter> {
        self.adapter.as_ref()
    }

    fn instance_descriptor(mut desc: wgpu::InstanceDescriptor, request: &AdapterRequest) -> Result<wgpu::InstanceDescriptor, SnowError> {
        if request.backends.is_some() {
            desc.backends = request.parse_backends()?;
        }
        Ok(desc)
    }

    fn choose(instance: wgpu::Instance, surface: Option<&wgpu::Surface<'_>>, request: &AdapterRequest) -> Result<Self, SnowError> {
        let backends = request.parse_backends()?;
        let mut adapters = gl_lock_panics_as_errors(|| pollster::block_on(instance.enumerate_adapters(backends)))?;
        if let Some(surface) = surface {
            adapters.retain(|a| a.is_surface_supported(surface));
        }
        let mut filter = String::new();
        if let Some(list) = &request.backends {
            filter.push_str(&format!(" with SNOWPACK_BACKEND={list}"));
        }
        if surface.is_some() {
            filter.push_str(" that can present to the window");
        }
        if let Some(name) = &request.adapter_name {
            let needle = name.to_ascii_lowercase();
            adapters.retain(|a| a.get_info().name.to_ascii_lowercase().contains(&needle));
            filter.push_str(&format!(" with SNOWPACK_ADAPTER={name}"));
        }
        adapters.sort_by_key(|a| {
            let info = a.get_info();
            (type_rank(info.device_type), u32::from(info.backend != wgpu::Backend::Vulkan))
        });
        let adapter = adapters.into_iter().next().ok_or_else(|| SnowError::NoAdapter { filter, hint: NO_ADAPTER_HINT.to_owned() })?;
        Self::from_adapter(instance, adapter)
    }

    fn from_adapter(instance: wgpu::Instance, adapter: wgpu::Adapter) -> Result<Self, SnowError> {
        let summary = AdapterSummary::from_info(&adapter.get_info());
        let optional = wgpu::Features::TIMESTAMP_QUERY;
        let required_features = adapter.features() & optional;
        // Ask for what the adapter has: large windows need large storage buffers,
        // and the defaults are below what most adapters offer.
        let required_limits = adapter.limits();
        let (device, queue) = gl_lock_panics_as_errors(|| {
            pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
                label: Some("snowpack"),
                required_features,
                required_limits,
                ..Default::default()
            }))
        })?
        .map_err(|source| SnowError::RequestDevice { adapter: summary.name.clone(), source })?;

        let sink = Arc::new(ErrorSink::default());
        install_handlers(&device, &sink);
        tracing::info!(
            "GPU: {} ({}, {}), timestamps: {}",
            summary.name,
            summary.backend,
            summary.device_type,
            device.features().contains(wgpu::Features::TIMESTAMP_QUERY)
        );
        let downlevel = adapter.get_downlevel_capabilities().flags;
        Ok(Self { instance: Some(instance), adapter: Some(adapter), device, queue, summary, downlevel, owns_handlers: true, sink })
    }

    fn adopt_device(device: wgpu::Device, queue: wgpu::Queue) -> Self {
        let mut ctx = Self::from_device(device, queue);
        install_handlers(&ctx.device, &ctx.sink);
        ctx.owns_handlers = true;
        ctx
    }

    fn has_timestamps(&self) -> bool {
        self.device.features().contains(wgpu::Features::TIMESTAMP_QUERY)
    }

    fn capturing<T>(&self, work: impl FnOnce() -> T) -> T {
        // In a browser an error scope answers only after the page's event
        // loop turns, so a blocking pop would hang: there the game's own
        // handlers see snowpack's errors (or use [`Self::adopt_device`]).
        if self.owns_handlers || cfg!(target_arch = "wasm32") {
            return work();
        }
        let memory = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let out = work();
        // Native wgpu reports errors as the calls happen, so the futures are ready.
        for error in [pollster::block_on(validation.pop()), pollster::block_on(memory.pop())].into_iter().flatten() {
            if let Ok(mut list) = self.sink.errors.lock() {
                list.push(error_message(&error));
            }
        }
        out
    }

    fn lost_reason(&self) -> Option<String> {
        self.sink.lost.lock().ok().and_then(|s| s.clone()).or_else(|| self.gl_lock_reason())
    }

    fn check(&self, context: &'static str) -> Result<(), crate::SnowError> {
        if let Some(reason) = self.lost_reason() {
            return Err(SnowError::DeviceLost(reason).into());
        }
        let mut errors = self.sink.errors.lock().map_err(|_| SnowError::Gpu { context, message: "error list poisoned".to_owned() })?;
        if errors.is_empty() {
            return Ok(());
        }
        let message = errors.join("\n");
        errors.clear();
        Err(SnowError::Gpu { context, message }.into())
    }

    fn wait_idle(&self, context: &'static str) -> Result<(), SnowError> {
        self.guarded(|| {
            self.device
                .poll(wgpu::PollType::Wait { submission_index: None, timeout: Some(WAIT_TIMEOUT) })
                .map_err(|e| SnowError::Gpu { context, message: format!("waiting for the GPU: {e}") })?;
            self.check(context).map_err(Into::into)
        })
    }
}

/// What snowpack's own app, tools and tests do with an [`AdapterRequest`] beyond the front door.
/// A named item of `low_level` (an extension trait): [`AdapterRequest`] has one
/// shape with or without the feature.
#[cfg_attr(not(feature = "low_level"), allow(dead_code, reason = "for the app, the tools and the tests (`low_level`)"))]
pub trait AdapterRequestExt: Sized {
    /// This request with `backends` replaced when given (a command-line
    /// `--backend` over the environment).
    #[must_use]
    fn with_backends(self, backends: Option<&str>) -> Self;

    /// The backends asked for, or every backend.
    fn parse_backends(&self) -> Result<wgpu::Backends, SnowError>;
}

impl AdapterRequestExt for AdapterRequest {
    fn with_backends(mut self, backends: Option<&str>) -> Self {
        if let Some(list) = backends {
            self.backends = Some(list.to_owned());
        }
        self
    }

    fn parse_backends(&self) -> Result<wgpu::Backends, SnowError> {
        self.backends.as_deref().map_or(Ok(wgpu::Backends::all()), parse_backends)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn backend_lists_parse_and_reject_nonsense() {
        assert_eq!(parse_backends("vulkan").ok(), Some(wgpu::Backends::VULKAN));
        assert_eq!(parse_backends("GL, vulkan").ok(), Some(wgpu::Backends::GL | wgpu::Backends::VULKAN));
        assert!(matches!(parse_backends("voodoo"), Err(SnowError::UnknownBackend(_))));
        assert!(matches!(parse_backends(" , "), Err(SnowError::UnknownBackend(_))));
    }

    /// wgpu's exact panic (a `String` from `expect`) becomes an error; any other panic goes on.
    #[test]
    fn the_gl_context_lock_panic_becomes_an_error() {
        let locked =
            gl_lock_panics_as_errors(|| -> u32 { std::panic::panic_any(format!("{GL_CONTEXT_LOCK_PANIC}. This is most-likely a deadlock.: Timeout")) });
        match locked {
            Err(e @ SnowError::GlContextLocked(_)) => assert!(e.to_string().contains("--backend"), "{e}"),
            other => panic!("the lock panic gave {other:?}"),
        }
        assert_eq!(gl_lock_panics_as_errors(|| 7).ok(), Some(7));
        let other = std::panic::catch_unwind(|| gl_lock_panics_as_errors(|| -> u32 { panic!("something else") }));
        assert!(other.is_err(), "another panic is not swallowed");
    }
}
