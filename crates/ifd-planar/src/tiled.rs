//! Filtering an image far larger than memory, tile by tile, with the
//! result of filtering it whole.

use ifd_image::{Image, NpyReader, NpyWriter};

use crate::pipeline::{FilterOptions, FilterPlan, filter_image};
use crate::{CheckedField, Decomposition, Field, FieldKind, FilterError, PixelRect};
use crate::{PreparedDecomposition, field::CheckField};

/// Reads a rectangle of an image (or of a one-channel map): the samples of
/// `rect`, `rect.width x rect.height` with the source's channels.
pub trait RegionReader {
    /// The samples of `rect`.
    ///
    /// # Errors
    /// Whatever reading fails with, as a [`FilterError`].
    fn read(&mut self, rect: PixelRect) -> Result<Image, FilterError>;
}

impl<F: FnMut(PixelRect) -> Result<Image, FilterError>> RegionReader for F {
    fn read(&mut self, rect: PixelRect) -> Result<Image, FilterError> {
        self(rect)
    }
}

/// Writes a tile of the result with its top-left corner at `(x0, y0)`.
pub trait RegionWriter {
    /// Stores `tile` at `(x0, y0)`.
    ///
    /// # Errors
    /// Whatever writing fails with, as a [`FilterError`].
    fn write(&mut self, x0: usize, y0: usize, tile: &Image) -> Result<(), FilterError>;
}

impl<F: FnMut(usize, usize, &Image) -> Result<(), FilterError>> RegionWriter for F {
    fn write(&mut self, x0: usize, y0: usize, tile: &Image) -> Result<(), FilterError> {
        self(x0, y0, tile)
    }
}

impl RegionReader for NpyReader {
    fn read(&mut self, r: PixelRect) -> Result<Image, FilterError> {
        self.read_region(r.x0, r.y0, r.width, r.height)
            .map_err(|e| FilterError::Io(e.to_string()))
    }
}

impl RegionWriter for NpyWriter {
    fn write(&mut self, x0: usize, y0: usize, tile: &Image) -> Result<(), FilterError> {
        self.write_region(x0, y0, tile)
            .map_err(|e| FilterError::Io(e.to_string()))
    }
}

/// A per-pixel angle or scale for a tiled run: one value, or a map read by
/// region like the image.
pub enum TiledField<'a> {
    /// The same value everywhere.
    Constant(f32),
    /// A one-channel map of the image's size.
    Map(&'a mut dyn RegionReader),
}

/// How far, in pixels, an output pixel reads from its position at scales up
/// to `scale_max`: the farthest term centre times the scale plus 5 of the
/// widest scaled term's effective sigma (beyond, a Gaussian is below 4e-6
/// of its peak).
///
/// # Errors
/// A bad decomposition, or a scale that is not finite and positive.
pub fn halo(decomposition: &Decomposition, scale_max: f32) -> Result<usize, FilterError> {
    if !(scale_max.is_finite() && scale_max > 0.0) {
        return Err(FilterError::InvalidParameter(format!(
            "scale {scale_max} must be finite and positive"
        )));
    }
    let p = PreparedDecomposition::new(decomposition)?;
    let s = f64::from(scale_max);
    let sigma = decomposition.sampling.effective_sigma(p.sigma_range().1, s);
    Ok((s * p.reach() + 5.0 * sigma).ceil() as usize)
}

/// Output tiles of `tile x tile` pixels (the last ones in a row or column
/// larger, up to `2 tile - 1`), each read with `halo` pixels around it, tile
/// origins and halo multiples of `align`: the geometry of any tiled run
/// (filtering here, smoothing in `ifd_smooth::smooth_tiled`).
///
/// ```
/// use ifd_planar::Tiling;
/// let t = Tiling::new((100, 70, 3), 30, 7, 4)?;
/// assert_eq!((t.tile, t.halo), (32, 8));
/// let tiles = t.tiles();
/// assert_eq!(tiles.len(), 3 * 2);
/// // The last column joins the one before it; reads stop at the image.
/// assert_eq!((tiles[2].0.x0, tiles[2].0.width), (64, 36));
/// assert_eq!((tiles[2].1.x0, tiles[2].1.width), (56, 44));
/// # Ok::<(), ifd_planar::FilterError>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tiling {
    /// Image width.
    pub width: usize,
    /// Image height.
    pub height: usize,
    /// Channels.
    pub channels: usize,
    /// Output tile side, a multiple of `align`.
    pub tile: usize,
    /// Pixels read around each tile, a multiple of `align`.
    pub halo: usize,
    /// The alignment of tile origins (the stack's coarsest subsampling factor).
    pub align: usize,
}

