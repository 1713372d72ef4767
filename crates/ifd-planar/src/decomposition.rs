//! The result of decomposing a filter: a list of weighted, displaced isotropic
//! Gaussians (Eq. 2 of the IFD paper), and its file format.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::dictionary::DictionaryParams;
use crate::kernel::{KernelSpec, Sampling};
use crate::term::Term;

/// The `format` field of decomposition files.
pub const FORMAT: &str = "ifd-decomposition";
/// The file format version written and read.
pub const VERSION: u64 = 1;

/// A filter decomposed into displaced isotropic Gaussians.
///
/// The result of decomposing a filter: a list of weighted, displaced isotropic
/// Gaussians (Eq. 2 of the IFD paper), and its file format.
///
/// # Why rotated and scaled filters cost one lookup per term
/// Let `k(d) = sum_t w_t g_{sigma_t}(d - c_t)` and
/// `k_{theta,s}(d) = k(R_{-theta} d / s) / s^2` (the crate convention). For one term,
/// using `R_{-theta} d / s - c = R_{-theta} (d - s R_theta c) / s`, the isotropy
/// `g_sigma(R u) = g_sigma(u)` and the scaling `g_sigma(u / s) / s^2 = g_{s sigma}(u)`:
///
/// ```text
/// g_sigma(R_{-theta} d / s - c) / s^2 = g_sigma((d - s R_theta c) / s) / s^2
///                                     = g_{s sigma}(d - s R_theta c),
/// ```
///
/// so `k_{theta,s}(d) = sum_t w_t g_{s sigma_t}(d - s R_theta c_t)`: the same
/// weights, atoms widened by `s`, centres rotated and scaled. Correlating an
/// image `f` with it, and using the symmetry `g(-u) = g(u)`,
///
/// ```text
/// out(p) = sum_q k_{theta,s}(q - p) f(q)
///        = sum_t w_t sum_q g_{s sigma_t}(q - p - s R_theta c_t) f(q)
///        = sum_t w_t fhat_{s sigma_t}(p + s R_theta c_t),   fhat_sigma = f (*) g_sigma,
/// ```
///
/// one lookup per term into the scale stack `fhat` (Eq. 3 of the paper).
///
/// # File format
/// JSON, versioned and self-describing:
///
/// ```json
/// {
///   "format": "ifd-decomposition",
///   "version": 1,
///   "kernel": { "width": 193, "height": 193, "spec": "gauss:sx=24,sy=3,theta=30" },
///   "dictionary": { "levels": 6, "ratio": 0.5, "sigmas_per_octave": 4, "oversampling": 1, "half_width": 96.0 },
///   "report": { "terms": 180, "rel_l2_error": 0.0098, "max_error": 0.01, "dc_error": 1e-4,
///               "iterations": 400, "seconds": 1.2, "dictionary_atoms": 20000, "tau": 1e-5 },
///   "terms": [ { "weight": 0.01, "x": -3.0, "y": 6.0, "sigma": 1.5 } ]
/// }
/// ```
///
/// `kernel`, `dictionary`, `report` and `kernel.spec` may be `null` (a
/// hand-made decomposition); `format`, `version` and `terms` are required.
/// [`Decomposition::load`] rejects anything else with a [`DecompositionFileError`].
#[derive(Clone, Debug, PartialEq)]
pub struct Decomposition {
    /// The non-zero terms.
    pub terms: Vec<Term>,
    /// Size `(width, height)` of the kernel that was fitted, if known.
    pub kernel_size: Option<(usize, usize)>,
    /// The spec string of the kernel that was fitted, if any.
    pub spec: Option<String>,
    /// The dictionary the terms were chosen from, if known.
    pub dictionary: Option<DictionaryParams>,
    /// What the fit achieved, if known.
    pub report: Option<FitReport>,
    /// How the fitted kernel sampled its filter, which decides how the
    /// decomposition is applied at other scales. Files written before this
    /// field existed infer it from the spec (hard-edged specs `Area`, other
    /// specs and kernel files `Point`).
    pub sampling: Sampling,
}

