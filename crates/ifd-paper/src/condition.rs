//! The condition-number study of ISD Fig. 13 (`ifd-paper isd-condition`):
//! [`condition_study`] computes the 2-norm condition number of the full ISD
//! matrix `M` (Eq. 17) for every [`Profile`], degrees `1..=L`, with per-band
//! and with shared Fibonacci directions, and [`condition_plot`] draws it.
//!
//! The plot: `x` = `L`, `y` = `cond(M)` on a log scale with a tick and a
//! label every decade, one colour per profile (legend on the right), solid
//! lines for per-band and dotted lines for shared directions. Condition
//! numbers above [`SINGULAR_COND`] (`1 / eps` of `f64`: the smallest singular
//! value is lost in rounding) or infinite ones are not meaningful numbers:
//! they are drawn on a separate row above the decades, labelled `> 1e16
//! (singular)`.

use ifd_image::Image;
use ifd_plot::draw::{
    BLACK, GREY, TEXT_HEIGHT, draw_text, draw_text_centred, hline, put, put_f, segment, text_width,
    vline,
};
use ifd_plot::profile_colour;
use ifd_plot::{
    PLOT_BOTTOM as BOTTOM, PLOT_LEFT as LEFT, PLOT_RIGHT as RIGHT, PLOT_SIZE, PLOT_TOP as TOP,
};
use ifd_sphere::Result;
use ifd_sphere::{Chooser, DirectionSet, Sharing, condition_number};
use ifd_sphere::{Profile, isd_matrix};

/// Gap between the top decade and the singular row, in pixels.
const SINGULAR_GAP: usize = 34;

/// Condition numbers at or above this (about `1 / f64::EPSILON`) count as singular.
pub const SINGULAR_COND: f64 = 1e16;

/// One curve of Fig. 13: `cond[i]` is the condition number of `M` at `L = i + 1`.
#[derive(Clone, Debug, PartialEq)]
pub struct ConditionSeries {
    /// The mother functions.
    pub profile: Profile,
    /// Per-band or shared directions.
    pub sharing: Sharing,
    /// Condition numbers for `L = 1, 2, ...` (infinite when singular).
    pub cond: Vec<f64>,
}

/// Whether a condition number is beyond what `f64` can resolve.
#[must_use]
pub fn is_singular(cond: f64) -> bool {
    !cond.is_finite() || cond >= SINGULAR_COND
}

/// Computes Fig. 13: every profile, per-band and shared Fibonacci directions,
/// `L = 1..=l_max`.
///
/// # Errors
/// [`ifd_sphere::SphereError::IsdTooLarge`] above [`ifd_sphere::MAX_ISD_DEGREE`].
pub fn condition_study(l_max: usize) -> Result<Vec<ConditionSeries>> {
    ifd_sphere::check_isd_degree(l_max)?;
    let mut out = Vec::new();
    for profile in Profile::ALL {
        for sharing in [Sharing::PerBand, Sharing::Shared] {
            let mut cond = Vec::with_capacity(l_max);
            for l in 1..=l_max {
                let dirs = DirectionSet::new(l, sharing, Chooser::Fibonacci)?;
                let (m, _) = isd_matrix(profile, &dirs)?;
                cond.push(condition_number(&m));
            }
            out.push(ConditionSeries {
                profile,
                sharing,
                cond,
            });
        }
    }
    Ok(out)
}

