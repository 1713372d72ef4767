//! The fuzz harness: one function per parser the project owns, each taking
//! arbitrary bytes and doing what the CLI or the apps do with a file or a
//! spec of that kind (parse it, check it, use it a little). Any panic, abort,
//! hang or unbounded allocation is a bug; an `Err` is the expected outcome
//! for nearly every input.
//!
//! Included (`#[path]`) by the cargo-fuzz targets in `fuzz/fuzz_targets/`
//! and by the corpus replay test `tests/fuzz_corpus.rs` of the `ifd` package,
//! which runs every input in `fuzz/regressions/<target>/` through the same
//! function under `cargo test`. The strokes target lives in
//! `fuzz/harness_brush.rs` (it needs the brush app's crate).

#![allow(dead_code, reason = "each fuzz target uses one function")]

use std::io::Write;
use std::path::PathBuf;

use ifd_image::{MemoryBudget, NonFinitePolicy, ReadOptions};

/// The budget every file reader gets: an input declaring more is refused
/// before anything is allocated (libFuzzer runs with `-rss_limit_mb=2048`).
pub const BUDGET: MemoryBudget = MemoryBudget::bytes(256 << 20);

/// A fuzz target: arbitrary bytes in, a panic on a bug.
pub type Target = fn(&[u8]);

/// Every target, by name, for the corpus replay.
pub const TARGETS: &[(&str, Target)] = &[
    ("decomposition", decomposition),
    ("planar_spec", planar_spec),
    ("sphere_spec", sphere_spec),
    ("brdf_spec", brdf_spec),
    ("sphere_decomposition", sphere_decomposition),
    ("npy", npy),
    ("image", image),
    ("sh_coeffs", sh_coeffs),
    ("brdf_table", brdf_table),
    ("merl", merl),
    ("obj", obj),
    ("smooth_bank", smooth_bank),
    ("gltf", gltf),
];

/// A scratch file holding `data`, unique to this process and target, for
/// the readers that take a path (as the CLI does). Reused across inputs.
pub struct Scratch(PathBuf);

