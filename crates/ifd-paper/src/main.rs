//! `ifd-paper`: the reproductions of the papers' tables and figures, apart
//! from the `ifd` tool. Each study is one subcommand; `ifd-paper list` names
//! them with what each regenerates, and the studies that stay scripts (they
//! need a Python peer or `cargo bench`) with their commands.
//!
//! Exit codes as `ifd`'s: 0 on success, 2 for bad input or any other error,
//! 101 for an internal bug (a panic).

// Doc comments of the commands are clap help text, shown verbatim to users:
// formulas and `HxW` in backticks would read worse there.
#![expect(clippy::doc_markdown, reason = "doc comments are clap help text")]

use std::io::Write as _;
use std::process::ExitCode;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

mod cli;

// The option groups (`--env`, `--scene`, the camera, `--json`, ...), the
// input reader and the output writers of the `ifd` binary, compiled into
// this one from their one source, so that a flag the two binaries share has
// one definition, one meaning and one message. `ifd-paper` does not depend
// on the `ifd-cli` package (a binary); these three files must only use the
// library crates and each other. Not every item is used by the studies.
#[allow(dead_code, reason = "the studies use part of the shared option groups")]
#[path = "../../../apps/ifd-cli/src/input.rs"]
mod input;
#[allow(dead_code, reason = "the studies use part of the shared option groups")]
#[path = "../../../apps/ifd-cli/src/options.rs"]
mod options;
#[allow(dead_code, reason = "the studies use part of the shared writers")]
#[path = "../../../apps/ifd-cli/src/output.rs"]
mod output;

/// Reproduce the papers' tables and figures (`ifd-paper list` names them and
/// what each regenerates).
#[derive(Debug, Parser)]
#[command(name = "ifd-paper", version, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// List the studies, what each regenerates, and the scripted ones with their commands.
    List,
    /// Run every study (or --only some) into one Markdown page each, the paper beside this run.
    All(cli::all::All),
    /// ISD Fig. 4: error of ISD and its SH reference against the exact oracle as L grows.
    IsdConvergence(Box<cli::isd_convergence::IsdConvergence>),
    /// ISD Fig. 13: condition number of M against L for every profile, per-band and shared directions.
    IsdCondition(cli::isd_condition::IsdCondition),
    /// ISD Sec. 6.2, Fig. 6: anti-aliased reflections on a bumpy mirror against supersampling.
    IsdMirror(cli::isd_mirror::Mirror),
    /// ISD Eq. 25, App. A: self-shadowed shading on a mesh against a ray-traced reference.
    IsdVisibility(cli::isd_visibility::Visibility),
    /// SHRM Table 4: Phong prefiltering, angular against frequency space.
    ShrmTable4(cli::shrm::ShrmTable4),
    /// SHRM Table 5: the microfacet BRDF of Eq. 11, SHRM against angular reflection maps.
    ShrmTable5(cli::shrm::ShrmTable5),
    /// ZHF Sec. 5-6, Table I, Fig. 3: lobe directions that make the ZHF matrix sparse.
    ZhfSparsity(cli::zhf_sparsity::SparsityCmd),
}

/// `--env-rotate -30` must reach the study's own check rather than be taken
/// for an unknown flag: every (sub)command accepts negative numbers as values
/// (as in `ifd`).
fn allow_negative_numbers(cmd: clap::Command) -> clap::Command {
    cmd.allow_negative_numbers(true)
        .mut_subcommands(allow_negative_numbers)
}

fn main() -> ExitCode {
    let matches = allow_negative_numbers(Cli::command()).get_matches();
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    // Ctrl-C or SIGTERM mid-write: outputs are written to hidden temporary
    // files renamed into place when complete; remove those, so that an
    // interrupted run leaves nothing behind.
    let handler = ctrlc::set_handler(|| {
        let n = ifd_image::remove_pending_outputs();
        let _ = writeln!(
            std::io::stderr(),
            "interrupted: {n} unfinished output file(s) removed"
        );
        std::process::exit(130);
    });
    if let Err(e) = handler {
        eprintln!(
            "warning: cannot handle interruptions ({e}); an interrupted run may leave .ifd-tmp-* files"
        );
    }
    let result = match cli.command {
        Command::List => {
            cli::list(&Cli::command());
            Ok(())
        }
        Command::All(c) => c.run(),
        Command::IsdConvergence(c) => c.run(),
        Command::IsdCondition(c) => c.run(),
        Command::IsdMirror(c) => c.run(),
        Command::IsdVisibility(c) => c.run(),
        Command::ShrmTable4(c) => c.run(),
        Command::ShrmTable5(c) => c.run(),
        Command::ZhfSparsity(c) => c.run(),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `docs/reference/cli/ifd-paper.json` is what this binary defines, and
    /// the tree alone follows the grammar (the binaries together are checked
    /// by `ifd-clidoc`'s tests, against the checked-in files).
    #[test]
    fn the_command_line_matches_its_checked_in_schema_and_the_grammar() {
        if let Err(e) = ifd_clidoc::check_binary(allow_negative_numbers(Cli::command())) {
            panic!("{e}");
        }
    }

    #[test]
    fn clap_accepts_the_definitions() {
        Cli::command().debug_assert();
    }
}
