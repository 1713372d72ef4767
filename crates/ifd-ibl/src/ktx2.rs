//! A KTX2 writer for RGBA16F cube maps (the container engines load).
//!
//! The derivation and conventions are documented on [`encode_ktx2_cube`].

use std::io::Write;
use std::path::Path;

use half::f16;

use crate::cube::CubeLevel;
use crate::error::{IblError, Result, param};

/// `VK_FORMAT_R16G16B16A16_SFLOAT`.
pub const VK_FORMAT_R16G16B16A16_SFLOAT: u32 = 97;

const IDENTIFIER: [u8; 12] = [
    0xAB, b'K', b'T', b'X', b' ', b'2', b'0', 0xBB, b'\r', b'\n', 0x1A, b'\n',
];

/// Encodes a full or partial mip chain (level 0 first, each level half the
/// previous size) as a KTX2 cube map; returns the bytes and how many values
/// were clamped to the half-float range.
///
/// ```
/// use ifd_ibl::{CubeLevel, encode_ktx2_cube};
/// let levels = [CubeLevel::zeros(4), CubeLevel::zeros(2), CubeLevel::zeros(1)];
/// let (bytes, clamped) = encode_ktx2_cube(&levels)?;
/// assert_eq!(&bytes[1..4], b"KTX");
/// assert_eq!(clamped, 0);
/// # Ok::<(), ifd_ibl::IblError>(())
/// ```
///
/// # Errors
/// An empty chain, or levels whose sizes do not halve.
///
/// Layout (KTX 2.0 specification, Khronos): the 12-byte identifier; the
/// header (`vkFormat = 97` `VK_FORMAT_R16G16B16A16_SFLOAT`, `typeSize = 2`,
/// `pixelWidth = pixelHeight = N`, `pixelDepth = 0`, `layerCount = 0`,
/// `faceCount = 6`, `levelCount = M`, no supercompression); the index
/// (offsets of the data format descriptor and key/value data); the level
/// index (offset and length of every level, level 0 first); the data format
/// descriptor (one basic block: RGBSDA colour model, BT.709 primaries,
/// linear transfer, four 16-bit signed-float samples R, G, B, A with
/// `sampleLower = -1.0f`, `sampleUpper = 1.0f`); key/value data
/// (`KTXwriter`); then the levels, **smallest first** as the specification
/// recommends, each 8-byte aligned, every level's six faces in order
/// `+X, -X, +Y, -Y, +Z, -Z`, rows from the top. Alpha is 1.
///
/// Values beyond the half-float range (65504) are clamped to it and counted.
pub fn encode_ktx2_cube(levels: &[CubeLevel]) -> Result<(Vec<u8>, usize)> {
    let Some(first) = levels.first() else {
        return Err(param("KTX2 levels", "no level to write"));
    };
    let n = first.size;
    for (m, l) in levels.iter().enumerate() {
        let want = (n >> m).max(1);
        if l.size != want || l.data.len() != 6 * want * want * 3 {
            return Err(param(
                "KTX2 levels",
                format!("level {m} is {0}x{0}, expected {want}x{want}", l.size),
            ));
        }
    }
    let m = levels.len();
    // the fixed parts
    let header_len = 12 + 9 * 4 + 4 * 4 + 2 * 8;
    let level_index_len = 24 * m;
    let dfd_offset = header_len + level_index_len;
    let dfd = data_format_descriptor();
    let kvd_offset = dfd_offset + dfd.len();
    let kvd = key_value_data();
    let data_start = (kvd_offset + kvd.len()).next_multiple_of(8);
    // level data, smallest level first in the file
    let level_bytes: Vec<usize> = levels.iter().map(|l| 6 * l.size * l.size * 8).collect();
    let mut offsets = vec![0usize; m];
    let mut at = data_start;
    for k in (0..m).rev() {
        offsets[k] = at;
        at = (at + level_bytes[k]).next_multiple_of(8);
    }
    let mut out = Vec::with_capacity(at);
    out.extend_from_slice(&IDENTIFIER);
    for v in [
        VK_FORMAT_R16G16B16A16_SFLOAT,
        2,
        n as u32,
        n as u32,
        0,
        0,
        6,
        m as u32,
        0,
    ] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for v in [
        dfd_offset as u32,
        dfd.len() as u32,
        kvd_offset as u32,
        kvd.len() as u32,
    ] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.extend_from_slice(&0u64.to_le_bytes());
    out.extend_from_slice(&0u64.to_le_bytes());
    for k in 0..m {
        out.extend_from_slice(&(offsets[k] as u64).to_le_bytes());
        out.extend_from_slice(&(level_bytes[k] as u64).to_le_bytes());
        out.extend_from_slice(&(level_bytes[k] as u64).to_le_bytes());
    }
    out.extend_from_slice(&dfd);
    out.extend_from_slice(&kvd);
    let mut clamped = 0;
    for k in (0..m).rev() {
        out.resize(offsets[k], 0);
        for px in levels[k].data.chunks_exact(3) {
            for &v in px {
                let h = f16::from_f32(v);
                let h = if h.is_infinite() || v.abs() > 65504.0 {
                    clamped += 1;
                    f16::from_f32(65504.0f32.copysign(v))
                } else {
                    h
                };
                out.extend_from_slice(&h.to_le_bytes());
            }
            out.extend_from_slice(&f16::ONE.to_le_bytes());
        }
    }
    Ok((out, clamped))
}

