//! The edit journal: every finished stroke, undo and redo appended to a file
//! as it happens and flushed to disk (`fsync`), so that a crash or a kill
//! while painting loses at most the stroke in progress. The next start on
//! the same image offers to recover the journal's edits.
//!
//! # File format
//! JSON lines, one file per image in the journal folder (by default
//! `$XDG_STATE_HOME/ifd-brush/journal/`, else `~/.local/state/ifd-brush/journal/`),
//! named by a hash of the image's absolute path. The first line describes the
//! image, each following line is one entry of a strokes file
//! ([`crate::strokes`]: a stroke with its brush and points, `{"undo": true}`
//! or `{"redo": true}`):
//!
//! ```text
//! {"format":"ifd-brush-journal","version":1,"image":"/photos/a.png","image_size":[640,480],"image_digest":"9c3f…"}
//! {"brush":{"radius":20.0,…},"points":[[30.0,40.0],[120.0,60.0]]}
//! {"undo":true}
//! ```
//!
//! A stroke is written whole when it ends, so a torn last line (the process
//! died inside a write) is the only partial entry a journal can hold; it is
//! ignored on reading. `image_digest` (FNV-1a over the samples) ties the
//! journal to the pixels it was recorded on: a journal whose image changed on
//! disk since is not offered. A clean exit deletes the journal.

use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use ifd_image::Image;
use serde::{Deserialize, Serialize};

use crate::strokes::{Action, StrokesFile};

/// The `format` field of the header line.
pub const FORMAT: &str = "ifd-brush-journal";
/// The file format version.
pub const VERSION: u32 = 1;

/// The first line of a journal: the image it belongs to.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Header {
    /// Always [`FORMAT`].
    pub format: String,
    /// [`VERSION`].
    pub version: u32,
    /// The image file (absolute path).
    pub image: PathBuf,
    /// `[width, height]`.
    pub image_size: [usize; 2],
    /// FNV-1a of the image's samples (f32 bits), in hex.
    pub image_digest: String,
}

impl Header {
    /// The header for `image` read from `path`.
    #[must_use]
    pub fn for_image(path: &Path, image: &Image) -> Self {
        Self {
            format: FORMAT.into(),
            version: VERSION,
            image: absolute(path),
            image_size: [image.width(), image.height()],
            image_digest: digest(image),
        }
    }
}

/// FNV-1a over the image's shape and samples, in hex.
#[must_use]
pub fn digest(image: &Image) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    };
    for n in [image.width(), image.height(), image.channels()] {
        eat(&(n as u64).to_le_bytes());
    }
    for v in image.data() {
        eat(&v.to_bits().to_le_bytes());
    }
    format!("{h:016x}")
}

fn absolute(path: &Path) -> PathBuf {
    std::fs::canonicalize(path)
        .or_else(|_| std::path::absolute(path))
        .unwrap_or_else(|_| path.to_path_buf())
}

/// The default journal folder: `$XDG_STATE_HOME/ifd-brush/journal`, else
/// `~/.local/state/ifd-brush/journal`.
#[must_use]
pub fn default_dir() -> Option<PathBuf> {
    let base = std::env::var_os("XDG_STATE_HOME")
        .map(PathBuf::from)
        .or_else(|| {
            std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".local").join("state"))
        })?;
    Some(base.join("ifd-brush").join("journal"))
}

/// The journal file of the image at `image_path` in `dir`.
#[must_use]
pub fn path_for(dir: &Path, image_path: &Path) -> PathBuf {
    let key = absolute(image_path);
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in key.as_os_str().as_encoded_bytes() {
        h ^= u64::from(*b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    dir.join(format!("{h:016x}.jsonl"))
}

/// A journal read back: its header and the complete entries.
#[derive(Clone, Debug)]
pub struct Recovered {
    /// The journal file.
    pub path: PathBuf,
    /// The image it belongs to.
    pub header: Header,
    /// The entries, as a strokes file (for [`crate::engine::Engine::replay`]).
    pub strokes: StrokesFile,
    /// Whether a torn last line was dropped.
    pub torn: bool,
}

/// Reads a journal. A last line without its newline (a write the process
/// did not finish) is dropped, as is anything after a line that does not
/// parse.
///
/// # Errors
/// An unreadable file, or a header that is not a journal's.
pub fn read(path: &Path) -> anyhow::Result<Recovered> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("reading journal {}", path.display()))?;
    let complete = text.ends_with('\n');
    let mut lines: Vec<&str> = text.split('\n').collect();
    // `split` leaves "" after a final newline, or the torn line without one.
    let last = lines.pop().unwrap_or_default();
    let mut torn = !complete && !last.is_empty();
    let Some((first, entries)) = lines.split_first() else {
        bail!("{}: empty journal", path.display());
    };
    let header: Header = serde_json::from_str(first)
        .with_context(|| format!("{}: not an ifd-brush journal", path.display()))?;
    if header.format != FORMAT || header.version != VERSION {
        bail!(
            "{}: format {:?} version {}, expected {FORMAT:?} version {VERSION}",
            path.display(),
            header.format,
            header.version
        );
    }
    let mut strokes = Vec::new();
    for line in entries {
        match serde_json::from_str::<Action>(line) {
            Ok(Action::Stroke(s)) if s.points.iter().flatten().any(|v| !v.is_finite()) => {
                torn = true;
                break;
            }
            Ok(a) => strokes.push(a),
            Err(_) => {
                torn = true;
                break;
            }
        }
    }
    Ok(Recovered {
        path: path.to_path_buf(),
        strokes: StrokesFile {
            image_size: Some(header.image_size),
            strokes,
            ..StrokesFile::default()
        },
        header,
        torn,
    })
}

