//! Unit tests of `equirect.rs`.

use super::*;
use crate::sh::ShEvaluator;
use crate::transform::{analyze_equirect, analyze_equirect_box};

#[test]
fn box_analysis_matches_subsampled_texels() {
    // even and odd heights (an odd height's equator row has no partner)
    box_analysis_case(12, 6);
    box_analysis_case(14, 7);
}

fn box_analysis_case(w: usize, h: usize) {
    // brute force: every texel split into k x k sub-texels (centres, exact
    // sub-texel solid angles), k large enough for 1e-6
    let (l_max, k) = (7usize, 64usize);
    let vals: Vec<f32> = (0..w * h).map(|i| ((i * 37 % 11) as f32) * 0.3).collect();
    let img = Image::from_vec(w, h, 1, vals.clone()).expect("image");
    let got = analyze_equirect_box(&img, l_max, Negatives::Keep)
        .expect("analysis")
        .coeffs;
    let sh = ShEvaluator::new(l_max).expect("evaluator");
    let mut want = vec![0.0; sh_count(l_max)];
    let mut y = vec![0.0; sh_count(l_max)];
    let (dp, dt) = (2.0 * PI / w as f64, PI / h as f64);
    for v in 0..h {
        for u in 0..w {
            let e = f64::from(vals[v * w + u]);
            for a in 0..k {
                let t0 = dt * (v as f64 + a as f64 / k as f64);
                let t1 = t0 + dt / k as f64;
                let t = 0.5 * (t0 + t1);
                let sa = (t0.cos() - t1.cos()) * dp / k as f64;
                for b in 0..k {
                    let p = dp * (u as f64 + (b as f64 + 0.5) / k as f64);
                    sh.eval_into([t.sin() * p.cos(), t.sin() * p.sin(), t.cos()], &mut y);
                    for (o, yi) in want.iter_mut().zip(&y) {
                        *o += e * sa * yi;
                    }
                }
            }
        }
    }
    let scale = want.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    for (i, (g, e)) in got.data().iter().zip(&want).enumerate() {
        assert!((g - e).abs() < 2e-5 * scale, "{i}: {g} vs {e}");
    }
    // and it differs from the pixel-centre rule at high degree
    let centre = analyze_equirect(&img, l_max, Negatives::Keep)
        .expect("analysis")
        .coeffs;
    let diff = centre
        .data()
        .iter()
        .zip(got.data())
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(diff > 1e-2 * scale, "{diff}");
}
