"""HIL rehearsal: a TOML file names the buses, the DBC on each, and which nodes are simulated here.

Residual-bus simulation: simulate only what the bench lacks. The project can simulate the ECU
(``VEHEST``, :class:`~vehest_can.service.daemon.EcuDaemon`, on every bus it is on) and the car of
every registered system (:mod:`vehest_can.systems`: each says which DBC nodes its car plays, e.g. the
driveline's ``DLS`` and ``SIM``, the tyre force's ``CHS``), each car a
:class:`~vehest_can.sim.SimMaster` on its bus, driven by a scenario of that system. Every other node
of a bus's DBC is real (on the bench) or absent.

The schema is documented in ``docs/hil.md``. ``load_hil_config`` checks every key and raises
:class:`~vehest_can.errors.ConfigError` whose message names the file, the key as a dotted path and
the problem; :class:`ResidualBus` runs the simulated nodes against the configured buses.
"""
from __future__ import annotations

import difflib
import logging
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import can

from ..bus import bus as busmod
from ..bus.busload import bus_load, check_cycles, load_dbc
from ..bus.frames import BUSES, database
from ..errors import ConfigError, ScenarioError, VehestError
from ..paths import dbc_dir
from ..schema import Checker, Num, read_toml, type_name
from ..sim.session import SimMaster
from ..systems import System, claiming, registered, shipped_scenarios, unclaimed
from ..systems.ecu import Ecu, EcuConfig
from .daemon import EcuDaemon

log = logging.getLogger(__name__)

#: Worst-case bus load a configuration may reach at its bit rates, %.
BUS_LOAD_LIMIT_PCT = 60.0

SIMULATED, REAL = "simulated", "real"
ECU_NODE = "VEHEST"
MODES = ("realtime", "lockstep")

_TOP = {"description", "mode", "scenario", "duration_s", "buses", "nodes"}
_BUS = {"interface", "channel", "bitrate", "data_bitrate", "fd", "dbc", "nodes", "timing", "kwargs"}
_NODES = {SIMULATED, REAL}
_TIMING_FD = ("f_clock", "nom_brp", "nom_tseg1", "nom_tseg2", "nom_sjw",
              "data_brp", "data_tseg1", "data_tseg2", "data_sjw")
_TIMING = ("f_clock", "brp", "tseg1", "tseg2", "sjw", "nof_samples")  # nof_samples optional (1)
_NOMINAL_RATE = (5_000, 1_000_000)   # bit/s: ISO 11898 nominal rates end at 1 Mbit/s
_DATA_RATE = (5_000, 16_000_000)     # bit/s: CAN FD data phase; transceivers go to 5..12 Mbit/s
_DURATION = Num(0.0, 86_400.0, lo_open=True)


# ---- the configuration ---------------------------------------------------------------------

@dataclass(frozen=True)
class HilBus:
    """One bus: how python-can opens it, its DBC, the nodes on it and its load at the configured rates."""

    name: str
    interface: str
    channel: str | int
    fd: bool
    dbc: Path
    nodes: tuple[str, ...]                   # nodes on this bus (the DBC's, or the bus's `nodes` list)
    bitrate: int | None = None               # None: the interface's default (and the DBC's for the load)
    data_bitrate: int | None = None
    timing: can.BitTiming | can.BitTimingFd | None = None
    kwargs: tuple[tuple[str, Any], ...] = ()  # extra python-can arguments, as written
    load_bitrate: int = 0                    # the rates the load was computed at
    load_data_bitrate: int | None = None
    load_worst_pct: float = 0.0
    load_nominal_pct: float = 0.0
    load_notes: tuple[str, ...] = ()
    not_checked: str = ""                    # why the kwargs could not be checked against the interface here

    def bus_kwargs(self) -> dict:
        """python-can configuration (``can.Bus(**kwargs)``, ``vehest_can.bus.open_bus``)."""
        out: dict[str, Any] = {"interface": self.interface, "channel": self.channel, "fd": self.fd}
        if self.timing is not None:
            out["timing"] = self.timing
        if self.bitrate is not None:
            out["bitrate"] = self.bitrate
        if self.data_bitrate is not None:
            out["data_bitrate"] = self.data_bitrate
        out.update(dict(self.kwargs))
        return out


@dataclass(frozen=True)
class HilCar:
    """One simulated car: a registered system's scenario, the nodes it plays here, its bus."""

    system: str
    scenario: Any
    nodes: tuple[str, ...]
    bus: str


