#!/usr/bin/env bash
# Storage, interpolation error and build time of lobe tables (docs/shading.md):
#   bash crates/ifd-paper/scripts/table_study.sh > docs/shading-tables.csv
# (run from the repository root after `cargo build -p ifd-cli`).
set -euo pipefail
B=${IFD_BIN:-${CARGO_TARGET_DIR:-target}/debug/ifd}
echo "brdf,L,theta_entries,phi_entries,weight_bytes,interpolation_error,interpolation_rms,albedo_min,albedo_max,seconds"
for spec in phong:s=32 blinn:s=64 ggx:alpha=0.3 ggx:alpha=0.1 ward:alpha=0.2; do
  for L in 7 11 15 30; do
    $B sphere brdf "$spec" --lmax $L -o /tmp/s.lobes --json | python3 -c "import json,sys; d=json.load(sys.stdin); print(','.join((chr(34)+str(d[k])+chr(34) if k=='brdf' else str(d[k])) for k in ['brdf','lmax','theta_entries','phi_entries','weight_bytes','interpolation_error','interpolation_rms','albedo_min','albedo_max','seconds']))"
  done
done
for L in 7 15; do
  $B sphere brdf "ggx:ax=0.2,ay=0.5" --lmax $L -o /tmp/s.lobes --json | python3 -c "import json,sys; d=json.load(sys.stdin); print(','.join((chr(34)+str(d[k])+chr(34) if k=='brdf' else str(d[k])) for k in ['brdf','lmax','theta_entries','phi_entries','weight_bytes','interpolation_error','interpolation_rms','albedo_min','albedo_max','seconds']))"
done
