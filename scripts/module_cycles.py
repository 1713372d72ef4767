#!/usr/bin/env python3
"""Import cycles inside each crate of the workspace, between files and
between top-level modules.

Every `.rs` file under a crate's `src/` is a module (`src/a/b.rs` and
`src/a/b/mod.rs` are `a::b`; `lib.rs`/`main.rs` the crate root). A file
depends on another when it names an item of that file through a path:
`use crate::a::b::Item`, `use super::x::{..}`, `super::x::f(..)` or
`crate::a::f(..)` in code, `use self::..`, or a `use` starting with a
child module or with a name the module imported. Paths are resolved through
the `use` declarations they meet, so `crate::ScaleStack` (re-exported at the
root) counts as a dependency on the file that defines `ScaleStack`, not on
`lib.rs`. Inline modules (`mod avx2 { .. }`) belong to their file.

A module's dependencies on its own submodules are not counted (declaring,
re-exporting and calling them is what a parent module is for); a
submodule's dependency on its parent, `use super::Item`, is.

Two checks, each a strongly connected component of more than one node:
- file cycles: files that depend on each other, directly or through others
  (`stack/gather.rs` <-> `stack/gather512.rs`);
- module cycles: the same edges between a crate root's top-level modules
  (`src/a.rs` or `src/a/`), the level ARCHITECTURE.md describes.

Unit tests (`#[cfg(test)]` items and the files they declare) are left out:
tests may use anything. Comments and string literals are ignored.

Usage: scripts/module_cycles.py [-v] [--root DIR]
  -v          also print every crate's file dependencies
  --root DIR  check another checkout (default: this script's repository)
Exit status: 0 no cycle, 1 cycles found (one line each, with the lines that
make each edge), 2 the check could not run (no crates found).
"""

import argparse
import pathlib
import re
import sys

IDENT = r"[A-Za-z_][A-Za-z0-9_]*"
# Keywords that start a path relative to the current or root module.
ANCHORS = ("crate", "super", "self")


# --------------------------------------------------------------------------
# Source text: comments and literals blanked out (offsets and lines kept).


def blank(text):
    """`text` with comments, string and char literals replaced by spaces
    (newlines kept), so braces and paths can be matched."""
    out = list(text)
    n = len(text)
    i = 0

    def wipe(a, b):
        for k in range(a, b):
            if out[k] != "\n":
                out[k] = " "

    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            wipe(i, j)
            i = j
        elif text.startswith("/*", i):
            depth, j = 1, i + 2
            while j < n and depth:
                if text.startswith("/*", j):
                    depth, j = depth + 1, j + 2
                elif text.startswith("*/", j):
                    depth, j = depth - 1, j + 2
                else:
                    j += 1
            wipe(i, j)
            i = j
        elif (m := re.compile(r'b?r(#*)"').match(text, i)) and (
            i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")
        ):
            end = '"' + m.group(1)
            j = text.find(end, m.end())
            j = n if j < 0 else j + len(end)
            wipe(i + 1, j - 1)
            i = j
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            wipe(i + 1, j)
            i = j + 1
        elif c == "'":
            # a char literal ('x', '\n', '\u{..}'), else a lifetime ('a)
            m = re.compile(r"'(\\(u\{[0-9a-fA-F]+\}|x[0-9a-fA-F]{2}|.)|[^\\'])'", re.S).match(text, i)
            if m:
                wipe(i + 1, m.end() - 1)
                i = m.end()
            else:
                i += 1
        else:
            i += 1
    return "".join(out)


def item_end(code, start):
    """End of the item starting at `start`: after its `;` or the `}` that
    closes its first block, whichever comes first at depth 0."""
    depth = 0
    for k in range(start, len(code)):
        ch = code[k]
        if ch in "{([":
            depth += 1
        elif ch in "})]":
            depth -= 1
            if depth == 0 and ch == "}":
                return k + 1
            if depth < 0:
                return k
        elif ch == ";" and depth == 0:
            return k + 1
    return len(code)


CFG_TEST = re.compile(r"#\[cfg\(test\)\]")
ATTRS = re.compile(r"\s*(#!?\[[^\]]*\]\s*)*")