@dataclass(frozen=True)
class HilConfig:
    """A validated HIL configuration (see the module docstring)."""

    path: Path
    mode: str
    buses: tuple[HilBus, ...]
    simulated: tuple[str, ...]
    real: tuple[str, ...]
    cars: tuple[HilCar, ...] = ()
    duration_s: float | None = None
    description: str = ""
    node_bus: tuple[tuple[str, str], ...] = ()  # (simulated node, its bus; the ECU's first bus)
    ecu_buses: tuple[str, ...] = ()             # every bus the simulated ECU is on

    def bus(self, name: str) -> HilBus:
        for b in self.buses:
            if b.name == name:
                return b
        raise KeyError(f"no bus {name!r} in {self.path} (buses: {', '.join(b.name for b in self.buses)})")

    def bus_kwargs(self, name: str) -> dict:
        """python-can configuration of bus `name`, for ``vehest_can.bus.open_bus``."""
        return self.bus(name).bus_kwargs()

    def bus_of(self, node: str) -> HilBus:
        """The bus a simulated node runs on (the ECU: its first)."""
        return self.bus(dict(self.node_bus)[node])

    def ecu_routes(self) -> dict[int, str]:
        """Frame ID -> bus for what the simulated ECU sends: the bus whose DBC has the frame from VEHEST."""
        routes: dict[int, str] = {}
        for name in self.ecu_buses:
            for m in load_dbc(self.bus(name).dbc).messages:
                if ECU_NODE in m.senders:
                    routes.setdefault(m.frame_id, name)
        return routes

    @property
    def scenario(self):
        """The first car's scenario (None: no car simulated here)."""
        return self.cars[0].scenario if self.cars else None

    @property
    def ecu_simulated(self) -> bool:
        return ECU_NODE in self.simulated

    @property
    def car_simulated(self) -> bool:
        return bool(self.cars)

    def summary(self) -> list[str]:
        """A table of the buses and a line per simulated part (``vehest-can hil --check``)."""
        head = ("bus", "interface", "channel", "bitrate", "FD", "DBC", "worst %", "nominal %",
                "simulated here", "real (bench)")
        rows = []
        for b in self.buses:
            rate = _rate_text(b.load_bitrate) + ("/" + _rate_text(b.load_data_bitrate) if b.fd else "")
            if b.bitrate is None and b.timing is None:
                rate += " (DBC)"
            rows.append((b.name, b.interface, str(b.channel), rate, "yes" if b.fd else "no", b.dbc.stem,
                         f"{b.load_worst_pct:.1f}", f"{b.load_nominal_pct:.1f}",
                         ", ".join(n for n in b.nodes if n in self.simulated) or "-",
                         ", ".join(n for n in b.nodes if n in self.real) or "-"))
        lines = _table(head, rows, right=(6, 7))
        lines += [f"buses.{b.name}.kwargs: {b.not_checked}" for b in self.buses if b.not_checked]
        lines.append(f"mode {self.mode}; bus load limit {BUS_LOAD_LIMIT_PCT:g}% (worst case, with stuff bits)")
        if self.ecu_simulated:
            lines.append(f"ECU (VEHEST): simulated here on bus{'es' if len(self.ecu_buses) > 1 else ''} "
                         f"{', '.join(self.ecu_buses)}")
        else:
            lines.append("ECU (VEHEST): real, on the bench")
        for car in self.cars:
            sc = car.scenario
            length = f"{self.duration_s:g} s" if self.duration_s else f"{sc.duration_s:g} s (the scenario's)"
            lines.append(f"car ({', '.join(car.nodes)}) of {car.system}: simulated here on bus {car.bus}, "
                         f"scenario {sc.name} ({sc.path}), {length}")
        real_cars = [n for n in self.real if any(n in g for g in _car_groups())]
        if real_cars:
            lines.append(f"car nodes ({', '.join(real_cars)}): real, on the bench")
        return lines


def _rate_text(bps: int | None) -> str:
    if not bps:
        return "-"
    for unit, scale in (("M", 1_000_000), ("k", 1_000)):
        if bps % scale == 0:
            return f"{bps // scale}{unit}"
    return str(bps)


def _table(head, rows, right=()) -> list[str]:
    widths = [max(len(r[i]) for r in (head, *rows)) for i in range(len(head))]
    return ["  ".join(c.rjust(w) if i in right else c.ljust(w) for i, (c, w) in enumerate(zip(r, widths))).rstrip()
            for r in (head, *rows)]


# ---- loading -------------------------------------------------------------------------------

class _Checker(Checker):
    """The schema reader's checks, raising ConfigError (``FILE: dotted.key: problem``), and a HIL file's own."""

    def __init__(self, path: Path):
        super().__init__(path, ConfigError)

    def rate(self, value, key: str, limits: tuple[int, int]) -> int:
        lo, hi = limits
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(key, f"must be a whole number of bit/s (e.g. 500_000), not {type_name(value)}")
        if not lo <= value <= hi:
            self.fail(key, f"{value} bit/s is out of range: must be in {lo}..{hi}")
        return value

    def names(self, value, key: str) -> list[str]:
        if not isinstance(value, list) or not all(isinstance(v, str) and v for v in value):
            self.fail(key, f"must be a list of node names (strings), not {value!r}")
        return value


