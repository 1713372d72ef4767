//! The spherical half: SH analysis and synthesis of environment maps, SH
//! rotation, decompositions of spherical filters into rotated lobes.

use ifd_sphere::Decomposition;
use ifd_sphere::{Chooser, DirectionSet, RzhBasis, Sharing};
use ifd_sphere::{EquirectTransform, Rotation, ShCoeffs, ShRotation};
use ifd_sphere::{IsdBasis, Profile, check_isd_degree};
use ifd_sphere::{Kernel, project_function};
use ifd_sphere::{Negatives, Projection, analyze_map};
use numpy::{PyArrayDyn, PyReadonlyArrayDyn};
use pyo3::prelude::*;

use crate::{arrays, errors};

/// SH coefficients from a `((L+1)^2,)` or `((L+1)^2, C)` float64 array, and
/// whether it had one dimension.
pub(crate) fn coeffs_from(
    what: &str,
    a: &PyReadonlyArrayDyn<'_, f64>,
) -> PyResult<(ShCoeffs, bool)> {
    let (shape, values) = arrays::values_f64(what, a)?;
    let (rows, channels, flat) = match shape[..] {
        [n] => (n, 1, true),
        [n, c] => (n, c, false),
        _ => {
            return Err(errors::value(
                what,
                format!("expected a ((L+1)^2,) or ((L+1)^2, C) array, got shape {shape:?}"),
            ));
        }
    };
    let c =
        ShCoeffs::from_rows(rows, channels, values.to_vec()).map_err(|e| errors::value(what, e))?;
    Ok((c, flat))
}

fn coeffs_array(py: Python<'_>, c: ShCoeffs, flat: bool) -> Bound<'_, PyArrayDyn<f64>> {
    let (rows, channels) = ((c.l_max() + 1).pow(2), c.channels());
    let shape = if flat {
        vec![rows]
    } else {
        vec![rows, channels]
    };
    arrays::array_f64(py, &shape, c.data().to_vec())
}

/// `projection`: `"texel"`, `"centre"` or `None` (texel for 2:1 maps, centre
/// for cube strips), as `ifd sphere sh --projection`.
fn parse_projection(projection: Option<&str>) -> PyResult<Option<Projection>> {
    match projection {
        None => Ok(None),
        Some("texel") => Ok(Some(Projection::Texel)),
        Some("centre") => Ok(Some(Projection::Centre)),
        Some(other) => Err(errors::value(
            "projection",
            format!("{other:?}: use \"texel\" or \"centre\""),
        )),
    }
}

/// An analysis error as a `ValueError` naming `projection` (a texel
/// projection asked of a cube strip) or else `env`.
fn projection_or_env(e: ifd_sphere::SphereError) -> PyErr {
    match e {
        ifd_sphere::SphereError::Parameter {
            name: "projection", ..
        } => errors::value("projection", e),
        e => errors::value("env", e),
    }
}

/// The SH coefficients `((L+1)^2, C)` of an equirectangular (2:1) or
/// cubemap-strip (6:1) map: `ifd sphere sh`.
#[pyfunction]
#[pyo3(signature = (env, lmax, *, keep_negatives=false, projection=None))]
fn sphere_sh<'py>(
    py: Python<'py>,
    env: PyReadonlyArrayDyn<'py, f32>,
    lmax: usize,
    keep_negatives: bool,
    projection: Option<&str>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let projection = parse_projection(projection)?;
    let img = arrays::image_view("env", &env)?.to_image();
    let (w, h) = (img.width(), img.height());
    let neg = if keep_negatives {
        Negatives::Keep
    } else {
        Negatives::Clamp
    };
    let analysis = py
        .detach(|| analyze_map(&img, lmax, neg, projection).map(|(a, _)| a))
        .map_err(|e| match e {
            ifd_sphere::SphereError::NotEquirect { .. } => errors::value(
                "env",
                format!(
                    "a map must be 2:1 (equirectangular, W = 2H, H >= 2) or 6:1 (cubemap strip \
                     +X,-X,+Y,-Y,+Z,-Z); got {w}x{h}"
                ),
            ),
            e => projection_or_env(e),
        })?;
    Ok(coeffs_array(py, analysis.coeffs, false))
}

/// The `height x width` equirectangular map of SH coefficients, `(H, W, C)`
/// float32 (`(H, W)` for one-dimensional coefficients).
#[pyfunction]
fn sphere_synthesize<'py>(
    py: Python<'py>,
    coeffs: PyReadonlyArrayDyn<'py, f64>,
    width: usize,
    height: usize,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let (c, flat) = coeffs_from("coeffs", &coeffs)?;
    let img = py
        .detach(|| EquirectTransform::new(c.l_max(), width, height)?.synthesize(&c))
        .map_err(|e| errors::value("", e))?;
    Ok(arrays::image_array(py, img, flat))
}

