#!/usr/bin/env bash
# Timings of ifd's GPU paths, from prebuilt binaries and the bundled data,
# written as one JSON file:
#
#   planar   a 256-term decomposition of an 8:1 Gaussian applied with a
#            per-pixel angle map to testdata/astronaut.png by `ifd filter
#            --gpu` (GPU time of the evaluation from timestamp queries,
#            median over runs; the CPU evaluation of the same run beside it);
#   isd      `ifd render --gpu --frames N` of a GGX sphere (alpha 0.3) under
#            testdata/forest.hdr at L = 7, 15 and 30 (median GPU time per
#            frame, frames per second);
#   brush    `ifd-brush` replaying strokes headless on camera.png with
#            --device gpu and --device cpu (whole replay, prefiltering
#            included; median over runs).
#
# It needs no Rust toolchain and no network: only the two binaries (a
# stripped release build is about 16 MB each), testdata/ and python3 (its
# standard library). Prepare them on a machine that builds:
#
#   cargo build --release -p ifd-cli -p ifd-brush
#   mkdir -p dist && strip -o dist/ifd target/release/ifd \
#     && strip -o dist/ifd-brush target/release/ifd-brush
#
# and run it where the GPU is:
#
#   scripts/gpu-bench.sh --bin dist --out gpu-bench.json
#
#   --bin DIR    folder of ifd and ifd-brush (default: target/release)
#   --out FILE   the JSON report (default: gpu-bench.json)
#   --runs N     process runs per planar/brush measurement (default 5)
#   --frames N   frames per ISD degree (default 20)
#   --quick      small sizes, 2 runs, 2 frames: a check that every step works
#                (the test suite runs this on lavapipe)
set -euo pipefail
export LC_ALL=C
root=$(cd "$(dirname "$0")/.." && pwd)
bin=$root/target/release
out=gpu-bench.json
runs=5
frames=20
quick=0
while [[ $# -gt 0 ]]; do
  case $1 in
    --bin) bin=${2:?--bin needs a folder}; shift 2 ;;
    --out) out=${2:?--out needs a file}; shift 2 ;;
    --runs) runs=${2:?--runs needs a count}; shift 2 ;;
    --frames) frames=${2:?--frames needs a count}; shift 2 ;;
    --quick) quick=1; runs=2; frames=2; shift ;;
    -h|--help) sed -n '2,33p' "$0"; exit 0 ;;
    *) echo "gpu-bench.sh: unknown option $1 (--help)" >&2; exit 2 ;;
  esac
done
for n in "$runs" "$frames"; do
  if ! [[ $n =~ ^[1-9][0-9]*$ ]]; then
    echo "gpu-bench.sh: --runs and --frames take a count of at least 1, not $n" >&2
    exit 2
  fi
done
for exe in ifd ifd-brush; do
  if [[ ! -x $bin/$exe ]]; then
    echo "gpu-bench.sh: $bin/$exe not found (--bin DIR; build with cargo build --release -p ifd-cli -p ifd-brush)" >&2
    exit 2
  fi
done
command -v python3 >/dev/null || { echo "gpu-bench.sh: python3 is needed" >&2; exit 2; }
ifd=$bin/ifd
brush=$bin/ifd-brush
data=$root/testdata
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# a failing step shows what its command printed before the folder goes
trap 'echo "gpu-bench.sh: a step failed; its logs:" >&2; tail -n 20 "$work"/*.log >&2 2>/dev/null || true' ERR

if [[ $quick == 1 ]]; then
  image=$data/camera.png; render_size=128x96; degrees="7"; terms=64
else
  image=$data/astronaut.png; render_size=1024x768; degrees="7 15 30"; terms=256
fi
log() { echo "==> $*" >&2; }

log "adapter"
"$ifd" gpu-info -v > "$work/adapter.txt" 2> "$work/gpu-info.log"

log "planar: fitting a decomposition with $terms terms"
"$ifd" decompose gauss:sx=24,sy=3,theta=0 --max-terms "$terms" --tol 0.001 --json \
  -o "$work/decomp.json" > "$work/decompose.json" 2> "$work/decompose.log"
python3 - "$image" "$work/angle.npy" <<'EOF'
# a per-pixel angle map (degrees) of the image's size: circles about the centre
import math, struct, sys, zlib
def png_size(path):
    with open(path, "rb") as f:
        head = f.read(24)
    return struct.unpack(">II", head[16:24])
w, h = png_size(sys.argv[1])
header = "{'descr': '<f4', 'fortran_order': False, 'shape': (%d, %d), }" % (h, w)
header += " " * (63 - (len(header) + 10) % 64) + "\n"
with open(sys.argv[2], "wb") as f:
    f.write(b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header.encode())
    row = bytearray()
    for y in range(h):
        row.clear()
        for x in range(w):
            row += struct.pack("<f", math.degrees(math.atan2(y - h / 2, x - w / 2)) + 90.0)
        f.write(row)
