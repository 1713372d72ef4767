#!/usr/bin/env python3
"""Checks that every performance figure in the prose has one source: BENCHMARKS.md.

A guide may link to a row of BENCHMARKS.md, or restate a figure that BENCHMARKS.md
holds; it may not carry a performance figure of its own, which would go stale the day
the benchmark is re-run. This script finds such figures.

Which files. README.md, CONTRIBUTING.md, ARCHITECTURE.md and every docs/**/*.md, except
generated pages, which their commands rewrite and which are the measurements rather
than claims about them:
  - docs/bench/      benchmark reports written by tests/bench/*.py (BENCHMARKS.md's
                     tables link to them);
  - docs/papers/     the papers' tables and figures, written by `ifd-paper all`: each
                     page quotes a paper's numbers beside ours;
  - docs/reference/  generated from the code (CLI, public APIs).
CHANGELOG.md is not checked: an entry records what a change did at the time.

What a figure is. A number (or a range `a-b`) with a unit of time, ratio, level or
share: `x` (`2.5x`, not `4x4` or `1024x1024`), `ms`, `us`, `s`, `dB`, `%`, `fps`, `Hz`.

When it is a performance claim. When its sentence (a sentence of a paragraph or list
item, a table row, a heading) also names a peer (OpenCV, scikit-image, SciPy, ducc0,
pyshtools, cmgen, glTF-IBL-Sampler, steerable filters, brute force, Monte Carlo,
bilateral or guided filtering, anisotropic diffusion, the CPU, the GPU, lavapipe) or a
speed word (faster, slower, speed-up, ahead, behind, cheaper, throughput, overhead, ...).
An accuracy figure that is no performance claim (a test's PSNR target, a fit's 1% error)
has neither and is not looked at. Fenced code blocks (commands and their printed
output), inline code spans and link targets are skipped.

When it is allowed. When BENCHMARKS.md holds the same figure string (compared with
spaces between number and unit removed, en dashes as hyphens, `×` as `x`), or the same
number in a column of a BENCHMARKS.md table whose header names the unit ("time (s)"
holds `0.23 s`), in a paragraph or table that names one of the peers the sentence names
(with its section's heading), or that names no peer: "about 10x slower than the CPU"
is not held by "the floor was 10x" beside brute force. A sentence with a speed word and
no peer is held by any occurrence. Otherwise the figure is reported as
FILE:LINE: FIGURE, with its sentence.

Links. Every link to a section of BENCHMARKS.md (`BENCHMARKS.md#anchor`) from these
files must name one of its headings (GitHub's anchors), so a renamed section does not
leave pages pointing nowhere.

Allowing a figure that is not a benchmark (rarely: a test's tolerance beside the
reference it is checked against, a cost model's constants): the HTML comment
`<!-- numbers: not-a-benchmark -->` at the end of the figure's line exempts that line;
on a line of its own it exempts the paragraph, list item or table that follows it.

Usage: scripts/check_numbers.py [--root DIR] [FILE ...]
  --root DIR  the repository to check (default: this one); BENCHMARKS.md is DIR's
  FILE ...    check these files instead of the default set
Exit status: 0 when every figure is held by BENCHMARKS.md, 1 with one line per figure.
"""

import argparse
import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
TOP_FILES = ("README.md", "CONTRIBUTING.md", "ARCHITECTURE.md")
GENERATED = ("docs/bench/", "docs/papers/", "docs/reference/")
ALLOW = re.compile(r"<!--\s*numbers:\s*not-a-benchmark\s*-->")

NUM = r"\d+(?:,\d{3})*(?:\.\d+)?"
FIGURE = re.compile(
    rf"(?<![\w.,/=-])({NUM}(?:\s?[-\u2013]\s?{NUM})?)"
    r"(?:(x|\u00d7)(?![\w\u00d7])|\s?(ms|us|\u00b5s|s|dB|fps|Hz)\b|\s?(%))"
)
# Peers, each with the name it is compared under (aliases of one tool share it).
PEERS = {
    r"open\s?cv": "opencv", r"cv2": "opencv", r"scikit-image": "scikit-image",
    r"skimage": "scikit-image", r"scipy": "scipy", r"steerable": "steerable",
    r"ducc0": "ducc0", r"pyshtools": "pyshtools", r"cmgen": "cmgen", r"filament": "cmgen",
    r"gltf-ibl-sampler": "gltf-ibl-sampler", r"ibl-sampler": "gltf-ibl-sampler",
    r"monte carlo": "monte carlo", r"brute[- ]force": "brute force",
    r"bilateral": "bilateral", r"guided filter(?:ing)?": "guided", r"anisotropic diffusion": "diffusion",
    r"cpus?": "cpu", r"gpus?": "gpu", r"lavapipe": "lavapipe", r"llvmpipe": "lavapipe",
}
SPEED = [
    r"faster", r"slower", r"speed-?ups?", r"speeds? up", r"sped up", r"ahead", r"behind",
    r"quicker", r"cheaper", r"costlier", r"dearer", r"outperforms?", r"beats?", r"throughput",
    r"as fast", r"times as", r"overhead", r"frame rates?",
]
CONTEXT = re.compile(r"\b(?:" + "|".join(list(PEERS) + SPEED) + r")\b", re.I)
PEER_RES = [(re.compile(rf"\b{k}\b", re.I), v) for k, v in PEERS.items()]
FENCE = re.compile(r"^\s*(`{3,}|~{3,})")
INLINE_CODE = re.compile(r"`[^`\n]*`")
LINK_TARGET = re.compile(r"\]\([^)\s]*\)")
BLOCK_START = re.compile(r"^\s*(?:[-*+]\s|\d+[.)]\s|#{1,6}\s|\|)")
HEADING = re.compile(r"^#{1,6}\s+(.*?)\s*#*\s*$")
BENCH_LINK = re.compile(r"BENCHMARKS\.md#([\w-]+)")
SENTENCE_END = re.compile(r"[.!?](?=\s+[A-Z*(\[`])")


