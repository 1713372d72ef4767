//! The planar half: decompositions, filtering, the Hessian, smoothing,
//! image comparison.

use std::fmt::Write as _;
use std::sync::{Arc, Mutex, OnceLock};

use ifd_planar::decompose_spec;
use ifd_planar::{
    Border, CheckedField, DecomposeOptions, Decomposition, Field, FieldKind, Interpolation, Kernel,
    KernelSpec, PreparedDecomposition, Term, decompose,
};
use ifd_planar::{FilterOptions, FilterPlan, FilterSetPlan};
use ifd_smooth::{AnisoParams, AspectBank, HessianBank, Mode, SmoothOptions, Smoother};
use numpy::{PyArrayDyn, PyReadonlyArray2, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::{arrays, errors, timed};

/// A decomposed planar filter: a sparse sum of displaced isotropic Gaussians
/// `k(d) = sum_t w_t g_{sigma_t}(d - c_t)`, with its fit report.
#[pyclass(module = "ifd._ifd", name = "Decomposition", frozen)]
pub(crate) struct PyDecomposition {
    pub(crate) inner: Decomposition,
}

#[pymethods]
impl PyDecomposition {
    /// Reads a decomposition file (the CLI's JSON format).
    #[staticmethod]
    fn load(path: std::path::PathBuf) -> PyResult<Self> {
        let inner = Decomposition::load(&path).map_err(|e| errors::decomposition_file(&e))?;
        Ok(Self { inner })
    }

    /// Parses the JSON text of a decomposition file.
    #[staticmethod]
    fn from_json(text: &str) -> PyResult<Self> {
        let inner = Decomposition::from_json_str(text).map_err(|e| errors::value("", e))?;
        Ok(Self { inner })
    }

    /// A decomposition from an `(N, 4)` float64 array of terms
    /// `(weight, x, y, sigma)` (pixels; `x` right, `y` down).
    #[staticmethod]
    fn from_terms(terms: PyReadonlyArrayDyn<'_, f64>) -> PyResult<Self> {
        let (shape, values) = arrays::values_f64("terms", &terms)?;
        if shape.len() != 2 || shape[1] != 4 {
            return Err(errors::value(
                "terms",
                format!("expected an (N, 4) array of (weight, x, y, sigma), got shape {shape:?}"),
            ));
        }
        let terms: Vec<Term> = values
            .chunks_exact(4)
            .map(|t| Term {
                weight: t[0],
                x: t[1],
                y: t[2],
                sigma: t[3],
            })
            .collect();
        let inner = Decomposition::from_terms(terms);
        // The checks every filter applies, at construction.
        PreparedDecomposition::new(&inner).map_err(|e| errors::value("terms", e))?;
        Ok(Self { inner })
    }

    /// Writes the decomposition file (atomically).
    fn save(&self, path: std::path::PathBuf) -> PyResult<()> {
        self.inner
            .save(&path)
            .map_err(|e| errors::decomposition_file(&e))
    }

    /// The file's JSON text.
    fn to_json(&self) -> String {
        self.inner.to_json_string()
    }

    /// The terms as an `(N, 4)` float64 array `(weight, x, y, sigma)`.
    #[getter]
    fn terms<'py>(&self, py: Python<'py>) -> Bound<'py, PyArrayDyn<f64>> {
        let data = self
            .inner
            .terms
            .iter()
            .flat_map(|t| [t.weight, t.x, t.y, t.sigma])
            .collect();
        arrays::array_f64(py, &[self.inner.terms.len(), 4], data)
    }

    /// The filter spec it was fitted to, if any.
    #[getter]
    fn spec(&self) -> Option<String> {
        self.inner.spec.clone()
    }

    /// The fitted kernel's `(width, height)`, if known.
    #[getter]
    fn kernel_size(&self) -> Option<(usize, usize)> {
        self.inner.kernel_size
    }

    /// How the kernel sampled the filter: `continuous`, `point` or `area`.
    #[getter]
    fn sampling(&self) -> String {
        format!("{:?}", self.inner.sampling).to_lowercase()
    }

    /// The fit report as a dict (the keys of `ifd decompose --json`), or
    /// `None` for a decomposition made from terms.
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(r) = &self.inner.report else {
            return Ok(None);
        };
        let d = PyDict::new(py);
        d.set_item("terms", r.terms)?;
        d.set_item("rel_l2_error", r.rel_l2_error)?;
        d.set_item("max_error", r.max_error)?;
        d.set_item("dc_error", r.dc_error)?;
        d.set_item("iterations", r.iterations)?;
        d.set_item("seconds", r.seconds)?;
        d.set_item("dictionary_atoms", r.dictionary_atoms)?;
        d.set_item("oversample", r.oversample)?;
        d.set_item("kernel_sum", r.kernel_sum)?;
        d.set_item("dc_gain", r.dc_gain)?;
        d.set_item("full_plane_dc_error", r.full_plane_dc_error())?;
        d.set_item("fine_rel_l2_error", r.fine_rel_l2_error)?;
        d.set_item("kernel_size", self.inner.kernel_size)?;
        d.set_item("spec", self.inner.spec.clone())?;
        Ok(Some(d))
    }

    /// How far, in pixels, an output pixel reads from its position at a
    /// scale up to `scale`: the farthest term centre plus 5 of the widest
    /// term's sigma (its tail beyond is below 4e-6 of its peak). Tiles and
    /// chunks need this much halo.
    #[pyo3(signature = (scale=1.0))]
    fn halo(&self, scale: f64) -> PyResult<usize> {
        if !(scale.is_finite() && scale > 0.0) {
            return Err(errors::value(
                "scale",
                format!("{scale} must be finite and positive"),
            ));
        }
        ifd_planar::tile_halo(&self.inner, scale as f32).map_err(|e| errors::value("", e))
    }

    fn __len__(&self) -> usize {
        self.inner.terms.len()
    }

    fn __repr__(&self) -> String {
        let mut s = format!("<ifd.Decomposition: {} terms", self.inner.terms.len());
        if let Some(spec) = &self.inner.spec {
            let _ = write!(s, ", {spec}");
        }
        if let Some(r) = &self.inner.report {
            let _ = write!(s, ", rel. L2 error {:.3}%", 100.0 * r.rel_l2_error);
        }
        s + ">"
    }

    fn __eq__(&self, other: &Self) -> bool {
        self.inner == other.inner
    }

    /// Pickling (Dask, multiprocessing): the file's JSON text.
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyAny>, (String,))> {
        let from_json = py.import("ifd._ifd")?.getattr("_decomposition_from_json")?;
        Ok((from_json, (self.inner.to_json_string(),)))
    }
}

