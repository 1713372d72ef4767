//! The GPU path of the engine: choosing the adapter (one meaning of
//! `--device`), the document on the device (`GpuCanvas`) and the smoother
//! uploaded there, kept in step with the CPU copy.

use anyhow::Context;
use ifd_gpu::DeviceChoice;
use ifd_image::Image;
use ifd_planar::PixelRect;

use super::Engine;

pub(super) struct GpuPath {
    pub(super) ctx: ifd_gpu::GpuContext,
    pub(super) smoother: Option<ifd_gpu::GpuSmoother>,
    /// The document on the device, displayed from there (only on a device
    /// shared with the renderer): dabs are not read back.
    pub(super) canvas: Option<ifd_gpu::GpuCanvas>,
    /// Whether the device is the renderer's (a canvas can be shown).
    pub(super) shared: bool,
    /// The compute path in words while the smoother is on the device.
    pub(super) label: String,
}

impl GpuPath {
    /// Copies the pixels of `rect` from the device's document into `image`
    /// (a no-op without a canvas).
    pub(super) fn pull(&self, image: &mut Image, rect: PixelRect) -> anyhow::Result<()> {
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
    pub(super) fn push(&self, image: &Image, rect: PixelRect) -> anyhow::Result<()> {
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

impl Engine {
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

    pub(super) fn choose_gpu(
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
    pub(super) fn make_canvas(&mut self) {
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
    pub(super) fn pull_from_canvas(&mut self, rect: PixelRect) -> anyhow::Result<()> {
        match (&self.gpu, &mut self.image) {
            (Some(g), Some(image)) => g.pull(image, rect),
            _ => Ok(()),
        }
    }

    /// Copies the pixels of `rect` from the CPU image to the device's
    /// document (a no-op without a canvas).
    pub(super) fn push_to_canvas(&self, rect: PixelRect) -> anyhow::Result<()> {
        match (&self.gpu, &self.image) {
            (Some(g), Some(image)) => g.push(image, rect),
            _ => Ok(()),
        }
    }

    /// Uploads the CPU smoother (stack, bank, field) to the GPU path, if
    /// any. When it does not fit (the device's limits), dabs run on the CPU
    /// ([`Engine::compute`] says why); a document on the device is still
    /// shown from there.
    pub(super) fn upload_gpu(&mut self) {
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
}

/// The compute path after the GPU failed with `e`.
pub(super) fn gpu_failed(e: &ifd_gpu::GpuError, shown_on_device: bool) -> (String, Option<String>) {
    (
        if shown_on_device {
            "CPU, shown from the GPU".into()
        } else {
            "CPU".into()
        },
        Some(format!("the GPU path failed, dabs run on the CPU: {e}")),
    )
}
