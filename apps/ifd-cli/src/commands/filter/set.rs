//! `ifd filter IMAGE --kernel A --kernel B ... --filter-map M.npy`: several
//! filters on one image, each for the pixels the map gives it, through one
//! stack (`ifd_planar::FilterSetPlan`).

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use ifd_planar::FilterSetPlan;

use super::{Filter, per_pixel_kernel, timings};

impl Filter {
    /// Runs the command with `--filter-map map`.
    pub(super) fn run_set(&self, map: &Path) -> Result<()> {
        let names = self.filter_names();
        let decompositions = self.decompositions()?;
        let n = decompositions.len();
        let image = self.input.read(&self.image)?.image;
        let (w, h) = (image.width(), image.height());
        let weights = read_weights(self, map, n, (w, h))?;
        let maps = self.read_maps((w, h))?;
        let (angle, scale) = self.fields((w, h), &maps)?;
        let refs: Vec<&ifd_planar::Decomposition> = decompositions.iter().collect();
        let planning = Instant::now();
        let plan = FilterSetPlan::new((w, h, image.channels()), &refs, &scale, &self.options())
            .map_err(|e| match e {
                ifd_planar::FilterError::InvalidParameter(m) => {
                    // "filter 1: ..." names the filter by its number
                    anyhow::anyhow!("{}", name_filter(&m, &names))
                }
                other => other.into(),
            })
            .with_context(|| format!("filtering with {}", self.filter_name()))?;
        let planning = planning.elapsed();
        let t0 = Instant::now();
        let stack = plan
            .build_stack_for(&image, &scale)
            .context("prefiltering")?;
        let t1 = Instant::now();
        let out = plan
            .evaluate(&stack, angle, scale, &weights)
            .context("filtering")?;
        let t2 = Instant::now();
        if self.verbose {
            let e = &plan.evals[0];
            let levels = match &plan.level_sigmas {
                Some(s) => format!("{} levels at the terms' sigmas", s.len()),
                None => format!(
                    "{} levels per octave ({})",
                    e.samples_per_octave,
                    if e.nearest_level {
                        "the nearest read"
                    } else {
                        "two blended"
                    }
                ),
            };
            eprintln!(
                "evaluation: one stack for {n} filters, {} interpolation, pyramid factor {}, \
                 {levels}",
                e.interpolation.name(),
                (e.pyramid_factor * 1e3).round() / 1e3,
            );
            for (i, ((d, e), budget)) in decompositions
                .iter()
                .zip(&plan.evals)
                .zip(&plan.eval_budgets)
                .enumerate()
            {
                let pixels = weights[i].iter().filter(|&&v| v != 0.0).count();
                eprintln!(
                    "filter {i} ({}): {} terms on {:.1}% of the pixels; expected error {:.3}% on \
                     white noise, budget {:.3}% (bound {:.3}%, amplification {:.1})",
                    names[i],
                    d.terms.len(),
                    100.0 * pixels as f64 / (w * h) as f64,
                    100.0 * e.error_estimate,
                    100.0 * budget,
                    100.0 * e.total_bound(),
                    e.amplification
                );
            }
            if angle.is_map() || scale.is_map() {
                eprintln!(
                    "per-pixel lookups: {}",
                    per_pixel_kernel(e.interpolation, image.channels(), plan.vector_kernels)
                );
            }
            let terms = format!(
                "{} terms in all",
                refs.iter().map(|d| d.terms.len()).sum::<usize>()
            );
            eprintln!("{}", timings(&terms, &stack, planning, (t0, t1, t2)));
        }
        self.output.write(&out)
    }
}

/// A planning message about "filter i" with the filter's name added.
fn name_filter(message: &str, names: &[String]) -> String {
    let numbered = message
        .strip_prefix("filter ")
        .and_then(|rest| rest.split_once(':'))
        .and_then(|(i, rest)| Some((i.parse::<usize>().ok()?, rest)));
    match numbered {
        Some((i, rest)) if i < names.len() => format!("filter {i} ({}):{rest}", names[i]),
        _ => message.to_string(),
    }
}

/// The weight map of each of `n` filters from `--filter-map`: labels (one
/// channel) or `n` weights per pixel.
fn read_weights(
    cmd: &Filter,
    path: &Path,
    n: usize,
    (w, h): (usize, usize),
) -> Result<Vec<Vec<f32>>> {
    let map = cmd.input.read_map(path, "filter map")?;
    let shown = path.display();
    if (map.width(), map.height()) != (w, h) {
        bail!(
            "filter map {shown} is {}x{} but the image is {w}x{h}",
            map.width(),
            map.height()
        );
    }
    match map.channels() {
        1 => FilterSetPlan::weights_from_labels(map.data(), n, w)
            .with_context(|| format!("filter map {shown} (labels, for {n} filters)")),
        c if c == n => {
            // (the reader refuses non-finite values, or replaces them with
            // --replace-nonfinite)
            let data = map.data();
            Ok((0..n)
                .map(|k| data.iter().skip(k).step_by(n).copied().collect())
                .collect())
        }
        c => bail!(
            "filter map {shown} has {c} channels: give one (each pixel's filter number) or one \
             weight per filter ({n})"
        ),
    }
}