/// Unpickling.
#[pyfunction]
fn _decomposition_from_json(text: &str) -> PyResult<PyDecomposition> {
    PyDecomposition::from_json(text)
}

/// The filter `ifd.decompose` and `ifd.filter` fit: a built-in spec or an
/// odd-sized float64 kernel array.
enum FilterArg {
    Spec(KernelSpec),
    Kernel(Kernel),
}

/// Exactly one of `spec` (parsed) and `kernel` (an `(H, W)` array, centre in
/// the middle); `oversample` above 1 only with a spec.
fn filter_arg(
    spec: Option<&str>,
    kernel: Option<PyReadonlyArrayDyn<'_, f64>>,
    oversample: Option<usize>,
) -> PyResult<FilterArg> {
    match (spec, kernel) {
        (Some(text), None) => text
            .parse()
            .map(FilterArg::Spec)
            .map_err(|e| errors::value(&format!("filter spec {text:?}"), e)),
        (None, Some(k)) => {
            if oversample.is_some_and(|q| q != 1) {
                return Err(errors::value(
                    "oversample",
                    "only built-in specs can be sampled between pixels",
                ));
            }
            let (shape, values) = arrays::values_f64("kernel", &k)?;
            let [h, w] = shape[..] else {
                return Err(errors::value(
                    "kernel",
                    format!("expected an (H, W) array, got shape {shape:?}"),
                ));
            };
            Kernel::new(w, h, values.to_vec())
                .map(FilterArg::Kernel)
                .map_err(|e| errors::value("kernel", e))
        }
        _ => Err(errors::value(
            "",
            "give exactly one of a filter spec and a kernel array",
        )),
    }
}

