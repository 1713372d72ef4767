//! Checks of the BRDF slices, closed forms, MERL files and lobe tables against
//! independent references (brute-force quadrature, analytic identities).

use std::f64::consts::PI;

use ifd_shade::Brdf;
use ifd_shade::LobeTable;
use ifd_shade::project_slice;
use ifd_shade::{Merl, merl_format as merl};
use ifd_shade::{legendre_moments, zonal_slice};
use ifd_sphere::{gauss_legendre, legendre_p};
use ifd_sphere::{project_band, project_function};

fn view(theta: f64, phi: f64) -> [f64; 3] {
    [
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    ]
}

/// `int k_wo(wi) dwi` by a dense midpoint rule in `(theta, phi)` over the
/// hemisphere (independent of the SH code).
fn brute_albedo(b: &Brdf, wo: [f64; 3], n: usize) -> f64 {
    let mut sum = 0.0;
    let mut k = [0.0; 3];
    for i in 0..n {
        let t = (i as f64 + 0.5) * (PI / 2.0) / n as f64;
        for j in 0..4 * n {
            let p = (j as f64 + 0.5) * 2.0 * PI / (4 * n) as f64;
            b.slice(view(t, p), wo, &mut k);
            sum += k[0] * t.sin();
        }
    }
    sum * (PI / 2.0 / n as f64) * (2.0 * PI / (4 * n) as f64)
}

#[test]
fn legendre_moments_match_quadrature() {
    let (x, w) = gauss_legendre(200);
    for s in [0.0, 1.0, 8.0, 32.5] {
        let m = legendre_moments(s, 20);
        for (l, ml) in m.iter().enumerate() {
            // int_0^1 t^s P_l(t) dt on [0, 1]
            let q: f64 = x
                .iter()
                .zip(&w)
                .map(|(xi, wi)| {
                    let t = 0.5 * (xi + 1.0);
                    0.5 * wi * t.powf(s) * legendre_p(l, t)
                })
                .sum();
            assert!((ml - q).abs() < 1e-12, "s = {s}, l = {l}: {ml} vs {q}");
        }
    }
}

#[test]
fn lambert_zonal_coefficients_are_the_irradiance_factors() {
    let b = Brdf::parse("lambert").unwrap();
    let (axis, k) = zonal_slice(&b, [0.0, 0.0, 1.0], 6).unwrap();
    assert_eq!(axis, [0.0, 0.0, 1.0]);
    // pi_l k_l = A_hat_l / pi: pi, 2 pi / 3, pi / 4, 0, -pi / 24 (Ramamoorthi-Hanrahan 2001)
    let want = [
        PI,
        2.0 * PI / 3.0,
        PI / 4.0,
        0.0,
        -PI / 24.0,
        0.0,
        PI / 64.0,
    ];
    for (l, wl) in want.iter().enumerate() {
        let pil = (4.0 * PI / (2 * l + 1) as f64).sqrt();
        assert!((pil * k[l] - wl / PI).abs() < 1e-14, "l = {l}");
    }
}

#[test]
fn closed_form_slices_match_numerical_projection() {
    // Phong about r and Lambert about n against the generic quadrature of the
    // slice function over the whole sphere
    for spec in ["phong:s=8", "phong:s=32,albedo=0.7", "lambert:albedo=0.5"] {
        let b = Brdf::parse(spec).unwrap();
        let wo = view(0.6, 0.4);
        let c = project_slice(&b, wo, 12, None).unwrap();
        let slice = |wi: [f64; 3]| {
            let mut k = [0.0];
            b.slice(wi, wo, &mut k);
            k[0]
        };
        // Lambert's kink is at the horizon: integrate the upper hemisphere only
        let f = if spec.starts_with("lambert") {
            project_band(12, 1, (0.0, 1.0), 64, |wi, o| o[0] = slice(wi)).unwrap()
        } else {
            project_function(12, slice, 600).unwrap()
        };
        let scale = f.data().iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for (a, e) in c.data().iter().zip(f.data()) {
            assert!((a - e).abs() < 1e-9 * scale, "{spec}: {a} vs {e}");
        }
    }
}