def strip_tests(code):
    """`code` without its `#[cfg(test)]` items (blanked), and the names of
    the file modules they declare (`#[cfg(test)] mod tests;`)."""
    test_mods = set()
    out = code
    pos = 0
    while m := CFG_TEST.search(out, pos):
        start = ATTRS.match(out, m.end()).end()
        end = item_end(out, start)
        decl = re.match(rf"(pub(\([^)]*\))?\s+)?mod\s+({IDENT})\s*;", out[start:end])
        if decl:
            test_mods.add(decl.group(3))
        out = out[: m.start()] + re.sub(r"[^\n]", " ", out[m.start():end]) + out[end:]
        pos = end
    return out, test_mods


def line_of(text, offset):
    return text.count("\n", 0, offset) + 1


# --------------------------------------------------------------------------
# Modules of a crate.


class File:
    def __init__(self, path, modpath, rel):
        self.path = path
        self.modpath = modpath  # tuple of module names from the crate root
        self.rel = rel  # path for messages, relative to the repository
        self.code = ""
        self.lines = []
        self.test_mods = set()
        self.inline = []  # (start, end, name) of inline modules
        self.uses = {}  # scope (tuple) -> {name: absolute-or-relative path}
        self.globs = {}  # scope -> [path]
        self.defined = set()  # names of items defined at any scope
        self.children = set()  # `mod x;` declared file modules


def module_path(src, f):
    rel = f.relative_to(src).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "mod" or (len(parts) == 1 and parts[0] in ("lib", "main")):
        parts = parts[:-1]
    return tuple(parts)


def split_top(s, sep=","):
    """`s` split at `sep` outside braces."""
    parts, depth, cur = [], 0, ""
    for ch in s:
        if ch == "{":
            depth += 1
        elif ch == "}":
            depth -= 1
        if ch == sep and depth == 0:
            parts.append(cur)
            cur = ""
        else:
            cur += ch
    parts.append(cur)
    return [p.strip() for p in parts if p.strip()]


def use_tree(tree, prefix=()):
    """(path, name) pairs of a use tree: name None for a glob."""
    tree = re.sub(r"\s+", " ", tree).strip()
    if not tree:
        return []
    if tree.startswith("::"):
        tree = tree[2:]
    m = re.match(r"^(.*?)::\{(.*)\}$", tree, re.S) or re.match(r"^()\{(.*)\}$", tree, re.S)
    if m:
        head = tuple(s.strip() for s in m.group(1).split("::") if s.strip())
        out = []
        for part in split_top(m.group(2)):
            out += use_tree(part, prefix + head)
        return out
    alias = None
    if " as " in tree:
        tree, alias = (s.strip() for s in tree.rsplit(" as ", 1))
    segs = tuple(s.strip() for s in tree.split("::"))
    if segs[-1] == "*":
        return [(prefix + segs[:-1], None)]
    if segs == ("self",):
        path = prefix
        name = alias or (prefix[-1] if prefix else None)
    elif segs[-1] == "self":
        path = prefix + segs[:-1]
        name = alias or path[-1]
    else:
        path = prefix + segs
        name = alias or segs[-1]
    if name == "_":
        name = None
        return [(path, "_")]
    return [(path, name)]


USE = re.compile(r"\buse\s+([^;]+);")
INLINE_MOD = re.compile(rf"\bmod\s+({IDENT})\s*\{{")
DECL_MOD = re.compile(rf"\bmod\s+({IDENT})\s*;")
DEFINES = re.compile(
    rf"\b(?:fn|struct|enum|union|trait|type|const|static|mod)\s+({IDENT})|macro_rules!\s*({IDENT})"
)
CODE_PATH = re.compile(rf"(?<![A-Za-z0-9_$])((?:crate|super|self)(?:\s*::\s*{IDENT})+)")
PUB_IN = re.compile(r"\bpub\s*\(\s*in\s+[^)]*\)")


