#!/usr/bin/env python3
"""Checks that ARCHITECTURE.md still describes the code.

1. The dependency table ("The exact edges") equals the ifd crates in each
   manifest's [dependencies] (and target-specific dependencies).
2. Every module of every crate (each `src/**.rs` file other than lib.rs,
   main.rs and mod.rs, and each module folder) is named in its crate's
   code-map section, as `name`, `name.rs`, `name/` or inside a path or item
   path in backticks (`stack/gather.rs`, `render::Job`).
3. The list under "## Unsafe code" names exactly the Rust files that contain
   an `unsafe` block, function or impl.

Module cycles are `scripts/module_cycles.py`'s. Usage:
scripts/check_architecture.py (exit 1 with one line per problem).
"""

import pathlib
import re
import sys
import tomllib

ROOT = pathlib.Path(__file__).resolve().parent.parent
DOC = ROOT / "ARCHITECTURE.md"


def manifest_of(name):
    """The Cargo.toml of a crate as the table names it."""
    if name == "ifd":
        return ROOT / "Cargo.toml"
    if name.startswith("apps/"):
        return ROOT / name / "Cargo.toml"
    return ROOT / "crates" / name / "Cargo.toml"


def ifd_dependencies(manifest):
    data = tomllib.loads(manifest.read_text())
    deps = set(data.get("dependencies", {}))
    for target in data.get("target", {}).values():
        deps |= set(target.get("dependencies", {}))
    return {d for d in deps if d.startswith("ifd-")}


def check_table(doc, problems):
    rows = re.findall(r"^\| `([^`]+)`( \(facade\))? \| (.*) \|$", doc, re.M)
    if not rows:
        problems.append("ARCHITECTURE.md: no dependency table found")
    named = set()
    for name, _, deps in rows:
        named.add(name)
        manifest = manifest_of(name)
        if not manifest.is_file():
            problems.append(f"dependency table: `{name}` has no {manifest.relative_to(ROOT)}")
            continue
        listed = set(re.findall(r"`(ifd-[a-z]+)`", deps))
        actual = ifd_dependencies(manifest)
        for d in sorted(actual - listed):
            problems.append(f"dependency table: `{name}` depends on `{d}` (not listed)")
        for d in sorted(listed - actual):
            problems.append(f"dependency table: `{name}` lists `{d}`, which its manifest lacks")
    for manifest in sorted(list((ROOT / "crates").glob("*/Cargo.toml"))
                           + list((ROOT / "apps").glob("*/Cargo.toml"))):
        d = manifest.parent
        name = d.name if d.parent.name == "crates" else f"apps/{d.name}"
        if name not in named:
            problems.append(f"dependency table: `{name}` is missing")


def sections(doc):
    """Code-map sections: the crate folders each `### ` heading names, and its text."""
    out = []
    parts = re.split(r"^### (.*)$", doc, flags=re.M)
    for heading, body in zip(parts[1::2], parts[2::2]):
        body = body.split("\n## ")[0]
        folders = re.findall(r"`((?:crates|apps)/[a-z0-9-]+|src/)`", heading)
        out.append((folders, body))
    return out


def modules(src):
    """Module names of a crate's source folder."""
    names = set()
    for f in src.rglob("*.rs"):
        rel = f.relative_to(src)
        for folder in rel.parts[:-1]:
            names.add(folder)
        if f.stem not in ("lib", "main", "mod"):
            names.add(f.stem)
    return names


def is_command(src, name):
    """Whether `name` is a module under the CLI's `commands/` tree only."""
    hits = [f for f in src.rglob("*.rs") if name in f.relative_to(src).with_suffix("").parts]
    return bool(hits) and all(f.relative_to(src).parts[0] == "commands" for f in hits)


def tokens(text):
    words = set()
    for t in re.findall(r"`([^`]+)`", text):
        words |= set(re.split(r"[^A-Za-z0-9_]+", t))
    return words


def check_code_map(doc, problems):
    covered = set()
    for folders, body in sections(doc):
        words = tokens(body)
        for folder in folders:
            covered.add(folder)
            src = ROOT / folder if folder == "src/" else ROOT / folder / "src"
            for m in sorted(modules(src)):
                if m == "error":
                    continue  # the convention stated at the top of the code map
                if folder == "apps/ifd-cli" and is_command(src, m):
                    continue  # commands/: the command names its file
                if m not in words:
                    problems.append(f"code map: {folder} module `{m}` is not named in its section")
    for d in sorted(list((ROOT / "crates").iterdir()) + list((ROOT / "apps").iterdir())):
        if (d / "Cargo.toml").is_file():
            folder = str(d.relative_to(ROOT))
            if folder not in covered:
                problems.append(f"code map: `{folder}` has no section")


UNSAFE = re.compile(r"\bunsafe\s*(\{|fn\b|impl\b)")


def check_unsafe(doc, problems):
    m = re.search(r"^## Unsafe code$(.*?)(?=^## |\Z)", doc, re.M | re.S)
    if not m:
        problems.append("ARCHITECTURE.md: no '## Unsafe code' section")
        return
    listed = set(re.findall(r"^- `([^`]+\.rs)`", m.group(1), re.M))
    found = set()
    for top in ("crates", "apps", "src", "tests", "fuzz"):
        for f in (ROOT / top).rglob("*.rs"):
            if "target" in f.parts:
                continue
            code = "\n".join(line.split("//")[0] for line in f.read_text().splitlines())
            if UNSAFE.search(code):
                found.add(str(f.relative_to(ROOT)))
    for f in sorted(found - listed):
        problems.append(f"unsafe code: {f} has unsafe code and is not listed")
    for f in sorted(listed - found):
        problems.append(f"unsafe code: {f} is listed and has no unsafe code")


def main():
    doc = DOC.read_text()
    problems = []
    check_table(doc, problems)
    check_code_map(doc, problems)
    check_unsafe(doc, problems)
    for p in problems:
        print(p)
    if problems:
        print(f"{len(problems)} problems: ARCHITECTURE.md no longer describes the code")
        return 1
    print("ok: ARCHITECTURE.md matches the manifests, the modules and the unsafe code")
    return 0


if __name__ == "__main__":
    sys.exit(main())
