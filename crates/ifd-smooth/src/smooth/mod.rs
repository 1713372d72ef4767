//! The [`Smoother`]: one prefiltered scale stack, the Hessian-derived
//! orientation field, and the aspect-ratio bank; smooths whole images or dabs.
//! The options are in `options.rs`, dabs and the dab grid in `dab.rs`, the
//! tensor blur in `blur.rs`, the refresh of a changed rectangle in
//! `refresh.rs`.

mod blur;
mod dab;
mod options;
mod refresh;

use std::sync::Arc;

use ifd_image::{Image, ImageView};
use ifd_planar::{Field, Filter, PreparedDecomposition, ScaleStack, StackLayout, StackPlan, Taps};
use rayon::prelude::*;

use crate::bank::{AspectBank, BANK_SAMPLING};
use crate::direct::DirectKernels;
use crate::error::SmoothError;
use crate::gaussians::{
    AnisoGaussian, BankLookups, NO_SHARES, PixelGaussians, SmallFootprints, bank_passes, shares_of,
};
use crate::hessian::{HessianBank, hessian_stack_options};
use crate::orientation::{Orientation, tensor};

pub(crate) use self::blur::blur_radius;
use self::blur::gaussian_blur;
pub use self::dab::{Dab, DabRegion, anchored_dab_grid_corners, dab_grid_corners, nearest_pixel};
pub use self::options::{Mode, SCALE_RANGE, SmoothOptions};
pub use self::refresh::RegionRefresh;

/// Hessian-driven anisotropic smoothing of one image.
#[derive(Debug)]
pub struct Smoother {
    stack: ScaleStack,
    /// Below [`DIRECT_BELOW`]: the tabulated pixel-integrated kernels and
    /// the image they read.
    direct: Option<(DirectKernels, Image)>,
    bank: Arc<AspectBank>,
    /// The bank's entries checked once, applied as [`BANK_SAMPLING`]: what
    /// the CPU filters and the GPU upload (`ifd_gpu::GpuSmoother`) read.
    prepared: Vec<PreparedDecomposition>,
    opts: SmoothOptions,
    field: Vec<Orientation>,
    width: usize,
    height: usize,
    channels: usize,
    /// Where the image's pixel (0, 0) lies in a larger image it is a tile
    /// of: the dab grid of [`Mode::Dab`] is anchored there.
    grid_origin: (usize, usize),
}

