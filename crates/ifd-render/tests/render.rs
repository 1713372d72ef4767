//! ISD shading against the exact texel quadrature on the bundled forest map
//! (the accuracy goals, at a small size for CI: a 40x40 view of the
//! unit sphere, the map averaged down to 32x16).

use glam::DVec3;
use ifd_image::Image;
use ifd_render::Camera;
use ifd_render::EnvMap;
use ifd_render::Scene;
use ifd_render::{Job, Method, Rendered, relative_rms, render};
use ifd_shade::Brdf;
use ifd_shade::Material;
use ifd_shade::{LobeTable, default_theta_entries};

fn forest() -> EnvMap {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../testdata/forest.hdr");
    let img = ifd_image::read(path).expect("bundled map");
    EnvMap::new(img, 30.0)
        .expect("a 2:1 map")
        .downsampled(32, 16)
        .expect("a divisor")
}

fn camera(size: usize) -> Camera {
    Camera::new(
        DVec3::new(3.0, -2.5, 1.2),
        DVec3::ZERO,
        DVec3::Z,
        40.0,
        size,
        size,
    )
    .expect("camera")
}

fn shoot(env: &EnvMap, brdf: &Brdf, material: Option<&Material>, method: Method) -> Rendered {
    let job = Job {
        spp: 64,
        seed: 1,
        ..Job::new(Scene::Sphere, camera(40), env, brdf, material, method)
    };
    render(&job, &|_, _| {}).expect("render")
}

fn material(brdf: &Brdf, l: usize) -> Material {
    let table = Material::new(brdf, l, None).is_err().then(|| {
        LobeTable::build(brdf, l, default_theta_entries(brdf), 1, &|_, _| {}).expect("table")
    });
    Material::new(brdf, l, table).expect("material")
}

/// RMS error over object pixels relative to the mean of the reference.
fn rms_of_mean(a: &Image, b: &Image, mask: &[bool]) -> f64 {
    let ch = a.channels();
    let (mut se, mut sum, mut n) = (0.0, 0.0, 0.0);
    for (i, m) in mask.iter().enumerate() {
        if *m {
            for c in 0..ch {
                let (x, y) = (
                    f64::from(a.data()[i * ch + c]),
                    f64::from(b.data()[i * ch + c]),
                );
                se += (x - y) * (x - y);
                sum += y;
                n += 1.0;
            }
        }
    }
    (se / n).sqrt() / (sum / n)
}

#[test]
fn isd_converges_to_the_quadrature_oracle() {
    let env = forest();
    // (spec, L, goal on the relative RMS error)
    let cases: [(&str, usize, f64); 4] = [
        ("phong:s=8", 9, 0.01),
        ("phong:s=32", 18, 0.01),
        ("ggx:alpha=0.3", 24, 0.01),
        ("lambert", 6, 0.01),
    ];
    for (spec, l, goal) in cases {
        let brdf = Brdf::parse(spec).unwrap();
        let oracle = shoot(&env, &brdf, None, Method::Quadrature);
        // texels across the horizon converge slowly: their remaining changes
        // must stay far below the goals
        assert!(
            oracle.max_residual < 1e-4,
            "{spec}: oracle residual {}",
            oracle.max_residual
        );
        let m = material(&brdf, l);
        let isd = shoot(&env, &brdf, Some(&m), Method::Isd);
        assert_eq!(isd.mask, oracle.mask);
        assert!(isd.object_pixels > 500, "{}", isd.object_pixels);
        let err = relative_rms(&isd.image, &oracle.image, &oracle.mask);
        eprintln!(
            "{spec} at L = {l}: relative RMS {err:.5} (oracle k <= {}, {} pixels unconverged, residual {:.1e})",
            oracle.max_k, oracle.not_converged, oracle.max_residual
        );
        assert!(err <= goal, "{spec} at L = {l}: relative RMS {err}");
        // a lower degree is measurably worse: the test can fail
        let coarse = shoot(&env, &brdf, Some(&material(&brdf, l / 3)), Method::Isd);
        let err_coarse = relative_rms(&coarse.image, &oracle.image, &oracle.mask);
        assert!(
            err_coarse > 2.0 * err,
            "{spec}: L = {} gives {err_coarse}",
            l / 3
        );
    }
    // Lambert at L = 2: the Ramamoorthi-Hanrahan bound (< 3% of the mean)
    let brdf = Brdf::parse("lambert").unwrap();
    let oracle = shoot(&env, &brdf, None, Method::Quadrature);
    let isd = shoot(&env, &brdf, Some(&material(&brdf, 2)), Method::Isd);
    let e = rms_of_mean(&isd.image, &oracle.image, &oracle.mask);
    eprintln!("lambert at L = 2: RMS error {e:.5} of the mean");
    assert!(e <= 0.03, "{e}");
}

