//! The recorded-strokes file (`--record FILE` writes one, `--replay FILE`
//! plays one back).
//!
//! JSON, one object:
//!
//! ```json
//! {
//!   "format": "ifd-brush-strokes",
//!   "version": 1,
//!   "image_size": [512, 512],
//!   "strokes": [
//!     {
//!       "brush": { "radius": 32, "strength": 0.6, "falloff": 0.5, "scale": 6,
//!                  "max_aspect": 8, "mode": "per-pixel", "spacing": 0.25 },
//!       "points": [[100.0, 120.5], [130.0, 121.0]]
//!     },
//!     { "undo": true },
//!     { "redo": true }
//!   ]
//! }
//! ```
//!
//! - `image_size` (optional): `[width, height]` of the image the strokes were
//!   recorded on; replay refuses another size.
//! - Each stroke's `points` are the pointer positions in image pixels
//!   (`x` = column, `y` = row, pixel centres at integers), in the order
//!   they were sampled; dabs are placed along the polyline through them every
//!   `spacing * radius` pixels ([`crate::stroke`]). `brush` fields left out
//!   take their defaults ([`crate::BrushSettings`]).
//! - `{"undo": true}` and `{"redo": true}` entries replay Ctrl+Z and
//!   Ctrl+Shift+Z.
//!
//! Semantics (identical in the app and in replay): within a stroke every dab
//! reads the prefiltered stack as it was when the stroke began; after the
//! stroke the stack and orientation field are refreshed where the image
//! changed, so the next stroke smooths the smoothed image.

use std::path::Path;

use anyhow::{Context, bail};
use serde::{Deserialize, Serialize};

use crate::settings::BrushSettings;

/// The `format` field's value.
pub const FORMAT: &str = "ifd-brush-strokes";
/// The current version.
pub const VERSION: u32 = 1;

/// One recorded stroke.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Stroke {
    /// The brush it was painted with.
    #[serde(default)]
    pub brush: BrushSettings,
    /// Pointer positions, image pixels.
    pub points: Vec<[f32; 2]>,
}

/// One entry of a strokes file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Action {
    /// Paint a stroke.
    Stroke(Stroke),
    /// Undo the latest stroke.
    Undo {
        /// Always `true`.
        undo: bool,
    },
    /// Redo the latest undone stroke.
    Redo {
        /// Always `true`.
        redo: bool,
    },
}

/// A strokes file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StrokesFile {
    /// Always [`FORMAT`].
    pub format: String,
    /// [`VERSION`].
    pub version: u32,
    /// `[width, height]` of the image, when known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image_size: Option<[usize; 2]>,
    /// Strokes, undos and redos in order.
    pub strokes: Vec<Action>,
}

impl Default for StrokesFile {
    fn default() -> Self {
        Self {
            format: FORMAT.into(),
            version: VERSION,
            image_size: None,
            strokes: Vec::new(),
        }
    }
}

impl StrokesFile {
    /// Reads and checks a strokes file.
    ///
    /// # Errors
    /// Unreadable file, bad JSON, wrong format or version, non-finite points.
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("reading strokes file {}", path.display()))?;
        let f: Self = serde_json::from_str(&text)
            .with_context(|| format!("parsing strokes file {}", path.display()))?;
        if f.format != FORMAT {
            bail!(
                "{}: format is {:?}, expected {FORMAT:?}",
                path.display(),
                f.format
            );
        }
        if f.version != VERSION {
            bail!(
                "{}: version {} is not supported (expected {VERSION})",
                path.display(),
                f.version
            );
        }
        for a in &f.strokes {
            if let Action::Stroke(s) = a
                && s.points.iter().flatten().any(|v| !v.is_finite())
            {
                bail!("{}: a stroke has non-finite points", path.display());
            }
        }
        Ok(f)
    }

    /// Writes the file (atomically).
    ///
    /// # Errors
    /// Serialisation or write failure.
    pub fn save(&self, path: &Path) -> anyhow::Result<()> {
        let text = serde_json::to_string_pretty(self)?;
        ifd_image::atomic_write(path, |w| {
            use std::io::Write;
            w.write_all(text.as_bytes()).map_err(|e| e.to_string())
        })?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_checks() {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = dir.path().join("s.json");
        let f = StrokesFile {
            image_size: Some([10, 20]),
            strokes: vec![
                Action::Stroke(Stroke {
                    brush: BrushSettings::default(),
                    points: vec![[1.0, 2.0], [3.5, 4.0]],
                }),
                Action::Undo { undo: true },
                Action::Redo { redo: true },
            ],
            ..StrokesFile::default()
        };
        f.save(&p).expect("save");
        assert_eq!(StrokesFile::load(&p).expect("load"), f);
        std::fs::write(&p, r#"{"format":"x","version":1,"strokes":[]}"#).expect("write");
        assert!(StrokesFile::load(&p).is_err());
        std::fs::write(
            &p,
            r#"{"format":"ifd-brush-strokes","version":1,"strokes":[{"points":[[1,2]]},{"undo":true}]}"#,
        )
        .expect("write");
        let f = StrokesFile::load(&p).expect("defaults");
        assert!(matches!(&f.strokes[0], Action::Stroke(s) if s.brush == BrushSettings::default()));
        assert!(matches!(f.strokes[1], Action::Undo { .. }));
    }
}