def load_hil_config(path: str | Path) -> HilConfig:
    """Load and validate a HIL configuration file."""
    path = Path(path)
    return hil_config_from_dict(read_toml(path, ConfigError), path)


def hil_config_from_dict(doc: dict, path: str | Path = "<hil config>") -> HilConfig:
    """Validate a parsed TOML document; relative paths in it are taken from ``path``'s folder."""
    path = Path(path)
    c = _Checker(path)
    base = path.parent
    c.table(doc, "", _TOP)
    description = c.string(doc.get("description", ""), "description")

    if "buses" not in doc:
        c.fail("buses", "missing (required: one [buses.<name>] table per bus)")
    buses_doc = c.table(doc["buses"], "buses", doc["buses"] if isinstance(doc["buses"], dict) else ())
    if not buses_doc:
        c.fail("buses", "no bus: add a [buses.<name>] table")
    databases: dict[Path, Any] = {}
    buses = [_bus(c, name, value, base, databases) for name, value in buses_doc.items()]

    # -- nodes -------------------------------------------------------------------------------
    if "nodes" not in doc:
        c.fail("nodes", "missing (required: nodes.simulated and nodes.real name every node of the buses' DBCs)")
    nodes_doc = c.table(doc["nodes"], "nodes", _NODES)
    declared: dict[str, str] = {}  # node -> "simulated" / "real"
    for role in (SIMULATED, REAL):
        for node in c.names(nodes_doc.get(role, []), f"nodes.{role}"):
            if node in declared:
                also = "" if declared[node] == role else f" (also in nodes.{declared[node]})"
                c.fail(f"nodes.{role}", f"node {node} is declared twice{also}")
            declared[node] = role
    on_bus = {b.name: set(b.nodes) for b in buses}
    in_dbc = {b.name: _dbc_nodes(databases[b.dbc]) for b in buses}
    anywhere = set().union(*on_bus.values())
    for node, role in declared.items():
        if not any(node in names for names in in_dbc.values()):
            known = "; ".join(f"buses.{b}: {', '.join(sorted(n)) or 'none'}" for b, n in in_dbc.items())
            c.fail(f"nodes.{role}", f"node {node} is in no bus's DBC ({known})")
    # A car's node left out follows its car's declared nodes (CIS with DLS and SIM): one role, or declare it.
    inferred: set[str] = set()  # left out, following their car: absent if no car here plays them
    for node in sorted(anywhere - set(declared)):
        partners = {n: declared[n] for g in _car_groups() if node in g for n in g if n in declared}
        if len(set(partners.values())) > 1:
            c.fail("nodes", f"node {node} is not declared and the car it belongs to is both simulated "
                            f"({', '.join(n for n, r in partners.items() if r == SIMULATED)}) and real "
                            f"({', '.join(n for n, r in partners.items() if r == REAL)}): simulate the car's nodes "
                            f"together or not at all")
        if partners:
            declared[node] = next(iter(partners.values()))
            inferred.add(node)
    # a listener (TESTER: the bench's loggers and monitor) sends nothing and no car plays it: nothing
    # to simulate, so it needs no role
    played = {n for g in _car_groups() for n in g} | {ECU_NODE}
    for b in buses:
        senders = {s for m in databases[b.dbc].messages for s in m.senders}
        for node in b.nodes:
            if node not in declared and (node in senders or node in played):
                c.fail("nodes", f"node {node} (on buses.{b.name}, DBC {b.dbc.name}) is not declared: "
                                f"add it to nodes.simulated or nodes.real")
    simulated = tuple(n for n, r in declared.items() if r == SIMULATED)
    real = tuple(n for n, r in declared.items() if r == REAL)
    simulatable = (ECU_NODE, *dict.fromkeys(n for g in _car_groups() for n in g))
    for node in simulated:
        if node not in simulatable:
            c.fail("nodes.simulated", f"vehest-can cannot simulate node {node} (it simulates "
                                      f"{', '.join(simulatable)}): declare {node} real")
    if not simulated:
        c.fail("nodes.simulated", "nothing is simulated here: name at least one node (a car's nodes such as "
                                  "DLS and SIM, VEHEST for the ECU)")
    node_bus: dict[str, str] = {}
    for node in simulated:
        where = [b for b, names in on_bus.items() if node in names]
        if not where:
            c.fail("nodes.simulated", f"node {node} is on no bus (its DBC's bus lists other nodes in `nodes`)")
        if len(where) > 1 and node != ECU_NODE:  # the ECU has a controller on each of its buses
            c.fail("nodes.simulated", f"node {node} would run on buses {' and '.join(where)}: name it in the "
                                      f"`nodes` list of one of them only")
        node_bus[node] = where[0]
    ecu_buses = tuple(b for b, names in on_bus.items() if ECU_NODE in names) if ECU_NODE in simulated else ()

    # -- mode, scenarios (one per simulated car), duration -------------------------------------
    mode = c.string(doc.get("mode", "realtime"), "mode")
    if mode not in MODES:
        c.fail("mode", f"unknown mode {mode!r} (expected one of: {', '.join(MODES)})")
    if mode == "lockstep" and real:
        c.fail("mode", f"lockstep needs every node simulated here (it steps them on SIM_Sync frames); "
                       f"{', '.join(real)} {'is' if len(real) == 1 else 'are'} real: use mode = \"realtime\"")
    duration = c.number(doc["duration_s"], "duration_s", _DURATION) if "duration_s" in doc else None
    car_nodes = [n for n in simulated if n != ECU_NODE]
    cars: list[HilCar] = []
    for key, value in _scenario_values(c, doc):
        system, sc = _scenario(c, key, value, base)
        plays = [n for n in getattr(system, "nodes", ()) if n in anywhere]
        here = [n for n in plays if declared.get(n) == SIMULATED]
        if not here:
            c.fail(key, f"the car of {sc.name} ({system.name}: {', '.join(plays) or 'no node on these buses'}) is "
                        f"real on the bench: there is nothing here for a scenario to drive (remove it, or simulate "
                        f"{', '.join(plays) or 'its nodes'})")
        for n in plays:
            if declared.get(n) == REAL:
                c.fail("nodes.real", f"node {n} belongs to the car of {sc.name} ({system.name}: "
                                     f"{', '.join(plays)}): it is simulated like {here[0]}; simulate the car's "
                                     f"nodes together or not at all (or leave {n} out if it follows)")
        for other in cars:
            both = sorted(set(here) & set(other.nodes))
            if both:
                c.fail(key, f"{', '.join(both)} would be played by two cars ({other.scenario.name} and {sc.name}): "
                            f"one scenario per car")
        buses_of = sorted({node_bus[n] for n in here})
        if len(buses_of) > 1:
            c.fail("nodes.simulated", f"the simulated car ({', '.join(here)}) must be on one bus, not on "
                                      f"{' and '.join(buses_of)}")
        cars.append(HilCar(system.name, sc, tuple(here), buses_of[0]))
    unplayed = [n for n in car_nodes if not any(n in car.nodes for car in cars)]
    # a node left out that no car here plays is not on this bench (ROLL beside a tyre-force car: the
    # chassis node is shared by two systems' cars); a declared one needs its car's scenario
    if all(n in inferred for n in unplayed):
        simulated = tuple(n for n in simulated if n not in unplayed)
        for n in unplayed:
            node_bus.pop(n, None)
        unplayed = []
    if unplayed:
        who = sorted({s.name for s in registered() if set(getattr(s, "nodes", ())) & set(unplayed)})
        c.fail("scenario", f"missing: the car ({', '.join(unplayed)}) is simulated here and needs a scenario to "
                           f"drive ({' or '.join(who)}: a shipped name such as \"launch_2nd\", or a .toml path; "
                           f"a list of them for several cars)")
    if mode == "lockstep" and len(cars) > 1:
        c.fail("scenario", f"lockstep steps one car (its SIM_Sync ticks the ECU): give one scenario, not "
                           f"{len(cars)}, or use mode = \"realtime\"")
    for node, bus_name in node_bus.items():
        for b in buses:
            if b.name == bus_name or (node == ECU_NODE and b.name in ecu_buses):
                _check_firmware_frames(c, b, databases[b.dbc], node)

    return HilConfig(path=path, mode=mode, buses=tuple(buses), simulated=simulated, real=real,
                     cars=tuple(cars), duration_s=duration, description=description,
                     node_bus=tuple(sorted(node_bus.items())), ecu_buses=ecu_buses)


