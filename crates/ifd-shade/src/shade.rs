//! Shading with ISD (ISD Eq. 22): the radiance leaving a surface point
//! towards `wo`, lit by a distant environment given by its SH coefficients.
//!
//! The derivation and conventions are documented on [`Environment`].

use ifd_sphere::{Rotation, ShCoeffs, ShRotation};
use ifd_sphere::{ShEvaluator, pi_l};

use crate::bands::Bands;
use crate::brdf::Brdf;
use crate::environment::Environment;
use crate::error::{Result, ShadeError};
use crate::frame::Frame;
use crate::slice::project_slice;
use crate::table::{LobeTable, view_frame_angle};
use crate::zonal::zonal_slice;

/// The values a shading call returns from the weighted sums `sums[p C + c]`
/// (BRDF channel `p` against environment channel `c`) into `out`: every pair
/// (`OUTER`, `kc C` values), else per environment channel the one BRDF
/// channel (`kc = 1`) or the matching one (`kc = C`).
fn pick_sums<const OUTER: bool>(sums: &[f64], kc: usize, ch: usize, out: &mut [f64]) {
    if OUTER {
        out[..kc * ch].copy_from_slice(&sums[..kc * ch]);
    } else {
        for (c, o) in out[..ch].iter_mut().enumerate() {
            *o = sums[if kc == 1 { c } else { c * ch + c }];
        }
    }
}
/// Where a material's lobe weights come from.
#[derive(Clone, Debug)]
enum Lobes {
    /// Closed-form zonal slices (Lambert, Phong).
    Zonal,
    /// A lobe table.
    Table(Box<LobeTable>),
}

/// A BRDF ready to shade at degree `L`.
#[derive(Debug)]
pub struct Material {
    brdf: Brdf,
    l_max: usize,
    lobes: Lobes,
    /// With a table: each lobe's first band (`<= L + 1`), and where each
    /// of a point's lobe weights comes from and goes, `(source, target)`:
    /// the table entry's weight `basis.index(l, j) P` and the lobes'
    /// layout `(j (L + 1) + l) P`, for the bands each lobe serves (so the
    /// per-point blend is one flat loop). Empty without a table.
    firsts: Vec<usize>,
    slots: Vec<(usize, usize)>,
}

/// Scratch buffers for one thread's shading.
#[derive(Clone, Debug)]
pub struct Scratch {
    y: Vec<f64>,
    bands: Vec<f64>,
    weights: Vec<f64>,
    /// A point's rotated lobe directions, their first bands, their weights
    /// per band (`[(j (L + 1) + l) P + p]`) and the weighted sums.
    dirs: Vec<[f64; 3]>,
    first: Vec<usize>,
    lobe_weights: Vec<f64>,
    sums: Vec<f64>,
    /// For a batch of points: each lobe's point among the lit ones, and the
    /// lit points' indices.
    owner: Vec<u32>,
    lit: Vec<usize>,
}

impl Scratch {
    /// Buffers for materials of degree `l_max` under an environment of
    /// `channels` channels.
    #[must_use]
    pub fn new(l_max: usize, channels: usize) -> Self {
        let n = (l_max + 1) * (l_max + 1);
        Self {
            y: vec![0.0; n],
            bands: vec![0.0; 4 * (l_max + 1) * channels.max(3)],
            weights: vec![0.0; n * 3],
            dirs: Vec::with_capacity(2 * l_max + 1),
            first: Vec::with_capacity(2 * l_max + 1),
            lobe_weights: Vec::with_capacity((2 * l_max + 1) * (l_max + 1) * 3),
            sums: vec![0.0; 3 * channels.max(3)],
            owner: Vec::new(),
            lit: Vec::new(),
        }
    }
}