/// Fits a decomposition to a built-in spec (`spec`) or to an odd-sized
/// float64 kernel (`kernel`, `(H, W)`, centre in the middle).
#[pyfunction]
#[pyo3(signature = (spec=None, kernel=None, *, tol=0.01, max_terms=None, levels=None, alpha=None, oversample=None, min_sigma=None, margin=None))]
#[expect(
    clippy::too_many_arguments,
    reason = "the keyword arguments of ifd.decompose"
)]
fn decompose_filter(
    py: Python<'_>,
    spec: Option<&str>,
    kernel: Option<PyReadonlyArrayDyn<'_, f64>>,
    tol: f64,
    max_terms: Option<usize>,
    levels: Option<usize>,
    alpha: Option<f64>,
    oversample: Option<usize>,
    min_sigma: Option<f64>,
    margin: Option<usize>,
) -> PyResult<PyDecomposition> {
    let mut opts = DecomposeOptions {
        alpha,
        max_terms,
        tol,
        margin,
        ..DecomposeOptions::default()
    };
    if let Some(b) = levels {
        opts.dictionary.levels = Some(b);
    }
    if let Some(m) = min_sigma {
        opts.dictionary.min_sigma = m;
    }
    let inner = match filter_arg(spec, kernel, oversample)? {
        FilterArg::Spec(spec) => py
            .detach(|| decompose_spec(&spec, &opts, oversample, |_, _, _| {}))
            .map_err(|e| errors::value(&format!("decomposing {spec}"), e))?,
        FilterArg::Kernel(kernel) => py
            .detach(|| decompose(&kernel, &opts, |_, _, _| {}))
            .map_err(|e| errors::value("decomposition failed", e))?,
    };
    Ok(PyDecomposition { inner })
}

/// A built-in spec (`spec`) or an odd-sized float64 kernel (`kernel`)
/// fitted at `tol` through the fit cache shared with `ifd filter --kernel`
/// (read back when the same filter was fitted with the same options before).
#[pyfunction]
#[pyo3(signature = (spec=None, kernel=None, *, tol=0.01))]
fn fit_cached(
    py: Python<'_>,
    spec: Option<&str>,
    kernel: Option<PyReadonlyArrayDyn<'_, f64>>,
    tol: f64,
) -> PyResult<PyDecomposition> {
    let opts = DecomposeOptions {
        tol,
        ..DecomposeOptions::default()
    };
    let cache = ifd_planar::FitCache::shared();
    let inner = match filter_arg(spec, kernel, None)? {
        FilterArg::Spec(spec) => {
            py.detach(|| cache.fit_spec(&spec, &opts, None, |_, _, _| {}))
                .map_err(|e| errors::value(&format!("decomposing {spec}"), e))?
                .0
        }
        FilterArg::Kernel(kernel) => {
            py.detach(|| cache.fit_kernel(&kernel, &opts, |_, _, _| {}))
                .map_err(|e| errors::value("decomposition failed", e))?
                .0
        }
    };
    Ok(PyDecomposition { inner })
}

/// A field argument: a constant, else an `(H, W)` float32 map.
fn checked_field<'a>(
    what: &str,
    kind: FieldKind,
    constant: f32,
    map: Option<&'a PyReadonlyArray2<'_, f32>>,
    (w, h): (usize, usize),
) -> PyResult<CheckedField<'a>> {
    let field = match map {
        Some(a) => {
            let (fh, fw) = arrays::field_shape(a);
            if (fw, fh) != (w, h) {
                return Err(errors::value(
                    what,
                    format!("the map is ({fh}, {fw}) but the image is ({h}, {w})"),
                ));
            }
            Field::Map(arrays::field(what, a)?)
        }
        None => Field::Constant(constant),
    };
    CheckedField::new(field, kind, w, h).map_err(|e| errors::value(what, e))
}

fn parse_interp(text: &str) -> PyResult<Option<Interpolation>> {
    match text {
        "auto" => Ok(None),
        "linear" => Ok(Some(Interpolation::Linear)),
        "cubic" => Ok(Some(Interpolation::Cubic)),
        other => Err(errors::value(
            "interp",
            format!("{other:?}: expected 'auto', 'linear' or 'cubic'"),
        )),
    }
}

fn parse_border(text: &str) -> PyResult<Border> {
    text.parse::<Border>()
        .map_err(|e| errors::value("border", e))
}