#[test]
fn white_furnace_albedo_of_every_model() {
    // the integral of the slice is c_00 sqrt(4 pi); Lambert and Phong are exact
    // Blinn-Phong's (s + 8) / (8 pi) is an approximate normalisation: its
    // albedo exceeds 1 near normal incidence (1.027 at s = 64, theta_o = 0:
    // s (s + 8) / ((s + 2)(s + 4))); `blinn-exact` normalises it at normal
    // view and stays below 1 elsewhere
    let cases: [(&str, f64); 9] = [
        ("lambert", 1e-12),
        ("phong:s=32", 1e-12),
        ("blinn:s=64", 3e-2),
        ("blinn-exact:s=64", 1e-3),
        ("blinn-exact:s=8", 1e-3),
        ("ggx:alpha=0.3", 1e-3),
        ("ggx:ax=0.1,ay=0.4", 1e-3),
        ("ward:ax=0.15,ay=0.3", 1e-3),
        ("ward:alpha=0.3", 1e-3),
    ];
    for (spec, tol) in cases {
        let b = Brdf::parse(spec).unwrap();
        for t in [0.0, 0.4, 0.8, 1.2, 1.5] {
            let wo = view(t, 0.3);
            let c = project_slice(&b, wo, 8, None).unwrap();
            let albedo = c.get(0, 0, 0) * (4.0 * PI).sqrt();
            assert!(
                albedo <= 1.0 + tol,
                "{spec} at theta_o = {t}: albedo {albedo}"
            );
            if spec == "lambert" || spec.starts_with("phong") {
                assert!((albedo - 1.0).abs() < 1e-12, "{spec}: {albedo}");
            } else {
                if spec.starts_with("blinn-exact") && t == 0.0 {
                    assert!(
                        (albedo - 1.0).abs() < 2e-3,
                        "{spec} at normal view: {albedo}"
                    );
                }
                // the SH quadrature against an independent brute-force sum
                let brute = brute_albedo(&b, wo, 800);
                assert!(
                    (albedo - brute).abs() < 2e-3 * brute.max(1e-3),
                    "{spec} at {t}: {albedo} vs brute force {brute}"
                );
            }
        }
    }
}

#[test]
fn ggx_matches_the_gltf_isotropic_formula() {
    let iso = Brdf::parse("ggx:alpha=0.35").unwrap();
    let aniso = Brdf::parse("ggx:ax=0.35,ay=0.35").unwrap();
    let (wi, wo) = (view(0.7, 2.0), view(0.4, -0.3));
    let (mut a, mut b) = ([0.0], [0.0]);
    iso.slice(wi, wo, &mut a);
    aniso.slice(wi, wo, &mut b);
    // glTF 2.0 Appendix B, written out
    let a2: f64 = 0.35 * 0.35;
    let h = {
        let s = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
        let n = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
        [s[0] / n, s[1] / n, s[2] / n]
    };
    let d = a2 / (PI * (h[2] * h[2] * (a2 - 1.0) + 1.0).powi(2));
    let (nl, nv) = (wi[2], wo[2]);
    let v =
        0.5 / (nl * (nv * nv * (1.0 - a2) + a2).sqrt() + nv * (nl * nl * (1.0 - a2) + a2).sqrt());
    let want = d * v * nl;
    assert!((a[0] - want).abs() < 1e-12 * want, "{} vs {want}", a[0]);
    assert!((b[0] - want).abs() < 1e-12 * want);
    assert!(!Brdf::parse("ggx:ax=0.1,ay=0.4").unwrap().is_isotropic());
}

#[test]
fn bad_specs_name_the_problem() {
    for (spec, needle) in [
        ("gx:alpha=0.3", "unknown BRDF"),
        ("ggx:alpha=nan", "not"),
        ("ggx:alpha=-0.2", "outside"),
        ("ggx:ax=0.2", "both ax= and ay="),
        ("phong", "missing s="),
        ("phong:s=1e9", "outside"),
        ("lambert:albedo=1.5", "outside"),
        ("lambert:s=3", "takes no parameter"),
        ("ward:alpha=0.2,alpha=0.3", "twice"),
        ("merl:", "merl:FILE"),
        ("merl:/nonexistent/x.binary", "cannot read"),
    ] {
        let e = Brdf::parse(spec).unwrap_err().to_string();
        assert!(e.contains(needle), "{spec}: {e}");
    }
}

fn ggx_rgb(th: f64, td: f64, pd: f64) -> [f64; 3] {
    let (wi, wo) = merl::from_half_diff(th, 0.0, td, pd);
    let b = Brdf::parse("ggx:alpha=0.4").expect("a valid spec");
    if wi[2] <= 0.0 || wo[2] <= 0.0 {
        return [-1.0; 3]; // invalid, as MERL marks unmeasured bins
    }
    let mut k = [0.0];
    b.slice(wi, wo, &mut k);
    let f = k[0] / wi[2];
    [f, 0.5 * f, 0.25 * f]
}