impl Material {
    /// A material at degree `l_max`: closed form for Lambert and Phong,
    /// otherwise the given table (checked against the BRDF and degree).
    ///
    /// # Errors
    /// [`ShadeError::Mismatch`] for a table of another BRDF or degree;
    /// [`ShadeError::Parameter`] when a table is needed and none is given.
    pub fn new(brdf: &Brdf, l_max: usize, table: Option<LobeTable>) -> Result<Self> {
        let closed = zonal_slice(brdf, [0.0, 0.0, 1.0], 0).is_some();
        let lobes = match (closed, table) {
            (true, None) => Lobes::Zonal,
            (_, Some(t)) => {
                t.check_for(brdf, l_max)?;
                Lobes::Table(Box::new(t))
            }
            (false, None) => {
                return Err(ShadeError::Parameter {
                    name: "lobe table",
                    value: brdf.spec().to_string(),
                    reason: "this BRDF has no closed-form weights: build a table with \
                             `ifd sphere brdf` (or LobeTable::build)"
                        .into(),
                });
            }
        };
        let (mut firsts, mut slots) = (Vec::new(), Vec::new());
        if let Lobes::Table(t) = &lobes {
            let (kc, nb, basis) = (brdf.channels(), l_max + 1, t.basis());
            for j in 0..basis.directions().len() {
                let first = basis.first_band(j).min(nb);
                firsts.push(first);
                slots.extend((first..nb).map(|l| (basis.index(l, j) * kc, (j * nb + l) * kc)));
            }
        }
        Ok(Self {
            brdf: brdf.clone(),
            l_max,
            lobes,
            firsts,
            slots,
        })
    }

    /// The BRDF.
    #[must_use]
    pub fn brdf(&self) -> &Brdf {
        &self.brdf
    }

    /// The degree `L`.
    #[must_use]
    pub fn l_max(&self) -> usize {
        self.l_max
    }

    /// The lobe table (`None` for closed-form weights).
    #[must_use]
    pub fn table(&self) -> Option<&LobeTable> {
        match &self.lobes {
            Lobes::Zonal => None,
            Lobes::Table(t) => Some(t),
        }
    }

    /// Whether the weights are closed-form (one lobe per band).
    #[must_use]
    pub fn is_closed_form(&self) -> bool {
        matches!(self.lobes, Lobes::Zonal)
    }

    /// Scratch buffers for [`Self::shade_isd`].
    #[must_use]
    pub fn scratch(&self, channels: usize) -> Scratch {
        Scratch::new(self.l_max, channels)
    }

    /// The rotation of the slice and the local view: `R` (local -> world,
    /// rotated by `phi_o` for isotropic tables) and `(theta_o, phi_o)`
    /// (`phi_o = 0` for isotropic tables, whose weights do not depend on it:
    /// their rotation by `phi_o` takes its cosine and sine from the view,
    /// `(x, y) / |(x, y)|`, without the angle).
    fn placement(&self, frame: &Frame, wo: [f64; 3]) -> (Rotation, [f64; 3], f64, f64) {
        let wl = frame.to_local(wo);
        let theta = wl[2].clamp(-1.0, 1.0).acos();
        let r = frame.rotation();
        match &self.lobes {
            Lobes::Table(t) if t.header().isotropic => {
                // on the axis (rho = 0) the angle is taken as 0
                let rho = (wl[0] * wl[0] + wl[1] * wl[1]).sqrt();
                let (c, s) = if rho > 0.0 && rho.is_finite() {
                    (wl[0] / rho, wl[1] / rho)
                } else {
                    (1.0, 0.0)
                };
                (r.mul(&Rotation::rz_cos_sin(c, s)), wl, theta, 0.0)
            }
            _ => {
                let on_axis = wl[0] == 0.0 && wl[1] == 0.0;
                let phi = if on_axis { 0.0 } else { view_frame_angle(wl) };
                (r, wl, theta, phi)
            }
        }
    }

    /// The channel count of the result for an environment of `env_channels`.
    fn out_channels(&self, env_channels: usize) -> Result<usize> {
        let kc = self.brdf.channels();
        if kc != 1 && kc != env_channels {
            return Err(ShadeError::Mismatch(format!(
                "a {kc}-channel BRDF under a {env_channels}-channel environment"
            )));
        }
        Ok(env_channels)
    }

