"""Bad input: every command refuses it with exit code 2, naming the file or option and the problem.

Each case makes its bad files in its own scratch folder (numpy arrays, plain
bytes, the bundled images truncated or overwritten), runs `ifd` once and checks:

- the exit code is exactly 2 (101 would be a panic; a run that does not end
  within the case's timeout is killed and counted as a hang);
- stderr names the offending file (its name) or option (e.g. `--scale`) and the
  problem (a few words per case, taken from what the CLI prints);
- stderr holds no panic or backtrace hint, no Rust debug formatting
  (`Some(..)`, `None`, escaped `\\n`, `crate::path`) and no clause said twice;
- nothing was written: afterwards the folder holds exactly the files the case
  made (no output, no partial output, no temporary file next to it).

The run also writes docs/bad-input.md, one row per case in the order below
(only when every case ran, so that `-k` does not truncate it).
"""

import dataclasses
import json
import pathlib
import re
import struct
import subprocess
from collections.abc import Callable, Sequence

import cv2
import numpy as np
import pytest

from conftest import ROOT, TESTDATA

DOC = ROOT / "docs" / "bad-input.md"

# Any of these words says that a file ended early.
TRUNCATED = r"truncated|unexpected end of file|not enough bytes|missing bytes"

# Never in a message for a user.
FORBIDDEN = {
    r"panicked": "a panic",
    r"RUST_BACKTRACE|stack backtrace": "a backtrace hint",
    r"\bSome\(|\bNone\b": "Rust debug formatting of an Option (Some(..)/None)",
    r"\\n": "an escaped newline (a dump of the file's text)",
    r"\bifd_\w+::": "a Rust path",
}


@dataclasses.dataclass(frozen=True)
class Case:
    """One bad invocation: how to make it and what its message must say."""

    id: str
    what: str
    build: Callable[["Files"], Sequence]
    names: tuple[str, ...]
    problem: tuple[str, ...]
    forbid: tuple[str, ...] = ()
    timeout: float = 60


class Files:
    """The scratch folder of one case and the inputs made in it."""

    def __init__(self, root: pathlib.Path, sphere_decomp: pathlib.Path):
        self.root = root
        self._sphere_decomp = sphere_decomp

    def path(self, name: str) -> pathlib.Path:
        """A path in the folder; nothing is created."""
        return self.root / name

    def raw(self, name: str, data: bytes) -> pathlib.Path:
        p = self.root / name
        p.write_bytes(data)
        return p

    def text(self, name: str, text: str) -> pathlib.Path:
        return self.raw(name, text.encode())

    def npy(self, name: str, arr) -> pathlib.Path:
        p = self.root / name
        np.save(p, arr, allow_pickle=True)
        return p

    def npy_header(self, name: str, shape: tuple, version: int = 1, payload: bytes = bytes(64)) -> pathlib.Path:
        """A float32 .npy file whose header declares `shape`, followed by just `payload`."""
        header = f"{{'descr': '<f4', 'fortran_order': False, 'shape': {shape}, }}"
        h = header + " " * (-(len(header) + 11) % 64) + "\n"
        return self.raw(name, b"\x93NUMPY" + bytes([version, 0]) + struct.pack("<H", len(h)) + h.encode() + payload)

    def image(self, name: str = "img.npy", shape=(32, 32)) -> pathlib.Path:
        """A valid float32 image of `shape`, values in [0, 1]."""
        return self.npy(name, np.random.default_rng(1).random(shape, dtype=np.float32))

    def encoded(self, name: str, shape=(32, 32, 3), keep: float = 1.0) -> pathlib.Path:
        """An 8-bit image encoded by OpenCV (format from `name`), its first `keep` fraction."""
        img = (np.random.default_rng(2).random(shape) * 255).astype(np.uint8)
        ok, buf = cv2.imencode(pathlib.Path(name).suffix, img)
        assert ok
        data = buf.tobytes()
        return self.raw(name, data[: int(len(data) * keep)])

    def testdata(self, src: str, name: str, keep: int | None = None) -> pathlib.Path:
        """A copy of the bundled `testdata/src`, its first `keep` bytes."""
        data = (TESTDATA / src).read_bytes()
        return self.raw(name, data if keep is None else data[:keep])

    def decomp(self, name: str = "g.json", **fields) -> pathlib.Path:
        """A planar decomposition file (one Gaussian of sigma 2, as `ifd decompose gauss:sx=2,sy=2` writes
        it), top-level fields replaced by `fields` (None: removed)."""
        d = {
            "format": "ifd-decomposition",
            "version": 1,
            "kernel": {"width": 17, "height": 17, "spec": "gauss:sx=2,sy=2,theta=0"},
            "terms": [{"weight": 1.0, "x": 0.0, "y": 0.0, "sigma": 2.0}],
        }
        d.update(fields)
        return self.text(name, json.dumps({k: v for k, v in d.items() if v is not None}, indent=2))

    def sphere_decomp(self, name: str = "sd.json") -> pathlib.Path:
        """A valid spherical decomposition (`ifd sphere decompose vmf:kappa=50 --lmax 2`)."""
        return self.raw(name, self._sphere_decomp.read_bytes())

    def regular_file(self, name: str = "afile") -> pathlib.Path:
        """A regular file, to be used where a folder is needed."""
        return self.raw(name, b"not a folder\n")

    def folder(self, name: str) -> pathlib.Path:
        p = self.root / name
        p.mkdir()
        return p


def exr_bytes(a: np.ndarray) -> bytes:
    """A minimal uncompressed single-part scanline OpenEXR file of float RGB(A) `a` (H, W, 3 or 4)."""
    a = np.asarray(a, np.float32)
    h, w, c = a.shape
    names = "RGBA"[:c]
    order = sorted(range(c), key=lambda i: names[i])  # channels are stored alphabetically

    def attr(name, typ, data):
        return name.encode() + b"\0" + typ.encode() + b"\0" + struct.pack("<i", len(data)) + data

    chlist = b"".join(names[i].encode() + b"\0" + struct.pack("<iB3xii", 2, 0, 1, 1) for i in order) + b"\0"
    box = struct.pack("<4i", 0, 0, w - 1, h - 1)
    header = b"".join([
        attr("channels", "chlist", chlist),
        attr("compression", "compression", b"\0"),
        attr("dataWindow", "box2i", box),
        attr("displayWindow", "box2i", box),
        attr("lineOrder", "lineOrder", b"\0"),
        attr("pixelAspectRatio", "float", struct.pack("<f", 1.0)),
        attr("screenWindowCenter", "v2f", struct.pack("<2f", 0.0, 0.0)),
        attr("screenWindowWidth", "float", struct.pack("<f", 1.0)),
    ]) + b"\0"
    head = struct.pack("<ii", 20000630, 2) + header
    lines = [
        struct.pack("<ii", y, w * c * 4) + b"".join(a[y, :, i].astype("<f4").tobytes() for i in order)
        for y in range(h)
    ]
    start = len(head) + 8 * h
    offsets = np.cumsum([start] + [len(line) for line in lines[:-1]])
    return head + struct.pack(f"<{h}Q", *offsets) + b"".join(lines)


