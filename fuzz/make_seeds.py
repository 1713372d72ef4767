"""Regenerates the seed corpus `fuzz/seeds/<target>/`: small valid (and a few
near-valid) inputs of every format, made with the `ifd` binary and numpy.

    IFD_BIN=target/debug/ifd .venv/bin/python fuzz/make_seeds.py

The seeds are committed: the fuzzers start from them (scripts/fuzz.sh) and
`cargo test` replays them (tests/fuzz_corpus.rs).
"""

import io
import os
import pathlib
import shutil
import subprocess
import tempfile

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
SEEDS = ROOT / "fuzz" / "seeds"
IFD = os.environ.get("IFD_BIN", str(ROOT / "target" / "debug" / "ifd"))


def ifd(*args):
    subprocess.run([IFD, *map(str, args)], check=True, capture_output=True)


def put(target, name, data):
    d = SEEDS / target
    d.mkdir(parents=True, exist_ok=True)
    (d / name).write_bytes(data if isinstance(data, bytes) else data.encode())


def npy_bytes(arr, fortran=False):
    buf = io.BytesIO()
    np.save(buf, np.asfortranarray(arr) if fortran else arr)
    return buf.getvalue()


def main():
    shutil.rmtree(SEEDS, ignore_errors=True)
    tmp = pathlib.Path(tempfile.mkdtemp())
    rng = np.random.default_rng(7)

    # planar decompositions and specs
    ifd("decompose", "gauss:sx=4,sy=1.5,theta=30", "--tol", "0.05", "-o", tmp / "d.json")
    put("decomposition", "gauss.json", (tmp / "d.json").read_bytes())
    put("decomposition", "hand.json",
        '{"format":"ifd-decomposition","version":1,"kernel":null,"dictionary":null,'
        '"report":null,"terms":[{"weight":1.0,"x":0.0,"y":0.0,"sigma":2.0}]}')
    for i, s in enumerate(["gauss:sx=6,sy=1,theta=30", "gauss:s=2", "dgauss:sigma=2,order=1",
                           "log:sigma=3", "gabor:sigma=3,freq=0.2,theta=10", "box:w=5,h=3",
                           "disk:r=4", "line:len=9,width=1,theta=45"]):
        put("planar_spec", f"spec{i}.txt", s)

    # spherical kernels, profiles, BRDFs
    for i, s in enumerate(["vmf:kappa=50", "phong:s=8", "gauss:s=0.3", "aniso-gauss:s1=0.2,s2=0.5",
                           "zh", "legendre", "phong", "gaussian", "vmf"]):
        put("sphere_spec", f"spec{i}.txt", s)
    for i, s in enumerate(["lambert", "lambert:albedo=0.5", "phong:s=32", "blinn:s=64",
                           "ggx:alpha=0.3", "ggx:ax=0.1,ay=0.4", "ward:ax=0.1,ay=0.2"]):
        put("brdf_spec", f"spec{i}.txt", s)
    ifd("sphere", "decompose", "vmf:kappa=10", "--lmax", "4", "-o", tmp / "s.json")
    put("sphere_decomposition", "vmf.json", (tmp / "s.json").read_bytes())

    # .npy arrays and SH coefficients
    put("npy", "f32.npy", npy_bytes(rng.random((5, 4), dtype=np.float32)))
    put("npy", "u8rgb.npy", npy_bytes((rng.random((4, 3, 3)) * 255).astype(np.uint8)))
    put("npy", "f64f.npy", npy_bytes(rng.random((3, 4)), fortran=True))
    put("npy", "u16.npy", npy_bytes((rng.random((2, 2, 4)) * 65535).astype(">u2")))
    coeffs = rng.standard_normal(9 * 3)
    put("sh_coeffs", "rgb.npy", npy_bytes(coeffs.reshape(9, 3)))
    put("sh_coeffs", "gray.npy", npy_bytes(coeffs[:9]))

    # images: first byte picks the extension (png, jpg, tif, exr, hdr)
    img = (rng.random((6, 5, 3)) * 255).astype(np.uint8)
    np.save(tmp / "img.npy", img)
    for k, ext in enumerate(["png", "jpg", "tif", "exr", "hdr"]):
        ifd("convert", tmp / "img.npy", tmp / f"img.{ext}")
        put("image", f"img-{ext}", bytes([k]) + (tmp / f"img.{ext}").read_bytes())

    # a lobe table, MERL headers, OBJ meshes, a smoothing bank
    ifd("sphere", "brdf", "phong:s=8", "--lmax", "3", "--theta-entries", "16", "-o", tmp / "t.lobes")
    put("brdf_table", "phong.lobes", (tmp / "t.lobes").read_bytes())
    dims = np.array([90, 90, 180], dtype="<i4").tobytes()
    put("merl", "header-only.binary", dims)
    put("merl", "short.binary", dims + np.full(64, 0.5, "<f8").tobytes())
    put("obj", "tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n")
    put("obj", "quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n")
    put("smooth_bank", "bank.json",
        '{"options":{"max_aspect":2.0,"steps_per_octave":1,"sigma_ref":6.0,"tol":0.01},'
        '"aspects":[1.0,2.0],"terms":[[{"weight":1.0,"x":0.0,"y":0.0,"sigma":6.0}],'
        '[{"weight":0.5,"x":-3.0,"y":0.0,"sigma":5.0},{"weight":0.5,"x":3.0,"y":0.0,"sigma":5.0}]]}')
    put("strokes", "strokes.json",
        '{"format":"ifd-brush-strokes","version":1,"image_size":[64,48],"strokes":[]}')
    put("strokes", "two.json",
        '{"format":"ifd-brush-strokes","version":1,"image_size":[64,48],"strokes":['
        '{"points":[[3.5,4.0],[30.0,20.0]]},{"undo":true},{"redo":true}]}')
    shutil.rmtree(tmp)
    print(f"seeds written under {SEEDS}")


if __name__ == "__main__":
    main()
