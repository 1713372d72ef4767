//! `ifd-paper all`: every study in one run, each into a Markdown page with
//! what the paper reports beside what this run measured, and its figures.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;

/// Run every study (or those named by --only) and write one page per study,
/// DIR/NAME.md, with what the paper reports, the command, its run time, its
/// report and its figures (DIR/NAME/). Run from the repository root (the
/// studies read testdata/forest.hdr). With --quick the studies run at small
/// sizes (seconds in all; what CI runs); without it, at the sizes of the
/// documentation (about 9 minutes on 2 cores).
#[derive(Debug, Args)]
pub struct All {
    /// Small sizes: checks that every study runs, not the papers' numbers.
    #[arg(long)]
    quick: bool,
    /// Folder of the pages and their figures (created if missing); default
    /// docs/papers, which holds the pages at the documentation's sizes (a
    /// --quick run needs a folder of its own).
    #[arg(long, value_name = "DIR")]
    out_dir: Option<PathBuf>,
    /// Run only this study (a name from `ifd-paper list`); repeatable.
    #[arg(long, value_name = "NAME")]
    only: Vec<String>,
}

/// One study: its name, the paper's account, its arguments at small and at
/// full size (`{out}` stands for the study's folder), a file of its output to
/// inline in the page, and the figures the page shows.
struct Study {
    name: &'static str,
    title: &'static str,
    paper: &'static str,
    quick: &'static str,
    full: &'static str,
    inline: Option<&'static str>,
    figures: &'static [&'static str],
}

const STUDIES: &[Study] = &[
    Study {
        name: "isd-convergence",
        title: "ISD Fig. 4: convergence of ISD shading as L grows",
        paper: "The paper shows renderings of measured BRDFs converging to a ray-traced \
                reference (300K samples per pixel) as L grows, with false-colour error \
                images; it gives no error numbers. Here: the relative RMS error of ISD \
                against the exact texel quadrature of the same environment, per BRDF and L.",
        quick: "--env testdata/forest.hdr --degrees 2..8:3 --brdf phong:s=8 --brdf lambert \
                --size 32x32 --no-sh --csv {out}/errors.csv --plot {out}/errors.png",
        full: "--env testdata/forest.hdr --degrees 2..36:2 --brdf phong:s=8 --brdf phong:s=32 \
               --brdf phong:s=128 --brdf ggx:alpha=0.5 --brdf ggx:alpha=0.3 --brdf lambert \
               --size 128x128 --no-sh --csv {out}/errors.csv --plot {out}/errors.png \
               --grid {out}/grid.png",
        inline: None,
        figures: &["errors.png", "grid.png"],
    },
    Study {
        name: "isd-condition",
        title: "ISD Fig. 13: condition number of M against L",
        paper: "The paper plots cond(M) against L for Phong, Gaussian, Legendre (RZH) and \
                hybrid profiles, with and without directions shared across bands, and \
                concludes that sharing has little impact on RZH's conditioning but a high \
                impact for Phong and Gaussian profiles.",
        quick: "--lmax 6 --csv {out}/cond.csv --plot {out}/cond.png",
        full: "--lmax 16 --csv {out}/cond.csv --plot {out}/cond.png",
        inline: None,
        figures: &["cond.png"],
    },
    Study {
        name: "isd-mirror",
        title: "ISD Sec. 6.2, Fig. 6: anti-aliased reflections on a bumpy mirror",
        paper: "The paper shows anti-aliased reflections of an environment on bumpy \
                mirrors (images, no error numbers). Here: relative RMS errors against a \
                stratified supersampled reference, and times, beside supersampling.",
        quick: "--env testdata/forest.hdr --size 48x48 --reference-grid 8 --runs 1 --lmax 24 \
                --out-dir {out}",
        full: "--env testdata/forest.hdr --out-dir {out}",
        inline: Some("table.md"),
        figures: &["strip.png"],
    },
    Study {
        name: "isd-visibility",
        title: "ISD App. A, Fig. 7: self-shadowed shading with per-vertex visibility",
        paper: "The paper shades meshes with per-vertex SH visibility (images and GPU \
                timings). Here: the error of ISD with and without visibility against a \
                ray-traced reference, per L.",
        quick: "--env testdata/forest.hdr --env-size 32x16 --size 32x32 --degrees 4..8:4 \
                --rays 512 --out-dir {out}",
        full: "--env testdata/forest.hdr --brdf phong:s=8 --degrees 2..14:2 --out-dir {out}",
        inline: None,
        figures: &["strip.png", "error.png"],
    },
    Study {
        name: "shrm-table4",
        title: "SHRM Table 4: Phong prefiltering, angular against frequency space",
        paper: "Ramamoorthi and Hanrahan time angular and frequency-space prefiltering of \
                a Phong reflection map (1.4 GHz Pentium IV); the table below has the \
                paper's ratio beside the ratio measured here.",
        quick: "testdata/forest.hdr --size 64x32 --exponents 8,32 --runs 1 --min-seconds 0 \
                --csv {out}/table4.csv --plot {out}/table4.png",
        full: "testdata/forest.hdr --csv {out}/table4.csv --plot {out}/table4.png",
        inline: None,
        figures: &["table4.png"],
    },
    Study {
        name: "shrm-table5",
        title: "SHRM Table 5: the microfacet BRDF, SHRM against angular reflection maps",
        paper: "The paper's orders F_B, P_B and timings for the microfacet BRDF of its \
                Eq. 11; the table below has the paper's numbers beside ours.",
        quick: "testdata/forest.hdr --size 32x16 --sigmas 0.2,0.4 --maps 1 --csv {out}/table5.csv",
        full: "testdata/forest.hdr --csv {out}/table5.csv",
        inline: None,
        figures: &[],
    },
    Study {
        name: "zhf-sparsity",
        title: "ZHF Table I, Fig. 3: sparse zonal harmonic factorization",
        paper: "The paper's Table I lists the per-band sparsity of the factorization found \
                by its search, Fig. 3 the cumulative sparsity of shared direction sets by \
                order against random draws; the table below has the paper's numbers beside \
                ours.",
        quick: "--bands 2..3 --orders 4..4 --stall 200 --generations 2000 --restarts 4 \
                --random 200 --markdown {out}/table1.md",
        full: "--bands 2..12 --orders 2..8 --markdown {out}/table1.md",
        inline: Some("table1.md"),
        figures: &[],
    },
];

