//! The egui UI: the viewport, the side panel of settings, the status bar,
//! frame times, and automated runs.

mod automation;
mod gpu_view;
mod panels;

use ifd_gpu::DeviceChoice;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use eframe::egui_wgpu::RenderState;
use ifd_gpu::GpuContext;
use ifd_gpu::GpuShader;
use ifd_render::Tonemap;

pub use automation::{Automation, ReferenceReport, ScreenReport, SplitSumReport};
pub use gpu_view::GpuView;

use crate::reference::{self, RefEvent, Request};
use crate::settings::{Compare, Settings};
use crate::worker::{self, Event, Frame, Handle, Info};

/// The Monte Carlo reference of the current view and ISD's error against it.
#[derive(Default)]
pub(crate) struct RefState {
    /// Settings changes that alter the image (answers carry it).
    generation: u64,
    /// The generation a request was sent for.
    requested: Option<u64>,
    /// When the image-changing settings last changed.
    changed_at: Option<Instant>,
    /// ISD's linear image of this generation.
    isd: Option<Arc<ifd_image::Image>>,
    /// The reference so far: image, mask, samples per pixel.
    image: Option<(Arc<ifd_image::Image>, Arc<Vec<bool>>, usize)>,
    texture: Option<egui::TextureHandle>,
    /// Relative RMS and PSNR (dB) of ISD against the reference.
    error: Option<(f64, f64)>,
    /// `(L, relative RMS)` and the reference's samples per pixel.
    curve: Option<(Vec<(usize, f64)>, usize)>,
    /// Reading the current GPU frame back failed (not retried).
    readback_failed: bool,
}

/// The split sum of the current frame and its difference from ISD's.
#[derive(Default)]
pub(crate) struct SplitState {
    /// The split-sum image (linear radiance) and its object mask.
    image: Option<(Arc<ifd_image::Image>, Arc<Vec<bool>>)>,
    /// Bake (when the map changed) and render time, seconds.
    seconds: Option<f64>,
    /// The split-sum image, display-transformed.
    texture: Option<egui::TextureHandle>,
    /// The split sum against ISD (ISD as the reference).
    difference: Option<ifd_render::Difference>,
    /// The difference relative to ISD, as a diverging colour map.
    difference_texture: Option<egui::TextureHandle>,
}

/// Where the views are in the window (points), as the last frame drew them.
#[derive(Clone, Debug)]
pub struct Layout {
    /// The central area beside the panel and above the status bar.
    pub area: egui::Rect,
    /// Each view's name (`isd`, then `reference`, `split-sum` or
    /// `split-sum-difference`) and rectangle.
    pub views: Vec<(&'static str, egui::Rect)>,
}

/// How the app starts.
pub struct StartOptions {
    /// The window's device (`None`: headless harness, or a GL backend).
    pub render_state: Option<RenderState>,
    /// GPU or CPU shading.
    pub gpu: DeviceChoice,
    /// Automated run.
    pub automation: Automation,
}

/// The app.
pub struct EnvApp {
    /// The settings (persisted by the shell).
    pub settings: Settings,
    sent: Option<Settings>,
    worker: Handle,
    gpu: Option<GpuView>,
    /// Why the CPU renderer is used (status bar), `None` on the GPU.
    cpu_reason: Option<String>,
    /// Why the current frame came from the CPU although the GPU path is on.
    fallback: Option<String>,
    adapter: String,
    cpu_texture: Option<egui::TextureHandle>,
    cpu_frame: Option<Duration>,
    progress: String,
    errors: Vec<String>,
    info: Info,
    frames_seen: u64,
    /// UI frame times, ms (latest 240).
    ui_times: Vec<f32>,
    automation: Automation,
    stage: automation::Stage,
    finish: ifd_app::Finish,
    /// Where the views were drawn in the last frame.
    layout: Option<Layout>,
    reference: reference::Handle,
    pub(crate) refs: RefState,
    pub(crate) split: SplitState,
}

impl std::fmt::Debug for EnvApp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EnvApp")
            .field("settings", &self.settings)
            .finish_non_exhaustive()
    }
}

