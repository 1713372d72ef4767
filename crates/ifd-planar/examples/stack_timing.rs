//! Times [`ifd_planar::ScaleStack::new`] on one image: the prefiltering
//! `ifd filter` does before its lookups. `IFD_STACK_BUILD=fft` or `direct`
//! forces a build (default: the cheaper by the cost model);
//! `tests/bench/bench_stack_build.py` runs it side by side.
//!
//! ```text
//! cargo run --release -p ifd-planar --example stack_timing -- IMAGE SIGMA_MIN SIGMA_MAX [PYRAMID_FACTOR [RUNS]]
//! ```
//!
//! Builds the stack `RUNS` times (default 7; 4 levels per octave, bilinear,
//! reflect-101, pyramid factor default 4) after one warm-up build and
//! prints the median and the fastest build in ms and the build used.

use ifd_planar::{Border, ScaleStack, StackOptions};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [image, lo, hi, rest @ ..] = args.as_slice() else {
        return Err("usage: stack_timing IMAGE SIGMA_MIN SIGMA_MAX [PYRAMID_FACTOR [RUNS]]".into());
    };
    let image = ifd_image::read(image)?;
    let (lo, hi): (f64, f64) = (lo.parse()?, hi.parse()?);
    let pyramid_factor: f64 = rest.first().map_or(Ok(4.0), |f| f.parse())?;
    let runs: usize = rest.get(1).map_or(Ok(7), |r| r.parse())?;
    let options = StackOptions {
        pyramid_factor,
        ..StackOptions::default()
    };
    let mut times = Vec::with_capacity(runs);
    let mut build = "";
    for i in 0..=runs {
        let t = std::time::Instant::now();
        let stack = ScaleStack::new(&image, lo, hi, Border::Reflect101, options)?;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        build = stack.build_method().name();
        std::hint::black_box(stack);
        if i > 0 {
            times.push(ms);
        }
    }
    times.sort_by(f64::total_cmp);
    println!(
        "median {:.2} ms, fastest {:.2} ms, {build} build",
        times[times.len() / 2],
        times[0]
    );
    Ok(())
}
