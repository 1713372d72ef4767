//! Device creation (headless) and the compiled pipelines.

use std::fmt::Write as _;
use std::sync::Arc;

use crate::error::{GpuError, fmt_bytes};
use crate::pipelines::{compute_pipeline, rgba8_target_entry, storage_entry, uniform_entry};
use crate::shaders;

/// Which adapter [`GpuContext::new_with`] may pick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum AdapterChoice {
    /// Any adapter: a hardware one when there is one, else a software one
    /// (lavapipe). What a command asked to run on the GPU gets.
    #[default]
    Any,
    /// Only a hardware (discrete, integrated or virtual) adapter.
    Hardware,
    /// Only a software (CPU) adapter such as Mesa's lavapipe.
    Software,
}

/// Where an application runs its image work: the one meaning of `--device
/// auto|gpu|cpu` in the apps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DeviceChoice {
    /// A hardware GPU when there is one, else the CPU: a software adapter
    /// (lavapipe) runs these kernels slower than the CPU paths on the same
    /// cores, so it is not used.
    #[default]
    Auto,
    /// The GPU on any adapter, software included.
    Gpu,
    /// The CPU paths.
    Cpu,
}

impl DeviceChoice {
    /// Whether work runs on an adapter that is `software` (or not).
    ///
    /// ```
    /// use ifd_gpu::DeviceChoice;
    /// assert!(DeviceChoice::Auto.uses_adapter(false) && !DeviceChoice::Auto.uses_adapter(true));
    /// assert!(DeviceChoice::Gpu.uses_adapter(true) && !DeviceChoice::Cpu.uses_adapter(false));
    /// ```
    #[must_use]
    pub fn uses_adapter(self, software: bool) -> bool {
        match self {
            Self::Auto => !software,
            Self::Gpu => true,
            Self::Cpu => false,
        }
    }
}

/// A device, its queue and the compiled IFD pipelines.
///
/// Create one with [`GpuContext::new`] (headless, picks the adapter) or wrap
/// a device you already have with [`GpuContext::from_device`] (a renderer's,
/// or a test's). Everything else in this crate takes a `&GpuContext`.
#[derive(Debug)]
pub struct GpuContext {
    device: wgpu::Device,
    queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
    pub(crate) eval_layout: wgpu::BindGroupLayout,
    pub(crate) eval_pipeline: wgpu::ComputePipeline,
    pub(crate) rgba8_layout: wgpu::BindGroupLayout,
    pub(crate) rgba8_pipeline: wgpu::ComputePipeline,
    pub(crate) blend_layout: wgpu::BindGroupLayout,
    pub(crate) blend_pipeline: wgpu::ComputePipeline,
}

/// The rank of an adapter type (lower is preferred).
fn rank(t: wgpu::DeviceType) -> u8 {
    match t {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    }
}

fn allowed(choice: AdapterChoice, t: wgpu::DeviceType) -> bool {
    match choice {
        AdapterChoice::Any => true,
        AdapterChoice::Hardware => t != wgpu::DeviceType::Cpu,
        AdapterChoice::Software => t == wgpu::DeviceType::Cpu,
    }
}

/// A headless instance (backends from `WGPU_BACKEND` when set, else all
/// compiled in: Vulkan).
fn instance() -> wgpu::Instance {
    wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env())
}

/// Every adapter the instance sees, best first.
#[must_use]
pub fn list_adapters() -> Vec<wgpu::AdapterInfo> {
    let mut infos: Vec<wgpu::AdapterInfo> =
        pollster::block_on(instance().enumerate_adapters(wgpu::Backends::all()))
            .iter()
            .map(wgpu::Adapter::get_info)
            .collect();
    infos.sort_by_key(|i| rank(i.device_type));
    infos
}

/// Picks an adapter: the best enumerated one that `choice` allows, else
/// what `request_adapter` returns without and then with
/// `force_fallback_adapter`.
async fn pick_adapter(
    instance: &wgpu::Instance,
    choice: AdapterChoice,
) -> Result<wgpu::Adapter, GpuError> {
    let mut adapters = instance.enumerate_adapters(wgpu::Backends::all()).await;
    adapters.retain(|a| allowed(choice, a.get_info().device_type));
    adapters.sort_by_key(|a| rank(a.get_info().device_type));
    if let Some(a) = adapters.into_iter().next() {
        return Ok(a);
    }
    let mut tried = Vec::new();
    for fallback in [false, true] {
        let options = wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: fallback,
            compatible_surface: None,
            apply_limit_buckets: false,
        };
        match instance.request_adapter(&options).await {
            Ok(a) if allowed(choice, a.get_info().device_type) => return Ok(a),
            Ok(a) => tried.push(format!(
                "{} ({:?}) is not a {choice:?} adapter",
                a.get_info().name,
                a.get_info().device_type
            )),
            Err(e) => tried.push(format!(
                "request_adapter(force_fallback_adapter: {fallback}): {e}"
            )),
        }
    }
    Err(GpuError::NoAdapter(tried.join("; ")))
}