def _car_groups() -> list[tuple[str, ...]]:
    """The nodes each registered system's car plays."""
    return [tuple(getattr(s, "nodes", ())) for s in registered()]


def _scenario_values(c: _Checker, doc: dict) -> list[tuple[str, str]]:
    """`scenario`: one name/path, or a list of them (one per simulated car), with each one's dotted key."""
    if "scenario" not in doc:
        return []
    value = doc["scenario"]
    if isinstance(value, list):
        if not value:
            c.fail("scenario", "an empty list: name one scenario per simulated car")
        return [(f"scenario[{i}]", c.string(v, f"scenario[{i}]")) for i, v in enumerate(value)]
    return [("scenario", c.string(value, "scenario"))]


def _bus(c: _Checker, name: str, doc, base: Path, databases: dict) -> HilBus:
    key = f"buses.{name}"
    if not name.strip():
        c.fail(key, "a bus needs a non-empty name")
    c.table(doc, key, _BUS)
    for required in ("interface", "channel", "dbc"):
        if required not in doc:
            c.fail(f"{key}.{required}", "missing (required)")

    interface = c.string(doc["interface"], f"{key}.interface")
    if interface not in can.VALID_INTERFACES:
        near = difflib.get_close_matches(interface, sorted(can.VALID_INTERFACES), n=1)
        hint = f"did you mean {near[0]!r}? " if near else ""
        c.fail(f"{key}.interface", f"unknown python-can interface {interface!r} ({hint}python-can knows: "
                                   f"{', '.join(sorted(can.VALID_INTERFACES))})")
    channel = doc["channel"]
    if isinstance(channel, bool) or not isinstance(channel, (str, int)) or channel == "":
        c.fail(f"{key}.channel", f"must be a non-empty string or an integer, not {type_name(channel)}")
    fd = c.boolean(doc.get("fd", False), f"{key}.fd")
    bitrate = c.rate(doc["bitrate"], f"{key}.bitrate", _NOMINAL_RATE) if "bitrate" in doc else None
    data_bitrate = c.rate(doc["data_bitrate"], f"{key}.data_bitrate", _DATA_RATE) if "data_bitrate" in doc else None
    if data_bitrate is not None and not fd:
        c.fail(f"{key}.data_bitrate", "a data bit rate needs CAN FD: set fd = true (or remove data_bitrate)")
    timing = _timing(c, doc["timing"], f"{key}.timing", fd) if "timing" in doc else None
    nominal: int | None
    if timing is not None:
        nominal = timing.nom_bitrate if isinstance(timing, can.BitTimingFd) else timing.bitrate
        if bitrate is not None and bitrate != nominal:
            c.fail(f"{key}.bitrate", f"{bitrate} bit/s disagrees with {key}.timing ({nominal} bit/s): "
                                     f"remove bitrate, the timing sets it")
        if isinstance(timing, can.BitTimingFd):
            if data_bitrate is not None and data_bitrate != timing.data_bitrate:
                c.fail(f"{key}.data_bitrate", f"{data_bitrate} bit/s disagrees with {key}.timing "
                                              f"({timing.data_bitrate} bit/s): remove data_bitrate, the timing sets it")
    if bitrate is not None and data_bitrate is not None and data_bitrate < bitrate:
        c.fail(f"{key}.data_bitrate", f"{data_bitrate} bit/s is lower than the nominal bitrate {bitrate} bit/s "
                                      f"(the data phase is the fast one)")
    if interface == "pcan" and fd and timing is None:
        c.fail(f"{key}.timing", "missing: python-can's pcan interface ignores bitrate/data_bitrate in CAN FD "
                                f"mode and needs the FD bit timing: a [{key}.timing] table with "
                                f"{', '.join(_TIMING_FD)}")
    kwargs = _kwargs(c, doc.get("kwargs", {}), f"{key}.kwargs")
    not_checked = _check_opening(c, key, interface, channel, kwargs)

    dbc = _dbc_file(c, c.string(doc["dbc"], f"{key}.dbc"), f"{key}.dbc", base)
    if dbc not in databases:
        try:
            databases[dbc] = load_dbc(dbc)
        except ConfigError as exc:
            c.fail(f"{key}.dbc", str(exc))
    db = databases[dbc]
    try:
        check_cycles(db, dbc.name)
    except ConfigError as exc:
        c.fail(f"{key}.dbc", str(exc))
    fd_frames = [m for m in db.messages if m.is_fd or m.length > 8]
    if fd_frames and not fd:
        listed = ", ".join(f"{m.name} ({m.length} bytes)" for m in fd_frames[:3])
        c.fail(f"{key}.fd", f"must be true: {dbc.name} has CAN FD frames ({listed})")
    dbc_nodes = _dbc_nodes(db)
    if "nodes" in doc:
        nodes = c.names(doc["nodes"], f"{key}.nodes")
        for n in nodes:
            if n not in dbc_nodes:
                c.fail(f"{key}.nodes", f"node {n} is not in {dbc.name} (its nodes: {', '.join(sorted(dbc_nodes))})")
        if len(set(nodes)) != len(nodes):
            c.fail(f"{key}.nodes", "a node is listed twice")
    else:
        nodes = sorted(dbc_nodes)

    # Load at the configured rates (the DBC's Baudrate / BaudrateCANFD where the file gives none).
    nominal = timing.nom_bitrate if isinstance(timing, can.BitTimingFd) else (
        timing.bitrate if timing is not None else bitrate)
    data = timing.data_bitrate if isinstance(timing, can.BitTimingFd) else data_bitrate
    try:
        load = bus_load(db, nominal, data if fd else None, name=name)
    except ConfigError as exc:
        c.fail(f"{key}.bitrate", f"{exc} ({dbc.name})")
    if load.worst_pct > BUS_LOAD_LIMIT_PCT:
        rates = _rate_text(load.bitrate) + (f"/{_rate_text(load.data_bitrate)}" if load.data_bitrate else "")
        where = "timing" if timing is not None else "data_bitrate" if fd else "bitrate"
        c.fail(f"{key}.{where}",
               f"worst-case bus load {load.worst_pct:.1f}% at {rates} bit/s exceeds {BUS_LOAD_LIMIT_PCT:g}% "
               f"({dbc.name}; see `vehest-can busload`): raise the bit rates")
    return HilBus(name=name, interface=interface, channel=channel, fd=fd, dbc=dbc, nodes=tuple(nodes),
                  bitrate=bitrate, data_bitrate=data_bitrate, timing=timing, kwargs=tuple(kwargs.items()),
                  load_bitrate=load.bitrate, load_data_bitrate=load.data_bitrate,
                  load_worst_pct=load.worst_pct, load_nominal_pct=load.nominal_pct, load_notes=load.notes,
                  not_checked=not_checked)


