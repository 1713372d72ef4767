//! The Hessian and Hessian-driven anisotropic smoothing of `ifd-smooth` on
//! the GPU: the same lookup kernel with other decompositions.

use ifd_image::Image;
use ifd_planar::{Field, ScaleStack};
use ifd_smooth::{Dab, HessianBank, Mode, RegionRefresh, Smoother};
use ifd_smooth::{DabRegion, anchored_dab_grid_corners, nearest_pixel};

use crate::context::GpuContext;
use crate::error::GpuError;
use crate::eval::{GpuDecomposition, GpuOutput, GpuPose, Region};
use crate::stack::GpuStack;

/// The Hessian filters of a [`HessianBank`] on the GPU.
#[derive(Debug)]
pub struct GpuHessian {
    xx: GpuDecomposition,
    xy: GpuDecomposition,
    sigma0: f64,
}

impl GpuHessian {
    /// Uploads the `xx` and `xy` decompositions.
    ///
    /// # Errors
    /// As [`GpuDecomposition::new`].
    pub fn new(ctx: &GpuContext, bank: &HessianBank) -> Result<Self, GpuError> {
        Ok(Self {
            xx: GpuDecomposition::new(ctx, &bank.xx)?,
            xy: GpuDecomposition::new(ctx, &bank.xy)?,
            sigma0: bank.sigma0,
        })
    }

    /// `(Hxx, Hxy, Hyy)` planes of the channel mean at scale `sigma`, as
    /// `ifd_smooth::HessianFilters::planes`: `xx` at 0 degrees, `xy`
    /// at 0 and `xx` at 90, at filter scale `s = sigma / sigma0`, divided by
    /// `s^2`. The lookups run on the GPU; the channel mean on the CPU.
    ///
    /// # Errors
    /// [`ifd_planar::FilterError::ScaleOutOfRange`] when the stack does not
    /// cover the scale, and the errors of [`GpuContext::evaluate`].
    pub fn planes(
        &self,
        ctx: &GpuContext,
        stack: &GpuStack,
        sigma: f64,
    ) -> Result<[Vec<f32>; 3], GpuError> {
        let s = (sigma / self.sigma0) as f32;
        let inv_s2 = 1.0 / (s * s);
        let c = stack.channels();
        let mean = |img: Image| -> Vec<f32> {
            img.data()
                .chunks_exact(c)
                .map(|px| px.iter().sum::<f32>() / c as f32 * inv_s2)
                .collect()
        };
        let p0 = GpuPose::constant(ctx, stack, 0.0, s)?;
        let p90 = GpuPose::constant(ctx, stack, 90.0, s)?;
        Ok([
            mean(ctx.evaluate_image(stack, &self.xx, &p0)?),
            mean(ctx.evaluate_image(stack, &self.xy, &p0)?),
            mean(ctx.evaluate_image(stack, &self.xx, &p90)?),
        ])
    }
}

/// A [`Smoother`]'s stack, aspect-ratio bank and orientation field on the
/// GPU, for whole images and brush dabs.
///
/// All bank entries' terms are uploaded concatenated with their offsets; each
/// pixel blends entries `i` and `i + 1` with weight `t` (from
/// `AspectBank::locate` of its aspect ratio, computed on the CPU) and rotates
/// by its orientation, at the smoother's constant filter scale. The
/// orientation field is uploaded once.
#[derive(Debug)]
pub struct GpuSmoother {
    stack: GpuStack,
    bank: GpuDecomposition,
    field: GpuPose,
    scale: f32,
    /// Spacing of the dab grid of whole-image [`Mode::Dab`] smoothing.
    grid: f32,
    /// The smoother's dab-grid anchor (`Smoother::grid_origin`).
    grid_origin: (usize, usize),
    entries: Vec<f32>,
    thetas: Vec<f32>,
}

