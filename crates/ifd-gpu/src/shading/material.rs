//! A material on the device: closed-form zonal weights or lobe tables (one,
//! or a roughness family), the lobe directions, and the constants of the SH
//! recurrences at its degree.

use ifd_render::RoughnessFamily;
use ifd_shade::Material;
use ifd_shade::Model;
use ifd_shade::zonal_slice;
use ifd_shade::{LobeBasis, LobeTable};

use crate::context::GpuContext;
use crate::error::GpuError;
use crate::shaders::shade_codes;
use crate::wgpu_helpers::buffer_init;

/// The `struct Table` of `shaders/isd_shade.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct TableInfo {
    offset: u32,
    n_theta: u32,
    n_phi: u32,
    roughness: f32,
}

/// A material uploaded for shading (see the module docs).
#[derive(Debug)]
pub struct GpuMaterial {
    pub(crate) l_max: usize,
    pub(crate) code: u32,
    pub(crate) isotropic: bool,
    pub(crate) in_plane: bool,
    pub(crate) n_lobes: usize,
    pub(crate) count: usize,
    pub(crate) kc: usize,
    pub(crate) n_tables: usize,
    pub(crate) consts: wgpu::Buffer,
    pub(crate) lobes: wgpu::Buffer,
    pub(crate) weights: wgpu::Buffer,
    pub(crate) tables: wgpu::Buffer,
}

/// Table headers the kernel's uniform array holds (a roughness family's
/// tables at most).
pub(crate) const MAX_TABLES: usize = 64;

/// The kernel's `consts`: per `k < L + 1` the sectoral factor
/// `-sqrt((2m + 1) / 2m)` and `sqrt(2m + 3)` of order `m = k`, and `(pi_l,
/// k_l)` of band `l = k`; then the Legendre recurrence `(a_lm, b_lm)` of
/// `ifd_sphere::ShEvaluator` at `L + 1 + l (l + 1) / 2 + m`.
fn constants(l_max: usize, k: &[f64]) -> Vec<[f32; 4]> {
    let nb = l_max + 1;
    let mut c = Vec::with_capacity(nb + nb * (nb + 1) / 2);
    for i in 0..nb {
        let mf = i as f64;
        let q = if i == 0 {
            1.0
        } else {
            -((2.0 * mf + 1.0) / (2.0 * mf)).sqrt()
        };
        let kl = k.get(i).copied().unwrap_or(0.0);
        c.push([
            q as f32,
            (2.0 * mf + 3.0).sqrt() as f32,
            ifd_sphere::pi_l(i) as f32,
            kl as f32,
        ]);
    }
    for l in 0..nb {
        for m in 0..=l {
            let (lf, mf) = (l as f64, m as f64);
            if l >= m + 2 {
                let a = ((4.0 * lf * lf - 1.0) / (lf * lf - mf * mf)).sqrt();
                let l1 = lf - 1.0;
                let b = ((l1 * l1 - mf * mf) / (4.0 * l1 * l1 - 1.0)).sqrt();
                c.push([a as f32, b as f32, 0.0, 0.0]);
            } else {
                c.push([0.0; 4]);
            }
        }
    }
    c
}

impl GpuMaterial {
    /// Uploads a material: Lambert and Phong as closed-form zonal weights,
    /// the others as their lobe table.
    ///
    /// # Errors
    /// [`GpuError::Limit`] beyond the device's limits.
    pub fn new(ctx: &GpuContext, material: &Material) -> Result<Self, GpuError> {
        let l = material.l_max();
        if let Some(t) = material.table() {
            return Self::from_tables(ctx, l, &[(t, 0.0)]);
        }
        let code = match material.brdf().model() {
            Model::Lambert => shade_codes::MATERIAL_LAMBERT,
            Model::Phong { .. } => shade_codes::MATERIAL_PHONG,
            _ => {
                return Err(GpuError::Unsupported(format!(
                    "closed-form weights of {}",
                    material.brdf().spec()
                )));
            }
        };
        let k = zonal_slice(material.brdf(), [0.0, 0.0, 1.0], l)
            .map(|(_, k)| k)
            .unwrap_or_default();
        Self::build(ctx, l, code, &k, None, &[])
    }

    /// Uploads a roughness family (ISD with a roughness map): its tables, the
    /// kernel blending the two around each pixel's roughness as the CPU does.
    ///
    /// # Errors
    /// As [`Self::new`]; [`GpuError::Unsupported`] for tables of different
    /// lobe layouts.
    pub fn family(ctx: &GpuContext, family: &RoughnessFamily) -> Result<Self, GpuError> {
        let mut tables = Vec::new();
        for (m, r) in family.materials().iter().zip(family.roughness()) {
            let Some(t) = m.table() else {
                return Err(GpuError::Unsupported(
                    "a roughness family of closed-form materials".into(),
                ));
            };
            tables.push((t, *r));
        }
        Self::from_tables(ctx, family.l_max(), &tables)
    }