class Crate:
    def __init__(self, name, src, root):
        self.name = name
        self.src = src
        self.files = {}  # modpath -> File
        for f in sorted(src.rglob("*.rs")):
            mp = module_path(src, f)
            self.files[mp] = File(f, mp, str(f.relative_to(root)))
        for file in self.files.values():
            self.read(file)
        # files declared only under #[cfg(test)], and files below them
        test_only = set()
        for file in self.files.values():
            for t in file.test_mods:
                test_only.add(file.modpath + (t,))
        self.files = {
            mp: f for mp, f in self.files.items()
            if not any(mp[: len(t)] == t for t in test_only)
        }

    def read(self, file):
        text = file.path.read_text()
        code, file.test_mods = strip_tests(blank(text))
        code = PUB_IN.sub(lambda m: " " * len(m.group(0)), code)
        file.code = code
        file.lines = text.splitlines()
        for m in INLINE_MOD.finditer(code):
            brace = m.end() - 1
            file.inline.append((brace, item_end(code, brace), m.group(1)))
        file.children = set(DECL_MOD.findall(code))
        for m in DEFINES.finditer(code):
            file.defined.add(m.group(1) or m.group(2))
        for m in USE.finditer(code):
            scope = self.scope_at(file, m.start())
            for path, name in use_tree(m.group(1)):
                if name is None:
                    file.globs.setdefault(scope, []).append(path)
                elif name != "_":
                    file.uses.setdefault(scope, {})[name] = path

    @staticmethod
    def scope_at(file, offset):
        """Module path (inline modules included) at `offset` of `file`."""
        inner = [n for (a, b, n) in sorted(file.inline) if a < offset < b]
        return file.modpath + tuple(inner)

    def file_of(self, modpath):
        """The file holding module `modpath` (inline modules: their file)."""
        while modpath not in self.files and modpath:
            modpath = modpath[:-1]
        return self.files.get(modpath)

    def is_module(self, modpath):
        if modpath in self.files:
            return True
        f = self.file_of(modpath)
        if f is None:
            return False
        inner = modpath[len(f.modpath):]
        spans = sorted(f.inline)
        # an inline module path: each name nested in the previous one
        lo, hi = 0, len(f.code)
        for name in inner:
            hit = [(a, b) for (a, b, n) in spans if n == name and lo <= a and b <= hi]
            if not hit:
                return False
            lo, hi = hit[0]
        return True

    def absolute(self, scope, segs):
        """`segs` (a path as written in module `scope`) from the crate root,
        or None for another crate, a prelude name or a local item."""
        if not segs:
            return None
        head = segs[0]
        if head == "crate":
            return segs[1:]
        if head in ("super", "self"):
            cur = scope
            i = 0
            while i < len(segs) and segs[i] in ("super", "self"):
                if segs[i] == "super":
                    if not cur:
                        return None
                    cur = cur[:-1]
                i += 1
            return cur + segs[i:]
        if self.is_module(scope + (head,)):
            return scope + segs
        f = self.file_of(scope)
        if f is not None:
            path = f.uses.get(scope, {}).get(head)
            if path is not None and path != segs[:1]:
                base = self.absolute(scope, path)
                return None if base is None else base + segs[1:]
        return None

    def target(self, segs, depth=0):
        """The file that defines what the absolute path `segs` names."""
        if depth > 16:
            return None
        mod = ()
        for i, seg in enumerate(segs):
            if self.is_module(mod + (seg,)):
                mod = mod + (seg,)
                continue
            # `seg` is an item of module `mod`: defined there or imported
            f = self.file_of(mod)
            if f is None:
                return None
            path = f.uses.get(mod, {}).get(seg)
            if path is not None:
                base = self.absolute(mod, path)
                if base is None:
                    return None  # from another crate: no edge
                return self.target(base + segs[i + 1:], depth + 1)
            if seg not in f.defined:
                for glob in f.globs.get(mod, []):
                    base = self.absolute(mod, glob)
                    if base is not None:
                        t = self.target(base + (seg,), depth + 1)
                        if t is not None and seg in t.defined:
                            return t
            return f
        return self.file_of(mod)

    def edges(self):
        """file modpath -> {target modpath: [line numbers]}."""
        out = {mp: {} for mp in self.files}
        for file in self.files.values():
            refs = []
            for m in USE.finditer(file.code):
                scope = self.scope_at(file, m.start())
                for path, _ in use_tree(m.group(1)):
                    refs.append((m.start(), scope, path))
            for m in CODE_PATH.finditer(file.code):
                segs = tuple(s.strip() for s in m.group(1).split("::"))
                refs.append((m.start(), self.scope_at(file, m.start()), segs))
            for offset, scope, path in refs:
                absolute = self.absolute(scope, path)
                if absolute is None:
                    continue
                t = self.target(absolute)
                if t is None or t is file:
                    continue
                if t.modpath[: len(file.modpath)] == file.modpath:
                    continue  # a module's own submodule
                out[file.modpath].setdefault(t.modpath, [])
                line = line_of(file.code, offset)
                if line not in out[file.modpath][t.modpath]:
                    out[file.modpath][t.modpath].append(line)
        return out


