// IFD evaluation (Eq. 3 of the 2013 paper) on the GPU, one invocation per
// output pixel and up to four channels:
//
//   out(p) = sum_e b_e sum_{t in entry e} w_t fhat_{s sigma_t}(p + s R_theta c_t)
//
// with one lookup per term: bilinear (or cubic B-spline, by the stack's
// interpolation) in space, linear in ln sigma. At a constant scale the host
// locates every term's levels once (FLAG_TERM_LEVELS, `term_levels`); on a
// stack built at the terms' sigmas that is one lookup per term, no level
// arithmetic per pixel. With a scale map the levels are located per pixel
// on a log-uniform stack.
// A plain filter is one entry with b = 1; anisotropic smoothing blends two
// entries of the aspect-ratio bank, b = (1 - t, t). Every step mirrors the
// CPU path `ifd_planar::Filter` (crates/ifd-planar/src/filter/, stack/):
// the same level location, the same fast bilinear path and the same
// border handling outside the stored region, so the two agree to f32
// rounding.
//
// Storage (see crates/ifd-gpu/src/lib.rs, "Design"): the scale stack is one
// storage buffer of f32 per chunk of at most four channels, level after
// level, each level planar per channel (`offset + k * plane + iy * nx + ix`).

struct Params {
    // Output region, in image pixels.
    region_x0: u32,
    region_y0: u32,
    region_w: u32,
    region_h: u32,
    // Image.
    width: u32,
    height: u32,
    channels: u32,
    // First channel and channel count (1..=4) of this chunk.
    chunk_c0: u32,
    chunk_nc: u32,
    n_levels: u32,
    // 0 reflect-101, 1 constant, 2 replicate, 3 wrap.
    border_mode: u32,
    border_value: f32,
    // Level position u = ln_sigma_t * inv_ln_ratio + u_offset, where
    // u_offset = (ln s - ln sigma_0) * inv_ln_ratio.
    inv_ln_ratio: f32,
    // Constant pose: cos(theta), sin(theta), s, u_offset and entry (i + t),
    // each replaced per pixel by its map when the map's flag is set.
    cos_t: f32,
    sin_t: f32,
    scale: f32,
    u_offset: f32,
    entry: f32,
    // Bit 0: rotation map (cos, sin pairs at rot_off); bit 1: scale map
    // (s, u_offset pairs at scale_off); bit 2: entry map at entry_off.
    flags: u32,
    rot_off: u32,
    scale_off: u32,
    entry_off: u32,
    n_entries: u32,
    // INTERP_LINEAR: levels hold samples, read bilinearly; INTERP_CUBIC:
    // levels hold cubic B-spline coefficients, read 4x4.
    interpolation: u32,
    // SAMPLING_*: how the decomposition's kernel was sampled, which sets the
    // atoms' effective sigma at each scale (Sampling::effective_sigma).
    sampling: u32,
    // Within this fraction of the level spacing a sigma reads one level:
    // LEVEL_SNAP, or 0.5 on a stack read at the nearest level (every sigma
    // but one exactly half-way reads the level nearest it alone).
    level_snap: f32,
    _pad1: u32,
    _pad2: u32,
}

struct Level {
    origin: f32,
    inv_step: f32,
    step: f32,
    nx: u32,
    ny: u32,
    // Index of sample (0, 0) of channel 0 of this chunk.
    offset: u32,
    // nx * ny: distance between channel planes.
    plane: u32,
    _pad: u32,
}

// (weight, cx, cy, ln sigma).
struct Term {
    weight: f32,
    cx: f32,
    cy: f32,
    ln_sigma: f32,
}

// The levels term i reads at a constant scale and their weights, located on
// the host exactly as the CPU path locates them (FLAG_TERM_LEVELS): b == a
// and wb == 0 for a sigma on a level, which a stack built at the terms'
// sigmas gives every term.
struct TermLevel {
    a: u32,
    b: u32,
    wa: f32,
    wb: f32,
}

