//! Keeping a [`Smoother`] in step with an image being edited: after a change
//! confined to a rectangle, [`Smoother::refresh_region`] recomputes the
//! affected samples of the scale stack (direct separable Gaussian
//! correlation, [`ScaleStack::refresh_region`]) and the orientation field
//! where the Hessian tensor can have changed, so that later dabs smooth the
//! already-smoothed image. The result equals a [`Smoother`] rebuilt from the
//! edited image up to float rounding (the tests check it).
//!
//! [`ScaleStack::refresh_region`]: ifd_planar::ScaleStack::refresh_region

use ifd_image::Image;
use ifd_planar::{Border, FixedTap, PixelRect, RefreshReport};
use rayon::prelude::*;

use super::Smoother;
use super::blur::{blur_kernel, reflect};
use crate::error::SmoothError;
use crate::hessian::HessianBank;
use crate::orientation::{Orientation, tensor};

/// What [`Smoother::refresh_region`] recomputed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RegionRefresh {
    /// Scale-stack samples.
    pub stack: RefreshReport,
    /// Orientation-field pixels recomputed.
    pub field_pixels: usize,
    /// The rectangle of the orientation field recomputed (`None`: none).
    pub field_rect: Option<PixelRect>,
}

/// `[a - r, b + r]` clipped to `[0, n - 1]`; the whole axis for wrap borders
/// when the dilation crosses an edge (the change is seen on the other side).
fn dilate_axis(a: usize, b: usize, r: usize, n: usize, border: Border) -> (usize, usize) {
    let crosses = a < r || b + r > n - 1;
    if matches!(border, Border::Wrap) && crosses {
        return (0, n - 1);
    }
    (a.saturating_sub(r), (b + r).min(n - 1))
}

