//! ISD Fig. 6 (`ifd-paper isd-mirror`): anti-aliased reflections off a
//! bumpy mirror sphere, ISD's filter (Eq. 26-29, [`ifd_render::render_mirror`])
//! against supersampling and a jittered reference, timed side by side and
//! measured over the bumpy and the smooth region.

use glam::DVec3;
use ifd_image::Image;
use ifd_render::Camera;
use ifd_render::EnvMap;
use ifd_render::Result;
use ifd_render::{
    AaImage, AaMethod, IsdFilter, MirrorScene, PixelFilter, Reflector, render_mirror,
};

/// What the study renders: the bumpy sphere seen by a camera under a map.
#[derive(Debug)]
pub struct BumpyScene<'a> {
    /// The mirror.
    pub mirror: BumpyMirror,
    /// The camera.
    pub camera: Camera,
    /// The environment (full resolution: looked up bilinearly).
    pub env: &'a EnvMap,
    /// The pixel filter.
    pub filter: PixelFilter,
}

/// The unit sphere as a mirror, its normals perturbed by sinusoidal bumps
/// above a latitude band (`z` from `band.0` to `band.1`, smoothstep), flat
/// below: a normal-mapped mirror with a bumpy and a smooth region.
#[derive(Clone, Debug, PartialEq)]
pub struct BumpyMirror {
    /// Wave vectors (world, per unit length) and phases of the height field
    /// `h(p) = amplitude sum sin(k . p + phase)`.
    pub waves: Vec<([f64; 3], f64)>,
    /// Height amplitude (the slopes are `amplitude |k|`).
    pub amplitude: f64,
    /// The latitude band over which the bumps fade in.
    pub band: (f64, f64),
}

impl Default for BumpyMirror {
    /// Three waves of `|k| = 60` (wavelength 0.105: about 10 pixels on a
    /// 256-pixel view of the sphere), slopes up to `0.3`, bumps above `z =
    /// 0.35`, smooth below `z = 0.15`.
    fn default() -> Self {
        let dirs = [[0.8, 0.6, 0.0], [-0.36, 0.48, 0.8], [0.0, -0.6, 0.8]];
        let phases = [0.3, 1.9, 4.1];
        Self {
            waves: dirs
                .iter()
                .zip(phases)
                .map(|(d, p)| ([60.0 * d[0], 60.0 * d[1], 60.0 * d[2]], p))
                .collect(),
            amplitude: 0.3 / 60.0,
            band: (0.15, 0.35),
        }
    }
}

impl BumpyMirror {
    /// How bumpy the surface is at `p`: 0 (smooth) to 1.
    #[must_use]
    pub fn bumpiness(&self, p: DVec3) -> f64 {
        let t = ((p.z - self.band.0) / (self.band.1 - self.band.0)).clamp(0.0, 1.0);
        t * t * (3.0 - 2.0 * t)
    }

    /// The perturbed unit normal at a point `p` of the unit sphere: the
    /// sphere's normal tilted against the tangential gradient of the height.
    #[must_use]
    pub fn normal(&self, p: DVec3) -> DVec3 {
        let n = p.normalize();
        let w = self.bumpiness(p);
        if w == 0.0 {
            return n;
        }
        let mut g = DVec3::ZERO;
        for (k, phase) in &self.waves {
            let k = DVec3::from_array(*k);
            g += k * (k.dot(p) + phase).cos();
        }
        g *= self.amplitude * w;
        (n - (g - g.dot(n) * n)).normalize()
    }
}

impl Reflector for BumpyMirror {
    fn trace(&self, camera: &Camera, x: f64, y: f64) -> std::result::Result<(DVec3, DVec3), DVec3> {
        let (o, d) = camera.ray(x, y);
        let b = o.dot(d);
        let disc = b * b - (o.length_squared() - 1.0);
        if disc < 0.0 {
            return Err(d);
        }
        let t = -b - disc.sqrt();
        if t <= 1e-9 {
            return Err(d);
        }
        let p = o + t * d;
        let n = self.normal(p);
        Ok((d - 2.0 * d.dot(n) * n, p))
    }
}

/// The pixel sets errors are measured over (row-major masks).
#[derive(Debug)]
pub struct Regions {
    /// Pixels whose whole filter footprint lies on the sphere.
    pub interior: Vec<bool>,
    /// Interior pixels in the bumpy region (bumpiness 1 at the centre).
    pub bumpy: Vec<bool>,
    /// Interior pixels in the smooth region (bumpiness 0 at the centre).
    pub smooth: Vec<bool>,
}

/// The regions of the scene's image: a pixel is interior when the four
/// corners of its filter's square see the sphere (its image is convex).
#[must_use]
pub fn regions(scene: &BumpyScene<'_>) -> Regions {
    let (w, h) = (scene.camera.width(), scene.camera.height());
    let rad = scene.filter.radius;
    let mut r = Regions {
        interior: vec![false; w * h],
        bumpy: vec![false; w * h],
        smooth: vec![false; w * h],
    };
    for yi in 0..h {
        for xi in 0..w {
            let (cx, cy) = (xi as f64 + 0.5, yi as f64 + 0.5);
            let trace = |dx: f64, dy: f64| scene.mirror.trace(&scene.camera, cx + dx, cy + dy);
            let interior = [(-rad, -rad), (rad, -rad), (-rad, rad), (rad, rad)]
                .iter()
                .all(|(dx, dy)| trace(*dx, *dy).is_ok());
            if interior && let Ok((_, p)) = trace(0.0, 0.0) {
                let b = scene.mirror.bumpiness(p);
                let i = yi * w + xi;
                r.interior[i] = true;
                r.bumpy[i] = b >= 1.0;
                r.smooth[i] = b <= 0.0;
            }
        }
    }
    r
}

