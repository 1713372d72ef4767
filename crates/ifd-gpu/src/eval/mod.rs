//! The evaluation dispatch ([`GpuContext::evaluate`]) and its parameter
//! block; the uploads it reads are in `decomposition.rs` (terms) and
//! `pose.rs` (per-pixel maps), its result in `output.rs`.

mod decomposition;
mod output;
mod pose;

use bytemuck::{Pod, Zeroable};
use ifd_image::Image;
use ifd_planar::{Border, FilterError, Sampling};

pub use self::decomposition::GpuDecomposition;
pub use self::output::GpuOutput;
pub use self::pose::GpuPose;
use self::pose::check_scale_map_reads;
use crate::context::GpuContext;
use crate::error::GpuError;
use crate::shaders::codes;
use crate::stack::GpuStack;
use crate::wgpu_helpers::{Timestamps, buffer_init, check_region, entry};

/// The shader's `struct Params`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct Params {
    region_x0: u32,
    region_y0: u32,
    region_w: u32,
    region_h: u32,
    width: u32,
    height: u32,
    channels: u32,
    chunk_c0: u32,
    chunk_nc: u32,
    n_levels: u32,
    border_mode: u32,
    border_value: f32,
    inv_ln_ratio: f32,
    cos_t: f32,
    sin_t: f32,
    scale: f32,
    u_offset: f32,
    entry: f32,
    flags: u32,
    rot_off: u32,
    scale_off: u32,
    entry_off: u32,
    n_entries: u32,
    /// 0 bilinear, 1 cubic B-spline (`INTERP_*` in the shader).
    interpolation: u32,
    /// How the decomposition's kernel was sampled (`SAMPLING_*` in the
    /// shader): the atoms' effective sigma at each scale.
    sampling: u32,
    /// Within this fraction of the level spacing a sigma reads one level:
    /// `1e-4` (f32 rounding of positions on a level), or 0.5 on a stack read
    /// at the nearest level ([`ifd_planar::StackOptions::nearest_level`]).
    level_snap: f32,
    pad: [u32; 2],
}

/// `Params::level_snap` on a stack read blending levels: f32 level
/// positions of up to ~20 levels carry rounding errors near 2e-6; snapping
/// within 1e-4 of the spacing changes a result by at most 1e-4 of the
/// difference between neighbouring levels.
const LEVEL_SNAP: f32 = 1e-4;

/// `Params::level_snap` on a stack read at the nearest level: the CPU's
/// rule (every sigma but one exactly half-way reads one level).
const NEAREST_SNAP: f32 = 0.5;

/// The shader's `struct TermLevel`: the levels a term reads at a constant
/// scale and their weights, located on the host as the CPU path locates them
/// ([`ifd_planar::LevelLocator::locate`]).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct GpuTermLevel {
    a: u32,
    b: u32,
    wa: f32,
    wb: f32,
}

/// A rectangle of output pixels, inside the image: the CPU path's
/// [`ifd_planar::PixelRect`], under the name the GPU API has used.
pub use ifd_planar::PixelRect as Region;

impl GpuContext {
    /// Evaluates over the whole image, as [`GpuContext::evaluate`] with no
    /// region, and reads the result back; in bands of rows when the result
    /// exceeds the device's `max_storage_buffer_binding_size` or
    /// `max_buffer_size` (each band is one evaluation and one readback), so
    /// the size of the result is limited by host memory, not the device.
    ///
    /// # Errors
    /// As [`GpuContext::evaluate`] and [`GpuOutput::read`]; [`GpuError::Limit`]
    /// when not even one row fits.
    pub fn evaluate_image(
        &self,
        stack: &GpuStack,
        decomposition: &GpuDecomposition,
        pose: &GpuPose,
    ) -> Result<Image, GpuError> {
        let (w, h, c) = (stack.width(), stack.height(), stack.channels());
        let limits = self.device().limits();
        let cap = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        let rows = (cap / (w * c * 4).max(1) as u64).clamp(1, h.max(1) as u64) as usize;
        if rows >= h {
            return self.evaluate(stack, decomposition, pose, None)?.read(self);
        }
        let mut data = Vec::with_capacity(w * h * c);
        for y0 in (0..h).step_by(rows) {
            let band = Region {
                x0: 0,
                y0,
                width: w,
                height: rows.min(h - y0),
            };
            let part = self
                .evaluate(stack, decomposition, pose, Some(band))?
                .read(self)?;
            data.extend_from_slice(part.data());
        }
        Image::from_vec(w, h, c, data).map_err(|e| GpuError::Readback {
            what: "the result",
            reason: e.to_string(),
        })
    }

