//! Prints the error the aspect-ratio bank adds by blending the weights of two
//! neighbouring entries, as a markdown table (used in `docs/smoothing.md`).
//!
//! ```sh
//! cargo run --release -p ifd-smooth --example blend_error [-- STEPS_PER_OCTAVE]
//! ```
//!
//! For each pair of neighbouring entries it reports the relative L2 error
//! (against the exact sampled Gaussian) of the entries themselves, and of the
//! blend at the geometric midpoint and at the quarter points (in log aspect),
//! where blending errs most.

use std::process::ExitCode;

use ifd_smooth::{AspectBank, BankOptions};

fn main() -> ExitCode {
    let steps = match std::env::args().nth(1).map(|s| s.parse::<usize>()) {
        None => BankOptions::default().steps_per_octave,
        Some(Ok(n)) => n,
        Some(Err(e)) => {
            eprintln!("error: STEPS_PER_OCTAVE must be a whole number: {e}");
            return ExitCode::from(2);
        }
    };
    let options = BankOptions {
        steps_per_octave: steps,
        ..BankOptions::default()
    };
    let bank = match AspectBank::build(options, |i, n| eprint!("\rfitting entry {i}/{n}")) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("\nerror: {e}");
            return ExitCode::from(2);
        }
    };
    eprintln!();
    println!(
        "bank: sigma_ref {}, max aspect {}, {} entries per octave, fit tolerance {}",
        options.sigma_ref, options.max_aspect, options.steps_per_octave, options.tol
    );
    println!();
    println!("| entries | terms | entry errors | blend at 1/4 | blend at 1/2 | blend at 3/4 |");
    println!("|---|---|---|---|---|---|");
    let err = |a: f64| bank.blend_error(a).map(|e| format!("{:.2}%", 100.0 * e));
    for (i, w) in bank.aspects.windows(2).enumerate() {
        let at = |t: f64| w[0] * (w[1] / w[0]).powf(t);
        let row = (|| -> Result<String, ifd_smooth::SmoothError> {
            Ok(format!(
                "| {:.2} - {:.2} | {} + {} | {} / {} | {} | {} | {} |",
                w[0],
                w[1],
                bank.terms[i].len(),
                bank.terms[i + 1].len(),
                err(w[0])?,
                err(w[1])?,
                err(at(0.25))?,
                err(at(0.5))?,
                err(at(0.75))?
            ))
        })();
        match row {
            Ok(r) => println!("{r}"),
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::from(2);
            }
        }
    }
    ExitCode::SUCCESS
}
