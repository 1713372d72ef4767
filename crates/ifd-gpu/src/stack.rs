//! Uploading a prefiltered scale stack.

use bytemuck::{Pod, Zeroable};
use ifd_planar::{Border, ScaleStack};

use crate::context::GpuContext;
use crate::error::{GpuError, fmt_bytes};

/// One level's geometry as the shader reads it (`struct Level`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct LevelMeta {
    origin: f32,
    inv_step: f32,
    step: f32,
    nx: u32,
    ny: u32,
    offset: u32,
    plane: u32,
    pad: u32,
}

/// Up to four channels of every level, in one storage buffer.
#[derive(Debug)]
pub(crate) struct Chunk {
    /// First channel.
    pub(crate) c0: u32,
    /// Channels (1..=4).
    pub(crate) nc: u32,
    pub(crate) levels: wgpu::Buffer,
    pub(crate) data: wgpu::Buffer,
    /// The host's copy of `levels` (offsets for row updates).
    metas: Vec<LevelMeta>,
}

/// A [`ScaleStack`] on the GPU: the same samples, the same level geometry and
/// border mode.
///
/// The samples are stored in storage buffers, one per group of at most four
/// channels, level after level and planar per channel within a level. A
/// stack whose channels do not all fit in one buffer (the device's
/// `max_storage_buffer_binding_size`) is split into more groups, down to one
/// channel per buffer; one channel that does not fit is refused with
/// [`GpuError::Limit`].
#[derive(Debug)]
pub struct GpuStack {
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) channels: u32,
    pub(crate) border: Border,
    pub(crate) interpolation: ifd_planar::Interpolation,
    pub(crate) n_levels: u32,
    pub(crate) sigma_range: (f64, f64),
    pub(crate) ln_params: (f64, f64),
    /// Locates sigmas among the levels (log-uniform or at given sigmas).
    pub(crate) locator: ifd_planar::LevelLocator,
    pub(crate) chunks: Vec<Chunk>,
    bytes: u64,
}

impl GpuStack {
    /// Uploads `stack`: log-uniform levels ([`ScaleStack::new`]), which any
    /// pose reads, or levels at given sigmas ([`ScaleStack::with_sigmas`],
    /// what a constant scale reads with one lookup per term), which only
    /// poses of a constant scale read.
    ///
    /// # Errors
    /// [`GpuError::Limit`] when one channel of the stack exceeds the device's
    /// `max_storage_buffer_binding_size` or `max_buffer_size` or the image is
    /// too large to index, [`GpuError::Device`] if wgpu fails to allocate.
    pub fn upload(ctx: &GpuContext, stack: &ScaleStack) -> Result<Self, GpuError> {
        if stack.computed_share() < 1.0 {
            // Built for one scale map's reads on the CPU: the rest are zeros.
            return Err(ifd_planar::FilterError::InvalidParameter(
                "the stack holds only the samples the CPU filters it was built for read \
                 (build_stack_for): upload one built with build_stack"
                    .into(),
            )
            .into());
        }
        let channels = stack.channels();
        let layouts: Vec<_> = stack.level_layouts().copied().collect();
        let plane_bytes = plane_bytes(&layouts);
        let too_big = |what: &str, v: usize| GpuError::Limit {
            what: what.to_string(),
            needed: v.to_string(),
            limit_name: "u32 indexing in the shader",
            limit: u32::MAX.to_string(),
        };
        let (w, h) = (stack.width(), stack.height());
        let width = u32::try_from(w).map_err(|_| too_big("image width", w))?;
        let height = u32::try_from(h).map_err(|_| too_big("image height", h))?;
        u32::try_from(w * h).map_err(|_| too_big("image pixels", w * h))?;
        let limits = ctx.device().limits();
        let cap = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        // Channels per buffer.
        let per = (cap / plane_bytes.max(1)).min(4) as usize;
        if per == 0 {
            check_channel_fits(ctx, (w, h), &layouts)?;
        }
        let per = per.max(1);
        let mut chunks = Vec::new();
        let mut c0 = 0;
        while c0 < channels {
            let nc = per.min(channels - c0);
            chunks.push(ctx.scoped("uploading the scale stack", || {
                upload_chunk(ctx, stack, &layouts, c0, nc)
            })?);
            c0 += nc;
        }
        Ok(Self {
            width,
            height,
            channels: channels as u32,
            border: stack.border(),
            interpolation: stack.interpolation(),
            n_levels: layouts.len() as u32,
            sigma_range: stack.sigma_range(),
            ln_params: stack.ln_sigma_params(),
            locator: stack.locator(),
            chunks,
            bytes: plane_bytes * channels as u64,
        })
    }

