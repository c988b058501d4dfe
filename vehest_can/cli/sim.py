"""``vehest-can sim SCENARIO``: the simulated car alone on a bus (the ECU is elsewhere)."""
from __future__ import annotations

import sys

from ..bus import bus as busmod
from ..errors import ConfigError
from ._common import (
    add_car_argument,
    add_log_arguments,
    add_secoc_arguments,
    car_from_args,
    check_log_arguments,
    check_seconds,
    open_session_log,
    secoc_from_args,
    with_car,
)

#: the verb's one line in `vehest-can --help` (read without building its parser)
HELP = "run the simulated car and sensor nodes on a bus"


def add_subparser(subparsers) -> None:
    p = subparsers.add_parser("sim", help=HELP,
                              description="Run a scenario's car on a python-can bus, against an ECU (daemon or "
                                          "real) on the same bus.")
    p.add_argument("scenario", metavar="SCENARIO", help="scenario file, or the name of a shipped one (any "
                                                        "system's car: driveline, camber, tyre force, roll)")
    p.add_argument("--mode", choices=("realtime", "lockstep"), default="realtime",
                   help="realtime: 2 kHz wall clock (default); lockstep: drive an ECU daemon in --mode lockstep")
    p.add_argument("--duration", type=float, metavar="S", help="run S seconds (repeats the driver profile)")
    p.add_argument("--pose", choices=("wheel", "x_down", "z_down"),
                   help="camber inspection devices in this pose (calibration fixture), overriding the scenario")
    add_car_argument(p, "the car the 14-DOF plant runs (a car file, docs/car.md, or a shipped car's name: paper, "
                        "commonroad_vehicle1 .. 3), instead of the scenario's own (its [vehicle] keys still "
                        "override it); tyre-force and roll scenarios")
    add_log_arguments(p)
    add_secoc_arguments(p)
    busmod.add_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from ..progress import Progress
    from ..sim.session import CAR_NODES, SimMaster
    from ..systems import load_any_scenario

    system, sc = load_any_scenario(args.scenario)
    if args.pose is not None:
        if getattr(sc, "camber", None) is None:
            raise ConfigError(f"{args.scenario}: --pose needs a scenario with a [camber] table")
        from dataclasses import replace

        sc = replace(sc, camber=replace(sc.camber, pose=args.pose))
    car = car_from_args(args)
    if car is not None:
        sc = with_car(sc, car)
    check_seconds(args.duration, "--duration")
    check_log_arguments(args)
    drive = system.car(sc, args.duration)
    nodes = getattr(drive, "SECOC_NODES", ())
    if args.secoc_keys and not nodes:
        raise ConfigError(f"{sc.name}: this car has no secured node: leave out --secoc-keys")
    secoc = secoc_from_args(args, nodes) if nodes else None
    if secoc is not None:
        drive.enable_secoc(*secoc)
        if secoc[1] is not None:
            print(f"vehest-can sim: SecOC freshness state {secoc[1].path}", file=sys.stderr, flush=True)
    config = busmod.bus_config(args)
    bus = busmod.open_bus(config)
    writer = open_session_log(args, CAR_NODES)
    progress = Progress(f"{sc.name} ({args.mode})")
    # Nothing kept: the frames go to --log as they come, so a long run's memory stays flat
    master = SimMaster(bus, drive, log_writer=writer, progress=progress, keep=False)
    try:
        with busmod.serving(bus, writer, master.stop_event.set):
            session = master.run_lockstep() if args.mode == "lockstep" else master.run_realtime()
    finally:
        for s in master.car.secoc_hooks() if hasattr(master.car, "secoc_hooks") else ():
            s.close()  # the exact state of a clean end
    st = session.stats
    progress.done(f"{st['ticks']} ticks, {st['frames']} frames")
    print(f"{sc.name}: {st['ticks']} ticks, {st['frames']} frames, {st.get('wall_s', 0):.1f} s", file=sys.stderr)
    return 0
