#!/usr/bin/env bash
# The whole ifd test suite, set-up included. Safe to re-run: every step that
# installs something skips itself when already done.
#
#   1. Debian packages (software Vulkan, Xvfb and the X11/EGL libraries the GPU
#      and GUI tests need, python3-venv), when missing and when running as root.
#      XDG_RUNTIME_DIR is set to a fresh private folder when unset.
#   2. A Python virtual environment in .venv with the reference libraries
#      (reused when tests/python/requirements.txt has not changed), and the
#      Node packages of tests/js (ktx-parse, an independent KTX2 reader; Node
#      and npm from Debian when missing).
#   3. rustfmt and clippy (rustup component add, when missing), then
#      cargo fmt --check, cargo clippy --all-targets -D warnings, cargo doc
#      with warnings denied, cargo machete (unused dependencies; installed
#      with cargo install when missing), the module-cycle check
#      (scripts/module_cycles.py), the public API lists
#      (scripts/public_api.py, rustdoc JSON), the architecture check
#      (scripts/check_architecture.py), the docs' performance figures
#      against BENCHMARKS.md (scripts/check_numbers.py), cargo test.
#   4. The Python module `ifd` (crates/ifd-py) built and installed into .venv
#      (maturin develop, the test profile), then the reference comparisons in
#      tests/python (pytest; scikit-image, OpenCV, SciPy, pyshtools, ducc0
#      against the `ifd` binary and the module).
# It ends with one line `N passed, M failed, K skipped, X known failures`
# (skips -- #[ignore]d tests, tests that returned early under IFD_GPU_TESTS=skip
# or IFD_WINDOW_TESTS=skip, pytest skips -- and known failures, pytest's xfails whose reasons are in the docs,
# are never counted as passes; a strict known failure that passes fails the
# run, a non-strict one is counted with the known failures) and exits
# non-zero on any failure.
set -uo pipefail
cd "$(dirname "$0")/.."
ROOT=$(pwd)
LOG_DIR=${IFD_TEST_LOG_DIR:-$ROOT/tests/artifacts}
mkdir -p "$LOG_DIR"
passed=0
failed=0
skipped=0
xfailed=0
failures=()
start=$(date +%s)

step() { printf '\n==> %s\n' "$*"; }
ok() { passed=$((passed + ${2:-1})); echo "ok: $1"; }
fail() { failed=$((failed + ${2:-1})); failures+=("$1"); echo "FAILED: $1"; }

APT_PACKAGES=(mesa-vulkan-drivers libvulkan1 xvfb xauth libxkbcommon-x11-0 libxkbcommon0
  libx11-6 libx11-xcb1 libxcursor1 libxi6 libgl1-mesa-dri libegl1 libegl-mesa0 libgl1
  libwayland-client0 x11-apps python3-venv)

# Mesa and winit complain on every start when XDG_RUNTIME_DIR is unset (as under
# CI or sudo): give the whole run a private one.
if [ -z "${XDG_RUNTIME_DIR:-}" ] || [ ! -d "$XDG_RUNTIME_DIR" ]; then
  XDG_RUNTIME_DIR=$(mktemp -d "${TMPDIR:-/tmp}/ifd-xdg-runtime.XXXXXX")
  chmod 700 "$XDG_RUNTIME_DIR"
  export XDG_RUNTIME_DIR
  trap 'rm -rf "$XDG_RUNTIME_DIR"' EXIT
fi

step "Debian packages"
missing=()
for p in "${APT_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "all present"
elif [ "$(id -u)" -eq 0 ]; then
  echo "installing: ${missing[*]}"
  if (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}") >"$LOG_DIR/apt.log" 2>&1; then
    ok "apt packages"
  else
    tail -20 "$LOG_DIR/apt.log"
    fail "apt packages (see $LOG_DIR/apt.log)"
  fi
else
  echo "warning: not root, cannot install: ${missing[*]}"
fi

step "Python virtual environment (.venv)"
PY=${PYTHON:-python3}
REQ=tests/python/requirements.txt
STAMP=.venv/.requirements.sha256
want=$(sha256sum "$REQ" | cut -d' ' -f1)
if [ ! -x .venv/bin/python ] || [ "$(cat "$STAMP" 2>/dev/null)" != "$want" ]; then
  if "$PY" -m venv .venv >"$LOG_DIR/pip.log" 2>&1 &&
    .venv/bin/pip install -q --upgrade pip >>"$LOG_DIR/pip.log" 2>&1 &&
    .venv/bin/pip install -q -r "$REQ" >>"$LOG_DIR/pip.log" 2>&1; then
    echo "$want" >"$STAMP"
    ok "python venv"
  else
    tail -20 "$LOG_DIR/pip.log"
    fail "python venv (see $LOG_DIR/pip.log)"
  fi
else
  echo "up to date"
fi

step "Node packages (tests/js: ktx-parse)"
if ! command -v node >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1; then
  if [ "$(id -u)" -eq 0 ] &&
    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends nodejs npm) >"$LOG_DIR/apt-node.log" 2>&1; then
    ok "apt nodejs npm"
  else
    tail -5 "$LOG_DIR/apt-node.log" 2>/dev/null
    fail "node and npm missing (apt-get install nodejs npm)"
  fi
