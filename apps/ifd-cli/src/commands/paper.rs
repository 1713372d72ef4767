//! Commands that moved to the `ifd-paper` binary (the reproductions of the
//! papers' tables and figures, `crates/ifd-paper`): `ifd paper ...` and the
//! older spellings of the studies are refused with the new spelling.

use anyhow::{Result, bail};
use clap::Args;

/// An old spelling of a command that moved: every argument is taken and the
/// command refuses to run, naming the new spelling (never reinterpreted).
#[derive(Debug, Args)]
pub struct Moved {
    /// Anything the old command took.
    #[arg(trailing_var_arg = true, allow_hyphen_values = true, hide = true)]
    rest: Vec<String>,
}

impl Moved {
    /// Refuses to run, naming the new spelling (and `renamed`, the flags
    /// renamed in the move, if any).
    pub fn refuse(old: &str, new: &str, renamed: &str) -> Result<()> {
        if renamed.is_empty() {
            bail!("`{old}` has moved: use `{new}` (see `ifd-paper list`)")
        }
        bail!("`{old}` has moved: use `{new}` ({renamed}; see `ifd-paper list`)")
    }
}
