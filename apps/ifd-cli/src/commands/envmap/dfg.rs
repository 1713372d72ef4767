//! `ifd envmap dfg`: the split-sum DFG table.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Result, bail};
use clap::Args;
use serde_json::json;

use crate::options::ReportOptions;

/// Writes the split-sum DFG table: texel (i, j) holds N.V = (i + 0.5)/size
/// (left to right) and perceptual roughness (j + 0.5)/size (top to bottom,
/// alpha = roughness^2), R = scale A, G = bias B (specular = F0 A + B), B = 0.
/// Computed by deterministic quadrature (docs/ibl.md). EXR keeps floats; PNG
/// is written with 16 bits.
#[derive(Debug, Args)]
pub(super) struct DfgCmd {
    /// Table side N (the table is N x N), 2 to 1024.
    #[arg(long, value_name = "N", default_value_t = 128)]
    table_size: usize,
    /// Output image (.exr, .png, .npy, ...).
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    report: ReportOptions,
}

/// The largest --table-size: every texel is a quadrature of about 0.3 ms on
/// 2 cores (128 in 4 to 7 s, 256 in 20 s), so 1024 takes about five minutes
/// and 4096 would take hours.
const MAX_TABLE_SIZE: usize = 1024;

/// The `size x size` table of [`ifd_ibl::dfg_table`] with a progress bar
/// by rows.
fn dfg_table_with_progress(size: usize) -> Vec<[f32; 2]> {
    let bar = crate::progress::bar("DFG table", "rows", size as u64);
    let table = ifd_ibl::dfg_table_with_progress(size, &|| bar.inc(1));
    bar.finish_and_clear();
    table
}

impl DfgCmd {
    pub(super) fn run(self) -> Result<()> {
        let size = self.table_size;
        if !(2..=MAX_TABLE_SIZE).contains(&size) {
            bail!(
                "--table-size {size}: must lie in 2..={MAX_TABLE_SIZE} (each texel is a \
                 quadrature: 1024 takes about five minutes on 2 cores)"
            );
        }
        crate::output::check_output_path(&self.output)?;
        let t = Instant::now();
        let table = dfg_table_with_progress(size);
        let data: Vec<f32> = table.iter().flat_map(|[a, b]| [*a, *b, 0.0]).collect();
        let img = ifd_image::Image::from_vec(size, size, 3, data)?;
        let opts = ifd_image::WriteOptions {
            bit_depth: ifd_image::BitDepth::Sixteen,
            ..ifd_image::WriteOptions::default()
        };
        crate::output::write_output(&self.output, &img, &opts)?;
        // three lines: kept as the summary
        let report = json!({"size": size, "output": self.output.display().to_string(),
               "seconds": t.elapsed().as_secs_f64()});
        self.report.emit(&report)?;
        Ok(())
    }
}
