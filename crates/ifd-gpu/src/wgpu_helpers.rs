//! Small wgpu helpers shared by the evaluation, the stack upload, the
//! smoother and the canvas: buffers and bind-group entries, the `rgba8`
//! conversion pass, one-pass submission, region checks and readback.

use bytemuck::{Pod, Zeroable};
use ifd_planar::{FilterError, PixelRect as Region};
use wgpu::util::DeviceExt as _;

use crate::context::GpuContext;
use crate::error::GpuError;

/// A buffer holding `contents` (at least 16 bytes: empty bindings are invalid).
pub(crate) fn buffer_init(
    device: &wgpu::Device,
    label: &str,
    contents: &[u8],
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    let mut padded;
    let contents = if contents.len() < 16 || !contents.len().is_multiple_of(4) {
        padded = contents.to_vec();
        padded.resize(contents.len().next_multiple_of(4).max(16), 0);
        &padded[..]
    } else {
        contents
    };
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents,
        usage,
    })
}

pub(crate) fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}

/// A `w x h` `rgba8unorm` texture that `shaders/to_rgba8.wgsl` writes and a
/// renderer samples (usages `STORAGE_BINDING | TEXTURE_BINDING | COPY_SRC`).
pub(crate) fn rgba8_texture(device: &wgpu::Device, label: &str, w: u32, h: u32) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8Unorm,
        usage: wgpu::TextureUsages::STORAGE_BINDING
            | wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    })
}

/// The `struct Params` of `shaders/to_rgba8.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub(crate) struct Rgba8Params {
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) channels: u32,
    pub(crate) srgb: u32,
    pub(crate) src_x0: u32,
    pub(crate) src_y0: u32,
    pub(crate) src_stride: u32,
    pub(crate) opaque: u32,
    pub(crate) dst_x0: u32,
    pub(crate) dst_y0: u32,
    pub(crate) pad: [u32; 2],
}

/// Submits the conversion of a rectangle of `src` into `view` (an
/// `rgba8unorm` storage texture view); see `shaders/to_rgba8.wgsl`.
pub(crate) fn submit_rgba8(
    ctx: &GpuContext,
    src: &wgpu::Buffer,
    params: &Rgba8Params,
    view: &wgpu::TextureView,
) {
    let device = ctx.device();
    let pb = buffer_init(
        device,
        "to_rgba8 params",
        bytemuck::bytes_of(params),
        wgpu::BufferUsages::UNIFORM,
    );
    let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("to_rgba8"),
        layout: &ctx.rgba8_layout,
        entries: &[
            entry(0, &pb),
            entry(1, src),
            wgpu::BindGroupEntry {
                binding: 2,
                resource: wgpu::BindingResource::TextureView(view),
            },
        ],
    });
    submit_pass(
        ctx,
        "to_rgba8",
        &ctx.rgba8_pipeline,
        &bind,
        (params.width, params.height),
    );
}

/// Submits one compute pass of `pipeline` with `bind` over `w x h`
/// invocations in 8x8 workgroups (the shaders' workgroup size).
pub(crate) fn submit_pass(
    ctx: &GpuContext,
    label: &str,
    pipeline: &wgpu::ComputePipeline,
    bind: &wgpu::BindGroup,
    (w, h): (u32, u32),
) {
    let mut enc = ctx
        .device()
        .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
    {
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(label),
            timestamp_writes: None,
        });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, bind, &[]);
        pass.dispatch_workgroups(w.div_ceil(8), h.div_ceil(8), 1);
    }
    ctx.queue().submit([enc.finish()]);
}

/// [`FilterError::InvalidParameter`] unless `r` is a non-empty rectangle
/// inside a `w x h` `what` (image, canvas).
pub(crate) fn check_region(r: Region, w: usize, h: usize, what: &str) -> Result<(), GpuError> {
    if r.width == 0 || r.height == 0 || r.x0 + r.width > w || r.y0 + r.height > h {
        return Err(FilterError::InvalidParameter(format!(
            "region {}x{} at ({}, {}) is empty or not inside the {w}x{h} {what}",
            r.width, r.height, r.x0, r.y0
        ))
        .into());
    }
    Ok(())
}

/// Copies `buffer` into a mappable one and reads it.
pub(crate) fn read_buffer(
    ctx: &GpuContext,
    buffer: &wgpu::Buffer,
    what: &'static str,
) -> Result<Vec<u8>, GpuError> {
    read_buffer_range(ctx, buffer, 0, buffer.size(), what)
}