#[test]
fn isd_and_sh_images_agree() {
    let env = forest();
    for spec in ["ggx:ax=0.2,ay=0.5", "phong:s=16"] {
        let brdf = Brdf::parse(spec).unwrap();
        let l = 6;
        let table =
            (!brdf.is_isotropic()).then(|| LobeTable::build(&brdf, l, 8, 16, &|_, _| {}).unwrap());
        let m = Material::new(&brdf, l, table).unwrap();
        let a = shoot(&env, &brdf, Some(&m), Method::Isd);
        let b = shoot(&env, &brdf, Some(&m), Method::Sh);
        let max = b.image.data().iter().fold(0.0f32, |m, v| m.max(v.abs()));
        let diff = a
            .image
            .data()
            .iter()
            .zip(b.image.data())
            .fold(0.0f32, |m, (x, y)| m.max((x - y).abs()));
        // f32 images: the f64 agreement (1e-9, ifd-shade's tests) rounded
        assert!(diff <= 2e-6 * max, "{spec}: {diff} vs max {max}");
        // the prefiltered-maps variant: bicubic lookups within 1e-3
        let c = shoot(&env, &brdf, Some(&m), Method::IsdMaps);
        let err = relative_rms(&c.image, &a.image, &a.mask);
        let worst = c
            .image
            .data()
            .iter()
            .zip(a.image.data())
            .fold(0.0f32, |m, (x, y)| m.max((x - y).abs()));
        eprintln!(
            "{spec}: isd-maps vs isd relative RMS {err:.2e}, max {:.2e} of the max",
            worst / max
        );
        assert!(err <= 1e-3 && worst <= 1e-3 * max, "{spec}: {err}, {worst}");
    }
}

#[test]
fn white_furnace_and_bad_cameras() {
    let one = EnvMap::new(Image::from_vec(16, 8, 3, vec![1.0; 384]).unwrap(), 0.0).unwrap();
    let brdf = Brdf::parse("lambert").unwrap();
    let m = Material::new(&brdf, 4, None).unwrap();
    let r = shoot(&one, &brdf, Some(&m), Method::Isd);
    for (i, on) in r.mask.iter().enumerate() {
        if *on {
            for c in 0..3 {
                let v = r.image.data()[i * 3 + c];
                assert!((v - 1.0).abs() < 1e-4, "pixel {i}: {v}");
            }
        }
    }
    let away = Camera::new(
        DVec3::new(0.0, -4.0, 0.0),
        DVec3::new(0.0, -8.0, 0.0),
        DVec3::Z,
        40.0,
        8,
        8,
    )
    .unwrap();
    let job = Job {
        background: Some(&one),
        ..Job::new(Scene::Sphere, away, &one, &brdf, Some(&m), Method::Isd)
    };
    let e = render(&job, &|_, _| {}).unwrap_err().to_string();
    assert!(
        e.contains("sees no object") && e.contains("hits the sphere"),
        "{e}"
    );
    // a mesh is named by its size, not printed vertex by vertex
    let obj = std::env::temp_dir().join(format!("ifd-away-{}.obj", std::process::id()));
    std::fs::write(&obj, uv_sphere_obj(1.0, 16, false, false)).unwrap();
    let mesh = Scene::parse(obj.to_str().unwrap(), false).unwrap();
    std::fs::remove_file(&obj).unwrap();
    let job = Job {
        background: Some(&one),
        ..Job::new(mesh, away, &one, &brdf, Some(&m), Method::Isd)
    };
    let e = render(&job, &|_, _| {}).unwrap_err().to_string();
    assert!(e.contains("hits the mesh of") && e.len() < 300, "{e}");
    let e = Camera::new(DVec3::ZERO, DVec3::Z, DVec3::Z, 40.0, 8, 8)
        .unwrap_err()
        .to_string();
    assert!(e.contains("--up"), "{e}");
    let e = Camera::new(DVec3::ZERO, DVec3::X, DVec3::Z, 190.0, 8, 8)
        .unwrap_err()
        .to_string();
    assert!(e.contains("--fov"), "{e}");
    let e = Camera::new(DVec3::new(1e300, 0.0, 0.0), DVec3::X, DVec3::Z, 40.0, 8, 8)
        .unwrap_err()
        .to_string();
    assert!(e.contains("--eye") && e.contains("too large"), "{e}");
}

