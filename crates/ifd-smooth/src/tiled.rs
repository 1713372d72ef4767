//! Smoothing an image far larger than memory, tile by tile, with the result
//! of smoothing it whole.
//!
//! The derivation and conventions are documented on [`smooth_tiled`].

use std::sync::Arc;

use ifd_image::Image;
use ifd_planar::{PixelRect, StackLayout};
use ifd_planar::{RegionReader, Tiling};

use crate::bank::AspectBank;
use crate::direct::DirectKernels;
use crate::error::SmoothError;
use crate::gaussians::Shares;
use crate::hessian::HessianBank;
use crate::orientation::Orientation;
use crate::smooth::{Mode, SmoothOptions, Smoother};

/// Level sigmas of reach a stack lookup needs around its position (see the
/// module documentation, item 1).
const LEVEL_REACH: f64 = 7.0;

/// How far, in pixels, an output pixel of the smoother with `opts` in `mode`
/// reads from its position (the module documentation derives it).
///
/// # Errors
/// Out-of-range options ([`SmoothOptions::validate`]).
pub fn smooth_halo(
    opts: &SmoothOptions,
    mode: Mode,
    bank: &AspectBank,
    hbank: &HessianBank,
) -> Result<usize, SmoothError> {
    opts.validate()?;
    let s_h = opts.hessian_sigma() / hbank.sigma0;
    let hessian_reach = hbank
        .xx
        .terms
        .iter()
        .chain(&hbank.xy.terms)
        .map(|t| t.x.hypot(t.y))
        .fold(0.0, f64::max);
    let hessian = s_h * hessian_reach + LEVEL_REACH * Smoother::hessian_sigmas(opts, hbank).1;
    let blur = crate::smooth::blur_radius(opts.tensor_sigma()) as f64;
    let grid = match mode {
        Mode::Dab => f64::from(opts.dab_grid_spacing()).ceil() + 1.0,
        Mode::PerPixel => 0.0,
    };
    let orientation = hessian + blur + grid;
    let smoothing = match Smoother::smoothing_sigmas(opts, bank) {
        Some((_, hi)) => {
            let s_b = opts.scale / bank.options.sigma_ref;
            s_b * bank.reach() + LEVEL_REACH * hi
        }
        None => DirectKernels::new(opts.scale, opts.aniso.max_aspect).reach() as f64,
    };
    Ok(orientation.max(smoothing).ceil() as usize + 2)
}

/// The stack's coarsest subsampling step: tile origins are multiples of it.
fn alignment(
    channels: usize,
    opts: &SmoothOptions,
    bank: &AspectBank,
    hbank: &HessianBank,
) -> Result<usize, SmoothError> {
    // Steps depend on the sigmas only, not on the image's size.
    let layout = Smoother::stack_layout((64, 64, channels), opts, bank, hbank)?;
    Ok(layout.levels().iter().map(|l| l.step).max().unwrap_or(1))
}

/// Bytes the smoother of a `(width, height, channels)` image needs at most:
/// its stack and the build's transient FFT buffers, the image (twice below
/// [`crate::DIRECT_BELOW`]), the orientation field, an image-sized
/// result, the larger of the Hessian and tensor planes while the field is
/// built and the smoothing passes' per-pixel angle, weight and bank shares,
/// and a result of `out_pixels`.
///
/// # Errors
/// As [`Smoother::stack_layout`].
pub fn smoother_bytes(
    dims: (usize, usize, usize),
    opts: &SmoothOptions,
    bank: &AspectBank,
    hbank: &HessianBank,
    out_pixels: usize,
) -> Result<u64, SmoothError> {
    let (w, h, c) = dims;
    let layout: StackLayout = Smoother::stack_layout(dims, opts, bank, hbank)?;
    let (fw, fh) = layout.fft_size();
    let px = (w * h) as u64;
    let images = if opts.evaluated_directly() { 2 } else { 1 };
    // ten float planes for the Hessian and tensor; the passes' buffers
    let transient = (4 * 10).max(4 * 2 + std::mem::size_of::<Shares>()) as u64;
    let per_pixel =
        4 * (images * c as u64 + c as u64) + transient + std::mem::size_of::<Orientation>() as u64;
    Ok(layout.bytes() + 24 * (fw * fh) as u64 + px * per_pixel + (out_pixels * c) as u64 * 4)
}

/// The tiles of a smoothing run: a [`Tiling`] whose halo is
/// [`smooth_halo`], aligned to the stack's coarsest step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SmoothTiles {
    /// Tile geometry.
    pub tiling: Tiling,
}