/// Rotated SH coefficients `g(w) = f(R^T w)` with `R = Rz(a) Ry(b) Rz(c)`:
/// `ifd sphere rotate`.
#[pyfunction]
#[pyo3(signature = (coeffs, zyz, *, method="zhf"))]
fn sphere_rotate<'py>(
    py: Python<'py>,
    coeffs: PyReadonlyArrayDyn<'py, f64>,
    zyz: (f64, f64, f64),
    method: &str,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let (a, b, c) = zyz;
    if ![a, b, c].iter().all(|x| x.is_finite()) {
        return Err(errors::value(
            "zyz",
            format!("{zyz:?}: expected three finite angles (radians)"),
        ));
    }
    if !matches!(method, "zhf" | "tailored" | "reference") {
        return Err(errors::value(
            "method",
            format!("{method:?}: expected 'zhf', 'tailored' or 'reference'"),
        ));
    }
    let (f, flat) = coeffs_from("coeffs", &coeffs)?;
    let r = Rotation::from_zyz(a, b, c);
    let g = py
        .detach(|| {
            let l = f.l_max();
            if method == "reference" {
                ShRotation::new(&r, l)?.apply(&f)
            } else {
                let basis =
                    RzhBasis::new(DirectionSet::new(l, Sharing::Shared, Chooser::Fibonacci)?)?;
                if method == "zhf" {
                    basis.rotate(&f, &r)
                } else {
                    basis.rotate_tailored(&f, &r)
                }
            }
        })
        .map_err(|e| errors::value("", e))?;
    Ok(coeffs_array(py, g, flat))
}

/// A spherical filter decomposed into rotated lobes (ISD Eq. 15-19).
#[pyclass(module = "ifd._ifd", name = "SphereDecomposition", frozen)]
pub(crate) struct PySphereDecomposition {
    inner: Decomposition,
}

#[pymethods]
impl PySphereDecomposition {
    /// Parses the JSON text of `ifd sphere decompose`.
    #[staticmethod]
    fn from_json(text: &str) -> PyResult<Self> {
        let inner = Decomposition::from_json(text).map_err(|e| errors::value("", e))?;
        Ok(Self { inner })
    }

    /// Reads a file written by `ifd sphere decompose` or [`Self::save`].
    #[staticmethod]
    fn load(path: std::path::PathBuf) -> PyResult<Self> {
        let text = std::fs::read_to_string(&path)
            .map_err(|e| errors::os(format!("{}: {e}", path.display())))?;
        Self::from_json(&text).map_err(|e| errors::value(&path.display().to_string(), e))
    }

    /// The JSON text (the file format of `ifd sphere decompose`).
    fn to_json(&self) -> PyResult<String> {
        self.inner.to_json().map_err(|e| errors::value("", e))
    }

    /// Writes the JSON file (atomically).
    fn save(&self, path: std::path::PathBuf) -> PyResult<()> {
        let text = self.to_json()?;
        ifd_image::atomic_write(&path, |w| {
            use std::io::Write;
            w.write_all(text.as_bytes()).map_err(|e| e.to_string())
        })
        .map_err(errors::os)
    }

    /// The maximum SH degree `L`.
    #[getter]
    fn lmax(&self) -> usize {
        self.inner.l_max()
    }

    /// The mother functions' name.
    #[getter]
    fn profile(&self) -> &'static str {
        self.inner.profile.name()
    }

    /// The lobe directions, `(N, 3)`.
    #[getter]
    fn directions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArrayDyn<f64>> {
        let dirs = self.inner.directions.all();
        let data = dirs.iter().flat_map(|d| d.iter().copied()).collect();
        arrays::array_f64(py, &[dirs.len(), 3], data)
    }

    /// The lobe weights `lambda_l^j`, `(lobes, C)`.
    #[getter]
    fn weights<'py>(&self, py: Python<'py>) -> Bound<'py, PyArrayDyn<f64>> {
        let w = &self.inner.weights;
        let c = w.channels.max(1);
        arrays::array_f64(py, &[w.data.len() / c, c], w.data.clone())
    }

    /// The condition number of `M`.
    #[getter]
    fn condition_number(&self) -> f64 {
        self.inner.condition_number
    }

    fn __repr__(&self) -> String {
        format!(
            "<ifd.sphere.Decomposition: L = {}, {} profile, {} directions, cond(M) = {:.3e}>",
            self.inner.l_max(),
            self.inner.profile.name(),
            self.inner.directions.all().len(),
            self.inner.condition_number
        )
    }

    /// Pickling: the JSON text.
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyAny>, (String,))> {
        let from_json = py
            .import("ifd._ifd")?
            .getattr("SphereDecomposition")?
            .getattr("from_json")?;
        Ok((from_json, (self.to_json()?,)))
    }
}

