// ISD shading (ISD Eq. 22) of a buffer of surface points, one invocation per
// pixel:
//
//   I(wo) = sum_{l, j} lambda_l^j(wo) Ehat_l(R z_j),
//   Ehat_l(d) = pi_l sum_m e_l^m y_l^m(d)
//
// with the per-band environment Ehat_l either reconstructed from the SH
// coefficients at each rotated lobe direction (VARIANT_SH) or read from the
// per-band prefiltered maps with Catmull-Rom weights computed here
// (VARIANT_MAPS; not the hardware filter, whose weights have 8 bits). The
// CPU reference is `ifd_shade::shade::Material::shade_isd` (docs/gpu-shading.md).
//
// The host prepends (ifd_gpu::shaders::isd_shade_source):
//   const NB: u32           bands, L + 1 (sizes the private band sums and the
//                           uniform arrays);
//   const VARIANT_*, MATERIAL_* codes (ifd_gpu::shaders::shade_codes).
//
// What every invocation reads at the same index (the SH coefficients, the
// recurrence constants, the lobes, the table headers) is in uniform buffers:
// broadcast from the constant cache on GPUs, and scalar loads rather than
// per-lane gathers on lavapipe (about 2x there). Limit: (L + 1)^2 vec4 of
// coefficients in a 64 KiB binding, L <= 63.
//
// Buffers:
//   surf     5 vec4 per pixel: (n, hit), (tangent, roughness), (wo,
//            metallic), (albedo, occlusion) on the object or (background, 0)
//            elsewhere, (emission, 0); the tangent is already orthogonal to
//            n (ifd_shade's Frame); MATERIAL_GLTF reads the albedo as the base
//            colour, combines the three parts' integrals with it and the
//            metalness (ifd_shade::GltfMaterial::combine), then scales by a
//            glTF asset's occlusion and adds its emission.
//   sh       VARIANT_SH: (L + 1)^2 vec4 (rgb, 0) coefficients e_l^m, index
//            l (l + 1) + m (zeros in the other variant).
//   consts   vec4 per k < NB: (sectoral factor of order m = k, sqrt(2m + 3),
//            pi_l, k_l of band l = k) (k_l: closed-form zonal weights); then
//            the Legendre recurrence (a_lm, b_lm, 0, 0) at NB + l (l + 1) / 2 + m.
//   lobes    vec4 per lobe: local direction, first band it serves.
//   weights  every lobe table of the material, one after another, each
//            [theta][phi][K][kc] f32.
//   tables   per table: offset into weights, n_theta, n_phi, roughness.
//   maps     VARIANT_MAPS: (L + 1) maps of map_w x map_h texels, 3 floats
//            each, band-major, rows from the zenith.

