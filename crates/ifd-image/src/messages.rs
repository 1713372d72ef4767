//! How every ifd crate's messages print numbers and sizes: one convention,
//! so that an error from the sphere code reads like one from the image code.
//! Here because every crate depends on `ifd-image` and its own errors are the
//! first users.

/// `x` for a message: as Rust prints it when its magnitude lies in
/// `[1e-4, 1e7)` (or it is 0 or not finite), else in scientific notation, so
/// that 1e300 is not printed with 301 digits.
///
/// ```
/// assert_eq!(ifd_image::short_number(0.25), "0.25");
/// assert_eq!(ifd_image::short_number(1e300), "1e300");
/// ```
#[must_use]
pub fn short_number(x: f64) -> String {
    if x == 0.0 || !x.is_finite() || (1e-4..1e7).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// Formats a byte count with a binary unit (`1.5 GiB`).
#[must_use]
pub fn fmt_bytes(bytes: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = bytes as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{bytes} B")
    } else {
        format!("{v:.1} {}", UNITS[u])
    }
}