def _timing(c: _Checker, doc, key: str, fd: bool) -> can.BitTiming | can.BitTimingFd:
    doc = c.table(doc, key, set(_TIMING_FD) | set(_TIMING))
    is_fd = any(k.startswith(("nom_", "data_")) for k in doc)
    fields = _TIMING_FD if is_fd else _TIMING
    for k in doc:
        if k not in fields:
            c.fail(f"{key}.{k}", f"does not belong in a{'n FD' if is_fd else ' classic'} bit timing "
                                 f"({', '.join(fields)})")
    for k in fields:
        if k not in doc and k != "nof_samples":
            c.fail(f"{key}.{k}", f"missing: a{'n FD' if is_fd else ' classic'} bit timing needs {', '.join(fields)}")
        if k in doc and (isinstance(doc[k], bool) or not isinstance(doc[k], int) or doc[k] <= 0):
            c.fail(f"{key}.{k}", f"must be a positive integer, not {doc[k]!r}")
    if is_fd and not fd:
        c.fail(f"{key}", "an FD bit timing (nom_*/data_*) needs fd = true")
    if fd and not is_fd:
        c.fail(f"{key}", "a CAN FD bus needs an FD bit timing (f_clock, nom_*, data_*), not a classic one")
    try:
        return can.BitTimingFd(**doc) if is_fd else can.BitTiming(**doc)
    except ValueError as exc:
        c.fail(key, f"python-can refuses this bit timing: {exc}")


