"""bench/cluster_speedup.py runs end to end in its quick mode (sleeping stand-in) on two real
LocalClusters and writes the ratio it promises; sleeping runs leave the cores free, so two
workers must beat one clearly even on a busy machine."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("distributed", reason="the dask extra (pip install '.[test]') is not installed")

SCRIPT = Path(__file__).resolve().parents[2] / "bench" / "cluster_speedup.py"


def test_cluster_speedup_bench_quick_mode(tmp_path):
    # As a script, the way it is run: its objective is in __main__, so workers get it by value.
    done = subprocess.run([sys.executable, str(SCRIPT), "--quick", "--out", str(tmp_path)],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "speed-up" in done.stdout
    result = json.loads((tmp_path / "cluster_speedup.json").read_text())
    one, two = result["one_worker"], result["two_workers"]
    assert one["workers"] == 1 and two["workers"] == 2
    assert one["runs"] == two["runs"] == result["sweep"]["runs"] == 14 and one["failed_runs"] == 0
    assert result["results_equal"] is True
    assert result["speedup_1_to_2_workers"] == pytest.approx(one["wall_s"] / two["wall_s"])
    assert result["speedup_1_to_2_workers"] > 1.3
    assert one["cpu_parallelism_before"] > 0 and two["cpu_parallelism_before"] > 0
