"""glTF 2.0 test assets, written with numpy and the standard library only.

    python tests/python/gltf_assets.py OUTDIR

writes into OUTDIR (created if missing):

- ``spheres.gltf`` (+ ``spheres.bin``) and ``spheres.glb``: a 5 x 5 grid of UV
  spheres (radius ``SPHERE_RADIUS``, 32 x 16 segments, poles along +y) as the
  MetalRoughSpheres sample does. Column ``j`` (x = ``(j - 2) * SPACING``) has
  roughness ``ROUGHNESS[j]`` (rougher to the right), row ``i`` (y = ``(i - 2) *
  SPACING``) has metallic ``METALLIC[i]`` (more metallic upwards); every sphere
  has its own material (base colour factor ``BASE_COLOR``, no textures; its
  factors are repeated in the material's ``extras``) and its own mesh, the 25
  meshes sharing one set of accessors (indexed triangles, POSITION, NORMAL,
  TEXCOORD_0). The sphere nodes are children of a root node ``grid``; a
  perspective camera node looks at the grid down -z. A default scene.
- ``textured.gltf`` (+ ``textured.bin`` and four PNG files) and ``textured.glb``
  (buffer and PNGs in the binary chunk, images through bufferViews): one
  material ``textured`` with every metallic-roughness input: base colour
  texture (sRGB checker with a gradient), metallicRoughness texture (linear,
  G = roughness, B = metal, R = 0), a tangent-space normal texture of raised
  round bumps with ``scale`` ``NORMAL_SCALE``, an occlusion texture (8-bit
  grey PNG, read as R) with ``strength`` ``OCCLUSION_STRENGTH``, emissive factor
  and texture. One sampler (wrapS REPEAT, wrapT MIRRORED_REPEAT, trilinear):
  texture coordinates leave [0, 1] (the sphere's u runs over [0, 2], the
  floor's over [-1, 2]) so wrapping matters. Used by two meshes:
  * ``ellipsoid``: a 64 x 32 UV sphere, indexed, on a node with a rotation
    (quaternion ``ELLIPSOID_ROTATION``) and a non-uniform scale
    (``ELLIPSOID_SCALE``: normals need the inverse transpose);
  * ``floor``: a quad in the xz plane facing +y made of 2 triangles **without
    indices** (the non-indexed path), on a translated node.
  No primitive has a TANGENT attribute: a renderer must generate MikkTSpace
  tangents for the normal map. No camera (a viewer must frame the asset).

Conventions written into the assets (what a renderer must do with them):
- Normal texture: glTF's (OpenGL's) tangent space, +x along +u, +y "up" in the
  image (towards smaller v, since glTF's v runs down the image), +z out of the
  surface; bumps are raised (a renderer that flips green shows dimples).
- Everything is deterministic: the same bytes on every run (the PNGs are
  written here with zlib at a fixed level, no timestamps; JSON with fixed key
  order).

Layout details the Khronos validator checks (``tests/js/validate_gltf.mjs``):
one bufferView per accessor, each starting on a 4-byte boundary with its
target (ARRAY_BUFFER / ELEMENT_ARRAY_BUFFER), image bufferViews with no
target; POSITION has exact ``min``/``max`` (of the float32 values); indices are
UNSIGNED_SHORT; buffers are padded to a multiple of 4 so the GLB BIN chunk
carries no extra padding beyond ``byteLength``; the GLB JSON chunk is padded
with spaces, the BIN chunk with zeros.
"""

from __future__ import annotations

import json
import math
import pathlib
import struct
import sys
import zlib

import numpy as np

# --- the sphere grid -------------------------------------------------------
METALLIC = (0.0, 0.25, 0.5, 0.75, 1.0)
ROUGHNESS = (0.1, 0.3, 0.5, 0.75, 1.0)
BASE_COLOR = (0.9, 0.6, 0.3, 1.0)
SPHERE_RADIUS = 0.4
SPACING = 1.0
SPHERE_SEGMENTS = (32, 16)  # around (longitude), pole to pole (latitude)
CAMERA_YFOV = 0.6
CAMERA_Z = 9.0