impl Tiling {
    /// Tiles of about `tile` pixels for a `(width, height, channels)`
    /// image, read with `halo` pixels around them: the halo is rounded up to
    /// a multiple of `align`, the tile to a multiple of it and to at least
    /// twice the halo (so that a tile at the image's edge still holds the
    /// whole reach).
    ///
    /// # Errors
    /// [`FilterError::InvalidParameter`] for a zero `tile` or `align`, or
    /// sizes that overflow.
    pub fn new(
        (width, height, channels): (usize, usize, usize),
        tile: usize,
        halo: usize,
        align: usize,
    ) -> Result<Self, FilterError> {
        if tile == 0 || align == 0 {
            return Err(FilterError::InvalidParameter(format!(
                "tile size {tile} and alignment {align} must be positive"
            )));
        }
        let up = |n: usize| {
            n.checked_next_multiple_of(align)
                .ok_or_else(|| FilterError::InvalidParameter(format!("a tile of {n} px is absurd")))
        };
        let halo = up(halo)?;
        let tile = up(tile.max(halo.saturating_mul(2)).max(1))?;
        Ok(Self {
            width,
            height,
            channels,
            tile,
            halo,
            align,
        })
    }

    /// The tiles, row by row: `(output rectangle, rectangle read)`. A last
    /// row or column narrower than a tile joins the one before it, so that
    /// every tile read holds the whole reach (tiles are `tile` to
    /// `2 tile - 1` pixels wide).
    #[must_use]
    pub fn tiles(&self) -> Vec<(PixelRect, PixelRect)> {
        let spans = |n: usize| {
            let mut starts: Vec<usize> = (0..n).step_by(self.tile).collect();
            if starts.len() > 1 && n - starts[starts.len() - 1] < self.tile {
                starts.pop();
            }
            let ends: Vec<usize> = starts.iter().skip(1).copied().chain([n]).collect();
            starts.into_iter().zip(ends).collect::<Vec<_>>()
        };
        let mut out = Vec::new();
        for &(y0, y1) in &spans(self.height) {
            for &(x0, x1) in &spans(self.width) {
                let inner = PixelRect {
                    x0,
                    y0,
                    width: x1 - x0,
                    height: y1 - y0,
                };
                let rx0 = x0.saturating_sub(self.halo);
                let ry0 = y0.saturating_sub(self.halo);
                let rx1 = (x0 + inner.width + self.halo).min(self.width);
                let ry1 = (y0 + inner.height + self.halo).min(self.height);
                let read = PixelRect {
                    x0: rx0,
                    y0: ry0,
                    width: rx1 - rx0,
                    height: ry1 - ry0,
                };
                out.push((inner, read));
            }
        }
        out
    }

    /// The side of the largest rectangle a tile reads: `2 tile - 1 + 2 halo`
    /// at most, clipped to the image (for memory estimates).
    #[must_use]
    pub fn largest_read(&self) -> (usize, usize) {
        let side = 2 * self.tile + 2 * self.halo;
        (side.min(self.width), side.min(self.height))
    }
}

/// The tiles of a filtering run: a [`Tiling`] whose halo is the
/// decomposition's reach ([`halo`]), and how every tile plans.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TileGrid {
    /// Tile geometry.
    pub tiling: Tiling,
    /// The scale range every tile plans with.
    pub scale_range: (f32, f32),
    /// Whether the angle is a per-pixel map.
    pub angle_varies: bool,
    /// How every tile plans (`scale_range` set to the grid's).
    pub options: FilterOptions,
}

