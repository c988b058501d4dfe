"""``vehest-can demo``: the main job. Car and ECU as two processes on a bus, every shipped scenario
of every registered system (:mod:`vehest_can.systems`), then each system's tables beside the
papers' figures, plots, metrics and candump logs. Nothing here knows a system by name."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING

from ..bus import bus as busmod
from ..bus.formats import FORMATS
from ..errors import ConfigError, VehestError
from ..sim import PLANTS
from ._common import CAR_HELP, add_car_argument, car_from_args, check_seconds, ecu_car, has_car, with_car
from ._target import add_target_argument, on_qemu

if TYPE_CHECKING:  # annotations only: the verb's parser loads none of it
    from ..systems import System


#: the verb's one line in `vehest-can --help` (read without building its parser)
HELP = "the full loop: plant -> bus -> ECU -> estimates, with table and plots"


def add_subparser(subparsers) -> None:
    p = subparsers.add_parser("demo", help=HELP,
                              description="Start the ECU daemon as its own process, run every system's scenarios in "
                                          "lockstep over the bus, and report against the papers.")
    p.add_argument("scenarios", nargs="*", metavar="SCENARIO",
                   help="scenario files (or names of shipped ones) of any system (default: every scenario "
                        "shipped with each registered system)")
    p.add_argument("-o", "--out", default="out/demo", metavar="DIR", help="output folder (default: out/demo)")
    p.add_argument("--realtime", type=float, default=0.0, metavar="S",
                   help="also run S seconds in real time (2 kHz wall clock on both sides)")
    p.add_argument("--check", action="store_true",
                   help="exit 4 when an acceptance line fails (FAIL), for CI and make targets")
    p.add_argument("--junit", metavar="FILE", help="write the acceptance lines as a JUnit XML report")
    p.add_argument("--log-format", choices=[k[1:] for k in FORMATS], default="log",
                   help="format of each scenario's session log (default: log, candump -L)")
    p.add_argument("--secoc", choices=("on", "off"), default="on",
                   help="SecOC-authenticated frames (default on: development keys are made for the run in a "
                        "private temporary folder and deleted after it; docs/secoc.md)")
    p.add_argument("--plant", choices=(*PLANTS, "both"), default="both",
                   help="the plant of the scenarios that can choose one and name none (default both: each such "
                        "scenario on every plant, side by side)")
    p.add_argument("--log-per-bus", action="store_true",
                   help="one session log per bus (session-pt.log, session-ch.log) instead of one with a channel per bus")
    add_car_argument(p, CAR_HELP + "; the ECU daemon and the references of the metrics are calibrated for the "
                                   "same car (scenarios naming different cars need --car)")
    add_target_argument(p)
    busmod.add_arguments(p)
    p.set_defaults(func=run)


def _daemon_cmd(config: dict, mode: str, extra: list[str]) -> list[str]:
    return [sys.executable, "-m", "vehest_can.cli", "daemon", "--mode", mode, *extra, *busmod.cli_args(config)]


def run(args, systems: list[System] | None = None) -> int:
    from ..carfile import car_spec
    from ..sim.car import on_plants
    from ..systems import Setup, load_any_scenario, registered, shipped_scenarios

    check_seconds(args.realtime, "--realtime", zero=True)
    if on_qemu(args):
        if args.realtime:
            raise ConfigError(f"--realtime with --target {args.target}: the emulated ECU runs in lockstep only")
        if args.secoc == "on":
            print(f"SecOC: off (--target {args.target}: the emulated board has no AES backend)")
            args.secoc = "off"
    systems = registered() if systems is None else systems
    paths = [Path(p) for p in args.scenarios] or shipped_scenarios(systems)
    runs = [load_any_scenario(p, systems) for p in paths]
    car = car_from_args(args)
    if car is not None:  # the 14-DOF cars run it; the other plants are not what a car file describes
        runs = [(s, with_car(sc, car) if has_car(sc) else sc) for s, sc in runs]
    plants = PLANTS if args.plant == "both" else (args.plant,)
    runs = [(s, v) for s, sc in runs for v in on_plants(sc, plants)]
    car = ecu_car(car, [sc for _, sc in runs])
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    config = busmod.bus_config(args)
    if config == {"interface": busmod.DEFAULT_INTERFACE, "channel": busmod.DEFAULT_CHANNEL, "fd": True}:
        # nothing chosen and both processes are ours: a bus of this run's own keeps other runs out
        config = busmod.private_multicast()
    port = f" port {config['port']}" if "port" in config else ""
    print(f"bus: {config['interface']} {config.get('channel')}{port}; ECU daemon in its own process; output in {out}/")

    setups: dict[str, Setup] = {s.name: s.setup([sc for r, sc in runs if r is s], out) for s in systems}
    for st in setups.values():
        st.car = car
    daemon_args = [a for st in setups.values() for a in st.daemon_args] + (["--car", car_spec(car)] if car else [])
    daemon_args += ["--target", args.target] if getattr(args, "target", "host") != "host" else []
    with tempfile.TemporaryDirectory(prefix="vehest-secoc-") as keydir:
        keys = _dev_keys(Path(keydir)) if args.secoc == "on" else None
        secoc_args = []
        if keys is not None:
            # Keys made for this run are a freshness domain of their own (no frame of another run
            # verifies under them), so neither side persists freshness: every session starts at FV 1
            # on both sides, the bus run and the in-process run alike (bit for bit, tails included).
            secoc_args = ["--secoc-keys", str(Path(keydir) / "dev_keys.toml"), "--secoc-state", "none"]
            print(f"SecOC: on ({len(keys)} development keys made for this run, deleted after it; "
                  f"freshness not persisted)")
        return _run(args, systems, runs, out, config, setups, daemon_args + secoc_args, keys, secoc_args)


def _dev_keys(keydir: Path) -> dict:
    from ..bus.secoc import write_dev_keys
    from .secoc import sending_nodes

    return write_dev_keys(keydir / "dev_keys.toml", sending_nodes())


def _with_secoc(car, keys):
    """The car with its secured nodes keyed (a car without any takes no keys)."""
    enable = getattr(car, "enable_secoc", None)
    if keys is not None and enable is not None:
        enable(keys)
    return car


#: In lockstep nothing waits on the wall clock but these bounds, each far beyond what a loaded machine
#: needs (docs/results.md): the daemon's first answer, one tick's answer, and the daemon's own idle stop
#: (between two scenarios the demo draws plots; the daemon must outlive that, and still stop if the
#: demo itself is killed).
RESET_WAIT_S, ACK_WAIT_S, DAEMON_IDLE_S = 120.0, 60.0, 1800.0


def _daemon_check(proc: subprocess.Popen, log: Path):
    """A callable: None while the daemon runs, else why it cannot answer, with its last lines."""
    def why() -> str | None:
        if proc.poll() is None:
            return None
        lines = log.read_text(errors="replace").strip().splitlines()[-5:] if log.exists() else []
        return (f"the ECU daemon exited (status {proc.returncode}); its last lines: "
                + (" | ".join(lines) if lines else "(none)"))
    return why


def _run(args, systems, runs, out: Path, config: dict, setups: dict, daemon_args: list[str], keys,
         secoc_args: list[str]) -> int:
    from ..service.daemon import stop_process
    from ..sim.report import FAIL, checks_of, checks_text, write_junit, write_metrics

    daemon_log = out / "ecu_daemon.log"
    with open(daemon_log, "w") as log_file:  # a file, not a pipe: a chatty daemon never blocks on it
        ecu_proc = subprocess.Popen(_daemon_cmd(config, "lockstep", ["--idle-timeout", f"{DAEMON_IDLE_S:g}",
                                                                     *daemon_args]),
                                    stdout=log_file, stderr=subprocess.STDOUT, text=True, env=os.environ.copy())
    daemon_gone = _daemon_check(ecu_proc, daemon_log)
    results: list[tuple[System, dict]] = []
    stopped: str | None = None  # why the demo stopped before its last scenario
    try:
        bus = busmod.open_bus(config)
        try:
            for system, sc in runs:
                metrics = _scenario(args, system, sc, out, bus, setups, keys, daemon_gone)
                results.append((system, metrics))
                # kept as it comes: the metrics so far and this scenario's table, whatever happens next
                write_metrics([m for _, m in results], out / "metrics.json")
                (out / sc.name / "table.txt").write_text("\n\n".join(system.tables([metrics])) + "\n")
        except KeyboardInterrupt:
            stopped = "interrupted (Ctrl-C)"
        except VehestError as exc:
            stopped = str(exc)
        finally:
            bus.shutdown()
    finally:
        stop_process(ecu_proc, timeout=10)
    tail = daemon_log.read_text(errors="replace").strip().splitlines()[-4:]
    print("ECU daemon: " + " | ".join(tail) + f" (its log: {daemon_log})")

    all_metrics = [m for _, m in results]
    if args.realtime > 0 and stopped is None:
        wall_clock = [(s, sc) for s, sc in runs if s.realtime]
        system, sc = (wall_clock or runs)[0]
        all_metrics.append(_realtime(args, config, _with_secoc(system.car(sc, args.realtime), keys), sc.name, out,
                                     secoc_args))

    write_metrics(all_metrics, out / "metrics.json")
    print()
    tables = [t for s in systems for t in s.tables([m for r, m in results if r is s])]
    if tables:
        print("\n\n".join(tables))
    checks = [c for system, m in results for c in checks_of(m, f"{system.name}.{m.get('scenario', '?')}")]
    if checks:
        print("\nacceptance:\n" + checks_text(checks))
    if args.junit:
        write_junit(checks, Path(args.junit))
        print(f"JUnit report: {args.junit}")
    print(f"\nplots: {', '.join(str(p) for p in sorted(out.glob('*/*.png')))}")
    logs = sorted(out.glob(f"*/session*.{args.log_format}"))
    print(f"metrics: {out / 'metrics.json'}; session logs: {', '.join(str(p) for p in logs)}")
    if stopped is not None:
        print(f"demo: stopped after {len(results)} of {len(runs)} scenarios: {stopped}", file=sys.stderr)
        return 130 if stopped.startswith("interrupted") else 1
    failed = [c for c in checks if not c["passed"]]
    if args.check and failed:
        print(f"demo --check: {len(failed)} acceptance line(s) {FAIL}", file=sys.stderr)
        return 4
    return 0


def _scenario(args, system, sc, out: Path, bus, setups: dict, keys, daemon_gone) -> dict:
    """One scenario over the bus, its in-process twin, and its metrics (plots written)."""
    import numpy as np

    from ..bus.log import SessionLog
    from ..progress import Progress
    from ..sim.session import SimMaster, run_inprocess
    from ..systems.ecu import Ecu, EcuConfig

    sdir = out / sc.name
    sdir.mkdir(parents=True, exist_ok=True)
    progress = Progress(f"{sc.name} (lockstep)")
    # the ECU's view of the session (its frames Tx), as the daemon would log it
    with SessionLog(sdir / f"session.{args.log_format}", {"VEHEST"}, per_bus=args.log_per_bus) as writer:
        master = SimMaster(bus, _with_secoc(system.car(sc), keys), log_writer=writer, progress=progress,
                           ack_timeout=ACK_WAIT_S, peer=daemon_gone)
        session = master.run_lockstep(end=False, connect_timeout_s=RESET_WAIT_S)
    progress.done(f"{session.stats['realtime_factor']:.1f}x real time over the bus")
    local_ecu = Ecu(EcuConfig(car=next(iter(setups.values())).car if setups else None))  # like the daemon
    for st in setups.values():
        st.configure(local_ecu)
    if keys is not None:
        local_ecu.enable_secoc(keys)
    local = run_inprocess(_with_secoc(system.car(sc), keys), local_ecu)
    same = (len(local.frames) == len(session.frames)
            and np.array_equal(local.frames, session.frames))
    print(f"  bus lockstep == in-process lockstep: {'identical' if same else 'DIFFERENT'} "
          f"({len(session.frames)} frames)")
    diverged = session.diverged_s()
    if diverged is not None:
        print(f"  plant: the car left the range its model holds at {diverged:.3f} s (its state not finite, or "
              f"rolling over): the figures below cover the run up to then")
        session = session.until(diverged)
    metrics = system.metrics(sc, session, sdir, setups[system.name])
    if diverged is not None:
        metrics["plant_diverged_s"] = diverged
        metrics.setdefault("acceptance", []).append(
            {"line": "the car stays in its plant's range", "verdict": "FAIL", "detail": f"left it at {diverged:.3f} s"})
    metrics["bus_equals_inprocess"] = bool(same)
    metrics["inprocess_realtime_factor"] = local.stats["realtime_factor"]
    return metrics


def _realtime(args, config, car, name: str, out: Path, extra: list[str]) -> dict:
    from ..progress import Progress
    from ..service.daemon import stop_process
    from ..sim.report import realtime_summary
    from ..sim.session import SimMaster

    stats_file = out / "realtime_daemon.json"
    stats_file.unlink(missing_ok=True)
    # no --duration: the daemon runs until the car is done and SIGTERM stops it (clean shutdown)
    ecu_proc = subprocess.Popen(_daemon_cmd(config, "realtime", ["--stats", str(stats_file), *extra]),
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(1.0)  # let the daemon open its bus
    bus = busmod.open_bus(config)
    try:
        progress = Progress(f"{name} (real time)")
        session = SimMaster(bus, car, progress=progress).run_realtime()
        progress.done()
    finally:
        bus.shutdown()
        err = stop_process(ecu_proc, timeout=10)
    if ecu_proc.returncode not in (0, -signal.SIGTERM):
        raise VehestError(f"real-time ECU daemon failed: {err}")
    if not stats_file.exists():
        raise VehestError(f"real-time ECU daemon wrote no statistics: {err}")
    summary = realtime_summary(session, json.loads(stats_file.read_text()))
    print("real time: " + summary["line"])
    return summary