# --- the textured asset ----------------------------------------------------
NORMAL_SCALE = 0.8
OCCLUSION_STRENGTH = 0.7
EMISSIVE_FACTOR = (1.0, 0.6, 0.2)
ELLIPSOID_SEGMENTS = (64, 32)
ELLIPSOID_SCALE = (1.2, 0.9, 1.0)
ELLIPSOID_TRANSLATION = (0.0, 0.2, 0.0)
FLOOR_TRANSLATION = (0.0, -1.0, 0.0)
FLOOR_HALF = 2.0
TEXTURE_SIZE = 256

GENERATOR = "ifd tests/python/gltf_assets.py"

# glTF enums
FLOAT, UNSIGNED_SHORT = 5126, 5123
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
LINEAR, LINEAR_MIPMAP_LINEAR = 9729, 9987
REPEAT, MIRRORED_REPEAT = 10497, 33648


def _axis_angle_quat(axis, angle):
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    s = math.sin(angle / 2)
    return (float(a[0] * s), float(a[1] * s), float(a[2] * s), math.cos(angle / 2))


# 35 degrees about a tilted axis: (x, y, z, w), unit to float64 precision
ELLIPSOID_ROTATION = _axis_angle_quat((1.0, 0.5, 0.25), math.radians(35.0))


# --- geometry --------------------------------------------------------------
def uv_sphere(radius, n_lon, n_lat, u_repeat=1.0):
    """A UV sphere with poles on +-y: (positions, normals, uvs, indices), float32
    and uint16. Vertices on a (n_lat + 1) x (n_lon + 1) grid (the seam column
    duplicated for its texture coordinates); u = u_repeat * lon / (2 pi), v =
    polar angle / pi (v = 0 at +y, glTF's top-left origin). Counter-clockwise
    seen from outside; the pole rows give one triangle per segment (no
    degenerate triangles)."""
    lat = np.arange(n_lat + 1) / n_lat * math.pi  # 0 at +y
    lon = np.arange(n_lon + 1) / n_lon * 2 * math.pi
    t, p = np.meshgrid(lat, lon, indexing="ij")
    # longitude 0 at +z, a quarter turn at +x; the winding is fixed below
    # against the outward normal
    n = np.stack([np.sin(t) * np.sin(p), np.cos(t), np.sin(t) * np.cos(p)], axis=-1)
    n[0, :] = (0.0, 1.0, 0.0)
    n[-1, :] = (0.0, -1.0, 0.0)
    uv = np.stack([u_repeat * p / (2 * math.pi), t / math.pi], axis=-1)
    idx = []
    w = n_lon + 1
    for i in range(n_lat):
        for j in range(n_lon):
            a, b = i * w + j, i * w + j + 1
            c, d = (i + 1) * w + j, (i + 1) * w + j + 1
            if i != 0:
                idx.append((a, c, b))
            if i != n_lat - 1:
                idx.append((b, c, d))
    idx = np.asarray(idx, dtype=np.int64)
    pos = (radius * n).reshape(-1, 3)
    nrm = n.reshape(-1, 3)
    # winding: the face normal points outwards
    e1 = pos[idx[:, 1]] - pos[idx[:, 0]]
    e2 = pos[idx[:, 2]] - pos[idx[:, 0]]
    fn = np.cross(e1, e2)
    centre = pos[idx].mean(axis=1)
    if np.all(np.einsum("ij,ij->i", fn, centre) < 0):
        idx = idx[:, [0, 2, 1]]
    fn = np.cross(pos[idx[:, 1]] - pos[idx[:, 0]], pos[idx[:, 2]] - pos[idx[:, 0]])
    assert np.all(np.einsum("ij,ij->i", fn, centre) > 0), "inconsistent winding"
    assert pos.shape[0] < 65536
    return (pos.astype(np.float32), nrm.astype(np.float32), uv.reshape(-1, 2).astype(np.float32),
            idx.reshape(-1).astype(np.uint16))


