"""``vehest-can bench``: benchmarks, printed side by side with their baselines (no pass/fail)."""
from __future__ import annotations

import json

from ..sim.car import PLANTS, on_plants
from ..systems import load_any_scenario, shipped_scenarios
from ..tools import bench, replay_bench
from ._common import check_range


def add_subparser(subparsers) -> None:
    p = subparsers.add_parser("bench", help="measure filter, ECU tick and lockstep speed against baselines",
                              description=bench.__doc__)
    p.add_argument("--quick", action="store_true", help="fewer steps and repeats (for a smoke run)")
    p.add_argument("--json", action="store_true", help="print the raw figures as JSON too")
    p.add_argument("--replay-frames", type=int, default=10_000_000, metavar="N",
                   help="frames of the generated log of the replay benchmark (default 10,000,000; --quick 1,000,000; "
                        "0 = no replay benchmark)")
    p.add_argument("--replay-only", action="store_true", help="only the replay benchmark")
    p.set_defaults(func=run)


def run(args) -> int:
    check_range(args.replay_frames, "--replay-frames", 0, 100_000_000, "frames")  # 100 M: a 6 GB log
    frames = min(args.replay_frames, 1_000_000) if args.quick else args.replay_frames
    rep = replay_bench.run(frames, repeats=1 if args.quick else 3) if frames else None
    if args.replay_only:
        if rep:
            print(replay_bench.table(rep))
            if args.json:
                print(json.dumps({"replay": rep}, indent=2))
        return 0
    res = bench.run(quick=args.quick)
    factors = {}  # every shipped scenario of every system: (car alone, car + ECU in lockstep)
    for path in shipped_scenarios():
        system, base = load_any_scenario(path)
        for sc in on_plants(base, PLANTS):  # the 14-DOF scenarios on both plants
            factors[f"{system.name} {sc.name}"] = bench.lockstep_factors(lambda s=system, sc=sc: s.car(sc),
                                                                         repeats=1 if args.quick else 3)
    print(bench.table(res, factors))
    if rep:
        print(replay_bench.table(rep))
    if args.json:
        print(json.dumps({**res, "lockstep_realtime_factor": factors, "replay": rep}, indent=2))
    return 0