/// Everything that can be wrong reading or writing a decomposition file.
#[derive(Debug, thiserror::Error)]
pub enum DecompositionFileError {
    /// The file could not be read or written.
    // `error`, not `source`: the message already says it, and as an error
    // source it would be printed twice by `{:#}` chains.
    #[error("{}: {error}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        error: std::io::Error,
    },
    /// Not JSON, truncated JSON, or a missing/mistyped field (serde's message
    /// names the field and the line).
    #[error("{}: not a valid decomposition file: {reason}", path.display())]
    Json {
        /// The file (empty when parsing a string).
        path: PathBuf,
        /// What the parser said.
        reason: String,
    },
    /// The `format` field is missing or not `"ifd-decomposition"`.
    #[error("{}: not an ifd decomposition file (format {}, expected \"{FORMAT}\"{})", path.display(),
        found.as_deref().map_or_else(|| "missing".to_string(), |f| format!("{f:?}")),
        if found.as_deref().is_some_and(|f| f.starts_with("ifd-sphere")) {
            "; this is a spherical decomposition from `ifd sphere decompose`, used by `ifd sphere filter`"
        } else { "" })]
    Format {
        /// The file.
        path: PathBuf,
        /// The format found.
        found: Option<String>,
    },
    /// A `version` this build does not read.
    #[error("{}: decomposition file version {} is not supported (this build reads version {VERSION})",
        path.display(), found.as_deref().unwrap_or("missing"))]
    Version {
        /// The file.
        path: PathBuf,
        /// The version found.
        found: Option<String>,
    },
    /// A field has an invalid value.
    #[error("{}: invalid {field}: {reason}", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// The field, e.g. `terms[3].sigma`.
        field: String,
        /// Why.
        reason: String,
    },
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct KernelInfo {
    width: usize,
    height: usize,
    spec: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    sampling: Option<Sampling>,
}

#[derive(Serialize, Deserialize)]
struct FileRepr {
    format: String,
    version: u64,
    kernel: Option<KernelInfo>,
    dictionary: Option<DictionaryParams>,
    report: Option<FitReport>,
    terms: Vec<Term>,
}

impl Decomposition {
    /// A decomposition made of the given terms (no fit metadata).
    #[must_use]
    pub fn from_terms(terms: Vec<Term>) -> Self {
        Self {
            terms,
            kernel_size: None,
            spec: None,
            dictionary: None,
            report: None,
            sampling: Sampling::Continuous,
        }
    }

    /// The file contents (pretty JSON).
    ///
    /// ```
    /// use ifd_planar::{Decomposition, Term};
    /// let d = Decomposition::from_terms(vec![Term { weight: 1.0, x: 0.0, y: 2.0, sigma: 1.5 }]);
    /// let back = Decomposition::from_json_str(&d.to_json_string())?;
    /// assert_eq!(back, d);
    /// assert!(Decomposition::from_json_str("{\"format\": \"ifd-decomposition\", \"version\": 2}").is_err());
    /// # Ok::<(), ifd_planar::DecompositionFileError>(())
    /// ```
    #[must_use]
    pub fn to_json_string(&self) -> String {
        let repr = FileRepr {
            format: FORMAT.to_string(),
            version: VERSION,
            kernel: self.kernel_size.map(|(width, height)| KernelInfo {
                width,
                height,
                spec: self.spec.clone(),
                sampling: Some(self.sampling),
            }),
            dictionary: self.dictionary.clone(),
            report: self.report.clone(),
            terms: self.terms.clone(),
        };
        serde_json::to_string_pretty(&repr).expect("a decomposition always serialises to JSON")
    }

    /// Parses file contents and validates them.
    ///
    /// # Errors
    /// See [`DecompositionFileError`].
    pub fn from_json_str(text: &str) -> Result<Self, DecompositionFileError> {
        Self::parse(text, Path::new(""))
    }