    /// Eq. 22 at one point: `frame` at the point, `wo` the unit direction
    /// towards the viewer (world). Returns one value per environment channel
    /// in `out`. A view below the surface gives 0 (but for Phong, whose slice
    /// is defined everywhere).
    ///
    /// # Errors
    /// [`ShadeError::Mismatch`] for a MERL (RGB) BRDF under a map of other
    /// than 3 channels, or an environment of another degree.
    pub fn shade_isd(
        &self,
        env: &impl Bands,
        frame: &Frame,
        wo: [f64; 3],
        s: &mut Scratch,
        out: &mut [f64],
    ) -> Result<()> {
        self.isd_into::<false>(env, frame, wo, s, out)
    }

    /// [`Self::shade_isd`] at several points at once: `points[i]` is the
    /// frame and view of point `i`, its value goes to `out[i C..]` (`C` the
    /// environment's channels). With a lobe table and [`Precision::F32`](crate::Precision::F32) the
    /// points' lobes share the vector lanes (at L = 7 two points fill the
    /// sixteen of an AVX-512 register where one fills eight); otherwise each
    /// point is shaded alone. Equal to [`Self::shade_isd`] point by point to
    /// `f32` rounding (`F32`) or exactly (`F64`).
    ///
    /// ```
    /// use ifd_shade::{Brdf, Environment, Frame, LobeTable, Material, Precision};
    /// use ifd_sphere::ShCoeffs;
    /// let l = 7;
    /// let mut e = ShCoeffs::zeros(l, 1)?;
    /// for (i, v) in e.data_mut().iter_mut().enumerate() {
    ///     *v = 1.0 / (1.0 + i as f64);
    /// }
    /// let env = Environment::new(e)?.with_precision(Precision::F32);
    /// let b = Brdf::parse("ggx:alpha=0.3")?;
    /// let m = Material::new(&b, l, Some(LobeTable::build(&b, l, 8, 1, &|_, _| {})?))?;
    /// let f = Frame::new([0.0, 0.0, 1.0], [1.0, 0.0, 0.0]);
    /// let points = [(f, [0.0, 0.6, 0.8]), (f, [0.6, 0.0, 0.8]), (f, [0.0, 0.0, -1.0])];
    /// let mut s = m.scratch(1);
    /// let mut batch = [0.0; 3];
    /// m.shade_isd_batch(&env, &points, &mut s, &mut batch)?;
    /// for (i, (f, wo)) in points.iter().enumerate() {
    ///     let mut one = [0.0];
    ///     m.shade_isd(&env, f, *wo, &mut s, &mut one)?;
    ///     assert!((batch[i] - one[0]).abs() <= 1e-6 * one[0].abs().max(1e-3));
    /// }
    /// assert_eq!(batch[2], 0.0); // a view below the surface
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// As [`Self::shade_isd`].
    pub fn shade_isd_batch(
        &self,
        env: &Environment,
        points: &[(Frame, [f64; 3])],
        s: &mut Scratch,
        out: &mut [f64],
    ) -> Result<()> {
        let ch = self.out_channels(env.channels())?;
        self.check_env(env)?;
        let Lobes::Table(t) = &self.lobes else {
            for (i, (f, wo)) in points.iter().enumerate() {
                self.shade_isd(env, f, *wo, s, &mut out[i * ch..(i + 1) * ch])?;
            }
            return Ok(());
        };
        let kc = self.brdf.channels();
        s.dirs.clear();
        s.first.clear();
        s.lobe_weights.clear();
        s.owner.clear();
        s.lit.clear();
        for (i, (frame, wo)) in points.iter().enumerate() {
            out[i * ch..(i + 1) * ch].fill(0.0);
            let (r, wl, theta, phi) = self.placement(frame, *wo);
            if wl[2] <= 0.0 {
                continue;
            }
            let point = s.lit.len() as u32;
            s.lit.push(i);
            s.owner
                .extend(std::iter::repeat_n(point, t.basis().directions().len()));
            self.push_lobes(t, &r, theta, phi, s);
        }
        let pc = kc * ch;
        s.sums.resize(s.lit.len().max(1) * pc, 0.0);
        env.lobe_sums_batch(
            &s.first,
            &s.dirs,
            &s.lobe_weights,
            kc,
            &s.owner,
            &mut s.y,
            &mut s.bands,
            &mut s.sums,
        );
        for (li, &i) in s.lit.iter().enumerate() {
            let sums = &s.sums[li * pc..(li + 1) * pc];
            pick_sums::<false>(sums, kc, ch, &mut out[i * ch..(i + 1) * ch]);
        }
        Ok(())
    }

