//! `ifd field`: synthetic per-pixel angle and scale maps.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use ifd_image::Image;

use crate::output::write_output;

/// The shape of a synthetic field.
#[derive(Debug, Clone, Copy, ValueEnum)]
enum Kind {
    /// Angle of the tangent to circles around the centre, in degrees
    /// (a filter elongated along x then follows the circles: a swirl blur).
    Swirl,
    /// Angle of the direction from the centre, in degrees (a zoom blur).
    Radial,
    /// Distance from the centre, mapped linearly from --min at the centre to --max at the corners.
    Distance,
    /// Left-to-right ramp from --min to --max.
    Ramp,
}

/// Write a synthetic per-pixel field (HxW float32 .npy) for `ifd filter
/// --angle-map/--scale-map`: swirl or radial angles, or distance/ramp scales.
#[derive(Debug, Args)]
pub struct FieldCmd {
    /// The kind of field.
    #[arg(value_enum)]
    kind: Kind,
    /// Size as WIDTHxHEIGHT, e.g. 512x512.
    #[arg(long, value_name = "WxH")]
    size: String,
    /// Smallest value (distance, ramp).
    #[arg(long, default_value_t = 1.0)]
    min: f32,
    /// Largest value (distance, ramp).
    #[arg(long, default_value_t = 2.0)]
    max: f32,
    /// Output .npy file.
    #[arg(short, long)]
    output: PathBuf,
}

/// The most values a field may have (2 GiB of float32).
const MAX_FIELD_PIXELS: usize = 1 << 29;

impl FieldCmd {
    /// Runs the command.
    pub fn run(self) -> Result<()> {
        let Some((w, h)) = self
            .size
            .split_once('x')
            .and_then(|(a, b)| Some((a.parse::<usize>().ok()?, b.parse::<usize>().ok()?)))
        else {
            bail!(
                "--size {:?}: expected WIDTHxHEIGHT such as 512x512",
                self.size
            );
        };
        if w == 0 || h == 0 || w > 65536 || h > 65536 {
            bail!("--size {w}x{h}: each side must be between 1 and 65536");
        }
        // The field is built in memory: at most 2^29 values (2 GiB of
        // float32, e.g. 20000x20000 or 23170x23170).
        if w * h > MAX_FIELD_PIXELS {
            bail!(
                "--size {w}x{h}: {} values, more than the {MAX_FIELD_PIXELS} (2 GiB of float32) \
                 a field may have",
                w * h
            );
        }
        ifd_image::MemoryBudget::default_for_machine()
            .check((w * h * 4) as u64)
            .with_context(|| format!("--size {w}x{h}"))?;
        // angles in degrees and scales are data: an image format would clip them to [0, 1]
        crate::output::check_npy_output(&self.output, "-o", "the field")?;
        if !(self.min.is_finite() && self.max.is_finite()) {
            bail!(
                "--min and --max must be finite float32 values (magnitude below 3.4e38), got \
                 --min {} --max {}",
                self.min,
                self.max
            );
        }
        if !(self.max - self.min).is_finite() {
            bail!(
                "--min {} --max {}: their difference overflows float32 (magnitude 3.4e38 or more)",
                ifd_image::short_number(f64::from(self.min)),
                ifd_image::short_number(f64::from(self.max))
            );
        }
        let (cx, cy) = ((w as f32 - 1.0) / 2.0, (h as f32 - 1.0) / 2.0);
        let rmax = (cx * cx + cy * cy).sqrt().max(1.0);
        let mut data = Vec::with_capacity(w * h);
        for y in 0..h {
            for x in 0..w {
                let (dx, dy) = (x as f32 - cx, y as f32 - cy);
                // Angles counter-clockwise on screen: y points down, so negate dy.
                let radial = (-dy).atan2(dx).to_degrees();
                let v = match self.kind {
                    Kind::Radial => radial,
                    Kind::Swirl => radial + 90.0,
                    Kind::Distance => {
                        self.min + (self.max - self.min) * (dx * dx + dy * dy).sqrt() / rmax
                    }
                    Kind::Ramp => {
                        self.min + (self.max - self.min) * x as f32 / (w.max(2) - 1) as f32
                    }
                };
                data.push(v);
            }
        }
        let img = Image::from_vec(w, h, 1, data)?;
        write_output(&self.output, &img, &ifd_image::WriteOptions::default())
    }
}