impl TileGrid {
    /// Plans the tiles of a `(width, height, channels)` image filtered with
    /// `decomposition` at a per-pixel (`angle_varies`) or constant angle and
    /// scales in `scale_range`, with output tiles of about `tile` pixels
    /// (rounded up to the alignment and to at least twice the halo, so that
    /// a tile at the image's edge still holds the whole kernel).
    ///
    /// # Errors
    /// As [`FilterPlan::new`] and [`halo`]; a zero `tile`.
    pub fn new(
        decomposition: &Decomposition,
        (width, height, channels): (usize, usize, usize),
        angle_varies: bool,
        scale_range: (f32, f32),
        options: &FilterOptions,
        tile: usize,
    ) -> Result<Self, FilterError> {
        if tile == 0 {
            return Err(FilterError::InvalidParameter("tile size 0".into()));
        }
        let options = FilterOptions {
            scale_range: Some(scale_range),
            ..*options
        };
        let plan = FilterPlan::for_ranges(
            (width, height, channels),
            decomposition,
            angle_varies,
            scale_range,
            &options,
        )?;
        let align = plan.alignment()?.max(1);
        let tiling = Tiling::new(
            (width, height, channels),
            tile,
            halo(decomposition, scale_range.1)?,
            align,
        )?;
        Ok(Self {
            tiling,
            scale_range,
            angle_varies,
            options,
        })
    }

    /// The tiles, row by row ([`Tiling::tiles`]).
    #[must_use]
    pub fn tiles(&self) -> Vec<(PixelRect, PixelRect)> {
        self.tiling.tiles()
    }

    /// Bytes one tile needs at most: the grown tile's samples, its stack
    /// (planned as for an image of that size), the maps and the result.
    ///
    /// # Errors
    /// As [`FilterPlan::new`].
    pub fn tile_bytes(&self, decomposition: &Decomposition) -> Result<u64, FilterError> {
        let (w, h) = self.tiling.largest_read();
        let c = self.tiling.channels;
        let plan = FilterPlan::for_ranges(
            (w, h, c),
            decomposition,
            self.angle_varies,
            self.scale_range,
            &self.options,
        )?;
        let px = (w * h) as u64;
        Ok(plan.stack.layout()?.bytes() + px * (2 * c as u64 + 2) * 4)
    }
}

