//! The environment on the device, in either variant of Eq. 22.

use ifd_shade::{BandMaps, Environment};

use crate::context::GpuContext;
use crate::error::GpuError;
use crate::wgpu_helpers::buffer_init;

/// How the kernel gets the per-band environment `Ehat_l(d)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EnvVariant {
    /// Reconstructed from the SH coefficients at each rotated lobe direction
    /// (`(L + 1)^2` recurrence steps per lobe).
    Sh,
    /// Read from per-band prefiltered maps (16 Catmull-Rom taps per band and
    /// lobe, weights computed in the kernel).
    Maps,
}

/// An environment uploaded for shading: SH coefficients or per-band maps,
/// always as RGB (a grey environment is repeated in the three channels).
#[derive(Debug)]
pub struct GpuEnvironment {
    /// `(L + 1)^2` RGB0 coefficients (uniform; zeros for maps).
    pub(crate) sh: wgpu::Buffer,
    /// The maps (storage; 16 bytes for SH).
    pub(crate) maps: wgpu::Buffer,
    pub(crate) l_max: usize,
    pub(crate) channels: usize,
    pub(crate) variant: EnvVariant,
    pub(crate) map_size: (usize, usize),
}

/// `values` (`channels` per item) as RGB(A) floats, `stride` per item.
fn rgb(values: &[f32], channels: usize, stride: usize) -> Vec<f32> {
    let n = values.len() / channels;
    let mut out = vec![0.0f32; n * stride];
    for (o, v) in out
        .chunks_exact_mut(stride)
        .zip(values.chunks_exact(channels))
    {
        for c in 0..3 {
            o[c] = v[c.min(channels - 1)];
        }
    }
    out
}

impl GpuEnvironment {
    /// The SH coefficients of `env` ([`EnvVariant::Sh`]).
    ///
    /// # Errors
    /// [`GpuError::Unsupported`] for other than 1 or 3 channels;
    /// [`GpuError::Limit`] for coefficients beyond a uniform binding (`L` 63
    /// with the usual 64 KiB).
    pub fn sh(ctx: &GpuContext, env: &Environment) -> Result<Self, GpuError> {
        let ch = env.channels();
        check_channels(ch)?;
        let values: Vec<f32> = env.coeffs().data().iter().map(|&v| v as f32).collect();
        let data = rgb(&values, ch, 4);
        Self::upload(ctx, &data, &[], env.l_max(), ch, EnvVariant::Sh, (0, 0))
    }

    /// The per-band prefiltered maps ([`EnvVariant::Maps`]).
    ///
    /// # Errors
    /// As [`Self::sh`]; maps larger than a storage binding (`L` about 60 on
    /// lavapipe's 128 MiB) are a [`GpuError::Limit`].
    pub fn maps(ctx: &GpuContext, maps: &BandMaps) -> Result<Self, GpuError> {
        let ch = maps.channels();
        check_channels(ch)?;
        let (w, h) = maps.size();
        let bytes = (maps.data().len() / ch * 12) as u64;
        ctx.check_buffer("the per-band environment maps", bytes, true)?;
        let data = rgb(maps.data(), ch, 3);
        let l_max = ifd_shade::Bands::l_max(maps);
        let zeros = vec![0.0f32; 4 * (l_max + 1) * (l_max + 1)];
        Self::upload(ctx, &zeros, &data, l_max, ch, EnvVariant::Maps, (w, h))
    }

    fn upload(
        ctx: &GpuContext,
        sh: &[f32],
        maps: &[f32],
        l_max: usize,
        channels: usize,
        variant: EnvVariant,
        map_size: (usize, usize),
    ) -> Result<Self, GpuError> {
        ctx.check_uniform(
            "the SH coefficients of the environment",
            std::mem::size_of_val(sh) as u64,
        )?;
        ctx.check_buffer("the environment", std::mem::size_of_val(maps) as u64, true)?;
        let (sh, maps) = ctx.scoped("uploading the environment", || {
            Ok((
                buffer_init(
                    ctx.device(),
                    "isd environment sh",
                    bytemuck::cast_slice(sh),
                    wgpu::BufferUsages::UNIFORM,
                ),
                buffer_init(
                    ctx.device(),
                    "isd environment maps",
                    bytemuck::cast_slice(maps),
                    wgpu::BufferUsages::STORAGE,
                ),
            ))
        })?;
        Ok(Self {
            sh,
            maps,
            l_max,
            channels,
            variant,
            map_size,
        })
    }

    /// The variant.
    #[must_use]
    pub fn variant(&self) -> EnvVariant {
        self.variant
    }

    /// Maximum degree `L`.
    #[must_use]
    pub fn l_max(&self) -> usize {
        self.l_max
    }

    /// Channels of the source (1 or 3; the device copy is RGB).
    #[must_use]
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// Bytes on the device.
    #[must_use]
    pub fn bytes(&self) -> u64 {
        self.sh.size() + self.maps.size()
    }
}

fn check_channels(ch: usize) -> Result<(), GpuError> {
    if ch == 1 || ch == 3 {
        Ok(())
    } else {
        Err(GpuError::Unsupported(format!(
            "an environment of {ch} channels (1 or 3 are shaded)"
        )))
    }
}