    /// Checks, before anything is built, that a stack of this layout (of a
    /// `width x height` image) can be uploaded to `ctx`'s device (one channel fits in a storage
    /// binding), so that callers can refuse early instead of after
    /// prefiltering.
    ///
    /// # Errors
    /// The [`GpuError::Limit`] that [`GpuStack::upload`] would return.
    pub fn check_fits(
        ctx: &GpuContext,
        (width, height): (usize, usize),
        layout: &ifd_planar::StackLayout,
    ) -> Result<(), GpuError> {
        check_channel_fits(ctx, (width, height), layout.levels())
    }

    /// Image width.
    #[must_use]
    pub fn width(&self) -> usize {
        self.width as usize
    }

    /// Image height.
    #[must_use]
    pub fn height(&self) -> usize {
        self.height as usize
    }

    /// Channels.
    #[must_use]
    pub fn channels(&self) -> usize {
        self.channels as usize
    }

    /// Bytes of samples on the device.
    #[must_use]
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// Storage buffers the samples are split into (one per group of at most
    /// four channels).
    #[must_use]
    pub fn buffers(&self) -> usize {
        self.chunks.len()
    }

    /// Copies rows of `stack` (the CPU stack this one was uploaded from,
    /// after [`ScaleStack::refresh_region`]) to the device: rows `j0..=j1` of
    /// level `l` for every `rows[l] = Some((j0, j1))`, as
    /// [`ScaleStack::refreshed_rows`] reports them, all channels. The brush
    /// keeps its uploaded stack in step with the edited image this way
    /// instead of uploading it again. Returns the bytes written.
    ///
    /// ```no_run
    /// use ifd_gpu::{GpuContext, GpuStack};
    /// use ifd_planar::{Border, PixelRect, ScaleStack, StackOptions};
    /// let ctx = GpuContext::new()?;
    /// let mut img = ifd_image::read("testdata/camera.png")?;
    /// let mut stack = ScaleStack::new(&img, 1.0, 16.0, Border::Reflect101, StackOptions::default())?;
    /// let gpu = GpuStack::upload(&ctx, &stack)?;
    /// img.set(10, 20, 0, 1.0);
    /// let rect = PixelRect { x0: 10, y0: 20, width: 1, height: 1 };
    /// let rows = stack.refreshed_rows(rect);
    /// stack.refresh_region(&img, rect)?;
    /// gpu.update_rows(&ctx, &stack, &rows)?;
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`ifd_planar::FilterError::InvalidParameter`] when `stack` has another
    /// shape or level layout than the uploaded one or a row range leaves its
    /// level, [`GpuError::Device`] for a wgpu error.
    pub fn update_rows(
        &self,
        ctx: &GpuContext,
        stack: &ScaleStack,
        rows: &[Option<(usize, usize)>],
    ) -> Result<u64, GpuError> {
        let bad = |m: String| GpuError::from(ifd_planar::FilterError::InvalidParameter(m));
        let (w, h, c) = (stack.width(), stack.height(), stack.channels());
        if (w, h, c) != (self.width(), self.height(), self.channels()) {
            return Err(bad(format!(
                "the stack is {w}x{h}x{c}, the uploaded one {}x{}x{}",
                self.width(),
                self.height(),
                self.channels()
            )));
        }
        let layouts: Vec<_> = stack.level_layouts().copied().collect();
        let same = self.chunks.iter().all(|ch| {
            ch.metas.len() == layouts.len()
                && ch.metas.iter().zip(&layouts).all(|(m, l)| {
                    (m.nx as usize, m.ny as usize) == (l.nx, l.ny)
                        && m.step == l.step as f32
                        && m.origin == l.origin as f32
                })
        });
        if !same || rows.len() != layouts.len() {
            return Err(bad(format!(
                "the stack has {} levels ({} row ranges given) laid out otherwise than the \
                 uploaded one; upload it again",
                layouts.len(),
                rows.len()
            )));
        }
        for (l, r) in layouts.iter().zip(rows) {
            if let Some((j0, j1)) = *r
                && (j0 > j1 || j1 >= l.ny)
            {
                return Err(bad(format!(
                    "rows {j0}..={j1} of a level with {} rows",
                    l.ny
                )));
            }
        }
        let mut written = 0u64;
        ctx.scoped("updating the scale stack", || {
            let mut part = Vec::new();
            for chunk in &self.chunks {
                for (li, (meta, r)) in chunk.metas.iter().zip(rows).enumerate() {
                    let (Some((j0, j1)), Some(src)) = (*r, stack.level_data(li)) else {
                        continue;
                    };
                    let nx = meta.nx as usize;
                    let src = &src[j0 * nx * c..(j1 + 1) * nx * c];
                    for k in 0..chunk.nc as usize {
                        part.clear();
                        part.extend(src.chunks_exact(c).map(|px| px[chunk.c0 as usize + k]));
                        let at = u64::from(meta.offset)
                            + k as u64 * u64::from(meta.plane)
                            + (j0 * nx) as u64;
                        ctx.queue()
                            .write_buffer(&chunk.data, at * 4, bytemuck::cast_slice(&part));
                        written += part.len() as u64 * 4;
                    }
                }
            }
            Ok(())
        })?;
        Ok(written)
    }

    /// Whether `sigma` lies in the covered range ([`ScaleStack::covers`]).
    #[must_use]
    pub fn covers(&self, sigma: f64) -> bool {
        let (lo, hi) = self.sigma_range;
        sigma >= lo * (1.0 - 1e-6) && sigma <= hi * (1.0 + 1e-6)
    }
}