fi
NODE_STAMP=tests/js/node_modules/.lock.sha256
want_node=$(sha256sum tests/js/package-lock.json | cut -d' ' -f1)
if [ "$(cat "$NODE_STAMP" 2>/dev/null)" = "$want_node" ]; then
  echo "up to date"
elif npm ci --prefix tests/js --no-audit --no-fund >"$LOG_DIR/npm.log" 2>&1; then
  echo "$want_node" >"$NODE_STAMP"
  ok "npm ci tests/js"
else
  tail -10 "$LOG_DIR/npm.log"
  fail "npm ci tests/js (see $LOG_DIR/npm.log)"
fi

step "Rust components (rustfmt, clippy)"
for pair in fmt:rustfmt clippy:clippy; do
  sub=${pair%%:*} comp=${pair#*:}
  cargo "$sub" --version >/dev/null 2>&1 && continue
  if command -v rustup >/dev/null 2>&1 && rustup component add "$comp" >>"$LOG_DIR/rustup.log" 2>&1; then
    ok "rustup component add $comp"
  else
    tail -5 "$LOG_DIR/rustup.log" 2>/dev/null
    fail "rust component $comp missing (rustup component add $comp)"
  fi
done

step "cargo fmt --check"
if cargo fmt --all -- --check >"$LOG_DIR/fmt.log" 2>&1; then ok "fmt"; else head -40 "$LOG_DIR/fmt.log"; fail "cargo fmt"; fi

step "cargo clippy --all-targets -- -D warnings"
if cargo clippy --workspace --all-targets --quiet -- -D warnings >"$LOG_DIR/clippy.log" 2>&1; then
  ok "clippy"
else
  grep -E '^(error|warning)' -A5 "$LOG_DIR/clippy.log" | head -60
  fail "cargo clippy"
fi

step "cargo doc --no-deps (warnings denied: broken and private links)"
if RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --quiet >"$LOG_DIR/doc.log" 2>&1; then
  ok "cargo doc"
else
  grep -E '^(error|warning)' -A7 "$LOG_DIR/doc.log" | head -40
  fail "cargo doc (see $LOG_DIR/doc.log)"
fi

step "unused dependencies (cargo-machete)"
if ! command -v cargo-machete >/dev/null 2>&1; then
  cargo install cargo-machete --locked --quiet >"$LOG_DIR/machete-install.log" 2>&1 ||
    { tail -5 "$LOG_DIR/machete-install.log"; }
fi
if ! command -v cargo-machete >/dev/null 2>&1; then
  fail "cargo-machete could not be installed (see $LOG_DIR/machete-install.log)"
elif cargo machete >"$LOG_DIR/machete.log" 2>&1; then
  ok "no unused dependencies"
else
  cat "$LOG_DIR/machete.log"
  fail "unused dependencies (cargo machete)"
fi

step "import cycles between files and modules of each crate (scripts/module_cycles.py)"
if python3 scripts/module_cycles.py >"$LOG_DIR/module-cycles.log" 2>&1; then
  ok "no import cycles"
else
  cat "$LOG_DIR/module-cycles.log"
  fail "import cycles (scripts/module_cycles.py names the files and lines)"
fi

step "public APIs against docs/reference/api (scripts/public_api.py)"
if python3 scripts/public_api.py >"$LOG_DIR/public-api.log" 2>&1; then
  ok "public APIs as listed"
else
  cat "$LOG_DIR/public-api.log"
  fail "a public API changed without its list (scripts/public_api.py --bless)"
fi

step "ARCHITECTURE.md against the code (scripts/check_architecture.py)"
if python3 scripts/check_architecture.py >"$LOG_DIR/architecture.log" 2>&1; then
  ok "ARCHITECTURE.md matches the manifests, the unsafe_code allowances, its paths and crates"
else
  cat "$LOG_DIR/architecture.log"
  fail "ARCHITECTURE.md has drifted from the code"
fi

step "performance figures in the docs against BENCHMARKS.md (scripts/check_numbers.py)"
if python3 scripts/check_numbers.py >"$LOG_DIR/numbers.log" 2>&1; then
  ok "every performance figure in README, CONTRIBUTING and docs/ is one BENCHMARKS.md holds"
else
  cat "$LOG_DIR/numbers.log"
  fail "a page restates a performance figure BENCHMARKS.md does not hold (scripts/check_numbers.py names file and line)"
fi

step "cargo test"
# Tests that return early because a GPU adapter or X server is missing (only
# allowed with IFD_GPU_TESTS=skip / IFD_WINDOW_TESTS=skip) append their names
# here (tests/support/skip.rs): libtest counts them as passed, this script
# moves them to the skipped count.
IFD_SKIP_LOG="$LOG_DIR/skipped-tests.log"
export IFD_SKIP_LOG
: >"$IFD_SKIP_LOG"
cargo test --workspace --no-fail-fast 2>&1 | tee "$LOG_DIR/cargo-test.log" | grep -E '^(test result|error|failures:|    [a-z_:]+$)|FAILED|panicked' || true
cargo_status=${PIPESTATUS[0]}
read -r cp cf ci < <(awk '/^test result:/ { for (i = 1; i <= NF; i++) { if ($(i+1) ~ /^passed/) p += $i; if ($(i+1) ~ /^failed/) f += $i; if ($(i+1) ~ /^ignored/) g += $i } } END { print p + 0, f + 0, g + 0 }' "$LOG_DIR/cargo-test.log")
runtime_skips=$(grep -c . "$IFD_SKIP_LOG" || true)
if [ "$runtime_skips" -gt 0 ]; then
  echo "skipped at run time (counted as skipped, not passed):"
  sed 's/^/  /' "$IFD_SKIP_LOG"
fi
passed=$((passed + cp - runtime_skips))
failed=$((failed + cf))
skipped=$((skipped + ci + runtime_skips))
if [ "$cargo_status" -ne 0 ] && [ "$cf" -eq 0 ]; then fail "cargo test (build or harness failure, see $LOG_DIR/cargo-test.log)"; fi
[ "$cf" -gt 0 ] && failures+=("$cf cargo tests")

step "Python module (maturin develop into .venv)"
# The dev profile, as the tests' binary: dependencies already built by cargo
# test are reused. Users install with `pip install ./crates/ifd-py` (release).
# A module left by an older build (a version-specific name such as
# _ifd.cpython-311-*.so) would be imported before the abi3 one built now.
rm -f crates/ifd-py/python/ifd/_ifd.*.so
if (cd crates/ifd-py && VIRTUAL_ENV="$ROOT/.venv" PATH="$ROOT/.venv/bin:$PATH" maturin develop --quiet) >"$LOG_DIR/maturin.log" 2>&1 &&
  .venv/bin/python -c "import ifd" >>"$LOG_DIR/maturin.log" 2>&1; then
  ok "python module"
else
  tail -20 "$LOG_DIR/maturin.log"
  fail "building the python module (see $LOG_DIR/maturin.log); its tests will fail"
fi

step "release artifacts, quick form (scripts/dist.sh --quick)"
# The archive and the abi3 wheel from the test build, unpacked and installed as a user
# would (see the script), so that the release script cannot go stale.
if grep -q '^error: could not compile' "$LOG_DIR/cargo-test.log"; then
  fail "scripts/dist.sh --quick not run: the test build failed (its binaries would be stale)"
elif scripts/dist.sh --quick >"$LOG_DIR/dist.log" 2>&1; then
  ok "dist.sh --quick: archive and wheel install and run"
else
  tail -20 "$LOG_DIR/dist.log"
  fail "scripts/dist.sh --quick (see $LOG_DIR/dist.log)"
fi

step "reference comparisons (pytest tests/python)"
# `cargo test --workspace` has just built the `ifd` and `ifd-paper` binaries
# (their integration tests run them) with the workspace's unified features.
# `cargo build -p ifd-cli` would resolve features for ifd-cli alone and rebuild
# wgpu and its dependencies (3 minutes cold) for the same program, so the
# tests' binaries are used whenever that build compiled; otherwise they are
# built here. The tests find `ifd-paper` beside `ifd` (or at IFD_PAPER_BIN).
IFD_BIN=${CARGO_TARGET_DIR:-$ROOT/target}/debug/ifd
export IFD_BIN
if { [ -x "$IFD_BIN" ] && [ -x "$(dirname "$IFD_BIN")/ifd-paper" ] &&
  ! grep -q '^error: could not compile' "$LOG_DIR/cargo-test.log"; } ||
  cargo build --quiet -p ifd-cli -p ifd-paper >"$LOG_DIR/build-cli.log" 2>&1; then
  .venv/bin/python -m pytest -q -p no:cacheprovider tests/python 2>&1 | tee "$LOG_DIR/pytest.log" | tail -25
  read -r pp pf ps px < <(awk '/ passed| failed| error| skipped| xfailed| xpassed/ { for (i = 1; i <= NF; i++) { if ($(i+1) ~ /^passed/) p = $i; if ($(i+1) ~ /^(failed|errors?)/) f += $i; if ($(i+1) ~ /^skipped/) s = $i; if ($(i+1) ~ /^(xfailed|xpassed)/) x += $i } } END { print p + 0, f + 0, s + 0, x + 0 }' <(tail -1 "$LOG_DIR/pytest.log"))
  passed=$((passed + pp))
  failed=$((failed + pf))
  skipped=$((skipped + ps))
  xfailed=$((xfailed + px))
  [ "$pf" -gt 0 ] && failures+=("$pf python reference tests")
  [ "$pp" -eq 0 ] && [ "$pf" -eq 0 ] && fail "pytest ran no test"
else
  tail -20 "$LOG_DIR/build-cli.log"
  fail "building the ifd and ifd-paper binaries"
fi

echo
echo "took $(( $(date +%s) - start )) s"
for f in "${failures[@]}"; do echo "failed: $f"; done
echo "$passed passed, $failed failed, $skipped skipped, $xfailed known failures"
[ "$failed" -eq 0 ]
