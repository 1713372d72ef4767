//! glTF metallic-roughness materials (factors, textures and their texture
//! coordinate sets, the normal scale, the occlusion strength, the emissive
//! factor with `KHR_materials_emissive_strength`), textures decoded by
//! `ifd-image` (PNG or JPEG; base colour and emissive sRGB-decoded, the rest
//! linear) and sampled bilinearly with their sampler's wrap modes.

use std::borrow::Cow;
use std::collections::HashMap;
use std::path::Path;

use gltf::json;
use gltf::json::texture::WrappingMode;
use gltf::json::validation::Checked;
use ifd_image::{FileFormat, Image, ReadOptions};

use super::document::{Ctx, Document};
use crate::error::{RenderError, Result};

/// A texture reference of a material: which decoded texture, which set of
/// texture coordinates.
#[derive(Clone, Copy, Debug)]
pub(super) struct TexRef {
    pub tex: usize,
    pub set: u32,
}

/// A material's values.
#[derive(Clone, Debug)]
pub(super) struct Mat {
    pub base: [f64; 4],
    pub base_tex: Option<TexRef>,
    pub metallic: f64,
    pub roughness: f64,
    pub mr_tex: Option<TexRef>,
    pub normal_tex: Option<TexRef>,
    pub normal_scale: f64,
    pub occlusion_tex: Option<TexRef>,
    pub occlusion_strength: f64,
    pub emissive: [f64; 3],
    pub emissive_tex: Option<TexRef>,
    pub double_sided: bool,
}

impl Default for Mat {
    /// glTF's default material: base colour 1, metallic 1, roughness 1, no
    /// textures, no emission, single-sided.
    fn default() -> Self {
        Self {
            base: [1.0; 4],
            base_tex: None,
            metallic: 1.0,
            roughness: 1.0,
            mr_tex: None,
            normal_tex: None,
            normal_scale: 1.0,
            occlusion_tex: None,
            occlusion_strength: 1.0,
            emissive: [0.0; 3],
            emissive_tex: None,
            double_sided: false,
        }
    }
}

/// A decoded texture with its wrap modes.
#[derive(Clone, Debug)]
pub(super) struct Tex {
    img: std::sync::Arc<Image>,
    wrap: [WrappingMode; 2],
}

impl Tex {
    /// Bilinear value of channel `c` (`0..4`: R, G, B, A; a grey image's
    /// R, G and B are its grey, a missing alpha is 1) at `uv` (`(0, 0)` the
    /// top-left corner of the image), wrapped per the sampler.
    pub fn sample(&self, uv: [f64; 2], c: usize) -> f64 {
        let (w, h, ch) = (self.img.width(), self.img.height(), self.img.channels());
        let ch_index = match (ch, c) {
            (1 | 2, 0..=2) => Some(0),
            (2, 3) => Some(1),
            (1 | 3, 3) => None,
            (_, c) => Some(c.min(ch - 1)),
        };
        let Some(ci) = ch_index else { return 1.0 };
        let coord = |t: f64, n: usize| {
            // Finite and far from i64's limits: the wrap modes are periodic.
            let x = if t.is_finite() {
                t.clamp(-1e9, 1e9)
            } else {
                0.0
            };
            x * n as f64 - 0.5
        };
        let (x, y) = (coord(uv[0], w), coord(uv[1], h));
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let xi = |k: i64| wrap(x0 + k, w, self.wrap[0]);
        let yi = |k: i64| wrap(y0 + k, h, self.wrap[1]);
        let data = self.img.data();
        let v = |xx: usize, yy: usize| f64::from(data[(yy * w + xx) * ch + ci]);
        (1.0 - fy) * ((1.0 - fx) * v(xi(0), yi(0)) + fx * v(xi(1), yi(0)))
            + fy * ((1.0 - fx) * v(xi(0), yi(1)) + fx * v(xi(1), yi(1)))
    }

    /// The smallest and largest value of channel `c` over the texels.
    pub fn range(&self, c: usize) -> (f64, f64) {
        let ch = self.img.channels();
        let ci = if ch <= 2 { 0 } else { c.min(ch - 1) };
        self.img
            .data()
            .iter()
            .skip(ci)
            .step_by(ch)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(f64::from(*v)), b.max(f64::from(*v)))
            })
    }
}

/// Texel index `i` of a row or column of `n` wrapped by `mode`.
fn wrap(i: i64, n: usize, mode: WrappingMode) -> usize {
    let n = n as i64;
    (match mode {
        WrappingMode::Repeat => i.rem_euclid(n),
        WrappingMode::ClampToEdge => i.clamp(0, n - 1),
        WrappingMode::MirroredRepeat => {
            let k = i.rem_euclid(2 * n);
            if k >= n { 2 * n - 1 - k } else { k }
        }
    }) as usize
}