impl EnvApp {
    /// Starts the worker (and the GPU view on the window's device).
    #[must_use]
    pub fn new(ctx: &egui::Context, settings: Settings, start: StartOptions) -> Self {
        let (gpu, cpu_reason, adapter) = gpu_view(start.render_state, start.gpu);
        let wake = ctx.clone();
        let wake_ref = ctx.clone();
        let reference = reference::spawn(move || wake_ref.request_repaint());
        let worker = worker::spawn(
            gpu.as_ref().map(|(c, s, _)| (Arc::clone(c), Arc::clone(s))),
            move || {
                wake.request_repaint();
            },
        );
        let finish = ifd_app::Finish::new(
            start.automation.screenshot.clone(),
            start.automation.exit,
            Arc::clone(&start.automation.failure),
        );
        Self {
            settings,
            sent: None,
            worker,
            gpu: gpu.map(|(_, _, v)| v),
            cpu_reason,
            fallback: None,
            adapter,
            cpu_texture: None,
            cpu_frame: None,
            progress: String::new(),
            errors: Vec::new(),
            info: Info::default(),
            frames_seen: 0,
            ui_times: Vec::new(),
            automation: start.automation,
            stage: automation::Stage::WaitFrame,
            finish,
            layout: None,
            reference,
            refs: RefState::default(),
            split: SplitState::default(),
        }
    }

    /// Errors reported so far (newest last).
    #[must_use]
    pub fn errors(&self) -> &[String] {
        &self.errors
    }

    /// Where the views were drawn in the last frame (`None` before the
    /// first).
    #[must_use]
    pub fn layout(&self) -> Option<&Layout> {
        self.layout.as_ref()
    }

    /// Whether frames are shaded on the GPU (else by the CPU renderer).
    #[must_use]
    pub fn shades_on_gpu(&self) -> bool {
        self.gpu.is_some() && self.fallback.is_none()
    }

    /// Frames received from the worker.
    #[must_use]
    pub fn frames_seen(&self) -> u64 {
        self.frames_seen
    }

    /// UI frame times so far, ms.
    #[must_use]
    pub fn ui_times(&self) -> &[f32] {
        &self.ui_times
    }

    /// Whether the latest frame is completely shown.
    #[must_use]
    pub fn frame_complete(&self) -> bool {
        match &self.gpu {
            Some(g) if self.fallback.is_none() => g.is_complete(),
            _ => self.cpu_texture.is_some(),
        }
    }

    fn tonemap(&self) -> Tonemap {
        Tonemap::parse(&self.settings.tonemap).unwrap_or(Tonemap::Aces)
    }

    /// One UI frame.
    pub fn frame(&mut self, ui: &mut egui::Ui) {
        let ctx = ui.ctx().clone();
        let t0 = Instant::now();
        // what the view beside ISD's shows changes nothing to render
        if let Some(sent) = &mut self.sent
            && sent.compare_image != self.settings.compare_image
        {
            sent.compare_image = self.settings.compare_image;
        }
        // the worker renders the latest settings that change the image
        let display_only = self.sent.as_ref().is_some_and(|s| {
            let mut a = s.clone();
            a.exposure = self.settings.exposure;
            a.tonemap.clone_from(&self.settings.tonemap);
            a == self.settings
        });
        if self.sent.as_ref() != Some(&self.settings) {
            if display_only && self.gpu.is_some() {
                if let Some(g) = &mut self.gpu {
                    g.redisplay();
                }
            } else {
                // The worker only stops when the app does.
                self.worker.tx.send(self.settings.clone()).ok();
                let reference_only = self.sent.as_ref().is_some_and(|s| {
                    let mut a = s.clone();
                    a.reference = self.settings.reference;
                    a == self.settings
                });
                if !reference_only {
                    let g = self.refs.generation + 1;
                    self.refs = RefState {
                        generation: g,
                        ..RefState::default()
                    };
                }
                self.refs.changed_at = Some(Instant::now());
            }
            let tm = self.tonemap();
            if let Some(t) = &mut self.refs.texture
                && let Some((img, _, _)) = &self.refs.image
            {
                t.set(
                    worker::display_image(img, tm, self.settings.exposure),
                    VIEW_TEXTURE,
                );
            }
            if let Some(t) = &mut self.split.texture
                && let Some((img, _)) = &self.split.image
            {
                t.set(
                    worker::display_image(img, tm, self.settings.exposure),
                    VIEW_TEXTURE,
                );
            }
            self.sent = Some(self.settings.clone());
        }
        self.events(&ctx);
        self.reference_step(&ctx);
        self.split_step(&ctx);
        let (curve, exposure) = (self.tonemap().into(), self.settings.exposure);
        if let Some(g) = &mut self.gpu {
            match g.step(curve, exposure) {
                Ok(true) => ctx.request_repaint(),
                Ok(false) => {}
                Err(e) => self.errors.push(format!("GPU: {e}")),
            }
        }
        panels::status_bar(self, ui);
        panels::side_panel(self, ui);
        panels::viewport(self, ui);
        self.automation_step(&ctx);
        // the UI thread's time in this frame (what a person waits for)
        self.ui_times.push(t0.elapsed().as_secs_f32() * 1e3);
        if self.ui_times.len() > 240 {
            self.ui_times.remove(0);
        }
    }

