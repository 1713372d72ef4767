//! The document and its edits, without any GUI: the app's worker thread and
//! headless replay both drive an [`Engine`].

use ifd_gpu::DeviceChoice;
use std::path::{Path, PathBuf};
use std::sync::{Arc, RwLock};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use ifd_image::{Image, LoadedImage, MemoryBudget, NonFinitePolicy, ReadOptions};
use ifd_planar::PixelRect;
use ifd_smooth::{AspectBank, BankOptions, Dab, HessianBank, Smoother};

use crate::history::{EditRecorder, History};
use crate::journal::{self, Journal, Recovered};
use crate::settings::BrushSettings;
use crate::stroke::StrokeInterpolator;
use crate::strokes::{Action, StrokesFile};

struct GpuPath {
    ctx: ifd_gpu::GpuContext,
    smoother: Option<ifd_gpu::GpuSmoother>,
    /// The document on the device, displayed from there (only on a device
    /// shared with the renderer): dabs are not read back.
    canvas: Option<ifd_gpu::GpuCanvas>,
    /// Whether the device is the renderer's (a canvas can be shown).
    shared: bool,
    /// The compute path in words while the smoother is on the device.
    label: String,
}

impl GpuPath {
    /// Copies the pixels of `rect` from the device's document into `image`
    /// (a no-op without a canvas).
    fn pull(&self, image: &mut Image, rect: PixelRect) -> anyhow::Result<()> {
        if let Some(canvas) = &self.canvas {
            let pixels = canvas
                .read(&self.ctx, rect)
                .context("reading the stroke back from the GPU")?;
            crate::history::paste(image, rect, &pixels);
        }
        Ok(())
    }

    /// Copies the pixels of `rect` from `image` to the device's document (a
    /// no-op without a canvas).
    fn push(&self, image: &Image, rect: PixelRect) -> anyhow::Result<()> {
        if let Some(canvas) = &self.canvas {
            canvas
                .write(&self.ctx, rect, &crate::history::extract(image, rect))
                .context("writing to the GPU's copy of the image")?;
        }
        Ok(())
    }
}

/// A renderer's device (the window's, from eframe) that the engine may
/// evaluate on; its results are then shown without a round trip to the CPU.
#[derive(Clone, Debug)]
pub struct SharedDevice {
    /// The device.
    pub device: eframe::wgpu::Device,
    /// Its queue.
    pub queue: eframe::wgpu::Queue,
    /// Its adapter.
    pub info: eframe::wgpu::AdapterInfo,
}

/// The smoother shared with the UI thread (which only ever `try_read`s it,
/// for the filter ellipse under the cursor).
pub type SharedSmoother = Arc<RwLock<Option<Smoother>>>;

/// The decompositions in use and what the UI shows about them.
#[derive(Clone, Debug)]
pub struct Banks {
    /// Anisotropic Gaussians over aspect ratio.
    pub aspect: Arc<AspectBank>,
    /// Second-derivative filters for the Hessian.
    pub hessian: Arc<HessianBank>,
    /// Summary for the decomposition panel.
    pub info: BankInfo,
}

/// Number of terms and fit error of each decomposition.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BankInfo {
    /// Tabulated aspect ratios.
    pub aspects: Vec<f64>,
    /// Terms of each entry.
    pub terms: Vec<usize>,
    /// Relative L2 error of each entry against its sampled Gaussian.
    pub errors: Vec<f64>,
    /// Terms of the `xx` and `xy` Hessian filters.
    pub hessian_terms: [usize; 2],
    /// Where the aspect bank came from (a file, or "fitted").
    pub source: String,
}

/// Fit tolerance of the Hessian filters.
const HESSIAN_TOL: f64 = 0.01;

impl Banks {
    /// Loads the aspect bank from `cache` when it holds a valid one with the
    /// default options, else fits it (a few seconds; `progress(done, total)`)
    /// and writes it there; fits the Hessian filters.
    ///
    /// # Errors
    /// Failed fits. A cache that cannot be written is not an error.
    pub fn load_or_build(
        cache: Option<&Path>,
        mut progress: impl FnMut(usize, usize),
    ) -> anyhow::Result<Self> {
        let (aspect, source) =
            AspectBank::load_or_build(BankOptions::default(), cache, &mut progress)
                .context("fitting the aspect bank")?;
        let hessian = HessianBank::new(HESSIAN_TOL).context("fitting the Hessian filters")?;
        let errors = aspect
            .aspects
            .iter()
            .map(|&a| aspect.blend_error(a).unwrap_or(f64::NAN))
            .collect();
        let info = BankInfo {
            aspects: aspect.aspects.clone(),
            terms: aspect.terms.iter().map(Vec::len).collect(),
            errors,
            hessian_terms: [hessian.xx.terms.len(), hessian.xy.terms.len()],
            source,
        };
        Ok(Self {
            aspect: Arc::new(aspect),
            hessian: Arc::new(hessian),
            info,
        })
    }