impl GpuSmoother {
    /// Uploads `smoother`'s stack, bank and orientation field.
    ///
    /// # Errors
    /// [`GpuError::Limit`] when something exceeds the device's limits, and
    /// the errors of [`GpuDecomposition::from_entries`].
    pub fn new(ctx: &GpuContext, smoother: &Smoother) -> Result<Self, GpuError> {
        if smoother.direct_kernels().is_some() {
            return Err(GpuError::Unsupported(format!(
                "footprint scale {} px: scales below {} px are evaluated directly, on the CPU only",
                smoother.options().scale,
                ifd_smooth::DIRECT_BELOW
            )));
        }
        let stack = GpuStack::upload(ctx, smoother.stack())?;
        let bank = smoother.bank();
        // The entries the CPU path reads, checked once when the smoother was built.
        let gbank = GpuDecomposition::from_entries(ctx, smoother.prepared_bank())?;
        let scale = (smoother.options().scale / bank.options.sigma_ref) as f32;
        let field = smoother.orientation_field();
        let thetas: Vec<f32> = field.iter().map(|o| o.theta).collect();
        let entries: Vec<f32> = field
            .iter()
            .map(|o| entry_value(bank.locate(f64::from(o.aspect))))
            .collect();
        let pose = GpuPose::new(
            ctx,
            &stack,
            Field::Map(&thetas),
            Field::Constant(scale),
            Field::Map(&entries),
        )?;
        Ok(Self {
            stack,
            bank: gbank,
            field: pose,
            scale,
            grid: smoother.dab_grid_spacing(),
            grid_origin: smoother.grid_origin(),
            entries,
            thetas,
        })
    }

    /// Brings the upload up to date with `smoother` after
    /// `smoother.refresh_region(image, changed, ..)` returned `report`: the
    /// stack rows of [`ScaleStack::refreshed_rows`]`(changed)` and the rows
    /// of the orientation field in `report.field_rect` are written to the
    /// device; nothing else is uploaded again. `smoother` must be the one
    /// this was made from. Returns the bytes written.
    ///
    /// # Errors
    /// [`ifd_planar::FilterError::InvalidParameter`] when `smoother` does not
    /// match the upload (another shape, level layout or filter scale), and
    /// [`GpuError::Device`] for a wgpu error.
    pub fn refresh(
        &mut self,
        ctx: &GpuContext,
        smoother: &Smoother,
        changed: ifd_planar::PixelRect,
        report: &RegionRefresh,
    ) -> Result<u64, GpuError> {
        let bank = smoother.bank();
        let scale = (smoother.options().scale / bank.options.sigma_ref) as f32;
        if scale != self.scale {
            return Err(ifd_planar::FilterError::InvalidParameter(format!(
                "the smoother's filter scale is {scale}, the uploaded one {}; upload it again",
                self.scale
            ))
            .into());
        }
        let rows = smoother.stack().refreshed_rows(changed);
        let mut written = self.stack.update_rows(ctx, smoother.stack(), &rows)?;
        if let Some(r) = report.field_rect.filter(|r| r.width > 0 && r.height > 0) {
            let w = self.stack.width();
            let field = smoother.orientation_field();
            let span = r.y0 * w..(r.y0 + r.height) * w;
            if span.end > field.len() {
                return Err(ifd_planar::FilterError::InvalidParameter(format!(
                    "field rows {}..{} of a {w}x{} field",
                    r.y0,
                    r.y0 + r.height,
                    field.len() / w.max(1)
                ))
                .into());
            }
            for i in span.clone() {
                self.thetas[i] = field[i].theta;
                self.entries[i] = entry_value(bank.locate(f64::from(field[i].aspect)));
            }
            self.field.write_rows(
                ctx,
                r.y0,
                r.height,
                Some(&self.thetas[span.clone()]),
                Some(&self.entries[span.clone()]),
            )?;
            written += span.len() as u64 * 12;
        }
        Ok(written)
    }

    /// The uploaded stack.
    #[must_use]
    pub fn stack(&self) -> &GpuStack {
        &self.stack
    }