    fn events(&mut self, ctx: &egui::Context) {
        while let Ok(e) = self.worker.rx.try_recv() {
            match e {
                Event::Progress(p) => self.progress = p,
                Event::Error(msg) => {
                    self.progress.clear();
                    if self.automation.active() {
                        self.fail(ctx, msg.clone());
                    }
                    self.errors.push(msg);
                }
                Event::Info(i) => self.info = i,
                Event::Fallback(why) => {
                    self.fallback = Some(why);
                }
                Event::SplitSum {
                    image,
                    mask,
                    seconds,
                } => {
                    self.progress.clear();
                    let shown =
                        worker::display_image(&image, self.tonemap(), self.settings.exposure);
                    show_in(
                        &mut self.split.texture,
                        ctx,
                        "ifd-envrender split sum",
                        shown,
                    );
                    self.split.image = Some((image, mask));
                    self.split.seconds = Some(seconds);
                    self.split.difference = None;
                }
                Event::Frame(f) => {
                    self.progress.clear();
                    self.frames_seen += 1;
                    // the split sum of the previous frame is stale
                    self.split.image = None;
                    self.split.difference = None;
                    match f {
                        Frame::Gpu {
                            surfaces,
                            env,
                            material,
                            row_objects,
                        } => {
                            self.fallback = None;
                            self.cpu_texture = None;
                            // ISD's linear image is this frame's, read back
                            // once it is complete
                            self.refs.isd = None;
                            self.refs.error = None;
                            self.refs.readback_failed = false;
                            if let Some(g) = &mut self.gpu
                                && let Err(e) = g.set_frame(surfaces, env, material, row_objects)
                            {
                                self.errors.push(format!("GPU: {e}"));
                            }
                        }
                        Frame::Cpu {
                            image,
                            linear,
                            seconds,
                        } => {
                            self.refs.isd = Some(linear);
                            self.refs.error = None;
                            self.cpu_frame = Some(Duration::from_secs_f64(seconds));
                            show_in(&mut self.cpu_texture, ctx, "ifd-envrender view", image);
                        }
                    }
                    ctx.request_repaint();
                }
            }
        }
        // a CPU frame's display settings are applied by re-rendering: keep
        // the worker's answer flowing
        if self.gpu.is_none() && self.sent.as_ref() != Some(&self.settings) {
            ctx.request_repaint_after(Duration::from_millis(30));
        }
    }

