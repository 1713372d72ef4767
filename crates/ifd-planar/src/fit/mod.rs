//! Fitting a [`Decomposition`] to a [`Kernel`]: Eq. 4 of the IFD paper solved by
//! `SpaRSA` over the `MoG` [`Dictionary`].

use std::time::Instant;

use serde::{Deserialize, Serialize};

use crate::decomposition::{Decomposition, FitReport};
use crate::dictionary::{Dictionary, DictionaryError, DictionaryOptions, DictionaryParams};
use crate::kernel::{Kernel, KernelSpec, Sampling};
use crate::sparsa::{LinearOperator, Sparsa, StopCriterion};

mod eliminate;
mod linalg;

use eliminate::{Candidate, DcConstraint, Fitter, STAGE_ITER, sampled_sum};

/// Options of [`decompose`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DecomposeOptions {
    /// Regularisation weight relative to `||A^T y||_inf` (in `(0, 1)`); `None`
    /// chooses it from `tol`.
    pub alpha: Option<f64>,
    /// Most terms allowed.
    pub max_terms: Option<usize>,
    /// Target relative L2 error of the fit.
    pub tol: f64,
    /// The dictionary.
    pub dictionary: DictionaryOptions,
    /// `SpaRSA` iteration limit (all stages together).
    pub max_iter: usize,
    /// Drop small terms after the fit while the error stays within `tol`.
    pub prune: bool,
    /// Relative duality gap at which each continuation stage stops (the
    /// support matters more than the exact weights, which are refitted).
    pub stage_gap: f64,
    /// Continuation stages solved (and pruned) after the first one that
    /// reaches `tol`; the sparsest result wins.
    pub extra_stages: usize,
    /// Pixels of zeros fitted around the kernel's window; `None`:
    /// `default_margin`.
    pub margin: Option<usize>,
    /// Constrain every least-squares refit so that the decomposition's DC
    /// gain (`sampled_dc_gain`) equals the kernel's sum exactly (see the
    /// documentation of [`decompose`]); `false` fits the L2 error alone.
    #[serde(default = "yes")]
    pub exact_dc: bool,
}

fn yes() -> bool {
    true
}

impl DecomposeOptions {
    /// Checks `tol`, `alpha` and `max_terms` (what [`decompose`] checks
    /// first), so that front ends can refuse them before any work.
    ///
    /// ```
    /// use ifd_planar::DecomposeOptions;
    /// assert!(DecomposeOptions::default().validate().is_ok());
    /// let bad = DecomposeOptions { tol: 0.0, ..DecomposeOptions::default() };
    /// assert!(bad.validate().unwrap_err().to_string().contains("tol = 0"));
    /// ```
    ///
    /// # Errors
    /// [`DecomposeError::Invalid`] naming the field.
    pub fn validate(&self) -> Result<(), DecomposeError> {
        if !(self.tol.is_finite() && self.tol > 0.0 && self.tol < 1.0) {
            return Err(DecomposeError::Invalid {
                name: "tol",
                value: self.tol,
                reason: "expected 0 < tol < 1",
            });
        }
        if let Some(a) = self.alpha
            && !(a.is_finite() && a > 0.0 && a < 1.0)
        {
            return Err(DecomposeError::Invalid {
                name: "alpha",
                value: a,
                reason: "expected 0 < alpha < 1 (relative to ||A^T y||_inf)",
            });
        }
        if self.max_terms == Some(0) {
            return Err(DecomposeError::Invalid {
                name: "max_terms",
                value: 0.0,
                reason: "expected at least 1",
            });
        }
        Ok(())
    }
}

impl Default for DecomposeOptions {
    fn default() -> Self {
        Self {
            alpha: None,
            max_terms: None,
            tol: 0.01,
            dictionary: DictionaryOptions::default(),
            max_iter: 20_000,
            prune: true,
            stage_gap: 0.1,
            extra_stages: 1,
            margin: None,
            exact_dc: true,
        }
    }
}

