//! IFD filtering (Eq. 3): `out(p) = sum_t w_t fhat_{s sigma_t}(p + s R_theta c_t)`
//! with one trilinear scale-stack lookup per term and pixel.

mod per_pixel;

use ifd_image::{Image, ImageView};
use rayon::prelude::*;

use crate::border::Border;
use crate::error::FilterError;
use crate::field::{CheckField, CheckedField, Field, FieldKind};
use crate::kernel::Sampling;
use crate::prepared::Prepare;
use crate::stack::for_decomposition::{is_direct, sigma_bounds};
use crate::stack::lookup::Tap;
use crate::stack::lookup::Taps;
use crate::stack::reads::{self, ReadMap};
use crate::stack::rows::ScaledTerm;
use crate::stack::{ScalePosition, ScaleStack};
use crate::trig::sin_cos_degrees;
use per_pixel::sigma_groups;

/// One decomposition term, prepared for lookups.
#[derive(Clone, Copy, Debug)]
struct Prepared {
    weight: f32,
    cx: f32,
    cy: f32,
    sigma: f64,
    /// `ln sigma` and `1 / sigma^2` for the per-pixel level rule.
    ln_sigma: f32,
    inv_sigma2: f32,
}

/// A decomposition bound to a scale stack, ready to filter.
///
/// IFD filtering (Eq. 3): `out(p) = sum_t w_t fhat_{s sigma_t}(p + s R_theta c_t)`
/// with one trilinear scale-stack lookup per term and pixel.
///
/// ```
/// use ifd_image::{Image, ImageView};
/// use ifd_planar::{Border, Decomposition, Field, Filter, StackOptions, Term, stack_for_decomposition};
/// // An anisotropic kernel: two displaced Gaussians along x.
/// let d = Decomposition::from_terms(vec![
///     Term { weight: 0.5, x: -6.0, y: 0.0, sigma: 1.5 },
///     Term { weight: 0.5, x: 6.0, y: 0.0, sigma: 1.5 },
/// ]);
/// let mut img = Image::new(64, 48, 1)?;
/// img.set(32, 24, 0, 1.0);
/// let stack = stack_for_decomposition(&img, &d, 1.0, 1.0, Border::Reflect101, StackOptions::default())?;
/// let filter = Filter::new(&stack, &d)?;
/// // Rotated by 90 degrees (counter-clockwise on screen) the lobes lie along
/// // y: the impulse response has its peaks 6 px above and below the impulse.
/// let out = filter.apply(Field::Constant(90.0), Field::Constant(1.0))?;
/// assert!(out.get(32, 18, 0) > 10.0 * out.get(38, 24, 0));
/// assert!(out.get(32, 30, 0) > 10.0 * out.get(26, 24, 0));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Debug)]
pub struct Filter<'a> {
    pub(crate) stack: &'a ScaleStack,
    terms: Vec<Prepared>,
    sigma_lo: f64,
    sigma_hi: f64,
    /// The stack's source image and the sigma below which (after scaling)
    /// terms of a constant pose are evaluated directly on it.
    direct: Option<(ImageView<'a>, f64)>,
    /// How the decomposition's kernel was sampled (the atoms' effective
    /// sigma at each scale, [`Sampling::effective_sigma`]).
    sampling: Sampling,
    /// Whether the per-pixel paths may use the vector rows.
    vector: bool,
    /// Whether weighted rows whose pixels come in runs run in place
    /// ([`Filter::with_runs_in_place`]); else every row with zeros packs.
    runs_in_place: bool,
    /// The distinct term sigmas (one representative term each) and the
    /// terms as the vector rows read them with a scale map, each with the
    /// index of its sigma: the levels and weights of a pixel depend on the
    /// sigma only, so they are located once per distinct sigma.
    sigma_groups: Vec<Prepared>,
    scaled_terms: Vec<ScaledTerm>,
    /// Where a per-pixel scale puts the levels of this stack (used where
    /// the stack is log-uniform).
    scale_position: ScalePosition,
}

