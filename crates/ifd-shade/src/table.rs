//! View-dependent lobe weights (ISD Sec. 6.1, 7.1): the ISD weights
//! `lambda_l^j(wo)` of a BRDF's slices, tabulated over the view direction and
//! interpolated between entries.
//!
//! # Layout
//! - Isotropic BRDFs: a 1D table over `theta_o`, the slice taken in the frame
//!   rotated about the normal so that `phi_o = 0`; the renderer applies the
//!   same rotation ([`view_frame_angle`]). In that frame the slice is even in
//!   `y`, so its band `l` needs only `l + 1` lobes: the in-plane basis of
//!   [`ifd_sphere::PlaneRzhBasis`], `L + 1` directions in the `xz` plane shared by
//!   all bands (band `l` uses the first `l + 1`), `(L + 1)(L + 2) / 2` weights
//!   per entry ([`LobeKind::InPlane`], the default).
//! - Anisotropic BRDFs: a 2D table over `(theta_o, phi_o)` in the tangent
//!   frame, with the general RZH basis: `2L + 1` Fibonacci directions shared
//!   by all bands (band `l` uses the first `2l + 1`; lobe sharing, ISD Sec. 7),
//!   `(L + 1)^2` weights per entry ([`LobeKind::Shared`], which isotropic
//!   tables may also use, for comparison).
//! - A shading point evaluates the environment at every direction of the
//!   table: `L + 1` for isotropic BRDFs, `2L + 1` for anisotropic ones.
//! - Entries at cell centres: `theta_i = (i + 1/2) pi / (2 N_theta)`,
//!   `phi_j = 2 pi j / N_phi`; linear (1D) or bilinear (2D, periodic in `phi`)
//!   interpolation, constant beyond the first and last `theta` centres.
//!   Interpolating `lambda` linearly is interpolating the slice's SH
//!   coefficients linearly (`c_l = M_l lambda_l` is linear), so the error is the
//!   slice's own interpolation error, measured at the midpoints between entries
//!   when a table is built ([`TableHeader::interpolation_error`]).
//! - Stored as `f32` (the paper's memory counts, Table I): `N_theta N_phi K C`
//!   values, `K` the weights per entry above.
//!
//! # File format (version 2)
//! JSON would be 3-4x larger than the values and slow to parse for 2D tables
//! of tens of MB, so tables are binary with a self-describing header: the 8
//! bytes `IFDLOBES`, a little-endian `u32` header length, the header as UTF-8
//! JSON ([`TableHeader`]), then the weights as little-endian `f32`,
//! entry-major (`[theta][phi][K][C]`, weight index `l^2 + j` for shared lobes,
//! `l (l + 1) / 2 + j` for in-plane ones). Readers check the magic, the
//! version, every header field (including the conditioning of the lobe
//! directions) and the exact file size. Version 1 (shared lobes for every
//! BRDF, before the in-plane basis) is refused with a request to rebuild.

use std::f64::consts::{FRAC_PI_2, PI};
use std::io::{Read, Write};
use std::path::Path;

use ifd_sphere::ShCoeffs;
use ifd_sphere::{Chooser, DirectionSet, RzhBasis, RzhCoeffs, Sharing};
use ifd_sphere::{PlaneRzhBasis, plane_count, plane_index};
use rayon::prelude::*;

use crate::brdf::{Brdf, Model};
use crate::error::{Result, ShadeError};
use crate::slice::project_slice;

const MAGIC: &[u8; 8] = b"IFDLOBES";
/// The format version this build reads and writes.
pub const VERSION: u32 = 2;
/// The largest degree a table may have.
pub const MAX_TABLE_DEGREE: usize = 100;

