"""What several verbs share: the session-log flags (``--log`` is always an output)."""
from __future__ import annotations

import argparse
import dataclasses
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..bus.formats import FORMATS
from ..errors import ConfigError

if TYPE_CHECKING:
    from ..bus.log import SessionLog

#: the longest run of a verb that keeps every tick of its session in memory (sim, faults, demo)
MAX_SESSION_S = 600.0
#: what matplotlib writes, by extension
PLOT_FORMATS = (".png", ".pdf", ".svg")

LOG_HELP = ("log every frame to FILE, in the format of its extension: "
            + ", ".join(f"{k} {v}" for k, v in FORMATS.items())
            + "; absolute time, Tx/Rx, one channel per bus (pt, ch)")


class DeprecatedAlias(argparse.Action):
    """An old flag kept working: stores into the new one's dest and says so on stderr."""

    def __init__(self, option_strings, dest, new: str = "", **kw):
        self.new = new
        super().__init__(option_strings, dest, **kw)

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"warning: {option_string} is deprecated here (it names an input, and --log is always an "
              f"output): use {self.new}", file=sys.stderr)
        setattr(namespace, self.dest, values)


def add_log_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--log", metavar="FILE", help=LOG_HELP)
    parser.add_argument("--log-per-bus", action="store_true",
                        help="one log per bus (FILE-pt.log, FILE-ch.log) instead of one with a channel per bus")


def check_log_arguments(args) -> None:
    """Before anything starts: a bad --log is an error now, not after the run."""
    if getattr(args, "log", None):
        from ..bus.log import check_log_path

        check_log_path(args.log)


def open_session_log(args, nodes) -> SessionLog | None:
    from ..bus.log import SessionLog

    return SessionLog(args.log, nodes, per_bus=args.log_per_bus) if args.log else None


def add_secoc_arguments(parser: argparse.ArgumentParser) -> None:
    """--secoc-keys and --secoc-state: SecOC on for this process's nodes (docs/secoc.md); off without keys."""
    parser.add_argument("--secoc-keys", metavar="KEYFILE",
                        help="SecOC on: secure this process's frames and verify the secured frames it receives, "
                             "with the keys of this file (mode 600; 'vehest-can secoc keygen'). Default: off")
    parser.add_argument("--secoc-state", metavar="FILE",
                        help="with --secoc-keys: the freshness state file (JSON, mode 600), so a restart resumes "
                             "above every FV sent and rejects frames replayed from earlier runs. Default: one file "
                             "per key set and node under $XDG_STATE_HOME/vehest-can (~/.local/state/vehest-can); "
                             "'none': not persisted (every start at FV 1: only for keys made for one run)")


def secoc_from_args(args, nodes: str | tuple[str, ...]):
    """(keys, FreshnessStore or None) for the process playing `nodes`, or None when SecOC is off. The
    state is persisted by default; --secoc-state none says so on stderr."""
    from ..bus.secoc import FreshnessStore, default_state_path, load_keys

    nodes = (nodes,) if isinstance(nodes, str) else tuple(nodes)
    state = getattr(args, "secoc_state", None)
    if not args.secoc_keys:
        if state:
            raise ConfigError("--secoc-state needs --secoc-keys")
        return None
    keys = load_keys(args.secoc_keys)
    for node in nodes:
        if node not in keys:
            raise ConfigError(f"{args.secoc_keys}: no key for {node}, a node this process plays")
    if state == "none":
        print("warning: --secoc-state none: SecOC freshness is not persisted; a restart starts at FV 1 again and "
              "accepts frames replayed from earlier runs (only for keys made for one run)", file=sys.stderr)
        return keys, None
    return keys, FreshnessStore(state or default_state_path(keys, nodes))


def check_seconds(value: float | None, option: str, *, maximum: float = MAX_SESSION_S, zero: bool = False) -> None:
    """A duration flag: a finite number of seconds, > 0 (>= 0 with zero=True), at most `maximum`
    (math.inf: no bound but finiteness, as for a daemon that runs for weeks). The default bound is a
    session's, and its message says why; another bound is the caller's own."""
    if value is None:
        return
    low_ok = value >= 0 if zero else value > 0
    if not (math.isfinite(value) and low_ok and value <= maximum):
        why = " (a session keeps every tick in memory)" if maximum == MAX_SESSION_S else ""
        bound = f" and at most {maximum:g}{why}" if math.isfinite(maximum) else ""
        raise ConfigError(f"{option} must be a finite number of seconds {'>= 0' if zero else '> 0'}{bound}, "
                          f"not {value}")


