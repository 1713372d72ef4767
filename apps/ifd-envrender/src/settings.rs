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

/// What the view beside the ISD image shows for the glTF BRDF: nothing, or
/// an engine's split-sum approximation of the same frame (`ifd render
/// --method split-sum` / `split-sum-sample-renderer`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Compare {
    /// No comparison.
    #[default]
    Off,
    /// The split sum with ISD's own BRDF split (its approximation alone).
    SplitSum,
    /// glTF-Sample-Renderer's shader as written.
    SampleRenderer,
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
    /// The split-sum comparison (glTF BRDF only).
    pub compare: Compare,
    /// With a comparison: show the split-sum image beside ISD's (else their
    /// difference).
    pub compare_image: bool,
}

impl Settings {
    /// Whether the scene is a glTF asset (`.gltf`/`.glb`).
    #[must_use]
    pub fn scene_is_gltf(&self) -> bool {
        is_gltf(&self.scene)
    }

    /// Whether the BRDF spec names the glTF BRDF (`gltf` or `gltf:..`), read
    /// from the spec's model name as `Brdf::parse` reads it, without parsing
    /// it (the UI asks every frame, and `merl:FILE` would read its file).
    #[must_use]
    pub fn brdf_is_gltf(&self) -> bool {
        let spec = self.brdf.trim();
        spec.split_once(':').map_or(spec, |(name, _)| name).trim() == "gltf"
    }

    /// Opens a scene file: an OBJ mesh, or a glTF asset shaded with its own
    /// materials (the BRDF becomes `gltf` unless it is one already); either
    /// is framed (meshes are fitted to the unit sphere).
    pub fn open_scene(&mut self, path: &std::path::Path) {
        self.scene = path.to_string_lossy().into_owned();
        if self.scene_is_gltf() {
            if !self.brdf_is_gltf() {
                "gltf".clone_into(&mut self.brdf);
            }
            // the asset's own textures replace the maps
            self.albedo_map = None;
            self.roughness_map = None;
        }
        self.camera.frame(1.0);
    }
}

/// Whether `scene` names a glTF file.
#[must_use]
pub fn is_gltf(scene: &str) -> bool {
    std::path::Path::new(scene)
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gltf") || e.eq_ignore_ascii_case("glb"))
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
            compare: Compare::Off,
            compare_image: false,
        }
    }
}

/// The bundled environment map (`testdata/forest.hdr` of the source tree).
#[must_use]
pub fn bundled_env() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../testdata/forest.hdr")
}

#[cfg(test)]
mod tests {
    use super::Settings;

    #[test]
    fn the_gltf_brdf_is_recognised_by_its_model_name_as_brdf_parse_reads_it() {
        for (spec, gltf) in [
            ("gltf", true),
            ("gltf:roughness=0.3,metallic=1", true),
            (" gltf : roughness=0.3", true),
            ("gltf-lobes:roughness=0.5", false),
            ("ggx:alpha=0.3", false),
            ("merl:gltf.binary", false),
        ] {
            let s = Settings {
                brdf: spec.into(),
                ..Settings::default()
            };
            assert_eq!(s.brdf_is_gltf(), gltf, "{spec}");
            if let Ok(b) = ifd_shade::Brdf::parse(spec) {
                assert_eq!(b.gltf_material().is_some(), gltf, "{spec}");
            }
        }
    }
}
