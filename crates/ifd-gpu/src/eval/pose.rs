//! [`GpuPose`]: the per-pixel angle, scale and bank-entry maps of an
//! evaluation, checked as the CPU path checks them and uploaded.

use ifd_planar::{CheckField, Field, FieldKind, FilterError};

use crate::context::GpuContext;
use crate::error::GpuError;
use crate::shaders::codes;
use crate::stack::GpuStack;
use crate::wgpu_helpers::buffer_init;

/// Per-pixel rotation, scale and bank entry, uploaded for one stack.
///
/// Angle maps are uploaded as `(cos, sin)` pairs computed on the CPU with
/// the same `f32` `sin_cos` as the CPU path (WGSL only promises `sin`/`cos`
/// to `2^-11` absolute, which would move a lookup 200 px away by 0.1 px);
/// scale maps as `(s, level offset)` pairs, the level offset
/// `(ln s - ln sigma_0) / ln r` computed in `f64`. Constant fields need no
/// map. A pose can be reused for many evaluations (the brush uploads the
/// orientation field once and evaluates dab after dab).
#[derive(Debug)]
pub struct GpuPose {
    pub(super) maps: wgpu::Buffer,
    pub(super) width: u32,
    pub(super) height: u32,
    pub(super) flags: u32,
    pub(super) rot_off: u32,
    pub(super) scale_off: u32,
    pub(super) entry_off: u32,
    pub(super) cos_t: f32,
    pub(super) sin_t: f32,
    pub(super) scale: f32,
    pub(super) u_offset: f32,
    pub(super) entry: f32,
    /// The smallest and largest scale.
    pub(super) scale_range: (f32, f32),
    /// Where they are (`" at pixel (x, y)"`, empty for a constant), for
    /// messages.
    pub(super) scale_where: [String; 2],
}

/// A per-pixel scale map locates levels in the shader by the log-uniform
/// formula: refused on a stack whose levels are at given sigmas.
pub(super) fn check_scale_map_reads(stack: &GpuStack, scale_map: bool) -> Result<(), GpuError> {
    if scale_map && !stack.locator.is_uniform() {
        return Err(FilterError::InvalidParameter(
            "a per-pixel scale map reads a stack of log-uniformly spaced levels \
             (ScaleStack::new); this one has levels at given sigmas, for a constant scale"
                .into(),
        )
        .into());
    }
    Ok(())
}

/// `[cos, sin]` of an angle in degrees, as the pose maps hold rotations
/// (the CPU path's `f32` `sin_cos`).
fn cos_sin(degrees: f32) -> [f32; 2] {
    let (s, c) = degrees.to_radians().sin_cos();
    [c, s]
}

