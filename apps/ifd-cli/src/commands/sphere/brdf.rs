//! `ifd sphere brdf`: tabulate a BRDF's view-dependent ISD lobe weights.

use std::path::PathBuf;

use anyhow::{Result, bail};
use clap::Args;

use serde_json::json;

use crate::options::{ReportOptions, number, seconds, written};

/// `ifd sphere brdf SPEC --lmax L -o table.lobes`.
///
/// SPEC is a BRDF (not a kernel of `sphere decompose`): `lambert`, `phong:s=32`
/// (normalised, about the mirror direction, cosine folded in), `blinn:s=64`
/// ((s+8)/(8 pi)) or `blinn-exact:s=64` (normalised exactly at normal view),
/// `ggx:alpha=0.3` or `ggx:ax=0.1,ay=0.4` (optional `f0=` for Schlick
/// Fresnel), `ward:ax=0.1,ay=0.3`, `merl:FILE`; each but merl takes
/// `albedo=` (default 1). Formulas: `cargo doc -p ifd-shade` (module `brdf`).
///
/// For each view direction of the table, the cosine-weighted slice
/// `k_wo(wi) = rho(wi, wo) max(cos, 0)` is projected on SH up to L and
/// decomposed into rotated zonal lobes shared by all bands. Isotropic BRDFs
/// get a 1D table over theta_o (frame rotated to phi_o = 0, where the slice is
/// even across the plane of the normal and the view, so L+1 lobes in that
/// plane suffice), anisotropic ones a 2D table over (theta_o, phi_o) with 2L+1
/// lobes. The interpolation error (relative L2
/// of the interpolated slice at the midpoints between entries) is measured and
/// reported. The file is binary with a JSON header (2D tables reach tens of
/// MB, which JSON text would triple), versioned and self-describing.
#[derive(Debug, Args)]
pub(super) struct BrdfCmd {
    /// BRDF spec (see above).
    spec: String,
    /// Maximum SH degree L (at most 100).
    #[arg(long, value_name = "L")]
    lmax: usize,
    /// Entries over theta_o (default: from the lobe width, 16..=512).
    #[arg(long, value_name = "N")]
    theta_entries: Option<usize>,
    /// Entries over phi_o for anisotropic BRDFs (default: 2x the theta entries, at most 128).
    #[arg(long, value_name = "N")]
    phi_entries: Option<usize>,
    /// Lobe layout: auto (in-plane for isotropic BRDFs, shared for anisotropic
    /// ones), shared (2L+1 directions, any BRDF; for comparison) or in-plane
    /// (L+1 directions, isotropic BRDFs only).
    #[arg(long, value_name = "LAYOUT", default_value = "auto",
          value_parser = ["auto", "shared", "in-plane"])]
    lobes: String,
    /// Output table file (binary, conventionally .lobes).
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    report: ReportOptions,
}

impl BrdfCmd {
    pub(super) fn run(self) -> Result<()> {
        use ifd_shade::{LobeTable, MAX_TABLE_DEGREE, default_theta_entries};
        if self.lmax > MAX_TABLE_DEGREE {
            bail!(
                "--lmax {}: lobe tables support L <= {MAX_TABLE_DEGREE}",
                self.lmax
            );
        }
        let brdf = ifd_shade::Brdf::parse(&self.spec)?;
        // an unwritable output is refused before the work
        crate::output::check_output_folder(&self.output)?;
        let nt = self
            .theta_entries
            .unwrap_or_else(|| default_theta_entries(&brdf));
        let np = self.phi_entries.unwrap_or((2 * nt).min(128));
        let start = std::time::Instant::now();
        let bar = crate::progress::bar("slices", "", 0);
        let kind = match self.lobes.as_str() {
            "shared" => ifd_shade::LobeKind::Shared,
            "in-plane" => ifd_shade::LobeKind::InPlane,
            _ => ifd_shade::LobeKind::default_for(&brdf),
        };
        let table = LobeTable::build_with(
            &brdf,
            self.lmax,
            nt,
            np,
            kind,
            &crate::progress::track(&bar),
        )?;
        bar.finish_and_clear();
        table.write(&self.output)?;
        let h = table.header();
        let albedo = table.entry_albedos();
        let (amin, amax) = albedo
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
        let secs = start.elapsed().as_secs_f64();
        let lobes = table.basis().directions().len();
        self.report.emit_summary(
            &json!({
                "brdf": h.brdf, "lmax": h.l_max, "isotropic": h.isotropic,
                "channels": h.channels, "theta_entries": h.n_theta, "phi_entries": h.n_phi,
                "lobes": lobes,
                "lobe_layout": h.lobes.name(),
                "weight_bytes": table.weight_bytes(),
                "interpolation_error": h.interpolation_error,
                "interpolation_rms": h.interpolation_rms,
                "albedo_min": amin, "albedo_max": amax,
                "seconds": secs,
            }),
            || {
                format!(
                    "wrote {}: {} lobe table, L = {}, {lobes} lobes ({}), {}x{} views\n\
                     interpolation error {} (RMS {}), albedo {} to {}\n\
                     time {}\n",
                    written(&self.output),
                    h.brdf,
                    h.l_max,
                    h.lobes.name(),
                    h.n_theta,
                    h.n_phi,
                    number(h.interpolation_error),
                    number(h.interpolation_rms),
                    number(amin),
                    number(amax),
                    seconds(secs),
                )
            },
        )?;
        Ok(())
    }
}
