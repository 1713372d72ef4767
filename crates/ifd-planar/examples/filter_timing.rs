//! Times [`ifd_planar::filter_image`], the call `ifd filter` and
//! the Python module's `ifd.filter` make, from Rust: the other side of the
//! module's throughput benchmark (`tests/bench/bench_python.py`).
//!
//! ```text
//! cargo run --release -p ifd-planar --example filter_timing -- IMAGE.npy DECOMP.json ANGLE.npy [RUNS [WARMUP]]
//! ```
//!
//! Reads a float32 image and an `(H, W)` angle map (degrees), filters
//! `WARMUP` times (default 3: the thread pool, the allocator's thresholds and
//! the page cache settle as in a long-lived process), then `RUNS` times
//! (default 1), printing one line per run: the seconds of that call.

use ifd_planar::{CheckField, Decomposition, Field, FieldKind};
use ifd_planar::{FilterOptions, filter_image};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [image, decomp, angle, rest @ ..] = args.as_slice() else {
        return Err("usage: filter_timing IMAGE.npy DECOMP.json ANGLE.npy [RUNS [WARMUP]]".into());
    };
    let runs: usize = rest.first().map_or(Ok(1), |r| r.parse())?;
    let warmup: usize = rest.get(1).map_or(Ok(3), |r| r.parse())?;
    let image = ifd_image::read(image)?;
    let angle = ifd_image::read(angle)?;
    let d = Decomposition::load(decomp)?;
    let (w, h) = (image.width(), image.height());
    let run = || -> Result<f64, Box<dyn std::error::Error>> {
        let a = Field::Map(angle.data()).check(FieldKind::Angle, w, h)?;
        let s = Field::Constant(1.0).check(FieldKind::Scale, w, h)?;
        let t = std::time::Instant::now();
        let out = filter_image(&image, &d, a, s, &FilterOptions::default())?;
        let secs = t.elapsed().as_secs_f64();
        std::hint::black_box(out);
        Ok(secs)
    };
    for _ in 0..warmup {
        run()?;
    }
    for _ in 0..runs {
        println!("{}", run()?);
    }
    Ok(())
}