#[test]
fn monte_carlo_converges_to_the_oracle() {
    let env = forest();
    for spec in [
        "ggx:alpha=0.3",
        "phong:s=32",
        "ward:ax=0.2,ay=0.4",
        "lambert",
    ] {
        let brdf = Brdf::parse(spec).unwrap();
        let oracle = shoot(&env, &brdf, None, Method::Quadrature);
        let mc = |spp: usize| {
            let job = Job {
                spp,
                seed: 7,
                ..Job::new(Scene::Sphere, camera(40), &env, &brdf, None, Method::Mc)
            };
            render(&job, &|_, _| {}).unwrap()
        };
        let (a, b) = (mc(16), mc(256));
        let (ea, eb) = (
            relative_rms(&a.image, &oracle.image, &oracle.mask),
            relative_rms(&b.image, &oracle.image, &oracle.mask),
        );
        eprintln!("{spec}: Monte Carlo relative RMS {ea:.4} at 16 spp, {eb:.4} at 256");
        assert!(eb <= 0.35 * ea, "{spec}: {eb} vs {ea}");
        // the reported standard error (an iid estimate: the low-discrepancy
        // points do better) bounds the actual error and is of its order
        let se = b.stderr.as_ref().unwrap();
        let (mut s2, mut r2) = (0.0f64, 0.0f64);
        for (i, m) in b.mask.iter().enumerate() {
            if *m {
                for c in 0..3 {
                    s2 += f64::from(se.data()[i * 3 + c]).powi(2);
                    r2 += f64::from(oracle.image.data()[i * 3 + c]).powi(2);
                }
            }
        }
        let rel_se = (s2 / r2).sqrt();
        eprintln!("{spec}: reported standard error {rel_se:.4} (relative RMS)");
        assert!(se.data().iter().all(|v| v.is_finite() && *v >= 0.0));
        assert!(
            rel_se >= eb && rel_se <= 20.0 * eb,
            "{spec}: {rel_se} vs {eb}"
        );
    }
}

/// A UV sphere of radius `r` as OBJ text (y-up, as OBJ files are), with exact
/// normals and texture coordinates when asked.
fn uv_sphere_obj(r: f64, seg: usize, with_n: bool, with_uv: bool) -> String {
    use std::fmt::Write as _;
    let mut s = String::from("# uv sphere\n");
    let rings = seg / 2;
    for i in 0..=rings {
        let t = std::f64::consts::PI * i as f64 / rings as f64;
        for j in 0..=seg {
            let p = 2.0 * std::f64::consts::PI * j as f64 / seg as f64;
            // z-up direction, written y-up: (x, y, z) -> (x, z, -y)
            let (x, y, z) = (t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
            let _ = writeln!(s, "v {} {} {}", r * x, r * z, -r * y);
            if with_n {
                let _ = writeln!(s, "vn {x} {z} {}", -y);
            }
            if with_uv {
                let _ = writeln!(
                    s,
                    "vt {} {}",
                    j as f64 / seg as f64,
                    1.0 - i as f64 / rings as f64
                );
            }
        }
    }
    let idx = |i: usize, j: usize| i * (seg + 1) + j + 1;
    for i in 0..rings {
        for j in 0..seg {
            let (a, b, c, d) = (idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1));
            let f = |k: usize| match (with_n, with_uv) {
                (true, true) => format!("{k}/{k}/{k}"),
                (true, false) => format!("{k}//{k}"),
                (false, true) => format!("{k}/{k}"),
                (false, false) => format!("{k}"),
            };
            let _ = writeln!(s, "f {} {} {} {}", f(a), f(b), f(c), f(d));
        }
    }
    s
}