def check_range(value: float | None, option: str, low: float, high: float, unit: str) -> None:
    """A physical flag (a resolution, a count, a duration with a physical bound): a finite number in
    [low, high], its physical range, else a ConfigError naming flag, range and unit (NaN and inf
    included: a value out of range would print a meaningless figure, not an error)."""
    if value is None:
        return
    if not (math.isfinite(value) and low <= value <= high):
        def text(x: float) -> str:
            return str(int(x)) if math.isfinite(x) and x == int(x) and abs(x) < 1e15 else f"{x:g}"
        raise ConfigError(f"{option} must be a finite number of {unit} in {text(low)}..{text(high)}, not {text(value)}")


def check_plot_path(path: str) -> Path:
    p = Path(path)
    if p.suffix.lower() not in PLOT_FORMATS:
        raise ConfigError(f"{path}: unknown plot format {p.suffix or '(no extension)'!r}; use one of "
                          f"{', '.join(PLOT_FORMATS)}")
    if p.is_dir():
        raise ConfigError(f"{path}: is a folder, not a plot file")
    if not p.parent.is_dir():
        raise ConfigError(f"{path}: folder {p.parent} does not exist")
    return p


CAR_HELP = ("the car (a car file, docs/car.md, or a shipped car's name: paper, commonroad_vehicle1 .. 3): "
            "the ECU is calibrated for it and the 14-DOF plant runs it (a scenario's [vehicle] keys still "
            "override it). Default: the scenario's own car (its `car` key), else the paper's")


def add_car_argument(parser: argparse.ArgumentParser, help: str = CAR_HELP) -> None:
    parser.add_argument("--car", metavar="FILE_OR_NAME", help=help)


def car_from_args(args, *, plant: bool = True):
    """--car loaded and checked before anything starts (its keys against their ranges, then the C of the
    ECU and, with `plant`, of the 14-DOF plant: a refusal names the key), or None when not given."""
    spec = getattr(args, "car", None)
    if not spec:
        return None
    from ..carfile import load_car
    from ..systems.ecu import check_car

    car = load_car(spec)
    check_car(car, plant=plant)
    return car


def ecu_car(car, scenarios) -> Any:
    """The car the ECU is calibrated for: --car (`car`), else the one car the scenarios name (None: the
    paper's); scenarios naming different cars need --car (one ECU serves them all)."""
    if car is not None:
        return car
    from ..carfile import car_of, paper_car

    by_name: dict = {}
    for sc in scenarios:
        if not has_car(sc):
            continue  # not the 14-DOF car: a car file is not its model
        c = car_of(sc) or paper_car()
        by_name.setdefault(str(c.path.resolve() if c.path else c.name), c)
    if len(by_name) > 1:
        raise ConfigError(f"the scenarios name different cars ({', '.join(sorted(by_name))}) and one ECU serves "
                          f"them all: run them separately, or give --car")
    car = next(iter(by_name.values()), None)
    return None if car is paper_car() else car  # the paper's car is the ECU's default


def has_car(scenario) -> bool:
    """Whether a scenario drives the 14-DOF plant (itself, or as its ``plant``): the car a car file describes."""
    from ..sim.veh14 import Veh14Scenario

    return isinstance(scenario, Veh14Scenario) or isinstance(getattr(scenario, "chassis", None), Veh14Scenario)


def with_car(scenario, car):
    """The scenario with its 14-DOF plant on `car` (its [vehicle] overrides kept): a 14-DOF scenario, or
    one holding one as ``chassis``; another scenario's car has no such plant (ConfigError)."""
    from ..sim.veh14 import Veh14Scenario

    if isinstance(scenario, Veh14Scenario):
        return dataclasses.replace(scenario, car=car)
    if has_car(scenario):
        return dataclasses.replace(scenario, chassis=dataclasses.replace(scenario.chassis, car=car))
    raise ConfigError(f"{scenario.name}: a car file is the 14-DOF car's (tyre-force and roll scenarios); this "
                      f"scenario's car is another plant")
