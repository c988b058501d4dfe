"""``vehest-can bench``: benchmarks, printed side by side with their baselines (no pass/fail)."""
from __future__ import annotations

import json

from ..sim.scenario import load_scenario, scenario_dir
from ..sim.session import drive_from_scenario
from ..tools import bench


def add_subparser(subparsers) -> None:
    p = subparsers.add_parser("bench", help="measure filter, ECU tick and lockstep speed against baselines",
                              description=bench.__doc__)
    p.add_argument("--quick", action="store_true", help="fewer steps and repeats (for a smoke run)")
    p.add_argument("--json", action="store_true", help="print the raw figures as JSON too")
    p.set_defaults(func=run)


def run(args) -> int:
    res = bench.run(quick=args.quick)
    factors = {}
    for path in sorted(scenario_dir().glob("*.toml")):
        sc = load_scenario(path)
        factors[sc.name] = bench.lockstep_factor(lambda sc=sc: drive_from_scenario(sc), repeats=1 if args.quick else 3)
    print(bench.table(res, factors))
    if args.json:
        print(json.dumps({**res, "lockstep_realtime_factor": factors}, indent=2))
    return 0