    /// Smooths `region` (the whole image when `None`), each pixel with the
    /// filter of its own orientation ([`Mode::PerPixel`]); the result stays
    /// on the device.
    ///
    /// # Errors
    /// The errors of [`GpuContext::evaluate`].
    pub fn smooth_per_pixel(
        &self,
        ctx: &GpuContext,
        region: Option<Region>,
    ) -> Result<GpuOutput, GpuError> {
        ctx.evaluate(&self.stack, &self.bank, &self.field, region)
    }

    /// Smooths `region` with one filter for every pixel: the orientation at
    /// image pixel `(x, y)` (clamped into the image, as
    /// `Smoother::orientation_at`), the paper's brush dab.
    ///
    /// # Errors
    /// The errors of [`GpuContext::evaluate`].
    pub fn smooth_with_orientation_at(
        &self,
        ctx: &GpuContext,
        x: f32,
        y: f32,
        region: Option<Region>,
    ) -> Result<GpuOutput, GpuError> {
        let i = nearest_pixel(x, y, self.stack.width(), self.stack.height());
        let pose = GpuPose::new(
            ctx,
            &self.stack,
            Field::Constant(self.thetas[i]),
            Field::Constant(self.scale),
            Field::Constant(self.entries[i]),
        )?;
        ctx.evaluate(&self.stack, &self.bank, &pose, region)
    }

    /// The whole image smoothed, read back, as `Smoother::smooth_image`.
    ///
    /// In [`Mode::Dab`] the filters sit on a grid of dab centres (spacing
    /// `max(2 S, 4)` pixels) and each pixel blends the results of the
    /// filters of its four surrounding centres with bilinear weights, as on
    /// the CPU: one evaluation per corner, each with a per-pixel pose whose
    /// orientation is that corner's, summed with the weights on the CPU.
    ///
    /// # Errors
    /// The errors of [`GpuPose::new`] and of evaluation.
    pub fn smooth_image(&self, ctx: &GpuContext, mode: Mode) -> Result<Image, GpuError> {
        match mode {
            Mode::PerPixel => ctx.evaluate_image(&self.stack, &self.bank, &self.field),
            Mode::Dab => self.smooth_dab_grid(ctx),
        }
    }

    /// Whole-image [`Mode::Dab`] smoothing (see [`GpuSmoother::smooth_image`]).
    fn smooth_dab_grid(&self, ctx: &GpuContext) -> Result<Image, GpuError> {
        let (w, h, c) = (
            self.stack.width(),
            self.stack.height(),
            self.stack.channels(),
        );
        let mut out = vec![0.0f32; w * h * c];
        let (mut thetas, mut entries, mut weights) = (
            Vec::with_capacity(w * h),
            Vec::with_capacity(w * h),
            Vec::with_capacity(w * h),
        );
        for corner in 0..4 {
            thetas.clear();
            entries.clear();
            weights.clear();
            for y in 0..h {
                for x in 0..w {
                    let ((cx, cy), wgt) =
                        anchored_dab_grid_corners(x as f32, y as f32, self.grid, self.grid_origin)
                            [corner];
                    let i = nearest_pixel(cx, cy, w, h);
                    thetas.push(self.thetas[i]);
                    entries.push(self.entries[i]);
                    weights.push(wgt);
                }
            }
            if weights.iter().all(|&v| v == 0.0) {
                continue;
            }
            let pose = GpuPose::new(
                ctx,
                &self.stack,
                Field::Map(&thetas),
                Field::Constant(self.scale),
                Field::Map(&entries),
            )?;
            let part = ctx.evaluate_image(&self.stack, &self.bank, &pose)?;
            for ((o, p), &wt) in out
                .chunks_exact_mut(c)
                .zip(part.data().chunks_exact(c))
                .zip(&weights)
            {
                if wt != 0.0 {
                    for (a, b) in o.iter_mut().zip(p) {
                        *a += wt * b;
                    }
                }
            }
        }
        Image::from_vec(w, h, c, out).map_err(|e| GpuError::Readback {
            what: "the smoothed image",
            reason: e.to_string(),
        })
    }

