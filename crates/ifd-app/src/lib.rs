//! The shell the two eframe apps share (`ifd-brush`, `ifd-envrender`), so
//! that each keeps only what is its own:
//!
//! - [`DeviceArg`]: the `--device auto|gpu|cpu` value, one meaning in both
//!   apps ([`ifd_gpu::DeviceChoice`]);
//! - [`wgpu_options`]: eframe's device with the adapter's own limits and GPU
//!   timestamps where there are any;
//! - [`write_screenshot`]: a window screenshot (`--screenshot`) as an image
//!   file;
//! - [`Shell`]: the `eframe::App` around an app's frame, persisting its
//!   settings under its storage key and finishing it on exit ([`AppFrame`]);
//! - [`Finish`] (`automation.rs`): the end of an automated run, settle,
//!   screenshot, exit, or a failure for `main` to report;
//! - [`Headless`] and [`FrameTimes`] (`harness.rs`): the headless frame
//!   harness of the frame-time tests, with the frame-time summary and plot;
//! - [`fit_views`] and [`PixelRect`] (`layout.rs`): images shown whole in
//!   the window's area, side by side or stacked, scaled down to fit, and
//!   the rectangles automated runs report.

mod automation;
mod harness;
mod layout;

use std::path::Path;

use egui::ColorImage;
use ifd_gpu::DeviceChoice;
use ifd_image::Image;

pub use crate::automation::{Finish, FinishStep, SETTLE_FRAMES};
pub use crate::harness::{FRAME_GOAL_MS, FrameTimes, Headless};
pub use crate::layout::{PixelRect, fit_views};

/// `--device` values.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum DeviceArg {
    /// A hardware GPU when there is one, else the CPU.
    Auto,
    /// Any GPU adapter, software included.
    Gpu,
    /// The CPU.
    Cpu,
}

impl From<DeviceArg> for DeviceChoice {
    fn from(d: DeviceArg) -> Self {
        match d {
            DeviceArg::Auto => DeviceChoice::Auto,
            DeviceArg::Gpu => DeviceChoice::Gpu,
            DeviceArg::Cpu => DeviceChoice::Cpu,
        }
    }
}

/// eframe's wgpu set-up with the adapter's own limits (not wgpu's
/// conservative defaults, so large images fit) and GPU timestamps when the
/// adapter has them; a GL backend keeps the defaults.
#[must_use]
pub fn wgpu_options() -> eframe::egui_wgpu::WgpuConfiguration {
    use eframe::egui_wgpu::WgpuSetup;
    use eframe::wgpu;
    let mut options = eframe::egui_wgpu::WgpuConfiguration::default();
    if let WgpuSetup::CreateNew(create) = &mut options.wgpu_setup {
        let base = std::sync::Arc::clone(&create.device_descriptor);
        create.device_descriptor = std::sync::Arc::new(move |adapter: &wgpu::Adapter| {
            let mut d = base(adapter);
            if adapter.get_info().backend != wgpu::Backend::Gl {
                d.required_limits = adapter.limits();
                if adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY) {
                    d.required_features |= wgpu::Features::TIMESTAMP_QUERY;
                }
            }
            d
        });
    }
    options
}

/// Writes a window screenshot (8-bit sRGB pixels) as an image file, its
/// format from the extension.
///
/// # Errors
/// The file cannot be written.
pub fn write_screenshot(path: &Path, img: &ColorImage) -> anyhow::Result<()> {
    let [w, h] = img.size;
    let data = img
        .pixels
        .iter()
        .flat_map(|c| [c.r(), c.g(), c.b()].map(|v| f32::from(v) / 255.0))
        .collect();
    let im = Image::from_vec(w, h, 3, data)?;
    ifd_image::write(path, &im)?;
    Ok(())
}

/// What an app gives the shell: its frame, its persisted settings, and
/// what it does on exit.
pub trait AppFrame {
    /// The settings persisted between runs.
    type Settings: serde::Serialize;
    /// Draws one frame.
    fn frame(&mut self, ui: &mut egui::Ui);
    /// The settings to persist.
    fn settings(&self) -> &Self::Settings;
    /// Stops the app's threads (the window is closing).
    fn finish(&mut self);
}

/// The `eframe::App` around an [`AppFrame`]: frames, settings saved under
/// `key`, and the app finished on exit.
pub struct Shell<A> {
    app: A,
    key: &'static str,
}

impl<A> Shell<A> {
    /// Wraps `app`, persisting its settings under `key`.
    pub fn new(app: A, key: &'static str) -> Self {
        Self { app, key }
    }
}

impl<A: AppFrame> eframe::App for Shell<A> {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.app.frame(ui);
    }

    fn save(&mut self, storage: &mut dyn eframe::Storage) {
        eframe::set_value(storage, self.key, self.app.settings());
    }

    fn on_exit(&mut self) {
        self.app.finish();
    }
}
