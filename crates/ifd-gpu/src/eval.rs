//! Decompositions, per-pixel poses and the evaluation dispatch.

use std::time::Duration;

use bytemuck::{Pod, Zeroable};
use ifd_image::Image;
use ifd_planar::Sampling;
use ifd_planar::{
    Border, CheckField, Field, FieldKind, FilterError, Prepare, PreparedDecomposition,
};

use crate::context::GpuContext;
use crate::error::GpuError;
use crate::shaders::codes;
use crate::stack::GpuStack;
use crate::wgpu_helpers::{
    Rgba8Params, Timestamps, buffer_init, check_region, entry, read_buffer, read_gpu_time,
    rgba8_texture, submit_rgba8,
};

/// The shader's `struct Params`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct Params {
    region_x0: u32,
    region_y0: u32,
    region_w: u32,
    region_h: u32,
    width: u32,
    height: u32,
    channels: u32,
    chunk_c0: u32,
    chunk_nc: u32,
    n_levels: u32,
    border_mode: u32,
    border_value: f32,
    inv_ln_ratio: f32,
    cos_t: f32,
    sin_t: f32,
    scale: f32,
    u_offset: f32,
    entry: f32,
    flags: u32,
    rot_off: u32,
    scale_off: u32,
    entry_off: u32,
    n_entries: u32,
    /// 0 bilinear, 1 cubic B-spline (`INTERP_*` in the shader).
    interpolation: u32,
    /// How the decomposition's kernel was sampled (`SAMPLING_*` in the
    /// shader): the atoms' effective sigma at each scale.
    sampling: u32,
    pad: [u32; 3],
}

/// The shader's `struct Term`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct GpuTerm {
    weight: f32,
    cx: f32,
    cy: f32,
    ln_sigma: f32,
}

/// The shader's `struct TermLevel`: the levels a term reads at a constant
/// scale and their weights, located on the host as the CPU path locates them
/// ([`ifd_planar::LevelLocator::locate`]).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct GpuTermLevel {
    a: u32,
    b: u32,
    wa: f32,
    wb: f32,
}

/// One or more decompositions ("entries") on the GPU, terms concatenated.
///
/// A plain filter is one entry. The aspect-ratio bank of anisotropic
/// smoothing is one entry per aspect ratio; each pixel then blends entries
/// `i` and `i + 1` with weight `t` (the pose's entry value `i + t`).
#[derive(Debug)]
pub struct GpuDecomposition {
    terms: wgpu::Buffer,
    entries: wgpu::Buffer,
    n_entries: u32,
    n_terms: usize,
    sigma_range: (f64, f64),
    sampling: Sampling,
    /// Every term's sigma, in upload order (to locate levels on the host).
    sigmas: Vec<f64>,
}

impl GpuDecomposition {
    /// Uploads one decomposition (an [`ifd_planar::Decomposition`], checked here, or an
    /// [`ifd_planar::PreparedDecomposition`], checked once for every path).
    ///
    /// # Errors
    /// As [`GpuDecomposition::from_entries`].
    pub fn new(
        ctx: &GpuContext,
        decomposition: &(impl Prepare + ?Sized),
    ) -> Result<Self, GpuError> {
        Self::from_entries(ctx, &[decomposition.prepare()?.into_owned()])
    }

