//! The SH degree a material needs for a stated accuracy (`ifd render --tol
//! E`): a measured rule, not a formula.
//!
//! `tests/bench/render_tol_table.py` renders the unit sphere (128x128 and
//! 64x64, the default camera of `ifd render`) by ISD at a ladder of degrees and by the
//! exact oracle, for each material kind below and each roughness (or Phong
//! exponent), on the bundled forest and sunrise maps (read at 128x64), and
//! writes `docs/render-tol.csv`: the relative RMS error over the object and
//! over its grazing pixels (`n . v < 0.2`). [`table`] is that CSV reduced
//! (`render_tol_table.py --rust`): for each material and degree, the
//! **largest** of the errors (object and grazing, on both maps, at both
//! sizes: the 64x64 images' silhouette pixels raise the lobe table's floor
//! at grazing views, for rough metals to 4%).
//!
//! The rule ([`degree_for`]): the smallest measured degree whose error,
//! times [`MARGIN`], is within `E`; between two measured roughness values
//! (or Phong exponents) the larger of the two rows' degrees (a smoother
//! lobe needs a higher degree, but a rougher one can have a higher floor).
//! An `E` below what a row reaches by the largest degree allowed (the lobe
//! table's interpolation floor, largest at grazing views, or the degree
//! limit) is [`Unreachable`], with the best value that is reachable; a
//! roughness below the smoothest measured (0.3) is refused too (roughness
//! 0.1 would need `L` near 400).
//!
//! What it guarantees: the measured maps and view. Another map with a
//! brighter, smaller source than the sunrise's sun may need more; the margin
//! covers image size and camera (the silhouette's weight), not arbitrary
//! maps.

mod table;

use ifd_shade::{Brdf, Model};

/// The factor the measured errors are multiplied by before they are
/// compared with the tolerance.
pub const MARGIN: f64 = 1.2;

/// Where a view counts as grazing: `n . v` below this.
pub const GRAZING_COS: f64 = 0.2;

/// A material kind the rule has measurements for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TolMaterial {
    /// The glTF BRDF with metallic 0 (perceptual roughness).
    GltfDielectric(f64),
    /// The glTF BRDF with metallic above 0 (perceptual roughness); a
    /// metal's specular lobe needs at least a dielectric's degree.
    GltfMetal(f64),
    /// Isotropic GGX, by its perceptual roughness `sqrt(alpha)`.
    Ggx(f64),
    /// Normalised Phong (its exponent).
    Phong(f64),
    /// Lambert.
    Lambert,
}

/// The degree the rule chose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DegreeChoice {
    /// The degree.
    pub l_max: usize,
    /// The largest measured error at that degree (object and grazing
    /// pixels, both maps) of the row used, without the margin.
    pub measured: f64,
    /// The roughness (or exponent) of the row that decided (of the two
    /// measured rows around the material's, the one needing more).
    pub row: f64,
}

/// Why a tolerance cannot be met.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Unreachable {
    /// The row's best error (times the margin) is above the tolerance.
    #[error(
        "{material}: relative RMS {tol} is not reachable up to L = {max_degree}; the smallest \
         reachable is {best:.2e} (at L = {best_l}: the worst of the object and its grazing \
         views on the bundled maps, docs/render-tol.csv)"
    )]
    Floor {
        /// The material, described.
        material: String,
        /// The tolerance asked for.
        tol: f64,
        /// The largest degree allowed.
        max_degree: usize,
        /// The smallest reachable tolerance (measured error times the
        /// margin).
        best: f64,
        /// The degree that reaches it.
        best_l: usize,
    },
    /// Smoother (or sharper) than any measured row.
    #[error(
        "{material}: beyond the measured rows, which end at {edge} (reaching {best:.2e} at best; \
         {why}); pass --lmax{mirror}",
        why = if *sharp {
            "a sharper lobe needs a higher degree"
        } else {
            "a smoother lobe needs more than L = 100, roughness 0.1 about 400"
        },
        mirror = if *sharp { "" } else { ", or use --brdf mirror for a near-mirror" }
    )]
    Unmeasured {
        /// The material, described.
        material: String,
        /// The hardest row measured: the smoothest roughness, or the
        /// sharpest Phong exponent.
        edge: f64,
        /// Whether the rows are Phong exponents.
        sharp: bool,
        /// The best error the hardest row reaches (times the margin), a
        /// lower bound of this material's.
        best: f64,
    },
    /// A BRDF the rule has no measurements for.
    #[error(
        "{0}: the tolerance rule is measured for lambert, phong, isotropic ggx and gltf only; pass --lmax"
    )]
    Kind(String),
}