#[test]
fn merl_files_round_trip_and_read_as_the_model() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ggx.binary");
    Merl::tabulate(ggx_rgb).write(&path).unwrap();
    assert_eq!(
        std::fs::metadata(&path).unwrap().len(),
        merl::FILE_BYTES as u64
    );
    let b = Brdf::parse(&format!("merl:{}", path.display())).unwrap();
    let Some(m) = (match b.model() {
        ifd_shade::Model::Merl(m) => Some(m.clone()),
        _ => None,
    }) else {
        panic!("not a MERL BRDF")
    };
    assert!(m.invalid_values() > 0);
    // at bin centres the reader returns the tabulated model (f32 storage)
    for i in (0..merl::SAMPLES).step_by(9973) {
        let (th, td, pd) = merl::bin_centre(i);
        let want = ggx_rgb(th, td, pd);
        let (wi, wo) = merl::from_half_diff(th, 1.1, td, pd);
        let got = m.eval(wi, wo);
        for c in 0..3 {
            let w = want[c].max(0.0);
            assert!(
                (got[c] - w).abs() <= 1e-6 * w + 1e-12,
                "bin {i} ch {c}: {} vs {w}",
                got[c]
            );
        }
    }
    // the slice of the MERL BRDF integrates like the model's (nearest-bin error)
    let model = Brdf::parse("ggx:alpha=0.4").unwrap();
    for t in [0.2, 0.9] {
        let wo = view(t, 0.0);
        let a = project_slice(&b, wo, 6, Some(160)).unwrap();
        let e = project_slice(&model, wo, 6, Some(160)).unwrap();
        let (ar, ab) = (a.get(0, 0, 0), a.get(0, 0, 2));
        assert!(
            (ar - e.get(0, 0, 0)).abs() < 0.03 * e.get(0, 0, 0),
            "{ar} vs {}",
            e.get(0, 0, 0)
        );
        assert!((ab - 0.25 * ar).abs() < 1e-6 * ar);
    }
}

#[test]
fn merl_reader_refuses_bad_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let short = d.join("short.binary");
    std::fs::write(&short, [0u8; 100]).unwrap();
    let e = Merl::read(&short).unwrap_err().to_string();
    assert!(e.contains("short.binary") && e.contains("100 bytes"), "{e}");
    let mut bytes = vec![0u8; merl::FILE_BYTES];
    for (i, dim) in [90i32, 90, 90].iter().enumerate() {
        bytes[4 * i..4 * i + 4].copy_from_slice(&dim.to_le_bytes());
    }
    let dims = d.join("dims.binary");
    std::fs::write(&dims, &bytes).unwrap();
    let e = Merl::read(&dims).unwrap_err().to_string();
    assert!(e.contains("[90, 90, 90]"), "{e}");
    bytes[8..12].copy_from_slice(&180i32.to_le_bytes());
    bytes[12 + 8 * 5..12 + 8 * 6].copy_from_slice(&f64::NAN.to_le_bytes());
    let nan = d.join("nan.binary");
    std::fs::write(&nan, &bytes).unwrap();
    let e = Merl::read(&nan).unwrap_err().to_string();
    assert!(e.contains("non-finite") && e.contains("sample 5"), "{e}");
}

#[test]
fn tables_interpolate_their_entries_and_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    for (spec, n_phi) in [("ggx:alpha=0.5", 1), ("ggx:ax=0.3,ay=0.6", 8)] {
        let b = Brdf::parse(spec).unwrap();
        let (l, nt) = (5, 12);
        let t = LobeTable::build(&b, l, nt, n_phi, &|_, _| {}).unwrap();
        let h = t.header();
        assert_eq!((h.n_theta, h.isotropic), (nt, n_phi == 1));
        // isotropic tables: L + 1 in-plane lobes; anisotropic: 2L + 1 shared
        let basis = t.basis();
        assert_eq!(
            basis.directions().len(),
            if n_phi == 1 { l + 1 } else { 2 * l + 1 }
        );
        // an entry's weights are the ZHF of that view's slice
        let (i, j) = (5, if n_phi == 1 { 0 } else { 3 });
        let th = (i as f64 + 0.5) * PI / 2.0 / nt as f64;
        let ph = 2.0 * PI * j as f64 / h.n_phi as f64;
        let exact = basis
            .zhf(&project_slice(&b, view(th, ph), l, None).unwrap())
            .unwrap();
        let got = t.weights_at(th, ph);
        let scale = exact.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for (g, e) in got.iter().zip(&exact) {
            assert!((g - e).abs() < 1e-6 * scale, "{spec}: {g} vs {e}");
        }
        // the measured interpolation error is real: recompute one midpoint
        let mid = (i as f64 + 1.0) * PI / 2.0 / nt as f64;
        let want = project_slice(&b, view(mid, ph), l, None).unwrap();
        let c = basis.zhe(&t.weights_at(mid, ph), 1).unwrap();
        let num: f64 = c
            .data()
            .iter()
            .zip(want.data())
            .map(|(a, b)| (a - b).powi(2))
            .sum();
        let den: f64 = want.data().iter().map(|b| b * b).sum();
        let err = (num / den).sqrt();
        assert!(
            err > 0.0 && err <= h.interpolation_error * 1.000_001,
            "{err} vs {}",
            h.interpolation_error
        );
        // files
        let path = dir.path().join("t.lobes");
        t.write(&path).unwrap();
        let r = LobeTable::read(&path).unwrap();
        assert_eq!(r.header(), t.header());
        assert_eq!(r.weights_at(0.77, 1.3), t.weights_at(0.77, 1.3));
        r.check_for(&b, l).unwrap();
        let e = r.check_for(&b, l + 1).unwrap_err().to_string();
        assert!(e.contains("L = 5, not L = 6"), "{e}");
        let other = Brdf::parse("ggx:alpha=0.2").unwrap();
        let e = r.check_for(&other, l).unwrap_err().to_string();
        assert!(e.contains(spec) && e.contains("ggx:alpha=0.2"), "{e}");
    }
}

