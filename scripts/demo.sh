#!/usr/bin/env bash
# The main job on bundled data: decompose an 8:1 anisotropic Gaussian once, then
# apply it to a bundled photo with an angle that follows circles around the
# centre (a swirl blur) and a scale that grows towards the corners -- a
# spatially varying anisotropic filter up to ~400 px across, at the cost of one
# lookup per term and pixel; then shade a glossy sphere lit by the bundled
# environment map with ISD. Results land in out/demo/.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-out/demo}
mkdir -p "$OUT"
# The dev profile of this workspace is optimised (opt-level 2, dependencies
# 3: see Cargo.toml), so this shares its build with `cargo test` instead of
# compiling wgpu and everything else a second time for `--release`.
echo "==> building ifd (a few minutes on a fresh clone; cargo shows its progress)"
cargo build -p ifd-cli
IFD=${CARGO_TARGET_DIR:-target}/debug/ifd

echo "==> decomposing gauss:sx=16,sy=2 (8:1)"
"$IFD" decompose gauss:sx=16,sy=2,theta=0 -o "$OUT/gauss8.json" --plot "$OUT/gauss8-decomposition.png"

echo "==> angle and scale fields"
"$IFD" field swirl --size 512x512 -o "$OUT/swirl.npy"
"$IFD" field distance --size 512x512 --min 0.5 --max 3 -o "$OUT/scale.npy"

echo "==> filtering testdata/astronaut.png (spatially varying angle and scale)"
"$IFD" filter testdata/astronaut.png --decomp "$OUT/gauss8.json" \
  --angle-map "$OUT/swirl.npy" --scale-map "$OUT/scale.npy" -o "$OUT/astronaut-swirl.png" --verbose

echo "==> how far the result is from the input"
"$IFD" compare testdata/astronaut.png "$OUT/astronaut-swirl.png"

echo "==> the spherical half: a GGX sphere lit by the bundled forest map (ISD, Eq. 22)"
"$IFD" render --env testdata/forest.hdr --brdf ggx:alpha=0.3 --lmax 16 --size 384x384 \
  -o "$OUT/forest-ggx.png"

echo "==> IBL for engines: GGX-prefiltered mips, irradiance and SH of the forest map (KTX2)"
"$IFD" envmap prefilter testdata/forest.hdr --out-dir "$OUT/ibl"

echo
echo "done: $OUT/astronaut-swirl.png (filtered), $OUT/gauss8-decomposition.png (the fit),"
echo "      $OUT/forest-ggx.png (shading with isotropic spherical decomposition),"
echo "      $OUT/ibl/ (radiance.ktx2, irradiance.ktx2, sh.json, sh.npy)"
