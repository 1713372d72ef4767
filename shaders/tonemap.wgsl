// The display transform of `ifd render`'s 8-bit output
// (`ifd_render::tonemap::Tonemap::display`) on the device: a shaded image
// (vec4 per pixel: linear RGB, object mask) times 2^exposure, a tone curve,
// the sRGB transfer function, into an rgba8unorm storage texture that a
// renderer on the same device shows (alpha 1).

struct Params {
    width: u32,
    height: u32,
    // 0: clip, 1: Reinhard x / (1 + x), 2: Narkowicz's ACES fit
    curve: u32,
    // the first row converted (a band of rows after banded shading)
    row0: u32,
    // 2^exposure
    scale: f32,
    pad1: f32,
    pad2: f32,
    pad3: f32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> src: array<vec4<f32>>;
@group(0) @binding(2) var dst: texture_storage_2d<rgba8unorm, write>;

fn srgb(v: f32) -> f32 {
    if v <= 0.0031308 {
        return 12.92 * v;
    }
    return 1.055 * pow(v, 1.0 / 2.4) - 0.055;
}

fn display(v: f32) -> f32 {
    let x = max(v * params.scale, 0.0);
    var y = x;
    if params.curve == 1u {
        y = x / (1.0 + x);
    } else if params.curve == 2u {
        y = x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14);
    }
    return srgb(clamp(y, 0.0, 1.0));
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let y = gid.y + params.row0;
    if gid.x >= params.width || y >= params.height {
        return;
    }
    let p = src[y * params.width + gid.x];
    textureStore(dst, vec2<u32>(gid.x, y), vec4<f32>(display(p.x), display(p.y), display(p.z), 1.0));
}