impl SmoothTiles {
    /// Plans tiles of about `tile` pixels for a `(width, height, channels)`
    /// image smoothed with `opts` in `mode`.
    ///
    /// # Errors
    /// Out-of-range options, a zero `tile`.
    pub fn new(
        dims: (usize, usize, usize),
        opts: &SmoothOptions,
        mode: Mode,
        bank: &AspectBank,
        hbank: &HessianBank,
        tile: usize,
    ) -> Result<Self, SmoothError> {
        let halo = smooth_halo(opts, mode, bank, hbank)?;
        let align = alignment(dims.2, opts, bank, hbank)?;
        Ok(Self {
            tiling: Tiling::new(dims, tile, halo, align)?,
        })
    }

    /// Bytes one tile needs at most ([`smoother_bytes`] of the largest read).
    ///
    /// # Errors
    /// As [`Smoother::stack_layout`].
    pub fn tile_bytes(
        &self,
        opts: &SmoothOptions,
        bank: &AspectBank,
        hbank: &HessianBank,
    ) -> Result<u64, SmoothError> {
        let (w, h) = self.tiling.largest_read();
        let inner = (2 * self.tiling.tile).min(w) * (2 * self.tiling.tile).min(h);
        smoother_bytes((w, h, self.tiling.channels), opts, bank, hbank, inner)
    }
}

/// One tile of a [`smooth_tiled`] run.
pub struct Tile<'a> {
    /// The output pixels, in the whole image's coordinates.
    pub inner: PixelRect,
    /// The pixels read (the tile and its halo, clipped to the image).
    pub read: PixelRect,
    /// The samples of `read`.
    pub image: &'a Image,
    /// The smoother of `image`, its dab grid anchored as the whole image's.
    pub smoother: &'a Smoother,
}

impl Tile<'_> {
    /// `inner` in the coordinates of the tile read (`image`, `smoother`).
    #[must_use]
    pub fn local_inner(&self) -> PixelRect {
        PixelRect {
            x0: self.inner.x0 - self.read.x0,
            y0: self.inner.y0 - self.read.y0,
            ..self.inner
        }
    }

    /// The smoothed output pixels ([`Smoother::smooth_rect`] of
    /// [`Tile::local_inner`]).
    ///
    /// # Errors
    /// As [`Smoother::smooth_rect`].
    pub fn smooth(&self, mode: Mode) -> Result<Image, SmoothError> {
        self.smoother.smooth_rect(mode, self.local_inner())
    }

    /// The input samples of the output pixels.
    #[must_use]
    pub fn input(&self) -> Image {
        let r = self.local_inner();
        self.image.crop(r.x0, r.y0, r.width, r.height)
    }

    /// The orientation field over the output pixels, row-major.
    #[must_use]
    pub fn orientations(&self) -> Vec<Orientation> {
        let r = self.local_inner();
        let w = self.read.width;
        let field = self.smoother.orientation_field();
        (r.y0..r.y0 + r.height)
            .flat_map(|y| field[y * w + r.x0..y * w + r.x0 + r.width].iter().copied())
            .collect()
    }
}