/// Writes [`encode_ktx2_cube`]'s bytes to `path` atomically (a temporary file in
/// the same folder, renamed over `path`); returns the clamped count.
///
/// # Errors
/// As [`encode_ktx2_cube`]; [`IblError::Write`] when the file cannot be written.
pub fn write_ktx2_cube(path: &Path, levels: &[CubeLevel]) -> Result<usize> {
    let (bytes, clamped) = encode_ktx2_cube(levels)?;
    ifd_image::atomic_write(path, |w| w.write_all(&bytes).map_err(|e| e.to_string())).map_err(
        |e| IblError::Write {
            path: path.to_path_buf(),
            reason: e.to_string(),
        },
    )?;
    Ok(clamped)
}

/// The basic data format descriptor block for RGBA16F, with its total-size
/// prefix (92 bytes).
fn data_format_descriptor() -> Vec<u8> {
    const SAMPLES: u32 = 4;
    let block_size = 24 + 16 * SAMPLES;
    let mut words: Vec<u32> = vec![
        4 + block_size,           // dfdTotalSize
        0,                        // vendorId 0 (Khronos), descriptorType 0 (basic)
        2 | (block_size << 16),   // versionNumber 2 (1.3), descriptorBlockSize
        1 | (1 << 8) | (1 << 16), // RGBSDA, BT709, LINEAR, flags 0 (straight alpha)
        0,                        // texelBlockDimension 1x1x1x1
        8,                        // bytesPlane0 = 8
        0,
    ];
    // channel ids R=0, G=1, B=2, A=15; qualifiers FLOAT (0x80) | SIGNED (0x40)
    for (k, id) in [0u32, 1, 2, 15].into_iter().enumerate() {
        let channel_type = 0x80 | 0x40 | id;
        words.push((16 * k as u32) | (15 << 16) | (channel_type << 24));
        words.push(0); // sample position
        words.push((-1.0f32).to_bits());
        words.push(1.0f32.to_bits());
    }
    words.iter().flat_map(|w| w.to_le_bytes()).collect()
}

/// Key/value data: `KTXwriter`, padded to 4 bytes.
fn key_value_data() -> Vec<u8> {
    let mut kv = b"KTXwriter\0".to_vec();
    kv.extend_from_slice(format!("ifd {}\0", env!("CARGO_PKG_VERSION")).as_bytes());
    let mut out = (kv.len() as u32).to_le_bytes().to_vec();
    out.extend_from_slice(&kv);
    while !out.len().is_multiple_of(4) {
        out.push(0);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ktx2_crate_reads_what_we_write() {
        let mut levels: Vec<CubeLevel> = (0..4).map(|m| CubeLevel::zeros(8 >> m)).collect();
        for (m, l) in levels.iter_mut().enumerate() {
            for (k, v) in l.data.iter_mut().enumerate() {
                *v = (m * 1000 + k) as f32 * 0.25;
            }
        }
        levels[0].data[0] = 1e6; // beyond half range: clamped and counted
        let (bytes, clamped) = encode_ktx2_cube(&levels).expect("encode");
        assert_eq!(clamped, 1);
        let reader = ktx2::Reader::new(&bytes[..]).expect("a valid KTX2 file");
        let h = reader.header();
        assert_eq!(h.format, Some(ktx2::Format::R16G16B16A16_SFLOAT));
        assert_eq!((h.pixel_width, h.pixel_height, h.face_count), (8, 8, 6));
        assert_eq!(h.level_count, 4);
        assert!(h.supercompression_scheme.is_none());
        let dfd = reader.dfd_blocks().next().expect("a DFD block");
        assert_eq!(dfd.header.vendor_id, 0);
        for (m, level) in reader.levels().enumerate() {
            let n = 8 >> m;
            assert_eq!(level.data.len(), 6 * n * n * 8, "level {m}");
            // texel 1 of face 0, green channel
            let g = f16::from_le_bytes([level.data[10], level.data[11]]).to_f32();
            assert_eq!(g, (m * 1000 + 4) as f32 * 0.25, "level {m}");
            let a = f16::from_le_bytes([level.data[6], level.data[7]]).to_f32();
            assert_eq!(a, 1.0);
        }
        let first = f16::from_le_bytes([bytes[0], bytes[1]]);
        let _ = first;
    }

    #[test]
    fn bad_chains_are_rejected() {
        assert!(encode_ktx2_cube(&[]).is_err());
        assert!(encode_ktx2_cube(&[CubeLevel::zeros(4), CubeLevel::zeros(4)]).is_err());
    }
}
