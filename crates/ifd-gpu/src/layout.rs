//! Test support: the Rust mirrors of WGSL structs checked against the
//! shaders as the pipelines compile them. naga lays out each WGSL struct
//! (member offsets and the struct's size); [`mirror!`] compares them with
//! `offset_of!` and `size_of` of the Rust struct, member by member, so a
//! field added, removed, renamed or moved on either side fails the test of
//! the module that owns the mirror.

/// The members (name, offset) and size of struct `name` in `src` (WGSL).
pub(crate) fn wgsl_layout(src: &str, name: &str) -> (Vec<(String, u32)>, u32) {
    let module = naga::front::wgsl::parse_str(src)
        .unwrap_or_else(|e| panic!("the shader does not parse: {}", e.emit_to_string(src)));
    for (_, ty) in module.types.iter() {
        if ty.name.as_deref() != Some(name) {
            continue;
        }
        if let naga::TypeInner::Struct { members, span } = &ty.inner {
            let m = members
                .iter()
                .map(|m| (m.name.clone().unwrap_or_default(), m.offset))
                .collect();
            return (m, *span);
        }
    }
    panic!("no struct {name} in the shader")
}

/// Compares a Rust mirror (`rust`: the WGSL member names with the Rust
/// offsets they land at, `size`) with the WGSL layout of `name`.
pub(crate) fn compare(src: &str, name: &str, mirror: &str, rust: &[(&str, usize)], size: usize) {
    let (wgsl, span) = wgsl_layout(src, name);
    let wgsl_names: Vec<&str> = wgsl.iter().map(|(n, _)| n.as_str()).collect();
    let rust_names: Vec<&str> = rust.iter().map(|(n, _)| *n).collect();
    assert_eq!(
        wgsl_names, rust_names,
        "WGSL struct {name} and its mirror {mirror} have different members"
    );
    for ((n, w), (_, r)) in wgsl.iter().zip(rust) {
        assert_eq!(
            *w as usize, *r,
            "{name}.{n}: offset {w} in WGSL, {r} in {mirror}"
        );
    }
    assert_eq!(
        span as usize, size,
        "struct {name} is {span} bytes in WGSL, {mirror} is {size}"
    );
}

/// `mirror!(source, "WgslName", RustType, ["wgsl_member" => rust_field (+ bytes)?, ...])`:
/// every WGSL member in order, with the Rust field (and byte offset into it,
/// for padding arrays) that mirrors it.
macro_rules! mirror {
    ($src:expr, $wgsl:literal, $ty:ty, [$($w:literal => $f:ident $(+ $k:literal)?),* $(,)?]) => {
        $crate::layout::compare(
            &$src,
            $wgsl,
            stringify!($ty),
            &[$(($w, std::mem::offset_of!($ty, $f) $(+ $k)?)),*],
            std::mem::size_of::<$ty>(),
        )
    };
}
pub(crate) use mirror;
