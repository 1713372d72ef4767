//! An image kept on the device and painted there: brush dabs are smoothed,
//! blended and shown without a round trip to the CPU.

use bytemuck::{Pod, Zeroable};
use ifd_image::Image;
use ifd_smooth::DabRegion;
use ifd_smooth::{Dab, Mode};

use crate::context::GpuContext;
use crate::error::GpuError;
use crate::eval::Region;
use crate::smooth::GpuSmoother;
use crate::wgpu_helpers::{
    Rgba8Params, buffer_init, check_region, entry, read_buffer_range, read_rgba8, rgba8_texture,
    submit_pass, submit_rgba8,
};

/// One display texture of a [`GpuCanvas`]: `rgba8unorm`, the pixels of
/// `region` of the image.
#[derive(Debug)]
pub struct DisplayTile {
    /// The image pixels it shows; texel `(0, 0)` is pixel `(x0, y0)`.
    pub region: Region,
    /// Usages `STORAGE_BINDING | TEXTURE_BINDING | COPY_SRC`.
    pub texture: wgpu::Texture,
}

/// The `struct Params` of `shaders/dab_blend.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct BlendParams {
    x0: u32,
    y0: u32,
    w: u32,
    h: u32,
    width: u32,
    channels: u32,
    pad0: [u32; 2],
    cx: f32,
    cy: f32,
    radius: f32,
    falloff: f32,
    strength: f32,
    pad1: [f32; 3],
}

/// An image (1 to 4 channels) on the device, with display textures.
///
/// [`GpuCanvas::apply_dab`] smooths a dab's bounding box with a
/// [`GpuSmoother`] (the same lookups as [`GpuSmoother::apply_dab`]), blends
/// it into the image with the dab's weights (`shaders/dab_blend.wgsl`, the
/// arithmetic of `ifd_smooth::Smoother::apply_dab`) and converts the changed
/// pixels into the display textures (`shaders/to_rgba8.wgsl`), all in
/// submitted GPU work: nothing is read back. A renderer on the same device
/// (the brush app's egui) draws the [`DisplayTile`]s; the CPU reads the image
/// back when it needs it ([`GpuCanvas::read`]: at the end of a stroke, for
/// undo and saving) and writes its changes in ([`GpuCanvas::write`]: undo).
///
/// The display is 8-bit: values clamped to `[0, 1]`, sRGB-encoded when the
/// canvas was made with `encode_srgb` (linear float data), alpha 1; one
/// channel is grey, two grey (the second ignored), three or four RGB.
///
/// ```no_run
/// use ifd_gpu::{GpuCanvas, GpuContext, GpuSmoother};
/// use ifd_smooth::{Dab, Mode, SmoothOptions, Smoother};
/// let ctx = GpuContext::new()?;
/// let img = ifd_image::read("testdata/camera.png")?;
/// let sm = Smoother::new(&img, &SmoothOptions::default())?;
/// let gsm = GpuSmoother::new(&ctx, &sm)?;
/// let canvas = GpuCanvas::new(&ctx, &img, false, 2048)?;
/// let dab = Dab { x: 200.0, y: 150.0, radius: 30.0, falloff: 0.5, strength: 1.0 };
/// let r = canvas.apply_dab(&ctx, &gsm, &dab, Mode::Dab)?.expect("inside");
/// // Draw canvas.tiles() now; read the pixels back only when needed.
/// let pixels = canvas.read(&ctx, r)?;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct GpuCanvas {
    width: u32,
    height: u32,
    channels: u32,
    srgb: bool,
    image: wgpu::Buffer,
    tiles: Vec<DisplayTile>,
}

