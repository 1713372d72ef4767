//! The document and its edits, without any GUI: the app's worker thread and
//! headless replay both drive an [`Engine`].

use std::path::{Path, PathBuf};
use std::sync::{Arc, RwLock};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use ifd_image::{Image, LoadedImage, MemoryBudget, NonFinitePolicy, ReadOptions};
use ifd_planar::PixelRect;
use ifd_smooth::{Dab, Smoother};

use crate::history::{EditRecorder, History};
use crate::journal::{self, Journal, Recovered};
use crate::settings::BrushSettings;
use crate::stroke::StrokeInterpolator;
use crate::strokes::{Action, StrokesFile};

mod banks;
mod gpu;
mod recovery;

pub use banks::{BankInfo, Banks};
pub use gpu::SharedDevice;
use gpu::{GpuPath, gpu_failed};

/// The smoother shared with the UI thread (which only ever `try_read`s it,
/// for the filter ellipse under the cursor).
pub type SharedSmoother = Arc<RwLock<Option<Smoother>>>;

/// What painting along a stroke did.
#[derive(Clone, Debug, Default)]
pub struct DabBatch {
    /// Union of the regions the dabs changed (`None`: all missed the image).
    pub rect: Option<PixelRect>,
    /// Time of each dab (apply only).
    pub times: Vec<Duration>,
}

struct ActiveStroke {
    brush: BrushSettings,
    /// The pointer positions so far (journaled whole when the stroke ends).
    points: Vec<[f32; 2]>,
    interp: StrokeInterpolator,
    recorder: EditRecorder,
    rect: Option<PixelRect>,
}

/// An opened image with its edit history and smoother.
pub struct Engine {
    banks: Banks,
    budget: MemoryBudget,
    image: Option<Image>,
    path: Option<PathBuf>,
    float_source: bool,
    smoother: SharedSmoother,
    history: History,
    stroke: Option<ActiveStroke>,
    recording: Option<StrokesFile>,
    journal: JournalState,
    gpu: Option<GpuPath>,
    /// The compute path in words, and why the GPU is not (fully) used.
    compute: (String, Option<String>),
}

/// The edit journal of the document ([`crate::journal`]).
#[derive(Debug, Default)]
struct JournalState {
    /// Where journals live; `None`: journaling off.
    dir: Option<PathBuf>,
    /// Print each saved entry on stderr.
    announce: bool,
    /// The open journal of the current document.
    open: Option<Journal>,
    /// A journal of an interrupted session on this image, waiting for
    /// [`Engine::resolve_recovery`] (nothing is journaled until then).
    pending: Option<Recovered>,
}

/// Bytes an image of this shape needs in the app with `brush`: the stack and
/// orientation field of its smoother, the document, the UI's copy, and the
/// display tiles (current and original).
#[must_use]
pub fn estimate_bytes(
    banks: &Banks,
    width: usize,
    height: usize,
    channels: usize,
    brush: &BrushSettings,
) -> u64 {
    let o = brush.smooth_options();
    let px = (width * height) as u64;
    let stack =
        Smoother::stack_layout((width, height, channels), &o, &banks.aspect, &banks.hessian)
            .map_or(u64::MAX / 2, |l| l.bytes());
    stack + px * 8 + 2 * px * channels as u64 * 4 + 2 * px * 4
}

impl Engine {
    /// An engine with no image, images limited by `budget`.
    #[must_use]
    pub fn new(banks: Banks, budget: MemoryBudget) -> Self {
        Self {
            banks,
            budget,
            image: None,
            path: None,
            float_source: false,
            smoother: Arc::new(RwLock::new(None)),
            history: History::default(),
            stroke: None,
            recording: None,
            journal: JournalState::default(),
            gpu: None,
            compute: ("CPU".into(), None),
        }
    }

    /// The decompositions.
    #[must_use]
    pub fn banks(&self) -> &Banks {
        &self.banks
    }

    /// The smoother, shared.
    #[must_use]
    pub fn shared_smoother(&self) -> SharedSmoother {
        Arc::clone(&self.smoother)
    }

    /// The current image. On the GPU display path ([`Engine::enable_gpu_on`]
    /// with a shared device) a stroke in progress is only on the device: this
    /// copy catches up when the stroke ends ([`Engine::end_stroke`]).
    #[must_use]
    pub fn image(&self) -> Option<&Image> {
        self.image.as_ref()
    }

    /// The current image's file.
    #[must_use]
    pub fn path(&self) -> Option<&Path> {
        self.path.as_deref()
    }

