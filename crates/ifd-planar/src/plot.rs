//! A picture of a fit for `ifd decompose --plot`: kernel, reconstruction,
//! error and the log-histogram of weights per level (the IFD paper's Fig. 3).

use ifd_image::Image;

use crate::decomposition::Decomposition;
use crate::kernel::Kernel;

/// Side of each panel, px.
const PANEL: usize = 256;
/// Gap around panels, px.
const GAP: usize = 8;
/// Magnitude bins of the histogram.
const BINS: usize = 32;

/// Diverging blue-white-red map of `t` in `[-1, 1]`.
fn diverging(t: f64) -> [f32; 3] {
    const BLUE: [f64; 3] = [0.13, 0.40, 0.67];
    const RED: [f64; 3] = [0.70, 0.09, 0.17];
    let t = if t.is_finite() {
        t.clamp(-1.0, 1.0)
    } else {
        0.0
    };
    let end = if t < 0.0 { BLUE } else { RED };
    let a = t.abs();
    std::array::from_fn(|c| ((1.0 - a) + a * end[c]) as f32)
}

/// Sequential white-to-dark-blue map of `t` in `[0, 1]`.
fn sequential(t: f64) -> [f32; 3] {
    const DARK: [f64; 3] = [0.03, 0.19, 0.42];
    let t = t.clamp(0.0, 1.0);
    std::array::from_fn(|c| ((1.0 - t) + t * DARK[c]) as f32)
}

fn put(img: &mut Image, x: usize, y: usize, rgb: [f32; 3]) {
    for (c, v) in rgb.into_iter().enumerate() {
        img.set(x, y, c, v);
    }
}

