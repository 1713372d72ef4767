//! The table file: its [`TableHeader`], the BRDF digest that ties a file to
//! its BRDF, and [`LobeTable::write`]/[`LobeTable::read`] (format in the
//! module docs of `table`).

use std::io::{Read, Write};
use std::path::Path;

use super::{LobeBasis, LobeLayout, LobeTable, MAX_TABLE_DEGREE};
use crate::brdf::{Brdf, Model};
use crate::error::{Result, ShadeError};

const MAGIC: &[u8; 8] = b"IFDLOBES";
/// The format version this build reads and writes.
pub const VERSION: u32 = 2;

/// The self-describing header of a table file.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TableHeader {
    /// Always `"ifd-lobe-table"`.
    pub format: String,
    /// Format version ([`VERSION`]).
    pub version: u32,
    /// The BRDF spec the table was built for.
    pub brdf: String,
    /// FNV-1a digest of the BRDF (its spec, and a MERL file's values).
    pub brdf_digest: String,
    /// Maximum SH degree `L`.
    pub l_max: usize,
    /// Channels of the weights (3 for MERL, else 1).
    pub channels: usize,
    /// Whether the table is 1D over `theta_o` (isotropic BRDF).
    pub isotropic: bool,
    /// Entries over `theta_o`.
    pub n_theta: usize,
    /// Entries over `phi_o` (1 for isotropic tables).
    pub n_phi: usize,
    /// The lobe directions and how bands use them.
    pub lobes: LobeLayout,
    /// Largest relative L2 error of an interpolated slice at the midpoints
    /// between entries (see the module docs).
    pub interpolation_error: f64,
    /// Root mean square of the same errors.
    pub interpolation_rms: f64,
}

/// FNV-1a over bytes.
fn fnv1a(bytes: impl IntoIterator<Item = u8>, mut h: u64) -> u64 {
    for b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    h
}

/// A digest identifying a BRDF: its spec and, for MERL, the values read.
#[must_use]
pub fn brdf_digest(brdf: &Brdf) -> String {
    let mut h = fnv1a(brdf.spec().bytes(), 0xcbf2_9ce4_8422_2325);
    if let Model::Merl(m) = brdf.model() {
        h = fnv1a(m.digest_bytes(), h);
    }
    format!("{h:016x}")
}

impl LobeTable {
    /// Writes the table (atomically; format in the module docs).
    ///
    /// # Errors
    /// [`ShadeError::File`].
    pub fn write(&self, path: &Path) -> Result<()> {
        let header = serde_json::to_vec(&self.header).map_err(|e| ShadeError::File {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        ifd_image::atomic_write(path, |w| {
            let e = |e: std::io::Error| e.to_string();
            w.write_all(MAGIC).map_err(e)?;
            w.write_all(&(header.len() as u32).to_le_bytes())
                .map_err(e)?;
            w.write_all(&header).map_err(e)?;
            for v in &self.weights {
                w.write_all(&v.to_le_bytes()).map_err(e)?;
            }
            Ok(())
        })
        .map_err(|e| ShadeError::File {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })
    }

    /// Reads a table, checking everything the module docs list.
    ///
    /// # Errors
    /// [`ShadeError::File`] naming the file and the problem.
    pub fn read(path: &Path) -> Result<Self> {
        let ferr = |reason: String| ShadeError::File {
            path: path.to_path_buf(),
            reason,
        };
        let meta = std::fs::metadata(path).map_err(|e| ferr(format!("cannot read: {e}")))?;
        if !meta.is_file() {
            return Err(ferr("not a regular file".into()));
        }
        let file_len = meta.len();
        let mut file = std::fs::File::open(path).map_err(|e| ferr(format!("cannot read: {e}")))?;
        let mut head = [0u8; 12];
        if file_len < 12 || file.read_exact(&mut head).is_err() || &head[..8] != MAGIC {
            return Err(ferr(
                "not an ifd lobe table (it does not start with IFDLOBES; build one with \
                 `ifd sphere brdf`)"
                    .into(),
            ));
        }
        let hl = u64::from(u32::from_le_bytes([head[8], head[9], head[10], head[11]]));
        if 12 + hl > file_len {
            return Err(ferr(format!(
                "truncated: the header declares {hl} bytes, the file has {}",
                file_len - 12
            )));
        }
        let mut hbytes = vec![0u8; hl as usize];
        file.read_exact(&mut hbytes)
            .map_err(|e| ferr(format!("cannot read the header: {e}")))?;
        let hbytes = hbytes.as_slice();
        let header: TableHeader =
            serde_json::from_slice(hbytes).map_err(|e| ferr(format!("malformed header: {e}")))?;
        if header.format != "ifd-lobe-table" {
            return Err(ferr(format!(
                "format {:?} is not ifd-lobe-table",
                header.format
            )));
        }
        if header.version != VERSION {
            return Err(ferr(format!(
                "table version {} is not supported (this build reads version {VERSION}{})",
                header.version,
                if header.version == 1 {
                    "; version 1 predates in-plane lobes: rebuild the table with `ifd sphere brdf`"
                } else {
                    ""
                }
            )));
        }
        let h = &header;
        let shape_ok = h.l_max <= MAX_TABLE_DEGREE
            && (1..=3).contains(&h.channels)
            && (2..=4096).contains(&h.n_theta)
            && (1..=4096).contains(&h.n_phi)
            && (h.isotropic == (h.n_phi == 1))
            && (h.isotropic || matches!(h.lobes, LobeLayout::Shared { .. }))
            // the layout's degree before building its matrices
            && match &h.lobes {
                LobeLayout::Shared { directions } => directions.l_max() == h.l_max,
                LobeLayout::InPlane { angles } => angles.len() == h.l_max + 1,
            };
        if !shape_ok {
            return Err(ferr(format!(
                "inconsistent header: L = {}, {} channel(s), {} x {} entries, isotropic {}, \
                 {} lobes",
                h.l_max,
                h.channels,
                h.n_theta,
                h.n_phi,
                h.isotropic,
                h.lobes.name()
            )));
        }
        if let LobeLayout::Shared { directions } = &h.lobes {
            directions
                .check()
                .map_err(|e| ferr(format!("lobe directions: {e}")))?;
        }
        let basis =
            LobeBasis::new(&h.lobes, h.l_max).map_err(|e| ferr(format!("lobe directions: {e}")))?;
        let count = (h.n_theta as u64) * (h.n_phi as u64) * (basis.count() * h.channels) as u64;
        let have = file_len - 12 - hl;
        if have != 4 * count {
            return Err(ferr(format!(
                "{have} bytes of weights, the header declares {count} f32 values ({} bytes){}",
                4 * count,
                if have < 4 * count { ": truncated" } else { "" }
            )));
        }
        let mut data = Vec::with_capacity(have as usize);
        file.read_to_end(&mut data)
            .map_err(|e| ferr(format!("cannot read the weights: {e}")))?;
        if data.len() as u64 != have {
            return Err(ferr("the file changed while it was read".into()));
        }
        let weights: Vec<f32> = data
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        if let Some(i) = weights.iter().position(|v| !v.is_finite()) {
            return Err(ferr(format!("weight {i} is not finite")));
        }
        Ok(Self {
            header,
            basis,
            weights,
        })
    }
}