/// The in-plane basis rests on the slice at `phi_o = 0` being even in `y`:
/// the numerical projection of the slice (independent of the basis) has no
/// `m < 0` part, and tables with in-plane and shared lobes shade alike (to
/// the f32 storage) while evaluating `L + 1` directions instead of `2L + 1`.
#[test]
fn in_plane_and_shared_tables_shade_alike() {
    use ifd_shade::LobeKind;
    use ifd_shade::{Environment, Frame, Material};
    use ifd_sphere::ShCoeffs;
    use ifd_sphere::SplitMix64;
    use ifd_sphere::odd_part_norm;
    let l = 10;
    for spec in ["ggx:alpha=0.3", "blinn-exact:s=40", "ward:ax=0.2,ay=0.2"] {
        let b = Brdf::parse(spec).unwrap();
        for t in [0.1, 0.7, 1.3] {
            let c = project_slice(&b, view(t, 0.0), l, None).unwrap();
            let all: f64 = c.data().iter().map(|v| v * v).sum::<f64>().sqrt();
            assert!(
                odd_part_norm(&c) < 1e-10 * all,
                "{spec} at {t}: {}",
                odd_part_norm(&c) / all
            );
        }
        let mut rng = SplitMix64::new(11);
        let mut e = ShCoeffs::zeros(l, 3).unwrap();
        for v in e.data_mut() {
            *v = rng.uniform() - 0.5;
        }
        let env = Environment::new(e).unwrap();
        let plane = LobeTable::build_with(&b, l, 8, 1, LobeKind::InPlane, &|_, _| {}).unwrap();
        let shared = LobeTable::build_with(&b, l, 8, 1, LobeKind::Shared, &|_, _| {}).unwrap();
        assert_eq!(plane.basis().directions().len(), l + 1);
        assert_eq!(shared.basis().directions().len(), 2 * l + 1);
        assert_eq!(plane.entry_len() * 2 - (l + 1), shared.entry_len());
        let mp = Material::new(&b, l, Some(plane)).unwrap();
        let ms = Material::new(&b, l, Some(shared)).unwrap();
        let mut s = mp.scratch(3);
        let (mut worst, mut scale) = (0.0f64, 0.0f64);
        for _ in 0..40 {
            let f = Frame::new(rng.direction(), rng.direction());
            let wo = rng.direction();
            let (mut a, mut c) = ([0.0; 3], [0.0; 3]);
            mp.shade_isd(&env, &f, wo, &mut s, &mut a).unwrap();
            ms.shade_isd(&env, &f, wo, &mut s, &mut c).unwrap();
            for k in 0..3 {
                worst = worst.max((a[k] - c[k]).abs());
                scale = scale.max(c[k].abs());
            }
        }
        assert!(
            scale > 0.0 && worst <= 1e-5 * scale,
            "{spec}: {worst} vs {scale}"
        );
    }
    let aniso = Brdf::parse("ggx:ax=0.2,ay=0.5").unwrap();
    let e = LobeTable::build_with(&aniso, 4, 4, 8, LobeKind::InPlane, &|_, _| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("not even in y"), "{e}");
}

