//! The container: `.gltf` JSON or `.glb` chunks, the JSON parsed and
//! validated by `gltf-json`, required extensions checked, and the buffers and
//! images resolved (the GLB's binary chunk, base64 `data:` URIs, or files
//! next to the asset; never the network, never absolute paths), each under
//! the memory budget and each error naming the file and the part.

use std::ops::Range;
use std::path::{Path, PathBuf};

use base64::Engine as _;
use gltf::json;
use ifd_image::{MemoryBudget, fmt_bytes};

use crate::error::{RenderError, Result};

/// The extensions whose content is read; any other one in
/// `extensionsRequired` refuses the file.
pub(super) const SUPPORTED_EXTENSIONS: &[&str] = &["KHR_materials_emissive_strength"];

/// The file being read and the memory it has been charged so far.
pub(super) struct Ctx {
    pub file: PathBuf,
    budget: MemoryBudget,
    used: u64,
}

impl Ctx {
    pub fn new(file: &Path, budget: MemoryBudget) -> Self {
        Self {
            file: file.to_path_buf(),
            budget,
            used: 0,
        }
    }

    /// An error naming the file and `part`.
    pub fn err(&self, part: impl Into<String>, reason: impl Into<String>) -> RenderError {
        RenderError::Asset {
            file: self.file.clone(),
            part: part.into(),
            reason: reason.into(),
        }
    }

    /// Charges `bytes` to the budget before they are allocated.
    pub fn charge(&mut self, bytes: u64, part: &str) -> Result<()> {
        let total = self.used.saturating_add(bytes);
        if total > self.budget.limit() {
            return Err(self.err(
                part,
                format!(
                    "needs {} of memory ({} for this part), more than the budget of {}",
                    fmt_bytes(total),
                    fmt_bytes(bytes),
                    fmt_bytes(self.budget.limit())
                ),
            ));
        }
        self.used = total;
        Ok(())
    }

    /// What is left of the budget.
    pub fn remaining(&self) -> MemoryBudget {
        MemoryBudget::bytes(self.budget.limit().saturating_sub(self.used))
    }
}

/// Where a buffer's bytes are.
enum BufData {
    /// A range of the GLB file's bytes (its BIN chunk).
    Glb(Range<usize>),
    /// Decoded from a `data:` URI or read from a file.
    Own(Vec<u8>),
}

/// The parsed asset with its buffers.
pub(super) struct Document {
    pub root: json::Root,
    /// The file's bytes (a GLB's BIN chunk is read from here).
    file_bytes: Vec<u8>,
    /// Every buffer's bytes, at least `byteLength` of them.
    buffers: Vec<BufData>,
    /// The folder relative URIs are resolved in.
    dir: PathBuf,
    /// The GLB's BIN chunk.
    bin: Option<Range<usize>>,
}