    /// Requests the reference once the view has been still for 400 ms and
    /// the frame is complete; takes the reference thread's answers.
    fn reference_step(&mut self, ctx: &egui::Context) {
        let r = &mut self.refs;
        let still = r
            .changed_at
            .is_none_or(|t| t.elapsed() > Duration::from_millis(400));
        if self.settings.reference && r.requested != Some(r.generation) {
            if still && self.frame_complete() {
                self.reference
                    .tx
                    .send(Request {
                        settings: self.settings.clone(),
                        generation: self.refs.generation,
                    })
                    .ok();
                self.refs.requested = Some(self.refs.generation);
            } else {
                ctx.request_repaint_after(Duration::from_millis(100));
            }
        }
        // the GPU frame's linear image, read back once it is complete
        if (self.settings.reference || self.settings.compare != Compare::Off)
            && self.refs.isd.is_none()
            && !self.refs.readback_failed
            && self.fallback.is_none()
            && let Some(g) = &self.gpu
            && g.is_complete()
        {
            match g.read_linear() {
                Ok(img) => self.refs.isd = Some(Arc::new(img)),
                Err(e) => {
                    self.refs.readback_failed = true;
                    let msg = format!("GPU: reading the frame back: {e}");
                    if self.automation.active() {
                        self.fail(ctx, msg.clone());
                    }
                    self.errors.push(msg);
                }
            }
        }
        while let Ok(e) = self.reference.rx.try_recv() {
            match e {
                RefEvent::Pass {
                    generation,
                    image,
                    mask,
                    spp,
                } if generation == self.refs.generation => {
                    let shown =
                        worker::display_image(&image, self.tonemap(), self.settings.exposure);
                    show_in(
                        &mut self.refs.texture,
                        ctx,
                        "ifd-envrender reference",
                        shown,
                    );
                    self.refs.image = Some((image, mask, spp));
                    self.refs.error = None;
                }
                RefEvent::Curve {
                    generation,
                    points,
                    spp,
                } if generation == self.refs.generation => {
                    self.refs.curve = Some((points, spp));
                }
                RefEvent::Error(msg) => self.errors.push(format!("reference: {msg}")),
                _ => {}
            }
        }
        let r = &mut self.refs;
        if r.error.is_none()
            && let (Some(isd), Some((reference, mask, _))) = (&r.isd, &r.image)
            && isd.width() == reference.width()
            && isd.height() == reference.height()
        {
            r.error = Some(errors(isd, reference, mask));
        }
    }

    /// The split sum's difference from ISD, once both images are here.
    fn split_step(&mut self, ctx: &egui::Context) {
        let sp = &mut self.split;
        if self.settings.compare == Compare::Off || sp.difference.is_some() {
            return;
        }
        let (Some(isd), Some((split, mask))) = (&self.refs.isd, &sp.image) else {
            return;
        };
        match ifd_render::Difference::new(split, &like(isd, split), mask) {
            Ok(d) => {
                let pixels = d
                    .relative
                    .iter()
                    .zip(mask.iter())
                    .map(|(v, on)| {
                        if *on {
                            let c = ifd_plot::diverging(v / d.full_scale);
                            let b = |x: f32| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
                            egui::Color32::from_rgb(b(c[0]), b(c[1]), b(c[2]))
                        } else {
                            egui::Color32::from_gray(40)
                        }
                    })
                    .collect();
                let image = egui::ColorImage::new([split.width(), split.height()], pixels);
                show_in(
                    &mut sp.difference_texture,
                    ctx,
                    "ifd-envrender split-sum difference",
                    image,
                );
                sp.difference = Some(d);
            }
            Err(e) => {
                sp.image = None;
                let msg = format!("split sum: {e}");
                if self.automation.active() {
                    self.fail(ctx, msg.clone());
                }
                self.errors.push(msg);
            }
        }
    }

    /// Called when the window closes.
    /// Stops the threads (waiting up to 5 s for work in progress) and drops
    /// the GPU resources while the window's device is still alive: a worker
    /// uploading while the device is torn down crashed lavapipe at exit.
    pub fn finish(&mut self) {
        let limit = Duration::from_secs(5);
        self.worker.stop(limit);
        self.reference.stop(limit);
        self.gpu = None;
    }
}

/// The GPU path's device, shader and view, why there is none, and the adapter.
type GpuStart = (
    Option<(Arc<GpuContext>, Arc<GpuShader>, GpuView)>,
    Option<String>,
    String,
);