def floor_quad(half):
    """Two triangles, no indices: a square in the xz plane facing +y,
    counter-clockwise seen from above; uv over [-1, 2]^2 (u along +x, v along
    +z)."""
    corners = np.array([[-half, 0, -half], [half, 0, -half], [half, 0, half], [-half, 0, half]])
    uvs = np.array([[-1, -1], [2, -1], [2, 2], [-1, 2]], dtype=np.float64)
    tri = [0, 2, 1, 0, 3, 2]
    pos = corners[tri]
    fn = np.cross(pos[1] - pos[0], pos[2] - pos[0])
    assert fn[1] > 0
    nrm = np.tile([0.0, 1.0, 0.0], (6, 1))
    return pos.astype(np.float32), nrm.astype(np.float32), uvs[tri].astype(np.float32)


# --- images ----------------------------------------------------------------
def png_bytes(img):
    """An 8-bit PNG (grey (H, W) or RGB (H, W, 3) uint8) with zlib level 9:
    deterministic (no time or text chunks)."""
    img = np.ascontiguousarray(img, dtype=np.uint8)
    h, w = img.shape[:2]
    colour = 0 if img.ndim == 2 else 2
    raw = b"".join(b"\x00" + img[r].tobytes() for r in range(h))

    def chunk(kind, data):
        c = struct.pack(">I", len(data)) + kind + data
        return c + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", w, h, 8, colour, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr)
            + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def _grid(n):
    c = (np.arange(n) + 0.5) / n
    return np.meshgrid(c, c)  # x along columns (u), y along rows (v, down)


def _bump_height(n, cells=8, radius=0.35):
    """Raised round bumps, one per cell: h(x, y) in texture units and its
    derivatives (dh/du, dh/dv) per unit of u and v."""
    x, y = _grid(n)
    fx, fy = (x * cells) % 1.0 - 0.5, (y * cells) % 1.0 - 0.5
    r2 = (fx * fx + fy * fy) / (radius * radius)
    inside = r2 < 1
    # a smooth cosine bump: h = A (1 + cos(pi r)) / 2, zero slope at the rim
    r = np.sqrt(np.where(inside, r2, 0.0))
    amp = 0.04
    h = np.where(inside, amp * 0.5 * (1 + np.cos(math.pi * r)), 0.0)
    dh_dr = np.where(inside, -amp * 0.5 * math.pi * np.sin(math.pi * r), 0.0)
    rr = np.where(r > 0, r, 1.0)
    # r = |f| / radius with f = (frac(u cells) - 0.5, ...): dr/du = fx cells / (radius^2 r)
    dh_du = np.where(r > 0, dh_dr * fx * cells / (radius * radius * rr), 0.0)
    dh_dv = np.where(r > 0, dh_dr * fy * cells / (radius * radius * rr), 0.0)
    return h, dh_du, dh_dv


