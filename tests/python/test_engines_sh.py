"""The SH conversion of docs/guide/engines.md, run as written, checked against Filament's
own SH of the same map (issue 55, item 5).

The guide's block evaluates `sh.npy` at world directions (y up) with `ifd sphere eval` and
fits three.js's basis there; Filament's coefficients are the same with the Condon-Shortley
signs. Here the "filament" set is taken to the frame of cmgen's --no-mirror cube, where a
world direction (x, y, z) is (z, y, x) (tests/python/test_ibl_cmgen.py derives it,
tests/bench/bench_ibl.py measures it), and compared with cmgen's radiance SH of the forest
map (testdata/cmgen_forest_sh3.txt) within the bound of test_ibl_cmgen.py: the guide's
frames and signs are right if this holds, and an axis or a sign wrong anywhere breaks it.
"""

import json
import os
import pathlib
import shutil
import subprocess
import sys

import numpy as np

from conftest import ROOT, TESTDATA
from test_doc_commands import parse_blocks
from test_ibl_cmgen import FIXTURE, read_cmgen_sh, sh9


def _run_guide_block(ifd_bin, work):
    blocks = [b for b in parse_blocks(ROOT / "docs" / "guide" / "engines.md") if "sh-engines.json" in b.body]
    assert len(blocks) == 1, [b.id for b in blocks]
    shutil.copytree(TESTDATA, work / "testdata")
    path = [str(ifd_bin.resolve().parent), str(pathlib.Path(sys.executable).parent), os.environ.get("PATH", "")]
    p = subprocess.run(["bash", "-ec", blocks[0].script()], cwd=work, capture_output=True, text=True,
                       env=dict(os.environ, PATH=os.pathsep.join(path)))
    assert p.returncode == 0, p.stderr[-2000:]
    sh = json.loads((work / "ibl" / "sh-engines.json").read_text())
    return np.array(sh["three"]), np.array(sh["filament"])


def test_engine_sh_match_cmgen(ifd_bin, tmp_path):
    three, filament = _run_guide_block(ifd_bin, tmp_path)
    assert three.shape == filament.shape == (9, 3)
    d = np.random.default_rng(1).normal(size=(400, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    x, y, z = d.T
    # three.js's SphericalHarmonics3.getAt and Filament's basis give the same radiance
    k = (0.282095, 0.488603, 1.092548, 0.315392, 0.546274)
    three_basis = np.stack([k[0] + 0 * x, k[1] * y, k[1] * z, k[1] * x, k[2] * x * y, k[2] * y * z,
                            k[3] * (3 * z * z - 1), k[2] * x * z, k[4] * (x * x - y * y)], 1)
    radiance = sh9(d) @ filament
    assert np.allclose(three_basis @ three, radiance, rtol=1e-5, atol=1e-5 * np.abs(radiance).max())
    # in the frame of cmgen's --no-mirror cube, against cmgen's own coefficients
    in_cmgen_frame = np.linalg.lstsq(sh9(d[:, [2, 1, 0]]), radiance, rcond=None)[0]
    ref = read_cmgen_sh(FIXTURE)
    err = np.linalg.norm(in_cmgen_frame - ref, axis=0) / np.linalg.norm(ref, axis=0)
    print("engines guide's Filament SH9 vs cmgen, rel L2 per channel R, G, B: "
          + ", ".join(f"{e:.3%}" for e in err))
    assert np.all(err <= 0.01), err