impl TolMaterial {
    /// The kind of `brdf`, with its roughness replaced by `roughness` when
    /// given (the smallest of a roughness map's, or of a glTF asset's
    /// materials).
    ///
    /// # Errors
    /// [`Unreachable::Kind`] for BRDFs without measurements (Blinn-Phong,
    /// Ward, MERL, anisotropic GGX).
    pub fn of(brdf: &Brdf, roughness: Option<f64>) -> Result<Self, Unreachable> {
        let r = |own: f64| roughness.unwrap_or(own);
        match brdf.model() {
            Model::Lambert => Ok(Self::Lambert),
            Model::Phong { s } => Ok(Self::Phong(*s)),
            Model::Ggx { ax, ay, .. } if ax == ay => Ok(Self::Ggx(r(ax.sqrt()))),
            Model::Gltf(m) if m.metallic > 0.0 => Ok(Self::GltfMetal(r(m.roughness))),
            Model::Gltf(m) => Ok(Self::GltfDielectric(r(m.roughness))),
            // the three parts: a metal is the hard case
            Model::GltfLobes { roughness: own } => Ok(Self::GltfMetal(r(*own))),
            _ => Err(Unreachable::Kind(brdf.spec().to_owned())),
        }
    }

    /// The same kind at roughness `r`; `None` for kinds without one (Phong,
    /// Lambert).
    #[must_use]
    pub fn with_roughness(self, r: f64) -> Option<Self> {
        match self {
            Self::GltfDielectric(_) => Some(Self::GltfDielectric(r)),
            Self::GltfMetal(_) => Some(Self::GltfMetal(r)),
            Self::Ggx(_) => Some(Self::Ggx(r)),
            Self::Phong(_) | Self::Lambert => None,
        }
    }

    /// The material, described for messages.
    #[must_use]
    pub fn describe(&self) -> String {
        // five significant digits: a texture's f32 roughness reads as such
        let g = |v: f64| format!("{}", format!("{v:.4e}").parse::<f64>().unwrap_or(v));
        match *self {
            Self::GltfDielectric(r) => format!("glTF dielectric, roughness {}", g(r)),
            Self::GltfMetal(r) => format!("glTF metal, roughness {}", g(r)),
            Self::Ggx(r) => format!("GGX, roughness {} (alpha {})", g(r), g(r * r)),
            Self::Phong(s) => format!("Phong, s = {}", g(s)),
            Self::Lambert => "Lambert".to_owned(),
        }
    }

    /// The measured rows of the kind, and the row parameter.
    fn rows(&self) -> (&'static [table::Row], Option<f64>) {
        match *self {
            Self::GltfDielectric(r) => (table::GLTF_DIELECTRIC, Some(r)),
            Self::GltfMetal(r) => (table::GLTF_METAL, Some(r)),
            Self::Ggx(r) => (table::GGX, Some(r)),
            Self::Phong(s) => (table::PHONG, Some(s)),
            Self::Lambert => (table::LAMBERT, None),
        }
    }
}

/// The smallest degree, at most `max_degree`, at which `material`'s
/// measured relative RMS error against the oracle (over the object and over
/// its grazing pixels, on both maps), times [`MARGIN`], is within `tol`;
/// between two measured rows, the larger of their degrees.
///
/// # Errors
/// [`Unreachable`] when no measured degree up to `max_degree` reaches `tol`
/// (with the best value that is reachable), or when the material is
/// smoother (sharper) than the measured rows.
pub fn degree_for(
    material: TolMaterial,
    tol: f64,
    max_degree: usize,
) -> Result<DegreeChoice, Unreachable> {
    let (rows, param) = material.rows();
    let used = bracket(material, rows, param, max_degree)?;
    let mut choice: Option<DegreeChoice> = None;
    for row in &used {
        let Some(&(l, _)) = row
            .errors
            .iter()
            .find(|&&(l, e)| l <= max_degree && e * MARGIN <= tol)
        else {
            // the reachable value: every row of the bracket reaches the
            // largest of their bests
            let (best_l, best) = used
                .iter()
                .map(|r| best(r, max_degree))
                .fold((0, 0.0), |(bl, be), (l, e)| (bl.max(l), f64::max(be, e)));
            return Err(Unreachable::Floor {
                material: material.describe(),
                tol,
                max_degree,
                best: best * MARGIN,
                best_l,
            });
        };
        if choice.is_none_or(|c| l > c.l_max) {
            choice = Some(DegreeChoice {
                l_max: l,
                measured: 0.0,
                row: row.param,
            });
        }
    }
    let mut c = choice.expect("a bracket has a row");
    // the measured error at the chosen degree, the worst of the bracket's
    // rows (a row whose ladder stopped below it: its last, converged, value)
    c.measured = used
        .iter()
        .map(|r| {
            r.errors
                .iter()
                .find(|(l, _)| *l >= c.l_max)
                .or(r.errors.last())
                .map_or(0.0, |&(_, e)| e)
        })
        .fold(0.0, f64::max);
    Ok(c)
}