    /// Uploads several decompositions, concatenated with their offsets.
    ///
    /// # Errors
    /// [`FilterError::InvalidParameter`] for no entries or entries applied
    /// with different [`Sampling`]s, [`GpuError::Limit`] when the terms
    /// exceed a device limit. The terms were checked when the entries were
    /// prepared ([`PreparedDecomposition::new`]), as for the CPU path.
    pub fn from_entries(
        ctx: &GpuContext,
        entries: &[PreparedDecomposition],
    ) -> Result<Self, GpuError> {
        let Some(first) = entries.first() else {
            return Err(FilterError::InvalidParameter("no decompositions given".into()).into());
        };
        let sampling = first.sampling();
        if let Some(e) = entries.iter().position(|e| e.sampling() != sampling) {
            return Err(FilterError::InvalidParameter(format!(
                "decomposition {e} is applied as {:?}, decomposition 0 as {sampling:?}: \
                 entries of one upload share their sampling",
                entries[e].sampling()
            ))
            .into());
        }
        let mut terms = Vec::new();
        let mut sigmas = Vec::new();
        let mut offsets: Vec<[u32; 2]> = Vec::with_capacity(entries.len());
        let mut lo = f64::INFINITY;
        let mut hi = 0.0f64;
        for entry in entries {
            offsets.push([terms.len() as u32, entry.len() as u32]);
            let (a, b) = entry.sigma_range();
            lo = lo.min(a);
            hi = hi.max(b);
            sigmas.extend(entry.terms().iter().map(|t| t.sigma));
            terms.extend(entry.terms().iter().map(|t| GpuTerm {
                weight: t.weight as f32,
                cx: t.x as f32,
                cy: t.y as f32,
                ln_sigma: t.sigma.ln() as f32,
            }));
        }
        let bytes = (terms.len() * std::mem::size_of::<GpuTerm>()) as u64;
        ctx.check_buffer(&format!("{} decomposition terms", terms.len()), bytes, true)?;
        let device = ctx.device();
        let (tb, eb) = ctx.scoped("uploading the decomposition", || {
            Ok((
                buffer_init(
                    device,
                    "ifd terms",
                    bytemuck::cast_slice(&terms),
                    wgpu::BufferUsages::STORAGE,
                ),
                buffer_init(
                    device,
                    "ifd entries",
                    bytemuck::cast_slice(&offsets),
                    wgpu::BufferUsages::STORAGE,
                ),
            ))
        })?;
        Ok(Self {
            terms: tb,
            entries: eb,
            n_entries: offsets.len() as u32,
            n_terms: terms.len(),
            sigma_range: (lo, hi),
            sampling,
            sigmas,
        })
    }

    /// Number of entries.
    #[must_use]
    pub fn entries(&self) -> usize {
        self.n_entries as usize
    }

    /// Total number of terms.
    #[must_use]
    pub fn terms(&self) -> usize {
        self.n_terms
    }
}

/// A rectangle of output pixels, inside the image: the CPU path's
/// [`ifd_planar::PixelRect`], under the name the GPU API has used.
pub use ifd_planar::PixelRect as Region;

/// Per-pixel rotation, scale and bank entry, uploaded for one stack.
///
/// Angle maps are uploaded as `(cos, sin)` pairs computed on the CPU with
/// the same `f32` `sin_cos` as the CPU path (WGSL only promises `sin`/`cos`
/// to `2^-11` absolute, which would move a lookup 200 px away by 0.1 px);
/// scale maps as `(s, level offset)` pairs, the level offset
/// `(ln s - ln sigma_0) / ln r` computed in `f64`. Constant fields need no
/// map. A pose can be reused for many evaluations (the brush uploads the
/// orientation field once and evaluates dab after dab).
#[derive(Debug)]
pub struct GpuPose {
    maps: wgpu::Buffer,
    width: u32,
    height: u32,
    flags: u32,
    rot_off: u32,
    scale_off: u32,
    entry_off: u32,
    cos_t: f32,
    sin_t: f32,
    scale: f32,
    u_offset: f32,
    entry: f32,
    /// The smallest and largest scale.
    scale_range: (f32, f32),
    /// Where they are (`" at pixel (x, y)"`, empty for a constant), for
    /// messages.
    scale_where: [String; 2],
}

/// A per-pixel scale map locates levels in the shader by the log-uniform
/// formula: refused on a stack whose levels are at given sigmas.
fn check_scale_map_reads(stack: &GpuStack, scale_map: bool) -> Result<(), GpuError> {
    if scale_map && !stack.locator.is_uniform() {
        return Err(FilterError::InvalidParameter(
            "a per-pixel scale map reads a stack of log-uniformly spaced levels \
             (ScaleStack::new); this one has levels at given sigmas, for a constant scale"
                .into(),
        )
        .into());
    }
    Ok(())
}