/// Reads the materials `used` (indices into the file's materials; the file's
/// count stands for the default material) and decodes the textures they
/// refer to. Returns every material (the default last; unused ones keep
/// their factors but no textures) and the decoded textures.
pub(super) fn load(
    ctx: &mut Ctx,
    doc: &Document,
    used: &[bool],
    notes: &mut Vec<String>,
) -> Result<(Vec<Mat>, Vec<Tex>)> {
    let mut loader = Loader {
        doc,
        textures: Vec::new(),
        by_key: HashMap::new(),
        images: HashMap::new(),
    };
    let mut mats = Vec::with_capacity(doc.root.materials.len() + 1);
    for (i, m) in doc.root.materials.iter().enumerate() {
        let mut mat = factors(m);
        if used.get(i).copied().unwrap_or(false) {
            loader.textures_of(ctx, i, m, &mut mat, notes)?;
        }
        mats.push(mat);
    }
    mats.push(Mat::default());
    Ok((mats, loader.textures))
}

/// A material's factors (textures are added by [`Loader::textures_of`]).
fn factors(m: &json::Material) -> Mat {
    let pbr = &m.pbr_metallic_roughness;
    let strength = m
        .extensions
        .as_ref()
        .and_then(|e| e.emissive_strength.as_ref())
        .map_or(1.0, |s| f64::from(s.emissive_strength.0));
    Mat {
        base: pbr.base_color_factor.0.map(f64::from),
        metallic: f64::from(pbr.metallic_factor.0),
        roughness: f64::from(pbr.roughness_factor.0),
        normal_scale: m
            .normal_texture
            .as_ref()
            .map_or(1.0, |t| f64::from(t.scale)),
        occlusion_strength: m
            .occlusion_texture
            .as_ref()
            .map_or(1.0, |t| f64::from(t.strength.0)),
        emissive: m.emissive_factor.0.map(|v| f64::from(v) * strength),
        double_sided: m.double_sided,
        ..Mat::default()
    }
}

/// The texture coordinate set of material `m`'s normal texture, when it has
/// one (its primitives need tangents).
pub(super) fn normal_uv(doc: &Document, m: usize) -> Option<u32> {
    doc.root
        .materials
        .get(m)?
        .normal_texture
        .as_ref()
        .map(|t| t.tex_coord)
}

struct Loader<'a> {
    doc: &'a Document,
    textures: Vec<Tex>,
    /// (texture index, sRGB) -> decoded texture.
    by_key: HashMap<(usize, bool), usize>,
    /// (image index, sRGB) -> decoded image.
    images: HashMap<(usize, bool), std::sync::Arc<Image>>,
}

