//! The GPU path in the window: frames shaded on eframe's own device in bands
//! of rows, one band in flight at a time (a slow adapter never holds the
//! queue, and so the window, for long), the display transform into a texture
//! egui draws directly (no readback).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use eframe::egui_wgpu::RenderState;
use eframe::wgpu;
use ifd_gpu::GpuContext;
use ifd_gpu::{GpuEnvironment, GpuMaterial, GpuShaded, GpuShader, GpuSurfaces, ToneCurve};

/// GPU time the UI allows one band, before the next frame is drawn (on
/// lavapipe a submission runs before `submit` returns, so this is also what
/// the UI thread waits).
const BAND_BUDGET: Duration = Duration::from_millis(12);

/// The first guess of the shading cost per object pixel (pessimistic, a
/// software adapter at high `L`); measured from then on.
const FIRST_COST_S: f64 = 50e-6;

struct Inputs {
    surfaces: Arc<GpuSurfaces>,
    env: Arc<GpuEnvironment>,
    material: Arc<GpuMaterial>,
    /// Object pixels per row (the cost of a row; background rows are copies).
    row_objects: Vec<u32>,
}

/// The GPU frame in progress and its display texture.
pub struct GpuView {
    ctx: Arc<GpuContext>,
    render_state: RenderState,
    shader: Arc<GpuShader>,
    inputs: Option<Inputs>,
    output: Option<GpuShaded>,
    texture: Option<(wgpu::Texture, egui::TextureId)>,
    next_row: usize,
    /// Measured GPU seconds per object pixel (the band sizes follow it).
    cost: f64,
    /// The band in flight: submission time, object pixels, done flag.
    in_flight: Option<(Instant, u64, Arc<AtomicBool>)>,
    frame_started: Instant,
    /// The last complete frame's shading time (submission of its first band
    /// to completion of its last).
    pub last_frame: Option<Duration>,
    /// GPU time of the frame in progress (sum of its bands' timestamps).
    frame_gpu: Duration,
    /// GPU time of each complete frame, ms (latest 120; empty without
    /// timestamp queries).
    pub gpu_frames: Vec<f32>,
    /// Whether the display needs redrawing (settings changed).
    dirty_display: bool,
}

impl std::fmt::Debug for GpuView {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuView")
            .field("next_row", &self.next_row)
            .field("cost", &self.cost)
            .finish_non_exhaustive()
    }
}

impl GpuView {
    /// The view on the window's device, shading with `shader` (shared with
    /// the worker, which compiles each degree's kernel before the UI uses
    /// it).
    #[must_use]
    pub fn new(ctx: Arc<GpuContext>, render_state: RenderState, shader: Arc<GpuShader>) -> Self {
        Self {
            ctx,
            render_state,
            shader,
            inputs: None,
            output: None,
            texture: None,
            next_row: 0,
            cost: FIRST_COST_S,
            in_flight: None,
            frame_started: Instant::now(),
            last_frame: None,
            frame_gpu: Duration::ZERO,
            gpu_frames: Vec::new(),
            dirty_display: false,
        }
    }

    /// Starts shading a new frame; `row_objects` are the object pixels of
    /// each row.
    ///
    /// # Errors
    /// When the output buffer for a new size cannot be made.
    pub fn set_frame(
        &mut self,
        surfaces: Arc<GpuSurfaces>,
        env: Arc<GpuEnvironment>,
        material: Arc<GpuMaterial>,
        row_objects: Vec<u32>,
    ) -> Result<(), ifd_gpu::GpuError> {
        let (w, h) = surfaces.size();
        let same = self.output.as_ref().is_some_and(|o| o.size() == (w, h));
        if !same {
            self.output = Some(self.shader.output(&self.ctx, w, h)?);
            if let Some((_, id)) = self.texture.take() {
                self.render_state.renderer.write().free_texture(&id);
            }
            let tex = GpuShader::display_texture(&self.ctx, w, h);
            let view = tex.create_view(&wgpu::TextureViewDescriptor::default());
            let id = self
                .render_state
                .renderer
                .write()
                .register_native_texture_with_sampler_options(
                    &self.render_state.device,
                    &view,
                    wgpu::SamplerDescriptor {
                        label: Some("ifd-envrender view"),
                        // pixel for pixel when the view fits, linear
                        // when it is scaled down to fit the window
                        mag_filter: wgpu::FilterMode::Nearest,
                        min_filter: wgpu::FilterMode::Linear,
                        ..wgpu::SamplerDescriptor::default()
                    },
                );
            self.texture = Some((tex, id));
        }
        self.inputs = Some(Inputs {
            surfaces,
            env,
            material,
            row_objects,
        });
        self.next_row = 0;
        self.frame_started = Instant::now();
        self.frame_gpu = Duration::ZERO;
        Ok(())
    }