/// Filters an image with a decomposition rotated by `angle` degrees
/// (counter-clockwise on screen) and scaled by `scale`, each constant or per
/// pixel: the steps of `ifd filter` on the CPU.
#[pyfunction]
#[pyo3(signature = (image, decomposition, *, angle=0.0, angle_map=None, scale=1.0, scale_map=None, border="reflect101", interp="auto", eval_budget=None, scale_range=None))]
#[expect(
    clippy::too_many_arguments,
    reason = "the keyword arguments of ifd.filter"
)]
fn filter<'py>(
    py: Python<'py>,
    image: PyReadonlyArrayDyn<'py, f32>,
    decomposition: &PyDecomposition,
    angle: f32,
    angle_map: Option<PyReadonlyArray2<'py, f32>>,
    scale: f32,
    scale_map: Option<PyReadonlyArray2<'py, f32>>,
    border: &str,
    interp: &str,
    eval_budget: Option<f64>,
    scale_range: Option<(f32, f32)>,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let squeeze = image.ndim() == 2;
    let view = arrays::image_view("image", &image)?;
    let dims = (view.width(), view.height());
    let angle = checked_field("angle", FieldKind::Angle, angle, angle_map.as_ref(), dims)?;
    let scale = checked_field("scale", FieldKind::Scale, scale, scale_map.as_ref(), dims)?;
    let options = FilterOptions {
        border: parse_border(border)?,
        interpolation: parse_interp(interp)?,
        eval_budget,
        log_uniform: false,
        direct_terms: true,
        scale_range,
        vector_kernels: true,
    };
    let inner = &decomposition.inner;
    let out = py
        .detach(|| {
            timed(|| {
                let plan = FilterPlan::new(
                    (view.width(), view.height(), view.channels()),
                    inner,
                    &angle,
                    &scale,
                    &options,
                )?;
                let stack = plan.build_stack_for(view, &scale)?;
                plan.evaluate(view, &stack, angle, scale)
            })
        })
        .map_err(|e| errors::value("", e))?;
    Ok(arrays::image_array(py, out, squeeze))
}

/// Several decompositions on one image through one stack, each for the
/// pixels `filter_map` gives it: an `(H, W)` array of labels (each pixel's
/// filter number) or an `(H, W, N)` array of one weight per filter: the
/// steps of `ifd filter --decomp ... --filter-map` on the CPU.
#[pyfunction]
#[pyo3(signature = (image, decompositions, filter_map, *, angle=0.0, angle_map=None, scale=1.0, scale_map=None, border="reflect101", interp="auto", eval_budget=None))]
#[expect(
    clippy::too_many_arguments,
    reason = "the keyword arguments of ifd.filter with several filters"
)]
fn filter_set<'py>(
    py: Python<'py>,
    image: PyReadonlyArrayDyn<'py, f32>,
    decompositions: Vec<PyRef<'py, PyDecomposition>>,
    filter_map: PyReadonlyArrayDyn<'py, f32>,
    angle: f32,
    angle_map: Option<PyReadonlyArray2<'py, f32>>,
    scale: f32,
    scale_map: Option<PyReadonlyArray2<'py, f32>>,
    border: &str,
    interp: &str,
    eval_budget: Option<f64>,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let squeeze = image.ndim() == 2;
    let view = arrays::image_view("image", &image)?;
    let (w, h) = (view.width(), view.height());
    let n = decompositions.len();
    let map = arrays::image_view("filter_map", &filter_map)?;
    if (map.width(), map.height()) != (w, h) {
        return Err(errors::value(
            "filter_map",
            format!(
                "the map is ({}, {}) but the image is ({h}, {w})",
                map.height(),
                map.width()
            ),
        ));
    }
    // (H, W) or (H, W, 1): labels, as the command reads both
    let weights: Vec<Vec<f32>> = if map.channels() == 1 {
        FilterSetPlan::weights_from_labels(map.data(), n, w)
            .map_err(|e| errors::value("filter_map", e))?
    } else if map.channels() == n && n >= 2 {
        if let Some(i) = map.data().iter().position(|v| !v.is_finite()) {
            return Err(errors::value(
                "filter_map",
                format!(
                    "weight {} of filter {} at pixel ({}, {}) is not finite",
                    map.data()[i],
                    i % n,
                    i / n % w,
                    i / n / w
                ),
            ));
        }
        (0..n)
            .map(|k| map.data().iter().skip(k).step_by(n).copied().collect())
            .collect()
    } else {
        return Err(errors::value(
            "filter_map",
            format!(
                "expected (H, W) labels or (H, W, N) weights, one per filter (N = {n} >= 2), got \
                 shape {:?}",
                filter_map.shape()
            ),
        ));
    };
    let angle = checked_field("angle", FieldKind::Angle, angle, angle_map.as_ref(), (w, h))?;
    let scale = checked_field("scale", FieldKind::Scale, scale, scale_map.as_ref(), (w, h))?;
    let options = FilterOptions {
        border: parse_border(border)?,
        interpolation: parse_interp(interp)?,
        eval_budget,
        ..FilterOptions::default()
    };
    let refs: Vec<&Decomposition> = decompositions.iter().map(|d| &d.inner).collect();
    let out = py
        .detach(|| {
            timed(|| {
                let plan = FilterSetPlan::new((w, h, view.channels()), &refs, &scale, &options)?;
                let stack = plan.build_stack_for(view, &scale)?;
                plan.evaluate(&stack, angle, scale, &weights)
            })
        })
        .map_err(|e| errors::value("", e))?;
    Ok(arrays::image_array(py, out, squeeze))
}