impl Smoother {
    /// Builds the decompositions (a few seconds), the stack and the orientation field.
    ///
    /// # Errors
    /// Out-of-range options, NaN pixels, empty images, failed fits.
    pub fn new<'a>(
        image: impl Into<ImageView<'a>>,
        opts: &SmoothOptions,
    ) -> Result<Self, SmoothError> {
        opts.validate()?;
        let hbank = HessianBank::new(opts.hessian_tol)?;
        let bank = AspectBank::build(opts.bank, |_, _| {})?;
        Self::with_banks(image, opts, Arc::new(bank), &hbank)
    }

    /// The scale stack a smoother of a `(width, height, channels)` image
    /// builds: the Hessian filters' sigma range and the aspect bank's at the
    /// footprint scale, Hessian-grade options and a margin for the bank's
    /// reach.
    #[must_use]
    pub fn stack_plan(
        (width, height, channels): (usize, usize, usize),
        opts: &SmoothOptions,
        bank: &AspectBank,
        hbank: &HessianBank,
    ) -> StackPlan {
        let (hlo, hhi) = Self::hessian_sigmas(opts, hbank);
        let (lo, hi) = match Self::smoothing_sigmas(opts, bank) {
            Some((blo, bhi)) => (hlo.min(blo), hhi.max(bhi)),
            None => (hlo, hhi),
        };
        StackPlan {
            dims: (width, height, channels),
            sigmas: (lo, hi),
            border: opts.border,
            options: smoother_stack_options(bank, opts.scale, (width, height, channels), (lo, hi)),
        }
    }

    /// The stack sigmas the Hessian filters read.
    pub(crate) fn hessian_sigmas(opts: &SmoothOptions, hbank: &HessianBank) -> (f64, f64) {
        let hs = opts.hessian_sigma();
        hbank.stack_sigmas(hs, hs)
    }

    /// The stack sigmas the smoothing filters read (`None` when they are
    /// evaluated directly and do not read the stack).
    pub(crate) fn smoothing_sigmas(opts: &SmoothOptions, bank: &AspectBank) -> Option<(f64, f64)> {
        if opts.evaluated_directly() {
            return None;
        }
        let s = opts.scale / bank.options.sigma_ref;
        Some(ifd_planar::sigma_bounds(
            BANK_SAMPLING,
            bank.sigma_range(),
            (s, s),
        ))
    }

    /// The layout of the scale stack a smoother of a `(width, height,
    /// channels)` image builds ([`Smoother::stack_plan`]), without building
    /// it (memory budgets, device limits).
    ///
    /// # Errors
    /// As [`StackLayout::new`].
    pub fn stack_layout(
        dims: (usize, usize, usize),
        opts: &SmoothOptions,
        bank: &AspectBank,
        hbank: &HessianBank,
    ) -> Result<StackLayout, SmoothError> {
        Ok(Self::stack_plan(dims, opts, bank, hbank).layout()?)
    }

    /// As [`Smoother::new`] with decompositions fitted (or loaded) beforehand.
    ///
    /// # Errors
    /// Out-of-range options, NaN pixels, empty images.
    pub fn with_banks<'a>(
        image: impl Into<ImageView<'a>>,
        opts: &SmoothOptions,
        bank: Arc<AspectBank>,
        hbank: &HessianBank,
    ) -> Result<Self, SmoothError> {
        let image = image.into();
        opts.validate()?;
        let n_bad = image.count_non_finite();
        if n_bad > 0 {
            return Err(SmoothError::BadImage(format!(
                "image has {n_bad} NaN or infinite values; replace them first"
            )));
        }
        let prepared = bank
            .terms
            .iter()
            .map(|t| PreparedDecomposition::from_terms(t, BANK_SAMPLING))
            .collect::<Result<Vec<_>, _>>()?;
        let hs = opts.hessian_sigma();
        let (w, h) = (image.width(), image.height());
        let stack = Self::stack_plan((w, h, image.channels()), opts, &bank, hbank).build(image)?;
        let field = {
            let [hxx, hxy, hyy] = hbank.bind(&stack)?.planes(hs)?;
            let mut t: [Vec<f32>; 3] = [vec![0.0; w * h], vec![0.0; w * h], vec![0.0; w * h]];
            for i in 0..w * h {
                let ti = tensor([f64::from(hxx[i]), f64::from(hxy[i]), f64::from(hyy[i])]);
                for k in 0..3 {
                    t[k][i] = ti[k] as f32;
                }
            }
            let rho = opts.tensor_sigma();
            let t = t.map(|p| gaussian_blur(&p, w, h, rho));
            (0..w * h)
                .into_par_iter()
                .map(|i| {
                    Orientation::from_tensor(
                        [f64::from(t[0][i]), f64::from(t[1][i]), f64::from(t[2][i])],
                        hs,
                        &opts.aniso,
                    )
                })
                .collect()
        };
        let direct = opts.evaluated_directly().then(|| {
            (
                DirectKernels::new(opts.scale, opts.aniso.max_aspect),
                image.to_image(),
            )
        });
        Ok(Self {
            stack,
            direct,
            bank,
            prepared,
            opts: *opts,
            field,
            width: w,
            height: h,
            channels: image.channels(),
            grid_origin: (0, 0),
        })
    }

    /// Declares the smoother's image a tile of a larger image, with its
    /// pixel (0, 0) at `(x0, y0)` there: whole-image [`Mode::Dab`]
    /// smoothing then places its dab grid as it would on the larger image
    /// ([`crate::smooth_tiled`]). Nothing else depends on the position.
    #[must_use]
    pub fn with_grid_origin(mut self, (x0, y0): (usize, usize)) -> Self {
        self.grid_origin = (x0, y0);
        self
    }

    /// The four dab-grid centres around pixel `(x, y)` of the smoother's
    /// image and their bilinear weights ([`dab_grid_corners`] on the
    /// grid anchored at [`Smoother::with_grid_origin`]), in the smoother's
    /// coordinates (centres past its edges are clamped by
    /// [`Smoother::orientation_at`]).
    #[must_use]
    pub fn dab_corners(&self, x: f32, y: f32) -> [((f32, f32), f32); 4] {
        anchored_dab_grid_corners(x, y, self.dab_grid_spacing(), self.grid_origin)
    }

    /// Where the smoother's pixel (0, 0) lies in the image it is a tile of
    /// ([`Smoother::with_grid_origin`]; `(0, 0)` for a whole image).
    #[must_use]
    pub fn grid_origin(&self) -> (usize, usize) {
        self.grid_origin
    }

    /// The options in use.
    #[must_use]
    pub fn options(&self) -> &SmoothOptions {
        &self.opts
    }

    /// The aspect-ratio bank.
    #[must_use]
    pub fn bank(&self) -> &AspectBank {
        &self.bank
    }

    /// The bank's entries, checked when the smoother was built, as they are
    /// applied (`Sampling::Averaged`).
    #[must_use]
    pub fn prepared_bank(&self) -> &[PreparedDecomposition] {
        &self.prepared
    }

    /// The prefiltered stack.
    #[must_use]
    pub fn stack(&self) -> &ScaleStack {
        &self.stack
    }

    /// The per-pixel filter orientations (row-major).
    #[must_use]
    pub fn orientation_field(&self) -> &[Orientation] {
        &self.field
    }

    /// The standard deviations `(sx, sy)` of the Gaussian of filter `o`:
    /// `sx = S sqrt(a)` along `o.theta`, `sy = S / sqrt(a)` across.
    #[must_use]
    pub fn footprint(&self, o: Orientation) -> (f64, f64) {
        let a = f64::from(o.aspect).sqrt();
        (self.opts.scale * a, self.opts.scale / a)
    }

    /// The tabulated kernels when the footprint is below [`DIRECT_BELOW`](crate::DIRECT_BELOW)
    /// and the smoothing filters are evaluated directly (the GPU path
    /// supports only the stack-based filters).
    #[must_use]
    pub fn direct_kernels(&self) -> Option<&DirectKernels> {
        self.direct.as_ref().map(|(k, _)| k)
    }

    /// The filter at pixel `(x, y)` (clamped into the image).
    #[must_use]
    pub fn orientation_at(&self, x: f32, y: f32) -> Orientation {
        self.field[nearest_pixel(x, y, self.width, self.height)]
    }

    /// Spacing of the dab grid of whole-image [`Mode::Dab`] smoothing:
    /// `max(2 S, 4)` pixels.
    #[must_use]
    pub fn dab_grid_spacing(&self) -> f32 {
        self.opts.dab_grid_spacing()
    }

    fn filters(&self) -> Result<Vec<Filter<'_>>, SmoothError> {
        if self.direct.is_some() {
            return Ok(Vec::new());
        }
        self.prepared
            .iter()
            .map(|d| Filter::new(&self.stack, d).map_err(SmoothError::from))
            .collect()
    }

    /// The bank bound to the stack at the footprint scale (stack levels
    /// resolved once, so each lookup is `s` bilinear samples), or the
    /// direct tables below [`DIRECT_BELOW`](crate::DIRECT_BELOW): the
    /// per-pixel Gaussians shared with the sigma map ([`PixelGaussians`]).
    fn gaussians<'f>(
        &'f self,
        filters: &'f [Filter<'f>],
    ) -> Result<PixelGaussians<'f, 'f>, SmoothError> {
        let s = self.filter_scale();
        let lookups = if self.direct.is_some() {
            None
        } else {
            Some(BankLookups::Fixed(
                filters
                    .iter()
                    .map(|f| f.at_scale(s).map_err(SmoothError::from))
                    .collect::<Result<Vec<_>, _>>()?,
            ))
        };
        let small = self
            .direct
            .as_ref()
            .map(|(kernels, image)| SmallFootprints::Tables { kernels, image });
        Ok(PixelGaussians::new(
            &self.bank,
            lookups,
            small,
            self.opts.border,
        ))
    }

    fn filter_scale(&self) -> f32 {
        (self.opts.scale / self.bank.options.sigma_ref) as f32
    }

    /// Adds `weight *` the smoothed value at `(x, y)` for filter `o` to
    /// `out` ([`PixelGaussians::accumulate`] at the footprint scale; pixel
    /// centres when the filters are evaluated directly: whole images and
    /// dabs evaluate at pixels).
    fn add_smoothed(
        &self,
        gauss: &PixelGaussians<'_, '_>,
        x: f32,
        y: f32,
        o: Orientation,
        weight: f32,
        out: &mut [f32],
    ) {
        let g = AnisoGaussian {
            theta: o.theta,
            aspect: o.aspect,
            footprint: self.opts.scale as f32,
        };
        gauss.accumulate(x, y, g, weight, out);
    }

    /// Smooths the whole image.
    ///
    /// # Errors
    /// Filtering errors (should not happen for a valid smoother).
    pub fn smooth_image(&self, mode: Mode) -> Result<Image, SmoothError> {
        self.smooth_rect(
            mode,
            DabRegion {
                x0: 0,
                y0: 0,
                width: self.width,
                height: self.height,
            },
        )
    }

    /// Smooths the pixels of `rect` (the rest of the image only feeds
    /// them): the rectangle of [`Smoother::smooth_image`]'s result, computed
    /// alone (how [`crate::smooth_tiled`] smooths a tile read with its halo).
    ///
    /// # Errors
    /// [`SmoothError::BadImage`] for a rectangle outside the image, and
    /// filtering errors (should not happen for a valid smoother).
    pub fn smooth_rect(&self, mode: Mode, rect: DabRegion) -> Result<Image, SmoothError> {
        let (w, h, c) = (self.width, self.height, self.channels);
        if rect.width == 0
            || rect.height == 0
            || rect.x0 + rect.width > w
            || rect.y0 + rect.height > h
        {
            return Err(SmoothError::BadImage(format!(
                "rectangle {}x{} at ({}, {}) is empty or outside the {w}x{h} image",
                rect.width, rect.height, rect.x0, rect.y0
            )));
        }
        let filters = self.filters()?;
        // Whole images and tiles as weighted passes over the smoother's
        // image; a small rectangle pixel by pixel (the passes' buffers and
        // scans are the whole image's).
        if self.direct.is_none() && rect.width * rect.height * SMALL_RECT >= w * h {
            return self.smooth_by_passes(mode, &filters, rect);
        }
        let gauss = self.gaussians(&filters)?;
        let mut out = vec![0.0f32; rect.width * rect.height * c];
        out.par_chunks_mut(rect.width * c)
            .enumerate()
            .for_each(|(j, row)| {
                let y = rect.y0 + j;
                for (i, px) in row.chunks_exact_mut(c).enumerate() {
                    let x = rect.x0 + i;
                    match mode {
                        Mode::PerPixel => {
                            let o = self.field[y * w + x];
                            self.add_smoothed(&gauss, x as f32, y as f32, o, 1.0, px);
                        }
                        // Dab centres on a grid of spacing g; each pixel
                        // blends the results of the filters of its four
                        // surrounding centres.
                        Mode::Dab => {
                            let (x, y) = (x as f32, y as f32);
                            for ((cx, cy), wgt) in self.dab_corners(x, y) {
                                if wgt == 0.0 {
                                    continue;
                                }
                                let o = self.orientation_at(cx, cy);
                                self.add_smoothed(&gauss, x, y, o, wgt, px);
                            }
                        }
                    }
                }
            });
        Ok(Image::from_vec(rect.width, rect.height, c, out)?)
    }

    /// `rect` smoothed in `mode` from the stack, as the bank's whole-image
    /// weighted passes ([`bank_passes`]: the vector rows, where the
    /// per-point loop takes one pixel at a time), then the rectangle cut
    /// out. [`Mode::PerPixel`]: each pixel's Gaussian of its orientation.
    /// [`Mode::Dab`]: for each of the four dab-grid corners in turn, every
    /// pixel's Gaussian of that corner's orientation, weighted by the
    /// corner's bilinear weight. The per-point loop's sums bit for bit (one
    /// to four channels; tested): each pixel adds the same `weight * wi *`
    /// sums in the same order.
    fn smooth_by_passes(
        &self,
        mode: Mode,
        filters: &[Filter<'_>],
        rect: DabRegion,
    ) -> Result<Image, SmoothError> {
        let (w, h, c) = (self.width, self.height, self.channels);
        let inside = |i: usize| {
            let (x, y) = (i % w, i / w);
            (rect.x0..rect.x0 + rect.width).contains(&x)
                && (rect.y0..rect.y0 + rect.height).contains(&y)
        };
        let mut out = Image::new(w, h, c)?;
        let scale = Field::Constant(self.filter_scale());
        let corners = match mode {
            Mode::PerPixel => 1,
            Mode::Dab => 4,
        };
        let (mut angle, mut shares) = (vec![0.0f32; w * h], vec![NO_SHARES; w * h]);
        for k in 0..corners {
            (&mut angle, &mut shares)
                .into_par_iter()
                .enumerate()
                .for_each(|(i, (a, sh))| {
                    let (o, weight) = match mode {
                        Mode::PerPixel => (self.field[i], 1.0),
                        Mode::Dab => {
                            let (x, y) = ((i % w) as f32, (i / w) as f32);
                            let ((cx, cy), weight) = self.dab_corners(x, y)[k];
                            (self.orientation_at(cx, cy), weight)
                        }
                    };
                    *a = o.theta;
                    *sh = NO_SHARES;
                    if inside(i) && weight != 0.0 {
                        *sh = shares_of(&self.bank, o.aspect).map(|(e, wi)| (e, weight * wi));
                    }
                });
            bank_passes(filters, &angle, scale, &shares, &mut out)?;
        }
        Ok(if (rect.width, rect.height) == (w, h) {
            out
        } else {
            out.crop(rect.x0, rect.y0, rect.width, rect.height)
        })
    }

    /// Applies one dab to `target` (an image of the smoother's size, usually
    /// the image being edited): inside the dab each pixel moves towards the
    /// smoothed value by the dab's weight. In [`Mode::Dab`] one filter, from
    /// the orientation at the dab's centre, serves every pixel; in
    /// [`Mode::PerPixel`] each pixel uses its own. Returns the touched region
    /// (`None` when the dab misses the image).
    ///
    /// # Errors
    /// [`SmoothError::OutOfRange`] for bad dab parameters,
    /// [`SmoothError::BadImage`] when `target` has another shape.
    pub fn apply_dab(
        &self,
        dab: &Dab,
        mode: Mode,
        target: &mut Image,
    ) -> Result<Option<DabRegion>, SmoothError> {
        dab.validate()?;
        let (w, h, c) = (self.width, self.height, self.channels);
        if (target.width(), target.height(), target.channels()) != (w, h, c) {
            return Err(SmoothError::BadImage(format!(
                "target is {}x{}x{}, the smoother's image {w}x{h}x{c}",
                target.width(),
                target.height(),
                target.channels()
            )));
        }
        let Some(bbox) = dab.region(w, h)? else {
            return Ok(None);
        };
        let (x0, y0) = (bbox.x0, bbox.y0);
        let (x1, y1) = (x0 + bbox.width - 1, y0 + bbox.height - 1);
        let filters = self.filters()?;
        let gauss = self.gaussians(&filters)?;
        let rh = y1 - y0 + 1;
        let rw = x1 - x0 + 1;
        // Paper's mode: one constant filter (the blend of two bank entries at
        // the centre's orientation) over the dab's bounding box, evaluated as
        // vectorised 2x2 stencils per tap; per pixel: `s` lookups per pixel.
        let constant = match mode {
            Mode::Dab if self.direct.is_some() => {
                let o = self.orientation_at(dab.x, dab.y);
                let mut region = vec![0.0f32; rw * rh * c];
                region
                    .par_chunks_mut(rw * c)
                    .enumerate()
                    .for_each(|(j, row)| {
                        for (i, px) in row.chunks_exact_mut(c).enumerate() {
                            let (x, y) = ((x0 + i) as f32, (y0 + j) as f32);
                            self.add_smoothed(&gauss, x, y, o, 1.0, px);
                        }
                    });
                Some(region)
            }
            Mode::Dab => {
                let o = self.orientation_at(dab.x, dab.y);
                let mut taps = Taps::default();
                let scaled = gauss.fixed().unwrap_or_default();
                for (i, wi) in gauss.blend(o.aspect) {
                    taps.extend(scaled[i].taps(o.theta, wi));
                }
                Some(taps.apply_region(&self.stack, x0, y0, rw, rh)?)
            }
            Mode::PerPixel => None,
        };
        target
            .data_mut()
            .par_chunks_mut(w * c)
            .enumerate()
            .skip(y0)
            .take(rh)
            .for_each(|(y, row)| {
                let mut sm = vec![0.0; c];
                for x in x0..=x1 {
                    let d = ((x as f32 - dab.x).powi(2) + (y as f32 - dab.y).powi(2)).sqrt();
                    let wgt = dab.weight(d);
                    if wgt <= 0.0 {
                        continue;
                    }
                    let sm: &[f32] = if let Some(region) = &constant {
                        let o = ((y - y0) * rw + (x - x0)) * c;
                        &region[o..o + c]
                    } else {
                        sm.fill(0.0);
                        let o = self.field[y * w + x];
                        self.add_smoothed(&gauss, x as f32, y as f32, o, 1.0, &mut sm);
                        &sm
                    };
                    for (p, s) in row[x * c..(x + 1) * c].iter_mut().zip(sm) {
                        *p += wgt * (s - *p);
                    }
                }
            });
        Ok(Some(DabRegion {
            x0,
            y0,
            width: rw,
            height: rh,
        }))
    }
}

