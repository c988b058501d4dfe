"""`vehest-can bench` pieces run on tiny sizes and give sane, positive figures (speed is measured, not asserted)."""
from __future__ import annotations

import math
import shutil

import numpy as np
import pytest

from vehest_can.tools import bench

needs_cc = pytest.mark.skipif(shutil.which("cc") is None and shutil.which("gcc") is None, reason="no C compiler")


def _positive(x) -> bool:
    return isinstance(x, float) and math.isfinite(x) and x > 0


def test_skf_inputs_are_the_c_bench_drive():
    inp = bench.skf_inputs(50)
    assert len(inp) == 50 and inp.matrix().shape == (50, 13)
    assert np.all(np.isfinite(inp.matrix()))
    assert inp.delta[0] == 0.0 and np.all(np.abs(inp.delta) <= 0.035)


@pytest.mark.rebuild
@needs_cc
def test_tireforce_rows_tiny():
    res = bench.tireforce(c_samples=200, ref_steps=5, repeats=1)
    assert _positive(res["numpy_ref_ns"])
    c = res["c_loop"]
    for key in ("skfmec_fixed_step", "skfmec_double_step", "ekf_double_step"):
        med, p99 = c[key]
        assert _positive(med) and p99 >= med
    text = bench.table({"array_api_ns": 1.0, "single_cffi_ns": 1.0, "numpy_ref_ns": 1.0, "tireforce": res})
    assert "SKFMEC fixed-point step, C loop" in text and "faster than the numpy reference step" in text


@pytest.mark.rebuild
@needs_cc
def test_ecu_tick_with_chassis_runs_the_estimator():
    c = bench.c_loop()
    for key in ("ecu_tick", "ecu_tick_chassis"):
        med, p99 = c[key]
        assert _positive(med) and p99 >= med
    steps, resets = c["ecu_chassis_skf"]  # c_loop keeps the last two columns: SKFMEC steps, resets
    assert steps == 40000 and resets == 0  # a fixed SKFMEC step in every one of the 40 000 ticks, no restart
    text = bench.table({"array_api_ns": 1.0, "single_cffi_ns": 1.0, "numpy_ref_ns": 1.0, "c_loop": c})
    assert "ECU tick + CHS frame" in text and "target <= 10 µs" in text


def test_chassis_plant_row_tiny():
    res = bench.chassis_plant(seconds=0.05, repeats=1)
    assert res["steps"] > 0
    for key in ("x_real_time_cpu_best", "x_real_time_cpu_median", "us_per_step_cpu_best"):
        assert _positive(res[key])
    text = bench.table({"array_api_ns": 1.0, "single_cffi_ns": 1.0, "numpy_ref_ns": 1.0, "chassis_plant": res})
    assert "14-DOF chassis plant" in text and "target >= 200x" in text


def _fnv1a(*arrays: np.ndarray) -> int:
    """FNV-1a over the little-endian bytes of int32 arrays (vh_bench_skf.c's checksum)."""
    h = 2166136261
    for b in b"".join(np.ascontiguousarray(a, dtype="<i4").tobytes() for a in arrays):
        h = ((h ^ b) * 16777619) & 0xFFFFFFFF
    return h


@pytest.mark.rebuild
@needs_cc
@pytest.mark.parametrize("n", [500, 3000])
def test_the_python_drive_is_the_c_drive(n):
    """The numpy reference row times skf_inputs(n), the C-loop rows vh_bench_skf.c's own drive: the
    fixed-point SKFMEC run on the Python drive ends in the state the C bench checksums, bit for bit."""
    from vehest_can.systems.tireforce.api import TireForceFixed

    kf = TireForceFixed()
    raw = kf.run_raw(kf.quantise(bench.skf_inputs(n)), covariances=True)
    c = bench.bench_c_loop(samples=n)
    assert _fnv1a(raw["x"][-1], raw["p"][-1], raw["fy"][-1], raw["fz"][-1]) == int(c["skfmec_fixed_checksum"][0])


@pytest.mark.slow  # three child interpreters
def test_replay_bench_tiny_runs_every_baseline_on_a_log_with_the_sync_frames():
    """The replay row on a small generated lockstep log: the ECU's replay is identical, and python-can's
    LogReader and cantools (with the simulator's DBC beside each bus's) read and decode every frame."""
    from vehest_can.tools import replay_bench

    r = replay_bench.run(20_000, repeats=1, baseline_frames=5_000)
    assert r["frames"] >= 20_000 and r["replay_identical"]
    assert r["logreader_frames"] == r["cantools_frames"] == 5_000
    assert all(_positive(float(r[k])) for k in ("replay_fps", "logreader_fps", "cantools_fps"))
