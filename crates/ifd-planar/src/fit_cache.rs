//! Fits kept between runs: a decomposition is fitted on first use and read
//! back the next time the same filter is asked for with the same options, so
//! that `ifd filter IMAGE --kernel SPEC` (and `ifd.filter(image, "SPEC")`)
//! costs a fit once per filter, not once per image.
//!
//! # What an entry is keyed by
//! The filter (a built-in spec in its canonical spelling, or a kernel's
//! samples and size), every fitting option ([`DecomposeOptions`], the
//! oversampling) and [`FIT_REVISION`]: an entry written by older fitting code,
//! or for other options, is never read. The file name is a 64-bit hash of the
//! key; the entry holds the key itself, compared in full when read.
//!
//! # Checked when read
//! An entry is used only when it parses as a decomposition file, its key is
//! the one asked for, and its terms reproduce the fit error its report
//! records, measured again against the kernel (a few milliseconds): a
//! damaged or altered entry is reported on stderr and refitted.
//!
//! # Concurrent use
//! Entries are written atomically (a temporary file renamed into place): two
//! processes fitting the same filter at once both succeed, and the entry
//! left is one of their two identical fits. A cache folder that cannot be
//! written is a note on stderr, not an error: the fit is still returned.
//!
//! ```
//! use ifd_planar::{DecomposeOptions, FitCache, FitSource, KernelSpec};
//! let dir = std::env::temp_dir().join(format!("ifd-fit-cache-doc-{}", std::process::id()));
//! let cache = FitCache::new(&dir);
//! let spec: KernelSpec = "gauss:sx=3,sy=1.5".parse()?;
//! let opts = DecomposeOptions { tol: 0.05, ..DecomposeOptions::default() };
//! let (first, how) = cache.fit_spec(&spec, &opts, None, |_, _, _| {})?;
//! assert!(matches!(how, FitSource::Fitted(Some(_))));
//! let (again, how) = cache.fit_spec(&spec, &opts, None, |_, _, _| {})?;
//! assert!(matches!(how, FitSource::Cached(_)));
//! assert_eq!(first.terms, again.terms);
//! # std::fs::remove_dir_all(&dir).ok();
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::path::{Path, PathBuf};

use crate::fit::{DecomposeError, DecomposeOptions, FIT_REVISION, decompose, decompose_spec};
use crate::{Decomposition, Kernel, KernelSpec, measure};

/// The format name of a cache entry.
const FORMAT: &str = "ifd-fit-cache";
/// The entry layout's version.
const VERSION: u64 = 1;

/// The folder ifd keeps its caches in: `$IFD_CACHE_DIR` when set, else
/// `$XDG_CACHE_HOME/ifd`, else `~/.cache/ifd`; `None` without any of them.
#[must_use]
pub fn cache_root() -> Option<PathBuf> {
    let var = |name: &str| std::env::var_os(name).filter(|v| !v.is_empty());
    var("IFD_CACHE_DIR").map(PathBuf::from).or_else(|| {
        var("XDG_CACHE_HOME")
            .map(PathBuf::from)
            .or_else(|| var("HOME").map(|h| PathBuf::from(h).join(".cache")))
            .map(|base| base.join("ifd"))
    })
}

/// Where a decomposition came from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FitSource {
    /// Read from this cache entry.
    Cached(PathBuf),
    /// Fitted now, and kept in this entry (`None`: not kept, the cache being
    /// off or its folder unwritable).
    Fitted(Option<PathBuf>),
}

/// A folder of fitted decompositions (see the module documentation).
#[derive(Clone, Debug)]
pub struct FitCache {
    dir: Option<PathBuf>,
}

