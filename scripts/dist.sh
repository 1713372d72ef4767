#!/usr/bin/env bash
# Release artifacts of ifd, built and then installed and tried as a user would.
#
#   scripts/dist.sh            the release form: optimised binaries (cargo --release), into dist/
#   scripts/dist.sh --quick    the same steps on the test-profile build that scripts/test-all.sh
#                              has just made (target/debug, `maturin build --profile dev`), into
#                              target/dist-quick/: the suite's check that this script still works
#
# Writes, for VERSION from the workspace manifest and the host's target triple:
#   ifd-VERSION-x86_64-unknown-linux-gnu.tar.gz
#       bin/ifd, bin/ifd-brush, bin/ifd-envrender (stripped; built for baseline x86-64, the
#       vector kernels chosen at run time: AVX-512, AVX2 or scalar),
#       share/bash-completion/completions/ifd, share/zsh/site-functions/_ifd,
#       share/fish/vendor_completions.d/ifd.fish (`ifd completions SHELL`),
#       share/man/man1/*.1 (`ifd manpages`), README.md, CHANGELOG.md, LICENSE-MIT, LICENSE-APACHE
#   ifd-VERSION-cp39-abi3-manylinux_*.whl   the Python module, one wheel for CPython 3.9 and later
#   SHA256SUMS
#
# Then, from the artifacts alone: the archive unpacked into a fresh folder runs the quick
# tour's commands on a copy of testdata/, the bash completion loads and completes a
# subcommand, the man pages render; the wheel installs into a fresh virtual environment with
# no Rust toolchain on PATH (numpy from the package index) and runs the Python quick tour.
# Exits non-zero, naming the step, when any of it fails.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
QUICK=0
case "${1:-}" in
  --quick) QUICK=1 ;;
  "") ;;
  *) echo "usage: scripts/dist.sh [--quick]" >&2; exit 2 ;;
esac

VERSION=$(sed -n 's/^version = "\(.*\)"/\1/p' Cargo.toml | head -1)
TRIPLE=$(rustc -vV | sed -n 's/^host: //p')
NAME="ifd-$VERSION-$TRIPLE"
TARGET=${CARGO_TARGET_DIR:-$ROOT/target}
if [ "$QUICK" = 1 ]; then
  DIST=$TARGET/dist-quick
  PROFILE=dev
  BIN=$TARGET/debug
else
  DIST=$ROOT/dist
  PROFILE=release
  BIN=$TARGET/release
fi
PY=${PYTHON:-python3}
step() { printf '\n==> %s\n' "$*"; }
die() { echo "dist.sh: $*" >&2; exit 1; }

# Baseline x86-64 code: no target-cpu from the environment (the kernels pick AVX2 or
# AVX-512 at run time, ifd_simd).
if [ "$QUICK" = 0 ] && { [ -n "${RUSTFLAGS:-}" ] || [ -n "${CARGO_ENCODED_RUSTFLAGS:-}" ]; }; then
  echo "note: ignoring RUSTFLAGS for the release artifacts (built for baseline x86-64)"
fi
unset RUSTFLAGS CARGO_ENCODED_RUSTFLAGS
if grep -qs 'target-cpu' .cargo/config.toml .cargo/config 2>/dev/null; then
  die ".cargo/config sets a target-cpu: the artifacts must run on any x86-64"
fi

step "binaries ($PROFILE profile)"
if [ "$QUICK" = 1 ] && [ -x "$BIN/ifd" ] && [ -x "$BIN/ifd-brush" ] && [ -x "$BIN/ifd-envrender" ]; then
  # the binaries `cargo test --workspace` built (with the workspace's unified features: a
  # `cargo build -p` of the apps alone would resolve other features and rebuild wgpu)
  echo "reusing the test build in $BIN"
else
  cargo build --profile "$PROFILE" -p ifd-cli -p ifd-brush -p ifd-envrender
fi
for b in ifd ifd-brush ifd-envrender; do
  [ -x "$BIN/$b" ] || die "$BIN/$b was not built"
done

step "staging $NAME"
# everything is built into DIST.partial and moved into place once it has been tried: a failed
# run leaves no half-made dist/
FINAL=$DIST
DIST=$FINAL.partial
rm -rf "$DIST"
STAGE=$DIST/$NAME
mkdir -p "$STAGE/bin" "$STAGE/share/bash-completion/completions" "$STAGE/share/zsh/site-functions" \
  "$STAGE/share/fish/vendor_completions.d" "$STAGE/share/man/man1"
for b in ifd ifd-brush ifd-envrender; do
  cp "$BIN/$b" "$STAGE/bin/$b"
  strip "$STAGE/bin/$b"
done
"$STAGE/bin/ifd" completions bash >"$STAGE/share/bash-completion/completions/ifd"
"$STAGE/bin/ifd" completions zsh >"$STAGE/share/zsh/site-functions/_ifd"
"$STAGE/bin/ifd" completions fish >"$STAGE/share/fish/vendor_completions.d/ifd.fish"
"$STAGE/bin/ifd" manpages --out-dir "$STAGE/share/man/man1" >/dev/null
cp README.md CHANGELOG.md LICENSE-MIT LICENSE-APACHE "$STAGE/"
tar -C "$DIST" -czf "$DIST/$NAME.tar.gz" "$NAME"
rm -rf "$STAGE"

