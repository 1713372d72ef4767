// Benchmark only (crates/ifd-gpu/benches/gpu.rs): the same IFD-style work,
// `n_terms` bilinear lookups at rotated offsets per pixel, reading a stack
// of equally sized single-channel levels either from a storage buffer
// (`buffer_main`, the layout ifd_eval.wgsl uses) or from an r32float
// texture array with textureLoad (`texture_main`). Both interpolate
// manually (hardware filtering is 8-bit fixed point, and r32float is not
// filterable in core WebGPU). The texture gets the easy case: every level
// at full resolution, no border handling beyond a clamp.

struct Params {
    width: u32,
    height: u32,
    n_levels: u32,
    n_terms: u32,
    cos_t: f32,
    sin_t: f32,
    _pad0: u32,
    _pad1: u32,
}

// (weight, cx, cy, level)
struct Term {
    weight: f32,
    cx: f32,
    cy: f32,
    level: f32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> terms: array<Term>;
@group(0) @binding(2) var<storage, read_write> out: array<f32>;
@group(0) @binding(3) var<storage, read> data: array<f32>;
@group(0) @binding(4) var levels: texture_2d_array<f32>;

fn from_buffer(level: u32, ix: u32, iy: u32) -> f32 {
    return data[(level * params.height + iy) * params.width + ix];
}

fn from_texture(level: u32, ix: u32, iy: u32) -> f32 {
    return textureLoad(levels, vec2<u32>(ix, iy), level, 0).x;
}

fn position(t: Term, x: f32, y: f32) -> vec2<f32> {
    let px = x + params.cos_t * t.cx + params.sin_t * t.cy;
    let py = y - params.sin_t * t.cx + params.cos_t * t.cy;
    let hi = vec2<f32>(f32(params.width) - 1.001, f32(params.height) - 1.001);
    return clamp(vec2<f32>(px, py), vec2<f32>(0.0), hi);
}

@compute @workgroup_size(8, 8, 1)
fn buffer_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.width || gid.y >= params.height {
        return;
    }
    var acc = 0.0;
    for (var i = 0u; i < params.n_terms; i++) {
        let t = terms[i];
        let p = position(t, f32(gid.x), f32(gid.y));
        let l = u32(t.level);
        let i0 = vec2<u32>(p);
        let f = p - vec2<f32>(i0);
        let a0 = from_buffer(l, i0.x, i0.y);
        let a1 = from_buffer(l, i0.x + 1u, i0.y);
        let b0 = from_buffer(l, i0.x, i0.y + 1u);
        let b1 = from_buffer(l, i0.x + 1u, i0.y + 1u);
        let r0 = a0 + f.x * (a1 - a0);
        let r1 = b0 + f.x * (b1 - b0);
        acc += t.weight * (r0 + f.y * (r1 - r0));
    }
    out[gid.y * params.width + gid.x] = acc;
}

@compute @workgroup_size(8, 8, 1)
fn texture_main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.width || gid.y >= params.height {
        return;
    }
    var acc = 0.0;
    for (var i = 0u; i < params.n_terms; i++) {
        let t = terms[i];
        let p = position(t, f32(gid.x), f32(gid.y));
        let l = u32(t.level);
        let i0 = vec2<u32>(p);
        let f = p - vec2<f32>(i0);
        let a0 = from_texture(l, i0.x, i0.y);
        let a1 = from_texture(l, i0.x + 1u, i0.y);
        let b0 = from_texture(l, i0.x, i0.y + 1u);
        let b1 = from_texture(l, i0.x + 1u, i0.y + 1u);
        let r0 = a0 + f.x * (a1 - a0);
        let r1 = b0 + f.x * (b1 - b0);
        acc += t.weight * (r0 + f.y * (r1 - r0));
    }
    out[gid.y * params.width + gid.x] = acc;
}