impl FitCache {
    /// The cache in `dir` (created when first written).
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Self {
            dir: Some(dir.into()),
        }
    }

    /// The cache shared by ifd's tools: `decompositions/` in [`cache_root`],
    /// or none (every call fits) where there is no such folder.
    #[must_use]
    pub fn shared() -> Self {
        Self {
            dir: cache_root().map(|r| r.join("decompositions")),
        }
    }

    /// No cache: every call fits, nothing is written.
    #[must_use]
    pub fn off() -> Self {
        Self { dir: None }
    }

    /// The folder, if any.
    #[must_use]
    pub fn dir(&self) -> Option<&Path> {
        self.dir.as_deref()
    }

    /// [`decompose_spec`] through the cache.
    ///
    /// # Errors
    /// As [`decompose_spec`]; a cache that cannot be read or written is not
    /// an error.
    pub fn fit_spec(
        &self,
        spec: &KernelSpec,
        opts: &DecomposeOptions,
        oversample: Option<usize>,
        progress: impl FnMut(usize, f64, usize),
    ) -> Result<(Decomposition, FitSource), DecomposeError> {
        opts.validate()?;
        let kernel = spec.to_kernel()?;
        let key = entry_key(&format!("spec:{spec}"), opts, oversample);
        self.fit_with(&key, &kernel, || {
            decompose_spec(spec, opts, oversample, progress)
        })
    }

    /// [`decompose`] of a kernel given by its samples, through the cache.
    ///
    /// # Errors
    /// As [`decompose`].
    pub fn fit_kernel(
        &self,
        kernel: &Kernel,
        opts: &DecomposeOptions,
        progress: impl FnMut(usize, f64, usize),
    ) -> Result<(Decomposition, FitSource), DecomposeError> {
        opts.validate()?;
        let mut h = Fnv::default();
        for v in kernel.data() {
            h.write(&v.to_bits().to_le_bytes());
        }
        let source = format!("kernel:{}x{}:{:016x}", kernel.width(), kernel.height(), h.0);
        let key = entry_key(&source, opts, None);
        self.fit_with(&key, kernel, || decompose(kernel, opts, progress))
    }

    fn fit_with(
        &self,
        key: &str,
        kernel: &Kernel,
        fit: impl FnOnce() -> Result<Decomposition, DecomposeError>,
    ) -> Result<(Decomposition, FitSource), DecomposeError> {
        let Some(dir) = &self.dir else {
            return Ok((fit()?, FitSource::Fitted(None)));
        };
        let mut h = Fnv::default();
        h.write(key.as_bytes());
        let path = dir.join(format!("{:016x}.json", h.0));
        if path.exists() {
            match read_entry(&path, key, kernel) {
                Ok(Some(d)) => return Ok((d, FitSource::Cached(path))),
                // another filter hashed to the same name: refitted, replaced
                Ok(None) => {}
                Err(why) => eprintln!(
                    "note: ignoring the cached fit {}: {why}; refitting",
                    path.display()
                ),
            }
        }
        let d = fit()?;
        match write_entry(&path, key, &d) {
            Ok(()) => Ok((d, FitSource::Fitted(Some(path)))),
            Err(why) => {
                eprintln!("note: cannot keep the fit in {}: {why}", dir.display());
                Ok((d, FitSource::Fitted(None)))
            }
        }
    }
}

/// The key of an entry: the filter, every option and the fitting code's
/// revision, as one JSON text.
fn entry_key(source: &str, opts: &DecomposeOptions, oversample: Option<usize>) -> String {
    serde_json::json!({
        "fit_revision": FIT_REVISION,
        "filter": source,
        "options": opts,
        "oversample": oversample,
    })
    .to_string()
}

