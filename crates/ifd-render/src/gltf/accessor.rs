//! Accessors read with every offset, stride, alignment and length checked
//! against the buffer views before anything is allocated (sparse accessors
//! included), into `f64` components.

use gltf::json;
use gltf::json::accessor::{ComponentType, Type};
use gltf::json::validation::Checked;

use super::document::{Ctx, Document};
use crate::error::Result;

/// What an attribute may be stored as.
#[derive(Clone, Copy)]
pub(super) struct Want {
    /// Allowed element types (`VEC3`, ...).
    pub types: &'static [Type],
    /// Allowed component types.
    pub components: &'static [ComponentType],
    /// Integer components must be normalized (texture coordinates, colours).
    pub normalized_ints: bool,
    /// Every value must be finite (positions).
    pub finite: bool,
}

pub(super) const POSITION: Want = Want {
    types: &[Type::Vec3],
    components: &[ComponentType::F32],
    normalized_ints: false,
    finite: true,
};
pub(super) const NORMAL: Want = Want {
    types: &[Type::Vec3],
    components: &[ComponentType::F32],
    normalized_ints: false,
    finite: false,
};
pub(super) const TANGENT: Want = Want {
    types: &[Type::Vec4],
    components: &[ComponentType::F32],
    normalized_ints: false,
    finite: false,
};
pub(super) const TEXCOORD: Want = Want {
    types: &[Type::Vec2],
    components: &[ComponentType::F32, ComponentType::U8, ComponentType::U16],
    normalized_ints: true,
    finite: false,
};
pub(super) const COLOR: Want = Want {
    types: &[Type::Vec3, Type::Vec4],
    components: &[ComponentType::F32, ComponentType::U8, ComponentType::U16],
    normalized_ints: true,
    finite: false,
};
pub(super) const INDICES: Want = Want {
    types: &[Type::Scalar],
    components: &[ComponentType::U8, ComponentType::U16, ComponentType::U32],
    normalized_ints: false,
    finite: false,
};

/// An accessor's values: `count` elements of `width` components.
pub(super) struct Values {
    pub data: Vec<f64>,
    pub width: usize,
    pub count: usize,
}

impl Values {
    /// Element `i`'s components.
    pub fn get(&self, i: usize) -> &[f64] {
        &self.data[i * self.width..(i + 1) * self.width]
    }
}

/// Reads accessor `index` (`what` says what for, e.g. `POSITION of mesh 0
/// primitive 1`).
pub(super) fn read(
    ctx: &mut Ctx,
    doc: &Document,
    index: usize,
    what: &str,
    want: Want,
) -> Result<Values> {
    let part = format!("accessor {index} ({what})");
    let acc = doc
        .root
        .accessors
        .get(index)
        .ok_or_else(|| ctx.err(&part, "does not exist"))?;
    let (Checked::Valid(ty), Checked::Valid(ct)) = (acc.type_, acc.component_type) else {
        return Err(ctx.err(&part, "unknown type or componentType"));
    };
    let ct = ct.0;
    if !want.types.contains(&ty) {
        let allowed: Vec<&str> = want.types.iter().map(|t| type_name(*t)).collect();
        return Err(ctx.err(
            &part,
            format!("type {} is not {}", type_name(ty), allowed.join(" or ")),
        ));
    }
    if !want.components.contains(&ct) {
        let allowed: Vec<&str> = want.components.iter().map(|c| component_name(*c)).collect();
        return Err(ctx.err(
            &part,
            format!(
                "componentType {} is not {}",
                component_name(ct),
                allowed.join(" or ")
            ),
        ));
    }
    if want.normalized_ints && ct != ComponentType::F32 && !acc.normalized {
        return Err(ctx.err(&part, "integer components must be normalized"));
    }
    let width = ty.multiplicity();
    let count = usize::try_from(acc.count.0).map_err(|_| ctx.err(&part, "count too large"))?;
    let bytes = (count as u64)
        .checked_mul(width as u64 * 8)
        .ok_or_else(|| ctx.err(&part, format!("count {count} overflows")))?;
    let decode = Decode {
        ct,
        normalized: acc.normalized,
    };
    let mut data = if let Some(v) = acc.buffer_view {
        // The view bounds the count before the budget is charged.
        let offset = acc.byte_offset.map_or(0, |o| o.0);
        let stride = doc
            .root
            .buffer_views
            .get(v.value())
            .and_then(|bv| bv.byte_stride)
            .map(|s| s.0);
        let raw = strided(ctx, doc, v.value(), offset, stride, count, width, ct, &part)?;
        ctx.charge(bytes, &part)?;
        let mut data = Vec::with_capacity(count * width);
        for i in 0..count {
            let at = i * raw.stride;
            for c in 0..width {
                data.push(decode.get(raw.bytes, at + c * ct.size()));
            }
        }
        data
    } else {
        // No view: zeros (a sparse accessor's base).
        ctx.charge(bytes, &part)?;
        vec![0.0; count * width]
    };
    if let Some(sparse) = &acc.sparse {
        apply_sparse(ctx, doc, sparse, &mut data, count, width, decode, &part)?;
    }
    if let Some(i) = data.iter().position(|v| !v.is_finite()) {
        if want.finite {
            return Err(ctx.err(
                &part,
                format!("element {} has a non-finite component", i / width),
            ));
        }
        // Normals, tangents, texture coordinates, colours: 0 (a zero normal
        // or tangent counts as missing).
        for v in &mut data[i..] {
            if !v.is_finite() {
                *v = 0.0;
            }
        }
    }
    Ok(Values { data, width, count })
}

