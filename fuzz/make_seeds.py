"""Regenerates the seed corpus `fuzz/seeds/<target>/`: small valid (and a few
near-valid) inputs of every format, made with the `ifd` binary and numpy.

    IFD_BIN=target/debug/ifd .venv/bin/python fuzz/make_seeds.py

The seeds are committed: the fuzzers start from them (scripts/fuzz.sh) and
`cargo test` replays them (tests/fuzz_corpus.rs).
"""

import base64
import io
import json
import os
import pathlib
import shutil
import struct
import subprocess
import tempfile
import zlib

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


def png_bytes(rows):
    """A tiny 8-bit RGB PNG of `rows` (lists of (r, g, b) tuples)."""
    raw = b"".join(b"\0" + bytes(c for px in row for c in px) for row in rows)

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    head = struct.pack(">IIBBBBB", len(rows[0]), len(rows), 8, 2, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", head) + chunk(b"IDAT", zlib.compress(raw))
            + chunk(b"IEND", b""))


class Gltf:
    """One buffer of views and accessors, as the glTF reader's tests build them."""

    def __init__(self):
        self.bin, self.views, self.accessors = bytearray(), [], []

    def view(self, data):
        while len(self.bin) % 4:
            self.bin.append(0)
        self.views.append({"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)})
        self.bin += data
        return len(self.views) - 1

    def accessor(self, fmt, values, ctype, kind, width, **extra):
        v = self.view(struct.pack("<" + fmt * len(values), *values))
        self.accessors.append(dict(bufferView=v, componentType=ctype, type=kind,
                                   count=len(values) // width, **extra))
        return len(self.accessors) - 1

    def doc(self, rest, uri=None):
        buf = {"byteLength": len(self.bin)}
        if uri is not None:
            buf["uri"] = uri
        return dict(asset={"version": "2.0"}, buffers=[buf], bufferViews=self.views,
                    accessors=self.accessors, **rest)

    def glb(self, rest):
        j = json.dumps(self.doc(rest)).encode()
        j += b" " * (-len(j) % 4)
        b = bytes(self.bin) + b"\0" * (-len(self.bin) % 4)
        total = 12 + 8 + len(j) + 8 + len(b)
        return (b"glTF" + struct.pack("<II", 2, total) + struct.pack("<I", len(j)) + b"JSON" + j
                + struct.pack("<I", len(b)) + b"BIN\0" + b)


def gltf_seeds():
    """glTF assets (`gltf` target): binary and JSON files the reader loads,
    and a few corruptions of them."""
    quad = [-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0]
    uv = [0, 1, 1, 1, 1, 0, 0, 0]

    def base(g):
        p = g.accessor("f", quad, 5126, "VEC3", 3, min=[-1, -1, 0], max=[1, 1, 0])
        n = g.accessor("f", [0, 0, 1] * 4, 5126, "VEC3", 3)
        t = g.accessor("f", uv, 5126, "VEC2", 2)
        i = g.accessor("H", [0, 1, 2, 0, 2, 3], 5123, "SCALAR", 1)
        return p, n, t, i

    # a quad with a material
    g = Gltf()
    p, n, t, i = base(g)
    quad_rest = dict(
        meshes=[{"primitives": [{"attributes": {"POSITION": p, "NORMAL": n, "TEXCOORD_0": t},
                                 "indices": i, "material": 0}]}],
        materials=[{"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.5, 0.2, 1],
                                             "metallicFactor": 0.3, "roughnessFactor": 0.6}}],
        nodes=[{"mesh": 0}], scenes=[{"nodes": [0]}], scene=0)
    good = g.glb(quad_rest)
    put("gltf", "quad.glb", good)
    b64 = base64.b64encode(bytes(g.bin)).decode()
    put("gltf", "quad-data-uri.gltf",
        json.dumps(g.doc(quad_rest, "data:application/octet-stream;base64," + b64)))

    # textures (PNG in a buffer view): base colour, metallic-roughness, a
    # normal map without tangents (MikkTSpace), occlusion, emission; a camera,
    # node transforms (a mirrored instance), a strip, points, a sparse accessor
    g = Gltf()
    p, n, t, i = base(g)
    img = g.view(png_bytes([[(255, 128, 0), (0, 255, 128)], [(128, 128, 255), (40, 200, 90)]]))
    strip = g.accessor("H", [0, 1, 3, 2], 5123, "SCALAR", 1)
    si = g.view(struct.pack("<H", 2))
    sv = g.view(struct.pack("<3f", 2, 1, 0))
    g.accessors.append(dict(bufferView=g.accessors[p]["bufferView"], componentType=5126,
                            type="VEC3", count=4, min=[-1, -1, 0], max=[2, 1, 0],
                            sparse={"count": 1, "indices": {"bufferView": si, "componentType": 5123},
                                    "values": {"bufferView": sv}}))
    sparse = len(g.accessors) - 1
    tex = {"index": 0}
    rest = dict(
        meshes=[{"primitives": [
            {"attributes": {"POSITION": p, "TEXCOORD_0": t}, "indices": i, "material": 0},
            {"attributes": {"POSITION": sparse, "NORMAL": n, "TEXCOORD_0": t}, "indices": strip,
             "mode": 5},
            {"attributes": {"POSITION": p}, "mode": 0}]}],
        materials=[{"pbrMetallicRoughness": {"baseColorTexture": tex,
                                             "metallicRoughnessTexture": tex},
                    "normalTexture": {"index": 0, "scale": 0.5},
                    "occlusionTexture": {"index": 0, "strength": 0.7},
                    "emissiveTexture": tex, "emissiveFactor": [1, 1, 1],
                    "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 3}},
                    "doubleSided": True}],
        textures=[{"source": 0, "sampler": 0}],
        samplers=[{"wrapS": 33648, "wrapT": 33071}],
        images=[{"bufferView": img, "mimeType": "image/png"}],
        cameras=[{"type": "perspective", "perspective": {"yfov": 0.6, "znear": 0.1}}],
        nodes=[{"mesh": 0, "children": [1, 2]},
               {"mesh": 0, "translation": [3, 0, 0], "scale": [-1, 1, 1]},
               {"camera": 0, "rotation": [0, 0.3826834, 0, 0.9238795], "translation": [0, 0, 5]}],
        scenes=[{"nodes": [0]}],
        extensionsUsed=["KHR_materials_emissive_strength", "KHR_texture_transform"],
        extensionsRequired=["KHR_materials_emissive_strength"])
    textured = g.glb(rest)
    put("gltf", "textured.glb", textured)

    # corruptions: truncated, a chunk length past the end, an index out of
    # range, an accessor past its view, a required extension
    put("gltf", "truncated.glb", good[: len(good) // 2])
    bad = bytearray(good)
    bad[12:16] = struct.pack("<I", len(good))
    put("gltf", "chunk-length.glb", bytes(bad))
    bad = bytearray(textured)
    bad[-4:] = b"\xff\xff\xff\xff"
    put("gltf", "tail.glb", bytes(bad))
    g = Gltf()
    p, n, t, i = base(g)
    g.accessors[i]["count"] = 600
    put("gltf", "accessor-past-view.glb", g.glb(quad_rest))
    put("gltf", "required.gltf", json.dumps(dict(
        asset={"version": "2.0"}, extensionsRequired=["KHR_draco_mesh_compression"])))


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
    gltf_seeds()
    shutil.rmtree(tmp)
    print(f"seeds written under {SEEDS}")


if __name__ == "__main__":
    main()