/// The GPU view on the window's device, or why there is none.
fn gpu_view(rs: Option<RenderState>, choice: DeviceChoice) -> GpuStart {
    let Some(rs) = rs else {
        return (
            None,
            Some("no wgpu device (headless)".into()),
            "none".into(),
        );
    };
    let info = rs.adapter.get_info();
    let adapter = format!("{} ({:?}, {:?})", info.name, info.device_type, info.backend);
    if choice == DeviceChoice::Cpu {
        return (None, Some("--device cpu".into()), adapter);
    }
    if !choice.uses_adapter(info.device_type == eframe::wgpu::DeviceType::Cpu) {
        return (
            None,
            Some(
                "a software adapter, slower than the CPU renderer here (--device gpu to use it)"
                    .into(),
            ),
            adapter,
        );
    }
    if info.backend == eframe::wgpu::Backend::Gl {
        return (
            None,
            Some("a GL device (the kernels need Vulkan)".into()),
            adapter,
        );
    }
    let ctx = match GpuContext::from_device(rs.device.clone(), rs.queue.clone(), info) {
        Ok(c) => Arc::new(c),
        Err(e) => return (None, Some(format!("the GPU path failed: {e}")), adapter),
    };
    match GpuShader::new(&ctx) {
        Ok(shader) => {
            let shader = Arc::new(shader);
            let view = GpuView::new(Arc::clone(&ctx), rs, Arc::clone(&shader));
            (Some((ctx, shader, view)), None, adapter)
        }
        Err(e) => (
            None,
            Some(format!("the shading kernels failed: {e}")),
            adapter,
        ),
    }
}

/// The default path of a file dropped or typed in.
#[must_use]
pub fn dropped_path(ctx: &egui::Context) -> Option<PathBuf> {
    ctx.input(|i| i.raw.dropped_files.first().map(|f| f.path().to_path_buf()))
}

/// Shows `image` in the texture `slot`, made (named `name`) the first time.
fn show_in(
    slot: &mut Option<egui::TextureHandle>,
    ctx: &egui::Context,
    name: &str,
    image: egui::ColorImage,
) {
    match slot {
        Some(t) => t.set(image, VIEW_TEXTURE),
        None => *slot = Some(ctx.load_texture(name, image, VIEW_TEXTURE)),
    }
}

/// How a view's texture is sampled: pixel for pixel when it fits, linear
/// when it is shown smaller than rendered (a view scaled to fit the window).
pub(crate) const VIEW_TEXTURE: egui::TextureOptions = egui::TextureOptions {
    minification: egui::TextureFilter::Linear,
    ..egui::TextureOptions::NEAREST
};

/// `img` with `other`'s channels: the GPU's frame is RGB, grey maps
/// repeat their one channel in it (the CPU renders one channel).
fn like<'a>(
    img: &'a ifd_image::Image,
    other: &ifd_image::Image,
) -> std::borrow::Cow<'a, ifd_image::Image> {
    if img.channels() == 3 && other.channels() == 1 {
        let grey = img.data().chunks_exact(3).map(|p| p[0]).collect();
        if let Ok(g) = ifd_image::Image::from_vec(img.width(), img.height(), 1, grey) {
            return std::borrow::Cow::Owned(g);
        }
    }
    std::borrow::Cow::Borrowed(img)
}

/// Relative RMS error and PSNR (dB; the reference's largest object value as
/// the data range) of `a` against `reference` over the object's pixels
/// (NaN when the images cannot be compared).
fn errors(a: &ifd_image::Image, reference: &ifd_image::Image, mask: &[bool]) -> (f64, f64) {
    ifd_render::Difference::new(&like(a, reference), reference, mask)
        .map_or((f64::NAN, f64::NAN), |d| (d.relative_rms, d.psnr_db))
}

impl ifd_app::AppFrame for EnvApp {
    type Settings = Settings;

    fn frame(&mut self, ui: &mut egui::Ui) {
        EnvApp::frame(self, ui);
    }

    fn settings(&self) -> &Settings {
        &self.settings
    }

    fn finish(&mut self) {
        EnvApp::finish(self);
    }
}