    /// Appends the lobes of one point to `s`: each lobe's direction `R z_j`,
    /// first band, and weights per band (the table's entries at `(theta,
    /// phi)` blended as [`LobeTable::weights_into`] blends them) in the
    /// layout of [`Bands::lobe_sums`] (`[(j (L + 1) + l) P + p]`, zero below
    /// the first band).
    #[inline]
    fn push_lobes(&self, t: &LobeTable, r: &Rotation, theta: f64, phi: f64, s: &mut Scratch) {
        let kc = self.brdf.channels();
        let nb = self.l_max + 1;
        let basis = t.basis();
        let dirs = basis.directions();
        // the table's entries blended straight into the lobes' layout (the
        // sums of `LobeTable::weights_into`, term for term)
        let mut entries = [(&[][..], 0.0); 4];
        let mut ne = 0;
        for (e, w) in t.blend(theta, phi) {
            entries[ne] = (t.entry(e), w);
            ne += 1;
        }
        let entries = &entries[..ne];
        let first_lobe = s.dirs.len();
        s.dirs.extend(dirs.iter().map(|&d| r.apply(d)));
        s.first.extend_from_slice(&self.firsts);
        s.lobe_weights.resize(s.dirs.len() * nb * kc, 0.0);
        let lobes = &mut s.lobe_weights[first_lobe * nb * kc..];
        match entries {
            // an isotropic table's two entries, unrolled, the choice made
            // once per point
            [(a, wa), (b, wb)] => {
                for &(src, dst) in &self.slots {
                    let (a, b) = (&a[src..src + kc], &b[src..src + kc]);
                    for ((o, &x), &y) in lobes[dst..dst + kc].iter_mut().zip(a).zip(b) {
                        *o = wa * f64::from(x) + wb * f64::from(y);
                    }
                }
            }
            _ => {
                for &(src, dst) in &self.slots {
                    for (p, o) in lobes[dst..dst + kc].iter_mut().enumerate() {
                        *o = entries
                            .iter()
                            .fold(0.0, |v, (e, w)| v + w * f64::from(e[src + p]));
                    }
                }
            }
        }
    }

    /// Eq. 22 for every channel of a multi-channel BRDF against every
    /// channel of the environment: `out[p C + c]` is BRDF channel `p`'s slice
    /// integrated against environment channel `c` (`C` environment channels,
    /// `P C` values in all). The glTF BRDF's three parts (`gltf-lobes`) this
    /// way share every environment lookup; [`crate::GltfMaterial::combine`]
    /// makes the whole BRDF's radiance of them.
    ///
    /// ```
    /// use ifd_shade::{Brdf, Environment, Frame, GltfMaterial, LobeTable, Material};
    /// use ifd_sphere::ShCoeffs;
    /// // a uniform white environment: each part integrates to its albedo
    /// let mut e = ShCoeffs::zeros(4, 1)?;
    /// e.data_mut()[0] = (4.0 * std::f64::consts::PI).sqrt();
    /// let env = Environment::new(e)?;
    /// let parts = Brdf::gltf_lobes(0.7)?;
    /// let table = LobeTable::build(&parts, 4, 32, 1, &|_, _| {})?;
    /// let m = Material::new(&parts, 4, Some(table))?;
    /// let frame = Frame::new([0.0, 0.0, 1.0], [1.0, 0.0, 0.0]);
    /// let mut s = m.scratch(1);
    /// let mut out = [0.0; 3];
    /// m.shade_isd_parts(&env, &frame, [0.0, 0.6, 0.8], &mut s, &mut out)?;
    /// // a white metal (f0 = 1): the GGX albedo, below 1, as the whole
    /// // BRDF's slice integrates
    /// let metal = GltfMaterial::new([1.0; 3], 1.0, 0.7)?;
    /// let mut rgb = [0.0; 3];
    /// metal.combine(&out, 1, &mut rgb);
    /// let whole = ifd_shade::project_slice(&Brdf::gltf(&metal), [0.0, 0.6, 0.8], 0, None)?;
    /// let albedo = whole.get(0, 0, 0) * (4.0 * std::f64::consts::PI).sqrt();
    /// assert!(rgb[0] < 1.0 && (rgb[0] - albedo).abs() < 1e-3, "{rgb:?} vs {albedo}");
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// As [`Self::shade_isd`].
    pub fn shade_isd_parts(
        &self,
        env: &impl Bands,
        frame: &Frame,
        wo: [f64; 3],
        s: &mut Scratch,
        out: &mut [f64],
    ) -> Result<()> {
        self.isd_into::<true>(env, frame, wo, s, out)
    }

