//! ISD shading against the exact texel quadrature on the bundled forest map
//! (the accuracy goals, at a small size for CI: a 40x40 view of the
//! unit sphere, the map averaged down to 32x16).

use glam::DVec3;
use ifd_image::Image;
use ifd_render::camera::Camera;
use ifd_render::envmap::EnvMap;
use ifd_render::render::{Job, Method, Rendered, relative_rms, render};
use ifd_render::scene::Scene;
use ifd_shade::Brdf;
use ifd_shade::shade::Material;
use ifd_shade::table::{LobeTable, default_theta_entries};

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
        scene: Scene::Sphere,
        camera: camera(40),
        env,
        background: None,
        brdf,
        material,
        method,
        spp: 64,
        seed: 1,
        maps: None,
        family: None,
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
        scene: Scene::Sphere,
        camera: away,
        env: &one,
        background: Some(&one),
        brdf: &brdf,
        material: Some(&m),
        method: Method::Isd,
        spp: 0,
        seed: 0,
        maps: None,
        family: None,
    };
    let e = render(&job, &|_, _| {}).unwrap_err().to_string();
    assert!(e.contains("sees no object"), "{e}");
    let e = Camera::new(DVec3::ZERO, DVec3::Z, DVec3::Z, 40.0, 8, 8)
        .unwrap_err()
        .to_string();
    assert!(e.contains("--up"), "{e}");
    let e = Camera::new(DVec3::ZERO, DVec3::X, DVec3::Z, 190.0, 8, 8)
        .unwrap_err()
        .to_string();
    assert!(e.contains("--fov"), "{e}");
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
                scene: Scene::Sphere,
                camera: camera(40),
                env: &env,
                background: None,
                brdf: &brdf,
                material: None,
                method: Method::Mc,
                spp,
                seed: 7,
                maps: None,
                family: None,
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
    use ifd_render::scene::Scene;
    let dir = tempfile::tempdir().unwrap();
    let env = forest();
    let brdf = Brdf::parse("phong:s=16").unwrap();
    let m = Material::new(&brdf, 10, None).unwrap();
    let render_scene = |scene: Scene| {
        let job = Job {
            scene,
            camera: camera(48),
            env: &env,
            background: None,
            brdf: &brdf,
            material: Some(&m),
            method: Method::Isd,
            spp: 0,
            seed: 0,
            maps: None,
            family: None,
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
fn textured_sphere_matches_the_oracle() {
    use ifd_render::textures::{RoughnessFamily, SurfaceMaps, Texture};
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
    };
    let brdf = Brdf::parse("ggx:alpha=0.5").unwrap();
    let range = maps.roughness.as_ref().unwrap().range();
    let family = RoughnessFamily::build(&brdf, 20, range, 6, &|_, _| {}).unwrap();
    let job = |method, family| Job {
        scene: Scene::Sphere,
        camera: camera(40),
        env: &env,
        background: None,
        brdf: &brdf,
        material: None,
        method,
        spp: 0,
        seed: 0,
        maps: Some(&maps),
        family,
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
                scene: Scene::Sphere,
                camera: camera(24),
                env: &env,
                background: Some(&env),
                brdf: &brdf,
                material,
                method,
                spp: 32,
                seed: 3,
                maps: None,
                family: None,
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