/// Decomposes a spherical filter (a kernel spec centred on +z, or SH
/// coefficients) into rotated lobes: `ifd sphere decompose`.
#[pyfunction]
#[pyo3(signature = (kernel, lmax, *, directions="fibonacci", profile="zonal", seed=1, max_cond=1e10))]
fn sphere_decompose(
    py: Python<'_>,
    kernel: &Bound<'_, PyAny>,
    lmax: usize,
    directions: &str,
    profile: &str,
    seed: u64,
    max_cond: f64,
) -> PyResult<PySphereDecomposition> {
    check_isd_degree(lmax).map_err(|e| errors::value("lmax", e))?;
    let profile = Profile::parse(profile).map_err(|e| errors::value("profile", e))?;
    let coeffs = if let Ok(spec) = kernel.extract::<String>() {
        let k = Kernel::parse(&spec).map_err(|e| errors::value("kernel", e))?;
        py.detach(|| project_function(lmax, |w| k.eval(w), k.suggested_nodes(lmax)))
            .map_err(|e| errors::value("kernel", e))?
    } else {
        let a: PyReadonlyArrayDyn<'_, f64> = kernel.extract().map_err(|_| {
            errors::value(
                "kernel",
                "expected a kernel spec (str) or an array of SH coefficients (float64)",
            )
        })?;
        coeffs_from("kernel", &a)?
            .0
            .resized(lmax)
            .map_err(|e| errors::value("kernel", e))?
    };
    let inner = py
        .detach(|| {
            let dirs = DirectionSet::by_name(directions, lmax, seed)?;
            let basis = IsdBasis::with_limit(profile, dirs, max_cond)?;
            Decomposition::new(&basis, &coeffs)
        })
        .map_err(|e| errors::value("", e))?;
    Ok(PySphereDecomposition { inner })
}

/// Filters an environment map with a spherical decomposition (ISD Eq.
/// 6/13/14): `ifd sphere filter`. The kernel is normalised to unit integral
/// unless `raw`; `size` is the output's `(width, height)` (2:1 or 6:1;
/// default the input's).
#[pyfunction]
#[pyo3(signature = (env, decomposition, *, size=None, raw=false, keep_negatives=false, projection=None))]
fn sphere_filter<'py>(
    py: Python<'py>,
    env: PyReadonlyArrayDyn<'py, f32>,
    decomposition: &PySphereDecomposition,
    size: Option<(usize, usize)>,
    raw: bool,
    keep_negatives: bool,
    projection: Option<&str>,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    use ifd_sphere::{MapLayout, Prefiltered};
    let projection = parse_projection(projection)?;
    let img = arrays::image_view("env", &env)?.to_image();
    let (w, h) = (img.width(), img.height());
    MapLayout::from_size(w, h).map_err(|_| {
        errors::value(
            "env",
            format!(
                "a map must be 2:1 (equirectangular, W = 2H, H >= 2) or 6:1 (cubemap strip \
                 +X,-X,+Y,-Y,+Z,-Z); got {w}x{h}"
            ),
        )
    })?;
    let (ow, oh) = size.unwrap_or((w, h));
    if MapLayout::from_size(ow, oh).is_err() || ow > 16384 || oh > 16384 {
        return Err(errors::value(
            "size",
            format!(
                "{ow}x{oh}: the output must be 2:1 (equirectangular, H >= 2) or 6:1 (cubemap \
                 strip), at most 16384 on a side"
            ),
        ));
    }
    let dec = &decomposition.inner;
    let l = dec.l_max();
    let neg = if keep_negatives {
        Negatives::Keep
    } else {
        Negatives::Clamp
    };
    let out = py.detach(|| -> PyResult<ifd_image::Image> {
        let (a, _) = analyze_map(&img, l, neg, projection).map_err(projection_or_env)?;
        let integral = dec.kernel_integral().map_err(|e| errors::value("", e))?;
        let l1: f64 = dec.weights.data.iter().map(|v| v.abs()).sum();
        let scale = if raw {
            1.0
        } else if integral.abs() > 1e-9 * l1.max(f64::MIN_POSITIVE) {
            1.0 / integral
        } else {
            return Err(errors::value(
                "decomposition",
                format!(
                    "the kernel integrates to {integral:.3e} (zero-mean or cancelling): it \
                     cannot be normalised to unit integral; pass raw=True"
                ),
            ));
        };
        let pre = Prefiltered::new(&a.coeffs, dec).map_err(|e| errors::value("", e))?;
        dec.filter_map(&pre, ow, oh, scale, &|_, _| {})
            .map_err(|e| errors::value("", e))
    })?;
    Ok(arrays::image_array(py, out, false))
}

/// Adds the spherical functions and classes to the module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PySphereDecomposition>()?;
    m.add_function(wrap_pyfunction!(sphere_sh, m)?)?;
    m.add_function(wrap_pyfunction!(sphere_synthesize, m)?)?;
    m.add_function(wrap_pyfunction!(sphere_rotate, m)?)?;
    m.add_function(wrap_pyfunction!(sphere_decompose, m)?)?;
    m.add_function(wrap_pyfunction!(sphere_filter, m)?)?;
    Ok(())
}
