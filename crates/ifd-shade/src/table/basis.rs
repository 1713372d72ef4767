//! The lobe bases of a table: [`LobeLayout`] (which directions),
//! [`LobeKind`] (in-plane or shared) and [`LobeBasis`] (ZHF/ZHE in either).

use ifd_sphere::ShCoeffs;
use ifd_sphere::{DirectionSet, RzhBasis, RzhCoeffs, Sharing};
use ifd_sphere::{PlaneRzhBasis, plane_count, plane_index};

use crate::brdf::Brdf;
use crate::error::{Result, ShadeError};

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