/// The self-describing header of a table file.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TableHeader {
    /// Always `"ifd-lobe-table"`.
    pub format: String,
    /// Format version ([`VERSION`]).
    pub version: u32,
    /// The BRDF spec the table was built for.
    pub brdf: String,
    /// FNV-1a digest of the BRDF (its spec, and a MERL file's values).
    pub brdf_digest: String,
    /// Maximum SH degree `L`.
    pub l_max: usize,
    /// Channels of the weights (3 for MERL, else 1).
    pub channels: usize,
    /// Whether the table is 1D over `theta_o` (isotropic BRDF).
    pub isotropic: bool,
    /// Entries over `theta_o`.
    pub n_theta: usize,
    /// Entries over `phi_o` (1 for isotropic tables).
    pub n_phi: usize,
    /// The lobe directions and how bands use them.
    pub lobes: LobeLayout,
    /// Largest relative L2 error of an interpolated slice at the midpoints
    /// between entries (see the module docs).
    pub interpolation_error: f64,
    /// Root mean square of the same errors.
    pub interpolation_rms: f64,
}

/// The lobes of a table, as stored in its header.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum LobeLayout {
    /// `2L + 1` directions shared by all bands; band `l` uses the first
    /// `2l + 1`; weight index `l^2 + j`.
    Shared {
        /// The directions.
        directions: DirectionSet,
    },
    /// `L + 1` directions `(sin a, 0, cos a)` in the `xz` plane, for slices
    /// even in `y`; band `l` uses the first `l + 1`; weight index
    /// `l (l + 1) / 2 + j`.
    InPlane {
        /// The angles `a_j` from `+z` towards `+x`, radians.
        angles: Vec<f64>,
    },
}

impl LobeLayout {
    /// `"shared"` or `"in-plane"` (as `ifd sphere brdf --lobes` spells them).
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Self::Shared { .. } => "shared",
            Self::InPlane { .. } => "in-plane",
        }
    }
}

/// Which lobes to build a table with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LobeKind {
    /// [`LobeLayout::Shared`] (any BRDF).
    Shared,
    /// [`LobeLayout::InPlane`] (isotropic BRDFs only).
    InPlane,
}

impl LobeKind {
    /// In-plane for isotropic BRDFs, shared for the others.
    #[must_use]
    pub fn default_for(brdf: &Brdf) -> Self {
        if brdf.is_isotropic() {
            Self::InPlane
        } else {
            Self::Shared
        }
    }
}

/// The basis of a table's lobes: the matrices that turn weights into SH
/// coefficients and back.
#[derive(Clone, Debug)]
pub enum LobeBasis {
    /// The general RZH basis.
    Shared(RzhBasis),
    /// The in-plane basis for slices even in `y`.
    InPlane(PlaneRzhBasis),
}

impl LobeBasis {
    /// The basis of a layout (checking the degree and conditioning).
    ///
    /// # Errors
    /// [`ShadeError::Sphere`] for degenerate directions;
    /// [`ShadeError::Mismatch`] for a layout of another degree.
    pub fn new(layout: &LobeLayout, l_max: usize) -> Result<Self> {
        let b = match layout {
            LobeLayout::Shared { directions } => {
                if directions.sharing() != Sharing::Shared {
                    return Err(ShadeError::Mismatch(
                        "lobe tables need directions shared across bands".into(),
                    ));
                }
                Self::Shared(RzhBasis::new(directions.clone())?)
            }
            LobeLayout::InPlane { angles } => Self::InPlane(PlaneRzhBasis::with_angles(angles)?),
        };
        if b.l_max() != l_max {
            return Err(ShadeError::Mismatch(format!(
                "lobe directions of degree {} in a table of degree {l_max}",
                b.l_max()
            )));
        }
        Ok(b)
    }

    /// Maximum degree.
    #[must_use]
    pub fn l_max(&self) -> usize {
        match self {
            Self::Shared(b) => b.l_max(),
            Self::InPlane(b) => b.l_max(),
        }
    }

    /// The lobe directions (local frame).
    #[must_use]
    pub fn directions(&self) -> &[[f64; 3]] {
        match self {
            Self::Shared(b) => b.directions().all(),
            Self::InPlane(b) => b.directions(),
        }
    }

    /// The lowest band lobe `j` serves: `ceil(j / 2)` (shared), `j` (in-plane).
    #[must_use]
    pub fn first_band(&self, j: usize) -> usize {
        match self {
            Self::Shared(_) => j.div_ceil(2),
            Self::InPlane(_) => j,
        }
    }

