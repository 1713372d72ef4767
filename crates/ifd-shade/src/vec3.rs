//! The few 3-vector operations the BRDF, sampling and shading code share
//! (directions are `[f64; 3]`, as in `ifd-sphere`).

pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub(crate) fn normalize(a: [f64; 3]) -> [f64; 3] {
    let n = dot(a, a).sqrt();
    [a[0] / n, a[1] / n, a[2] / n]
}

/// The normalised half vector of two unit vectors in the upper hemisphere.
pub(crate) fn half(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    normalize([a[0] + b[0], a[1] + b[1], a[2] + b[2]])
}

/// `wo` mirrored about `h`: `2 (wo . h) h - wo`.
pub(crate) fn reflect(wo: [f64; 3], h: [f64; 3]) -> [f64; 3] {
    let d = 2.0 * dot(wo, h);
    [d * h[0] - wo[0], d * h[1] - wo[1], d * h[2] - wo[2]]
}
