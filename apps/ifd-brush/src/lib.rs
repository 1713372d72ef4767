//! `ifd-brush`: an interactive brush that smooths an image along its
//! structures — Hessian-driven anisotropic Gaussians evaluated through
//! isotropic filter decompositions (Section 5.1 and Fig. 5 of the IFD paper),
//! with `ifd-smooth` as the engine.
//!
//! The app logic lives in this library so that it can be tested and
//! benchmarked without a window:
//!
//! - [`engine`]: the document, strokes, undo/redo, stack refresh, replay —
//!   no GUI. Headless replay and the worker thread both drive it.
//! - [`worker`]: the thread that owns the engine; the UI sends it commands
//!   and receives pixels and progress, so the UI thread never blocks.
//! - [`app`]: the egui UI (canvas, panels, file browser, dialogs).
//! - [`stroke`], [`history`], [`display`], [`view`], [`settings`],
//!   [`strokes`] (the recorded-strokes file format), [`journal`] (edits
//!   saved as you paint, recovered after a crash), [`browser`].
//!
//! # Replay without a person
//! ```text
//! ifd-brush IN.png --replay STROKES.json --save OUT.exr --exit
//! ```
//! replays the strokes headlessly (no window) and saves the result; add
//! `--screenshot SHOT.png` to do it in a window and capture it.
//! `--record FILE` writes the strokes painted in a session. The file format
//! is documented in [`strokes`]. Edits are journaled as they are painted
//! ([`journal`]): after a crash, the next start on the image offers them back
//! (`--recover` headless).
//!
//! ```no_run
//! use ifd_brush::engine::{Banks, Engine};
//! use ifd_brush::strokes::StrokesFile;
//! let banks = Banks::load_or_build(None, |_, _| {})?;
//! let mut engine = Engine::new(banks, ifd_image::MemoryBudget::default_for_machine());
//! let brush = ifd_brush::BrushSettings::default();
//! let loaded = engine.read("testdata/camera.png".as_ref(), &brush)?;
//! engine.set_image(loaded.image, None, false);
//! engine.replay(&StrokesFile::load("strokes.json".as_ref())?)?;
//! engine.save("out.exr".as_ref())?;
//! # Ok::<(), anyhow::Error>(())
//! ```

pub mod app;
pub mod browser;
pub mod display;
pub mod engine;
pub mod history;
pub mod journal;
pub mod settings;
pub mod stroke;
pub mod strokes;
pub mod view;
pub mod worker;

pub use app::{BrushApp, Persisted, StartOptions};
pub use settings::{BrushMode, BrushSettings};
