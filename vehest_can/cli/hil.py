"""``vehest-can hil CONFIG``: residual-bus simulation on the buses a HIL configuration names."""
from __future__ import annotations

from dataclasses import asdict

import numpy as np

from ..bus import bus as busmod
from ..bus.frames import TICK_S, database
from ..errors import ConfigError, VehestError
from ..progress import Progress
from ..service import sdnotify
from ..service.hil import ResidualBus, load_hil_config
from ..sim.report import realtime_summary
from ..systems.driveline import report


def add_subparser(subparsers) -> None:
    p = subparsers.add_parser(
        "hil", help="HIL rehearsal: simulate only the nodes the bench lacks",
        description="Residual-bus simulation from a TOML configuration (docs/hil.md): the ECU daemon if "
                    "VEHEST is simulated, the car (plant + sensor node) if DLS and SIM are, both in one "
                    "process if both are, on the configured python-can buses.")
    p.add_argument("config", metavar="CONFIG", help="HIL configuration (TOML)")
    p.add_argument("--check", action="store_true",
                   help="validate the configuration and print its buses, bit rates, bus load and nodes; run nothing")
    p.add_argument("--duration", type=float, metavar="S",
                   help="run S seconds (default: the configuration's duration_s, else the scenario's length; "
                        "an ECU alone runs until SIGINT/SIGTERM)")
    sdnotify.add_log_level(p)
    p.set_defaults(func=run)


def run(args) -> int:
    if args.duration is not None and not args.duration > 0:
        raise ConfigError("--duration must be positive")
    config = load_hil_config(args.config)
    if args.check:
        print("\n".join(config.summary()))
        print(f"{config.path}: valid")
        return 0

    sdnotify.apply_log_level(args.log_level)
    notifier = sdnotify.Notifier.from_env()
    name = config.scenario.name if config.scenario is not None else ""
    progress = Progress(f"{name} (real time)" if config.mode == "realtime"
                        else f"{name} (lockstep)") if config.car_simulated else None
    runner = ResidualBus(config, duration_s=args.duration, notifier=notifier, progress=progress)
    try:
        with busmod.stop_on_signals(runner.stop):
            if not config.ecu_simulated:
                notifier.ready(f"car simulated on bus {config.bus_of('DLS').name}")
            result = runner.run()
    finally:
        if not config.ecu_simulated:
            notifier.stopping()
    if progress is not None:
        progress.done()
    print("\n".join(result.bus_info))

    if result.ecu is not None:
        print(f"ECU (simulated here, bus {result.ecu_bus}):")
        print("\n".join(f"  {line}" for line in result.ecu.lines()))
    if result.session is None:
        return 0
    session = result.session
    est_id = database("pt").get_message_by_name("VEHEST_DrivelineEst").frame_id
    n_est = int(np.sum(session.frames["id"] == est_id))
    st = session.stats
    print(f"car (simulated here, bus {result.car_bus}): {session.name}, {len(session.truth)} ticks "
          f"({len(session.truth) * TICK_S:.1f} s simulated, {st.get('wall_s', 0.0):.1f} s wall), "
          f"{n_est} VEHEST_DrivelineEst frames received")
    if session.mode == "realtime":
        late = st.get("lateness_us", {})
        print(f"  {st.get('frames_sent', 0)} sensor frames sent; deadline misses {st.get('deadline_misses', 0)}; "
              f"tick lateness µs p50={late.get('p50', float('nan')):.0f} p99={late.get('p99', float('nan')):.0f}")
    if result.ecu is not None and session.mode == "realtime":
        # Both sides here: frames lost on the way in are exact (both counts are ours). The ECU's own
        # frames are not compared: it ticks on before the car starts listening and after it stops.
        rt = realtime_summary(session, asdict(result.ecu))
        lat = rt["frame_to_estimate_latency_us"]
        print(f"  sensor frames: {rt['sensor_frames_sent']} sent, {rt['sensor_frames_received_by_ecu']} received "
              f"by the ECU; frame-to-estimate latency µs p50={lat.get('p50', float('nan')):.0f} "
              f"p99={lat.get('p99', float('nan')):.0f}")
    if n_est == 0:
        raise VehestError(f"no VEHEST_DrivelineEst frame arrived on bus {result.car_bus}: is the ECU on the bus "
                          f"(powered, same bit rates, terminated)?")
    print(report.table([report.driveline_metrics(session)]))
    return 0