impl<'a> Filter<'a> {
    /// Prepares `decomposition` (a [`Decomposition`](crate::Decomposition), checked here, or a
    /// [`crate::PreparedDecomposition`]) for lookups into `stack`.
    ///
    /// # Errors
    /// As [`crate::PreparedDecomposition::new`]: [`FilterError::InvalidTerm`] for
    /// non-finite values or a sigma `<= 0`, [`FilterError::InvalidParameter`]
    /// for a decomposition without terms.
    pub fn new(
        stack: &'a ScaleStack,
        decomposition: &(impl Prepare + ?Sized),
    ) -> Result<Self, FilterError> {
        let d = decomposition.prepare()?;
        let terms: Vec<Prepared> = d
            .terms()
            .iter()
            .map(|t| Prepared {
                weight: t.weight as f32,
                cx: t.x as f32,
                cy: t.y as f32,
                sigma: t.sigma,
                ln_sigma: t.sigma.ln() as f32,
                inv_sigma2: (1.0 / (t.sigma * t.sigma)) as f32,
            })
            .collect();
        let (sigma_lo, sigma_hi) = d.sigma_range();
        let (sigma_groups, group_of) = sigma_groups(&terms);
        let scaled_terms = terms
            .iter()
            .zip(group_of)
            .map(|(t, group)| ScaledTerm {
                cx: t.cx,
                cy: t.cy,
                weight: t.weight,
                group,
            })
            .collect();
        Ok(Self {
            stack,
            terms,
            sigma_lo,
            sigma_hi,
            direct: None,
            sampling: d.sampling(),
            vector: true,
            runs_in_place: false,
            sigma_groups,
            scaled_terms,
            scale_position: ScalePosition::new(d.sampling(), stack.ln_params()),
        })
    }

    /// Evaluates the terms of a constant pose whose scaled sigma is below
    /// `below` px (normally [`DIRECT_SIGMA`](crate::DIRECT_SIGMA)) directly on `source`, the image
    /// the stack was built from: their sum of sampled Gaussians is
    /// correlated with it as one small kernel, exactly, instead of being
    /// interpolated from the stack. Per-pixel poses still read every term
    /// from the stack.
    ///
    /// ```
    /// use ifd_image::{Image, ImageView};
    /// use ifd_planar::{Border, Decomposition, DIRECT_SIGMA, Field, Filter, StackOptions, Term};
    /// use ifd_planar::{internals::reference, stack_for_decomposition};
    /// // A narrow atom at a fractional offset: interpolating the stack misses it.
    /// let d = Decomposition::from_terms(vec![Term { weight: 1.0, x: 0.5, y: 0.25, sigma: 0.7 }]);
    /// let img = Image::from_vec(32, 32, 1, (0..1024).map(|i| ((i * 7919) % 101) as f32).collect())?;
    /// let stack = stack_for_decomposition(&img, &d, 1.0, 1.0, Border::Reflect101, StackOptions::default())?;
    /// let filter = Filter::new(&stack, &d)?.with_direct(&img, DIRECT_SIGMA)?;
    /// let out = filter.apply(Field::Constant(0.0), Field::Constant(1.0))?;
    /// let k = reference::sample_kernel(|u, v| d.eval(u, v), 0.0, 1.0, 6);
    /// let want = reference::correlate(&img, &k, 13, 13, Border::Reflect101)?;
    /// let err = out.data().iter().zip(want.data()).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
    /// assert!(err < 1e-3);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`FilterError::Shape`] when `source` is not the stack's shape,
    /// [`FilterError::InvalidParameter`] for a negative or non-finite `below`.
    pub fn with_direct(
        mut self,
        source: impl Into<ImageView<'a>>,
        below: f64,
    ) -> Result<Self, FilterError> {
        let source = source.into();
        let s = self.stack;
        if (source.width(), source.height(), source.channels())
            != (s.width(), s.height(), s.channels())
        {
            return Err(FilterError::Shape(format!(
                "source image is {}x{}x{}, the stack's {}x{}x{}",
                source.width(),
                source.height(),
                source.channels(),
                s.width(),
                s.height(),
                s.channels()
            )));
        }
        if !(below.is_finite() && below >= 0.0) {
            return Err(FilterError::InvalidParameter(format!(
                "direct-evaluation threshold {below} px must be finite and non-negative"
            )));
        }
        self.direct = Some((source, below));
        Ok(self)
    }