    /// The index of lobe `j` of band `l` among an entry's weights.
    #[must_use]
    pub fn index(&self, l: usize, j: usize) -> usize {
        match self {
            Self::Shared(_) => l * l + j,
            Self::InPlane(_) => plane_index(l, j),
        }
    }

    /// Weights per channel of an entry: `(L + 1)^2` or `(L + 1)(L + 2) / 2`.
    #[must_use]
    pub fn count(&self) -> usize {
        match self {
            Self::Shared(b) => (b.l_max() + 1) * (b.l_max() + 1),
            Self::InPlane(b) => plane_count(b.l_max()),
        }
    }

    /// Weights of an SH expansion (ZHF).
    ///
    /// # Errors
    /// Degree mismatch.
    pub fn zhf(&self, f: &ShCoeffs) -> Result<Vec<f64>> {
        Ok(match self {
            Self::Shared(b) => b.zhf(f)?.data,
            Self::InPlane(b) => b.zhf(f)?,
        })
    }

    /// SH coefficients of weights with `channels` channels (ZHE).
    ///
    /// # Errors
    /// Length or degree mismatch.
    pub fn zhe(&self, weights: &[f64], channels: usize) -> Result<ShCoeffs> {
        Ok(match self {
            Self::Shared(b) => b.zhe(&RzhCoeffs {
                l_max: b.l_max(),
                channels,
                data: weights.to_vec(),
            })?,
            Self::InPlane(b) => b.zhe(weights, channels)?,
        })
    }
}

/// A BRDF's lobe weights over view directions.
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

/// FNV-1a over bytes.
fn fnv1a(bytes: impl IntoIterator<Item = u8>, mut h: u64) -> u64 {
    for b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    h
}

/// A digest identifying a BRDF: its spec and, for MERL, the values read.
#[must_use]
pub fn brdf_digest(brdf: &Brdf) -> String {
    let mut h = fnv1a(brdf.spec().bytes(), 0xcbf2_9ce4_8422_2325);
    if let Model::Merl(m) = brdf.model() {
        h = fnv1a(m.digest_bytes(), h);
    }
    format!("{h:016x}")
}

impl LobeTable {
    /// Builds the table of `brdf` at degree `l_max` with `n_theta` entries over
    /// `theta_o` and, for anisotropic BRDFs, `n_phi` over `phi_o` (ignored for
    /// isotropic ones), with the lobes of [`LobeKind::default_for`].
    /// `progress(done, total)` is called after each entry.
    ///
    /// ```
    /// use ifd_shade::{brdf::Brdf, table::LobeTable};
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
        let h = &self.header;
        let n = self.entry_len();
        assert_eq!(out.len(), n);
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
        out.fill(0.0);
        for (e, w) in corners {
            if w == 0.0 {
                continue;
            }
            for (o, v) in out.iter_mut().zip(&self.weights[e * n..(e + 1) * n]) {
                *o += w * f64::from(*v);
            }
        }
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