    fn parse(text: &str, path: &Path) -> Result<Self, DecompositionFileError> {
        let json_err = |e: serde_json::Error| DecompositionFileError::Json {
            path: path.to_path_buf(),
            reason: e.to_string(),
        };
        let value: serde_json::Value = serde_json::from_str(text).map_err(json_err)?;
        let format = value.get("format").map(|f| match f.as_str() {
            Some(s) => s.to_string(),
            None => f.to_string(),
        });
        if format.as_deref() != Some(FORMAT) {
            return Err(DecompositionFileError::Format {
                path: path.to_path_buf(),
                found: format,
            });
        }
        let version = value.get("version");
        if version.and_then(serde_json::Value::as_u64) != Some(VERSION) {
            return Err(DecompositionFileError::Version {
                path: path.to_path_buf(),
                found: version.map(ToString::to_string),
            });
        }
        let repr: FileRepr = serde_json::from_value(value).map_err(json_err)?;
        let invalid = |field: String, reason: String| DecompositionFileError::Invalid {
            path: path.to_path_buf(),
            field,
            reason,
        };
        for (i, t) in repr.terms.iter().enumerate() {
            for (name, v) in [
                ("weight", t.weight),
                ("x", t.x),
                ("y", t.y),
                ("sigma", t.sigma),
            ] {
                if !v.is_finite() {
                    return Err(invalid(
                        format!("terms[{i}].{name}"),
                        format!("{v} is not finite"),
                    ));
                }
            }
            if t.sigma <= 0.0 {
                return Err(invalid(
                    format!("terms[{i}].sigma"),
                    format!("{} is not positive", t.sigma),
                ));
            }
        }
        if let Some(k) = &repr.kernel
            && (k.width.is_multiple_of(2) || k.height.is_multiple_of(2))
        {
            return Err(invalid(
                "kernel".into(),
                format!("size {}x{} is not odd", k.width, k.height),
            ));
        }
        if let Some(p) = &repr.dictionary {
            // the first field out of its range, named as the file names it
            let bad = [
                ("levels", p.levels as f64, p.levels >= 1, "at least 1"),
                (
                    "ratio",
                    p.ratio,
                    p.ratio.is_finite() && p.ratio > 0.0,
                    "finite and positive",
                ),
                (
                    "sigmas_per_octave",
                    p.sigmas_per_octave as f64,
                    p.sigmas_per_octave >= 1,
                    "at least 1",
                ),
                (
                    "oversampling",
                    p.oversampling as f64,
                    p.oversampling >= 1,
                    "at least 1",
                ),
                (
                    "half_width",
                    p.half_width,
                    p.half_width.is_finite() && p.half_width > 0.0,
                    "finite and positive",
                ),
            ]
            .into_iter()
            .find(|(_, _, ok, _)| !ok);
            if let Some((name, value, _, want)) = bad {
                return Err(invalid(
                    "dictionary".into(),
                    format!("{name} is {value}, must be {want}"),
                ));
            }
        }
        // Version-1 files before `sampling`: a fitted kernel was sampled as
        // its spec samples (hard-edged specs by area), a kernel file by point.
        let sampling = match &repr.kernel {
            None => Sampling::Continuous,
            Some(KernelInfo {
                sampling: Some(s), ..
            }) => *s,
            Some(KernelInfo { spec, .. }) => spec
                .as_deref()
                .and_then(|s| s.parse::<KernelSpec>().ok())
                .map_or(Sampling::Point, |s| s.sampling()),
        };
        Ok(Self {
            terms: repr.terms,
            kernel_size: repr.kernel.as_ref().map(|k| (k.width, k.height)),
            spec: repr.kernel.and_then(|k| k.spec),
            dictionary: repr.dictionary,
            report: repr.report,
            sampling,
        })
    }

    /// Writes the decomposition file (atomically: on failure no partial
    /// file is left, and an existing one is unchanged).
    ///
    /// # Errors
    /// [`DecompositionFileError::Io`] when the file cannot be written.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), DecompositionFileError> {
        let path = path.as_ref();
        let text = self.to_json_string() + "\n";
        ifd_image::atomic_write(path, |w| {
            std::io::Write::write_all(w, text.as_bytes()).map_err(|e| e.to_string())
        })
        .map_err(|e| DecompositionFileError::Io {
            path: path.to_path_buf(),
            error: std::io::Error::other(match e {
                ifd_image::ImageError::Write { reason, .. } => reason,
                other => other.to_string(),
            }),
        })
    }

    /// Reads and validates a decomposition file.
    ///
    /// # Errors
    /// See [`DecompositionFileError`]: unreadable file, malformed or truncated
    /// JSON, missing fields, wrong format or version, non-finite values,
    /// non-positive widths.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, DecompositionFileError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|error| DecompositionFileError::Io {
            path: path.to_path_buf(),
            error,
        })?;
        Self::parse(&text, path)
    }

    /// The kernel the decomposition represents, evaluated at integer offset
    /// `(dx, dy)` from the kernel centre.
    #[must_use]
    pub fn eval(&self, dx: f64, dy: f64) -> f64 {
        self.terms
            .iter()
            .map(|t| {
                let ex = dx - t.x;
                let ey = dy - t.y;
                let s2 = t.sigma * t.sigma;
                t.weight * (-(ex * ex + ey * ey) / (2.0 * s2)).exp()
                    / (2.0 * std::f64::consts::PI * s2)
            })
            .sum()
    }
}

