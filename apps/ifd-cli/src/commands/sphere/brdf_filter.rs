//! `ifd sphere brdf-filter`: noisy and sparse BRDF data filtered with a
//! separable vMF kernel on the 4D SH basis (ISD Sec. 6.3, Eq. 30-32).

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Result, bail};
use clap::Args;
use ifd_shade::Brdf;
use ifd_shade::BrdfSh;
use ifd_shade::{Merl, merl_format::from_half_diff};
use ifd_sphere::ShEvaluator;
use rayon::prelude::*;
use serde_json::json;

use crate::options::{ReportOptions, number, seconds, written};

/// Filter a BRDF (typically a noisy or sparse MERL measurement) with the
/// separable von Mises-Fisher kernel of ISD Sec. 6.3 on the 4D SH basis.
///
/// The BRDF is projected on SH of degree --lmax in both directions (its even
/// extension across the horizon, the reflective boundary), the coefficients
/// are scaled by the vMF factors of --kappa in each direction (Eq. 32), and
/// the result is reconstructed, clamped at zero and below the horizon. Holes
/// (negative values in a MERL file) are missing data: the mask is filtered
/// alike and divides the result (normalised convolution). Reciprocity is
/// kept by construction. Output: a MERL file (.binary; isotropic BRDFs, for
/// `ifd render --brdf merl:FILE`) or the coefficients as an (M, M, C)
/// float64 .npy (M = (L+1)(L+2)/2 basis functions with l+m even). The report
/// gives the filtered BRDF's directional albedo range, its reciprocity and,
/// with --clean, the relative L2 errors of the input and of the result
/// against a clean BRDF.
///
/// Example: `ifd sphere brdf-filter --brdf merl:noisy.binary --lmax 8 --kappa 60 -o smooth.binary`
#[derive(Debug, Args)]
pub struct BrdfFilterCmd {
    /// The BRDF to filter (merl:FILE, or any spec of `ifd render`).
    #[arg(long, value_name = "SPEC")]
    brdf: String,
    /// SH degree L per direction (at most 20: the reconstruction costs M^2 per value).
    #[arg(long, value_name = "L", default_value_t = 8)]
    lmax: usize,
    /// vMF concentration kappa per direction (lobe width about 1/sqrt(kappa) radians).
    #[arg(long, value_name = "K", default_value_t = 60.0)]
    kappa: f64,
    /// Quadrature nodes in cos(theta) per direction (default max(2L + 4, 24), at most 45).
    #[arg(long, value_name = "N")]
    nodes: Option<usize>,
    /// A clean BRDF to measure the input and the result against.
    #[arg(long, value_name = "SPEC")]
    clean: Option<String>,
    /// Output: .binary (MERL) or .npy (coefficients).
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    #[command(flatten)]
    report: ReportOptions,
}

