//! `ifd sphere eval`: evaluate the real SH at directions.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use ifd_image::write_npy_f64;
use ifd_sphere::read_npy_f64;

use ifd_sphere::ShEvaluator;

/// `ifd sphere eval --lmax L --dirs dirs.npy -o values.npy`.
#[derive(Debug, Args)]
pub(super) struct EvalCmd {
    /// Maximum degree L.
    #[arg(long, value_name = "L")]
    lmax: usize,
    /// Directions, (N, 3) .npy (normalised here).
    #[arg(long)]
    dirs: PathBuf,
    /// Use the f32 fast path (values still written as float64).
    #[arg(long)]
    f32: bool,
    /// Output (N, (L+1)^2) float64 .npy.
    #[arg(short, long)]
    output: PathBuf,
}

impl EvalCmd {
    pub(super) fn run(self) -> Result<()> {
        crate::output::check_npy_output(&self.output, "-o", "the table of SH values")?;
        let (shape, data) = read_npy_f64(&self.dirs)?;
        let [n, 3] = shape.as_slice() else {
            bail!(
                "{}: expected an (N, 3) array, got {shape:?}",
                self.dirs.display()
            );
        };
        let sh = ShEvaluator::new(self.lmax).with_context(|| format!("--lmax {}", self.lmax))?;
        let k = sh.count();
        ifd_image::MemoryBudget::default_for_machine()
            .check((n.saturating_mul(k) as u64).saturating_mul(8))
            .with_context(|| format!("{} directions at --lmax {}", n, self.lmax))?;
        let mut out = vec![0.0; n * k];
        let mut y32 = vec![0.0f32; k];
        for i in 0..*n {
            // normalised here, so that the f32 path sees a unit vector too
            let d = ifd_sphere::check_direction(i, [data[3 * i], data[3 * i + 1], data[3 * i + 2]])
                .with_context(|| format!("--dirs {}", self.dirs.display()))?;
            if self.f32 {
                sh.eval_f32_into([d[0] as f32, d[1] as f32, d[2] as f32], &mut y32);
                for (o, v) in out[i * k..(i + 1) * k].iter_mut().zip(&y32) {
                    *o = f64::from(*v);
                }
            } else {
                sh.eval_into(d, &mut out[i * k..(i + 1) * k]);
            }
        }
        write_npy_f64(&self.output, &[*n, k], &out)?;
        Ok(())
    }
}
