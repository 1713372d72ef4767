"""Every shell block of README.md, docs/guide/*.md, docs/tutorial.md and docs/faq.md runs, as
written (issue 36, item 4; the tutorial and the FAQ: issue 55, item 5).

Each ```sh, ```bash and ```console block is one test (id `FILE:LINE`, the line of its
opening fence). The block runs with `bash` and `set -e` in a fresh temporary folder that
holds a copy of `testdata/`, so relative paths such as `testdata/astronaut.png` work, with
`ifd`, `ifd-paper`, `ifd-brush` and `ifd-envrender` (the binaries beside the one conftest.py finds:
`IFD_BIN`, else `target/debug/ifd`) and the repository's `.venv/bin` (for `python`) first
on PATH. The test asserts exit code 0 and that every output the block names exists
afterwards: the value of `-o`, `--output`, `--out`, `--out-dir` and the other output flags
in OUTPUT_FLAGS, the target of a `>` redirect, the second file of `ifd convert`.

A ```console block runs the lines that start with `$ ` (the rest is the output it
printed when the docs were written; it is not compared, timings differ).

A block that needs what CI lacks (a hardware GPU, a window, many minutes, the network,
the repository's own scripts) carries an HTML comment on the line before its fence,

    <!-- doc-test: skip (needs a window) -->

and is listed in SKIPPED below with the same reason: it is reported as skipped, never as
passed, and `test_skip_marks_match_the_list` fails when a mark and the list disagree, so a
block cannot be switched off in the markdown alone. Blocks that use the GPU (`--gpu`,
`gpu-info`, `--device gpu`) run on whatever Vulkan adapter there is (Mesa's lavapipe in CI)
and are skipped, as the other GPU tests are, only under IFD_GPU_TESTS=skip.

Keep documented commands fast on the bundled data (small sizes): the whole file should
take well under 2 minutes on 2 cores with the debug binary.
"""

from __future__ import annotations

import dataclasses
import os
import pathlib
import re
import shlex
import shutil
import subprocess
import sys

import pytest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "scripts"))
from check_numbers import github_anchors  # noqa: E402

from conftest import ROOT, TESTDATA

GUIDES = sorted((ROOT / "docs" / "guide").glob("*.md"))
DOCS = [ROOT / "README.md", *GUIDES, ROOT / "docs" / "tutorial.md", ROOT / "docs" / "faq.md"]
SHELL_LANGS = {"sh", "bash", "console"}
MARK = re.compile(r"^\s*<!--\s*doc-test:\s*(.*?)\s*-->\s*$")
SKIP_MARK = re.compile(r"^skip\s*\((.+)\)$")
FENCE = re.compile(r"^(\s*)(`{3,}|~{3,})\s*([\w+-]*)")
HEREDOC = re.compile(r"<<-?\s*['\"]?(\w+)['\"]?")

# Blocks that do not run here, by (file, first command: continuations joined, the comment
# and repeated blanks left out): the reason, exactly as the block's
# `<!-- doc-test: skip (REASON) -->` mark gives it.
SKIPPED = {
    ("README.md", "ifd-brush"): "opens a window",
    ("README.md", "cargo build --release -p ifd-cli -p ifd-brush -p ifd-envrender"):
        "builds with cargo and pip (minutes)",
    ("README.md", "cd dist && sha256sum -c SHA256SUMS"):
        "needs the artifacts of scripts/dist.sh, which builds for minutes; the suite installs them this way in dist.sh --quick",
    ("README.md", "./scripts/demo.sh"):
        "the set-up scripts themselves: they build with cargo (minutes) and test-all.sh runs this test",
    ("docs/guide/gpu.md", "ifd render --env testdata/forest.hdr --brdf ggx:alpha=0.3 --lmax 16 "
     "--size 1024x1024 --gpu --frames 50 -o ggx-gpu.png"):
        "a timing: meaningful on a hardware GPU only, minutes on a software one",
    ("docs/guide/gpu.md", "cargo build --release -p ifd-cli -p ifd-brush"):
        "builds release binaries with cargo (minutes); the timing is meaningful on a hardware GPU only",
    ("docs/guide/ibl.md", ".venv/bin/python tests/bench/bench_ibl.py"):
        "runs from the repository root, needs Filament's cmgen and glTF-IBL-Sampler, and takes minutes",
    ("docs/guide/python.md", "pip install ./crates/ifd-py"): "builds with cargo and pip (minutes)",
    ("docs/guide/python.md", ".venv/bin/python examples/python/compare_with_opencv.py --size 512 --runs 3"):
        "runs from the repository root and takes minutes",
    ("docs/guide/rendering.md", "ifd-paper isd-convergence --env testdata/forest.hdr --degrees 2..36:2 "
     "--brdf phong:s=8 --brdf phong:s=32 --brdf phong:s=128 --brdf ggx:alpha=0.5 --brdf ggx:alpha=0.3 "
     "--brdf lambert --size 128x128 --no-sh --csv docs/shading-convergence.csv "
     "--plot docs/shading-convergence.png --grid docs/shading-grid.png"):
        "rewrites the figures under docs/ from the repository root and takes minutes",
    ("docs/guide/rendering.md", "ifd-envrender"): "opens a window",
    ("docs/guide/rendering.md", "ifd-envrender --brdf ggx:alpha=0.3 --lmax 8 --size 320x240 --device gpu "
     "--screenshot shot.png --exit"):
        "opens a window (tests/python/test_envrender.py runs it under Xvfb)",
    ("docs/guide/smoothing-and-brush.md", "ifd-brush"): "opens a window",
    ("docs/guide/spherical.md", ".venv/bin/python tests/bench/isd_table1.py --out isd-table1"):
        "runs from the repository root and takes minutes",
}