/// Draws Fig. 13 (see the module docs) as a white RGB image of [`PLOT_SIZE`].
///
/// ```
/// use ifd_paper::condition::{ConditionSeries, condition_plot};
/// use ifd_sphere::{Profile, Sharing};
/// let s = ConditionSeries { profile: Profile::Gauss, sharing: Sharing::Shared,
///                           cond: vec![2.0, 40.0, 1e9, f64::INFINITY] };
/// let img = condition_plot(&[s])?;
/// assert_eq!((img.width(), img.height(), img.channels()), (1000, 640, 3));
/// # Ok::<(), ifd_image::ImageError>(())
/// ```
///
/// # Errors
/// Only if the image cannot be allocated.
pub fn condition_plot(
    series: &[ConditionSeries],
) -> std::result::Result<Image, ifd_image::ImageError> {
    let (w, h) = PLOT_SIZE;
    let mut img = Image::from_vec(w, h, 3, vec![1.0; w * h * 3])?;
    let l_max = series
        .iter()
        .map(|s| s.cond.len())
        .max()
        .unwrap_or(1)
        .max(2);
    let any_singular = series.iter().flat_map(|s| &s.cond).any(|&c| is_singular(c));
    // decades shown: 10^0 .. 10^dmax, dmax = ceil(log10 of the largest regular value)
    let dmax = series
        .iter()
        .flat_map(|s| &s.cond)
        .filter(|&&c| !is_singular(c) && c > 0.0)
        .fold(1.0f64, |a, &c| a.max(c.log10()))
        .ceil()
        .clamp(1.0, 16.0) as i32;
    let (x0, x1) = (LEFT as f64, (w - RIGHT) as f64);
    let y_bottom = (h - BOTTOM) as f64;
    let y_top = (TOP + if any_singular { SINGULAR_GAP } else { 0 }) as f64;
    let y_singular = TOP as f64;
    let px = |l: f64| x0 + (l - 1.0) / (l_max - 1) as f64 * (x1 - x0);
    let py = |c: f64| {
        if is_singular(c) {
            y_singular
        } else {
            let d = c.max(1.0).log10().min(f64::from(dmax));
            y_bottom - d / f64::from(dmax) * (y_bottom - y_top)
        }
    };
    // decade grid lines, ticks and labels
    for d in 0..=dmax {
        let y = py(10f64.powi(d)).round() as usize;
        hline(
            &mut img,
            LEFT,
            w - RIGHT,
            y,
            if d == 0 { BLACK } else { GREY },
        );
        hline(&mut img, LEFT - 6, LEFT, y, BLACK);
        let label = format!("1e{d}");
        let tw = text_width(&label);
        draw_text(
            &mut img,
            LEFT - 10 - tw,
            y - TEXT_HEIGHT / 2 + 2,
            &label,
            BLACK,
        );
    }
    if any_singular {
        let y = y_singular.round() as usize;
        for x in (LEFT..w - RIGHT).filter(|x| x % 8 < 4) {
            put(&mut img, x, y, BLACK);
        }
        draw_text(
            &mut img,
            LEFT + 6,
            y - TEXT_HEIGHT - 3,
            &format!("> 1e{} (singular)", SINGULAR_COND.log10().round()),
            BLACK,
        );
    }
    // x axis: a tick at every L, a label every `step`
    let step = [1, 2, 5, 10, 20, 50]
        .into_iter()
        .find(|s| l_max / s <= 20)
        .unwrap_or(100);
    vline(&mut img, LEFT, y_top as usize, h - BOTTOM, BLACK);
    for l in 1..=l_max {
        let x = px(l as f64).round() as usize;
        vline(&mut img, x, h - BOTTOM, h - BOTTOM + 5, BLACK);
        if l == 1 || l % step == 0 {
            let label = l.to_string();
            draw_text_centred(&mut img, x, h - BOTTOM + 10, &label, BLACK);
        }
    }
    let xl = "L (maximum SH degree)";
    draw_text(
        &mut img,
        (LEFT + w - RIGHT - text_width(xl)) / 2,
        h - BOTTOM + 36,
        xl,
        BLACK,
    );
    draw_text(&mut img, 10, 10, "cond(M), log scale", BLACK);
    // curves
    for s in series {
        let col = profile_colour(s.profile);
        for (i, pair) in s.cond.windows(2).enumerate() {
            let (xa, ya) = (px((i + 1) as f64), py(pair[0]));
            let (xb, yb) = (px((i + 2) as f64), py(pair[1]));
            segment(
                &mut img,
                (xa, ya),
                (xb, yb),
                col,
                s.sharing == Sharing::Shared,
            );
        }
        for (i, &c) in s.cond.iter().enumerate() {
            let (x, y) = (px((i + 1) as f64), py(c));
            for dy in -1..=1 {
                for dx in -1..=1 {
                    put_f(&mut img, x + f64::from(dx), y + f64::from(dy), col);
                }
            }
        }
    }
    // legend
    let lx = w - RIGHT + 20;
    let mut ly = TOP + 10;
    draw_text(&mut img, lx, ly, "profile", BLACK);
    ly += 26;
    for p in Profile::ALL {
        let y = ly + TEXT_HEIGHT / 2 - 2;
        for t in 0..3 {
            hline(&mut img, lx, lx + 36, y + t, profile_colour(p));
        }
        draw_text(&mut img, lx + 46, ly, p.name(), BLACK);
        ly += 24;
    }
    ly += 14;
    for (shared, name) in [(false, "per-band dirs"), (true, "shared dirs")] {
        let y = (ly + TEXT_HEIGHT / 2 - 2) as f64;
        segment(
            &mut img,
            (lx as f64, y),
            (lx as f64 + 36.0, y),
            BLACK,
            shared,
        );
        draw_text(&mut img, lx + 46, ly, name, BLACK);
        ly += 24;
    }
    Ok(img)
}

