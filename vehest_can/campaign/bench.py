"""Campaign throughput side by side in one run: the same runs on 1 and N local workers, on a
running Dask LocalCluster with N workers (as an existing cluster would be) and on one started for
the campaign (`--scheduler local-dask`); runs per minute, scaling efficiency and Dask's overhead
per run against the local pool.

    vehest-can study campaign.throughput tireforce_payload --runs 200 --repeats 3
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import tempfile
import time
from pathlib import Path

from ..errors import ConfigError
from .runner import LOCAL_DASK, Store, execute, local_cluster
from .spec import CAMPAIGNS, load_campaign


def measure(spec: str, runs: int | None = None, workers: int | None = None, repeats: int = 3,
            batch_size: int | None = None) -> dict:

    c = load_campaign(CAMPAIGNS.path(spec))
    if runs is not None:
        c = dataclasses.replace(c, runs=runs)
    n = workers or os.cpu_count() or 1
    # an already running cluster (as a user's would be): its start-up is not a per-run cost
    cluster = local_cluster(n)
    setups = {"local x1": (1, None), f"local x{n}": (n, None), f"dask x{n}": (n, cluster.scheduler_address),
              f"dask x{n} + start": (n, LOCAL_DASK)}
    wall: dict[str, list[float]] = {k: [] for k in setups}
    try:
        with tempfile.TemporaryDirectory() as d:  # its workers import vehest_can once, as a cluster's do
            warm = dataclasses.replace(c, runs=2 * n)
            execute(warm, Store(Path(d), warm), workers=n, scheduler=cluster.scheduler_address, batch_size=1)
        for _ in range(repeats):
            for label, (w, sched) in setups.items():  # interleaved: a noisy machine hurts each alike
                with tempfile.TemporaryDirectory() as d:
                    t0 = time.perf_counter()
                    counts = execute(c, Store(Path(d), c), workers=w, scheduler=sched, batch_size=batch_size)
                    wall[label].append(time.perf_counter() - t0)
                    assert counts["ran"] == c.runs and counts["failed"] == 0, counts
    finally:
        cluster.close()
    med = {k: statistics.median(v) for k, v in wall.items()}
    one, many, dask = med["local x1"], med[f"local x{n}"], med[f"dask x{n}"]
    return {"campaign": c.name, "runs": c.runs, "workers": n, "repeats": repeats,
            "median_wall_s": med, "runs_per_min": {k: c.runs / v * 60 for k, v in med.items()},
            "scaling_efficiency": one / (n * many),
            "dask_overhead_per_run_ms": (dask - many) / c.runs * 1e3,
            "dask_overhead_pct": 100 * (dask - many) / many,
            "dask_cluster_start_s": med[f"dask x{n} + start"] - dask}


def main(argv: list[str], prog: str) -> int:
    p = argparse.ArgumentParser(prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("spec")
    p.add_argument("--runs", type=int)
    p.add_argument("-j", "--workers", type=int)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--batch-size", type=int)
    a = p.parse_args(argv)
    for flag, value in (("--runs", a.runs), ("--workers", a.workers), ("--repeats", a.repeats),
                        ("--batch-size", a.batch_size)):
        if value is not None and value < 1:
            p.error(f"{flag} must be at least 1")
    try:
        r = measure(a.spec, a.runs, a.workers, a.repeats, a.batch_size)
    except ConfigError as e:
        p.exit(2, f"error: {e}\n")
    print(f"campaign {r['campaign']}: {r['runs']} runs, median of {r['repeats']} (interleaved)")
    for k, v in r["median_wall_s"].items():
        print(f"  {k:<10} {v:7.2f} s  {r['runs_per_min'][k]:8.1f} runs/min")
    print(f"  scaling efficiency 1 -> {r['workers']} workers: {100 * r['scaling_efficiency']:.0f} %")
    print(f"  Dask (running cluster) over the local pool: {r['dask_overhead_per_run_ms']:+.1f} ms per run "
          f"({r['dask_overhead_pct']:+.1f} %); starting a LocalCluster adds {r['dask_cluster_start_s']:.1f} s once")
    return 0