def _kwargs(c: _Checker, doc, key: str) -> dict:
    doc = c.table(doc, key, doc if isinstance(doc, dict) else ())
    reserved = _BUS | set(_TIMING_FD) | set(_TIMING)
    for k, v in doc.items():
        if k in reserved:
            where = "the timing table" if k in set(_TIMING_FD) | set(_TIMING) else key.rsplit(".", 1)[0]
            c.fail(f"{key}.{k}", f"set {k} in {where}, not among the extra python-can arguments")
        values = v if isinstance(v, list) else [v]
        if not all(isinstance(x, (str, int, float, bool)) for x in values):
            c.fail(f"{key}.{k}", f"must be a string, number, boolean or a list of them, not {type_name(v)}")
    return dict(doc)


_IFNAMSIZ = 16  # Linux <net/if.h>: a network interface name is at most 15 bytes


def _check_opening(c: _Checker, key: str, interface: str, channel, kwargs: dict) -> str:
    """What opening the bus would refuse (or silently ignore), found now rather than at run time: the
    channel where its form is known without the hardware, and each `kwargs` key against the arguments
    the interface takes (its signature and documented parameters). Returns why the arguments could not
    be checked here ("" when they were)."""
    if interface == "udp_multicast":
        for args, where in (({}, "channel"), (kwargs, "kwargs")):
            try:
                busmod.multicast_settings(channel, **{k: v for k, v in args.items()
                                                      if k in ("port", "hop_limit", "multicast_interface")})
            except can.CanInitializationError as exc:
                c.fail(f"{key}.{where}", str(exc))
    elif interface == "socketcan" and not (isinstance(channel, str) and 0 < len(channel.encode()) < _IFNAMSIZ
                                           and not any(ch in channel for ch in "/ \t")):
        c.fail(f"{key}.channel", f"a SocketCAN channel is a network interface name (can0, vcan0: at most "
                                 f"{_IFNAMSIZ - 1} bytes, no '/' or space), not {channel!r}")
    elif interface == "kvaser" and (isinstance(channel, bool) or not isinstance(channel, int) or channel < 0):
        c.fail(f"{key}.channel", f"a Kvaser channel is a channel number (0, 1, ...), not {channel!r}")
    elif interface == "pcan":
        names = _pcan_channels()
        if names and channel not in names:
            near = difflib.get_close_matches(str(channel), names, n=1)
            c.fail(f"{key}.channel", f"unknown PCAN channel {channel!r} ({f'did you mean {near[0]!r}? ' if near else ''}"
                                     f"e.g. PCAN_USBBUS1)")
    problems, not_checked = busmod.check_bus_kwargs(interface, kwargs)
    for k, problem in problems:
        c.fail(f"{key}.kwargs.{k}", problem)
    return not_checked


