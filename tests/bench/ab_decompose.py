#!/usr/bin/env python3
"""Fit time of two `ifd` builds, alternating run by run: `ifd decompose SPEC` whole process,
medians, and whether both gave the same terms bit for bit.

    tests/bench/ab_decompose.py BASE_IFD NEW_IFD ROUNDS [SPEC]
"""
import statistics, subprocess, sys, time, json
base, new, rounds = sys.argv[1], sys.argv[2], int(sys.argv[3])
spec = sys.argv[4] if len(sys.argv) > 4 else "gauss:sx=16,sy=2,theta=0"
import tempfile
out = tempfile.mkdtemp()
t = {"b": [], "n": []}
for _ in range(rounds):
    for side, exe in (("b", base), ("n", new)):
        t0 = time.perf_counter()
        subprocess.run([exe, "decompose", spec, "-o", f"{out}/fit-{side}.json"], check=True, capture_output=True)
        t[side].append(time.perf_counter() - t0)
b, n = statistics.median(t["b"]), statistics.median(t["n"])
print(f"{spec}: base {b:.3f} s, new {n:.3f} s, ratio {b/n:.2f}x (medians of {rounds})")
jb, jn = json.load(open(f"{out}/fit-b.json")), json.load(open(f"{out}/fit-n.json"))
print("terms identical:", jb["terms"] == jn["terms"], len(jb["terms"]), len(jn["terms"]), jb["report"]["rel_l2_error"], jn["report"]["rel_l2_error"])
