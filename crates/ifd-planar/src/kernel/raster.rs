//! Rasterising a [`KernelSpec`]: its grid radius and its samples, point
//! samples or pixel averages (supersampled), on the pixel grid or finer.

use super::{DerivOrder, Kernel, KernelError, KernelSpec, MAX_RADIUS, SUPERSAMPLE, Sampling};

/// `(u, v) = R_{-theta} (x, y)`: offsets in the filter's own (unrotated) frame.
pub(super) fn to_local(x: f64, y: f64, cos: f64, sin: f64) -> (f64, f64) {
    (cos * x - sin * y, sin * x + cos * y)
}

impl KernelSpec {
    /// The grid half-size `R` this spec samples on, before the size check.
    pub(super) fn radius_f(&self) -> f64 {
        let given = match self {
            Self::Gauss { radius, .. }
            | Self::DGauss { radius, .. }
            | Self::Log { radius, .. }
            | Self::Gabor { radius, .. }
            | Self::Box { radius, .. }
            | Self::Disk { radius, .. }
            | Self::Line { radius, .. } => *radius,
        };
        if let Some(r) = given {
            return r as f64;
        }
        let rect = |w: f64, h: f64, theta: f64| {
            let (s, c) = theta.to_radians().sin_cos();
            let ex = 0.5 * (c.abs() * w + s.abs() * h);
            let ey = 0.5 * (s.abs() * w + c.abs() * h);
            (ex.max(ey) - 0.5).max(0.0).ceil()
        };
        match *self {
            Self::Gauss { sx, sy, .. } => (4.0 * sx.max(sy)).ceil(),
            Self::DGauss { sigma, .. } | Self::Log { sigma, .. } | Self::Gabor { sigma, .. } => {
                (4.0 * sigma).ceil()
            }
            Self::Box { w, h, theta, .. } => rect(w, h, theta),
            Self::Line {
                len, width, theta, ..
            } => rect(len, width, theta),
            Self::Disk { r, .. } => (r - 0.5).max(0.0).ceil(),
        }
    }

    pub(super) fn check_size(&self) -> Result<(), KernelError> {
        let r = self.radius_f();
        if r > MAX_RADIUS as f64 {
            return Err(KernelError::TooLarge { radius: r });
        }
        Ok(())
    }

    /// How [`KernelSpec::to_kernel`] samples the filter: pixel averages for
    /// the hard-edged `box`, `line` and `disk`, pixel-centre values otherwise.
    #[must_use]
    pub fn sampling(&self) -> Sampling {
        match self {
            Self::Box { .. } | Self::Line { .. } | Self::Disk { .. } => Sampling::Area,
            _ => Sampling::Point,
        }
    }

    /// The grid half-size `R`: the kernel is `(2R+1) x (2R+1)`.
    #[must_use]
    pub fn radius(&self) -> usize {
        self.radius_f().min(MAX_RADIUS as f64) as usize
    }

    /// Samples the filter.
    ///
    /// # Errors
    /// [`KernelError::AllZero`] when the sampled filter vanishes (e.g. a tiny
    /// grid for a Gabor filter), [`KernelError::TooLarge`] for `R > MAX_RADIUS`.
    pub fn to_kernel(&self) -> Result<Kernel, KernelError> {
        let (k, _) = self.sample(1)?;
        Ok(k)
    }

    /// The same filter over the same extent, sampled `q` times more finely
    /// (spacing `1/q` px: a `(2 R q + 1)^2` grid), each fine sample taken as
    /// [`KernelSpec::to_kernel`] takes a pixel's (the value at the point, or
    /// for hard-edged specs the average over the unit pixel centred there),
    /// with the pixel grid's normalisation: a fit to it constrains the
    /// continuous filter between pixel centres too (`decompose_oversampled`).
    ///
    /// ```
    /// use ifd_planar::KernelSpec;
    /// let spec: KernelSpec = "gauss:sx=3,sy=1".parse()?;
    /// let (coarse, fine) = (spec.to_kernel()?, spec.to_kernel_fine(2)?);
    /// assert_eq!((coarse.width(), fine.width()), (25, 49));
    /// // Every other fine sample is a pixel-grid sample.
    /// assert!((fine.get(4, 2) - coarse.get(2, 1)).abs() < 1e-15);
    /// # Ok::<(), ifd_planar::KernelError>(())
    /// ```
    ///
    /// # Errors
    /// As [`KernelSpec::to_kernel`], and [`KernelError::TooLarge`] for `q`
    /// outside `1..=8` or a fine grid past `MAX_RADIUS`.
    pub fn to_kernel_fine(&self, q: usize) -> Result<Kernel, KernelError> {
        if !(1..=8).contains(&q) {
            return Err(KernelError::TooLarge {
                radius: self.radius_f() * q as f64,
            });
        }
        let (_, norm) = self.sample(1)?;
        let (k, _) = self.sample_scaled(q, Some(norm))?;
        Ok(k)
    }

    /// [`Self::sample_scaled`] at `q` with its own normalisation.
    pub(super) fn sample(&self, q: usize) -> Result<(Kernel, f64), KernelError> {
        self.sample_scaled(q, None)
    }

