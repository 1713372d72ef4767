#!/usr/bin/env python3
"""Checks that ARCHITECTURE.md still describes the code.

1. The dependency table (rows "| `crate` | depends on |") lists exactly the
   ifd crates in each manifest's [dependencies] (target-specific ones
   included), and has a row for every crate under crates/ and apps/.
2. The list of files allowed `unsafe_code` (the "- `path.rs`" items of the
   section whose heading names `unsafe`) equals the Rust files with an
   `#[allow(..)]`/`#[expect(..)]` (or `#![..]`) attribute naming
   `unsafe_code`.
3. Every path the page names in backticks exists: a token with a `/` or
   ending in .rs, .md, .wgsl, .py, .sh, .toml, .json. It is looked up from the
   repository root, then, inside a code-map section, from that crate's folder
   and its src/; a bare file name (`config.rs`) anywhere in that crate, or
   outside the code map anywhere in the repository. Tokens with `*`, `<` or
   spaces are patterns, not paths; a token with a `/` whose first part is no
   folder of the repository (`dP/du`) is not taken for a path.
4. Every crate and app has a code-map section: a `### ` heading under
   "## Code map" that names its folder (`crates/x`, `apps/x`, `src/`).
5. The page is at most MAX_LINES lines long.

Module import cycles are `scripts/module_cycles.py`'s.
Usage: scripts/check_architecture.py [--root DIR]
  --root DIR  check DIR/ARCHITECTURE.md against DIR (default: this repository)
Exit status: 0 when the page matches, 1 with one line per problem.
"""

import argparse
import pathlib
import re
import sys
import tomllib

ROOT = pathlib.Path(__file__).resolve().parent.parent
DOC = ROOT / "ARCHITECTURE.md"
MAX_LINES = 400
PATH_EXT = (".rs", ".md", ".wgsl", ".py", ".sh", ".toml", ".json")
SKIP_DIRS = {"target", ".git", "node_modules", ".venv", "__pycache__"}


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


def member_folders():
    """crates/x and apps/x folders that hold a Cargo.toml."""
    return sorted(
        str(d.relative_to(ROOT))
        for top in ("crates", "apps") if (ROOT / top).is_dir()
        for d in (ROOT / top).iterdir() if (d / "Cargo.toml").is_file()
    )


def check_table(doc, problems):
    rows = re.findall(r"^\| `([^`]+)`( \(facade\))? \| (.*) \|$", doc, re.M)
    if not rows:
        problems.append("dependency table: not found (rows '| `crate` | `ifd-x`, ... |')")
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
    for folder in member_folders():
        name = folder if folder.startswith("apps/") else folder.removeprefix("crates/")
        if name not in named:
            problems.append(f"dependency table: no row for `{name}`")


UNSAFE_ATTR = re.compile(r"#!?\[\s*(?:allow|expect)\s*\(([^\]]*)\)\s*\]", re.S)


def rust_files():
    for top in ("crates", "apps", "src", "tests", "fuzz", "examples", "benches"):
        for f in (ROOT / top).rglob("*.rs"):
            if not SKIP_DIRS.intersection(f.relative_to(ROOT).parts):
                yield f


def allows_unsafe(text):
    code = "\n".join(line.split("//")[0] for line in text.splitlines())
    return any(re.search(r"\bunsafe_code\b", m.group(1)) for m in UNSAFE_ATTR.finditer(code))


def check_unsafe(doc, problems):
    m = re.search(r"^(#{2,3}) [^\n]*unsafe[^\n]*$(.*?)(?=^#{2,3} |\Z)", doc, re.M | re.S)
    if not m:
        problems.append("unsafe code: no section whose heading names `unsafe`")
        return
    listed = set(re.findall(r"^- `([^`]+\.rs)`", m.group(2), re.M))
    found = {str(f.relative_to(ROOT)) for f in rust_files() if allows_unsafe(f.read_text())}
    for f in sorted(found - listed):
        problems.append(f"unsafe code: {f} allows unsafe_code and is not listed")
    for f in sorted(listed - found):
        problems.append(f"unsafe code: {f} is listed but does not allow unsafe_code")