impl Loader<'_> {
    fn textures_of(
        &mut self,
        ctx: &mut Ctx,
        i: usize,
        m: &json::Material,
        mat: &mut Mat,
        notes: &mut Vec<String>,
    ) -> Result<()> {
        let pbr = &m.pbr_metallic_roughness;
        let mut get = |ctx: &mut Ctx, index: usize, set: u32, srgb: bool, what: &str| {
            if set > 1 {
                notes.push(format!(
                    "material {i}: the {what} texture uses TEXCOORD_{set} (only 0 and 1 are read): ignored"
                ));
                return Ok(None);
            }
            self.texture(ctx, index, srgb)
                .map(|tex| Some(TexRef { tex, set }))
        };
        if let Some(t) = &pbr.base_color_texture {
            mat.base_tex = get(ctx, t.index.value(), t.tex_coord, true, "base colour")?;
        }
        if let Some(t) = &pbr.metallic_roughness_texture {
            mat.mr_tex = get(
                ctx,
                t.index.value(),
                t.tex_coord,
                false,
                "metallic-roughness",
            )?;
        }
        if let Some(t) = &m.normal_texture {
            mat.normal_tex = get(ctx, t.index.value(), t.tex_coord, false, "normal")?;
        }
        if let Some(t) = &m.occlusion_texture {
            mat.occlusion_tex = get(ctx, t.index.value(), t.tex_coord, false, "occlusion")?;
        }
        if let Some(t) = &m.emissive_texture {
            mat.emissive_tex = get(ctx, t.index.value(), t.tex_coord, true, "emissive")?;
        }
        Ok(())
    }

    /// Texture `index` decoded (once per colour space).
    fn texture(&mut self, ctx: &mut Ctx, index: usize, srgb: bool) -> Result<usize> {
        if let Some(&k) = self.by_key.get(&(index, srgb)) {
            return Ok(k);
        }
        let part = format!("texture {index}");
        let t = self
            .doc
            .root
            .textures
            .get(index)
            .ok_or_else(|| ctx.err(&part, "does not exist"))?;
        let wrap = match t.sampler {
            None => [WrappingMode::Repeat; 2],
            Some(s) => {
                let s = self.doc.root.samplers.get(s.value()).ok_or_else(|| {
                    ctx.err(&part, format!("sampler {} does not exist", s.value()))
                })?;
                let mode = |m: Checked<WrappingMode>| match m {
                    Checked::Valid(m) => Ok(m),
                    Checked::Invalid => Err(ctx.err(&part, "unknown wrap mode")),
                };
                [mode(s.wrap_s)?, mode(s.wrap_t)?]
            }
        };
        let source = t.source.value();
        let img = if let Some(img) = self.images.get(&(source, srgb)) {
            img.clone()
        } else {
            let img = std::sync::Arc::new(self.image(ctx, source, srgb)?);
            self.images.insert((source, srgb), img.clone());
            img
        };
        self.textures.push(Tex { img, wrap });
        let k = self.textures.len() - 1;
        self.by_key.insert((index, srgb), k);
        Ok(k)
    }

    /// Image `index` decoded by `ifd-image` (PNG or JPEG, by its bytes'
    /// signature, else by its declared type).
    fn image(&self, ctx: &mut Ctx, index: usize, srgb: bool) -> Result<Image> {
        let doc = self.doc;
        let img = doc
            .root
            .images
            .get(index)
            .ok_or_else(|| ctx.err(format!("image {index}"), "does not exist"))?;
        let declared = img.mime_type.as_ref().map(|m| m.0.clone());
        let (bytes, declared) = match (&img.uri, img.buffer_view) {
            (Some(uri), _) => {
                let part = if uri.starts_with("data:") {
                    format!("image {index} (data: URI)")
                } else {
                    format!("image {index} ({uri:?})")
                };
                let bytes = Cow::Owned(doc.resolve_uri(ctx, uri, &part)?);
                let mime = uri
                    .strip_prefix("data:")
                    .and_then(|r| r.split([';', ',']).next())
                    .map(str::to_string)
                    .or(declared)
                    .or_else(|| {
                        let ext = Path::new(uri).extension()?.to_str()?.to_ascii_lowercase();
                        Some(match ext.as_str() {
                            "png" => "image/png".into(),
                            "jpg" | "jpeg" => "image/jpeg".into(),
                            _ => format!(".{ext}"),
                        })
                    });
                (bytes, mime)
            }
            (None, Some(v)) => {
                let part = format!("image {index} (bufferView {})", v.value());
                (Cow::Borrowed(doc.view(ctx, v.value(), &part)?), declared)
            }
            (None, None) => {
                return Err(ctx.err(
                    format!("image {index}"),
                    "has neither a uri nor a bufferView",
                ));
            }
        };
        let kind = declared.clone().unwrap_or_else(|| "no type".into());
        let name = format!("{}: image {index} ({kind})", ctx.file.display());
        let format = if bytes.starts_with(&[0x89, b'P', b'N', b'G']) {
            FileFormat::Png
        } else if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
            FileFormat::Jpeg
        } else {
            match declared.as_deref() {
                Some("image/png") => FileFormat::Png,
                Some("image/jpeg") => FileFormat::Jpeg,
                _ => {
                    return Err(ctx.err(
                        format!("image {index} ({kind})"),
                        "not a PNG or JPEG image (the formats glTF 2.0 allows)",
                    ));
                }
            }
        };
        let opts = ReadOptions {
            srgb_decode: srgb,
            budget: ctx.remaining(),
            ..ReadOptions::default()
        };
        let loaded = ifd_image::read_image_bytes(&bytes, Path::new(&name), format, &opts)
            .map_err(RenderError::Image)?;
        let (w, h, c) = (
            loaded.image.width(),
            loaded.image.height(),
            loaded.image.channels(),
        );
        ctx.charge((w * h * c * 4) as u64, &format!("image {index} ({kind})"))?;
        Ok(loaded.image)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_modes() {
        let r: Vec<usize> = (-3..6).map(|i| wrap(i, 3, WrappingMode::Repeat)).collect();
        assert_eq!(r, [0, 1, 2, 0, 1, 2, 0, 1, 2]);
        let c: Vec<usize> = (-3..6)
            .map(|i| wrap(i, 3, WrappingMode::ClampToEdge))
            .collect();
        assert_eq!(c, [0, 0, 0, 0, 1, 2, 2, 2, 2]);
        let m: Vec<usize> = (-3..9)
            .map(|i| wrap(i, 3, WrappingMode::MirroredRepeat))
            .collect();
        assert_eq!(m, [2, 1, 0, 0, 1, 2, 2, 1, 0, 0, 1, 2]);
    }
}