#[test]
fn obj_meshes_render_like_the_analytic_surface() {
    use ifd_render::Scene;
    let dir = tempfile::tempdir().unwrap();
    let env = forest();
    let brdf = Brdf::parse("phong:s=16").unwrap();
    let m = Material::new(&brdf, 10, None).unwrap();
    let render_scene = |scene: Scene| {
        let job = Job {
            ..Job::new(scene, camera(48), &env, &brdf, Some(&m), Method::Isd)
        };
        render(&job, &|_, _| {}).unwrap()
    };
    let analytic = render_scene(Scene::Sphere);
    for (with_n, with_uv) in [(true, true), (false, false)] {
        // radius 3: the loader rescales to the unit bounding sphere
        let path = dir.path().join(format!("s{with_n}{with_uv}.obj"));
        std::fs::write(&path, uv_sphere_obj(3.0, 96, with_n, with_uv)).unwrap();
        let scene = Scene::parse(path.to_str().unwrap(), false).unwrap();
        assert_eq!(scene.has_tangents(), with_uv);
        let mesh = render_scene(scene);
        let both: Vec<bool> = mesh
            .mask
            .iter()
            .zip(&analytic.mask)
            .map(|(a, b)| *a && *b)
            .collect();
        let differ = mesh
            .mask
            .iter()
            .zip(&analytic.mask)
            .filter(|(a, b)| a != b)
            .count();
        assert!(differ < 60, "{differ} silhouette pixels differ");
        let err = relative_rms(&mesh.image, &analytic.image, &both);
        eprintln!("mesh (normals {with_n}, uv {with_uv}) vs analytic sphere: {err:.4}");
        assert!(err < 0.01, "{err}");
    }
    // axes: a ground square of a y-up file (y = 0) lies in ifd's z = 0 plane
    let p = dir.path().join("ground.obj");
    std::fs::write(&p, "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nf 1 2 3 4\n").unwrap();
    let ground = Scene::parse(p.to_str().unwrap(), false).unwrap();
    let hit = ground
        .intersect(DVec3::new(0.1, 0.2, 5.0), DVec3::new(0.0, 0.0, -1.0))
        .unwrap();
    assert!(
        hit.p.z.abs() < 1e-12 && (hit.n - DVec3::Z).length() < 1e-12,
        "{hit:?}"
    );
    // declared z-up, the same file is a wall (x-z plane): the ray misses it
    let wall = Scene::parse(p.to_str().unwrap(), true).unwrap();
    assert!(
        wall.intersect(DVec3::new(0.1, 0.2, 5.0), DVec3::new(0.0, 0.0, -1.0))
            .is_none()
    );
    // bad files
    for (name, text, needle) in [
        ("empty.obj", "# nothing\nv 0 0 0\n", "no triangles"),
        (
            "bad.obj",
            "f 1 2 3\n",
            "position index 1 refers to none of the 0",
        ),
        // found by fuzzing: a relative texture index with no texture
        // coordinates overflowed tobj's index arithmetic (a panic)
        (
            "relative.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/-1 2/-1 3/-1\n",
            "texture coordinate index -1 refers to none of the 0",
        ),
        ("garbage.obj", "v 0 0 0\nf 1/x 1 1\n", "is not an integer"),
    ] {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        let e = Scene::parse(p.to_str().unwrap(), false)
            .unwrap_err()
            .to_string();
        assert!(e.contains(name) && e.contains(needle), "{e}");
    }
}

#[test]
fn roughness_ranges_below_the_smallest_table_build_one() {
    use ifd_render::RoughnessFamily;
    // An all-zero roughness map (common in glTF assets) gives the range
    // (0, 0), wholly below the smallest roughness a table is built for: the
    // family brackets that smallest one (its bounds once crossed).
    let brdf = Brdf::parse("ggx:alpha=0.3").unwrap();
    for range in [(0.0, 0.0), (0.0, 0.01), (0.02, 0.02)] {
        let family = RoughnessFamily::build(&brdf, 4, range, 3, &|_, _| {}).unwrap();
        let r = family.roughness();
        assert!(r.windows(2).all(|w| w[0] < w[1]), "{range:?}: {r:?}");
        let (_, _, w) = family.locate(0.0);
        assert_eq!(w, 0.0, "{range:?}");
    }
}

#[test]
fn textured_sphere_matches_the_oracle() {
    use ifd_render::{RoughnessFamily, SurfaceMaps, Texture};
    let env = forest();
    // roughness 0.55..0.8 across u (alpha 0.30..0.64), albedo stripes across v
    let (tw, th) = (32, 16);
    let rough: Vec<f32> = (0..tw * th)
        .map(|i| 0.55 + 0.25 * ((i % tw) as f32 / (tw - 1) as f32))
        .collect();
    let albedo: Vec<f32> = (0..tw * th)
        .flat_map(|i| {
            let v = (i / tw) as f32 / (th - 1) as f32;
            [0.9 - 0.5 * v, 0.5, 0.2 + 0.6 * v]
        })
        .collect();
    let maps = SurfaceMaps {
        albedo: Some(Texture::new(Image::from_vec(tw, th, 3, albedo).unwrap(), "albedo").unwrap()),
        roughness: Some(
            Texture::new(Image::from_vec(tw, th, 1, rough).unwrap(), "roughness").unwrap(),
        ),
        normal: None,
    };
    let brdf = Brdf::parse("ggx:alpha=0.5").unwrap();
    let range = maps.roughness.as_ref().unwrap().range();
    let family = RoughnessFamily::build(&brdf, 20, range, 6, &|_, _| {}).unwrap();
    let job = |method, family| Job {
        maps: Some(&maps),
        family,
        ..Job::new(Scene::Sphere, camera(40), &env, &brdf, None, method)
    };
    let oracle = render(&job(Method::Quadrature, None), &|_, _| {}).unwrap();
    let isd = render(&job(Method::Isd, Some(&family)), &|_, _| {}).unwrap();
    let err = relative_rms(&isd.image, &oracle.image, &oracle.mask);
    eprintln!("textured GGX (alpha 0.30-0.64, 6 tables, L = 20): relative RMS {err:.4}");
    assert!(err < 0.01, "{err}");
    // the maps matter: a constant material is far off
    let plain = Material::new(
        &brdf,
        20,
        Some(LobeTable::build(&brdf, 20, 16, 1, &|_, _| {}).unwrap()),
    )
    .unwrap();
    let mut j = job(Method::Isd, None);
    j.maps = None;
    j.material = Some(&plain);
    let flat = render(&j, &|_, _| {}).unwrap();
    assert!(relative_rms(&flat.image, &oracle.image, &oracle.mask) > 10.0 * err);
}

