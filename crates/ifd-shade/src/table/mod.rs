//! View-dependent lobe weights (ISD Sec. 6.1, 7.1): the ISD weights
//! `lambda_l^j(wo)` of a BRDF's slices, tabulated over the view direction and
//! interpolated between entries.
//!
//! The derivation and conventions are documented on [`LobeTable`].

mod basis;
mod file;

use std::f64::consts::{FRAC_PI_2, PI};

use ifd_sphere::{Chooser, DirectionSet, ShCoeffs, Sharing};
use rayon::prelude::*;

pub use self::basis::{LobeBasis, LobeKind, LobeLayout};
pub use self::file::{TableHeader, VERSION, brdf_digest};

/// The largest degree a table may have.
pub const MAX_TABLE_DEGREE: usize = 100;
use crate::brdf::Brdf;
use crate::error::{Result, ShadeError};
use crate::slice::project_slice;

/// A BRDF's lobe weights over view directions.
///
/// # Layout
/// - Isotropic BRDFs: a 1D table over `theta_o`, the slice taken in the frame
///   rotated about the normal so that `phi_o = 0`; the renderer applies the
///   same rotation ([`view_frame_angle`]). In that frame the slice is even in
///   `y`, so its band `l` needs only `l + 1` lobes: the in-plane basis of
///   [`ifd_sphere::PlaneRzhBasis`], `L + 1` directions in the `xz` plane shared by
///   all bands (band `l` uses the first `l + 1`), `(L + 1)(L + 2) / 2` weights
///   per entry ([`LobeKind::InPlane`], the default).
/// - Anisotropic BRDFs: a 2D table over `(theta_o, phi_o)` in the tangent
///   frame, with the general RZH basis: `2L + 1` Fibonacci directions shared
///   by all bands (band `l` uses the first `2l + 1`; lobe sharing, ISD Sec. 7),
///   `(L + 1)^2` weights per entry ([`LobeKind::Shared`], which isotropic
///   tables may also use, for comparison).
/// - A shading point evaluates the environment at every direction of the
///   table: `L + 1` for isotropic BRDFs, `2L + 1` for anisotropic ones.
/// - Entries at cell centres: `theta_i = (i + 1/2) pi / (2 N_theta)`,
///   `phi_j = 2 pi j / N_phi`; linear (1D) or bilinear (2D, periodic in `phi`)
///   interpolation, constant beyond the first and last `theta` centres.
///   Interpolating `lambda` linearly is interpolating the slice's SH
///   coefficients linearly (`c_l = M_l lambda_l` is linear), so the error is the
///   slice's own interpolation error, measured at the midpoints between entries
///   when a table is built ([`TableHeader::interpolation_error`]).
/// - Stored as `f32` (the paper's memory counts, Table I): `N_theta N_phi K C`
///   values, `K` the weights per entry above.
///
///
/// The lobe bases are in `basis.rs`, the file format (below) in `file.rs`.
///
/// # File format (version 2)
/// JSON would be 3-4x larger than the values and slow to parse for 2D tables
/// of tens of MB, so tables are binary with a self-describing header: the 8
/// bytes `IFDLOBES`, a little-endian `u32` header length, the header as UTF-8
/// JSON ([`TableHeader`]), then the weights as little-endian `f32`,
/// entry-major (`[theta][phi][K][C]`, weight index `l^2 + j` for shared lobes,
/// `l (l + 1) / 2 + j` for in-plane ones). Readers check the magic, the
/// version, every header field (including the conditioning of the lobe
/// directions) and the exact file size. Version 1 (shared lobes for every
/// BRDF, before the in-plane basis) is refused with a request to rebuild.
#[derive(Clone, Debug)]
pub struct LobeTable {
    header: TableHeader,
    basis: LobeBasis,
    weights: Vec<f32>,
}

/// Default entries over `theta_o` for a BRDF: `4 pi / width` (about eight
/// entries across the lobe's width in `theta_o`), between 16 and 512.
#[must_use]
pub fn default_theta_entries(brdf: &Brdf) -> usize {
    ((4.0 * PI / brdf.lobe_width()).ceil() as usize).clamp(16, 512)
}

/// The rotation angle about the normal that brings `wo` to `phi_o = 0`
/// (isotropic tables): `atan2(wo_y, wo_x)`.
#[must_use]
pub fn view_frame_angle(wo: [f64; 3]) -> f64 {
    wo[1].atan2(wo[0])
}

