#!/usr/bin/env bash
# Coverage-guided fuzzing of every parser ifd owns (cargo-fuzz, libFuzzer with
# AddressSanitizer), on the stable toolchain through RUSTC_BOOTSTRAP=1.
#
#   scripts/fuzz.sh                     # every target: 600 s or 1,000,000 inputs, whichever first
#   scripts/fuzz.sh --time 60 npy image # two targets, a minute each
#   scripts/fuzz.sh --list              # the targets
#
# Options: --time SECONDS (per target, default 600), --runs N (default
# 1000000), --jobs J (targets fuzzed at once, default 1), --rss-mb MB (memory
# limit per input, default 2048; also the largest single allocation).
#
# Each target starts from fuzz/seeds/<target>/ and grows a working corpus in
# fuzz/corpus/<target>/ (not committed). An input that panics, aborts, hangs
# (over 20 s) or allocates past the limit is saved by libFuzzer under
# fuzz/artifacts/<target>/ and copied here into fuzz/regressions/<target>/,
# which is committed and replayed by `cargo test` (tests/fuzz_corpus.rs, and
# apps/ifd-brush/tests/replay.rs for strokes) once the bug is fixed. The
# harness functions are in fuzz/harness.rs and fuzz/harness_brush.rs.
#
# It ends with a table (target, inputs, seconds, inputs/s, corpus, result)
# and exits non-zero when any target failed. Logs: fuzz/artifacts/<target>.log.
set -uo pipefail
cd "$(dirname "$0")/.."
TIME=600
RUNS=1000000
JOBS=1
RSS=2048
targets=()
while [ $# -gt 0 ]; do
  case "$1" in
    --time) TIME=$2; shift 2 ;;
    --runs) RUNS=$2; shift 2 ;;
    --jobs) JOBS=$2; shift 2 ;;
    --rss-mb) RSS=$2; shift 2 ;;
    --list) sed -n 's/^name = "\(.*\)"/\1/p' fuzz/Cargo.toml | grep -v '^ifd-fuzz$'; exit 0 ;;
    -h|--help) sed -n '2,22p' "$0"; exit 0 ;;
    -*) echo "unknown option $1 (see --help)" >&2; exit 2 ;;
    *) targets+=("$1"); shift ;;
  esac
done
all=$(sed -n 's/^name = "\(.*\)"/\1/p' fuzz/Cargo.toml | grep -v '^ifd-fuzz$')
[ ${#targets[@]} -eq 0 ] && read -r -d '' -a targets <<<"$all"
for t in "${targets[@]}"; do
  grep -qx "$t" <<<"$all" || { echo "unknown target $t; targets: $(echo $all)" >&2; exit 2; }
done

if ! cargo fuzz --version >/dev/null 2>&1; then
  echo "installing cargo-fuzz (cargo install cargo-fuzz --locked)"
  cargo install cargo-fuzz --locked --quiet || { echo "cannot install cargo-fuzz" >&2; exit 2; }
fi
export RUSTC_BOOTSTRAP=1
echo "building the fuzz targets (release, debug assertions, AddressSanitizer)"
(cd fuzz && cargo fuzz build) || { echo "fuzz build failed" >&2; exit 2; }
BIN=$(pwd)/fuzz/target/$(rustc -vV | sed -n 's/^host: //p')/release

fuzz_one() {
  local t=$1 log=fuzz/artifacts/$1.log
  mkdir -p "fuzz/corpus/$t" "fuzz/artifacts/$t"
  local before
  before=$(ls "fuzz/artifacts/$t" | wc -l)
  local start=$SECONDS
  # The binaries built above, run directly (not `cargo fuzz run`, which
  # would rebuild from a tree that may have changed since).
  (cd fuzz && ASAN_OPTIONS=detect_odr_violation=0 "$BIN/$t" "corpus/$t" "seeds/$t" \
    -artifact_prefix="artifacts/$t/" \
    -max_total_time="$TIME" -runs="$RUNS" -rss_limit_mb="$RSS" -malloc_limit_mb="$RSS" \
    -timeout=20 -print_final_stats=1 -close_fd_mask=1) >"$log" 2>&1
  local rc=$?
  local secs=$((SECONDS - start))
  local execs
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  local result=ok
  if [ $rc -ne 0 ]; then
    result="FAILED (exit $rc)"
    mkdir -p "fuzz/regressions/$t"
    for f in fuzz/artifacts/"$t"/*; do
      [ -f "$f" ] && cp -n "$f" "fuzz/regressions/$t/"
    done
  fi
  local after
  after=$(ls "fuzz/artifacts/$t" | wc -l)
  [ "$after" -gt "$before" ] && [ $rc -eq 0 ] && result="FAILED (new artifact)"
  printf '%s\t%s\t%s\t%s\t%s\n' "$t" "${execs:-?}" "$secs" "$(ls "fuzz/corpus/$t" | wc -l)" "$result" >"fuzz/artifacts/$t.result"
  echo "$t: ${execs:-?} inputs in $secs s: $result"
}

running=0
for t in "${targets[@]}"; do
  rm -f "fuzz/artifacts/$t.result"
  fuzz_one "$t" &
  running=$((running + 1))
  if [ "$running" -ge "$JOBS" ]; then
    wait -n
    running=$((running - 1))
  fi
done
wait

echo
echo "| target | inputs | seconds | inputs/s | corpus | result |"
echo "|---|---:|---:|---:|---:|---|"
failed=0
for t in "${targets[@]}"; do
  IFS=$'\t' read -r name execs secs corpus result <"fuzz/artifacts/$t.result"
  rate='?'
  [ "$execs" != '?' ] && [ "$secs" -gt 0 ] && rate=$((execs / secs))
  echo "| $name | $execs | $secs | $rate | $corpus | $result |"
  [ "$result" = ok ] || failed=$((failed + 1))
done
if [ "$failed" -gt 0 ]; then
  echo "$failed target(s) failed: inputs copied to fuzz/regressions/<target>/ (see fuzz/artifacts/<target>.log)"
  exit 1
fi
