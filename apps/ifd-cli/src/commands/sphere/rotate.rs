//! `ifd sphere rotate`: rotate SH coefficients.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};

use ifd_sphere::{Chooser, DirectionSet, RzhBasis, Sharing};
use ifd_sphere::{Rotation, ShCoeffs, ShRotation};

#[derive(Debug, Clone, Copy, ValueEnum)]
pub(super) enum Method {
    /// ZHF standard algorithm (ZHF Eq. 10), shared Fibonacci lobes; L <= 400.
    Zhf,
    /// Signal-tailored ZHF (ZHF Eq. 11), shared Fibonacci lobes; L <= 400.
    Tailored,
    /// Ivanic-Ruedenberg recurrences; L <= 1000.
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

/// The largest degree of the ZHF methods: their cost grows as L^4 (measured
/// on 2 cores: L = 200 in 3.6 s, 300 in 18 s, 400 in 65 s), so beyond this a
/// run takes many minutes; the reference rotation does L = 1000 in about 30 s.
const MAX_ZHF_DEGREE: usize = 400;

/// Bytes a rotation of degree `l` holds, estimated from the `(2l + 1)^2`
/// float64 band matrices, `sum (2l + 1)^2 = (L + 1)(2L + 1)(2L + 3) / 3`
/// (the reference rotation stores each once; the ZHF methods hold about
/// four times as much, measured).
fn rotation_bytes(l: usize, method: Method) -> u64 {
    let l = l as u64;
    let blocks = (l + 1) * (2 * l + 1) * (2 * l + 3) / 3 * 8;
    match method {
        Method::Reference => blocks,
        Method::Zhf | Method::Tailored => 4 * blocks,
    }
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
        crate::output::check_npy_output(&self.output, "-o", "the SH coefficient table")?;
        let (f, shape) = ShCoeffs::read_npy_shaped(&self.coeffs)?;
        let r = Rotation::from_zyz(a, b, c);
        let l = f.l_max();
        if l > MAX_ZHF_DEGREE && !matches!(self.method, Method::Reference) {
            let name = self
                .method
                .to_possible_value()
                .map(|v| v.get_name().to_string())
                .unwrap_or_default();
            bail!(
                "--method {name}: {} holds coefficients of degree L = {l}, but this method \
                 rotates at most L = {MAX_ZHF_DEGREE} (its time grows as L^4: L = 400 takes about \
                 a minute on 2 cores); --method reference rotates up to L = {}",
                self.coeffs.display(),
                ifd_sphere::MAX_DEGREE
            );
        }
        ifd_image::MemoryBudget::default_for_machine()
            .check(rotation_bytes(l, self.method))
            .with_context(|| format!("rotating {} (L = {l})", self.coeffs.display()))?;
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
        // the input's shape: ((L+1)^2,) stays 1-D
        ifd_image::write_npy_f64(&self.output, &shape, g.data())?;
        Ok(())
    }
}