impl GpuCanvas {
    /// Uploads `image` and makes display textures of at most `tile` pixels
    /// a side (and at most the device's `max_texture_dimension_2d`),
    /// showing it.
    ///
    /// # Errors
    /// [`GpuError::Unsupported`] for more than 4 channels or an empty
    /// image, [`GpuError::Limit`] when the image exceeds a buffer limit,
    /// [`GpuError::Device`] for a wgpu error.
    pub fn new(
        ctx: &GpuContext,
        image: &Image,
        encode_srgb: bool,
        tile: usize,
    ) -> Result<Self, GpuError> {
        let (w, h, c) = (image.width(), image.height(), image.channels());
        if c == 0 || c > 4 || w == 0 || h == 0 {
            return Err(GpuError::Unsupported(format!(
                "a display canvas of a {w}x{h} image with {c} channels (1 to 4 channels)"
            )));
        }
        let too_big = |v: usize| GpuError::Limit {
            what: format!("a {w}x{h}x{c} canvas"),
            needed: format!("{v} samples"),
            limit_name: "u32 indexing in the shader",
            limit: u32::MAX.to_string(),
        };
        let samples = u32::try_from(w * h * c).map_err(|_| too_big(w * h * c))?;
        let bytes = u64::from(samples) * 4;
        ctx.check_buffer(&format!("the {w}x{h}x{c} canvas"), bytes, true)?;
        ctx.check_dispatch("the canvas display", w as u32, h as u32)?;
        let max_tex = ctx.device().limits().max_texture_dimension_2d as usize;
        let side = tile.clamp(1, max_tex.max(1));
        let canvas = ctx.scoped("creating the canvas", || {
            let device = ctx.device();
            let buffer = buffer_init(
                device,
                "ifd canvas",
                bytemuck::cast_slice(image.data()),
                wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_DST
                    | wgpu::BufferUsages::COPY_SRC,
            );
            let tiles = Region::tiles(w, h, side)
                .into_iter()
                .map(|region| DisplayTile {
                    region,
                    texture: rgba8_texture(
                        device,
                        "ifd canvas display",
                        region.width as u32,
                        region.height as u32,
                    ),
                })
                .collect();
            Ok(Self {
                width: w as u32,
                height: h as u32,
                channels: c as u32,
                srgb: encode_srgb,
                image: buffer,
                tiles,
            })
        })?;
        canvas.show(ctx, Region::full(w, h))?;
        Ok(canvas)
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

    /// The display textures, row by row.
    #[must_use]
    pub fn tiles(&self) -> &[DisplayTile] {
        &self.tiles
    }

    /// The image buffer (`f32`, interleaved, row-major; usages `STORAGE |
    /// COPY_DST | COPY_SRC`).
    #[must_use]
    pub fn buffer(&self) -> &wgpu::Buffer {
        &self.image
    }

    fn check_region(&self, r: Region) -> Result<(), GpuError> {
        check_region(r, self.width(), self.height(), "canvas")
    }

    /// Converts the pixels of `r` into the display textures.
    fn show(&self, ctx: &GpuContext, r: Region) -> Result<(), GpuError> {
        ctx.scoped("updating the canvas display", || {
            for t in &self.tiles {
                let Some(part) = r.intersect(t.region) else {
                    continue;
                };
                let view = t
                    .texture
                    .create_view(&wgpu::TextureViewDescriptor::default());
                submit_rgba8(
                    ctx,
                    &self.image,
                    &Rgba8Params {
                        width: part.width as u32,
                        height: part.height as u32,
                        channels: self.channels,
                        srgb: u32::from(self.srgb),
                        src_x0: part.x0 as u32,
                        src_y0: part.y0 as u32,
                        src_stride: self.width,
                        opaque: 1,
                        dst_x0: (part.x0 - t.region.x0) as u32,
                        dst_y0: (part.y0 - t.region.y0) as u32,
                        pad: [0; 2],
                    },
                    &view,
                );
            }
            Ok(())
        })
    }

    /// Applies one dab, as [`GpuSmoother::apply_dab`] does to a CPU image,
    /// to the canvas and its display; submits the work and returns the
    /// touched region (`None` when the dab misses the image) without
    /// waiting for it.
    ///
    /// # Errors
    /// [`ifd_smooth::SmoothError::BadImage`] when `smoother` was made for
    /// another image shape, [`ifd_smooth::SmoothError::OutOfRange`] for bad
    /// dab parameters, and the errors of evaluation.
    pub fn apply_dab(
        &self,
        ctx: &GpuContext,
        smoother: &GpuSmoother,
        dab: &Dab,
        mode: Mode,
    ) -> Result<Option<DabRegion>, GpuError> {
        let st = smoother.stack();
        if (st.width(), st.height(), st.channels())
            != (self.width(), self.height(), self.channels())
        {
            return Err(ifd_smooth::SmoothError::BadImage(format!(
                "the canvas is {}x{}x{}, the smoother's image {}x{}x{}",
                self.width(),
                self.height(),
                self.channels(),
                st.width(),
                st.height(),
                st.channels()
            ))
            .into());
        }
        let Some((r, out)) = smoother.smooth_dab_box(ctx, dab, mode)? else {
            return Ok(None);
        };
        ctx.scoped("blending the dab into the canvas", || {
            let device = ctx.device();
            let params = BlendParams {
                x0: r.x0 as u32,
                y0: r.y0 as u32,
                w: r.width as u32,
                h: r.height as u32,
                width: self.width,
                channels: self.channels,
                cx: dab.x,
                cy: dab.y,
                radius: dab.radius,
                falloff: dab.falloff,
                strength: dab.strength,
                ..BlendParams::default()
            };
            let pb = buffer_init(
                device,
                "dab_blend params",
                bytemuck::bytes_of(&params),
                wgpu::BufferUsages::UNIFORM,
            );
            let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("dab_blend"),
                layout: &ctx.blend_layout,
                entries: &[entry(0, &pb), entry(1, out.buffer()), entry(2, &self.image)],
            });
            submit_pass(
                ctx,
                "dab_blend",
                &ctx.blend_pipeline,
                &bind,
                (r.width as u32, r.height as u32),
            );
            Ok(())
        })?;
        self.show(ctx, r)?;
        Ok(Some(r))
    }

    /// Writes `pixels` (`r.width * r.height * channels` samples,
    /// interleaved, row-major) into region `r` and shows them.
    ///
    /// # Errors
    /// [`ifd_planar::FilterError::InvalidParameter`] for a region outside
    /// the canvas or the wrong number of samples, [`GpuError::Device`] for a
    /// wgpu error.
    pub fn write(&self, ctx: &GpuContext, r: Region, pixels: &[f32]) -> Result<(), GpuError> {
        self.check_region(r)?;
        let c = self.channels();
        if pixels.len() != r.width * r.height * c {
            return Err(ifd_planar::FilterError::InvalidParameter(format!(
                "{} samples for a {}x{} region with {c} channels",
                pixels.len(),
                r.width,
                r.height
            ))
            .into());
        }
        ctx.scoped("writing to the canvas", || {
            for (j, row) in pixels.chunks_exact(r.width * c).enumerate() {
                let at = ((r.y0 + j) * self.width() + r.x0) * c * 4;
                ctx.queue()
                    .write_buffer(&self.image, at as u64, bytemuck::cast_slice(row));
            }
            Ok(())
        })?;
        self.show(ctx, r)
    }

    /// Reads region `r` of the image back: `r.width * r.height * channels`
    /// samples, interleaved, row-major. Waits for the work submitted before.
    ///
    /// # Errors
    /// [`ifd_planar::FilterError::InvalidParameter`] for a region outside
    /// the canvas, [`GpuError::Readback`] when mapping fails.
    pub fn read(&self, ctx: &GpuContext, r: Region) -> Result<Vec<f32>, GpuError> {
        self.check_region(r)?;
        let (w, c) = (self.width(), self.channels());
        // The rows' full width: one contiguous copy.
        let offset = (r.y0 * w * c * 4) as u64;
        let size = (r.height * w * c * 4) as u64;
        let bytes = read_buffer_range(ctx, &self.image, offset, size, "the canvas")?;
        let rows: Vec<f32> = bytemuck::pod_collect_to_vec(&bytes);
        let mut out = Vec::with_capacity(r.width * r.height * c);
        for row in rows.chunks_exact(w * c) {
            out.extend_from_slice(&row[r.x0 * c..(r.x0 + r.width) * c]);
        }
        Ok(out)
    }

    /// Reads display tile `index` back: `width * height` RGBA texels,
    /// row-major (for tests and screenshots).
    ///
    /// # Errors
    /// [`ifd_planar::FilterError::InvalidParameter`] for an index past the
    /// last tile, [`GpuError::Readback`] when mapping fails.
    pub fn read_tile(&self, ctx: &GpuContext, index: usize) -> Result<Vec<[u8; 4]>, GpuError> {
        let Some(t) = self.tiles.get(index) else {
            return Err(ifd_planar::FilterError::InvalidParameter(format!(
                "display tile {index} of {}",
                self.tiles.len()
            ))
            .into());
        };
        read_rgba8(ctx, &t.texture, "a display tile")
    }
}

#[cfg(test)]
mod layout_tests {
    use super::BlendParams;
    use crate::layout::mirror;

    #[test]
    fn the_mirror_matches_dab_blend_wgsl() {
        mirror!(crate::shaders::DAB_BLEND, "Params", BlendParams, [
            "x0" => x0, "y0" => y0, "w" => w, "h" => h, "width" => width,
            "channels" => channels, "pad0" => pad0, "pad1" => pad0 + 4, "cx" => cx,
            "cy" => cy, "radius" => radius, "falloff" => falloff, "strength" => strength,
            "pad2" => pad1, "pad3" => pad1 + 4, "pad4" => pad1 + 8,
        ]);
    }
}
