//! `ifd paper ...`: reproductions of the papers' tables and figures, apart
//! from the tools. Each study is one subcommand; `ifd paper list` names them
//! with what each regenerates, and the studies that stay scripts (they need
//! a Python peer or `cargo bench`) with their commands.

use anyhow::Result;
use clap::{Args, Subcommand};

pub mod all;
pub mod isd_condition;
pub mod isd_convergence;
pub mod isd_mirror;
pub mod isd_visibility;
pub mod shrm;
pub mod zhf_sparsity;

/// Reproductions of the papers' tables and figures (`ifd paper list` names
/// them and what each regenerates).
#[derive(Debug, Args)]
pub struct Paper {
    #[command(subcommand)]
    command: PaperCommand,
}

#[derive(Debug, Subcommand)]
enum PaperCommand {
    /// List the studies, what each regenerates, and the scripted ones with their commands.
    List,
    /// Run every study (or --only some) into one Markdown page each, the paper beside this run.
    All(all::All),
    /// ISD Fig. 4: error of ISD and its SH reference against the exact oracle as L grows.
    IsdConvergence(Box<isd_convergence::IsdConvergence>),
    /// ISD Fig. 13: condition number of M against L for every profile, per-band and shared directions.
    IsdCondition(isd_condition::IsdCondition),
    /// ISD Sec. 6.2, Fig. 6: anti-aliased reflections on a bumpy mirror against supersampling.
    IsdMirror(isd_mirror::Mirror),
    /// ISD Eq. 25, App. A: self-shadowed shading on a mesh against a ray-traced reference.
    IsdVisibility(isd_visibility::Visibility),
    /// SHRM Table 4: Phong prefiltering, angular against frequency space.
    ShrmTable4(shrm::ShrmTable4),
    /// SHRM Table 5: the microfacet BRDF of Eq. 11, SHRM against angular reflection maps.
    ShrmTable5(shrm::ShrmTable5),
    /// ZHF Sec. 5-6, Table I, Fig. 3: lobe directions that make the ZHF matrix sparse.
    ZhfSparsity(zhf_sparsity::SparsityCmd),
}

/// The studies that stay scripts, with their commands.
const SCRIPTED: &[(&str, &str, &str)] = &[
    (
        "isd-table1",
        "ISD Table I: lobe-table memory and error against SH tables",
        "tests/bench/isd_table1.py",
    ),
    (
        "zhf-table2",
        "ZHF Table II: rotation cost against zxzxz and ducc0 (needs the Python venv)",
        "tests/bench/zhf_table2.py",
    ),
    (
        "ifd-decomposition-table",
        "IFD decomposition table: terms and errors per kernel",
        "tests/bench/decompose_report.py",
    ),
    (
        "ifd-vs-opencv",
        "IFD Figs. 3-4 against OpenCV: time against PSNR (needs the Python venv)",
        "tests/bench/curves_vs_opencv.py",
    ),
];

impl Paper {
    /// Runs the study.
    pub fn run(self) -> Result<()> {
        match self.command {
            PaperCommand::List => {
                list();
                Ok(())
            }
            PaperCommand::All(c) => c.run(),
            PaperCommand::IsdConvergence(c) => c.run(),
            PaperCommand::IsdCondition(c) => c.run(),
            PaperCommand::IsdMirror(c) => c.run(),
            PaperCommand::IsdVisibility(c) => c.run(),
            PaperCommand::ShrmTable4(c) => c.run(),
            PaperCommand::ShrmTable5(c) => c.run(),
            PaperCommand::ZhfSparsity(c) => c.run(),
        }
    }
}

fn list() {
    use clap::CommandFactory as _;
    let cmd = crate::Cli::command();
    let paper = cmd.find_subcommand("paper");
    println!("studies (ifd paper NAME --help for each one's flags):");
    for sub in paper
        .into_iter()
        .flat_map(clap::Command::get_subcommands)
        .filter(|s| !matches!(s.get_name(), "list" | "all" | "help"))
    {
        println!(
            "  {:<18} {}",
            sub.get_name(),
            sub.get_about().map(ToString::to_string).unwrap_or_default()
        );
    }
    println!(
        "\n`ifd paper all [--quick]` runs {} into one page each (docs/papers/NAME.md)",
        all::names().collect::<Vec<_>>().join(", ")
    );
    println!("\nscripted studies (run from the repository root):");
    for (name, what, script) in SCRIPTED {
        println!("  {name:<24} {what}\n  {:<24} {script}", "");
    }
}
