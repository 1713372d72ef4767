//! The picture of a fit for `ifd decompose --plot` (the IFD paper's Fig. 3,
//! with what a reader needs to read it): four titled panels with axes in
//! pixels and colour bars.
//!
//! 1. **kernel**: the sampled kernel, diverging blue-white-red on `+-max |k|`;
//! 2. **sum of Gaussians**: the decomposition at the same pixels, same scale;
//! 3. **error**: `sum of Gaussians - kernel`, on its own scale `+-max |error|`
//!    (white is exact), the relative L2 error in the title;
//! 4. **abs(w) per level**: the histogram of `log10 abs(w)` of the terms per
//!    dictionary level (columns, coarse to fine; rows, weight magnitude,
//!    large at the top), darker = more terms.

use ifd_image::Image;
use ifd_planar::{Decomposition, Kernel};

use crate::draw::{
    BLACK, TEXT_HEIGHT, canvas, draw_text, draw_text_centred, hline, put, text_width, vline,
};

/// Side of each panel, px.
const PANEL: usize = 256;
/// Room left of each panel for the `y` tick labels, px.
const AXIS: usize = 64;
/// Gap right of each panel, px.
const GAP: usize = 16;
/// Top of the panels (below the titles), px.
const TOP: usize = 34;
/// Magnitude bins of the histogram.
const BINS: usize = 32;
/// Height of a colour bar, px.
const BAR: usize = 12;