/// As [`degree_for`] for a material whose roughness spans `range` (a
/// roughness map, a glTF asset's materials): the largest degree over the
/// range's two ends and every measured row between them, since neither end
/// alone bounds the error (smooth materials need the larger degree, rough
/// ones have the higher floor). For kinds without a roughness (Phong,
/// Lambert) the range is ignored.
///
/// # Errors
/// [`Unreachable`] as [`degree_for`], for the first point of the range
/// that cannot reach `tol`.
pub fn degree_for_range(
    material: TolMaterial,
    range: (f64, f64),
    tol: f64,
    max_degree: usize,
) -> Result<DegreeChoice, Unreachable> {
    let (lo, hi) = (range.0.min(range.1), range.0.max(range.1));
    if material.with_roughness(lo).is_none() {
        return degree_for(material, tol, max_degree);
    }
    let (rows, _) = material.rows();
    let mut points = vec![lo, hi];
    points.extend(rows.iter().map(|r| r.param).filter(|&p| p > lo && p < hi));
    let mut worst: Option<DegreeChoice> = None;
    for p in points {
        let at = material.with_roughness(p).expect("a roughness kind");
        let c = degree_for(at, tol, max_degree)?;
        if worst.is_none_or(|w| (c.l_max, c.measured) > (w.l_max, w.measured)) {
            worst = Some(c);
        }
    }
    Ok(worst.expect("two points at least"))
}

/// The degree `--tol` gives a render (`ifd render`, `ifd-envrender`): the
/// material kind of `brdf`, held over the `roughness` range a roughness map
/// or a glTF asset's materials span ([`degree_for_range`]; `None`: the
/// BRDF's own); with `asset`, the glTF asset's materials, which may be
/// metals, so a dielectric is taken by the metal's row, which covers both.
/// Returns the material the rule saw (its smoothest roughness) and the
/// choice.
///
/// # Errors
/// [`Unreachable`] for unmeasured BRDFs and tolerances out of reach.
pub fn degree_for_render(
    brdf: &Brdf,
    roughness: Option<(f64, f64)>,
    asset: bool,
    tol: f64,
    max_degree: usize,
) -> Result<(TolMaterial, DegreeChoice), Unreachable> {
    let mut material = TolMaterial::of(brdf, roughness.map(|r| r.0.min(r.1)))?;
    if asset && let TolMaterial::GltfDielectric(r) = material {
        material = TolMaterial::GltfMetal(r);
    }
    let choice = match roughness {
        Some(range) => degree_for_range(material, range, tol, max_degree),
        None => degree_for(material, tol, max_degree),
    }?;
    Ok((material, choice))
}

/// The measured rows `param` falls between (one when it is a row's, or
/// beyond the rows on the easy side), or why none.
fn bracket(
    material: TolMaterial,
    rows: &'static [table::Row],
    param: Option<f64>,
    max_degree: usize,
) -> Result<Vec<&'static table::Row>, Unreachable> {
    let Some(p) = param else {
        return Ok(vec![&rows[0]]);
    };
    let (first, last) = (&rows[0], &rows[rows.len() - 1]);
    // Phong: a larger exponent is harder; roughness: a smaller one
    let sharp = matches!(material, TolMaterial::Phong(_));
    let (hard_edge, beyond_hard, beyond_easy) = if sharp {
        (last, p > last.param * (1.0 + 1e-9), p < first.param)
    } else {
        (first, p < first.param * (1.0 - 1e-9), p > last.param)
    };
    if beyond_hard {
        return Err(unmeasured(material, hard_edge, max_degree));
    }
    if beyond_easy {
        return Ok(vec![if sharp { first } else { last }]);
    }
    if let Some(r) = rows.iter().find(|r| (r.param - p).abs() <= 1e-9 * p) {
        return Ok(vec![r]);
    }
    let i = rows.iter().rposition(|r| r.param < p).unwrap_or(0);
    Ok(vec![&rows[i], &rows[(i + 1).min(rows.len() - 1)]])
}