def code_map_sections(doc):
    """(crate folders named by the heading, body) of each `### ` section
    under "## Code map"."""
    m = re.search(r"^## Code map$(.*?)(?=^## |\Z)", doc, re.M | re.S)
    if not m:
        return None
    parts = re.split(r"^### (.*)$", m.group(1), flags=re.M)
    return [
        (re.findall(r"`((?:crates|apps)/[a-z0-9-]+|src/)`", heading), body)
        for heading, body in zip(parts[1::2], parts[2::2])
    ]


def check_code_map(doc, problems):
    sections = code_map_sections(doc)
    if sections is None:
        problems.append("code map: no '## Code map' section")
        return
    covered = {f for folders, _ in sections for f in folders}
    for folder in member_folders():
        if folder not in covered:
            problems.append(f"code map: `{folder}` has no section (a `### ` heading naming it)")
    for folders, _ in sections:
        for f in folders:
            if not (ROOT / f).is_dir():
                problems.append(f"code map: section for `{f}`, which does not exist")


def files_named(base, name):
    return any(
        not SKIP_DIRS.intersection(p.relative_to(base).parts)
        for p in base.rglob(name)
    )


def path_exists(token, bases, crate_dirs):
    if "/" not in token:  # a bare file name: anywhere in the crate (or repository)
        return any(files_named(r, token) for r in crate_dirs or [ROOT])
    return any((b / token.rstrip("/")).exists() for b in bases)


def looks_like_path(token, bases):
    if any(c in token for c in "*<> ") or "://" in token or "::" in token:
        return False
    if not re.fullmatch(r"[\w.\-/$~]+", token):
        return False
    if token.endswith(PATH_EXT) or (token.endswith("/") and len(token) > 1):
        return True
    if "/" in token:
        first = token.split("/")[0]
        return any((b / first).is_dir() for b in bases)
    return False


def check_paths(doc, problems):
    # the crate folders of the code-map section each line is in
    context = []
    current = []
    in_map = False
    for line in doc.splitlines():
        if line.startswith("## "):
            in_map = line.strip() == "## Code map"
            current = []
        elif line.startswith("### "):
            current = re.findall(r"`((?:crates|apps)/[a-z0-9-]+|src/)`", line) if in_map else []
        context.append(list(current))
    every_crate = [ROOT / f for f in member_folders()]
    seen = set()
    for n, line in enumerate(doc.splitlines()):
        crate_dirs = [ROOT / f for f in context[n]]
        # outside the code map a relative path may be any crate's
        bases = [ROOT] + [b for d in crate_dirs or every_crate for b in (d, d / "src")]
        for token in re.findall(r"`([^`\n]+)`", line):
            if token.startswith("$") or token.startswith("~"):
                continue
            if not looks_like_path(token, bases):
                continue
            key = (token, tuple(context[n]))
            if key in seen:
                continue
            seen.add(key)
            if not path_exists(token, bases, crate_dirs):
                where = f" (in the section of {', '.join(context[n])})" if context[n] else ""
                problems.append(f"paths: line {n + 1}: `{token}` does not exist{where}")


def check_length(doc, problems):
    n = len(doc.splitlines())
    if n > MAX_LINES:
        problems.append(f"length: {n} lines, more than {MAX_LINES}: a map, not an inventory")


def main():
    global ROOT, DOC
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--root", type=pathlib.Path, default=ROOT)
    ROOT = ap.parse_args().root.resolve()
    DOC = ROOT / "ARCHITECTURE.md"
    if not DOC.is_file():
        print(f"check_architecture: {DOC} not found")
        return 1
    doc = DOC.read_text()
    problems = []
    check_table(doc, problems)
    check_unsafe(doc, problems)
    check_code_map(doc, problems)
    check_paths(doc, problems)
    check_length(doc, problems)
    for p in problems:
        print(p)
    if problems:
        print(f"FAIL: {len(problems)} problem(s): ARCHITECTURE.md no longer describes the code")
        return 1
    print("ok: ARCHITECTURE.md matches the manifests, the unsafe_code allowances, "
          "the paths it names and the crates, within its length")
    return 0


if __name__ == "__main__":
    sys.exit(main())