impl LobeTable {
    /// Builds the table of `brdf` at degree `l_max` with `n_theta` entries over
    /// `theta_o` and, for anisotropic BRDFs, `n_phi` over `phi_o` (ignored for
    /// isotropic ones), with the lobes of [`LobeKind::default_for`].
    /// `progress(done, total)` is called after each entry.
    ///
    /// ```
    /// use ifd_shade::{Brdf, LobeTable};
    /// let b = Brdf::parse("ggx:alpha=0.5")?;
    /// let t = LobeTable::build(&b, 4, 8, 1, &|_, _| {})?;
    /// assert_eq!(t.header().n_phi, 1);
    /// // isotropic: 5 in-plane lobes, 1 + 2 + 3 + 4 + 5 weights per entry
    /// assert_eq!(t.basis().directions().len(), 5);
    /// assert_eq!(t.weights_at(0.3, 0.0).len(), 15);
    /// # Ok::<(), ifd_shade::ShadeError>(())
    /// ```
    ///
    /// # Errors
    /// As [`Self::build_with`].
    pub fn build(
        brdf: &Brdf,
        l_max: usize,
        n_theta: usize,
        n_phi: usize,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Self> {
        Self::build_with(
            brdf,
            l_max,
            n_theta,
            n_phi,
            LobeKind::default_for(brdf),
            progress,
        )
    }

    /// [`Self::build`] with the given lobes.
    ///
    /// # Errors
    /// [`ShadeError::Parameter`] for `l_max` above [`MAX_TABLE_DEGREE`], fewer
    /// than 2 entries, or in-plane lobes for an anisotropic BRDF; degenerate
    /// lobe directions.
    pub fn build_with(
        brdf: &Brdf,
        l_max: usize,
        n_theta: usize,
        n_phi: usize,
        kind: LobeKind,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Self> {
        if kind == LobeKind::InPlane && !brdf.is_isotropic() {
            return Err(ShadeError::Parameter {
                name: "lobes",
                value: "in-plane".into(),
                reason: format!(
                    "the slices of the anisotropic BRDF {:?} are not even in y: use shared lobes",
                    brdf.spec()
                ),
            });
        }
        if l_max > MAX_TABLE_DEGREE {
            return Err(ShadeError::Parameter {
                name: "--lmax",
                value: l_max.to_string(),
                reason: format!("lobe tables support L <= {MAX_TABLE_DEGREE}"),
            });
        }
        let isotropic = brdf.is_isotropic();
        let n_phi = if isotropic { 1 } else { n_phi };
        if !(2..=4096).contains(&n_theta)
            || !(1..=4096).contains(&n_phi)
            || (!isotropic && n_phi < 4)
        {
            return Err(ShadeError::Parameter {
                name: "table entries",
                value: format!("{n_theta} x {n_phi}"),
                reason: "use 2..=4096 entries over theta_o and 4..=4096 over phi_o".into(),
            });
        }
        let total = n_theta * n_phi;
        let layout = match kind {
            LobeKind::Shared => LobeLayout::Shared {
                directions: DirectionSet::new(l_max, Sharing::Shared, Chooser::Fibonacci)?,
            },
            LobeKind::InPlane => LobeLayout::InPlane {
                angles: ifd_sphere::default_angles(l_max),
            },
        };
        let basis = LobeBasis::new(&layout, l_max)?;
        let per_entry = basis.count();
        // f64 weights per entry while building, then the f32 table
        let values = (total as u64) * (per_entry * brdf.channels()) as u64;
        let budget = ifd_image::MemoryBudget::default_for_machine();
        budget
            .check(values.saturating_mul(12))
            .map_err(|e| ShadeError::Parameter {
                name: "table size",
                value: format!("{n_theta} x {n_phi} entries at L = {l_max}"),
                reason: format!("{e}; use fewer entries or a lower L"),
            })?;
        let done = std::sync::atomic::AtomicUsize::new(0);
        let entries: Vec<Result<Vec<f64>>> = (0..total)
            .into_par_iter()
            .map(|e| {
                let wo = entry_view(e / n_phi, e % n_phi, n_theta, n_phi);
                let c = project_slice(brdf, wo, l_max, None)?;
                let z = basis.zhf(&c)?;
                let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                progress(n, total);
                Ok(z)
            })
            .collect();
        let channels = brdf.channels();
        let mut weights = Vec::with_capacity(total * per_entry * channels);
        for e in entries {
            weights.extend(e?.iter().map(|&v| v as f32));
        }
        let mut table = Self {
            header: TableHeader {
                format: "ifd-lobe-table".into(),
                version: VERSION,
                brdf: brdf.spec().to_string(),
                brdf_digest: brdf_digest(brdf),
                l_max,
                channels,
                isotropic,
                n_theta,
                n_phi,
                lobes: layout,
                interpolation_error: 0.0,
                interpolation_rms: 0.0,
            },
            basis,
            weights,
        };
        let (max, rms) = table.measure_interpolation(brdf)?;
        table.header.interpolation_error = max;
        table.header.interpolation_rms = rms;
        Ok(table)
    }

    /// Relative L2 errors of interpolated slices at midpoints between entries:
    /// `|c_interp - c_exact| / |c_exact|` (Parseval: the L2 error of the
    /// band-limited slice), max and RMS over the midpoints (all `theta`
    /// midpoints; for 2D tables, those at every fourth `phi` midpoint).
    fn measure_interpolation(&self, brdf: &Brdf) -> Result<(f64, f64)> {
        let h = &self.header;
        let (nt, np) = (h.n_theta, h.n_phi);
        let phis: Vec<f64> = if h.isotropic {
            vec![0.0]
        } else {
            (0..np)
                .step_by(4)
                .map(|j| 2.0 * PI * (j as f64 + 0.5) / np as f64)
                .collect()
        };
        let points: Vec<(f64, f64)> = (0..nt - 1)
            .flat_map(|i| {
                let t = (i as f64 + 1.0) * FRAC_PI_2 / nt as f64;
                phis.iter().map(move |&p| (t, p))
            })
            .collect();
        let errs: Vec<Result<f64>> = points
            .par_iter()
            .map(|&(t, p)| {
                let wo = [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()];
                let exact = project_slice(brdf, wo, h.l_max, None)?;
                let got = self.basis.zhe(&self.weights_at(t, p), h.channels)?;
                Ok(relative_l2(&got, &exact))
            })
            .collect();
        let mut max = 0.0f64;
        let mut sum = 0.0;
        let n = errs.len().max(1) as f64;
        for e in errs {
            let e = e?;
            max = max.max(e);
            sum += e * e;
        }
        Ok((max, (sum / n).sqrt()))
    }

    /// The header.
    #[must_use]
    pub fn header(&self) -> &TableHeader {
        &self.header
    }

    /// The basis of the lobes.
    #[must_use]
    pub fn basis(&self) -> &LobeBasis {
        &self.basis
    }

    /// The directional albedo `int k_wo` of every entry, channel 0: band 0 has
    /// one lobe and `M_0 = pi_0 y_0^0 = 1` (both bases), so `c_0^0 =
    /// lambda_0^0` and the integral is `lambda_0^0 sqrt(4 pi)`.
    #[must_use]
    pub fn entry_albedos(&self) -> Vec<f64> {
        let n = self.entry_len();
        self.weights
            .chunks_exact(n)
            .map(|e| f64::from(e[0]) * (4.0 * PI).sqrt())
            .collect()
    }

    /// The stored weights, entry-major (`[theta][phi][K][C]`, as in the file):
    /// what a GPU interpolates itself.
    #[must_use]
    pub fn raw_weights(&self) -> &[f32] {
        &self.weights
    }

    /// Bytes of the stored weights.
    #[must_use]
    pub fn weight_bytes(&self) -> usize {
        self.weights.len() * 4
    }

    /// Interpolated weights at `(theta_o, phi_o)`, `(K, C)` row-major (`K`
    /// from [`LobeBasis::count`], index [`LobeBasis::index`])
    /// (`phi_o` is ignored by isotropic tables: rotate the frame by
    /// [`view_frame_angle`] first).
    #[must_use]
    pub fn weights_at(&self, theta: f64, phi: f64) -> Vec<f64> {
        let mut out = vec![0.0; self.entry_len()];
        self.weights_into(theta, phi, &mut out);
        out
    }

    /// Values per entry, `K C`.
    #[must_use]
    pub fn entry_len(&self) -> usize {
        self.basis.count() * self.header.channels
    }

    /// [`Self::weights_at`] into a buffer of [`Self::entry_len`] values.
    ///
    /// # Panics
    /// If `out` has another length.
    pub fn weights_into(&self, theta: f64, phi: f64, out: &mut [f64]) {
        let n = self.entry_len();
        assert_eq!(out.len(), n);
        out.fill(0.0);
        for (e, w) in self.blend(theta, phi) {
            for (o, v) in out.iter_mut().zip(self.entry(e)) {
                *o += w * f64::from(*v);
            }
        }
    }

    /// The entries [`Self::weights_into`] blends at `(theta_o, phi_o)` and
    /// their weights, bilinear between entry centres (linear in `theta_o`
    /// for isotropic tables, which give two), zero weights left out.
    pub(crate) fn blend(&self, theta: f64, phi: f64) -> impl Iterator<Item = (usize, f64)> {
        let h = &self.header;
        let (nt, np) = (h.n_theta, h.n_phi);
        // theta: centres (i + 1/2) * (pi/2) / nt
        let x =
            (theta.clamp(0.0, FRAC_PI_2) / FRAC_PI_2 * nt as f64 - 0.5).clamp(0.0, (nt - 1) as f64);
        let i0 = (x.floor() as usize).min(nt - 2);
        let ft = x - i0 as f64;
        // (entry, weight); isotropic tables use the first two (no allocation:
        // this runs once per shaded pixel)
        let corners: [(usize, f64); 4] = if h.isotropic {
            [(i0, 1.0 - ft), (i0 + 1, ft), (0, 0.0), (0, 0.0)]
        } else {
            let y = phi.rem_euclid(2.0 * PI) / (2.0 * PI) * np as f64;
            let j0 = (y.floor() as usize) % np;
            let fp = y - y.floor();
            let j1 = (j0 + 1) % np;
            [
                (i0 * np + j0, (1.0 - ft) * (1.0 - fp)),
                (i0 * np + j1, (1.0 - ft) * fp),
                ((i0 + 1) * np + j0, ft * (1.0 - fp)),
                ((i0 + 1) * np + j1, ft * fp),
            ]
        };
        corners.into_iter().filter(|&(_, w)| w != 0.0)
    }

    /// Entry `e`'s weights ([`Self::entry_len`] values; panics beyond the
    /// table).
    #[must_use]
    pub(crate) fn entry(&self, e: usize) -> &[f32] {
        let n = self.entry_len();
        &self.weights[e * n..(e + 1) * n]
    }

    /// Refuses a table built for another BRDF or degree.
    ///
    /// # Errors
    /// [`ShadeError::Mismatch`] naming both.
    pub fn check_for(&self, brdf: &Brdf, l_max: usize) -> Result<()> {
        let h = &self.header;
        if h.brdf_digest != brdf_digest(brdf) {
            return Err(ShadeError::Mismatch(format!(
                "the table was built for the BRDF {:?}, not {:?}",
                h.brdf,
                brdf.spec()
            )));
        }
        if h.l_max != l_max {
            return Err(ShadeError::Mismatch(format!(
                "the table was built for L = {}, not L = {l_max}",
                h.l_max
            )));
        }
        if h.channels != brdf.channels() || h.isotropic != brdf.is_isotropic() {
            return Err(ShadeError::Mismatch(format!(
                "the table has {} channel(s) and is {}, the BRDF {:?} has {} and is {}",
                h.channels,
                if h.isotropic { "1D" } else { "2D" },
                brdf.spec(),
                brdf.channels(),
                if brdf.is_isotropic() {
                    "isotropic"
                } else {
                    "anisotropic"
                }
            )));
        }
        Ok(())
    }
}

/// The view direction of entry `(i, j)`.
fn entry_view(i: usize, j: usize, n_theta: usize, n_phi: usize) -> [f64; 3] {
    let t = (i as f64 + 0.5) * FRAC_PI_2 / n_theta as f64;
    let p = 2.0 * PI * j as f64 / n_phi as f64;
    [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()]
}

/// `|a - b| / |b|` over all coefficients and channels.
fn relative_l2(a: &ShCoeffs, b: &ShCoeffs) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (x, y) in a.data().iter().zip(b.data()) {
        num += (x - y) * (x - y);
        den += y * y;
    }
    if den > 0.0 {
        (num / den).sqrt()
    } else {
        num.sqrt()
    }
}