/// Smooths an image read by region, tile by tile ([`Tiling::tiles`]): for
/// each tile, reads it with its halo, builds its [`Smoother`] (the banks
/// shared), and hands it to `each`, which smooths ([`Tile::smooth`]) and
/// stores the result; `progress(done, total)` after each tile. The results
/// equal [`Smoother::smooth_image`] of the whole image to float rounding
/// (tested to 1e-5).
///
/// `each` may fail with any error a [`SmoothError`] converts into (the
/// caller's writer's or device's errors, for example).
///
/// # Errors
/// The reader's errors, a reader that returns another size, the errors of
/// building a tile's smoother (NaN pixels name the tile), and `each`'s.
///
/// # What an output pixel reads
/// The smoother is a chain of local operations, so each output pixel depends
/// on a bounded neighbourhood of the input ([`smooth_halo`]):
///
/// 1. **Stack levels.** A level of sigma `sigma` at a sample is the image
///    correlated with a Gaussian of that sigma: outside `5 sigma` its
///    weights are below `4e-6` of the peak, and its total mass beyond a line
///    at `5 sigma` is `3e-7`. Levels are read with cubic B-splines whose
///    coefficients come from an infinite prefilter decaying as `0.268^n`
///    (samples of step `<= sigma / 8` here), so `7 sigma` covers both.
/// 2. **Hessian.** The derivative filters' atoms sit up to `s_h |c_t|` from
///    the pixel (`s_h = hessian sigma / sigma0`) and read levels up to the
///    Hessian's largest stack sigma `sigma_h`: `s_h max|c_t| + 7 sigma_h`.
/// 3. **Tensor averaging.** The tensor is blurred with a Gaussian truncated
///    at `ceil(3 rho)` pixels: exactly that much more.
/// 4. **Dab grid** ([`Mode::Dab`] only). A pixel uses the orientations of
///    the four dab centres around it, up to one grid spacing `g` away.
/// 5. **Smoothing filters.** The bank's atoms sit up to `s_b max|c_t|` from
///    the pixel and read levels up to `sigma_b`: `s_b max|c_t| + 7 sigma_b`
///    (below [`crate::DIRECT_BELOW`], the direct kernels' reach).
///
/// The halo is the larger of the orientation's chain (2 + 3 + 4) and the
/// smoothing's (5). Two more things make tiles agree with the whole image:
/// tile origins are multiples of the stack's coarsest subsampling step (levels
/// sample the same positions), and the dab grid stays anchored at the image's
/// origin ([`Smoother::with_grid_origin`]). At the image's true edges a tile
/// read stops at the edge and the border rule acts there, as for the whole
/// image.
///
/// Pixels come from a [`RegionReader`] (for example a streamed `.npy`,
/// [`ifd_image::NpyReader`]); each smoothed tile goes to a callback, so that
/// the caller can blend, write, or evaluate on another device.
///
/// ```
/// use std::sync::Arc;
/// use ifd_image::Image;
/// use ifd_planar::PixelRect;
/// use ifd_smooth::{AspectBank, BankOptions, HessianBank, Mode, SmoothOptions, Smoother};
/// use ifd_smooth::{SmoothTiles, smooth_tiled};
/// // A small bank (aspects 1, 2, 4) keeps the example quick.
/// let bank_opts = BankOptions { max_aspect: 4.0, steps_per_octave: 1, ..BankOptions::default() };
/// let opts = SmoothOptions { scale: 3.0, bank: bank_opts, ..SmoothOptions::default() };
/// let opts = SmoothOptions { aniso: ifd_smooth::AnisoParams { max_aspect: 4.0, ..opts.aniso }, ..opts };
/// let bank = Arc::new(AspectBank::build(opts.bank, |_, _| {})?);
/// let hbank = HessianBank::new(0.01)?;
/// let (w, h) = (150, 120);
/// let img = Image::from_vec(w, h, 1, (0..w * h).map(|i| ((i % w) / 10 % 2) as f32).collect())?;
/// let tiles = SmoothTiles::new((w, h, 1), &opts, Mode::Dab, &bank, &hbank, 32)?;
/// let mut out = Image::new(w, h, 1)?;
/// smooth_tiled(
///     &tiles, &opts, &bank, &hbank,
///     &mut |r: PixelRect| Ok(img.crop(r.x0, r.y0, r.width, r.height)),
///     |tile| -> Result<(), ifd_smooth::SmoothError> {
///         out.paste(tile.inner.x0, tile.inner.y0, &tile.smooth(Mode::Dab)?);
///         Ok(())
///     },
///     |_, _| {},
/// )?;
/// let whole = Smoother::with_banks(&img, &opts, bank, &hbank)?.smooth_image(Mode::Dab)?;
/// let diff = out.data().iter().zip(whole.data()).fold(0f32, |m, (a, b)| m.max((a - b).abs()));
/// assert!(diff < 1e-5, "{diff}");
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn smooth_tiled<E: From<SmoothError>>(
    tiles: &SmoothTiles,
    opts: &SmoothOptions,
    bank: &Arc<AspectBank>,
    hbank: &HessianBank,
    image: &mut dyn RegionReader,
    mut each: impl FnMut(&Tile<'_>) -> Result<(), E>,
    mut progress: impl FnMut(usize, usize),
) -> Result<(), E> {
    let list = tiles.tiling.tiles();
    for (k, &(inner, read)) in list.iter().enumerate() {
        let src = image.read(read).map_err(SmoothError::from)?;
        if (src.width(), src.height(), src.channels())
            != (read.width, read.height, tiles.tiling.channels)
        {
            return Err(E::from(SmoothError::BadImage(format!(
                "the reader gave {}x{}x{} for a {}x{}x{} region",
                src.width(),
                src.height(),
                src.channels(),
                read.width,
                read.height,
                tiles.tiling.channels
            ))));
        }
        let smoother = Smoother::with_banks(&src, opts, bank.clone(), hbank)
            .map_err(|e| match e {
                SmoothError::BadImage(why) => SmoothError::BadImage(format!(
                    "the {}x{} region at ({}, {}): {why}",
                    read.width, read.height, read.x0, read.y0
                )),
                e => e,
            })
            .map_err(E::from)?
            .with_grid_origin((read.x0, read.y0));
        each(&Tile {
            inner,
            read,
            image: &src,
            smoother: &smoother,
        })?;
        progress(k + 1, list.len());
    }
    Ok(())
}
