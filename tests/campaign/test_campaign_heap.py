"""A campaign worker keeps the memory its runs free: no page faults per run, also under a Dask
nanny's MALLOC_TRIM_THRESHOLD_=65536 (which made every run fault its numpy arrays back in)."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.slow

PROBE = r"""
import json, resource, sys
from vehest_can.campaign import runner
from vehest_can.campaign.spec import CAMPAIGNS, load_campaign
if sys.argv[1] == "off":
    runner.keep_heap = lambda *a, **k: False  # the worker as it was
c = load_campaign(CAMPAIGNS.path("tireforce_payload"))
runner.run_batch(c, [0])  # imports and first allocations
f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
rows = runner.run_batch(c, [1, 2, 3])
assert all(r["error"] is None for r in rows), rows
print(json.dumps((resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0) / 3))
"""


def _faults_per_run(mode: str) -> float:
    env = dict(os.environ, MALLOC_TRIM_THRESHOLD_="65536")
    out = subprocess.run([sys.executable, "-c", PROBE, mode], env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    return float(json.loads(out.stdout.splitlines()[-1]))


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt")
def test_runs_do_not_page_fault_their_arrays_back():
    on, off = _faults_per_run("on"), _faults_per_run("off")
    print(f"\nminor page faults per tyre-force run: {off:.0f} as a Dask worker was, {on:.0f} with keep_heap")
    assert off > 5000  # the probe sees the problem it guards against
    assert on < off / 20