def _with(arr: np.ndarray, index, value) -> np.ndarray:
    arr = arr.copy()
    arr[index] = value
    return arr


def _filter(f: Files, *extra, image=None, decomp=None, out: str = "out.png") -> list:
    """`ifd filter IMAGE --decomp DECOMP EXTRA... -o OUT`, by default a 32x32 image and g.json."""
    return ["filter", image or f.image(), "--decomp", decomp or f.decomp(), *extra, "-o", f.path(out)]


def _sphere_weights(f: Files, value: float) -> dict:
    """The valid spherical decomposition with every weight set to `value`."""
    d = json.loads(f.sphere_decomp().read_text())
    d["weights"]["data"] = [value] * len(d["weights"]["data"])
    return d


def _sphere_direction(f: Files, direction: list) -> dict:
    """The valid spherical decomposition with its fourth lobe direction replaced."""
    d = json.loads(f.sphere_decomp().read_text())
    d["directions"]["dirs"][3] = direction
    return d


def _corrupt_png(f: Files) -> pathlib.Path:
    """camera.png with 40 bytes of its first IDAT chunk's deflate stream zeroed."""
    raw = bytearray((TESTDATA / "camera.png").read_bytes())
    i = raw.find(b"IDAT") + 4
    raw[i + 100 : i + 140] = bytes(40)
    return f.raw("corrupt.png", bytes(raw))


ONES = np.ones((32, 32), np.float32)
ZEROS = np.zeros((32, 32), np.float32)
ENV = np.random.default_rng(3).random((16, 32, 3), dtype=np.float32)  # 2:1 equirectangular