    /// Whether the image came from a float file (EXR, HDR).
    #[must_use]
    pub fn float_source(&self) -> bool {
        self.float_source
    }

    /// The undo history.
    #[must_use]
    pub fn history(&self) -> &History {
        &self.history
    }

    /// Reads an image file and checks that the app can hold it with `brush`
    /// (memory budget) and smooth it (no NaN or infinite values). Does not
    /// change the engine: on error the current document is untouched.
    ///
    /// # Errors
    /// Unreadable or unsupported files, images beyond the budget, non-finite samples.
    pub fn read(&self, path: &Path, brush: &BrushSettings) -> anyhow::Result<LoadedImage> {
        let opts = ReadOptions {
            budget: self.budget,
            non_finite: NonFinitePolicy::Error,
            ..ReadOptions::default()
        };
        let loaded = ifd_image::read_image(path, &opts)?;
        self.check_fits(&loaded.image, brush)
            .with_context(|| format!("{}", path.display()))?;
        Ok(loaded)
    }

    /// Checks the memory budget and the samples of an image.
    ///
    /// # Errors
    /// As [`Engine::read`].
    pub fn check_fits(&self, image: &Image, brush: &BrushSettings) -> anyhow::Result<()> {
        let (w, h, c) = (image.width(), image.height(), image.channels());
        let need = estimate_bytes(&self.banks, w, h, c, brush);
        if need > self.budget.limit() {
            bail!(
                "a {w}x{h} image with {c} channel(s) needs about {} for smoothing, more than the memory budget of {}",
                ifd_image::fmt_bytes(need),
                self.budget.describe()
            );
        }
        let bad = image.count_non_finite();
        if bad > 0 {
            bail!("the image has {bad} NaN or infinite values; the smoother cannot use it");
        }
        Ok(())
    }

    /// Makes `image` the document (history cleared, smoother dropped until
    /// [`Engine::prepare`]).
    pub fn set_image(&mut self, image: Image, path: Option<PathBuf>, float_source: bool) {
        if let Ok(mut s) = self.smoother.write() {
            *s = None;
        }
        if let Some(r) = &mut self.recording {
            r.image_size = Some([image.width(), image.height()]);
            r.strokes.clear();
        }
        self.image = Some(image);
        self.path = path;
        self.float_source = float_source;
        self.history = History::default();
        self.stroke = None;
        if let Some(g) = &mut self.gpu {
            // The old document's smoother and canvas go with it.
            g.smoother = None;
        }
        self.make_canvas();
        // The previous document closed normally; this one's journal starts
        // now, unless an interrupted session left one to offer first.
        self.close_journal();
        self.journal.pending = None;
        if let (Some(dir), Some(p), Some(img)) = (&self.journal.dir, &self.path, &self.image) {
            self.journal.pending = journal::recoverable(dir, p, img);
        }
        if self.journal.pending.is_none() {
            self.start_journal();
        }
    }

    /// Builds the smoother for `brush` unless the current one fits (the
    /// stack depends on the footprint scale, the field on the anisotropy).
    /// Returns whether it built one.
    ///
    /// # Errors
    /// No image, or prefiltering failed.
    pub fn prepare(&mut self, brush: &BrushSettings) -> anyhow::Result<bool> {
        if self.image.is_none() {
            bail!("no image");
        }
        let opts = brush.smooth_options();
        let fits = self
            .smoother
            .read()
            .map_err(|_| anyhow::anyhow!("smoother lock poisoned"))?
            .as_ref()
            .is_some_and(|s| *s.options() == opts);
        if fits {
            return Ok(false);
        }
        // The new smoother starts from the image as it is, a stroke in
        // progress included (which goes on): on the GPU display path its
        // pixels are brought over from the device first.
        if let Some(r) = self.stroke.as_ref().and_then(|s| s.rect) {
            self.pull_from_canvas(r)?;
        }
        let Some(image) = &self.image else {
            bail!("no image");
        };
        let sm = Smoother::with_banks(
            image,
            &opts,
            Arc::clone(&self.banks.aspect),
            &self.banks.hessian,
        )
        .context("prefiltering")?;
        *self
            .smoother
            .write()
            .map_err(|_| anyhow::anyhow!("smoother lock poisoned"))? = Some(sm);
        self.upload_gpu();
        Ok(true)
    }

    /// Whether a smoother is ready.
    #[must_use]
    pub fn is_ready(&self) -> bool {
        self.smoother.read().is_ok_and(|s| s.is_some())
    }