/// Bytes of one channel of a stack with these levels.
fn plane_bytes(levels: &[ifd_planar::LevelLayout]) -> u64 {
    levels.iter().map(|l| (l.nx * l.ny * 4) as u64).sum()
}

/// [`GpuError::Limit`] when one channel of a stack with these levels does
/// not fit in a storage binding.
fn check_channel_fits(
    ctx: &GpuContext,
    (width, height): (usize, usize),
    levels: &[ifd_planar::LevelLayout],
) -> Result<(), GpuError> {
    let (sig_lo, sig_hi) = (
        levels.first().map_or(0.0, |l| l.sigma),
        levels.last().map_or(0.0, |l| l.sigma),
    );
    ctx.check_buffer(
        &format!(
            "one channel of the {width}x{height} scale stack ({} levels, sigma \
             {sig_lo:.3}..{sig_hi:.3} px)",
            levels.len(),
        ),
        plane_bytes(levels),
        true,
    )
}

fn upload_chunk(
    ctx: &GpuContext,
    stack: &ScaleStack,
    layouts: &[ifd_planar::LevelLayout],
    c0: usize,
    nc: usize,
) -> Result<Chunk, GpuError> {
    let channels = stack.channels();
    let mut metas = Vec::with_capacity(layouts.len());
    let mut offset = 0u64;
    for l in layouts {
        let plane = (l.nx * l.ny) as u64;
        metas.push(LevelMeta {
            origin: l.origin as f32,
            inv_step: 1.0 / l.step as f32,
            step: l.step as f32,
            nx: l.nx as u32,
            ny: l.ny as u32,
            offset: offset as u32,
            plane: plane as u32,
            pad: 0,
        });
        offset += plane * nc as u64;
    }
    let bytes = offset * 4;
    ctx.check_buffer(
        &format!("scale stack channels {c0}..{}", c0 + nc),
        bytes,
        true,
    )?;
    let device = ctx.device();
    let levels = crate::wgpu_helpers::buffer_init(
        device,
        "ifd stack levels",
        bytemuck::cast_slice(&metas),
        wgpu::BufferUsages::STORAGE,
    );
    let data = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("ifd stack samples"),
        size: bytes,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: true,
    });
    {
        let mut view = data
            .get_mapped_range_mut(..)
            .map_err(|e| GpuError::Device {
                context: format!("mapping the stack buffer ({})", fmt_bytes(bytes)),
                message: e.to_string(),
            })?;
        // Mapped memory is write-only: fill one level at a time on the host.
        let mut at = 0usize;
        let mut level = Vec::new();
        for (li, l) in layouts.iter().enumerate() {
            let src = stack.level_data(li).unwrap_or(&[]);
            let plane = l.nx * l.ny;
            level.clear();
            level.resize(plane * nc, 0.0f32);
            for k in 0..nc {
                let out = &mut level[k * plane..(k + 1) * plane];
                for (o, px) in out.iter_mut().zip(src.chunks_exact(channels)) {
                    *o = px[c0 + k];
                }
            }
            let bytes: &[u8] = bytemuck::cast_slice(&level);
            view.slice(at..at + bytes.len()).copy_from_slice(bytes);
            at += bytes.len();
        }
    }
    data.unmap();
    Ok(Chunk {
        c0: c0 as u32,
        nc: nc as u32,
        levels,
        data,
        metas,
    })
}

#[cfg(test)]
mod layout_tests {
    use super::LevelMeta;
    use crate::layout::mirror;

    #[test]
    fn the_level_mirror_matches_ifd_eval_wgsl() {
        mirror!(crate::shaders::ifd_eval_source(), "Level", LevelMeta, [
            "origin" => origin, "inv_step" => inv_step, "step" => step, "nx" => nx,
            "ny" => ny, "offset" => offset, "plane" => plane, "_pad" => pad,
        ]);
    }
}