EOF
for ((i = 0; i < runs; i++)); do
  "$ifd" filter "$image" --decomp "$work/decomp.json" --angle-map "$work/angle.npy" --gpu -v \
    -o "$work/planar-gpu.exr" 2>> "$work/planar-gpu.log" >/dev/null
  TIMEFORMAT=%R
  { time "$ifd" filter "$image" --decomp "$work/decomp.json" --angle-map "$work/angle.npy" \
      -o "$work/planar-cpu.exr" 2>> "$work/planar-cpu.log" >/dev/null; } 2> "$work/planar-cpu-$i.time"
done

log "isd: ifd render --gpu --frames $frames at $render_size, L = $degrees"
for l in $degrees; do
  "$ifd" render --env "$data/forest.hdr" --brdf ggx:alpha=0.3 --lmax "$l" --size "$render_size" \
    --gpu --frames "$frames" --json -o "$work/isd-$l.exr" 2> "$work/isd-$l.log" > "$work/isd-$l.json"
done

log "brush: headless replay, --device gpu and cpu"
cat > "$work/strokes.json" <<'EOF'
{"format": "ifd-brush-strokes", "version": 1, "strokes": [
  {"brush": {"radius": 40, "scale": 6, "mode": "per-pixel"}, "points": [[150, 60], [250, 70], [340, 140]]},
  {"brush": {"radius": 48, "mode": "dab"}, "points": [[60, 420], [450, 430]]}]}
EOF
for dev in gpu cpu; do
  # the first run fits the aspect bank (cached) and is not counted
  for ((i = -1; i < runs; i++)); do
    "$brush" "$data/camera.png" --replay "$work/strokes.json" --device "$dev" \
      --no-journal --exit 2>> "$work/brush-$dev-$i.log" >/dev/null
  done
done

python3 - "$work" "$out" "$runs" "$frames" "$degrees" "$render_size" "$image" <<'EOF'
import glob, json, os, re, statistics, sys
work, out, runs, frames, degrees, size, image = sys.argv[1:8]
def median(v):
    v = [x for x in v if x is not None]
    return statistics.median(v) if v else None
adapter = dict(line.split(": ", 1) for line in open(os.path.join(work, "adapter.txt")).read().splitlines()
               if ": " in line and not line.startswith(("error", "note")))
decomp = json.load(open(os.path.join(work, "decompose.json")))
gpu_ms, wall_ms = [], []
for line in open(os.path.join(work, "planar-gpu.log")):
    m = re.search(r"evaluation \+ readback ([0-9.]+) ms \(([0-9.]+) ms GPU time\)", line)
    if m:
        wall_ms.append(float(m.group(1)))
        gpu_ms.append(float(m.group(2)))
    elif "evaluation + readback" in line:
        m = re.search(r"evaluation \+ readback ([0-9.]+) ms", line)
        wall_ms.append(float(m.group(1)))
cpu_s = [float(open(p).read().split()[-1]) for p in glob.glob(os.path.join(work, "planar-cpu-*.time"))]
isd = []
for l in degrees.split():
    r = json.load(open(os.path.join(work, f"isd-{l}.json")))
    g = r.get("gpu") or {}
    isd.append({"lmax": int(l), "size": size, "frames": g.get("frames"),
                "gpu_ms_median": None if g.get("gpu_seconds_median") is None else 1e3 * g["gpu_seconds_median"],
                "frame_ms_median": None if g.get("frame_seconds_median") is None else 1e3 * g["frame_seconds_median"],
                "fps_gpu": g.get("fps_gpu"), "upload_s": g.get("upload_seconds")})
brush = {}
for dev in ("gpu", "cpu"):
    secs, dabs, compute = [], None, None
    for p in sorted(glob.glob(os.path.join(work, f"brush-{dev}-*.log"))):
        if p.endswith("--1.log"):
            continue
        text = open(p).read()
        m = re.search(r"replayed (\d+) dabs in ([0-9.]+) s", text)
        if m:
            dabs, secs = int(m.group(1)), secs + [float(m.group(2))]
        m = re.search(r"compute: (.*)", text)
        if m:
            compute = m.group(1)
    brush[dev] = {"dabs": dabs, "replay_s_median": median(secs), "runs": len(secs), "compute": compute}
report = {
    "adapter": adapter,
    "planar": {"image": os.path.basename(image), "terms": decomp.get("terms"), "runs": int(runs),
               "gpu_eval_ms_median": median(gpu_ms), "gpu_eval_readback_ms_median": median(wall_ms),
               "cpu_whole_process_s_median": median(cpu_s)},
    "isd": isd,
    "brush": brush,
}
missing = [k for k, v in [("planar GPU time", report["planar"]["gpu_eval_readback_ms_median"]),
                          ("brush gpu", brush["gpu"]["replay_s_median"]),
                          ("brush cpu", brush["cpu"]["replay_s_median"])] if v is None]
missing += [f"isd L={x['lmax']}" for x in isd if x["frame_ms_median"] is None]
with open(out, "w") as f:
    json.dump(report, f, indent=2)
print(json.dumps(report, indent=2))
if missing:
    sys.exit("gpu-bench.sh: no timing for " + ", ".join(missing))
EOF
