"""HIL rehearsal: a TOML file names the buses, the DBC on each, and which nodes are simulated here.

Residual-bus simulation: simulate only what the bench lacks. The project can simulate three nodes
of the PT bus (``dbc/vehest_pt.dbc``): ``VEHEST`` (the ECU, :class:`~vehest_can.service.daemon.EcuDaemon`)
and the car, ``DLS`` (driveline sensor node) with ``SIM`` (the plant / simulation master), both in
:class:`~vehest_can.sim.SimMaster`. Every other node of a bus's DBC is real (on the bench) or absent.

The schema is documented in ``docs/hil.md``. ``load_hil_config`` checks every key and raises
:class:`~vehest_can.errors.ConfigError` whose message names the file, the key as a dotted path and
the problem; ``run_residual`` runs the simulated nodes against the configured buses.
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
from ..bus.busload import bus_load, load_dbc
from ..bus.frames import database
from ..errors import ConfigError, ScenarioError, VehestError
from ..paths import dbc_dir
from ..schema import Checker, Num, read_toml, type_name
from ..sim.scenario import Scenario, list_scenarios, load_scenario, scenario_path
from ..sim.session import SimMaster, drive_from_scenario
from .daemon import EcuDaemon

log = logging.getLogger(__name__)

#: Worst-case bus load a configuration may reach at its bit rates, %.
BUS_LOAD_LIMIT_PCT = 60.0

SIMULATED, REAL = "simulated", "real"
ECU_NODE = "VEHEST"
CAR_NODES = ("DLS", "SIM")  # one simulated car: sensor node + plant/simulation master, one SimMaster
# Nodes the simulated car also plays when its DBC has them (the camber inspection devices): they
# follow the car's role unless declared, and may not be declared otherwise.
CAR_ACCESSORIES = ("CIS",)
SIMULATABLE = (*CAR_NODES, *CAR_ACCESSORIES, ECU_NODE)
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
# python-can interfaces where several handles on one channel all see each other's frames.
SHAREABLE_INTERFACES = ("virtual", "udp_multicast", "socketcan")


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
class HilConfig:
    """A validated HIL configuration (see the module docstring)."""

    path: Path
    mode: str
    buses: tuple[HilBus, ...]
    simulated: tuple[str, ...]
    real: tuple[str, ...]
    scenario: Scenario | None = None
    duration_s: float | None = None
    description: str = ""
    node_bus: tuple[tuple[str, str], ...] = ()  # (simulated node, bus name)

    def bus(self, name: str) -> HilBus:
        for b in self.buses:
            if b.name == name:
                return b
        raise KeyError(f"no bus {name!r} in {self.path} (buses: {', '.join(b.name for b in self.buses)})")

    def bus_kwargs(self, name: str) -> dict:
        """python-can configuration of bus `name`, for ``vehest_can.bus.open_bus``."""
        return self.bus(name).bus_kwargs()

    def bus_of(self, node: str) -> HilBus:
        """The bus a simulated node runs on."""
        return self.bus(dict(self.node_bus)[node])

    @property
    def ecu_simulated(self) -> bool:
        return ECU_NODE in self.simulated

    @property
    def car_simulated(self) -> bool:
        return CAR_NODES[0] in self.simulated

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
        lines.append(f"mode {self.mode}; bus load limit {BUS_LOAD_LIMIT_PCT:g}% (worst case, with stuff bits)")
        if self.ecu_simulated:
            lines.append(f"ECU (VEHEST): simulated here on bus {self.bus_of(ECU_NODE).name}")
        if self.car_simulated:
            sc = self.scenario
            assert sc is not None  # a simulated car has its scenario
            length = f"{self.duration_s:g} s" if self.duration_s else f"{sc.duration_s:g} s (the scenario's)"
            lines.append(f"car (DLS, SIM): simulated here on bus {self.bus_of(CAR_NODES[0]).name}, "
                         f"scenario {sc.name} ({sc.path}), {length}")
        if not self.ecu_simulated:
            lines.append("ECU (VEHEST): real, on the bench")
        if not self.car_simulated:
            lines.append("car (DLS, SIM): real, on the bench")
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
    car_role = declared.get(CAR_NODES[0])
    for node in CAR_ACCESSORIES:
        if node in declared and car_role is not None and declared[node] != car_role:
            c.fail(f"nodes.{declared[node]}", f"node {node} belongs to the car: it is {car_role} like "
                                              f"{CAR_NODES[0]}, or leave it out")
        if node not in declared and car_role is not None and any(node in n for n in on_bus.values()):
            declared[node] = car_role
    for node, role in declared.items():
        if not any(node in names for names in in_dbc.values()):
            known = "; ".join(f"buses.{b}: {', '.join(sorted(n)) or 'none'}" for b, n in in_dbc.items())
            c.fail(f"nodes.{role}", f"node {node} is in no bus's DBC ({known})")
    for b in buses:
        for node in b.nodes:
            if node not in declared:
                c.fail("nodes", f"node {node} (on buses.{b.name}, DBC {b.dbc.name}) is not declared: "
                                f"add it to nodes.simulated or nodes.real")
    simulated = tuple(n for n, r in declared.items() if r == SIMULATED)
    real = tuple(n for n, r in declared.items() if r == REAL)
    for node in simulated:
        if node not in SIMULATABLE:
            c.fail("nodes.simulated", f"vehest-can cannot simulate node {node} (it simulates "
                                      f"{', '.join(SIMULATABLE)}): declare {node} real")
    if not simulated:
        c.fail("nodes.simulated", "nothing is simulated here: name at least one node (DLS and SIM for the "
                                  "car, VEHEST for the ECU)")
    car = [n for n in CAR_NODES if n in simulated]
    if car and len(car) != len(CAR_NODES):
        c.fail("nodes.simulated", f"{' and '.join(CAR_NODES)} are one simulated car (sensor node and plant): "
                                  f"simulate both or neither, not only {car[0]}")
    node_bus: dict[str, str] = {}
    for node in simulated:
        where = [b for b, names in on_bus.items() if node in names]
        if not where:
            c.fail("nodes.simulated", f"node {node} is on no bus (its DBC's bus lists other nodes in `nodes`)")
        if len(where) > 1:
            c.fail("nodes.simulated", f"node {node} would run on buses {' and '.join(where)}: name it in the "
                                      f"`nodes` list of one of them only")
        node_bus[node] = where[0]
    if car and node_bus[CAR_NODES[0]] != node_bus[CAR_NODES[1]]:
        c.fail("nodes.simulated", f"the simulated car ({', '.join(CAR_NODES)}) must be on one bus, not on "
                                  f"{node_bus[CAR_NODES[0]]} and {node_bus[CAR_NODES[1]]}")
    for node, bus_name in node_bus.items():
        b = next(x for x in buses if x.name == bus_name)
        _check_firmware_frames(c, b, databases[b.dbc], node)

    # -- mode, scenario, duration ------------------------------------------------------------
    mode = c.string(doc.get("mode", "realtime"), "mode")
    if mode not in MODES:
        c.fail("mode", f"unknown mode {mode!r} (expected one of: {', '.join(MODES)})")
    if mode == "lockstep" and real:
        c.fail("mode", f"lockstep needs every node simulated here (it steps them on SIM_Sync frames); "
                       f"{', '.join(real)} {'is' if len(real) == 1 else 'are'} real: use mode = \"realtime\"")
    duration = c.number(doc["duration_s"], "duration_s", _DURATION) if "duration_s" in doc else None
    scenario = None
    if car:
        if "scenario" not in doc:
            c.fail("scenario", "missing: the car (DLS, SIM) is simulated here and needs a scenario to drive "
                               "(a shipped name such as \"launch_2nd\", or a .toml path)")
        scenario = _scenario(c, c.string(doc["scenario"], "scenario"), base)
    elif "scenario" in doc:
        c.fail("scenario", "the car (DLS, SIM) is real on the bench: there is nothing here for a scenario to "
                           "drive (remove the key, or simulate DLS and SIM)")

    return HilConfig(path=path, mode=mode, buses=tuple(buses), simulated=simulated, real=real,
                     scenario=scenario, duration_s=duration, description=description,
                     node_bus=tuple(sorted(node_bus.items())))


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

    dbc = _dbc_file(c, c.string(doc["dbc"], f"{key}.dbc"), f"{key}.dbc", base)
    if dbc not in databases:
        try:
            databases[dbc] = load_dbc(dbc)
        except ConfigError as exc:
            c.fail(f"{key}.dbc", str(exc))
    db = databases[dbc]
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
                  load_worst_pct=load.worst_pct, load_nominal_pct=load.nominal_pct, load_notes=load.notes)


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
    """A simulated node sends the frames its firmware was built with (the bundled PT DBC): the bus's
    DBC must describe them the same way (name, ID, length), or the bench would decode garbage."""
    def sends(d):
        return {(m.name, m.frame_id, m.is_extended_frame, m.length) for m in d.messages if node in m.senders}

    built, here = sends(database("pt")), sends(db)
    if built != here:
        missing = sorted(built - here)
        extra = sorted(here - built)
        what = "; ".join(
            [f"the firmware sends {n} as ID 0x{i:X}, {ln} bytes" for n, i, _, ln in missing[:2]]
            + [f"the DBC has {n} (ID 0x{i:X}, {ln} bytes) from {node}, which the firmware does not send"
               for n, i, _, ln in extra[:2]])
        c.fail(f"buses.{b.name}.dbc", f"{b.dbc.name} does not match the frames of simulated node {node} "
                                      f"(built from the bundled vehest_pt.dbc): {what}")


def _scenario(c: _Checker, value: str, base: Path) -> Scenario:
    p = Path(value)
    if p.suffix == ".toml" or len(p.parts) > 1:
        p = p if p.is_absolute() else base / p
    else:
        p = scenario_path(value)  # a shipped scenario's name
        if not p.is_file():
            c.fail("scenario", f"no shipped scenario named {value!r} (shipped: {', '.join(list_scenarios())}; "
                               f"or give a .toml path)")
    try:
        return load_scenario(p)
    except ScenarioError as exc:
        c.fail("scenario", str(exc))


# ---- running the simulated part -------------------------------------------------------------

@dataclass
class HilResult:
    ecu: Any = None          # DaemonStats when the ECU was simulated here
    session: Any = None      # sim.Session when the car was simulated here
    ecu_bus: str | None = None
    car_bus: str | None = None
    bus_info: list[str] = field(default_factory=list)  # where each opened handle's frames go


class ResidualBus:
    """Runs the simulated nodes of a configuration: an EcuDaemon, a SimMaster, or both (one process).

    ``stop()`` (e.g. from a signal handler) ends the run early, cleanly.
    """

    def __init__(self, config: HilConfig, *, duration_s: float | None = None, notifier=None, progress=None):
        self.config = config
        self.duration_s = duration_s if duration_s is not None else config.duration_s
        self.notifier = notifier
        self.progress = progress
        self.stop_event = threading.Event()

    def stop(self) -> None:
        self.stop_event.set()

    def run(self) -> HilResult:
        cfg = self.config
        result = HilResult()
        opened: list[can.BusABC] = []
        try:
            daemon = master = None
            if cfg.ecu_simulated:
                result.ecu_bus = cfg.bus_of(ECU_NODE).name
                opened.append(busmod.open_bus(cfg.bus_kwargs(result.ecu_bus)))
                result.bus_info.append(f"ecu: bus {result.ecu_bus}: "
                                       + busmod.describe_bus(opened[-1], cfg.bus_kwargs(result.ecu_bus)))
                daemon = EcuDaemon(opened[-1], notifier=self.notifier)
                daemon.stop_event = self.stop_event
            if cfg.car_simulated:
                # Its own handle even on the ECU's bus: python-can hands each frame to one reader per handle.
                result.car_bus = cfg.bus_of(CAR_NODES[0]).name
                opened.append(busmod.open_bus(cfg.bus_kwargs(result.car_bus)))
                result.bus_info.append(f"car: bus {result.car_bus}: "
                                       + busmod.describe_bus(opened[-1], cfg.bus_kwargs(result.car_bus)))
                drive = drive_from_scenario(cfg.scenario, self.duration_s)
                master = SimMaster(opened[-1], drive, progress=self.progress)
                master.stop_event = self.stop_event
            if master is None:
                assert daemon is not None  # a configuration simulates the ECU, the car or both
                result.ecu = daemon.serve_realtime(duration=self.duration_s)
            elif daemon is None:
                result.session = master.run_realtime()
            else:
                result.ecu, result.session = self._both(daemon, master)
        finally:
            for b in opened:
                b.shutdown()
        return result

    def _both(self, daemon, master):
        """The ECU daemon in a thread, the car in this one; the ECU stops when the car is done."""
        lockstep = self.config.mode == "lockstep"
        out: dict[str, Any] = {}

        def serve():
            try:
                out["stats"] = daemon.serve_lockstep(exit_on_end=True) if lockstep else daemon.serve_realtime()
            except BaseException as exc:  # re-raised in the main thread
                out["error"] = exc

        # Both 2 kHz loops share one GIL; they release it while they sleep to their next tick. (A shorter
        # sys.setswitchinterval measured no better: docs/hil.md.)
        thread = threading.Thread(target=serve, name="ecu-daemon", daemon=True)
        thread.start()
        try:
            if lockstep:
                session = master.run_lockstep()  # its RESET handshake waits for the daemon
                thread.join(5.0)                 # the daemon stops on END
            else:
                self.stop_event.wait(0.2)        # the daemon's receiver is up before the first sensor frame
                session = master.run_realtime()
        finally:
            self.stop_event.set()
            thread.join(10.0)
        if "error" in out:
            raise out["error"]
        if "stats" not in out:
            raise VehestError("the simulated ECU did not stop within 10 s")
        return out["stats"], session