/// The studies `ifd-paper all` runs, for `ifd-paper list`.
pub fn names() -> impl Iterator<Item = &'static str> {
    STUDIES.iter().map(|s| s.name)
}

impl All {
    /// Runs the studies and writes their pages.
    pub fn run(self) -> Result<()> {
        let out_dir = match (&self.out_dir, self.quick) {
            (Some(d), _) => d.clone(),
            (None, false) => PathBuf::from("docs/papers"),
            (None, true) => bail!(
                "--quick needs --out-dir DIR: docs/papers holds the pages at the documentation's \
                 sizes"
            ),
        };
        if let Some(bad) = self
            .only
            .iter()
            .find(|n| !STUDIES.iter().any(|s| s.name == n.as_str()))
        {
            bail!(
                "--only {bad}: not a study run by `ifd-paper all` (one of: {})",
                names().collect::<Vec<_>>().join(", ")
            );
        }
        if !Path::new("testdata/forest.hdr").is_file() {
            bail!("testdata/forest.hdr not found: run `ifd-paper all` from the repository root");
        }
        let exe = std::env::current_exe().context("locating the ifd-paper binary")?;
        std::fs::create_dir_all(&out_dir)
            .with_context(|| format!("--out-dir {}", out_dir.display()))?;
        let chosen: Vec<&Study> = STUDIES
            .iter()
            .filter(|s| self.only.is_empty() || self.only.iter().any(|n| n == s.name))
            .collect();
        let total = Instant::now();
        for (i, study) in chosen.iter().enumerate() {
            let dir = out_dir.join(study.name);
            std::fs::create_dir_all(&dir)
                .with_context(|| format!("{}: cannot create", dir.display()))?;
            // the page shows only what this run writes: figures of an earlier
            // run (another size) go first
            for f in study.figures.iter().chain(study.inline.iter()) {
                let old = dir.join(f);
                if old.is_file() {
                    std::fs::remove_file(&old)
                        .with_context(|| format!("{}: cannot replace", old.display()))?;
                }
            }
            let template = if self.quick { study.quick } else { study.full };
            let dir_text = dir.to_string_lossy();
            let args: Vec<String> = template
                .split_whitespace()
                .map(|a| a.replace("{out}", &dir_text))
                .collect();
            eprintln!("[{}/{}] ifd-paper {} ...", i + 1, chosen.len(), study.name);
            let start = Instant::now();
            let out = std::process::Command::new(&exe)
                .arg(study.name)
                .args(&args)
                .stdin(std::process::Stdio::null())
                .output()
                .with_context(|| format!("running ifd-paper {}", study.name))?;
            let secs = start.elapsed().as_secs_f64();
            if !out.status.success() {
                let err = String::from_utf8_lossy(&out.stderr);
                bail!(
                    "ifd-paper {} failed ({}):\n{}",
                    study.name,
                    out.status,
                    err.trim_end()
                );
            }
            let page = self.page(
                study,
                &args,
                secs,
                &String::from_utf8_lossy(&out.stdout),
                &dir,
            )?;
            let path = out_dir.join(format!("{}.md", study.name));
            crate::output::write_text(&path, &page)?;
            eprintln!("      {secs:.1} s -> {}", path.display());
        }
        Self::write_index(&out_dir)?;
        eprintln!(
            "{} studies in {:.1} s; pages in {}",
            chosen.len(),
            total.elapsed().as_secs_f64(),
            out_dir.display()
        );
        Ok(())
    }