    /// Whether the per-pixel paths (an angle or scale map) may evaluate eight
    /// or sixteen pixels at a time with the CPU's vector instructions, where
    /// it has them
    /// ([`ifd_simd::isa`]); on by default. The output is the same bit
    /// for bit either way: turning them off is for measuring.
    ///
    /// ```
    /// use ifd_image::Image;
    /// use ifd_planar::{Border, Decomposition, Field, Filter, StackOptions, Term, stack_for_decomposition};
    /// let d = Decomposition::from_terms(vec![
    ///     Term { weight: 0.5, x: -4.0, y: 0.0, sigma: 1.5 },
    ///     Term { weight: 0.5, x: 4.0, y: 1.0, sigma: 2.5 },
    /// ]);
    /// let img = Image::from_vec(40, 30, 1, (0..1200).map(|i| ((i * 37) % 17) as f32).collect())?;
    /// let stack = stack_for_decomposition(&img, &d, 1.0, 1.0, Border::Reflect101, StackOptions::default())?;
    /// let angles: Vec<f32> = (0..1200).map(|i| (i % 40) as f32 * 9.0).collect();
    /// let fast = Filter::new(&stack, &d)?.apply(Field::Map(&angles), Field::Constant(1.0))?;
    /// let scalar = Filter::new(&stack, &d)?
    ///     .with_vector_kernels(false)
    ///     .apply(Field::Map(&angles), Field::Constant(1.0))?;
    /// assert_eq!(fast.data(), scalar.data());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    #[must_use]
    pub fn with_vector_kernels(mut self, on: bool) -> Self {
        self.vector = on;
        self
    }

    /// Weighted rows ([`Filter::accumulate_weighted`]) whose pixels of
    /// non-zero weight come in runs (a filter per region) are evaluated in
    /// place, their blocks without weight skipped, so that a block of
    /// neighbouring pixels reads row windows where the angle map turns
    /// slowly; rows of scattered pixels are still packed. Off by default:
    /// a bank of entries blended per pixel along a fast-turning map (sigma
    /// maps, smoothing) gathers either way and runs fastest packed (in
    /// place was 1.15-1.2x slower there; on a swirl, three regions in place
    /// were 1.3x faster).
    #[must_use]
    pub(crate) fn with_runs_in_place(mut self, on: bool) -> Self {
        self.runs_in_place = on;
        self
    }

    /// The stack the filter reads.
    #[must_use]
    pub fn stack(&self) -> &ScaleStack {
        self.stack
    }

    /// Number of terms `s` (lookups per pixel, each trilinear).
    #[must_use]
    pub fn len(&self) -> usize {
        self.terms.len()
    }