#[test]
fn images_do_not_depend_on_the_thread_count() {
    let env = forest();
    let brdf = Brdf::parse("ggx:alpha=0.4").unwrap();
    let m = material(&brdf, 8);
    let run = |threads: usize, method: Method| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let material = (method == Method::Isd).then_some(&m);
            let job = Job {
                background: Some(&env),
                spp: 32,
                seed: 3,
                ..Job::new(Scene::Sphere, camera(24), &env, &brdf, material, method)
            };
            render(&job, &|_, _| {}).unwrap().image
        })
    };
    for method in [Method::Isd, Method::Mc, Method::Quadrature] {
        let (a, b) = (run(1, method), run(3, method));
        assert!(
            a.data() == b.data(),
            "{method:?} differs between 1 and 3 threads"
        );
    }
}

/// Spherical lights (ISD Sec. 7.3, Eq. 33-34): two local lights, one grey
/// and one coloured, plus the environment; ISD (zonal lighting per point) and
/// the SH reference against the quadrature of the caps (plus the texel
/// oracle): relative RMS error at most 1% for Lambert, Phong and a GGX lobe
/// table. The lights alone carry most of the energy, so the check is on
/// them.
#[test]
fn spherical_lights_match_the_quadrature() {
    use ifd_shade::SphericalLight;
    let env = forest();
    let lights = [
        SphericalLight::parse("2,-1.5,2,0.4,30").unwrap(),
        SphericalLight::parse("-1,-2.5,0.3,0.3,0,5,40").unwrap(),
    ];
    let go =
        |brdf: &Brdf, material: Option<&Material>, method: Method, lights: &[SphericalLight]| {
            let job = Job {
                spp: 1,
                seed: 1,
                lights,
                ..Job::new(Scene::Sphere, camera(32), &env, brdf, material, method)
            };
            render(&job, &|_, _| {}).expect("render")
        };
    for (spec, l) in [("lambert", 10), ("phong:s=20", 20), ("ggx:alpha=0.35", 16)] {
        let brdf = Brdf::parse(spec).unwrap();
        let m = material(&brdf, l);
        let reference = go(&brdf, None, Method::Quadrature, &lights);
        let without = go(&brdf, None, Method::Quadrature, &[]);
        // the caps' quadrature converges to 1e-6 of the pixel but where a
        // cap straddles the horizon (a kink: a few pixels reach 1e-5)
        let unconverged = reference.not_converged - without.not_converged;
        assert!(
            unconverged * 50 <= reference.object_pixels,
            "{spec}: {unconverged}"
        );
        let share = relative_rms(&without.image, &reference.image, &reference.mask);
        assert!(share > 0.3, "{spec}: the lights carry {share} of the image");
        for method in [Method::Isd, Method::Sh] {
            let r = go(&brdf, Some(&m), method, &lights);
            let e = relative_rms(&r.image, &reference.image, &reference.mask);
            eprintln!("{spec} L={l} {method:?}: relative RMS {e:.2e}");
            assert!(e <= 0.01, "{spec} {method:?}: {e}");
        }
    }
    // a light the camera sees is drawn; Monte Carlo refuses lights
    let brdf = Brdf::parse("lambert").unwrap();
    let m = material(&brdf, 4);
    let seen = [SphericalLight::parse("1.5,-1.25,0.6,0.2,7").unwrap()];
    let r = go(&brdf, Some(&m), Method::Isd, &seen);
    assert!(r.image.data().contains(&7.0));
    let job = Job {
        spp: 1,
        seed: 1,
        lights: &seen,
        ..Job::new(Scene::Sphere, camera(8), &env, &brdf, None, Method::Mc)
    };
    assert!(render(&job, &|_, _| {}).is_err());
}