impl Document {
    /// Reads and parses the file, checks its version and required
    /// extensions, validates it and loads its buffers. Notes the optional
    /// extensions it ignores.
    pub fn load(ctx: &mut Ctx, notes: &mut Vec<String>) -> Result<Self> {
        let path = ctx.file.clone();
        let size = std::fs::metadata(&path)
            .map_err(|e| ctx.err("file", format!("cannot read: {e}")))?
            .len();
        ctx.charge(size, "file")?;
        let bytes =
            std::fs::read(&path).map_err(|e| ctx.err("file", format!("cannot read: {e}")))?;
        let is_glb_name = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("glb"));
        let (json_range, bin) = if bytes.starts_with(b"glTF") || is_glb_name {
            let (j, b) = split_glb(ctx, &bytes)?;
            (j, b)
        } else {
            (0..bytes.len(), None)
        };
        // Lenient about a byte-order mark and NUL padding, which some
        // exporters write.
        let json_bytes = &bytes[json_range];
        let json_bytes = json_bytes
            .strip_prefix(b"\xEF\xBB\xBF")
            .unwrap_or(json_bytes);
        let end = json_bytes
            .iter()
            .rposition(|&b| b != 0 && !b.is_ascii_whitespace())
            .map_or(0, |i| i + 1);
        let json_bytes = &json_bytes[..end];
        ctx.charge(json_cost(json_bytes), "JSON")?;
        let root: json::Root = json::deserialize::from_slice(json_bytes)
            .map_err(|e| ctx.err("JSON", format!("malformed: {e}")))?;
        check_version(ctx, &root)?;
        check_extensions(ctx, &root, notes)?;
        validate(ctx, &root)?;
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let mut doc = Self {
            root,
            file_bytes: bytes,
            buffers: Vec::new(),
            dir,
            bin,
        };
        doc.load_buffers(ctx)?;
        Ok(doc)
    }

    fn load_buffers(&mut self, ctx: &mut Ctx) -> Result<()> {
        for (i, b) in self.root.buffers.iter().enumerate() {
            let part = match &b.uri {
                Some(uri) if uri.starts_with("data:") => format!("buffer {i} (data: URI)"),
                Some(uri) => format!("buffer {i} ({uri:?})"),
                None => format!("buffer {i} (GLB binary chunk)"),
            };
            let declared = b.byte_length.0;
            let data = match &b.uri {
                None => {
                    let Some(bin) = self.bin.clone() else {
                        return Err(
                            ctx.err(part, "has no uri and the file has no binary (BIN) chunk")
                        );
                    };
                    if i != 0 {
                        return Err(ctx.err(
                            part,
                            "has no uri: only buffer 0 may refer to the GLB binary chunk",
                        ));
                    }
                    BufData::Glb(bin)
                }
                Some(uri) => BufData::Own(self.resolve_uri(ctx, uri, &part)?),
            };
            let len = match &data {
                BufData::Glb(r) => r.len(),
                BufData::Own(v) => v.len(),
            } as u64;
            if len < declared {
                return Err(ctx.err(
                    part,
                    format!(
                        "byteLength is {declared} but the data has {len} bytes (missing or truncated)"
                    ),
                ));
            }
            self.buffers.push(data);
        }
        Ok(())
    }

    /// The bytes of a `data:` URI or of a file next to the asset.
    pub fn resolve_uri(&self, ctx: &mut Ctx, uri: &str, part: &str) -> Result<Vec<u8>> {
        if let Some(rest) = uri.strip_prefix("data:") {
            let Some((meta, payload)) = rest.split_once(',') else {
                return Err(ctx.err(part, "malformed data: URI (no comma)"));
            };
            if !meta.ends_with(";base64") {
                return Err(ctx.err(part, "only base64 data: URIs are read"));
            }
            ctx.charge(payload.len() as u64 / 4 * 3 + 3, part)?;
            let engine = base64::engine::GeneralPurpose::new(
                &base64::alphabet::STANDARD,
                base64::engine::GeneralPurposeConfig::new()
                    .with_decode_padding_mode(base64::engine::DecodePaddingMode::Indifferent),
            );
            return engine
                .decode(payload.trim())
                .map_err(|e| ctx.err(part, format!("invalid base64 data: {e}")));
        }
        if has_scheme(uri) {
            return Err(ctx.err(
                part,
                "URIs other than data: and relative file names are not read (no network access)",
            ));
        }
        let name =
            percent_decode(uri).ok_or_else(|| ctx.err(part, "malformed percent-encoding"))?;
        if name.starts_with('/') || name.starts_with('\\') || Path::new(&name).is_absolute() {
            return Err(ctx.err(
                part,
                "absolute paths are not read (use a relative file name)",
            ));
        }
        if name.is_empty() {
            return Err(ctx.err(part, "empty uri"));
        }
        let file = self.dir.join(&name);
        let size = std::fs::metadata(&file)
            .map_err(|e| ctx.err(part, format!("cannot read {}: {e}", file.display())))?
            .len();
        ctx.charge(size, part)?;
        std::fs::read(&file)
            .map_err(|e| ctx.err(part, format!("cannot read {}: {e}", file.display())))
    }

    /// Buffer `i`'s bytes (at least its `byteLength`).
    pub fn buffer(&self, i: usize) -> Option<&[u8]> {
        Some(match self.buffers.get(i)? {
            BufData::Glb(r) => &self.file_bytes[r.clone()],
            BufData::Own(v) => v,
        })
    }

    /// The bytes of buffer view `v`, checked against its buffer.
    pub fn view(&self, ctx: &Ctx, v: usize, part: &str) -> Result<&[u8]> {
        let view = self
            .root
            .buffer_views
            .get(v)
            .ok_or_else(|| ctx.err(part, format!("bufferView {v} does not exist")))?;
        let b = view.buffer.value();
        let declared = self
            .root
            .buffers
            .get(b)
            .map(|b| b.byte_length.0)
            .ok_or_else(|| {
                ctx.err(
                    format!("bufferView {v}"),
                    format!("buffer {b} does not exist"),
                )
            })?;
        let data = self.buffer(b).ok_or_else(|| {
            ctx.err(
                format!("bufferView {v}"),
                format!("buffer {b} does not exist"),
            )
        })?;
        let start = view.byte_offset.map_or(0, |o| o.0);
        let end = start.checked_add(view.byte_length.0);
        match end {
            Some(end) if end <= declared && end <= data.len() as u64 => {
                Ok(&data[start as usize..end as usize])
            }
            _ => Err(ctx.err(
                format!("bufferView {v}"),
                format!(
                    "bytes {start} + {} lie outside buffer {b} ({declared} bytes)",
                    view.byte_length.0
                ),
            )),
        }
    }
}

