//! `ifd filter` tile by tile (`ifd_planar::tiled`), streaming `.npy` input,
//! maps and output ([`ifd_image::NpyReader`], [`ifd_image::NpyWriter`]):
//! images far larger than memory in about one tile's memory.

use std::path::Path;

use anyhow::{Context, Result, bail};
use ifd_image::{FileFormat, NpyReader, NpyWriter};
use ifd_planar::pipeline::FilterOptions;
use ifd_planar::tiled::{TileGrid, TiledField, filter_tiled};
use ifd_planar::{Decomposition, FilterError, PixelRect};
use indicatif::{ProgressBar, ProgressStyle};

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

#[expect(clippy::needless_pass_by_value, reason = "used as map_err(io)")]
fn io(e: ifd_image::ImageError) -> FilterError {
    FilterError::Io(e.to_string())
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
/// than memory too); every value checked.
fn map_range(r: &mut NpyReader, path: &Path) -> Result<(f32, f32)> {
    let (w, h) = (r.width(), r.height());
    let band = (1 << 22) / w.max(1) + 1;
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for y0 in (0..h).step_by(band) {
        let rows = band.min(h - y0);
        let m = r.read_region(0, y0, w, rows)?;
        for (i, &v) in m.data().iter().enumerate() {
            let valid = ifd_planar::field::MIN_FIELD_SCALE..=ifd_planar::field::MAX_FIELD_VALUE;
            if !valid.contains(&v) {
                bail!(
                    "scale map {}: value {v} at x={}, y={} is not a valid scale (finite, in \
                     [{}, {}])",
                    path.display(),
                    i % w,
                    y0 + i / w,
                    ifd_planar::field::MIN_FIELD_SCALE,
                    ifd_planar::field::MAX_FIELD_VALUE
                );
            }
            lo = lo.min(v);
            hi = hi.max(v);
        }
    }
    Ok((lo, hi))
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
    let mut amap = match t.angle {
        Err(p) => Some(open_map(p, "angle map", w, h)?),
        Ok(_) => None,
    };
    let mut smap = match t.scale {
        Err(p) => Some(open_map(p, "scale map", w, h)?),
        Ok(_) => None,
    };
    let scale_range = match (&mut smap, t.scale) {
        (Some(r), Err(p)) => map_range(r, p)?,
        (_, Ok(s)) => (s, s),
        (None, Err(_)) => unreachable!("a scale map path opens a reader"),
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
    // The largest tile whose work fits half the budget (the rest: buffers,
    // the reader's rows, the allocator's slack), from 4096 px down.
    let grid = if let Some(n) = t.tile {
        grid_for(n)?
    } else {
        let mut n = 4096;
        loop {
            let g = grid_for(n)?;
            let bytes = g.tile_bytes(t.decomposition, angle_varies, &t.options)?;
            if bytes <= t.budget / 2 || n <= g.align.max(2 * g.halo) {
                if bytes > t.budget {
                    bail!(
                        "even the smallest tile ({}x{} px with a halo of {} px) needs {}, \
                         more than the memory budget of {}",
                        g.tile,
                        g.tile,
                        g.halo,
                        ifd_image::fmt_bytes(bytes),
                        ifd_image::fmt_bytes(t.budget)
                    );
                }
                break g;
            }
            n /= 2;
        }
    };
    let tiles = grid.tiles().len();
    if t.verbose {
        eprintln!(
            "tiled: {tiles} tiles of {} px, halo {} px, aligned to {} px, scales {:?}",
            grid.tile, grid.halo, grid.align, scale_range
        );
    }
    let mut writer = NpyWriter::create(t.output, w, h, c)?;
    let bar = ProgressBar::new(tiles as u64);
    bar.set_style(
        ProgressStyle::with_template("filtering tiles {bar:30} {pos}/{len} [{elapsed} < {eta}]")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let mut read_image = |r: PixelRect| {
        reader
            .read_region(r.x0, r.y0, r.width, r.height)
            .map_err(io)
    };
    let mut read_amap = |r: PixelRect| match &mut amap {
        Some(m) => m.read_region(r.x0, r.y0, r.width, r.height).map_err(io),
        None => Err(FilterError::Io("no angle map".into())),
    };
    let mut read_smap = |r: PixelRect| match &mut smap {
        Some(m) => m.read_region(r.x0, r.y0, r.width, r.height).map_err(io),
        None => Err(FilterError::Io("no scale map".into())),
    };
    let angle = match t.angle {
        Ok(a) => TiledField::Constant(a),
        Err(_) => TiledField::Map(&mut read_amap),
    };
    let scale = match t.scale {
        Ok(s) => TiledField::Constant(s),
        Err(_) => TiledField::Map(&mut read_smap),
    };
    let mut write = |x0, y0, tile: &ifd_image::Image| writer.write_region(x0, y0, tile).map_err(io);
    filter_tiled(
        t.decomposition,
        &grid,
        &t.options,
        &mut read_image,
        angle,
        scale,
        &mut write,
        |done, _| bar.set_position(done as u64),
    )
    .context("filtering tile by tile")?;
    bar.finish_and_clear();
    writer.finish()?;
    Ok(())
}
