"""scripts/check_numbers.py: performance figures in the docs come from BENCHMARKS.md (issue 55, item 4).

The repository passes; a guide planted in a copy of the repository with a figure BENCHMARKS.md
does not hold fails, naming the file, the line and the figure; a figure BENCHMARKS.md holds, an
accuracy figure with no peer beside it and a figure marked as not a benchmark pass; a link to a
section BENCHMARKS.md does not have fails.
"""

import shutil
import subprocess
import sys

from conftest import ROOT

SCRIPT = ROOT / "scripts" / "check_numbers.py"


def run(*args):
    return subprocess.run([sys.executable, str(SCRIPT), *map(str, args)], capture_output=True, text=True)


def test_the_repository_passes():
    p = run()
    assert p.returncode == 0, f"scripts/check_numbers.py failed:\n{p.stdout}{p.stderr}"
    assert p.stdout.startswith("ok:"), p.stdout


def planted(tmp_path, text):
    """A repository with this repository's BENCHMARKS.md and one guide holding `text`."""
    shutil.copy(ROOT / "BENCHMARKS.md", tmp_path / "BENCHMARKS.md")
    guide = tmp_path / "docs" / "guide" / "planted.md"
    guide.parent.mkdir(parents=True)
    guide.write_text(text)
    return tmp_path


def test_a_figure_not_in_benchmarks_fails(tmp_path):
    root = planted(tmp_path, "# Planted\n\nSome prose.\n\nFiltering with ifd is 17.3x faster than OpenCV's\nbins on a photograph.\n")
    p = run("--root", root)
    assert p.returncode == 1, p.stdout
    assert "docs/guide/planted.md:5: 17.3x is not in BENCHMARKS.md" in p.stdout, p.stdout
    assert "FAIL: 1 performance figure(s)" in p.stdout, p.stdout


def test_a_table_row_and_a_wrapped_sentence_fail(tmp_path):
    root = planted(tmp_path, "| tool | time |\n|---|---|\n| cmgen | 9.99 s |\n\nOn lavapipe the GPU path\nruns 123-456x slower.\n")
    p = run("--root", root)
    assert p.returncode == 1, p.stdout
    assert "planted.md:3: 9.99s" in p.stdout, p.stdout
    assert "planted.md:6: 123-456x" in p.stdout, p.stdout


def test_held_unrelated_and_marked_figures_pass(tmp_path):
    root = planted(
        tmp_path,
        "On lavapipe the GPU path is 35-273x slower than the CPU path\n"
        "([measured](../../BENCHMARKS.md#planar-evaluation-on-lavapipe)).\n\n"
        "The fit reaches 1% relative L2 error with 90 terms; a 4x4 grid; 1024x1024 pixels.\n\n"
        "Tested against brute force to 0.123%. <!-- numbers: not-a-benchmark -->\n\n"
        "<!-- numbers: not-a-benchmark -->\n"
        "A quoted paper's GPU ran at 999 Hz.\n\n"
        "```sh\n# 77x faster than OpenCV (a command block is not prose)\n```\n",
    )
    p = run("--root", root)
    assert p.returncode == 0, p.stdout


def test_a_figure_held_only_beside_another_peer_fails(tmp_path):
    # BENCHMARKS.md's "10x" is the smoothing floor beside brute force, not a lavapipe ratio
    root = planted(tmp_path, "A software adapter is about 10x slower than the CPU for a dab.\n")
    p = run("--root", root)
    assert p.returncode == 1, p.stdout
    assert "planted.md:1: 10x" in p.stdout, p.stdout


def test_a_link_to_a_missing_section_fails(tmp_path):
    root = planted(tmp_path, "Timings: [BENCHMARKS.md](../../BENCHMARKS.md#no-such-section).\n")
    p = run("--root", root)
    assert p.returncode == 1, p.stdout
    assert "planted.md:1: BENCHMARKS.md#no-such-section: BENCHMARKS.md has no such section" in p.stdout, p.stdout


def test_generated_reports_are_not_checked(tmp_path):
    root = planted(tmp_path, "Nothing here.\n")
    report = root / "docs" / "bench" / "report.md"
    report.parent.mkdir(parents=True)
    report.write_text("OpenCV best / ifd best = **17.3x**.\n")
    p = run("--root", root)
    assert p.returncode == 0, p.stdout