/// [`Smoother::smooth_rect`] takes the per-point loop for rectangles under
/// `1 / SMALL_RECT` of the image.
const SMALL_RECT: usize = 16;

/// The stack options of a [`Smoother`] for a `width x height x channels`
/// image at footprint scale `scale`, with stack sigmas `[sigma_lo,
/// sigma_hi]`: Hessian-grade levels ([`hessian_stack_options`]) plus a stored
/// margin covering the reach of the bank's filters at that scale, as far as
/// memory allows ([`ifd_planar::StackLayout::affordable_margin`]). Without
/// it, dabs whose filters reach past the image border take the slow
/// border-resolving lookup for every tap (an 8:1 dab of radius 64 px, 72 px
/// from the border, measured 20x slower than one in the middle).
#[must_use]
pub fn smoother_stack_options(
    bank: &AspectBank,
    scale: f64,
    (width, height, channels): (usize, usize, usize),
    (sigma_lo, sigma_hi): (f64, f64),
) -> ifd_planar::StackOptions {
    let reach = bank.reach() * scale / bank.options.sigma_ref;
    let need = reach.ceil() as usize + 2;
    let options = hessian_stack_options();
    // An invalid layout fails later, in `ScaleStack::new`, with its error.
    let margin = ifd_planar::StackLayout::affordable_margin(
        width, height, channels, sigma_lo, sigma_hi, options, need,
    )
    .unwrap_or(options.margin);
    ifd_planar::StackOptions { margin, ..options }
}
