//! `ifd`: isotropic filter decomposition from the command line.
//!
//! Exit codes: 0 on success, 2 for bad input or any other error (the message
//! names the file and the problem), 101 for an internal bug (a panic).

// Doc comments of the commands are clap help text, shown verbatim to users:
// formulas and `HxW` in backticks would read worse there.
#![expect(clippy::doc_markdown, reason = "doc comments are clap help text")]

use std::io::Write as _;
use std::process::ExitCode;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

mod alloc;
mod commands;
mod input;
mod options;
mod output;
mod progress;
/// Unit tests that cannot run on this machine record themselves as skipped.
#[cfg(test)]
#[path = "../../../tests/support/skip.rs"]
mod test_skip;

#[global_allocator]
static ALLOCATOR: alloc::HugePages = alloc::HugePages;

/// Isotropic filter decomposition: apply huge, anisotropic, rotated, scaled,
/// spatially varying filters at the cost of a few lookups per pixel.
#[derive(Debug, Parser)]
#[command(name = "ifd", version, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Compare two images: PSNR, SSIM, max and mean absolute error, per channel and overall.
    Compare(commands::compare::Compare),
    /// Decompose a 2D filter into a sparse sum of displaced isotropic Gaussians.
    Decompose(commands::decompose::Decompose),
    /// Filter an image with a decomposed filter, rotated and scaled per pixel.
    Filter(commands::filter::Filter),
    /// Write a synthetic per-pixel angle or scale field (.npy).
    Field(commands::field::FieldCmd),
    /// Convert an image between formats (PNG, JPEG, TIFF, EXR, HDR, NPY).
    Convert(commands::convert::Convert),
    /// Print an image's size, channels, format and value range.
    Info(commands::info::Info),
    /// Print the GPU adapter that `--gpu` uses, its limits and timestamp support.
    GpuInfo(commands::gpu_info::GpuInfo),
    /// Hessian (Hxx, Hxy, Hyy) of an image at a scale, computed with IFD.
    Hessian(commands::hessian::Hessian),
    /// Edge-respecting anisotropic smoothing driven by the image Hessian.
    Smooth(commands::smooth::Smooth),
    /// Spherical harmonics, SH rotation and isotropic spherical decompositions.
    Sphere(commands::sphere::Sphere),
    /// Render an object lit by an environment map: ISD shading (Eq. 22; self-shadowed meshes, Eq. 25; anti-aliased mirrors, Eq. 29), its SH reference, the exact quadrature or Monte Carlo.
    Render(Box<commands::render::Render>),
    /// Image-based lighting for engines: prefiltered GGX radiance mips, irradiance, SH (KTX2), the DFG table.
    Envmap(commands::envmap::Envmap),
    /// Print a shell completion script (bash, zsh, fish, elvish, powershell).
    Completions(commands::shell::Completions),
    /// Write the man pages of ifd and its subcommands into a folder.
    Manpages(commands::shell::Manpages),
}

/// `--scale -1` must reach the command's own check (which names the option
/// and says what is wrong) rather than be taken for an unknown flag: every
/// (sub)command accepts negative numbers as values.
fn allow_negative_numbers(cmd: clap::Command) -> clap::Command {
    cmd.allow_negative_numbers(true)
        .mut_subcommands(allow_negative_numbers)
}

/// `ifd --version`: the version, the commit the binary was built from and
/// the vector path the CPU kernels take here (`ifd_simd`: avx512, avx2 or
/// baseline; `IFD_SIMD` caps it).
fn version_line() -> &'static str {
    let line = format!(
        "{} (commit {}, vector path {})",
        env!("CARGO_PKG_VERSION"),
        env!("IFD_COMMIT"),
        ifd_simd::isa().name()
    );
    // once per process: clap keeps `'static` strings
    Box::leak(line.into_boxed_str())
}

/// A reader that closes the pipe early (`ifd info x.exr | head -3`) makes
/// `println!` panic; end quietly instead, as a process killed by SIGPIPE
/// does (status 141), and on other failures to write the standard output
/// (a full disk) with one error line and status 2, unfinished outputs
/// removed either way. Other panics keep the default report.
fn quiet_on_closed_stdout() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let message = info
            .payload()
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| info.payload().downcast_ref::<&str>().copied())
            .unwrap_or("");
        if let Some(reason) = message.strip_prefix("failed printing to stdout: ") {
            ifd_image::remove_pending_outputs();
            if reason.contains("Broken pipe") {
                std::process::exit(141);
            }
            let _ = writeln!(
                std::io::stderr(),
                "error: writing to standard output: {reason}"
            );
            std::process::exit(2);
        }
        default(info);
    }));
}

fn main() -> ExitCode {
    quiet_on_closed_stdout();
    let matches = allow_negative_numbers(Cli::command())
        .version(version_line())
        .get_matches();
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    // Ctrl-C or SIGTERM mid-write: outputs are written to hidden temporary
    // files renamed into place when complete; remove those, so that an
    // interrupted run leaves nothing behind.
    let handler = ctrlc::set_handler(|| {
        let n = ifd_image::remove_pending_outputs();
        // not eprintln!: it panics on a closed stderr (a pipe whose reader
        // is gone), which would end this handler's thread before the exit
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
        Command::Compare(c) => c.run(),
        Command::Decompose(c) => c.run(),
        Command::Filter(c) => c.run(),
        Command::Field(c) => c.run(),
        Command::Sphere(c) => c.run(),
        Command::Render(c) => c.run(),
        Command::Envmap(c) => c.run(),
        Command::Convert(c) => c.run(),
        Command::Info(c) => c.run(),
        Command::GpuInfo(c) => c.run(),
        Command::Hessian(c) => c.run(),
        Command::Smooth(c) => c.run(),
        Command::Completions(c) => {
            c.run(allow_negative_numbers(Cli::command()));
            Ok(())
        }
        Command::Manpages(c) => c.run(allow_negative_numbers(Cli::command())),
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

    /// `docs/reference/cli/ifd.json` is what this binary defines, and the
    /// tree alone follows the grammar (the binaries together are
    /// checked by `ifd-clidoc`'s tests, against the checked-in files).
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
