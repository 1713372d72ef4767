#!/usr/bin/env python3
"""One-off cost against PSNR from a `curves_vs_opencv.py --json` report: for a filter
used once, the fit is part of the wait. For each image, case and PSNR target, the
cheapest point of each method reaching the target, counting its fit (ifd's
decomposition; the steerable basis' weighted SVD, weights and kernel spectra; the
bins' kernels and spectra) plus its median time; then the ratio of the best peer to
ifd. Points are measured ones (no interpolation), so a ratio here is between two
runs that both reach the target.

    .venv/bin/python tests/bench/one_off_table.py docs/bench/ifd-vs-steerable.json
"""

import json
import sys

TARGETS = (45, 50, 55, 60)


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    d = json.load(open(sys.argv[1]))
    pts = d["points"]
    keys = []
    for p in pts:
        if (p["image"], p["case"]) not in keys:
            keys.append((p["image"], p["case"]))
    print("| image, case | " + " | ".join(f"{t} dB: peer / ifd (s)" for t in TARGETS) + " |")
    print("|---|" + "---|" * len(TARGETS))
    for image, case in keys:
        cells = []
        for t in TARGETS:
            best = {}
            for p in pts:
                if (p["image"], p["case"]) != (image, case) or p["psnr"] < t:
                    continue
                fit = p["params"].get("fit_seconds")
                if fit is None:
                    continue
                kind = "ifd" if p["method"] == "ifd" else "peer"
                cost = fit + p["ms"] / 1e3
                if kind not in best or cost < best[kind][0]:
                    best[kind] = (cost, p["series"])
            if "ifd" in best and "peer" in best:
                cells.append(f"{best['peer'][0]:.2f} / {best['ifd'][0]:.2f} = **{best['peer'][0] / best['ifd'][0]:.0f}x**")
            elif "ifd" in best:
                cells.append(f"peer n.r. / {best['ifd'][0]:.2f}")
            else:
                cells.append("-")
        print(f"| {image}, {case} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
