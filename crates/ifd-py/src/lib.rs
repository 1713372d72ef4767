//! `ifd._ifd`, the compiled half of the Python module `ifd`.
//!
//! The Python package (`python/ifd/`) is the public API: it converts what
//! users pass (dtypes, scalars or per-pixel arrays, paths) and documents it;
//! this module takes strict types only: C-contiguous `float32` images
//! (`(H, W)` or `(H, W, C)`, borrowed, never copied), `float32` fields and
//! `float64` SH coefficients. Every call releases the GIL while it works.
//!
//! Errors: bad values, shapes and parameters raise `ValueError` with the
//! library's message (the CLI's); files that cannot be read or written raise
//! `OSError`. Nothing panics across the boundary (a panic would become
//! `pyo3_runtime.PanicException`, a bug).

// PyO3 extracts every argument by value (arrays, paths, strings).
#![allow(clippy::needless_pass_by_value)]

mod arrays;
mod errors;
mod planar;
mod shade;
mod sphere;

use std::sync::atomic::{AtomicU64, Ordering};

use pyo3::prelude::*;

/// Seconds spent in Rust by the last call of a timed function (`filter`,
/// `hessian`, `smooth`), GIL released, conversions excluded: the benchmark
/// of call overhead subtracts it from Python's wall time.
static LAST_CALL_SECONDS: AtomicU64 = AtomicU64::new(0);

/// Runs `f`, recording its duration as the last call's Rust time.
pub(crate) fn timed<T>(f: impl FnOnce() -> T) -> T {
    let t = std::time::Instant::now();
    let out = f();
    LAST_CALL_SECONDS.store(t.elapsed().as_secs_f64().to_bits(), Ordering::Relaxed);
    out
}

/// Seconds the last `filter`, `hessian` or `smooth` call spent in Rust.
#[pyfunction]
fn last_call_seconds() -> f64 {
    f64::from_bits(LAST_CALL_SECONDS.load(Ordering::Relaxed))
}

/// The compiled module.
#[pymodule]
fn _ifd(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    // Which Cargo profile built the module (benchmarks compare like with like).
    m.add(
        "__build_profile__",
        if cfg!(debug_assertions) {
            "dev"
        } else {
            "release"
        },
    )?;
    m.add_function(wrap_pyfunction!(last_call_seconds, m)?)?;
    planar::register(m)?;
    sphere::register(m)?;
    shade::register(m)?;
    Ok(())
}
