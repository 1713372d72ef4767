// Copies a `width x height` rectangle of an image (interleaved f32, 1 to 4
// channels, row-major, `src_stride` pixels a row, the rectangle at
// (`src_x0`, `src_y0`)) into an rgba8unorm storage texture at (`dst_x0`,
// `dst_y0`), for display without a round trip to the CPU. 1 channel: grey;
// 2: grey + alpha; 3: RGB; 4: RGBA; with `opaque` set alpha is 1. Values
// are clamped to [0, 1]; with `srgb` set, colour channels are encoded with
// the sRGB transfer function (data is linear, as in ifd-image).

struct Params {
    width: u32,
    height: u32,
    channels: u32,
    srgb: u32,
    src_x0: u32,
    src_y0: u32,
    src_stride: u32,
    opaque: u32,
    dst_x0: u32,
    dst_y0: u32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> src: array<f32>;
@group(0) @binding(2) var dst: texture_storage_2d<rgba8unorm, write>;

fn encode(v: f32) -> f32 {
    let c = clamp(v, 0.0, 1.0);
    if params.srgb == 0u {
        return c;
    }
    if c <= 0.0031308 {
        return 12.92 * c;
    }
    return 1.055 * pow(c, 1.0 / 2.4) - 0.055;
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.width || gid.y >= params.height {
        return;
    }
    let c = params.channels;
    let i = ((params.src_y0 + gid.y) * params.src_stride + params.src_x0 + gid.x) * c;
    var rgba = vec4<f32>(0.0, 0.0, 0.0, 1.0);
    if c == 1u || c == 2u {
        let g = encode(src[i]);
        rgba = vec4<f32>(g, g, g, 1.0);
        if c == 2u {
            rgba.w = clamp(src[i + 1u], 0.0, 1.0);
        }
    } else {
        rgba = vec4<f32>(encode(src[i]), encode(src[i + 1u]), encode(src[i + 2u]), 1.0);
        if c >= 4u {
            rgba.w = clamp(src[i + 3u], 0.0, 1.0);
        }
    }
    if params.opaque != 0u {
        rgba.w = 1.0;
    }
    textureStore(dst, vec2<u32>(params.dst_x0 + gid.x, params.dst_y0 + gid.y), rgba);
}