/// Relative RMS error of `a` against `b` over `mask` (all channels), and
/// the pixel count.
#[must_use]
pub fn region_error(a: &Image, b: &Image, mask: &[bool]) -> (f64, usize) {
    let n = mask.iter().filter(|m| **m).count();
    (ifd_render::relative_rms(a, b, mask), n)
}

/// One method's row of the comparison.
#[derive(Clone, Debug, PartialEq)]
pub struct StudyRow {
    /// Method name ([`AaMethod::name`]).
    pub method: String,
    /// Median seconds per image over the runs (rendering only).
    pub seconds: f64,
    /// Every run's seconds.
    pub runs: Vec<f64>,
    /// Relative RMS error against the reference over interior, bumpy and
    /// smooth pixels.
    pub errors: [f64; 3],
    /// Pixels ISD filtered by Eq. 29.
    pub filtered: usize,
}

/// What [`study`] measured.
#[derive(Debug)]
pub struct Study {
    /// One row per method.
    pub rows: Vec<StudyRow>,
    /// Each method's image, named, then the reference's.
    pub images: Vec<(String, Image)>,
    /// The regions the errors are measured over.
    pub regions: Regions,
}

/// The comparison of Fig. 6: the reference once, then every method `runs`
/// times, interleaved (method after method within a run, so that the
/// machine's drift hits them alike), with the median time and the errors.
///
/// # Errors
/// As [`render_mirror`].
pub fn study(
    scene: &BumpyScene<'_>,
    methods: &[AaMethod],
    reference: AaMethod,
    isd: Option<&IsdFilter>,
    runs: usize,
    progress: &dyn Fn(&str),
) -> Result<Study> {
    progress("regions");
    let reg = regions(scene);
    let scene = &MirrorScene {
        mirror: &scene.mirror,
        camera: scene.camera,
        env: scene.env,
        filter: scene.filter,
    };
    progress(&format!("reference ({})", reference.name()));
    let refimg = render_mirror(scene, reference, isd)?.image;
    let mut times = vec![Vec::new(); methods.len()];
    let mut images: Vec<Option<AaImage>> = methods.iter().map(|_| None).collect();
    for run in 0..runs.max(1) {
        for (i, m) in methods.iter().enumerate() {
            progress(&format!("run {}/{}: {}", run + 1, runs.max(1), m.name()));
            let t = std::time::Instant::now();
            let img = render_mirror(scene, *m, isd)?;
            times[i].push(t.elapsed().as_secs_f64());
            images[i] = Some(img);
        }
    }
    let mut rows = Vec::new();
    let mut out = Vec::new();
    for ((m, t), img) in methods.iter().zip(times).zip(images) {
        let Some(img) = img else {
            unreachable!("every method ran at least once")
        };
        let mut sorted = t.clone();
        sorted.sort_by(f64::total_cmp);
        let errors = [&reg.interior, &reg.bumpy, &reg.smooth]
            .map(|mask| region_error(&img.image, &refimg, mask).0);
        rows.push(StudyRow {
            method: m.name(),
            seconds: sorted[sorted.len() / 2],
            runs: t,
            errors,
            filtered: img.filtered,
        });
        out.push((m.name(), img.image));
    }
    out.push((reference.name(), refimg));
    Ok(Study {
        rows,
        images: out,
        regions: reg,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Fig. 6 at a small size: ISD's filter has a lower error than no
    /// anti-aliasing in every region and at most 4x4 supersampling's on the bumpy
    /// region, against a 32x32 jittered reference.
    #[test]
    fn mirror_antialiasing_beats_supersampling_on_bumps() {
        let img = ifd_image::read(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../testdata/forest.hdr"
        ))
        .expect("ok");
        let env = EnvMap::new(img, 0.0).expect("ok");
        let scene = BumpyScene {
            mirror: BumpyMirror::default(),
            camera: Camera::new(
                DVec3::new(0.0, -3.2, 1.1),
                DVec3::ZERO,
                DVec3::Z,
                42.0,
                96,
                96,
            )
            .expect("ok"),
            env: &env,
            filter: PixelFilter::default(),
        };
        let isd = IsdFilter::new(&env, 32).expect("ok");
        let Study { rows, regions, .. } = study(
            &scene,
            &[AaMethod::Centre, AaMethod::Supersample(4), AaMethod::Isd],
            AaMethod::Reference(32),
            Some(&isd),
            1,
            &|_| {},
        )
        .expect("ok");
        assert!(regions.bumpy.iter().filter(|b| **b).count() > 1000);
        assert!(regions.smooth.iter().filter(|b| **b).count() > 1000);
        for r in &rows {
            eprintln!("{} {:?} filtered {}", r.method, r.errors, r.filtered);
        }
        let (none, ss4, isd) = (&rows[0], &rows[1], &rows[2]);
        assert!(isd.filtered > 500, "Eq. 29 shaded {} pixels", isd.filtered);
        for k in 0..3 {
            assert!(
                isd.errors[k] < none.errors[k],
                "region {k}: {:?} vs {:?}",
                isd.errors,
                none.errors
            );
        }
        assert!(
            isd.errors[1] <= ss4.errors[1],
            "bumpy: {:?} vs {:?}",
            isd.errors,
            ss4.errors
        );
    }
}