/// Splits a GLB file into its JSON chunk and its BIN chunk (if any),
/// checking the header and every chunk length.
fn split_glb(ctx: &Ctx, bytes: &[u8]) -> Result<(Range<usize>, Option<Range<usize>>)> {
    let part = "GLB header";
    if bytes.len() < 12 {
        return Err(ctx.err(
            part,
            format!(
                "the file has {} bytes, fewer than a 12-byte GLB header",
                bytes.len()
            ),
        ));
    }
    let word =
        |at: usize| u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]);
    if &bytes[..4] != b"glTF" {
        return Err(ctx.err(
            part,
            format!(
                "magic {:?} is not \"glTF\" (not a binary glTF file)",
                String::from_utf8_lossy(&bytes[..4])
            ),
        ));
    }
    let version = word(4);
    if version != 2 {
        return Err(ctx.err(part, format!("version {version} (only glTF 2 is read)")));
    }
    let length = word(8) as usize;
    if length > bytes.len() {
        return Err(ctx.err(
            part,
            format!("declares {length} bytes but the file has {}", bytes.len()),
        ));
    }
    if length < 20 {
        return Err(ctx.err(
            part,
            format!("declares {length} bytes, too few for a JSON chunk"),
        ));
    }
    let mut at = 12;
    let mut json = None;
    let mut bin = None;
    let mut k = 0;
    while at < length {
        if length - at < 8 {
            return Err(ctx.err(
                format!("GLB chunk {k}"),
                format!(
                    "its 8-byte header runs past the end of the file ({} bytes left)",
                    length - at
                ),
            ));
        }
        let len = word(at) as usize;
        let kind = word(at + 4);
        let name = match kind {
            0x4E4F_534A => "JSON",
            0x004E_4942 => "BIN",
            _ => "unknown",
        };
        let start = at + 8;
        if len > length - start {
            return Err(ctx.err(
                format!("GLB chunk {k} ({name})"),
                format!(
                    "length {len} runs past the end of the file ({} bytes left)",
                    length - start
                ),
            ));
        }
        let range = start..start + len;
        match (k, kind) {
            (0, 0x4E4F_534A) => json = Some(range),
            (0, _) => {
                return Err(ctx.err(
                    "GLB chunk 0",
                    format!("type {kind:#010x} is not JSON (the first chunk must be)"),
                ));
            }
            (1, 0x004E_4942) => bin = Some(range),
            // Later or unknown chunks are ignored, as the specification says.
            _ => {}
        }
        // Chunks are padded to 4 bytes; a last unpadded chunk still ends the file.
        at = (start + len).saturating_add(3) & !3;
        k += 1;
    }
    let json = json.ok_or_else(|| ctx.err("GLB chunk 0", "missing JSON chunk"))?;
    Ok((json, bin))
}

/// An upper bound of the memory the parsed JSON needs: its bytes, plus room
/// for every object or array (a parsed node or accessor is a few hundred
/// bytes) and every value in a list.
fn json_cost(bytes: &[u8]) -> u64 {
    let (mut in_string, mut escaped) = (false, false);
    let (mut containers, mut commas) = (0u64, 0u64);
    for &b in bytes {
        if in_string {
            if escaped {
                escaped = false;
            } else if b == b'\\' {
                escaped = true;
            } else if b == b'"' {
                in_string = false;
            }
            continue;
        }
        match b {
            b'"' => in_string = true,
            b'{' | b'[' => containers += 1,
            b',' => commas += 1,
            _ => {}
        }
    }
    bytes.len() as u64 + 512 * containers + 32 * commas
}