impl GpuContext {
    /// A headless device on the best adapter: hardware when there is one,
    /// otherwise a software Vulkan driver (Mesa's lavapipe). Requests the
    /// adapter's own limits (the largest buffers it allows) and timestamp
    /// queries when the adapter has them.
    ///
    /// ```no_run
    /// let ctx = ifd_gpu::GpuContext::new()?;
    /// println!("{}", ctx.describe());
    /// # Ok::<(), ifd_gpu::GpuError>(())
    /// ```
    ///
    /// # Errors
    /// [`GpuError::NoAdapter`] when there is no adapter at all (callers that
    /// allow it then use the CPU path), [`GpuError::RequestDevice`] when the
    /// adapter refuses a device.
    pub fn new() -> Result<Self, GpuError> {
        Self::new_with(AdapterChoice::Any)
    }

    /// As [`GpuContext::new`], restricted to the adapters `choice` allows.
    ///
    /// # Errors
    /// As [`GpuContext::new`].
    pub fn new_with(choice: AdapterChoice) -> Result<Self, GpuError> {
        pollster::block_on(async {
            let instance = instance();
            let adapter = pick_adapter(&instance, choice).await?;
            let info = adapter.get_info();
            let mut features = wgpu::Features::empty();
            if adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY) {
                features |= wgpu::Features::TIMESTAMP_QUERY;
            }
            let desc = wgpu::DeviceDescriptor {
                label: Some("ifd-gpu"),
                required_features: features,
                required_limits: adapter.limits(),
                ..wgpu::DeviceDescriptor::default()
            };
            let (device, queue) =
                adapter
                    .request_device(&desc)
                    .await
                    .map_err(|e| GpuError::RequestDevice {
                        adapter: info.name.clone(),
                        reason: e.to_string(),
                    })?;
            // Our own device: an error that escapes the error scopes (a bug)
            // is reported on stderr instead of wgpu's default panic.
            device.on_uncaptured_error(Arc::new(|e| {
                eprintln!("ifd-gpu: uncaptured wgpu error: {e}");
            }));
            Self::from_device(device, queue, info)
        })
    }

    /// Wraps an existing device (a renderer's, or one a test made): compiles
    /// the pipelines on it. Timestamps are used when the device was created
    /// with [`wgpu::Features::TIMESTAMP_QUERY`]; limits are the device's.
    ///
    /// # Errors
    /// [`GpuError::Device`] when the shaders or pipelines fail to build on
    /// this device.
    pub fn from_device(
        device: wgpu::Device,
        queue: wgpu::Queue,
        info: wgpu::AdapterInfo,
    ) -> Result<Self, GpuError> {
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let (storage, uniform) = (storage_entry, uniform_entry(0));
        let eval_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("ifd_eval"),
            entries: &[
                uniform,
                storage(1, true),
                storage(2, true),
                storage(3, true),
                storage(4, true),
                storage(5, true),
                storage(6, false),
                storage(7, true),
            ],
        });
        let rgba8_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("to_rgba8"),
            entries: &[uniform, storage(1, true), rgba8_target_entry(2)],
        });
        let blend_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("dab_blend"),
            entries: &[uniform, storage(1, true), storage(2, false)],
        });
        let pipeline = |name: &str, source: &str, layout: &wgpu::BindGroupLayout| {
            compute_pipeline(&device, name, source, layout)
        };
        let eval_source = shaders::ifd_eval_source();
        let eval_pipeline = pipeline("ifd_eval", &eval_source, &eval_layout);
        let rgba8_pipeline = pipeline("to_rgba8", shaders::TO_RGBA8, &rgba8_layout);
        let blend_pipeline = pipeline("dab_blend", shaders::DAB_BLEND, &blend_layout);
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(GpuError::Device {
                context: "building the compute pipelines".into(),
                message: e.to_string(),
            });
        }
        Ok(Self {
            device,
            queue,
            info,
            eval_layout,
            eval_pipeline,
            rgba8_layout,
            rgba8_pipeline,
            blend_layout,
            blend_pipeline,
        })
    }

    /// The device.
    #[must_use]
    pub fn device(&self) -> &wgpu::Device {
        &self.device
    }

    /// The queue.
    #[must_use]
    pub fn queue(&self) -> &wgpu::Queue {
        &self.queue
    }

    /// The adapter in use.
    #[must_use]
    pub fn adapter_info(&self) -> &wgpu::AdapterInfo {
        &self.info
    }

    /// Whether the adapter is a software (CPU) one such as lavapipe.
    #[must_use]
    pub fn is_software(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// Whether GPU time is measured (timestamp queries).
    #[must_use]
    pub fn has_timestamps(&self) -> bool {
        self.device
            .features()
            .contains(wgpu::Features::TIMESTAMP_QUERY)
    }

    /// A multi-line description: adapter, backend, driver, the limits that
    /// bound what can be evaluated, timestamp support.
    #[must_use]
    pub fn describe(&self) -> String {
        let i = &self.info;
        let l = self.device.limits();
        let mut s = String::new();
        let _ = writeln!(
            s,
            "adapter: {} ({:?}, {:?})",
            i.name, i.device_type, i.backend
        );
        let _ = writeln!(s, "driver: {} {}", i.driver, i.driver_info);
        let _ = writeln!(s, "vendor: 0x{:04x}, device: 0x{:04x}", i.vendor, i.device);
        let _ = writeln!(s, "max_buffer_size: {}", fmt_bytes(l.max_buffer_size));
        let _ = writeln!(
            s,
            "max_storage_buffer_binding_size: {}",
            fmt_bytes(l.max_storage_buffer_binding_size)
        );
        let _ = writeln!(
            s,
            "max_texture_dimension_2d: {}",
            l.max_texture_dimension_2d
        );
        let _ = writeln!(
            s,
            "max_compute_workgroups_per_dimension: {}",
            l.max_compute_workgroups_per_dimension
        );
        let _ = write!(
            s,
            "timestamp queries: {}",
            if self.has_timestamps() { "yes" } else { "no" }
        );
        s
    }

    /// Runs `f` inside validation and out-of-memory error scopes; an error
    /// wgpu reports there becomes [`GpuError::Device`] naming `context`.
    pub(crate) fn scoped<T>(
        &self,
        context: &str,
        f: impl FnOnce() -> Result<T, GpuError>,
    ) -> Result<T, GpuError> {
        let oom = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let result = f();
        let v = pollster::block_on(validation.pop());
        let o = pollster::block_on(oom.pop());
        if let Some(e) = v.or(o) {
            return Err(GpuError::Device {
                context: context.to_string(),
                message: e.to_string(),
            });
        }
        result
    }

    /// Checks a buffer size against `max_buffer_size` and, for storage
    /// buffers, `max_storage_buffer_binding_size`.
    pub(crate) fn check_buffer(
        &self,
        what: &str,
        bytes: u64,
        storage: bool,
    ) -> Result<(), GpuError> {
        let l = self.device.limits();
        if bytes > l.max_buffer_size {
            return Err(GpuError::Limit {
                what: what.to_string(),
                needed: fmt_bytes(bytes),
                limit_name: "max_buffer_size",
                limit: fmt_bytes(l.max_buffer_size),
            });
        }
        let binding = l.max_storage_buffer_binding_size;
        if storage && bytes > binding {
            return Err(GpuError::Limit {
                what: what.to_string(),
                needed: fmt_bytes(bytes),
                limit_name: "max_storage_buffer_binding_size",
                limit: fmt_bytes(binding),
            });
        }
        Ok(())
    }

    /// Checks a uniform buffer's size against `max_uniform_buffer_binding_size`.
    pub(crate) fn check_uniform(&self, what: &str, bytes: u64) -> Result<(), GpuError> {
        let limit = self.device.limits().max_uniform_buffer_binding_size;
        if bytes > limit {
            return Err(GpuError::Limit {
                what: what.to_string(),
                needed: fmt_bytes(bytes),
                limit_name: "max_uniform_buffer_binding_size",
                limit: fmt_bytes(limit),
            });
        }
        Ok(())
    }

    /// Checks a dispatch of `w x h` invocations in 8x8 workgroups.
    pub(crate) fn check_dispatch(&self, what: &str, w: u32, h: u32) -> Result<(), GpuError> {
        let max = self.device.limits().max_compute_workgroups_per_dimension;
        let groups = w.div_ceil(8).max(h.div_ceil(8));
        if groups > max {
            return Err(GpuError::Limit {
                what: what.to_string(),
                needed: format!("{groups} workgroups of 8x8 along one axis ({w}x{h} pixels)"),
                limit_name: "max_compute_workgroups_per_dimension",
                limit: max.to_string(),
            });
        }
        Ok(())
    }
}
