//! Shading with ISD (Eq. 22): the radiance leaving surface points lit by an
//! environment, for any BRDF of `ifd-shade`.

use ifd_shade::Brdf;
use ifd_shade::LobeTable;
use ifd_shade::{Environment, Frame, Material};
use numpy::{PyArrayDyn, PyReadonlyArrayDyn};
use pyo3::prelude::*;
use rayon::prelude::*;

use crate::{arrays, errors, sphere};

/// `(N, 3)` unit vectors, checked.
fn directions(what: &str, a: &PyReadonlyArrayDyn<'_, f64>) -> PyResult<Vec<[f64; 3]>> {
    let (shape, values) = arrays::values_f64(what, a)?;
    if shape.len() != 2 || shape[1] != 3 {
        return Err(errors::value(
            what,
            format!("expected an (N, 3) array, got shape {shape:?}"),
        ));
    }
    values
        .chunks_exact(3)
        .enumerate()
        .map(|(i, v)| {
            let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            if !(n.is_finite() && (n - 1.0).abs() <= 1e-6) {
                return Err(errors::value(
                    what,
                    format!(
                        "row {i} ({}, {}, {}) is not a unit vector (length {n})",
                        v[0], v[1], v[2]
                    ),
                ));
            }
            Ok([v[0], v[1], v[2]])
        })
        .collect()
}

/// Radiance towards `views` from points with `normals` (both `(N, 3)`
/// world-space unit vectors; `views` point from the surface to the viewer),
/// lit by the environment of SH coefficients `coeffs` (`((L+1)^2, C)`), with
/// the BRDF `brdf` (an `ifd sphere brdf` spec) by ISD (Eq. 22) at degree
/// `lmax` (default the coefficients'). BRDFs without closed-form lobe weights
/// (all but Lambert and Phong) need a lobe table from `ifd sphere brdf`
/// (`table`, a path). `tangents` (`(N, 3)`) orient anisotropic BRDFs (default
/// world +x made orthogonal to the normal). Returns `(N, C)` float64.
#[pyfunction]
#[pyo3(signature = (coeffs, brdf, normals, views, *, lmax=None, table=None, tangents=None))]
#[expect(
    clippy::too_many_arguments,
    reason = "the keyword arguments of ifd.sphere.shade"
)]
fn sphere_shade<'py>(
    py: Python<'py>,
    coeffs: PyReadonlyArrayDyn<'py, f64>,
    brdf: &str,
    normals: PyReadonlyArrayDyn<'py, f64>,
    views: PyReadonlyArrayDyn<'py, f64>,
    lmax: Option<usize>,
    table: Option<std::path::PathBuf>,
    tangents: Option<PyReadonlyArrayDyn<'py, f64>>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let (c, _) = sphere::coeffs_from("coeffs", &coeffs)?;
    let l = lmax.unwrap_or(c.l_max());
    let c = c.resized(l).map_err(|e| errors::value("lmax", e))?;
    let channels = c.channels();
    let normals = directions("normals", &normals)?;
    let views = directions("views", &views)?;
    if views.len() != normals.len() {
        return Err(errors::value(
            "views",
            format!("{} views for {} normals", views.len(), normals.len()),
        ));
    }
    let tangents = match &tangents {
        Some(t) => {
            let t = directions("tangents", t)?;
            if t.len() != normals.len() {
                return Err(errors::value(
                    "tangents",
                    format!("{} tangents for {} normals", t.len(), normals.len()),
                ));
            }
            t
        }
        None => vec![[1.0, 0.0, 0.0]; normals.len()],
    };
    let brdf = Brdf::parse(brdf).map_err(|e| errors::value("brdf", e))?;
    let table = match &table {
        Some(p) => Some(LobeTable::read(p).map_err(|e| {
            if p.exists() {
                errors::value(&p.display().to_string(), e)
            } else {
                errors::os(format!("{}: {e}", p.display()))
            }
        })?),
        None => None,
    };
    let material = Material::new(&brdf, l, table).map_err(|e| errors::value("", e))?;
    let env = Environment::new(c).map_err(|e| errors::value("coeffs", e))?;
    let out = py.detach(|| {
        let rows: Result<Vec<Vec<f64>>, _> = (0..normals.len())
            .into_par_iter()
            .map_init(
                || material.scratch(channels),
                |s, i| {
                    let frame = Frame::new(normals[i], tangents[i]);
                    let mut o = vec![0.0; channels];
                    material
                        .shade_isd(&env, &frame, views[i], s, &mut o)
                        .map(|()| o)
                },
            )
            .collect();
        rows.map(|r| r.concat())
    });
    let out = out.map_err(|e| errors::value("", e))?;
    Ok(arrays::array_f64(py, &[normals.len(), channels], out))
}

/// Adds the shading function to the module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(sphere_shade, m)?)?;
    Ok(())
}