    /// Writes the table (atomically; format in the module docs).
    ///
    /// # Errors
    /// [`ShadeError::File`].
    pub fn write(&self, path: &Path) -> Result<()> {
        let header = serde_json::to_vec(&self.header).map_err(|e| ShadeError::File {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        ifd_image::atomic_write(path, |w| {
            let e = |e: std::io::Error| e.to_string();
            w.write_all(MAGIC).map_err(e)?;
            w.write_all(&(header.len() as u32).to_le_bytes())
                .map_err(e)?;
            w.write_all(&header).map_err(e)?;
            for v in &self.weights {
                w.write_all(&v.to_le_bytes()).map_err(e)?;
            }
            Ok(())
        })
        .map_err(|e| ShadeError::File {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })
    }

    /// Reads a table, checking everything the module docs list.
    ///
    /// # Errors
    /// [`ShadeError::File`] naming the file and the problem.
    pub fn read(path: &Path) -> Result<Self> {
        let ferr = |reason: String| ShadeError::File {
            path: path.to_path_buf(),
            reason,
        };
        let meta = std::fs::metadata(path).map_err(|e| ferr(format!("cannot read: {e}")))?;
        if !meta.is_file() {
            return Err(ferr("not a regular file".into()));
        }
        let file_len = meta.len();
        let mut file = std::fs::File::open(path).map_err(|e| ferr(format!("cannot read: {e}")))?;
        let mut head = [0u8; 12];
        if file_len < 12 || file.read_exact(&mut head).is_err() || &head[..8] != MAGIC {
            return Err(ferr(
                "not an ifd lobe table (it does not start with IFDLOBES; build one with \
                 `ifd sphere brdf`)"
                    .into(),
            ));
        }
        let hl = u64::from(u32::from_le_bytes([head[8], head[9], head[10], head[11]]));
        if 12 + hl > file_len {
            return Err(ferr(format!(
                "truncated: the header declares {hl} bytes, the file has {}",
                file_len - 12
            )));
        }
        let mut hbytes = vec![0u8; hl as usize];
        file.read_exact(&mut hbytes)
            .map_err(|e| ferr(format!("cannot read the header: {e}")))?;
        let hbytes = hbytes.as_slice();
        let header: TableHeader =
            serde_json::from_slice(hbytes).map_err(|e| ferr(format!("malformed header: {e}")))?;
        if header.format != "ifd-lobe-table" {
            return Err(ferr(format!(
                "format {:?} is not ifd-lobe-table",
                header.format
            )));
        }
        if header.version != VERSION {
            return Err(ferr(format!(
                "table version {} is not supported (this build reads version {VERSION}{})",
                header.version,
                if header.version == 1 {
                    "; version 1 predates in-plane lobes: rebuild the table with `ifd sphere brdf`"
                } else {
                    ""
                }
            )));
        }
        let h = &header;
        let shape_ok = h.l_max <= MAX_TABLE_DEGREE
            && (1..=3).contains(&h.channels)
            && (2..=4096).contains(&h.n_theta)
            && (1..=4096).contains(&h.n_phi)
            && (h.isotropic == (h.n_phi == 1))
            && (h.isotropic || matches!(h.lobes, LobeLayout::Shared { .. }))
            // the layout's degree before building its matrices
            && match &h.lobes {
                LobeLayout::Shared { directions } => directions.l_max() == h.l_max,
                LobeLayout::InPlane { angles } => angles.len() == h.l_max + 1,
            };
        if !shape_ok {
            return Err(ferr(format!(
                "inconsistent header: L = {}, {} channel(s), {} x {} entries, isotropic {}, \
                 {} lobes",
                h.l_max,
                h.channels,
                h.n_theta,
                h.n_phi,
                h.isotropic,
                h.lobes.name()
            )));
        }
        if let LobeLayout::Shared { directions } = &h.lobes {
            directions
                .check()
                .map_err(|e| ferr(format!("lobe directions: {e}")))?;
        }
        let basis =
            LobeBasis::new(&h.lobes, h.l_max).map_err(|e| ferr(format!("lobe directions: {e}")))?;
        let count = (h.n_theta as u64) * (h.n_phi as u64) * (basis.count() * h.channels) as u64;
        let have = file_len - 12 - hl;
        if have != 4 * count {
            return Err(ferr(format!(
                "{have} bytes of weights, the header declares {count} f32 values ({} bytes){}",
                4 * count,
                if have < 4 * count { ": truncated" } else { "" }
            )));
        }
        let mut data = Vec::with_capacity(have as usize);
        file.read_to_end(&mut data)
            .map_err(|e| ferr(format!("cannot read the weights: {e}")))?;
        if data.len() as u64 != have {
            return Err(ferr("the file changed while it was read".into()));
        }
        let weights: Vec<f32> = data
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        if let Some(i) = weights.iter().position(|v| !v.is_finite()) {
            return Err(ferr(format!("weight {i} is not finite")));
        }
        Ok(Self {
            header,
            basis,
            weights,
        })
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