/// The entry at `path` if it holds `key` and checks out against `kernel`;
/// `Ok(None)` for another key; `Err` naming what is wrong with it.
fn read_entry(path: &Path, key: &str, kernel: &Kernel) -> Result<Option<Decomposition>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| e.to_string())?;
    let value: serde_json::Value = serde_json::from_str(&text).map_err(|e| e.to_string())?;
    if value.get("format").and_then(serde_json::Value::as_str) != Some(FORMAT)
        || value.get("version").and_then(serde_json::Value::as_u64) != Some(VERSION)
    {
        return Err("not a fit-cache entry of this version".into());
    }
    if value.get("key").and_then(serde_json::Value::as_str) != Some(key) {
        return Ok(None);
    }
    let d = value
        .get("decomposition")
        .ok_or("no decomposition")
        .map_err(str::to_string)
        .and_then(|v| Decomposition::from_json_str(&v.to_string()).map_err(|e| e.to_string()))?;
    let report = d.report.as_ref().ok_or("no fit report")?;
    if report.terms != d.terms.len() {
        return Err(format!(
            "{} terms where its report says {}",
            d.terms.len(),
            report.terms
        ));
    }
    let (err, _, _) = measure(&kernel.padded(report.margin), &d);
    let recorded = report.rel_l2_error;
    let agrees = (err - recorded).abs() <= 1e-9 + 1e-6 * recorded;
    if !agrees {
        return Err(format!(
            "its terms fit the kernel to {:.4}%, its report says {:.4}%",
            100.0 * err,
            100.0 * recorded
        ));
    }
    Ok(Some(d))
}

/// Writes the entry atomically, creating the folder.
fn write_entry(path: &Path, key: &str, d: &Decomposition) -> Result<(), String> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| e.to_string())?;
    }
    let decomposition: serde_json::Value =
        serde_json::from_str(&d.to_json_string()).map_err(|e| e.to_string())?;
    let text = serde_json::to_string_pretty(&serde_json::json!({
        "format": FORMAT,
        "version": VERSION,
        "key": key,
        "decomposition": decomposition,
    }))
    .map_err(|e| e.to_string())?;
    ifd_image::atomic_write(path, |w| {
        std::io::Write::write_all(w, text.as_bytes()).map_err(|e| e.to_string())
    })
    .map_err(|e| e.to_string())
}

/// FNV-1a, 64 bits: a stable hash for file names (the entry's key is
/// compared in full, so collisions only cost a refit).
struct Fnv(u64);