#[test]
fn table_reader_refuses_bad_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let b = Brdf::parse("ggx:alpha=0.5").unwrap();
    let t = LobeTable::build(&b, 3, 4, 1, &|_, _| {}).unwrap();
    let path = d.join("t.lobes");
    t.write(&path).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("empty", vec![], "IFDLOBES"),
        ("json", b"{\"brdf\": 1}".to_vec(), "IFDLOBES"),
        ("truncated", bytes[..bytes.len() - 7].to_vec(), "truncated"),
        ("header", bytes[..40].to_vec(), "header declares"),
        (
            "longer",
            [bytes.clone(), vec![0; 4]].concat(),
            "bytes of weights",
        ),
        (
            "version",
            {
                let mut v = bytes.clone();
                let at = v.windows(11).position(|w| w == b"\"version\":2").unwrap();
                v[at + 10] = b'7';
                v
            },
            "version 7",
        ),
        (
            "angles",
            {
                // one in-plane angle too many for the declared L = 3
                let hl = u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize;
                let mut head = std::str::from_utf8(&bytes[12..12 + hl])
                    .unwrap()
                    .to_string();
                let at = head.find("\"angles\":[").unwrap() + 10;
                head.insert_str(at, "0.5,");
                let mut v = b"IFDLOBES".to_vec();
                v.extend_from_slice(&(head.len() as u32).to_le_bytes());
                v.extend_from_slice(head.as_bytes());
                v.extend_from_slice(&bytes[12 + hl..]);
                v
            },
            "in-plane lobes",
        ),
    ];
    for (name, data, needle) in cases {
        let p = d.join(format!("{name}.lobes"));
        std::fs::write(&p, &data).unwrap();
        let e = LobeTable::read(&p).unwrap_err().to_string();
        assert!(
            e.contains(&format!("{name}.lobes")) && e.contains(needle),
            "{name}: {e}"
        );
    }
}

fn unit(v: [f64; 3]) -> [f64; 3] {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [v[0] / n, v[1] / n, v[2] / n]
}

/// Three-channel SH coefficients up to `l`, each uniform in `[-0.5, 0.5)`.
fn random_env(l: usize, rng: &mut ifd_sphere::SplitMix64) -> ifd_sphere::ShCoeffs {
    let mut e = ifd_sphere::ShCoeffs::zeros(l, 3).expect("coefficients");
    for v in e.data_mut() {
        *v = rng.uniform() - 0.5;
    }
    e
}

#[test]
fn isd_and_sh_shading_agree() {
    use ifd_shade::{Environment, Frame, Material};
    use ifd_sphere::SplitMix64;
    let l = 8;
    let mut rng = SplitMix64::new(3);
    let env = Environment::new(random_env(l, &mut rng)).unwrap();
    for (spec, table) in [
        ("lambert:albedo=0.8", false),
        ("phong:s=16", false),
        ("ggx:alpha=0.4", true),
        ("ggx:ax=0.2,ay=0.5", true),
    ] {
        let b = Brdf::parse(spec).unwrap();
        let t = table.then(|| LobeTable::build(&b, l, 6, 8, &|_, _| {}).unwrap());
        let m = Material::new(&b, l, t).unwrap();
        assert_eq!(m.is_closed_form(), !table);
        let mut s = m.scratch(3);
        let (mut worst, mut scale, mut lit) = (0.0f64, 0.0f64, 0);
        for _ in 0..30 {
            let n = rng.direction();
            let f = Frame::new(n, rng.direction());
            let wo = rng.direction();
            let (mut a, mut c) = ([0.0; 3], [0.0; 3]);
            m.shade_isd(&env, &f, wo, &mut s, &mut a).unwrap();
            m.shade_sh(&env, &f, wo, &mut c).unwrap();
            lit += usize::from(a.iter().any(|x| *x != 0.0));
            for k in 0..3 {
                worst = worst.max((a[k] - c[k]).abs());
                scale = scale.max(c[k].abs());
            }
        }
        assert!(lit >= 10, "{spec}: only {lit} lit views");
        assert!(worst <= 1e-9 * scale, "{spec}: {worst} vs {scale}");
    }
}

