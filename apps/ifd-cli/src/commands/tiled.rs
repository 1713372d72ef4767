//! `ifd filter` tile by tile (`ifd_planar::filter_tiled`), streaming `.npy` input,
//! maps and output ([`ifd_image::NpyReader`], [`ifd_image::NpyWriter`]):
//! images far larger than memory in about one tile's memory.

use std::path::Path;

use anyhow::{Context, Result, bail};
use ifd_image::{FileFormat, NpyReader, NpyWriter};
use ifd_planar::FilterOptions;
use ifd_planar::{Decomposition, FieldKind};
use ifd_planar::{TileGrid, TiledField, filter_tiled};

/// The formats that stream, for messages.
pub const STREAMING: &str = ".npy (C order; numpy.save writes it)";

/// What a tiled run reads and writes.
pub struct TiledRun<'a> {
    pub image: &'a Path,
    pub decomposition: &'a Decomposition,
    pub angle: Result<f32, &'a Path>,
    pub scale: Result<f32, &'a Path>,
    pub output: &'a Path,
    pub options: FilterOptions,
    /// `--tile`, else chosen from the budget.
    pub tile: Option<usize>,
    pub budget: u64,
    pub replace_non_finite: Option<f32>,
    pub verbose: bool,
}

/// Whether `path` streams.
pub fn streams(path: &Path) -> bool {
    FileFormat::from_path(path).is_ok_and(|f| f == FileFormat::Npy)
}

fn open_map(path: &Path, what: &str, w: usize, h: usize) -> Result<NpyReader> {
    if !streams(path) {
        bail!(
            "{what} {}: tiled filtering reads maps as {STREAMING} only",
            path.display()
        );
    }
    let r = NpyReader::open(path, None)?;
    if r.channels() != 1 || (r.width(), r.height()) != (w, h) {
        bail!(
            "{what} {} is {}x{}x{}, expected {w}x{h}x1 (the image's size)",
            path.display(),
            r.width(),
            r.height(),
            r.channels()
        );
    }
    Ok(r)
}

/// The range of a scale map, read in bands of rows (the map may be larger
/// than memory too); every value checked by the rule every scale field
/// follows ([`FieldKind::why_invalid`]), naming the pixel.
fn map_range(r: &mut NpyReader) -> Result<(f32, f32)> {
    let (w, h) = (r.width(), r.height());
    let band = (1 << 22) / w.max(1) + 1;
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for y0 in (0..h).step_by(band) {
        let rows = band.min(h - y0);
        let m = r.read_region(0, y0, w, rows)?;
        for (i, &v) in m.data().iter().enumerate() {
            if let Some(why) = FieldKind::Scale.why_invalid(v) {
                bail!(
                    "scale map {}: value {v} at x={}, y={}: {why}",
                    r.path().display(),
                    i % w,
                    y0 + i / w
                );
            }
            lo = lo.min(v);
            hi = hi.max(v);
        }
    }
    Ok((lo, hi))
}

/// The tiles of a run: `forced` (`--tile`) as given, else the largest tile
/// side, from 4096 px down by halves, whose work (`bytes`) fits half the
/// budget (the rest: buffers, the reader's rows, the allocator's slack);
/// refused, naming the sizes, when even the smallest tile exceeds the budget.
pub fn choose_tiles<T, E>(
    forced: Option<usize>,
    budget: u64,
    plan: impl Fn(usize) -> Result<T, E>,
    tiling: impl Fn(&T) -> ifd_planar::Tiling,
    bytes: impl Fn(&T) -> Result<u64>,
) -> Result<T>
where
    E: std::error::Error + Send + Sync + 'static,
{
    if let Some(n) = forced {
        return Ok(plan(n)?);
    }
    let mut n = 4096;
    loop {
        let t = plan(n)?;
        let b = bytes(&t)?;
        let g = tiling(&t);
        if b <= budget / 2 || n <= g.align.max(2 * g.halo) {
            if b > budget {
                bail!(
                    "even the smallest tile ({}x{} px with a halo of {} px) needs {}, \
                     more than the memory budget of {}",
                    g.tile,
                    g.tile,
                    g.halo,
                    ifd_image::fmt_bytes(b),
                    ifd_image::fmt_bytes(budget)
                );
            }
            return Ok(t);
        }
        n /= 2;
    }
}

/// Runs the tiled filter.
pub fn run(t: &TiledRun<'_>) -> Result<()> {
    if !streams(t.image) {
        bail!(
            "{}: tiled filtering streams {STREAMING} only; convert the image first \
             (ifd convert IMAGE IMAGE.npy streams nothing: use numpy or another tool for \
             images larger than memory)",
            t.image.display()
        );
    }
    if !streams(t.output) {
        bail!(
            "{}: tiled filtering writes {STREAMING} only",
            t.output.display()
        );
    }
    let mut reader = NpyReader::open(t.image, t.replace_non_finite)?;
    let (w, h, c) = (reader.width(), reader.height(), reader.channels());
    let mut amap = t
        .angle
        .err()
        .map(|p| open_map(p, "angle map", w, h))
        .transpose()?;
    let mut smap = t
        .scale
        .err()
        .map(|p| open_map(p, "scale map", w, h))
        .transpose()?;
    // (a constant when there is no map)
    let scale_range = if let Some(r) = &mut smap {
        map_range(r)?
    } else {
        let s = t.scale.unwrap_or(1.0);
        (s, s)
    };
    let angle_varies = amap.is_some();
    let grid_for = |tile: usize| {
        TileGrid::new(
            t.decomposition,
            (w, h, c),
            angle_varies,
            scale_range,
            &t.options,
            tile,
        )
    };
    let grid = choose_tiles(
        t.tile,
        t.budget,
        grid_for,
        |g| g.tiling,
        |g| Ok(g.tile_bytes(t.decomposition)?),
    )?;
    let tiles = grid.tiles().len();
    if t.verbose {
        eprintln!(
            "tiled: {tiles} tiles of {} px, halo {} px, aligned to {} px, scales {:?}",
            grid.tiling.tile, grid.tiling.halo, grid.tiling.align, scale_range
        );
    }
    let mut writer = NpyWriter::create(t.output, w, h, c)?;
    let bar = crate::progress::bar("filtering tiles", "", tiles as u64);
    let angle = match &mut amap {
        Some(m) => TiledField::Map(m),
        None => TiledField::Constant(t.angle.unwrap_or(0.0)),
    };
    let scale = match &mut smap {
        Some(m) => TiledField::Map(m),
        None => TiledField::Constant(t.scale.unwrap_or(1.0)),
    };
    filter_tiled(
        t.decomposition,
        &grid,
        &mut reader,
        angle,
        scale,
        &mut writer,
        |done, _| bar.set_position(done as u64),
    )
    .context("filtering tile by tile")?;
    bar.finish_and_clear();
    writer.finish()?;
    Ok(())
}