/// `[cos, sin]` of an angle in degrees, as the pose maps hold rotations
/// (the CPU path's `f32` `sin_cos`).
fn cos_sin(degrees: f32) -> [f32; 2] {
    let (s, c) = degrees.to_radians().sin_cos();
    [c, s]
}

impl GpuPose {
    /// Uploads the per-pixel maps among `angle` (degrees, counter-clockwise
    /// on screen), `scale` and `entry` (bank entry `i + t`: entries `i` and
    /// `i + 1` blended with weight `t`; 0 for a single decomposition) for
    /// evaluations on `stack`: raw [`Field`]s, checked here as the CPU path
    /// checks them, or [`ifd_planar::CheckedField`]s, checked once for both paths.
    ///
    /// # Errors
    /// As the CPU path: [`FilterError::MapSize`] for maps of the wrong size,
    /// [`FilterError::InvalidValue`] for non-finite angles, non-positive
    /// scales or negative entries; [`GpuError::Limit`] when the maps exceed
    /// a buffer limit.
    pub fn new<'f>(
        ctx: &GpuContext,
        stack: &GpuStack,
        angle: impl CheckField<'f>,
        scale: impl CheckField<'f>,
        entry: impl CheckField<'f>,
    ) -> Result<Self, GpuError> {
        let (w, h) = (stack.width(), stack.height());
        let checked_scale = scale.check(FieldKind::Scale, w, h)?;
        let angle = angle.check(FieldKind::Angle, w, h)?.field();
        let entry = entry.check(FieldKind::Entry, w, h)?.field();
        let scale = checked_scale.field();
        let (ln0, inv) = stack.ln_params;
        let uniform = stack.locator.is_uniform();
        check_scale_map_reads(stack, matches!(scale, Field::Map(_)))?;
        // (Unused with levels at given sigmas: the host locates every term.)
        let level_offset = |s: f32| {
            if uniform {
                ((f64::from(s).ln() - ln0) * inv) as f32
            } else {
                0.0
            }
        };
        let mut maps: Vec<f32> = Vec::new();
        let mut flags = 0;
        let (mut rot_off, mut scale_off, mut entry_off) = (0, 0, 0);
        let (mut cos_t, mut sin_t, mut s_c, mut u_c, mut e_c) = (1.0, 0.0, 1.0, 0.0, 0.0);
        match angle {
            Field::Constant(a) => [cos_t, sin_t] = cos_sin(a),
            Field::Map(m) => {
                flags |= codes::FLAG_ANGLE_MAP;
                rot_off = maps.len();
                maps.reserve(2 * m.len());
                maps.extend(m.iter().flat_map(|&a| cos_sin(a)));
            }
        }
        match scale {
            Field::Constant(s) => {
                s_c = s;
                u_c = level_offset(s);
            }
            Field::Map(m) => {
                flags |= codes::FLAG_SCALE_MAP;
                scale_off = maps.len();
                maps.reserve(2 * m.len());
                for &s in m {
                    maps.extend([s, level_offset(s)]);
                }
            }
        }
        match entry {
            Field::Constant(e) => e_c = e,
            Field::Map(m) => {
                flags |= codes::FLAG_ENTRY_MAP;
                entry_off = maps.len();
                maps.extend_from_slice(m);
            }
        }
        let too_big = |what| GpuError::Limit {
            what: format!("the {what} offset in the pose maps"),
            needed: maps.len().to_string(),
            limit_name: "u32 indexing in the shader",
            limit: u32::MAX.to_string(),
        };
        let rot_off = u32::try_from(rot_off).map_err(|_| too_big("rotation"))?;
        let scale_off = u32::try_from(scale_off).map_err(|_| too_big("scale"))?;
        let entry_off = u32::try_from(entry_off).map_err(|_| too_big("entry"))?;
        ctx.check_buffer(
            &format!("per-pixel maps of a {w}x{h} image"),
            (maps.len() * 4) as u64,
            true,
        )?;
        let buffer = ctx.scoped("uploading the per-pixel maps", || {
            Ok(buffer_init(
                ctx.device(),
                "ifd pose maps",
                bytemuck::cast_slice(&maps),
                wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            ))
        })?;
        Ok(Self {
            maps: buffer,
            width: stack.width,
            height: stack.height,
            flags,
            rot_off,
            scale_off,
            entry_off,
            cos_t,
            sin_t,
            scale: s_c,
            u_offset: u_c,
            entry: e_c,
            scale_range: checked_scale.range(),
            scale_where: [
                checked_scale.location_of_min(),
                checked_scale.location_of_max(),
            ],
        })
    }

    /// Overwrites rows `y0..y0 + rows` of the angle and bank-entry maps
    /// (each `rows * width` values; `None` keeps a map, and a field that is
    /// not a map takes no rows).
    ///
    /// # Errors
    /// [`FilterError::InvalidParameter`] for rows outside the image, maps of
    /// the wrong length or not uploaded as maps, non-finite values or
    /// negative entries; [`GpuError::Device`] for a wgpu error.
    pub(crate) fn write_rows(
        &self,
        ctx: &GpuContext,
        y0: usize,
        rows: usize,
        angle: Option<&[f32]>,
        entry: Option<&[f32]>,
    ) -> Result<(), GpuError> {
        let (w, h) = (self.width as usize, self.height as usize);
        let bad = |m: String| GpuError::from(FilterError::InvalidParameter(m));
        if y0 + rows > h {
            return Err(bad(format!("rows {y0}..{} of a {w}x{h} pose", y0 + rows)));
        }
        let n = rows * w;
        for (name, m, flag, min) in [
            ("angle", angle, codes::FLAG_ANGLE_MAP, f32::NEG_INFINITY),
            ("bank entry", entry, codes::FLAG_ENTRY_MAP, 0.0),
        ] {
            let Some(m) = m else { continue };
            if self.flags & flag == 0 || m.len() != n {
                return Err(bad(format!(
                    "{} {name} values for {rows} rows of a pose whose {name} {}",
                    m.len(),
                    if self.flags & flag == 0 {
                        "is constant"
                    } else {
                        "is a map"
                    }
                )));
            }
            if let Some(i) = m.iter().position(|v| !v.is_finite() || *v < min) {
                return Err(bad(format!(
                    "{name} {} at pixel ({}, {}) is not finite or negative",
                    m[i],
                    i % w,
                    y0 + i / w
                )));
            }
        }
        ctx.scoped("updating the per-pixel maps", || {
            if let Some(a) = angle {
                let cs: Vec<f32> = a.iter().flat_map(|&a| cos_sin(a)).collect();
                let at = (self.rot_off as usize + 2 * y0 * w) * 4;
                ctx.queue()
                    .write_buffer(&self.maps, at as u64, bytemuck::cast_slice(&cs));
            }
            if let Some(e) = entry {
                let at = (self.entry_off as usize + y0 * w) * 4;
                ctx.queue()
                    .write_buffer(&self.maps, at as u64, bytemuck::cast_slice(e));
            }
            Ok(())
        })
    }

    /// A constant angle and scale on `stack`, entry 0 (no upload beyond a
    /// 16-byte placeholder).
    ///
    /// # Errors
    /// As [`GpuPose::new`].
    pub fn constant(
        ctx: &GpuContext,
        stack: &GpuStack,
        angle: f32,
        scale: f32,
    ) -> Result<Self, GpuError> {
        Self::new(
            ctx,
            stack,
            Field::Constant(angle),
            Field::Constant(scale),
            Field::Constant(0.0),
        )
    }
}

