"""The ZHF paper's Table II for this code: multiplication counts of its rotations
against the paper's zxzxz counts, and measured rotation times per order N = 2..20
against ducc0's rotate_alm in one run (issue 14 item 9).

Run from the repository root:
    .venv/bin/python tests/bench/zhf_table2.py [--no-timings] [--out FILE.md]

Counts (one function, one channel, order N = L + 1, shared lobes: 2N - 1 directions,
band l using the first 2l + 1), derived from the code (crates/ifd-sphere/src/sh.rs
`eval_body!`, zhf.rs `zhf`/`rotate_rzh`/`rotate_tailored`/`tailored_from_samples`,
tabulated.rs `BandTables::rotate`):
  E(L)  SH evaluation: 6 to normalise; per m >= 1: 4 for (x + iy)^m and 2 for
        sqrt(2) c, s; 2 per stored (l, m > 0); 2 for the first step of each m < L;
        3 per further step of the Legendre recurrence.
  D     dense band blocks: sum_l (2l + 1)^2 = N (4N^2 - 1) / 3.
  standard (Eq. 10):  zhf D  +  per lobe (9 to rotate it + E(L))  +  2 D ([Y^R]^T z with pi_l).
  tailored (Eq. 11):  per lobe (9 + E(L))  +  D (band samples)  +  D + N^2 ((M^-1)^T, pi_l).
  tabulated (Eq. 11, lookups): per lobe (9 + 8 for the bilinear taps)  +  4 per (lobe, band
        served) = 4 N^2  +  D + N^2.
  sparse: the same with the dense (M^-1)^T replaced by its nonzeros for the order-N shared set of
        `ifd-paper zhf-sparsity` (read from docs/zhf-sparsity.md; orders 2..8), as the paper counts
        its hard-coded sparse multiplication. Our code multiplies densely; the sparse column is
        what hard-coding the found sets would cost.
zxzxz: the paper's Table II totals (its optimised CPU implementation), quoted.

Timings (--timings, default): `cargo bench -p ifd-sphere --bench sphere -- rotate` (criterion,
release profile, one thread; medians of its samples) for zhf, tailored and tabulated, then, in
the same run, ducc0.sht.rotate_alm (one thread) three ways: one function per call; the same
with the call overhead subtracted (the overhead: the time of a call at lmax = 0, one
coefficient); and per function in a batch of 256 functions per call (ncomp = 256, the API's
batching, which also shares the rotation's own work across the functions). Medians of 7 repeats
of timeit's best.
"""

import argparse
import json
import pathlib
import re
import subprocess
import sys
import timeit

ROOT = pathlib.Path(__file__).resolve().parents[2]

# the paper's Table II (N = 3..19)
PAPER_ZXZXZ = dict(zip(range(3, 20), [112, 192, 300, 442, 620, 834, 1092, 1400, 1760, 2172, 2648,
                                       3188, 5056, 7176, 9564, 12236, 15208]))
PAPER_STANDARD_CPU = dict(zip(range(3, 20), [90, 275, 606, 1123, 1891, 2930, 4297, 6046, 8199,
                                             10783, 13860, 17495, 21672, 26550, 32014, 38256,
                                             45311]))
PAPER_TAILORED = dict(zip(range(3, 20), [9, 33, 75, 137, 246, 384, 570, 820, 1118, 1453, 1849,
                                         2333, 2851, 3524, 4199, 5030, 6014]))


def sh_eval_mults(L):
    m = 6
    for mm in range(1, L + 1):
        m += 6 + 2 * (L - mm + 1)
    for mm in range(0, L):
        m += 2 + 3 * max(L - mm - 1, 0)
    return m


def dense(N):
    return sum((2 * l + 1) ** 2 for l in range(N))


def sparsity_table():
    """Order N -> sparsity (fraction) of the shared set, from docs/zhf-sparsity.md."""
    path = ROOT / "docs" / "zhf-sparsity.md"
    out = {}
    if not path.exists():
        return out
    in_orders = False
    for line in path.read_text().splitlines():
        if line.startswith("| order N"):
            in_orders = True
            continue
        m = re.match(r"\|\s*(\d+)\s*\|\s*([\d.]+)\s*\|", line)
        if in_orders and m:
            out[int(m.group(1))] = float(m.group(2)) / 100
    return out


def counts(N, sp):
    L = N - 1
    J = 2 * N - 1
    E = sh_eval_mults(L)
    D = dense(N)
    row = {
        "N": N, "sh_eval": E, "dense_blocks": D,
        "standard": D + J * (9 + E) + 2 * D,
        "tailored": J * (9 + E) + D + D + N * N,
        "tabulated": J * (9 + 8) + 4 * N * N + D + N * N,
    }
    if N in sp:
        # bands 1..N-1 sparse as found, band 0 one entry
        nnz = round((1 - sp[N]) * (D - 1)) + 1
        row["sparse_nnz"] = nnz
        row["tailored_sparse"] = J * (9 + E) + D + nnz + N * N
        row["tabulated_sparse"] = J * (9 + 8) + 4 * N * N + nnz + N * N
    return row