    /// Always false: a filter has at least one term.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.terms.is_empty()
    }

    /// Whether this filter evaluates `t` directly at the constant pose of
    /// scale `s` ([`evaluated_directly`]).
    fn direct_at(&self, t: &Prepared, s: f32) -> bool {
        self.direct.is_some_and(|(_, below)| {
            let reach = f64::from(t.cx).hypot(f64::from(t.cy));
            is_direct(self.sampling, t.sigma, reach, f64::from(s), below)
        })
    }

    /// On a stack built for one filter's reads
    /// ([`crate::FilterPlan::build_stack_for`]), checks that this filter
    /// with `scale` reads only samples it computed.
    fn check_reads(&self, scale: &CheckedField<'_>) -> Result<(), FilterError> {
        let Some(computed) = self.stack.computed_windows() else {
            return Ok(());
        };
        let terms: Vec<(f64, f32, f32)> =
            self.terms.iter().map(|t| (t.sigma, t.cx, t.cy)).collect();
        let dims = (self.stack.width(), self.stack.height());
        let held = ReadMap::of_stack(self.stack, self.sampling, &terms)
            .is_some_and(|reads| reads::holds(computed, &reads.windows(scale.field(), dims)));
        if held {
            Ok(())
        } else {
            Err(FilterError::InvalidParameter(
                "the stack holds only the samples that the filter and scale map it was built for \
                 read (FilterPlan::build_stack_for, FilterSetPlan::build_stack_for), and this filter \
                 or scale reads others: build it for them, or with build_stack"
                    .into(),
            ))
        }
    }

    /// Checks that every effective sigma at scales in `[lo, hi]` is covered
    /// by the stack; at a constant pose (`constant_pose`, `lo == hi`), the
    /// terms evaluated directly read no level and are left out.
    pub(crate) fn check_scales(
        &self,
        scale: &CheckedField<'_>,
        constant_pose: bool,
    ) -> Result<(), FilterError> {
        let (lo, hi) = scale.range();
        let (min, max) = self.stack.sigma_range();
        let (mut need_lo, mut need_hi) = sigma_bounds(
            self.sampling,
            (self.sigma_lo, self.sigma_hi),
            (f64::from(lo), f64::from(hi)),
        );
        if constant_pose && self.direct.is_some() {
            let read: Vec<f64> = self
                .terms
                .iter()
                .filter(|t| !self.direct_at(t, lo))
                .map(|t| self.sampling.effective_sigma(t.sigma, f64::from(lo)))
                .collect();
            if read.is_empty() {
                return Ok(());
            }
            need_lo = read.iter().copied().fold(f64::INFINITY, f64::min);
            need_hi = read.iter().copied().fold(0.0, f64::max);
        }
        for (s, term_sigma, needed, location) in [
            (lo, self.sigma_lo, need_lo, scale.location_of_min()),
            (hi, self.sigma_hi, need_hi, scale.location_of_max()),
        ] {
            if !self.stack.covers(needed) {
                return Err(FilterError::ScaleOutOfRange {
                    scale: f64::from(s),
                    location,
                    term_sigma,
                    needed,
                    min,
                    max,
                });
            }
        }
        Ok(())
    }

    /// Filters the whole image with the decomposed kernel rotated by `angle`
    /// (degrees, counter-clockwise on screen) and scaled by `scale`, each a
    /// constant or a per-pixel map: a raw [`Field`], checked here, or a
    /// [`CheckedField`].
    ///
    /// # Errors
    /// [`FilterError::MapSize`] for maps of the wrong size,
    /// [`FilterError::InvalidValue`] for non-finite angles or non-positive
    /// scales, [`FilterError::ScaleOutOfRange`] when some `scale * sigma_t`
    /// is not covered by the stack.
    pub fn apply<'f>(
        &self,
        angle: impl CheckField<'f>,
        scale: impl CheckField<'f>,
    ) -> Result<Image, FilterError> {
        let (w, h, c) = (
            self.stack.width(),
            self.stack.height(),
            self.stack.channels(),
        );
        let angle = angle.check(FieldKind::Angle, w, h)?;
        let scale = scale.check(FieldKind::Scale, w, h)?;
        let constant_pose = !angle.is_map() && !scale.is_map();
        self.check_scales(&scale, constant_pose)?;
        self.check_reads(&scale)?;
        let out = match (angle.field(), scale.field()) {
            (Field::Constant(theta), Field::Constant(s)) => {
                let taps = self.taps_where(theta, s, |t| !self.direct_at(t, s));
                let mut out = Taps { taps }.apply_region(self.stack, 0, 0, w, h)?;
                if let Some((source, _)) = self.direct {
                    let direct: Vec<Prepared> = self
                        .terms
                        .iter()
                        .copied()
                        .filter(|t| self.direct_at(t, s))
                        .collect();
                    if !direct.is_empty() {
                        let d = direct_correlation(
                            source,
                            &direct,
                            (theta, s),
                            self.sampling,
                            self.stack.border(),
                        )?;
                        for (o, v) in out.iter_mut().zip(d.data()) {
                            *o += v;
                        }
                    }
                }
                out
            }
            (angle, scale) => {
                let mut out = vec![0.0f32; w * h * c];
                self.per_pixel_channels(angle, scale, None, &mut out);
                out
            }
        };
        Image::from_vec(w, h, c, out).map_err(|e| FilterError::Shape(e.to_string()))
    }

    /// Adds `weight[p] *` the filtered value at each pixel `p` to `out`, for
    /// the kernel rotated by `angle` and scaled by `scale` (as
    /// [`Filter::apply`]), skipping the pixels of weight zero: several
    /// filters on one stack, each for the pixels it serves (a bank of
    /// decompositions blended per pixel, a filter per region). Every term
    /// is read from the stack (none is evaluated directly), on the vector
    /// rows where the CPU has them; the pixels of weight zero cost almost
    /// nothing (each row's others are packed into whole blocks).
    ///
    /// The scale is checked at every pixel, weighted or not: give the
    /// pixels of weight zero any scale the stack covers.
    ///
    /// ```
    /// use ifd_image::Image;
    /// use ifd_planar::{Border, Decomposition, Field, Filter, StackOptions, Term, stack_for_decomposition};
    /// let d = Decomposition::from_terms(vec![
    ///     Term { weight: 0.5, x: -4.0, y: 0.0, sigma: 1.5 },
    ///     Term { weight: 0.5, x: 4.0, y: 1.0, sigma: 2.5 },
    /// ]);
    /// let img = Image::from_vec(40, 30, 1, (0..1200).map(|i| ((i * 37) % 17) as f32).collect())?;
    /// let stack = stack_for_decomposition(&img, &d, 1.0, 1.0, Border::Reflect101, StackOptions::default())?;
    /// let filter = Filter::new(&stack, &d)?;
    /// let angles: Vec<f32> = (0..1200).map(|i| (i % 40) as f32 * 9.0).collect();
    /// // the left half of the image at weight 0.25, the right half skipped
    /// let weight: Vec<f32> = (0..1200).map(|i| if i % 40 < 20 { 0.25 } else { 0.0 }).collect();
    /// let mut out = Image::new(40, 30, 1)?;
    /// filter.accumulate_weighted(Field::Map(&angles), Field::Constant(1.0), &weight, &mut out)?;
    /// let full = filter.apply(Field::Map(&angles), Field::Constant(1.0))?;
    /// assert_eq!(out.get(5, 7, 0), 0.25 * full.get(5, 7, 0));
    /// assert_eq!(out.get(25, 7, 0), 0.0);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// As [`Filter::apply`]; [`FilterError::Shape`] when `out` is not the
    /// stack's shape or `weight` not one value per pixel,
    /// [`FilterError::InvalidValue`] for a weight that is not finite.
    pub fn accumulate_weighted<'f>(
        &self,
        angle: impl CheckField<'f>,
        scale: impl CheckField<'f>,
        weight: &[f32],
        out: &mut Image,
    ) -> Result<(), FilterError> {
        let (w, h, c) = (
            self.stack.width(),
            self.stack.height(),
            self.stack.channels(),
        );
        if (out.width(), out.height(), out.channels()) != (w, h, c) || weight.len() != w * h {
            return Err(FilterError::Shape(format!(
                "output is {}x{}x{} with {} weights, the stack {w}x{h}x{c} (one weight a pixel)",
                out.width(),
                out.height(),
                out.channels(),
                weight.len()
            )));
        }
        if let Some(i) = weight.iter().position(|v| !v.is_finite()) {
            return Err(FilterError::InvalidValue {
                name: "weight",
                value: weight[i],
                location: crate::field::pixel_location(i, w),
                why: "not finite",
            });
        }
        let angle = angle.check(FieldKind::Angle, w, h)?;
        let scale = scale.check(FieldKind::Scale, w, h)?;
        self.check_scales(&scale, false)?;
        self.check_reads(&scale)?;
        self.per_pixel_channels(angle.field(), scale.field(), Some(weight), out.data_mut());
        Ok(())
    }

    /// [`Filter::per_pixel`] for the stack's channel count.
    fn per_pixel_channels(
        &self,
        angle: Field<'_>,
        scale: Field<'_>,
        weight: Option<&[f32]>,
        out: &mut [f32],
    ) {
        match self.stack.channels() {
            1 => self.per_pixel::<1>(angle, scale, weight, out),
            2 => self.per_pixel::<2>(angle, scale, weight, out),
            3 => self.per_pixel::<3>(angle, scale, weight, out),
            4 => self.per_pixel::<4>(angle, scale, weight, out),
            _ => self.per_pixel::<0>(angle, scale, weight, out),
        }
    }

    /// The filtered value (all channels) at one point `(x, y)` (pixel
    /// coordinates, need not be integers) for angle `theta` (degrees) and
    /// scale `s`: `s` trilinear lookups, for interactive use.
    ///
    /// # Errors
    /// [`FilterError::InvalidValue`] for non-finite input or `s <= 0`,
    /// [`FilterError::ScaleOutOfRange`] when `s * sigma_t` is not covered.
    pub fn filter_at(&self, x: f32, y: f32, theta: f32, s: f32) -> Result<Vec<f32>, FilterError> {
        let mut out = vec![0.0; self.stack.channels()];
        self.filter_at_into(x, y, theta, s, &mut out)?;
        Ok(out)
    }

    /// As [`Filter::filter_at`], writing one value per channel into `out`.
    ///
    /// # Errors
    /// As [`Filter::filter_at`], and [`FilterError::Shape`] when `out.len()`
    /// is not the channel count.
    pub fn filter_at_into(
        &self,
        x: f32,
        y: f32,
        theta: f32,
        s: f32,
        out: &mut [f32],
    ) -> Result<(), FilterError> {
        if out.len() != self.stack.channels() {
            return Err(FilterError::Shape(format!(
                "output has {} channels, the stack {}",
                out.len(),
                self.stack.channels()
            )));
        }
        for (name, v) in [("x", x), ("y", y)] {
            if !v.is_finite() {
                return Err(FilterError::InvalidValue {
                    name,
                    value: v,
                    location: String::new(),
                    why: "not finite",
                });
            }
        }
        Field::Constant(theta).check(FieldKind::Angle, 1, 1)?;
        let scale = Field::Constant(s).check(FieldKind::Scale, 1, 1)?;
        // A point lookup reads every term from the stack.
        self.check_scales(&scale, false)?;
        self.stack.check_whole("a lookup at a point")?;
        out.fill(0.0);
        let (sin, cos) = sin_cos_degrees(theta);
        self.pixel_general::<0>(x, y, cos, sin, s, 1.0, out);
        Ok(())
    }

    /// Per term: `(level a, level b, weight a, weight b)` for scale `s`.
    pub(crate) fn term_levels(&self, s: f32) -> Vec<(usize, usize, f32, f32)> {
        let s = f64::from(s);
        self.terms
            .iter()
            .map(|t| {
                let sigma = self.sampling.effective_sigma(t.sigma, s);
                let (a, b, wa, wb) = self.stack.locate_ln(sigma.ln());
                (a, b, wa * t.weight, wb * t.weight)
            })
            .collect()
    }

    /// The lookups for a constant angle and scale of the terms that `keep`,
    /// zero weights dropped.
    fn taps_where(&self, theta: f32, s: f32, keep: impl Fn(&Prepared) -> bool) -> Vec<Tap> {
        let levels = self.term_levels(s);
        let (terms, levels): (Vec<Prepared>, Vec<_>) = self
            .terms
            .iter()
            .zip(levels)
            .filter(|(t, _)| keep(t))
            .map(|(t, l)| (*t, l))
            .unzip();
        taps_of(&terms, theta, s, &levels)
    }

    /// The lookups of every term for a constant pose, with the term levels
    /// of `s` given.
    pub(crate) fn taps_with_levels(
        &self,
        theta: f32,
        s: f32,
        levels: &[(usize, usize, f32, f32)],
    ) -> Vec<Tap> {
        taps_of(&self.terms, theta, s, levels)
    }
}