impl Smoother {
    /// Brings the smoother up to date with `image` (its image after a change
    /// confined to `rect`): the scale stack where it depends on `rect`, and
    /// the orientation field where the Hessian tensor does.
    ///
    /// # Errors
    /// [`SmoothError::BadImage`] for another shape or NaN pixels in `rect`,
    /// [`SmoothError::Filter`] for a rectangle outside the image.
    pub fn refresh_region(
        &mut self,
        image: &Image,
        rect: PixelRect,
        hbank: &HessianBank,
    ) -> Result<RegionRefresh, SmoothError> {
        let (w, h) = (self.width, self.height);
        if (image.width(), image.height(), image.channels()) != (w, h, self.channels) {
            return Err(SmoothError::BadImage(format!(
                "image is {}x{}x{}, the smoother's {w}x{h}x{}",
                image.width(),
                image.height(),
                image.channels(),
                self.channels
            )));
        }
        let stack = self.stack.refresh_region(image, rect)?;
        if let Some((_, copy)) = &mut self.direct {
            // The directly evaluated filters read the image itself.
            let c = self.channels;
            let (src, dst) = (image.data(), copy.data_mut());
            for y in rect.y0..(rect.y0 + rect.height).min(h) {
                let o = (y * w + rect.x0) * c;
                let n = rect.width.min(w.saturating_sub(rect.x0)) * c;
                dst[o..o + n].copy_from_slice(&src[o..o + n]);
            }
        }
        if rect.width == 0 || rect.height == 0 {
            return Ok(RegionRefresh {
                stack,
                field_pixels: 0,
                field_rect: None,
            });
        }
        // Reach of the Hessian filters: atom offset plus 6 atom sigmas (the
        // stack's own 5-sigma support and the bilinear lookup), in pixels.
        let hs = self.opts.hessian_sigma();
        let s = hs / hbank.sigma0;
        let reach_h = hbank
            .xx
            .terms
            .iter()
            .chain(&hbank.xy.terms)
            .map(|t| s * (t.x.hypot(t.y) + 6.0 * t.sigma))
            .fold(0.0, f64::max)
            .ceil() as usize
            + 2;
        let rho = self.opts.tensor_sigma();
        let rb = super::blur_radius(rho);
        let border = self.opts.border;
        let (rx0, rx1) = (rect.x0, rect.x0 + rect.width - 1);
        let (ry0, ry1) = (rect.y0, rect.y0 + rect.height - 1);
        // Field pixels whose tensor neighbourhood saw a changed Hessian.
        let (fx0, fx1) = dilate_axis(rx0, rx1, reach_h + rb, w, border);
        let (fy0, fy1) = dilate_axis(ry0, ry1, reach_h + rb, h, border);
        // Hessians needed by their blur.
        let (tx0, tx1) = (fx0.saturating_sub(rb), (fx1 + rb).min(w - 1));
        let (ty0, ty1) = (fy0.saturating_sub(rb), (fy1 + rb).min(h - 1));
        let (tw, th) = (tx1 - tx0 + 1, ty1 - ty0 + 1);
        // The Hessian over the window: the three filters of
        // `HessianFilters::at` (xx, xy, and xx rotated by 90 degrees) as
        // fixed taps at scale s, each evaluated once over the rectangle.
        let s32 = (hs / hbank.sigma0) as f32;
        let taps = |d: &ifd_planar::Decomposition, theta: f32| -> Vec<FixedTap> {
            let (sin, cos) = theta.to_radians().sin_cos();
            d.terms
                .iter()
                .map(|t| {
                    let (cx, cy) = (t.x as f32, t.y as f32);
                    FixedTap {
                        dx: s32 * (cos * cx + sin * cy),
                        dy: s32 * (-sin * cx + cos * cy),
                        sigma: f64::from(s32) * t.sigma,
                        weight: t.weight as f32,
                    }
                })
                .collect()
        };
        let window = PixelRect {
            x0: tx0,
            y0: ty0,
            width: tw,
            height: th,
        };
        let c = self.channels;
        let s2 = f64::from(s32) * f64::from(s32);
        let mut hplanes: Vec<Vec<f64>> = Vec::with_capacity(3);
        for (d, theta) in [(&hbank.xx, 0.0), (&hbank.xy, 0.0), (&hbank.xx, 90.0)] {
            let v = self.stack.correlate_region(&taps(d, theta), window)?;
            hplanes.push(
                v.chunks_exact(c)
                    .map(|px| px.iter().map(|&a| f64::from(a)).sum::<f64>() / c as f64 / s2)
                    .collect(),
            );
        }
        // Tensor planes over the window, as in `with_banks` (Hessian rounded
        // to f32 first).
        let mut t: [Vec<f32>; 3] = [vec![0.0; tw * th], vec![0.0; tw * th], vec![0.0; tw * th]];
        for q in 0..tw * th {
            let hv = [hplanes[0][q], hplanes[1][q], hplanes[2][q]].map(|v| f64::from(v as f32));
            let tv = tensor(hv);
            for k in 0..3 {
                t[k][q] = tv[k] as f32;
            }
        }
        // Separable blur of the window (same kernel and border as `gaussian_blur`).
        let (fw, fh) = (fx1 - fx0 + 1, fy1 - fy0 + 1);
        let blurred: [Vec<f32>; 3] = if rb == 0 {
            t.map(|p| {
                (0..fw * fh)
                    .map(|i| p[(fy0 - ty0 + i / fw) * tw + fx0 - tx0 + i % fw])
                    .collect()
            })
        } else {
            let r = rb as i64;
            let k = blur_kernel(rho, r);
            t.map(|p| {
                // Horizontal pass for every window row, at the field's columns.
                let mut tmp = vec![0.0f32; th * fw];
                tmp.par_chunks_mut(fw).enumerate().for_each(|(j, row)| {
                    let src = &p[j * tw..(j + 1) * tw];
                    for (i, o) in row.iter_mut().enumerate() {
                        let x = (fx0 + i) as i64;
                        *o = k
                            .iter()
                            .enumerate()
                            .map(|(d, kv)| kv * src[reflect(x + d as i64 - r, w) - tx0])
                            .sum();
                    }
                });
                let mut out = vec![0.0f32; fw * fh];
                out.par_chunks_mut(fw).enumerate().for_each(|(j, row)| {
                    let y = (fy0 + j) as i64;
                    for (i, o) in row.iter_mut().enumerate() {
                        *o = k
                            .iter()
                            .enumerate()
                            .map(|(d, kv)| kv * tmp[(reflect(y + d as i64 - r, h) - ty0) * fw + i])
                            .sum();
                    }
                });
                out
            })
        };
        let aniso = self.opts.aniso;
        for j in 0..fh {
            let y = fy0 + j;
            let row = &mut self.field[y * w + fx0..y * w + fx0 + fw];
            for (i, o) in row.iter_mut().enumerate() {
                let q = j * fw + i;
                *o = Orientation::from_tensor(
                    [
                        f64::from(blurred[0][q]),
                        f64::from(blurred[1][q]),
                        f64::from(blurred[2][q]),
                    ],
                    hs,
                    &aniso,
                );
            }
        }
        Ok(RegionRefresh {
            stack,
            field_pixels: fw * fh,
            field_rect: Some(PixelRect {
                x0: fx0,
                y0: fy0,
                width: fw,
                height: fh,
            }),
        })
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::bank::{AspectBank, BankOptions};
    use crate::smooth::{Dab, Mode, SmoothOptions};

    fn camera() -> Image {
        let img = ifd_image::read(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../testdata/camera.png"
        ))
        .expect("bundled image");
        // A 160x128 crop keeps the test quick.
        let data = (0..160 * 128)
            .map(|i| img.get(200 + i % 160, 150 + i / 160, 0))
            .collect();
        Image::from_vec(160, 128, 1, data).expect("crop")
    }