    /// Applies one dab to `target` as `Smoother::apply_dab` does: the dab's
    /// bounding box is smoothed on the GPU (per pixel, or with the filter at
    /// the dab's centre in [`Mode::Dab`]), read back and blended in with the
    /// dab's weights. Returns the touched region (`None` when the dab misses
    /// the image).
    ///
    /// # Errors
    /// [`ifd_smooth::SmoothError::BadImage`] when `target` has another shape,
    /// [`ifd_smooth::SmoothError::OutOfRange`] for bad dab parameters, and
    /// the errors of evaluation.
    pub fn apply_dab(
        &self,
        ctx: &GpuContext,
        dab: &Dab,
        mode: Mode,
        target: &mut Image,
    ) -> Result<Option<DabRegion>, GpuError> {
        let (w, h, c) = (
            self.stack.width(),
            self.stack.height(),
            self.stack.channels(),
        );
        if (target.width(), target.height(), target.channels()) != (w, h, c) {
            return Err(ifd_smooth::SmoothError::BadImage(format!(
                "target is {}x{}x{}, the smoother's image {w}x{h}x{c}",
                target.width(),
                target.height(),
                target.channels()
            ))
            .into());
        }
        let Some((r, out)) = self.smooth_dab_box(ctx, dab, mode)? else {
            return Ok(None);
        };
        let sm = out.read(ctx)?;
        let data = target.data_mut();
        for ry in 0..r.height {
            let y = r.y0 + ry;
            for rx in 0..r.width {
                let x = r.x0 + rx;
                let d = ((x as f32 - dab.x).powi(2) + (y as f32 - dab.y).powi(2)).sqrt();
                let wgt = dab.weight(d);
                if wgt <= 0.0 {
                    continue;
                }
                let src = &sm.data()[(ry * r.width + rx) * c..(ry * r.width + rx + 1) * c];
                for (p, s) in data[(y * w + x) * c..(y * w + x + 1) * c]
                    .iter_mut()
                    .zip(src)
                {
                    *p += wgt * (s - *p);
                }
            }
        }
        Ok(Some(r))
    }
}

impl GpuSmoother {
    /// Smooths the bounding box of `dab` (clipped to the image) as
    /// [`GpuSmoother::apply_dab`] does before blending; `None` when the dab
    /// misses the image. The result stays on the device.
    pub(crate) fn smooth_dab_box(
        &self,
        ctx: &GpuContext,
        dab: &Dab,
        mode: Mode,
    ) -> Result<Option<(DabRegion, GpuOutput)>, GpuError> {
        let Some(r) = dab.region(self.stack.width(), self.stack.height())? else {
            return Ok(None);
        };
        let out = match mode {
            Mode::PerPixel => self.smooth_per_pixel(ctx, Some(r))?,
            Mode::Dab => self.smooth_with_orientation_at(ctx, dab.x, dab.y, Some(r))?,
        };
        Ok(Some((r, out)))
    }
}

/// `i + t` for the shader, from `AspectBank::locate`.
fn entry_value((i, t): (usize, f64)) -> f32 {
    (i as f64 + t) as f32
}

/// Filters a whole image on the GPU from its prefiltered `stack`: uploads
/// `stack` and `decomposition`, evaluates with `angle` and `scale`
/// (constants or per-pixel maps) and reads the result back. The GPU
/// counterpart of `Filter::new(stack, decomposition)?.apply(angle, scale)`
/// (`ifd_planar::filter_image` builds the stack itself, from the image).
///
/// # Errors
/// The errors of [`GpuStack::upload`], [`GpuPose::new`] and
/// [`GpuContext::evaluate`].
pub fn filter_stack(
    ctx: &GpuContext,
    stack: &ScaleStack,
    decomposition: &ifd_planar::Decomposition,
    angle: Field<'_>,
    scale: Field<'_>,
) -> Result<Image, GpuError> {
    let gstack = GpuStack::upload(ctx, stack)?;
    let gd = GpuDecomposition::new(ctx, decomposition)?;
    let pose = GpuPose::new(ctx, &gstack, angle, scale, Field::Constant(0.0))?;
    ctx.evaluate_image(&gstack, &gd, &pose)
}