# --------------------------------------------------------------------------
# Cycles.


def sccs(nodes, succ):
    """Strongly connected components with more than one node (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]
    sys.setrecursionlimit(max(1000, 4 * len(nodes) + 100))

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(succ.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            out.append(sorted(comp))

    for v in sorted(nodes):
        if v not in index:
            visit(v)
    return [c for c in out if len(c) > 1]


def crates(root):
    out = []
    for cargo in sorted(list((root / "crates").glob("*/Cargo.toml"))
                        + list((root / "apps").glob("*/Cargo.toml"))):
        if (cargo.parent / "src").is_dir():
            out.append((cargo.parent.name, cargo.parent / "src"))
    if (root / "src").is_dir() and (root / "Cargo.toml").is_file():
        out.append(("ifd", root / "src"))
    return out


def check(root, verbose):
    """Problems found (lines) and the number of crates and files read."""
    problems, n_files = [], 0
    found = crates(root)
    for name, src in found:
        crate = Crate(name, src, root)
        n_files += len(crate.files)
        edges = crate.edges()
        rel = {mp: crate.files[mp].rel for mp in crate.files}
        if verbose:
            for a in sorted(edges):
                targets = ", ".join(rel[b] for b in sorted(edges[a])) or "-"
                print(f"{name}: {rel[a]} -> {targets}")
        for comp in sccs(edges, edges):
            inner = []
            for a in comp:
                for b in sorted(edges[a]):
                    if b in comp:
                        lines = ",".join(str(n) for n in edges[a][b][:3])
                        inner.append(f"{rel[a]}:{lines} uses {rel[b]}")
            problems.append(
                f"{name}: file cycle among {', '.join(rel[f] for f in comp)}\n    "
                + "\n    ".join(inner)
            )
        top = {}
        for a, targets in edges.items():
            for b in targets:
                if a and b and a[0] != b[0]:
                    top.setdefault(a[0], {}).setdefault(b[0], []).append((a, b))
        for comp in sccs(top, top):
            inner = []
            for x in comp:
                for y in sorted(top.get(x, {})):
                    if y in comp:
                        a, b = top[x][y][0]
                        inner.append(f"{x} -> {y} ({rel[a]} uses {rel[b]})")
            problems.append(
                f"{name}: module cycle among {', '.join(comp)}\n    " + "\n    ".join(inner)
            )
    return problems, len(found), n_files


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("-v", "--verbose", action="store_true")
    ap.add_argument("--root", type=pathlib.Path,
                    default=pathlib.Path(__file__).resolve().parents[1])
    a = ap.parse_args()
    problems, n_crates, n_files = check(a.root.resolve(), a.verbose)
    if n_crates == 0:
        print(f"module_cycles: no crates under {a.root} (crates/*, apps/*, src/)")
        return 2
    for p in problems:
        print(p)
    if problems:
        print(f"FAIL: {len(problems)} import cycle(s) in {n_crates} crates: each file (or "
              "module) above depends, through the paths it names, on one that depends "
              "back on it. Move the shared part into one of them or a third file.")
        return 1
    print(f"ok: no import cycles between files or top-level modules "
          f"({n_crates} crates, {n_files} files)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