/// Filters an image read by region with `decomposition`, tile by tile
/// ([`TileGrid::tiles`]), writing each output tile as it is done;
/// `progress(done, total)` after each tile. The result equals
/// [`filter_image`] of the whole image with `scale_range` set to the grid's
/// (to float rounding; tested to 1e-5 relative).
///
/// # Errors
/// The readers' and writer's errors, bad field values (as
/// [`CheckedField::new`]), and the errors of filtering a tile.
///
/// Filtering an image far larger than memory, tile by tile, with the
/// result of filtering it whole.
///
/// Every output pixel reads a bounded neighbourhood: the filter's terms reach
/// at most `s * reach` from it (`reach`: the farthest term centre), and
/// their Gaussians are below 4e-6 of their peak beyond 5 sigma. So a tile
/// of the output needs the input tile grown by a halo of
/// `ceil(s_max * reach + 5 * sigma_max(s_max))` pixels ([`halo`]). Two more
/// things make a tile's result equal the whole image's:
///
/// - the scale stack samples each level at multiples of its subsampling step
///   from the image origin, so every tile read (halo included) starts at a
///   multiple of the coarsest step ([`crate::pipeline::FilterPlan::alignment`]):
///   tile sizes and the halo are rounded up to multiples of it;
/// - every tile plans with the whole image's scale range
///   ([`crate::pipeline::FilterOptions::scale_range`]), so that all read the
///   same levels.
///
/// At the image's true edges a tile's read stops at the edge and the border
/// rule acts there, as for the whole image; inside, the halo is wide enough
/// that the tile's own border never reaches its output pixels.
///
/// Pixels come from and go to [`RegionReader`] and [`RegionWriter`]
/// (implemented by [`ifd_image::NpyReader`] and [`ifd_image::NpyWriter`],
/// which stream `.npy` files with positioned reads and writes, and by
/// closures), so peak memory is about one grown tile's stack, not the image.
///
/// ```
/// use ifd_image::Image;
/// use ifd_planar::{FilterOptions, filter_image};
/// use ifd_planar::{TileGrid, TiledField, filter_tiled};
/// use ifd_planar::{CheckField, Decomposition, Field, FieldKind, PixelRect, Term};
/// let d = Decomposition::from_terms(vec![Term { weight: 1.0, x: 3.0, y: 0.0, sigma: 2.0 }]);
/// let img = Image::from_vec(90, 70, 1, (0..90 * 70).map(|i| ((i * 7) % 31) as f32).collect())?;
/// let opts = FilterOptions::default();
/// let grid = TileGrid::new(&d, (90, 70, 1), false, (1.0, 1.0), &opts, 32)?;
/// let mut out = Image::new(90, 70, 1)?;
/// filter_tiled(
///     &d, &grid,
///     &mut |r: PixelRect| Ok(img.crop(r.x0, r.y0, r.width, r.height)),
///     TiledField::Constant(20.0), TiledField::Constant(1.0),
///     &mut |x0, y0, t: &Image| { out.paste(x0, y0, t); Ok(()) },
///     |_, _| {},
/// )?;
/// let angle = Field::Constant(20.0).check(FieldKind::Angle, 90, 70)?;
/// let scale = Field::Constant(1.0).check(FieldKind::Scale, 90, 70)?;
/// let whole = filter_image(&img, &d, angle, scale, &opts)?;
/// let diff = out.data().iter().zip(whole.data()).fold(0f32, |m, (a, b)| m.max((a - b).abs()));
/// assert!(diff < 1e-4);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn filter_tiled(
    decomposition: &Decomposition,
    grid: &TileGrid,
    image: &mut dyn RegionReader,
    mut angle: TiledField<'_>,
    mut scale: TiledField<'_>,
    output: &mut dyn RegionWriter,
    mut progress: impl FnMut(usize, usize),
) -> Result<(), FilterError> {
    let tiles = grid.tiles();
    for (k, (inner, read)) in tiles.iter().enumerate() {
        let src = image.read(*read)?;
        if (src.width(), src.height()) != (read.width, read.height) {
            return Err(FilterError::Shape(format!(
                "the reader gave {}x{} for a {}x{} region",
                src.width(),
                src.height(),
                read.width,
                read.height
            )));
        }
        let (mut amap, mut smap) = (None, None);
        let a = region_field(&mut angle, FieldKind::Angle, *read, &mut amap)?;
        let s = region_field(&mut scale, FieldKind::Scale, *read, &mut smap)?;
        let out = filter_image(&src, decomposition, a, s, &grid.options)?;
        let (ox, oy) = (inner.x0 - read.x0, inner.y0 - read.y0);
        let tile = out.crop(ox, oy, inner.width, inner.height);
        output.write(inner.x0, inner.y0, &tile)?;
        progress(k + 1, tiles.len());
    }
    Ok(())
}

/// The field of the region `rect`: the constant, or the map's samples of
/// `rect` read into `buf` (which the field borrows), checked as a `kind`.
fn region_field<'a>(
    f: &mut TiledField<'_>,
    kind: FieldKind,
    rect: PixelRect,
    buf: &'a mut Option<Image>,
) -> Result<CheckedField<'a>, FilterError> {
    match f {
        TiledField::Constant(v) => Field::Constant(*v).check(kind, rect.width, rect.height),
        TiledField::Map(r) => {
            let m = r.read(rect)?;
            if m.channels() != 1 || (m.width(), m.height()) != (rect.width, rect.height) {
                return Err(FilterError::Shape(format!(
                    "a map region is {}x{}x{}, expected {}x{}x1",
                    m.width(),
                    m.height(),
                    m.channels(),
                    rect.width,
                    rect.height
                )));
            }
            let m = buf.insert(m);
            CheckedField::new(Field::Map(m.data()), kind, rect.width, rect.height)
        }
    }
}