    /// DIR/README.md: every study with its page, and the scripted studies
    /// with their commands.
    fn write_index(out_dir: &Path) -> Result<()> {
        let mut index = String::from(
            "# The papers' tables and figures, regenerated\n\n\
             Written by `ifd-paper all` (run from the repository root; `--quick` for small \
             sizes). Each page has what the paper reports, the command and its run time, the \
             report, and the figures.\n\n| study | page |\n|---|---|\n",
        );
        for s in STUDIES {
            let page = out_dir.join(format!("{}.md", s.name));
            let link = if page.is_file() {
                format!("[{0}.md]({0}.md)", s.name)
            } else {
                "not run yet".to_owned()
            };
            let _ = writeln!(index, "| {} | {link} |", s.title);
        }
        index.push_str(
            "\nStudies that need a Python peer or `cargo bench` stay scripts:\n\n\
             | study | command |\n|---|---|\n",
        );
        for (_, what, script) in super::SCRIPTED {
            let _ = writeln!(index, "| {what} | `.venv/bin/python {script}` |");
        }
        let path = out_dir.join("README.md");
        crate::output::write_text(&path, &index)
    }

    fn page(
        &self,
        study: &Study,
        args: &[String],
        secs: f64,
        stdout: &str,
        dir: &Path,
    ) -> Result<String> {
        let mut page = String::new();
        let _ = writeln!(page, "# {}\n", study.title);
        let _ = writeln!(page, "## What the paper reports\n\n{}\n", study.paper);
        let _ = writeln!(
            page,
            "## This run\n\n{}, {secs:.1} s on this machine ({} threads):\n\n```sh\nifd-paper {} {}\n```\n",
            if self.quick {
                "Small sizes (`ifd-paper all --quick`: checks that the study runs, not the paper's sizes)"
            } else {
                "The documentation's sizes (`ifd-paper all`)"
            },
            rayon::current_num_threads(),
            study.name,
            args.join(" ")
        );
        // a study that writes its own table (the paper beside ours) is shown
        // by it; the others by their report
        if let Some(name) = study.inline {
            let text = std::fs::read_to_string(dir.join(name))
                .with_context(|| format!("{}: not written", dir.join(name).display()))?;
            let _ = writeln!(page, "{}\n", text.trim_end());
        } else if stdout.contains("\n|---") {
            let _ = writeln!(page, "{}\n", stdout.trim_end());
        } else {
            let _ = writeln!(page, "```text\n{}\n```\n", stdout.trim_end());
        }
        for f in study.figures {
            // a figure the study did not write (the quick sizes skip some) is left out
            if dir.join(f).is_file() {
                let _ = writeln!(page, "![{f}]({}/{f})\n", study.name);
            }
        }
        Ok(page)
    }
}