def textures(n=TEXTURE_SIZE):
    """The four textures as uint8 arrays: base colour (sRGB RGB),
    metallicRoughness (RGB: R 0, G roughness, B metal), normal (RGB) and
    occlusion (grey), plus emissive (sRGB RGB)."""
    x, y = _grid(n)
    checker = ((np.floor(x * 8) + np.floor(y * 8)) % 2).astype(np.float64)
    base = np.stack([
        0.25 + 0.7 * x,
        0.3 + 0.5 * checker,
        0.85 - 0.6 * y,
    ], axis=-1)
    base = np.where(checker[..., None] > 0, base, 0.15 + 0.2 * base)
    # metal: the checker's light squares; roughness: a gradient along u, 0.15..0.95
    rough = 0.15 + 0.8 * x
    metal = checker
    mr = np.stack([np.zeros_like(x), rough, metal], axis=-1)
    # tangent-space normal: surface z = s h(u, v) seen with x = +u, y = image up = -v:
    # n ~ (-dh/dx, -dh/dy, 1) = (-dh/du, +dh/dv, 1)
    _, du, dv = _bump_height(n)
    nrm = np.stack([-du, dv, np.ones_like(du)], axis=-1)
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    nrm_u8 = np.round((nrm * 0.5 + 0.5) * 255)
    # occlusion: darker in the creases around the bumps and towards the bottom
    h, _, _ = _bump_height(n)
    occ = 1.0 - 0.5 * (h == 0) * (0.3 + 0.7 * y)
    # emissive: a few glowing dots
    fx, fy = (x * 4) % 1.0 - 0.5, (y * 4) % 1.0 - 0.5
    dot = np.clip(1 - (fx * fx + fy * fy) / 0.02, 0, 1) * ((np.floor(x * 4) + np.floor(y * 4)) % 3 == 0)
    emis = np.stack([dot, dot, dot], axis=-1)

    def u8(a):
        return np.clip(np.round(np.asarray(a) * 255), 0, 255).astype(np.uint8)

    return {
        "basecolor": u8(base),
        "metallic_roughness": u8(mr),
        "normal": nrm_u8.astype(np.uint8),
        "occlusion": u8(occ),
        "emissive": u8(emis),
    }


# --- the glTF document builder ---------------------------------------------
class Builder:
    """Accumulates one binary buffer and the JSON arrays that describe it."""

    def __init__(self):
        self.bin = bytearray()
        self.doc = {
            "asset": {"version": "2.0", "generator": GENERATOR},
            "scene": 0,
            "scenes": [],
            "nodes": [],
            "meshes": [],
            "materials": [],
            "accessors": [],
            "bufferViews": [],
            "buffers": [],
        }

    def _align(self):
        while len(self.bin) % 4:
            self.bin.append(0)

    def view(self, data: bytes, target=None):
        self._align()
        v = {"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)}
        if target is not None:
            v["target"] = target
        self.bin += data
        self._align()
        self.doc["bufferViews"].append(v)
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, arr, target, minmax=False):
        arr = np.ascontiguousarray(arr)
        if arr.dtype == np.float32:
            ctype = FLOAT
        elif arr.dtype == np.uint16:
            ctype = UNSIGNED_SHORT
        else:
            raise TypeError(arr.dtype)
        kind = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4"}[1 if arr.ndim == 1 else arr.shape[1]]
        bv = self.view(arr.astype(arr.dtype.newbyteorder("<")).tobytes(), target)
        a = {"bufferView": bv, "byteOffset": 0, "componentType": ctype,
             "count": int(arr.shape[0]), "type": kind}
        if minmax:
            a["min"] = [float(x) for x in np.atleast_1d(arr.min(axis=0))]
            a["max"] = [float(x) for x in np.atleast_1d(arr.max(axis=0))]
        self.doc["accessors"].append(a)
        return len(self.doc["accessors"]) - 1

    def attributes(self, pos, nrm, uv):
        return {
            "POSITION": self.accessor(pos, ARRAY_BUFFER, minmax=True),
            "NORMAL": self.accessor(nrm, ARRAY_BUFFER),
            "TEXCOORD_0": self.accessor(uv, ARRAY_BUFFER),
        }

    def add(self, key, obj):
        self.doc.setdefault(key, []).append(obj)
        return len(self.doc[key]) - 1

    def finish(self, bin_uri):
        """(gltf_json_dict, glb_json_dict, bin_bytes): the same document with
        an external buffer (``bin_uri``) and with the GLB-stored buffer."""
        self._align()
        data = bytes(self.bin)
        gltf = json.loads(json.dumps(self.doc))
        glb = json.loads(json.dumps(self.doc))
        gltf["buffers"] = [{"uri": bin_uri, "byteLength": len(data)}]
        glb["buffers"] = [{"byteLength": len(data)}]
        return gltf, glb, data