impl Scratch {
    pub fn new(target: &str, ext: &str, data: &[u8]) -> Self {
        let dir = std::env::temp_dir().join(format!("ifd-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("scratch folder");
        let path = dir.join(format!("{target}.{ext}"));
        let mut f = std::fs::File::create(&path).expect("scratch file");
        f.write_all(data).expect("scratch write");
        Self(path)
    }

    pub fn path(&self) -> &std::path::Path {
        &self.0
    }
}

fn text(data: &[u8]) -> Option<&str> {
    std::str::from_utf8(data).ok()
}

/// `ifd filter --decomp FILE`: the planar decomposition JSON format.
pub fn decomposition(data: &[u8]) {
    let Some(t) = text(data) else { return };
    let Ok(d) = ifd_planar::Decomposition::from_json_str(t) else {
        return;
    };
    let again = ifd_planar::Decomposition::from_json_str(&d.to_json_string())
        .expect("a decomposition that loaded writes a file that loads");
    assert_eq!(again.terms.len(), d.terms.len());
    let _ = d.eval(0.5, -1.5);
    let _ = d
        .report
        .as_ref()
        .map(ifd_planar::FitReport::full_plane_dc_error);
    // what every filter path does with it first
    let _ = ifd_planar::Prepare::prepare(&d);
}

/// `ifd decompose SPEC`: planar filter specs, sampled into a kernel.
pub fn planar_spec(data: &[u8]) {
    let Some(t) = text(data) else { return };
    if let Ok(spec) = t.parse::<ifd_planar::KernelSpec>() {
        let _ = spec.to_kernel();
    }
}

/// `ifd sphere decompose SPEC` and `--profile`: spherical kernel specs.
pub fn sphere_spec(data: &[u8]) {
    let Some(t) = text(data) else { return };
    if let Ok(k) = ifd_sphere::Kernel::parse(t) {
        let _ = k.eval([0.0, 0.6, 0.8]);
        let _ = k.suggested_nodes(8);
    }
    if let Ok(p) = ifd_sphere::Profile::parse(t) {
        let _ = p.beta(8);
    }
}

/// `--brdf SPEC` and `ifd sphere brdf SPEC` (MERL paths are files, fuzzed by
/// [`merl`]; a spec naming one is not opened here).
pub fn brdf_spec(data: &[u8]) {
    let Some(t) = text(data) else { return };
    if t.to_ascii_lowercase().contains("merl") {
        return;
    }
    if let Ok(b) = ifd_shade::Brdf::parse(t) {
        let _ = format!("{b:?}");
    }
}

/// `ifd sphere filter --decomp FILE`: the spherical decomposition JSON.
pub fn sphere_decomposition(data: &[u8]) {
    let Some(t) = text(data) else { return };
    if let Ok(d) = ifd_sphere::Decomposition::from_json(t)
        && d.validate().is_ok()
    {
        let _ = d.eval_kernel([0.0, 0.0, 1.0]);
        let _ = d.kernel_integral();
    }
}

/// `.npy` files: the array reader and the image reader on top of it.
pub fn npy(data: &[u8]) {
    let f = Scratch::new("npy", "npy", data);
    let _ = ifd_image::read_npy_array(f.path(), BUDGET);
    let _ = ifd_image::read_image(f.path(), &read_options());
}

fn read_options() -> ReadOptions {
    ReadOptions {
        budget: BUDGET,
        non_finite: NonFinitePolicy::Error,
        ..ReadOptions::default()
    }
}

/// Images through the project's reader (`image`/`exr` behind the budget
/// checks): the first byte picks the extension, the rest is the file.
pub fn image(data: &[u8]) {
    let Some((&pick, rest)) = data.split_first() else {
        return;
    };
    let ext = ["png", "jpg", "tif", "exr", "hdr"][usize::from(pick) % 5];
    let f = Scratch::new("image", ext, rest);
    let _ = ifd_image::read_image(f.path(), &read_options());
}

/// `ifd sphere rotate COEFFS` and friends: SH coefficient `.npy` files.
pub fn sh_coeffs(data: &[u8]) {
    let f = Scratch::new("sh_coeffs", "npy", data);
    let _ = ifd_sphere::ShCoeffs::read_npy(f.path());
    let _ = ifd_sphere::read_npy_f64(f.path());
}

/// `--table FILE`: view-dependent lobe tables of `ifd sphere brdf`.
pub fn brdf_table(data: &[u8]) {
    let f = Scratch::new("brdf_table", "bin", data);
    let _ = ifd_shade::LobeTable::read(f.path());
}

/// `--brdf merl:FILE`: measured BRDFs in the MERL binary format.
pub fn merl(data: &[u8]) {
    let f = Scratch::new("merl", "binary", data);
    if let Ok(m) = ifd_shade::Merl::read(f.path()) {
        let _ = m.eval([0.0, 0.6, 0.8], [0.3, 0.0, 0.95]);
    }
}

/// `--scene FILE.obj`: Wavefront OBJ meshes.
pub fn obj(data: &[u8]) {
    let f = Scratch::new("obj", "obj", data);
    let _ = ifd_render::Mesh::load(f.path(), false);
}

/// The smoothing decomposition banks cached by the brush app and the CLI.
pub fn smooth_bank(data: &[u8]) {
    let f = Scratch::new("smooth_bank", "json", data);
    let _ = ifd_smooth::AspectBank::load(f.path());
}

/// `--scene FILE.glb` / `FILE.gltf`: glTF 2.0 assets, written as `.glb`
/// (or as `.gltf` when the bytes do not start with the GLB magic, so the
/// JSON path is fuzzed too), loaded under the budget, and shaded at a few
/// rays from outside the mesh towards its vertices.
pub fn gltf(data: &[u8]) {
    let ext = if data.starts_with(b"glTF") {
        "glb"
    } else {
        "gltf"
    };
    let f = Scratch::new("gltf", ext, data);
    let Ok(asset) = ifd_render::GltfAsset::load(f.path(), BUDGET) else {
        return;
    };
    let _ = (asset.notes(), asset.roughness_range(), asset.camera());
    let mesh = asset.mesh();
    for (p, n) in mesh.positions().iter().zip(mesh.normals()).take(16) {
        if let Some(hit) = mesh.intersect(*p + *n * 3.0, -*n) {
            let _ = asset.point(&hit);
        }
    }
}