    fn from_tables(
        ctx: &GpuContext,
        l_max: usize,
        tables: &[(&LobeTable, f64)],
    ) -> Result<Self, GpuError> {
        let first = tables[0].0;
        for (t, _) in tables {
            let (h, f) = (t.header(), first.header());
            if h.lobes != f.lobes || h.channels != f.channels || h.isotropic != f.isotropic {
                return Err(GpuError::Unsupported(
                    "lobe tables of different lobe layouts in one material".into(),
                ));
            }
        }
        // the glTF BRDF's parts: every part against every colour channel
        let code = if first.header().brdf.starts_with("gltf-lobes") {
            shade_codes::MATERIAL_GLTF
        } else {
            shade_codes::MATERIAL_TABLE
        };
        Self::build(ctx, l_max, code, &[], Some(first.basis()), tables)
    }

    fn build(
        ctx: &GpuContext,
        l_max: usize,
        code: u32,
        k: &[f64],
        basis: Option<&LobeBasis>,
        tables: &[(&LobeTable, f64)],
    ) -> Result<Self, GpuError> {
        if tables.len() > MAX_TABLES {
            return Err(GpuError::Unsupported(format!(
                "{} lobe tables in one material (at most {MAX_TABLES})",
                tables.len()
            )));
        }
        let consts = constants(l_max, k);
        ctx.check_uniform("the shading constants", (consts.len() * 16) as u64)?;
        let mut lobes: Vec<[f32; 4]> = basis.map_or_else(Vec::new, |b| {
            b.directions()
                .iter()
                .enumerate()
                .map(|(j, d)| {
                    [
                        d[0] as f32,
                        d[1] as f32,
                        d[2] as f32,
                        b.first_band(j) as f32,
                    ]
                })
                .collect()
        });
        let n_lobes = lobes.len();
        // the kernel's uniform arrays have fixed sizes
        lobes.resize(2 * l_max + 1, [0.0; 4]);
        let total: usize = tables.iter().map(|(t, _)| t.raw_weights().len()).sum();
        ctx.check_buffer("the lobe tables", total as u64 * 4, true)?;
        let mut weights = Vec::with_capacity(total);
        let mut infos = Vec::with_capacity(tables.len());
        for (t, r) in tables {
            let offset = u32::try_from(weights.len()).map_err(|_| {
                GpuError::Unsupported("lobe tables of more than 2^32 weights".into())
            })?;
            infos.push(TableInfo {
                offset,
                n_theta: t.header().n_theta as u32,
                n_phi: t.header().n_phi as u32,
                roughness: *r as f32,
            });
            weights.extend_from_slice(t.raw_weights());
        }
        infos.resize(
            MAX_TABLES,
            TableInfo {
                offset: 0,
                n_theta: 0,
                n_phi: 0,
                roughness: 0.0,
            },
        );
        let header = tables.first().map(|(t, _)| t.header());
        let device = ctx.device();
        let (uniform, storage) = (wgpu::BufferUsages::UNIFORM, wgpu::BufferUsages::STORAGE);
        let (consts_b, lobes_b, weights_b, tables_b) =
            ctx.scoped("uploading the material", || {
                Ok((
                    buffer_init(device, "isd consts", bytemuck::cast_slice(&consts), uniform),
                    buffer_init(device, "isd lobes", bytemuck::cast_slice(&lobes), uniform),
                    buffer_init(
                        device,
                        "isd weights",
                        bytemuck::cast_slice(&weights),
                        storage,
                    ),
                    buffer_init(device, "isd tables", bytemuck::cast_slice(&infos), uniform),
                ))
            })?;
        Ok(Self {
            l_max,
            code,
            isotropic: header.is_none_or(|h| h.isotropic),
            in_plane: matches!(basis, Some(LobeBasis::InPlane(_))),
            n_lobes,
            count: basis.map_or(0, LobeBasis::count),
            kc: header.map_or(1, |h| h.channels),
            n_tables: tables.len(),
            consts: consts_b,
            lobes: lobes_b,
            weights: weights_b,
            tables: tables_b,
        })
    }

    /// Maximum degree `L`.
    #[must_use]
    pub fn l_max(&self) -> usize {
        self.l_max
    }

    /// Bytes on the device (tables, lobes, constants).
    #[must_use]
    pub fn bytes(&self) -> u64 {
        self.consts.size() + self.lobes.size() + self.weights.size() + self.tables.size()
    }
}

#[cfg(test)]
mod layout_tests {
    use super::TableInfo;
    use crate::layout::mirror;

    #[test]
    fn the_table_mirror_matches_isd_shade_wgsl() {
        mirror!(crate::shaders::isd_shade_source(7), "Table", TableInfo, [
            "offset" => offset, "n_theta" => n_theta, "n_phi" => n_phi,
            "roughness" => roughness,
        ]);
    }
}
