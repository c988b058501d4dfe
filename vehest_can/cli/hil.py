"""``vehest-can hil CONFIG``: residual-bus simulation on the buses a HIL configuration names.

Nothing here knows a system by name: each car's figures come from its system in the registry."""
from __future__ import annotations

import collections
from dataclasses import replace
from pathlib import Path

from ..bus import bus as busmod
from ..errors import VehestError
from ._common import add_car_argument, car_from_args, check_seconds, ecu_car, has_car, with_car

#: the verb's one line in `vehest-can --help` (read without building its parser)
HELP = "HIL rehearsal: simulate only the nodes the bench lacks"


def add_subparser(subparsers) -> None:
    from ..service import sdnotify

    p = subparsers.add_parser(
        "hil", help=HELP,
        description="Residual-bus simulation from a TOML configuration (docs/hil.md): the ECU daemon on each of "
                    "its buses if VEHEST is simulated, the car of each scenario (plant + sensor node of a "
                    "registered system) if its nodes are, all in one process, on the configured python-can buses.")
    p.add_argument("config", metavar="CONFIG", help="HIL configuration (TOML)")
    p.add_argument("--check", action="store_true",
                   help="validate the configuration and print its buses, bit rates, bus load and nodes; run nothing")
    p.add_argument("--duration", type=float, metavar="S",
                   help="run S seconds (default: the configuration's duration_s, else the scenario's length; "
                        "an ECU alone runs until SIGINT/SIGTERM)")
    p.add_argument("-o", "--out", default="out/hil", metavar="DIR",
                   help="where each car's plots go (default: out/hil)")
    add_car_argument(p)
    sdnotify.add_log_level(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from ..bus.frames import DBCS, TICK_S, database, sent_by
    from ..progress import Progress
    from ..service import sdnotify
    from ..service.hil import ResidualBus, load_hil_config
    from ..systems import Setup, registered

    check_seconds(args.duration, "--duration", maximum=86_400)
    config = load_hil_config(args.config)
    if args.check:
        print("\n".join(config.summary()))
        print(f"{config.path}: valid")
        return 0

    ecar = car_from_args(args)
    if ecar is not None:  # the simulated 14-DOF cars run it
        config = replace(config, cars=tuple(replace(c, scenario=with_car(c.scenario, ecar)) if has_car(c.scenario)
                                            else c for c in config.cars))
    ecar = ecu_car(ecar, [c.scenario for c in config.cars])  # the ECU's calibration
    sdnotify.apply_log_level(args.log_level)
    notifier = sdnotify.Notifier.from_env()
    out = Path(args.out)
    systems = {s.name: s for s in registered()}
    setups: dict[str, Setup] = {}
    if config.ecu_simulated:  # what each car's system asks of the ECU first (e.g. calibrations)
        for name in dict.fromkeys(car.system for car in config.cars):
            out.mkdir(parents=True, exist_ok=True)
            setups[name] = systems[name].setup([c.scenario for c in config.cars if c.system == name], out)
            setups[name].car = ecar

    def configure(ecu) -> None:
        for st in setups.values():
            st.configure(ecu)

    name = config.scenario.name if config.scenario is not None else ""
    progress = Progress(f"{name} (real time)" if config.mode == "realtime"
                        else f"{name} (lockstep)") if config.car_simulated else None
    runner = ResidualBus(config, duration_s=args.duration, notifier=notifier, progress=progress, configure=configure,
                         car=ecar)
    try:
        with busmod.stop_on_signals(runner.stop):
            if not config.ecu_simulated:
                notifier.ready("cars simulated on " + ", ".join(f"bus {c.bus}" for c in config.cars))
            result = runner.run()
    finally:
        if not config.ecu_simulated:
            notifier.stopping()
    if progress is not None:
        progress.done()
    print("\n".join(result.bus_info))

    if result.ecu is not None:
        print(f"ECU (simulated here, bus{'es' if len(result.ecu_buses) > 1 else ''} {', '.join(result.ecu_buses)}):")
        print("\n".join(f"  {line}" for line in result.ecu.lines()))
    ecu_ids = sent_by({"VEHEST"})
    names = {m.frame_id: m.name for b in DBCS for m in database(b).messages}
    metrics: dict[str, list] = collections.defaultdict(list)
    for car, session in result.sessions:
        st = session.stats
        ids = collections.Counter(int(i) for i in session.frames["id"] if int(i) in ecu_ids)
        heard = ", ".join(f"{n} {names[i]}" for i, n in sorted(ids.items())) or "none"
        print(f"car (simulated here, bus {car.bus}): {session.name}, {len(session.truth)} ticks "
              f"({len(session.truth) * TICK_S:.1f} s simulated, {st.get('wall_s', 0.0):.1f} s wall); "
              f"frames received from the ECU: {heard}")
        if session.mode == "realtime":
            late = st.get("lateness_us", {})
            print(f"  {st.get('frames_sent', 0)} sensor frames sent; deadline misses {st.get('deadline_misses', 0)}; "
                  f"tick lateness µs p50={late.get('p50', float('nan')):.0f} p99={late.get('p99', float('nan')):.0f}")
            if result.ecu is not None:
                # Both sides here: frames lost on the way in are exact (both counts are ours).
                got = result.ecu.buses.get(car.bus, {}).get("rx", 0)
                print(f"  sensor frames: {st.get('frames_sent', 0)} sent, {got} received by the ECU on bus {car.bus}")
        if not ids:
            raise VehestError(f"no frame of the ECU (VEHEST) arrived on bus {car.bus}: is the ECU on the bus "
                              f"(powered, same bit rates, terminated)?")
        sdir = out / session.name
        sdir.mkdir(parents=True, exist_ok=True)
        metrics[car.system].append(systems[car.system].metrics(car.scenario, session, sdir,
                                                               setups.get(car.system, Setup(car=ecar))))
    tables = [t for s in systems.values() for t in s.tables(metrics.get(s.name, []))]
    if tables:
        print("\n\n".join(tables))
    return 0