/// ISD's anti-aliasing filter (Eq. 29) is the map convolved with a von
/// Mises-Fisher lobe: against the brute-force convolution of the
/// piecewise-constant map (every texel, at its centre, times its solid angle).
#[test]
fn mirror_filter_is_the_vmf_convolution() {
    use ifd_render::{IsdFilter, PixelFilter};
    let env = forest();
    let f = IsdFilter::new(&env, 40).unwrap();
    let img = env.image();
    let (w, h) = (img.width(), img.height());
    let mut y = vec![0.0; 41 * 41];
    let mut bands = vec![0.0; 41 * 3];
    for (d, sigma) in [([0.0, 0.6, 0.8], 0.3), ([0.48, -0.6, -0.64], 0.5)] {
        let kappa = 1.0 / (sigma * sigma);
        let mut brute = [0.0; 3];
        let mut norm = 0.0;
        // each texel (constant) against the kernel sampled on 8x8 sub-cells
        let sub = 8;
        for v in 0..h * sub {
            let t0 = std::f64::consts::PI * v as f64 / (h * sub) as f64;
            let t1 = std::f64::consts::PI * (v + 1) as f64 / (h * sub) as f64;
            let area = (t0.cos() - t1.cos()) * std::f64::consts::TAU / (w * sub) as f64;
            let th = 0.5 * (t0 + t1);
            for u in 0..w * sub {
                // rotated like the map (30 degrees)
                let ph = std::f64::consts::TAU * (u as f64 + 0.5) / (w * sub) as f64
                    + 30f64.to_radians();
                let wv = [th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()];
                let k = (kappa * (wv[0] * d[0] + wv[1] * d[1] + wv[2] * d[2] - 1.0)).exp() * area;
                norm += k;
                for (c, b) in brute.iter_mut().enumerate() {
                    *b += k * f64::from(img.get(u / sub, v / sub, c));
                }
            }
        }
        let mut out = [0.0; 3];
        f.filter(DVec3::from_array(d), sigma, &mut y, &mut bands, &mut out);
        for c in 0..3 {
            let b = brute[c] / norm;
            // sub-cell centres against exact texel integrals
            assert!(
                (out[c] - b).abs() < 1e-3 * b,
                "sigma {sigma} c {c}: {} vs {b}",
                out[c]
            );
        }
    }
    let v = PixelFilter::default().variance();
    assert!((v - 0.193_44).abs() < 1e-4, "{v}");
}

/// Shading with visibility (ISD Eq. 25, Appendix A): step 1 (the slice's
/// world SH from the rotated lobes) dotted with the environment is Eq. 22;
/// the product matrix with `v = 1` is the unshadowed ISD. (Its convergence to
/// the ray-traced reference on a torus is `ifd-paper`'s visibility test.)
#[test]
fn visibility_three_steps_converge_to_the_ray_traced_reference() {
    use ifd_render::ProductMatrix;
    use ifd_shade::{Environment, Frame};
    let env = forest();
    let e = Environment::new(env.sh(10).unwrap()).unwrap();
    let product = ProductMatrix::new(&env, 10).unwrap();
    let frame = Frame::new([0.36, -0.48, 0.8], [1.0, 0.0, 0.0]);
    let wo = [0.0, -0.6, 0.8];
    let mut one = vec![0.0; 121];
    one[0] = (4.0 * std::f64::consts::PI).sqrt();
    for spec in ["phong:s=12", "ggx:alpha=0.4", "ggx:ax=0.2,ay=0.5"] {
        let brdf = Brdf::parse(spec).unwrap();
        let m = if brdf.is_isotropic() {
            material(&brdf, 10)
        } else {
            let t = LobeTable::build(&brdf, 10, 12, 12, &|_, _| {}).unwrap();
            Material::new(&brdf, 10, Some(t)).unwrap()
        };
        let mut s = m.scratch(3);
        let (mut a, mut b) = ([0.0; 3], [0.0; 3]);
        m.shade_isd(&e, &frame, wo, &mut s, &mut a).unwrap();
        let rho = m.world_sh(&frame, wo, &mut s).unwrap().unwrap();
        let kc = rho.channels();
        for (c, ac) in a.iter().enumerate() {
            let dot: f64 = (0..121)
                .map(|i| {
                    rho.data()[i * kc + if kc == 1 { 0 } else { c }] * e.coeffs().data()[i * 3 + c]
                })
                .sum();
            assert!(
                (dot - ac).abs() < 1e-9 * ac.abs().max(1e-3),
                "{spec}: {dot} vs {ac}"
            );
        }
        product.apply(rho.data(), kc, &one, 10, &mut b);
        for c in 0..3 {
            // T from 2x2 nodes per texel, E's SH from exact texel integrals
            assert!(
                (a[c] - b[c]).abs() < 2e-3 * a[c],
                "{spec}: {} vs {}",
                a[c],
                b[c]
            );
        }
    }
}

