//! [`GpuDecomposition`]: decompositions uploaded as one buffer of terms with
//! their entries' offsets.

use bytemuck::{Pod, Zeroable};
use ifd_planar::{FilterError, Prepare, PreparedDecomposition, Sampling};

use crate::context::GpuContext;
use crate::error::GpuError;
use crate::wgpu_helpers::buffer_init;

/// The shader's `struct Term`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(super) struct GpuTerm {
    pub(super) weight: f32,
    pub(super) cx: f32,
    pub(super) cy: f32,
    pub(super) ln_sigma: f32,
}

/// One or more decompositions ("entries") on the GPU, terms concatenated.
///
/// A plain filter is one entry. The aspect-ratio bank of anisotropic
/// smoothing is one entry per aspect ratio; each pixel then blends entries
/// `i` and `i + 1` with weight `t` (the pose's entry value `i + t`).
#[derive(Debug)]
pub struct GpuDecomposition {
    pub(super) terms: wgpu::Buffer,
    pub(super) entries: wgpu::Buffer,
    pub(super) n_entries: u32,
    pub(super) n_terms: usize,
    pub(super) sigma_range: (f64, f64),
    pub(super) sampling: Sampling,
    /// Every term's sigma, in upload order (to locate levels on the host).
    pub(super) sigmas: Vec<f64>,
}

impl GpuDecomposition {
    /// Uploads one decomposition (an [`ifd_planar::Decomposition`], checked here, or an
    /// [`ifd_planar::PreparedDecomposition`], checked once for every path).
    ///
    /// # Errors
    /// As [`GpuDecomposition::from_entries`].
    pub fn new(
        ctx: &GpuContext,
        decomposition: &(impl Prepare + ?Sized),
    ) -> Result<Self, GpuError> {
        Self::from_entries(ctx, &[decomposition.prepare()?.into_owned()])
    }

    /// Uploads several decompositions, concatenated with their offsets.
    ///
    /// # Errors
    /// [`FilterError::InvalidParameter`] for no entries or entries applied
    /// with different [`Sampling`]s, [`GpuError::Limit`] when the terms
    /// exceed a device limit. The terms were checked when the entries were
    /// prepared ([`PreparedDecomposition::new`]), as for the CPU path.
    pub fn from_entries(
        ctx: &GpuContext,
        entries: &[PreparedDecomposition],
    ) -> Result<Self, GpuError> {
        let Some(first) = entries.first() else {
            return Err(FilterError::InvalidParameter("no decompositions given".into()).into());
        };
        let sampling = first.sampling();
        if let Some(e) = entries.iter().position(|e| e.sampling() != sampling) {
            return Err(FilterError::InvalidParameter(format!(
                "decomposition {e} is applied as {:?}, decomposition 0 as {sampling:?}: \
                 entries of one upload share their sampling",
                entries[e].sampling()
            ))
            .into());
        }
        let mut terms = Vec::new();
        let mut sigmas = Vec::new();
        let mut offsets: Vec<[u32; 2]> = Vec::with_capacity(entries.len());
        let mut lo = f64::INFINITY;
        let mut hi = 0.0f64;
        for entry in entries {
            offsets.push([terms.len() as u32, entry.len() as u32]);
            let (a, b) = entry.sigma_range();
            lo = lo.min(a);
            hi = hi.max(b);
            sigmas.extend(entry.terms().iter().map(|t| t.sigma));
            terms.extend(entry.terms().iter().map(|t| GpuTerm {
                weight: t.weight as f32,
                cx: t.x as f32,
                cy: t.y as f32,
                ln_sigma: t.sigma.ln() as f32,
            }));
        }
        let bytes = (terms.len() * std::mem::size_of::<GpuTerm>()) as u64;
        ctx.check_buffer(&format!("{} decomposition terms", terms.len()), bytes, true)?;
        let device = ctx.device();
        let (tb, eb) = ctx.scoped("uploading the decomposition", || {
            Ok((
                buffer_init(
                    device,
                    "ifd terms",
                    bytemuck::cast_slice(&terms),
                    wgpu::BufferUsages::STORAGE,
                ),
                buffer_init(
                    device,
                    "ifd entries",
                    bytemuck::cast_slice(&offsets),
                    wgpu::BufferUsages::STORAGE,
                ),
            ))
        })?;
        Ok(Self {
            terms: tb,
            entries: eb,
            n_entries: offsets.len() as u32,
            n_terms: terms.len(),
            sigma_range: (lo, hi),
            sampling,
            sigmas,
        })
    }

    /// Number of entries.
    #[must_use]
    pub fn entries(&self) -> usize {
        self.n_entries as usize
    }

    /// Total number of terms.
    #[must_use]
    pub fn terms(&self) -> usize {
        self.n_terms
    }
}
