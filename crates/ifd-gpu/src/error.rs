//! Errors of GPU evaluation.

use ifd_planar::FilterError;

/// Everything that can go wrong creating a device or evaluating on it.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No adapter at all (neither hardware nor software Vulkan).
    #[error(
        "no GPU adapter found ({0}); install a Vulkan driver (for a software one, Debian's \
         mesa-vulkan-drivers provides lavapipe) or use the CPU path"
    )]
    NoAdapter(String),
    /// The adapter refused to create a device.
    #[error("creating a device on {adapter}: {reason}")]
    RequestDevice {
        /// The adapter's name.
        adapter: String,
        /// What wgpu said.
        reason: String,
    },
    /// A resource or dispatch would exceed one of the device's limits.
    #[error(
        "{what} needs {needed} but the device's {limit_name} is {limit}; use a smaller image, L, \
         region or sigma range, or the CPU path"
    )]
    Limit {
        /// What was being created.
        what: String,
        /// How much it needs (with units).
        needed: String,
        /// The `wgpu::Limits` field.
        limit_name: &'static str,
        /// The limit's value (with units).
        limit: String,
    },
    /// Invalid input (the same checks and messages as the CPU path).
    #[error(transparent)]
    Filter(#[from] FilterError),
    /// Invalid smoothing input.
    #[error(transparent)]
    Smooth(#[from] ifd_smooth::SmoothError),
    /// Invalid shading input (the CPU shading's checks and messages).
    #[error(transparent)]
    Shade(#[from] ifd_shade::ShadeError),
    /// A render job the CPU renderer refuses too (nothing visible, maps
    /// without texture coordinates).
    #[error(transparent)]
    Render(#[from] ifd_render::RenderError),
    /// Something the GPU path does not do (yet).
    #[error("not supported on the GPU: {0}")]
    Unsupported(String),
    /// wgpu reported an error while `context` (caught by an error scope).
    #[error("GPU error while {context}: {message}")]
    Device {
        /// What was being done.
        context: String,
        /// wgpu's message.
        message: String,
    },
    /// Reading a result back failed.
    #[error("reading back {what}: {reason}")]
    Readback {
        /// What was read.
        what: &'static str,
        /// Why it failed.
        reason: String,
    },
}

/// Bytes in words with the exact count, for device limits: `1.5 GiB
/// (1610612736 bytes)` (the unit formatting is [`ifd_image::fmt_bytes`]).
pub(crate) fn fmt_bytes(n: u64) -> String {
    if n < 1024 {
        ifd_image::fmt_bytes(n)
    } else {
        format!("{} ({n} bytes)", ifd_image::fmt_bytes(n))
    }
}