/// `Job::shadows` (`ifd render --shadows`): the traced reference only removes
/// light (each pixel at most its unshadowed quadrature, and darker where the
/// torus hides the sky from itself); shadowed ISD follows the reference more
/// closely than unshadowed ISD; a scene that is not the shadows' mesh and
/// the methods without a shadowed path are refused.
#[test]
fn shadows_darken_the_torus_and_isd_follows_the_traced_reference() {
    use ifd_render::{Shadows, torus_mesh};
    use std::sync::Arc;
    let env = forest();
    let mesh = Arc::new(torus_mesh(1.0, 0.4, 48, 24).unwrap());
    let brdf = Brdf::parse("lambert").unwrap();
    let m = material(&brdf, 8);
    let traced = Shadows::traced(mesh.clone(), &env).unwrap();
    let shadows = Shadows::new(mesh.clone(), &env, 8, 1024, &|_, _| {}).unwrap();
    let camera = Camera::new(
        DVec3::new(0.0, -2.4, 1.7),
        DVec3::ZERO,
        DVec3::Z,
        40.0,
        32,
        32,
    )
    .unwrap();
    let job = |method, material, shadows| Job {
        spp: 1,
        seed: 1,
        shadows,
        ..Job::new(
            Scene::Mesh(mesh.clone()),
            camera,
            &env,
            &brdf,
            material,
            method,
        )
    };
    let go = |method, material, shadows| render(&job(method, material, shadows), &|_, _| {});
    let reference = go(Method::Quadrature, None, Some(&traced)).unwrap();
    let open = go(Method::Quadrature, None, None).unwrap();
    let (r, o) = (reference.image.data(), open.image.data());
    // (2x2 nodes per texel against the adaptive oracle: equal to a few 1e-3
    // where nothing is hidden)
    let worst = r
        .iter()
        .zip(o)
        .map(|(a, b)| (a - b) / b.max(1e-6))
        .fold(f32::MIN, f32::max);
    eprintln!("largest excess of the shadowed over the open reference: {worst:.2e}");
    assert!(worst < 5e-3, "{worst}");
    let darker = r.iter().zip(o).filter(|(a, b)| **a < 0.9 * **b).count();
    assert!(darker > 50, "{darker} values at least 10% darker");
    let isd = go(Method::Isd, Some(&m), Some(&shadows)).unwrap();
    let unshadowed = go(Method::Isd, Some(&m), None).unwrap();
    let mask = &reference.mask;
    let (e1, e0) = (
        relative_rms(&isd.image, &reference.image, mask),
        relative_rms(&unshadowed.image, &reference.image, mask),
    );
    assert!(e1 < 0.5 * e0, "shadowed {e1:.3e}, unshadowed {e0:.3e}");
    // the sphere, another mesh, and methods without a shadowed path
    let mut on_sphere = job(Method::Isd, Some(&m), Some(&shadows));
    on_sphere.scene = Scene::Sphere;
    assert!(render(&on_sphere, &|_, _| {}).is_err());
    let mut other = job(Method::Isd, Some(&m), Some(&shadows));
    other.scene = Scene::Mesh(Arc::new(torus_mesh(1.0, 0.4, 48, 24).unwrap()));
    assert!(render(&other, &|_, _| {}).is_err());
    for method in [Method::Sh, Method::IsdMaps, Method::Mc] {
        assert!(go(method, Some(&m), Some(&shadows)).is_err(), "{method:?}");
    }
    // a material above the visibility's degree
    let m12 = material(&brdf, 12);
    assert!(go(Method::Isd, Some(&m12), Some(&shadows)).is_err());
}

