#!/usr/bin/env python3
"""Module import cycles inside each crate of the workspace.

A module `a` depends on `b` when a file of `a` (its own file or a file below
it) names `crate::b` (in a `use` or a path) or, from a child module,
`super::b`. Dependencies are taken between the crate root's top-level modules
(`src/a.rs` or `src/a/`), which is the level ARCHITECTURE.md describes; a
strongly connected component with more than one module is a cycle. Unit-test
modules (`#[cfg(test)] mod tests`) are left out: tests may use anything.

Usage: scripts/module_cycles.py [--allow FILE]   (exit 1 when a cycle is found)
Prints each crate's dependency edges with -v.
"""

import argparse
import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
CRATE_PATH = re.compile(r"\bcrate::(?:\{([^}]*)\}|([a-z_][a-z0-9_]*))")


def strip_comments(text):
    """Code without comments and without the unit tests (`#[cfg(test)] mod
    tests`, last in a file by convention): tests may use any module."""
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    text = re.split(r"#\[cfg\(test\)\]\s*mod\s+\w+\s*\{", text)[0]
    return "\n".join(line.split("//", 1)[0] for line in text.splitlines())


def top_module(src, path):
    rel = path.relative_to(src)
    first = rel.parts[0]
    if first in ("lib.rs", "main.rs"):
        return None
    return first.removesuffix(".rs")


def crate_graph(src):
    mods = {top_module(src, p) for p in src.rglob("*.rs")} - {None}
    edges = {m: set() for m in mods}
    for p in src.rglob("*.rs"):
        a = top_module(src, p)
        if a is None:
            continue
        text = strip_comments(p.read_text())
        names = []
        for group, single in CRATE_PATH.findall(text):
            if single:
                names.append(single)
            else:
                names += [n.strip().split("::")[0] for n in group.split(",")]
        # `super::b` from a file one level below the top-level module.
        if len(p.relative_to(src).parts) == 2:
            names += re.findall(r"\bsuper::([a-z_][a-z0-9_]*)", text)
        for b in names:
            if b in mods and b != a:
                edges[a].add(b)
    return edges


def sccs(edges):
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(edges[v]):
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

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return [c for c in out if len(c) > 1]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("-v", "--verbose", action="store_true")
    a = ap.parse_args()
    found = 0
    for cargo in sorted(list((ROOT / "crates").glob("*/Cargo.toml")) + list((ROOT / "apps").glob("*/Cargo.toml"))):
        src = cargo.parent / "src"
        edges = crate_graph(src)
        if a.verbose:
            for m in sorted(edges):
                print(f"{cargo.parent.name}: {m} -> {', '.join(sorted(edges[m])) or '-'}")
        for comp in sccs(edges):
            found += 1
            inner = [f"{x} -> {y}" for x in comp for y in sorted(edges[x]) if y in comp]
            print(f"{cargo.parent.name}: cycle among {', '.join(comp)} ({'; '.join(inner)})")
    if found:
        print(f"{found} module cycle(s)")
        return 1
    print("no module cycles")
    return 0


if __name__ == "__main__":
    sys.exit(main())
