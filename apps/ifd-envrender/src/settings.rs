//! The renderer's settings: what a person chose, persisted by eframe.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

/// Storage key of the persisted settings.
pub const STORAGE_KEY: &str = "ifd-envrender-settings";

/// How the per-band environment is evaluated (Eq. 22's two variants).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Variant {
    /// Reconstructed from SH at each rotated lobe direction.
    Sh,
    /// Looked up in per-band prefiltered maps.
    Maps,
}

/// Everything that determines the rendered image.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Settings {
    /// Always `"ifd-envrender-settings"` (recognises the stored value).
    pub format: String,
    /// The environment map (`None`: the bundled one).
    pub env: Option<PathBuf>,
    /// The scene: `sphere`, `torus`, `plane` or an OBJ file.
    pub scene: String,
    /// The BRDF spec (`ifd render --brdf`).
    pub brdf: String,
    /// Maximum SH degree `L`.
    pub l_max: usize,
    /// Evaluation variant.
    pub variant: Variant,
    /// Viewport size in pixels.
    pub size: [usize; 2],
    /// The orbit camera.
    pub camera: crate::orbit::Orbit,
    /// Exposure in stops.
    pub exposure: f32,
    /// Tone curve: `none`, `reinhard`, `aces`.
    pub tonemap: String,
    /// Environment rotation about `+z`, degrees.
    pub env_rotate: f64,
    /// Show the environment behind the object.
    pub background: bool,
    /// Refine a Monte Carlo reference of the view while the camera is still,
    /// shown beside the ISD image with the error against it.
    pub reference: bool,
    /// Albedo map over the surface's texture coordinates (`ifd render
    /// --albedo-map`).
    pub albedo_map: Option<PathBuf>,
    /// Roughness map (`ifd render --roughness-map`; isotropic GGX or Ward).
    pub roughness_map: Option<PathBuf>,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            format: STORAGE_KEY.into(),
            env: None,
            scene: "sphere".into(),
            brdf: "ggx:alpha=0.3".into(),
            l_max: 8,
            variant: Variant::Sh,
            size: [640, 480],
            camera: crate::orbit::Orbit::default(),
            exposure: 0.0,
            tonemap: "aces".into(),
            env_rotate: 0.0,
            background: true,
            reference: false,
            albedo_map: None,
            roughness_map: None,
        }
    }
}

/// The bundled environment map (`testdata/forest.hdr` of the source tree).
#[must_use]
pub fn bundled_env() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../testdata/forest.hdr")
}
