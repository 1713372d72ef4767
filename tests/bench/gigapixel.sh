#!/usr/bin/env bash
# Filters an N x N RGB float32 image (default 20000: 4.8 GB as float32) with a
# spatially varying 8:1 Gaussian of extent 257 (gauss:sx=32,sy=4, rotated per
# pixel along circles) under --memory-budget MIB (default 4096), tile by tile,
# and reports the peak resident memory and the time (/usr/bin/time -v).
# With OP = smooth, smooths it instead (ifd smooth --sigma 4, per pixel: the
# Hessian field, its tensor averaging and the anisotropic filters, tile by
# tile).
#
#   tests/bench/gigapixel.sh [N] [BUDGET_MIB] [DIR] [filter|smooth]
#
# Needs about 11 * N^2 * 4 bytes of disk in DIR (default /tmp/ifd-gigapixel):
# the image, the angle map and the output. Uses target/release/ifd when built,
# else target/debug/ifd (the dev profile is optimised).
set -euo pipefail
N=${1:-20000}
BUDGET=${2:-4096}
DIR=${3:-/tmp/ifd-gigapixel}
OP=${4:-filter}
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
T=${CARGO_TARGET_DIR:-$ROOT/target}
IFD=$T/release/ifd
[ -x "$IFD" ] || IFD=$T/debug/ifd
PY=${PYTHON:-$ROOT/.venv/bin/python}
mkdir -p "$DIR"
cd "$DIR"
[ -f img.npy ] && [ "$(stat -c %s img.npy)" -gt $((N * N * 12)) ] || "$PY" "$ROOT/tests/bench/make_large_npy.py" "$N"
case $OP in
  filter)
    "$IFD" decompose gauss:sx=32,sy=4,theta=0 -o g8.json >/dev/null
    set -- filter img.npy --decomp g8.json --angle-map angle.npy ;;
  smooth)
    set -- smooth img.npy --sigma 4 ;;
  *) echo "unknown OP $OP (filter or smooth)" >&2; exit 2 ;;
esac
/usr/bin/time -v "$IFD" "$@" --memory-budget "$BUDGET" -v -o out.npy 2>&1 |
  grep -E "tiled:|Maximum resident|Elapsed|Exit status|error"
