//! Opening files with the crate's errors, and writing them atomically:
//! shared by the image formats ([`crate::io`]) and `.npy` arrays.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::ImageError;

/// Opens `path` for reading: [`ImageError::NotFound`] for a missing file,
/// [`ImageError::Io`] otherwise.
pub(crate) fn open(path: &Path) -> Result<File, ImageError> {
    File::open(path).map_err(|e| {
        if e.kind() == std::io::ErrorKind::NotFound {
            ImageError::NotFound {
                path: path.to_path_buf(),
            }
        } else {
            ImageError::Io {
                path: path.to_path_buf(),
                error: e,
            }
        }
    })
}

/// Temporary files of outputs being written ([`atomic_write`],
/// [`crate::NpyWriter`]), for [`remove_pending_outputs`].
static PENDING: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

/// Registers a temporary output file while it lives (removed from the
/// registry on drop; the file itself is removed by its `NamedTempFile`).
#[derive(Debug)]
pub(crate) struct Pending(PathBuf);

impl Pending {
    pub(crate) fn new(path: &Path) -> Self {
        if let Ok(mut v) = PENDING.lock() {
            v.push(path.to_path_buf());
        }
        Self(path.to_path_buf())
    }
}

impl Drop for Pending {
    fn drop(&mut self) {
        if let Ok(mut v) = PENDING.lock()
            && let Some(i) = v.iter().position(|p| *p == self.0)
        {
            v.swap_remove(i);
        }
    }
}

/// Removes the temporary files of every output still being written and
/// returns how many: what a signal handler calls before the process exits,
/// so that an interrupted run leaves neither its output (never renamed into
/// place) nor the hidden `.ifd-tmp-*` file behind. `SIGKILL` cannot be
/// caught; after one, such a file can be deleted by hand.
///
/// ```
/// let dir = tempfile::tempdir()?;
/// let out = dir.path().join("big.npy");
/// let w = ifd_image::NpyWriter::create(&out, 4, 4, 1)?;
/// assert_eq!(std::fs::read_dir(dir.path())?.count(), 1); // the hidden temporary
/// assert_eq!(ifd_image::remove_pending_outputs(), 1);
/// assert_eq!(std::fs::read_dir(dir.path())?.count(), 0);
/// drop(w);
/// assert!(!out.exists());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn remove_pending_outputs() -> usize {
    let Ok(v) = PENDING.lock() else {
        return 0;
    };
    v.iter().filter(|p| std::fs::remove_file(p).is_ok()).count()
}

/// Writes a file atomically: `fill` writes into a temporary file in the
/// destination's folder, which is flushed, synced and renamed over `path`.
/// On any failure the temporary file is removed and `path` is untouched.
///
/// # Errors
/// [`ImageError::Write`] naming `path` and the reason.
pub fn atomic_write<F>(path: &Path, fill: F) -> Result<(), ImageError>
where
    F: FnOnce(&mut BufWriter<&File>) -> Result<(), String>,
{
    let werr = |reason: String| ImageError::Write {
        path: path.to_path_buf(),
        reason,
    };
    if let Some(problem) = output_folder_problem(path) {
        return Err(werr(problem));
    }
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    // The file gets the permissions an ordinary `File::create` would give
    // (0666 less the umask; a temporary file alone would be 0600), or those
    // of the file it replaces.
    let existing = std::fs::metadata(path).ok().map(|m| m.permissions());
    let mut builder = tempfile::Builder::new();
    builder.prefix(".ifd-tmp-");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt as _;
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    let tmp = builder.tempfile_in(&dir).map_err(|e| {
        werr(format!(
            "cannot create a temporary file in {}: {e}",
            dir.display()
        ))
    })?;
    let _pending = Pending::new(tmp.path());
    {
        let mut w = BufWriter::new(tmp.as_file());
        fill(&mut w).map_err(werr)?;
        w.flush().map_err(|e| werr(e.to_string()))?;
    }
    tmp.as_file().sync_all().map_err(|e| werr(e.to_string()))?;
    if let Some(p) = existing {
        tmp.as_file()
            .set_permissions(p)
            .map_err(|e| werr(format!("keeping the permissions of the old file: {e}")))?;
    }
    tmp.persist(path).map_err(|e| werr(e.error.to_string()))?;
    Ok(())
}

/// Why a file cannot be created at `path` because of its folder, or `None`
/// when the folder exists: "folder X does not exist", or "X is not a
/// folder" when some part of the parent path is a regular file. Commands call
/// it before long work so that an unwritable output is refused up front.
///
/// ```
/// let dir = tempfile::tempdir().unwrap();
/// let file = dir.path().join("afile");
/// std::fs::write(&file, b"x").unwrap();
/// assert!(ifd_image::output_folder_problem(&dir.path().join("out.png")).is_none());
/// let why = ifd_image::output_folder_problem(&file.join("out.png")).unwrap();
/// assert!(why.ends_with("afile is not a folder"), "{why}");
/// let why = ifd_image::output_folder_problem(&dir.path().join("no/out.png")).unwrap();
/// assert!(why.ends_with("does not exist"), "{why}");
/// ```
#[must_use]
pub fn output_folder_problem(path: &Path) -> Option<String> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if dir.is_dir() {
        return None;
    }
    // The nearest ancestor that exists tells a missing folder from a file.
    let mut up = Some(dir);
    while let Some(d) = up {
        if d.as_os_str().is_empty() {
            break;
        }
        if let Ok(m) = std::fs::metadata(d) {
            if !m.is_dir() {
                return Some(format!("{} is not a folder", d.display()));
            }
            break;
        }
        up = d.parent();
    }
    Some(format!("folder {} does not exist", dir.display()))
}