def glb_bytes(doc, binary: bytes) -> bytes:
    """A GLB container: 12-byte header, JSON chunk padded with spaces, BIN
    chunk padded with zeros."""
    js = json.dumps(doc, separators=(",", ":")).encode("utf-8")
    js += b" " * (-len(js) % 4)
    binary = binary + b"\x00" * (-len(binary) % 4)
    total = 12 + 8 + len(js) + 8 + len(binary)
    return (struct.pack("<4sII", b"glTF", 2, total)
            + struct.pack("<I4s", len(js), b"JSON") + js
            + struct.pack("<I4s", len(binary), b"BIN\x00") + binary)


def gltf_text(doc) -> bytes:
    return (json.dumps(doc, indent=1) + "\n").encode("utf-8")


# --- the two assets ----------------------------------------------------------
def sphere_grid():
    """The grid's layout: a list of dicts (row, col, metallic, roughness,
    translation), row-major."""
    out = []
    for i, m in enumerate(METALLIC):
        for j, r in enumerate(ROUGHNESS):
            out.append({"row": i, "col": j, "metallic": m, "roughness": r,
                        "translation": [(j - 2) * SPACING, (i - 2) * SPACING, 0.0]})
    return out


def build_spheres():
    """(files): {name: bytes} for spheres.gltf, spheres.bin, spheres.glb."""
    b = Builder()
    pos, nrm, uv, idx = uv_sphere(SPHERE_RADIUS, *SPHERE_SEGMENTS)
    attrs = b.attributes(pos, nrm, uv)
    ind = b.accessor(idx, ELEMENT_ARRAY_BUFFER)
    children = []
    for s in sphere_grid():
        name = f"sphere_m{s['metallic']}_r{s['roughness']}"
        mat = b.add("materials", {
            "name": name,
            "pbrMetallicRoughness": {
                "baseColorFactor": list(BASE_COLOR),
                "metallicFactor": s["metallic"],
                "roughnessFactor": s["roughness"],
            },
            "extras": {"metallic": s["metallic"], "roughness": s["roughness"],
                       "row": s["row"], "col": s["col"]},
        })
        mesh = b.add("meshes", {"name": name, "primitives": [
            {"attributes": dict(attrs), "indices": ind, "material": mat, "mode": 4}]})
        children.append(b.add("nodes", {"name": name, "mesh": mesh,
                                        "translation": s["translation"]}))
    grid = b.add("nodes", {"name": "grid", "children": children})
    cam = b.add("cameras", {"name": "front", "type": "perspective", "perspective": {
        "aspectRatio": 1.0, "yfov": CAMERA_YFOV, "znear": 0.1, "zfar": 100.0}})
    cam_node = b.add("nodes", {"name": "camera", "camera": cam, "translation": [0.0, 0.0, CAMERA_Z]})
    b.doc["scenes"].append({"name": "metal_rough_spheres", "nodes": [grid, cam_node]})
    gltf, glb, data = b.finish("spheres.bin")
    return {
        "spheres.gltf": gltf_text(gltf),
        "spheres.bin": data,
        "spheres.glb": glb_bytes(glb, data),
    }


IMAGE_FILES = {
    "basecolor": "textured_basecolor.png",
    "metallic_roughness": "textured_metallic_roughness.png",
    "normal": "textured_normal.png",
    "occlusion": "textured_occlusion.png",
    "emissive": "textured_emissive.png",
}