/// The result of an evaluation: a storage buffer of `f32`, interleaved
/// `height x width x channels`, row-major, on the device.
///
/// Read it back with [`GpuOutput::read`], or hand [`GpuOutput::buffer`] (or
/// [`GpuOutput::to_rgba8_texture`]) to a renderer on the same device.
#[derive(Debug)]
pub struct GpuOutput {
    buffer: wgpu::Buffer,
    region: Region,
    channels: usize,
    timestamps: Option<wgpu::Buffer>,
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

impl GpuContext {
    /// Evaluates over the whole image, as [`GpuContext::evaluate`] with no
    /// region, and reads the result back; in bands of rows when the result
    /// exceeds the device's `max_storage_buffer_binding_size` or
    /// `max_buffer_size` (each band is one evaluation and one readback), so
    /// the size of the result is limited by host memory, not the device.
    ///
    /// # Errors
    /// As [`GpuContext::evaluate`] and [`GpuOutput::read`]; [`GpuError::Limit`]
    /// when not even one row fits.
    pub fn evaluate_image(
        &self,
        stack: &GpuStack,
        decomposition: &GpuDecomposition,
        pose: &GpuPose,
    ) -> Result<Image, GpuError> {
        let (w, h, c) = (stack.width(), stack.height(), stack.channels());
        let limits = self.device().limits();
        let cap = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        let rows = (cap / (w * c * 4).max(1) as u64).clamp(1, h.max(1) as u64) as usize;
        if rows >= h {
            return self.evaluate(stack, decomposition, pose, None)?.read(self);
        }
        let mut data = Vec::with_capacity(w * h * c);
        for y0 in (0..h).step_by(rows) {
            let band = Region {
                x0: 0,
                y0,
                width: w,
                height: rows.min(h - y0),
            };
            let part = self
                .evaluate(stack, decomposition, pose, Some(band))?
                .read(self)?;
            data.extend_from_slice(part.data());
        }
        Image::from_vec(w, h, c, data).map_err(|e| GpuError::Readback {
            what: "the result",
            reason: e.to_string(),
        })
    }