impl BrdfFilterCmd {
    /// Runs the command.
    pub fn run(self) -> Result<()> {
        if self.lmax > 20 {
            bail!("--lmax {}: at most 20", self.lmax);
        }
        if !self.kappa.is_finite() || self.kappa < 0.0 || self.kappa > 1e6 {
            bail!(
                "--kappa {}: use a finite value in [0, 1e6]",
                ifd_image::short_number(self.kappa)
            );
        }
        let nodes = self.nodes.unwrap_or((2 * self.lmax + 4).max(24));
        if nodes < self.lmax + 1 || nodes > 45 {
            bail!("--nodes {nodes}: use L + 1 ..= 45");
        }
        let ext = self
            .output
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        let merl_out = match ext.as_deref() {
            Some("binary") => true,
            Some("npy") => false,
            _ => bail!(
                "-o {}: use .binary (MERL) or .npy (coefficients)",
                self.output.display()
            ),
        };
        crate::output::check_output_folder(&self.output)?;
        let brdf = Brdf::parse(&self.brdf)?;
        if merl_out && !brdf.is_isotropic() {
            bail!(
                "-o {}: the MERL format holds isotropic BRDFs only; write the coefficients (.npy)",
                self.output.display()
            );
        }
        let clean = self.clean.as_deref().map(Brdf::parse).transpose()?;
        let start = std::time::Instant::now();
        let bar = crate::progress::bar("projecting", "", 0);
        let sh4 = BrdfSh::from_brdf(&brdf, self.lmax, nodes, &crate::progress::track(&bar))?;
        bar.finish_and_clear();
        let filtered = sh4.filtered(self.kappa);
        let sh = ShEvaluator::new(self.lmax)?;
        let ch = filtered.channels();
        let eval = |wi: [f64; 3], wo: [f64; 3], s: &mut Vec<f64>, out: &mut [f64]| {
            filtered.eval(&sh, wi, wo, s, out);
        };
        // directional albedo of the result over a grid of views
        let (gx, gw) = ifd_sphere::gauss_legendre(32);
        let mut albedo = (f64::INFINITY, f64::NEG_INFINITY);
        let mut s = filtered.scratch();
        let mut v = vec![0.0; ch];
        for k in 0..16 {
            let to = (k as f64 + 0.5) / 16.0 * std::f64::consts::FRAC_PI_2;
            for po in [0.0, 0.7, 1.9] {
                let wo = [to.sin() * f64::cos(po), to.sin() * f64::sin(po), to.cos()];
                let mut a = vec![0.0; ch];
                for (t, wt) in gx.iter().zip(&gw) {
                    let z = 0.5 * (t + 1.0);
                    let st = (1.0 - z * z).sqrt();
                    for j in 0..64 {
                        let p = std::f64::consts::TAU * (j as f64 + 0.5) / 64.0;
                        eval([st * p.cos(), st * p.sin(), z], wo, &mut s, &mut v);
                        let q = 0.5 * wt * std::f64::consts::TAU / 64.0 * z;
                        for c in 0..ch {
                            a[c] += q * v[c];
                        }
                    }
                }
                for x in a {
                    albedo = (albedo.0.min(x), albedo.1.max(x));
                }
            }
        }
        // reciprocity of the result at scattered pairs
        let mut recip = 0.0f64;
        let mut peak = 0.0f64;
        let mut u = vec![0.0; ch];
        for k in 0..200 {
            let g = |i: usize| (k as f64 * 0.754_877_666 + i as f64 * 0.569_840_29).fract();
            let dir = |a: f64, b: f64| {
                let z = 0.05 + 0.95 * a;
                let st = (1.0 - z * z).sqrt();
                let p = std::f64::consts::TAU * b;
                [st * p.cos(), st * p.sin(), z]
            };
            let (wi, wo) = (dir(g(0), g(1)), dir(g(2), g(3)));
            eval(wi, wo, &mut s, &mut v);
            eval(wo, wi, &mut s, &mut u);
            for c in 0..ch {
                recip = recip.max((v[c] - u[c]).abs());
                peak = peak.max(v[c].abs());
            }
        }
        // errors against a clean BRDF over the hemisphere pairs
        let errors = clean
            .as_ref()
            .map(|c| l2_errors(c, &brdf, &filtered, &sh))
            .transpose()?;
        if merl_out {
            // bins whose centre has a direction below the horizon still
            // serve lookups above it: they get the even extension's value
            let merl = Merl::tabulate(|th, td, pd| {
                let (wi, wo) = from_half_diff(th, 0.0, td, pd);
                let up = |w: [f64; 3]| [w[0], w[1], w[2].abs().max(1e-9)];
                let (wi, wo) = (up(wi), up(wo));
                let mut s = filtered.scratch();
                let mut out = vec![0.0; ch];
                filtered.eval(&sh, wi, wo, &mut s, &mut out);
                if ch == 1 {
                    [out[0]; 3]
                } else {
                    [out[0], out[1], out[2]]
                }
            });
            merl.write(&self.output)?;
        } else {
            let m = filtered.basis_len();
            ifd_image::write_npy_f64(&self.output, &[m, m, ch], filtered.coeffs())?;
        }
        let secs = start.elapsed().as_secs_f64();
        let summary = || {
            let mut text = format!(
                "wrote {}: {} filtered at L = {}, kappa = {}\n",
                written(&self.output),
                brdf.spec(),
                self.lmax,
                number(self.kappa)
            );
            if let Some(e) = &errors {
                let f = |k: &str| e[k].as_f64().map_or_else(|| "-".to_owned(), number);
                let _ = writeln!(
                    text,
                    "relative L2 error against the clean BRDF: input {}, filtered {}",
                    f("input_vs_clean"),
                    f("filtered_vs_clean")
                );
            }
            text + &format!(
                "albedo {} to {}, reciprocity error {} (largest value {})\ntime {}\n",
                number(albedo.0),
                number(albedo.1),
                number(recip),
                number(peak),
                seconds(secs)
            )
        };
        self.report.emit_summary(
            &json!({
                "brdf": brdf.spec(), "lmax": self.lmax, "kappa": self.kappa, "nodes": nodes,
                "basis_per_direction": filtered.basis_len(), "holes": sh4.has_holes(),
                "coefficient_asymmetry": sh4.asymmetry(),
                "albedo_min": albedo.0, "albedo_max": albedo.1,
                "reciprocity_max_abs": recip, "value_max": peak,
                "errors": errors,
                "seconds": secs,
            }),
            summary,
        )?;
        Ok(())
    }
}