/// The lookups of `terms` (with their levels) for a constant pose, zero
/// weights dropped.
fn taps_of(
    terms: &[Prepared],
    theta: f32,
    s: f32,
    levels: &[(usize, usize, f32, f32)],
) -> Vec<Tap> {
    let (sin, cos) = sin_cos_degrees(theta);
    let mut taps = Vec::with_capacity(2 * terms.len());
    for (t, &(a, b, wa, wb)) in terms.iter().zip(levels) {
        let ox = s * (cos * t.cx + sin * t.cy);
        let oy = s * (-sin * t.cx + cos * t.cy);
        for (level, weight) in [(a, wa), (b, wb)] {
            if weight != 0.0 {
                taps.push(Tap {
                    level,
                    ox,
                    oy,
                    weight,
                });
            }
        }
    }
    taps
}

/// The correlation of `source` with the sampled sum of the `terms`' Gaussians
/// for a constant pose: `sum_t w_t g_{sigma_eff}(d - s R_theta c_t)` at
/// integer offsets `d`, each term within `ceil(5 s sigma_t) + 1` px of its
/// centre (its tail beyond is below `4e-6` of its peak), one row `axpy` per
/// non-zero offset.
fn direct_correlation(
    source: ImageView<'_>,
    terms: &[Prepared],
    (theta, s): (f32, f32),
    sampling: Sampling,
    border: Border,
) -> Result<Image, FilterError> {
    let (sin, cos) = f64::from(theta).to_radians().sin_cos();
    let s = f64::from(s);
    let centres: Vec<(f64, f64, f64, f64, f64)> = terms
        .iter()
        .map(|t| {
            let (cx, cy) = (f64::from(t.cx), f64::from(t.cy));
            let ox = s * (cos * cx + sin * cy);
            let oy = s * (-sin * cx + cos * cy);
            let sigma = sampling.effective_sigma(t.sigma, s);
            // The term's support radius.
            let r = (5.0 * sigma).ceil() + 1.0;
            (ox, oy, sigma, r, f64::from(t.weight))
        })
        .collect();
    let radius = centres
        .iter()
        .map(|&(ox, oy, _, r, _)| (ox.abs().max(oy.abs()) + r).ceil() as usize)
        .max()
        .unwrap_or(0);
    // The sampled kernel, sparse: (dx, dy) -> value.
    let mut kernel = std::collections::BTreeMap::<(i64, i64), f64>::new();
    for &(ox, oy, sigma, r, w) in &centres {
        let norm = w / (std::f64::consts::TAU * sigma * sigma);
        for dy in (oy - r).floor() as i64..=(oy + r).ceil() as i64 {
            for dx in (ox - r).floor() as i64..=(ox + r).ceil() as i64 {
                let (ex, ey) = (dx as f64 - ox, dy as f64 - oy);
                let d2 = ex * ex + ey * ey;
                if d2 <= r * r {
                    *kernel.entry((dx, dy)).or_default() +=
                        norm * (-d2 / (2.0 * sigma * sigma)).exp();
                }
            }
        }
    }
    let (w, h, c) = (source.width(), source.height(), source.channels());
    let (ext, ew) = crate::border::extend(source, radius, radius, border);
    let taps: Vec<(usize, usize, f32)> = kernel
        .into_iter()
        .map(|((dx, dy), v)| {
            let i = (dx + radius as i64) as usize;
            let j = (dy + radius as i64) as usize;
            (i, j, v as f32)
        })
        .collect();
    let mut out = vec![0.0f32; w * h * c];
    out.par_chunks_mut(w * c).enumerate().for_each(|(y, row)| {
        for &(i, j, k) in &taps {
            let src = &ext[((y + j) * ew + i) * c..((y + j) * ew + i + w) * c];
            for (o, &v) in row.iter_mut().zip(src) {
                *o += k * v;
            }
        }
    });
    Image::from_vec(w, h, c, out).map_err(|e| FilterError::Shape(e.to_string()))
}