#[test]
fn gltf_brdf_isd_matches_the_oracle_and_monte_carlo_converges() {
    // the glTF metallic-roughness BRDF: ISD integrates its three parts and
    // combines them per pixel; the oracle and Monte Carlo evaluate the whole
    // BRDF (the goal: relative RMS <= 1% for roughness >= 0.5 at L <= 24)
    let env = forest();
    for (spec, l) in [
        ("gltf:roughness=0.5,metallic=1,base=0.95:0.64:0.54", 16),
        ("gltf:roughness=0.7,metallic=0,base=0.8:0.2:0.2", 12),
        ("gltf:roughness=1,metallic=0.5,base=0.5", 8),
    ] {
        let brdf = Brdf::parse(spec).unwrap();
        let parts = brdf.tabulated().unwrap();
        let m = material(&parts, l);
        let oracle = shoot(&env, &brdf, None, Method::Quadrature);
        let isd = shoot(&env, &brdf, Some(&m), Method::Isd);
        let sh = shoot(&env, &brdf, Some(&m), Method::Sh);
        let err = relative_rms(&isd.image, &oracle.image, &oracle.mask);
        let err_sh = relative_rms(&isd.image, &sh.image, &sh.mask);
        eprintln!(
            "{spec} at L = {l}: relative RMS {err:.5} against the oracle, {err_sh:.1e} against sh"
        );
        assert!(err <= 0.01, "{spec}: {err}");
        // f32 images: ISD and its SH reference agree to rounding
        assert!(err_sh <= 1e-6, "{spec}: isd vs sh {err_sh}");
        let coarse = shoot(&env, &brdf, Some(&material(&parts, 2)), Method::Isd);
        let err_coarse = relative_rms(&coarse.image, &oracle.image, &oracle.mask);
        assert!(err_coarse > 2.0 * err, "{spec}: L = 2 gives {err_coarse}");
        // the whole BRDF's own table is refused: ISD shades the parts
        let whole = Brdf::parse(spec).unwrap();
        let wrong = LobeTable::build(&whole, 2, 16, 1, &|_, _| {}).unwrap();
        let wrong = Material::new(&whole, 2, Some(wrong)).unwrap();
        let job = Job::new(
            Scene::Sphere,
            camera(8),
            &env,
            &brdf,
            Some(&wrong),
            Method::Isd,
        );
        let e = render(&job, &|_, _| {}).unwrap_err().to_string();
        assert!(e.contains("gltf-lobes"), "{e}");
    }
    // Monte Carlo with the mixture of GGX and cosine sampling converges to it
    let brdf = Brdf::parse("gltf:roughness=0.6,metallic=0.3,base=0.9:0.7:0.4").unwrap();
    let oracle = shoot(&env, &brdf, None, Method::Quadrature);
    let mc = |spp: usize| {
        let job = Job {
            spp,
            seed: 3,
            ..Job::new(Scene::Sphere, camera(40), &env, &brdf, None, Method::Mc)
        };
        render(&job, &|_, _| {}).unwrap()
    };
    let (a, b) = (mc(16), mc(256));
    let (ea, eb) = (
        relative_rms(&a.image, &oracle.image, &oracle.mask),
        relative_rms(&b.image, &oracle.image, &oracle.mask),
    );
    eprintln!("gltf: Monte Carlo relative RMS {ea:.4} at 16 spp, {eb:.4} at 256");
    assert!(eb <= 0.35 * ea && eb < 0.05, "{eb} vs {ea}");
}

/// The background is the map filtered bilinearly, not its nearest texel
/// (issue 54): vertical stripes one texel wide (0.1 and 0.9), magnified
/// about 8 pixels a texel by the view, show no run of equal pixels along a
/// row, where the nearest texel made 8-pixel-wide bars (7 of 8 horizontal
/// neighbours equal); every background pixel is
/// `EnvMap::lookup_bilinear` of its direction, within the polynomial
/// `atan2`'s error.
#[test]
fn the_background_is_the_map_filtered_bilinearly() {
    let (w, h) = (256, 128);
    let stripes = (0..w * h)
        .map(|i| if i % w % 2 == 0 { 0.1 } else { 0.9 })
        .collect();
    let env = EnvMap::new(Image::from_vec(w, h, 1, stripes).unwrap(), 0.0).unwrap();
    // 40 degrees over 240 pixels: 1/6 degree a pixel; a texel is 1.4 degrees
    let camera = Camera::new(
        DVec3::new(0.0, -8.0, 0.0),
        DVec3::ZERO,
        DVec3::Z,
        40.0,
        320,
        240,
    )
    .unwrap();
    let brdf = Brdf::parse("lambert").unwrap();
    let m = material(&brdf, 2);
    let job = Job {
        background: Some(&env),
        ..Job::new(Scene::Sphere, camera, &env, &brdf, Some(&m), Method::Isd)
    };
    let r = render(&job, &|_, _| {}).unwrap();
    let (iw, ih) = (r.image.width(), r.image.height());
    let (mut pairs, mut equal) = (0usize, 0usize);
    for y in 0..ih {
        for x in 0..iw - 1 {
            let (i, j) = (y * iw + x, y * iw + x + 1);
            if !r.mask[i] && !r.mask[j] {
                pairs += 1;
                equal += usize::from(r.image.data()[i] == r.image.data()[j]);
            }
        }
    }
    let share = equal as f64 / pairs as f64;
    eprintln!("background: {equal} of {pairs} horizontal neighbours equal ({share:.3})");
    assert!(pairs > iw * ih / 2, "{pairs} background pairs");
    assert!(
        share < 0.05,
        "{share:.3} of the background's horizontal neighbours are equal: the map is read at \
         its nearest texel (blocky), not filtered"
    );
    let px = ifd_render::pixels(&Scene::Sphere, &camera, None).unwrap();
    let mut worst = 0.0f64;
    for (i, p) in px.iter().enumerate().filter(|(i, _)| !r.mask[*i]) {
        let mut v = [0.0];
        env.lookup_bilinear(p.dir, &mut v);
        worst = worst.max((f64::from(r.image.data()[i]) - v[0]).abs());
    }
    assert!(
        worst < 1e-5,
        "the background is {worst} from the bilinear lookup"
    );
}