#[test]
fn white_furnace_through_shading() {
    use ifd_shade::{Environment, Frame, Material};
    use ifd_sphere::ShCoeffs;
    let l = 6;
    let mut e = ShCoeffs::zeros(l, 1).unwrap();
    e.set(0, 0, 0, (4.0 * PI).sqrt()); // E = 1
    let env = Environment::new(e).unwrap();
    let f = Frame::new(unit([0.3, -0.2, 0.9]), [1.0, 0.0, 0.0]);
    for (spec, tol) in [
        ("lambert", 1e-12),
        ("phong:s=64", 1e-12),
        ("ggx:alpha=0.3", 1e-3),
        ("blinn-exact:s=16", 1e-3),
    ] {
        let b = Brdf::parse(spec).unwrap();
        let t = (spec.starts_with("ggx") || spec.starts_with("blinn"))
            .then(|| LobeTable::build(&b, l, 16, 1, &|_, _| {}).unwrap());
        let m = Material::new(&b, l, t).unwrap();
        let mut s = m.scratch(1);
        for k in 0..8 {
            let t = 0.19 * k as f64;
            let wl = view(t, 0.7);
            let wo = [
                f.t[0] * wl[0] + f.b[0] * wl[1] + f.n[0] * wl[2],
                f.t[1] * wl[0] + f.b[1] * wl[1] + f.n[1] * wl[2],
                f.t[2] * wl[0] + f.b[2] * wl[1] + f.n[2] * wl[2],
            ];
            let mut out = [0.0];
            m.shade_isd(&env, &f, wo, &mut s, &mut out).unwrap();
            if tol < 1e-6 {
                assert!((out[0] - 1.0).abs() < tol, "{spec} at {t}: {}", out[0]);
            } else {
                // Blinn-Phong's albedo falls about as cos^2 theta_o (0.43 at
                // 0.95 rad, 0.16 at 1.33), GGX's far less
                let floor = if spec.starts_with("blinn") { 0.1 } else { 0.5 };
                assert!(
                    out[0] <= 1.0 + tol && out[0] > floor,
                    "{spec} at {t}: {}",
                    out[0]
                );
            }
        }
    }
}

#[test]
fn samplers_are_consistent_with_their_densities() {
    use ifd_sphere::SplitMix64;
    // E[k(wi) / pdf(wi)] over the sampler's draws is the slice's integral
    let dir = tempfile::tempdir().unwrap();
    let merl_path = dir.path().join("m.binary");
    Merl::tabulate(ggx_rgb).write(&merl_path).unwrap();
    let merl = format!("merl:{}", merl_path.display());
    for spec in [
        "lambert",
        "phong:s=20",
        "blinn:s=40",
        "ggx:alpha=0.3",
        "ggx:ax=0.15,ay=0.5",
        "ward:ax=0.2,ay=0.35",
        merl.as_str(),
        "gltf:roughness=0.5,metallic=0.3,base=0.8:0.5:0.2",
        "gltf:roughness=0.3,metallic=1",
        "gltf-lobes:roughness=0.6",
    ] {
        let b = Brdf::parse(spec).unwrap();
        let mut rng = SplitMix64::new(9);
        for t in [0.4, 1.1] {
            let wo = view(t, 0.8);
            let n = 200_000;
            let mut k = [0.0; 3];
            let mut sum = 0.0;
            for _ in 0..n {
                if let Some(wi) = b.sample(wo, [rng.uniform(), rng.uniform()]) {
                    let p = b.pdf(wi, wo);
                    assert!(p > 0.0, "{spec}: a drawn direction has density 0");
                    b.slice(wi, wo, &mut k);
                    sum += k[0] / p;
                }
            }
            let mc = sum / n as f64;
            let want = project_slice(&b, wo, 2, None).unwrap().get(0, 0, 0) * (4.0 * PI).sqrt();
            assert!(
                (mc - want).abs() < 0.01 * want,
                "{spec} at {t}: {mc} vs {want}"
            );
        }
    }
}

#[test]
fn gltf_white_furnace_metal_albedo_is_below_one_and_matches_brute_force() {
    // a metal with f0 = 1 (base 1): the BRDF is S, its albedo the GGX
    // albedo, at most 1, from the SH projection and from a brute-force sum
    for r in [0.2, 0.3, 0.5, 0.8, 1.0] {
        let b = Brdf::parse(&format!("gltf:roughness={r},metallic=1,base=1")).unwrap();
        for t in [0.0, 0.5, 1.0, 1.4] {
            let wo = view(t, 0.4);
            let c = project_slice(&b, wo, 4, None).unwrap();
            let albedo = c.get(0, 0, 0) * (4.0 * PI).sqrt();
            let brute = brute_albedo(&b, wo, 600);
            assert!(albedo <= 1.0 + 1e-9, "roughness {r} at {t}: {albedo}");
            assert!(
                (albedo - brute).abs() < 1e-3,
                "roughness {r} at {t}: {albedo} vs brute force {brute}"
            );
            // every channel alike (white)
            assert!((c.get(0, 0, 2) - c.get(0, 0, 0)).abs() < 1e-15);
        }
    }
}