    /// Redraw the display texture on the next step (exposure, tone curve).
    pub fn redisplay(&mut self) {
        self.dirty_display = true;
    }

    /// Whether the current frame is completely shaded and shown.
    #[must_use]
    pub fn is_complete(&self) -> bool {
        self.inputs.is_some()
            && self.in_flight.is_none()
            && self
                .output
                .as_ref()
                .is_some_and(|o| self.next_row >= o.size().1)
            && !self.dirty_display
    }

    /// The shaded frame's linear RGB (blocks until the GPU is done: call it
    /// once the frame is complete).
    ///
    /// # Errors
    /// Readback failures.
    pub fn read_linear(&self) -> Result<ifd_image::Image, ifd_gpu::GpuError> {
        let Some(o) = &self.output else {
            return Err(ifd_gpu::GpuError::Unsupported("no frame yet".into()));
        };
        Ok(o.read(&self.ctx)?.0)
    }

    /// The texture to draw and its size.
    #[must_use]
    pub fn texture(&self) -> Option<(egui::TextureId, [usize; 2])> {
        let (_, id) = self.texture.as_ref()?;
        let (w, h) = self.output.as_ref()?.size();
        Some((*id, [w, h]))
    }

    /// One UI frame's worth of work: when the band in flight is done, the
    /// next band and the display transform are submitted. Returns whether
    /// more work remains (the UI asks for another frame).
    ///
    /// # Errors
    /// GPU errors (caught by error scopes).
    pub fn step(&mut self, curve: ToneCurve, exposure: f32) -> Result<bool, ifd_gpu::GpuError> {
        if let Some((t0, objects, done)) = &self.in_flight {
            // fire the completion callback if the band is done (non-blocking)
            let _ = self.ctx.device().poll(wgpu::PollType::Poll);
            if !done.load(Ordering::Acquire) {
                return Ok(true);
            }
            // the cost per object pixel from the band's GPU time
            // (timestamps: the band is done, so reading them does not wait),
            // else from the time to its completion callback
            let gpu = self
                .output
                .as_ref()
                .and_then(|o| o.gpu_time(&self.ctx).ok().flatten());
            if let Some(g) = gpu {
                self.frame_gpu += g;
            }
            if *objects >= 256 {
                let secs = gpu.unwrap_or_else(|| t0.elapsed()).as_secs_f64();
                self.cost = secs / *objects as f64;
            }
            self.in_flight = None;
            if let Some(o) = &self.output
                && self.next_row >= o.size().1
            {
                self.last_frame = Some(self.frame_started.elapsed());
                if self.ctx.has_timestamps() {
                    self.gpu_frames.push(self.frame_gpu.as_secs_f32() * 1e3);
                    if self.gpu_frames.len() > 120 {
                        self.gpu_frames.remove(0);
                    }
                }
            }
        }
        let (Some(inputs), Some(out)) = (&self.inputs, &mut self.output) else {
            return Ok(false);
        };
        let h = out.size().1;
        if self.next_row < h {
            // as many rows as the budget allows at the measured cost (at least one)
            let r0 = self.next_row;
            let allowed = (BAND_BUDGET.as_secs_f64() / self.cost.max(1e-12)) as u64;
            let (mut r1, mut objects) = (r0, 0u64);
            while r1 < h {
                let next = objects + u64::from(inputs.row_objects.get(r1).copied().unwrap_or(0));
                if r1 > r0 && next > allowed {
                    break;
                }
                objects = next;
                r1 += 1;
            }
            self.shader.shade_rows(
                &self.ctx,
                &inputs.surfaces,
                &inputs.env,
                &inputs.material,
                out,
                r0..r1,
            )?;
            self.next_row = r1;
            let done = Arc::new(AtomicBool::new(false));
            let flag = Arc::clone(&done);
            self.ctx
                .queue()
                .on_submitted_work_done(move || flag.store(true, Ordering::Release));
            self.in_flight = Some((Instant::now(), objects, done));
            if let Some((tex, _)) = &self.texture {
                let rows = if self.dirty_display { 0..h } else { r0..r1 };
                self.shader
                    .display_rows(&self.ctx, out, curve, exposure, tex, rows)?;
            }
            self.dirty_display = false;
        } else if self.dirty_display {
            if let Some((tex, _)) = &self.texture {
                self.shader.display(&self.ctx, out, curve, exposure, tex)?;
            }
            self.dirty_display = false;
        }
        Ok(self.in_flight.is_some())
    }
}
