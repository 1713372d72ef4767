"""Shared fixtures: the `ifd` and `ifd-paper` binaries, the bundled test data, a scratch folder."""

import json
import os
import pathlib
import subprocess

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
TESTDATA = ROOT / "testdata"


def _binary() -> pathlib.Path:
    if "IFD_BIN" in os.environ:
        return pathlib.Path(os.environ["IFD_BIN"])
    target = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    return target / "debug" / "ifd"


@pytest.fixture(scope="session")
def ifd_bin() -> pathlib.Path:
    b = _binary()
    if not b.exists():
        pytest.fail(f"{b} not built: run `cargo build -p ifd-cli` first")
    return b


@pytest.fixture(scope="session")
def run_ifd(ifd_bin):
    """Runs `ifd ARGS...`; returns the CompletedProcess (text mode)."""

    def run(*args, check=True):
        p = subprocess.run([str(ifd_bin), *map(str, args)], capture_output=True, text=True)
        if check and p.returncode != 0:
            raise AssertionError(f"ifd {' '.join(map(str, args))} failed ({p.returncode}):\n{p.stderr}")
        return p

    return run


def _paper_binary() -> pathlib.Path:
    """`IFD_PAPER_BIN`, else `ifd-paper` beside the `ifd` binary (`cargo build -p ifd-paper`)."""
    if "IFD_PAPER_BIN" in os.environ:
        return pathlib.Path(os.environ["IFD_PAPER_BIN"])
    return _binary().with_name("ifd-paper")


@pytest.fixture(scope="session")
def run_paper():
    """Runs `ifd-paper ARGS...` (the papers' studies); returns the CompletedProcess (text mode)."""
    b = _paper_binary()
    if not b.exists():
        pytest.fail(f"{b} not built: run `cargo build -p ifd-paper` first")

    def run(*args, check=True):
        p = subprocess.run([str(b), *map(str, args)], capture_output=True, text=True)
        if check and p.returncode != 0:
            raise AssertionError(f"ifd-paper {' '.join(map(str, args))} failed ({p.returncode}):\n{p.stderr}")
        return p

    return run


@pytest.fixture(scope="session")
def run_paper_json(run_paper):
    """Runs `ifd-paper ARGS... --json`; returns the parsed report."""

    def run(*args):
        if "--json" not in map(str, args):
            args = (*args, "--json")
        return json.loads(run_paper(*args).stdout)

    return run


@pytest.fixture(scope="session")
def run_json(run_ifd):
    """Runs `ifd ARGS... --json`; returns the parsed report."""

    def run(*args):
        if "--json" not in map(str, args):
            args = (*args, "--json")
        return json.loads(run_ifd(*args).stdout)

    return run


def load_gray(name: str) -> np.ndarray:
    import skimage.io

    img = skimage.io.imread(TESTDATA / name)
    return img.astype(np.float64) / 255.0


def save_npy(path, arr) -> pathlib.Path:
    np.save(path, np.asarray(arr, dtype=np.float32))
    return pathlib.Path(path)


# A reference test whose library failed to import is a failure, never a skip:
# `pytest.importorskip` (in a test or at module level) and `pytest.skip` with
# an import error both raise a skip whose reason starts "could not import";
# these hooks turn such skips into failures with the reason.
_IMPORT_SKIP = ("could not import", "no module named")


def _import_skip_reason(rep):
    if not rep.skipped or not isinstance(rep.longrepr, tuple):
        return None
    reason = str(rep.longrepr[-1])
    low = reason.lower()
    return reason if any(s in low for s in _IMPORT_SKIP) else None


def _fail_import_skip(rep):
    reason = _import_skip_reason(rep)
    if reason is not None:
        rep.outcome = "failed"
        rep.longrepr = f"a reference library failed to import (a failure, not a skip): {reason}"


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    _fail_import_skip(outcome.get_result())


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector):
    outcome = yield
    _fail_import_skip(outcome.get_result())
