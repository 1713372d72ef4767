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
import statistics, subprocess, sys, time
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
jobs = {
    "decompose 8:1 Gaussian": ["decompose", "gauss:sx=16,sy=2,theta=0", "-o", f"{out}/g.json"],
    "filter 512x512, angle + scale maps": [
        "filter", "testdata/astronaut.png", "--decomp", f"{out}/gauss8.json",
        "--angle-map", f"{out}/swirl.npy", "--scale-map", f"{out}/scale.npy", "-o", f"{out}/f.png"],
    "smooth camera, S = 6": ["smooth", "testdata/camera.png", "--sigma", "6", "-o", f"{out}/s.png"],
    "sphere sh forest, L = 32": ["sphere", "sh", "testdata/forest.hdr", "--lmax", "32", "-o", f"{out}/sh.npy"],
    "render GGX sphere, L = 16, 384x384": [
        "render", "--env", "testdata/forest.hdr", "--brdf", "ggx:alpha=0.3", "--lmax", "16",
        "--size", "384x384", "-o", f"{out}/r.png"],
    "envmap prefilter forest": ["envmap", "prefilter", "testdata/forest.hdr", "--out-dir", f"{out}/ibl"],
}
def run(exe, args):
    t0 = time.perf_counter()
    r = subprocess.run([exe, *args], capture_output=True, text=True)
    dt = time.perf_counter() - t0
    if r.returncode != 0:
        sys.exit(f"{exe} {' '.join(args)} failed:\n{r.stderr}")
    return dt
print(f"{'job':40} {'base s':>8} {'new s':>8} {'new/base':>9}  (medians of {rounds}, interleaved)")
for name, args in jobs.items():
    run(new, args)  # warm the file cache
    tb, tn = [], []
    for _ in range(rounds):
        tb.append(run(base, args))
        tn.append(run(new, args))
    mb, mn = statistics.median(tb), statistics.median(tn)
    spread = (max(tb) - min(tb)) / mb
    print(f"{name:40} {mb:8.3f} {mn:8.3f} {mn / mb:9.3f}  (base spread {spread:.0%})")
PY
