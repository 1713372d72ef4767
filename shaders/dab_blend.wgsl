// Blends a smoothed region into an image on the device with a brush dab's
// weights, as ifd_smooth::Smoother::apply_dab does on the CPU:
//   p += w(d) * (s - p),  d = distance from the dab's centre,
//   w(d) = strength                         for d <= radius * (1 - falloff),
//          strength * t^2 (3 - 2 t)         between, t = (radius - d) / (radius - inner),
//          0                                for d >= radius.
// `smoothed` holds the region (interleaved, row-major, `w x h x channels`),
// `image` the whole `width`-wide image, interleaved.

struct Params {
    x0: u32,
    y0: u32,
    w: u32,
    h: u32,
    width: u32,
    channels: u32,
    pad0: u32,
    pad1: u32,
    cx: f32,
    cy: f32,
    radius: f32,
    falloff: f32,
    strength: f32,
    pad2: f32,
    pad3: f32,
    pad4: f32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> smoothed: array<f32>;
@group(0) @binding(2) var<storage, read_write> image: array<f32>;

fn weight(d: f32) -> f32 {
    let inner = params.radius * (1.0 - params.falloff);
    if d >= params.radius {
        return 0.0;
    }
    if d <= inner {
        return params.strength;
    }
    let t = (params.radius - d) / (params.radius - inner);
    return params.strength * t * t * (3.0 - 2.0 * t);
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.w || gid.y >= params.h {
        return;
    }
    let x = params.x0 + gid.x;
    let y = params.y0 + gid.y;
    let dx = f32(x) - params.cx;
    let dy = f32(y) - params.cy;
    let wgt = weight(sqrt(dx * dx + dy * dy));
    if wgt <= 0.0 {
        return;
    }
    let c = params.channels;
    let src = (gid.y * params.w + gid.x) * c;
    let dst = (y * params.width + x) * c;
    for (var k = 0u; k < c; k = k + 1u) {
        let p = image[dst + k];
        image[dst + k] = p + wgt * (smoothed[src + k] - p);
    }
}
