"""Paths shared by the study scripts: the repository root and the `ifd`
binary they run (a copy of tests/bench/ifd_paths.py, from this folder)."""

import os
import pathlib

ROOT = pathlib.Path(__file__).resolve().parents[3]


def ifd_binary(arg):
    """`arg` when given, else target/release/ifd, else target/debug/ifd
    (under CARGO_TARGET_DIR when set)."""
    if arg:
        return pathlib.Path(arg)
    target = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    for p in (target / "release" / "ifd", target / "debug" / "ifd"):
        if p.exists():
            return p
    raise SystemExit("build ifd first (cargo build --release -p ifd-cli)")
