//! `ifd gpu-info`.

use std::fmt::Write as _;

use anyhow::Result;
use clap::Args;
use serde_json::json;

use crate::options::ReportOptions;

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
    #[command(flatten)]
    report: ReportOptions,
}

impl GpuInfo {
    /// Runs the command.
    pub fn run(self) -> Result<()> {
        let adapters = self.all.then(ifd_gpu::list_adapters);
        let ctx = ifd_gpu::GpuContext::new()?;
        // (a macro: the adapter type is wgpu's, not a dependency here)
        macro_rules! describe {
            ($a:expr) => {{
                let a = $a;
                json!({
                    "name": a.name,
                    "type": format!("{:?}", a.device_type),
                    "backend": format!("{:?}", a.backend),
                    "driver": a.driver,
                    "driver_info": a.driver_info,
                    "vendor": a.vendor,
                    "device": a.device,
                })
            }};
        }
        let limits = ctx.device().limits();
        let report = json!({
            "adapter": describe!(ctx.adapter_info()),
            "software": ctx.is_software(),
            "timestamp_queries": ctx.has_timestamps(),
            "limits": {
                "max_buffer_size": limits.max_buffer_size,
                "max_storage_buffer_binding_size": limits.max_storage_buffer_binding_size,
                "max_texture_dimension_2d": limits.max_texture_dimension_2d,
                "max_compute_workgroups_per_dimension": limits.max_compute_workgroups_per_dimension,
            },
            "adapters": adapters.as_ref().map(|list| list.iter().map(|a| describe!(a)).collect::<Vec<_>>()),
        });
        // the adapters found (--all, asked for), then the chosen one: its
        // first two lines and timestamp support by default, every limit with -v
        let text = |detail: bool| {
            let mut text = String::new();
            if let Some(list) = &adapters {
                let _ = writeln!(text, "adapters found: {}", list.len());
                for a in list {
                    let _ = writeln!(
                        text,
                        "  {} ({:?}, {:?}, driver {} {})",
                        a.name, a.device_type, a.backend, a.driver, a.driver_info
                    );
                }
            }
            let described = ctx.describe();
            if detail {
                text += &described;
                text.push('\n');
            } else {
                for line in described.lines().filter(|l| {
                    l.starts_with("adapter: ")
                        || l.starts_with("driver: ")
                        || l.starts_with("timestamp queries: ")
                }) {
                    text += line;
                    text.push('\n');
                }
            }
            if ctx.is_software() {
                text += "note: a software (CPU) adapter: expect CPU-like speed\n";
            }
            text
        };
        self.report
            .emit_detailed(&report, || text(false), || text(true))
    }
}
