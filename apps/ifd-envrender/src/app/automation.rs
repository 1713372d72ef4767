//! Runs without a person (`--screenshot`, `--exit`): wait for the first
//! complete frame (and the reference, when asked), then the end that both
//! apps share ([`ifd_app::Finish`]: settle, screenshot, close), reporting
//! the window's size and each view's rectangle in it (the screenshot's
//! pixels). A failure closes the window with a message that `main` reports
//! (exit status 2).

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use ifd_app::{FinishStep, PixelRect};

use super::EnvApp;

/// What to do without a person.
#[derive(Clone, Debug, Default)]
pub struct Automation {
    /// Save a screenshot of the window here (PNG) once the frame is shown.
    pub screenshot: Option<PathBuf>,
    /// Close the window when done.
    pub exit: bool,
    /// Where a failed automated run leaves its message.
    pub failure: Arc<Mutex<Option<String>>>,
    /// Where the window's size and the views' rectangles are reported
    /// at the end of the run (physical pixels: the screenshot's).
    pub screen: Arc<Mutex<Option<ScreenReport>>>,
    /// Wait for the Monte Carlo reference to reach this many samples per
    /// pixel (and, from 64, the error-against-`L` curve) before finishing.
    pub reference_spp: Option<usize>,
    /// Where the reference's result is reported: samples per pixel, ISD's
    /// relative RMS error and PSNR against it, the curve `(L, error)`.
    pub reference: Arc<Mutex<Option<ReferenceReport>>>,
    /// Wait for the split sum's difference from ISD (with a comparison on)
    /// and report it here.
    pub split_sum: Arc<Mutex<Option<SplitSumReport>>>,
}

/// Where things are on the screen at the end of an automated run, in
/// physical pixels (the screenshot's).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ScreenReport {
    /// The window's inner size (the screenshot's), `[width, height]`.
    pub window: [i64; 2],
    /// The central area that holds the views (beside the panel, above the
    /// status bar).
    pub area: PixelRect,
    /// Each view's name (`isd`, then `reference`, `split-sum` or
    /// `split-sum-difference`) and rectangle.
    pub views: Vec<(String, PixelRect)>,
    /// Whether the frame was shaded on the GPU (else on the CPU).
    pub gpu: bool,
}

/// The reference's result at the end of an automated run.
pub type ReferenceReport = (usize, f64, f64, Vec<(usize, f64)>);

/// The split sum against ISD at the end of an automated run.
#[derive(Clone, Debug)]
pub struct SplitSumReport {
    /// The difference (ISD as the reference).
    pub difference: ifd_render::Difference,
    /// Bake and render time of the split sum, seconds.
    pub seconds: f64,
}

impl Automation {
    /// Whether anything is automated.
    #[must_use]
    pub fn active(&self) -> bool {
        self.screenshot.is_some() || self.exit
    }
}

/// Where an automated run is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Stage {
    WaitFrame,
    /// The shared end of the run ([`ifd_app::Finish`]).
    Finishing,
    Done,
}

impl EnvApp {
    pub(super) fn fail(&mut self, ctx: &egui::Context, msg: String) {
        self.stage = Stage::Done;
        self.finish.fail(ctx, msg);
    }

    pub(super) fn automation_step(&mut self, ctx: &egui::Context) {
        if !self.automation.active() {
            return;
        }
        match self.stage {
            Stage::WaitFrame => {
                let reference_done = self.automation.reference_spp.is_none_or(|n| {
                    let r = &self.refs;
                    let spp = r.image.as_ref().map_or(0, |i| i.2);
                    spp >= n && r.error.is_some() && (n < 64 || r.curve.is_some())
                });
                // (the worker compares the glTF BRDF only)
                let split_done = self.settings.compare == crate::settings::Compare::Off
                    || !self.settings.brdf_is_gltf()
                    || self.split.difference.is_some();
                if self.frame_complete() && reference_done && split_done {
                    if let (Some(d), Ok(mut slot)) =
                        (&self.split.difference, self.automation.split_sum.lock())
                    {
                        *slot = Some(SplitSumReport {
                            difference: d.clone(),
                            seconds: self.split.seconds.unwrap_or(f64::NAN),
                        });
                    }
                    if self.automation.reference_spp.is_some()
                        && let (Some((_, _, spp)), Some((rel, psnr)), Ok(mut slot)) = (
                            &self.refs.image,
                            self.refs.error,
                            self.automation.reference.lock(),
                        )
                    {
                        let curve = self.refs.curve.as_ref().map(|c| c.0.clone());
                        *slot = Some((*spp, rel, psnr, curve.unwrap_or_default()));
                    }
                    self.stage = Stage::Finishing;
                    self.finish.start();
                }
                ctx.request_repaint_after(Duration::from_millis(20));
            }
            Stage::Finishing => match self.finish.step(ctx) {
                FinishStep::Pending => {}
                FinishStep::Finished => {
                    self.stage = Stage::Done;
                    self.report_screen(ctx);
                }
                FinishStep::Failed | FinishStep::Done => self.stage = Stage::Done,
            },
            Stage::Done => {}
        }
    }

    /// Reports the window's size and the views' rectangles (physical
    /// pixels) for the screenshot's reader and the window tests.
    fn report_screen(&self, ctx: &egui::Context) {
        let Some(layout) = &self.layout else {
            return;
        };
        let ppp = ctx.pixels_per_point();
        let window = PixelRect::from_points(ctx.content_rect(), ppp);
        let report = ScreenReport {
            window: [window.width, window.height],
            area: PixelRect::from_points(layout.area, ppp),
            views: (layout.views.iter())
                .map(|(name, r)| ((*name).to_owned(), PixelRect::from_points(*r, ppp)))
                .collect(),
            gpu: self.shades_on_gpu(),
        };
        if let Ok(mut slot) = self.automation.screen.lock() {
            *slot = Some(report);
        }
    }
}