    /// Refreshing after dabs gives the smoother a fresh build would give:
    /// same stack samples, same orientations (up to rounding), and the same
    /// result for a further dab.
    #[test]
    fn refresh_matches_rebuild() {
        let bank = Arc::new(
            AspectBank::build(
                BankOptions {
                    steps_per_octave: 1,
                    tol: 0.03,
                    ..BankOptions::default()
                },
                |_, _| {},
            )
            .expect("bank"),
        );
        let hbank = HessianBank::new(0.01).expect("hessian bank");
        let opts = SmoothOptions::default();
        let mut img = camera();
        let mut sm = Smoother::with_banks(&img, &opts, bank.clone(), &hbank).expect("smoother");
        let mut rect: Option<PixelRect> = None;
        for (x, y) in [(20.0, 30.0), (60.0, 40.0), (150.0, 120.0)] {
            let dab = Dab {
                x,
                y,
                radius: 14.0,
                falloff: 0.5,
                strength: 1.0,
            };
            let r = sm
                .apply_dab(&dab, Mode::PerPixel, &mut img)
                .expect("dab")
                .expect("inside");
            rect = Some(rect.map_or(r, |a| a.union(r)));
        }
        let rect = rect.expect("dabs applied");
        let stale: Vec<Orientation> = sm.orientation_field().to_vec();
        let report = sm.refresh_region(&img, rect, &hbank).expect("refresh");
        assert!(report.field_pixels > 0);
        let fresh = Smoother::with_banks(&img, &opts, bank, &hbank).expect("smoother");
        let aspect_diff = |a: &[Orientation], b: &[Orientation]| {
            a.iter()
                .zip(b)
                .map(|(p, q)| (p.aspect - q.aspect).abs())
                .fold(0.0f32, f32::max)
        };
        let changed = aspect_diff(&stale, fresh.orientation_field());
        let left = aspect_diff(sm.orientation_field(), fresh.orientation_field());
        assert!(changed > 0.1, "the dabs must change the field ({changed})");
        assert!(left < 1e-3, "refreshed field differs by {left} in aspect");
        let dab = Dab {
            x: 55.0,
            y: 35.0,
            radius: 20.0,
            falloff: 0.3,
            strength: 1.0,
        };
        let mut a = img.clone();
        let mut b = img.clone();
        sm.apply_dab(&dab, Mode::PerPixel, &mut a).expect("dab");
        fresh.apply_dab(&dab, Mode::PerPixel, &mut b).expect("dab");
        let d = a
            .data()
            .iter()
            .zip(b.data())
            .map(|(p, q)| (p - q).abs())
            .fold(0.0f32, f32::max);
        assert!(d < 1e-4, "dab after refresh differs by {d}");
    }
}
