"""scripts/gpu-bench.sh, the GPU timing script meant for a machine with a GPU but no Rust
toolchain, run here in its quick mode on lavapipe with the test build's binaries: every step
runs and the JSON report carries a positive timing for each (the figures themselves are
lavapipe's and are not checked)."""

import json
import os
import subprocess

from conftest import ROOT, _binary


def test_gpu_bench_script_runs_every_step_and_reports_json(tmp_path):
    out = tmp_path / "gpu-bench.json"
    env = dict(os.environ)
    runtime = tmp_path / "xdg"
    runtime.mkdir(mode=0o700)
    env.setdefault("XDG_RUNTIME_DIR", str(runtime))
    p = subprocess.run(["bash", str(ROOT / "scripts" / "gpu-bench.sh"), "--bin",
                        str(_binary().parent), "--quick", "--out", str(out)],
                       capture_output=True, text=True, env=env, timeout=900)
    assert p.returncode == 0, p.stderr[-3000:]
    r = json.loads(out.read_text())
    assert r["adapter"]["adapter"], r["adapter"]
    planar = r["planar"]
    assert planar["terms"] == 64 and planar["gpu_eval_readback_ms_median"] > 0, planar
    assert planar["cpu_whole_process_s_median"] > 0, planar
    assert [x["lmax"] for x in r["isd"]] == [7], r["isd"]
    assert all(x["frame_ms_median"] > 0 and x["frames"] == 2 for x in r["isd"]), r["isd"]
    for dev in ("gpu", "cpu"):
        b = r["brush"][dev]
        assert b["dabs"] > 0 and b["replay_s_median"] > 0 and b["runs"] == 2, (dev, b)
    assert r["brush"]["gpu"]["compute"].startswith("GPU"), r["brush"]
    assert r["brush"]["cpu"]["compute"] == "CPU", r["brush"]


def test_gpu_bench_script_refuses_a_missing_binary(tmp_path):
    p = subprocess.run(["bash", str(ROOT / "scripts" / "gpu-bench.sh"), "--bin", str(tmp_path),
                        "--quick"], capture_output=True, text=True, timeout=60)
    assert p.returncode == 2 and "not found" in p.stderr, p.stderr