/// A normalised anisotropic Gaussian per pixel from an `(H, W, 3)` sigma
/// map (major sigma, minor sigma, angle in degrees counter-clockwise on
/// screen): `ifd filter --kernel gauss --sigma-map`, with the aspect bank
/// `ifd smooth` uses (read from and written to its cache, as the CLI does).
#[pyfunction]
#[pyo3(signature = (image, sigma_map, *, border="reflect101"))]
fn filter_sigma_map<'py>(
    py: Python<'py>,
    image: PyReadonlyArrayDyn<'py, f32>,
    sigma_map: PyReadonlyArrayDyn<'py, f32>,
    border: &str,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let squeeze = image.ndim() == 2;
    let view = arrays::image_view("image", &image)?;
    if sigma_map.ndim() != 3 {
        return Err(errors::value(
            "sigma_map",
            format!(
                "expected an (H, W, 3) array of (major sigma, minor sigma, angle), got shape {:?}",
                sigma_map.shape()
            ),
        ));
    }
    let map = arrays::image_view("sigma_map", &sigma_map)?;
    let border = parse_border(border)?;
    let options = ifd_smooth::BankOptions::default();
    // Bad maps are refused before the bank is loaded or fitted.
    ifd_smooth::sigma_map_gaussians(map, (view.width(), view.height()), options.max_aspect)
        .map_err(|e| errors::value("sigma_map", e))?;
    let out = py.detach(|| {
        timed(|| {
            let bank = cached_aspect_bank(options)?;
            ifd_smooth::filter_sigma_map(view, map, &bank, border).map_err(|e| errors::value("", e))
        })
    })?;
    Ok(arrays::image_array(py, out, squeeze))
}

/// The aspect bank of `options` as the CLI gets it: from the cache file
/// shared with `ifd smooth` and ifd-brush, else fitted and written there;
/// kept for the process.
fn cached_aspect_bank(options: ifd_smooth::BankOptions) -> PyResult<Arc<AspectBank>> {
    static BANKS: Cache<ifd_smooth::BankOptions, AspectBank> = OnceLock::new();
    let banks = BANKS.get_or_init(|| Mutex::new(Vec::new()));
    let mut banks = banks
        .lock()
        .map_err(|_| errors::value("", "a previous call panicked"))?;
    if let Some((_, b)) = banks.iter().find(|(o, _)| *o == options) {
        return Ok(Arc::clone(b));
    }
    let cache = AspectBank::default_cache();
    let (bank, _) = AspectBank::load_or_build(options, cache.as_deref(), |_, _| {})
        .map_err(|e| errors::value("", e))?;
    let bank = Arc::new(bank);
    banks.push((options, Arc::clone(&bank)));
    Ok(bank)
}