#[test]
fn gltf_parts_isd_matches_sh_and_combines_to_the_whole_brdf() {
    use ifd_shade::{Environment, Frame, GltfMaterial, Material};
    use ifd_sphere::ShCoeffs;
    use ifd_sphere::SplitMix64;
    let l = 10;
    let mut rng = SplitMix64::new(5);
    let mut e = ShCoeffs::zeros(l, 3).unwrap();
    for v in e.data_mut() {
        *v = rng.uniform() - 0.5;
    }
    e.set(0, 0, 0, 3.0);
    let env = Environment::new(e.clone()).unwrap();
    let parts = Brdf::gltf_lobes(0.6).unwrap();
    let t = LobeTable::build(&parts, l, 48, 1, &|_, _| {}).unwrap();
    let m = Material::new(&parts, l, Some(t)).unwrap();
    let mut s = m.scratch(3);
    let gm = GltfMaterial::new([0.9, 0.5, 0.2], 0.4, 0.6).unwrap();
    let whole = Brdf::gltf(&gm);
    let direct = Material::new(
        &whole,
        l,
        Some(LobeTable::build(&whole, l, 48, 1, &|_, _| {}).unwrap()),
    )
    .unwrap();
    let (mut worst, mut scale) = (0.0f64, 0.0f64);
    let (mut worst_whole, mut scale_whole) = (0.0f64, 0.0f64);
    for _ in 0..30 {
        let f = Frame::new(rng.direction(), rng.direction());
        let wo = rng.direction();
        let (mut a, mut c) = ([0.0; 9], [0.0; 9]);
        m.shade_isd_parts(&env, &f, wo, &mut s, &mut a).unwrap();
        m.shade_sh_parts(&env, &f, wo, &mut c).unwrap();
        for k in 0..9 {
            worst = worst.max((a[k] - c[k]).abs());
            scale = scale.max(c[k].abs());
        }
        // the combination against the whole BRDF's own SH projection, rotated
        let mut rgb = [0.0; 3];
        gm.combine(&a, 3, &mut rgb);
        let wl = f.to_local(wo);
        if wl[2] <= 0.05 {
            continue;
        }
        let mut want = [0.0; 3];
        direct.shade_sh(&env, &f, wo, &mut want).unwrap();
        for k in 0..3 {
            worst_whole = worst_whole.max((rgb[k] - want[k]).abs());
            scale_whole = scale_whole.max(want[k].abs());
        }
    }
    assert!(worst <= 1e-9 * scale, "parts: {worst} vs {scale}");
    // both sides interpolate tables over theta_o (48 entries): the slices
    // are linear in the colour, so the difference is rounding plus the
    // two tables' interpolation of the same slices
    assert!(
        worst_whole <= 1e-6 * scale_whole,
        "whole BRDF: {worst_whole} vs {scale_whole}"
    );
}

/// The `f32` lanes of [`ifd_shade::Precision::F32`] against the `f64`
/// reference: every layout (in-plane lobes in one chunk of eight and in
/// chunks of sixteen with a remainder, shared lobes), channel counts 1, 2 and
/// 3, the glTF parts (every BRDF channel against every environment channel)
/// and an RGB MERL BRDF (channel against channel), up to `L = 60`: within
/// 1e-5 of the largest reference value.
#[test]
fn f32_lanes_agree_with_the_f64_reference() {
    use ifd_shade::{Environment, Frame, Material, Precision};
    use ifd_sphere::ShCoeffs;
    use ifd_sphere::SplitMix64;
    let dir = tempfile::tempdir().unwrap();
    let merl_path = dir.path().join("ggx.binary");
    Merl::tabulate(ggx_rgb).write(&merl_path).unwrap();
    let merl_spec = format!("merl:{}", merl_path.display());
    // (BRDF, L, phi entries, environment channels, every part)
    let cases: [(&str, usize, usize, usize, bool); 8] = [
        ("ggx:alpha=0.3", 7, 1, 3, false),
        ("ggx:alpha=0.3", 16, 1, 1, false),
        ("ggx:alpha=0.3", 30, 1, 3, false),
        ("ggx:alpha=0.1", 60, 1, 3, false),
        ("ggx:ax=0.2,ay=0.5", 8, 8, 2, false),
        ("gltf-lobes:roughness=0.5", 10, 1, 3, true),
        (&merl_spec, 6, 1, 3, false),
        ("blinn:s=20", 12, 1, 3, false),
    ];
    let mut rng = SplitMix64::new(23);
    for (spec, l, n_phi, ch, parts) in cases {
        let b = Brdf::parse(spec).unwrap();
        let table = LobeTable::build(&b, l, 8, n_phi, &|_, _| {}).unwrap();
        let m = Material::new(&b, l, Some(table)).unwrap();
        // a map-like spectrum: a large mean, bands falling as 1 / (l + 1)
        let mut e = ShCoeffs::zeros(l, ch).unwrap();
        for band in 0..=l {
            for i in band * band..(band + 1) * (band + 1) {
                for c in 0..ch {
                    e.data_mut()[i * ch + c] = (rng.uniform() - 0.5) / (band + 1) as f64;
                }
            }
        }
        for c in 0..ch {
            e.set(0, 0, c, 3.0);
        }
        let reference = Environment::new(e.clone()).unwrap();
        assert_eq!(reference.precision(), Precision::F64);
        let fast = Environment::new(e).unwrap().with_precision(Precision::F32);
        let n = if parts { 3 * ch } else { ch };
        let mut s = m.scratch(ch);
        let (mut worst, mut scale, mut lit) = (0.0f64, 0.0f64, 0);
        for _ in 0..40 {
            let f = Frame::new(rng.direction(), rng.direction());
            let wo = rng.direction();
            let (mut a, mut c) = ([0.0; 9], [0.0; 9]);
            if parts {
                m.shade_isd_parts(&reference, &f, wo, &mut s, &mut a)
                    .unwrap();
                m.shade_isd_parts(&fast, &f, wo, &mut s, &mut c).unwrap();
            } else {
                m.shade_isd(&reference, &f, wo, &mut s, &mut a).unwrap();
                m.shade_isd(&fast, &f, wo, &mut s, &mut c).unwrap();
            }
            lit += usize::from(a[..n].iter().any(|x| *x != 0.0));
            for k in 0..n {
                worst = worst.max((a[k] - c[k]).abs());
                scale = scale.max(a[k].abs());
            }
        }
        assert!(lit >= 10, "{spec}: only {lit} lit views");
        assert!(
            worst <= 1e-5 * scale && worst > 0.0,
            "{spec} at L = {l}: {worst} vs {scale}"
        );
    }
}

