//! `ifd-paper shrm-table4` and `shrm-table5`: Ramamoorthi and Hanrahan
//! (2002), Tables 4 and 5.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;

use super::csv_report;
use crate::input::InputOptions;
use crate::options::ReportOptions;

/// Reproduces Tables 4 and 5 of Ramamoorthi and Hanrahan (2002).
///
/// Table 4: a normalised Phong reflection map prefiltered in frequency space
/// (lighting SH to the paper's order F_B = 1 + sqrt(6 s), zonal scaling,
/// synthesis) and in angular space (per output texel, a sum over the input
/// texels of the lobe's eps-support, App. D), on the same equirectangular grid
/// with the same threads; medians of --runs measurements. The table also shows
/// App. D's order sqrt(-s ln 0.01) and App. B's conservative bound on the
/// truncation's relative error energy, then the log-log slopes (theory: +1/2
/// and -1) and the crossover exponent extrapolated from the fits.
///
/// Table 5: the microfacet BRDF of Eq. 11 (--sigmas): BRDF coefficients and
/// the orders F_B, P_B for 1 - eps of its energy, the SHRM and 10 x 10
/// reflection maps for distant viewers against angular integration of --maps
/// x --maps of them (time extrapolated to 100).
#[derive(Debug, Args)]
pub struct Shrm {
    /// Environment map (2:1), averaged down to --size by solid angle.
    envmap: PathBuf,
    #[command(flatten)]
    report: ReportOptions,
    /// Working size WxH (2:1; default 256x128 for Table 4, whose S_L = S_B = 128 is the
    /// number of rows here, and 128x64 for Table 5, whose angular side is slow).
    #[arg(long, value_name = "WxH")]
    size: Option<String>,
    /// The angular side's support tolerance (the paper: 0.05).
    #[arg(long, default_value_t = 0.05)]
    eps_angular: f64,
    /// Also write the rows as CSV.
    #[arg(long)]
    csv: Option<PathBuf>,
    #[command(flatten)]
    input: InputOptions,
}

/// `ifd-paper shrm-table4`: the Phong lobe, angular against frequency space.
#[derive(Debug, Args)]
pub struct ShrmTable4 {
    #[command(flatten)]
    common: Shrm,
    /// Phong exponents.
    #[arg(long, value_delimiter = ',', default_value = "8,16,32,64,128,256,512")]
    exponents: Vec<f64>,
    /// Measurements per side and exponent (medians); each repeats the work for at least
    /// --min-seconds and takes the mean per run.
    #[arg(long, value_name = "N", default_value_t = 5)]
    runs: usize,
    /// Minimum time of one measurement.
    #[arg(long, default_value_t = 0.2)]
    min_seconds: f64,
    /// Also write a log-log plot of both times against s (PNG).
    #[arg(long)]
    plot: Option<PathBuf>,
}

/// `ifd-paper shrm-table5`: the microfacet BRDF of Eq. 11, SHRM against
/// angular reflection maps.
#[derive(Debug, Args)]
pub struct ShrmTable5 {
    #[command(flatten)]
    common: Shrm,
    /// Roughness values sigma.
    #[arg(long, value_delimiter = ',', default_value = "0.1,0.2,0.3,0.4,0.5")]
    sigmas: Vec<f64>,
    /// The angular side computes T x T of the paper's T_B x T_B = 10 x 10 maps and its time
    /// is extrapolated to 100 (the frequency side makes all 100).
    #[arg(long, default_value_t = 3)]
    maps: usize,
    /// The BRDF energy tolerance choosing F_B, P_B (the paper: 0.03).
    #[arg(long, default_value_t = 0.03)]
    eps: f64,
}

/// SHRM Table 4 (1.4 GHz Pentium IV): (s, angular, frequency).
const PAPER_TABLE4: [(f64, f64, f64); 7] = [
    (8.0, 67.28, 0.081),
    (16.0, 38.03, 0.114),
    (32.0, 21.80, 0.159),
    (64.0, 11.94, 0.227),
    (128.0, 7.17, 0.328),
    (256.0, 3.55, 0.461),
    (512.0, 2.28, 0.686),
];

impl Shrm {
    /// The map averaged down to `--size` (else `default`) by solid angle.
    fn load(&self, default: &str) -> Result<(ifd_image::Image, usize, usize)> {
        if !(self.eps_angular > 0.0 && self.eps_angular < 1.0) {
            bail!("--eps-angular {}: must lie in (0, 1)", self.eps_angular);
        }
        let (w, h) = crate::input::parse_size(self.size.as_deref().unwrap_or(default), "--size")?;
        let img = self.input.read(&self.envmap)?.image;
        if img.channels() != 3 {
            bail!(
                "{}: needs RGB; got {} channel(s)",
                self.envmap.display(),
                img.channels()
            );
        }
        let src = ifd_sphere::downsample_equirect(&img, w, h).with_context(|| {
            format!(
                "{}: averaging down to --size {w}x{h}",
                self.envmap.display()
            )
        })?;
        Ok((src, w, h))
    }
}