/// Copies `size` bytes of `buffer` from `offset` (both multiples of 4) into
/// a mappable buffer and reads them.
pub(crate) fn read_buffer_range(
    ctx: &GpuContext,
    buffer: &wgpu::Buffer,
    offset: u64,
    size: u64,
    what: &'static str,
) -> Result<Vec<u8>, GpuError> {
    let device = ctx.device();
    let staging = ctx.scoped("copying the result for readback", || {
        let staging = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("ifd readback"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("ifd readback"),
        });
        enc.copy_buffer_to_buffer(buffer, offset, &staging, 0, size);
        ctx.queue().submit([enc.finish()]);
        Ok(staging)
    })?;
    let (tx, rx) = std::sync::mpsc::channel();
    staging.map_async(wgpu::MapMode::Read, .., move |r| {
        // The receiver outlives the poll below; a send error cannot happen.
        tx.send(r).ok();
    });
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| GpuError::Readback {
            what,
            reason: e.to_string(),
        })?;
    rx.recv()
        .map_err(|e| GpuError::Readback {
            what,
            reason: e.to_string(),
        })?
        .map_err(|e| GpuError::Readback {
            what,
            reason: e.to_string(),
        })?;
    let bytes = staging
        .get_mapped_range(..)
        .map_err(|e| GpuError::Readback {
            what,
            reason: e.to_string(),
        })?
        .to_vec();
    staging.unmap();
    Ok(bytes)
}

/// Reads an `rgba8unorm` texture (usage `COPY_SRC`) back: `width * height`
/// texels, row-major.
pub(crate) fn read_rgba8(
    ctx: &GpuContext,
    texture: &wgpu::Texture,
    what: &'static str,
) -> Result<Vec<[u8; 4]>, GpuError> {
    let (tw, th) = (texture.width() as usize, texture.height() as usize);
    let row = (tw as u32 * 4).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
    let device = ctx.device();
    let staging = ctx.scoped("copying a texture for readback", || {
        let staging = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("ifd texture readback"),
            size: u64::from(row) * th as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("ifd texture readback"),
        });
        enc.copy_texture_to_buffer(
            texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &staging,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(row),
                    rows_per_image: None,
                },
            },
            texture.size(),
        );
        ctx.queue().submit([enc.finish()]);
        Ok(staging)
    })?;
    let bytes = read_buffer_range(ctx, &staging, 0, staging.size(), what)?;
    let mut out = Vec::with_capacity(tw * th);
    for y in 0..th {
        let line = &bytes[y * row as usize..y * row as usize + tw * 4];
        out.extend(line.chunks_exact(4).map(|p| [p[0], p[1], p[2], p[3]]));
    }
    Ok(out)
}

/// A pair of timestamp queries bracketing a pass and the buffer they resolve
/// into, when the device has timestamp queries.
pub(crate) struct Timestamps {
    set: wgpu::QuerySet,
    pub(crate) resolve: wgpu::Buffer,
}

impl Timestamps {
    /// The pair, or `None` without timestamp queries.
    pub(crate) fn new(ctx: &GpuContext, label: &str) -> Option<Self> {
        let device = ctx.device();
        ctx.has_timestamps().then(|| Self {
            set: device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some(label),
                ty: wgpu::QueryType::Timestamp,
                count: 2,
            }),
            resolve: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: 16,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
        })
    }

    /// The pass's timestamp writes (beginning and end).
    pub(crate) fn writes(&self) -> wgpu::ComputePassTimestampWrites<'_> {
        wgpu::ComputePassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(0),
            end_of_pass_write_index: Some(1),
        }
    }

    /// Resolves the queries into the buffer (after the pass).
    pub(crate) fn resolve(&self, enc: &mut wgpu::CommandEncoder) {
        enc.resolve_query_set(&self.set, 0..2, &self.resolve, 0);
    }
}

/// The time between a resolved pair of timestamps (`None` for none).
pub(crate) fn read_gpu_time(
    ctx: &GpuContext,
    resolved: Option<&wgpu::Buffer>,
) -> Result<Option<std::time::Duration>, GpuError> {
    let Some(ts) = resolved else {
        return Ok(None);
    };
    let data = read_buffer(ctx, ts, "the timestamps")?;
    let t: Vec<u64> = bytemuck::pod_collect_to_vec(&data);
    let ticks = t[1].saturating_sub(t[0]);
    let ns = ticks as f64 * f64::from(ctx.queue().get_timestamp_period());
    Ok(Some(std::time::Duration::from_secs_f64(ns * 1e-9)))
}

#[cfg(test)]
mod layout_tests {
    use super::Rgba8Params;
    use crate::layout::mirror;

    #[test]
    fn the_mirror_matches_to_rgba8_wgsl() {
        mirror!(crate::shaders::TO_RGBA8, "Params", Rgba8Params, [
            "width" => width, "height" => height, "channels" => channels, "srgb" => srgb,
            "src_x0" => src_x0, "src_y0" => src_y0, "src_stride" => src_stride,
            "opaque" => opaque, "dst_x0" => dst_x0, "dst_y0" => dst_y0,
            "pad0" => pad, "pad1" => pad + 4,
        ]);
    }
}