step "Python wheel (abi3, CPython 3.9+)"
MATURIN=$(command -v maturin || true)
[ -n "$MATURIN" ] || MATURIN=$ROOT/.venv/bin/maturin
[ -x "$MATURIN" ] || die "maturin not found (scripts/test-all.sh installs it into .venv)"
(cd crates/ifd-py && "$MATURIN" build --quiet --profile "$PROFILE" --out "$DIST")
WHEEL=$(ls "$DIST"/ifd-"$VERSION"-*abi3*.whl 2>/dev/null | head -1)
[ -n "$WHEEL" ] || die "no abi3 wheel in $DIST"

(cd "$DIST" && sha256sum -- *.tar.gz *.whl >SHA256SUMS)
ls -l "$DIST"

step "installing the archive into a fresh folder"
TRY=$(mktemp -d)
trap 'rm -rf "$TRY" "$DIST"' EXIT
# as a user who downloaded the files: checked against SHA256SUMS where they landed
mkdir "$TRY/download"
cp "$DIST"/* "$TRY/download/"
(cd "$TRY/download" && sha256sum -c --quiet SHA256SUMS) || die "SHA256SUMS does not match the files"
tar -C "$TRY" -xzf "$TRY/download/$NAME.tar.gz"
PREFIX=$TRY/$NAME
cp -r testdata "$TRY/work"
# a user's shell: the unpacked bin/ first, no cargo; a shell of its own, so that `set -e`
# stops at the first failing command
TOUR=$(cat <<'TOUR'

  cd "$WORK"
  ifd --version | grep -q "^ifd $VERSION (commit"
  ifd decompose gauss:sx=16,sy=2,theta=0 -o gauss8.json
  ifd field swirl --size 512x512 -o swirl.npy
  ifd filter astronaut.png --decomp gauss8.json --angle-map swirl.npy -o swirl.png
  ifd filter astronaut.png --kernel gauss:sx=8,sy=2 --angle 30 -o blur.png
  ifd compare astronaut.png swirl.png >/dev/null
  ifd convert astronaut.png astronaut.npy
  ifd render --env forest.hdr --brdf ggx:alpha=0.3 --lmax 8 --size 96x96 -o sphere.png
  ifd envmap prefilter forest.hdr --face-size 16 --irradiance-size 8 --out-dir ibl >/dev/null
  for f in gauss8.json swirl.png blur.png sphere.png ibl/radiance.ktx2; do
    [ -s "$f" ] || { echo "the quick tour did not write $f" >&2; exit 1; }
  done
  ifd-brush --help >/dev/null
  ifd-envrender --help >/dev/null
TOUR
)
env PATH="$PREFIX/bin:/usr/local/bin:/usr/bin:/bin" VERSION="$VERSION" WORK="$TRY/work" \
  bash -euo pipefail -c "$TOUR" </dev/null || die "the unpacked archive's quick tour failed"
bash -c "source '$PREFIX/share/bash-completion/completions/ifd' && complete -p ifd >/dev/null &&
  COMP_WORDS=(ifd fil) && COMP_CWORD=1 && COMP_LINE='ifd fil' && COMP_POINT=7 && _ifd ifd fil ifd &&
  printf '%s\n' \"\${COMPREPLY[@]}\" | grep -qx filter" || die "the bash completion does not load or complete"
for page in ifd ifd-filter ifd-envmap-prefilter; do
  grep -q '^\.TH' "$PREFIX/share/man/man1/$page.1" || die "man page $page.1"
done
if command -v man >/dev/null; then
  page=$(MANPATH="$PREFIX/share/man" man -P cat ifd-filter 2>/dev/null) || die "man ifd-filter"
  grep -q -- '--kernel' <<<"$page" || die "man ifd-filter does not show the page"
fi
echo "archive: quick tour, bash completion and man pages work"

step "installing the wheel into a fresh virtual environment, no Rust on PATH"
"$PY" -m venv "$TRY/venv"
# the system's folders, less any that holds a Rust toolchain
NORUST="$TRY/venv/bin"
for d in /usr/local/bin /usr/bin /bin; do
  [ -x "$d/cargo" ] || [ -x "$d/rustc" ] || NORUST="$NORUST:$d"
done
TOUR=$(cat <<'WHEEL'

  if command -v cargo >/dev/null || command -v rustc >/dev/null; then echo "Rust is still on PATH" >&2; exit 1; fi
  # numpy, the wheel's one dependency, from the package index (or pip's cache)
  pip install --quiet --disable-pip-version-check --only-binary :all: "$WHEEL_FILE"
  cd "$WORK"
  python - <<'PY'
import numpy as np
import ifd

img = np.load("astronaut.npy")  # written by the archive's `ifd convert`
d = ifd.decompose("gauss:sx=16,sy=2,theta=0")
assert d.report["rel_l2_error"] <= 0.01, d.report
out = ifd.filter(img, d, angle=30.0)
assert out.shape == img.shape and np.isfinite(out).all()
direct = ifd.filter(img, "gauss:sx=8,sy=2", angle=30.0)
assert direct.shape == img.shape
print(f"python: ifd {ifd.__version__}, {d.report['terms']} terms, filtered {img.shape}")
PY
WHEEL
)
env PATH="$NORUST" WHEEL_FILE="$WHEEL" WORK="$TRY/work" \
  bash -euo pipefail -c "$TOUR" </dev/null || die "the wheel's Python quick tour failed"
rm -rf "$FINAL"
mv "$DIST" "$FINAL"
echo
echo "artifacts in $FINAL:"
cat "$FINAL/SHA256SUMS"