def build_textured():
    """{name: bytes} for textured.gltf, textured.bin, the PNGs, textured.glb."""
    b = Builder()
    pos, nrm, uv, idx = uv_sphere(1.0, *ELLIPSOID_SEGMENTS, u_repeat=2.0)
    e_attrs = b.attributes(pos, nrm, uv)
    e_ind = b.accessor(idx, ELEMENT_ARRAY_BUFFER)
    f_attrs = b.attributes(*floor_quad(FLOOR_HALF))
    geometry_end = len(b.bin)

    pngs = {k: png_bytes(v) for k, v in textures().items()}
    sampler = b.add("samplers", {"magFilter": LINEAR, "minFilter": LINEAR_MIPMAP_LINEAR,
                                 "wrapS": REPEAT, "wrapT": MIRRORED_REPEAT})
    tex = {}
    image_views = {}
    for key in IMAGE_FILES:
        # the images' bytes go after the geometry (only the GLB refers to them)
        image_views[key] = b.view(pngs[key])
        img = b.add("images", {"name": key, "mimeType": "image/png", "bufferView": image_views[key]})
        tex[key] = b.add("textures", {"name": key, "sampler": sampler, "source": img})
    mat = b.add("materials", {
        "name": "textured",
        "pbrMetallicRoughness": {
            "baseColorFactor": [1.0, 1.0, 1.0, 1.0],
            "baseColorTexture": {"index": tex["basecolor"], "texCoord": 0},
            "metallicFactor": 1.0,
            "roughnessFactor": 1.0,
            "metallicRoughnessTexture": {"index": tex["metallic_roughness"]},
        },
        "normalTexture": {"index": tex["normal"], "scale": NORMAL_SCALE},
        "occlusionTexture": {"index": tex["occlusion"], "strength": OCCLUSION_STRENGTH},
        "emissiveTexture": {"index": tex["emissive"]},
        "emissiveFactor": list(EMISSIVE_FACTOR),
    })
    ell = b.add("meshes", {"name": "ellipsoid", "primitives": [
        {"attributes": e_attrs, "indices": e_ind, "material": mat}]})
    flo = b.add("meshes", {"name": "floor", "primitives": [
        {"attributes": f_attrs, "material": mat, "mode": 4}]})
    n_ell = b.add("nodes", {"name": "ellipsoid", "mesh": ell,
                            "rotation": list(ELLIPSOID_ROTATION),
                            "scale": list(ELLIPSOID_SCALE),
                            "translation": list(ELLIPSOID_TRANSLATION)})
    n_flo = b.add("nodes", {"name": "floor", "mesh": flo, "translation": list(FLOOR_TRANSLATION)})
    b.doc["scenes"].append({"name": "textured", "nodes": [n_ell, n_flo]})
    _, glb, data = b.finish("textured.bin")

    # the .gltf: the geometry only in textured.bin, the images as files
    gltf = json.loads(json.dumps(glb))
    gltf["bufferViews"] = gltf["bufferViews"][:min(image_views.values())]
    gltf["buffers"] = [{"uri": "textured.bin", "byteLength": geometry_end}]
    for img, key in zip(gltf["images"], IMAGE_FILES):
        del img["bufferView"], img["mimeType"]
        img["uri"] = IMAGE_FILES[key]
    files = {
        "textured.gltf": gltf_text(gltf),
        "textured.bin": data[:geometry_end],
        "textured.glb": glb_bytes(glb, data),
    }
    for key, name in IMAGE_FILES.items():
        files[name] = pngs[key]
    return files


def build_all():
    """Every file, {name: bytes}, in a fixed order."""
    return {**build_spheres(), **build_textured()}


ASSETS = ("spheres.gltf", "spheres.glb", "textured.gltf", "textured.glb")


def write_all(outdir) -> list[pathlib.Path]:
    """Writes every file into ``outdir``; returns the four asset paths."""
    out = pathlib.Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    for name, data in build_all().items():
        (out / name).write_bytes(data)
    return [out / a for a in ASSETS]


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1:
        print("usage: python tests/python/gltf_assets.py OUTDIR", file=sys.stderr)
        return 2
    for p in write_all(argv[0]):
        print(p)
    return 0


if __name__ == "__main__":
    sys.exit(main())
