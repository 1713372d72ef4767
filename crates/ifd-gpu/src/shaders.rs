//! The WGSL sources (in the workspace's top-level `shaders/` folder), compiled
//! into the library. A test parses and validates every `.wgsl` file there
//! with naga.

/// The IFD evaluation kernel (`shaders/ifd_eval.wgsl`) as written: it uses
/// the constants of [`codes`], which [`ifd_eval_source`] prepends.
pub const IFD_EVAL: &str = include_str!("../../../shaders/ifd_eval.wgsl");

/// The numbers the evaluation shader and the host agree on (fields of its
/// `Params`), defined once: the host writes them, and [`ifd_eval_source`]
/// gives them to the shader as WGSL constants of the same names.
pub mod codes {
    /// `flags`: the angle is a per-pixel map.
    pub const FLAG_ANGLE_MAP: u32 = 1;
    /// `flags`: the scale is a per-pixel map.
    pub const FLAG_SCALE_MAP: u32 = 2;
    /// `flags`: the bank entry is a per-pixel map.
    pub const FLAG_ENTRY_MAP: u32 = 4;
    /// `flags`: every term's levels and weights come located from the host
    /// (a constant scale): one lookup per term on a stack at the terms'
    /// sigmas.
    pub const FLAG_TERM_LEVELS: u32 = 8;
    /// `border_mode`: `Border::Reflect101`.
    pub const BORDER_REFLECT101: u32 = 0;
    /// `border_mode`: `Border::Constant`.
    pub const BORDER_CONSTANT: u32 = 1;
    /// `border_mode`: `Border::Replicate`.
    pub const BORDER_REPLICATE: u32 = 2;
    /// `border_mode`: `Border::Wrap`.
    pub const BORDER_WRAP: u32 = 3;
    /// `interpolation`: bilinear samples.
    pub const INTERP_LINEAR: u32 = 0;
    /// `interpolation`: cubic B-spline coefficients.
    pub const INTERP_CUBIC: u32 = 1;
    /// `sampling`: `Sampling::Continuous`.
    pub const SAMPLING_CONTINUOUS: u32 = 0;
    /// `sampling`: `Sampling::Point`.
    pub const SAMPLING_POINT: u32 = 1;
    /// `sampling`: `Sampling::Area`.
    pub const SAMPLING_AREA: u32 = 2;
    /// `sampling`: `Sampling::Averaged`.
    pub const SAMPLING_AVERAGED: u32 = 3;

    /// Every code with its name, as [`super::ifd_eval_source`] declares them.
    pub const ALL: [(&str, u32); 14] = [
        ("FLAG_ANGLE_MAP", FLAG_ANGLE_MAP),
        ("FLAG_SCALE_MAP", FLAG_SCALE_MAP),
        ("FLAG_ENTRY_MAP", FLAG_ENTRY_MAP),
        ("FLAG_TERM_LEVELS", FLAG_TERM_LEVELS),
        ("BORDER_REFLECT101", BORDER_REFLECT101),
        ("BORDER_CONSTANT", BORDER_CONSTANT),
        ("BORDER_REPLICATE", BORDER_REPLICATE),
        ("BORDER_WRAP", BORDER_WRAP),
        ("INTERP_LINEAR", INTERP_LINEAR),
        ("INTERP_CUBIC", INTERP_CUBIC),
        ("SAMPLING_CONTINUOUS", SAMPLING_CONTINUOUS),
        ("SAMPLING_POINT", SAMPLING_POINT),
        ("SAMPLING_AREA", SAMPLING_AREA),
        ("SAMPLING_AVERAGED", SAMPLING_AVERAGED),
    ];
}

/// The evaluation kernel as compiled: the [`codes`] as WGSL `const`s, then
/// [`IFD_EVAL`].
///
/// ```
/// let src = ifd_gpu::shaders::ifd_eval_source();
/// assert!(src.starts_with("const FLAG_ANGLE_MAP: u32 = 1u;"));
/// assert!(src.ends_with(ifd_gpu::shaders::IFD_EVAL));
/// ```
#[must_use]
pub fn ifd_eval_source() -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    for (name, v) in codes::ALL {
        // Writing into a String cannot fail.
        let _ = writeln!(s, "const {name}: u32 = {v}u;");
    }
    s.push('\n');
    s.push_str(IFD_EVAL);
    s
}

/// Result to `rgba8unorm` texture (`shaders/to_rgba8.wgsl`).
pub const TO_RGBA8: &str = include_str!("../../../shaders/to_rgba8.wgsl");

/// The display transform of shaded images (`shaders/tonemap.wgsl`).
pub const TONEMAP: &str = include_str!("../../../shaders/tonemap.wgsl");

/// Brush-dab blend into an image on the device (`shaders/dab_blend.wgsl`).
pub const DAB_BLEND: &str = include_str!("../../../shaders/dab_blend.wgsl");

/// ISD shading, Eq. 22 (`shaders/isd_shade.wgsl`) as written: it uses the
/// band count `NB` and the constants of [`shade_codes`], which
/// [`isd_shade_source`] prepends.
pub const ISD_SHADE: &str = include_str!("../../../shaders/isd_shade.wgsl");

/// The numbers the shading kernel and the host agree on.
pub mod shade_codes {
    /// `variant`: the per-band environment from SH coefficients.
    pub const VARIANT_SH: u32 = 0;
    /// `variant`: the per-band environment from prefiltered maps.
    pub const VARIANT_MAPS: u32 = 1;
    /// `material`: Lambert, closed-form zonal weights about the normal.
    pub const MATERIAL_LAMBERT: u32 = 0;
    /// `material`: Phong, closed-form zonal weights about the mirror direction.
    pub const MATERIAL_PHONG: u32 = 1;
    /// `material`: lobe tables (one, or a roughness family).
    pub const MATERIAL_TABLE: u32 = 2;
    /// `material`: the glTF BRDF: tables of its three parts (`gltf-lobes`),
    /// combined per pixel with the G-buffer's base colour and metalness.
    pub const MATERIAL_GLTF: u32 = 3;

    /// Every code with its name, as [`super::isd_shade_source`] declares them.
    pub const ALL: [(&str, u32); 6] = [
        ("VARIANT_SH", VARIANT_SH),
        ("VARIANT_MAPS", VARIANT_MAPS),
        ("MATERIAL_LAMBERT", MATERIAL_LAMBERT),
        ("MATERIAL_PHONG", MATERIAL_PHONG),
        ("MATERIAL_TABLE", MATERIAL_TABLE),
        ("MATERIAL_GLTF", MATERIAL_GLTF),
    ];
}

/// The shading kernel as compiled for degree `l_max`: `const NB` (the band
/// count `l_max + 1`, which sizes the kernel's private band sums), the
/// [`shade_codes`], then [`ISD_SHADE`].
///
/// ```
/// let src = ifd_gpu::shaders::isd_shade_source(7);
/// assert!(src.starts_with("const NB: u32 = 8u;"));
/// assert!(src.ends_with(ifd_gpu::shaders::ISD_SHADE));
/// ```
#[must_use]
pub fn isd_shade_source(l_max: usize) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(s, "const NB: u32 = {}u;", l_max + 1);
    for (name, v) in shade_codes::ALL {
        let _ = writeln!(s, "const {name}: u32 = {v}u;");
    }
    s.push('\n');
    s.push_str(ISD_SHADE);
    s
}
