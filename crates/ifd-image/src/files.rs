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
                source: e,
            }
        }
    })
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
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !dir.is_dir() {
        return Err(werr(format!("folder {} does not exist", dir.display())));
    }
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
