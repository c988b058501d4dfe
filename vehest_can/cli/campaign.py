"""``vehest-can campaign SPEC.toml``: Monte-Carlo validation of an estimator over a spread of
scenarios, on a local process pool (default) or a Dask cluster; resumable."""
from __future__ import annotations

import json
import os
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from ._common import add_car_argument, car_from_args

#: the verb's one line in `vehest-can --help` (read without building its parser)
HELP = "Monte-Carlo validation: many runs of a varied scenario, resumable"


def add_subparser(subparsers) -> None:
    p = subparsers.add_parser("campaign", help=HELP,
                              description="Run a campaign file's runs in process (lockstep), stream each batch's "
                                          "results to a Parquet dataset, and report the spread, the worst run "
                                          "and the pass rate of each acceptance line.")
    p.add_argument("spec", metavar="SPEC.toml", help="campaign file (docs/campaigns.md), or a shipped campaign's name")
    p.add_argument("-o", "--out", metavar="DIR", help="output folder (default: out/campaign/<name>)")
    p.add_argument("-j", "--workers", type=int, metavar="N", help="local worker processes (default: all cores)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run on a Dask distributed cluster (tcp://host:8786), or 'local-dask' to start a "
                        "LocalCluster on this machine")
    p.add_argument("--batch-size", type=int, metavar="N", help="runs per task (default: a few tasks per worker, <= 16)")
    p.add_argument("--fresh", action="store_true", help="discard results already in the output folder")
    p.add_argument("--no-plots", action="store_true", help="skip the plots")
    p.add_argument("--seed", type=int, metavar="N",
                   help="draw the runs with this seed instead of the file's: another draw of the same spread, to "
                        "judge a setting on runs it was not chosen on (default output folder <name>-seed<N>)")
    add_car_argument(p, "every run's car (a car file, docs/car.md, or a shipped car's name: paper, "
                        "commonroad_vehicle1 .. 3): the base scenario's `car` key, so the 14-DOF plant runs it and "
                        "the ECU is calibrated for it; a `car` axis in the file overrides it")
    p.set_defaults(func=run)


class Bar:
    """tqdm's bar on a terminal (runs done, rate, ETA, failures); elsewhere a line every 10 %."""

    def __init__(self, label: str):
        self.label, self.tty = label, sys.stderr.isatty()
        self.bar: Any = None

    def start(self, total: int, initial: int) -> None:
        from tqdm import tqdm

        self.bar = tqdm(total=total, initial=initial, desc=self.label, unit="run", dynamic_ncols=True,
                        file=sys.stderr, mininterval=0.5, disable=not self.tty)
        self.bar.set_postfix(failed=0)
        self.total, self.done, self.initial = total, initial, initial
        self.decile, self.t0 = initial * 10 // max(total, 1), time.perf_counter()

    def update(self, n: int, failed: int) -> None:
        self.bar.update(n)
        self.bar.set_postfix(failed=failed)
        self.done += n
        if not self.tty and self.done * 10 // self.total > self.decile:
            self.decile = self.done * 10 // self.total
            rate = (self.done - self.initial) / max(time.perf_counter() - self.t0, 1e-9)
            eta = (self.total - self.done) / rate if rate > 0 else float("nan")
            print(f"{self.label}: {self.done}/{self.total} runs, {rate * 60:.1f} runs/min, ETA {eta:.0f} s, "
                  f"{failed} failed", file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def run(args) -> int:
    from ..campaign import Store, execute, load_campaign, plots, spec, summarize, table_text, write_run_scenario

    if args.workers is not None and args.workers < 1:
        raise ConfigError("--workers must be at least 1")
    if args.batch_size is not None and args.batch_size < 1:
        raise ConfigError("--batch-size must be at least 1")
    if args.scheduler is not None:
        try:
            import distributed  # noqa: F401
        except ImportError:
            raise ConfigError("--scheduler needs Dask: pip install 'vehest-can[dask]'") from None

    path = spec.CAMPAIGNS.path(args.spec)
    if not path.exists() and Path(args.spec).suffix != ".toml" and len(Path(args.spec).parts) == 1:
        raise ConfigError(f"{args.spec}: no such campaign file, nor a shipped campaign's name (shipped: "
                          f"{', '.join(spec.CAMPAIGNS.names())})")
    campaign = load_campaign(path)
    if args.seed is not None:
        if not 0 <= args.seed < 2**63:
            raise ConfigError(f"--seed {args.seed}: must be an integer in [0, 2^63)")
        campaign = replace(campaign, seed=args.seed, name=f"{campaign.name}-seed{args.seed}")
    car = car_from_args(args)
    if car is not None:
        from ..carfile import car_spec

        if campaign.base.get("kind") not in ("tireforce", "chassis", "roll"):
            raise ConfigError(f"--car: {campaign.base_path.name} is a {campaign.base.get('kind')} scenario; a car "
                              f"file is the 14-DOF car's (tireforce and roll scenarios)")
        campaign = replace(campaign, base={**campaign.base, "car": car_spec(car)})
    out = Path(args.out or Path("out") / "campaign" / campaign.name)
    workers = args.workers or os.cpu_count() or 1
    store = Store(out, campaign)
    where = f"Dask {args.scheduler}" if args.scheduler else f"{workers} local worker{'s' * (workers > 1)}"
    print(f"campaign {campaign.name}: {campaign.runs} runs of {campaign.base_path.name} on {where}; results in {out}/",
          file=sys.stderr)
    bar = Bar(campaign.name)
    t0 = time.perf_counter()
    try:
        counts = execute(campaign, store, workers=workers, scheduler=args.scheduler,
                         batch_size=args.batch_size, progress=bar, fresh=args.fresh)
    except KeyboardInterrupt:
        bar.close()
        n = len(store.table(columns=["run"])) if store.has_rows() else 0
        print(f"interrupted: {n} of {campaign.runs} runs kept in {out}/runs; the same command resumes",
              file=sys.stderr)
        return 130
    bar.close()
    wall = time.perf_counter() - t0
    table = store.table()
    summary = summarize(campaign, table)
    summary["executor"] = where
    summary["this_session"] = {**counts, "wall_s": wall,
                               "runs_per_min": counts["ran"] / wall * 60 if wall > 0 and counts["ran"] else None}
    worst = {}
    for a in campaign.acceptance:
        m = summary["metrics"].get(a.metric)
        if m is not None and "worst_run" in m and m["worst_run"] not in worst:
            worst[m["worst_run"]] = write_run_scenario(campaign, m["worst_run"], out / f"worst_run{m['worst_run']:05d}.toml")
    summary["worst_run_scenarios"] = {str(k): str(v) for k, v in worst.items()}
    if not args.no_plots:
        summary["plots"] = [str(p) for p in plots(campaign, table, summary, out)]
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=str) + "\n")
    print(table_text(summary))
    if counts["ran"]:
        print(f"{counts['ran']} runs in {wall:.1f} s ({summary['this_session']['runs_per_min']:.1f} runs/min), "
              f"{counts['already_done']} already done")
    for k, v in worst.items():
        print(f"worst run #{k} as a scenario: {v}")
    print(f"results: {out}/runs (Parquet), {out}/summary.json")
    return 0
