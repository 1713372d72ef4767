//! Line plots with a logarithmic `y` axis ([`log_line_plot`]: convergence
//! and timing studies) and the colour of each ISD profile's curves.

use ifd_image::Image;
use ifd_sphere::Profile;

use crate::draw::{
    BLACK, GREY, TEXT_HEIGHT, draw_text, draw_text_centred, hline, put_f, segment, text_width,
    vline,
};

/// The plots' errors: only allocation can fail.
pub type Result<T> = std::result::Result<T, ifd_image::ImageError>;

/// Colour of a profile's curves.
#[must_use]
pub fn profile_colour(p: Profile) -> [f32; 3] {
    match p {
        Profile::Zonal => [0.0, 0.0, 0.0],
        Profile::Legendre => [0.1, 0.3, 0.9],
        Profile::Phong => [0.9, 0.1, 0.1],
        Profile::Gauss => [0.1, 0.65, 0.2],
        Profile::Vmf => [1.0, 0.55, 0.0],
        Profile::Hybrid => [0.6, 0.2, 0.8],
    }
}

/// Plot size in pixels.
pub const PLOT_SIZE: (usize, usize) = (1000, 640);
/// Left margin (the `y` labels) in pixels.
pub const LEFT: usize = 90;
/// Right margin (the legend) in pixels.
pub const RIGHT: usize = 250;
/// Top margin (the `y` axis title) in pixels.
pub const TOP: usize = 60;
/// Bottom margin (the `x` labels and title) in pixels.
pub const BOTTOM: usize = 70;

/// One curve of [`log_line_plot`].
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// Legend text.
    pub name: String,
    /// Colour (linear RGB in `[0, 1]`).
    pub colour: [f32; 3],
    /// Dotted instead of solid.
    pub dotted: bool,
    /// `(x, y)` points; `y <= 0` or non-finite points are skipped.
    pub points: Vec<(f64, f64)>,
}

/// A line plot with a linear `x` axis and a log-scale `y` axis (a labelled
/// grid line every decade), one curve per series and a legend on the right,
/// with the axes of the other plots.
///
/// ```
/// use ifd_plot::{Series, log_line_plot};
/// let s = Series { name: "a".into(), colour: [1.0, 0.0, 0.0], dotted: false,
///                  points: vec![(1.0, 1.0), (2.0, 0.1), (3.0, 0.01)] };
/// let img = log_line_plot(&[s], "L", "error")?;
/// assert_eq!(img.channels(), 3);
/// # Ok::<(), ifd_image::ImageError>(())
/// ```
///
/// # Errors
/// Only if the image cannot be allocated.
pub fn log_line_plot(series: &[Series], x_label: &str, y_label: &str) -> Result<Image> {
    let (w, h) = PLOT_SIZE;
    let mut img = Image::from_vec(w, h, 3, vec![1.0; w * h * 3])?;
    let good = |&(x, y): &(f64, f64)| x.is_finite() && y.is_finite() && y > 0.0;
    let pts = || {
        series
            .iter()
            .flat_map(|s| s.points.iter().copied().filter(good))
    };
    let (xmin, xmax) = pts().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), (x, _)| {
        (a.min(x), b.max(x))
    });
    let (xmin, xmax) = if xmin < xmax {
        (xmin, xmax)
    } else if xmin.is_finite() {
        (xmin - 1.0, xmin + 1.0)
    } else {
        (0.0, 1.0)
    };
    let (lo, hi) = pts().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), (_, y)| {
        (a.min(y.log10()), b.max(y.log10()))
    });
    let (dlo, dhi) = if lo.is_finite() {
        (
            lo.floor() as i32,
            (hi.ceil() as i32).max(lo.floor() as i32 + 1),
        )
    } else {
        (0, 1)
    };
    let (x0, x1) = (LEFT as f64, (w - RIGHT) as f64);
    let (yb, yt) = ((h - BOTTOM) as f64, TOP as f64);
    let px = |x: f64| x0 + (x - xmin) / (xmax - xmin) * (x1 - x0);
    let py = |y: f64| yb - (y.log10() - f64::from(dlo)) / f64::from(dhi - dlo) * (yb - yt);
    for d in dlo..=dhi {
        let y = py(10f64.powi(d)).round() as usize;
        hline(
            &mut img,
            LEFT,
            w - RIGHT,
            y,
            if d == dlo { BLACK } else { GREY },
        );
        hline(&mut img, LEFT - 6, LEFT, y, BLACK);
        let label = format!("1e{d}");
        draw_text(
            &mut img,
            LEFT - 10 - text_width(&label),
            y - TEXT_HEIGHT / 2 + 2,
            &label,
            BLACK,
        );
    }
    vline(&mut img, LEFT, TOP, h - BOTTOM, BLACK);
    let span = xmax - xmin;
    let step = [1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0]
        .into_iter()
        .find(|s| span / s <= 12.0)
        .unwrap_or(span / 10.0);
    let mut t = (xmin / step).ceil() * step;
    while t <= xmax + 1e-9 {
        let x = px(t).round() as usize;
        vline(&mut img, x, h - BOTTOM, h - BOTTOM + 5, BLACK);
        let label = format!("{t}");
        draw_text_centred(&mut img, x, h - BOTTOM + 10, &label, BLACK);
        t += step;
    }
    draw_text(
        &mut img,
        (LEFT + w - RIGHT - text_width(x_label)) / 2,
        h - BOTTOM + 36,
        x_label,
        BLACK,
    );
    draw_text(&mut img, 10, 10, y_label, BLACK);
    for s in series {
        let p: Vec<(f64, f64)> = s.points.iter().copied().filter(good).collect();
        for pair in p.windows(2) {
            let (a, b) = (pair[0], pair[1]);
            segment(
                &mut img,
                (px(a.0), py(a.1)),
                (px(b.0), py(b.1)),
                s.colour,
                s.dotted,
            );
        }
        for &(x, y) in &p {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    put_f(
                        &mut img,
                        px(x) + f64::from(dx),
                        py(y) + f64::from(dy),
                        s.colour,
                    );
                }
            }
        }
    }
    let lx = w - RIGHT + 20;
    let mut ly = TOP + 10;
    for s in series {
        let y = (ly + TEXT_HEIGHT / 2 - 2) as f64;
        segment(
            &mut img,
            (lx as f64, y),
            (lx as f64 + 36.0, y),
            s.colour,
            s.dotted,
        );
        draw_text(&mut img, lx + 46, ly, &s.name, BLACK);
        ly += 24;
    }
    Ok(img)
}