# Flags whose value is a file or folder the command writes.
OUTPUT_FLAGS = {
    "-o", "--output", "--out", "--out-dir", "--plot", "--csv", "--grid", "--mask", "--stderr",
    "--reconstruct", "--preview", "--field", "--save", "--screenshot", "--markdown", "--coeffs",
    "--record",
}
GPU_WORDS = re.compile(r"(--gpu\b|\bgpu-info\b|--device gpu)")


@dataclasses.dataclass(frozen=True)
class Block:
    path: pathlib.Path
    line: int  # 1-based line of the opening fence
    lang: str
    body: str
    mark: str | None

    @property
    def rel(self) -> str:
        return self.path.relative_to(ROOT).as_posix()

    @property
    def id(self) -> str:
        return f"{self.rel}:{self.line}"

    def script(self) -> str:
        """The commands as bash runs them."""
        if self.lang != "console":
            return self.body
        out, cont, heredoc = [], False, None
        for line in self.body.splitlines():
            if heredoc is not None:  # a heredoc's body, up to its terminator
                out.append(line)
                if line.strip() == heredoc:
                    heredoc = None
                continue
            if line.startswith("$ "):
                out.append(line[2:])
            elif cont:
                out.append(line[2:] if line.startswith("> ") else line)
            else:
                continue  # output
            cont = out[-1].rstrip().endswith("\\")
            h = HEREDOC.search(out[-1])
            heredoc = h.group(1) if h else None
        return "\n".join(out) + "\n"

    def first_command(self) -> str:
        """The first command line, continuations joined, without its comment."""
        for line in logical_commands(self.script()):
            s = " ".join(re.sub(r"(^|\s)#.*$", "", line).split())
            if s:
                return s
        return ""

    def skip_reason(self) -> str | None:
        if self.mark is None:
            return None
        m = SKIP_MARK.match(self.mark)
        return m.group(1) if m else None


def parse_blocks(path: pathlib.Path) -> list[Block]:
    lines = path.read_text().splitlines()
    blocks, i = [], 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent, fence, lang = m.group(1), m.group(2), m.group(3)
        start = i
        body = []
        i += 1
        while i < len(lines) and not re.match(rf"^\s*{re.escape(fence[0])}{{{len(fence)},}}\s*$", lines[i]):
            body.append(lines[i][len(indent):] if lines[i].startswith(indent) else lines[i].lstrip())
            i += 1
        i += 1
        if lang not in SHELL_LANGS:
            continue
        j = start - 1
        while j >= 0 and not lines[j].strip():
            j -= 1
        mm = MARK.match(lines[j]) if j >= 0 else None
        blocks.append(Block(path, start + 1, lang, "\n".join(body) + "\n", mm.group(1) if mm else None))
    return blocks


ALL_BLOCKS = [b for p in DOCS for b in parse_blocks(p)]


def logical_commands(script: str) -> list[str]:
    """The script's command lines: continuations joined, heredoc bodies left out."""
    out, pending, heredoc = [], "", None
    for line in script.splitlines():
        if heredoc is not None:
            if line.strip() == heredoc:
                heredoc = None
            continue
        if line.rstrip().endswith("\\"):
            pending += line.rstrip()[:-1] + " "
            continue
        cmd = pending + line
        pending = ""
        h = HEREDOC.search(cmd)
        if h:
            heredoc = h.group(1)
        out.append(cmd)
    return out


