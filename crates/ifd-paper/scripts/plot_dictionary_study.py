"""Plot docs/dictionary-study.csv (written by the dictionary_study example of ifd-paper).

    .venv/bin/python crates/ifd-paper/scripts/plot_dictionary_study.py docs/dictionary-study.csv docs/dictionary-study.png

One panel per filter: relative L2 error (log) against the number of terms,
one line per dictionary configuration, joining the fits at decreasing target
errors (tol = 4%, 2%, 1%, 0.5%, 0.25%).
"""

import csv
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main() -> None:
    src = sys.argv[1] if len(sys.argv) > 1 else "docs/dictionary-study.csv"
    dst = sys.argv[2] if len(sys.argv) > 2 else "docs/dictionary-study.png"
    rows = list(csv.DictReader(open(src, newline="")))
    filters = list(dict.fromkeys(r["filter"] for r in rows))
    configs = list(dict.fromkeys(r["config"] for r in rows))
    data = defaultdict(list)
    for r in rows:
        data[(r["filter"], r["config"])].append((-float(r["tol"]), int(r["terms"]), float(r["rel_l2_error"])))
    fig, axes = plt.subplots(1, len(filters), figsize=(5.2 * len(filters), 4.4), sharey=True)
    styles = ["-o", "--s", "-.^", ":v", "-D", "--x", "-.P", ":*", "-h", "--p"]
    for ax, f in zip(axes, filters):
        for i, c in enumerate(configs):
            pts = sorted(data[(f, c)])
            if not pts:
                continue
            ax.plot([p[1] for p in pts], [100 * p[2] for p in pts], styles[i % len(styles)],
                    label=c, lw=2.2 if c == "default" else 1.0, ms=4,
                    color="black" if c == "default" else None)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.axhline(1.0, color="gray", lw=0.6)
        ax.set_title(f, fontsize=10)
        ax.set_xlabel("terms s")
        ax.grid(True, which="both", lw=0.3)
    axes[0].set_ylabel("relative L2 error (%)")
    axes[-1].legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    fig.savefig(dst, dpi=110)
    print(f"wrote {dst}")


if __name__ == "__main__":
    main()