    /// Evaluates `decomposition` (rotated, scaled and blended per `pose`) on
    /// `stack` over `region` (the whole image when `None`): the GPU version of
    /// [`ifd_planar::Filter::apply`], one trilinear lookup per term and pixel.
    /// The work is submitted; [`GpuOutput::read`] waits for it.
    ///
    /// ```no_run
    /// use ifd_gpu::{GpuContext, GpuDecomposition, GpuPose, GpuStack};
    /// use ifd_planar::{Border, Decomposition, StackOptions, Term, stack_for_decomposition};
    /// let ctx = GpuContext::new()?;
    /// let img = ifd_image::read("testdata/camera.png")?;
    /// let d = Decomposition::from_terms(vec![Term { weight: 1.0, x: 4.0, y: 0.0, sigma: 2.0 }]);
    /// let stack = stack_for_decomposition(&img, &d, 1.0, 1.0, Border::Reflect101, StackOptions::default())?;
    /// let gstack = GpuStack::upload(&ctx, &stack)?;
    /// let gd = GpuDecomposition::new(&ctx, &d)?;
    /// let pose = GpuPose::constant(&ctx, &gstack, 30.0, 1.0)?;
    /// let out = ctx.evaluate(&gstack, &gd, &pose, None)?.read(&ctx)?;
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`FilterError::ScaleOutOfRange`] when some `scale * sigma_t` is not
    /// covered by the stack, [`FilterError::InvalidParameter`] for a region
    /// outside the image or a pose made for another stack, a bank entry past
    /// the last, [`GpuError::Limit`] for an output larger than the device's
    /// buffer limits, [`GpuError::Device`] for a wgpu error.
    pub fn evaluate(
        &self,
        stack: &GpuStack,
        decomposition: &GpuDecomposition,
        pose: &GpuPose,
        region: Option<Region>,
    ) -> Result<GpuOutput, GpuError> {
        let (w, h) = (stack.width(), stack.height());
        if (pose.width, pose.height) != (stack.width, stack.height) {
            return Err(FilterError::InvalidParameter(format!(
                "the pose was made for a {}x{} image, the stack is {w}x{h}",
                pose.width, pose.height
            ))
            .into());
        }
        // A pose made for a log-uniform stack of the same size may be
        // handed a stack at given sigmas: its scale map cannot be read there.
        check_scale_map_reads(stack, pose.flags & codes::FLAG_SCALE_MAP != 0)?;
        let region = region.unwrap_or(Region::full(w, h));
        check_region(region, w, h, "image")?;
        if pose.flags & codes::FLAG_ENTRY_MAP == 0
            && pose.entry > (decomposition.n_entries - 1) as f32
        {
            return Err(FilterError::InvalidParameter(format!(
                "bank entry {} is past the last entry {}",
                pose.entry,
                decomposition.n_entries - 1
            ))
            .into());
        }
        // Coverage, as the CPU's Filter::check_scales.
        let (min, max) = stack.sigma_range;
        let (slo, shi) = decomposition.sigma_range;
        let (s_lo, s_hi) = pose.scale_range;
        let (need_lo, need_hi) = ifd_planar::sigma_bounds(
            decomposition.sampling,
            (slo, shi),
            (f64::from(s_lo), f64::from(s_hi)),
        );
        for (((scale, location), term_sigma), needed) in [s_lo, s_hi]
            .into_iter()
            .zip(&pose.scale_where)
            .zip([slo, shi])
            .zip([need_lo, need_hi])
        {
            if !stack.covers(needed) {
                return Err(FilterError::ScaleOutOfRange {
                    scale: f64::from(scale),
                    location: location.clone(),
                    term_sigma,
                    needed,
                    min,
                    max,
                }
                .into());
            }
        }
        debug_assert!(pose.scale_range.0 <= pose.scale_range.1);
        let (rw, rh) = (region.width as u32, region.height as u32);
        self.check_dispatch("the evaluation", rw, rh)?;
        let out_bytes = (region.width * region.height * stack.channels()) as u64 * 4;
        self.check_buffer(
            &format!(
                "the {}x{}x{} result",
                region.width,
                region.height,
                stack.channels()
            ),
            out_bytes,
            true,
        )?;
        let (border_mode, border_value) = match stack.border {
            Border::Reflect101 => (codes::BORDER_REFLECT101, 0.0),
            Border::Constant(v) => (codes::BORDER_CONSTANT, v),
            Border::Replicate => (codes::BORDER_REPLICATE, 0.0),
            Border::Wrap => (codes::BORDER_WRAP, 0.0),
        };
        // A constant scale: every term's levels located here, once, as the
        // CPU path locates them (one lookup per term on a stack at the
        // terms' sigmas), instead of per pixel in the shader.
        let mut flags = pose.flags;
        let term_levels: Vec<GpuTermLevel> = if pose.flags & codes::FLAG_SCALE_MAP == 0 {
            flags |= codes::FLAG_TERM_LEVELS;
            let s = f64::from(pose.scale);
            decomposition
                .sigmas
                .iter()
                .map(|&sigma| {
                    let (a, b, wa, wb) = stack
                        .locator
                        .locate(decomposition.sampling.effective_sigma(sigma, s));
                    GpuTermLevel {
                        a: a as u32,
                        b: b as u32,
                        wa,
                        wb,
                    }
                })
                .collect()
        } else {
            Vec::new()
        };
        let device = self.device();
        self.scoped("evaluating the decomposition", || {
            let levels_buffer = buffer_init(
                device,
                "ifd term levels",
                if term_levels.is_empty() {
                    &[0u8; 16]
                } else {
                    bytemuck::cast_slice(&term_levels)
                },
                wgpu::BufferUsages::STORAGE,
            );
            let output = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("ifd result"),
                size: out_bytes.max(16),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let binds: Vec<wgpu::BindGroup> = stack
                .chunks
                .iter()
                .map(|chunk| {
                    let params = Params {
                        region_x0: region.x0 as u32,
                        region_y0: region.y0 as u32,
                        region_w: rw,
                        region_h: rh,
                        width: stack.width,
                        height: stack.height,
                        channels: stack.channels,
                        chunk_c0: chunk.c0,
                        chunk_nc: chunk.nc,
                        n_levels: stack.n_levels,
                        border_mode,
                        border_value,
                        inv_ln_ratio: stack.ln_params.1 as f32,
                        cos_t: pose.cos_t,
                        sin_t: pose.sin_t,
                        scale: pose.scale,
                        u_offset: pose.u_offset,
                        entry: pose.entry,
                        flags,
                        rot_off: pose.rot_off,
                        scale_off: pose.scale_off,
                        entry_off: pose.entry_off,
                        n_entries: decomposition.n_entries,
                        interpolation: match stack.interpolation {
                            ifd_planar::Interpolation::Linear => codes::INTERP_LINEAR,
                            ifd_planar::Interpolation::Cubic => codes::INTERP_CUBIC,
                        },
                        sampling: match decomposition.sampling {
                            Sampling::Continuous => codes::SAMPLING_CONTINUOUS,
                            Sampling::Point => codes::SAMPLING_POINT,
                            Sampling::Area => codes::SAMPLING_AREA,
                            Sampling::Averaged => codes::SAMPLING_AVERAGED,
                        },
                        pad: [0; 3],
                    };
                    let pb = buffer_init(
                        device,
                        "ifd params",
                        bytemuck::bytes_of(&params),
                        wgpu::BufferUsages::UNIFORM,
                    );
                    device.create_bind_group(&wgpu::BindGroupDescriptor {
                        label: Some("ifd_eval"),
                        layout: &self.eval_layout,
                        entries: &[
                            entry(0, &pb),
                            entry(1, &chunk.levels),
                            entry(2, &chunk.data),
                            entry(3, &decomposition.terms),
                            entry(4, &decomposition.entries),
                            entry(5, &pose.maps),
                            entry(6, &output),
                            entry(7, &levels_buffer),
                        ],
                    })
                })
                .collect();
            let timing = Timestamps::new(self, "ifd timestamps");
            let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("ifd_eval"),
            });
            {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("ifd_eval"),
                    timestamp_writes: timing.as_ref().map(Timestamps::writes),
                });
                pass.set_pipeline(&self.eval_pipeline);
                for bind in &binds {
                    pass.set_bind_group(0, bind, &[]);
                    pass.dispatch_workgroups(rw.div_ceil(8), rh.div_ceil(8), 1);
                }
            }
            if let Some(t) = &timing {
                t.resolve(&mut enc);
            }
            self.queue().submit([enc.finish()]);
            Ok(GpuOutput {
                buffer: output,
                region,
                channels: stack.channels(),
                timestamps: timing.map(|t| t.resolve),
            })
        })
    }
}