def named_outputs(script: str) -> list[str]:
    """The files and folders the block's commands say they write."""
    outs = []
    for cmd in logical_commands(script):
        try:
            words = shlex.split(cmd, comments=True)
        except ValueError:
            continue
        for k, w in enumerate(words):
            nxt = words[k + 1] if k + 1 < len(words) else None
            if w in OUTPUT_FLAGS and nxt is not None:
                outs.append(nxt)
            elif "=" in w and w.split("=", 1)[0] in OUTPUT_FLAGS and w.startswith("--"):
                outs.append(w.split("=", 1)[1])
            elif re.fullmatch(r"[12&]?>>?", w) and nxt is not None:
                outs.append(nxt)
            elif (r := re.fullmatch(r"[12&]?>>?(.+)", w)) and not r.group(1).startswith("&"):
                outs.append(r.group(1))
        for k in range(len(words) - 1):
            # ifd convert IN OUT
            if words[k] == "ifd" and words[k + 1] == "convert":
                pos = [w for w in words[k + 2:] if not w.startswith("-")]
                if len(pos) >= 2:
                    outs.append(pos[1])
    return [o for o in outs if "$" not in o and o != "/dev/null" and not o.startswith("&")]


@pytest.fixture(scope="session")
def doc_env(ifd_bin, tmp_path_factory):
    """PATH with ifd, ifd-paper, ifd-brush and ifd-envrender first, and a private state folder."""
    base = tmp_path_factory.mktemp("doc-env")
    bindir = base / "bin"
    bindir.mkdir()
    (bindir / "ifd").symlink_to(ifd_bin.resolve())
    for app in ("ifd-paper", "ifd-brush", "ifd-envrender"):
        exe = ifd_bin.resolve().with_name(app)
        if exe.exists():
            (bindir / app).symlink_to(exe)
    paths = [str(bindir)]
    venv = ROOT / ".venv" / "bin"
    if venv.is_dir():
        paths.append(str(venv))
    paths.append(str(pathlib.Path(sys.executable).parent))
    env = dict(os.environ)
    # The caches stay where the rest of the suite has them (the aspect bank of `ifd smooth`,
    # Mesa's shader cache: a cold lavapipe compiles a shader for tens of seconds); the apps'
    # state (settings, the brush's journal) goes to a private folder.
    env.update(
        PATH=os.pathsep.join([*paths, env.get("PATH", "")]),
        XDG_STATE_HOME=str(base / "state"),
        IFD_ENVRENDER_STATE_DIR=str(base / "envrender-state"),
    )
    if not os.path.isdir(env.get("XDG_RUNTIME_DIR", "")):
        runtime = base / "xdg-runtime"
        runtime.mkdir(mode=0o700)
        env["XDG_RUNTIME_DIR"] = str(runtime)
    return env


def test_docs_have_shell_blocks():
    assert DOCS[0].name == "README.md" and len(DOCS) > 1, DOCS
    assert len(ALL_BLOCKS) >= 20, [b.id for b in ALL_BLOCKS]


def test_skip_marks_match_the_list():
    marked = {(b.rel, b.first_command()): b.skip_reason() for b in ALL_BLOCKS if b.mark is not None}
    bad = [b.id + ": " + b.mark for b in ALL_BLOCKS if b.mark is not None and b.skip_reason() is None]
    assert not bad, f"marks other than `doc-test: skip (REASON)`: {bad}"
    unlisted = {k: v for k, v in marked.items() if SKIPPED.get(k) != v}
    stale = {k: v for k, v in SKIPPED.items() if k not in marked}
    assert not unlisted, f"blocks marked skip in the docs, not listed in SKIPPED (or another reason): {unlisted}"
    assert not stale, f"SKIPPED lists blocks that are not marked in the docs: {stale}"