    /// Starts recording strokes (for `--record`).
    pub fn start_recording(&mut self) {
        self.recording = Some(StrokesFile {
            image_size: self.image.as_ref().map(|i| [i.width(), i.height()]),
            ..StrokesFile::default()
        });
    }

    /// The recording so far.
    #[must_use]
    pub fn recording(&self) -> Option<&StrokesFile> {
        self.recording.as_ref()
    }

    /// Starts a stroke (ends one in progress), building the smoother if the
    /// brush needs another.
    ///
    /// # Errors
    /// As [`Engine::prepare`].
    pub fn begin_stroke(&mut self, brush: BrushSettings) -> anyhow::Result<()> {
        self.end_stroke()?;
        let brush = brush.clamped();
        self.prepare(&brush)?;
        let Some(image) = &self.image else {
            bail!("no image");
        };
        if let Some(r) = &mut self.recording {
            r.strokes.push(Action::Stroke(crate::strokes::Stroke {
                brush,
                points: Vec::new(),
            }));
        }
        self.stroke = Some(ActiveStroke {
            brush,
            points: Vec::new(),
            interp: StrokeInterpolator::with_bounds(
                brush.spacing_px(),
                [
                    -brush.radius - 1.0,
                    -brush.radius - 1.0,
                    image.width() as f32 + brush.radius,
                    image.height() as f32 + brush.radius,
                ],
            ),
            recorder: EditRecorder::new(image),
            rect: None,
        });
        Ok(())
    }

    /// The pointer moved to `(x, y)` (image pixels) during a stroke: applies
    /// the dabs it adds.
    ///
    /// # Errors
    /// No stroke in progress, or a dab failed.
    pub fn stroke_to(&mut self, x: f32, y: f32) -> anyhow::Result<DabBatch> {
        let (Some(st), Some(image)) = (&mut self.stroke, &mut self.image) else {
            bail!("no stroke in progress");
        };
        if let Some(Action::Stroke(s)) = self.recording.as_mut().and_then(|r| r.strokes.last_mut())
        {
            s.points.push([x, y]);
        }
        st.points.push([x, y]);
        let guard = self
            .smoother
            .read()
            .map_err(|_| anyhow::anyhow!("smoother lock poisoned"))?;
        let Some(sm) = guard.as_ref() else {
            bail!("the smoother is not ready");
        };
        let mut batch = DabBatch::default();
        let b = st.brush;
        for (cx, cy) in st.interp.push(x, y) {
            let dab = Dab {
                x: cx,
                y: cy,
                radius: b.radius,
                falloff: b.falloff,
                strength: b.strength,
            };
            let t0 = Instant::now();
            // (A bad dab is reported by `apply_dab` below.)
            if let Ok(Some(r)) = dab.region(image.width(), image.height()) {
                st.recorder.before_change(image, r);
            }
            let mode = b.mode.into();
            let on_gpu = self.gpu.as_ref().and_then(|g| {
                let gs = g.smoother.as_ref()?;
                Some(match &g.canvas {
                    // Painted and shown on the device; the CPU image follows
                    // at the end of the stroke.
                    Some(canvas) => canvas.apply_dab(&g.ctx, gs, &dab, mode),
                    None => gs.apply_dab(&g.ctx, &dab, mode, image),
                })
            });
            let region = match on_gpu {
                Some(Ok(r)) => r,
                other => {
                    if let (Some(Err(e)), Some(g)) = (other, &mut self.gpu) {
                        // From now on the CPU paints (this dab included),
                        // starting from the stroke so far, which is only on
                        // the device.
                        g.smoother = None;
                        self.compute = gpu_failed(&e, g.canvas.is_some());
                        if let Some(r) = st.rect {
                            g.pull(image, r)?;
                        }
                    }
                    let r = sm.apply_dab(&dab, mode, image)?;
                    // A document on the device is shown from there.
                    if let (Some(r), Some(g)) = (r, &self.gpu) {
                        g.push(image, r)?;
                    }
                    r
                }
            };
            if let Some(r) = region {
                batch.rect = Some(batch.rect.map_or(r, |a| a.union(r)));
                st.rect = Some(st.rect.map_or(r, |a| a.union(r)));
            }
            batch.times.push(t0.elapsed());
        }
        Ok(batch)
    }