/// Diverging blue-white-red map of `t` in `[-1, 1]`.
#[must_use]
pub fn diverging(t: f64) -> [f32; 3] {
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
#[must_use]
pub fn sequential(t: f64) -> [f32; 3] {
    const DARK: [f64; 3] = [0.03, 0.19, 0.42];
    let t = t.clamp(0.0, 1.0);
    std::array::from_fn(|c| ((1.0 - t) + t * DARK[c]) as f32)
}

/// Left edge of panel `i`.
fn panel_x(i: usize) -> usize {
    AXIS + i * (PANEL + AXIS + GAP)
}

/// A number short enough for a tick label.
fn label(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if (0.01..1000.0).contains(&v.abs()) {
        let s = format!("{v:.3}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        format!("{v:.1e}")
    }
}

/// A frame around panel `i`.
fn frame(img: &mut Image, i: usize) {
    let x0 = panel_x(i) - 1;
    hline(img, x0, x0 + PANEL + 1, TOP - 1, BLACK);
    hline(img, x0, x0 + PANEL + 1, TOP + PANEL, BLACK);
    vline(img, x0, TOP - 1, TOP + PANEL, BLACK);
    vline(img, x0 + PANEL + 1, TOP - 1, TOP + PANEL, BLACK);
}

/// Ticks and labels of pixel offsets `-r..=r` along both axes of panel `i`
/// (the kernel's window, `side` pixels fitted into the panel).
fn offset_axes(img: &mut Image, i: usize, (rx, ry): (f64, f64), side: f64) {
    let x0 = panel_x(i);
    let per = PANEL as f64 / side;
    let ticks = |r: f64| -> Vec<f64> { if r < 1.0 { vec![0.0] } else { vec![-r, 0.0, r] } };
    for d in ticks(rx) {
        let px = x0 + (PANEL as f64 / 2.0 + d * per) as usize;
        let px = px.min(x0 + PANEL - 1);
        vline(img, px, TOP + PANEL, TOP + PANEL + 4, BLACK);
        draw_text_centred(img, px, TOP + PANEL + 7, &label(d), BLACK);
    }
    for d in ticks(ry) {
        let py = TOP + ((PANEL as f64 / 2.0 + d * per) as usize).min(PANEL - 1);
        hline(img, x0 - 5, x0 - 1, py, BLACK);
        let t = label(d);
        draw_text(
            img,
            x0 - 8 - text_width(&t),
            py - TEXT_HEIGHT / 2,
            &t,
            BLACK,
        );
    }
    draw_text_centred(
        img,
        x0 + PANEL / 2,
        TOP + PANEL + 26,
        "x, y offset (px)",
        BLACK,
    );
}

/// A horizontal colour bar under panel `i` for `map` on `[lo, hi]`,
/// labelled at both ends and the middle, with `what` (the quantity) below.
fn colour_bar(
    img: &mut Image,
    i: usize,
    map: impl Fn(f64) -> [f32; 3],
    (lo, hi): (f64, f64),
    what: &str,
) {
    let x0 = panel_x(i);
    let y0 = TOP + PANEL + 52;
    for px in 0..PANEL {
        let t = px as f64 / (PANEL - 1) as f64;
        let rgb = map(t);
        for py in 0..BAR {
            put(img, x0 + px, y0 + py, rgb);
        }
    }
    hline(img, x0 - 1, x0 + PANEL, y0 - 1, BLACK);
    hline(img, x0 - 1, x0 + PANEL, y0 + BAR, BLACK);
    vline(img, x0 - 1, y0 - 1, y0 + BAR, BLACK);
    vline(img, x0 + PANEL, y0 - 1, y0 + BAR, BLACK);
    let ly = y0 + BAR + 4;
    draw_text(img, x0, ly, &label(lo), BLACK);
    draw_text_centred(img, x0 + PANEL / 2, ly, &label(0.5 * (lo + hi)), BLACK);
    let t = label(hi);
    draw_text(img, x0 + PANEL - text_width(&t), ly, &t, BLACK);
    draw_text_centred(img, x0 + PANEL / 2, ly + TEXT_HEIGHT + 6, what, BLACK);
}

/// Renders the four panels (see the module documentation) as an RGB image,
/// values in `[0, 1]`.
///
/// ```
/// use ifd_planar::{Decomposition, Kernel, Term};
/// let k: Kernel = "gauss:sx=2".parse()?;
/// let d = Decomposition::from_terms(vec![Term { weight: 1.0, x: 0.0, y: 0.0, sigma: 2.0 }]);
/// let img = ifd_plot::decomposition_plot(&k, &d)?;
/// assert_eq!(img.channels(), 3);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// Only if the image cannot be allocated.
pub fn decomposition_plot(
    kernel: &Kernel,
    decomposition: &Decomposition,
) -> Result<Image, ifd_image::ImageError> {
    let width = panel_x(4) - AXIS + GAP;
    let height = TOP + PANEL + 52 + BAR + 4 + 2 * TEXT_HEIGHT + 16;
    let mut img = canvas(width, height)?;
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
    let knorm = kernel.data().iter().map(|v| v * v).sum::<f64>().sqrt();
    let enorm = recon
        .iter()
        .zip(kernel.data())
        .map(|(r, k)| (r - k) * (r - k))
        .sum::<f64>()
        .sqrt();
    let at = |data: &[f64], dx: f64, dy: f64| data[(dy + ry) as usize * w + (dx + rx) as usize];
    for py in 0..PANEL {
        for px in 0..PANEL {
            let Some((dx, dy)) = sample(px, py) else {
                continue;
            };
            let k = at(kernel.data(), dx, dy);
            let r = at(&recon, dx, dy);
            put(&mut img, panel_x(0) + px, TOP + py, diverging(k / kmax));
            put(&mut img, panel_x(1) + px, TOP + py, diverging(r / kmax));
            put(
                &mut img,
                panel_x(2) + px,
                TOP + py,
                diverging((r - k) / emax),
            );
        }
    }
    let titles = [
        "kernel".to_string(),
        format!("sum of {} Gaussians", decomposition.terms.len()),
        format!(
            "error, rel. L2 {}",
            label(enorm / knorm.max(f64::MIN_POSITIVE))
        ),
        "abs(w) per level".to_string(),
    ];
    for (i, t) in titles.iter().enumerate() {
        draw_text_centred(&mut img, panel_x(i) + PANEL / 2, 10, t, BLACK);
        frame(&mut img, i);
    }
    for i in 0..3 {
        offset_axes(&mut img, i, (rx, ry), side);
    }
    let div = |t: f64| diverging(2.0 * t - 1.0);
    colour_bar(&mut img, 0, div, (-kmax, kmax), "kernel value");
    colour_bar(&mut img, 1, div, (-kmax, kmax), "kernel value");
    colour_bar(&mut img, 2, div, (-emax, emax), "error");
    weights_panel(&mut img, decomposition);
    Ok(img)
}

/// Panel 4: the histogram of `log10 abs(w)` per level, with its axes and
/// colour bar.
fn weights_panel(img: &mut Image, decomposition: &Decomposition) {
    let terms: Vec<_> = decomposition
        .terms
        .iter()
        .filter(|t| t.weight != 0.0)
        .collect();
    let x0 = panel_x(3);
    if terms.is_empty() {
        draw_text_centred(img, x0 + PANEL / 2, TOP + PANEL / 2, "no terms", BLACK);
        return;
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
    let shade = |c: f64| {
        if c <= 0.0 {
            0.0
        } else {
            0.15 + 0.85 * c.ln_1p() / cmax.ln_1p()
        }
    };
    for py in 0..PANEL {
        for px in 0..PANEL {
            let l = px * levels / PANEL;
            let b = py * BINS / PANEL;
            let mut rgb = sequential(shade(counts[b * levels + l] as f64));
            // Faint grid: level separators and one line per decade.
            let per = PANEL as f64 / (hi - lo);
            if (px * levels) % PANEL < levels || (py as f64 % per) < 1.0 {
                rgb = rgb.map(|v| v * 0.85);
            }
            put(img, x0 + px, TOP + py, rgb);
        }
    }
    // x: level numbers at column centres (1 = coarsest).
    let step = levels.div_ceil(8).max(1);
    for l in (0..levels).step_by(step) {
        let px = x0 + ((l as f64 + 0.5) * PANEL as f64 / levels as f64) as usize;
        vline(img, px, TOP + PANEL, TOP + PANEL + 4, BLACK);
        draw_text_centred(img, px, TOP + PANEL + 7, &(l + 1).to_string(), BLACK);
    }
    draw_text_centred(
        img,
        x0 + PANEL / 2,
        TOP + PANEL + 26,
        "level, coarse to fine",
        BLACK,
    );
    // y: decades of abs(w).
    let decades = (hi - lo) as usize;
    let dstep = decades.div_ceil(8).max(1);
    for d in (0..=decades).step_by(dstep) {
        let py = (TOP + (d as f64 * PANEL as f64 / (hi - lo)) as usize).min(TOP + PANEL - 1);
        hline(img, x0 - 5, x0 - 1, py, BLACK);
        let t = format!("1e{}", (hi as i64) - d as i64);
        draw_text(
            img,
            x0 - 8 - text_width(&t),
            py.saturating_sub(TEXT_HEIGHT / 2),
            &t,
            BLACK,
        );
    }
    colour_bar(
        img,
        3,
        |t| sequential(shade(t * cmax)),
        (0.0, cmax),
        "terms per bin",
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use ifd_planar::{DecomposeOptions, decompose};

    #[test]
    fn plot_is_rgb_in_range_with_both_signs_and_labels() {
        let k: Kernel = "dgauss:order=xy,sigma=3".parse().unwrap();
        let d = decompose(&k, &DecomposeOptions::default(), |_, _, _| {}).unwrap();
        let img = decomposition_plot(&k, &d).unwrap();
        assert_eq!(img.channels(), 3);
        assert!(img.data().iter().all(|v| (0.0..=1.0).contains(v)));
        // The kernel panel is not blank: xy has both signs.
        let (mut reds, mut blues) = (0, 0);
        for y in TOP..TOP + PANEL {
            for x in panel_x(0)..panel_x(0) + PANEL {
                let (r, b) = (img.get(x, y, 0), img.get(x, y, 2));
                if r > b + 0.1 {
                    reds += 1;
                } else if b > r + 0.1 {
                    blues += 1;
                }
            }
        }
        assert!(reds > 100 && blues > 100);
        // Titles and tick labels are drawn: black pixels above the panels
        // and left of the first one.
        let dark = |x0: usize, x1: usize, y0: usize, y1: usize| {
            (y0..y1)
                .flat_map(|y| (x0..x1).map(move |x| (x, y)))
                .filter(|&(x, y)| img.get(x, y, 0) < 0.2 && img.get(x, y, 2) < 0.2)
                .count()
        };
        for i in 0..4 {
            assert!(
                dark(panel_x(i), panel_x(i) + PANEL, 0, TOP - 2) > 20,
                "title {i}"
            );
        }
        assert!(dark(0, AXIS - 4, TOP, TOP + PANEL) > 20, "y ticks");
        if let Ok(dir) = std::env::var("IFD_PLOT_DIR") {
            let path = std::path::Path::new(&dir).join("decomposition_plot.png");
            ifd_image::write(&path, &img).unwrap();
        }
    }

    #[test]
    fn every_label_has_glyphs() {
        for s in [
            "kernel",
            "sum of 12 Gaussians",
            "error, rel. L2 0.01",
            "abs(w) per level",
            "x, y offset (px)",
            "level, coarse to fine",
            "kernel value",
            "terms per bin",
            "1.2e-3",
            "no terms",
        ] {
            for c in s.chars() {
                assert!(crate::draw::glyph(c).is_some(), "{c:?} in {s:?}");
            }
        }
    }
}