CASES = [
    # --- truncated and corrupt files, every input format ---
    Case("png-truncated", "PNG cut after 1000 bytes",
         lambda f: ["info", f.testdata("camera.png", "trunc.png", keep=1000)],
         ("trunc.png",), (TRUNCATED,)),
    Case("png-empty", "PNG of 0 bytes",
         lambda f: ["info", f.raw("empty.png", b"")],
         ("empty.png",), (TRUNCATED,)),
    Case("png-not-png", "text in a .png file",
         lambda f: ["convert", f.raw("text.png", b"this is not a PNG file at all\n"), f.path("out.npy")],
         ("text.png",), ("cannot decode PNG", "signature")),
    Case("png-corrupt", "PNG with a corrupt deflate stream",
         lambda f: _filter(f, image=_corrupt_png(f)),
         ("corrupt.png",), ("cannot decode PNG", "corrupt")),
    Case("jpeg-truncated", "JPEG cut at 60% (inside the scan data)",
         lambda f: ["convert", f.encoded("trunc.jpg", keep=0.6), f.path("out.png")],
         ("trunc.jpg",), (TRUNCATED,)),
    Case("jpeg-not-jpeg", "JPEG start marker followed by garbage",
         lambda f: ["info", f.raw("garbage.jpg", b"\xff\xd8\xff\xe0" + b"garbage" * 20)],
         ("garbage.jpg",), ("cannot decode JPEG",)),
    Case("tiff-truncated", "TIFF cut in half",
         lambda f: ["info", f.encoded("trunc.tif", keep=0.5)],
         ("trunc.tif",), ("cannot decode TIFF", TRUNCATED)),
    Case("tiff-bad-signature", "TIFF without its `II*`/`MM*` signature",
         lambda f: ["info", f.raw("sig.tif", b"XX*\0garbagegarbage")],
         ("sig.tif",), ("cannot decode TIFF", "signature")),
    Case("exr-truncated", "OpenEXR (DWAB) cut after 3000 bytes",
         lambda f: ["info", f.testdata("forest_dwab.exr", "trunc.exr", keep=3000)],
         ("trunc.exr",), ("cannot decode OpenEXR", TRUNCATED)),
    Case("exr-not-exr", "no OpenEXR magic number",
         lambda f: ["info", f.raw("magic.exr", b"notanexr" + bytes(64))],
         ("magic.exr",), ("cannot decode OpenEXR", "identifier")),
    Case("exr-nan", "OpenEXR holding a NaN",
         lambda f: ["convert", f.raw("nan.exr", exr_bytes(_with(ENV, (2, 3, 1), np.nan))), f.path("out.npy")],
         ("nan.exr",), ("non-finite", "NaN", "--replace-nonfinite")),
    Case("hdr-truncated", "Radiance HDR cut after 3000 bytes",
         lambda f: ["info", f.testdata("forest.hdr", "trunc.hdr", keep=3000)],
         ("trunc.hdr",), ("cannot decode Radiance HDR", TRUNCATED)),
    Case("hdr-huge-header", "Radiance HDR header declaring 99999x99999 pixels",
         lambda f: ["info", f.text("huge.hdr", "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 99999 +X 99999\n"),
                    "--memory-budget", "64"],
         ("huge.hdr",), ("would need", "budget of 64.0 MiB")),
    Case("npy-declares-more-data", ".npy header declaring 4096x4096 float32, 64 data bytes",
         lambda f: ["info", f.npy_header("short.npy", (4096, 4096))],
         ("short.npy",), ("truncated", "67108864")),
    Case("npy-truncated-header", ".npy cut inside its header",
         lambda f: ["info", f.raw("head.npy", f.image().read_bytes()[:20])],
         ("head.npy",), ("truncated",)),
    Case("npy-bad-magic", ".npy without the \\x93NUMPY magic",
         lambda f: ["info", f.raw("magic.npy", b"\x93NUMPZ" + f.image().read_bytes()[6:])],
         ("magic.npy",), ("magic",)),
    Case("npy-version", ".npy format version 9",
         lambda f: ["info", f.npy_header("v9.npy", (2, 2), version=9)],
         ("v9.npy",), ("version 9",)),
    Case("npy-complex64", ".npy of complex64",
         lambda f: ["info", f.npy("c64.npy", np.zeros((4, 4), np.complex64))],
         ("c64.npy",), ("<c8", "not supported")),
    Case("npy-object", ".npy of Python objects (pickled)",
         lambda f: ["info", f.npy("obj.npy", np.array([[1, "a"]], dtype=object))],
         ("obj.npy",), (r"\|O", "not supported")),
    Case("npy-f64-past-f32", ".npy of float64 with 1e300 (finite, past float32)",
         lambda f: ["info", f.npy("big64.npy", np.full((4, 4), 1e300))],
         ("big64.npy",), ("1e300", "32-bit floats")),
    Case("npy-structured", ".npy of a structured dtype (record fields)",
         lambda f: ["info", f.npy("rec.npy", np.zeros((4, 4), dtype=[("a", "<f4"), ("b", "<f4")]))],
         ("rec.npy",), ("structured dtype", "not supported")),
    Case("npy-4d", ".npy of shape (2, 3, 4, 5)",
         lambda f: ["convert", f.npy("4d.npy", np.zeros((2, 3, 4, 5), np.float32)), f.path("out.exr")],
         ("4d.npy",), ("not an image", r"\[2, 3, 4, 5\]")),
    Case("npy-1d", ".npy of shape (5,)",
         lambda f: ["info", f.npy("1d.npy", np.zeros(5, np.float32))],
         ("1d.npy",), ("not an image",)),
    Case("npy-zero-size", ".npy of shape (0, 5)",
         lambda f: ["info", f.npy("zero.npy", np.zeros((0, 5), np.float32))],
         ("zero.npy",), ("empty",)),
    Case("npy-huge-shape", ".npy header declaring 100000x100000 float32 in a 64-byte body (checked before any allocation)",
         lambda f: ["info", f.npy_header("huge.npy", (100000, 100000)),
                    "--memory-budget", "64"],
         ("huge.npy",), ("truncated", "40000000000 data bytes", "holds 64")),
    Case("image-nan", "NaN in the image",
         lambda f: _filter(f, image=f.npy("nan.npy", _with(ONES, (3, 5), np.nan))),
         ("nan.npy",), ("non-finite", "x=5, y=3", "--replace-nonfinite")),
    Case("image-inf", "+Inf in the image",
         lambda f: ["hessian", f.npy("inf.npy", _with(ONES, (7, 1), np.inf)), "--sigma", "2", "-o", f.path("h.npy")],
         ("inf.npy",), ("non-finite",)),
    Case("input-missing", "input file does not exist",
         lambda f: ["convert", f.path("missing.png"), f.path("out.png")],
         ("missing.png",), ("no such file",)),
    Case("input-is-folder", "input is a folder",
         lambda f: ["info", f.folder("dir.png")],
         ("dir.png",), ("directory",)),
    # --- per-pixel maps: size, channels, values ---
    Case("angle-map-size", "16x16 angle map for a 32x32 image",
         lambda f: _filter(f, "--angle-map", f.npy("angle.npy", np.zeros((16, 16), np.float32))),
         ("angle.npy",), ("16x16", "32x32")),
    Case("angle-map-channels", "angle map with 2 channels",
         lambda f: _filter(f, "--angle-map", f.npy("angle.npy", np.zeros((32, 32, 2), np.float32))),
         ("angle.npy",), ("2 channels", "expected 1")),
    Case("angle-map-8-bit", "angle map stored as an 8-bit PNG",
         lambda f: _filter(f, "--angle-map", f.encoded("angle.png", shape=(32, 32))),
         ("angle.png",), ("8-bit", r"\.npy")),
    Case("angle-map-nan", "NaN in the angle map",
         lambda f: _filter(f, "--angle-map", f.npy("angle.npy", _with(ZEROS, (2, 3), np.nan))),
         ("angle.npy",), ("non-finite",)),
    Case("scale-map-inf", "Inf in the scale map",
         lambda f: _filter(f, "--scale-map", f.npy("scale.npy", _with(ONES, (4, 4), np.inf))),
         ("scale.npy",), ("non-finite",)),
    Case("scale-map-negative", "negative value in the scale map",
         lambda f: _filter(f, "--scale-map", f.npy("scale.npy", _with(ONES, (4, 4), -1.0))),
         ("scale.npy",), ("must be positive", r"\(4, 4\)")),
    Case("scale-map-huge", "scale map of 1e9",
         lambda f: _filter(f, "--scale-map", f.npy("scale.npy", ONES * 1e9)),
         ("scale.npy",), ("absurdly large",)),
    # --- channel counts and shapes ---
    Case("jpeg-2-channels", "2-channel image written as JPEG (1 or 3)",
         lambda f: ["convert", f.npy("two.npy", np.zeros((8, 8, 2), np.float32)), f.path("out.jpg")],
         ("out.jpg",), ("2 channels",)),
    Case("envmap-2-channels", "2-channel environment map (RGB needed)",
         lambda f: ["envmap", "prefilter", f.npy("env2.npy", ENV[..., :2]), "--face-size", "8", "--out-dir", f.path("ibl")],
         ("env2.npy",), ("RGB", "2 channel")),
    Case("render-env-2-channels", "2-channel environment map for render",
         lambda f: ["render", "--env", f.npy("env2.npy", ENV[..., :2]), "--brdf", "ggx:alpha=0.3", "--lmax", "2",
                    "--size", "8x8", "-o", f.path("out.png")],
         ("env2.npy",), ("1, 3 or 4",)),
    Case("sphere-sh-square-map", "16x16 map is neither 2:1 nor 6:1",
         lambda f: ["sphere", "sh", f.npy("square.npy", ENV[:, :16]), "--lmax", "2", "-o", f.path("sh.npy")],
         ("square.npy",), ("2:1", "16x16")),
    Case("compare-sizes", "compare 32x32 with 32x24",
         lambda f: ["compare", f.image("a.npy"), f.image("b.npy", shape=(24, 32))],
         ("a.npy", "b.npy"), ("32x32", "32x24")),
    Case("compare-channels", "compare 1 channel with 3",
         lambda f: ["compare", f.image("a.npy"), f.image("b.npy", shape=(32, 32, 3))],
         ("a.npy", "b.npy"), ("1 channels", "3 channels")),
    # --- absurd parameters: filter ---
    Case("filter-scale-negative", "--scale=-1",
         lambda f: _filter(f, "--scale=-1"),
         ("--scale",), ("must be positive",)),
    Case("filter-scale-negative-spaced", "--scale -1 (value as a separate argument)",
         lambda f: _filter(f, "--scale", "-1"),
         ("--scale",), ("positive|negative",)),
    Case("filter-scale-zero", "--scale 0",
         lambda f: _filter(f, "--scale", "0"),
         ("--scale",), ("must be positive",)),
    Case("filter-scale-huge", "--scale 1e9",
         lambda f: _filter(f, "--scale", "1e9"),
         ("--scale",), ("absurdly large",)),
    Case("filter-scale-tiny", "--scale 1e-20 (every term far below a pixel)",
         lambda f: _filter(f, "--scale", "1e-20"),
         ("--scale",), ("small",)),
    Case("filter-scale-nan", "--scale nan",
         lambda f: _filter(f, "--scale", "nan"),
         ("--scale",), ("not finite",)),
    Case("filter-angle-inf", "--angle inf",
         lambda f: _filter(f, "--angle", "inf"),
         ("--angle",), ("not finite",)),
    Case("filter-kernel-too-large", "--scale 1000: the filter spans 17000 px of a 32x32 image",
         lambda f: _filter(f, "--scale", "1000"),
         ("g.json",), ("scale 1000", "larger than the 32x32 image")),
    Case("filter-scale-no-kernel-block",
         "--scale 100 (reach 600 px on a 32x32 image), decomposition without its kernel block",
         lambda f: _filter(f, "--scale", "100", decomp=f.decomp("terms.json", kernel=None)),
         ("terms.json",), ("larger than the 32x32 image",)),
    Case("filter-eval-budget", "--eval-budget=-1",
         lambda f: _filter(f, "--eval-budget=-1"),
         ("--eval-budget",), ("positive",)),
    Case("filter-border", "--border bogus",
         lambda f: _filter(f, "--border", "bogus"),
         ("--border",), ("unknown border mode",)),
    Case("filter-memory-budget", "--memory-budget 1 (MiB) for a 512x512 PNG (cannot stream)",
         lambda f: _filter(f, "--memory-budget", "1", image=f.encoded("big.png", shape=(512, 512, 3))),
         ("big.png",), ("would need", "budget of 1.0 MiB", r"\.npy")),
    Case("filter-budget-png-output", "a .npy image over --memory-budget, written to .png (tiles stream to .npy only)",
         lambda f: _filter(f, "--memory-budget", "1", image=f.image("big.npy", shape=(512, 512))),
         ("big.npy",), ("more than the memory budget", r"\.npy")),
    Case("filter-tile-zero", "--tile 0",
         lambda f: _filter(f, "--tile", "0"),
         ("--tile",), ("at least 1",)),
    Case("filter-tile-fortran", "--tile with a Fortran-ordered .npy (cannot be read by region)",
         lambda f: _filter(f, "--tile", "16", out="out.npy",
                           image=f.npy("fort.npy", np.asfortranarray(np.ones((40, 30), np.float32)))),
         ("fort.npy",), ("Fortran", "ascontiguousarray")),
    Case("filter-angle-and-map", "--angle and --angle-map together",
         lambda f: _filter(f, "--angle", "5", "--angle-map", f.npy("angle.npy", ZEROS)),
         ("--angle", "--angle-map"), ("cannot be used with",)),
    # --- absurd parameters: decompose, filter specs, kernel files ---
    Case("decompose-tol-zero", "--tol 0",
         lambda f: ["decompose", "gauss:sx=2,sy=2", "--tol", "0", "-o", f.path("d.json")],
         ("--tol",), (r"0 < tol < 1|between 0 and 1",)),
    Case("decompose-max-terms-zero", "--max-terms 0",
         lambda f: ["decompose", "gauss:sx=2,sy=2", "--max-terms", "0", "-o", f.path("d.json")],
         ("--max-terms",), ("at least 1",)),
    Case("decompose-oversample", "--oversample 9",
         lambda f: ["decompose", "gauss:sx=2,sy=2", "--oversample", "9", "-o", f.path("d.json")],
         ("--oversample",), ("1 to 8",)),
    Case("spec-negative-sigma", "gauss:sx=-1,sy=2",
         lambda f: ["decompose", "gauss:sx=-1,sy=2", "-o", f.path("d.json")],
         ("gauss:sx=-1,sy=2",), ("must be positive",)),
    Case("spec-unknown", "unknown:a=1",
         lambda f: ["decompose", "unknown:a=1", "-o", f.path("d.json")],
         ("unknown:a=1",), ("unknown kernel spec", "known: gauss")),
    Case("spec-unknown-key", "gauss:sx=2,sy=2,foo=3",
         lambda f: ["decompose", "gauss:sx=2,sy=2,foo=3", "-o", f.path("d.json")],
         ("gauss:sx=2,sy=2,foo=3",), ('no key "foo"',)),
    Case("spec-huge", "gauss:sx=1e6,sy=1 (kernel of 8 million px)",
         lambda f: ["decompose", "gauss:sx=1e6,sy=1", "-o", f.path("d.json")],
         ("gauss:sx=1e6,sy=1",), ("larger than the limit",)),
    Case("kernel-even", "4x4 kernel file",
         lambda f: ["decompose", f.npy("even.npy", np.ones((4, 4), np.float32)), "-o", f.path("d.json")],
         ("even.npy",), ("4x4", "odd")),
    Case("kernel-zero", "all-zero kernel file",
         lambda f: ["decompose", f.npy("zero.npy", np.zeros((5, 5), np.float32)), "-o", f.path("d.json")],
         ("zero.npy",), ("all zero",)),
    Case("kernel-channels", "3-channel kernel file",
         lambda f: ["decompose", f.npy("rgb.npy", np.ones((5, 5, 3), np.float32)), "-o", f.path("d.json")],
         ("rgb.npy",), ("3 channels", "expected 1")),
    Case("kernel-nan", "NaN in the kernel file",
         lambda f: ["decompose", f.npy("nan.npy", _with(np.ones((5, 5), np.float32), (2, 2), np.nan)),
                    "-o", f.path("d.json")],
         ("nan.npy",), ("non-finite",)),
    Case("decompose-plot-extension", "--plot plot.xyz (unknown extension): no decomposition may be left",
         lambda f: ["decompose", "gauss:sx=2,sy=2", "-o", f.path("d.json"), "--plot", f.path("plot.xyz")],
         ("plot.xyz",), ("unsupported file extension",)),
    # --- absurd parameters: hessian, smooth, compare ---
    Case("hessian-sigma-zero", "--sigma 0",
         lambda f: ["hessian", f.image(), "--sigma", "0", "-o", f.path("h.npy")],
         ("--sigma",), (r"\[1, 256\]",)),
    Case("smooth-scale-zero", "--sigma 0",
         lambda f: ["smooth", f.image(), "--sigma", "0", "-o", f.path("out.png")],
         ("--sigma",), (r"\[0\.5, 128\]",)),
    Case("smooth-max-aspect", "--max-aspect 100",
         lambda f: ["smooth", f.image(), "--sigma", "3", "--max-aspect", "100", "-o", f.path("out.png")],
         ("--max-aspect",), (r"\[1, 16\]",)),
    Case("smooth-strength", "--strength 2",
         lambda f: ["smooth", f.image(), "--sigma", "3", "--strength", "2", "-o", f.path("out.png")],
         ("--strength",), (r"outside \[0, 1\]",)),
    Case("smooth-field-extension", "--field field.png (data must be .npy)",
         lambda f: ["smooth", f.image(), "--sigma", "3", "--field", f.path("field.png"), "-o", f.path("out.png")],
         ("--field",), (r"\.npy only",)),
    Case("smooth-tile-png", "--tile 64 on a PNG (tiles stream .npy only)",
         lambda f: ["smooth", f.encoded("in.png", shape=(40, 40, 3)), "--sigma", "3", "--tile", "64",
                    "-o", f.path("out.npy")],
         ("in.png",), (r"\.npy",)),
    Case("smooth-tile-zero", "--tile 0",
         lambda f: ["smooth", f.image(), "--sigma", "3", "--tile", "0", "-o", f.path("out.npy")],
         ("--tile",), ("at least 1",)),
    Case("smooth-budget-png-output", "a .npy image over --memory-budget, written to .png (tiles stream to .npy only)",
         lambda f: ["smooth", f.image("big.npy", shape=(512, 512)), "--sigma", "3", "--memory-budget", "1",
                    "-o", f.path("out.png")],
         ("big.npy", "out.png"), ("more than the memory budget", r"\.npy")),
    Case("compare-crop-border", "--crop-border 16 of a 32x32 image",
         lambda f: ["compare", f.image("a.npy"), f.image("b.npy"), "--crop-border", "16"],
         ("--crop-border",), ("cannot crop",)),
    Case("compare-data-range", "--data-range 0",
         lambda f: ["compare", f.image("a.npy"), f.image("b.npy"), "--data-range", "0"],
         ("--data-range",), ("finite and positive",)),
    # --- decomposition files ---
    Case("decomp-missing", "decomposition file does not exist",
         lambda f: _filter(f, decomp=f.path("missing.json")),
         ("missing.json",), ("no such file",)),
    Case("decomp-not-json", "decomposition file is not JSON",
         lambda f: _filter(f, decomp=f.text("text.json", "this is not json {")),
         ("text.json",), ("not a valid decomposition file",)),
    Case("decomp-truncated", "decomposition file cut after 60 bytes",
         lambda f: _filter(f, decomp=f.raw("cut.json", f.decomp().read_bytes()[:60])),
         ("cut.json",), ("not a valid decomposition file", "EOF")),
    Case("decomp-format", 'decomposition with "format": "something-else"',
         lambda f: _filter(f, decomp=f.decomp("fmt.json", format="something-else")),
         ("fmt.json",), ("not an ifd decomposition file", '"something-else"')),
    Case("decomp-version", "decomposition of version 99",
         lambda f: _filter(f, decomp=f.decomp("v99.json", version=99)),
         ("v99.json",), ("version", "99", "not supported")),
    Case("decomp-spherical", "spherical decomposition given to `ifd filter`",
         lambda f: _filter(f, decomp=f.sphere_decomp()),
         ("sd.json",), ("not an ifd decomposition file",)),
    Case("decomp-negative-sigma", "decomposition term with sigma -2",
         lambda f: _filter(f, decomp=f.decomp("neg.json", terms=[{"weight": 1, "x": 0, "y": 0, "sigma": -2}])),
         ("neg.json",), (r"terms\[0\]\.sigma", "not positive")),
    Case("decomp-no-terms", "decomposition with no terms",
         lambda f: _filter(f, decomp=f.decomp("empty.json", terms=[])),
         ("empty.json",), ("no terms",)),
    Case("decomp-nan-weight", "decomposition weight NaN (as Python's json writes it)",
         lambda f: _filter(f, decomp=f.decomp("nan.json", terms=[{"weight": float("nan"), "x": 0, "y": 0,
                                                                              "sigma": 2}])),
         ("nan.json",), ("not a valid decomposition file",)),
    # --- spherical ---
    Case("sphere-sh-lmax", "sphere sh --lmax 100000",
         lambda f: ["sphere", "sh", f.npy("env.npy", ENV), "--lmax", "100000", "-o", f.path("sh.npy")],
         ("--lmax",), ("at most L = 1000",)),
    Case("sphere-decompose-lmax", "sphere decompose --lmax 41 (limit 40)",
         lambda f: ["sphere", "decompose", "vmf:kappa=50", "--lmax", "41", "-o", f.path("sd.json")],
         ("--lmax",), ("at most L = 40|40",)),
    Case("sphere-brdf-lmax", "sphere brdf --lmax 101 (limit 100)",
         lambda f: ["sphere", "brdf", "ggx:alpha=0.3", "--lmax", "101", "-o", f.path("t.lobes")],
         ("--lmax",), ("L <= 100",)),
    Case("sh-wrong-length", "10 SH coefficient rows (not (L+1)^2)",
         lambda f: ["sphere", "rotate", f.npy("c.npy", np.ones((10, 3))), "--zyz", "0.1,0.2,0.3",
                    "-o", f.path("r.npy")],
         ("c.npy",), (r"\(L\+1\)\^2", "10")),
    Case("sh-nan", "NaN SH coefficient",
         lambda f: ["sphere", "rotate", f.npy("c.npy", _with(np.ones((9, 3)), (4, 1), np.nan)), "--zyz", "0.1,0.2,0.3",
                    "-o", f.path("r.npy")],
         ("c.npy",), ("non-finite", "row 4, column 1")),
    Case("sh-3d", "SH coefficients of shape (9, 3, 2)",
         lambda f: ["sphere", "rotate", f.npy("c.npy", np.ones((9, 3, 2))), "--zyz", "0.1,0.2,0.3",
                    "-o", f.path("r.npy")],
         ("c.npy",), ("1-D or 2-D",)),
    Case("rotate-nan-angle", "--zyz nan,0.2,0.3",
         lambda f: ["sphere", "rotate", f.npy("c.npy", np.ones((9, 3))), "--zyz", "nan,0.2,0.3", "-o", f.path("r.npy")],
         ("--zyz",), ("finite",)),
    Case("rotate-two-angles", "--zyz 0.1,0.2 (two angles)",
         lambda f: ["sphere", "rotate", f.npy("c.npy", np.ones((9, 3))), "--zyz", "0.1,0.2", "-o", f.path("r.npy")],
         ("--zyz",), ("three",)),
    Case("eval-zero-direction", "direction (0, 0, 0) in sphere eval --dirs",
         lambda f: ["sphere", "eval", "--lmax", "2", "--dirs", f.npy("dirs.npy", np.zeros((4, 3))),
                    "-o", f.path("y.npy")],
         ("dirs.npy",), ("zero vector",)),
    Case("sphere-filter-planar-decomp", "planar decomposition given to `ifd sphere filter`",
         lambda f: ["sphere", "filter", f.npy("env.npy", ENV), "--decomp", f.decomp(), "-o", f.path("out.exr")],
         ("g.json",), ("ifd decompose|planar|not a spherical",)),
    Case("sphere-filter-version", "spherical decomposition of version 7",
         lambda f: ["sphere", "filter", f.npy("env.npy", ENV), "--decomp",
                    f.text("v7.json", json.dumps({**json.loads(f.sphere_decomp().read_text()), "version": 7})),
                    "-o", f.path("out.exr")],
         ("v7.json",), ("version 7", "not supported"), forbid=('""',)),
    Case("sphere-filter-size-huge", "sphere filter --size 100000x50000",
         lambda f: ["sphere", "filter", f.npy("env.npy", ENV), "--decomp", f.sphere_decomp(), "--size", "100000x50000",
                    "-o", f.path("out.exr")],
         ("--size",), ("16384",)),
    Case("sphere-filter-size-budget", "sphere filter --size 16384x8192 with --memory-budget 64",
         lambda f: ["sphere", "filter", f.npy("env.npy", ENV), "--decomp", f.sphere_decomp(), "--size", "16384x8192",
                    "--memory-budget", "64", "-o", f.path("out.exr")],
         ("--size",), ("would need 1.5 GiB", "budget of 64.0 MiB")),
    Case("sphere-filter-size-ratio", "sphere filter --size 30x16 (neither 2:1 nor 6:1)",
         lambda f: ["sphere", "filter", f.npy("env.npy", ENV), "--decomp", f.sphere_decomp(), "--size", "30x16",
                    "-o", f.path("out.exr")],
         ("--size",), ("2:1",)),
    Case("sphere-sh-reconstruct-folder", "--reconstruct into a missing folder: no coefficients may be left",
         lambda f: ["sphere", "sh", f.npy("env.npy", ENV), "--lmax", "2", "-o", f.path("sh.npy"),
                    "--reconstruct", f.path("nodir/rec.exr")],
         ("nodir",), ("does not exist",)),
    Case("brdf-spec", "BRDF spec ggx:alpha=-1",
         lambda f: ["sphere", "brdf", "ggx:alpha=-1", "--lmax", "4", "-o", f.path("t.lobes")],
         ("ggx:alpha=-1",), ("outside",)),
    Case("radial-radiance-huge", "sphere radial --radiance 1e300 (the float32 map would be all inf)",
         lambda f: ["sphere", "radial", "--brdf", "lambert", "--lmax", "2", "--light-profile", "overcast",
                    "--radiance", "1e300", "--cells", "2x2x2", "-o", f.path("rad.npy")],
         ("--radiance",), ("at most 1e30", "float32")),
    Case("radial-preview-extension", "sphere radial --preview p.xyz: no map or coefficients may be left",
         lambda f: ["sphere", "radial", "--brdf", "lambert", "--lmax", "2", "--light-profile", "overcast",
                    "--cells", "2x2x2", "-o", f.path("rad.npy"), "--coeffs", f.path("c.npy"),
                    "--preview", f.path("p.xyz")],
         ("--preview", "p.xyz"), ("unsupported file extension",)),
    Case("radial-output-png", "sphere radial -o r.png (the map is .npy data)",
         lambda f: ["sphere", "radial", "--brdf", "lambert", "--lmax", "2", "--light-profile", "overcast",
                    "--cells", "2x2x2", "-o", f.path("r.png")],
         ("-o", "r.png"), (r"\.npy only",)),
    Case("radial-coeffs-xyz", "sphere radial --coeffs c.xyz (the coefficients are .npy data)",
         lambda f: ["sphere", "radial", "--brdf", "lambert", "--lmax", "2", "--light-profile", "overcast",
                    "--cells", "2x2x2", "-o", f.path("rad.npy"), "--coeffs", f.path("c.xyz")],
         ("--coeffs", "c.xyz"), (r"\.npy only",)),
    Case("sphere-sh-output-png", "sphere sh -o sh.png (the coefficients are .npy data)",
         lambda f: ["sphere", "sh", f.npy("env.npy", ENV), "--lmax", "2", "-o", f.path("sh.png")],
         ("-o", "sh.png"), (r"\.npy only",)),
    Case("rotate-output-txt", "sphere rotate -o r.txt (the coefficients are .npy data)",
         lambda f: ["sphere", "rotate", f.npy("c.npy", np.ones((9, 3))), "--zyz", "0.1,0.2,0.3",
                    "-o", f.path("r.txt")],
         ("-o", "r.txt"), (r"\.npy only",)),
    Case("rotate-zhf-degree", "sphere rotate --method zhf at L = 401 (L^4 time: over a minute)",
         lambda f: ["sphere", "rotate", f.npy("c.npy", np.ones((402 ** 2, 1))), "--zyz", "0.1,0.2,0.3",
                    "-o", f.path("r.npy")],
         ("--method zhf", "c.npy"), ("at most L = 400", "--method reference")),
    Case("sphere-filter-raw-overflow", "sphere filter --raw with weights 1e300 (all-inf result)",
         lambda f: ["sphere", "filter", f.npy("env.npy", ENV), "--decomp",
                    f.text("w.json", json.dumps(_sphere_weights(f, 1e300))), "--raw", "-o", f.path("out.exr")],
         ("w.json", "--raw"), ("overflow float32",)),
    Case("sphere-filter-integral-overflow", "sphere filter with weights 1e308 (the integral overflows)",
         lambda f: ["sphere", "filter", f.npy("env.npy", ENV), "--decomp",
                    f.text("w.json", json.dumps(_sphere_weights(f, 1e308))), "-o", f.path("out.exr")],
         ("w.json",), ("integral overflows", "weights are too large", "1e308")),
    Case("sphere-filter-beta-huge", "spherical decomposition with beta[0] = 1e300 (printed short)",
         lambda f: ["sphere", "filter", f.npy("env.npy", ENV), "--decomp",
                    f.text("b.json", json.dumps({**json.loads(f.sphere_decomp().read_text()),
                                                 "beta": [1e300] + json.loads(f.sphere_decomp().read_text())["beta"][1:]})),
                    "-o", f.path("out.exr")],
         ("b.json",), (r"beta\[0\] = 1e300", "does not belong"), forbid=("0000000000",)),
    Case("sphere-filter-direction-not-unit", "spherical decomposition with a lobe direction (1e300, 0, 0)",
         lambda f: ["sphere", "filter", f.npy("env.npy", ENV), "--decomp",
                    f.text("d.json", json.dumps(_sphere_direction(f, [1e300, 0, 0]))), "-o", f.path("out.exr")],
         ("d.json",), (r"\(1e300, 0, 0\)", "not a unit vector"), forbid=("0000000000",)),
    Case("sphere-decompose-max-cond-nan", "sphere decompose --max-cond nan (would switch the guard off)",
         lambda f: ["sphere", "decompose", "vmf:kappa=50", "--lmax", "2", "--max-cond", "nan",
                    "-o", f.path("sd.json")],
         ("--max-cond",), ("finite and at least 1",)),
    Case("sphere-decompose-max-cond-zero", "sphere decompose --max-cond 0",
         lambda f: ["sphere", "decompose", "vmf:kappa=50", "--lmax", "2", "--max-cond", "0",
                    "-o", f.path("sd.json")],
         ("--max-cond",), ("finite and at least 1",)),
    Case("sphere-decompose-cap", "sphere decompose cap:deg=0 (cap is a light profile, not a kernel)",
         lambda f: ["sphere", "decompose", "cap:deg=0", "--lmax", "2", "-o", f.path("sd.json")],
         ("cap:deg=0",), ("unknown kernel", "vmf")),
    Case("eval-tiny-direction", "direction (1e-320, 0, 0) in sphere eval --dirs",
         lambda f: ["sphere", "eval", "--lmax", "2", "--dirs", f.npy("dirs.npy", np.array([[1e-320, 0, 0]])),
                    "-o", f.path("y.npy")],
         ("dirs.npy", "1e-320"), ("too short to normalise",)),
    Case("eval-huge-direction", "direction (1e300, 1e300, 1e300) in sphere eval --dirs",
         lambda f: ["sphere", "eval", "--lmax", "2", "--dirs", f.npy("dirs.npy", np.full((1, 3), 1e300)),
                    "-o", f.path("y.npy")],
         ("dirs.npy", "1e300"), ("overflows",), forbid=("0000000000",)),
    Case("eval-output-png", "sphere eval -o y.png (the values are .npy data)",
         lambda f: ["sphere", "eval", "--lmax", "2", "--dirs", f.npy("dirs.npy", np.eye(3)), "-o", f.path("y.png")],
         ("-o", "y.png"), (r"\.npy only",)),
    Case("brdf-filter-kappa-huge", "sphere brdf-filter --kappa 1e300 (printed short)",
         lambda f: ["sphere", "brdf-filter", "--brdf", "lambert", "--kappa", "1e300", "-o", f.path("x.npy")],
         ("--kappa 1e300",), (r"\[0, 1e6\]",), forbid=("0000000000",)),
    # --- render, envmap, field ---
    Case("render-size", "render --size 100000x100000",
         lambda f: ["render", "--env", f.npy("env.npy", ENV), "--brdf", "lambert", "--lmax", "2",
                    "--size", "100000x100000", "-o", f.path("out.png")],
         ("--size",), ("16384",)),
    Case("render-fov", "render --fov 0",
         lambda f: ["render", "--env", f.npy("env.npy", ENV), "--brdf", "lambert", "--lmax", "2", "--size", "8x8",
                    "--fov", "0", "-o", f.path("out.png")],
         ("--fov",), ("0 < fov < 180",)),
    Case("envmap-face-size", "envmap prefilter --face-size 7",
         lambda f: ["envmap", "prefilter", f.npy("env.npy", ENV), "--face-size", "7", "--out-dir", f.path("ibl")],
         ("--face-size",), ("power of two",)),
    Case("envmap-output-is-file", "envmap prefilter --out-dir a regular file",
         lambda f: ["envmap", "prefilter", f.npy("env.npy", ENV), "--face-size", "8", "--out-dir", f.regular_file()],
         ("afile",), ("not a folder",)),
    Case("dfg-size", "envmap dfg --table-size 0",
         lambda f: ["envmap", "dfg", "--table-size", "0", "-o", f.path("dfg.exr")],
         ("--table-size",), (r"2\.\.=1024",)),
    Case("field-size-zero", "field --size 0x5",
         lambda f: ["field", "swirl", "--size", "0x5", "-o", f.path("angle.npy")],
         ("--size",), ("between 1 and",)),
    Case("field-size-huge", "field --size 65536x65536 (16 GiB; a correct CLI refuses it at once)",
         lambda f: ["field", "swirl", "--size", "65536x65536", "-o", f.path("angle.npy")],
         ("--size",), ("a field may have",), timeout=5),
    Case("field-min-nan", "field --min nan",
         lambda f: ["field", "ramp", "--size", "8x8", "--min", "nan", "-o", f.path("scale.npy")],
         ("--min",), ("finite",)),
    Case("field-output-png", "field -o f.png (angles would be clipped to [0, 1])",
         lambda f: ["field", "swirl", "--size", "8x8", "-o", f.path("f.png")],
         ("-o", "f.png"), (r"\.npy only",)),
    Case("field-min-max-overflow", "field --min -3e38 --max 3e38 (the range overflows float32)",
         lambda f: ["field", "ramp", "--size", "8x8", "--min", "-3e38", "--max", "3e38", "-o", f.path("scale.npy")],
         ("--min", "--max"), ("overflows float32",), forbid=("0000000000",)),
    Case("dfg-size-huge", "envmap dfg --table-size 4096 (hours of quadrature)",
         lambda f: ["envmap", "dfg", "--table-size", "4096", "-o", f.path("dfg.exr")],
         ("--table-size",), (r"2\.\.=1024", "minutes"), timeout=10),
    # --- outputs that cannot be written ---
    Case("out-parent-is-file", "output under a regular file (afile/out.png)",
         lambda f: ["convert", f.image(), f.regular_file() / "out.png"],
         ("afile",), ("not a (folder|directory)",)),
    Case("out-missing-folder", "output folder does not exist",
         lambda f: _filter(f, out="nodir/out.png"),
         ("nodir",), ("does not exist",)),
    Case("out-unknown-extension", "output extension .xyz",
         lambda f: _filter(f, out="out.xyz"),
         ("out.xyz",), ("unsupported file extension",)),
    Case("out-no-extension", "output without an extension",
         lambda f: ["convert", f.image(), f.path("out")],
         ("<tmp>/out",), ("unsupported file extension",)),
    Case("decompose-out-missing-folder", "decompose -o into a missing folder",
         lambda f: ["decompose", "gauss:sx=2,sy=2", "-o", f.path("nodir/d.json")],
         ("nodir",), ("does not exist",)),
    Case("brdf-out-parent-is-file", "sphere brdf -o under a regular file",
         lambda f: ["sphere", "brdf", "ggx:alpha=0.3", "--lmax", "4", "-o", f.regular_file() / "t.lobes"],
         ("afile",), ("not a (folder|directory)",)),
]

