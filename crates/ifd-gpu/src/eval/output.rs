//! [`GpuOutput`]: an evaluation's result on the device, read back or
//! converted to a texture.

use std::time::Duration;

use ifd_image::Image;

use super::Region;
use crate::context::GpuContext;
use crate::error::GpuError;
use crate::wgpu_helpers::{Rgba8Params, read_buffer, read_gpu_time, rgba8_texture, submit_rgba8};

/// The result of an evaluation: a storage buffer of `f32`, interleaved
/// `height x width x channels`, row-major, on the device.
///
/// Read it back with [`GpuOutput::read`], or hand [`GpuOutput::buffer`] (or
/// [`GpuOutput::to_rgba8_texture`]) to a renderer on the same device.
#[derive(Debug)]
pub struct GpuOutput {
    pub(super) buffer: wgpu::Buffer,
    pub(super) region: Region,
    pub(super) channels: usize,
    pub(super) timestamps: Option<wgpu::Buffer>,
}

impl GpuOutput {
    /// The output buffer (usage `STORAGE | COPY_SRC`).
    #[must_use]
    pub fn buffer(&self) -> &wgpu::Buffer {
        &self.buffer
    }

    /// The region evaluated; output pixel `(0, 0)` is image pixel `(x0, y0)`.
    #[must_use]
    pub fn region(&self) -> Region {
        self.region
    }

    /// Channels per pixel.
    #[must_use]
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// Copies the result to the CPU as a `width x height` image of the region.
    ///
    /// # Errors
    /// [`GpuError::Readback`] when mapping fails, [`GpuError::Device`] for a
    /// wgpu error.
    pub fn read(&self, ctx: &GpuContext) -> Result<Image, GpuError> {
        let data = read_buffer(ctx, &self.buffer, "the result")?;
        let floats: Vec<f32> = bytemuck::pod_collect_to_vec(&data);
        let n = self.region.width * self.region.height * self.channels;
        Image::from_vec(
            self.region.width,
            self.region.height,
            self.channels,
            floats[..n].to_vec(),
        )
        .map_err(|e| GpuError::Readback {
            what: "the result",
            reason: e.to_string(),
        })
    }

    /// GPU time of the evaluation, from timestamp queries; `None` when the
    /// device has no timestamp queries.
    ///
    /// # Errors
    /// As [`GpuOutput::read`].
    pub fn gpu_time(&self, ctx: &GpuContext) -> Result<Option<Duration>, GpuError> {
        read_gpu_time(ctx, self.timestamps.as_ref())
    }

    /// Converts the result to a new `rgba8unorm` texture of the region's size
    /// (usages `STORAGE_BINDING | TEXTURE_BINDING | COPY_SRC`) on the GPU, for
    /// display without a round trip: 1 channel grey, 2 grey + alpha, 3 RGB,
    /// 4 RGBA, clamped to `[0, 1]`, sRGB-encoded when `srgb`.
    ///
    /// # Errors
    /// [`GpuError::Unsupported`] for more than 4 channels, [`GpuError::Limit`]
    /// for a region larger than `max_texture_dimension_2d`.
    pub fn to_rgba8_texture(
        &self,
        ctx: &GpuContext,
        srgb: bool,
    ) -> Result<wgpu::Texture, GpuError> {
        if self.channels > 4 {
            return Err(GpuError::Unsupported(format!(
                "an RGBA8 texture of a {}-channel result",
                self.channels
            )));
        }
        let (w, h) = (self.region.width as u32, self.region.height as u32);
        let max = ctx.device().limits().max_texture_dimension_2d;
        if w.max(h) > max {
            return Err(GpuError::Limit {
                what: "the display texture".into(),
                needed: format!("{w}x{h} texels"),
                limit_name: "max_texture_dimension_2d",
                limit: max.to_string(),
            });
        }
        ctx.check_dispatch("the display conversion", w, h)?;
        ctx.scoped("converting the result to a texture", || {
            let device = ctx.device();
            let texture = rgba8_texture(device, "ifd result rgba8", w, h);
            let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
            submit_rgba8(
                ctx,
                &self.buffer,
                &Rgba8Params {
                    width: w,
                    height: h,
                    channels: self.channels as u32,
                    srgb: u32::from(srgb),
                    src_stride: w,
                    ..Rgba8Params::default()
                },
                &view,
            );
            Ok(texture)
        })
    }
}