/// What a fit achieved.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FitReport {
    /// Number of terms `s`.
    pub terms: usize,
    /// `||recon - k||_2 / ||k||_2` over the kernel's samples.
    pub rel_l2_error: f64,
    /// `max |recon - k| / max |k|`.
    pub max_error: f64,
    /// `|sum recon - sum k| / sum |k|` (the relative DC error for non-negative kernels).
    pub dc_error: f64,
    /// `SpaRSA` iterations, all stages.
    pub iterations: usize,
    /// Wall-clock seconds of the fit.
    pub seconds: f64,
    /// Atoms in the dictionary.
    pub dictionary_atoms: usize,
    /// The final absolute `tau`.
    pub tau: f64,
    /// The fit's grid was this many times finer than the pixels
    /// (`decompose_oversampled`); 1 for the pixel grid.
    #[serde(default = "one")]
    pub oversample: usize,
    /// With `oversample > 1`, the relative L2 error on the fine grid (the
    /// continuous filter between pixel centres).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fine_rel_l2_error: Option<f64>,
    /// Pixels of zeros around the kernel's window over which the fit was
    /// made and the errors are measured (0 in files written before it
    /// existed: errors inside the window only).
    #[serde(default)]
    pub margin: usize,
    /// The sum of the kernel's samples (1 for normalised kernels, 0 for
    /// zero-mean ones); `None` in files written before it existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kernel_sum: Option<f64>,
    /// The DC gain of the filter as applied at the fitted pose: the sum over
    /// the whole plane of the sum of Gaussians sampled at pixel centres
    /// (`sampled_dc_gain`), what a constant image is multiplied by;
    /// `None` in files written before it existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dc_gain: Option<f64>,
}

impl FitReport {
    /// The full-plane DC error `|dc_gain - sum k|`: how much the filter
    /// changes a constant image relative to the kernel, next to the windowed
    /// [`FitReport::dc_error`]. `None` in older files.
    #[must_use]
    pub fn full_plane_dc_error(&self) -> Option<f64> {
        Some((self.dc_gain? - self.kernel_sum?).abs())
    }
}

fn one() -> usize {
    1
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Decomposition {
        let k: crate::Kernel = "gauss:sx=5,sy=2,theta=20".parse().unwrap();
        crate::fit::decompose(&k, &crate::fit::DecomposeOptions::default(), |_, _, _| {}).unwrap()
    }

    #[test]
    fn file_round_trip() {
        let d = sample();
        assert!(d.report.is_some() && d.dictionary.is_some());
        let dir = std::env::temp_dir().join(format!("ifd-planar-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("d.json");
        d.save(&path).unwrap();
        let back = Decomposition::load(&path).unwrap();
        assert_eq!(back, d);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn malformed_files_are_rejected() {
        let good = sample().to_json_string();
        let parse = |s: &str| Decomposition::from_json_str(s).unwrap_err();
        assert!(matches!(
            parse(&good[..good.len() / 2]),
            DecompositionFileError::Json { .. }
        ));
        assert!(matches!(
            parse(&good.replace("ifd-decomposition", "other")),
            DecompositionFileError::Format { .. }
        ));
        assert!(matches!(
            parse(&good.replace("\"version\": 1", "\"version\": 7")),
            DecompositionFileError::Version { .. }
        ));
        assert!(matches!(
            parse("{\"format\": \"ifd-decomposition\"}"),
            DecompositionFileError::Version { .. }
        ));
        let e = parse(
            "{\"format\": \"ifd-decomposition\", \"version\": 1, \"kernel\": null, \"dictionary\": null, \"report\": null}",
        );
        assert!(e.to_string().contains("terms"), "{e}");
        let one = |t: &str| {
            format!(
                "{{\"format\": \"ifd-decomposition\", \"version\": 1, \"kernel\": null, \"dictionary\": null, \"report\": null, \"terms\": [{t}]}}"
            )
        };
        assert!(
            Decomposition::from_json_str(&one("{\"weight\": 1, \"x\": 0, \"y\": 0, \"sigma\": 1}"))
                .is_ok()
        );
        let e = parse(&one("{\"weight\": 1, \"x\": 0, \"y\": 0, \"sigma\": -1}"));
        assert!(e.to_string().contains("terms[0].sigma"), "{e}");
        // NaN is not JSON; a string in its place is a type error naming the field.
        let e = parse(&one(
            "{\"weight\": \"NaN\", \"x\": 0, \"y\": 0, \"sigma\": 1}",
        ));
        assert!(matches!(e, DecompositionFileError::Json { .. }), "{e}");
        let e = parse(&one(
            "{\"weight\": 1e999, \"x\": 0, \"y\": 0, \"sigma\": 1}",
        ));
        assert!(
            e.to_string().contains("weight") || e.to_string().contains("number"),
            "{e}"
        );
        let e = parse(&one("{\"weight\": 1, \"x\": 0, \"sigma\": 1}"));
        assert!(e.to_string().contains("`y`"), "{e}");
        assert!(matches!(
            Decomposition::load("/nonexistent/d.json"),
            Err(DecompositionFileError::Io { .. })
        ));
    }
}