/// The sum over the whole pixel grid of the decomposition's Gaussians
/// sampled at pixel centres, `sum_t w_t Sx_t Sy_t` with the 1D sums
/// `S = sum_i exp(-(i - c)^2 / (2 sigma^2)) / (sqrt(2 pi) sigma)` (1 for
/// wide atoms, phase-dependent for atoms narrower than a pixel: 1.34 at
/// `sigma = 0.3` on a sample, 0.66 half-way).
///
/// ```
/// use ifd_planar::{Decomposition, Term, internals::fit::sampled_dc_gain};
/// let t = |weight, x, sigma| Term { weight, x, y: 0.0, sigma };
/// assert!((sampled_dc_gain(&Decomposition::from_terms(vec![t(2.0, 0.3, 3.0)])) - 2.0).abs() < 1e-9);
/// assert!(sampled_dc_gain(&Decomposition::from_terms(vec![t(1.0, 0.0, 0.3)])) > 1.3);
/// ```
#[must_use]
pub fn sampled_dc_gain(decomposition: &Decomposition) -> f64 {
    decomposition
        .terms
        .iter()
        .map(|t| t.weight * sampled_sum(t.x, t.sigma) * sampled_sum(t.y, t.sigma))
        .sum()
}

/// The revision of what [`decompose`] returns for given options: it changes
/// whenever the fitting changes its results, so that stored fits made by
/// older code (the smoother's cached aspect bank) are refitted, not reused.
/// 2: DC-exact refits ([`DecomposeOptions::exact_dc`], 2026-12-04).
/// 3: the refits' linear algebra on nalgebra (rounding only, 2026-12-05).
/// 4: the solver's iterations in coefficient space through the dictionary's
/// Gram structure (rounding only; supports of some fits change, 2026-12-07).
pub const FIT_REVISION: u32 = 4;

/// The most samples (kernel window and margin) a fit runs over.
const MAX_FIT_SAMPLES: usize = 1 << 26;

/// The default margin of zeros fitted around a kernel of half-size `r`
/// ([`DecomposeOptions::margin`]): `r` itself, at least 2 px. The widest
/// atoms have a standard deviation of `r / 2`, so an atom at the window's
/// edge is matched over two of its standard deviations outside. With a
/// quarter of that, wide atoms whose tails cancel inside the margin but not
/// beyond it still scaled a constant image by 17 (`box:w=31,h=31`) and 40
/// (`disk:r=10`), measured; with no margin, by 3.96 and -2887.
#[must_use]
pub fn default_margin(r: usize) -> usize {
    r.max(2)
}