struct Params {
    width: u32,
    height: u32,
    variant: u32,
    material: u32,
    isotropic: u32,
    in_plane: u32,
    n_lobes: u32,
    count: u32,
    kc: u32,
    n_tables: u32,
    map_w: u32,
    map_h: u32,
    // the rows shaded by this dispatch start here (frames are shaded in
    // bands, so that a slow adapter never holds the queue for long)
    row0: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

struct Table {
    offset: u32,
    n_theta: u32,
    n_phi: u32,
    roughness: f32,
}

const MAX_LOBES: u32 = 2u * NB - 1u;
const N_CONSTS: u32 = NB + NB * (NB + 1u) / 2u;
const MAX_TABLES: u32 = 64u;

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> surf: array<vec4<f32>>;
@group(0) @binding(2) var<uniform> sh: array<vec4<f32>, NB * NB>;
@group(0) @binding(3) var<uniform> consts: array<vec4<f32>, N_CONSTS>;
@group(0) @binding(4) var<uniform> lobes: array<vec4<f32>, MAX_LOBES>;
@group(0) @binding(5) var<storage, read> weights: array<f32>;
@group(0) @binding(6) var<uniform> tables: array<Table, MAX_TABLES>;
@group(0) @binding(7) var<storage, read> maps: array<f32>;
@group(0) @binding(8) var<storage, read_write> out: array<vec4<f32>>;

const PI: f32 = 3.14159265358979;
const HALF_PI: f32 = 1.57079632679490;
const TWO_PI: f32 = 6.28318530717959;
const SQRT2: f32 = 1.41421356237310;

// Per-band sums of the environment at one direction, for the bands the
// current lobe serves.
var<private> bands: array<vec3<f32>, NB>;

fn coeff(i: u32) -> vec3<f32> {
    return sh[i].xyz;
}

// bands[l] = sum_m e_l^m y_l^m(d) for l >= l0 (the others are left as they
// are). The recurrences of ifd_sphere::sh with sin^m(theta) folded into the
// sectoral start value (the reduced values of the CPU code overflow f32
// beyond L ~ 38), and (cos m phi, sin m phi) by rotation.
fn band_sums(d: vec3<f32>, l0: u32) {
    let z = clamp(d.z, -1.0, 1.0);
    let rxy = length(d.xy);
    let st = rxy;
    var cp = 1.0;
    var sp = 0.0;
    if rxy > 0.0 {
        cp = d.x / rxy;
        sp = d.y / rxy;
    }
    for (var l = l0; l < NB; l++) {
        bands[l] = vec3<f32>(0.0);
    }
    var pmm = 0.28209479177387814; // y_0^0
    var cm = 1.0;
    var sm = 0.0;
    for (var m = 0u; m < NB; m++) {
        if m > 0u {
            pmm = pmm * consts[m].x * st;
            let c = cm * cp - sm * sp;
            sm = sm * cp + cm * sp;
            cm = c;
        }
        var fc = 1.0;
        var fs = 0.0;
        if m > 0u {
            fc = SQRT2 * cm;
            fs = SQRT2 * sm;
        }
        var p2 = pmm;
        if m >= l0 {
            bands[m] += p2 * band_term(m, m, fc, fs);
        }
        if m + 1u < NB {
            var p1 = consts[m].y * z * p2;
            if m + 1u >= l0 {
                bands[m + 1u] += p1 * band_term(m + 1u, m, fc, fs);
            }
            for (var l = m + 2u; l < NB; l++) {
                let ab = consts[NB + l * (l + 1u) / 2u + m];
                let p = ab.x * (z * p1 - ab.y * p2);
                if l >= l0 {
                    bands[l] += p * band_term(l, m, fc, fs);
                }
                p2 = p1;
                p1 = p;
            }
        }
    }
}

// fc e_l^m + fs e_l^-m (m > 0), or e_l^0.
fn band_term(l: u32, m: u32, fc: f32, fs: f32) -> vec3<f32> {
    let base = l * (l + 1u);
    if m == 0u {
        return coeff(base);
    }
    return fc * coeff(base + m) + fs * coeff(base - m);
}

// The 16 Catmull-Rom taps of ifd_sphere::transform::bicubic_taps at d:
// texel indices and weights.
var<private> tap_index: array<u32, 16>;
var<private> tap_weight: array<f32, 16>;

fn catmull_rom(f: f32) -> vec4<f32> {
    let f2 = f * f;
    let f3 = f2 * f;
    return 0.5 * vec4<f32>(-f3 + 2.0 * f2 - f, 3.0 * f3 - 5.0 * f2 + 2.0,
        -3.0 * f3 + 4.0 * f2 + f, f3 - f2);
}

fn map_taps(d: vec3<f32>) {
    let w = i32(params.map_w);
    let h = i32(params.map_h);
    // atan2 rather than the CPU's acos: accurate near the poles in f32
    let t = atan2(length(d.xy), d.z);
    var p = 0.0;
    if length(d.xy) > 0.0 {
        p = atan2(d.y, d.x);
    }
    if p < 0.0 {
        p += TWO_PI;
    }
    let x = p / TWO_PI * f32(w) - 0.5;
    let y = t / PI * f32(h) - 0.5;
    let x0 = floor(x);
    let y0 = floor(y);
    let wx = catmull_rom(x - x0);
    let wy = catmull_rom(y - y0);
    let xi = i32(x0);
    let yi = i32(y0);
    for (var a = 0; a < 4; a++) {
        var v = yi - 1 + a;
        var shift = 0;
        if v < 0 {
            v = -1 - v;
            shift = w / 2;
        } else if v >= h {
            v = 2 * h - 1 - v;
            shift = w / 2;
        }
        v = clamp(v, 0, h - 1);
        for (var b = 0; b < 4; b++) {
            var u = (xi - 1 + b + shift) % w;
            if u < 0 {
                u += w;
            }
            tap_index[a * 4 + b] = u32(v * w + u);
            tap_weight[a * 4 + b] = wy[a] * wx[b];
        }
    }
}

fn map_band(l: u32) -> vec3<f32> {
    let base = l * params.map_w * params.map_h;
    var acc = vec3<f32>(0.0);
    for (var k = 0u; k < 16u; k++) {
        let i = 3u * (base + tap_index[k]);
        acc += tap_weight[k] * vec3<f32>(maps[i], maps[i + 1u], maps[i + 2u]);
    }
    return acc;
}

// Ehat_l(d) for l >= l0 into bands[l] (pi_l included), in either variant.
fn environment_bands(d: vec3<f32>, l0: u32) {
    if params.variant == VARIANT_SH {
        band_sums(d, l0);
        for (var l = l0; l < NB; l++) {
            bands[l] *= consts[l].z;
        }
    } else {
        map_taps(d);
        for (var l = l0; l < NB; l++) {
            bands[l] = map_band(l);
        }
    }
}

// A closed-form zonal slice about `axis`: sum_l k_l Ehat_l(axis).
fn shade_zonal(axis: vec3<f32>) -> vec3<f32> {
    environment_bands(axis, 0u);
    var acc = vec3<f32>(0.0);
    for (var l = 0u; l < NB; l++) {
        acc += consts[l].w * bands[l];
    }
    return acc;
}

// The table entries around the view and their weights (two tables of a
// roughness family, two or four entries each): offsets into `weights`.
var<private> corner_offset: array<u32, 8>;
var<private> corner_weight: array<f32, 8>;

fn table_corners(k: u32, theta: f32, phi: f32, tw: f32, slot: u32) {
    let tb = tables[k];
    let nt = tb.n_theta;
    let np = tb.n_phi;
    let entry = params.count * params.kc;
    let x = clamp(clamp(theta, 0.0, HALF_PI) / HALF_PI * f32(nt) - 0.5, 0.0, f32(nt - 1u));
    let i0 = min(u32(floor(x)), nt - 2u);
    let ft = x - f32(i0);
    if params.isotropic != 0u {
        corner_offset[slot] = tb.offset + i0 * entry;
        corner_weight[slot] = tw * (1.0 - ft);
        corner_offset[slot + 1u] = tb.offset + (i0 + 1u) * entry;
        corner_weight[slot + 1u] = tw * ft;
        corner_weight[slot + 2u] = 0.0;
        corner_weight[slot + 3u] = 0.0;
        corner_offset[slot + 2u] = tb.offset;
        corner_offset[slot + 3u] = tb.offset;
    } else {
        var pr = phi;
        if pr < 0.0 {
            pr += TWO_PI;
        }
        let y = pr / TWO_PI * f32(np);
        let j0 = u32(floor(y)) % np;
        let fp = y - floor(y);
        let j1 = (j0 + 1u) % np;
        corner_offset[slot] = tb.offset + (i0 * np + j0) * entry;
        corner_weight[slot] = tw * (1.0 - ft) * (1.0 - fp);
        corner_offset[slot + 1u] = tb.offset + (i0 * np + j1) * entry;
        corner_weight[slot + 1u] = tw * (1.0 - ft) * fp;
        corner_offset[slot + 2u] = tb.offset + ((i0 + 1u) * np + j0) * entry;
        corner_weight[slot + 2u] = tw * ft * (1.0 - fp);
        corner_offset[slot + 3u] = tb.offset + ((i0 + 1u) * np + j1) * entry;
        corner_weight[slot + 3u] = tw * ft * fp;
    }
}

// MATERIAL_GLTF: the integrals of the three parts (S (1 - w), S w,
// (1 - w) / pi), each RGB.
var<private> part_acc: array<vec3<f32>, 3>;

// The interpolated weight lambda_l^j (per channel).
fn lobe_weight(l: u32, j: u32) -> vec3<f32> {
    var idx = l * l + j;
    if params.in_plane != 0u {
        idx = l * (l + 1u) / 2u + j;
    }
    var acc = vec3<f32>(0.0);
    for (var c = 0u; c < 8u; c++) {
        let wt = corner_weight[c];
        if wt != 0.0 {
            let o = corner_offset[c] + idx * params.kc;
            if params.kc == 1u {
                acc += vec3<f32>(wt * weights[o]);
            } else {
                acc += wt * vec3<f32>(weights[o], weights[o + 1u], weights[o + 2u]);
            }
        }
    }
    return acc;
}

fn shade_table(n: vec3<f32>, t_in: vec3<f32>, wl: vec3<f32>, roughness: f32) -> vec3<f32> {
    let rxy = length(wl.xy);
    var phi = 0.0;
    if rxy > 0.0 {
        phi = atan2(wl.y, wl.x);
    }
    let theta = atan2(rxy, wl.z);
    // isotropic tables: the frame rotated about n by phi_o, so that the view
    // lies in its xz plane (x = the view projected on the tangent plane)
    var t = t_in;
    let b_in = cross(n, t_in);
    if params.isotropic != 0u && rxy > 0.0 {
        t = (wl.x * t_in + wl.y * b_in) / rxy;
    }
    let b = cross(n, t);
    // the roughness family: the two tables around `roughness`
    let nt = params.n_tables;
    var k = 0u;
    var tw = 0.0;
    if nt > 1u {
        let x = clamp(roughness, tables[0].roughness, tables[nt - 1u].roughness);
        var below = 0u;
        for (var i = 0u; i < nt; i++) {
            if tables[i].roughness <= x {
                below = i + 1u;
            }
        }
        k = clamp(below, 1u, nt - 1u) - 1u;
        let r0 = tables[k].roughness;
        let r1 = tables[k + 1u].roughness;
        tw = clamp((x - r0) / (r1 - r0), 0.0, 1.0);
        table_corners(k + 1u, theta, phi, tw, 4u);
    } else {
        for (var c = 4u; c < 8u; c++) {
            corner_weight[c] = 0.0;
            corner_offset[c] = 0u;
        }
    }
    table_corners(k, theta, phi, 1.0 - tw, 0u);
    var acc = vec3<f32>(0.0);
    let parts = params.material == MATERIAL_GLTF;
    for (var p = 0u; p < 3u; p++) {
        part_acc[p] = vec3<f32>(0.0);
    }
    for (var j = 0u; j < params.n_lobes; j++) {
        let lobe = lobes[j];
        let l0 = u32(lobe.w);
        let d = lobe.x * t + lobe.y * b + lobe.z * n;
        environment_bands(d, l0);
        for (var l = l0; l < NB; l++) {
            let w = lobe_weight(l, j);
            if parts {
                // every part against every colour channel
                part_acc[0] += w.x * bands[l];
                part_acc[1] += w.y * bands[l];
                part_acc[2] += w.z * bands[l];
            } else {
                acc += w * bands[l];
            }
        }
    }
    return acc;
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let y = gid.y + params.row0;
    if gid.x >= params.width || y >= params.height {
        return;
    }
    let i = y * params.width + gid.x;
    let s0 = surf[5u * i];
    let s1 = surf[5u * i + 1u];
    let s2 = surf[5u * i + 2u];
    let s3 = surf[5u * i + 3u];
    if s0.w < 0.5 {
        out[i] = vec4<f32>(s3.xyz, 0.0);
        return;
    }
    let n = s0.xyz;
    let t = s1.xyz;
    let wo = s2.xyz;
    let b = cross(n, t);
    let wl = vec3<f32>(dot(t, wo), dot(b, wo), dot(n, wo));
    var c = vec3<f32>(0.0);
    if params.material == MATERIAL_LAMBERT {
        if wl.z > 0.0 {
            c = shade_zonal(n);
        }
    } else if params.material == MATERIAL_PHONG {
        // the mirror direction; Phong's slice is defined below the horizon too
        c = shade_zonal(2.0 * wl.z * n - wo);
    } else if wl.z > 0.0 {
        c = shade_table(n, t, wl, s1.w);
        if params.material == MATERIAL_GLTF {
            // f0 = 0.04 (1 - m) + m base, c_diff = base (1 - m)
            let base = s3.xyz;
            let m = s2.w;
            let f0 = vec3<f32>(0.04 * (1.0 - m)) + m * base;
            let c_diff = base * (1.0 - m);
            c = f0 * part_acc[0] + part_acc[1] + 0.96 * c_diff * part_acc[2];
        }
    }
    if params.material == MATERIAL_GLTF {
        // a glTF asset's occlusion scales the environment's light, its
        // emission adds (1 and 0 elsewhere), as ifd_render applies them
        out[i] = vec4<f32>(c * s3.w + surf[5u * i + 4u].xyz, 1.0);
        return;
    }
    out[i] = vec4<f32>(c * s3.xyz, 1.0);
}
