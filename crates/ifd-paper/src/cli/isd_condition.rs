//! `ifd-paper isd-condition`: ISD Fig. 13, the condition number of the ISD
//! system against L for every lobe profile, per-band and shared directions.

use std::path::PathBuf;

use anyhow::{Result, bail};
use clap::Args;
use ifd_paper::condition::condition_plot;
use ifd_paper::condition::{condition_study, is_singular};
use ifd_sphere::MAX_ISD_DEGREE;
use serde_json::json;

use super::sharing_name;
use crate::options::ReportOptions;

/// `ifd-paper isd-condition --lmax L --plot cond.png` (ISD Fig. 13).
///
/// Plot: x = L (1..=lmax), y = cond(M) on a log scale with a labelled tick every
/// decade; colours (legend on the right): zonal black, legendre blue, phong red,
/// gauss green, vmf orange, hybrid purple; solid = per-band directions, dotted =
/// shared directions. Condition numbers >= 1e16 (beyond f64 precision) or
/// infinite are drawn on a separate top row labelled "> 1e16 (singular)", reported
/// as null in the JSON and flagged in the CSV's `singular` column.
#[derive(Debug, Args)]
pub struct IsdCondition {
    /// Largest degree L (1..=40).
    #[arg(long, value_name = "L", default_value_t = 16)]
    lmax: usize,
    /// Write the plot (PNG).
    #[arg(long, value_name = "FILE")]
    plot: Option<PathBuf>,
    /// Write the numbers as CSV (L, profile, sharing, cond, singular).
    #[arg(long, value_name = "FILE")]
    csv: Option<PathBuf>,
    #[command(flatten)]
    report: ReportOptions,
}

impl IsdCondition {
    /// Runs the study.
    pub fn run(self) -> Result<()> {
        if self.lmax == 0 || self.lmax > MAX_ISD_DEGREE {
            bail!(
                "--lmax {}: use 1..={MAX_ISD_DEGREE} (M is a dense (L+1)^2 x (L+1)^2 matrix)",
                self.lmax
            );
        }
        let rows = condition_study(self.lmax)?;
        let lines: Vec<String> = rows
            .iter()
            .flat_map(|r| {
                r.cond.iter().enumerate().map(move |(i, c)| {
                    format!(
                        "{},{},{},{c:e},{}\n",
                        i + 1,
                        r.profile.name(),
                        sharing_name(r.sharing),
                        is_singular(*c)
                    )
                })
            })
            .collect();
        let csv = format!("L,profile,sharing,cond,singular\n{}", lines.concat());
        if let Some(path) = &self.csv {
            crate::output::write_text(path, &csv)?;
        }
        if let Some(path) = &self.plot {
            let img = condition_plot(&rows)?;
            crate::output::write_output(path, &img, &ifd_image::WriteOptions::default())?;
        }
        let out: Vec<_> = rows
            .iter()
            .map(|r| {
                json!({"profile": r.profile.name(), "sharing": sharing_name(r.sharing),
                       "cond": r.cond.iter().map(|c| if is_singular(*c) { json!(null) } else { json!(c) }).collect::<Vec<_>>()})
            })
            .collect();
        self.report.emit(&json!(out))?;
        Ok(())
    }
}