def _pcan_channels() -> list[str]:
    try:
        names = busmod.import_quietly("can.interfaces.pcan.basic").PCAN_CHANNEL_NAMES
    except Exception:  # noqa: BLE001 - a module that does not import here: not checked
        return []
    return sorted(names)


def _dbc_file(c: _Checker, value: str, key: str, base: Path) -> Path:
    p = Path(value)
    if not p.suffix and len(p.parts) == 1:  # a bundled DBC by name: "vehest_pt"
        bundled = sorted(f.stem for f in dbc_dir().glob("*.dbc"))
        if value not in bundled:
            c.fail(key, f"no bundled DBC named {value!r} (bundled: {', '.join(bundled)}; or give a path to a .dbc file)")
        return dbc_dir() / f"{value}.dbc"
    p = p if p.is_absolute() else base / p
    if not p.is_file():
        c.fail(key, f"no such file: {p}")
    return p


def _dbc_nodes(db) -> set[str]:
    names = {n.name for n in db.nodes}
    names.update(s for m in db.messages for s in m.senders)
    names.discard("Vector__XXX")  # the DBC placeholder for "no node"
    return names


def _check_firmware_frames(c: _Checker, b: HilBus, db, node: str) -> None:
    """A simulated node sends the frames its firmware was built with (the bundled DBC of that bus): the
    bus's DBC must describe them the same way (name, ID, length), or the bench would decode garbage."""
    def sends(d):
        return {(m.name, m.frame_id, m.is_extended_frame, m.length) for m in d.messages if node in m.senders}

    here = sends(db)
    names = {m.name for m in db.messages}
    bundled = max(BUSES, key=lambda bus: len(names & {m.name for m in database(bus).messages}))
    built = sends(database(bundled))
    if built != here:
        missing = sorted(built - here)
        extra = sorted(here - built)
        what = "; ".join(
            [f"the firmware sends {n} as ID 0x{i:X}, {ln} bytes" for n, i, _, ln in missing[:2]]
            + [f"the DBC has {n} (ID 0x{i:X}, {ln} bytes) from {node}, which the firmware does not send"
               for n, i, _, ln in extra[:2]])
        c.fail(f"buses.{b.name}.dbc", f"{b.dbc.name} does not match the frames of simulated node {node} "
                                      f"(built from the bundled vehest_{bundled}.dbc): {what}")


def _scenario(c: _Checker, key: str, value: str, base: Path) -> tuple[System, Any]:
    """A scenario of any registered system: a shipped one's name, or a .toml path (relative to `base`)."""
    p = Path(value)
    if p.suffix == ".toml" or len(p.parts) > 1:
        p = p if p.is_absolute() else base / p
    else:
        shipped = {q.stem: q for q in shipped_scenarios()}
        if value not in shipped:
            c.fail(key, f"no shipped scenario named {value!r} (shipped: {', '.join(sorted(shipped))}; "
                        f"or give a .toml path)")
        p = shipped[value]
    try:
        doc = read_toml(p, ScenarioError)
        system = claiming(doc)
        if system is None:
            c.fail(key, f"{p}: {unclaimed(doc)}")
        return system, system.load(p)
    except ScenarioError as exc:
        c.fail(key, str(exc))


# ---- running the simulated part -------------------------------------------------------------

@dataclass
class HilResult:
    ecu: Any = None          # DaemonStats when the ECU was simulated here
    sessions: list = field(default_factory=list)  # (HilCar, sim.Session) of each car simulated here
    ecu_buses: tuple[str, ...] = ()
    bus_info: list[str] = field(default_factory=list)  # where each opened handle's frames go

    @property
    def session(self):
        """The first car's session (None: no car here)."""
        return self.sessions[0][1] if self.sessions else None

    @property
    def ecu_bus(self) -> str | None:
        return self.ecu_buses[0] if self.ecu_buses else None

    @property
    def car_bus(self) -> str | None:
        return self.sessions[0][0].bus if self.sessions else None