    /// Evaluates `decomposition` (rotated, scaled and blended per `pose`) on
    /// `stack` over `region` (the whole image when `None`): the GPU version of
    /// [`ifd_planar::Filter::apply`], one trilinear lookup per term and pixel.
    /// The work is submitted; [`GpuOutput::read`] waits for it.
    ///
    /// ```no_run
    /// use ifd_gpu::{GpuContext, GpuDecomposition, GpuPose, GpuStack};
    /// use ifd_planar::{Border, Decomposition, StackOptions, Term, stack_for_decomposition};
    /// let ctx = GpuContext::new()?;
    /// let img = ifd_image::read("testdata/camera.png")?;
    /// let d = Decomposition::from_terms(vec![Term { weight: 1.0, x: 4.0, y: 0.0, sigma: 2.0 }]);
    /// let stack = stack_for_decomposition(&img, &d, 1.0, 1.0, Border::Reflect101, StackOptions::default())?;
    /// let gstack = GpuStack::upload(&ctx, &stack)?;
    /// let gd = GpuDecomposition::new(&ctx, &d)?;
    /// let pose = GpuPose::constant(&ctx, &gstack, 30.0, 1.0)?;
    /// let out = ctx.evaluate(&gstack, &gd, &pose, None)?.read(&ctx)?;
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`FilterError::ScaleOutOfRange`] when some `scale * sigma_t` is not
    /// covered by the stack, [`FilterError::InvalidParameter`] for a region
    /// outside the image or a pose made for another stack, a bank entry past
    /// the last, [`GpuError::Limit`] for an output larger than the device's
    /// buffer limits, [`GpuError::Device`] for a wgpu error.
    pub fn evaluate(
        &self,
        stack: &GpuStack,
        decomposition: &GpuDecomposition,
        pose: &GpuPose,
        region: Option<Region>,
    ) -> Result<GpuOutput, GpuError> {
        let (w, h) = (stack.width(), stack.height());
        if (pose.width, pose.height) != (stack.width, stack.height) {
            return Err(FilterError::InvalidParameter(format!(
                "the pose was made for a {}x{} image, the stack is {w}x{h}",
                pose.width, pose.height
            ))
            .into());
        }
        // A pose made for a log-uniform stack of the same size may be
        // handed a stack at given sigmas: its scale map cannot be read there.
        check_scale_map_reads(stack, pose.flags & codes::FLAG_SCALE_MAP != 0)?;
        let region = region.unwrap_or(Region::full(w, h));
        check_region(region, w, h, "image")?;
        if pose.flags & codes::FLAG_ENTRY_MAP == 0
            && pose.entry > (decomposition.n_entries - 1) as f32
        {
            return Err(FilterError::InvalidParameter(format!(
                "bank entry {} is past the last entry {}",
                pose.entry,
                decomposition.n_entries - 1
            ))
            .into());
        }
        // Coverage, as the CPU's Filter::check_scales.
        let (min, max) = stack.sigma_range;
        let (slo, shi) = decomposition.sigma_range;
        let (s_lo, s_hi) = pose.scale_range;
        let (need_lo, need_hi) = ifd_planar::sigma_bounds(
            decomposition.sampling,
            (slo, shi),
            (f64::from(s_lo), f64::from(s_hi)),
        );
        for (((scale, location), term_sigma), needed) in [s_lo, s_hi]
            .into_iter()
            .zip(&pose.scale_where)
            .zip([slo, shi])
            .zip([need_lo, need_hi])
        {
            if !stack.covers(needed) {
                return Err(FilterError::ScaleOutOfRange {
                    scale: f64::from(scale),
                    location: location.clone(),
                    term_sigma,
                    needed,
                    min,
                    max,
                }
                .into());
            }
        }
        debug_assert!(pose.scale_range.0 <= pose.scale_range.1);
        let (rw, rh) = (region.width as u32, region.height as u32);
        self.check_dispatch("the evaluation", rw, rh)?;
        let out_bytes = (region.width * region.height * stack.channels()) as u64 * 4;
        self.check_buffer(
            &format!(
                "the {}x{}x{} result",
                region.width,
                region.height,
                stack.channels()
            ),
            out_bytes,
            true,
        )?;
        let (border_mode, border_value) = match stack.border {
            Border::Reflect101 => (codes::BORDER_REFLECT101, 0.0),
            Border::Constant(v) => (codes::BORDER_CONSTANT, v),
            Border::Replicate => (codes::BORDER_REPLICATE, 0.0),
            Border::Wrap => (codes::BORDER_WRAP, 0.0),
        };
        // A constant scale: every term's levels located here, once, as the
        // CPU path locates them (one lookup per term on a stack at the
        // terms' sigmas), instead of per pixel in the shader.
        let mut flags = pose.flags;
        let term_levels: Vec<GpuTermLevel> = if pose.flags & codes::FLAG_SCALE_MAP == 0 {
            flags |= codes::FLAG_TERM_LEVELS;
            let s = f64::from(pose.scale);
            decomposition
                .sigmas
                .iter()
                .map(|&sigma| {
                    let (a, b, wa, wb) = stack
                        .locator
                        .locate(decomposition.sampling.effective_sigma(sigma, s));
                    GpuTermLevel {
                        a: a as u32,
                        b: b as u32,
                        wa,
                        wb,
                    }
                })
                .collect()
        } else {
            Vec::new()
        };
        let device = self.device();
        self.scoped("evaluating the decomposition", || {
            let levels_buffer = buffer_init(
                device,
                "ifd term levels",
                if term_levels.is_empty() {
                    &[0u8; 16]
                } else {
                    bytemuck::cast_slice(&term_levels)
                },
                wgpu::BufferUsages::STORAGE,
            );
            let output = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("ifd result"),
                size: out_bytes.max(16),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let binds: Vec<wgpu::BindGroup> = stack
                .chunks
                .iter()
                .map(|chunk| {
                    let params = Params {
                        region_x0: region.x0 as u32,
                        region_y0: region.y0 as u32,
                        region_w: rw,
                        region_h: rh,
                        width: stack.width,
                        height: stack.height,
                        channels: stack.channels,
                        chunk_c0: chunk.c0,
                        chunk_nc: chunk.nc,
                        n_levels: stack.n_levels,
                        border_mode,
                        border_value,
                        inv_ln_ratio: stack.ln_params.1 as f32,
                        cos_t: pose.cos_t,
                        sin_t: pose.sin_t,
                        scale: pose.scale,
                        u_offset: pose.u_offset,
                        entry: pose.entry,
                        flags,
                        rot_off: pose.rot_off,
                        scale_off: pose.scale_off,
                        entry_off: pose.entry_off,
                        n_entries: decomposition.n_entries,
                        interpolation: match stack.interpolation {
                            ifd_planar::Interpolation::Linear => codes::INTERP_LINEAR,
                            ifd_planar::Interpolation::Cubic => codes::INTERP_CUBIC,
                        },
                        sampling: match decomposition.sampling {
                            Sampling::Continuous => codes::SAMPLING_CONTINUOUS,
                            Sampling::Point => codes::SAMPLING_POINT,
                            Sampling::Area => codes::SAMPLING_AREA,
                            Sampling::Averaged => codes::SAMPLING_AVERAGED,
                        },
                        level_snap: if stack.locator.reads_nearest_level() {
                            NEAREST_SNAP
                        } else {
                            LEVEL_SNAP
                        },
                        pad: [0; 2],
                    };
                    let pb = buffer_init(
                        device,
                        "ifd params",
                        bytemuck::bytes_of(&params),
                        wgpu::BufferUsages::UNIFORM,
                    );
                    device.create_bind_group(&wgpu::BindGroupDescriptor {
                        label: Some("ifd_eval"),
                        layout: &self.eval_layout,
                        entries: &[
                            entry(0, &pb),
                            entry(1, &chunk.levels),
                            entry(2, &chunk.data),
                            entry(3, &decomposition.terms),
                            entry(4, &decomposition.entries),
                            entry(5, &pose.maps),
                            entry(6, &output),
                            entry(7, &levels_buffer),
                        ],
                    })
                })
                .collect();
            let timing = Timestamps::new(self, "ifd timestamps");
            let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("ifd_eval"),
            });
            {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("ifd_eval"),
                    timestamp_writes: timing.as_ref().map(Timestamps::writes),
                });
                pass.set_pipeline(&self.eval_pipeline);
                for bind in &binds {
                    pass.set_bind_group(0, bind, &[]);
                    pass.dispatch_workgroups(rw.div_ceil(8), rh.div_ceil(8), 1);
                }
            }
            if let Some(t) = &timing {
                t.resolve(&mut enc);
            }
            self.queue().submit([enc.finish()]);
            Ok(GpuOutput {
                buffer: output,
                region,
                channels: stack.channels(),
                timestamps: timing.map(|t| t.resolve),
            })
        })
    }
}