impl GpuPose {
    /// Uploads the per-pixel maps among `angle` (degrees, counter-clockwise
    /// on screen), `scale` and `entry` (bank entry `i + t`: entries `i` and
    /// `i + 1` blended with weight `t`; 0 for a single decomposition) for
    /// evaluations on `stack`: raw [`Field`]s, checked here as the CPU path
    /// checks them, or [`ifd_planar::CheckedField`]s, checked once for both paths.
    ///
    /// # Errors
    /// As the CPU path: [`FilterError::MapSize`] for maps of the wrong size,
    /// [`FilterError::InvalidValue`] for non-finite angles, non-positive
    /// scales or negative entries; [`GpuError::Limit`] when the maps exceed
    /// a buffer limit.
    pub fn new<'f>(
        ctx: &GpuContext,
        stack: &GpuStack,
        angle: impl CheckField<'f>,
        scale: impl CheckField<'f>,
        entry: impl CheckField<'f>,
    ) -> Result<Self, GpuError> {
        let (w, h) = (stack.width(), stack.height());
        let checked_scale = scale.check(FieldKind::Scale, w, h)?;
        let angle = angle.check(FieldKind::Angle, w, h)?.field();
        let entry = entry.check(FieldKind::Entry, w, h)?.field();
        let scale = checked_scale.field();
        let (ln0, inv) = stack.ln_params;
        let uniform = stack.locator.is_uniform();
        check_scale_map_reads(stack, matches!(scale, Field::Map(_)))?;
        // (Unused with levels at given sigmas: the host locates every term.)
        let level_offset = |s: f32| {
            if uniform {
                ((f64::from(s).ln() - ln0) * inv) as f32
            } else {
                0.0
            }
        };
        let mut maps: Vec<f32> = Vec::new();
        let mut flags = 0;
        let (mut rot_off, mut scale_off, mut entry_off) = (0, 0, 0);
        let (mut cos_t, mut sin_t, mut s_c, mut u_c, mut e_c) = (1.0, 0.0, 1.0, 0.0, 0.0);
        match angle {
            Field::Constant(a) => [cos_t, sin_t] = cos_sin(a),
            Field::Map(m) => {
                flags |= codes::FLAG_ANGLE_MAP;
                rot_off = maps.len();
                maps.reserve(2 * m.len());
                maps.extend(m.iter().flat_map(|&a| cos_sin(a)));
            }
        }
        match scale {
            Field::Constant(s) => {
                s_c = s;
                u_c = level_offset(s);
            }
            Field::Map(m) => {
                flags |= codes::FLAG_SCALE_MAP;
                scale_off = maps.len();
                maps.reserve(2 * m.len());
                for &s in m {
                    maps.extend([s, level_offset(s)]);
                }
            }
        }
        match entry {
            Field::Constant(e) => e_c = e,
            Field::Map(m) => {
                flags |= codes::FLAG_ENTRY_MAP;
                entry_off = maps.len();
                maps.extend_from_slice(m);
            }
        }
        let too_big = |what| GpuError::Limit {
            what: format!("the {what} offset in the pose maps"),
            needed: maps.len().to_string(),
            limit_name: "u32 indexing in the shader",
            limit: u32::MAX.to_string(),
        };
        let rot_off = u32::try_from(rot_off).map_err(|_| too_big("rotation"))?;
        let scale_off = u32::try_from(scale_off).map_err(|_| too_big("scale"))?;
        let entry_off = u32::try_from(entry_off).map_err(|_| too_big("entry"))?;
        ctx.check_buffer(
            &format!("per-pixel maps of a {w}x{h} image"),
            (maps.len() * 4) as u64,
            true,
        )?;
        let buffer = ctx.scoped("uploading the per-pixel maps", || {
            Ok(buffer_init(
                ctx.device(),
                "ifd pose maps",
                bytemuck::cast_slice(&maps),
                wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            ))
        })?;
        Ok(Self {
            maps: buffer,
            width: stack.width,
            height: stack.height,
            flags,
            rot_off,
            scale_off,
            entry_off,
            cos_t,
            sin_t,
            scale: s_c,
            u_offset: u_c,
            entry: e_c,
            scale_range: checked_scale.range(),
            scale_where: [
                checked_scale.location_of_min(),
                checked_scale.location_of_max(),
            ],
        })
    }

    /// Overwrites rows `y0..y0 + rows` of the angle and bank-entry maps
    /// (each `rows * width` values; `None` keeps a map, and a field that is
    /// not a map takes no rows).
    ///
    /// # Errors
    /// [`FilterError::InvalidParameter`] for rows outside the image, maps of
    /// the wrong length or not uploaded as maps, non-finite values or
    /// negative entries; [`GpuError::Device`] for a wgpu error.
    pub(crate) fn write_rows(
        &self,
        ctx: &GpuContext,
        y0: usize,
        rows: usize,
        angle: Option<&[f32]>,
        entry: Option<&[f32]>,
    ) -> Result<(), GpuError> {
        let (w, h) = (self.width as usize, self.height as usize);
        let bad = |m: String| GpuError::from(FilterError::InvalidParameter(m));
        if y0 + rows > h {
            return Err(bad(format!("rows {y0}..{} of a {w}x{h} pose", y0 + rows)));
        }
        let n = rows * w;
        for (name, m, flag, min) in [
            ("angle", angle, codes::FLAG_ANGLE_MAP, f32::NEG_INFINITY),
            ("bank entry", entry, codes::FLAG_ENTRY_MAP, 0.0),
        ] {
            let Some(m) = m else { continue };
            if self.flags & flag == 0 || m.len() != n {
                return Err(bad(format!(
                    "{} {name} values for {rows} rows of a pose whose {name} {}",
                    m.len(),
                    if self.flags & flag == 0 {
                        "is constant"
                    } else {
                        "is a map"
                    }
                )));
            }
            if let Some(i) = m.iter().position(|v| !v.is_finite() || *v < min) {
                return Err(bad(format!(
                    "{name} {} at pixel ({}, {}) is not finite or negative",
                    m[i],
                    i % w,
                    y0 + i / w
                )));
            }
        }
        ctx.scoped("updating the per-pixel maps", || {
            if let Some(a) = angle {
                let cs: Vec<f32> = a.iter().flat_map(|&a| cos_sin(a)).collect();
                let at = (self.rot_off as usize + 2 * y0 * w) * 4;
                ctx.queue()
                    .write_buffer(&self.maps, at as u64, bytemuck::cast_slice(&cs));
            }
            if let Some(e) = entry {
                let at = (self.entry_off as usize + y0 * w) * 4;
                ctx.queue()
                    .write_buffer(&self.maps, at as u64, bytemuck::cast_slice(e));
            }
            Ok(())
        })
    }

    /// A constant angle and scale on `stack`, entry 0 (no upload beyond a
    /// 16-byte placeholder).
    ///
    /// # Errors
    /// As [`GpuPose::new`].
    pub fn constant(
        ctx: &GpuContext,
        stack: &GpuStack,
        angle: f32,
        scale: f32,
    ) -> Result<Self, GpuError> {
        Self::new(
            ctx,
            stack,
            Field::Constant(angle),
            Field::Constant(scale),
            Field::Constant(0.0),
        )
    }
}
