//! `ifd info FILE`.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use serde_json::json;

use crate::input::InputOptions;

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
        if self.report.json {
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
            println!("{}", serde_json::to_string_pretty(&v)?);
        } else {
            let depth = loaded
                .integer_bits
                .map_or_else(|| "float".to_string(), |b| format!("{b}-bit"));
            println!(
                "{}: {}x{}, {} channel(s), {} {}",
                self.path.display(),
                img.width(),
                img.height(),
                img.channels(),
                loaded.format.name(),
                depth
            );
            for (c, (lo, hi, mean)) in stats.iter().enumerate() {
                println!("  channel {c}: min {lo:.6}, max {hi:.6}, mean {mean:.6}");
            }
        }
        Ok(())
    }
}
