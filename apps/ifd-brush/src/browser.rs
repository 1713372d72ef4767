//! A small file browser drawn with egui (no GTK dialog): folders, image
//! files, a path field; for saving, a file name and a format.

use std::path::{Path, PathBuf};

/// Extensions the browser lists for opening.
pub const OPEN_EXTENSIONS: &[&str] = &["png", "jpg", "jpeg", "tif", "tiff", "exr", "hdr"];
/// Formats offered for saving.
pub const SAVE_EXTENSIONS: &[&str] = &["png", "exr", "tiff"];

/// What the browser is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Purpose {
    /// Pick an image to open.
    Open,
    /// Pick where to save.
    Save,
}

/// One listed entry.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Entry {
    /// File name.
    pub name: String,
    /// A folder.
    pub is_dir: bool,
}

/// The browser's state.
#[derive(Clone, Debug)]
pub struct FileBrowser {
    /// Open or save.
    pub purpose: Purpose,
    /// The folder shown.
    pub dir: PathBuf,
    /// Its entries (folders first, then matching files, by name).
    pub entries: Vec<Entry>,
    /// File name field (save) or typed path (open).
    pub name: String,
    /// Save format index into [`SAVE_EXTENSIONS`].
    pub format: usize,
    /// Why the folder could not be listed.
    pub error: Option<String>,
}

fn has_ext(name: &str, exts: &[&str]) -> bool {
    Path::new(name)
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| exts.contains(&e.to_ascii_lowercase().as_str()))
}

/// Lists `dir`: sub-folders and files with one of `exts` (hidden entries skipped).
///
/// # Errors
/// The folder cannot be read.
pub fn list(dir: &Path, exts: &[&str]) -> std::io::Result<Vec<Entry>> {
    let mut out: Vec<Entry> = std::fs::read_dir(dir)?
        .filter_map(Result::ok)
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            let is_dir = e.file_type().ok()?.is_dir() || e.path().is_dir();
            (!name.starts_with('.') && (is_dir || has_ext(&name, exts)))
                .then_some(Entry { name, is_dir })
        })
        .collect();
    out.sort_by(|a, b| b.is_dir.cmp(&a.is_dir).then(a.name.cmp(&b.name)));
    Ok(out)
}

impl FileBrowser {
    /// A browser showing `dir`.
    #[must_use]
    pub fn new(purpose: Purpose, dir: PathBuf, name: String) -> Self {
        let mut b = Self {
            purpose,
            dir,
            entries: Vec::new(),
            name,
            format: 0,
            error: None,
        };
        b.refresh();
        b
    }

    fn exts(&self) -> &'static [&'static str] {
        match self.purpose {
            Purpose::Open => OPEN_EXTENSIONS,
            Purpose::Save => SAVE_EXTENSIONS,
        }
    }

    /// Re-reads the folder.
    pub fn refresh(&mut self) {
        match list(&self.dir, self.exts()) {
            Ok(e) => {
                self.entries = e;
                self.error = None;
            }
            Err(e) => {
                self.entries.clear();
                self.error = Some(format!("{}: {e}", self.dir.display()));
            }
        }
    }

    /// Enters a sub-folder, or the parent for `".."`.
    pub fn enter(&mut self, name: &str) {
        if name == ".." {
            if let Some(p) = self.dir.parent() {
                self.dir = p.to_path_buf();
            }
        } else {
            self.dir = self.dir.join(name);
        }
        self.refresh();
    }

    /// The path to save to: the name with the chosen format's extension
    /// unless it already has a savable one.
    #[must_use]
    pub fn save_path(&self) -> Option<PathBuf> {
        let name = self.name.trim();
        if name.is_empty() {
            return None;
        }
        let p = self.dir.join(name);
        if has_ext(name, SAVE_EXTENSIONS) || has_ext(name, &["tif"]) {
            Some(p)
        } else {
            Some(p.with_extension(SAVE_EXTENSIONS[self.format.min(SAVE_EXTENSIONS.len() - 1)]))
        }
    }

    /// Draws the browser; returns the chosen path, or `Some(None)` when cancelled.
    pub fn show(&mut self, ui: &mut egui::Ui) -> Option<Option<PathBuf>> {
        let mut result = None;
        ui.horizontal(|ui| {
            if ui.button("⬆ Up").clicked() {
                self.enter("..");
            }
            ui.label(self.dir.display().to_string());
        });
        if let Some(e) = &self.error {
            ui.colored_label(egui::Color32::LIGHT_RED, e);
        }
        let mut enter = None;
        egui::ScrollArea::vertical()
            .max_height(300.0)
            .auto_shrink([false, false])
            .show(ui, |ui| {
                for e in &self.entries {
                    let label = if e.is_dir {
                        format!("📁 {}", e.name)
                    } else {
                        e.name.clone()
                    };
                    let r = ui.selectable_label(!e.is_dir && self.name == e.name, label);
                    if r.clicked() {
                        if e.is_dir {
                            enter = Some(e.name.clone());
                        } else {
                            self.name.clone_from(&e.name);
                        }
                    }
                    if r.double_clicked() && !e.is_dir {
                        result = Some(Some(self.dir.join(&e.name)));
                    }
                }
            });
        if let Some(n) = enter {
            self.enter(&n);
        }
        ui.horizontal(|ui| {
            ui.label(match self.purpose {
                Purpose::Open => "File:",
                Purpose::Save => "Save as:",
            });
            ui.text_edit_singleline(&mut self.name);
            if self.purpose == Purpose::Save {
                egui::ComboBox::from_id_salt("save-format")
                    .selected_text(SAVE_EXTENSIONS[self.format])
                    .show_ui(ui, |ui| {
                        for (i, e) in SAVE_EXTENSIONS.iter().enumerate() {
                            ui.selectable_value(&mut self.format, i, *e);
                        }
                    });
            }
        });
        ui.horizontal(|ui| {
            let ok = match self.purpose {
                Purpose::Open => "Open",
                Purpose::Save => "Save",
            };
            if ui.button(ok).clicked() {
                let name = self.name.trim();
                if !name.is_empty() {
                    result = Some(match self.purpose {
                        // A typed absolute path is taken as it is.
                        Purpose::Open => Some(self.dir.join(name)),
                        Purpose::Save => self.save_path(),
                    });
                }
            }
            if ui.button("Cancel").clicked() {
                result = Some(None);
            }
        });
        result
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lists_folders_then_images() {
        let d = tempfile::tempdir().expect("tempdir");
        for f in ["b.png", "a.EXR", "notes.txt", ".hidden.png"] {
            std::fs::write(d.path().join(f), b"").expect("write");
        }
        std::fs::create_dir(d.path().join("sub")).expect("mkdir");
        let e = list(d.path(), OPEN_EXTENSIONS).expect("list");
        let names: Vec<&str> = e.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(names, ["sub", "a.EXR", "b.png"]);
        let mut b = FileBrowser::new(Purpose::Save, d.path().to_path_buf(), "out".into());
        b.format = 1;
        assert_eq!(b.save_path(), Some(d.path().join("out.exr")));
        b.name = "x.tiff".into();
        assert_eq!(b.save_path(), Some(d.path().join("x.tiff")));
        b.enter("sub");
        assert!(b.entries.is_empty() && b.error.is_none());
        b.enter("missing");
        assert!(b.error.is_some());
    }
}