impl ShrmTable4 {
    /// Runs the study.
    pub fn run(self) -> Result<()> {
        use ifd_paper::shrm::{loglog_fit, paper_order, time_phong};
        let mut out = String::new();
        if self.exponents.is_empty()
            || self
                .exponents
                .iter()
                .any(|s| !(s.is_finite() && *s >= 1.0 && *s <= 1e5))
        {
            bail!("--exponents: each must lie in 1..=100000");
        }
        if !(1..=50).contains(&self.runs) {
            bail!("--runs {}: must lie in 1..=50", self.runs);
        }
        if !(self.min_seconds >= 0.0 && self.min_seconds <= 60.0) {
            bail!("--min-seconds {}: must lie in 0..=60", self.min_seconds);
        }
        let (src, w, h) = self.common.load("256x128")?;
        let max_order = self
            .exponents
            .iter()
            .map(|s| paper_order(*s))
            .max()
            .unwrap_or(0);
        if max_order >= h {
            bail!("--size {w}x{h}: F_B = {max_order} needs more than {h} rows");
        }
        let threads = rayon::current_num_threads();
        let mut rows = Vec::new();
        for &s in &self.exponents {
            eprintln!("s = {s}: timing ...");
            rows.push(time_phong(
                &src,
                s,
                self.common.eps_angular,
                self.runs,
                self.min_seconds,
            )?);
        }
        let _ = writeln!(
            out,
            "SHRM Table 4 on this machine: {w}x{h} in and out, {threads} threads, medians of {} measurements of at least {} s each, angular eps {}",
            self.runs, self.min_seconds, self.common.eps_angular
        );
        out.push('\n');
        let _ = writeln!(
            out,
            "| s | F_B | App. D order | angular (s) | frequency (s) | ratio | support texels | rel. diff | App. B bound | paper ratio |"
        );
        let _ = writeln!(out, "|---|---|---|---|---|---|---|---|---|---|");
        for r in &rows {
            let paper = PAPER_TABLE4
                .iter()
                .find(|p| (p.0 - r.s).abs() < 1e-9)
                .map_or_else(|| "-".to_string(), |p| format!("{:.1}", p.1 / p.2));
            let _ = writeln!(
                out,
                "| {} | {} | {} | {:.4} | {:.4} | {:.1} | {:.0} | {:.2e} | {:.1e} | {} |",
                r.s,
                r.order,
                ifd_paper::shrm::phong_order(r.s, 0.01),
                r.angular,
                r.frequency,
                r.angular / r.frequency,
                r.support,
                r.rel_diff,
                r.residual_bound,
                paper
            );
        }
        let xs: Vec<f64> = rows.iter().map(|r| r.s).collect();
        let (fa, ia) = loglog_fit(&xs, &rows.iter().map(|r| r.angular).collect::<Vec<_>>());
        let (ff, iff) = loglog_fit(&xs, &rows.iter().map(|r| r.frequency).collect::<Vec<_>>());
        // crossover: ia + fa ln s = iff + ff ln s
        let crossover = ((iff - ia) / (fa - ff)).exp();
        out.push('\n');
        let _ = writeln!(
            out,
            "log-log slopes: angular {fa:.2} (theory -1), frequency {ff:.2} (theory +0.5); crossover s* = {crossover:.0} (extrapolated; the paper predicts s* ~ S_L^(4/3) = {:.0} up to constants)",
            (h as f64).powf(4.0 / 3.0)
        );
        let mut text = String::from(
            "s,order,angular_s,frequency_s,ratio,support_texels,rel_diff,residual_bound\n",
        );
        for r in &rows {
            let ratio = r.angular / r.frequency;
            let _ = writeln!(
                text,
                "{},{},{},{},{ratio},{},{},{}",
                r.s, r.order, r.angular, r.frequency, r.support, r.rel_diff, r.residual_bound
            );
        }
        if let Some(path) = &self.common.csv {
            crate::output::write_text(path, &text)?;
        }
        if let Some(path) = &self.plot {
            use ifd_plot::{Series, log_line_plot};
            let pts = |f: &dyn Fn(&ifd_paper::shrm::PhongTiming) -> f64| -> Vec<(f64, f64)> {
                rows.iter().map(|r| (r.s.log2(), f(r))).collect()
            };
            let series = vec![
                Series {
                    name: "angular, ifd".into(),
                    colour: [0.8, 0.2, 0.1],
                    dotted: false,
                    points: pts(&|r| r.angular),
                },
                Series {
                    name: "frequency, ifd".into(),
                    colour: [0.1, 0.3, 0.8],
                    dotted: false,
                    points: pts(&|r| r.frequency),
                },
                Series {
                    name: "angular, paper".into(),
                    colour: [0.8, 0.2, 0.1],
                    dotted: true,
                    points: PAPER_TABLE4.iter().map(|p| (p.0.log2(), p.1)).collect(),
                },
                Series {
                    name: "frequency, paper".into(),
                    colour: [0.1, 0.3, 0.8],
                    dotted: true,
                    points: PAPER_TABLE4.iter().map(|p| (p.0.log2(), p.2)).collect(),
                },
            ];
            let img = log_line_plot(&series, "log2 s (Phong exponent)", "seconds")?;
            crate::output::write_output(path, &img, &ifd_image::WriteOptions::default())?;
        }
        let mut report = csv_report(&text);
        report["slopes"] =
            serde_json::json!({"angular": fa, "frequency": ff, "crossover_s": crossover});
        self.common.report.emit_with(&report, || out)
    }
}

