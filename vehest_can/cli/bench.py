"""``vehest-can bench``: benchmarks, printed side by side with their baselines (no pass/fail)."""
from __future__ import annotations

import json

from ._common import check_range

DESCRIPTION = """Speed figures, measured side by side in one process: each filter step through the array API
against filterpy; the ECU tick (unpack, checks, filters, pack) in a C loop, with XCP and SecOC off
and on; the tyre-force steps (fixed point, double, the plain EKF) against the numpy reference; the
14-DOF chassis plant alone; per shipped scenario, and on both plants for the 14-DOF car, the car
alone and its in-process lockstep with the ECU in multiples of real time; the replay of a generated
log against python-can's LogReader. Medians of repeated runs; ratios are against baselines timed in
the same run. Targets: filter >= 100x filterpy, ECU tick <= 5 µs median (every system: <= 15 µs,
longest <= 100 µs), lockstep >= 100x real time (CommonRoad's multi-body car alone >= 10x). Last, the
same ECU on an emulated Cortex-M4F (QEMU, instruction counting): instructions per tick per system as
cycles at 168 MHz against the 84,000 of a tick, and beside it on a Cortex-M7 at 400 MHz (200,000)
(skipped, with the reason, without qemu-system-arm and arm-none-eabi-gcc)."""


#: the verb's one line in `vehest-can --help` (read without building its parser)
HELP = "measure filter, ECU tick and lockstep speed against baselines"


def add_subparser(subparsers) -> None:
    p = subparsers.add_parser("bench", help=HELP,
                              description=DESCRIPTION)
    p.add_argument("--quick", action="store_true", help="fewer steps and repeats (for a smoke run)")
    p.add_argument("--json", action="store_true", help="print the raw figures as JSON too")
    p.add_argument("--replay-frames", type=int, default=10_000_000, metavar="N",
                   help="frames of the generated log of the replay benchmark (default 10,000,000; --quick 1,000,000; "
                        "0 = no replay benchmark)")
    p.add_argument("--replay-only", action="store_true", help="only the replay benchmark")
    p.add_argument("--no-pil", action="store_true",
                   help="leave out the emulated Cortex-M4F's and Cortex-M7's cost per tick (minutes of QEMU)")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..sim.car import PLANTS, on_plants
    from ..systems import load_any_scenario, shipped_scenarios
    from ..tools import bench, replay_bench

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
    if args.no_pil:
        from ..tools.pil_bench import PARTS

        targets: dict[str, dict | None] = dict.fromkeys(PARTS)  # the JSON's keys stay, as null
    else:
        targets = _pil(args.quick)
    if args.json:
        print(json.dumps({**res, "lockstep_realtime_factor": factors, "replay": rep,
                          **{core.replace("-", "_"): r for core, r in targets.items()}}, indent=2))
    return 0


def _pil(quick: bool) -> dict[str, dict | None]:
    """The emulated ECU's cost per tick on the Cortex-M4F and, beside it, the Cortex-M7, printed; None
    (and the reason) where it cannot run."""
    from ..service.pil import missing_tools
    from ..tools import pil_bench

    why = missing_tools()
    out: dict[str, dict | None] = {}
    for core in pil_bench.PARTS:
        if why:
            print(f"{pil_bench.PARTS[core].name} cost per tick: skipped ({why})")
            out[core] = None
            continue
        res = pil_bench.measure(0.25 if quick else 1.0, core=core)
        print(pil_bench.table(res))
        out[core] = res
    return out