fn check_version(ctx: &Ctx, root: &json::Root) -> Result<()> {
    let v = &root.asset.version;
    let major = v.split('.').next().unwrap_or_default();
    if major != "2" {
        return Err(ctx.err("asset.version", format!("{v:?} (only glTF 2.x is read)")));
    }
    Ok(())
}

fn check_extensions(ctx: &Ctx, root: &json::Root, notes: &mut Vec<String>) -> Result<()> {
    for ext in &root.extensions_required {
        if !SUPPORTED_EXTENSIONS.contains(&ext.as_str()) {
            return Err(ctx.err(
                "extensionsRequired",
                format!(
                    "extension {ext} is required but not supported (ifd reads {})",
                    SUPPORTED_EXTENSIONS.join(", ")
                ),
            ));
        }
    }
    for ext in &root.extensions_used {
        if SUPPORTED_EXTENSIONS.contains(&ext.as_str()) {
            continue;
        }
        notes.push(if ext == "KHR_texture_transform" {
            "extension KHR_texture_transform is not supported: texture transforms are ignored"
                .into()
        } else {
            format!("extension {ext} is not supported: ignored")
        });
    }
    Ok(())
}

/// `gltf-json`'s validation (references in range, enumerations known,
/// required fields present): the first problem, by its JSON path.
fn validate(ctx: &Ctx, root: &json::Root) -> Result<()> {
    use json::validation::Validate as _;
    // gltf-json's check of POSITION's bounds indexes the accessors without
    // checking the index (a panic): that index first.
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let pos = json::validation::Checked::Valid(json::mesh::Semantic::Positions);
            if let Some(i) = prim.attributes.get(&pos)
                && i.value() >= root.accessors.len()
            {
                return Err(ctx.err(
                    format!("meshes[{m}].primitives[{p}].attributes[\"POSITION\"]"),
                    format!(
                        "accessor {} does not exist ({} accessors)",
                        i.value(),
                        root.accessors.len()
                    ),
                ));
            }
        }
    }
    let mut first: Option<(String, String)> = None;
    root.validate(root, json::Path::new, &mut |path, e| {
        let path = path().to_string();
        // POSITION's min and max are required but not needed here.
        let bounds = matches!(path.rsplit('.').next(), Some("min" | "max"));
        if first.is_none() && !bounds {
            first = Some((path, e.to_string()));
        }
    });
    match first {
        Some((path, e)) => Err(ctx.err(path, e.to_lowercase())),
        None => Ok(()),
    }
}

/// Whether a URI starts with a scheme (`http:`, `file:`, `C:`): letters,
/// then letters, digits, `+`, `-` or `.`, then a colon.
fn has_scheme(uri: &str) -> bool {
    let Some((scheme, _)) = uri.split_once(':') else {
        return false;
    };
    let mut chars = scheme.chars();
    chars.next().is_some_and(|c| c.is_ascii_alphabetic())
        && chars.all(|c| c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.'))
}

/// `%XX` sequences decoded (URIs in glTF are percent-encoded); `None` for
/// malformed sequences or non-UTF-8 results.
fn percent_decode(s: &str) -> Option<String> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let hex = b.get(i + 1..i + 3)?;
            let v = u8::from_str_radix(std::str::from_utf8(hex).ok()?, 16).ok()?;
            out.push(v);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uri_helpers() {
        assert!(has_scheme("http://x/y.bin"));
        assert!(has_scheme("file:///tmp/a.bin"));
        assert!(has_scheme("C:\\a.bin"));
        assert!(!has_scheme("a.bin"));
        assert!(!has_scheme("sub/a:b.bin"));
        assert_eq!(percent_decode("a%20b.bin").as_deref(), Some("a b.bin"));
        assert_eq!(percent_decode("a%2"), None);
        assert!(json_cost(br#"{"a":"{{{,,,"}"#) < 600);
    }
}