fn type_name(t: Type) -> &'static str {
    match t {
        Type::Scalar => "SCALAR",
        Type::Vec2 => "VEC2",
        Type::Vec3 => "VEC3",
        Type::Vec4 => "VEC4",
        Type::Mat2 => "MAT2",
        Type::Mat3 => "MAT3",
        Type::Mat4 => "MAT4",
    }
}

fn component_name(c: ComponentType) -> &'static str {
    match c {
        ComponentType::I8 => "BYTE",
        ComponentType::U8 => "UNSIGNED_BYTE",
        ComponentType::I16 => "SHORT",
        ComponentType::U16 => "UNSIGNED_SHORT",
        ComponentType::U32 => "UNSIGNED_INT",
        ComponentType::F32 => "FLOAT",
    }
}

/// Bytes of a strided array in a view, checked.
struct Strided<'a> {
    bytes: &'a [u8],
    stride: usize,
}

#[allow(
    clippy::too_many_arguments,
    reason = "one checked read, its parts named"
)]
fn strided<'a>(
    ctx: &Ctx,
    doc: &'a Document,
    view: usize,
    offset: u64,
    stride: Option<usize>,
    count: usize,
    width: usize,
    ct: ComponentType,
    part: &str,
) -> Result<Strided<'a>> {
    let bytes = doc.view(ctx, view, part)?;
    let size = ct.size();
    let elem = width * size;
    let stride = stride.unwrap_or(elem);
    if stride < elem {
        return Err(ctx.err(
            part,
            format!(
                "byteStride {stride} of bufferView {view} is smaller than an element ({elem} bytes)"
            ),
        ));
    }
    let view_offset = doc
        .root
        .buffer_views
        .get(view)
        .and_then(|v| v.byte_offset)
        .map_or(0, |o| o.0);
    if !offset.is_multiple_of(size as u64)
        || !view_offset.wrapping_add(offset).is_multiple_of(size as u64)
        || !stride.is_multiple_of(size)
    {
        return Err(ctx.err(
            part,
            format!(
                "misaligned: byteOffset {offset} (+ {view_offset} of bufferView {view}) or stride {stride} is not a multiple of the component size {size}"
            ),
        ));
    }
    if count == 0 {
        return Ok(Strided { bytes: &[], stride });
    }
    let end = (count as u64 - 1)
        .checked_mul(stride as u64)
        .and_then(|v| v.checked_add(offset))
        .and_then(|v| v.checked_add(elem as u64));
    match end {
        Some(end) if end <= bytes.len() as u64 => Ok(Strided {
            bytes: &bytes[offset as usize..end as usize],
            stride,
        }),
        _ => Err(ctx.err(
            part,
            format!(
                "{count} elements of {elem} bytes (stride {stride}) from byteOffset {offset} run past the end of bufferView {view} ({} bytes)",
                bytes.len()
            ),
        )),
    }
}

#[derive(Clone, Copy)]
struct Decode {
    ct: ComponentType,
    normalized: bool,
}

impl Decode {
    /// The component at byte `at` (in range: checked by [`strided`]).
    fn get(self, b: &[u8], at: usize) -> f64 {
        let n = self.normalized;
        match self.ct {
            ComponentType::F32 => {
                f64::from(f32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]))
            }
            ComponentType::U32 => {
                f64::from(u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]))
            }
            ComponentType::U16 => {
                let v = f64::from(u16::from_le_bytes([b[at], b[at + 1]]));
                if n { v / 65535.0 } else { v }
            }
            ComponentType::I16 => {
                let v = f64::from(i16::from_le_bytes([b[at], b[at + 1]]));
                if n { (v / 32767.0).max(-1.0) } else { v }
            }
            ComponentType::U8 => {
                let v = f64::from(b[at]);
                if n { v / 255.0 } else { v }
            }
            ComponentType::I8 => {
                let v = f64::from(b[at] as i8);
                if n { (v / 127.0).max(-1.0) } else { v }
            }
        }
    }
}

#[allow(
    clippy::too_many_arguments,
    reason = "one checked read, its parts named"
)]
fn apply_sparse(
    ctx: &Ctx,
    doc: &Document,
    sparse: &json::accessor::sparse::Sparse,
    data: &mut [f64],
    count: usize,
    width: usize,
    decode: Decode,
    part: &str,
) -> Result<()> {
    let n = usize::try_from(sparse.count.0).unwrap_or(usize::MAX);
    if n > count {
        return Err(ctx.err(
            part,
            format!("sparse count {n} exceeds the accessor's count {count}"),
        ));
    }
    let Checked::Valid(ict) = sparse.indices.component_type else {
        return Err(ctx.err(part, "sparse indices: unknown componentType"));
    };
    let ict = ict.0;
    let sparse_part = format!("{part}, sparse indices");
    let idx = strided(
        ctx,
        doc,
        sparse.indices.buffer_view.value(),
        sparse.indices.byte_offset.0,
        None,
        n,
        1,
        ict,
        &sparse_part,
    )?;
    let values_part = format!("{part}, sparse values");
    let vals = strided(
        ctx,
        doc,
        sparse.values.buffer_view.value(),
        sparse.values.byte_offset.0,
        None,
        n,
        width,
        decode.ct,
        &values_part,
    )?;
    let idec = Decode {
        ct: ict,
        normalized: false,
    };
    for k in 0..n {
        let i = idec.get(idx.bytes, k * idx.stride) as usize;
        if i >= count {
            return Err(ctx.err(
                sparse_part,
                format!("index {i} (entry {k}) is out of range ({count} elements)"),
            ));
        }
        for c in 0..width {
            data[i * width + c] = decode.get(vals.bytes, k * vals.stride + c * decode.ct.size());
        }
    }
    Ok(())
}