    /// [`Self::shade_isd`] (`OUTER = false`: BRDF channel `c`, or the only
    /// one, against environment channel `c`) and [`Self::shade_isd_parts`]
    /// (`OUTER`: every BRDF channel against every environment channel).
    fn isd_into<const OUTER: bool>(
        &self,
        env: &impl Bands,
        frame: &Frame,
        wo: [f64; 3],
        s: &mut Scratch,
        out: &mut [f64],
    ) -> Result<()> {
        let kc = self.brdf.channels();
        let ch = if OUTER {
            env.channels()
        } else {
            self.out_channels(env.channels())?
        };
        let parts = if OUTER { kc } else { 1 };
        self.check_env(env)?;
        out[..parts * ch].fill(0.0);
        let (r, wl, theta, phi) = self.placement(frame, wo);
        match &self.lobes {
            Lobes::Zonal => {
                let Some((axis, k)) = zonal_slice(&self.brdf, wl, self.l_max) else {
                    return Ok(());
                };
                env.bands_into(r.apply(axis), &mut s.y, &mut s.bands);
                for (l, kl) in k.iter().enumerate() {
                    for (o, b) in out[..ch].iter_mut().zip(&s.bands[l * ch..(l + 1) * ch]) {
                        *o += kl * b;
                    }
                }
            }
            Lobes::Table(t) => {
                if wl[2] <= 0.0 {
                    return Ok(());
                }
                s.dirs.clear();
                s.first.clear();
                s.lobe_weights.clear();
                self.push_lobes(t, &r, theta, phi, s);
                env.lobe_sums(
                    &s.first,
                    &s.dirs,
                    &s.lobe_weights,
                    kc,
                    &mut s.y,
                    &mut s.bands,
                    &mut s.sums,
                );
                pick_sums::<OUTER>(&s.sums, kc, ch, out);
            }
        }
        Ok(())
    }

    /// Step 1 of shading with visibility (ISD Appendix A): the slice's SH
    /// coefficients in the world frame, `rho_l^m = pi_l sum_j lambda_l^j(wo)
    /// y_l^m(R z_j)`, straight from the rotated lobes (no SH rotation);
    /// `None` for a view below the surface (tables). One value per BRDF
    /// channel.
    ///
    /// # Errors
    /// Degrees beyond [`ifd_sphere::MAX_DEGREE`].
    pub fn world_sh(
        &self,
        frame: &Frame,
        wo: [f64; 3],
        s: &mut Scratch,
    ) -> Result<Option<ShCoeffs>> {
        let (r, wl, theta, phi) = self.placement(frame, wo);
        let kc = self.brdf.channels();
        let sh = ShEvaluator::new(self.l_max)?;
        let mut c = ShCoeffs::zeros(self.l_max, kc)?;
        let n = (self.l_max + 1) * (self.l_max + 1);
        match &self.lobes {
            Lobes::Zonal => {
                let Some((axis, k)) = zonal_slice(&self.brdf, wl, self.l_max) else {
                    return Ok(None);
                };
                sh.eval_into(r.apply(axis), &mut s.y[..n]);
                let d = c.data_mut();
                for (l, kl) in k.iter().enumerate() {
                    let band = l * l..(l + 1) * (l + 1);
                    for (di, yi) in d[band.clone()].iter_mut().zip(&s.y[band]) {
                        *di = kl * pi_l(l) * yi;
                    }
                }
            }
            Lobes::Table(t) => {
                if wl[2] <= 0.0 {
                    return Ok(None);
                }
                let ne = t.entry_len();
                t.weights_into(theta, phi, &mut s.weights[..ne]);
                let basis = t.basis();
                let d = c.data_mut();
                for (j, dir) in basis.directions().iter().enumerate() {
                    sh.eval_into(r.apply(*dir), &mut s.y[..n]);
                    for l in basis.first_band(j)..=self.l_max {
                        let base = basis.index(l, j) * kc;
                        for i in l * l..(l + 1) * (l + 1) {
                            for cc in 0..kc {
                                d[i * kc + cc] += pi_l(l) * s.weights[base + cc] * s.y[i];
                            }
                        }
                    }
                }
            }
        }
        Ok(Some(c))
    }