/// The smallest measured error of `row` up to `max_degree`, and its degree.
fn best(row: &table::Row, max_degree: usize) -> (usize, f64) {
    row.errors.iter().filter(|(l, _)| *l <= max_degree).fold(
        (0, f64::INFINITY),
        |(bl, be), &(l, e)| {
            if e < be { (l, e) } else { (bl, be) }
        },
    )
}

fn unmeasured(material: TolMaterial, edge: &table::Row, max_degree: usize) -> Unreachable {
    Unreachable::Unmeasured {
        material: material.describe(),
        edge: edge.param,
        sharp: matches!(material, TolMaterial::Phong(_)),
        best: best(edge, max_degree).1 * MARGIN,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TOLS: [f64; 9] = [0.2, 0.1, 0.05, 0.03, 0.02, 0.01, 0.005, 0.003, 0.001];

    fn all() -> Vec<TolMaterial> {
        let mut v = vec![TolMaterial::Lambert];
        for r in [0.2, 0.25, 0.3, 0.35, 0.45, 0.5, 0.55, 0.7, 0.9, 1.0, 1.5] {
            v.extend([
                TolMaterial::GltfDielectric(r),
                TolMaterial::GltfMetal(r),
                TolMaterial::Ggx(r),
            ]);
        }
        for s in [1.0, 4.0, 10.0, 64.0, 200.0, 256.0] {
            v.push(TolMaterial::Phong(s));
        }
        v
    }

    #[test]
    fn the_issues_dielectric_needs_more_than_l_24_for_one_percent() {
        // L = 24 errs 3.3% at grazing views on the issue's held-out map
        let c = degree_for(TolMaterial::GltfDielectric(0.5), 0.01, 100).unwrap();
        assert!(c.l_max > 24, "{c:?}");
    }

    #[test]
    fn rows_are_sorted_and_degrees_ascend() {
        for rows in [
            table::GLTF_DIELECTRIC,
            table::GLTF_METAL,
            table::GGX,
            table::PHONG,
            table::LAMBERT,
        ] {
            assert!(!rows.is_empty());
            assert!(rows.windows(2).all(|w| w[0].param < w[1].param));
            for r in rows {
                assert!(!r.errors.is_empty(), "{}", r.param);
                assert!(r.errors.windows(2).all(|w| w[0].0 < w[1].0));
                assert!(r.errors.iter().all(|(l, e)| *l <= 100 && *e > 0.0));
            }
        }
    }

    #[test]
    fn a_smaller_tolerance_never_gives_a_smaller_degree() {
        for m in all() {
            let mut last = 0;
            let mut refused = false;
            for tol in TOLS {
                match degree_for(m, tol, 100) {
                    Ok(c) => {
                        assert!(
                            !refused,
                            "{m:?}: {tol} reachable after a larger one was not"
                        );
                        assert!(c.l_max >= last, "{m:?} {tol}: {} < {last}", c.l_max);
                        assert!(c.measured * MARGIN <= tol);
                        last = c.l_max;
                    }
                    Err(_) => refused = true,
                }
            }
        }
    }

    #[test]
    fn between_two_rows_the_degree_covers_both() {
        let kinds: [fn(f64) -> TolMaterial; 4] = [
            TolMaterial::GltfDielectric,
            TolMaterial::GltfMetal,
            TolMaterial::Ggx,
            TolMaterial::Phong,
        ];
        for kind in kinds {
            let rows = kind(0.5).rows().0;
            for w in rows.windows(2) {
                let mid = 0.5 * (w[0].param + w[1].param);
                for tol in TOLS {
                    let (a, b) = (
                        degree_for(kind(w[0].param), tol, 100),
                        degree_for(kind(w[1].param), tol, 100),
                    );
                    match (a, b, degree_for(kind(mid), tol, 100)) {
                        (Ok(a), Ok(b), Ok(m)) => {
                            assert_eq!(m.l_max, a.l_max.max(b.l_max), "{mid} {tol}");
                            assert!(m.measured * MARGIN <= tol);
                        }
                        (a, b, Err(_)) => assert!(a.is_err() || b.is_err(), "{mid} {tol}"),
                        (_, _, Ok(m)) => panic!("{mid} {tol}: {m:?} where a row is refused"),
                    }
                }
            }
        }
    }

    #[test]
    fn unreachable_tolerances_are_refused_with_the_reachable_value() {
        for m in all() {
            // a tolerance below every measurement
            match degree_for(m, 1e-9, 100) {
                Err(Unreachable::Floor { best, best_l, .. }) => {
                    // the reachable value is reachable, at that degree
                    let c = degree_for(m, best, 100).unwrap();
                    assert!(c.l_max <= best_l, "{m:?}");
                }
                Err(Unreachable::Unmeasured { .. }) => {}
                other => panic!("{m:?}: {other:?}"),
            }
        }
        // roughness 0.1 is below the measured rows
        let e = degree_for(TolMaterial::GltfMetal(0.1), 0.01, 100).unwrap_err();
        assert!(matches!(e, Unreachable::Unmeasured { .. }), "{e}");
        assert!(e.to_string().contains("400"), "{e}");
        // the degree limit of the GPU kernel
        let r = degree_for(TolMaterial::GltfMetal(0.4), 0.05, 100).unwrap();
        if r.l_max > 63 {
            let e = degree_for(TolMaterial::GltfMetal(0.4), 0.05, 63).unwrap_err();
            assert!(e.to_string().contains("L = 63"), "{e}");
        }
    }

    #[test]
    fn kinds_of_brdfs() {
        let of = |s: &str| TolMaterial::of(&Brdf::parse(s).unwrap(), None);
        assert_eq!(of("lambert"), Ok(TolMaterial::Lambert));
        assert_eq!(of("phong:s=32"), Ok(TolMaterial::Phong(32.0)));
        assert_eq!(of("ggx:alpha=0.25"), Ok(TolMaterial::Ggx(0.5)));
        assert_eq!(
            of("gltf:roughness=0.5,metallic=0"),
            Ok(TolMaterial::GltfDielectric(0.5))
        );
        assert_eq!(
            of("gltf:roughness=0.5,metallic=0.3"),
            Ok(TolMaterial::GltfMetal(0.5))
        );
        assert!(matches!(of("ggx:ax=0.1,ay=0.4"), Err(Unreachable::Kind(_))));
        assert!(matches!(of("blinn:s=8"), Err(Unreachable::Kind(_))));
        assert_eq!(
            TolMaterial::GltfMetal(f64::from(0.1_f32)).describe(),
            "glTF metal, roughness 0.1"
        );
        let b = Brdf::parse("ggx:alpha=0.25").unwrap();
        assert_eq!(TolMaterial::of(&b, Some(0.3)), Ok(TolMaterial::Ggx(0.3)));
    }

    /// A roughness range is held to both its ends and the rows between:
    /// the smooth end's degree, and the rough end's floor.
    #[test]
    fn a_roughness_range_covers_its_smooth_and_rough_ends() {
        let metal = TolMaterial::GltfMetal(0.5);
        for tol in [0.01, 0.02, 0.05, 0.1] {
            let at = |r: f64| degree_for(TolMaterial::GltfMetal(r), tol, 100);
            let range = degree_for_range(metal, (0.5, 1.0), tol, 100);
            match (at(0.5), at(1.0)) {
                (Ok(lo), Ok(hi)) => {
                    let c = range.unwrap();
                    assert!(c.l_max >= lo.l_max.max(hi.l_max), "{tol}: {c:?}");
                }
                // either end out of reach: the range is too
                _ => assert!(range.is_err(), "{tol}: {range:?}"),
            }
        }
        // the rough end's floor (a few percent at grazing views) refuses
        // what the smooth end alone accepts
        assert!(degree_for(metal, 0.03, 100).is_ok());
        assert!(degree_for(TolMaterial::GltfMetal(1.0), 0.03, 100).is_err());
        assert!(degree_for_range(metal, (0.5, 1.0), 0.03, 100).is_err());
        // kinds without a roughness ignore the range
        assert_eq!(
            degree_for_range(TolMaterial::Lambert, (0.1, 0.9), 0.05, 100),
            degree_for(TolMaterial::Lambert, 0.05, 100)
        );
    }
}