    /// Samples on the grid of spacing `1/q` px; normalises by `norm` when
    /// given, else (for normalised specs) by the grid's own sum. Returns the
    /// kernel and the factor applied.
    pub(super) fn sample_scaled(
        &self,
        q: usize,
        norm: Option<f64>,
    ) -> Result<(Kernel, f64), KernelError> {
        self.check_size()?;
        let r = self.radius() * q;
        if r > MAX_RADIUS * 2 {
            return Err(KernelError::TooLarge { radius: r as f64 });
        }
        let n = 2 * r + 1;
        let rf = r as f64;
        let qf = q as f64;
        let mut data = vec![0.0; n * n];
        let pixel = |f: &dyn Fn(f64, f64) -> f64, data: &mut Vec<f64>| {
            for row in 0..n {
                for col in 0..n {
                    data[row * n + col] = f((col as f64 - rf) / qf, (row as f64 - rf) / qf);
                }
            }
        };
        // Hard-edged shapes: the fraction of each pixel inside, from
        // SUPERSAMPLE^2 points. `sdf` (a signed distance, negative inside)
        // skips pixels whose whole square lies inside or outside (the
        // centre farther from the edge than the half-diagonal): their points
        // would all agree, so the result is the same, in time proportional
        // to the edge's length instead of the area (a disk of radius 2000 in
        // a fraction of a second instead of minutes).
        // (each sample covers a unit pixel, whatever the grid spacing `1/q`)
        let half_diagonal = std::f64::consts::FRAC_1_SQRT_2;
        let area = |inside: &dyn Fn(f64, f64) -> bool,
                    sdf: &dyn Fn(f64, f64) -> f64,
                    data: &mut Vec<f64>| {
            let ss = SUPERSAMPLE as f64;
            for row in 0..n {
                for col in 0..n {
                    let (cx, cy) = ((col as f64 - rf) / qf, (row as f64 - rf) / qf);
                    let d = sdf(cx, cy);
                    if d.abs() > half_diagonal * (1.0 + 1e-9) + 1e-12 {
                        data[row * n + col] = if d < 0.0 { 1.0 } else { 0.0 };
                        continue;
                    }
                    let mut count = 0usize;
                    for sy in 0..SUPERSAMPLE {
                        for sx in 0..SUPERSAMPLE {
                            let x = cx - 0.5 + (sx as f64 + 0.5) / ss;
                            let y = cy - 0.5 + (sy as f64 + 0.5) / ss;
                            if inside(x, y) {
                                count += 1;
                            }
                        }
                    }
                    data[row * n + col] = count as f64 / (ss * ss);
                }
            }
        };
        let mut normalise = false;
        match *self {
            Self::Gauss { sx, sy, theta, .. } => {
                let (s, c) = theta.to_radians().sin_cos();
                pixel(
                    &|x, y| {
                        let (u, v) = to_local(x, y, c, s);
                        (-0.5 * ((u / sx).powi(2) + (v / sy).powi(2))).exp()
                    },
                    &mut data,
                );
                normalise = true;
            }
            Self::DGauss {
                order,
                sigma,
                theta,
                ..
            } => {
                let (s, c) = theta.to_radians().sin_cos();
                let s2 = sigma * sigma;
                pixel(
                    &|x, y| {
                        let (u, v) = to_local(x, y, c, s);
                        let g = (-(u * u + v * v) / (2.0 * s2)).exp()
                            / (2.0 * std::f64::consts::PI * s2);
                        match order {
                            DerivOrder::Xx => g * (u * u / (s2 * s2) - 1.0 / s2),
                            DerivOrder::Xy => g * u * v / (s2 * s2),
                            DerivOrder::Yy => g * (v * v / (s2 * s2) - 1.0 / s2),
                        }
                    },
                    &mut data,
                );
            }
            Self::Log { sigma, .. } => {
                let s2 = sigma * sigma;
                pixel(
                    &|x, y| {
                        let q = x * x + y * y;
                        let g = (-q / (2.0 * s2)).exp() / (2.0 * std::f64::consts::PI * s2);
                        g * (q / (s2 * s2) - 2.0 / s2)
                    },
                    &mut data,
                );
            }
            Self::Gabor {
                sigma, freq, theta, ..
            } => {
                let (s, c) = theta.to_radians().sin_cos();
                let s2 = sigma * sigma;
                pixel(
                    &|x, y| {
                        let (u, _) = to_local(x, y, c, s);
                        let g = (-(x * x + y * y) / (2.0 * s2)).exp()
                            / (2.0 * std::f64::consts::PI * s2);
                        g * (2.0 * std::f64::consts::PI * freq * u).cos()
                    },
                    &mut data,
                );
            }
            Self::Box { w, h, theta, .. }
            | Self::Line {
                len: w,
                width: h,
                theta,
                ..
            } => {
                let (s, c) = theta.to_radians().sin_cos();
                area(
                    &|x, y| {
                        let (u, v) = to_local(x, y, c, s);
                        u.abs() <= 0.5 * w && v.abs() <= 0.5 * h
                    },
                    &|x, y| {
                        let (u, v) = to_local(x, y, c, s);
                        let (dx, dy) = (u.abs() - 0.5 * w, v.abs() - 0.5 * h);
                        dx.max(0.0).hypot(dy.max(0.0)) + dx.max(dy).min(0.0)
                    },
                    &mut data,
                );
                normalise = true;
            }
            Self::Disk { r: rad, .. } => {
                area(
                    &|x, y| x * x + y * y <= rad * rad,
                    &|x, y| x.hypot(y) - rad,
                    &mut data,
                );
                normalise = true;
            }
        }
        let mut factor = 1.0;
        if normalise {
            let sum: f64 = data.iter().sum();
            factor = norm.unwrap_or(if sum > 0.0 { 1.0 / sum } else { 1.0 });
            for v in &mut data {
                *v *= factor;
            }
        }
        let mut k = Kernel::new(n, n, data)?;
        k.spec = Some(self.to_string());
        k.sampling = self.sampling();
        Ok((k, factor))
    }
}