/// SHRM Table 5 (1.4 GHz Pentium IV): (sigma, F_B, P_B, angular total for 100
/// maps, frequency total, SHRM alone).
const PAPER_TABLE5: [(f64, usize, usize, f64, f64, f64); 5] = [
    (0.1, 24, 3, 923.0, 2.70, 1.55),
    (0.2, 12, 2, 2744.0, 1.55, 0.72),
    (0.3, 7, 2, 5731.0, 1.49, 0.67),
    (0.4, 5, 2, 9034.0, 1.47, 0.65),
    (0.5, 5, 2, 12580.0, 1.45, 0.64),
];

impl ShrmTable5 {
    /// Runs the study.
    pub fn run(self) -> Result<()> {
        use ifd_paper::shrm_general::{time_microfacet, view_grid};
        let mut out = String::new();
        if self.sigmas.is_empty()
            || self
                .sigmas
                .iter()
                .any(|s| !(s.is_finite() && *s >= 0.02 && *s <= 1.5))
        {
            bail!("--sigmas: each must lie in 0.02..=1.5");
        }
        if !(1..=10).contains(&self.maps) {
            bail!("--maps {}: must lie in 1..=10", self.maps);
        }
        if !(self.eps > 0.0 && self.eps < 1.0) {
            bail!("--eps {}: must lie in (0, 1)", self.eps);
        }
        let (src, w, h) = self.common.load("128x64")?;
        let views = view_grid(self.maps);
        let mut rows = Vec::new();
        for &sigma in &self.sigmas {
            eprintln!(
                "sigma = {sigma}: SHRM, 100 maps, {} angular maps ...",
                views.len()
            );
            rows.push(time_microfacet(
                &src,
                sigma,
                self.eps,
                self.common.eps_angular,
                10,
                &views,
            )?);
        }
        let _ = writeln!(
            out,
            "SHRM Table 5 on this machine: {w}x{h} in and out, {} threads; F_B, P_B for BRDF energy eps {}; angular support eps {}; \
             angular time measured on {} of the 10 x 10 maps and extrapolated to 100",
            rayon::current_num_threads(),
            self.eps,
            self.common.eps_angular,
            views.len()
        );
        out.push('\n');
        let _ = writeln!(
            out,
            "| sigma | F_B, P_B | paper | angular per map (s) | angular, 100 maps (s) | SHRM (s) | SHRM + 100 maps (s) | ratio | paper ratio | rel. diff | support texels |"
        );
        let _ = writeln!(out, "|---|---|---|---|---|---|---|---|---|---|---|");
        let mut csv = String::from(
            "sigma,f,p,angular_per_map_s,angular_100_s,shrm_s,frequency_100_s,ratio,rel_diff,support_texels\n",
        );
        for r in &rows {
            let ang100 = 100.0 * r.angular_per_map;
            let freq100 = r.shrm + 100.0 * r.per_map;
            let paper = PAPER_TABLE5.iter().find(|p| (p.0 - r.sigma).abs() < 1e-9);
            let _ = writeln!(
                out,
                "| {} | {}, {} | {} | {:.3} | {:.1} | {:.3} | {:.3} | {:.0} | {} | {:.2e} | {:.0} |",
                r.sigma,
                r.f,
                r.p,
                paper.map_or_else(|| "-".into(), |p| format!("{}, {}", p.1, p.2)),
                r.angular_per_map,
                ang100,
                r.shrm,
                freq100,
                ang100 / freq100,
                paper.map_or_else(|| "-".into(), |p| format!("{:.0}", p.3 / p.4)),
                r.rel_diff,
                r.support
            );
            let _ = std::fmt::Write::write_fmt(
                &mut csv,
                format_args!(
                    "{},{},{},{},{},{},{},{},{},{}\n",
                    r.sigma,
                    r.f,
                    r.p,
                    r.angular_per_map,
                    ang100,
                    r.shrm,
                    freq100,
                    ang100 / freq100,
                    r.rel_diff,
                    r.support
                ),
            );
        }
        if let Some(path) = &self.common.csv {
            crate::output::write_text(path, &csv)?;
        }
        self.common.report.emit_with(&csv_report(&csv), || out)
    }
}