class ResidualBus:
    """Runs the simulated nodes of a configuration: an EcuDaemon on every bus of the ECU, a SimMaster
    per car, or both (one process, one thread each). ``stop()`` (e.g. from a signal handler) ends the
    run early, cleanly. `configure(ecu)` is applied to the simulated ECU first (e.g. calibrations)."""

    def __init__(self, config: HilConfig, *, duration_s: float | None = None, notifier=None, progress=None,
                 configure=None, car=None):
        self.config = config
        self.duration_s = duration_s if duration_s is not None else config.duration_s
        self.notifier = notifier
        self.progress = progress
        self.configure = configure
        self.car = car  # the car the simulated ECU is calibrated for (None: the paper's)
        self.stop_event = threading.Event()

    def stop(self) -> None:
        self.stop_event.set()

    def run(self) -> HilResult:
        cfg = self.config
        result = HilResult()
        opened: list[can.BusABC] = []

        def open_(name: str, who: str) -> can.BusABC:
            # A handle of its own for each part even on a shared bus: python-can hands each frame to
            # one reader per handle.
            opened.append(busmod.open_bus(cfg.bus_kwargs(name)))
            result.bus_info.append(f"{who}: bus {name}: " + busmod.describe_bus(opened[-1], cfg.bus_kwargs(name)))
            return opened[-1]

        try:
            daemon = None
            if cfg.ecu_simulated:
                result.ecu_buses = cfg.ecu_buses
                daemon = EcuDaemon({n: open_(n, "ecu") for n in cfg.ecu_buses}, Ecu(EcuConfig(car=self.car)),
                                   routes=cfg.ecu_routes(), notifier=self.notifier)
                if self.configure is not None:
                    self.configure(daemon.ecu)
                daemon.stop_event = self.stop_event
            masters = []
            for i, car in enumerate(cfg.cars):
                system = next(s for s in registered() if s.name == car.system)
                master = SimMaster(open_(car.bus, f"car {car.scenario.name}"),
                                   system.car(car.scenario, self.duration_s),
                                   progress=self.progress if i == 0 else None)
                master.stop_event = self.stop_event
                masters.append((car, master))
            result.ecu, sessions = self._run(daemon, masters)
            result.sessions = list(zip([car for car, _ in masters], sessions))
        finally:
            for b in opened:
                b.shutdown()
        return result

    def _run(self, daemon, masters):
        """The ECU daemon in a thread, the first car in this one, any other car in a thread of its
        own; the ECU stops when the cars are done. An ECU alone runs for the duration (or until stopped)."""
        if not masters:
            return daemon.serve_realtime(duration=self.duration_s), []
        lockstep = self.config.mode == "lockstep"
        out: dict[str, Any] = {}

        def guarded(key, fn):
            def run():
                try:
                    out[key] = fn()
                except BaseException as exc:  # re-raised in the main thread
                    out.setdefault("error", exc)
                    self.stop_event.set()
            return run

        threads = []
        if daemon is not None:
            serve = (lambda: daemon.serve_lockstep(exit_on_end=True)) if lockstep else daemon.serve_realtime
            # Both 2 kHz loops share one GIL; they release it while they sleep to their next tick. (A
            # shorter sys.setswitchinterval measured no better: docs/hil.md.)
            threads.append(threading.Thread(target=guarded("stats", serve), name="ecu-daemon", daemon=True))
            threads[-1].start()
        try:
            if lockstep:  # one car (the loader's rule); its RESET handshake waits for the daemon
                sessions = [masters[0][1].run_lockstep()]
                if threads:
                    threads[0].join(5.0)  # the daemon stops on END
            else:
                if daemon is not None:
                    self.stop_event.wait(0.2)  # the daemon's receiver is up before the first sensor frame
                cars = [threading.Thread(target=guarded(i, m.run_realtime), name=f"car-{i}", daemon=True)
                        for i, (_, m) in enumerate(masters[1:], 1)]
                for t in cars:
                    t.start()
                first = masters[0][1].run_realtime()
                for t in cars:
                    t.join()
                if "error" in out:
                    raise out["error"]
                sessions = [first, *(out[i] for i in range(1, len(masters)))]
        finally:
            self.stop_event.set()
            for t in threads:
                t.join(10.0)
        if "error" in out:
            raise out["error"]
        if daemon is not None and "stats" not in out:
            raise VehestError("the simulated ECU did not stop within 10 s")
        return out.get("stats"), sessions