/// Renders, left to right: the kernel, its reconstruction (both on one
/// symmetric diverging scale, `+-max |k|`), the error `recon - k` (diverging,
/// scaled to its own maximum: white is exact), and the histogram of
/// `log10 |weight|` per level (columns: levels, coarse to fine; rows: weight
/// magnitude, large at the top; darker = more terms). RGB, values in `[0, 1]`.
///
/// ```
/// use ifd_planar::{Decomposition, Kernel, Term, plot::render_plot};
/// let k: Kernel = "gauss:sx=2".parse()?;
/// let d = Decomposition::from_terms(vec![Term { weight: 1.0, x: 0.0, y: 0.0, sigma: 2.0 }]);
/// let img = render_plot(&k, &d);
/// assert_eq!((img.channels(), img.height()), (3, 256 + 16));
/// # Ok::<(), ifd_planar::KernelError>(())
/// ```
#[must_use]
pub fn render_plot(kernel: &Kernel, decomposition: &Decomposition) -> Image {
    let width = 4 * PANEL + 5 * GAP;
    let height = PANEL + 2 * GAP;
    let mut img = Image::new(width, height, 3).expect("the plot has a fixed non-zero size");
    img.data_mut().fill(1.0);
    let (w, h) = (kernel.width(), kernel.height());
    let (rx, ry) = (kernel.radius_x() as f64, kernel.radius_y() as f64);
    // Panel pixel -> kernel pixel (nearest), keeping the aspect ratio.
    let side = w.max(h) as f64;
    let sample = |px: usize, py: usize| -> Option<(f64, f64)> {
        let u = (px as f64 + 0.5) / PANEL as f64 * side - (side - w as f64) / 2.0;
        let v = (py as f64 + 0.5) / PANEL as f64 * side - (side - h as f64) / 2.0;
        if u < 0.0 || v < 0.0 || u >= w as f64 || v >= h as f64 {
            return None;
        }
        Some((u.floor() - rx, v.floor() - ry))
    };
    let kmax = kernel.max_abs().max(f64::MIN_POSITIVE);
    let recon: Vec<f64> = (0..w * h)
        .map(|i| decomposition.eval((i % w) as f64 - rx, (i / w) as f64 - ry))
        .collect();
    let emax = recon
        .iter()
        .zip(kernel.data())
        .fold(0.0_f64, |m, (r, k)| m.max((r - k).abs()))
        .max(f64::MIN_POSITIVE);
    let at = |data: &[f64], dx: f64, dy: f64| data[(dy + ry) as usize * w + (dx + rx) as usize];
    for py in 0..PANEL {
        for px in 0..PANEL {
            let Some((dx, dy)) = sample(px, py) else {
                continue;
            };
            let k = at(kernel.data(), dx, dy);
            let r = at(&recon, dx, dy);
            put(&mut img, GAP + px, GAP + py, diverging(k / kmax));
            put(
                &mut img,
                2 * GAP + PANEL + px,
                GAP + py,
                diverging(r / kmax),
            );
            put(
                &mut img,
                3 * GAP + 2 * PANEL + px,
                GAP + py,
                diverging((r - k) / emax),
            );
        }
    }
    // Histogram of log10 |weight| per level.
    let terms: Vec<_> = decomposition
        .terms
        .iter()
        .filter(|t| t.weight != 0.0)
        .collect();
    if terms.is_empty() {
        return img;
    }
    let smax = terms.iter().fold(0.0_f64, |m, t| m.max(t.sigma));
    let level = |sigma: f64| -> usize {
        if let Some(p) = &decomposition.dictionary {
            p.level_of(sigma) - 1
        } else {
            ((smax / sigma).log2() + 1e-6).floor().max(0.0) as usize
        }
    };
    let levels = terms.iter().map(|t| level(t.sigma)).max().unwrap_or(0) + 1;
    let levels = decomposition
        .dictionary
        .as_ref()
        .map_or(levels, |p| p.levels.max(levels));
    let logs: Vec<f64> = terms.iter().map(|t| t.weight.abs().log10()).collect();
    let lo = logs.iter().copied().fold(f64::INFINITY, f64::min).floor();
    let hi = logs
        .iter()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max)
        .ceil()
        .max(lo + 1.0);
    let mut counts = vec![0usize; levels * BINS];
    for (t, lg) in terms.iter().zip(&logs) {
        let b = (((hi - lg) / (hi - lo)) * BINS as f64)
            .floor()
            .clamp(0.0, (BINS - 1) as f64) as usize;
        counts[b * levels + level(t.sigma)] += 1;
    }
    let cmax = counts.iter().copied().max().unwrap_or(1).max(1) as f64;
    let x0 = 4 * GAP + 3 * PANEL;
    for py in 0..PANEL {
        for px in 0..PANEL {
            let l = px * levels / PANEL;
            let b = py * BINS / PANEL;
            let c = counts[b * levels + l];
            let t = if c == 0 {
                0.0
            } else {
                0.15 + 0.85 * (c as f64).ln_1p() / cmax.ln_1p()
            };
            let mut rgb = sequential(t);
            // Faint grid: level separators and one line per decade.
            let decade_row = {
                let per = PANEL as f64 / (hi - lo);
                (py as f64 % per) < 1.0
            };
            if (px * levels) % PANEL < levels || decade_row {
                rgb = rgb.map(|v| v * 0.85);
            }
            put(&mut img, x0 + px, GAP + py, rgb);
        }
    }
    img
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::{DecomposeOptions, decompose};

    #[test]
    fn plot_is_rgb_in_range() {
        let k: Kernel = "dgauss:order=xy,sigma=3".parse().unwrap();
        let d = decompose(&k, &DecomposeOptions::default(), |_, _, _| {}).unwrap();
        let img = render_plot(&k, &d);
        assert_eq!(img.channels(), 3);
        assert!(img.data().iter().all(|v| (0.0..=1.0).contains(v)));
        // The kernel panel is not blank: xy has both signs.
        let mut reds = 0;
        let mut blues = 0;
        for y in 0..img.height() {
            for x in GAP..GAP + PANEL {
                let (r, b) = (img.get(x, y, 0), img.get(x, y, 2));
                if r > b + 0.1 {
                    reds += 1;
                } else if b > r + 0.1 {
                    blues += 1;
                }
            }
        }
        assert!(reds > 100 && blues > 100);
        if let Ok(dir) = std::env::var("IFD_PLOT_DIR") {
            let bytes: Vec<u8> = img
                .data()
                .iter()
                .map(|v| (v * 255.0).round() as u8)
                .collect();
            let header = format!("P6\n{} {}\n255\n", img.width(), img.height());
            let mut out = header.into_bytes();
            out.extend(bytes);
            std::fs::write(std::path::Path::new(&dir).join("plot.ppm"), out).unwrap();
        }
    }
}
