//! What to render and what comes back: the [`Job`] (scene, camera,
//! environment, BRDF and [`Method`]) and the [`Rendered`] image.

use ifd_image::Image;
use ifd_shade::{Brdf, Material, Precision, SphericalLight};

use crate::camera::Camera;
use crate::envmap::EnvMap;
use crate::error::{RenderError, Result};
use crate::scene::Scene;
use crate::split_sum::SplitSum;
use crate::textures::{RoughnessFamily, SurfaceMaps};
use crate::visibility::Shadows;

/// How object pixels are shaded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// ISD, Eq. 22: rotated lobes, the per-band environment reconstructed from SH.
    Isd,
    /// ISD with the per-band environment looked up in prefiltered maps
    /// ([`ifd_shade::BandMaps`], bicubic).
    IsdMaps,
    /// The rotated slice's SH dotted with the environment's (same weights).
    Sh,
    /// The exact texel quadrature ([`crate::Oracle`]).
    Quadrature,
    /// Monte Carlo with environment and BRDF sampling and MIS ([`crate::estimate_mc`]).
    Mc,
    /// The split-sum approximation of the glTF BRDF ([`crate::SplitSum`],
    /// [`crate::SplitSumVariant::Consistent`]): engines' prefiltered chain and
    /// DFG table, the same BRDF otherwise.
    SplitSum,
    /// glTF-Sample-Renderer's split-sum shader as written
    /// ([`crate::SplitSumVariant::SampleRenderer`]).
    SplitSumSampleRenderer,
}

impl Method {
    /// `isd`, `isd-maps`, `sh`, `quadrature`, `mc`, `split-sum` or
    /// `split-sum-sample-renderer`.
    ///
    /// # Errors
    /// [`RenderError::Parameter`] for other names.
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "isd" => Ok(Self::Isd),
            "isd-maps" => Ok(Self::IsdMaps),
            "sh" => Ok(Self::Sh),
            "quadrature" => Ok(Self::Quadrature),
            "mc" => Ok(Self::Mc),
            "split-sum" => Ok(Self::SplitSum),
            "split-sum-sample-renderer" => Ok(Self::SplitSumSampleRenderer),
            _ => Err(RenderError::Parameter {
                name: "--method",
                value: s.into(),
                reason: "use isd, isd-maps, sh, quadrature, mc, split-sum or \
                         split-sum-sample-renderer"
                    .into(),
            }),
        }
    }
}

/// What to render.
#[derive(Debug)]
pub struct Job<'a> {
    /// The scene.
    pub scene: Scene,
    /// The camera.
    pub camera: Camera,
    /// The environment every method integrates (already downsampled).
    pub env: &'a EnvMap,
    /// The map shown behind the object, bilinear ([`EnvMap::background`];
    /// `None`: black).
    pub background: Option<&'a EnvMap>,
    /// The BRDF (the oracle evaluates it directly). For the glTF BRDF
    /// (`gltf:..`) the ISD methods shade with a material of its three parts
    /// (`gltf-lobes`, [`Brdf::tabulated`]) and combine them per pixel with
    /// the point's colour (the factor times the albedo map) and roughness (the
    /// roughness map's, else the factor's).
    pub brdf: &'a Brdf,
    /// The material for `isd` and `sh` (same BRDF, degree `L`).
    pub material: Option<&'a Material>,
    /// The method.
    pub method: Method,
    /// Samples per pixel of each strategy (Monte Carlo).
    pub spp: usize,
    /// Seed of the Monte Carlo sequence.
    pub seed: u64,
    /// Albedo and roughness maps (spatially varying BRDF), if any.
    pub maps: Option<&'a SurfaceMaps>,
    /// ISD materials over roughness, for a roughness map.
    pub family: Option<&'a RoughnessFamily>,
    /// Local spherical lights added to the environment (ISD Sec. 7.3):
    /// zonal lighting per point for `isd`, `isd-maps` and `sh` (Eq. 33-34), the
    /// cap's quadrature for `quadrature`; refused by `mc`. Pixels whose ray
    /// meets a light before the object show its radiance.
    pub lights: &'a [SphericalLight],
    /// Self-shadowing of the mesh (ISD Eq. 25, Appendix A): `isd` shades by
    /// the three steps with the per-vertex visibility, `quadrature` traces
    /// the visibility of every node (the reference); other methods, lights
    /// and roughness maps are refused. `None`: unshadowed.
    pub shadows: Option<&'a Shadows>,
    /// For the split-sum methods: the split sum baked from `env`
    /// ([`SplitSum::bake`]), for callers that render one environment
    /// often; `None`: baked by each render.
    pub split_sum: Option<&'a SplitSum>,
    /// The arithmetic of `isd`'s lookups at the lobes ([`Precision::F32`]:
    /// the fast path, within 1e-5 of the image maximum of `F64`'s, the
    /// reference and [`Job::new`]'s default).
    pub precision: Precision,
}

impl<'a> Job<'a> {
    /// A job with nothing optional: the object black-backed, unshadowed,
    /// without texture maps or spherical lights, Monte Carlo at 0 samples
    /// and seed 0; set the other fields by struct update.
    #[must_use]
    pub fn new(
        scene: Scene,
        camera: Camera,
        env: &'a EnvMap,
        brdf: &'a Brdf,
        material: Option<&'a Material>,
        method: Method,
    ) -> Self {
        Self {
            scene,
            camera,
            env,
            background: None,
            brdf,
            material,
            method,
            spp: 0,
            seed: 0,
            maps: None,
            family: None,
            lights: &[],
            shadows: None,
            split_sum: None,
            precision: Precision::F64,
        }
    }
}

/// A rendered image with what a caller needs to measure it.
#[derive(Debug)]
pub struct Rendered {
    /// Linear radiance, one value per environment channel.
    pub image: Image,
    /// Whether each pixel (row-major) sees the object.
    pub mask: Vec<bool>,
    /// Object pixels.
    pub object_pixels: usize,
    /// Largest `k` the oracle used (quadrature only).
    pub max_k: usize,
    /// Pixels whose quadrature did not converge to the tolerance.
    pub not_converged: usize,
    /// The largest residual estimate of the quadrature, relative to the pixel.
    pub max_residual: f64,
    /// The per-pixel standard error (Monte Carlo only).
    pub stderr: Option<Image>,
}
