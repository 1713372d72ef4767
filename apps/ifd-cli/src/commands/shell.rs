//! `ifd completions SHELL` and `ifd manpages --out-dir DIR`: shell
//! completions and man pages generated from the command line's own
//! definitions (`clap_complete`, `clap_mangen`), so they cannot drift from
//! `--help`. `scripts/dist.sh` puts both in the release archive.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;

/// Print a completion script for a shell (bash, zsh, fish, elvish, powershell) to standard output.
///
/// bash: `ifd completions bash > ~/.local/share/bash-completion/completions/ifd`;
/// zsh: into a folder of `$fpath` as `_ifd`; fish: `~/.config/fish/completions/ifd.fish`.
#[derive(Debug, Args)]
pub struct Completions {
    /// The shell.
    shell: clap_complete::Shell,
}

impl Completions {
    /// Writes the script for `cmd` (the whole `ifd` command line).
    pub fn run(self, mut cmd: clap::Command) {
        let mut out = Vec::new();
        clap_complete::generate(self.shell, &mut cmd, "ifd", &mut out);
        // print!: a reader that closes the pipe early ends the process
        // quietly (status 141), as for every other command
        print!("{}", String::from_utf8_lossy(&out));
    }
}

/// Write man pages into a folder: ifd.1 and one page per subcommand (ifd-filter.1, ifd-envmap-bake.1, ...).
#[derive(Debug, Args)]
pub struct Manpages {
    /// Output folder (created if missing; pages in it are replaced).
    #[arg(long, value_name = "DIR")]
    out_dir: PathBuf,
}

impl Manpages {
    /// Writes the pages of `cmd` and of each of its subcommands.
    pub fn run(self, cmd: clap::Command) -> Result<()> {
        let out = &self.out_dir;
        if out.exists() && !out.is_dir() {
            bail!("{}: exists and is not a folder", out.display());
        }
        std::fs::create_dir_all(out)
            .with_context(|| format!("{}: cannot create the output folder", out.display()))?;
        let mut pages = Vec::new();
        collect(cmd, "", &mut pages);
        for (name, cmd) in &pages {
            let mut text = Vec::new();
            clap_mangen::Man::new(cmd.clone())
                .render(&mut text)
                .with_context(|| format!("rendering the man page of {name}"))?;
            write_atomically(&out.join(format!("{name}.1")), &text)?;
        }
        println!("wrote {} man pages to {}", pages.len(), out.display());
        Ok(())
    }
}

/// `cmd` named by its path (`ifd`, `ifd-envmap`, `ifd-envmap-bake`) and its
/// subcommands after it, depth first; `help` left out.
fn collect(cmd: clap::Command, parent: &str, pages: &mut Vec<(String, clap::Command)>) {
    let name = if parent.is_empty() {
        cmd.get_name().to_string()
    } else {
        format!("{parent}-{}", cmd.get_name())
    };
    // clap keeps `'static` names (its `string` feature would rebuild clap
    // for every binary); a few dozen short strings, once per process
    let leak = |s: String| -> &'static str { Box::leak(s.into_boxed_str()) };
    let cmd = cmd
        .name(leak(name.clone()))
        .bin_name(leak(name.replace('-', " ")))
        .version(env!("CARGO_PKG_VERSION"))
        .disable_help_subcommand(true);
    let subs: Vec<clap::Command> = cmd
        .get_subcommands()
        .filter(|s| s.get_name() != "help")
        .cloned()
        .collect();
    pages.push((name.clone(), cmd));
    for s in subs {
        collect(s, &name, pages);
    }
}

/// Writes `bytes` to `path` atomically ([`ifd_image::atomic_write`]: an
/// interrupted run leaves no partial page).
fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    ifd_image::atomic_write(path, |w| {
        std::io::Write::write_all(w, bytes).map_err(|e| e.to_string())
    })
    .map_err(anyhow::Error::from)
}
