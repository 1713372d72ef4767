#!/usr/bin/env python3
"""BENCHMARKS.md's tables against the steerable basis, from `curves_vs_opencv.py --json`
reports: per report, image and case, the best peer's time over ifd's at 45, 50, 55 and 60
dB, as the paired median over the rounds (each round's ratio of the two lower envelopes,
interpolated in PSNR as the report does; the machine's drift between rounds cancels) and
its range. Two rows each: ifd's best series (any `--eval-budgets` setting) and ifd with its
default evaluation budget only (series without "eval budget"). "n.r.": the peer never
reaches the PSNR in that run (ifd does); "-": ifd does not either. The last column is the
ratio at the highest PSNR the peer reaches (in every round), where it falls short of 60 dB.

    .venv/bin/python tests/bench/steerable_summary.py LABEL=REPORT.json [LABEL=REPORT.json ...]
"""

import json
import pathlib
import statistics
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import curves_vs_opencv as cvo  # noqa: E402

TARGETS = (45.0, 50.0, 55.0, 60.0)


def paired_at(pts, iseries, peers, t):
    """Each round's best peer / ifd best time at PSNR `t`; None unless both
    reach it in every round."""
    return cvo.paired_ratios(pts, iseries, peers, targets=(t,)).get(t)


def fmt(v):
    return f"{statistics.median(v):.1f}x ({min(v):.1f}-{max(v):.1f})"


def cell(pts, iseries, peers, t):
    v = paired_at(pts, iseries, peers, t)
    if v is not None:
        return fmt(v)
    reach = lambda series: any(q["psnr"] >= t for q in pts if q["series"] in series)  # noqa: E731
    if reach(iseries) and not reach(peers):
        return "n.r."
    return "-"


def cases(pts):
    """(image, case, its points) for each image and case of a report's points, in order."""
    keys = []
    for q in pts:
        if (q["image"], q["case"]) not in keys:
            keys.append((q["image"], q["case"]))
    for image, case in keys:
        yield image, case, [q for q in pts if (q["image"], q["case"]) == (image, case)]


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    print("| run | image, case | ifd | " + " | ".join(f"{t:.0f} dB" for t in TARGETS) + " | the peer's best PSNR |")
    print("|---|---|---|" + "---|" * (len(TARGETS) + 1))
    for arg in sys.argv[1:]:
        label, path = arg.split("=", 1)
        with open(path) as f:
            pts = json.load(f)["points"]
        for image, case, sub in cases(pts):
            ifd = sorted({q["series"] for q in sub if q["method"] == "ifd"})
            default = [s for s in ifd if "eval budget" not in s]
            peers = sorted({q["series"] for q in sub if q["method"] != "ifd"})
            # the highest PSNR every round of the peers reaches: their best point
            top = max(q["psnr"] for q in sub if q["method"] != "ifd")
            for name, series in (("best", ifd), ("default budget", default)):
                cells = [cell(sub, series, peers, t) for t in TARGETS]
                v = paired_at(sub, series, peers, top) if top < TARGETS[-1] else None
                cells.append(f"{top:.1f} dB: {fmt(v)}" if v else "")
                print(f"| {label} | {image}, {case} | ifd {name} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
