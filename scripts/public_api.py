#!/usr/bin/env python3
"""The public surface of each library crate, from rustdoc's JSON output.

For every library crate of the workspace, runs
`cargo rustdoc -p CRATE --lib -- -Z unstable-options --output-format json`
(stable toolchain, RUSTC_BOOTSTRAP=1, as the fuzzing does) and walks the
module tree from the crate root the way a user reaches items: public modules
and public re-exports (`pub use`), recursively. Every reachable path is one
line, `path kind` (a struct reachable by two paths is two lines: the list
shows where an API offers two ways to the same thing), with the public
inherent methods of structs, enums and traits as `Type::method function`,
public fields as `Type::field struct_field` and variants as `Enum::Variant
variant`.

Usage:
  scripts/public_api.py            compare with docs/reference/api/CRATE.txt
  scripts/public_api.py --bless    rewrite those files
Exit 1 when a crate's surface differs from its checked-in list, printing the
lines added and removed: a change to a public API is then a deliberate
change to that file, reviewed with the code.
"""

import functools
import json
import os
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
OUT = ROOT / "docs" / "reference" / "api"
# crates whose surface is listed (the libraries others build on); ifd-py's is
# Python's (its stubs), ifd-clidoc is dev-only and ifd-paper the studies'; ifd-app is the
# apps' shell
CRATES = [
    "ifd-simd", "ifd-image", "ifd-planar", "ifd-smooth", "ifd-sphere", "ifd-shade",
    "ifd-render", "ifd-ibl", "ifd-gpu", "ifd-plot", "ifd-app",
]


@functools.cache
def target_dir():
    meta = subprocess.run(
        ["cargo", "metadata", "--format-version", "1", "--no-deps"],
        cwd=ROOT, check=True, capture_output=True, text=True,
    )
    return pathlib.Path(json.loads(meta.stdout)["target_directory"])


def rustdoc_json(crate):
    # a target folder of its own: RUSTC_BOOTSTRAP changes what cargo
    # fingerprints, and would rebuild the main target folder each time
    target = target_dir() / "api-json"
    env = dict(os.environ, RUSTC_BOOTSTRAP="1", CARGO_TARGET_DIR=str(target))
    subprocess.run(
        ["cargo", "rustdoc", "-q", "-p", crate, "--lib", "--",
         "-Z", "unstable-options", "--output-format", "json"],
        cwd=ROOT, check=True, env=env,
    )
    path = target / "doc" / (crate.replace("-", "_") + ".json")
    return json.loads(path.read_text())


def kind_of(item):
    inner = item.get("inner", {})
    return next(iter(inner)) if isinstance(inner, dict) and inner else str(inner)


def surface(doc):
    index = doc["index"]
    root = index[str(doc["root"])]
    lines = set()

    def public(item):
        return item.get("visibility") == "public"

    def methods(path, item):
        inner = item["inner"]
        k = kind_of(item)
        ids = []
        if k in ("struct", "enum", "union"):
            ids = inner[k].get("impls", [])
        members = []
        if k == "struct":
            kind = inner["struct"].get("kind", {})
            if isinstance(kind, dict) and "plain" in kind:
                members = kind["plain"].get("fields", [])
        elif k == "enum":
            members = inner["enum"].get("variants", [])
        for fid in members:
            f = index.get(str(fid))
            if f and f.get("name") and (k == "enum" or public(f)):
                lines.add(f"{path}::{f['name']} {kind_of(f)}")
        for impl_id in ids:
            impl = index.get(str(impl_id))
            if not impl:
                continue
            body = impl["inner"]["impl"]
            if body.get("trait") is not None or body.get("synthetic") or body.get("blanket_impl"):
                continue
            for mid in body.get("items", []):
                m = index.get(str(mid))
                if m and public(m) and m.get("name"):
                    lines.add(f"{path}::{m['name']} {kind_of(m)}")
        if k == "trait":
            for mid in inner["trait"].get("items", []):
                m = index.get(str(mid))
                if m and m.get("name"):
                    lines.add(f"{path}::{m['name']} {kind_of(m)}")

    def walk(module, prefix, seen):
        for iid in module["inner"]["module"]["items"]:
            item = index.get(str(iid))
            if item is None or not public(item):
                continue
            k = kind_of(item)
            if k == "use":
                use = item["inner"]["use"]
                target = index.get(str(use.get("id"))) if use.get("id") is not None else None
                if use.get("is_glob"):
                    if target and kind_of(target) == "module" and use["id"] not in seen:
                        walk(target, prefix, seen | {use["id"]})
                    continue
                name = use["name"]
                if target is None:
                    lines.add(f"{prefix}::{name} use (external {use['source']})")
                    continue
                emit(target, f"{prefix}::{name}", seen, use["id"])
                continue
            emit(item, f"{prefix}::{item['name']}", seen, iid)

    def emit(item, path, seen, iid):
        k = kind_of(item)
        if k == "impl":
            return
        lines.add(f"{path} {k}")
        if k == "module" and iid not in seen:
            walk(item, path, seen | {iid})
        else:
            methods(path, item)

    walk(root, root["name"], {doc["root"]})
    return sorted(lines)


def main():
    bless = "--bless" in sys.argv[1:]
    OUT.mkdir(parents=True, exist_ok=True)
    changed = 0
    for crate in CRATES:
        lines = surface(rustdoc_json(crate))
        text = "\n".join(lines) + "\n"
        path = OUT / f"{crate}.txt"
        if bless:
            path.write_text(text)
            print(f"{path.relative_to(ROOT)}: {len(lines)} public paths")
            continue
        old = path.read_text().splitlines() if path.is_file() else []
        added = sorted(set(lines) - set(old))
        removed = sorted(set(old) - set(lines))
        if added or removed:
            changed += 1
            print(f"{crate}: the public API changed ({path.relative_to(ROOT)}):")
            for line in added:
                print(f"  + {line}")
            for line in removed:
                print(f"  - {line}")
        else:
            print(f"ok: {crate}, {len(lines)} public paths")
    if changed:
        print(f"{changed} crates changed their public API: if deliberate, run "
              "scripts/public_api.py --bless and commit the lists")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
