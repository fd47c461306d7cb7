"""The benchmark suite's smoke size runs end to end and writes its page, JSON and figures."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

RUN_ALL = Path(__file__).resolve().parents[1] / "benchmarks" / "run_all.py"


@pytest.mark.slow
def test_run_all_smoke(tmp_path):
    proc = subprocess.run([sys.executable, str(RUN_ALL), "--smoke", "--jobs", "1",
                           "--out", str(tmp_path)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    page = (tmp_path / "benchmarks.md").read_text()
    for heading in ("## Accuracy (Monte Carlo)", "## Peers on the same data", "## Speed and scale",
                    "Streaming"):
        assert heading in page
    results = json.loads((tmp_path / "benchmarks" / "results.json").read_text())
    assert results["meta"]["size"] == "smoke"
    cells = results["cells"]
    assert {c["method"] for c in cells} >= {"ols", "sdp-pseudo-inertia"}
    # what the suite measures must be numbers, and the SDP's bodies realizable
    for c in cells:
        assert c["failed"] == 0, c
        assert c["held_rms_over_sigma"] > 0.5
        if c["method"].startswith("sdp"):
            assert c["bodies_not_psd"] == 0, c
    peers = {r["method"].split(" ")[0]: r for r in results["peers"]}
    assert {"consistid", "numpy", "naive", "FIGAROH"} <= set(peers)
    stream = results["streaming"][0]
    assert stream["status"] == "optimal" and stream["peak_rss_mb"] < 1000
    for name in ("accuracy.png", "scale.png"):
        assert (tmp_path / "benchmarks" / name).stat().st_size > 1000
