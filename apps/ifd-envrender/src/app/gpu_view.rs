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
use ifd_gpu::shading::{Curve, GpuEnvironment, GpuMaterial, GpuShaded, GpuShader, GpuSurfaces};

/// GPU time the UI allows one band, before the next frame is drawn.
const BAND_BUDGET: Duration = Duration::from_millis(12);

struct Inputs {
    surfaces: Arc<GpuSurfaces>,
    env: Arc<GpuEnvironment>,
    material: Arc<GpuMaterial>,
}

/// The GPU frame in progress and its display texture.
pub struct GpuView {
    ctx: Arc<GpuContext>,
    render_state: RenderState,
    shader: GpuShader,
    inputs: Option<Inputs>,
    output: Option<GpuShaded>,
    texture: Option<(wgpu::Texture, egui::TextureId)>,
    next_row: usize,
    rows_per_band: usize,
    in_flight: Option<(Instant, usize, Arc<AtomicBool>)>,
    frame_started: Instant,
    /// The last complete frame's shading time (submission of its first band
    /// to completion of its last).
    pub last_frame: Option<Duration>,
    /// Whether the display needs redrawing (settings changed).
    dirty_display: bool,
}

impl std::fmt::Debug for GpuView {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuView")
            .field("next_row", &self.next_row)
            .field("rows_per_band", &self.rows_per_band)
            .finish_non_exhaustive()
    }
}

impl GpuView {
    /// The view on the window's device.
    ///
    /// # Errors
    /// When the shading pipelines cannot be built there.
    pub fn new(ctx: Arc<GpuContext>, render_state: RenderState) -> Result<Self, ifd_gpu::GpuError> {
        let shader = GpuShader::new(&ctx)?;
        Ok(Self {
            ctx,
            render_state,
            shader,
            inputs: None,
            output: None,
            texture: None,
            next_row: 0,
            rows_per_band: 8,
            in_flight: None,
            frame_started: Instant::now(),
            last_frame: None,
            dirty_display: false,
        })
    }

    /// Starts shading a new frame.
    ///
    /// # Errors
    /// When the output buffer for a new size cannot be made.
    pub fn set_frame(
        &mut self,
        surfaces: Arc<GpuSurfaces>,
        env: Arc<GpuEnvironment>,
        material: Arc<GpuMaterial>,
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
                        mag_filter: wgpu::FilterMode::Nearest,
                        min_filter: wgpu::FilterMode::Nearest,
                        ..wgpu::SamplerDescriptor::default()
                    },
                );
            self.texture = Some((tex, id));
        }
        self.inputs = Some(Inputs {
            surfaces,
            env,
            material,
        });
        self.next_row = 0;
        self.frame_started = Instant::now();
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
    pub fn step(&mut self, curve: Curve, exposure: f32) -> Result<bool, ifd_gpu::GpuError> {
        if let Some((t0, rows, done)) = &self.in_flight {
            // fire the completion callback if the band is done (non-blocking)
            let _ = self.ctx.device().poll(wgpu::PollType::Poll);
            if !done.load(Ordering::Acquire) {
                return Ok(true);
            }
            // adapt the band to the budget from the last band's GPU time
            // (timestamps: the band is done, so reading them does not wait
            // for shading), else from the time to its completion callback
            let gpu = self
                .output
                .as_ref()
                .and_then(|o| o.gpu_time(&self.ctx).ok().flatten());
            let secs = gpu.unwrap_or_else(|| t0.elapsed()).as_secs_f64().max(1e-4);
            let scale = (BAND_BUDGET.as_secs_f64() / secs).clamp(0.25, 4.0);
            self.rows_per_band = ((*rows as f64 * scale) as usize).max(1);
            self.in_flight = None;
            if let Some(o) = &self.output
                && self.next_row >= o.size().1
            {
                self.last_frame = Some(self.frame_started.elapsed());
            }
        }
        let (Some(inputs), Some(out)) = (&self.inputs, &mut self.output) else {
            return Ok(false);
        };
        let h = out.size().1;
        let shading = self.next_row < h;
        if shading {
            let r0 = self.next_row;
            let r1 = (r0 + self.rows_per_band).min(h);
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
            self.in_flight = Some((Instant::now(), r1 - r0, done));
        }
        if shading || self.dirty_display {
            if let Some((tex, _)) = &self.texture {
                self.shader.display(&self.ctx, out, curve, exposure, tex)?;
            }
            self.dirty_display = false;
        }
        Ok(self.in_flight.is_some())
    }
}
