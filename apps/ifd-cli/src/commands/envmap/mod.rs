//! `ifd envmap`: image-based lighting assets for engines. One module per
//! subcommand.

mod dfg;
mod prefilter;

use anyhow::Result;
use clap::{Args, Subcommand};

/// `ifd envmap prefilter|dfg`.
#[derive(Debug, Args)]
pub struct Envmap {
    #[command(subcommand)]
    command: EnvmapCommand,
}

#[derive(Debug, Subcommand)]
enum EnvmapCommand {
    /// Bake GGX-prefiltered radiance mips, an irradiance map and SH coefficients (KTX2 or EXR).
    Prefilter(Box<prefilter::PrefilterCmd>),
    /// Write the split-sum DFG table (x = N.V, y = roughness; R = scale, G = bias).
    Dfg(dfg::DfgCmd),
    /// Moved: `ifd-paper shrm-table4` and `ifd-paper shrm-table5`.
    #[command(hide = true, disable_help_flag = true)]
    Shrm(crate::commands::paper::Moved),
}

impl Envmap {
    pub fn run(self) -> Result<()> {
        match self.command {
            EnvmapCommand::Prefilter(c) => c.run(),
            EnvmapCommand::Dfg(c) => c.run(),
            EnvmapCommand::Shrm(_) => crate::commands::paper::Moved::refuse(
                "ifd envmap shrm --table N",
                "ifd-paper shrm-table4 or shrm-table5",
                "--table is gone",
            ),
        }
    }
}