    /// Ends the stroke in progress: records it for undo and refreshes the
    /// smoother where the image changed. Returns the changed rectangle.
    ///
    /// # Errors
    /// A failed refresh.
    pub fn end_stroke(&mut self) -> anyhow::Result<Option<PixelRect>> {
        // The stroke's pixels first: if they cannot be read back, the stroke
        // stays open (and on screen) rather than being half recorded.
        if let Some(r) = self.stroke.as_ref().and_then(|s| s.rect) {
            self.pull_from_canvas(r)?;
        }
        let Some(mut st) = self.stroke.take() else {
            return Ok(None);
        };
        let points = std::mem::take(&mut st.points);
        self.journal_append(&Action::Stroke(crate::strokes::Stroke {
            brush: st.brush,
            points,
        }));
        let Some(rect) = st.rect else {
            return Ok(None);
        };
        let Some(image) = &self.image else {
            return Ok(None);
        };
        if let Some(edit) = st.recorder.finish(image) {
            self.history.push(edit);
        }
        self.refresh(rect)?;
        Ok(Some(rect))
    }

    fn refresh(&mut self, rect: PixelRect) -> anyhow::Result<()> {
        let Some(image) = &self.image else {
            return Ok(());
        };
        let mut guard = self
            .smoother
            .write()
            .map_err(|_| anyhow::anyhow!("smoother lock poisoned"))?;
        let Some(sm) = guard.as_mut() else {
            return Ok(());
        };
        let report = sm
            .refresh_region(image, rect, &self.banks.hessian)
            .context("refreshing the prefiltered stack")?;
        // The GPU copy follows row by row; should that fail, it is uploaded again.
        let updated = match &mut self.gpu {
            Some(GpuPath {
                ctx,
                smoother: Some(gs),
                ..
            }) => gs.refresh(ctx, sm, rect, &report).is_ok(),
            _ => true,
        };
        drop(guard);
        if !updated {
            self.upload_gpu();
        }
        Ok(())
    }

    /// Undoes the latest stroke; returns the changed rectangle.
    ///
    /// # Errors
    /// A failed refresh.
    pub fn undo(&mut self) -> anyhow::Result<Option<PixelRect>> {
        self.end_stroke()?;
        let Some(image) = &mut self.image else {
            return Ok(None);
        };
        let r = self.history.undo(image);
        if let Some(rec) = &mut self.recording {
            rec.strokes.push(Action::Undo { undo: true });
        }
        self.journal_append(&Action::Undo { undo: true });
        if let Some(r) = r {
            self.push_to_canvas(r)?;
            self.refresh(r)?;
        }
        Ok(r)
    }

    /// Redoes the latest undone stroke; returns the changed rectangle.
    ///
    /// # Errors
    /// A failed refresh.
    pub fn redo(&mut self) -> anyhow::Result<Option<PixelRect>> {
        self.end_stroke()?;
        let Some(image) = &mut self.image else {
            return Ok(None);
        };
        let r = self.history.redo(image);
        if let Some(rec) = &mut self.recording {
            rec.strokes.push(Action::Redo { redo: true });
        }
        self.journal_append(&Action::Redo { redo: true });
        if let Some(r) = r {
            self.push_to_canvas(r)?;
            self.refresh(r)?;
        }
        Ok(r)
    }

    /// Writes the image (format from the extension: PNG, TIFF, EXR, ...; atomic).
    ///
    /// # Errors
    /// No image, unsupported extension, write failure.
    pub fn save(&mut self, path: &Path) -> anyhow::Result<()> {
        let Some(image) = &self.image else {
            bail!("no image to save");
        };
        ifd_image::write(path, image).with_context(|| format!("saving {}", path.display()))?;
        Ok(())
    }

    /// Replays a strokes file on the current image; returns the dabs applied.
    ///
    /// # Errors
    /// Another image size than recorded, and the errors of painting.
    pub fn replay(&mut self, file: &StrokesFile) -> anyhow::Result<usize> {
        let Some(image) = &self.image else {
            bail!("no image");
        };
        if let Some([w, h]) = file.image_size
            && (w, h) != (image.width(), image.height())
        {
            bail!(
                "the strokes were recorded on a {w}x{h} image, this one is {}x{}",
                image.width(),
                image.height()
            );
        }
        let mut dabs = 0;
        for a in &file.strokes {
            match a {
                Action::Stroke(s) => {
                    self.begin_stroke(s.brush)?;
                    for p in &s.points {
                        dabs += self.stroke_to(p[0], p[1])?.times.len();
                    }
                    self.end_stroke()?;
                }
                Action::Undo { .. } => {
                    self.undo()?;
                }
                Action::Redo { .. } => {
                    self.redo()?;
                }
            }
        }
        Ok(dabs)
    }
}
