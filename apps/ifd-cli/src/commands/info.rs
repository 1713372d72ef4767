//! `ifd info FILE`.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use serde_json::json;

use crate::input::InputOptions;
use crate::options::SUMMARY_LINES;

/// Print an image's size, channels, source format and value range per channel.
#[derive(Debug, Args)]
pub struct Info {
    /// The image.
    path: PathBuf,
    #[command(flatten)]
    report: crate::options::ReportOptions,
    #[command(flatten)]
    input: InputOptions,
}

impl Info {
    /// Runs the command.
    pub fn run(self) -> Result<()> {
        let loaded = self.input.read(&self.path)?;
        let img = &loaded.image;
        let stats: Vec<(f32, f32, f64)> = (0..img.channels())
            .map(|c| {
                let p = img.plane(c);
                let (lo, hi) = p
                    .iter()
                    .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
                        (lo.min(v), hi.max(v))
                    });
                let mean = p.iter().map(|&v| f64::from(v)).sum::<f64>() / p.len() as f64;
                (lo, hi, mean)
            })
            .collect();
        let v = json!({
            "width": img.width(),
            "height": img.height(),
            "channels": img.channels(),
            "format": loaded.format.name(),
            "integer_bits": loaded.integer_bits,
            "min": stats.iter().map(|s| s.0).collect::<Vec<_>>(),
            "max": stats.iter().map(|s| s.1).collect::<Vec<_>>(),
            "mean": stats.iter().map(|s| s.2).collect::<Vec<_>>(),
        });
        // a line per channel, or (the summary of an image with more
        // channels than fit in it) one line over all of them
        let text = |every: bool| {
            let depth = loaded
                .integer_bits
                .map_or_else(|| "float".to_string(), |b| format!("{b}-bit"));
            let mut text = format!(
                "{}: {}x{}, {} channel(s), {} {}\n",
                self.path.display(),
                img.width(),
                img.height(),
                img.channels(),
                loaded.format.name(),
                depth
            );
            if every || stats.len() < SUMMARY_LINES {
                for (c, (lo, hi, mean)) in stats.iter().enumerate() {
                    let _ = writeln!(
                        text,
                        "  channel {c}: min {lo:.6}, max {hi:.6}, mean {mean:.6}"
                    );
                }
            } else {
                let lo = stats.iter().map(|s| s.0).fold(f32::INFINITY, f32::min);
                let hi = stats.iter().map(|s| s.1).fold(f32::NEG_INFINITY, f32::max);
                let mean = stats.iter().map(|s| s.2).sum::<f64>() / stats.len() as f64;
                let _ = writeln!(
                    text,
                    "  all channels: min {lo:.6}, max {hi:.6}, mean {mean:.6} (-v lists each)"
                );
            }
            text
        };
        self.report.emit_detailed(&v, || text(false), || text(true))
    }
}