/// Relative L2 errors over hemisphere pairs (Gauss-Legendre x trapezoid, 12 x
/// 24 nodes per direction, valid bins of the input only) of the input and of
/// the filtered BRDF against `clean`.
fn l2_errors(
    clean: &Brdf,
    input: &Brdf,
    filtered: &BrdfSh,
    sh: &ShEvaluator,
) -> Result<serde_json::Value> {
    let (gx, gw) = ifd_sphere::gauss_legendre(12);
    let mut nodes = Vec::new();
    for (t, wt) in gx.iter().zip(&gw) {
        let z = 0.5 * (t + 1.0);
        let st = (1.0 - z * z).sqrt();
        for j in 0..24 {
            let p = std::f64::consts::TAU * (j as f64 + 0.5) / 24.0;
            nodes.push((
                [st * p.cos(), st * p.sin(), z],
                wt * std::f64::consts::PI / 24.0,
            ));
        }
    }
    let ch = filtered.channels();
    let sums: Vec<[f64; 3]> = nodes
        .par_iter()
        .map(|(wi, w1)| {
            let mut s = filtered.scratch();
            let (mut a, mut b, mut c) = (vec![0.0; 3], vec![0.0; 3], vec![0.0; 3]);
            let mut acc = [0.0; 3];
            for (wo, w2) in &nodes {
                let to_brdf = |k: &mut [f64], n: usize| {
                    for x in k.iter_mut().take(n) {
                        *x /= wi[2];
                    }
                };
                clean.slice(*wi, *wo, &mut a);
                to_brdf(&mut a, clean.channels());
                input.slice(*wi, *wo, &mut b);
                to_brdf(&mut b, input.channels());
                filtered.eval(sh, *wi, *wo, &mut s, &mut c);
                let valid = match input.model() {
                    ifd_shade::Model::Merl(m) => m.is_valid(*wi, *wo),
                    _ => true,
                };
                if !valid {
                    continue;
                }
                for k in 0..ch {
                    let r = a[if clean.channels() == 1 { 0 } else { k }];
                    let x = b[if input.channels() == 1 { 0 } else { k }];
                    let w = w1 * w2;
                    acc[0] += w * r * r;
                    acc[1] += w * (x - r) * (x - r);
                    acc[2] += w * (c[k] - r) * (c[k] - r);
                }
            }
            acc
        })
        .collect();
    let t = sums
        .iter()
        .fold([0.0; 3], |a, s| [a[0] + s[0], a[1] + s[1], a[2] + s[2]]);
    if t[0] <= 0.0 {
        bail!("--clean: the clean BRDF is zero everywhere");
    }
    Ok(json!({
        "input_vs_clean": (t[1] / t[0]).sqrt(),
        "filtered_vs_clean": (t[2] / t[0]).sqrt(),
    }))
}