def norm(num, unit):
    unit = {"\u00d7": "x", "\u00b5s": "us"}.get(unit, unit)
    num = re.sub(r"\s", "", num).replace("\u2013", "-")
    return num + unit


def figures(text):
    """(start, end, normalised figure) of each figure in a text."""
    for m in FIGURE.finditer(text):
        unit = m.group(2) or m.group(3) or m.group(4)
        yield m.start(), m.end(), norm(m.group(1), unit)


def header_unit(cell):
    """The unit a table header names: `time (s)` gives `s`, `dB` gives `dB`."""
    m = re.search(r"\((ms|us|\u00b5s|s|dB|%|fps|Hz|x)\)|\b(ms|us|dB|fps|Hz)\b|(%)", cell)
    if not m:
        return None
    return {"\u00b5s": "us"}.get(m.group(0).strip("()"), m.group(0).strip("()"))


def peers_in(text):
    """The peers a text names, by the name they are compared under."""
    return {name for r, name in PEER_RES if r.search(text)}


def held_figures(path):
    """Every figure BENCHMARKS.md holds: normalised figure -> the peers named beside it.

    "Beside" is the figure's paragraph, list item or table, with its section's heading.
    Cells of a column whose header names a unit take that unit."""
    held = {}
    heading = ""
    table = []

    def add_table():
        if not table:
            return
        near = peers_in(" ".join(table) + " " + heading)
        header_units = []
        for row in table:
            cells = [c.strip() for c in row.strip().strip("|").split("|")]
            if all(re.fullmatch(r":?-+:?", c) for c in cells):
                continue
            for _, _, f in figures(row):
                held.setdefault(f, []).append(near)
            if not header_units:
                header_units = [header_unit(c) for c in cells]
                continue
            for cell, unit in zip(cells, header_units):
                if unit is None:
                    continue
                for num in re.findall(rf"(?<![\w.]){NUM}(?:-{NUM})?(?![\w.])", cell.replace("*", "")):
                    held.setdefault(norm(num, unit), []).append(near)
        table.clear()

    for _, unit_lines, _ in units(path, keep_code=True):
        first = unit_lines[0][1].strip()
        if first.startswith("|"):
            table.append(first)
            continue
        add_table()
        if HEADING.match(unit_lines[0][1]) and len(unit_lines) == 1:
            heading = first
        text = " ".join(line for _, line in unit_lines)
        near = peers_in(text + " " + heading)
        for _, _, f in figures(text):
            held.setdefault(f, []).append(near)
    add_table()
    return held


def is_held(figure, peers, held):
    """Whether BENCHMARKS.md holds a figure: the same string, in a paragraph or table that
    names one of the peers the figure's sentence names, or names no peer at all (any
    occurrence when the sentence names no peer, only a speed word)."""
    if figure not in held:
        return False
    return not peers or any(not near or peers & near for near in held[figure])


def units(path, keep_code=False):
    """The text units of a markdown file: (first line number, [(line number, text)], exempt).

    A unit is a paragraph or list item (split into sentences later), a table row or a
    heading; fenced code is left out, or with `keep_code` kept as exempt units."""
    lines = path.read_text(encoding="utf-8").splitlines()
    out = []
    cur = []
    exempt_next = False
    cur_exempt = False
    in_fence = None
    in_table_exempt = False

    def flush(code=False):
        nonlocal cur, cur_exempt
        if cur and not code:
            out.append((cur[0][0], cur, cur_exempt))
        elif cur:
            out.append((cur[0][0], cur, True))  # code: exempt from the check, held by BENCHMARKS
        cur = []
        cur_exempt = False

    for i, line in enumerate(lines, 1):
        m = FENCE.match(line)
        if in_fence:
            if m and m.group(1)[0] == in_fence[0] and len(m.group(1)) >= len(in_fence):
                in_fence = None
                flush(code=True)
            elif keep_code:
                cur.append((i, line))
            continue
        if m:
            flush()
            in_fence = m.group(1)
            exempt_next = False
            continue
        stripped = line.strip()
        if not stripped:
            flush()
            in_table_exempt = False
            continue
        if ALLOW.fullmatch(stripped) or (stripped.startswith("<!--") and ALLOW.search(stripped)
                                         and stripped.endswith("-->")):
            flush()
            exempt_next = True
            continue
        if ALLOW.search(line):
            line = ALLOW.sub("", line)
            line_exempt = True
        else:
            line_exempt = False
        if BLOCK_START.match(line) or stripped.startswith("#"):
            flush()
            if exempt_next:
                cur_exempt = True
                exempt_next = False
                if stripped.startswith("|"):
                    in_table_exempt = True
            if stripped.startswith("|") and in_table_exempt:
                cur_exempt = True
        elif not cur and exempt_next:
            cur_exempt = True
            exempt_next = False
        cur.append((i, "" if line_exempt else line))
        if stripped.startswith("|") or stripped.startswith("#"):
            flush()
    flush()
    return out


