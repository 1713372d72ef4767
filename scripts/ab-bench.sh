#!/usr/bin/env bash
# Interleaved A/B of the main jobs: the `ifd` CLI built (release) at a base
# revision and at the working tree, each job run alternately base, new,
# base, new, ... ROUNDS times on the same cores, whole process, bundled data.
# Prints the median wall time of each side and the ratio new / base; a
# ratio within the rounds' spread is noise.
#
#   scripts/ab-bench.sh BASE_REV [ROUNDS]     (default 5 rounds)
#
# The base is built in a temporary worktree with its own target folder
# (AB_BASE_TARGET, default target/ab-base), so the first run builds it cold.
set -euo pipefail
BASE=${1:?usage: scripts/ab-bench.sh BASE_REV [ROUNDS]}
ROUNDS=${2:-5}
root=$(git rev-parse --show-toplevel)
cd "$root"
work=$(mktemp -d)
git worktree add -q --detach "$work/base" "$BASE"
cleanup() {
  git worktree remove --force "$work/base" || true
  rm -rf "$work"
}
trap cleanup EXIT

base_target=${AB_BASE_TARGET:-$root/target/ab-base}
echo "==> building ifd at $BASE (release, $base_target)"
(cd "$work/base" && CARGO_TARGET_DIR="$base_target" cargo build --release --quiet -p ifd-cli)
echo "==> building ifd at the working tree (release)"
cargo build --release --quiet -p ifd-cli
new_target=${CARGO_TARGET_DIR:-$root/target}

python3 - "$base_target/release/ifd" "$new_target/release/ifd" "$ROUNDS" "$work" <<'PY'
import re, statistics, subprocess, sys, time
differ = []
base, new, rounds, work = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
out = f"{work}/out"
subprocess.run(["mkdir", "-p", out], check=True)
# Inputs both sides read (made once, by the new build).
prep = [
    ["decompose", "gauss:sx=16,sy=2,theta=0", "-o", f"{out}/gauss8.json"],
    ["field", "swirl", "--size", "512x512", "-o", f"{out}/swirl.npy"],
    ["field", "distance", "--size", "512x512", "--min", "0.5", "--max", "3", "-o", f"{out}/scale.npy"],
]
for p in prep:
    subprocess.run([new, *p], check=True, capture_output=True)
# Each job's output is written once per side ({o}: a path of the side's
# own); the filter jobs write .npy, compared byte for byte between the sides
# (a faster path must not change a bit), and print -v, whose filtering time
# (the per-pixel lookups alone) is reported beside the whole process.
jobs = {
    "decompose 8:1 Gaussian": ["decompose", "gauss:sx=16,sy=2,theta=0", "-o", "{o}.json"],
    "filter 512x512, angle + scale maps": [
        "filter", "testdata/camera.png", "--decomp", f"{out}/gauss8.json",
        "--angle-map", f"{out}/swirl.npy", "--scale-map", f"{out}/scale.npy", "-v", "-o", "{o}.npy"],
    "filter 512x512, angle map": [
        "filter", "testdata/camera.png", "--decomp", f"{out}/gauss8.json",
        "--angle-map", f"{out}/swirl.npy", "--eval-budget", "0.003", "-v", "-o", "{o}.npy"],
    "filter 512x512 RGB, angle map": [
        "filter", "testdata/astronaut.png", "--decomp", f"{out}/gauss8.json",
        "--angle-map", f"{out}/swirl.npy", "-v", "-o", "{o}.npy"],
    "filter 512x512 RGB, angle + scale, cubic": [
        "filter", "testdata/astronaut.png", "--decomp", f"{out}/gauss8.json",
        "--angle-map", f"{out}/swirl.npy", "--scale-map", f"{out}/scale.npy", "--interp", "cubic",
        "-v", "-o", "{o}.npy"],
    "smooth camera, S = 6": ["smooth", "testdata/camera.png", "--sigma", "6", "-o", "{o}.png"],
    "sphere sh forest, L = 32": ["sphere", "sh", "testdata/forest.hdr", "--lmax", "32", "-o", "{o}.npy"],
    "render GGX sphere, L = 16, 384x384": [
        "render", "--env", "testdata/forest.hdr", "--brdf", "ggx:alpha=0.3", "--lmax", "16",
        "--size", "384x384", "-o", "{o}.png"],
    "envmap prefilter forest": ["envmap", "prefilter", "testdata/forest.hdr", "--out-dir", "{o}"],
}
def run(exe, args, side):
    args = [a.replace("{o}", f"{out}/{side}") for a in args]
    t0 = time.perf_counter()
    r = subprocess.run([exe, *args], capture_output=True, text=True)
    dt = time.perf_counter() - t0
    if r.returncode != 0:
        sys.exit(f"{exe} {' '.join(args)} failed:\n{r.stderr}")
    m = re.search(r"filtering ([0-9.]+) ms", r.stdout + r.stderr)
    return dt, float(m.group(1)) if m else None
print(f"{'job':42} {'base s':>8} {'new s':>8} {'new/base':>9}  (medians of {rounds}, interleaved)")
for name, args in jobs.items():
    run(new, args, "new")  # warm the file cache
    tb, tn, fb, fn = [], [], [], []
    for _ in range(rounds):
        for side, exe, t, f in (("base", base, tb, fb), ("new", new, tn, fn)):
            dt, filtering = run(exe, args, side)
            t.append(dt)
            if filtering is not None:
                f.append(filtering)
    mb, mn = statistics.median(tb), statistics.median(tn)
    spread = (max(tb) - min(tb)) / mb
    print(f"{name:42} {mb:8.3f} {mn:8.3f} {mn / mb:9.3f}  (base spread {spread:.0%})")
    if fb and fn:
        b, n = statistics.median(fb), statistics.median(fn)
        print(f"{'  filtering alone (-v), ms':42} {b:8.1f} {n:8.1f} {n / b:9.3f}")
    if any(a.endswith(".npy") for a in args) and name.startswith("filter"):
        same = open(f"{out}/base.npy", "rb").read() == open(f"{out}/new.npy", "rb").read()
        print(f"{'  outputs':42} {'identical bit for bit' if same else 'DIFFER'}")
        if not same:
            differ.append(name)
if differ:
    sys.exit(f"outputs differ: {', '.join(differ)}")
PY
