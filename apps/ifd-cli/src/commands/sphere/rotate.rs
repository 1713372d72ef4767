//! `ifd sphere rotate`: rotate SH coefficients.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};

use ifd_sphere::{Chooser, DirectionSet, RzhBasis, Sharing};
use ifd_sphere::{Rotation, ShCoeffs, ShRotation};

#[derive(Debug, Clone, Copy, ValueEnum)]
pub(super) enum Method {
    /// ZHF standard algorithm (ZHF Eq. 10), shared Fibonacci lobes.
    Zhf,
    /// Signal-tailored ZHF (ZHF Eq. 11), shared Fibonacci lobes.
    Tailored,
    /// Ivanic-Ruedenberg recurrences.
    Reference,
}

/// `ifd sphere rotate coeffs.npy --zyz a,b,c -o out.npy`.
#[derive(Debug, Args)]
pub(super) struct RotateCmd {
    /// SH coefficients, ((L+1)^2, C) or ((L+1)^2,) .npy (float64 or float32).
    coeffs: PathBuf,
    /// Euler angles a,b,c in radians: R = Rz(a) Ry(b) Rz(c); the result is g(w) = f(R^T w).
    #[arg(long, value_name = "A,B,C", allow_hyphen_values = true)]
    zyz: String,
    /// Rotation algorithm.
    #[arg(long, value_enum, default_value_t = Method::Zhf)]
    method: Method,
    /// Output coefficients (float64 .npy, same shape).
    #[arg(short, long)]
    output: PathBuf,
}

fn parse_triple(s: &str) -> Result<(f64, f64, f64)> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .with_context(|| format!("--zyz {s:?}: expected three numbers a,b,c"))?;
    if v.len() != 3 || v.iter().any(|x| !x.is_finite()) {
        bail!("--zyz {s:?}: expected three finite numbers a,b,c (radians)");
    }
    Ok((v[0], v[1], v[2]))
}

impl RotateCmd {
    pub(super) fn run(self) -> Result<()> {
        let (a, b, c) = parse_triple(&self.zyz)?;
        let f = ShCoeffs::read_npy(&self.coeffs)?;
        let r = Rotation::from_zyz(a, b, c);
        let l = f.l_max();
        let g = match self.method {
            Method::Reference => ShRotation::new(&r, l)?.apply(&f)?,
            Method::Zhf | Method::Tailored => {
                let basis =
                    RzhBasis::new(DirectionSet::new(l, Sharing::Shared, Chooser::Fibonacci)?)?;
                if matches!(self.method, Method::Zhf) {
                    basis.rotate(&f, &r)?
                } else {
                    basis.rotate_tailored(&f, &r)?
                }
            }
        };
        g.write_npy(&self.output)?;
        Ok(())
    }
}