/// The subsampling factor chunk origins must be multiples of for chunks to
/// give the whole image's result (`FilterPlan::alignment`), for an image of
/// `shape` `(H, W, C)` filtered with a constant or per-pixel angle at scales
/// in `scale_range` (per pixel when the range is not one value).
#[pyfunction]
#[pyo3(signature = (decomposition, shape, scale_range, angle_varies, *, border="reflect101", interp="auto", eval_budget=None))]
fn filter_alignment(
    decomposition: &PyDecomposition,
    shape: (usize, usize, usize),
    scale_range: (f32, f32),
    angle_varies: bool,
    border: &str,
    interp: &str,
    eval_budget: Option<f64>,
) -> PyResult<usize> {
    let (h, w, c) = shape;
    let options = FilterOptions {
        border: parse_border(border)?,
        interpolation: parse_interp(interp)?,
        eval_budget,
        log_uniform: false,
        direct_terms: true,
        scale_range: None,
        vector_kernels: true,
    };
    FilterPlan::for_ranges(
        (w, h, c),
        &decomposition.inner,
        angle_varies,
        scale_range,
        &options,
    )
    .and_then(|p| p.alignment())
    .map_err(|e| errors::value("", e))
}

/// Fitted banks kept for the process, by their options.
type Cache<K, V> = OnceLock<Mutex<Vec<(K, Arc<V>)>>>;

/// One Hessian bank per fit tolerance, fitted once per process.
fn hessian_bank(tol: f64) -> PyResult<Arc<HessianBank>> {
    static BANKS: Cache<u64, HessianBank> = OnceLock::new();
    let banks = BANKS.get_or_init(|| Mutex::new(Vec::new()));
    let mut banks = banks
        .lock()
        .map_err(|_| errors::value("", "a previous call panicked"))?;
    if let Some((_, b)) = banks.iter().find(|(t, _)| *t == tol.to_bits()) {
        return Ok(Arc::clone(b));
    }
    let bank = Arc::new(HessianBank::new(tol).map_err(|e| errors::value("", e))?);
    banks.push((tol.to_bits(), Arc::clone(&bank)));
    Ok(bank)
}

/// The aspect-ratio bank of the default options, fitted once per process.
fn aspect_bank(options: ifd_smooth::BankOptions) -> PyResult<Arc<AspectBank>> {
    static BANKS: Cache<ifd_smooth::BankOptions, AspectBank> = OnceLock::new();
    let banks = BANKS.get_or_init(|| Mutex::new(Vec::new()));
    let mut banks = banks
        .lock()
        .map_err(|_| errors::value("", "a previous call panicked"))?;
    if let Some((_, b)) = banks.iter().find(|(o, _)| *o == options) {
        return Ok(Arc::clone(b));
    }
    let bank = Arc::new(AspectBank::build(options, |_, _| {}).map_err(|e| errors::value("", e))?);
    banks.push((options, Arc::clone(&bank)));
    Ok(bank)
}

/// The Hessian `(Hxx, Hxy, Hyy)` of the image's channel mean at scale
/// `sigma`, as `(H, W, 3)` float32: `ifd hessian`.
#[pyfunction]
#[pyo3(signature = (image, sigma, *, border="reflect101"))]
fn hessian<'py>(
    py: Python<'py>,
    image: PyReadonlyArrayDyn<'py, f32>,
    sigma: f64,
    border: &str,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let view = arrays::image_view("image", &image)?;
    let border = parse_border(border)?;
    let out = py.detach(|| {
        timed(|| {
            let bank = hessian_bank(0.01)?;
            ifd_smooth::hessian_image(view, sigma, &bank, border).map_err(|e| errors::value("", e))
        })
    })?;
    Ok(arrays::image_array(py, out, false))
}

