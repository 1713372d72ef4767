//! `ifd gpu-info`.

use anyhow::Result;
use clap::Args;

/// Print the GPU adapter that `--gpu` uses (name, type, driver, limits,
/// timestamp support), or why there is none.
///
/// The adapter is chosen headless: a hardware GPU when there is one,
/// otherwise a software Vulkan driver (Mesa's lavapipe). `WGPU_BACKEND` is
/// honoured when set.
#[derive(Debug, Args)]
pub struct GpuInfo {
    /// Also list every adapter found, best first.
    #[arg(long)]
    all: bool,
}

impl GpuInfo {
    /// Runs the command.
    pub fn run(self) -> Result<()> {
        if self.all {
            let adapters = ifd_gpu::list_adapters();
            println!("adapters found: {}", adapters.len());
            for a in &adapters {
                println!(
                    "  {} ({:?}, {:?}, driver {} {})",
                    a.name, a.device_type, a.backend, a.driver, a.driver_info
                );
            }
        }
        let ctx = ifd_gpu::GpuContext::new()?;
        println!("{}", ctx.describe());
        if ctx.is_software() {
            println!("note: a software (CPU) adapter: expect CPU-like speed");
        }
        Ok(())
    }
}