# One row per case that ran: (command, what is wrong, exit code, first line of stderr).
ROWS: dict[str, tuple[str, str, str, str]] = {}


@pytest.fixture(scope="module")
def sphere_decomp(run_ifd, tmp_path_factory) -> pathlib.Path:
    p = tmp_path_factory.mktemp("sphere") / "sd.json"
    run_ifd("sphere", "decompose", "vmf:kappa=50", "--lmax", "2", "-o", p)
    return p


@pytest.fixture(scope="module", autouse=True)
def bad_input_doc():
    """Writes docs/bad-input.md after the module, when every case produced a row."""
    yield
    if all(c.id in ROWS for c in CASES):
        DOC.write_text(_doc())


def _listing(folder: pathlib.Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


def _shorten(text: str, folder: pathlib.Path) -> str:
    return text.replace(str(folder), "<tmp>").replace(str(TESTDATA), "testdata")


def _repeated_clause(line: str) -> str | None:
    """A clause (between ': ') said twice in a row, as when an error's cause is printed twice."""
    parts = [p.strip() for p in line.split(": ")]
    for a, b in zip(parts, parts[1:]):
        if a == b and len(a) > 8:
            return a
    return None


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_input(case, ifd_bin, tmp_path, sphere_decomp):
    files = Files(tmp_path, sphere_decomp)
    args = [str(a) for a in case.build(files)]
    before = _listing(tmp_path)
    # The binary is resolved (IFD_BIN may be relative); the run happens in the case's folder.
    command = [str(pathlib.Path(ifd_bin).resolve()), *args]
    try:
        p = subprocess.run(command, capture_output=True, text=True, timeout=case.timeout, cwd=tmp_path)
        code, stderr = str(p.returncode), p.stderr
    except subprocess.TimeoutExpired as e:  # a hang: the process was killed
        err = e.stderr or b""
        code = f"killed after {case.timeout:g} s"
        stderr = err.decode(errors="replace") if isinstance(err, bytes) else err
    new = sorted(_listing(tmp_path) - before)
    first = stderr.strip().splitlines()[0] if stderr.strip() else "(nothing on stderr)"
    ROWS[case.id] = (_shorten("ifd " + " ".join(args), tmp_path), case.what, code, _shorten(first, tmp_path))

    # Names and words are looked for with the folder shortened, as the folder's name holds the case's.
    said = _shorten(stderr, tmp_path)
    problems = []
    if code != "2":
        problems.append(f"exit code {code}, expected 2")
    for name in case.names:
        if name not in said:
            problems.append(f"the message does not name {name!r}")
    for word in case.problem:
        if not re.search(word, said, re.IGNORECASE):
            problems.append(f"the message does not say /{word}/")
    for pattern, why in [*FORBIDDEN.items(), *((w, f"/{w}/") for w in case.forbid)]:
        if re.search(pattern, said):
            problems.append(f"the message contains {why}")
    if (clause := _repeated_clause(first)) is not None:
        problems.append(f"the message says {clause!r} twice")
    if new:
        problems.append(f"files left behind: {new}")
    assert not problems, f"ifd {' '.join(args)}\n" + "\n".join(problems) + f"\nstderr:\n{stderr}"


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def _doc() -> str:
    lines = [
        "# Bad input: what the CLI says",
        "",
        "Generated by `tests/python/test_bad_input.py` (do not edit by hand): every row is one bad",
        "invocation of `ifd`, run by the test, with the exit code and the first line of the message it",
        "printed. Every error must exit with code 2 (101 would be a panic) with a message naming the",
        "file or option and the problem, write nothing, and leave no temporary file; the test fails on",
        "any row that does not. `<tmp>` is the case's scratch folder.",
        "",
        "Regenerate it with",
        "",
        "```sh",
        "IFD_BIN=target/debug/ifd .venv/bin/python -m pytest -q -p no:cacheprovider tests/python/test_bad_input.py",
        "```",
        "",
        "| command | what is wrong | exit code | message |",
        "|---|---|---|---|",
    ]
    for c in CASES:
        command, what, code, message = ROWS[c.id]
        message = message.replace("<", "&lt;").replace(">", "&gt;")
        lines.append(f"| `{_cell(command)}` | {_cell(what)} | {code} | {_cell(message)} |")
    return "\n".join(lines) + "\n"


def test_a_closed_or_full_standard_output_is_not_a_panic(ifd_bin):
    """`ifd info FILE | head -1` (the reader gone) ends quietly with SIGPIPE's
    status; a full disk is one error line and status 2; neither panics."""
    p = subprocess.run(f"'{ifd_bin}' info '{TESTDATA / 'forest.hdr'}' | true; "
                       "echo rc=${PIPESTATUS[0]}", shell=True, executable="/bin/bash",
                       capture_output=True, text=True)
    assert "rc=141" in p.stdout and "panicked" not in p.stderr, p
    with open("/dev/full", "w") as full:
        p = subprocess.run([str(ifd_bin), "info", str(TESTDATA / "forest.hdr")], stdout=full,
                           stderr=subprocess.PIPE, text=True)
    assert p.returncode == 2, p.stderr
    assert "error: writing to standard output" in p.stderr and "panicked" not in p.stderr