    /// The default cache file ([`AspectBank::default_cache`], shared with
    /// `ifd smooth`).
    #[must_use]
    pub fn default_cache() -> Option<PathBuf> {
        AspectBank::default_cache()
    }
}

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

    /// Journals every stroke, undo and redo of documents opened from a file
    /// in `dir` ([`crate::journal`]); `announce` prints each saved entry on
    /// stderr. `None` turns journaling off. Applies from the next
    /// [`Engine::set_image`].
    pub fn set_journal_dir(&mut self, dir: Option<PathBuf>, announce: bool) {
        self.journal.dir = dir;
        self.journal.announce = announce;
    }

    /// The journal of an interrupted session on the current image, when the
    /// last [`Engine::set_image`] found one: offer it, then call
    /// [`Engine::resolve_recovery`].
    #[must_use]
    pub fn recoverable(&self) -> Option<&Recovered> {
        self.journal.pending.as_ref()
    }

    /// Applies (`recover`) or discards the journal of an interrupted session
    /// and starts this session's journal (which then holds the recovered
    /// edits too). Returns the dabs applied.
    ///
    /// # Errors
    /// As [`Engine::replay`].
    pub fn resolve_recovery(&mut self, recover: bool) -> anyhow::Result<usize> {
        let Some(r) = self.journal.pending.take() else {
            return Ok(0);
        };
        self.start_journal();
        if recover {
            self.replay(&r.strokes)
        } else {
            Ok(0)
        }
    }

    /// Ends journaling cleanly (the app closes normally): the journal is
    /// deleted, there is nothing to recover. A pending journal is kept.
    pub fn close_journal(&mut self) {
        if let Some(j) = self.journal.open.take() {
            j.remove();
        }
    }

    fn start_journal(&mut self) {
        self.journal.open = None;
        let (Some(dir), Some(path), Some(image)) = (&self.journal.dir, &self.path, &self.image)
        else {
            return;
        };
        match Journal::create(dir, path, image) {
            Ok(mut j) => {
                j.set_announce(self.journal.announce);
                self.journal.open = Some(j);
            }
            Err(e) => eprintln!("warning: edits are not journaled: {e:#}"),
        }
    }

    fn journal_append(&mut self, action: &Action) {
        if let Some(j) = &mut self.journal.open
            && let Err(e) = j.append(action)
        {
            eprintln!("warning: journaling stopped: {e:#}");
            self.journal.open = None;
        }
    }

    /// Sets up the GPU path as `choice` allows, on a headless device of its
    /// own; returns the path in use, in words ("CPU", or "GPU: adapter
    /// name"), and why the GPU is not used.
    pub fn enable_gpu(&mut self, choice: DeviceChoice) -> (String, Option<String>) {
        self.enable_gpu_on(choice, None)
    }

    /// As [`Engine::enable_gpu`], on the renderer's device `shared` when one
    /// is given and it is not a GL device (the compute shaders need Vulkan,
    /// Metal or DX12): the document then lives on the device as well
    /// ([`Engine::display_tiles`]), dabs are painted and shown there, and
    /// the CPU copy is brought up to date at the end of each stroke. Without
    /// `shared`, or on a GL device, a headless device of its own is used and
    /// every dab is read back.
    pub fn enable_gpu_on(
        &mut self,
        choice: DeviceChoice,
        shared: Option<SharedDevice>,
    ) -> (String, Option<String>) {
        self.compute = self.choose_gpu(choice, shared);
        self.compute.clone()
    }

    /// The compute path in use, in words, and why the GPU is not (fully)
    /// used: as [`Engine::enable_gpu_on`] returned it, updated when a
    /// smoother does not fit on the device (its dabs then run on the CPU).
    #[must_use]
    pub fn compute(&self) -> (String, Option<String>) {
        self.compute.clone()
    }

    fn choose_gpu(
        &mut self,
        choice: DeviceChoice,
        shared: Option<SharedDevice>,
    ) -> (String, Option<String>) {
        self.gpu = None;
        if choice == DeviceChoice::Cpu {
            return ("CPU".into(), None);
        }
        let mut note = None;
        let made = match shared {
            Some(d) if d.info.backend == eframe::wgpu::Backend::Gl => {
                note = Some(format!(
                    "the window renders with GL ({}); dabs run on a device of their own and are read back",
                    d.info.name
                ));
                ifd_gpu::GpuContext::new().map(|c| (c, false))
            }
            Some(d) => {
                ifd_gpu::GpuContext::from_device(d.device, d.queue, d.info).map(|c| (c, true))
            }
            None => ifd_gpu::GpuContext::new().map(|c| (c, false)),
        };
        match made {
            Ok((ctx, _)) if !choice.uses_adapter(ctx.is_software()) => (
                "CPU".into(),
                Some(format!(
                    "the GPU adapter ({}) is software; the CPU path is faster (--device gpu forces it)",
                    ctx.adapter_info().name
                )),
            ),
            Ok((ctx, shared)) => {
                let label = format!(
                    "GPU: {}{}",
                    ctx.adapter_info().name,
                    if shared {
                        ", shown without readback"
                    } else {
                        ""
                    }
                );
                self.gpu = Some(GpuPath {
                    ctx,
                    smoother: None,
                    canvas: None,
                    shared,
                    label: label.clone(),
                });
                self.compute = (label, note);
                self.upload_gpu();
                self.make_canvas();
                self.compute.clone()
            }
            Err(e) => (
                "CPU".into(),
                Some(note.map_or_else(|| e.to_string(), |n| format!("{n}; {e}"))),
            ),
        }
    }

    /// Whether dabs run on the GPU.
    #[must_use]
    pub fn uses_gpu(&self) -> bool {
        self.gpu.is_some()
    }

    /// Whether the document lives on the renderer's device and is shown from
    /// there ([`Engine::enable_gpu_on`]): dabs are not read back, and
    /// [`Engine::image`] lags a stroke in progress.
    #[must_use]
    pub fn displays_on_device(&self) -> bool {
        self.gpu.as_ref().is_some_and(|g| g.canvas.is_some())
    }

    /// The display textures of the document on the renderer's device, with
    /// the image pixels each shows, when the document lives there (see
    /// [`Engine::enable_gpu_on`]); `None` on the other paths.
    #[must_use]
    pub fn display_tiles(&self) -> Option<Vec<(PixelRect, eframe::wgpu::Texture)>> {
        let canvas = self.gpu.as_ref()?.canvas.as_ref()?;
        Some(
            canvas
                .tiles()
                .iter()
                .map(|t| (t.region, t.texture.clone()))
                .collect(),
        )
    }

    /// Puts the document on the shared device, if there is one; on failure
    /// (limits) dabs are read back instead.
    fn make_canvas(&mut self) {
        let (Some(g), Some(image)) = (&mut self.gpu, &self.image) else {
            return;
        };
        g.canvas = None;
        if g.shared {
            g.canvas = ifd_gpu::GpuCanvas::new(
                &g.ctx,
                image,
                self.float_source,
                crate::display::DISPLAY_TILE,
            )
            .map_err(|e| eprintln!("ifd-brush: the image stays on the CPU for display: {e}"))
            .ok();
        }
    }

    /// Copies the pixels of `rect` from the device's document into the CPU
    /// image (a no-op without a canvas).
    fn pull_from_canvas(&mut self, rect: PixelRect) -> anyhow::Result<()> {
        match (&self.gpu, &mut self.image) {
            (Some(g), Some(image)) => g.pull(image, rect),
            _ => Ok(()),
        }
    }

    /// Copies the pixels of `rect` from the CPU image to the device's
    /// document (a no-op without a canvas).
    fn push_to_canvas(&self, rect: PixelRect) -> anyhow::Result<()> {
        match (&self.gpu, &self.image) {
            (Some(g), Some(image)) => g.push(image, rect),
            _ => Ok(()),
        }
    }

    /// Uploads the CPU smoother (stack, bank, field) to the GPU path, if
    /// any. When it does not fit (the device's limits), dabs run on the CPU
    /// ([`Engine::compute`] says why); a document on the device is still
    /// shown from there.
    fn upload_gpu(&mut self) {
        let Some(g) = &mut self.gpu else {
            return;
        };
        g.smoother = None;
        let Ok(guard) = self.smoother.read() else {
            return;
        };
        let Some(sm) = guard.as_ref() else {
            return;
        };
        match ifd_gpu::GpuSmoother::new(&g.ctx, sm) {
            Ok(gs) => {
                g.smoother = Some(gs);
                if self.compute.0 != g.label {
                    self.compute = (g.label.clone(), None);
                }
            }
            Err(e) => self.compute = gpu_failed(&e, g.canvas.is_some()),
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

/// The compute path after the GPU failed with `e`.
fn gpu_failed(e: &ifd_gpu::GpuError, shown_on_device: bool) -> (String, Option<String>) {
    (
        if shown_on_device {
            "CPU, shown from the GPU".into()
        } else {
            "CPU".into()
        },
        Some(format!("the GPU path failed, dabs run on the CPU: {e}")),
    )
}