impl Default for Fnv {
    fn default() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv {
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!(
            "ifd-fit-cache-{name}-{}-{:?}",
            std::process::id(),
            std::thread::current().id()
        ));
        std::fs::remove_dir_all(&dir).ok();
        dir
    }

    fn opts() -> DecomposeOptions {
        DecomposeOptions {
            tol: 0.05,
            ..DecomposeOptions::default()
        }
    }

    /// A fit is kept and read back; other options, another filter and a
    /// kernel given by samples each get their own entry.
    #[test]
    fn fits_are_kept_per_filter_and_options() {
        let dir = temp("keys");
        let cache = FitCache::new(&dir);
        let spec: KernelSpec = "gauss:sx=3,sy=1.5".parse().expect("spec");
        let (a, how) = cache
            .fit_spec(&spec, &opts(), None, |_, _, _| {})
            .expect("fit");
        let FitSource::Fitted(Some(path)) = how else {
            panic!("{how:?}")
        };
        let (b, how) = cache
            .fit_spec(&spec, &opts(), None, |_, _, _| {})
            .expect("fit");
        assert_eq!(how, FitSource::Cached(path.clone()));
        assert_eq!(a.terms, b.terms);
        let tighter = DecomposeOptions {
            tol: 0.02,
            ..opts()
        };
        let (_, how) = cache
            .fit_spec(&spec, &tighter, None, |_, _, _| {})
            .expect("fit");
        assert!(
            matches!(how, FitSource::Fitted(Some(ref p)) if *p != path),
            "{how:?}"
        );
        let kernel = spec.to_kernel().expect("kernel");
        let (_, how) = cache
            .fit_kernel(&kernel, &opts(), |_, _, _| {})
            .expect("fit");
        assert!(matches!(how, FitSource::Fitted(Some(_))), "{how:?}");
        let (_, how) = cache
            .fit_kernel(&kernel, &opts(), |_, _, _| {})
            .expect("fit");
        assert!(matches!(how, FitSource::Cached(_)), "{how:?}");
        assert_eq!(std::fs::read_dir(&dir).expect("dir").count(), 3);
        std::fs::remove_dir_all(&dir).ok();
    }

    /// An entry whose weights were altered, or that is truncated, is not
    /// used: the filter is refitted and the entry replaced.
    #[test]
    fn damaged_entries_are_refitted() {
        let dir = temp("damaged");
        let cache = FitCache::new(&dir);
        let spec: KernelSpec = "gauss:sx=3,sy=1.5".parse().expect("spec");
        let (good, how) = cache
            .fit_spec(&spec, &opts(), None, |_, _, _| {})
            .expect("fit");
        let FitSource::Fitted(Some(path)) = how else {
            panic!("{how:?}")
        };
        let text = std::fs::read_to_string(&path).expect("entry");
        let mut v: serde_json::Value = serde_json::from_str(&text).expect("json");
        let w = &mut v["decomposition"]["terms"][0]["weight"];
        *w = serde_json::json!(w.as_f64().expect("weight") * 10.0);
        std::fs::write(&path, v.to_string()).expect("write");
        let kernel = spec.to_kernel().expect("kernel");
        assert!(
            read_entry(
                &path,
                &entry_key(&format!("spec:{spec}"), &opts(), None),
                &kernel
            )
            .expect_err("altered")
            .contains("fit the kernel")
        );
        let (again, how) = cache
            .fit_spec(&spec, &opts(), None, |_, _, _| {})
            .expect("fit");
        assert_eq!(how, FitSource::Fitted(Some(path.clone())));
        assert_eq!(again.terms, good.terms);
        std::fs::write(&path, &text[..text.len() / 2]).expect("truncate");
        let (_, how) = cache
            .fit_spec(&spec, &opts(), None, |_, _, _| {})
            .expect("fit");
        assert_eq!(how, FitSource::Fitted(Some(path.clone())));
        let (_, how) = cache
            .fit_spec(&spec, &opts(), None, |_, _, _| {})
            .expect("fit");
        assert_eq!(how, FitSource::Cached(path));
        std::fs::remove_dir_all(&dir).ok();
    }

    /// Processes fitting one filter at once (threads here, with their own
    /// cache handles) all succeed, and leave one good entry.
    #[test]
    fn concurrent_fits_leave_one_good_entry() {
        let dir = temp("concurrent");
        let spec: KernelSpec = "gauss:sx=2.5,sy=1".parse().expect("spec");
        let fits: Vec<Decomposition> = std::thread::scope(|s| {
            let handles: Vec<_> = (0..4)
                .map(|_| {
                    let (dir, spec) = (&dir, &spec);
                    s.spawn(move || {
                        FitCache::new(dir)
                            .fit_spec(spec, &opts(), None, |_, _, _| {})
                            .expect("fit")
                            .0
                    })
                })
                .collect();
            handles
                .into_iter()
                .map(|h| h.join().expect("thread"))
                .collect()
        });
        assert!(fits.windows(2).all(|p| p[0].terms == p[1].terms));
        let entries: Vec<_> = std::fs::read_dir(&dir)
            .expect("dir")
            .map(|e| e.expect("entry").path())
            .collect();
        assert_eq!(entries.len(), 1, "{entries:?}");
        let (_, how) = FitCache::new(&dir)
            .fit_spec(&spec, &opts(), None, |_, _, _| {})
            .expect("fit");
        assert_eq!(how, FitSource::Cached(entries[0].clone()));
        std::fs::remove_dir_all(&dir).ok();
    }

    /// Without a folder every call fits and nothing is written.
    #[test]
    fn off_fits_every_time() {
        let spec: KernelSpec = "gauss:sx=2,sy=2".parse().expect("spec");
        let (_, how) = FitCache::off()
            .fit_spec(&spec, &opts(), None, |_, _, _| {})
            .expect("fit");
        assert_eq!(how, FitSource::Fitted(None));
    }
}