    fn check_env(&self, env: &impl Bands) -> Result<()> {
        if env.l_max() != self.l_max {
            return Err(ShadeError::Mismatch(format!(
                "an environment projected to L = {} for a material of L = {}",
                env.l_max(),
                self.l_max
            )));
        }
        Ok(())
    }

    /// The band-limited slice for the view `wo` at this frame, as SH
    /// coefficients in the local frame used by [`Self::shade_isd`] (rotated
    /// by `phi_o` for isotropic tables), from the same weights.
    ///
    /// # Errors
    /// As [`Self::shade_isd`].
    pub fn slice_sh(&self, frame: &Frame, wo: [f64; 3]) -> Result<(Rotation, Option<ShCoeffs>)> {
        let (r, wl, theta, phi) = self.placement(frame, wo);
        let l = self.l_max;
        let c = match &self.lobes {
            // the closed form, as the tables' slices are projected
            Lobes::Zonal => project_slice(&self.brdf, wl, l, None)?,
            Lobes::Table(t) => {
                if wl[2] <= 0.0 {
                    return Ok((r, None));
                }
                t.basis()
                    .zhe(&t.weights_at(theta, phi), t.header().channels)?
            }
        };
        Ok((r, Some(c)))
    }

    /// The SH reference of Eq. 22: the slice's SH coefficients (from the same
    /// weights as [`Self::shade_isd`]) rotated by `R` with the
    /// Ivanic-Ruedenberg recurrences, dotted with the environment's.
    ///
    /// # Errors
    /// As [`Self::shade_isd`].
    pub fn shade_sh(
        &self,
        env: &Environment,
        frame: &Frame,
        wo: [f64; 3],
        out: &mut [f64],
    ) -> Result<()> {
        let ch = self.out_channels(env.channels())?;
        self.sh_into(env, frame, wo, false, &mut out[..ch])
    }

    /// The SH reference of [`Self::shade_isd_parts`]: `out[p C + c]`.
    ///
    /// # Errors
    /// As [`Self::shade_isd`].
    pub fn shade_sh_parts(
        &self,
        env: &Environment,
        frame: &Frame,
        wo: [f64; 3],
        out: &mut [f64],
    ) -> Result<()> {
        let n = self.brdf.channels() * env.channels();
        self.sh_into(env, frame, wo, true, &mut out[..n])
    }

    fn sh_into(
        &self,
        env: &Environment,
        frame: &Frame,
        wo: [f64; 3],
        outer: bool,
        out: &mut [f64],
    ) -> Result<()> {
        let ch = env.channels();
        self.check_env(env)?;
        out.fill(0.0);
        let (r, c) = self.slice_sh(frame, wo)?;
        let Some(c) = c else {
            return Ok(());
        };
        let g = ShRotation::new(&r, self.l_max)?.apply(&c)?;
        let kc = g.channels();
        let e = env.coeffs().data();
        for i in 0..g.data().len() / kc {
            for cc in 0..ch {
                if outer {
                    for p in 0..kc {
                        out[p * ch + cc] += g.data()[i * kc + p] * e[i * ch + cc];
                    }
                } else {
                    out[cc] += g.data()[i * kc + if kc == 1 { 0 } else { cc }] * e[i * ch + cc];
                }
            }
        }
        Ok(())
    }
}
