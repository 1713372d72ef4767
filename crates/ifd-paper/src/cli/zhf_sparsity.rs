//! `ifd-paper zhf-sparsity`: the ZHF paper's sparsity search (Sec. 5-6, Table
//! I, Fig. 3).

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Result, bail};
use clap::Args;
use ifd_paper::sparsity::{
    PAPER_TABLE_I, SearchOptions, random_shared, search_band, search_shared,
};
use serde_json::json;

use crate::options::ReportOptions;

/// Search lobe directions that make the ZHF matrix A_l = Y_l^-1 sparse (ZHF
/// Sec. 5): candidates at the zeros of the associated Legendre functions and
/// of the sinusoids, a genetic search per band (--bands) and for shared,
/// nested sets of 2N-1 directions per order (--orders, Sec. 6), beside random
/// draws from the same candidates (Fig. 3). Prints the report (every set's directions
/// included) and, with --markdown, a table against the paper's Table I.
///
/// Example: `ifd-paper zhf-sparsity --bands 2..12 --orders 2..8 --markdown sparsity.md` (minutes:
/// the search is long on purpose, see `ifd_paper::sparsity`)
#[derive(Debug, Args)]
pub struct SparsityCmd {
    /// Bands A..B searched one by one (1 <= A <= B <= 30); "none" to skip.
    #[arg(long, value_name = "A..B", default_value = "2..12")]
    bands: String,
    /// Orders A..B searched with shared lobes (2 <= A <= B <= 31); "none" to skip.
    #[arg(long, value_name = "A..B", default_value = "2..8")]
    orders: String,
    /// Individuals per generation.
    #[arg(long, default_value_t = 100)]
    population: usize,
    /// Stop a run after this many generations without improvement.
    #[arg(long, default_value_t = 1000)]
    stall: usize,
    /// Largest number of generations per run.
    #[arg(long, default_value_t = 20000)]
    generations: usize,
    /// Independent runs per search (in parallel); the best is kept.
    #[arg(long, default_value_t = 4)]
    restarts: usize,
    /// Seed of the first run.
    #[arg(long, value_name = "N", default_value_t = 1)]
    seed: u64,
    /// Random draws per order for the baseline.
    #[arg(long, default_value_t = 2000)]
    random: usize,
    /// Also write the table as Markdown.
    #[arg(long, value_name = "FILE")]
    markdown: Option<PathBuf>,
    #[command(flatten)]
    report: ReportOptions,
}

fn range(text: &str, option: &str, lo: usize, hi: usize) -> Result<Vec<usize>> {
    if text == "none" {
        return Ok(Vec::new());
    }
    let parsed = text.split_once("..").and_then(|(a, b)| {
        Some((
            a.trim().parse::<usize>().ok()?,
            b.trim().parse::<usize>().ok()?,
        ))
    });
    match parsed {
        Some((a, b)) if lo <= a && a <= b && b <= hi => Ok((a..=b).collect()),
        _ => bail!("{option} {text:?}: expected A..B with {lo} <= A <= B <= {hi}, or none"),
    }
}

impl SparsityCmd {
    /// Runs the command.
    pub fn run(self) -> Result<()> {
        let bands = range(&self.bands, "--bands", 1, 30)?;
        let orders = range(&self.orders, "--orders", 2, 31)?;
        if self.population < 4 || self.stall == 0 || self.generations == 0 {
            bail!("--population >= 4, --stall >= 1 and --generations >= 1 please");
        }
        if !(1..=256).contains(&self.restarts) {
            bail!("--restarts {}: use 1..=256", self.restarts);
        }
        if self.random > 10_000_000 {
            bail!("--random {}: at most 10000000", self.random);
        }
        if let Some(p) = &self.markdown {
            crate::output::check_output_folder(p)?;
        }
        let opts = SearchOptions {
            population: self.population,
            generations: self.generations,
            stall: self.stall,
            seed: self.seed,
            restarts: self.restarts,
        };
        let mut md = String::from(
            "| band l | sparsity of A_l (%) | paper Table I (%) | lobes per function m = -l..l |\n|---|---|---|---|\n",
        );
        let mut band_rows = Vec::new();
        for &l in &bands {
            let t = std::time::Instant::now();
            let f = search_band(l, opts)?;
            let secs = t.elapsed().as_secs_f64();
            let paper = (2..=18).contains(&l).then(|| PAPER_TABLE_I[l - 2]);
            eprintln!("band {l}: {:.1}% ({secs:.1} s)", 100.0 * f.sparsity);
            let _ = writeln!(
                md,
                "| {l} | {:.1} | {} | {} |",
                100.0 * f.sparsity,
                paper.map_or("-".into(), |p| format!("{p:.0}")),
                f.lobes_per_function
                    .iter()
                    .map(ToString::to_string)
                    .collect::<Vec<_>>()
                    .join(" ")
            );
            band_rows.push(json!({
                "l": l, "sparsity": f.sparsity, "paper": paper.map(|p| p / 100.0),
                "lobes_per_function": f.lobes_per_function, "residual": f.residual,
                "evaluations": f.evaluations, "seconds": secs, "directions": f.directions,
            }));
        }
        md.push_str(
            "\n| order N | shared search (%) | random mean (%) | random max (%) | random singular |\n|---|---|---|---|---|\n",
        );
        let mut order_rows = Vec::new();
        for &n in &orders {
            let t = std::time::Instant::now();
            let f = search_shared(n, opts)?;
            let (mean, max, singular) = random_shared(n, self.random, self.seed)?;
            let secs = t.elapsed().as_secs_f64();
            eprintln!("order {n}: {:.1}% ({secs:.1} s)", 100.0 * f.sparsity);
            let _ = writeln!(
                md,
                "| {n} | {:.1} | {:.1} | {:.1} | {singular} of {} |",
                100.0 * f.sparsity,
                100.0 * mean,
                100.0 * max,
                self.random
            );
            order_rows.push(json!({
                "order": n, "sparsity": f.sparsity, "per_band": f.per_band,
                "residual": f.residual, "random_mean": mean, "random_max": max,
                "random_singular": singular, "random_draws": self.random,
                "evaluations": f.evaluations, "seconds": secs, "directions": f.directions,
            }));
        }
        if let Some(p) = &self.markdown {
            crate::output::write_text(p, &md)?;
        }
        self.report.emit(
            &json!({"bands": band_rows, "orders": order_rows, "population": self.population,
                   "stall": self.stall, "restarts": self.restarts, "seed": self.seed}),
        )?;
        Ok(())
    }
}