def criterion_medians():
    subprocess.run(["cargo", "bench", "-p", "ifd-sphere", "--bench", "sphere", "--", "rotate",
                    "--noplot"], cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    base = ROOT / "target" / "criterion" / "rotate"
    out = {}
    for method in ["zhf", "tailored", "tabulated", "reference"]:
        for N in range(2, 21):
            est = base / method / str(N) / "new" / "estimates.json"
            if est.exists():
                out[(method, N)] = json.loads(est.read_text())["median"]["point_estimate"] * 1e-9
    return out


def ducc0_times(N, repeats=7, batch=256):
    import ducc0
    import numpy as np

    L = N - 1
    ncoef = (L + 1) * (L + 2) // 2
    rng = np.random.default_rng(N)
    one = (rng.standard_normal(ncoef) + 1j * rng.standard_normal(ncoef)).astype(np.complex128)
    many = (rng.standard_normal((batch, ncoef)) + 1j * rng.standard_normal((batch, ncoef)))
    many = many.astype(np.complex128)

    def best(f, number):
        return min(timeit.repeat(f, repeat=3, number=number)) / number

    singles, batched = [], []
    for _ in range(repeats):
        singles.append(best(lambda: ducc0.sht.rotate_alm(one, L, 0.3, 1.1, -0.7, 1), 2000))
        batched.append(best(lambda: ducc0.sht.rotate_alm(many, L, 0.3, 1.1, -0.7, 1), 20) / batch)
    singles.sort()
    batched.sort()
    return {"single": singles[repeats // 2], "per_function_batched": batched[repeats // 2]}


def ducc0_overhead(repeats=7):
    """The call overhead: one call at lmax = 0 (one coefficient, no work to speak of)."""
    import ducc0
    import numpy as np

    one = np.array([1.0 + 0.0j])
    t = sorted(min(timeit.repeat(lambda: ducc0.sht.rotate_alm(one, 0, 0.3, 1.1, -0.7, 1),
                                 repeat=3, number=5000)) / 5000 for _ in range(repeats))
    return t[repeats // 2]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--no-timings", action="store_true", help="counts only")
    ap.add_argument("--out", type=pathlib.Path, help="also write the tables as Markdown")
    args = ap.parse_args()
    sp = sparsity_table()
    rows = [counts(N, sp) for N in range(2, 21)]
    md = ["| N | SH eval | standard (Eq. 10) | tailored (Eq. 11) | tabulated | tailored, sparse | "
          "tabulated, sparse | paper: zxzxz | paper: standard CPU | paper: tailored (sparse) |",
          "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        N = r["N"]
        md.append(f"| {N} | {r['sh_eval']} | {r['standard']} | {r['tailored']} | {r['tabulated']} | "
                  f"{r.get('tailored_sparse', '-')} | {r.get('tabulated_sparse', '-')} | "
                  f"{PAPER_ZXZXZ.get(N, '-')} | {PAPER_STANDARD_CPU.get(N, '-')} | "
                  f"{PAPER_TAILORED.get(N, '-')} |")
    out = {"counts": rows}
    if not args.no_timings:
        crit = criterion_medians()
        md += ["", "| N | zhf (us) | tailored | tabulated | ducc0, one call | ducc0 overhead | "
               "ducc0, corrected | ducc0, batched per function | best ZHF / ducc0 corrected |",
               "|---|---|---|---|---|---|---|---|---|"]
        timing_rows = []
        crossover = None
        overhead = ducc0_overhead()
        for N in range(3, 21):
            d = ducc0_times(N)
            d["overhead"] = overhead
            d["single_corrected"] = max(d["single"] - overhead, 1e-12)
            ours = {m: crit.get((m, N)) for m in ["zhf", "tailored", "tabulated"]}
            best_ours = min(v for v in ours.values() if v is not None)
            ratio = best_ours / d["single_corrected"]
            if ratio >= 1 and crossover is None:
                crossover = N
            us = lambda x: "-" if x is None else f"{x * 1e6:.2f}"
            md.append(f"| {N} | {us(ours['zhf'])} | {us(ours['tailored'])} | {us(ours['tabulated'])} | "
                      f"{us(d['single'])} | {us(d['overhead'])} | {us(d['single_corrected'])} | "
                      f"{us(d['per_function_batched'])} | {ratio:.2f} |")
            timing_rows.append({"N": N, **{k: v for k, v in ours.items()}, **d})
            print(md[-1], file=sys.stderr)
        md.append("")
        md.append(f"First order where ducc0 (corrected) is faster than the best ZHF variant: "
                  f"{crossover if crossover else 'none up to 20'}.")
        out["timings"] = timing_rows
        out["crossover"] = crossover
    text = "\n".join(md) + "\n"
    print(text)
    if args.out:
        args.out.write_text(text)
        args.out.with_suffix(".json").write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
