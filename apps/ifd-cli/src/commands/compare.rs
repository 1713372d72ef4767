//! `ifd compare A B`.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use ifd_image::{Comparison, Metrics};
use serde_json::json;

use crate::input::InputOptions;
use crate::options::SUMMARY_LINES;

/// Compare two images of the same size and channel count.
///
/// PSNR and SSIM are defined exactly as scikit-image's
/// `peak_signal_noise_ratio` and `structural_similarity(gaussian_weights=True,
/// sigma=1.5, use_sample_covariance=False)`.
#[derive(Debug, Args)]
pub struct Compare {
    /// The reference image.
    a: PathBuf,
    /// The image to compare with it.
    b: PathBuf,
    #[command(flatten)]
    report: crate::options::ReportOptions,
    /// The data range R of PSNR and SSIM. Default: 1 when every value of both
    /// images lies in [0, 1] (all 8/16-bit files), else max - min of A.
    #[arg(long, value_name = "R")]
    data_range: Option<f64>,
    /// Ignore N pixels at every side of both images.
    #[arg(long, value_name = "N", default_value_t = 0)]
    crop_border: usize,
    #[command(flatten)]
    input: InputOptions,
}

impl Compare {
    /// Runs the command.
    pub fn run(self) -> Result<()> {
        let a = self.input.read(&self.a)?.image;
        let b = self.input.read(&self.b)?.image;
        if !a.same_shape(&b) {
            bail!(
                "{} is {}x{} with {} channels but {} is {}x{} with {} channels",
                self.a.display(),
                a.width(),
                a.height(),
                a.channels(),
                self.b.display(),
                b.width(),
                b.height(),
                b.channels()
            );
        }
        let a = ifd_image::crop_border(&a, self.crop_border).context("--crop-border")?;
        let b = ifd_image::crop_border(&b, self.crop_border).context("--crop-border")?;
        if let Some(r) = self.data_range
            && !(r.is_finite() && r > 0.0)
        {
            bail!("--data-range {r}: must be finite and positive");
        }
        let range = self
            .data_range
            .unwrap_or_else(|| ifd_image::default_data_range(a.data(), b.data()));
        if !(range.is_finite() && range > 0.0) {
            bail!(
                "the images are not both within [0, 1], so the data range is max - min of {}, \
                 which is {range}; give --data-range",
                self.a.display()
            );
        }
        let cmp = ifd_image::compare(&a, &b, range).context("comparing images")?;
        self.report
            .emit_detailed(&to_json(&cmp), || table(&cmp, false), || table(&cmp, true))
    }
}

fn metrics_json(m: &Metrics) -> serde_json::Value {
    // JSON has no infinity: identical images report psnr = null and identical = true.
    json!({
        "psnr": if m.psnr.is_finite() { json!(m.psnr) } else { json!(null) },
        "ssim": m.ssim,
        "max_abs": m.max_abs,
        "mean_abs": m.mean_abs,
        "mse": m.mse,
        "identical": m.mse == 0.0,
    })
}

fn to_json(c: &Comparison) -> serde_json::Value {
    let mut v = metrics_json(&c.overall);
    v["data_range"] = json!(c.data_range);
    v["channels"] = json!(c.channels.iter().map(metrics_json).collect::<Vec<_>>());
    v
}

/// The table: the data range, a header, a row per channel (when there are
/// several) and the overall row. The summary (`every` false) leaves out the
/// channels' rows when the table would pass [`SUMMARY_LINES`] lines.
fn table(c: &Comparison, every: bool) -> String {
    let mut text = String::new();
    let _ = writeln!(text, "data range {}", c.data_range);
    let _ = writeln!(
        text,
        "{:<9} {:>10} {:>9} {:>12} {:>12}",
        "channel", "PSNR [dB]", "SSIM", "max |a-b|", "mean |a-b|"
    );
    let mut row = |name: &str, m: &Metrics| {
        let _ = writeln!(
            text,
            "{name:<9} {:>10.4} {:>9.6} {:>12.6e} {:>12.6e}",
            m.psnr, m.ssim, m.max_abs, m.mean_abs
        );
    };
    let n = c.channels.len();
    let per_channel = n > 1 && (every || n + 3 <= SUMMARY_LINES);
    if per_channel {
        for (i, m) in c.channels.iter().enumerate() {
            row(&i.to_string(), m);
        }
    }
    row("overall", &c.overall);
    if n > 1 && !per_channel {
        let _ = writeln!(text, "({n} channels: -v lists each)");
    }
    text
}
