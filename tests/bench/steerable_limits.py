#!/usr/bin/env python3
"""Where ifd falls short of the steerable-basis goals, what each side's time is made of:
BENCHMARKS.md's table of measured limits, from `curves_vs_opencv.py --json` reports.

For every report, image, case and PSNR (45, 50, 55, 60 dB, and the best PSNR the peer
reaches where that is lower) at which ifd's paired median ratio (as `steerable_summary.py`
computes it, ifd's best series) is below the report's goal, one row:

- ifd's cheapest point that reaches the PSNR (median of its rounds): its terms, its time
  split into planning + prefiltering and the per-pixel lookups, and the lookups' cost per
  term and pixel (ns);
- the peer's cheapest point that reaches it: K basis kernels (or bins), its time and its
  cost per basis kernel (time / K);
- the lookup bound: the peer's time over ifd's lookups alone, the ratio ifd would have if
  planning and prefiltering took no time. Where it is below the goal, the goal is out of
  reach of these lookups at all; where it is above, the distance is in the prefiltering.

    .venv/bin/python tests/bench/steerable_limits.py LABEL=GOAL=REPORT.json [...]

GOAL is the ratio the issue asks for in that run (2 for the standard case, 5 elsewhere).
"""

import json
import pathlib
import statistics
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import curves_vs_opencv as cvo  # noqa: E402
import steerable_summary  # noqa: E402

TARGETS = (45.0, 50.0, 55.0, 60.0)


def cheapest(points, t):
    """The point of least median time among `points` reaching `t` dB."""
    ok = [q for q in points if q["psnr"] >= t]
    return min(ok, key=lambda q: q["ms"]) if ok else None


def basis_count(q):
    p = q["params"]
    return p.get("k") or p.get("bins") or 1


def rows(label, goal, report):
    with open(report) as f:
        d = json.load(f)
    n = d["meta"]["size"]
    for image, case, sub in steerable_summary.cases(d["points"]):
        ifd = [q for q in sub if q["method"] == "ifd"]
        peers = [q for q in sub if q["method"] != "ifd"]
        if not ifd or not peers:
            continue
        iseries = sorted({q["series"] for q in ifd})
        pseries = sorted({q["series"] for q in peers})
        top = max(q["psnr"] for q in peers)
        targets = [t for t in TARGETS if t <= top] + ([top] if top < TARGETS[-1] else [])
        for t in targets:
            v = cvo.paired_ratios(sub, iseries, pseries, targets=(t,)).get(t)
            if v is None or statistics.median(v) >= goal:
                continue
            qi, qp = cheapest(ifd, t), cheapest(peers, t)
            if qi is None or qp is None:
                continue
            pre, look = qi["prefilter_ms"], qi["filter_ms"]
            if not look > 0:
                continue
            ns = look * 1e6 / (n * n * qi["params"]["terms"])
            k = basis_count(qp)
            yield (
                f"| {label} | {image}, {case} | {t:.1f} | {statistics.median(v):.1f}x | {goal:g}x "
                f"| {qi['params']['terms']} terms: {pre:.0f} + {look:.0f} ms ({ns:.2f} ns) "
                f"| {qp['series'].split(' ')[0]} {qp['note']}: {qp['ms']:.0f} ms ({qp['ms'] / k:.1f} ms each) "
                f"| {qp['ms'] / look:.1f}x |"
            )


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    print(
        "| run | image, case | dB | now | goal | ifd: planning + prefiltering + lookups (per term and pixel) "
        "| peer: K, time (per basis kernel) | lookup bound |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for arg in sys.argv[1:]:
        label, goal, path = arg.split("=", 2)
        for r in rows(label, float(goal), path):
            print(r)


if __name__ == "__main__":
    main()