@pytest.mark.parametrize("block", ALL_BLOCKS, ids=[b.id for b in ALL_BLOCKS])
def test_doc_block_runs(block, doc_env, tmp_path):
    reason = block.skip_reason()
    if reason is not None:
        pytest.skip(reason)
    script = block.script()
    if GPU_WORDS.search(script) and os.environ.get("IFD_GPU_TESTS") == "skip":
        pytest.skip("uses the GPU (IFD_GPU_TESTS=skip)")
    for app in ("ifd-paper", "ifd-brush", "ifd-envrender"):
        uses = re.search(rf"(^|[\s;&|(]){app}\b", script, re.M)
        if uses and not shutil.which(app, path=doc_env["PATH"].split(os.pathsep)[0]):
            pytest.fail(f"{block.id} runs {app}, which is not built beside the ifd binary "
                        f"(cargo build -p {app})")
    work = tmp_path / "work"
    work.mkdir()
    shutil.copytree(TESTDATA, work / "testdata")
    p = subprocess.run(["bash", "-c", "set -e\n" + script], cwd=work, env=doc_env,
                       capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, (
        f"{block.id} exited {p.returncode}\n--- script\n{script}--- stdout\n{p.stdout[-4000:]}"
        f"--- stderr\n{p.stderr[-4000:]}")
    missing = [o for o in named_outputs(script) if not (work / o).exists()]
    assert not missing, f"{block.id}: outputs named but not written: {missing}\n{p.stderr[-2000:]}"


def test_output_detection():
    s = ("ifd decompose gauss:sx=4 -o g.json --plot g.png  # comment -o not.json\n"
         "ifd convert testdata/camera.png cam.npy\n"
         "ifd compare a.png b.png --json > report.json\n"
         "python - <<'EOF'\nprint('-o nope')\nEOF\n"
         "ifd envmap prefilter testdata/forest.hdr \\\n  --out-dir ibl\n")
    assert named_outputs(s) == ["g.json", "g.png", "cam.npy", "report.json", "ibl"]


# --- the front door and the index (issue 36, items 1 and 2) -------------------------------

LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")


def _prose_lines(path: pathlib.Path) -> list[str]:
    """The file's lines outside fenced code blocks."""
    out, fence = [], None
    for line in path.read_text().splitlines():
        m = FENCE.match(line)
        if fence is None and m:
            fence = m.group(2)[0]
        elif fence is not None and re.match(rf"^\s*{re.escape(fence)}{{3,}}\s*$", line):
            fence = None
        elif fence is None:
            out.append(line)
    return out


def _anchors(path: pathlib.Path) -> set[str]:
    """GitHub's heading anchors of a Markdown file (the rule of scripts/check_numbers.py)."""
    headings = [m.group(1) for line in _prose_lines(path) if (m := re.match(r"^#{1,6}\s+(.*?)\s*#*\s*$", line))]
    return github_anchors(headings)


LINKED_PAGES = [ROOT / "README.md", ROOT / "docs" / "README.md", *DOCS[1:], ROOT / "docs" / "glossary.md"]


@pytest.mark.parametrize("page", LINKED_PAGES, ids=[p.relative_to(ROOT).as_posix() for p in LINKED_PAGES])
def test_links_resolve(page):
    """Every relative link (and its #anchor) of the README, the docs index, the guides, the
    tutorial, the FAQ and the glossary."""
    bad = []
    for line in _prose_lines(page):
        for target in LINK.findall(line):
            if re.match(r"^[a-z]+:", target):
                continue  # https:, mailto:
            file, _, anchor = target.partition("#")
            dest = (page.parent / file).resolve() if file else page
            if not dest.exists():
                bad.append(f"{target} (no such file)")
            elif anchor and dest.suffix == ".md" and anchor not in _anchors(dest):
                bad.append(f"{target} (no heading with that anchor)")
    assert not bad, f"{page.relative_to(ROOT)}: broken links: {bad}"


def test_readme_is_a_front_door():
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) <= 250, f"README.md has {len(lines)} lines (at most 250: the guides hold the rest)"
    first_screen = "\n".join(lines[:60])
    for guide in GUIDES:
        assert f"docs/guide/{guide.name}" in first_screen, f"README.md's first screen does not link {guide.name}"


def test_docs_index_lists_every_file():
    """docs/README.md links every file under docs/, itself or through a linked folder."""
    try:
        files = subprocess.run(["git", "ls-files", "-co", "--exclude-standard", "docs"], cwd=ROOT,
                               capture_output=True, text=True, check=True).stdout.split()
    except (OSError, subprocess.CalledProcessError) as e:
        pytest.fail(f"git ls-files failed: {e}")
    docs = ROOT / "docs"
    index = docs / "README.md"
    linked = set()
    for line in _prose_lines(index):
        for target in LINK.findall(line):
            if not re.match(r"^[a-z]+:", target):
                linked.add((index.parent / target.partition("#")[0]).resolve())
    missing = []
    for f in files:
        path = (ROOT / f).resolve()
        if path == index or path.name.startswith(".") or not path.exists():
            continue
        folders = [p for p in path.parents if docs in p.parents]  # the folders under docs/
        if not any(p in linked for p in [path, *folders]):
            missing.append(f)
    assert not missing, f"docs/README.md does not index: {missing}"
