//! The headless frame harness both apps' frame-time tests use: an egui
//! context run without a window or GPU (a frame's time is the app's drawing
//! plus egui's layout and tessellation; texture uploads are dropped), and
//! the frame times it collects, summarised and plotted.

use std::path::Path;
use std::time::Instant;

use egui::{RawInput, Rect, pos2, vec2};
use ifd_image::Image;
use ifd_plot::{Series, log_line_plot};

/// The frame-time goal the apps are held to: 50 ms (20 frames per second)
/// while work runs in the background.
pub const FRAME_GOAL_MS: f32 = 50.0;

/// An egui context driven without a window.
///
/// ```
/// use ifd_app::Headless;
/// let mut h = Headless::new([320.0, 200.0]);
/// let ms = h.frame(Vec::new(), |ui| { ui.label("hello"); });
/// assert!(ms >= 0.0 && h.times().len() == 1);
/// ```
#[derive(Debug)]
pub struct Headless {
    ctx: egui::Context,
    screen: Rect,
    times: Vec<f32>,
}

impl Headless {
    /// A new context whose screen is `size` points.
    #[must_use]
    pub fn new(size: [f32; 2]) -> Self {
        Self {
            ctx: egui::Context::default(),
            screen: Rect::from_min_size(pos2(0.0, 0.0), vec2(size[0], size[1])),
            times: Vec::new(),
        }
    }

    /// Resizes the screen to `size` points (a window resized): the next
    /// frame is laid out in it.
    pub fn resize(&mut self, size: [f32; 2]) {
        self.screen = Rect::from_min_size(pos2(0.0, 0.0), vec2(size[0], size[1]));
    }

    /// The context (to create the app with).
    #[must_use]
    pub fn ctx(&self) -> &egui::Context {
        &self.ctx
    }

    /// Runs one frame with `events` as its input, drawn by `draw`, and
    /// returns (and records) its time in milliseconds.
    pub fn frame(&mut self, events: Vec<egui::Event>, draw: impl FnMut(&mut egui::Ui)) -> f32 {
        let input = RawInput {
            screen_rect: Some(self.screen),
            events,
            ..RawInput::default()
        };
        let t0 = Instant::now();
        let mut out = self.ctx.run_ui(input, draw);
        // No renderer: the texture uploads are dropped.
        out.textures_delta.clear();
        drop(self.ctx.tessellate(out.shapes, out.pixels_per_point));
        let ms = t0.elapsed().as_secs_f32() * 1e3;
        self.times.push(ms);
        ms
    }

    /// The frame times recorded so far.
    #[must_use]
    pub fn times(&self) -> FrameTimes {
        FrameTimes {
            ms: self.times.clone(),
        }
    }
}

/// Frame times in milliseconds, in the order drawn.
#[derive(Clone, Debug, Default)]
pub struct FrameTimes {
    /// One time per frame.
    pub ms: Vec<f32>,
}

impl FrameTimes {
    /// Number of frames.
    #[must_use]
    pub fn len(&self) -> usize {
        self.ms.len()
    }

    /// Whether no frame was drawn.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.ms.is_empty()
    }

    /// `(median, p99, max)`, zeros when empty.
    ///
    /// ```
    /// let t = ifd_app::FrameTimes { ms: vec![3.0, 1.0, 2.0] };
    /// assert_eq!(t.stats(), (2.0, 3.0, 3.0));
    /// ```
    #[must_use]
    pub fn stats(&self) -> (f32, f32, f32) {
        if self.ms.is_empty() {
            return (0.0, 0.0, 0.0);
        }
        let mut s = self.ms.clone();
        s.sort_by(f32::total_cmp);
        let n = s.len();
        (s[n / 2], s[(n * 99 / 100).min(n - 1)], s[n - 1])
    }

    /// One line: frames, median, p99, max (what BENCHMARKS.md reports).
    #[must_use]
    pub fn summary(&self) -> String {
        let (median, p99, max) = self.stats();
        format!(
            "{} UI frames, median {median:.2} ms, p99 {p99:.2} ms, max {max:.2} ms",
            self.len()
        )
    }

    /// The frame times against the frame index (log scale) with the
    /// [`FRAME_GOAL_MS`] line, titled `title` in the legend.
    ///
    /// # Errors
    /// Only if the image cannot be allocated.
    pub fn plot(&self, title: &str) -> Result<Image, ifd_image::ImageError> {
        let n = self.ms.len().max(1) as f64;
        let times = Series {
            name: format!("{title}: frame time (ms)"),
            colour: [0.1, 0.3, 0.8],
            dotted: false,
            points: (self.ms.iter().enumerate())
                .map(|(i, &t)| (i as f64, f64::from(t)))
                .collect(),
        };
        let goal = Series {
            name: format!("goal {FRAME_GOAL_MS} ms"),
            colour: [0.8, 0.1, 0.1],
            dotted: true,
            points: vec![
                (0.0, f64::from(FRAME_GOAL_MS)),
                (n, f64::from(FRAME_GOAL_MS)),
            ],
        };
        log_line_plot(&[times, goal], "frame", "ms")
    }

    /// The end of a frame-time test: a note on stderr when a frame took
    /// longer than [`FRAME_GOAL_MS`] (reported, not asserted: a timed
    /// assertion flakes on a loaded machine), and the [`Self::plot`] written
    /// to `path`.
    ///
    /// # Errors
    /// The plot cannot be made or written.
    pub fn report(&self, title: &str, path: &Path) -> Result<(), ifd_image::ImageError> {
        let (_, _, max) = self.stats();
        if max >= FRAME_GOAL_MS {
            eprintln!(
                "note: a UI frame took {max:.1} ms, above the {FRAME_GOAL_MS} ms goal (not asserted)"
            );
        }
        ifd_image::write(path, &self.plot(title)?)?;
        eprintln!("frame-time plot: {}", path.display());
        Ok(())
    }
}