def sentences(unit_lines, strip_code=True):
    """Split a unit's joined text into sentences; yields (text, offset, [(offset, line)])."""
    text = ""
    marks = []
    for n, line in unit_lines:
        marks.append((len(text), n))
        if strip_code:
            line = INLINE_CODE.sub(lambda m: " " * len(m.group(0)), line)
        line = LINK_TARGET.sub(lambda m: "]" + " " * (len(m.group(0)) - 1), line)
        text += line + " "
    start = 0
    ends = [m.end() for m in SENTENCE_END.finditer(text)] + [len(text)]
    for end in ends:
        yield text[start:end], start, marks
        start = end


def line_at(marks, offset):
    n = marks[0][1]
    for o, line in marks:
        if o <= offset:
            n = line
    return n


def check_file(path, held, root):
    problems = []
    for _, unit_lines, exempt in units(path):
        if exempt:
            continue
        for text, base, marks in sentences(unit_lines):
            if not CONTEXT.search(text):
                continue
            peers = peers_in(text)
            for s, _, f in figures(text):
                if is_held(f, peers, held):
                    continue
                n = line_at(marks, base + s)
                rel = path.relative_to(root) if path.is_relative_to(root) else path
                problems.append((str(rel), n, f, " ".join(text.split())))
    return problems


def github_anchors(headings):
    """GitHub's anchors of headings' texts, in order: the text lower-cased,
    punctuation dropped, spaces as hyphens, a repeat suffixed -1, -2, ...
    (tests/python/test_doc_commands.py checks links with it too)."""
    seen = {}
    out = set()
    for text in headings:
        slug = re.sub(r"[^\w\- ]", "", text.lower()).replace(" ", "-")
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        out.add(slug if n == 0 else f"{slug}-{n}")
    return out


def anchors(path):
    """GitHub's heading anchors of a markdown file."""
    headings = []
    for _, unit_lines, _exempt in units(path):
        m = HEADING.match(unit_lines[0][1])
        if m and len(unit_lines) == 1:
            headings.append(m.group(1))
    return github_anchors(headings)


def check_links(path, sections, root):
    """Links to BENCHMARKS.md#anchor that name no heading there."""
    problems = []
    for _, unit_lines, _ in units(path):
        for n, line in unit_lines:
            for m in BENCH_LINK.finditer(INLINE_CODE.sub("", line)):
                if m.group(1) not in sections:
                    rel = path.relative_to(root) if path.is_relative_to(root) else path
                    problems.append((str(rel), n, f"BENCHMARKS.md#{m.group(1)}"))
    return problems


def default_files(root):
    files = [root / f for f in TOP_FILES if (root / f).is_file()]
    for p in sorted((root / "docs").rglob("*.md")):
        rel = p.relative_to(root).as_posix()
        if not rel.startswith(GENERATED):
            files.append(p)
    return files


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--root", type=pathlib.Path, default=ROOT)
    ap.add_argument("files", nargs="*", type=pathlib.Path)
    a = ap.parse_args()
    root = a.root.resolve()
    bench = root / "BENCHMARKS.md"
    if not bench.is_file():
        print(f"check_numbers: {bench} not found")
        return 1
    held = held_figures(bench)
    files = [p.resolve() for p in a.files] if a.files else default_files(root)
    sections = anchors(bench)
    problems = []
    links = []
    for p in files:
        problems += check_file(p, held, root)
        links += check_links(p, sections, root)
    for rel, n, f, text in problems:
        if len(text) > 160:
            text = text[:157] + "..."
        print(f"{rel}:{n}: {f} is not in BENCHMARKS.md: {text}")
    for rel, n, link in links:
        print(f"{rel}:{n}: {link}: BENCHMARKS.md has no such section")
    if problems:
        print(f"FAIL: {len(problems)} performance figure(s) restated outside BENCHMARKS.md: "
              "link to its section, or use its figure (scripts/check_numbers.py says how to "
              "allow one that is not a benchmark)")
    if links:
        print(f"FAIL: {len(links)} link(s) to a section BENCHMARKS.md does not have")
    if problems or links:
        return 1
    print(f"ok: every performance figure in {len(files)} pages is one BENCHMARKS.md holds")
    return 0


if __name__ == "__main__":
    sys.exit(main())