/// Hessian-driven anisotropic smoothing: `ifd smooth` on the CPU.
#[pyfunction]
#[pyo3(signature = (image, sigma, *, max_aspect=8.0, gamma=1.0, epsilon=0.02, hessian_sigma=None, strength=1.0, mode="per-pixel", border="reflect101"))]
#[expect(
    clippy::too_many_arguments,
    reason = "the keyword arguments of ifd.smooth"
)]
fn smooth<'py>(
    py: Python<'py>,
    image: PyReadonlyArrayDyn<'py, f32>,
    sigma: f64,
    max_aspect: f64,
    gamma: f64,
    epsilon: f64,
    hessian_sigma: Option<f64>,
    strength: f32,
    mode: &str,
    border: &str,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let squeeze = image.ndim() == 2;
    let view = arrays::image_view("image", &image)?;
    if !(0.0..=1.0).contains(&strength) {
        return Err(errors::value(
            "strength",
            format!("{strength} is outside [0, 1]"),
        ));
    }
    let mode = match mode {
        "per-pixel" => Mode::PerPixel,
        "dab" => Mode::Dab,
        other => {
            return Err(errors::value(
                "mode",
                format!("{other:?}: expected 'per-pixel' or 'dab'"),
            ));
        }
    };
    let opts = SmoothOptions {
        scale: sigma,
        hessian_sigma,
        aniso: AnisoParams {
            max_aspect,
            gamma,
            epsilon,
        },
        border: parse_border(border)?,
        ..SmoothOptions::default()
    };
    opts.validate().map_err(|e| match e {
        // the options' `scale` is this function's `sigma`
        ifd_smooth::SmoothError::OutOfRange {
            name: "scale",
            value,
            range,
        } => errors::value(
            "sigma",
            format!("{value} is outside the supported range {range}"),
        ),
        e => errors::value("", e),
    })?;
    let out = py.detach(|| {
        timed(|| {
            let hbank = hessian_bank(opts.hessian_tol)?;
            let bank = aspect_bank(opts.bank)?;
            let smoother = Smoother::with_banks(view, &opts, bank, &hbank)
                .map_err(|e| errors::value("", e))?;
            let mut out = smoother
                .smooth_image(mode)
                .map_err(|e| errors::value("", e))?;
            if strength < 1.0 {
                for (o, &i) in out.data_mut().iter_mut().zip(view.data()) {
                    *o = i + strength * (*o - i);
                }
            }
            Ok::<_, PyErr>(out)
        })
    })?;
    Ok(arrays::image_array(py, out, squeeze))
}

fn metrics_dict<'py>(py: Python<'py>, m: &ifd_image::Metrics) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("psnr", m.psnr.is_finite().then_some(m.psnr))?;
    d.set_item("ssim", m.ssim)?;
    d.set_item("max_abs", m.max_abs)?;
    d.set_item("mean_abs", m.mean_abs)?;
    d.set_item("mse", m.mse)?;
    d.set_item("identical", m.mse == 0.0)?;
    Ok(d)
}

/// PSNR, SSIM and error statistics of `b` against the reference `a`: the
/// numbers of `ifd compare --json`.
#[pyfunction]
#[pyo3(signature = (a, b, *, data_range=None, crop_border=0))]
fn compare<'py>(
    py: Python<'py>,
    a: PyReadonlyArrayDyn<'py, f32>,
    b: PyReadonlyArrayDyn<'py, f32>,
    data_range: Option<f64>,
    crop_border: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let va = arrays::image_view("a", &a)?;
    let vb = arrays::image_view("b", &b)?;
    if (va.width(), va.height(), va.channels()) != (vb.width(), vb.height(), vb.channels()) {
        return Err(errors::value(
            "",
            format!(
                "a is {:?} but b is {:?}: the images must have the same shape",
                a.shape(),
                b.shape()
            ),
        ));
    }
    let cmp = py
        .detach(|| {
            let ia = ifd_image::crop_border(&va.to_image(), crop_border)?;
            let ib = ifd_image::crop_border(&vb.to_image(), crop_border)?;
            let range =
                data_range.unwrap_or_else(|| ifd_image::default_data_range(ia.data(), ib.data()));
            ifd_image::compare(&ia, &ib, range)
        })
        .map_err(|e| errors::value("", e))?;
    let d = metrics_dict(py, &cmp.overall)?;
    d.set_item("data_range", cmp.data_range)?;
    let channels = cmp
        .channels
        .iter()
        .map(|m| metrics_dict(py, m))
        .collect::<PyResult<Vec<_>>>()?;
    d.set_item("channels", channels)?;
    Ok(d)
}

/// Adds the planar functions and classes to the module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyDecomposition>()?;
    m.add_function(wrap_pyfunction!(_decomposition_from_json, m)?)?;
    m.add_function(wrap_pyfunction!(decompose_filter, m)?)?;
    m.add_function(wrap_pyfunction!(fit_cached, m)?)?;
    m.add_function(wrap_pyfunction!(filter, m)?)?;
    m.add_function(wrap_pyfunction!(filter_sigma_map, m)?)?;
    m.add_function(wrap_pyfunction!(filter_set, m)?)?;
    m.add_function(wrap_pyfunction!(filter_alignment, m)?)?;
    m.add_function(wrap_pyfunction!(hessian, m)?)?;
    m.add_function(wrap_pyfunction!(smooth, m)?)?;
    m.add_function(wrap_pyfunction!(compare, m)?)?;
    Ok(())
}