#[cfg(test)]
mod tests {
    use super::*;
    use ifd_plot::draw::glyph;

    fn dark_pixels(img: &Image, x0: usize, x1: usize, y0: usize, y1: usize) -> usize {
        (y0..y1)
            .flat_map(|y| (x0..x1).map(move |x| (x, y)))
            .filter(|&(x, y)| img.get(x, y, 0) < 0.5)
            .count()
    }

    #[test]
    fn every_label_of_the_plot_has_glyphs() {
        let mut labels: Vec<String> = (0..=16).map(|d| format!("1e{d}")).collect();
        labels.extend((1..=100).map(|l| l.to_string()));
        labels.extend(Profile::ALL.iter().map(|p| p.name().to_string()));
        labels.extend(
            [
                "> 1e16 (singular)",
                "L (maximum SH degree)",
                "cond(M), log scale",
                "profile",
                "per-band dirs",
                "shared dirs",
            ]
            .map(String::from),
        );
        for s in &labels {
            for c in s.chars() {
                assert!(glyph(c).is_some(), "no glyph for {c:?} in {s:?}");
            }
        }
    }

    #[test]
    fn singular_values_go_to_their_own_row() {
        let regular = ConditionSeries {
            profile: Profile::Gauss,
            sharing: Sharing::PerBand,
            cond: vec![1.0, 10.0, 100.0],
        };
        let a = condition_plot(std::slice::from_ref(&regular)).unwrap();
        let mut sing = regular.clone();
        sing.cond[2] = f64::INFINITY;
        let b = condition_plot(&[regular, sing]).unwrap();
        let (w, _) = PLOT_SIZE;
        // the label of the singular row only exists in b
        let band =
            |img: &Image| dark_pixels(img, LEFT + 1, w - RIGHT, TOP - TEXT_HEIGHT - 4, TOP - 2);
        assert_eq!(band(&a), 0);
        assert!(band(&b) > 100, "{}", band(&b));
        // the point at L = 3 is drawn on the singular row in green
        let x = w - RIGHT;
        let green = (TOP - 1..=TOP + 1)
            .any(|y| (x - 1..=x + 1).any(|x| b.get(x, y, 1) > 0.5 && b.get(x, y, 0) < 0.5));
        assert!(green);
        assert!(is_singular(2e16) && is_singular(f64::NAN) && !is_singular(9e15));
    }
}