#[cfg(test)]
mod layout_tests {
    use super::decomposition::GpuTerm;
    use super::{GpuTermLevel, Params};
    use crate::layout::mirror;

    #[test]
    fn the_mirrors_match_ifd_eval_wgsl() {
        let src = crate::shaders::ifd_eval_source();
        mirror!(src, "Params", Params, [
            "region_x0" => region_x0, "region_y0" => region_y0, "region_w" => region_w,
            "region_h" => region_h, "width" => width, "height" => height,
            "channels" => channels, "chunk_c0" => chunk_c0, "chunk_nc" => chunk_nc,
            "n_levels" => n_levels, "border_mode" => border_mode,
            "border_value" => border_value, "inv_ln_ratio" => inv_ln_ratio,
            "cos_t" => cos_t, "sin_t" => sin_t, "scale" => scale, "u_offset" => u_offset,
            "entry" => entry, "flags" => flags, "rot_off" => rot_off,
            "scale_off" => scale_off, "entry_off" => entry_off, "n_entries" => n_entries,
            "interpolation" => interpolation, "sampling" => sampling,
            "level_snap" => level_snap, "_pad1" => pad, "_pad2" => pad + 4,
        ]);
        mirror!(src, "Term", GpuTerm, [
            "weight" => weight, "cx" => cx, "cy" => cy, "ln_sigma" => ln_sigma,
        ]);
        mirror!(src, "TermLevel", GpuTermLevel, ["a" => a, "b" => b, "wa" => wa, "wb" => wb]);
    }
}