#[cfg(test)]
mod layout_tests {
    use super::{GpuTerm, GpuTermLevel, Params};
    use crate::layout::mirror;

    #[test]
    fn the_mirrors_match_ifd_eval_wgsl() {
        let src = crate::shaders::ifd_eval_source();
        mirror!(src, "Params", Params, [
            "region_x0" => region_x0, "region_y0" => region_y0, "region_w" => region_w,
            "region_h" => region_h, "width" => width, "height" => height,
            "channels" => channels, "chunk_c0" => chunk_c0, "chunk_nc" => chunk_nc,
            "n_levels" => n_levels, "border_mode" => border_mode,
            "border_value" => border_value, "inv_ln_ratio" => inv_ln_ratio,
            "cos_t" => cos_t, "sin_t" => sin_t, "scale" => scale, "u_offset" => u_offset,
            "entry" => entry, "flags" => flags, "rot_off" => rot_off,
            "scale_off" => scale_off, "entry_off" => entry_off, "n_entries" => n_entries,
            "interpolation" => interpolation, "sampling" => sampling,
            "_pad0" => pad, "_pad1" => pad + 4, "_pad2" => pad + 8,
        ]);
        mirror!(src, "Term", GpuTerm, [
            "weight" => weight, "cx" => cx, "cy" => cy, "ln_sigma" => ln_sigma,
        ]);
        mirror!(src, "TermLevel", GpuTermLevel, ["a" => a, "b" => b, "wa" => wa, "wb" => wb]);
    }
}