/// The journal of `image` (read from `image_path`) in `dir`, when one exists
/// for exactly these pixels and holds at least one entry.
#[must_use]
pub fn recoverable(dir: &Path, image_path: &Path, image: &Image) -> Option<Recovered> {
    let path = path_for(dir, image_path);
    let r = read(&path).ok()?;
    let want = Header::for_image(image_path, image);
    (r.header == want && !r.strokes.strokes.is_empty()).then_some(r)
}

/// An open journal, appending entries.
#[derive(Debug)]
pub struct Journal {
    file: File,
    path: PathBuf,
    written: usize,
    announce: bool,
}

impl Journal {
    /// Starts a new journal for `image` (read from `image_path`) in `dir`,
    /// replacing an older one, with the header line written and synced.
    ///
    /// # Errors
    /// The folder cannot be made or the file written.
    pub fn create(dir: &Path, image_path: &Path, image: &Image) -> anyhow::Result<Self> {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("creating the journal folder {}", dir.display()))?;
        let path = path_for(dir, image_path);
        let file = OpenOptions::new()
            .create(true)
            .write(true)
            .truncate(true)
            .open(&path)
            .with_context(|| format!("creating journal {}", path.display()))?;
        let mut j = Self {
            file,
            path,
            written: 0,
            announce: false,
        };
        let header = serde_json::to_string(&Header::for_image(image_path, image))?;
        j.write_line(&header)?;
        // The new file's directory entry, durable too.
        if let Ok(d) = File::open(dir) {
            d.sync_all().ok();
        }
        Ok(j)
    }

    /// Print `journal: saved entry N (stroke|undo|redo)` on stderr after
    /// each entry is on disk (headless runs; the recovery test waits for it).
    pub fn set_announce(&mut self, yes: bool) {
        self.announce = yes;
    }

    /// The journal file.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Entries written.
    #[must_use]
    pub fn entries(&self) -> usize {
        self.written
    }

    fn write_line(&mut self, line: &str) -> anyhow::Result<()> {
        let mut buf = Vec::with_capacity(line.len() + 1);
        buf.extend_from_slice(line.as_bytes());
        buf.push(b'\n');
        self.file
            .write_all(&buf)
            .and_then(|()| self.file.sync_data())
            .with_context(|| format!("writing journal {}", self.path.display()))
    }

    /// Appends one entry and syncs it to disk.
    ///
    /// # Errors
    /// The write or the sync failed.
    pub fn append(&mut self, action: &Action) -> anyhow::Result<()> {
        self.write_line(&serde_json::to_string(action)?)?;
        self.written += 1;
        if self.announce {
            let kind = match action {
                Action::Stroke(_) => "stroke",
                Action::Undo { .. } => "undo",
                Action::Redo { .. } => "redo",
            };
            eprintln!("journal: saved entry {} ({kind})", self.written);
        }
        Ok(())
    }

    /// Deletes the journal (a clean exit: nothing to recover).
    pub fn remove(self) {
        std::fs::remove_file(&self.path).ok();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::strokes::Stroke;

    fn image() -> Image {
        Image::from_vec(4, 3, 1, (0..12).map(|i| i as f32 / 12.0).collect()).unwrap()
    }

    #[test]
    fn entries_round_trip_and_a_torn_line_is_dropped() {
        let dir = tempfile::tempdir().unwrap();
        let img_path = dir.path().join("a.png");
        std::fs::write(&img_path, b"not read").unwrap();
        let img = image();
        let mut j = Journal::create(dir.path(), &img_path, &img).unwrap();
        let stroke = Action::Stroke(Stroke {
            points: vec![[1.0, 2.0], [3.5, 1.25]],
            ..Stroke::default()
        });
        j.append(&stroke).unwrap();
        j.append(&Action::Undo { undo: true }).unwrap();
        let path = j.path().to_path_buf();
        let r = recoverable(dir.path(), &img_path, &img).expect("recoverable");
        assert_eq!(
            r.strokes.strokes,
            vec![stroke.clone(), Action::Undo { undo: true }]
        );
        assert!(!r.torn);
        // A write cut short: the torn entry is dropped, the others kept.
        let mut f = OpenOptions::new().append(true).open(&path).unwrap();
        f.write_all(br#"{"points":[[1.0,"#).unwrap();
        let r = read(&path).unwrap();
        assert_eq!(r.strokes.strokes.len(), 2);
        assert!(r.torn);
        // Other pixels: not offered.
        let mut other = img.clone();
        other.data_mut()[0] = 0.5;
        assert!(recoverable(dir.path(), &img_path, &other).is_none());
        j.remove();
        assert!(!path.exists());
    }
}