// Terms [start, start + count) form one bank entry.
struct Entry {
    start: u32,
    count: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> levels: array<Level>;
@group(0) @binding(2) var<storage, read> data: array<f32>;
@group(0) @binding(3) var<storage, read> terms: array<Term>;
@group(0) @binding(4) var<storage, read> entries: array<Entry>;
@group(0) @binding(5) var<storage, read> maps: array<f32>;
@group(0) @binding(6) var<storage, read_write> out: array<f32>;
@group(0) @binding(7) var<storage, read> term_levels: array<TermLevel>;

// The codes the host writes into Params (BORDER_*, INTERP_*, SAMPLING_*,
// FLAG_*) are defined once, in Rust (`ifd_gpu::shaders::codes`), and
// prepended to this file as WGSL constants (`ifd_gpu::shaders::ifd_eval_source`).

// The variance (px^2) a pixel's footprint adds to every atom at scale s
// (Sampling::footprint_variance).
fn footprint_variance(s: f32) -> f32 {
    switch params.sampling {
        case SAMPLING_POINT: {
            return select(0.0, 1.0 / 12.0, s < 1.0);
        }
        case SAMPLING_AREA: {
            return (1.0 - s * s) / 12.0;
        }
        case SAMPLING_AVERAGED: {
            return 1.0 / 12.0;
        }
        default: {
            return 0.0;
        }
    }
}

// Rust's f32::rem_euclid: truncated remainder, shifted into [0, |m|).
fn rem_euclid(x: f32, m: f32) -> f32 {
    let r = x % m;
    if r < 0.0 {
        return r + abs(m);
    }
    return r;
}

// Border::map_continuous of ifd-planar.
fn map_continuous(x: f32, n: u32) -> f32 {
    let last = f32(max(n, 1u) - 1u);
    if params.border_mode == BORDER_WRAP {
        let nf = f32(max(n, 1u));
        let r = rem_euclid(x, nf);
        if r >= nf {
            return 0.0;
        }
        return r;
    }
    // Reflect-101.
    if n <= 1u {
        return 0.0;
    }
    var once = x;
    if x < 0.0 {
        once = -x;
    } else if x > last {
        once = 2.0 * last - x;
    }
    if once >= 0.0 && once <= last {
        return once;
    }
    let period = 2.0 * last;
    var r = rem_euclid(x, period);
    if r > last {
        r = period - r;
    }
    return clamp(r, 0.0, last);
}

// Coordinate p resolved into the stored range [lo, hi] of a level.
fn map_coord(p: f32, n: u32, lo: f32, hi: f32) -> f32 {
    if p >= lo && p <= hi {
        return p;
    }
    switch params.border_mode {
        case BORDER_CONSTANT: {
            return p;
        }
        case BORDER_REPLICATE: {
            return clamp(p, lo, hi);
        }
        default: {
            return map_continuous(p, n);
        }
    }
}

// Channels k < nc of one sample (nc is uniform: the branches are coherent;
// a loop with a dynamic vector index is several times slower on lavapipe).
fn texel(base: u32, plane: u32, nc: u32) -> vec4<f32> {
    let a = data[base];
    if nc == 1u {
        return vec4<f32>(a, 0.0, 0.0, 0.0);
    }
    let b = data[base + plane];
    if nc == 2u {
        return vec4<f32>(a, b, 0.0, 0.0);
    }
    let c = data[base + 2u * plane];
    if nc == 3u {
        return vec4<f32>(a, b, c, 0.0);
    }
    return vec4<f32>(a, b, c, data[base + 3u * plane]);
}

// Bilinear lookup of level li at full-resolution (x, y), all channels of the
// chunk (ScaleStack::accumulate and accumulate_outside).
fn bilinear(li: u32, x: f32, y: f32) -> vec4<f32> {
    let lv = levels[li];
    let nc = params.chunk_nc;
    let u = (x - lv.origin) * lv.inv_step;
    let v = (y - lv.origin) * lv.inv_step;
    // Fast path: the 2x2 footprint is stored (u < nx - 1 also keeps the
    // float-to-integer conversion in range).
    if u >= 0.0 && v >= 0.0 && u < f32(lv.nx - 1u) && v < f32(lv.ny - 1u) {
        let iu = u32(u);
        let iv = u32(v);
        let fu = u - f32(iu);
        let fv = v - f32(iv);
        let i00 = lv.offset + iv * lv.nx + iu;
        let a0 = texel(i00, lv.plane, nc);
        let a1 = texel(i00 + 1u, lv.plane, nc);
        let b0 = texel(i00 + lv.nx, lv.plane, nc);
        let b1 = texel(i00 + lv.nx + 1u, lv.plane, nc);
        let r0 = a0 + fu * (a1 - a0);
        let r1 = b0 + fu * (b1 - b0);
        return r0 + fv * (r1 - r0);
    }
    return lookup_outside(li, x, y, false);
}

// Cubic B-spline weights of the samples at -1, 0, 1, 2 for fraction t
// (bspline_weights of ifd-planar's stack.rs).
fn bspline(t: f32) -> vec4<f32> {
    let t2 = t * t;
    let t3 = t2 * t;
    let s = 1.0 - t;
    return vec4<f32>(
        s * s * s * (1.0 / 6.0),
        (3.0 * t3 - 6.0 * t2 + 4.0) * (1.0 / 6.0),
        (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) * (1.0 / 6.0),
        t3 * (1.0 / 6.0),
    );
}

// Cubic B-spline lookup of level li at full-resolution (x, y)
// (ScaleStack::accumulate_cubic and accumulate_outside).
fn cubic(li: u32, x: f32, y: f32) -> vec4<f32> {
    let lv = levels[li];
    let nc = params.chunk_nc;
    let u = (x - lv.origin) * lv.inv_step;
    let v = (y - lv.origin) * lv.inv_step;
    var acc = vec4<f32>(0.0);
    // Fast path: the 4x4 footprint is stored.
    if u >= 1.0 && v >= 1.0 && u < f32(lv.nx - 2u) && v < f32(lv.ny - 2u) {
        let iu = u32(u);
        let iv = u32(v);
        let wx = bspline(u - f32(iu));
        let wy = bspline(v - f32(iv));
        for (var j = 0u; j < 4u; j++) {
            let base = lv.offset + (iv + j - 1u) * lv.nx + iu - 1u;
            let r = wx.x * texel(base, lv.plane, nc) + wx.y * texel(base + 1u, lv.plane, nc)
                + wx.z * texel(base + 2u, lv.plane, nc) + wx.w * texel(base + 3u, lv.plane, nc);
            acc += wy[j] * r;
        }
        return acc;
    }
    return lookup_outside(li, x, y, true);
}

// Slow path of both lookups (ScaleStack::accumulate_outside): resolve (x, y)
// by the border mode so that the footprint (2x2 bilinear, 4x4 cubic) is
// stored, then read each of its samples, clamped to the stored region or
// replaced by the constant.
fn lookup_outside(li: u32, x: f32, y: f32, is_cubic: bool) -> vec4<f32> {
    let lv = levels[li];
    let nc = params.chunk_nc;
    let lo = lv.origin;
    // Stored samples the footprint reads before and after the one below.
    let before = select(0u, 1u, is_cubic);
    let after = select(1u, 2u, is_cubic);
    let first = lo + f32(before) * lv.step;
    let hi_x = lo + f32(lv.nx - after) * lv.step;
    let hi_y = lo + f32(lv.ny - after) * lv.step;
    let mx = map_coord(x, params.width, first, hi_x);
    let my = map_coord(y, params.height, first, hi_y);
    let mu = (mx - lo) * lv.inv_step;
    let mv = (my - lo) * lv.inv_step;
    let fiu = floor(mu);
    let fiv = floor(mv);
    var wx = vec4<f32>(1.0 - (mu - fiu), mu - fiu, 0.0, 0.0);
    var wy = vec4<f32>(1.0 - (mv - fiv), mv - fiv, 0.0, 0.0);
    if is_cubic {
        wx = bspline(mu - fiu);
        wy = bspline(mv - fiv);
    }
    let n = i32(before + after + 1u);
    let is_constant = params.border_mode == BORDER_CONSTANT;
    let nxi = i32(lv.nx);
    let nyi = i32(lv.ny);
    var acc = vec4<f32>(0.0);
    for (var j = 0; j < n; j++) {
        for (var i = 0; i < n; i++) {
            let w = wx[i] * wy[j];
            if w == 0.0 {
                continue;
            }
            var ix = i32(fiu) + i - i32(before);
            var iy = i32(fiv) + j - i32(before);
            let inside = ix >= 0 && ix < nxi && iy >= 0 && iy < nyi;
            if !inside && is_constant {
                acc += vec4<f32>(w * params.border_value);
                continue;
            }
            ix = clamp(ix, 0, nxi - 1);
            iy = clamp(iy, 0, nyi - 1);
            let base = lv.offset + u32(iy) * lv.nx + u32(ix);
            acc += w * texel(base, lv.plane, nc);
        }
    }
    return acc;
}

// One lookup of level li, by the stack's interpolation.
fn lookup(li: u32, x: f32, y: f32) -> vec4<f32> {
    if params.interpolation == INTERP_CUBIC {
        return cubic(li, x, y);
    }
    return bilinear(li, x, y);
}

// params.level_snap (the host's LEVEL_SNAP, 1e-4, or NEAREST_SNAP, 0.5): the
// fraction of the level spacing within which a sigma reads one level.

// One bank entry at pixel (x, y) for pose (cs, ss, u_offset) at scale s.
fn eval_entry(e: u32, x: f32, y: f32, cs: f32, ss: f32, u_offset: f32, s: f32) -> vec4<f32> {
    let entry = entries[e];
    let last = params.n_levels - 1u;
    if (params.flags & FLAG_TERM_LEVELS) != 0u {
        // A constant scale: levels located once on the host, not per pixel.
        var acc = vec4<f32>(0.0);
        for (var i = entry.start; i < entry.start + entry.count; i++) {
            let t = terms[i];
            let l = term_levels[i];
            let px = x + cs * t.cx + ss * t.cy;
            let py = y - ss * t.cx + cs * t.cy;
            acc += (t.weight * l.wa) * lookup(l.a, px, py);
            if l.wb != 0.0 {
                acc += (t.weight * l.wb) * lookup(l.b, px, py);
            }
        }
        return acc;
    }
    let var_s = footprint_variance(s);
    let ln_s = log(s);
    var acc = vec4<f32>(0.0);
    for (var i = entry.start; i < entry.start + entry.count; i++) {
        let t = terms[i];
        let px = x + cs * t.cx + ss * t.cy;
        let py = y - ss * t.cx + cs * t.cy;
        if last == 0u {
            acc += t.weight * lookup(0u, px, py);
            continue;
        }
        // ln(sigma_eff / s), sigma_eff^2 = (s sigma)^2 + var_s, kept at
        // least s sigma / 2.
        var ln_sigma = t.ln_sigma;
        if var_s != 0.0 {
            let q = var_s * exp(-2.0 * (ln_s + t.ln_sigma));
            ln_sigma += 0.5 * log(max(1.0 + q, 0.25));
        }
        let u = clamp(ln_sigma * params.inv_ln_ratio + u_offset, 0.0, f32(last));
        var a = min(u32(u), last - 1u);
        var f = u - f32(a);
        // A sigma on a level up to rounding (the CPU's snap_to_level, with a
        // tolerance for f32 level positions), or nearest a level on a stack
        // read at the nearest level, reads that level alone.
        let snap = params.level_snap;
        if f < snap {
            f = 0.0;
        } else if f > 1.0 - snap {
            a += 1u;
            f = 0.0;
        }
        acc += (t.weight * (1.0 - f)) * lookup(a, px, py);
        if f != 0.0 {
            acc += (t.weight * f) * lookup(a + 1u, px, py);
        }
    }
    return acc;
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= params.region_w || gid.y >= params.region_h {
        return;
    }
    let x = params.region_x0 + gid.x;
    let y = params.region_y0 + gid.y;
    let pixel = y * params.width + x;
    var cos_t = params.cos_t;
    var sin_t = params.sin_t;
    var scale = params.scale;
    var u_offset = params.u_offset;
    var entry = params.entry;
    if (params.flags & FLAG_ANGLE_MAP) != 0u {
        // (cos, sin) of the pixel's angle, computed on the CPU exactly as
        // the CPU path does (WGSL's sin/cos may be as coarse as 2^-11).
        cos_t = maps[params.rot_off + 2u * pixel];
        sin_t = maps[params.rot_off + 2u * pixel + 1u];
    }
    if (params.flags & FLAG_SCALE_MAP) != 0u {
        scale = maps[params.scale_off + 2u * pixel];
        u_offset = maps[params.scale_off + 2u * pixel + 1u];
    }
    if (params.flags & FLAG_ENTRY_MAP) != 0u {
        entry = maps[params.entry_off + pixel];
    }
    let cs = cos_t * scale;
    let ss = sin_t * scale;
    let xf = f32(x);
    let yf = f32(y);
    let e0 = min(u32(max(entry, 0.0)), params.n_entries - 1u);
    let t = clamp(entry - f32(e0), 0.0, 1.0);
    var acc = eval_entry(e0, xf, yf, cs, ss, u_offset, scale);
    if t > 0.0 && e0 + 1u < params.n_entries {
        let b = eval_entry(e0 + 1u, xf, yf, cs, ss, u_offset, scale);
        acc = (1.0 - t) * acc + t * b;
    }
    let o = ((gid.y * params.region_w + gid.x) * params.channels) + params.chunk_c0;
    out[o] = acc.x;
    if params.chunk_nc > 1u {
        out[o + 1u] = acc.y;
    }
    if params.chunk_nc > 2u {
        out[o + 2u] = acc.z;
    }
    if params.chunk_nc > 3u {
        out[o + 3u] = acc.w;
    }
}