/// Why a decomposition failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DecomposeError {
    /// Bad dictionary parameters.
    #[error(transparent)]
    Dictionary(#[from] DictionaryError),
    /// The filter spec cannot be sampled.
    #[error(transparent)]
    Kernel(#[from] crate::kernel::KernelError),
    /// An option is out of range.
    #[error("invalid option {name} = {value}: {reason}")]
    Invalid {
        /// The option.
        name: &'static str,
        /// Its value.
        value: f64,
        /// Why.
        reason: &'static str,
    },
}

/// Errors of a set of terms against a kernel (the report's error fields).
#[must_use]
pub fn measure(kernel: &Kernel, decomposition: &Decomposition) -> (f64, f64, f64) {
    use rayon::prelude::*;
    let (w, h) = (kernel.width(), kernel.height());
    let (rx, ry) = (kernel.radius_x() as f64, kernel.radius_y() as f64);
    // Each term is separable: its profiles along x and y (one exponential
    // per column and per row instead of one per pixel), the product summed
    // over terms per pixel, in term order as `Decomposition::eval` sums.
    let profile = |c: f64, sigma: f64, n: usize, r: f64| -> Vec<f64> {
        (0..n)
            .map(|i| {
                let e = i as f64 - r - c;
                (-(e * e) / (2.0 * sigma * sigma)).exp()
            })
            .collect()
    };
    let terms = &decomposition.terms;
    if terms.len() * (w + h) > 1 << 24 {
        // profiles past 128 MiB (thousands of terms on a huge window): one
        // exponential per term and pixel instead
        let recon: Vec<f64> = (0..w * h)
            .into_par_iter()
            .map(|i| decomposition.eval((i % w) as f64 - rx, (i / w) as f64 - ry))
            .collect();
        return errors_of(kernel, &recon);
    }
    let px: Vec<Vec<f64>> = terms.iter().map(|t| profile(t.x, t.sigma, w, rx)).collect();
    let py: Vec<Vec<f64>> = terms.iter().map(|t| profile(t.y, t.sigma, h, ry)).collect();
    let coef: Vec<f64> = terms
        .iter()
        .map(|t| t.weight / (2.0 * std::f64::consts::PI * t.sigma * t.sigma))
        .collect();
    let mut recon = vec![0.0; w * h];
    recon.par_chunks_mut(w).enumerate().for_each(|(j, row)| {
        for (k, px) in px.iter().enumerate() {
            let cy = coef[k] * py[k][j];
            if cy == 0.0 {
                continue;
            }
            for (r, gx) in row.iter_mut().zip(px) {
                *r += cy * gx;
            }
        }
    });
    errors_of(kernel, &recon)
}

/// The report's errors of the reconstruction `recon` (the kernel's layout).
fn errors_of(kernel: &Kernel, recon: &[f64]) -> (f64, f64, f64) {
    let k = kernel.data();
    let mut e2 = 0.0;
    let mut emax: f64 = 0.0;
    let (mut sr, mut sk, mut sa) = (0.0, 0.0, 0.0);
    for (r, kv) in recon.iter().zip(k) {
        e2 += (r - kv).powi(2);
        emax = emax.max((r - kv).abs());
        sr += r;
        sk += kv;
        sa += kv.abs();
    }
    (
        e2.sqrt() / kernel.l2_norm(),
        emax / kernel.max_abs(),
        (sr - sk).abs() / sa,
    )
}

/// Decomposes `kernel` into displaced isotropic Gaussians (see the documentation of [`decompose`]).
///
/// `progress(iteration, objective, nnz)` is called after every `SpaRSA` iteration.
///
/// ```
/// use ifd_planar::{DecomposeOptions, Kernel, decompose};
/// let k: Kernel = "gauss:sx=6,sy=2,theta=30".parse()?;
/// let d = decompose(&k, &DecomposeOptions::default(), |_, _, _| {})?;
/// let report = d.report.as_ref().expect("decompose fills the report");
/// assert!(report.rel_l2_error <= 0.01);
/// assert_eq!(report.terms, d.terms.len());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`DecomposeError`] for out-of-range options or dictionary parameters.
///
/// Fitting a [`Decomposition`] to a [`Kernel`]: Eq. 4 of the IFD paper solved by
/// `SpaRSA` over the `MoG` [`Dictionary`].
///
/// # Choosing the regularisation
/// With `alpha` unset (the default), [`decompose`] walks the continuation path
/// `tau_k = tau_max 2^-k` (`tau_max = ||A^T y||_inf`, the smallest weight whose
/// solution is zero), solving each stage warm-started to a loose relative
/// duality gap (`stage_gap`, 0.1: only the support is used), and after each
/// stage *debiases* — exact least squares on the support, from the Cholesky
/// factor of the support's Gram matrix `G = A_S^T A_S`, which the separable
/// atoms give cheaply — and measures the relative L2 error
/// `sqrt(||y||^2 - 2 z.b + z^T G z) / ||y||`.
///
/// The first stage whose refit reaches `tol`, and `extra_stages` (1) more, are
/// then *pruned* by backward elimination: the atoms whose removal costs least
/// (`z_k^2 / (G^-1)_kk`, the exact increase of the squared residual when atom
/// `k` is dropped and the rest refitted) are removed in batches while the
/// error stays within `tol`. The sparsest result wins. The path stops early when
/// the refitted error stagnates (less than 30% better over three stages: the
/// dictionary is too coarse for `tol`).
///
/// `max_terms` caps the support: once a stage exceeds it before `tol` was
/// reached, the stage's support (and richer ones, up to twice the cap) is cut
/// down to the cap by the same backward elimination, and the lowest error wins.
///
/// With `alpha` set, `tau = alpha ||A^T y||_inf` is solved (with continuation)
/// and refitted on its support (cut to `max_terms` if needed); `tol` is then
/// only reported against.
///
/// # Exact DC
/// A filter's error on an image is not its L2 error alone: on flat regions
/// the output is the input times the DC gain, so a 0.2% DC error caps the
/// PSNR of a mid-grey image near 60 dB whatever the L2 error. With
/// [`DecomposeOptions::exact_dc`] (the default) every refit is the
/// equality-constrained least squares
/// `min ||y - A z||^2` subject to `c^T z = s`, where `s` is the kernel's sum
/// and `c_k` the DC gain of unit-norm atom `k` as `sampled_dc_gain`
/// measures it (`Sx Sy / ||a_k||`, 1D sums of the sampled Gaussian). With
/// `H = G^-1`, `z0 = H b` the free solution and `u = H c`:
///
/// `z = z0 + u (s - c^T z0) / (c^T u)`, and the squared residual grows by
/// `(s - c^T z0)^2 / (c^T u)`.
///
/// Removing atom `k` from a constrained fit is again a rank-one downdate,
/// of the constrained inverse `P = H - u u^T / (c^T u)` (the upper-left
/// block of the inverse of the KKT matrix `[G c; c^T 0]`) instead of `H`:
/// the residual grows by `z_k^2 / P_kk` and `P' = P - p_k p_k^T / P_kk`,
/// `z' = z - z_k p_k / P_kk`, the same formulas as without the constraint.
/// (Forcing `z_k = 0` is one more equality constraint `e_k^T z = 0`; the
/// growth of a quadratic under an added constraint `a^T z = 0` is
/// `(a^T z)^2 / (a^T P a)`.) So pruning keeps the constraint at no extra
/// cost. Supports above 2500 atoms, refitted by conjugate gradients, are
/// not constrained.
pub fn decompose(
    kernel: &Kernel,
    opts: &DecomposeOptions,
    progress: impl FnMut(usize, f64, usize),
) -> Result<Decomposition, DecomposeError> {
    let target = kernel.data().iter().sum();
    decompose_on_grid(kernel, opts, (1.0, target), progress)
}

/// [`decompose`] on a grid `dc.0` times finer than the pixels, with the DC
/// target `dc.1` (the kernel's sum on the pixel grid) when
/// [`DecomposeOptions::exact_dc`] is set.
fn decompose_on_grid(
    kernel: &Kernel,
    opts: &DecomposeOptions,
    dc: (f64, f64),
    mut progress: impl FnMut(usize, f64, usize),
) -> Result<Decomposition, DecomposeError> {
    let start = Instant::now();
    opts.validate()?;
    // Fit (and measure) over the window plus a margin where the kernel is
    // zero: the filter applies whole Gaussians, so the sum must vanish
    // outside the window too, not only match inside it.
    let unpadded = kernel;
    let margin = opts
        .margin
        .unwrap_or_else(|| default_margin(unpadded.radius_x().max(unpadded.radius_y())));
    let samples = (unpadded.width() as u128 + 2 * margin as u128)
        * (unpadded.height() as u128 + 2 * margin as u128);
    if samples > MAX_FIT_SAMPLES as u128 {
        return Err(DecomposeError::Invalid {
            name: "margin",
            value: margin as f64,
            reason: "the kernel and its margin exceed 2^26 samples",
        });
    }
    let params = DictionaryParams::for_kernel(unpadded, &opts.dictionary)?;
    let padded = unpadded.padded(margin);
    let kernel = &padded;
    let dict = Dictionary::with_margin(&params, kernel.width(), kernel.height(), margin);
    let y = kernel.data();
    let mut aty = vec![0.0; dict.len()];
    dict.apply_adjoint(y, &mut aty);
    let fitter = Fitter {
        dict: &dict,
        y,
        aty: aty.clone(),
        yy: y.iter().map(|v| v * v).sum(),
        dc: (opts.exact_dc && dc.1.is_finite()).then_some(DcConstraint {
            q: dc.0,
            target: dc.1,
        }),
    };
    let max_terms = opts.max_terms.unwrap_or(usize::MAX);
    let mut solver = Sparsa::with_aty(&dict, y, aty, None);
    let tau_max = solver.max_correlation();
    let stop = StopCriterion::DualityGap(opts.stage_gap);
    let cb = &mut progress;

    let best = if let Some(alpha) = opts.alpha {
        let tau = alpha * tau_max;
        let mut t = tau_max;
        while t > tau && solver.iterations() < opts.max_iter {
            t = (0.5 * t).max(tau);
            let left = opts.max_iter - solver.iterations();
            solver.solve_stage(t, stop, 1, left, cb);
        }
        let c = fitter.solve_x(solver.x(), tau);
        fitter.reduce_to(c, max_terms)
    } else {
        // The continuation path, 2x per stage.
        let mut reached: Vec<Candidate> = Vec::new();
        let mut capped: Vec<Candidate> = Vec::new();
        let mut last: Option<Candidate> = None;
        let mut errors: Vec<f64> = Vec::new();
        let mut tau = tau_max;
        while solver.iterations() < opts.max_iter && tau > 1e-12 * tau_max {
            tau *= 0.5;
            // A stage that does not converge in STAGE_ITER iterations still
            // gives a usable support; the refit does the rest.
            let left = (opts.max_iter - solver.iterations()).min(STAGE_ITER);
            solver.solve_stage(tau, stop, 1, left, cb);
            let c = fitter.solve_x(solver.x(), tau);
            if c.nnz() > max_terms {
                if !reached.is_empty() {
                    break;
                }
                // The target is out of reach within the cap: cut richer and
                // richer supports down to the cap, keep the best.
                let over = c.nnz() > 2 * max_terms;
                capped.push(fitter.reduce_to(c, max_terms));
                if over {
                    break;
                }
                continue;
            }
            if c.err <= opts.tol {
                reached.push(if opts.prune {
                    fitter.prune(c.clone(), opts.tol)
                } else {
                    c.clone()
                });
                if reached.len() > opts.extra_stages {
                    break;
                }
            }
            // Stop when the dictionary cannot get closer: the refitted error
            // improved by less than 30% over the last five stages (a 32x
            // smaller tau; three stages stopped fits of pixel-averaged
            // disks at 10% that reach 0.4%).
            errors.push(c.err);
            if errors.len() > 5 && c.err > 0.7 * errors[errors.len() - 6] {
                last = Some(c);
                break;
            }
            last = Some(c);
        }
        let best = reached
            .into_iter()
            .min_by(|a, b| a.nnz().cmp(&b.nnz()).then(a.err.total_cmp(&b.err)));
        best.or_else(|| {
            capped
                .into_iter()
                .chain(last)
                .min_by(|a, b| a.err.total_cmp(&b.err))
        })
        .unwrap_or_else(|| fitter.solve_x(solver.x(), tau))
    };

    let mut x = vec![0.0; dict.len()];
    for (&k, &v) in best.support.iter().zip(&best.z) {
        x[k] = v;
    }
    let mut d = Decomposition::from_terms(dict.to_terms(&x));
    let (rel_l2_error, max_error, dc_error) = measure(kernel, &d);
    d.kernel_size = Some((unpadded.width(), unpadded.height()));
    d.spec = kernel.spec().map(str::to_string);
    d.sampling = kernel.sampling();
    d.dictionary = Some(params);
    let dc_gain = Some(sampled_dc_gain(&d));
    d.report = Some(FitReport {
        terms: d.terms.len(),
        rel_l2_error,
        max_error,
        dc_error,
        iterations: solver.iterations(),
        seconds: start.elapsed().as_secs_f64(),
        dictionary_atoms: dict.len(),
        tau: best.tau,
        oversample: 1,
        fine_rel_l2_error: None,
        margin,
        kernel_sum: Some(unpadded.data().iter().sum()),
        dc_gain,
    });
    Ok(d)
}

/// The finest atom width (px) that an oversampled fit of a pixel-averaged
/// (hard-edged) filter goes down to: 1.2 times the pixel box's standard
/// deviation `1 / sqrt(12)`.
pub const PIXEL_BLUR_WIDTH: f64 = 0.35;

/// The narrowest atom (px) of an oversampled fit of a pixel-averaged
/// filter: the pixel box's standard deviation, rounded up.
pub const PIXEL_BLUR_FLOOR: f64 = 0.3;

/// Fits a kernel on a grid `q` times finer than its pixels, so that the sum
/// of Gaussians matches the continuous filter between pixel centres too,
/// which is what rotating and scaling it samples: `fine` is the kernel
/// sampled with spacing `1/q` px ([`crate::KernelSpec::to_kernel_fine`]),
/// `kernel` the same filter on the pixel grid (for the report).
///
/// The fine grid is fitted as a kernel `q` times larger (with
/// `min_sigma` scaled to match), and its terms `(w, c, sigma)` in fine
/// pixels become `(w / q^2, c / q, sigma / q)` in pixels, since
/// `g_sigma(q x - c) = g_{sigma/q}(x - c/q) / q^2`. The report's errors are
/// measured on the pixel grid; `tol` bounds the fine grid's error. The
/// dictionary parameters recorded are the fine grid's. For a pixel-averaged
/// kernel ([`crate::kernel::Sampling::Area`]) the levels go down to
/// `PIXEL_BLUR_WIDTH` unless `opts` fixes them.
///
/// ```
/// use ifd_planar::{DecomposeOptions, KernelSpec, internals::fit::decompose_oversampled};
/// let spec: KernelSpec = "box:w=9,h=3".parse()?;
/// let (k, fine) = (spec.to_kernel()?, spec.to_kernel_fine(2)?);
/// let d = decompose_oversampled(&k, &fine, 2, &DecomposeOptions::default(), |_, _, _| {})?;
/// let r = d.report.as_ref().expect("report");
/// assert_eq!(r.oversample, 2);
/// assert!(r.rel_l2_error < 0.05, "{r:?}");
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// As [`decompose`], and [`DecomposeError::Invalid`] for `q` outside
/// `1..=8` or a `fine` grid that is not `kernel`'s refined by `q`.
pub fn decompose_oversampled(
    kernel: &Kernel,
    fine: &Kernel,
    q: usize,
    opts: &DecomposeOptions,
    progress: impl FnMut(usize, f64, usize),
) -> Result<Decomposition, DecomposeError> {
    if !(1..=8).contains(&q) {
        return Err(DecomposeError::Invalid {
            name: "oversample",
            value: q as f64,
            reason: "expected 1..=8",
        });
    }
    if fine.width() != (kernel.width() - 1) * q + 1
        || fine.height() != (kernel.height() - 1) * q + 1
    {
        return Err(DecomposeError::Invalid {
            name: "oversample",
            value: q as f64,
            reason: "the fine kernel is not the pixel kernel refined by this factor",
        });
    }
    let start = Instant::now();
    let mut fine_opts = opts.clone();
    fine_opts.dictionary.min_sigma *= q as f64;
    if kernel.sampling() == crate::kernel::Sampling::Area {
        // Pixel averages are as smooth as the pixel's box, whose standard
        // deviation is 1/sqrt(12) = 0.29 px: resolve that, in fine pixels,
        // and nothing narrower (no narrower atom is needed, and the fine
        // grid could not constrain it).
        let finest = fine_opts
            .dictionary
            .finest_at_most
            .unwrap_or(PIXEL_BLUR_WIDTH);
        fine_opts.dictionary.finest_at_most = Some(finest * q as f64);
        if fine_opts.dictionary.min_width == 0.0 {
            fine_opts.dictionary.min_width = PIXEL_BLUR_FLOOR * q as f64;
        }
    }
    let qf = q as f64;
    let target = kernel.data().iter().sum();
    let mut d = decompose_on_grid(fine, &fine_opts, (qf, target), progress)?;
    for t in &mut d.terms {
        t.weight /= qf * qf;
        t.x /= qf;
        t.y /= qf;
        t.sigma /= qf;
    }
    // The pixel grid within the fine grid's window.
    let margin = d.report.as_ref().map_or(0, |r| r.margin / q);
    let (rel_l2_error, max_error, dc_error) = measure(&kernel.padded(margin), &d);
    d.kernel_size = Some((kernel.width(), kernel.height()));
    d.spec = kernel.spec().map(str::to_string);
    d.sampling = kernel.sampling();
    let gain = sampled_dc_gain(&d);
    if let Some(r) = &mut d.report {
        r.margin = margin;
        r.kernel_sum = Some(kernel.data().iter().sum());
        r.dc_gain = Some(gain);
        r.fine_rel_l2_error = Some(r.rel_l2_error);
        r.rel_l2_error = rel_l2_error;
        r.max_error = max_error;
        r.dc_error = dc_error;
        r.oversample = q;
        r.seconds = start.elapsed().as_secs_f64();
    }
    Ok(d)
}

/// Decomposes a built-in filter spec, sampled on the pixel grid and, when
/// `oversample` (the factor `q`, `1..=8`) is above 1, fitted on a grid `q`
/// times finer (`decompose_oversampled`) so that the sum of Gaussians also
/// matches the filter between pixel centres, which rotated and scaled copies
/// sample. `None` chooses: 2 for the hard-edged specs (box, line, disk:
/// [`Sampling::Area`]), 1 otherwise. The spec is recorded in the result.
///
/// ```
/// use ifd_planar::{DecomposeOptions, KernelSpec, decompose_spec};
/// let spec: KernelSpec = "box:w=9,h=3".parse()?;
/// let d = decompose_spec(&spec, &DecomposeOptions::default(), None, |_, _, _| {})?;
/// assert_eq!(d.report.as_ref().map(|r| r.oversample), Some(2));
/// assert_eq!(d.spec.as_deref(), Some(spec.to_string().as_str()));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`DecomposeError::Kernel`] when the spec cannot be sampled, and as
/// `decompose_oversampled`.
pub fn decompose_spec(
    spec: &KernelSpec,
    opts: &DecomposeOptions,
    oversample: Option<usize>,
    progress: impl FnMut(usize, f64, usize),
) -> Result<Decomposition, DecomposeError> {
    let q = oversample.unwrap_or(if spec.sampling() == Sampling::Area {
        2
    } else {
        1
    });
    if !(1..=8).contains(&q) {
        return Err(DecomposeError::Invalid {
            name: "oversample",
            value: q as f64,
            reason: "expected 1..=8",
        });
    }
    let kernel = spec.to_kernel()?;
    let mut d = if q > 1 {
        let fine = spec.to_kernel_fine(q)?;
        decompose_oversampled(&kernel, &fine, q, opts, progress)?
    } else {
        decompose(&kernel, opts, progress)?
    };
    d.spec = Some(spec.to_string());
    Ok(d)
}

#[cfg(test)]
mod tests;