/// [`ifd_shade::Material::shade_isd_batch`] (the renderer's plain path)
/// against [`ifd_shade::Material::shade_sh`] (the slice's SH projection,
/// which blends the table's entries apart from the lobes) point by point:
/// isotropic and anisotropic tables (two and four blended entries), a
/// closed form, `f64` and `f32` lanes, a batch of points that is no multiple
/// of the lanes with views below the horizon among them (unlit but for
/// Phong): within 1e-9 (`f64`) and 1e-5 (`f32`) of the largest value; and
/// equal bit for bit to [`ifd_shade::Material::shade_isd`] point by point.
#[test]
fn batched_shading_matches_sh_point_by_point() {
    use ifd_shade::{Environment, Frame, Material, Precision};
    use ifd_sphere::SplitMix64;
    let l = 7;
    let mut rng = SplitMix64::new(41);
    let mut e = random_env(l, &mut rng);
    for c in 0..3 {
        e.set(0, 0, c, 3.0);
    }
    for (spec, n_phi) in [
        ("ggx:alpha=0.3", 1),
        ("ggx:ax=0.2,ay=0.5", 8),
        ("phong:s=16", 0),
    ] {
        let b = Brdf::parse(spec).unwrap();
        let t = (n_phi > 0).then(|| LobeTable::build(&b, l, 8, n_phi, &|_, _| {}).unwrap());
        let m = Material::new(&b, l, t).unwrap();
        let reference = Environment::new(e.clone()).unwrap();
        for (precision, tol) in [(Precision::F64, 1e-9), (Precision::F32, 1e-5)] {
            let env = Environment::new(e.clone())
                .unwrap()
                .with_precision(precision);
            let points: Vec<(Frame, [f64; 3])> = (0..37)
                .map(|_| {
                    (
                        Frame::new(rng.direction(), rng.direction()),
                        rng.direction(),
                    )
                })
                .collect();
            let mut s = m.scratch(3);
            let mut batch = vec![0.0; 3 * points.len()];
            m.shade_isd_batch(&env, &points, &mut s, &mut batch)
                .unwrap();
            let (mut worst, mut scale, mut lit) = (0.0f64, 0.0f64, 0);
            for (i, (f, wo)) in points.iter().enumerate() {
                // the batch (its lanes take the lobes lobe-major, across
                // points) is the point-by-point path bit for bit
                let mut alone = [0.0; 3];
                m.shade_isd(&env, f, *wo, &mut s, &mut alone).unwrap();
                assert_eq!(
                    alone,
                    batch[3 * i..3 * i + 3],
                    "{spec} {precision:?} point {i}"
                );
                let mut one = [0.0; 3];
                m.shade_sh(&reference, f, *wo, &mut one).unwrap();
                lit += usize::from(one.iter().any(|x| *x != 0.0));
                for c in 0..3 {
                    worst = worst.max((one[c] - batch[3 * i + c]).abs());
                    scale = scale.max(one[c].abs());
                }
            }
            // Phong's slice is defined below the horizon too
            let some_unlit = n_phi == 0 || lit < points.len();
            assert!(lit >= 10 && some_unlit, "{spec}: {lit} lit views");
            assert!(
                worst <= tol * scale,
                "{spec} {precision:?}: {worst} vs {scale}"
            );
        }
    }
}
